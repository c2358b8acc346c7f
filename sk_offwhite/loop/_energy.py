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
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..effects import AdditiveEffect
from ..model._kinds import VELOCITY_KINDS

__all__ = ["CONSERVATIVE_SHARE", "net_power_share", "power_sentence"]

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


def power_sentence(effect, physics, theta: dict, states, u) -> str | None:
    """What ``effect`` does to the energy of the velocity whose equation it enters, on the
    simulated ``states`` and inputs ``u``; ``None`` for an effect that is not an added term
    of a velocity's (or rate's) equation, or that does no work there."""
    if not isinstance(effect, AdditiveEffect):
        return None
    i = effect.state
    if physics.state_kinds[i] not in VELOCITY_KINDS:
        return None
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
