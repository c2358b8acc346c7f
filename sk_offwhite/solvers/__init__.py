"""The solvers of the multi-step cost, passed to an estimator as objects.

``GreyBoxSparseRegressor(..., solver=LevenbergMarquardt())`` (the default for most fits) or
``solver=Optax(optimizer)``. Levenberg-Marquardt has one set of rules
(`sk_offwhite.solvers._rules`) and two ways to solve its damped normal equations: the dense
Jacobian, whose whole run is one compiled program, and, for multiple shooting over many
windows, a coloured Jacobian with sparse normal equations solved on the host.
"""

from ._solver import LevenbergMarquardt, Optax

__all__ = ["LevenbergMarquardt", "Optax"]
