r"""Local linearisation of a fitted multi-step model, and Theorems 4-5, (15), FPS/SFPS on it.

Around the fit $(\hat\theta, \hat\omega)$ the simulated outputs (the whole record,
from the fitted initial state) are, to first order,

$$
\hat z(\theta, \omega) \approx \hat z + J_\theta(\theta - \hat\theta)
+ J_\omega(\omega - \hat\omega),
$$

with $J_\theta = \partial\hat z/\partial\theta$ and $J_\omega =
\partial\hat z/\partial\omega$ from JAX (forward mode through the ``lax.scan`` rollout, in
float64). The free initial state is a nuisance parameter: its columns join
$J_\theta$. Then $z \approx J_\theta\theta + J_\omega\omega + \eta$ with the
shifted residual

$$
\tilde z_\ell = z - \hat z + J_\theta\hat\theta + J_\omega\hat\omega
$$

(the paper's Theorem 4 prints minus signs on the last two terms; the plus signs follow
from its own linearisation). This is the linear problem of `_relaxation` with
$\Phi_\theta = J_\theta$, $\Phi = J_\omega$, $y = \tilde z_\ell$, so the
relaxation (15), the certificate of Theorem 5 ($\Upsilon_\ell = \Upsilon(J_\theta)$)
and FPS/SFPS hold *locally*, as far as the linearisation does.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np
from sklearn.utils.validation import check_is_fitted

from .._validation import check_pair
from ..model._equations import correction_rows
from ..simulation._rollout import simulate
from ._certificates import SparsityCertificate, certify_problem
from ._estimate import refined_mu, select_estimate
from ._feasible import FeasibleSetBounds, feasible_set_bounds
from ._relaxation import LinearProblem, SparseRelaxation, linear_problem, solve_relaxation

__all__ = [
    "Linearisation",
    "certify_estimator",
    "estimator_feasible_set",
    "linearise_estimator",
    "multistep_relaxation",
]


@dataclass(frozen=True)
class Linearisation:
    r"""First-order model of a fitted estimator's simulated outputs.

    Attributes
    ----------
    jac_theta : ndarray of shape (T * n_outputs, n_free)
        $J_\theta$: free physical parameters first, then free initial states.
    jac_omega : ndarray of shape (T * n_outputs, n_omega)
        $J_\omega$ for every trainable entry of $\Omega$.
    y : ndarray of shape (T * n_outputs,)
        Shifted residual $\tilde z_\ell$.
    theta_hat, omega_hat : ndarray
        The fit (``omega_hat`` = the thresholded ``coef_`` entries).
    residual : ndarray of shape (T * n_outputs,)
        $z - \hat z$ at the fit.
    theta_names, feature_names : tuple of str
    n_physical : int
        Number of physical parameters among the columns of ``jac_theta``.
    """

    jac_theta: np.ndarray
    jac_omega: np.ndarray
    y: np.ndarray
    theta_hat: np.ndarray
    omega_hat: np.ndarray
    residual: np.ndarray
    theta_names: tuple[str, ...]
    feature_names: tuple[str, ...]
    n_physical: int

    def problem(self, mu: float) -> LinearProblem:
        r"""The local problem $\tilde z_\ell = J_\theta\theta + J_\omega\omega + \eta$."""
        return linear_problem(
            self.jac_theta,
            self.jac_omega,
            self.y,
            mu,
            theta_names=self.theta_names,
            feature_names=self.feature_names,
        )


def _omega_mask(estimator) -> np.ndarray:
    """Trainable entries of $\\Omega$ (all when the compiled basis is not at hand)."""
    compiled = getattr(estimator, "_compiled", None)
    mask = getattr(compiled[0], "omega_trainable", None) if compiled else None
    shape = estimator.coef_.shape
    return np.ones(shape, bool) if mask is None else np.broadcast_to(np.asarray(mask, bool), shape)


def _omega_names(estimator, mask: np.ndarray) -> tuple[str, ...]:
    """``feature`` (one corrected equation) or ``state: feature`` per trainable entry."""
    rows = correction_rows(estimator)
    names = [
        name if len(rows) == 1 else f"{row}: {name}"
        for row in rows
        for name in estimator.feature_names_
    ]
    return tuple(n for n, keep in zip(names, mask.reshape(-1), strict=True) if keep)


def _free_masks(estimator) -> tuple[np.ndarray, np.ndarray]:
    """Free physical parameters and free initial-state entries of the fit."""
    physics = estimator.physics_
    theta_free = np.array([not p.fixed for p in physics.parameters.values()], dtype=bool)
    return theta_free, ~np.asarray(physics.x0_fixed, bool)


def _output_function(estimator, u: np.ndarray, x0: np.ndarray, masks):
    """``(theta_free, x0_free, omega_free) -> flattened simulated outputs`` (pure JAX)."""
    theta_free, x0_free, omega_mask = masks
    model, blocks = estimator._fitted_model(), estimator._fitted_blocks()
    params = {k: jnp.asarray(v) for k, v in blocks.items()}
    omega0 = jnp.asarray(estimator.coef_)
    theta_index, x0_index = np.flatnonzero(theta_free), np.flatnonzero(x0_free)
    omega_index = np.nonzero(omega_mask)

    def outputs(theta, start, omega):
        full = dict(params, theta=params["theta"].at[theta_index].set(theta))
        full["omega"] = omega0.at[omega_index].set(omega)
        x_start = jnp.asarray(x0).at[x0_index].set(start)
        return simulate(model, full, x_start, jnp.asarray(u))[1].reshape(-1)

    return outputs


def _jacobians(estimator, u, x0, masks):
    """Simulated outputs and the three Jacobian blocks at the fit (float64, forward mode)."""
    theta_free, x0_free, omega_mask = masks
    point = (
        jnp.asarray(estimator.theta_[theta_free]),
        jnp.asarray(np.asarray(x0)[x0_free]),
        jnp.asarray(estimator.coef_[omega_mask]),
    )
    outputs = _output_function(estimator, u, x0, masks)
    value = jax.jit(outputs)(*point)
    blocks = jax.jit(jax.jacfwd(outputs, argnums=(0, 1, 2)))(*point)
    return np.asarray(value), [np.asarray(b).reshape(value.shape[0], -1) for b in blocks]


def linearise_estimator(estimator, u, z, *, x0=None) -> Linearisation:
    r"""Jacobians $J_\theta$, $J_\omega$ and the shifted residual of a fitted model.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        Fitted, with a dictionary (``coef_`` not empty).
    u : array-like of shape (T, n_inputs)
        Inputs of the record (normally the one the model was fitted on).
    z : array-like of shape (T,) or (T, n_outputs)
        Measured outputs of that record.
    x0 : array-like of shape (n_states,), optional
        Initial state of the simulation (default: the fitted ``x0_``).

    Returns
    -------
    Linearisation
        The columns of ``jac_theta`` are the free physical parameters, then the free
        initial-state entries (``x0[name]``); those of ``jac_omega`` the trainable
        entries of $\Omega$.
    """
    check_is_fitted(estimator)
    if estimator.coef_.size == 0:
        raise ValueError("estimator has no dictionary (library=None): there is no omega.")
    u, z = check_pair(u, z)
    x0 = estimator.x0_ if x0 is None else np.asarray(x0, float).reshape(-1)
    if x0.shape != estimator.x0_.shape or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be {estimator.x0_.shape[0]} finite values.")
    masks = (*_free_masks(estimator), _omega_mask(estimator))
    with jax.enable_x64(True):
        z_hat, (j_theta, j_x0, j_omega) = _jacobians(estimator, u, x0, masks)
    return _assemble(estimator, z.reshape(-1), z_hat, (j_theta, j_x0, j_omega), x0, masks)


def _assemble(estimator, z, z_hat, jacobians, x0, masks) -> Linearisation:
    """The [`Linearisation`][sk_offwhite.certify.Linearisation] from the Jacobian blocks at the
    fit."""
    theta_free, x0_free, omega_mask = masks
    j_theta, j_x0, j_omega = jacobians
    theta_hat = np.concatenate([estimator.theta_[theta_free], np.asarray(x0)[x0_free]])
    omega_hat = estimator.coef_[omega_mask]
    jac_theta = np.hstack([j_theta, j_x0])
    physics = estimator.physics_
    names = [n for n, f in zip(physics.parameter_names, theta_free, strict=True) if f]
    names += [f"x0[{n}]" for n, f in zip(physics.state_names, x0_free, strict=True) if f]
    residual = z - z_hat
    shifted = residual + jac_theta @ theta_hat + j_omega @ omega_hat
    return Linearisation(
        jac_theta,
        j_omega,
        shifted,
        theta_hat,
        omega_hat,
        residual,
        tuple(names),
        _omega_names(estimator, omega_mask),
        int(theta_free.sum()),
    )


def _linearisation(estimator, u, z, linearisation) -> Linearisation:
    return linearise_estimator(estimator, u, z) if linearisation is None else linearisation


def multistep_relaxation(
    estimator,
    u,
    z,
    mu: float,
    *,
    support_tol: float = 1e-6,
    normalize_columns: bool = False,
    prune: bool = True,
    linearisation=None,
) -> SparseRelaxation:
    r"""The multi-step relaxation (15), solved on the local linearisation of the fit.

    $$
    \min_{\theta, \omega} \|\omega\|_1 \quad \text{s.t.} \quad
    \|\tilde z_\ell - J_\theta\theta - J_\omega\omega\|_2 \le \mu,
    $$

    the first-order form of $\|z - \hat z(\theta, \omega)\|_2 \le \mu$ around the fit
    (``theta`` includes the free initial states).

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        Fitted, with a dictionary.
    u, z : array-like
        The record (see [`linearise_estimator`][sk_offwhite.certify.linearise_estimator]).
    mu : float
        Bound on the 2-norm of the output noise over the record; with a per-sample bound
        $|\eta_k| \le b$ use $\mu = b\sqrt{T n_z}$.
    support_tol : float, default=1e-6
        See [`sparse_relaxation`][sk_offwhite.certify.sparse_relaxation].
    normalize_columns : bool, default=False
        Weigh each $|\omega_j|$ by the norm of its column of $J_\omega$ (see
        [`sparse_relaxation`][sk_offwhite.certify.sparse_relaxation]).
    prune : bool, default=True
        Make the support exact (see [`sparse_relaxation`][sk_offwhite.certify.sparse_relaxation]):
        the candidate terms, in ascending order of $\|J_{\omega,j}\hat\omega_j\|_2$,
        are removed from $S$ while the least-squares refit
        $\min_{\theta, \omega_{S \setminus j}} \|\tilde z_\ell - J_\theta\theta -
        J_{\omega, S \setminus j}\,\omega_{S \setminus j}\|_2 \le \mu$ stays feasible,
        and the estimate returned is that refit on the final support (exact zeros
        elsewhere). ``False`` returns the thresholded $\ell_1$ solution.
    linearisation : Linearisation, optional
        Reuse a linearisation computed before (``u`` and ``z`` are then ignored).

    Returns
    -------
    SparseRelaxation
    """
    lin = _linearisation(estimator, u, z, linearisation)
    options = dict(support_tol=support_tol, normalize_columns=normalize_columns, prune=prune)
    return solve_relaxation(lin.problem(mu), **options)


def certify_estimator(
    estimator,
    u,
    z,
    mu: float | str,
    *,
    omega_hat=None,
    estimate: str = "fit",
    prune_tol: float = 0.01,
    refit: bool = False,
    mu_factor: float = 1.01,
    linearisation=None,
    **options,
) -> SparsityCertificate:
    r"""Theorem 5: is the fitted correction locally maximally sparse?

    Runs [`certify_sparsity`][sk_offwhite.certify.certify_sparsity] on the local linearisation
    ($\Phi_\theta = J_\theta$, $\Phi = J_\omega$, $y = \tilde z_\ell$)
    for the multi-step fit's own $\hat\omega$ (Section 5.1; Remark 1 allows any
    estimate), with its terms of contribution $\|J_{\omega,j}\hat\omega_j\|_2$
    below ``prune_tol`` of the largest set to zero.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        Fitted, with a dictionary.
    u, z : array-like
        The record (see [`linearise_estimator`][sk_offwhite.certify.linearise_estimator]).
    mu : float or ``'refined'``
        Bound on the 2-norm of the output noise over the record (see
        [`multistep_relaxation`][sk_offwhite.certify.multistep_relaxation]). ``'refined'``:
        ``mu_factor`` times the residual the estimate leaves on the linearisation, $\min_\theta
        \|\tilde z_\ell - J_\theta\theta - J_\omega\hat\omega\|_2$ (the smallest bound under which
        it is feasible).
    omega_hat : array-like, optional
        An explicit estimate, one entry per trainable $\Omega$ entry, certified as
        given (no pruning, no refit): e.g. ``multistep_relaxation(...).omega``.
    estimate : {'fit', 'relaxation'}, default='fit'
        Without ``omega_hat``: ``'fit'`` certifies the fit's ``coef_`` (the default, as
        before); ``'relaxation'`` the pruned solution of (15) at ``mu``.
    prune_tol : float, default=0.01
        Terms whose contribution is below this fraction of the largest are zeroed
        (``0`` keeps the estimate's support as it is).
    refit : bool, default=False
        Certify the least-squares refit on the support instead of the estimate itself.
    mu_factor : float, default=1.01
        Safety factor of ``mu='refined'``.
    linearisation : Linearisation, optional
        Reuse a linearisation computed before.
    **options
        ``max_subsets``, ``active_rtol``, ``normalize_columns``, ``diagnose``, ``level``,
        ``vertex``
        of [`certify_sparsity`][sk_offwhite.certify.certify_sparsity] (``level='vertex'``, the
        default: $\sigma^2_n$ at $n = \min(\|\omega^v\|_0 + M, m')$; ``'2M'``: the
        paper's literal level; ``vertex='search'``, the default: where the test fails at
        (11)'s solution, also at a searched vertex; ``'l1'``: the paper's vertex only).

    Returns
    -------
    SparsityCertificate
        ``certificate.mu`` is the bound used; ``certificate.explain()`` says why the
        verdict is what it is.
    """
    lin = _linearisation(estimator, u, z, linearisation)
    refined = isinstance(mu, str)
    if refined and (mu != "refined" or (omega_hat is None and estimate == "relaxation")):
        raise ValueError(
            f"mu must be a positive float (or 'refined' with estimate='fit'), got {mu!r}."
        )
    problem = lin.problem(1.0 if refined else mu)
    omega = omega_hat
    if omega is None:
        choice = dict(estimate=estimate, prune_tol=prune_tol, refit=refit)
        normalize = bool(options.get("normalize_columns", False))
        omega = select_estimate(problem, lin.omega_hat, normalize_columns=normalize, **choice)
    if refined:
        problem = replace(problem, mu=refined_mu(problem, omega, mu_factor))
    return certify_problem(problem, omega, **options)


def estimator_feasible_set(
    estimator, u, z, mu: float, *, support=None, linearisation=None
) -> FeasibleSetBounds:
    r"""FPS (19) or SFPS (20) of the physical parameters on the local linearisation.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        Fitted, with a dictionary.
    u, z : array-like
        The record (see [`linearise_estimator`][sk_offwhite.certify.linearise_estimator]).
    mu : float
        Bound on the 2-norm of the output noise over the record.
    support : ``'fit'`` or array-like of bool, optional
        ``None``: FPS (every dictionary entry free). ``'fit'``: SFPS on the support of the
        fit's ``coef_``; or an explicit boolean mask over the trainable entries.
    linearisation : Linearisation, optional
        Reuse a linearisation computed before.

    Returns
    -------
    FeasibleSetBounds
        Extremes of the free physical parameters around ``theta_`` (initial states are
        free nuisance parameters).
    """
    lin = _linearisation(estimator, u, z, linearisation)
    mask = lin.omega_hat != 0 if isinstance(support, str) and support == "fit" else support
    physical = np.arange(lin.n_physical)
    return feasible_set_bounds(
        lin.problem(mu), lin.theta_hat[physical], support=mask, parameters=physical
    )
