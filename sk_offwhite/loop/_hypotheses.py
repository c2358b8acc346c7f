r"""From the evidence of the dictionary terms to named hypotheses about the missing physics.

[`evidence_hypotheses`][sk_offwhite.loop.evidence_hypotheses] reads the hypotheses off the
physics-only fit: each term's projected gain (`TermEvidence`, the part of the residual it
explains that no re-adjustment of the declared parameters can), so a term that only
re-parametrises the physics (a linear spring in a linear oscillator) carries no weight.
Terms that add at least ``min_share`` of the strongest gain beyond the stronger terms
(matching pursuit) make up one hypothesis per equation, its
correction $\hat\delta_i = \hat\Omega_{ij}\varphi_j$ taken from the equation's
strongest term.

[`form_hypotheses`][sk_offwhite.loop.form_hypotheses] reads them off a fitted sparse correction
instead: for a correction $\delta_i = \sum_j \Omega_{ij}\varphi_j$ of state equation $i$,
each selected term is ranked by its contribution along the simulated trajectory,
$c_{ij} = \mathrm{RMS}_k(\Omega_{ij}\varphi_j(\hat x_k, u_k))$, with share
$c_{ij}^2 / \sum_{j'} c_{ij'}^2$.

Either way, the variables of the dominant terms, the sign of
$\sum_k \delta_{i,k} \hat x_{i,k}$ (``-1``: the correction drives $x_i$ toward
zero, i.e. removes from a level) and the range of a variable where $|\delta_i|$
concentrates ([`residual_regions`][sk_offwhite.diagnose.residual_regions] applied to
$\delta_i$) make up one hypothesis per corrected equation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace

import jax
import numpy as np

from ..diagnose import residual_regions
from ..effects._hidden import n_declared_states

__all__ = ["Hypothesis", "Term", "evidence_hypotheses", "form_hypotheses", "rank_terms"]


@dataclass(frozen=True)
class Term:
    """One selected dictionary term of one corrected equation."""

    equation: str
    feature: str
    coefficient: float
    contribution: float
    share: float
    variables: tuple[str, ...]
    column: int = -1


@dataclass(frozen=True)
class Hypothesis:
    """What the correction of one state equation says is missing."""

    equation: str
    equation_index: int
    variables: tuple[str, ...]
    sign: int
    region: tuple[str, float, float] | None
    terms: tuple[Term, ...] = field(default=())
    sentence: str = ""
    correction: np.ndarray | None = field(default=None, compare=False, repr=False)
    gain: float = 0.0
    source: str = "evidence"


def feature_variables(feature: str, names: tuple[str, ...]) -> tuple[str, ...]:
    """Names of the variables a feature name mentions (whole-word matches), in order."""
    return tuple(n for n in names if re.search(rf"(?<![\w]){re.escape(n)}(?![\w])", feature))


def _basis_values(est, run, u) -> np.ndarray:
    """The dictionary ``φ_j`` along the trajectory, shape (n, n_delta, m)."""
    from .._basis import evaluate_matrix

    basis, _ = est._compile(est.physics_)
    v = _dictionary_signals(est, run, u)
    with jax.enable_x64(True):
        return np.asarray(evaluate_matrix(basis, est.inner_params_, v))


def _features(est, run, u) -> np.ndarray:
    """Per-term contributions ``Ω_ij φ_j`` along the trajectory, shape (n, n_delta, m)."""
    return _basis_values(est, run, u) * est.coef_[None]


def rank_terms(est, run, u) -> list[list[Term]]:
    """Selected terms of each corrected equation, largest contribution first."""
    contributions = _features(est, run, u)
    names = _variable_names(est)
    ranked = []
    for row, state in enumerate(est.delta_states_):
        rms = np.sqrt(np.mean(contributions[:, row, :] ** 2, axis=0))
        total = max(float(np.sum(rms**2)), 1e-300)
        terms = [
            Term(
                est.physics_.state_names[state],
                est.feature_names_[j],
                float(est.coef_[row, j]),
                float(rms[j]),
                float(rms[j] ** 2 / total),
                feature_variables(est.feature_names_[j], names),
                int(j),
            )
            for j in np.flatnonzero(est.support_[row])
        ]
        ranked.append(sorted(terms, key=lambda t: -t.contribution))
    return ranked


def _dominant_variables(terms: list[Term], share: float = 0.9) -> tuple[str, ...]:
    """Variables of the fewest terms that hold ``share`` of the contribution."""
    variables, held = [], 0.0
    for term in terms:
        variables.extend(v for v in term.variables if v not in variables)
        held += term.share
        if held >= share:
            break
    return tuple(variables)


def _verb(sign: int, equation: str, one_signed: bool) -> str:
    if one_signed:
        return f"{'removes' if sign < 0 else 'adds'} {equation}"
    return f"drives {equation} {'toward' if sign < 0 else 'away from'} zero"


def _sentence(equation, variables, sign, region, one_signed=True) -> str:
    text = f"The {equation} equation lacks a term in {', '.join(variables) or 'a constant'}"
    text += f" that {_verb(sign, equation, one_signed)}"
    if region is not None:
        name, low, high = region
        if np.isfinite(low) and not np.isfinite(high):
            text += f", acting mainly when {name} is above {low:.3g}"
        elif np.isfinite(high) and not np.isfinite(low):
            text += f", acting mainly when {name} is below {high:.3g}"
        else:
            text += f", acting mainly when {name} is in [{low:.3g}, {high:.3g}]"
    return text + "."


def _agreement(weight: np.ndarray) -> float:
    """How much of its absolute weight the net weight keeps, in [0, 1] (0 for no weight)."""
    total = np.sum(np.abs(weight))
    return float(abs(np.sum(weight)) / total) if total > 0 else 0.0


def _sign(delta: np.ndarray, state: np.ndarray, signals: dict, region) -> int:
    r"""Sign of $\sum_k \delta_k x_k$ over the samples that agree most on it: those of
    the region where the correction acts, if any, unless the whole record's net weight is
    a larger share of its absolute weight $\sum_k|\delta_k x_k|$ (`_agreement`).

    ``-1``: the correction drives the state toward zero (for a level: removes from it);
    ``+1``: away from zero. Where the terms of both signs cancel, the net is left to
    rounding: on the noise-free vehicle the region keeps 15 % of its weight and its sign
    flipped with XLA's threading options, while the record keeps 68 %.
    """
    weight = delta * state
    if region is not None:
        name, low, high = region
        inside = weight[(signals[name] >= low) & (signals[name] <= high)]
        if inside.size and _agreement(inside) >= _agreement(weight):
            weight = inside
    return int(np.sign(np.sum(weight)) or 1)


def _hypothesis(state, equation, terms, delta, run, signals) -> Hypothesis:
    """The hypothesis of one equation from its ranked terms and its correction ``delta``."""
    variables = _dominant_variables(terms)
    names = tuple(signals)
    regions = residual_regions(delta, {v: signals[v] for v in variables or names}, n_shifts=0)
    best = regions[0] if regions and regions[0].rms_ratio >= 1.25 else None
    region = None if best is None else (best.variable, best.low, best.high)
    sign = _sign(delta, run.states[:, state], signals, region)
    one_signed = bool(np.all(run.states[:, state] >= 0) or np.all(run.states[:, state] <= 0))
    sentence = _sentence(equation, variables, sign, region, one_signed)
    return Hypothesis(
        equation, state, variables, sign, region, tuple(terms), sentence, correction=delta
    )


def _variable_names(est) -> tuple[str, ...]:
    """Names of ``v = [x; u]`` the dictionary is evaluated on (the declared states')."""
    declared = est.physics_.state_names[: n_declared_states(est.physics_)]
    return tuple(declared) + tuple(est.physics_.input_names)


def _dictionary_signals(est, run, u) -> np.ndarray:
    """``v = [x; u]`` along ``run``, one row per sample: the declared states and the inputs."""
    return np.hstack([run.states[:, : n_declared_states(est.physics_)], np.asarray(u, float)])


def _signals(est, run, u) -> dict:
    names = _variable_names(est)
    return dict(zip(names, _dictionary_signals(est, run, u).T, strict=True))


def form_hypotheses(est, run, u) -> list[Hypothesis]:
    """One hypothesis per equation whose fitted correction is not zero, strongest first."""
    ranked = rank_terms(est, run, u)
    signals = _signals(est, run, u)
    hypotheses = []
    for row, state in enumerate(est.delta_states_):
        if not ranked[row]:
            continue
        equation = est.physics_.state_names[state]
        hypothesis = _hypothesis(
            state, equation, ranked[row], run.correction[:, state], run, signals
        )
        hypotheses.append(replace(hypothesis, source="sparse δ"))
    return sorted(hypotheses, key=lambda h: -sum(t.contribution**2 for t in h.terms))


def _evidence_terms(est, phi, row, chosen) -> list[Term]:
    """Terms ``chosen`` of correction row ``row``, by conditional gain, shares within the
    equation."""
    gain, estimate = est.term_conditional_gain_[row], est.term_estimate_[row]
    names = _variable_names(est)
    total = float(np.sum(gain[chosen]))
    terms = [
        Term(
            est.physics_.state_names[est.delta_states_[row]],
            est.feature_names_[j],
            float(estimate[j]),
            float(np.sqrt(np.mean((estimate[j] * phi[:, row, j]) ** 2))),
            float(gain[j] / total),
            feature_variables(est.feature_names_[j], names),
            int(j),
        )
        for j in chosen
    ]
    return sorted(terms, key=lambda t: -t.share)


def evidence_hypotheses(est, run, u, *, min_share: float = 0.1) -> list[Hypothesis]:
    """Hypotheses from the projected evidence of a physics-only fit, strongest first.

    Parameters
    ----------
    est : GreyBoxSparseRegressor
        Fitted with a library (``term_gain_`` set), typically with the weights at zero.
    run : Bunch
        ``est.simulate(u)``.
    u : ndarray of shape (n_samples, n_inputs)
    min_share : float, default=0.1
        Terms whose conditional gain (``term_conditional_gain_``: what a term adds beyond
        the stronger ones) is at least this fraction of the largest are evidence.

    Returns
    -------
    list of Hypothesis
        ``gain`` is the largest conditional gain of the equation (the fraction of the
        physics-only cost its strongest term removes); empty when no term has any.
    """
    gain = np.nan_to_num(np.asarray(est.term_conditional_gain_, float))
    top = float(np.max(gain, initial=0.0))
    if top <= 0:
        return []
    phi = _basis_values(est, run, u)
    signals = _signals(est, run, u)
    hypotheses = []
    for row, state in enumerate(est.delta_states_):
        chosen = np.flatnonzero(gain[row] >= min_share * top)
        if chosen.size == 0:
            continue
        terms = _evidence_terms(est, phi, row, chosen)
        strongest = terms[0].column
        delta = est.term_estimate_[row, strongest] * phi[:, row, strongest]
        equation = est.physics_.state_names[state]
        hypothesis = _hypothesis(state, equation, terms, delta, run, signals)
        hypotheses.append(replace(hypothesis, gain=float(gain[row, strongest])))
    return sorted(hypotheses, key=lambda h: -h.gain)
