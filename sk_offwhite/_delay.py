r"""A dead time of an input: the command reaches the plant late (transport delay).

Fluid that carries heat or a dose along a pipe, a conveyor, a sensor placed downstream,
a controller's computation: the plant sees the command $d$ later than it was given.
Under a zero-order hold the command is a staircase, and what the declared step sees over
sample $k$ is the delayed staircase's mean over that sample; with
$d = (m + f)\,T_s$, $m$ whole samples and a fraction $0 \le f < 1$,

$$
\tilde u_k = \frac{1}{T_s}\int_{kT_s}^{(k+1)T_s} u(t - d)\,dt
           = (1 - f)\,u_{k-m} + f\,u_{k-m-1},
$$

exactly: the linear interpolation of the held commands. At $d = 0$ it is the
command itself (the declared model). The commands of the last $D$ samples are the
effect's hidden states, so the delay can move continuously between whole samples while it
is fitted; $D T_s$ bounds it.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ._effects import Effect, _widened_range, checked_positive
from ._physics import Parameter

__all__ = ["InputDelay", "delayed_command"]


def delayed_command(u, delay: float, sampling_time: float, start=None) -> np.ndarray:
    r"""What a dead time ``delay`` delivers over each held sample of the command sequence
    ``u`` (1-D): $\tilde u_k = (1 - f) u_{k-m} + f u_{k-m-1}$ with
    $d / T_s = m + f$, the commands before the record at ``start`` (``u[0]`` when
    ``None``: settled at the first command)."""
    u = np.asarray(u, dtype=np.float64)
    whole, fraction = divmod(delay / sampling_time, 1.0)
    first = float(u[0]) if start is None else float(start)
    padded = np.concatenate([np.full(int(whole) + 1, first), u])
    now = padded[1 : u.size + 1]  # u_{k-m}
    before = padded[: u.size]  # u_{k-m-1}
    return (1.0 - fraction) * now + fraction * before


class InputDelay(Effect):
    r"""Input ``input`` reaches the plant after a dead time (a transport delay).

    $$
    \tilde u_k = (1 - f)\,u_{k-m} + f\,u_{k-m-1}, \qquad d = (m + f)\,T_s,
    $$

    the mean over sample $k$ of the held command delayed by $d$ (exact under a
    zero-order hold; see `sk_offwhite._delay`). Parameter ``{name}_delay``
    ($0 \le d \le D T_s$, in the effects' unit of time,
    `time_step`, like ``sampling_time`` $T_s$); hidden
    states ``{name}_past_1`` … ``{name}_past_D``, the commands of the last
    $D$ = ``ceil(max_delay / sampling_time)`` samples: each record starts them at
    its first command, and they are not fitted (only the first $m + 1$ samples see
    them; the rest would be parameters without influence). ``initial`` is their value in
    the model's ``x0``. ``max_delay`` defaults to eight samples, or four times ``delay``
    when that is longer; the richer variant (`richer`), which the loop tries once
    the delay is chosen, doubles it.

    Its derivative in $d$ is $(u_{k-m-1} - u_{k-m})/T_s$, the one-sided
    derivative at a whole number of samples, so a fit started at a whole sample moves.
    """

    target = "hidden"
    hidden_free = False
    DEFAULT_SAMPLES = 8

    def __init__(
        self,
        input: int,
        delay: float,
        *,
        sampling_time: float = 1.0,
        max_delay: float | None = None,
        initial: float = 0.0,
        name: str = "delay",
    ):
        sampling_time = checked_positive(sampling_time, "sampling_time")
        delay = checked_positive(delay, "delay")
        if max_delay is None:
            max_delay = max(self.DEFAULT_SAMPLES * sampling_time, 4.0 * delay)
        if not (np.isfinite(max_delay) and max_delay >= delay):
            raise ValueError(f"max_delay must be at least delay, got {max_delay!r}.")
        self.input, self.delay, self.sampling_time = int(input), delay, sampling_time
        self.max_delay, self.initial, self.name = float(max_delay), float(initial), name

    @property
    def n_taps(self) -> int:
        """$D$, the number of past commands the effect keeps."""
        return max(1, math.ceil(self.max_delay / self.sampling_time - 1e-9))

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return tuple(f"{self.name}_past_{i}" for i in range(1, self.n_taps + 1))

    def parameters(self) -> dict[str, Parameter]:
        upper = self.n_taps * self.sampling_time
        return {f"{self.name}_delay": Parameter(self.delay, (0.0, upper))}

    @property
    def mechanism(self) -> str:
        """The dynamics of one input's actuator (the lag's mechanism: the two are variants
        of how the command reaches the plant)."""
        return f"dynamics of input {self.input}"

    def hidden_initial(self) -> tuple[float, ...]:
        return (self.initial,) * self.n_taps

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return (input_kinds[self.input],) * self.n_taps

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        """The commands before the record taken as its first."""
        return (float(u[self.input]),) * self.n_taps

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        """The record's input range widened by itself on each side, for every past command."""
        return (_widened_range(u, self.input),) * self.n_taps

    def hidden_path(self, u, theta) -> np.ndarray:
        """The commands before each sample: row $k$ holds
        $u_{k-1}, \\dots, u_{k-D}$, the record's first command before it starts."""
        commands = np.asarray(u, float)[:, self.input]
        padded = np.concatenate([np.full(self.n_taps, commands[0]), commands])
        rows = np.arange(commands.size)[:, None] + self.n_taps - np.arange(1, self.n_taps + 1)
        return padded[rows]

    def advance(self, hidden, u, theta):
        commands = jnp.concatenate([jnp.reshape(u[self.input], (1,)), hidden])
        samples = jnp.clip(theta[f"{self.name}_delay"] / self.sampling_time, 0.0, self.n_taps)
        whole = jnp.clip(jnp.floor(samples), 0, self.n_taps - 1)
        fraction = samples - whole
        index = whole.astype(jnp.int32)
        seen = (1.0 - fraction) * commands[index] + fraction * commands[index + 1]
        return u.at[self.input].set(seen), commands[:-1]

    def richer(self) -> InputDelay:
        """The same dead time with twice the reach ($2D$ past commands): a delay
        the fit left at its bound may be longer. Its fit starts at this one's delay."""
        reach = 2 * self.n_taps * self.sampling_time
        return self.replace(max_delay=reach, name=f"{self.name}_longer")

    def describe(self, state_names, output_names, values=None) -> str:
        return "the input acts late: a dead time between command and plant (its length fitted)"
