r"""Theorem 1 of Donati et al.: a computable parametric error bound for a fit.

Lemma 1 and the proof of Theorem 1 differentiate the optimality condition
$\nabla_p C_T(p^*; \eta) = 0$ (implicit function theorem):

$$
\frac{\partial p^*}{\partial \eta} = -H^{-1} G, \qquad
H = \frac{\partial^2 C_T}{\partial p^2}, \qquad
G = \frac{\partial^2 C_T}{\partial \eta\, \partial p},
$$

for three perturbations of the data (see `_ident_derivatives`): input noise
$\eta^u$, output noise $\eta^z$ and the model error
$\tilde\Delta_k = \Delta(x_k, u_k) - \delta(\hat x_k, u_k; \omega)$ acting as an
additive disturbance on the corrected state equations. The rows of $H^{-1}G$ that belong
to the physical parameters $\theta$ give the sensitivities, and their induced norms the
constants of bound (5),

$$
\|\theta^* - \bar\theta\|_q \le M_u \|\eta^u\|_p + M_z \|\eta^z\|_p
    + M_\Delta \|\tilde\Delta\|_p, \qquad
M_\bullet = \big\|[H^{-1}G]_{\theta,\bullet}\big\|_{p \to q}.
$$

What is computed, and how it differs from the paper:

* $H$ and $G$ are taken **at the fitted solution**, not maximised over a noise set
  $\mathcal N$ as in Lemma 1: the bound is the first-order (linearised) estimate of the
  theorem, exact for models linear in the parameters and to first order otherwise.
* The initial state and the black-box weights on the support are re-optimised together with
  $\theta$ (they are rows of $H$); only the $\theta$ rows enter the bound.
  The paper assumes $x_0$ known "for simplicity".
* $M_\Delta$ is the sensitivity to an additive state disturbance whose effect on the
  data is propagated along the fitted model; the paper's $M_\Delta$ is a Lipschitz
  constant of $\theta^*(0, \tilde\Delta)$, of which this is the local value.
* Norms: ``noise_norm`` $p \in \{2, \infty\}$ on the stacked perturbation sequences,
  ``error_norm`` $q \in \{2, \infty\}$ on $\theta$. For $p = q$ and for
  $(2, \infty)$ the induced norm is exact; for $(\infty, 2)$, whose exact value is
  NP-hard, the bound uses $\|A\|_{\infty\to 2} \le \| |A|\,\mathbf 1 \|_2$ (exact per
  parameter: $|(A\eta)_i| \le \sum_j |A_{ij}|\, \|\eta\|_\infty$).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import jax
import numpy as np
from sklearn.utils.validation import check_is_fitted

from ._ident_derivatives import mixed_derivatives
from ._ident_problem import LocalProblem, local_problem
from ._identifiability import (
    UnidentifiableWarning,
    hessian_at_solution,
    relative_inverse,
    variable_scales,
)

__all__ = ["ParameterErrorBound", "induced_norm", "parameter_error_bound"]

_NORMS = (2.0, np.inf)


@dataclass(frozen=True)
class ParameterErrorBound:
    """Sensitivities of Lemma 1 and the bound (5) of Theorem 1 for one fit.

    Attributes
    ----------
    names : tuple of str
        The free physical parameters (rows of the sensitivities).
    sensitivity_u, sensitivity_z, sensitivity_delta : ndarray
        $[H^{-1}G]_\\theta$ for input noise (columns: samples x inputs), output noise
        (samples x outputs) and model error (samples x ``disturbed_states``), in sample-major
        order over the measured samples of every record.
    m_u, m_z, m_delta : float
        Induced norms of the three sensitivities ($M_u, M_z, M_\\Delta$).
    noise_norm, error_norm : float
        $p$ and $q$ (2 or ``inf``).
    noise_u, noise_z, delta_norm : float
        $\\|\\eta^u\\|_p$, $\\|\\eta^z\\|_p$, $\\|\\tilde\\Delta\\|_p$ given.
    disturbed_states : tuple of int
        State equations the model error $\\tilde\\Delta$ acts on.
    identifiable : bool
        $H \\succ 0$; otherwise a pseudo-inverse was used and the bound is not valid.
    """

    names: tuple[str, ...]
    sensitivity_u: np.ndarray
    sensitivity_z: np.ndarray
    sensitivity_delta: np.ndarray
    m_u: float
    m_z: float
    m_delta: float
    noise_norm: float
    error_norm: float
    noise_u: float
    noise_z: float
    delta_norm: float
    disturbed_states: tuple[int, ...]
    identifiable: bool

    @property
    def bound(self) -> float:
        """$M_u\\|\\eta^u\\| + M_z\\|\\eta^z\\| + M_\\Delta\\|\\tilde\\Delta\\|$ (eq. 5)."""
        return self.evaluate(self.noise_u, self.noise_z, self.delta_norm)

    def evaluate(self, noise_u: float = 0.0, noise_z: float = 0.0, delta_norm: float = 0.0):
        """Bound (5) for other perturbation sizes, same fit (norms as ``noise_norm``)."""
        sizes = _check_sizes(noise_u, noise_z, delta_norm)
        return float(np.dot((self.m_u, self.m_z, self.m_delta), sizes))

    def summary(self) -> str:
        """The constants, the perturbation sizes and the bound, one line each."""
        p, q = _norm_label(self.noise_norm), _norm_label(self.error_norm)
        valid = "" if self.identifiable else " (H singular: NOT a valid bound)"
        return "\n".join(
            [
                f"Theorem 1 bound on ||theta* - theta_bar||_{q}{valid}:",
                f"  M_u = {self.m_u:.4g}  x ||eta_u||_{p} = {self.noise_u:.4g}",
                f"  M_z = {self.m_z:.4g}  x ||eta_z||_{p} = {self.noise_z:.4g}",
                f"  M_Delta = {self.m_delta:.4g}  x ||Delta~||_{p} = {self.delta_norm:.4g}",
                f"  bound = {self.bound:.4g}  (parameters: {', '.join(self.names)})",
            ]
        )


def _norm_label(norm: float) -> str:
    return "inf" if np.isinf(norm) else "2"


def _check_norm(name: str, norm) -> float:
    try:
        value = float(norm)
    except (TypeError, ValueError):
        value = np.nan
    if value not in _NORMS:
        raise ValueError(f"{name} must be 2 or numpy.inf, got {norm!r}.")
    return value


def _check_sizes(noise_u, noise_z, delta_norm) -> np.ndarray:
    sizes = np.array([noise_u, noise_z, delta_norm], dtype=float)
    if not np.all(np.isfinite(sizes)) or np.any(sizes < 0):
        raise ValueError(
            "noise_u, noise_z and delta_norm must be finite and >= 0 (norms of the "
            f"perturbations), got {noise_u!r}, {noise_z!r}, {delta_norm!r}."
        )
    return sizes


def induced_norm(matrix, noise_norm: float = np.inf, error_norm: float = 2.0) -> float:
    r"""Operator norm $\|A\|_{p\to q}$ (an upper bound for $p=\infty, q=2$).

    ========  ========  =============================================
    ``p``     ``q``     value
    ========  ========  =============================================
    2         2         largest singular value
    2         inf       largest row 2-norm
    inf       inf       largest row 1-norm
    inf       2         $\| |A|\mathbf 1\|_2$ (upper bound)
    ========  ========  =============================================
    """
    p, q = _check_norm("noise_norm", noise_norm), _check_norm("error_norm", error_norm)
    matrix = np.atleast_2d(np.asarray(matrix, float))
    if matrix.size == 0:
        return 0.0
    if p == 2.0:
        rows = np.linalg.norm(matrix, axis=1)
        return float(np.linalg.norm(matrix, 2) if q == 2.0 else rows.max())
    sums = np.abs(matrix).sum(axis=1)
    return float(np.linalg.norm(sums) if q == 2.0 else sums.max())


def _columns(mixed, mask, select=None) -> np.ndarray:
    """``(n_segments, length, n, P)`` -> ``(P, n_columns)`` over the measured samples."""
    values = np.asarray(mixed)[np.asarray(mask, bool)]
    if select is not None:
        values = values[:, list(select)]
    return values.reshape(-1, values.shape[-1]).T


def _disturbed_states(estimator, states) -> tuple[int, ...]:
    n_states = estimator.physics_.n_states
    if states is None:
        states = estimator.delta_states_ or range(n_states)
    states = tuple(int(i) for i in np.atleast_1d(states))
    if not states or not all(0 <= i < n_states for i in states):
        raise ValueError(f"disturbed_states must be indices in [0, {n_states}), got {states}.")
    return states


def sensitivities(local: LocalProblem, states, rtol) -> tuple[list[np.ndarray], bool]:
    r"""Rows $\theta$ of $H^{-1}G$ for inputs, outputs and model error."""
    _, _, hessian = hessian_at_solution(local)
    inverse, flat, _ = relative_inverse(hessian, variable_scales(local.values), rtol)
    mixed = mixed_derivatives(local.values, local.problem, model=local.model, layout=local.layout)
    mask = local.problem.segments.mask
    blocks = [_columns(mixed.inputs, mask), _columns(mixed.outputs, mask)]
    blocks.append(_columns(mixed.states, mask, states))
    rows = np.flatnonzero(np.asarray(local.kinds) == "theta")
    return [(inverse @ block)[rows] for block in blocks], flat.size == 0


def parameter_error_bound(
    estimator,
    u,
    z,
    *,
    noise_u: float = 0.0,
    noise_z: float = 0.0,
    delta_norm: float = 0.0,
    noise_norm: float = np.inf,
    error_norm: float = 2.0,
    disturbed_states=None,
    sample_index=None,
    include_omega: bool = True,
    rtol: float = 1e-9,
) -> ParameterErrorBound:
    r"""Constants $M_u, M_z, M_\Delta$ of Theorem 1 and the bound (5) for a fit.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        A fitted estimator.
    u, z : array-like or list of arrays
        The data it was fitted on.
    noise_u, noise_z, delta_norm : float, default=0.0
        $\|\eta^u\|_p$, $\|\eta^z\|_p$ and $\|\tilde\Delta\|_p$ (for
        ``noise_norm=inf``: the largest absolute input noise, output noise and model error
        over all samples).
        [`ParameterErrorBound.evaluate`][sk_offwhite.certify.ParameterErrorBound.evaluate]
        re-evaluates for other sizes.
    noise_norm : {inf, 2}, default=inf
        $p$, the norm of the perturbation sequences (the paper's figures use inf).
    error_norm : {2, inf}, default=2
        $q$, the norm of the parameter error $\theta^* - \bar\theta$.
    disturbed_states : sequence of int, default=None
        State equations $\tilde\Delta$ acts on; ``None``: the estimator's
        ``delta_states_`` (all states for a physics-only fit).
    sample_index : array-like, default=None
        As for ``fit``.
    include_omega : bool, default=True
        Re-optimise the weights on the fitted support with $\theta$ (see module notes).
    rtol : float, default=1e-9
        Relative eigenvalue tolerance for $H \succ 0$ (as
        [`identifiability`][sk_offwhite.certify.identifiability]).

    Returns
    -------
    ParameterErrorBound
        ``.bound``, ``.m_u``, ``.m_z``, ``.m_delta``, ``.summary()``.
    """
    p, q = _check_norm("noise_norm", noise_norm), _check_norm("error_norm", error_norm)
    check_is_fitted(estimator)
    sizes = _check_sizes(noise_u, noise_z, delta_norm)
    states = _disturbed_states(estimator, disturbed_states)
    with jax.enable_x64(True):
        local = local_problem(estimator, u, z, sample_index, include_omega)
        if "theta" not in local.kinds:
            raise ValueError("the estimator has no free physical parameter to bound.")
        blocks, regular = sensitivities(local, states, rtol)
    if not regular:
        warnings.warn(
            "H is singular (Assumption 1 fails): the sensitivities use a pseudo-inverse and "
            "the bound does not hold along the unidentifiable directions; see identifiability().",
            UnidentifiableWarning,
            stacklevel=2,
        )
    constants = [induced_norm(block, p, q) for block in blocks]
    names = tuple(n for n, k in zip(local.names, local.kinds, strict=True) if k == "theta")
    return ParameterErrorBound(names, *blocks, *constants, p, q, *sizes.tolist(), states, regular)
