r"""Local identifiability (Assumption 1 of Donati et al.) and parameter uncertainty of a fit.

At the fitted solution $p^*$ of the multi-step cost $C_T$ (see
`_ident_problem` for the certified variables $p$: free physical parameters,
free initial states and, optionally, the black-box weights on the support), the package
computes the Hessian

$$
H = \frac{\partial^2 C_T}{\partial p^2}\Big|_{p^*}
$$

with JAX (forward-over-reverse). Variables of very different magnitudes make $H$
ill-conditioned for reasons of units alone, so the verdict uses the *relative* Hessian
$H_s = D H D$, $D = \operatorname{diag}(|p^*_i|)$ (entries at zero keep scale 1),
the curvature with respect to relative changes $\mathrm{d}p_i/|p_i|$:

$$
\text{identifiable} \iff \lambda_{\min}(H_s) > \texttt{rtol}\cdot\lambda_{\max}(H_s).
$$

Eigenvectors of $H_s$ whose eigenvalue fails the test are the directions along which
the cost is flat: they are returned as ``{name: loading}`` in relative units, e.g. for the
Cascaded Tanks with only $x_2$ measured the orbit $x_1 \to a x_1$,
$(k_1, k_2, k_4) \to (\sqrt a k_1, k_2/\sqrt a, a k_4)$ gives
$(k_1, k_2, k_4, x_1(0)) \propto (\tfrac12, -\tfrac12, 1, 1)$.

Uncertainty is the Gauss-Newton covariance of nonlinear least squares,

$$
\operatorname{Cov}(p) = \hat\sigma^2 (J^\top J)^{-1}, \qquad
\hat\sigma^2 = \frac{\|\hat z(p^*) - z\|_2^2}{N - P},
$$

with $J = \partial\hat z/\partial p$ the Jacobian of the simulated outputs
($N$ measured values, $P$ variables); for a model linear in its parameters this
is exactly the ordinary-least-squares covariance. When $J^\top J$ is singular the
pseudo-inverse is used, a [`UnidentifiableWarning`][sk_offwhite.certify.UnidentifiableWarning] is
issued and the standard errors of the variables that load on a null direction are ``inf``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import jax
import numpy as np

from ._ident_derivatives import cost_hessian, output_jacobian
from ._ident_problem import LocalProblem, local_problem

__all__ = ["IdentifiabilityReport", "UnidentifiableWarning", "identifiability"]

MIN_LOADING = 1e-6


class UnidentifiableWarning(UserWarning):
    """The Hessian or the Gauss-Newton matrix of a fit is singular (Assumption 1 fails)."""


@dataclass(frozen=True)
class IdentifiabilityReport:
    """Identifiability verdict and uncertainty of a fitted estimator.

    Attributes
    ----------
    names : tuple of str
        Certified variables: free parameters, free initial states (``"x1(0)"``) and, when
        included, support weights (``"omega[x1: x1 x6]"``).
    kinds : tuple of str
        ``"theta"``, ``"x0"`` or ``"omega"`` for each variable.
    values : ndarray of shape (n_variables,)
        The fitted values $p^*$.
    hessian : ndarray of shape (n_variables, n_variables)
        $\\partial^2 C_T/\\partial p^2$ at $p^*$ (in the variables' own units).
    scales : ndarray of shape (n_variables,)
        $D$: $|p^*_i|$, or 1 where $p^*_i = 0$.
    eigenvalues, eigenvectors : ndarray
        Ascending spectrum of the relative Hessian $D H D$ (columns are eigenvectors).
    rtol : float
        Relative eigenvalue tolerance of the verdict.
    identifiable : bool
        $\\lambda_{\\min} > \\texttt{rtol}\\,\\lambda_{\\max}$ (Assumption 1, locally).
    unidentifiable_directions : tuple of dict
        One ``{name: loading}`` per failing eigenvector, in relative units, unit norm,
        largest loading positive, loadings below ``1e-6`` dropped.
    covariance : ndarray of shape (n_variables, n_variables)
        Gauss-Newton covariance $\\hat\\sigma^2 (J^\\top J)^{+}$.
    standard_errors : dict
        ``name -> sqrt(covariance[i, i])``, ``inf`` on unidentifiable variables.
    noise_variance : float
        $\\hat\\sigma^2$ from the residual (``nan`` when $N \\le P$).
    n_observations : int
        $N$, measured output values in the cost.
    cost, gradient_norm : float
        $C_T(p^*)$ and $\\|\\nabla C_T(p^*)\\|_2$ (near 0 at a minimum).
    """

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    values: np.ndarray
    hessian: np.ndarray
    scales: np.ndarray
    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    rtol: float
    identifiable: bool
    unidentifiable_directions: tuple[dict[str, float], ...]
    covariance: np.ndarray
    standard_errors: dict[str, float]
    noise_variance: float
    n_observations: int
    cost: float
    gradient_norm: float

    @property
    def verdict(self) -> str:
        """One line: is $H \\succ 0$ at the solution."""
        if self.identifiable:
            return "locally identifiable: H is positive definite at the solution"
        count = len(self.unidentifiable_directions)
        return f"NOT locally identifiable: H is singular in {count} direction(s)"

    @property
    def condition_number(self) -> float:
        """$\\lambda_{\\max}/\\lambda_{\\min}$ of the relative Hessian (inf if singular)."""
        smallest = self.eigenvalues[0]
        return float(self.eigenvalues[-1] / smallest) if smallest > 0 else np.inf

    def summary(self) -> str:
        """Readable report: verdict, flat directions with what to fix, standard errors."""
        lines = [f"Identifiability (Assumption 1): {self.verdict}."]
        lines.append(
            f"  relative Hessian eigenvalues: min {self.eigenvalues[0]:.3e}, "
            f"max {self.eigenvalues[-1]:.3e} (tolerance {self.rtol:g} x max)"
        )
        lines.extend(_direction_lines(self.unidentifiable_directions))
        lines.append(f"  {'variable':<28}{'value':>14}{'std. error':>14}")
        for name, value in zip(self.names, self.values, strict=True):
            lines.append(f"  {name:<28}{value:>14.6g}{self.standard_errors[name]:>14.4g}")
        return "\n".join(lines)


def _direction_lines(directions) -> list[str]:
    lines = []
    for number, direction in enumerate(directions, start=1):
        loadings = ", ".join(f"{name} {value:+.3f}" for name, value in direction.items())
        lines.append(f"  flat direction {number} (relative changes dp/|p|): {loadings}")
        lines.append(
            "    only this combination is fixed by the data: fix one of "
            f"{', '.join(list(direction)[:3])} (Parameter(fixed=True) or "
            "PhysicsModel(x0_fixed=...)) or measure more outputs."
        )
    return lines


def variable_scales(values: np.ndarray) -> np.ndarray:
    """$|p_i|$, with 1 where $p_i = 0$ (relative units for the verdict)."""
    scales = np.abs(np.asarray(values, float))
    return np.where(scales > 0, scales, 1.0)


def relative_spectrum(matrix: np.ndarray, scales: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ascending eigenvalues and eigenvectors of $D M D$ (symmetrised)."""
    scaled = matrix * np.outer(scales, scales)
    return np.linalg.eigh(0.5 * (scaled + scaled.T))


def flat_indices(eigenvalues: np.ndarray, rtol: float) -> np.ndarray:
    """Indices of eigenvalues at or below ``rtol`` times the largest one."""
    top = max(float(np.max(np.abs(eigenvalues))), np.finfo(float).tiny)
    return np.flatnonzero(eigenvalues <= rtol * top)


def direction_loadings(vector: np.ndarray, names) -> dict[str, float]:
    """``{name: loading}`` by decreasing magnitude, largest positive, tiny loadings dropped."""
    vector = np.asarray(vector, float) / np.linalg.norm(vector)
    vector = vector * np.sign(vector[np.argmax(np.abs(vector))])
    order = np.argsort(-np.abs(vector), kind="stable")
    return {names[i]: float(vector[i]) for i in order if abs(vector[i]) >= MIN_LOADING}


def relative_inverse(matrix, scales, rtol) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Pseudo-inverse of ``matrix`` computed in relative units, $D (D M D)^{+} D$.

    Eigenvalues of $DMD$ at or below ``rtol`` times the largest are dropped. Returns
    the inverse, the indices of the dropped eigenvalues and the eigenvectors of $DMD$.
    """
    eigenvalues, eigenvectors = relative_spectrum(matrix, scales)
    flat = flat_indices(eigenvalues, rtol)
    kept = np.setdiff1d(np.arange(eigenvalues.size), flat)
    inverse = (eigenvectors[:, kept] / eigenvalues[kept]) @ eigenvectors[:, kept].T
    return inverse * np.outer(scales, scales), flat, eigenvectors


def _noise_variance(residual: np.ndarray, n_variables: int) -> float:
    """$\\|e\\|^2 / (N - P)$, ``nan`` without degrees of freedom."""
    dof = residual.size - n_variables
    return float(residual @ residual / dof) if dof > 0 else np.nan


def gauss_newton_covariance(jacobian, residual, scales, rtol):
    r"""Covariance $\hat\sigma^2 (J^\top J)^{+}$, computed in relative units.

    Returns the covariance, $\hat\sigma^2$ and the indices of the variables that load
    on a null direction of $J^\top J$ (empty when it is regular).
    """
    inverse, flat, eigenvectors = relative_inverse(jacobian.T @ jacobian, scales, rtol)
    sigma2 = _noise_variance(residual, scales.size)
    covariance = sigma2 * inverse
    loading = np.abs(eigenvectors[:, flat]).max(axis=1) if flat.size else np.zeros(scales.size)
    return covariance, sigma2, np.flatnonzero(loading >= MIN_LOADING)


def fit_residual_and_jacobian(local: LocalProblem) -> tuple[np.ndarray, np.ndarray]:
    """Residual $\\hat z - z$ and $J$ over the measured (unpadded) samples."""
    static = dict(model=local.model, layout=local.layout)
    outputs, jacobian = output_jacobian(local.values, local.problem, **static)
    segments = local.problem.segments
    valid = np.asarray(segments.mask, bool)
    residual = np.asarray(outputs - segments.z)[valid].reshape(-1)
    return residual, np.asarray(jacobian)[valid].reshape(residual.size, -1)


def hessian_at_solution(local: LocalProblem) -> tuple[float, np.ndarray, np.ndarray]:
    """$C_T$, its gradient and its Hessian at the fitted values (numpy)."""
    value, gradient, hessian = cost_hessian(
        local.values, local.problem, model=local.model, layout=local.layout
    )
    return float(value), np.asarray(gradient), np.asarray(hessian)


def _standard_errors(names, covariance, unidentifiable) -> dict[str, float]:
    errors = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    errors[unidentifiable] = np.inf
    return dict(zip(names, errors.tolist(), strict=True))


def _warn_singular(directions, names, what: str) -> None:
    listed = "; ".join(", ".join(list(d)[:4]) for d in directions) or ", ".join(names)
    warnings.warn(
        f"{what} is singular: the data do not determine {listed} separately. "
        "Standard errors of these variables are inf and the covariance uses a pseudo-inverse; "
        "fix one of them or measure more outputs.",
        UnidentifiableWarning,
        stacklevel=3,
    )


def identifiability(
    estimator,
    u,
    z,
    sample_index=None,
    *,
    include_omega: bool = True,
    rtol: float = 1e-9,
) -> IdentifiabilityReport:
    r"""Identifiability verdict (Assumption 1), flat directions and standard errors of a fit.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        A fitted estimator.
    u, z : array-like or list of arrays
        The data it was fitted on.
    sample_index : array-like of shape (n_samples,), default=None
        As for ``fit``: a jump in the index starts a new record.
    include_omega : bool, default=True
        Treat the black-box weights on the fitted support as variables of $H$
        (they are fitted jointly with $\theta$); ``False`` keeps them fixed.
    rtol : float, default=1e-9
        Relative eigenvalue tolerance: $H$ counts as positive definite when every
        eigenvalue of the relative Hessian exceeds ``rtol`` times the largest.

    Returns
    -------
    IdentifiabilityReport
        ``report.identifiable``, ``report.unidentifiable_directions``,
        ``report.standard_errors``; ``print(report.summary())`` for a readable account.

    Warns
    -----
    UnidentifiableWarning
        When $H$ or $J^\top J$ is singular.
    """
    if not rtol > 0:
        raise ValueError(f"rtol must be positive, got {rtol!r}.")
    with jax.enable_x64(True):
        local = local_problem(estimator, u, z, sample_index, include_omega)
        cost, gradient, hessian = hessian_at_solution(local)
        residual, jacobian = fit_residual_and_jacobian(local)
    return _report(local, cost, gradient, hessian, residual, jacobian, rtol)


def _report(local, cost, gradient, hessian, residual, jacobian, rtol) -> IdentifiabilityReport:
    scales = variable_scales(local.values)
    eigenvalues, eigenvectors = relative_spectrum(hessian, scales)
    flat = flat_indices(eigenvalues, rtol)
    directions = tuple(direction_loadings(eigenvectors[:, i], local.names) for i in flat)
    covariance, sigma2, unidentifiable = gauss_newton_covariance(jacobian, residual, scales, rtol)
    if flat.size or unidentifiable.size:
        _warn_singular(directions, [local.names[i] for i in unidentifiable], "The Hessian of C_T")
    return IdentifiabilityReport(
        local.names, local.kinds, local.values, hessian, scales, eigenvalues, eigenvectors,
        float(rtol), flat.size == 0, directions, covariance,
        _standard_errors(local.names, covariance, unidentifiable), sigma2,
        local.n_observations, cost, float(np.linalg.norm(gradient)),
    )  # fmt: skip
