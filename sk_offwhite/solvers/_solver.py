r"""The solvers a fit can be given: objects with one ``run`` method.

``GreyBoxSparseRegressor(solver=LevenbergMarquardt(...))`` or ``solver=Optax(...)``; the
strings ``'auto'``, ``'lm'`` and ``'optax'`` name the same solvers built from the
estimator's ``lm_scaling`` and ``optimizer`` (`resolve_solver`). A solver runs on the flat
vector of free variables of a `Problem` and returns a `SolverResult`; what it does is the
same whatever ``verbose`` says (a verbose run only prints).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._coloured import structured_levenberg_marquardt
from ._core import SolverResult
from ._device import levenberg_marquardt_on_device
from ._optax import run_optax
from ._rules import LM_SCALINGS

__all__ = ["LM_MAX_FREE", "STRUCTURED_MIN_FREE", "LevenbergMarquardt", "Optax", "resolve_solver"]

LM_MAX_FREE = 400
"""Without shooting windows, ``solver='auto'`` uses Levenberg-Marquardt up to this many free
variables and the optax loop above."""

STRUCTURED_MIN_FREE = 100
"""With shooting windows, ``jacobian='auto'`` uses the coloured Jacobian above this many
free variables: its memory and time per iteration grow linearly with the record's length,
the dense Jacobian's quadratically and cubically."""

JACOBIANS = ("auto", "dense", "coloured")


@dataclass(frozen=True)
class LevenbergMarquardt:
    r"""Projected Levenberg-Marquardt with forward-mode Jacobians.

    Each step solves $(J^TJ + \mu D)\,s = -J^Tr$ over the variables that can move and
    projects the candidate on the box bounds; the smoothed $\ell_1$ term is majorised at
    the current iterate (reweighted least squares), so an accepted step lowers the
    penalised cost.

    Parameters
    ----------
    scaling : {'per-variable', 'global'}, default='per-variable'
        Marquardt's scaling $D = \mathrm{diag}(J^TJ)$ plus a floor of $10^{-9}$ times, with
        ``'per-variable'``, the largest $(J^TJ)_{ii}$ that variable has had in the run, so
        that rescaling a state, an input or a dictionary column leaves the iterates the
        same up to rounding; with ``'global'``, the largest entry of all variables now,
        one floor for all (the iterates then depend on the units).
    jacobian : {'auto', 'dense', 'coloured'}, default='auto'
        ``'dense'``: the whole Jacobian and its normal equations, the whole run in one
        compiled program. ``'coloured'``: for multiple shooting, the Jacobian by window
        colouring ($G + 2 n_x$ tangents for $G$ global variables, however many windows)
        and sparse normal equations solved on the host. ``'auto'``: coloured with windows
        and more than `STRUCTURED_MIN_FREE` free variables.
    """

    scaling: str = "per-variable"
    jacobian: str = "auto"

    def __post_init__(self):
        if self.scaling not in LM_SCALINGS:
            raise ValueError(f"scaling must be one of {LM_SCALINGS}, got {self.scaling!r}.")
        if self.jacobian not in JACOBIANS:
            raise ValueError(f"jacobian must be one of {JACOBIANS}, got {self.jacobian!r}.")

    def run(self, free0, problem, model, layout, *, max_iter, tol, verbose=0) -> SolverResult:
        """Minimise from ``free0``; see the class docstring."""
        options = dict(max_iter=max_iter, tol=tol, verbose=verbose, scaling=self.scaling)
        if self._coloured(problem, np.shape(free0)[0]):
            return structured_levenberg_marquardt(free0, problem, model, layout, **options)
        return levenberg_marquardt_on_device(free0, problem, model, layout, **options)

    def _coloured(self, problem, n_free: int) -> bool:
        if self.jacobian != "auto":
            return self.jacobian == "coloured"
        return _has_windows(problem) and n_free > STRUCTURED_MIN_FREE


@dataclass(frozen=True)
class Optax:
    """A first-order loop with any optax transformation and reverse-mode gradients.

    Parameters
    ----------
    optimizer : optax.GradientTransformation, default=None
        ``None`` is Adam, its step cosine-decayed from 1e-2 to 1e-4 over ``max_iter``
        iterations, behind clipping of the gradient's global norm at 1.
    patience : int, default=100
        Iterations without a relative improvement of ``tol`` of the best cost after which
        the loop stops.
    """

    optimizer: object = None
    patience: int = 100

    def __post_init__(self):
        if isinstance(self.patience, bool) or not int(self.patience) == self.patience >= 1:
            raise ValueError(f"patience must be an integer >= 1, got {self.patience!r}.")

    def run(self, free0, problem, model, layout, *, max_iter, tol, verbose=0) -> SolverResult:
        """Minimise from ``free0``, keeping the best finite iterate."""
        options = dict(max_iter=max_iter, tol=tol, verbose=verbose, patience=self.patience)
        return run_optax(free0, problem, model, layout, self.optimizer, **options)


def _has_windows(problem) -> bool:
    return bool(np.any(np.asarray(problem.segments.linked) > 0))


def resolve_solver(solver, *, lm_scaling: str, optimizer, problem, n_free: int):
    """The solver object ``solver`` names: itself when it is one; for ``'lm'``
    `LevenbergMarquardt` with ``lm_scaling``; for ``'optax'`` `Optax` with ``optimizer``;
    for ``'auto'`` Levenberg-Marquardt with shooting windows or up to `LM_MAX_FREE` free
    variables, the optax loop above."""
    if not isinstance(solver, str):
        return solver
    if solver == "lm" or (solver == "auto" and (_has_windows(problem) or n_free <= LM_MAX_FREE)):
        return LevenbergMarquardt(scaling=lm_scaling)
    return Optax(optimizer=optimizer)
