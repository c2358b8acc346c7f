r"""Adding effects to a declared physics.

[`augment`][sk_offwhite.augment] returns a new physics model whose step and output apply the
effects after the declared physics,

$$
x_{k+1} = E_m \circ \dots \circ E_1\bigl(f(x_k, u_k; \theta);\ x_k, u_k, \theta_E\bigr),
\qquad z_k = O_m \circ \dots \circ O_1\bigl(h(x_k, u_k; \theta)\bigr),
$$

with the effects' own named parameters $\theta_E$ appended to $\theta$. For a physics built
with [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode], input effects and additive
terms act inside the integrated right-hand side instead.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..model._physics import DiscretizedStep, Parameter, PhysicsModel
from ._base import AdditiveEffect, Effect, LawEffect
from ._hidden import SensorReading, sensor_readings, with_hidden_states
from ._hold import InputHold

__all__ = ["augment", "continuous_time", "time_step"]


class _EffectChain:
    """A base map and the effects applied around it; compared by value (a ``jit`` static
    argument), picklable."""

    def __init__(self, base, effects: tuple[Effect, ...]):
        self.base, self.effects = base, effects

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and (self.base, self.effects) == (
            other.base,
            other.effects,
        )

    def __hash__(self) -> int:
        return hash((type(self), self.base, self.effects))


class AugmentedStep(_EffectChain):
    """``step`` of an augmented model: input effects, the base step, then state effects."""

    def __call__(self, x, u, theta):
        u_seen, theta_seen = u, theta
        for effect in self.effects:
            u_seen = effect.apply_input(x, u_seen, theta)
            theta_seen = effect.apply_parameters(x, u, theta_seen)
        x_next = jnp.asarray(self.base(x, u_seen, theta_seen), dtype=x.dtype).reshape(x.shape)
        for effect in self.effects:
            x_next = effect.apply_state(x, u, x_next, theta)
        return x_next


class AugmentedOutput(_EffectChain):
    """``output`` of an augmented model: the base map, then each output effect in turn."""

    def __call__(self, x, u, theta):
        z = jnp.atleast_1d(self.base(x, u, theta))
        for effect in self.effects:
            z = effect.apply_output(x, u, z, theta)
        return z


class AugmentedRhs(_EffectChain):
    """Right-hand side of an augmented continuous-time model: input effects, the declared
    right-hand side, then the additive terms."""

    def __init__(self, base, effects: tuple[Effect, ...]):
        super().__init__(base, effects)
        self.__name__ = getattr(base, "__name__", "rhs")  # names the discretised step

    def __call__(self, x, u, theta):
        u_seen, theta_seen = u, theta
        for effect in self.effects:
            u_seen = effect.apply_input(x, u_seen, theta)
            theta_seen = effect.apply_parameters(x, u, theta_seen)
        rate = jnp.asarray(self.base(x, u_seen, theta_seen), dtype=x.dtype).reshape(x.shape)
        for effect in self.effects:
            if isinstance(effect, AdditiveEffect):
                rate = rate.at[effect.state].add(effect.term(x, u, theta))
        return rate


def time_step(physics: PhysicsModel) -> float:
    """The unit of time of the effects' rates: the sampling time of a physics built with
    [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode], else 1 (one sample)."""
    return float(physics.sampling_time) if continuous_time(physics) else 1.0


def continuous_time(physics: PhysicsModel) -> bool:
    """Whether ``physics`` integrates a right-hand side (built with `PhysicsModel.from_ode`)."""
    declared = getattr(physics, "declared", (physics.step,))[0]
    return isinstance(declared, DiscretizedStep)


def _in_rhs(effect: Effect) -> bool:
    return isinstance(effect, AdditiveEffect) or effect.target in ("input", "parameter")


def _step(declared_step, effects: tuple[Effect, ...]):
    """The augmented step: additive and input effects inside the integrated right-hand
    side of a continuous-time model, the others after the step."""
    after = effects
    if isinstance(declared_step, DiscretizedStep):
        inside = tuple(e for e in effects if _in_rhs(e))
        after = tuple(e for e in effects if not _in_rhs(e))
        if inside:
            declared_step = declared_step.with_rhs(AugmentedRhs(declared_step.rhs, inside))
    return AugmentedStep(declared_step, after) if after else declared_step


def _held(physics: PhysicsModel, declared_step, effects):
    """The declared step under a first-order hold when ``effects`` hold an
    [`InputHold`][sk_offwhite.InputHold] (only a physics built with
    [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] has one)."""
    if not any(isinstance(effect, InputHold) for effect in effects):
        return declared_step
    if not isinstance(declared_step, DiscretizedStep):
        raise ValueError(
            "InputHold interpolates the input between samples of a continuous-time physics: "
            "build the physics with PhysicsModel.from_ode (its step here is discrete-time)."
        )
    return declared_step.with_hold("linear")


def _merged_parameters(physics: PhysicsModel, effects) -> dict[str, Parameter]:
    parameters = dict(physics.parameters)
    for effect in effects:
        for name, spec in effect.parameters().items():
            relaxing = isinstance(effect, LawEffect) and getattr(
                parameters.get(name), "relaxable", 0
            )
            if name in parameters and not relaxing:
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
        (output effects; those that act on the final reading,
        `Effect.reads_output`, after the others); for a physics
        built with [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode], input effects and
        [`AdditiveEffect`][sk_offwhite.AdditiveEffect] terms act inside the integrated right-hand
        side instead. Effects with memory ([`Backlash`][sk_offwhite.Backlash]) act first, on the
        input, through hidden states of their own. Their parameters are appended to the model's, by
        name. Augmenting an augmented model adds to its effects.

    Returns
    -------
    PhysicsModel
        Same states, inputs, names, initial-state settings and constraints; the hidden
        states of the effects that have some are appended to the states (with free initial
        values, see `sk_offwhite.effects._hidden`), and ``n_declared_states`` counts the
        declared ones.
    """
    for effect in effects:
        if not isinstance(effect, Effect):
            raise TypeError(f"effects must be Effect instances, got {effect!r}.")
    declared = getattr(physics, "declared", (physics.step, physics.output))
    everything = tuple(getattr(physics, "effects", ())) + tuple(effects)
    states = tuple(e for e in everything if e.target in ("input", "state", "parameter"))
    outputs = tuple(e for e in everything if e.target == "output" and not e.reads_output)
    outputs += tuple(e for e in everything if e.target == "output" and e.reads_output)
    model = PhysicsModel.__new__(PhysicsModel)
    model.__dict__.update(physics.__dict__)
    model.declared = declared
    declared_step = _held(physics, declared[0], everything)
    model.input_hold = getattr(declared_step, "hold", "zero")
    model.step = _step(declared_step, states) if states else declared_step
    model.output = AugmentedOutput(declared[1], outputs) if outputs else declared[1]
    model.parameters = _merged_parameters(physics, effects)
    model.effects = everything
    hidden = tuple(e for e in everything if e.hidden_states)
    if hidden:
        with_hidden_states(model, physics, hidden, tuple(e for e in effects if e.hidden_states))
    readings = sensor_readings(model.step)
    if readings:
        base = SensorReading(declared[1], model.n_declared_states, readings)
        model.output = AugmentedOutput(base, outputs) if outputs else base
    return model
