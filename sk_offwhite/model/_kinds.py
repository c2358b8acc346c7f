r"""Physical kinds of states and inputs, declared or read off the structure of the physics.

A kind tells which missing effects make physical sense for a variable: an overflow for a
level, friction and drag for a velocity, a stiffness for a position, an offset for a force,
a dead zone or a saturation for an actuator. Kinds are declared with
``PhysicsModel(..., state_kinds=..., input_kinds=...)``, and what is declared is the truth:
a declared velocity is paired with a declared position whatever the integrator. A state
left ``"generic"`` takes a kind from the structure of the physics when it is a kinematic
pair: if the time derivative (the right-hand side of a physics built with
[`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode], else the step's increment) is

$$
\dot x_i = c\, x_j \quad\text{or}\quad x^+_i - x_i = c\, x_j \qquad
(c \ne 0 \text{ constant}, \text{ nothing else})
$$

then $x_i$ is a position and $x_j$ its velocity (an angle and its rate when $x_i$ was
declared an angle). The test evaluates the Jacobian at a few random points.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "ACTUATOR_KINDS",
    "KINDS",
    "LEVEL_KINDS",
    "POSITION_KINDS",
    "VELOCITY_KINDS",
    "Kinds",
    "check_kinds",
    "physical_kinds",
]

KINDS = (
    "level",
    "position",
    "velocity",
    "angle",
    "rate",
    "force",
    "torque",
    "flow",
    "voltage",
    "current",
    "temperature",
    "generic",
)
POSITION_KINDS = ("position", "angle")
VELOCITY_KINDS = ("velocity", "rate")
LEVEL_KINDS = ("level",)
ACTUATOR_KINDS = ("force", "torque", "flow", "voltage", "current", "temperature", "generic")


class Kinds(NamedTuple):
    """Kinds of the states and inputs, and each velocity's position (``partner``)."""

    states: tuple[str, ...]
    inputs: tuple[str, ...]
    partner: dict[int, int]


def check_kinds(argument: str, kinds, count: int) -> tuple[str, ...]:
    """``kinds`` as a tuple of ``count`` known kinds (``None``: all ``"generic"``)."""
    if kinds is None:
        return ("generic",) * count
    kinds = tuple(str(k) for k in kinds)
    if len(kinds) != count:
        raise ValueError(f"{argument} must have {count} entries, got {len(kinds)}.")
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        raise ValueError(f"{argument} has unknown kinds {unknown}; known: {KINDS}.")
    return kinds


def _rate_function(physics):
    """``(rate(x, u), n)``: the right-hand side of a physics built with ``from_ode`` (on its
    declared states), else the step's increment $f(x, u) - x$."""
    theta = {k: p.value for k, p in physics.parameters.items()}
    declared = getattr(physics, "declared", (physics.step,))[0]
    rhs = getattr(physics, "rhs", None) or getattr(declared, "rhs", None)
    if rhs is not None:
        n = getattr(physics, "n_declared_states", physics.n_states)
        return (lambda x, u: jnp.asarray(rhs(x, u, theta)).reshape(x.shape)), n

    def increment(x, u):
        return jnp.asarray(physics.step(x, u, theta)).reshape(x.shape) - x

    return increment, physics.n_states


def _increment_jacobians(physics, n_points: int, seed: int):
    """Jacobians of the rate (`_rate_function`) in ``x`` and ``u`` at random points."""
    rng = np.random.default_rng(seed)
    rate, n = _rate_function(physics)
    scale = np.maximum(np.abs(np.asarray(physics.x0, float)[:n]), 1.0)
    jac = jax.jacfwd(rate, argnums=(0, 1))
    out = []
    with jax.enable_x64(True):
        for _ in range(n_points):
            x = jnp.asarray(scale * (0.5 + rng.random(n)))
            u = jnp.asarray(0.5 + rng.random(physics.n_inputs))
            jx, ju = jac(x, u)
            out.append((np.asarray(jx), np.asarray(ju)))
    return out


def kinematic_pairs(physics, n_points: int = 3, seed: int = 0) -> dict[int, int]:
    """``{velocity: position}`` for every state pair with $x^+_i - x_i = c\\,x_j$."""
    try:
        jacobians = _increment_jacobians(physics, n_points, seed)
    except Exception:  # a step that cannot be differentiated here: no inference
        return {}
    pairs = {}
    for i in range(jacobians[0][0].shape[0]):
        rows = np.array([jx[i] for jx, _ in jacobians])
        inputs = np.array([ju[i] for _, ju in jacobians])
        nonzero = np.flatnonzero(np.any(np.abs(rows) > 1e-12 * np.abs(rows).max(initial=1.0), 0))
        if len(nonzero) != 1 or nonzero[0] == i or np.any(inputs != 0):
            continue
        values = rows[:, nonzero[0]]
        if np.ptp(values) <= 1e-9 * abs(values[0]) and values[0] != 0:
            pairs[int(nonzero[0])] = i
    return pairs


def physical_kinds(physics) -> Kinds:
    """The declared kinds, with kinematic pairs completed (module docstring): the pairs the
    structure shows, then each declared velocity (rate) without one paired with a declared
    position (angle) in order."""
    states = list(getattr(physics, "state_kinds", None) or ("generic",) * physics.n_states)
    inputs = tuple(getattr(physics, "input_kinds", None) or ("generic",) * physics.n_inputs)
    pairs = kinematic_pairs(physics)
    for velocity, position in pairs.items():
        angular = states[position] == "angle" or states[velocity] == "rate"
        if states[position] == "generic":
            states[position] = "angle" if angular else "position"
        if states[velocity] == "generic":
            states[velocity] = "rate" if angular else "velocity"
    pairs.update(declared_pairs(states, pairs))
    return Kinds(tuple(states), inputs, pairs)


def declared_pairs(states, pairs: dict[int, int]) -> dict[int, int]:
    """``{velocity: position}`` for the declared velocities (rates) that ``pairs`` leaves
    alone, each with the next declared position (angle) no pair holds yet."""
    found, taken = {}, set(pairs.values())
    for kinds in (("velocity", "position"), ("rate", "angle")):
        velocities = [i for i, k in enumerate(states) if k == kinds[0] and i not in pairs]
        positions = [i for i, k in enumerate(states) if k == kinds[1] and i not in taken]
        found.update(zip(velocities, positions, strict=False))
    return found
