r"""A dictionary of Gaussian bumps of chosen variables: smooth, local corrections.

A polynomial bends a whole curve to fix one stretch of it; a sensor whose reading is off by
a bump between two levels (a capacitive gauge, a thermocouple's junction) is better told by
terms that are local in the level:

$$
\varphi_{jk}(v) = \exp\Big(-\tfrac12 \Big(\frac{v_j - c_{jk}}{w_j}\Big)^2\Big),
$$

with centres $c_{jk}$ and a width $w_j$ per variable $v_j$ of
$v = [x; u]$, after (``linear=True``) the constant 1 and $v_j$ itself. With
``limits``, $v_j$ is first clipped into $[a_j, b_j]$, so that beyond the range
the correction was fitted on it holds its value at the edge instead of falling back to
zero (or growing, for the linear term): a curve known only over the data is not
extrapolated. [`RadialBasis.from_data`][sk_offwhite.RadialBasis.from_data] spreads the centres
evenly over the mean $\pm$ ``span`` standard deviations of the variable, sets the width to their
spacing and the limits to the data's range, so the dictionary, and the model fitted with it, do
not depend on the variable's units.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np

from ._compiled import _shared_row

__all__ = ["RadialBasis"]


class RadialBasis:
    """Gaussian bumps of chosen entries of $[x; u]$, a dictionary for the correction.

    Parameters
    ----------
    centers : mapping of str to sequence of float
        The centres of each variable's bumps, by the variable's name (a state or input
        name of the physics), in its units.
    widths : mapping of str to float
        The width $w_j > 0$ of each variable's bumps, in its units.
    linear : bool, default=True
        Put the constant 1 and each variable itself before its bumps (an offset and a gain).
    limits : mapping of str to (float, float), default=None
        The range $[a_j, b_j]$ each named variable is clipped into before its
        features are evaluated; variables not named are not clipped.

    Notes
    -----
    Features are named ``exp(-0.5 ((x2 - 5.63) / 0.65)^2)`` (``clip(x2)`` for a clipped
    variable), so a fitted correction reads as an equation. Compiled by
    `compile_basis`.
    """

    def __init__(self, centers: Mapping, widths: Mapping, *, linear: bool = True, limits=None):
        self.centers = {str(k): tuple(float(c) for c in v) for k, v in dict(centers).items()}
        self.widths = {str(k): float(v) for k, v in dict(widths).items()}
        self.linear = bool(linear)
        self.limits = {str(k): tuple(float(b) for b in v) for k, v in dict(limits or {}).items()}
        _check(self.centers, self.widths, self.limits)

    @classmethod
    def from_data(
        cls,
        values,
        names: Sequence[str],
        *,
        n_bumps: int = 7,
        span: float = 2.0,
        width: float | None = None,
        linear: bool = True,
    ) -> RadialBasis:
        """Bumps of each column of ``values`` (named ``names``), ``n_bumps`` centres evenly
        over its mean ± ``span`` standard deviations, of ``width`` standard deviations
        (``None``: the centres' spacing)."""
        values = np.asarray(values, float).reshape(len(values), -1)
        if values.shape[1] != len(names) or not np.all(np.isfinite(values)):
            raise ValueError(f"values must be finite, one column per name of {list(names)}.")
        if isinstance(n_bumps, bool) or int(n_bumps) != n_bumps or n_bumps < 2:
            raise ValueError(f"n_bumps must be an integer >= 2, got {n_bumps!r}.")
        mean, spread = values.mean(axis=0), values.std(axis=0)
        if not np.all(spread > 0):
            raise ValueError("every variable must vary over values (a standard deviation > 0).")
        offsets = np.linspace(-span, span, int(n_bumps))
        centers = {n: mean[j] + spread[j] * offsets for j, n in enumerate(names)}
        relative = offsets[1] - offsets[0] if width is None else float(width)
        widths = {n: spread[j] * relative for j, n in enumerate(names)}
        limits = {n: (values[:, j].min(), values[:, j].max()) for j, n in enumerate(names)}
        return cls(centers, widths, linear=linear, limits=limits)

    def feature_names(self) -> list[str]:
        """The names of the features, in order."""
        names = ["1"] if self.linear else []
        for name, centers in self.centers.items():
            variable = f"clip({name})" if name in self.limits else name
            names += [variable] if self.linear else []
            width = self.widths[name]
            names += [f"exp(-0.5 (({variable} - {c:.4g}) / {width:.4g})^2)" for c in centers]
        return names

    def key(self) -> tuple:
        """A hashable description (equal dictionaries share one compiled program)."""
        settings = (self.centers, self.widths, self.limits)
        return ("radial", *(tuple(d.items()) for d in settings), self.linear)

    def __eq__(self, other) -> bool:
        return isinstance(other, RadialBasis) and self.key() == other.key()

    def __hash__(self) -> int:
        return hash(self.key())

    def __repr__(self) -> str:
        settings = f"centers={self.centers!r}, widths={self.widths!r}, linear={self.linear}"
        return f"RadialBasis({settings}, limits={self.limits!r})"


def _check(centers: dict, widths: dict, limits: dict) -> None:
    if not centers or set(centers) != set(widths):
        raise ValueError(
            "centers and widths must name the same, non-empty set of variables; got "
            f"{sorted(centers)} and {sorted(widths)}."
        )
    for name, values in centers.items():
        if not values or not np.all(np.isfinite(values)):
            raise ValueError(f"centers[{name!r}] must be a non-empty sequence of finite values.")
        if not (np.isfinite(widths[name]) and widths[name] > 0):
            raise ValueError(f"widths[{name!r}] must be finite and > 0, got {widths[name]!r}.")
    for name, bounds in limits.items():
        if name not in centers or len(bounds) != 2 or not bounds[0] <= bounds[1]:
            raise ValueError(
                f"limits[{name!r}] must be (low, high) with low <= high for a variable of "
                f"centers; got {bounds!r}."
            )


def _compile_radial(library: RadialBasis, features: tuple[str, ...], n_delta: int):
    """Compile a `RadialBasis` (the row shared by all rows)."""
    missing = [name for name in library.centers if name not in features]
    if missing:
        raise ValueError(f"RadialBasis names {missing}, which are not among {list(features)}.")
    groups = [
        (features.index(name), centers, library.widths[name], library.limits.get(name))
        for name, centers in library.centers.items()
    ]

    def phi(v: jnp.ndarray) -> jnp.ndarray:
        columns = [jnp.ones((), v.dtype)] if library.linear else []
        for j, centers, width, limits in groups:
            value = v[j] if limits is None else jnp.clip(v[j], *limits)
            columns += [value] if library.linear else []
            columns += [jnp.exp(-0.5 * ((value - c) / width) ** 2) for c in centers]
        return jnp.stack(columns)

    return _shared_row(phi, tuple(library.feature_names()), features, n_delta)
