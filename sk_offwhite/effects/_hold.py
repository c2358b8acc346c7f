r"""What a sampled input does between two samples.

A physics built with [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] holds each
input sample until the next (a zero-order hold), which is what a digital command does. A
smooth signal that was sampled (a band-limited excitation, a measured voltage) moves between
its samples; held, it reaches the plant half a sample late on average, a lag that a
resonance or a fast mode amplifies. [`InputHold`][sk_offwhite.InputHold] integrates the
declared right-hand side with the input interpolated linearly between samples (a
first-order hold),

$$
u(t_k + s\,T_s) = u_k + s\,(u_{k+1} - u_k), \qquad 0 \le s \le 1,
$$

so each RK4 step reads $u_k$, $(u_k + u_{k+1})/2$ and $u_{k+1}$. It has no parameters.
"""

from __future__ import annotations

from ._base import Effect

__all__ = ["InputHold"]


class InputHold(Effect):
    """The inputs move linearly between samples (a first-order hold), not in steps.

    Only for a physics built with
    [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] (a discrete-time step has no
    time between samples to interpolate over); every input of the physics is interpolated,
    but one that passes through an effect with memory
    ([`InputDelay`][sk_offwhite.InputDelay], [`InputLag`][sk_offwhite.InputLag],
    [`Backlash`][sk_offwhite.Backlash]): what that effect delivers is known up to the
    current sample only, and is held over it.
    """

    target = "hold"

    def __init__(self, *, name: str = "input_hold"):
        self.name = name

    def parameters(self) -> dict:
        return {}

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            "the inputs move smoothly between samples: they are interpolated linearly "
            "(a first-order hold) instead of held over each sample"
        )
