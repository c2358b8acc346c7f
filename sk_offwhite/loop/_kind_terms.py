r"""What a physicist would look for first, by the declared kind of each variable.

Besides the evidence of the user's dictionary (the projected gain of every term at the
declared fit), the loop reads, for a pysindy dictionary and on a fit of its own, the
functions a physicist tries first for each declared kind and where each variable is
seen (``LoopSettings(kind_notes=True)``, the default):

| variable | functions | a sign of |
|---|---|---|
| velocity, rate | $\operatorname{sign}(v)$, $v\lvert v\rvert$ | a Coulomb friction, a drag |
| level | $\sqrt{\lvert h\rvert}$ | an outflow through an orifice |
| temperature | $(T - T_{\min})^{5/4}$, $(T - T_{\min})^2$ | convection, radiation |
| changes sign | $\lvert x\rvert$ | a loss in an effort's size, a directional damping |
| measured state, input | $x / (s + \lvert x\rvert)$ | a saturation |

$T_{\min}$ is the lowest temperature the declared physics simulates on the record and
$s$ the variable's RMS there, so each function is unit-free: rescaling a variable's unit
(or shifting a temperature's, from kelvin to degrees Celsius) rescales its column, which
the gains do not see. The note names those
that explain more than the dictionary's best term: a friction then shows up as an odd
function of the velocity rather than as the sign-blind $v^2$ of a polynomial dictionary,
a saturation as a saturation rather than as a cubic. The functions inform the reader
only: the hypotheses, the candidates and the promoted terms stay the dictionary's, whose
choices the functions' columns would otherwise shift.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from ..dictionaries._compiled import _xp
from ..effects._hidden import n_declared_states
from ..model._kinds import LEVEL_KINDS, VELOCITY_KINDS, physical_kinds
from ..model._physics import measured_states

__all__ = ["with_kind_terms"]

TEMPERATURE_POWERS = (1.25, 2.0)
"""Powers of a temperature's excess: natural convection's 5/4 and radiation's first
correction (the square term of $T^4 - T_a^4$ about the ambient)."""


class KindGroup(NamedTuple):
    """Functions of one pysindy ``CustomLibrary``: each with its name function and what it
    is a sign of, on the variables ``columns`` of ``v = [x; u]``."""

    functions: tuple[Callable, ...]
    names: tuple[Callable, ...]
    meanings: tuple[str, ...]
    columns: list[int]


def sign_of(x):
    """The sign of ``x``: a Coulomb friction's shape."""
    return _xp(x).sign(x)


def signed_square(x):
    """``x |x|``: a drag's shape."""
    return x * _xp(x).abs(x)


def root_of(x):
    """``sqrt(|x|)``: an orifice's outflow from a level."""
    return _xp(x).sqrt(_xp(x).abs(x))


def size_of(x):
    """``|x|``: a loss in the size of an effort."""
    return _xp(x).abs(x)


def sign_name(x: str) -> str:
    return f"sign({x})"


def signed_square_name(x: str) -> str:
    return f"{x}|{x}|"


def root_name(x: str) -> str:
    return f"sqrt|{x}|"


def size_name(x: str) -> str:
    return f"|{x}|"


def saturation(scale: float) -> tuple[Callable, Callable]:
    """``x / (scale + |x|)`` and its name: a saturation whose knee is at ``scale``."""

    def saturating(x):
        return x / (scale + _xp(x).abs(x))

    def saturating_name(x: str) -> str:
        return f"{x}/({scale:.3g}+|{x}|)"

    return saturating, saturating_name


def excess_power(floor: float, power: float) -> tuple[Callable, Callable]:
    """``|x - floor|^power`` and its name: a power of the excess over ``floor``."""

    def excess(x):
        return _xp(x).abs(x - floor) ** power

    def excess_name(x: str) -> str:
        return f"({x}-{floor:.4g})^{power:g}"

    return excess, excess_name


def kind_groups(physics, u: np.ndarray, states: np.ndarray) -> list[KindGroup]:
    """The `KindGroup` of each kind's functions, for the declared states (simulated as
    ``states``) and the inputs ``u`` that have that kind (the module docstring's table)."""
    n_declared = n_declared_states(physics)
    values = np.column_stack([np.asarray(states, float)[:, :n_declared], np.asarray(u, float)])
    kinds = physical_kinds(physics).states[:n_declared]
    velocities = [i for i, kind in enumerate(kinds) if kind in VELOCITY_KINDS]
    levels = [i for i, kind in enumerate(kinds) if kind in LEVEL_KINDS]
    signed = [j for j in range(values.shape[1]) if values[:, j].min() < 0 < values[:, j].max()]
    groups = [
        KindGroup(
            (sign_of, signed_square), (sign_name, signed_square_name),
            ("a Coulomb friction", "a drag"), velocities,
        ),
        KindGroup((root_of,), (root_name,), ("an outflow through an orifice",), levels),
        KindGroup(
            (size_of,), (size_name,), ("a damping that differs with the direction",),
            [j for j in signed if j in velocities],
        ),
        KindGroup(
            (size_of,), (size_name,), ("a loss in its size",),
            [j for j in signed if j not in velocities],
        ),
    ]  # fmt: skip
    groups += _temperature_groups(kinds, values) + _saturation_groups(physics, values)
    return [group for group in groups if group.columns]


def _temperature_groups(kinds, values: np.ndarray) -> list[KindGroup]:
    """Powers of each temperature's excess over its lowest simulated value."""
    groups = []
    for i, kind in enumerate(kinds):
        if kind == "temperature" and np.ptp(values[:, i]) > 0:
            pairs = [excess_power(float(values[:, i].min()), p) for p in TEMPERATURE_POWERS]
            functions, names = zip(*pairs, strict=True)
            meanings = ("a convective loss", "a radiative loss")
            groups.append(KindGroup(functions, names, meanings, [i]))
    return groups


def _saturation_groups(physics, values: np.ndarray) -> list[KindGroup]:
    """A saturation of each measured state and each input, its knee at the variable's RMS."""
    n_declared = n_declared_states(physics)
    measured = [i for i in measured_states(physics.output) or () if i < n_declared]
    columns = sorted(set(measured)) + list(range(n_declared, values.shape[1]))
    groups = []
    for j in columns:
        scale = float(np.sqrt(np.mean(values[:, j] ** 2)))
        if scale > 0 and np.isfinite(scale):
            function, name = saturation(scale)
            groups.append(KindGroup((function,), (name,), ("a saturation",), [j]))
    return groups


def column_meanings(groups: Sequence[KindGroup]) -> list[str]:
    """What each column of the groups' libraries is a sign of, in `with_kind_terms`' column
    order (a ``CustomLibrary`` lists its functions' columns one function after the other)."""
    return [meaning for group in groups for meaning in group.meanings for _ in group.columns]


def with_kind_terms(library, physics, groups: Sequence[KindGroup]):
    """The evidence dictionary: ``library`` with the functions of ``groups`` (`kind_groups`
    of ``physics``' variables) appended after its own columns; ``None`` where ``library``
    is no pysindy library or there are no groups."""
    import pysindy as ps

    if not isinstance(library, ps.feature_library.base.BaseFeatureLibrary) or not groups:
        return None
    n_variables = n_declared_states(physics) + physics.n_inputs
    libraries = [library] + [
        ps.CustomLibrary(list(group.functions), list(group.names)) for group in groups
    ]
    inputs = [list(range(n_variables))] + [group.columns for group in groups]
    return ps.GeneralizedLibrary(libraries, inputs_per_library=inputs)
