r"""Play in a transmission (backlash): an effect with a hidden state."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..model._physics import Parameter
from ._base import SHARPNESS, Effect, _positive, _widened_range
from ._hidden import HiddenStates

__all__ = ["Backlash"]


class Backlash(HiddenStates, Effect):
    r"""Input ``input`` drives the plant through a play of half-width $w$ (backlash).

    The driven side's position $p$ is a hidden state: it stays where it is until the
    input pushes it from one side of the play,

    $$
    \begin{gathered}
    p_{k+1} = \mathrm{clip}(p_k,\ u_k - w,\ u_k + w)
    \approx p_k + \eta(u_k - w - p_k) - \eta(p_k - u_k - w), \\
    \eta(a) = \frac{w}{s}\,\mathrm{sp}\Bigl(\frac{s\,a}{w}\Bigr),
    \end{gathered}
    $$

    and the declared step sees $p_{k+1}$ in place of $u_k$ ($\mathrm{sp}$
    the softplus, $s$ = ``sharpness``, relative to $w$, so the smoothing
    follows the input's units). A gear's or a lead screw's play between a commanded position
    and the load: proposed for inputs of kind ``"position"`` or ``"angle"``. Parameter
    ``{name}_width`` ($w > 0$, in the input's units); hidden state
    ``{name}_position`` ($p$, started at ``position`` and estimated with the initial
    state).
    """

    def __init__(
        self, input: int, width: float, *, position=0.0, sharpness=SHARPNESS, name="backlash"
    ):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        self.input, self.width, self.position = int(input), float(width), float(position)
        self.sharpness, self.name = sharpness, name

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return (f"{self.name}_position",)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_width": _positive(self.width)}

    def hidden_initial(self) -> tuple[float, ...]:
        return (self.position,)

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return (input_kinds[self.input],)

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        r"""The guess where the play holds it at the first input ($|p - u| \le w$),
        else the input itself: beyond the play the first step moves $p$ to its edge
        whatever the guess, so a fit started there cannot move it."""
        position, command = float(hidden[0]), float(u[self.input])
        inside = abs(position - command) <= float(theta[f"{self.name}_width"])
        return (position if inside else command,)

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        r"""The record's input range widened by itself on each side,
        $[\min u - R,\ \max u + R]$ with $R = \max u - \min u$. A start
        farther out is held at the play's edge by the first step as long as $w \le R$
        (a wider play never moves), so the bounds remove no model; without them a fit
        can run the start along that flat direction to magnitudes where neighbouring
        doubles are farther apart than the play is wide. A constant input ($R = 0$)
        bounds nothing."""
        return (_widened_range(u, self.input),)

    def advance(self, hidden, u, theta):
        width, s = theta[f"{self.name}_width"], self.sharpness
        position, command = hidden[0], u[self.input]

        def push(gap):
            return width * jax.nn.softplus(s * gap / width) / s

        moved = position + push(command - width - position) - push(position - command - width)
        return u.at[self.input].set(moved), jnp.reshape(moved, (1,))

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            "the transmission has play (backlash): the load follows the input only once "
            "the input has crossed the play"
        )
