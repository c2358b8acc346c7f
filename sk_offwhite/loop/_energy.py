r"""The physical sign of a term added to a velocity's equation: where does its energy go?

A term $g(x, u)$ added to the equation of a velocity $v$ does the specific power $v\,g$
on the motion. Over the simulated record its *net power share*

$$
s = \frac{\sum_k v_k\, g_k}{\sum_k \lvert v_k\, g_k \rvert} \in [-1, 1]
$$

says what it is physically: $s \le -$ `CONSERVATIVE_SHARE` a **dissipative** term (a
friction, a drag: it takes energy out of the motion), $s \ge$ `CONSERVATIVE_SHARE` an
**energy-adding** one (it drives the motion; in a passive mechanism only an input can), and
in between a **conservative** one (a spring: it stores the energy it takes and returns it).
The share is unit-free: rescaling $v$, $g$ or time leaves it unchanged.

A [`DirectionalDamping`][sk_offwhite.DirectionalDamping] $-c\,\lvert v\rvert$ does no net
work on a motion that goes both ways; what makes it physical is that it leaves both
directions damped: with the declared physics' damping $b = -\partial f_v / \partial v$ (its
mean over the states, for a physics declared by its right-hand side), the damping is
$b + c$ moving forward and $b - c$ moving back (`directional_dampings`), and a set in which
one of them is negative makes that direction an energy source: a stand-in
(`sk_offwhite.loop._plausibility.direction_reasons`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..effects import AdditiveEffect, DirectionalDamping
from ..model._kinds import VELOCITY_KINDS

__all__ = [
    "CONSERVATIVE_SHARE",
    "declared_damping",
    "directional_dampings",
    "net_power_share",
    "power_sentence",
]

CONSERVATIVE_SHARE = 0.1
"""Net power share (in absolute value) under which a term counts as conservative."""


def net_power_share(velocity: np.ndarray, term: np.ndarray) -> float:
    r"""$\sum v g / \sum \lvert v g\rvert$ (``nan`` where the term does no work)."""
    power = np.asarray(velocity, float) * np.asarray(term, float)
    total = float(np.sum(np.abs(power)))
    return float(np.sum(power)) / total if total > 0 and np.isfinite(total) else np.nan


def _term_values(effect: AdditiveEffect, theta: dict, states, u) -> np.ndarray:
    """``effect``'s term at each simulated ``(x_k, u_k)`` with the fitted ``theta``."""
    with jax.enable_x64(True):
        values = {name: jnp.asarray(value, jnp.float64) for name, value in theta.items()}
        term = jax.vmap(lambda x, w: effect.term(x, w, values))(
            jnp.asarray(states, jnp.float64), jnp.asarray(u, jnp.float64)
        )
    return np.asarray(term, float)


def declared_damping(physics, theta: dict, i: int, states=None, u=None) -> float | None:
    r"""$b = -\partial f_i / \partial x_i$ of the declared right-hand side, the declared
    parameters' values (numbers) read from ``theta``, averaged over ``states`` and ``u``
    (at the declared initial state and zero inputs when ``None``); ``None`` for a physics
    declared by its step, whose rate is not at hand, or where $b$ is not finite."""
    rhs = getattr(physics, "rhs", None)
    if rhs is None:
        return None
    n = physics.n_states
    if states is None:
        states, u = np.asarray(physics.x0, float)[None], np.zeros((1, physics.n_inputs))
    values = {name: theta.get(name, p.value) for name, p in physics.parameters.items()}
    with jax.enable_x64(True):
        params = {name: jnp.asarray(value, jnp.float64) for name, value in values.items()}
        rate = jax.grad(lambda x, w: rhs(x, w, params)[i])
        slopes = jax.vmap(rate)(jnp.asarray(np.asarray(states)[:, :n]), jnp.asarray(u, float))
    damping = -float(np.mean(np.asarray(slopes)[:, i]))
    return damping if np.isfinite(damping) else None


def directional_dampings(effect, physics, theta: dict, states=None, u=None):
    r"""``(forward, backward)``: the damping $b \pm c$ of the velocity a
    [`DirectionalDamping`][sk_offwhite.DirectionalDamping] brakes, in each direction
    (`declared_damping` over ``states``); ``None`` where the declared damping is not at hand."""
    b = declared_damping(physics, theta, effect.velocity, states, u)
    if b is None:
        return None
    c = float(theta.get(f"{effect.name}_difference", effect.difference))
    return b + c, b - c


def direction_sentence(effect, physics, theta: dict, states, u) -> str | None:
    """The damping of each direction a [`DirectionalDamping`][sk_offwhite.DirectionalDamping]
    leaves, over the simulated ``states``."""
    pair = directional_dampings(effect, physics, theta, states, u)
    if pair is None:
        return None
    forward, backward = pair
    what = "dissipative both ways" if min(pair) >= 0 else "not physical: a direction is driven"
    return (
        f"{what}: the damping of {physics.state_names[effect.velocity]} is {forward:.4g} "
        f"moving forward and {backward:.4g} moving back (per unit time)"
    )


def power_sentence(effect, physics, theta: dict, states, u) -> str | None:
    """What ``effect`` does to the energy of the velocity whose equation it enters, on the
    simulated ``states`` and inputs ``u``; ``None`` for an effect that is not an added term
    of a velocity's (or rate's) equation, or that does no work there. A directional damping
    gets the damping of each direction instead (`direction_sentence`)."""
    if not isinstance(effect, AdditiveEffect):
        return None
    i = effect.state
    if physics.state_kinds[i] not in VELOCITY_KINDS:
        return None
    if isinstance(effect, DirectionalDamping):
        return direction_sentence(effect, physics, theta, states, u)
    share = net_power_share(states[:, i], _term_values(effect, theta, states, u))
    if not np.isfinite(share):
        return None
    name = physics.state_names[i]
    if share <= -CONSERVATIVE_SHARE:
        what = f"dissipative: it takes energy out of the motion of {name}"
    elif share >= CONSERVATIVE_SHARE:
        what = f"energy-adding: it drives the motion of {name}"
    else:
        what = f"conservative: it stores the energy it takes from {name} and returns it"
    return f"{what} (net power share {share:+.2f} on the estimation record)"
