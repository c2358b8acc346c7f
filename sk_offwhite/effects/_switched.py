r"""Effects behind switches: models that differ only in which effects act share one program."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..model._physics import Parameter
from ._base import AdditiveEffect, Effect

__all__ = ["Switched", "SwitchedTerm", "switched", "switches"]


class Switched(Effect):
    r"""``effect`` behind a switch: a fixed parameter ``{name}_on`` ($s$) says
    whether it acts,

    $$
    u \leftarrow E(u) \text{ if } s > \tfrac12 \text{ else } u
    $$

    (and likewise for the state update and the output), so $s = 1$ is the effect,
    exactly as [`augment`][sk_offwhite.augment] adds it, and $s = 0$ the model without it. The
    switch is a parameter value, not structure: models that differ only in which effects are on
    share one compiled program (``LoopSettings(share_programs=True)`` fits the loop's
    candidate sets this way, see `sk_offwhite.loop._switchboard`). An effect that is off is not
    computed (a ``lax.cond`` on the switch) and has zero derivatives; a fit leaves its
    parameters where they start. The memory of an effect whose hidden states follow the
    inputs alone (``hidden_free`` false: a dead time's past commands) follows them on or
    off, so a shooting window starts it where the inputs put it either way.
    """

    def __init__(self, effect: Effect):
        if not isinstance(effect, Effect) or isinstance(effect, Switched):
            raise TypeError(f"Switched takes an Effect that is not switched, got {effect!r}.")
        self.effect, self.name, self.target = effect, effect.name, effect.target

    @property
    def reads_output(self) -> bool:
        return getattr(self.effect, "reads_output", False)

    @property
    def switch(self) -> str:
        """Name of the switch parameter."""
        return f"{self.name}_on"

    def parameters(self) -> dict[str, Parameter]:
        return {**self.effect.parameters(), self.switch: _switch_value(True)}

    def on(self, theta):
        """Whether the effect acts (a traced boolean)."""
        return theta[self.switch] > 0.5

    def apply_input(self, x, u, theta):
        return _if_on(self.on(theta), lambda: self.effect.apply_input(x, u, theta), u)

    def apply_state(self, x, u, x_next, theta):
        return _if_on(self.on(theta), lambda: self.effect.apply_state(x, u, x_next, theta), x_next)

    def apply_output(self, x, u, z, theta):
        return _if_on(self.on(theta), lambda: self.effect.apply_output(x, u, z, theta), z)

    def apply_parameters(self, x, u, theta):
        on = self.on(theta)
        return _if_on(on, lambda: self.effect.apply_parameters(x, u, theta), theta)

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return self.effect.hidden_states

    def hidden_initial(self) -> tuple[float, ...]:
        return self.effect.hidden_initial()

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return self.effect.hidden_kinds(input_kinds)

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        return self.effect.hidden_start(hidden, u, theta)

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        return self.effect.hidden_bounds(u)

    @property
    def hidden_free(self) -> bool:
        return getattr(self.effect, "hidden_free", True)

    def hidden_path(self, u, theta) -> np.ndarray:
        return self.effect.hidden_path(u, theta)

    def advance(self, hidden, u, theta):
        if self.hidden_free:
            return _if_on(
                self.on(theta), lambda: self.effect.advance(hidden, u, theta), (u, hidden)
            )
        seen, memory = self.effect.advance(hidden, u, theta)  # the inputs' memory, on or off
        return _if_on(self.on(theta), lambda: seen, u), memory

    @property
    def follows_output(self) -> bool:
        return getattr(self.effect, "follows_output", False)

    @property
    def output(self) -> int:
        """The output the effect acts on or reads (when it has one)."""
        return self.effect.output

    def follow(self, hidden, now, after, theta):
        off = self.effect.follow_off(hidden, now, after)
        return _if_on(self.on(theta), lambda: self.effect.follow(hidden, now, after, theta), off)

    def describe(self, state_names, output_names, values=None) -> str:
        return self.effect.describe(state_names, output_names, values)


class SwitchedTerm(Switched, AdditiveEffect):
    """[`Switched`][sk_offwhite.Switched] for an [`AdditiveEffect`][sk_offwhite.AdditiveEffect]: the
    term, or zero when off (inside the integrated right-hand side of a continuous-time model, like
    the term itself)."""

    def __init__(self, effect: AdditiveEffect):
        super().__init__(effect)
        self.state = effect.state

    def term(self, x, u, theta):
        return _if_on(self.on(theta), lambda: self.effect.term(x, u, theta), jnp.zeros_like(x[0]))

    def basis(self, x, u):
        return self.effect.basis(x, u)


def _if_on(on, changed, unchanged):
    """``changed()`` where the switch ``on`` is set, else ``unchanged`` (arrays or a tuple
    of them, ``changed()`` cast to their types); a switched-off effect is not computed."""
    unchanged = jax.tree.map(jnp.asarray, unchanged)

    def computed():
        return jax.tree.map(lambda new, old: jnp.asarray(new, old.dtype), changed(), unchanged)

    return jax.lax.cond(on, computed, lambda: unchanged)


def switched(effect: Effect) -> Switched:
    """``effect`` behind a switch (`SwitchedTerm` for an additive term)."""
    return SwitchedTerm(effect) if isinstance(effect, AdditiveEffect) else Switched(effect)


def switches(effects, on) -> dict[str, Parameter]:
    """Switch parameters of the switched ``effects``: ``1`` for those in ``on``, else ``0``
    (to pass to [`PhysicsModel.with_parameters`][sk_offwhite.PhysicsModel.with_parameters])."""
    names = {e.name for e in on}
    return {e.switch: _switch_value(e.name in names) for e in effects}


def _switch_value(on: bool) -> Parameter:
    return Parameter(float(on), (0.0, 1.0), fixed=True)
