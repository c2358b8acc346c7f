"""Readable print-out of the identified model."""

from __future__ import annotations

import numpy as np

__all__ = ["format_correction", "format_equations"]


def _term(coefficient: float, name: str, precision: int) -> str:
    sign = "-" if coefficient < 0 else "+"
    factor = "" if name == "1" else f" {name}"
    return f" {sign} {abs(coefficient):.{precision}g}{factor}"


def format_correction(row, names, precision: int = 4) -> str:
    """Non-zero terms of one correction row, e.g. ``" + 0.12 x1 u - 3.4 x2^2"``."""
    return "".join(_term(c, n, precision) for c, n in zip(row, names, strict=True) if c != 0)


def format_equations(physics, coef, feature_names, delta_states, precision: int = 4) -> list:
    """One line per state: ``x1[k+1] = f_1(x, u; θ) + <sparse correction>``."""
    rows = dict(zip(delta_states, np.atleast_2d(coef), strict=False)) if np.size(coef) else {}
    lines = []
    for i, state in enumerate(physics.state_names):
        correction = format_correction(rows[i], feature_names, precision) if i in rows else ""
        lines.append(f"{state}[k+1] = f_{i + 1}(x[k], u[k]; θ){correction}")
    return lines
