r"""Named physical effects that can be added to a :class:`PhysicsModel`.

An effect is the explicit, parametrised form of something a residual analysis can point
at: an overflow (a level capped at a height, the excess spilling elsewhere), a saturation of
the measured output, a leak, a friction. :func:`augment` returns a new physics model whose
step and output apply the effects after the declared physics,

.. math::

    x_{k+1} = E_m \circ \dots \circ E_1\bigl(f(x_k, u_k; \theta);\ x_k, u_k, \theta_E\bigr),
    \qquad z_k = O_m \circ \dots \circ O_1\bigl(h(x_k, u_k; \theta)\bigr),

with the effects' own named parameters :math:`\theta_E` appended to :math:`\theta`. Hard
limits are smoothed, :math:`\mathrm{hinge}_\beta(a) = \mathrm{softplus}(\beta a)/\beta`, so
the simulation error stays differentiable. Effects are immutable and compared by value, so
augmented models are valid ``jit`` static arguments and picklable.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ._physics import Parameter, PhysicsModel

__all__ = [
    "Effect",
    "Friction",
    "InputSaturation",
    "Leak",
    "OutputOffset",
    "OutputSaturation",
    "Overflow",
    "augment",
    "hinge",
]


def hinge(a, sharpness: float):
    r"""Smooth :math:`\max(a, 0)`: :math:`\mathrm{softplus}(\beta a)/\beta`."""
    return jax.nn.softplus(sharpness * a) / sharpness


class Effect:
    """Base class: an effect acting on the state update and/or the output map.

    Subclasses set ``name`` and ``target`` (``"input"``, ``"state"`` or ``"output"``) and
    implement :meth:`parameters` and one of :meth:`apply_input` (before the declared step),
    :meth:`apply_state` (after it) or :meth:`apply_output`.
    """

    target = "state"

    def parameters(self) -> dict[str, Parameter]:
        """The effect's own parameters, with initial values and bounds."""
        raise NotImplementedError

    def apply_input(self, x, u, theta):
        """Return the input the declared step sees (identity by default)."""
        return u

    def apply_state(self, x, u, x_next, theta):
        """Return the state update after the effect (identity by default)."""
        return x_next

    def apply_output(self, x, u, z, theta):
        """Return the output after the effect (identity by default)."""
        return z

    def describe(self, state_names, output_names) -> str:
        """One line in words, naming the variables."""
        raise NotImplementedError

    def _key(self):
        return (type(self), tuple(sorted(vars(self).items())))

    def __eq__(self, other) -> bool:
        return isinstance(other, Effect) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in vars(self).items())
        return f"{type(self).__name__}({args})"


class Overflow(Effect):
    r"""State ``state`` cannot exceed a level; a fraction of the excess reaches ``sink``.

    .. math::

        o = \mathrm{hinge}_\beta(x^+_s - h), \quad x^+_s \leftarrow x^+_s - o, \quad
        x^+_{d} \leftarrow x^+_{d} + \rho\, o,

    with parameters ``{name}_level`` (:math:`h`) and, with a sink, ``{name}_fraction``
    (:math:`\rho \in [0, 1]`; the rest leaves the system).
    """

    def __init__(
        self,
        state: int,
        level: float,
        sink: int | None = None,
        *,
        fraction: float = 0.5,
        sharpness: float = 20.0,
        name: str = "overflow",
    ):
        self.state, self.level, self.sink = int(state), float(level), sink
        self.fraction, self.sharpness, self.name = float(fraction), float(sharpness), name

    def parameters(self) -> dict[str, Parameter]:
        params = {f"{self.name}_level": Parameter(self.level)}
        if self.sink is not None:
            params[f"{self.name}_fraction"] = Parameter(self.fraction, (0.0, 1.0))
        return params

    def apply_state(self, x, u, x_next, theta):
        excess = hinge(x_next[self.state] - theta[f"{self.name}_level"], self.sharpness)
        x_next = x_next.at[self.state].add(-excess)
        if self.sink is None:
            return x_next
        return x_next.at[self.sink].add(theta[f"{self.name}_fraction"] * excess)

    def describe(self, state_names, output_names) -> str:
        where = (
            ""
            if self.sink is None
            else f", part of the excess flowing into {state_names[self.sink]}"
        )
        return f"{state_names[self.state]} overflows above a level{where}"


class OutputSaturation(Effect):
    r"""Output ``output`` saturates at an upper level.

    :math:`z \leftarrow z - \mathrm{hinge}_\beta(z - z_{max})`;
    parameter ``{name}_level`` (:math:`z_{max}`).
    """

    target = "output"

    def __init__(
        self, output: int, level: float, *, sharpness: float = 20.0, name: str = "saturation"
    ):
        self.output, self.level, self.sharpness, self.name = (
            int(output),
            float(level),
            float(sharpness),
            name,
        )

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_level": Parameter(self.level)}

    def apply_output(self, x, u, z, theta):
        excess = hinge(z[self.output] - theta[f"{self.name}_level"], self.sharpness)
        return z.at[self.output].add(-excess)

    def describe(self, state_names, output_names) -> str:
        return f"the measured {output_names[self.output]} saturates at an upper level"


class InputSaturation(Effect):
    r"""Input ``input`` reaches the physics through a saturating actuator.

    :math:`u_j \leftarrow u_{max} \tanh(u_j / u_{max})` before the declared step (linear
    for :math:`|u_j| \ll u_{max}`, bounded by :math:`u_{max}`); parameter
    ``{name}_level`` (:math:`u_{max} > 0`).
    """

    target = "input"

    def __init__(self, input: int, level: float, *, name: str = "actuator"):
        self.input, self.level, self.name = int(input), float(level), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_level": Parameter(self.level, (1e-6, None))}

    def apply_input(self, x, u, theta):
        level = theta[f"{self.name}_level"]
        return u.at[self.input].set(level * jnp.tanh(u[self.input] / level))

    def describe(self, state_names, output_names) -> str:
        return "the actuator saturates: the input acts as u_max tanh(u / u_max)"


class OutputOffset(Effect):
    r"""The measured output reads the model output plus a constant: :math:`z \leftarrow z + b`.

    An uncalibrated sensor whose zero is not the physical zero of the state it measures;
    the dynamics then act on the physical level :math:`z - b`. Parameter ``{name}_offset``
    (:math:`b`).
    """

    target = "output"

    def __init__(self, output: int, *, offset: float = 0.0, name: str = "sensor"):
        self.output, self.offset, self.name = int(output), float(offset), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_offset": Parameter(self.offset)}

    def apply_output(self, x, u, z, theta):
        return z.at[self.output].add(theta[f"{self.name}_offset"])

    def describe(self, state_names, output_names) -> str:
        return f"the sensor of {output_names[self.output]} reads with a constant offset"


class Leak(Effect):
    r"""A loss proportional to the state: :math:`x^+_s \leftarrow x^+_s - c\, x_s`.

    Parameter ``{name}_rate`` (:math:`c \ge 0`).
    """

    def __init__(self, state: int, *, rate: float = 0.01, name: str = "leak"):
        self.state, self.rate, self.name = int(state), float(rate), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_rate": Parameter(self.rate, (0.0, None))}

    def apply_state(self, x, u, x_next, theta):
        return x_next.at[self.state].add(-theta[f"{self.name}_rate"] * x[self.state])

    def describe(self, state_names, output_names) -> str:
        return f"{state_names[self.state]} leaks in proportion to its value"


class Friction(Effect):
    r"""Coulomb friction on a velocity state: :math:`x^+_v \leftarrow x^+_v - F \tanh(\beta x_v)`.

    Parameter ``{name}_force`` (:math:`F \ge 0`, in state units per sample).
    """

    def __init__(
        self, state: int, *, force: float = 0.01, sharpness: float = 20.0, name: str = "friction"
    ):
        self.state, self.force, self.sharpness, self.name = (
            int(state),
            float(force),
            float(sharpness),
            name,
        )

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_force": Parameter(self.force, (0.0, None))}

    def apply_state(self, x, u, x_next, theta):
        force = theta[f"{self.name}_force"] * jnp.tanh(self.sharpness * x[self.state])
        return x_next.at[self.state].add(-force)

    def describe(self, state_names, output_names) -> str:
        return f"{state_names[self.state]} is braked by a constant (Coulomb) friction"


class AugmentedStep:
    """``step`` of an augmented model: input effects, the base step, then state effects."""

    def __init__(self, base, effects: tuple[Effect, ...]):
        self.base, self.effects = base, effects

    def __call__(self, x, u, theta):
        u_seen = u
        for effect in self.effects:
            u_seen = effect.apply_input(x, u_seen, theta)
        x_next = jnp.asarray(self.base(x, u_seen, theta), dtype=x.dtype).reshape(x.shape)
        for effect in self.effects:
            x_next = effect.apply_state(x, u, x_next, theta)
        return x_next

    def __eq__(self, other) -> bool:
        return isinstance(other, AugmentedStep) and (self.base, self.effects) == (
            other.base,
            other.effects,
        )

    def __hash__(self) -> int:
        return hash((AugmentedStep, self.base, self.effects))


class AugmentedOutput(AugmentedStep):
    """``output`` of an augmented model: the base map, then each output effect in turn."""

    def __call__(self, x, u, theta):
        z = jnp.atleast_1d(self.base(x, u, theta))
        for effect in self.effects:
            z = effect.apply_output(x, u, z, theta)
        return z


def _merged_parameters(physics: PhysicsModel, effects) -> dict[str, Parameter]:
    parameters = dict(physics.parameters)
    for effect in effects:
        for name, spec in effect.parameters().items():
            if name in parameters:
                raise ValueError(
                    f"effect parameter {name!r} clashes with an existing parameter; "
                    "give the effect another name=."
                )
            parameters[name] = spec
    return parameters


def augment(physics: PhysicsModel, *effects: Effect) -> PhysicsModel:
    """A copy of ``physics`` with ``effects`` added to its step and output map.

    Parameters
    ----------
    physics : PhysicsModel
        The declared model; it is not modified.
    *effects : Effect
        Effects applied in order after the declared step (state effects) and output map
        (output effects). Their parameters are appended to the model's, by name.

    Returns
    -------
    PhysicsModel
        Same states, inputs, names, initial-state settings and constraints.
    """
    for effect in effects:
        if not isinstance(effect, Effect):
            raise TypeError(f"effects must be Effect instances, got {effect!r}.")
    states = tuple(e for e in effects if e.target in ("input", "state"))
    outputs = tuple(e for e in effects if e.target == "output")
    model = PhysicsModel.__new__(PhysicsModel)
    model.__dict__.update(physics.__dict__)
    model.step = AugmentedStep(physics.step, states) if states else physics.step
    model.output = AugmentedOutput(physics.output, outputs) if outputs else physics.output
    model.parameters = _merged_parameters(physics, effects)
    model.effects = tuple(getattr(physics, "effects", ())) + tuple(effects)
    return model
