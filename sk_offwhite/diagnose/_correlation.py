r"""Correlation tests of a residual: is it white, and is it independent of the inputs?

A model that has captured the system leaves a residual $\varepsilon_k$ (measured minus
simulated output) that is white and unrelated to past inputs. With centred signals
(the sample mean removed) and $N$ samples, the normalised correlations are

$$
r_\varepsilon(\tau) = \frac{\sum_k \varepsilon_{k+\tau}\,\varepsilon_k}
                           {\sum_k \varepsilon_k^2}, \qquad
r_{\varepsilon u}(\tau) = \frac{\sum_k \varepsilon_{k+\tau}\,u_k}
                               {\sqrt{\sum_k \varepsilon_k^2 \sum_k u_k^2}},
$$

summing over the samples where both indices exist. A positive lag $\tau$ compares the
residual with the input $\tau$ samples *earlier* (the causal direction); a negative lag
with later inputs (which points at feedback).

Under the null hypothesis each $r(\tau)$ is approximately normal with standard
deviation $1/\sqrt N$, so the band at confidence $c$ is
$\pm z_{(1+c)/2}/\sqrt N$.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft
from scipy.stats import chi2, norm

from ._arrays import (
    as_columns,
    as_signal,
    check_confidence,
    check_integer,
    check_rows,
    is_constant,
    read_only,
)

__all__ = [
    "CrossCorrelationResult",
    "WhitenessResult",
    "correlated_inputs",
    "cross_correlation_test",
    "lagging_outputs",
    "whiteness_test",
]


@dataclass(frozen=True)
class WhitenessResult:
    """Outcome of [`whiteness_test`][sk_offwhite.diagnose.whiteness_test].

    Attributes
    ----------
    lags : array of shape (max_lag + 1,)
        ``0, 1, ..., max_lag``.
    autocorrelation : array of shape (max_lag + 1,)
        Normalised autocorrelation $r_\\varepsilon(\\tau)$; ``autocorrelation[0] == 1``.
    band : float
        Half-width $z_{(1+c)/2}/\\sqrt N$ of the confidence band.
    fraction_outside : float
        Fraction of the lags ``1..max_lag`` with $|r_\\varepsilon(\\tau)|$ above ``band``
        (about ``1 - confidence`` for a white residual).
    q_statistic, p_value : float
        Ljung-Box statistic and its chi-squared p-value with ``max_lag`` degrees of freedom.
    confidence : float
    n_samples : int
    white : bool
        ``p_value >= 1 - confidence``: whiteness is not rejected.
    """

    lags: np.ndarray
    autocorrelation: np.ndarray
    band: float
    fraction_outside: float
    q_statistic: float
    p_value: float
    confidence: float
    n_samples: int
    white: bool


@dataclass(frozen=True)
class CrossCorrelationResult:
    """Outcome of [`cross_correlation_test`][sk_offwhite.diagnose.cross_correlation_test], one row
    per input column.

    Attributes
    ----------
    lags : array of shape (2 * max_lag + 1,)
        ``-max_lag, ..., max_lag``; positive lags compare the residual with earlier inputs.
    correlation : array of shape (n_inputs, 2 * max_lag + 1)
        Normalised cross-correlation $r_{\\varepsilon u}(\\tau)$; NaN for a constant
        input, which is not tested.
    band : array of shape (n_inputs,)
        Per-lag band half-width $z_{(1+c)/2}\\sqrt{P/N}$, with the Bartlett factor
        $P = \\max(1, 1 + 2\\sum_{k=1}^{L} r_\\varepsilon(k)\\,r_u(k))$ that widens the
        white-noise band when residual and input are both coloured.
    fraction_outside : array of shape (n_inputs,)
        Fraction of the lags with $|r_{\\varepsilon u}(\\tau)|$ above ``band``.
    statistic : array of shape (n_inputs,)
        Largest standardised correlation $\\max_\\tau |r_{\\varepsilon u}(\\tau)|
        \\sqrt{N/P}$.
    p_value : array of shape (n_inputs,)
        Bonferroni-corrected p-value of ``statistic`` over the ``2 * max_lag + 1`` lags
        (conservative even though neighbouring lags are correlated).
    confidence : float
    n_samples : int
    independent : bool
        Every tested input has ``p_value >= 1 - confidence``.
    """

    lags: np.ndarray
    correlation: np.ndarray
    band: np.ndarray
    fraction_outside: np.ndarray
    statistic: np.ndarray
    p_value: np.ndarray
    confidence: float
    n_samples: int
    independent: bool


def whiteness_test(residual, max_lag: int = 25, confidence: float = 0.99) -> WhitenessResult:
    r"""Autocorrelation and Ljung-Box test of a residual for whiteness.

    The Ljung-Box statistic

    $$
    Q = N (N + 2) \sum_{\tau=1}^{L} \frac{r_\varepsilon(\tau)^2}{N - \tau}
    $$

    is approximately $\chi^2_L$ for a white residual, with $L$ = ``max_lag``.

    Parameters
    ----------
    residual : array of shape (n_samples,) or (n_samples, 1)
        Measured minus simulated output; not constant.
    max_lag : int, default 25
        Largest lag $L$, between 1 and ``n_samples - 1``.
    confidence : float, default 0.99
        Confidence level of the band and of the verdict.

    Returns
    -------
    WhitenessResult
    """
    signal = _checked_signal(residual)
    max_lag = _checked_lag(max_lag, signal.size)
    confidence = check_confidence(confidence)
    autocorrelation = _autocorrelation(signal, max_lag)
    band = _white_band(confidence, signal.size)
    q_statistic, p_value = _ljung_box(autocorrelation, signal.size)
    return WhitenessResult(
        lags=read_only(np.arange(max_lag + 1)),
        autocorrelation=read_only(autocorrelation),
        band=band,
        fraction_outside=float(np.mean(np.abs(autocorrelation[1:]) > band)),
        q_statistic=q_statistic,
        p_value=p_value,
        confidence=confidence,
        n_samples=int(signal.size),
        white=bool(p_value >= 1.0 - confidence),
    )


def cross_correlation_test(
    residual, u, max_lag: int = 25, confidence: float = 0.99
) -> CrossCorrelationResult:
    """Cross-correlation between a residual and each input, for lags ``-max_lag..max_lag``.

    A residual correlated with past inputs means part of the input's effect on the output
    is missing from the model.

    Parameters
    ----------
    residual : array of shape (n_samples,) or (n_samples, 1)
        Measured minus simulated output; not constant.
    u : array of shape (n_samples, n_inputs) or (n_samples,)
        Inputs over the same samples. Constant columns get NaN and are not tested.
    max_lag : int, default 25
        Largest lag, between 1 and ``n_samples - 1``. The Bartlett factor uses the
        autocorrelations up to this lag too.
    confidence : float, default 0.99
        Confidence level of the band and of the verdict.

    Returns
    -------
    CrossCorrelationResult
    """
    signal = _checked_signal(residual)
    inputs = as_columns(u, "u")
    check_rows("u", inputs, signal.size, "residual")
    max_lag = _checked_lag(max_lag, signal.size)
    confidence = check_confidence(confidence)
    rows = [_input_test(signal, column, max_lag, confidence) for column in inputs.T]
    correlation, band, outside, statistic, p_value = (
        np.array(part) for part in zip(*rows, strict=True)
    )
    tested = np.isfinite(p_value)
    return CrossCorrelationResult(
        lags=read_only(np.arange(-max_lag, max_lag + 1)),
        correlation=read_only(correlation),
        band=read_only(band),
        fraction_outside=read_only(outside),
        statistic=read_only(statistic),
        p_value=read_only(p_value),
        confidence=confidence,
        n_samples=int(signal.size),
        independent=bool(np.all(p_value[tested] >= 1.0 - confidence)),
    )


def correlated_inputs(residual, u, max_lag: int = 25, confidence: float = 0.99) -> tuple[int, ...]:
    """Indices of the inputs that some column of ``residual`` correlates with.

    [`cross_correlation_test`][sk_offwhite.diagnose.cross_correlation_test] on each column (an
    output's residual, shape ``(n_samples, n_outputs)`` or ``(n_samples,)``): an input is named when
    its ``p_value`` is below ``1 - confidence`` for one of them. A column that is not finite
    or is constant names none (there is nothing to test). A missing effect that acts
    through an input's history (an actuator's lag) leaves such a correlation; a residual
    independent of every input says the input reaches the model as it should.
    """
    columns = np.asarray(residual, float).reshape(len(residual), -1)
    named: set[int] = set()
    for column in columns.T:
        if not (np.all(np.isfinite(column)) and np.ptp(column) > 0):
            continue
        result = cross_correlation_test(column, u, max_lag, confidence)
        named |= {int(j) for j in np.flatnonzero(result.p_value < 1.0 - confidence)}
    return tuple(sorted(named))


def lagging_outputs(
    residual, outputs, confidence: float = 0.99, max_lag: int = 25
) -> tuple[int, ...]:
    r"""Indices of the outputs whose measurement lags the model: the residual runs against
    the simulated output's rate.

    A reading $s$ that follows the output $y$ through a lag of time constant
    $\tau$ differs from it by $s - y \approx -\tau \dot y$, so the residual
    $\varepsilon = z - \hat y$ and the rate $\dot{\hat y}$ (central
    differences) are negatively correlated at lag 0. An output is named when that
    correlation $r_0$ lies below $-z_c \sqrt{P/N}$, one-sided at
    ``confidence`` $c$, with the Bartlett factor $P$ of
    [`cross_correlation_test`][sk_offwhite.diagnose.cross_correlation_test] over ``max_lag`` lags
    (both signals are coloured). A column that is not finite or is constant names none.

    Parameters
    ----------
    residual, outputs : array of shape (n_samples, n_outputs) or (n_samples,)
        Measured minus simulated output, and the simulated output.
    confidence : float, default 0.99
    max_lag : int, default 25
        Lags of the autocorrelations in the Bartlett factor (at most the record's length
        less one).
    """
    residuals = np.asarray(residual, float).reshape(len(residual), -1)
    simulated = np.asarray(outputs, float).reshape(len(outputs), -1)
    check_rows("outputs", simulated, len(residuals), "residual")
    confidence = check_confidence(confidence)
    named = []
    for j, (column, output) in enumerate(zip(residuals.T, simulated.T, strict=True)):
        if column.size < 3:
            continue
        rate = np.gradient(output)
        usable = np.all(np.isfinite(column)) and np.all(np.isfinite(rate))
        if not (usable and np.ptp(column) > 0 and not is_constant(rate)):
            continue
        lags = _checked_lag(min(max_lag, column.size - 1), column.size)
        r0 = float(_cross_correlation(column, rate, 0)[0])
        standard_error = np.sqrt(_bartlett_factor(column, rate, lags) / column.size)
        if r0 < -norm.ppf(confidence) * standard_error:
            named.append(j)
    return tuple(named)


def _checked_signal(residual) -> np.ndarray:
    signal = as_signal(residual, "residual")
    if is_constant(signal):
        raise ValueError("residual is constant, so its correlations are undefined.")
    return signal


def _checked_lag(max_lag, n_samples: int) -> int:
    why = "lags must be shorter than the record"
    return check_integer(max_lag, "max_lag", 1, n_samples - 1, why)


def _white_band(confidence: float, n_samples: int) -> float:
    """Half-width $z_{(1+c)/2}/\\sqrt N$ of the white-noise band."""
    return float(norm.ppf(0.5 + confidence / 2.0) / np.sqrt(n_samples))


def _lagged_products(first: np.ndarray, second: np.ndarray, max_lag: int) -> np.ndarray:
    """$\\sum_k a_{k+\\tau} b_k$ for $\\tau = -L, \\dots, L$, by zero-padded FFT."""
    size = fft.next_fast_len(2 * first.size - 1, real=True)
    spectrum = fft.rfft(first, size) * np.conj(fft.rfft(second, size))
    circular = fft.irfft(spectrum, size)
    return np.concatenate([circular[size - max_lag :], circular[: max_lag + 1]])


def _autocorrelation(signal: np.ndarray, max_lag: int) -> np.ndarray:
    centred = signal - signal.mean()
    products = _lagged_products(centred, centred, max_lag)[max_lag:]
    return products / (centred @ centred)


def _cross_correlation(residual: np.ndarray, column: np.ndarray, max_lag: int) -> np.ndarray:
    centred_residual = residual - residual.mean()
    centred_input = column - column.mean()
    scale = np.sqrt((centred_residual @ centred_residual) * (centred_input @ centred_input))
    return _lagged_products(centred_residual, centred_input, max_lag) / scale


def _ljung_box(autocorrelation: np.ndarray, n_samples: int) -> tuple[float, float]:
    lags = np.arange(1, autocorrelation.size)
    terms = autocorrelation[1:] ** 2 / (n_samples - lags)
    q_statistic = float(n_samples * (n_samples + 2) * terms.sum())
    return q_statistic, float(chi2.sf(q_statistic, lags.size))


def _bartlett_factor(residual: np.ndarray, column: np.ndarray, max_lag: int) -> float:
    """$P = \\max(1, 1 + 2\\sum_{k=1}^{L} r_\\varepsilon(k) r_u(k))$."""
    products = _autocorrelation(residual, max_lag)[1:] @ _autocorrelation(column, max_lag)[1:]
    return max(1.0, 1.0 + 2.0 * float(products))


def _input_test(residual: np.ndarray, column: np.ndarray, max_lag: int, confidence: float):
    """Correlation, band, fraction outside, statistic and p-value for one input column."""
    n_lags = 2 * max_lag + 1
    if is_constant(column):
        return np.full(n_lags, np.nan), np.nan, np.nan, np.nan, np.nan
    correlation = _cross_correlation(residual, column, max_lag)
    standard_error = np.sqrt(_bartlett_factor(residual, column, max_lag) / residual.size)
    band = float(norm.ppf(0.5 + confidence / 2.0) * standard_error)
    statistic = float(np.max(np.abs(correlation)) / standard_error)
    p_value = min(1.0, n_lags * 2.0 * float(norm.sf(statistic)))
    return correlation, band, float(np.mean(np.abs(correlation) > band)), statistic, p_value
