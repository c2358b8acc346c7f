r"""Where the residual lives: ranges of a variable in which the model error concentrates.

For a named variable $v$ (a simulated state, an input, the simulated output) the
samples are cut into quantile bins of $v$, so each bin holds about the same number of
samples. For a contiguous run of bins $R$ (not all of them) let

$$
S(R) = \frac{\sum_{k: v_k \in R} \varepsilon_k^2}{\sum_k \varepsilon_k^2}, \qquad
F(R) = \frac{\#\{k: v_k \in R\}}{N}
$$

be its share of the squared residual and of the samples. The region reported is the run
that maximises the *concentration* $S(R) - F(R)$: it gathers exactly the bins whose
mean squared residual is above the overall one, as long as they are contiguous. A residual
spread evenly over $v$ has a concentration near 0; one living only in a small range
has a concentration near 1.

Binning always finds *some* run with a positive concentration, so each region gets a
p-value from circular time shifts: the variable is shifted against the residual by ``s``
samples (wrapping around), which keeps the time structure of each but breaks their
alignment, and the best concentration is found again. With ``m`` evenly spaced shifts,
$p = (1 + \#\{\text{shifted} \ge \text{observed}\}) / (1 + m)$.

The residual is $\varepsilon = z - \hat z$ (measured minus simulated), so a
positive mean in the region means the model under-predicts there.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ._arrays import as_signal, check_integer, check_rows, read_only

__all__ = ["ResidualRegion", "residual_regions"]

_LARGE_RATIO = 2.0  # region RMS at least this multiple of the RMS elsewhere: "large only"
_NOTABLE_RATIO = 1.25  # at least this multiple: "somewhat larger"
_BIASED_MEAN = 0.5  # |mean| at least this fraction of the region's RMS: a consistent sign
_SIGNIFICANCE = 0.05  # largest circular-shift p-value of a reported region
_MAX_SHIFT_CORRELATION = 0.5  # shifts that leave the labels this correlated are no null
_MIN_SHIFTS = 19  # fewer usable shifts cannot reach p = 0.05: the p-value is NaN


@dataclass(frozen=True)
class ResidualRegion:
    """The range of one variable where the residual concentrates.

    Attributes
    ----------
    variable : str
    bin_edges : array of shape (n_bins + 1,)
        Quantile bin edges; bins are closed on the left, the last one on both sides.
    bin_count, bin_mean, bin_rms : arrays of shape (n_bins,)
        Samples, mean residual and RMS residual in each bin.
    low, high : float
        The region's range of the variable; ``-inf`` / ``inf`` when it reaches the lowest /
        highest bin (the region is "below high" / "above low").
    error_share, sample_share : float
        $S$ and $F$: the region's shares of the squared residual and of the
        samples.
    concentration : float
        $S - F$, in ``[0, 1)``; results are sorted by it.
    rms_inside, rms_outside, mean_inside : float
        RMS residual in and out of the region, and the mean residual in it.
    rms_ratio : float
        ``rms_inside / rms_outside`` (``inf`` when the residual is zero elsewhere).
    p_value : float
        Circular-shift p-value of ``concentration`` (NaN with ``n_shifts=0``).
    notable : bool
        ``rms_ratio >= 1.25`` and ``p_value <= 0.05`` (or NaN): worth reporting.
    sentence : str
        The finding in words.
    """

    variable: str
    bin_edges: np.ndarray
    bin_count: np.ndarray
    bin_mean: np.ndarray
    bin_rms: np.ndarray
    low: float
    high: float
    error_share: float
    sample_share: float
    concentration: float
    rms_inside: float
    rms_outside: float
    mean_inside: float
    rms_ratio: float
    p_value: float
    notable: bool
    sentence: str = ""


class _BinStats(NamedTuple):
    count: np.ndarray
    mean: np.ndarray
    rms: np.ndarray
    squared_sum: np.ndarray


def residual_regions(
    residual,
    variables: Mapping[str, np.ndarray],
    n_bins: int = 10,
    min_count: int = 10,
    *,
    n_shifts: int = 99,
) -> list[ResidualRegion]:
    """For each variable, the range in which the residual is concentrated.

    Parameters
    ----------
    residual : array of shape (n_samples,) or (n_samples, 1)
        Measured minus simulated output.
    variables : mapping of str to array of shape (n_samples,)
        The variables to bin the residual by, e.g. ``{"x1 (simulated)": x_sim[:, 0]}``.
    n_bins : int, default 10
        Number of quantile bins, at least 2; fewer are used when a bin would hold fewer than
        ``min_count`` samples or when tied values make quantiles coincide.
    min_count : int, default 10
        Fewest samples in a bin; smaller bins are merged into a neighbour.
    n_shifts : int, default 99
        Circular time shifts tried for each region's p-value; shifts that barely move the
        variable are dropped, and with fewer than 19 left (or ``n_shifts=0``) the p-value is
        NaN.

    Returns
    -------
    list of ResidualRegion
        One per variable that can be cut into at least two bins, most concentrated first.
        Empty when the residual is zero everywhere.
    """
    signal = as_signal(residual, "residual")
    n_bins = check_integer(n_bins, "n_bins", 2, signal.size)
    min_count = check_integer(min_count, "min_count", 1, signal.size)
    n_shifts = check_integer(n_shifts, "n_shifts", 0, 100_000)
    columns = _checked_variables(variables, signal.size)
    if not np.any(signal):
        return []
    found = (
        _region(name, signal, values, n_bins, min_count, n_shifts)
        for name, values in columns.items()
    )
    return sorted((r for r in found if r is not None), key=lambda r: -r.concentration)


def _checked_variables(variables, n_samples: int) -> dict[str, np.ndarray]:
    if not isinstance(variables, Mapping):
        raise TypeError(f"variables must be a mapping name -> array, got {type(variables)}.")
    columns = {}
    for name, values in variables.items():
        if not isinstance(name, str):
            raise TypeError(f"variables keys must be strings, got {name!r}.")
        label = f"variables[{name!r}]"
        columns[name] = as_signal(values, label)
        check_rows(label, columns[name].reshape(-1, 1), n_samples, "residual")
    return columns


def _region(name, residual, values, n_bins, min_count, n_shifts) -> ResidualRegion | None:
    edges = _bin_edges(values, n_bins, min_count)
    if edges.size < 3:
        return None
    index = _bin_index(values, edges)
    stats = _bin_stats(residual, index, edges.size - 1)
    first, last, concentration = _best_run(stats.squared_sum, stats.count)
    p_value = _shift_p_value(residual**2, index, stats.count, concentration, n_shifts)
    inside = (first <= index) & (index <= last)
    bounds = _run_bounds(edges, first, last)
    region = _build_region(name, residual, inside, edges, stats, bounds, p_value)
    return dataclasses.replace(region, sentence=describe_region(region))


def _run_bounds(edges: np.ndarray, first: int, last: int) -> tuple[float, float]:
    """Range of bins ``first..last``, open (infinite) where it reaches an end bin."""
    low = edges[first] if first > 0 else -np.inf
    high = edges[last + 1] if last < edges.size - 2 else np.inf
    return float(low), float(high)


def _bin_edges(values: np.ndarray, n_bins: int, min_count: int) -> np.ndarray:
    n_bins = min(n_bins, values.size // min_count)
    if n_bins < 2:
        return np.array([values.min(), values.max()])
    edges = np.unique(np.quantile(values, np.linspace(0.0, 1.0, n_bins + 1)))
    return _merge_small_bins(edges, values, min_count)


def _bin_index(values: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Bin of each value: ``i`` for ``edges[i] <= v < edges[i + 1]``, the last bin closed."""
    return np.searchsorted(edges[1:-1], values, side="right")


def _merge_small_bins(edges: np.ndarray, values: np.ndarray, min_count: int) -> np.ndarray:
    """Drop interior edges until every bin holds at least ``min_count`` samples."""
    while edges.size > 2:
        counts = np.bincount(_bin_index(values, edges), minlength=edges.size - 1)
        smallest = int(np.argmin(counts))
        if counts[smallest] >= min_count:
            break
        edges = np.delete(edges, _edge_to_drop(counts, smallest))
    return edges


def _edge_to_drop(counts: np.ndarray, small_bin: int) -> int:
    """Interior edge shared by ``small_bin`` and its smaller neighbour."""
    if small_bin == 0:
        return 1
    if small_bin == counts.size - 1:
        return small_bin
    return small_bin if counts[small_bin - 1] <= counts[small_bin + 1] else small_bin + 1


def _bin_stats(residual: np.ndarray, index: np.ndarray, n_bins: int) -> _BinStats:
    count = np.bincount(index, minlength=n_bins)
    total = np.bincount(index, weights=residual, minlength=n_bins)
    squared_sum = np.bincount(index, weights=residual**2, minlength=n_bins)
    return _BinStats(count, total / count, np.sqrt(squared_sum / count), squared_sum)


def _best_run(squared_sum: np.ndarray, count: np.ndarray) -> tuple[int, int, float]:
    """Bins ``first..last`` (not all) maximising error share minus sample share, and it."""
    error_before = np.concatenate([[0.0], np.cumsum(squared_sum)]) / squared_sum.sum()
    samples_before = np.concatenate([[0.0], np.cumsum(count)]) / count.sum()
    excess = error_before[None, 1:] - error_before[:-1, None]
    excess -= samples_before[None, 1:] - samples_before[:-1, None]
    first, last = np.indices(excess.shape)
    excess[(last < first) | ((first == 0) & (last == count.size - 1))] = -np.inf
    best_first, best_last = np.unravel_index(np.argmax(excess), excess.shape)
    return int(best_first), int(best_last), float(excess[best_first, best_last])


def _shift_p_value(squared, index, count, observed: float, n_shifts: int) -> float:
    """Share of circular shifts of the bin labels whose best run is as concentrated."""
    shifts = _null_shifts(index, n_shifts)
    if shifts.size < _MIN_SHIFTS:
        return float("nan")
    shifted = [
        _best_run(np.bincount(np.roll(index, shift), weights=squared, minlength=count.size), count)
        for shift in shifts
    ]
    as_large = sum(run[2] >= observed - 1e-12 for run in shifted)
    return (1.0 + as_large) / (1.0 + shifts.size)


def _null_shifts(index: np.ndarray, n_shifts: int) -> np.ndarray:
    """Evenly spaced circular shifts (5% to 95% of the record) that really move the labels.

    A shift near a period of a periodic variable, or a tiny one of a slow variable, barely
    changes the bin labels and is no null sample; shifts whose circular autocorrelation of
    the labels is 0.5 or more in magnitude are dropped.
    """
    n_samples = index.size
    shifts = np.unique((np.linspace(0.05, 0.95, n_shifts) * n_samples).astype(int))
    shifts = shifts[(shifts > 0) & (shifts < n_samples)]
    centred = index - index.mean()
    circular = np.fft.irfft(np.abs(np.fft.rfft(centred)) ** 2, n_samples) / (centred @ centred)
    return shifts[np.abs(circular[shifts]) < _MAX_SHIFT_CORRELATION]


def _build_region(name, residual, inside, edges, stats, bounds, p_value) -> ResidualRegion:
    error_share = float(residual[inside] @ residual[inside] / (residual @ residual))
    sample_share = float(inside.mean())
    rms_inside = float(np.sqrt(np.mean(residual[inside] ** 2)))
    rms_outside = float(np.sqrt(np.mean(residual[~inside] ** 2)))
    rms_ratio = rms_inside / rms_outside if rms_outside > 0.0 else np.inf
    return ResidualRegion(
        variable=name,
        bin_edges=read_only(edges),
        bin_count=read_only(stats.count),
        bin_mean=read_only(stats.mean),
        bin_rms=read_only(stats.rms),
        low=bounds[0],
        high=bounds[1],
        error_share=error_share,
        sample_share=sample_share,
        concentration=error_share - sample_share,
        rms_inside=rms_inside,
        rms_outside=rms_outside,
        mean_inside=float(residual[inside].mean()),
        rms_ratio=rms_ratio,
        p_value=p_value,
        notable=bool(rms_ratio >= _NOTABLE_RATIO and not p_value > _SIGNIFICANCE),
    )


def describe_region(region: ResidualRegion) -> str:
    """The finding in words, e.g. "the residual is large only when x1 is above 8.7: ..."."""
    where = f"{region.variable} is {_range_phrase(region.low, region.high)}"
    contrast = f"RMS {region.rms_inside:.3g} vs {region.rms_outside:.3g} elsewhere"
    shares = (
        f"{region.error_share:.0%} of the squared error in {region.sample_share:.0%} of the samples"
    )
    sign = _sign_phrase(region.mean_inside, region.rms_inside)
    if region.p_value > _SIGNIFICANCE:
        sign += f"; this may be chance (time-shift p = {region.p_value:.2g})"
    if region.rms_ratio >= _LARGE_RATIO:
        return f"the residual is large only when {where}: {contrast} ({shares}); {sign}"
    if region.rms_ratio >= _NOTABLE_RATIO:
        return f"the residual is somewhat larger when {where}: {contrast} ({shares}); {sign}"
    return (
        f"the residual is spread evenly over {region.variable} (largest contrast: RMS "
        f"{region.rms_inside:.3g} when {where} vs {region.rms_outside:.3g} elsewhere)"
    )


def _range_phrase(low: float, high: float) -> str:
    if np.isinf(low):
        return f"below {high:.3g}"
    if np.isinf(high):
        return f"above {low:.3g}"
    return f"between {low:.3g} and {high:.3g}"


def _sign_phrase(mean_inside: float, rms_inside: float) -> str:
    if abs(mean_inside) < _BIASED_MEAN * rms_inside:
        return f"there it has no consistent sign (mean residual {mean_inside:+.3g})"
    direction = "under-predicts" if mean_inside > 0.0 else "over-predicts"
    return f"there the model {direction} (mean residual {mean_inside:+.3g})"
