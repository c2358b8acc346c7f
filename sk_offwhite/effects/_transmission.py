r"""Friction that grows with the force a transmission carries: the efficiency of a screw or
a gear.

A lead screw, a ball screw or a gear train loses to friction a share of the force (or
torque) it transmits, on top of the friction it has unloaded: its contact forces, and with
them its friction, grow with the load. The force that reaches the load is then

$$
\tau_{\mathrm{seen}} = \tau - \mu\,|\tau|\,\tanh(v / w),
$$

with $v$ the velocity the transmission drives and $\mu \in [0, 1)$ the share lost: while
the drive pushes the motion ($\tau v > 0$) a fraction $1 - \mu$ of its force arrives (the
forward efficiency), while it brakes the motion the friction adds to the braking
($1 + \mu$). The share is unit-free, so it reads the same in any units of the force and
the velocity.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..model._physics import Parameter
from ._base import InputEffect, checked_positive

__all__ = ["TransmissionFriction"]


class TransmissionFriction(InputEffect):
    r"""A friction proportional to the force an input transmits, opposing a velocity.

    The declared step sees input ``input`` as
    $u_j - \mu\,|u_j|\,\tanh(x_{velocity} / w)$ (see the module docstring).
    Parameter ``{name}_share`` ($\mu \in [0, 0.95]$, started at ``share``); the width
    $w$ of the smooth sign (in the velocity's units; the loop takes 1 % of the
    velocity's RMS) is fixed. For a physics built with
    [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] it acts inside the
    integrated right-hand side, at every stage.
    """

    MAX_SHARE = 0.95
    """The largest share of the force the fit may take as lost."""

    def __init__(
        self,
        input: int,
        velocity: int,
        *,
        share: float = 0.05,
        width: float = 0.01,
        name: str = "transmission",
    ):
        share = float(share)
        if not 0.0 <= share <= self.MAX_SHARE:
            raise ValueError(f"share must lie in [0, {self.MAX_SHARE}], got {share!r}.")
        self.input, self.velocity, self.share = int(input), int(velocity), share
        self.width, self.name = checked_positive(width, "width"), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_share": Parameter(self.share, (0.0, self.MAX_SHARE))}

    def apply_input(self, x, u, theta):
        force = u[self.input]
        sign = jnp.tanh(x[self.velocity] / self.width)
        lost = theta[f"{self.name}_share"] * jnp.abs(force) * sign
        return u.at[self.input].set(force - lost)

    def describe(self, state_names, output_names, values=None) -> str:
        share = (values or {}).get(f"{self.name}_share")
        amount = "a share" if share is None else f"{100 * float(share):.3g} %"
        return (
            f"the transmission loses {amount} of the force it carries to friction opposing "
            f"{state_names[self.velocity]} (a screw or gear whose friction grows with its load)"
        )
