r"""A slow sensor: the measurement follows the measured quantity through a first-order lag.

A thermocouple in a well, a damped pressure transducer, a filtered tachometer: the sensing
element has dynamics of its own, so the reading $s$ follows the quantity the declared
output map gives, $y = h(x, u)$, with a time constant $\tau$,
$\tau \dot s = y - s$. With $y$ taken linear over each sample (between
$y_k$ and $y_{k+1}$), exactly,

$$
s_{k+1} = s_k + \alpha\,(y_k - s_k) + \beta\,(y_{k+1} - y_k), \qquad
\alpha = 1 - e^{-T_s/\tau}, \quad \beta = 1 - \frac{\tau}{T_s}\,\alpha,
$$

and the output reads $s_k$ in place of $y_k$; the static output effects
(a calibration, a saturation, a step) act on that reading. As $\tau \to 0$,
$s_{k+1} = y_{k+1}$: the declared model from the second sample on. The reading is a
hidden state (`sk_offwhite._hidden`) that follows the declared output instead of an
input. For a linear plant a lag of the sensor and a lag of the actuator give the same
input-output behaviour; only a nonlinear plant tells them apart.
"""

from __future__ import annotations

import jax.numpy as jnp

from ._effects import FirstOrderLag, lag_coefficients

__all__ = ["SensorLag", "sensor_lag_law"]


def sensor_lag_law(reading, now, after, ratio, xp=jnp):
    r"""$s_{k+1}$ from the reading $s_k$ and the measured quantity now and after
    the sample ($y_k$, $y_{k+1}$), ``ratio`` $= \tau / T_s$, in the
    array module ``xp`` (JAX, or NumPy for a generator)."""
    alpha, beta = lag_coefficients(ratio, xp)
    return reading + alpha * (now - reading) + beta * (after - now)


class SensorLag(FirstOrderLag):
    r"""Output ``output`` is read through a first-order lag (sensor dynamics).

    $$
    \tau \dot s = h_j(x, u) - s, \qquad z_j = s,
    $$

    discretised exactly for an output linear over each sample (see
    `sk_offwhite._sensor_lag`). Parameter ``{name}_time_constant`` ($\tau > 0$,
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

    @property
    def mechanism(self) -> str:
        """The dynamics of one output's sensor."""
        return f"dynamics of the sensor of output {self.output}"

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
