r"""The bases of the effects and the smooth corners they share.

Hard limits are smoothed, $\mathrm{hinge}_\beta(a) = \mathrm{softplus}(\beta a)/\beta$, so
that the simulation error stays differentiable; every positive level or width is bounded
below by a fraction of its start (`RELATIVE_FLOOR`), a floor in the parameter's own scale.
"""

from __future__ import annotations

import jax
import numpy as np

from ..model._physics import Parameter


def hinge(a, sharpness: float):
    r"""Smooth $\max(a, 0)$: $\mathrm{softplus}(\beta a)/\beta$."""
    return jax.nn.softplus(sharpness * a) / sharpness


SHARPNESS = 1000.0
r"""Default sharpness $s$ of the rounded corners of the hard input limit, the dead
zones and the play, relative to the effect's own level or width (so unit-free): a corner
moves the effect's edge by $\ln 2 / s$ of that width, 0.07 % at 1000."""


RELATIVE_FLOOR = 1e-6
"""A positive level or width stays above this fraction of its start: a floor in the
parameter's own scale, so that a fit in other units meets the same floor."""


def _positive(value: float) -> Parameter:
    """A positive parameter started at ``value``, bounded below by ``RELATIVE_FLOOR`` of it."""
    return Parameter(value, (RELATIVE_FLOOR * abs(value), None))


def _beyond(ratio, sharpness: float, one_sided: bool = False):
    r"""How far ``ratio`` lies beyond $\pm 1$, smoothed and times ``sharpness``:
    $\mathrm{sp}(s(r - 1)) - \mathrm{sp}(s(-r - 1))$, or its first term alone when
    ``one_sided`` (divided by $s$, a smooth $\mathrm{sign}(r)\max(|r| - 1, 0)$,
    resp. $\max(r - 1, 0)$): the dead zones and the hard input limit."""
    passed = jax.nn.softplus(sharpness * (ratio - 1.0))
    if one_sided:
        return passed
    return passed - jax.nn.softplus(sharpness * (-ratio - 1.0))


def _hinge_corner(effect, theta):
    """The corner of ``effect``'s hinge: its fitted parameter ``{name}_corner`` with
    ``fit_corner``, else the fixed ``corner``."""
    return theta[f"{effect.name}_corner"] if effect.fit_corner else effect.corner


def _corner_parameters(effect) -> dict[str, Parameter]:
    """``{name}_corner`` when ``effect`` fits its corner, else nothing."""
    return {f"{effect.name}_corner": _positive(effect.corner)} if effect.fit_corner else {}


def _widened_range(u, index: int) -> tuple[float, float]:
    r"""Column ``index`` of the record ``u``'s range widened by itself on each side,
    $[\min u - R,\ \max u + R]$, $R = \max u - \min u$ (unbounded for a
    constant column): the bounds of a hidden state that follows an input."""
    command = np.asarray(u, float)[:, index]
    low, high = float(command.min()), float(command.max())
    if not high > low:
        return (-np.inf, np.inf)
    return (2 * low - high, 2 * high - low)


def checked_positive(value, name: str) -> float:
    """``value`` as a float, or a ``ValueError`` naming ``name`` unless it is positive and
    finite."""
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
    return value


def _checked_corner(corner) -> float:
    return checked_positive(corner, "corner")


class Effect:
    """Base class of every effect: named, parametrised, immutable and compared by value.

    An effect derives from the base of what it acts on:
    [`InputEffect`][sk_offwhite.effects.InputEffect] (the input the declared step sees),
    [`StateEffect`][sk_offwhite.effects.StateEffect] (the state update after it;
    [`AdditiveEffect`][sk_offwhite.AdditiveEffect] adds a term to one equation),
    [`OutputEffect`][sk_offwhite.effects.OutputEffect] (the output map) or
    [`LawEffect`][sk_offwhite.effects.LawEffect] (the declared parameters); an effect with memory of
    its own also derives from `HiddenStates`. It sets ``name`` and implements `parameters`,
    `describe` and its base's ``apply_*`` method; the others leave their argument as it is, so that
    [`augment`][sk_offwhite.augment] can chain every effect the same way. Its attributes are its
    constructor's arguments: equal effects give equal, hashable models (valid ``jit`` static
    arguments) and pickle.
    """

    target = ""
    """What the effect acts on: ``"input"``, ``"state"``, ``"output"``, ``"law"``,
    ``"parameter"``, ``"hidden"`` or ``"hold"`` (set by the bases)."""
    hidden_states: tuple[str, ...] = ()
    """Names of the hidden states the effect carries: none unless it has memory."""

    def parameters(self) -> dict[str, Parameter]:
        """The effect's own parameters, with initial values and bounds."""
        raise NotImplementedError

    def describe(self, state_names, output_names, values=None) -> str:
        """One line in words, naming the variables (``values``: fitted parameters, used
        where they change the wording)."""
        raise NotImplementedError

    def apply_input(self, x, u, theta):
        """The input the declared step sees (unchanged unless the effect acts on it)."""
        return u

    def apply_state(self, x, u, x_next, theta):
        """The state update after the effect (unchanged unless the effect acts on it)."""
        return x_next

    def apply_output(self, x, u, z, theta):
        """The output after the effect (unchanged unless the effect acts on it)."""
        return z

    def apply_parameters(self, x, u, theta):
        """The parameters the declared step sees at ``(x, u)`` (unchanged unless the effect
        makes a declared constant vary)."""
        return theta

    def _key(self):
        return (type(self), tuple(sorted(vars(self).items())))

    def __eq__(self, other) -> bool:
        return isinstance(other, Effect) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def replace(self, **changes) -> Effect:
        """A copy with some constructor arguments changed (an effect's attributes are its
        constructor's arguments)."""
        return type(self)(**{**vars(self), **changes})

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in vars(self).items())
        return f"{type(self).__name__}({args})"


class InputEffect(Effect):
    """An effect on the input the declared step sees: implement `apply_input` (an actuator's
    saturation or dead zone). For a physics built with
    [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] it acts inside the integrated
    right-hand side."""

    target = "input"


class StateEffect(Effect):
    """An effect on the state update after the declared step: implement `apply_state` (an
    overflow that caps a level)."""

    target = "state"


class OutputEffect(Effect):
    """An effect on the output map: implement `apply_output` (a sensor's offset, curve or
    saturation)."""

    target = "output"
    reads_output = False
    """Whether the effect acts on the final reading, after every other output effect
    whatever the order the effects are given in ([`SensorStep`][sk_offwhite.SensorStep])."""


class LawEffect(Effect):
    """An effect on the declared law itself: its parameters replace declared ones of the same
    name ([`RelaxedLaw`][sk_offwhite.RelaxedLaw] frees a constant the user marked relaxable)."""

    target = "law"


class AdditiveEffect(StateEffect):
    r"""A term $g(x, u; \theta_E)$ added to the equation of state ``state``.

    ``basis`` (when the term is $p\,b(x, u)$, linear in its first parameter ``p``,
    the others held) lets the loop start ``p`` from a least-squares fit to a correction.

    For a physics built with [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] the term
    is added to the right-hand side, $\dot x_s = r_s(x, u) + g$, and integrated with it, so its
    parameters are rates in the state's units per unit time (per second when the sampling
    time is in seconds); for a discrete-time physics it is added to $x^+_s$ (an
    increment per sample). Subclasses implement `term`.
    """

    state: int

    def term(self, x, u, theta):
        """The added term (a scalar)."""
        raise NotImplementedError

    def basis(self, x, u):
        r"""$b(x, u)$ of a term $p\,b(x, u)$ (numpy rows), else ``None``."""
        return None

    def apply_state(self, x, u, x_next, theta):
        return x_next.at[self.state].add(self.term(x, u, theta))
