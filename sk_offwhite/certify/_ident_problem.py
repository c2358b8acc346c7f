r"""A fitted estimator's cost $C_T$ as a function of the variables being certified.

The certificates of this package (Hessian, covariance, Theorem 1 sensitivities) differentiate
the same multi-step cost the estimator minimised (eq. 3 of Donati et al.,
`sk_offwhite.simulation._objective`) at its solution, with respect to the *certified variables*

$$
p = (\theta_{\text{free}},\ \hat x_0^{\text{free}},\ \Omega_{\text{supp}}),
$$

the free physical parameters, the free initial-state entries of every record and, optionally,
the black-box weights on the fitted support. Weights off the support stay at zero and the
inner weights of a ridge basis stay at their fitted values. Every record is simulated whole
from its own initial state (``horizon=None``), whatever horizon the fit used, so $C_T$
is the single-shooting cost of the paper.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from sklearn.utils.validation import check_is_fitted

from .._estimator import GreyBoxSparseRegressor
from .._estimator_checks import records_digest
from ..fitting._problem import make_problem
from ..model._equations import correction_rows
from ..simulation._layout import Layout
from ..simulation._objective import CostWeights
from ..simulation._rollout import Model
from ..simulation._segments import make_segments
from ..solvers._core import Problem

__all__ = ["LocalProblem", "check_fitted", "local_problem"]


class LocalProblem(NamedTuple):
    """The cost of a fitted estimator restricted to the certified variables.

    Attributes
    ----------
    model : Model
        Static model structure (a ``jit`` static argument).
    layout : Layout
        Packing of all blocks (``theta``, ``x0``, ``omega``, inner weights).
    problem : Problem
        Dynamic data: segments, base vector, the free index of the certified variables.
    values : ndarray of shape (n_variables,)
        The certified variables at the fitted solution.
    names : tuple of str
        One name per certified variable (``"k1"``, ``"x1(0)"``, ``"omega[x1: x1 x6]"``).
    kinds : tuple of str
        ``"theta"``, ``"x0"`` or ``"omega"`` per variable.
    n_observations : int
        Number of measured output values in the cost (samples times outputs).
    """

    model: Model
    layout: Layout
    problem: Problem
    values: np.ndarray
    names: tuple[str, ...]
    kinds: tuple[str, ...]
    n_observations: int


def check_fitted(estimator) -> None:
    """Raise a clear error unless ``estimator`` is a fitted
    [`GreyBoxSparseRegressor`][sk_offwhite.GreyBoxSparseRegressor]."""
    if not isinstance(estimator, GreyBoxSparseRegressor):
        raise TypeError(
            f"estimator must be a fitted GreyBoxSparseRegressor, got {type(estimator).__name__}."
        )
    check_is_fitted(estimator)


def _records(estimator, u, z, sample_index) -> list[tuple[np.ndarray, np.ndarray]]:
    """Validated records of ``(u, z)``, one per fitted initial state."""
    records = estimator._records(u, z, sample_index, reset=False)
    n_fitted = estimator.initial_states_.shape[0]
    if len(records) != n_fitted:
        raise ValueError(
            f"u and z hold {len(records)} record(s) but the estimator was fitted on {n_fitted}; "
            "pass the data the estimator was fitted on (with the same sample_index)."
        )
    if min(u_r.shape[0] for u_r, _ in records) < 2:
        raise ValueError("every record of u and z needs at least 2 samples.")
    fitted = getattr(estimator, "_fitted_data", None)
    if fitted is not None and records_digest(records) != fitted:
        raise ValueError(
            "u and z are not the data the estimator was fitted on (their values differ): "
            "the certificates hold at the minimum of the cost on the fitted data; pass that "
            "data, or fit on this one first."
        )
    return records


def _blocks(estimator) -> dict[str, np.ndarray]:
    """Fitted blocks in packing order: ``theta``, ``x0`` (one row per record), ``omega``, inner."""
    blocks = {"theta": estimator.theta_, "x0": estimator.initial_states_}
    if estimator.coef_.size:
        blocks["omega"] = estimator.coef_
    blocks.update(estimator.inner_params_)
    return {name: np.asarray(value, float) for name, value in blocks.items()}


def _free_masks(estimator, blocks: dict, include_omega: bool) -> dict[str, np.ndarray]:
    """True where a block entry is a certified variable."""
    physics = estimator.physics_
    free = {name: np.zeros(np.shape(value), bool) for name, value in blocks.items()}
    free["theta"] = np.array([not p.fixed for p in physics.parameters.values()], bool)
    free["x0"][:] = ~np.asarray(physics.x0_fixed, bool)
    if "omega" in blocks and include_omega:
        free["omega"] = np.asarray(estimator.support_, bool).copy()
    return free


def _block_names(estimator, blocks: dict) -> dict[str, np.ndarray]:
    """Name of every entry of the ``theta``, ``x0`` and ``omega`` blocks."""
    physics = estimator.physics_
    n_records = blocks["x0"].shape[0]
    x0 = [
        [f"{state}(0)" + (f"[{r}]" if n_records > 1 else "") for state in physics.state_names]
        for r in range(n_records)
    ]
    names = {"theta": np.array(physics.parameter_names, object), "x0": np.array(x0, object)}
    if "omega" in blocks:
        rows = correction_rows(estimator)
        omega = [[f"omega[{row}: {term}]" for term in estimator.feature_names_] for row in rows]
        names["omega"] = np.array(omega, object)
    return names


def _selected(layout: Layout, free: dict, per_block: dict) -> tuple:
    """Entries of ``per_block`` at the certified variables, in packing order."""
    picked = []
    for name, _ in layout.blocks:
        if name in per_block:
            picked.extend(np.asarray(per_block[name], object)[free[name]].tolist())
    return tuple(picked)


def _weights(estimator) -> CostWeights:
    return estimator._fitted_cost_weights()


def local_problem(estimator, u, z, sample_index=None, include_omega: bool = True) -> LocalProblem:
    """Build the fitted estimator's cost as a function of the certified variables.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        A fitted estimator.
    u, z : array-like or list of arrays
        The data it was fitted on (same layout as for ``fit``).
    sample_index : array-like of shape (n_samples,), default=None
        As for ``fit``: a jump starts a new record.
    include_omega : bool, default=True
        Certify the black-box weights on the fitted support jointly with
        $\\theta$ and $\\hat x_0$.

    Returns
    -------
    LocalProblem
        Must be used under ``jax.enable_x64(True)`` (its arrays are float64).
    """
    check_fitted(estimator)
    records = _records(estimator, u, z, sample_index)
    blocks = _blocks(estimator)
    free = _free_masks(estimator, blocks, include_omega)
    layout = Layout.from_arrays(blocks)
    infinite = tuple(
        {k: np.full(v.shape, side) for k, v in blocks.items()} for side in (-np.inf, np.inf)
    )
    segments = make_segments(records, None)
    problem, values = make_problem(layout, blocks, free, infinite, segments, _weights(estimator))
    if values.shape[0] == 0:
        raise ValueError("nothing to certify: every parameter and initial state is fixed.")
    kinds = {name: np.full(np.shape(v), name, object) for name, v in blocks.items()}
    n_observations = int(np.sum(segments.mask)) * segments.z.shape[-1]
    return LocalProblem(
        estimator._fitted_model(),
        layout,
        problem,
        np.asarray(values),
        _selected(layout, free, _block_names(estimator, blocks)),
        _selected(layout, free, kinds),
        n_observations,
    )
