"""Readable print-out of the identified model."""

from __future__ import annotations

import numpy as np

__all__ = ["correction_rows", "format_correction", "format_equations", "output_name"]


def _term(coefficient: float, name: str, precision: int) -> str:
    sign = "-" if coefficient < 0 else "+"
    factor = "" if name == "1" else f" {name}"
    return f" {sign} {abs(coefficient):.{precision}g}{factor}"


def format_correction(row, names, precision: int = 4) -> str:
    """Non-zero terms of one correction row, e.g. ``" + 0.12 x1 u - 3.4 x2^2"``."""
    return "".join(_term(c, n, precision) for c, n in zip(row, names, strict=True) if c != 0)


def format_equations(physics, coef, feature_names, rows, precision: int = 4) -> list:
    """One line per state, ``x1[k+1] = f_1(x, u; θ) + <sparse correction>``, then one per
    corrected output, ``output z1 = h_1(x, u; θ) + <sparse correction>``.

    ``rows`` is ``(delta_states, delta_outputs)``, the targets of the rows of ``coef``."""
    delta_states, delta_outputs = rows
    coef = np.atleast_2d(coef) if np.size(coef) else np.zeros((0, len(feature_names)))
    states = dict(zip(delta_states, coef, strict=False))
    outputs = dict(zip(delta_outputs, coef[len(delta_states) :], strict=False))
    lines = []
    for i, state in enumerate(physics.state_names):
        correction = format_correction(states[i], feature_names, precision) if i in states else ""
        lines.append(f"{state}[k+1] = f_{i + 1}(x[k], u[k]; θ){correction}")
    for i, row in outputs.items():
        correction = format_correction(row, feature_names, precision)
        lines.append(f"output {output_name(physics, i)} = h_{i + 1}(x[k], u[k]; θ){correction}")
    return lines


def output_name(physics, index: int) -> str:
    """The name of output ``index`` (``physics.output_names``, else ``z1``, ``z2``, ...)."""
    names = getattr(physics, "output_names", None)
    return names[index] if names else f"z{index + 1}"


def correction_rows(estimator) -> list[str]:
    """The variable each row of a fitted estimator's ``coef_`` corrects: state names, then
    ``output <name>`` for each corrected output."""
    physics = estimator.physics_
    return [physics.state_names[i] for i in estimator.delta_states_] + [
        f"output {output_name(physics, i)}" for i in estimator.delta_outputs_
    ]
