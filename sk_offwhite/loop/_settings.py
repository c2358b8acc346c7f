r"""The loop's settings, checked when they are made.

Every setting is validated at construction against a declarative table, so that a wrong
value is refused at once, with its name and what it must be, before any fit starts.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from numbers import Integral, Real

import numpy as np
from sklearn.utils._param_validation import (
    Interval,
    InvalidParameterError,
    StrOptions,
    validate_parameter_constraints,
)

from ..solvers._rules import LM_SCALINGS

__all__ = ["LoopSettings"]

_COUNT = "count"  # an integer that must not be a boolean


def _count(low: int | None, high: int | None = None) -> list:
    return [Interval(Integral, low, high, closed="both" if high is not None else "left")]


CONSTRAINTS: dict[str, list] = {
    "gammas": ["array-like", None],
    "n_gammas": _count(1),
    "gamma_eps": [Interval(Real, 0, 1, closed="neither")],
    "n_folds": _count(2),
    "horizon": [*_count(1), None],
    "cv_horizon": [*_count(1), None],
    "max_iter": _count(1),
    "max_effects": _count(0),
    "min_gain": [Interval(Real, 0, 1, closed="left")],
    "tolerance": [Interval(Real, 0, None, closed="left")],
    "delta_states": ["array-like", None],
    "init_window": _count(0),
    "max_candidates": [*_count(1), None],
    "beam": _count(1),
    "fit_top": [*_count(1), None],
    "n_pairs": _count(0),
    "min_share": [Interval(Real, 0, 1, closed="both")],
    "n_promoted": _count(0),
    "fit_delta": ["boolean"],
    "share_programs": ["boolean"],
    "selection": [StrOptions({"cv", "tail"})],
    "tail_fraction": [Interval(Real, 0, 1, closed="neither")],
    "n_jobs": [Integral, None],
    "lm_scaling": [StrOptions(set(LM_SCALINGS))],
    "one_standard_error": ["boolean"],
    "release_programs": ["boolean"],
    "fit_output_delta": ["boolean"],
    "output_bumps": _count(2),
    "kind_notes": ["boolean"],
}
"""What each field of [`LoopSettings`][sk_offwhite.loop.LoopSettings] may hold (scikit-learn's
parameter constraints)."""


@dataclass(frozen=True)
class LoopSettings:
    r"""Settings of the closed loop ([`close_the_loop`][sk_offwhite.loop.close_the_loop],
    [`EffectSearchCV`][sk_offwhite.loop.EffectSearchCV]), all applied on the estimation record.

    Parameters
    ----------
    gammas : tuple of float, default=None
        The grid of the (dimensionless) $\gamma$ of the fits with a sparse $\delta$; ``None``
        uses ``n_gammas`` values from $\gamma_{max}$ down to ``gamma_eps`` times it
        ([`gamma_grid`][sk_offwhite.gamma_grid]); a single value is fitted without a search.
    n_gammas : int, default=5
    gamma_eps : float, default=1e-6
    n_folds : int, default=3
        Contiguous blocks of the estimation record held out in turn (``selection='cv'``).
    horizon : int, default=128
        The multiple-shooting window of the first stage of every fit on the record (the
        declared physics, each candidate and effect set, the final physics), each refined
        on the whole record; a set with an effect on the output map is fitted on the whole
        record alone.
    cv_horizon : int, default=None
        The window of the fits inside cross-validation (``None``: each training block is
        simulated whole, which is what the held-out blocks are scored on).
    max_iter : int, default=300
        Iterations of every fit.
    max_effects : int, default=3
        The most effects a set holds.
    min_gain : float, default=0.05
        The relative reduction of the cross-validated error an effect set must bring.
    tolerance : float, default=0.02
        The relative slack within which a smaller set is preferred.
    delta_states : tuple of int, default=None
        The state equations the sparse $\delta$ corrects (``None``: every declared one).
    init_window : int, default=50
        Samples that estimate each held-out block's initial state (not scored).
    max_candidates : int, default=None
        How many proposed mechanisms are fitted, in the order they are proposed (strongest
        hypothesis first), each with all its variants; ``None`` fits them all.
    beam : int, default=4
        How many of the best single candidates forward selection combines.
    fit_top : int, default=8
        How many of the candidates a switchboard can scan are fitted alone: the best by the
        error one Gauss-Newton step from their start would reach (`sk_offwhite.loop._scan`);
        candidates the scan cannot judge are always fitted. ``None`` fits every candidate.
    n_pairs : int, default=2
        How many pairs of candidates are fitted jointly besides the single fits: those one
        Gauss-Newton step takes furthest below their better member alone (effects that
        only help together, such as a Coulomb friction and a force offset).
    min_share : float, default=0.1
        The fraction of the strongest term's gain a term needs to be evidence.
    n_promoted : int, default=3
        How many of the strongest dictionary terms are proposed as they are.
    fit_delta : bool, default=True
        Whether the models with a sparse $\delta$ are fitted (they show what is left).
    share_programs : bool, default=False
        Whether every effect set is fitted on one compiled program (a switchboard), in
        this process (each worker would compile it again), rather than on a model of its
        own, its fits and folds spread over ``n_jobs`` processes. Sharing pays where the
        fits are mostly compilation (short records); on long records, where they are
        mostly simulation, the workers pay.
    selection : {'cv', 'tail'}, default='cv'
        How every choice is scored: ``'cv'``, the mean held-out error over ``n_folds``
        contiguous blocks; ``'tail'``, the held-out error of the last ``tail_fraction`` of
        the record when the rest is fitted (fitted on the past, run into the future).
    tail_fraction : float, default=0.25
    n_jobs : int, default=None
        Processes that fit the folds, the candidates and the effect sets (joblib's
        convention: ``None`` one, ``-1`` all cores); the numbers are the same as with one.
    lm_scaling : {'per-variable', 'global'}, default='per-variable'
        Every fit's Levenberg-Marquardt scaling
        ([`LevenbergMarquardt`][sk_offwhite.solvers.LevenbergMarquardt]).
    one_standard_error : bool, default=False
        Choose each $\delta$'s $\gamma$ as the largest whose CV error is within one
        standard error of the lowest, instead of the lowest.
    release_programs : bool, default=True
        Drop the package's compiled programs after each stage (the structures fitted there
        are seldom fitted again).
    fit_output_delta : bool, default=True
        With ``fit_delta``, also fit the augmented physics with a sparse correction of its
        output map, where the outputs read states (a sensor's static nonlinearity).
    output_bumps : int, default=7
        Gaussian bumps of each measured state in that correction's dictionary.
    kind_notes : bool, default=True
        Also read, on an evidence fit of its own, the functions a physicist tries first for
        each variable (a velocity's sign and $v|v|$, a level's square root, powers of a
        temperature's excess, the size of a variable that changes sign, a saturation of a
        measured state or an input), and note those that explain more than the
        dictionary's best term and at least ``min_gain`` of the declared physics' cost,
        with what each one's fitted sign says. They inform the reader and change no
        choice; ``False`` skips that fit (a program of its own to compile).
    """

    gammas: tuple[float, ...] | None = None
    n_gammas: int = 5
    gamma_eps: float = 1e-6
    n_folds: int = 3
    horizon: int | None = 128
    cv_horizon: int | None = None
    max_iter: int = 300
    max_effects: int = 3
    min_gain: float = 0.05
    tolerance: float = 0.02
    delta_states: tuple[int, ...] | None = None
    init_window: int = 50
    max_candidates: int | None = None
    beam: int = 4
    fit_top: int | None = 8
    n_pairs: int = 2
    min_share: float = 0.1
    n_promoted: int = 3
    fit_delta: bool = True
    share_programs: bool = False
    selection: str = "cv"
    tail_fraction: float = 0.25
    n_jobs: int | None = None
    lm_scaling: str = "per-variable"
    one_standard_error: bool = False
    release_programs: bool = True
    fit_output_delta: bool = True
    output_bumps: int = 7
    kind_notes: bool = True

    def __post_init__(self):
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        validate_parameter_constraints(CONSTRAINTS, values, type(self).__name__)
        _reject_booleans(values)
        _check_grid(self.gammas)
        _check_indices(self.delta_states)
        if self.n_jobs == 0:
            raise InvalidParameterError(
                "The 'n_jobs' parameter of LoopSettings must be None, a positive number of "
                "processes or a negative one (-1: all cores), got 0."
            )

    def replace(self, **changes) -> LoopSettings:
        """A copy with some settings changed (validated again)."""
        return dataclasses.replace(self, **changes)


def _reject_booleans(values: dict) -> None:
    """``True`` passes as the integer 1: a count must not be a boolean."""
    for name, rules in CONSTRAINTS.items():
        counts = any(isinstance(r, Interval) and r.type is Integral for r in rules)
        if counts and isinstance(values[name], bool | np.bool_):
            raise InvalidParameterError(
                f"The {name!r} parameter of LoopSettings must be an integer, got {values[name]!r}."
            )


def _check_grid(gammas) -> None:
    if gammas is None:
        return
    try:
        values = np.asarray(gammas, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        values = None
    if values is None or values.size == 0 or not np.all(np.isfinite(values) & (values >= 0)):
        raise InvalidParameterError(
            f"The 'gammas' parameter of LoopSettings must be None or one or more finite "
            f"numbers >= 0, got {gammas!r}."
        )


def _check_indices(indices) -> None:
    if indices is None:
        return
    values = np.asarray(indices).reshape(-1)
    if values.size and (values.dtype.kind not in "iu" or np.any(values < 0)):
        raise InvalidParameterError(
            f"The 'delta_states' parameter of LoopSettings must be None or state indices "
            f"(integers >= 0), got {indices!r}."
        )
