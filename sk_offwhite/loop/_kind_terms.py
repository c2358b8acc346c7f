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
| measured state, input | $x / (s + \lvert x\rvert)$ | a saturation, a hardening |

$T_{\min}$ is the lowest temperature the declared physics simulates on the record and
$s$ the variable's RMS there, so each function is unit-free: rescaling a variable's unit
(or shifting a temperature's, from kelvin to degrees Celsius) rescales its column, which
the gains do not see. The note names those that explain more than the dictionary's best
term, each with what its fitted sign says (`column_meaning`): a friction then shows up
as a friction rather than as the sign-blind $v^2$ of a polynomial dictionary, or as a
source where its sign is no friction's; a saturation as a saturation rather than as a
cubic, or, with the other sign, as an effect that grows faster than linearly (a
hardening spring, a dead zone). The functions inform the reader only: the hypotheses,
the candidates and the promoted terms stay the dictionary's, whose choices the
functions' columns would otherwise shift.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..dictionaries._compiled import _xp
from ..effects._hidden import n_declared_states
from ..model._kinds import LEVEL_KINDS, VELOCITY_KINDS, physical_kinds
from ..model._physics import measured_states, reads_next_input

__all__ = ["with_kind_terms"]

TEMPERATURE_POWERS = (1.25, 2.0)
"""Powers of a temperature's excess: natural convection's 5/4 and radiation's first
correction (the square term of $T^4 - T_a^4$ about the ambient)."""


FIXED, DISSIPATIVE, SATURATING = "fixed", "dissipative", "saturating"
"""How a kind function's fitted sign is read (`column_meaning`): not at all; as a loss of
its own state (a negative weight in its own equation); as a saturation."""


class KindGroup(NamedTuple):
    """Functions of one pysindy ``CustomLibrary``: each with its name function and what it
    is a sign of, on the variables ``columns`` of ``v = [x; u]``; ``reading``: how the
    fitted sign is read (`FIXED`, `DISSIPATIVE`, `SATURATING`)."""

    functions: tuple[Callable, ...]
    names: tuple[Callable, ...]
    meanings: tuple[str, ...]
    columns: list[int]
    reading: str = FIXED


class KindColumn(NamedTuple):
    """One column of the kinds' functions: what it is a sign of, its variable (in
    ``v = [x; u]``) and how its fitted sign is read."""

    meaning: str
    variable: int
    reading: str


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
            ("a Coulomb friction", "a drag"), velocities, DISSIPATIVE,
        ),
        KindGroup(
            (root_of,), (root_name,), ("an outflow through an orifice",), levels, DISSIPATIVE
        ),
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
            groups.append(KindGroup(functions, names, meanings, [i], DISSIPATIVE))
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
            groups.append(KindGroup((function,), (name,), ("a saturation",), [j], SATURATING))
    return groups


def kind_columns(groups: Sequence[KindGroup]) -> list[KindColumn]:
    """The `KindColumn` of each column of the groups' libraries, in `with_kind_terms`'
    column order (a ``CustomLibrary`` lists its functions' columns one function after the
    other)."""
    return [
        KindColumn(meaning, variable, group.reading)
        for group in groups
        for meaning in group.meanings
        for variable in group.columns
    ]


def column_meaning(column: KindColumn, equation: int, weight: float, slopes) -> str:
    """What ``column``, of fitted (linearised) ``weight`` in the equation of state
    ``equation`` whose declared slopes (`declared_slopes`) are ``slopes``, is a sign of."""
    if column.reading == SATURATING:
        return saturation_meaning(weight, float(slopes[column.variable]))
    if column.reading == DISSIPATIVE and column.variable == equation and weight > 0:
        return f"of the sign of a source, not of {column.meaning}"
    return column.meaning


def saturation_meaning(weight: float, slope: float) -> str:
    r"""What a saturation column $x/(s + |x|)$ of fitted (linearised) ``weight`` says of
    the equation whose declared increment changes by ``slope`` per unit of $x$.

    Beyond its linear part the column is $\approx -x|x|/s^2$, against $x$: with a weight of
    the declared slope's sign it takes from the declared effect of $x$ (the effect levels
    off: a saturation), with the other sign it adds to it (the effect grows faster than
    linearly: a hardening). Where the declared equation does not depend on $x$ the column
    is a law of $x$ that levels off."""
    if slope == 0 or not np.isfinite(slope):
        return "a law that levels off"
    return "a saturation" if weight * slope > 0 else "an effect that grows faster than linearly"


def declared_slopes(physics, states: np.ndarray, u: np.ndarray) -> np.ndarray:
    r"""$\partial (x^+_i - x_i) / \partial v_j$ of the declared step at its parameters'
    values, averaged over the run (``states``, ``u``): the declared effect of each
    variable $v = [x; u]$ on each state's increment, shape ``(n_declared, n_declared +
    n_inputs)``."""
    n, held = physics.n_states, 2 if reads_next_input(physics) else 1
    theta = dict(zip(physics.parameter_names, physics.parameter_values(), strict=True))
    with jax.enable_x64(True):

        def increment(v):  # a first-order hold reads the input of the next sample too
            return physics.step(v[:n], jnp.tile(v[n:], held), theta)[:n] - v[:n]

        values = jnp.column_stack([jnp.asarray(states)[:, :n], jnp.asarray(u, float)])
        slopes = np.asarray(jax.vmap(jax.jacfwd(increment))(values))
    n_declared = n_declared_states(physics)
    columns = list(range(n_declared)) + list(range(n, n + physics.n_inputs))
    return np.mean(slopes, axis=0)[:n_declared][:, columns]


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
