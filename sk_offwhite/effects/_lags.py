r"""How a command reaches the plant late, and how a sensor reads late: first-order lags of an
input ([`InputLag`][sk_offwhite.InputLag]) and of an output ([`SensorLag`][sk_offwhite.SensorLag])
on one exact zero-order-hold law, and a dead time ([`InputDelay`][sk_offwhite.InputDelay]). Each
carries hidden states.

For a lag of time constant $\tau$ at sampling time $T_s$, held over each sample,

$$
\alpha = 1 - e^{-T_s/\tau}, \qquad \beta = 1 - \frac{\tau}{T_s}\,\alpha,
$$

where $\alpha$ moves the lag's state toward its target over one sample and $\beta$ weighs
the lag's mean over the sample; as $\tau \to 0$ both tend to 1, the declared model.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..model._physics import Parameter
from ._base import Effect, _positive, _widened_range, checked_positive
from ._hidden import FollowsOutput, HiddenStates

__all__ = [
    "FirstOrderLag",
    "InputDelay",
    "InputLag",
    "SensorLag",
    "delayed_command",
    "lag_coefficients",
    "sensor_lag_law",
]


def lag_coefficients(ratio, xp=jnp):
    r"""$\alpha = 1 - e^{-T_s/\tau}$ and $\beta = 1 - \frac{\tau}{T_s}\,\alpha$
    of a first-order lag of time constant $\tau$ over a sample $T_s$, from
    ``ratio`` $= \tau / T_s$, in the array module ``xp``: the share of the gap to
    its input that the lag closes over the sample, and the share its mean over the sample
    closes ([`InputLag`][sk_offwhite.InputLag], [`SensorLag`][sk_offwhite.SensorLag])."""
    alpha = -xp.expm1(-1.0 / ratio)
    return alpha, 1.0 - ratio * alpha


class FirstOrderLag(HiddenStates, Effect):
    """What the first-order lags of an input ([`InputLag`][sk_offwhite.InputLag]) and of an output
    ([`SensorLag`][sk_offwhite.SensorLag]) share: the time constant $\\tau$, a positive
    parameter ``{name}_time_constant`` in the effects' unit of time, like the sampling time
    $T_s$, and one hidden state started at ``initial``."""

    def _set_lag(self, time_constant, sampling_time, initial, name) -> None:
        self.time_constant = checked_positive(time_constant, "time_constant")
        self.sampling_time = checked_positive(sampling_time, "sampling_time")
        self.initial, self.name = float(initial), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_time_constant": _positive(self.time_constant)}

    def hidden_initial(self) -> tuple[float, ...]:
        return (self.initial,)

    def ratio(self, theta):
        r"""$\tau / T_s$ at the parameters ``theta``."""
        return theta[f"{self.name}_time_constant"] / self.sampling_time


class InputLag(FirstOrderLag):
    r"""Input ``input`` reaches the plant through a first-order lag (actuator dynamics).

    A drive's amplifier, a valve's positioner, a heater's element: the actuator's output
    $p$ follows the command with a time constant $\tau$ that the declared
    physics leaves out. Held over each sample (zero-order hold), exactly,

    $$
    \begin{gathered}
    p_{k+1} = p_k + \alpha\,(u_k - p_k), \qquad
    \tilde u_k = p_k + \beta\,(u_k - p_k), \\
    \alpha = 1 - e^{-T_s/\tau}, \quad \beta = 1 - \frac{\tau}{T_s}\,\alpha,
    \end{gathered}
    $$

    where $\tilde u_k$, what the declared step sees, is the lag's mean over the
    sample. As $\tau \to 0$ it is the command itself (the declared model), so a fit
    started at a short lag starts near the declared model. Parameter
    ``{name}_time_constant`` ($\tau > 0$, in the effects' unit of time,
    `time_step`, like ``sampling_time`` $T_s$); hidden state
    ``{name}_output`` ($p$, started at ``initial``, the actuator settled at the
    first command, and estimated with the initial state).
    """

    def __init__(
        self,
        input: int,
        time_constant: float,
        *,
        sampling_time: float = 1.0,
        initial: float = 0.0,
        name: str = "lag",
    ):
        self.input = int(input)
        self._set_lag(time_constant, sampling_time, initial, name)

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return (f"{self.name}_output",)

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return (input_kinds[self.input],)

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        """The actuator settled at the first command."""
        return (float(u[self.input]),)

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        r"""The record's input range widened by itself on each side (the lag's output is
        an average of commands, $[\min u - R,\ \max u + R]$); a constant input
        bounds nothing."""
        return (_widened_range(u, self.input),)

    def advance(self, hidden, u, theta):
        alpha, beta = lag_coefficients(self.ratio(theta))
        output, gap = hidden[0], u[self.input] - hidden[0]
        seen = output + beta * gap
        return u.at[self.input].set(seen), jnp.reshape(output + alpha * gap, (1,))

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            "the actuator lags its command: the input acts through a first-order lag "
            "(its time constant fitted)"
        )


def sensor_lag_law(reading, now, after, ratio, xp=jnp):
    r"""$s_{k+1}$ from the reading $s_k$ and the measured quantity now and after
    the sample ($y_k$, $y_{k+1}$), ``ratio`` $= \tau / T_s$, in the
    array module ``xp`` (JAX, or NumPy for a generator)."""
    alpha, beta = lag_coefficients(ratio, xp)
    return reading + alpha * (now - reading) + beta * (after - now)


class SensorLag(FollowsOutput, FirstOrderLag):
    r"""Output ``output`` is read through a first-order lag (sensor dynamics).

    $$
    \tau \dot s = h_j(x, u) - s, \qquad z_j = s,
    $$

    discretised exactly for an output linear over each sample (see
    the module docstring). Parameter ``{name}_time_constant`` ($\tau > 0$,
    in the effects' unit of time, `time_step`, like
    ``sampling_time`` $T_s$); hidden state ``{name}_reading`` ($s$, started
    at ``initial`` in the model's ``x0``, at the first measurement of each record when a
    fit guesses initial states, and estimated with the initial state). The output map's
    input is taken at sample $k$ for $y_{k+1}$ too (exact for a map without
    feedthrough).
    """

    follows_output = True

    def __init__(
        self,
        output: int,
        time_constant: float,
        *,
        sampling_time: float = 1.0,
        initial: float = 0.0,
        name: str = "sensor_lag",
    ):
        self.output = int(output)
        self._set_lag(time_constant, sampling_time, initial, name)

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return (f"{self.name}_reading",)

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return ("generic",)

    def follow(self, hidden, now, after, theta):
        """The next reading from this one and the declared outputs at samples $k$
        (``now``) and $k + 1$ (``after``)."""
        reading = sensor_lag_law(hidden[0], now[self.output], after[self.output], self.ratio(theta))
        return jnp.reshape(reading, (1,))

    def follow_off(self, hidden, now, after):
        """The declared output itself: a switched-off lag reads $y_k$ from the second
        sample on."""
        return jnp.reshape(after[self.output], (1,)).astype(jnp.result_type(hidden))

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            f"the sensor of {output_names[self.output]} lags what it measures: its reading "
            "follows through a first-order lag (its time constant fitted)"
        )


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


class InputDelay(HiddenStates, Effect):
    r"""Input ``input`` reaches the plant after a dead time (a transport delay).

    $$
    \tilde u_k = (1 - f)\,u_{k-m} + f\,u_{k-m-1}, \qquad d = (m + f)\,T_s,
    $$

    the mean over sample $k$ of the held command delayed by $d$ (exact under a
    zero-order hold; see the module docstring). Parameter ``{name}_delay``
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

    def describe(self, state_names, output_names, values=None) -> str:
        return "the input acts late: a dead time between command and plant (its length fitted)"
