"""What scikit-learn's machinery needs of the package's estimators: the checks that do not
apply, with the reason, and clones of what ``clone`` refuses."""

from __future__ import annotations

import copy

from sklearn.base import clone

__all__ = ["expected_failed_checks"]


_ROW_ORDER_REASON = (
    "rows are consecutive time samples of one simulated trajectory, not independent "
    "observations: reordering or subsetting them changes the simulation"
)


_ARGUMENT_NAME_REASON = (
    "the signature follows the system-identification contract fit(u, z) / score(u, z); the "
    "check calls score(X, y=...) by keyword or reads the literal name 'y'. Positional calls, "
    "which Pipeline, GridSearchCV and cross_validate make, are unaffected, and the "
    "n_features_in_ consistency the check is after is tested separately"
)


def expected_failed_checks(estimator=None) -> dict[str, str]:
    """scikit-learn checks that do not apply, each with the reason.

    Pass it to ``check_estimator(..., expected_failed_checks=...)`` or
    ``parametrize_with_checks(..., expected_failed_checks=...)``.
    """
    return {
        "check_methods_sample_order_invariance": _ROW_ORDER_REASON,
        "check_methods_subset_invariance": _ROW_ORDER_REASON,
        "check_fit_score_takes_y": _ARGUMENT_NAME_REASON,
        "check_n_features_in_after_fitting": _ARGUMENT_NAME_REASON,
    }


def _safe_clone(value):
    """``sklearn.clone`` for estimators, ``deepcopy`` for what clone refuses.

    pysindy's ``CustomLibrary`` renames its constructor arguments, so ``clone`` fails on it.
    """
    try:
        return clone(value, safe=False)
    except (AttributeError, RuntimeError, TypeError):
        return copy.deepcopy(value)


def _short_repr(value) -> str:
    try:
        return repr(value)
    except AttributeError:
        return f"{type(value).__name__}(...)"


def _nested_params(value) -> dict:
    """``value.get_params()`` where it works (not on pysindy's ``CustomLibrary``)."""
    if not hasattr(value, "get_params") or isinstance(value, type):
        return {}
    try:
        return value.get_params(deep=True)
    except (AttributeError, TypeError):
        return {}
