r"""The paper's guarantees, computable: identifiability, error bounds, sparsity certificates.

``identifiability`` and ``parameter_error_bound`` differentiate the fitted multi-step cost
(Assumption 1, Lemma 1 and Theorem 1 of Donati et al.).

``sparse_relaxation``, ``certify_sparsity`` and ``feasible_parameter_set`` solve the convex
problems (10), (11)-(13) and (19)-(20) on a linear-in-parameters problem with cvxpy;
``linearise_estimator``, ``multistep_relaxation``, ``certify_estimator`` and
``estimator_feasible_set`` apply them to the local linearisation of a fitted multi-step model
(relaxation 15, Theorems 4-5). ``certify_estimator`` certifies the fit's own
$\hat\omega$ (pruned at 1 % of the largest term's contribution), and every
certificate carries a ``SparsityDiagnosis`` (``explain()``): the sparsest support with fewer
terms that fits within $\mu$, searched by ``sparsest_feasible_support``.
``hull_errors``, ``principal_components`` and ``hull_polygon`` give the paper's Fig. 2
statistic: FPS and SFPS as convex hulls of Monte Carlo estimates.
"""

from ._bounds import ParameterErrorBound, induced_norm, parameter_error_bound
from ._certificates import SparsityCertificate, certify_sparsity, restricted_eigenvalue
from ._diagnosis import SparsityDiagnosis, sparsest_feasible_support
from ._estimate import prune_by_contribution, refined_mu
from ._feasible import FeasibleSetBounds, feasible_parameter_set
from ._hulls import hull_errors, hull_polygon, principal_components
from ._identifiability import IdentifiabilityReport, UnidentifiableWarning, identifiability
from ._linearise import (
    Linearisation,
    certify_estimator,
    estimator_feasible_set,
    linearise_estimator,
    multistep_relaxation,
)
from ._relaxation import SparseRelaxation, sparse_relaxation

__all__ = [
    "FeasibleSetBounds",
    "IdentifiabilityReport",
    "Linearisation",
    "ParameterErrorBound",
    "SparseRelaxation",
    "SparsityCertificate",
    "SparsityDiagnosis",
    "UnidentifiableWarning",
    "certify_estimator",
    "certify_sparsity",
    "estimator_feasible_set",
    "feasible_parameter_set",
    "hull_errors",
    "hull_polygon",
    "identifiability",
    "induced_norm",
    "linearise_estimator",
    "multistep_relaxation",
    "parameter_error_bound",
    "principal_components",
    "prune_by_contribution",
    "refined_mu",
    "restricted_eigenvalue",
    "sparse_relaxation",
    "sparsest_feasible_support",
]
