"""The case table of ``audit_bad_inputs.py``: the data, the fixtures and every bad input.

Each :class:`Case` names its entry point, says what is wrong with the input (``what``) and
what the right outcome is (``expected``; for an input that may be accepted, ``right`` says
what a right result is and ``check`` tests it). :func:`build_cases` returns the table; the
cases of ``GreyBoxSparseRegressorCV`` and ``EffectSearchCV`` are added only where the
package has them.

The data: a noise-free record of 300 samples of the 1-state linear system
``x+ = 0.8 x + 0.5 u``, ``z = x``, ``x0 = 0.5``, driven by a piecewise-constant input (every
fit of the declared model recovers ``a = 0.8``, ``b = 0.5`` to rounding), and for the
two-state cases the noise-free two-tank record of
:func:`sk_offwhite.datasets.make_cascaded_tanks` (300 samples, no overflow, no saturation).
"""

from __future__ import annotations

import functools
import inspect
import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import jax.numpy as jnp
import numpy as np

LOOP_ENTRIES = frozenset({"close_the_loop", "EffectSearchCV"})
TRUE = {"a": 0.8, "b": 0.5}
TRUE_X0 = 0.5
N_SAMPLES = 300
CLEAN = object()  # the clean record, where a case gives no data of its own


@dataclass(frozen=True)
class Case:
    """One bad (or hostile-but-fair) input and how to judge what it does."""

    id: str
    entry: str
    what: str
    run: Callable[[Any], Any]
    expected: str = "clear"
    names: tuple[str, ...] = ()
    check: Callable[[Any, Any], tuple[bool, str]] | None = None
    accept_class: str = "correct"
    right: str = ""
    warn_words: tuple[str, ...] = ()
    early: bool = True
    limit: float | None = None
    on_timeout: str = "hang"
    needs: tuple[str, ...] = field(default=())


# ---------------------------------------------------------------------- data and fixtures
def linear_step(x, u, theta):
    """``x+ = a x + b u`` (one state, one input)."""
    return theta["a"] * x + theta["b"] * u


def linear_physics(a: float = 0.5, b: float = 0.1, **kwargs):
    from sk_offwhite import Parameter, PhysicsModel

    parameters = kwargs.pop("parameters", {"a": Parameter(a), "b": Parameter(b)})
    return PhysicsModel(linear_step, [0], parameters, 1, 1, **kwargs)


def physics_with_step(step, n_states: int = 1, output=(0,), **kwargs):
    """The linear model's parameters with another ``step`` (and ``n_states``)."""
    from sk_offwhite import Parameter, PhysicsModel

    parameters = {"a": Parameter(0.5), "b": Parameter(0.1)}
    return PhysicsModel(step, list(output), parameters, n_states, 1, **kwargs)


def linear_record(n: int = N_SAMPLES, a: float = 0.8, b: float = 0.5, seed: int = 0):
    """``(u, z)`` of ``x+ = a x + b u`` from ``x0 = 0.5``, ``u`` held for 10 samples."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.0, 1.0, (n // 10 + 1, 1)), 10, axis=0)[:n]
    x = np.empty(n)
    x[0] = TRUE_X0
    for k in range(n - 1):
        x[k + 1] = a * x[k] + b * u[k, 0]
    return u, x[:, None]


def tanks_rhs(x, u, theta):
    """The two tanks' right-hand side (eq. 21), square roots kept finite at 0."""
    root = jnp.sqrt(jnp.maximum(x, 1e-6))
    return jnp.stack(
        [
            -theta["k1"] * root[0] + theta["k4"] * u[0],
            theta["k2"] * root[0] - theta["k3"] * root[1],
        ]
    )


def tanks_physics(rhs=tanks_rhs, **kwargs):
    from sk_offwhite import Parameter, PhysicsModel

    parameters = {
        "k1": Parameter(0.1, bounds=(0, None)),
        "k2": Parameter(0.075, bounds=(0, None)),
        "k3": Parameter(0.07, bounds=(0, None)),
        "k4": Parameter(0.088, fixed=True),
    }
    settings = dict(method="euler", x0=[5.0, 6.0]) | kwargs
    return PhysicsModel.from_ode(rhs, 4.0, [1], parameters, 2, 1, **settings)


class Context:
    """The data and the cached fixtures of one worker process."""

    def __init__(self):
        self.u, self.z = linear_record()
        self.physics = linear_physics()

    def estimator(self, **params):
        from sk_offwhite import GreyBoxSparseRegressor

        return GreyBoxSparseRegressor(params.pop("physics", self.physics), **params)

    def fit(self, u=CLEAN, z=CLEAN, **params):
        """A fit of ``u``, ``z`` (the clean record where not given)."""
        u = self.u if u is CLEAN else u
        z = self.z if z is CLEAN else z
        return self.estimator(**params).fit(u, z)

    @functools.cache  # noqa: B019 (one context per process, kept for its life)
    def fitted(self):
        """The declared model fitted on the clean record (predict / score cases)."""
        return self.fit()

    @functools.cache  # noqa: B019
    def poly2(self):
        import pysindy as ps

        return ps.PolynomialLibrary(degree=2)

    @functools.cache  # noqa: B019
    def tanks(self):
        from sk_offwhite.datasets import make_cascaded_tanks

        data = make_cascaded_tanks(
            N_SAMPLES, overflow=False, saturation=False, noise_std=0.0, random_state=0
        )
        return data.u, data.z

    @functools.cache  # noqa: B019
    def loop_result(self):
        """A cheap closed loop on the clean record (``score_models`` / ``write_report``)."""
        from sk_offwhite.loop import close_the_loop

        return close_the_loop(self.physics, self.poly2(), self.u, self.z, settings=cheap_loop())


def warm_up(context: Context) -> None:
    """Import every module the cases use and build the shared library, so that no case's
    time (the loop's 1 s rule) includes an import."""
    import pysindy  # noqa: F401
    import sklearn.model_selection  # noqa: F401

    import sk_offwhite.baselines  # noqa: F401
    import sk_offwhite.certify  # noqa: F401
    import sk_offwhite.datasets  # noqa: F401
    import sk_offwhite.diagnose  # noqa: F401
    from sk_offwhite.loop import LoopSettings

    LoopSettings()
    context.poly2()


def cheap_loop(**changes):
    from sk_offwhite.loop import LoopSettings

    settings = dict(
        n_gammas=2, max_iter=30, max_effects=1, max_candidates=1, beam=1, n_promoted=0,
        fit_delta=False, horizon=None, fit_output_delta=False,
    )  # fmt: skip
    return LoopSettings(**(settings | changes))


# ---------------------------------------------------------------------- checks
def truth_error(est) -> float:
    """Largest relative error of the fitted ``a``, ``b`` against the truth."""
    return max(abs(est.parameters_[k] - v) / abs(v) for k, v in TRUE.items())


def recovers_truth(est, ctx=None, tol: float = 1e-4) -> tuple[bool, str]:
    error = truth_error(est)
    shown = ", ".join(f"{k}={est.parameters_[k]:.6g}" for k in TRUE)
    return error < tol, f"{shown} (relative error {error:.1e})"


def same_as_reference(est, ctx, tol: float = 1e-6) -> tuple[bool, str]:
    """The same parameters as the clean fit."""
    reference = ctx.fitted()
    error = max(abs(est.parameters_[k] - reference.parameters_[k]) for k in TRUE)
    return error < tol, f"parameters differ from the clean fit by {error:.1e}"


def good_score(value, ctx=None) -> tuple[bool, str]:
    value = float(value)
    return bool(np.isfinite(value) and value > 0.999), f"score {value!r}"


def finite_prediction(value, ctx=None) -> tuple[bool, str]:
    values = np.asarray(value, float)
    ok = values.size > 0 and bool(np.all(np.isfinite(values)))
    return ok, f"prediction of shape {values.shape}, finite: {ok}"


def matches_clean_prediction(value, ctx) -> tuple[bool, str]:
    """The clean fit's free run from its fitted initial state."""
    reference = ctx.fitted().predict(ctx.u)
    values = np.asarray(value, float).reshape(reference.shape)
    error = float(np.max(np.abs(values - reference)))
    return error < 1e-8, f"differs from the clean prediction by {error:.1e}"


def all_cv_scores_exact(scores, ctx=None) -> tuple[bool, str]:
    """The physics is exact and the data noise-free: every honest held-out R² is 1."""
    scores = np.asarray(scores, float).reshape(-1)
    worst = float(np.min(scores)) if scores.size else float("nan")
    shown = np.array2string(np.round(scores, 5), threshold=8)
    return bool(np.isfinite(worst) and worst > 0.9999), f"fold scores {shown}"


def grid_scores_exact(search, ctx=None) -> tuple[bool, str]:
    folds = [k for k in search.cv_results_ if k.startswith("split") and k.endswith("test_score")]
    scores = np.array([search.cv_results_[k] for k in folds])
    return all_cv_scores_exact(scores)


def returned(value, ctx=None) -> tuple[bool, str]:
    return True, f"returned {type(value).__name__}"


def is_bool_attribute(name: str):
    """The object's ``name`` became a real bool (the documented type)."""

    def check(value, ctx=None):
        stored = getattr(value, name)
        ok = isinstance(stored, bool | np.bool_) or (
            isinstance(stored, np.ndarray) and stored.dtype == bool
        )
        return ok, f"{name} stored as {stored!r}"

    return check


# ---------------------------------------------------------------------- case builders
def refuse(id, entry, what, run, names, **kwargs) -> Case:
    """A case whose right outcome is a clear refusal naming one of ``names``."""
    names = (names,) if isinstance(names, str) else tuple(names)
    return Case(id, entry, what, run, names=names, **kwargs)


def accept(id, entry, what, run, check, right, accept_class="correct", **kwargs) -> Case:
    """A case whose input is acceptable; ``check`` says whether the result is ``right``."""
    kwargs.setdefault("expected", accept_class)
    return Case(id, entry, what, run, check=check, right=right, accept_class=accept_class, **kwargs)


def _fit_with(**params):
    return lambda ctx: ctx.fit(**params)


def _fit_data(u, z, **params):
    return lambda ctx: ctx.fit(u(ctx), z(ctx), **params)


def _u(ctx):
    return ctx.u


def _z(ctx):
    return ctx.z


def _with_value(array, index, value, dtype=float):
    out = np.array(array, dtype=dtype, copy=True)
    out.flat[index] = value
    return out


# ---------------------------------------------------------------------- arrays given to fit
FIT = "GreyBoxSparseRegressor.fit"
PREDICT = "GreyBoxSparseRegressor.predict"
SCORE = "GreyBoxSparseRegressor.score"


def array_cases() -> list[Case]:
    cases = []
    for label, bad in (("nan", np.nan), ("inf", np.inf), ("-inf", -np.inf)):
        cases.append(
            refuse(
                f"fit.u.{label}", FIT, f"u[17] = {label}",
                _fit_data(lambda c, b=bad: _with_value(c.u, 17, b), _z), "u",
            )
        )  # fmt: skip
        cases.append(
            refuse(
                f"fit.z.{label}", FIT, f"z[3] = {label}",
                _fit_data(_u, lambda c, b=bad: _with_value(c.z, 3, b)), "z",
            )
        )  # fmt: skip
    shapes = [
        ("fit.u.1d", "u of shape (300,) instead of (300, 1)", lambda c: c.u.ravel(), _z, "u"),
        ("fit.u.3d", "u of shape (300, 1, 1)", lambda c: c.u[:, :, None], _z, "u"),
        ("fit.z.3d", "z of shape (300, 1, 1)", _u, lambda c: c.z[:, :, None], "z"),
        ("fit.u.2cols", "u with 2 columns, physics.n_inputs = 1", lambda c: np.hstack([c.u] * 2),
         _z, ("u", "n_inputs")),
        ("fit.z.2cols", "z with 2 columns, physics has 1 output", _u,
         lambda c: np.hstack([c.z] * 2), ("z", "output")),
        ("fit.u.shorter", "u of 299 samples, z of 300", lambda c: c.u[:-1], _z, ("u", "z")),
        ("fit.z.shorter", "z of 299 samples, u of 300", _u, lambda c: c.z[:-1], ("u", "z")),
        ("fit.samples.0", "0 samples", lambda c: c.u[:0], lambda c: c.z[:0], ("u", "samples")),
        ("fit.samples.1", "1 sample", lambda c: c.u[:1], lambda c: c.z[:1], ("u", "samples")),
        ("fit.u.strings", "u holds the string 'abc'", lambda c: np.full(c.u.shape, "abc"), _z,
         "u"),
        ("fit.u.object-none", "u is an object array with a None", lambda c: _with_value(
            c.u.astype(object), 5, None, object), _z, "u"),
        ("fit.u.complex", "u is complex (u + 1j)", lambda c: c.u + 1j, _z, "u"),
        ("fit.z.complex", "z is complex (z + 0.5j)", _u, lambda c: c.z + 0.5j, "z"),
        ("fit.z.strings", "z holds the string 'x'", _u, lambda c: np.full(c.z.shape, "x"), "z"),
        ("fit.u.none", "u is None", lambda c: None, _z, "u"),
        ("fit.z.none", "z is None", _u, lambda c: None, "z"),
        ("fit.u.scalar", "u is the scalar 1.0", lambda c: 1.0, _z, "u"),
        ("fit.u.ragged-list", "u is a ragged list of rows", lambda c: [[1.0], [2.0, 3.0]] * 150,
         _z, "u"),
        ("fit.u.dict", "u is a dict", lambda c: {"u": c.u}, _z, "u"),
    ]  # fmt: skip
    for id, what, u, z, names in shapes:
        cases.append(refuse(id, FIT, what, _fit_data(u, z), names))
    cases += [
        accept(
            "fit.samples.2", FIT, "2 samples: one transition for a, b and x0",
            _fit_data(lambda c: c.u[:2], lambda c: c.z[:2]), recovers_truth,
            "a refusal, a warning that 3 unknowns are not determined by 2 outputs, or the "
            "truth", names=("samples",), warn_words=("determine", "identifiab", "few"),
            expected="clear (too little data) or correct",
        ),
        accept(
            "fit.z.1d", FIT, "z of shape (300,) (documented)",
            _fit_data(_u, lambda c: c.z.ravel()), same_as_reference, "the clean fit",
        ),
        accept(
            "fit.u.list", FIT, "u and z as nested Python lists",
            _fit_data(lambda c: c.u.tolist(), lambda c: c.z.tolist()), same_as_reference,
            "the clean fit",
        ),
        accept(
            "fit.u.numeric-strings", FIT, "u as strings of numbers ('0.27', ...)",
            _fit_data(lambda c: c.u.astype(str), _z), same_as_reference,
            "the clean fit (the strings are the numbers) or a refusal naming u",
            accept_class="harmless", names=("u",),
        ),
        accept(
            "fit.u.object-floats", FIT, "u as an object array of floats",
            _fit_data(lambda c: c.u.astype(object), _z), same_as_reference, "the clean fit",
            accept_class="harmless",
        ),
        accept(
            "fit.u.int", FIT, "u of integer dtype (u rounded: its own truth)",
            lambda c: c.fit(np.round(c.u * 4).astype(int), linear_record_for(np.round(c.u * 4))),
            recovers_truth, "the truth of the rounded input",
        ),
        accept(
            "fit.u.bool", FIT, "u of boolean dtype (on/off input)",
            lambda c: c.fit(c.u > 0, linear_record_for((c.u > 0).astype(float))),
            recovers_truth, "the truth of the 0/1 input", accept_class="harmless",
        ),
        accept(
            "fit.z.bool", FIT, "z of boolean dtype",
            _fit_data(_u, lambda c: c.z > 0.2), returned_finite_fit,
            "a refusal naming z, or a finite fit", accept_class="harmless", names=("z",),
        ),
        accept(
            "fit.u.scaled-1e6", FIT, "u scaled by 1e6 (b then 5e-7): units must not matter",
            _fit_data(lambda c: c.u * 1e6, _z), scaled_truth(b=1e-6),
            "a = 0.8, b = 0.5e-6 (the estimator claims scale invariance)",
        ),
        accept(
            "fit.z.scaled-1e-8", FIT, "z scaled by 1e-8 (b then 5e-9)",
            _fit_data(_u, lambda c: c.z * 1e-8), scaled_truth(b=1e-8, x0=1e-8),
            "a = 0.8, b = 5e-9",
        ),
        accept(
            "fit.z.scaled-1e200", FIT, "u and z scaled by 1e200 (squares overflow)",
            _fit_data(lambda c: c.u * 1e200, lambda c: c.z * 1e200), recovers_truth,
            "a = 0.8, b = 0.5, or a refusal naming u/z", names=("u", "z"),
        ),
        accept(
            "fit.z.constant", FIT, "z constant (all zeros): a is not determined",
            _fit_data(_u, lambda c: np.zeros_like(c.z)), flags_undetermined,
            "a refusal or a warning that z is constant / a is undetermined",
            expected="clear", names=("z",), warn_words=("constant", "determine", "identifiab"),
        ),
        accept(
            "fit.u.constant", FIT, "u constant (all zeros): b is not determined",
            _fit_data(lambda c: np.zeros_like(c.u), lambda c: _free_response(c)),
            flags_undetermined, "a refusal or a warning that u is constant / b undetermined",
            expected="clear", names=("u", "b"), warn_words=("constant", "determine", "identifiab"),
        ),
    ]  # fmt: skip
    return cases


def linear_record_for(u):
    """``z`` of the true system driven by ``u`` (from ``x0 = 0.5``)."""
    u = np.asarray(u, float).reshape(-1, 1)
    x = np.empty(len(u))
    x[0] = TRUE_X0
    for k in range(len(u) - 1):
        x[k + 1] = TRUE["a"] * x[k] + TRUE["b"] * u[k, 0]
    return x[:, None]


def _free_response(ctx):
    return linear_record_for(np.zeros_like(ctx.u))


def returned_finite_fit(est, ctx=None) -> tuple[bool, str]:
    theta = np.asarray(est.theta_, float)
    return bool(np.all(np.isfinite(theta))), f"theta {theta}"


def scaled_truth(b: float, x0: float = 1.0):
    """The truth after rescaling: ``b`` multiplied by ``b`` (``a`` unchanged)."""

    def check(est, ctx=None):
        a, fitted_b = est.parameters_["a"], est.parameters_["b"]
        error = max(abs(a - 0.8) / 0.8, abs(fitted_b - 0.5 * b) / (0.5 * b))
        return error < 1e-4, f"a={a:.6g}, b={fitted_b:.6g} (relative error {error:.1e})"

    return check


def flags_undetermined(est, ctx=None) -> tuple[bool, str]:
    """Always fails: such a fit is right only with a warning (classified as ``warned``)."""
    return False, "accepted; fitted " + ", ".join(
        f"{k}={v:.4g}" for k, v in est.parameters_.items()
    )


def record_list_cases() -> list[Case]:
    def halves(c):
        return [c.u[:150], c.u[150:]], [c.z[:150], c.z[150:]]

    def split(u_of, z_of):
        return lambda c: c.fit(u_of(c), z_of(c))

    return [
        accept(
            "fit.records.two", FIT, "two records as lists (documented)",
            split(lambda c: halves(c)[0], lambda c: halves(c)[1]), recovers_truth, "the truth",
        ),
        accept(
            "fit.records.tuple", FIT, "two records as tuples",
            split(lambda c: tuple(halves(c)[0]), lambda c: tuple(halves(c)[1])), recovers_truth,
            "the truth",
        ),
        accept(
            "fit.records.z-1d", FIT, "records: u 2-D, z 1-D arrays",
            split(lambda c: halves(c)[0], lambda c: [z.ravel() for z in halves(c)[1]]),
            recovers_truth, "the truth",
        ),
        refuse(
            "fit.records.count", FIT, "two u records, one z record",
            split(lambda c: halves(c)[0], lambda c: halves(c)[1][:1]), ("u", "z"),
        ),
        refuse(
            "fit.records.lengths", FIT, "record 1: u of 150 samples, z of 149",
            split(lambda c: halves(c)[0], lambda c: [halves(c)[1][0], c.z[150:-1]]),
            ("u[1]", "z[1]"),
        ),
        refuse(
            "fit.records.widths", FIT, "record 1 has 2 input columns",
            split(lambda c: [c.u[:150], np.hstack([c.u[150:]] * 2)], lambda c: halves(c)[1]),
            ("u", "u[1]", "columns"),
        ),
        refuse(
            "fit.records.nan", FIT, "record 1 of z holds a NaN",
            split(lambda c: halves(c)[0], lambda c: [c.z[:150], _with_value(c.z[150:], 4, np.nan)]),
            ("z[1]",),
        ),
        refuse(
            "fit.records.1d-u", FIT, "records given as 1-D arrays (each read as one row)",
            split(lambda c: [u.ravel() for u in halves(c)[0]], lambda c: halves(c)[1]),
            ("u",),
        ),
        refuse(
            "fit.records.u-list-z-array", FIT, "u a list of records, z one array",
            split(lambda c: halves(c)[0], _z), ("u", "z"),
        ),
        refuse(
            "fit.records.empty", FIT, "u = [], z = []",
            split(lambda c: [], lambda c: []), ("u",),
        ),
        refuse(
            "fit.records.mixed", FIT, "u records: an array and a nested list",
            split(lambda c: [c.u[:150], c.u[150:].tolist()], lambda c: halves(c)[1]), ("u",),
        ),
        accept(
            "fit.records.one-sample", FIT, "two records, the second of 1 sample",
            split(lambda c: [c.u[:299], c.u[299:]], lambda c: [c.z[:299], c.z[299:]]),
            recovers_truth, "the truth (a 1-sample record adds nothing) or a refusal",
            accept_class="harmless", names=("u", "samples"),
        ),
    ]  # fmt: skip


def sample_index_cases() -> list[Case]:
    def fit_index(index_of):
        return lambda c: c.estimator().fit(c.u, c.z, sample_index=index_of(c))

    def gap(c):
        return np.concatenate([np.arange(150), np.arange(160, 310)])

    refusals = [
        ("nan", "sample_index with a NaN", lambda c: _with_value(np.arange(300.0), 7, np.nan)),
        ("inf", "sample_index with an inf", lambda c: _with_value(np.arange(300.0), 7, np.inf)),
        ("fractions", "sample_index = arange(300) / 2", lambda c: np.arange(300) / 2),
        ("strings", "sample_index of strings", lambda c: np.arange(300).astype(str)),
        ("bool", "sample_index of booleans", lambda c: np.ones(300, bool)),
        ("short", "sample_index of 299 entries for 300 rows", lambda c: np.arange(299)),
        ("long", "sample_index of 301 entries for 300 rows", lambda c: np.arange(301)),
        ("scalar", "sample_index = 5", lambda c: 5),
    ]
    cases = [
        refuse(f"fit.sample_index.{label}", FIT, what, fit_index(index), "sample_index")
        for label, what, index in refusals
    ]
    warn = ("sample_index", "record", "single row", "shuffle")
    cases += [
        accept(
            "fit.sample_index.reversed", FIT, "sample_index decreasing (300 records of 1 row)",
            fit_index(lambda c: np.arange(300)[::-1]), recovers_truth,
            "a refusal or a SequenceWarning", expected="clear (warned)",
            names=("sample_index",), warn_words=warn,
        ),
        accept(
            "fit.sample_index.zeros", FIT, "sample_index all zeros",
            fit_index(lambda c: np.zeros(300, int)), recovers_truth,
            "a refusal or a SequenceWarning", expected="clear (warned)",
            names=("sample_index",), warn_words=warn,
        ),
        accept(
            "fit.sample_index.permuted", FIT, "sample_index a random permutation",
            fit_index(lambda c: np.random.default_rng(1).permutation(300)), recovers_truth,
            "a refusal or a SequenceWarning", expected="clear (warned)",
            names=("sample_index",), warn_words=warn,
        ),
        accept(
            "fit.sample_index.gap", FIT, "sample_index with a jump of 10 (two records)",
            fit_index(gap), recovers_truth, "the truth (each record its own x0)",
        ),
        accept(
            "fit.sample_index.offset", FIT, "sample_index = arange(300) + 1000",
            fit_index(lambda c: np.arange(300) + 1000), same_as_reference, "the clean fit",
        ),
        accept(
            "fit.sample_index.floats", FIT, "sample_index of integral floats",
            fit_index(lambda c: np.arange(300.0)), same_as_reference, "the clean fit",
        ),
        accept(
            "fit.sample_index.column", FIT, "sample_index of shape (300, 1)",
            fit_index(lambda c: np.arange(300)[:, None]), same_as_reference, "the clean fit",
            accept_class="harmless",
        ),
    ]  # fmt: skip
    return cases


# ---------------------------------------------------------------------- predict and score
def prediction_cases() -> list[Case]:
    def predict_with(**arguments):
        return lambda c: c.fitted().predict(
            c.u, **{k: v(c) if callable(v) else v for k, v in arguments.items()}
        )

    needs = ("fitted",)
    cases = [
        refuse("predict.u.nan", PREDICT, "u[4] = NaN",
               lambda c: c.fitted().predict(_with_value(c.u, 4, np.nan)), "u", needs=needs),
        refuse("predict.u.2cols", PREDICT, "u with 2 columns (fitted on 1)",
               lambda c: c.fitted().predict(np.hstack([c.u] * 2)), "u", needs=needs),
        refuse("predict.u.0rows", PREDICT, "u with 0 rows",
               lambda c: c.fitted().predict(c.u[:0]), "u", needs=needs),
        refuse("predict.u.1d", PREDICT, "u of shape (300,)",
               lambda c: c.fitted().predict(c.u.ravel()), "u", needs=needs),
        refuse("predict.x0.nan", PREDICT, "x0 = [NaN]", predict_with(x0=[np.nan]), "x0",
               needs=needs),
        refuse("predict.x0.inf", PREDICT, "x0 = [inf]", predict_with(x0=[np.inf]), "x0",
               needs=needs),
        refuse("predict.x0.length", PREDICT, "x0 of 2 entries for 1 state",
               predict_with(x0=[0.1, 0.2]), "x0", needs=needs),
        refuse("predict.x0.string", PREDICT, "x0 = 'abc'", predict_with(x0="abc"), "x0",
               needs=needs),
        refuse("predict.z_init.nan", PREDICT, "z_init with a NaN",
               predict_with(z_init=lambda c: _with_value(c.z[:20], 3, np.nan)), "z_init",
               needs=needs),
        refuse("predict.z_init.inf", PREDICT, "z_init with an inf",
               predict_with(z_init=lambda c: _with_value(c.z[:20], 3, np.inf)), "z_init",
               needs=needs),
        refuse("predict.z_init.too-long", PREDICT, "z_init of 301 rows, u of 300",
               predict_with(z_init=lambda c: np.vstack([c.z, c.z[:1]])), "z_init", needs=needs),
        refuse("predict.z_init.width", PREDICT, "z_init with 2 columns (1 output)",
               predict_with(z_init=lambda c: np.hstack([c.z[:20]] * 2)), "z_init", needs=needs),
        refuse("predict.z_init.list", PREDICT, "z_init a list while u is one record",
               predict_with(z_init=lambda c: [c.z[:20]]), "z_init", needs=needs),
        refuse("predict.z_init.string", PREDICT, "z_init = 'abc'",
               predict_with(z_init="abc"), "z_init", needs=needs),
        accept("predict.z_init.3d", PREDICT, "z_init of shape (20, 1, 1)",
               predict_with(z_init=lambda c: c.z[:20, :, None]), matches_clean_prediction,
               "the clean prediction (the extra axis is of length 1), or a refusal",
               accept_class="harmless", names=("z_init",), needs=needs),
        refuse("predict.records.z_init-count", PREDICT, "two records, one z_init",
               lambda c: c.fitted().predict([c.u[:150], c.u[150:]], z_init=[c.z[:20]]),
               "z_init", needs=needs),
        accept("predict.x0.2d", PREDICT, "x0 = [[0.5]] (2-D)", predict_with(x0=[[TRUE_X0]]),
               matches_clean_prediction, "the clean prediction", accept_class="harmless",
               needs=needs),
        accept("predict.z_init.empty", PREDICT, "z_init of 0 rows (documented: x0_)",
               predict_with(z_init=lambda c: c.z[:0]), matches_clean_prediction,
               "the prediction from x0_", needs=needs),
        accept("predict.z_init.1d", PREDICT, "z_init of shape (20,)",
               predict_with(z_init=lambda c: c.z[:20].ravel()), matches_clean_prediction,
               "the clean prediction", needs=needs),
        accept("predict.x0-and-z_init", PREDICT, "both x0 and z_init (x0 documented to win)",
               predict_with(x0=[TRUE_X0], z_init=lambda c: c.z[:20] + 1.0),
               matches_clean_prediction, "the prediction from x0", accept_class="harmless",
               needs=needs),
        accept("predict.u.1row", PREDICT, "u of 1 row", lambda c: c.fitted().predict(c.u[:1]),
               finite_prediction, "one finite output", needs=needs),
        accept("predict.records", PREDICT, "two records as a list",
               lambda c: np.concatenate(c.fitted().predict([c.u, c.u])), finite_prediction,
               "finite outputs for both", needs=needs),
        refuse("predict.unfitted", PREDICT, "predict before fit",
               lambda c: c.estimator().predict(c.u), ("fit", "fitted")),
    ]  # fmt: skip
    return cases


def score_cases() -> list[Case]:
    needs = ("fitted",)

    def score(u_of, z_of, **kwargs):
        return lambda c: c.fitted().score(u_of(c), z_of(c), **kwargs)

    return [
        refuse("score.unfitted", SCORE, "score before fit", lambda c: c.estimator().score(c.u, c.z),
               ("fit", "fitted")),
        accept("score.1sample", SCORE, "score on 1 sample", score(
            lambda c: c.u[:1], lambda c: c.z[:1]), good_score,
            "a refusal naming the too-short record, or a warning", names=("u", "z", "samples"),
            expected="clear", warn_words=("sample", "samples"), needs=needs),
        accept("score.2samples", SCORE, "score on 2 samples", score(
            lambda c: c.u[:2], lambda c: c.z[:2]), good_score,
            "R² = 1 (exact model) or a refusal naming the record", names=("u", "z", "samples"),
            expected="correct", warn_words=("sample", "samples"), needs=needs),
        refuse("score.z.nan", SCORE, "z[9] = NaN", score(
            _u, lambda c: _with_value(c.z, 9, np.nan)), "z", needs=needs),
        refuse("score.z.width", SCORE, "z with 2 columns", score(
            _u, lambda c: np.hstack([c.z] * 2)), "z", needs=needs),
        refuse("score.z.shorter", SCORE, "z of 299 samples", score(_u, lambda c: c.z[:-1]),
               ("u", "z"), needs=needs),
        refuse("score.sample_weight.length", SCORE, "sample_weight of 10 entries", score(
            _u, _z, sample_weight=np.ones(10)), "sample_weight", needs=needs),
        refuse("score.sample_weight.negative", SCORE, "sample_weight all -1", score(
            _u, _z, sample_weight=-np.ones(300)), "sample_weight", needs=needs),
        refuse("score.sample_weight.nan", SCORE, "sample_weight with a NaN", score(
            _u, _z, sample_weight=_with_value(np.ones(300), 100, np.nan)), "sample_weight",
            needs=needs),
        refuse("score.sample_index.nan", SCORE, "sample_index with a NaN", score(
            _u, _z, sample_index=_with_value(np.arange(300.0), 3, np.nan)), "sample_index",
            needs=needs),
        accept("score.init_window.huge", SCORE, "init_window = 10**6 (record of 300)",
               lambda c: c.fit(init_window=10**6).score(c.u, c.z), good_score,
               "a refusal naming init_window (at fit or score), or R² = 1", names=(
                   "init_window",), expected="clear"),
        accept("score.init_window.record", SCORE, "init_window = 300 (the whole record)",
               lambda c: c.fit(init_window=300).score(c.u, c.z), good_score,
               "a refusal naming init_window, or R² = 1", names=("init_window",),
               expected="clear"),
        accept("score.short-record", SCORE, "score on 5 samples",
               score(lambda c: c.u[:5], lambda c: c.z[:5]), good_score, "R² = 1", needs=needs),
        accept("score.records", SCORE, "score on two records",
               score(lambda c: [c.u[:150], c.u[150:]], lambda c: [c.z[:150], c.z[150:]]),
               good_score, "R² = 1", needs=needs),
    ]  # fmt: skip


# ---------------------------------------------------------------------- hyperparameters
NUMBER_VALUES = (
    ("negative", -1.0), ("nan", math.nan), ("inf", math.inf), ("str-4", "4"),
    ("str-abc", "abc"), ("none", None), ("true", True), ("list", [0.1]),
)  # fmt: skip
INTEGER_VALUES = (
    ("zero", 0), ("negative", -1), ("float", 1.5), ("str-4", "4"), ("str-abc", "abc"),
    ("true", True), ("nan", math.nan),
)  # fmt: skip


def _inequality(x, u, theta):
    return x - 10.0


def _equality(x, u, theta):
    return 0.0 * x


def _active_estimator(name: str):
    """Settings under which the hyperparameter ``name`` matters."""
    if name in ("gamma", "prune_tol", "l1_smoothing", "refit"):
        return lambda c: {"library": c.poly2()}
    if name == "lam":
        return lambda c: {"physics": linear_physics(inequality=_inequality)}
    if name == "nu":
        return lambda c: {"physics": linear_physics(equality=_equality)}
    if name == "shooting_weight":
        return lambda c: {"horizon": 50}
    return lambda c: {}


def _fit_param(name, value):
    active = _active_estimator(name)
    return lambda c: c.fit(**active(c), **{name: value})


def number_parameter_cases() -> list[Case]:
    cases = []
    for name in ("gamma", "lam", "nu", "prune_tol", "l1_smoothing", "shooting_weight", "tol"):
        for label, value in NUMBER_VALUES:
            if label == "none" and name in ("tol",):
                continue
            if label == "true":  # True is the number 1: judged by the result
                cases.append(
                    accept(f"fit.{name}.true", FIT, f"{name}=True (a bool for a float)",
                           _fit_param(name, True), same_as_value(name, 1.0),
                           f"the fit with {name}=1.0, or a refusal naming {name}",
                           accept_class="harmless", names=(name,), expected="clear or harmless")
                )  # fmt: skip
                continue
            cases.append(
                refuse(f"fit.{name}.{label}", FIT, f"{name}={value!r}", _fit_param(name, value),
                       name)
            )  # fmt: skip
    cases += [
        refuse("fit.prune_tol.one", FIT, "prune_tol=1 (the interval is [0, 1))",
               _fit_param("prune_tol", 1.0), "prune_tol"),
        refuse("fit.l1_smoothing.zero", FIT, "l1_smoothing=0", _fit_param("l1_smoothing", 0.0),
               "l1_smoothing"),
        refuse("fit.gamma.complex", FIT, "gamma=1j", _fit_param("gamma", 1j), "gamma"),
        refuse("fit.gamma.array", FIT, "gamma=np.array([0.01, 0.1])",
               _fit_param("gamma", np.array([0.01, 0.1])), "gamma"),
        accept("fit.gamma.numpy-float", FIT, "gamma=np.float32(0.01)",
               _fit_param("gamma", np.float32(0.01)), recovers_truth, "the truth"),
    ]  # fmt: skip
    return cases


def same_as_value(name: str, value):
    """The same fit as with ``name=value``."""

    def check(est, ctx):
        reference = _fit_param(name, value)(ctx)
        error = float(np.max(np.abs(est.theta_ - reference.theta_)))
        if est.coef_.size or reference.coef_.size:
            error = max(error, float(np.max(np.abs(est.coef_ - reference.coef_))))
        return error < 1e-9, f"differs from the fit with {name}={value!r} by {error:.1e}"

    return check


def integer_parameter_cases() -> list[Case]:
    cases = []
    for name in ("horizon", "max_iter", "init_window", "verbose"):
        for label, value in INTEGER_VALUES:
            if name in ("init_window",) and label == "zero":
                continue  # documented: simulate from x0_
            if name == "verbose" and label in ("zero", "true"):
                continue  # valid
            cases.append(
                refuse(f"fit.{name}.{label}", FIT, f"{name}={value!r}", _fit_param(name, value),
                       name)
            )  # fmt: skip
    cases += [
        refuse("fit.horizon.longer", FIT, "horizon=301 (record of 300)",
               _fit_param("horizon", 301), "horizon"),
        refuse("fit.horizon.huge", FIT, "horizon=10**6", _fit_param("horizon", 10**6), "horizon"),
        refuse("fit.max_iter.huge-float", FIT, "max_iter=1e9 (a float)",
               _fit_param("max_iter", 1e9), "max_iter"),
        accept("fit.horizon.record", FIT, "horizon=300 (the whole record)",
               _fit_param("horizon", 300), recovers_truth, "the truth"),
        accept("fit.horizon.one", FIT, "horizon=1 (windows of one step)",
               _fit_param("horizon", 1), recovers_truth, "the truth"),
        accept("fit.horizon.numpy-int", FIT, "horizon=np.int64(20)",
               _fit_param("horizon", np.int64(20)), recovers_truth, "the truth"),
        accept("fit.max_iter.one", FIT, "max_iter=1 (stops early)",
               _fit_param("max_iter", 1), stopped_with_warning,
               "converged_ False with a ConvergenceWarning", warn_words=("converge",)),
    ]  # fmt: skip
    return cases


def stopped_with_warning(est, ctx=None) -> tuple[bool, str]:
    """Right if the fit is the truth, or says it did not converge (then judged by its
    warning: classified ``warned`` when one names it)."""
    ok, detail = recovers_truth(est)
    return ok, f"{detail}, converged_={est.converged_}"


def choice_parameter_cases() -> list[Case]:
    bad = {
        "solver": ("newton", "", None, 3, "LM"),
        "lm_scaling": ("x", None, 1),
        "refit": ("yes", 1, None, "no"),
        "warm_start": ("yes", 1, None),
        "random_state": ("abc", -1, 1.5, [1]),
        "delta_states": ([5], [-1], [0, 0], [0.5], "0", [], [[0]], True, 0.0),
        "delta_outputs": ([3], [0, 0], [], ["a"], [-1], 1.5),
        "optimizer": ("adam", 3, object()),
        "physics": ("tanks", {}, "PhysicsModel-class", "a-function", "an-estimator"),
    }
    cases = []
    for name, values in bad.items():
        for value in values:
            label = _label(value)
            extra = {}
            if name in ("delta_states", "delta_outputs", "refit"):
                extra = {"library": "poly2"}
            if name == "optimizer":
                extra = {"solver": "optax"}
            cases.append(
                refuse(f"fit.{name}.{label}", FIT, f"{name}={_shown(value)}",
                       _fit_choice(name, value, extra), name)
            )  # fmt: skip
    cases += [
        refuse("fit.optimizer.with-lm", FIT, "optimizer='adam' with solver='lm'",
               _fit_choice("optimizer", "adam", {"solver": "lm"}), "optimizer"),
        accept("fit.delta_states.no-library", FIT, "delta_states=[0] without a library",
               _fit_choice("delta_states", [0], {}), recovers_truth,
               "the truth (nothing to correct), or a refusal naming delta_states",
               accept_class="harmless", names=("delta_states",)),
        accept("fit.delta_outputs.no-library", FIT, "delta_outputs=[0] without a library",
               _fit_choice("delta_outputs", [0], {}), recovers_truth,
               "the truth (nothing to correct), or a refusal naming delta_outputs",
               accept_class="harmless", names=("delta_outputs",)),
        accept("fit.delta_states.tuple", FIT, "delta_states=(0,) with a library",
               _fit_choice("delta_states", (0,), {"library": "poly2"}), recovers_truth,
               "the truth"),
        accept("fit.solver.optax", FIT, "solver='optax' (valid, first-order)",
               _fit_choice("solver", "optax", {"max_iter": 2000}), lambda e, c: recovers_truth(
                   e, c, tol=1e-2), "the truth within 1 %, or a ConvergenceWarning",
               warn_words=("converge",)),
    ]  # fmt: skip
    return cases


def _label(value) -> str:
    if isinstance(value, str):
        return f"str-{value or 'empty'}"
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list):
        return "list-" + "-".join(_label(v) for v in value) if value else "empty-list"
    if isinstance(value, float):
        return f"float-{value:g}"
    if isinstance(value, int):
        return f"int-{value}"
    return type(value).__name__


def _shown(value) -> str:
    return "object()" if type(value) is object else repr(value)


def _fit_choice(name, value, extra):
    def run(c):
        settings = dict(extra)
        if settings.get("library") == "poly2":
            settings["library"] = c.poly2()
        chosen = _special_physics(value) if name == "physics" else value
        return c.fit(**settings, **{name: chosen})

    return run


def _special_physics(value):
    from sk_offwhite import GreyBoxSparseRegressor, PhysicsModel

    specials = {
        "PhysicsModel-class": PhysicsModel,
        "a-function": linear_step,
        "an-estimator": GreyBoxSparseRegressor(),
    }
    return specials.get(value, value) if isinstance(value, str) else value


# ---------------------------------------------------------------------- libraries
def _library(kind: str):
    import pysindy as ps

    if kind == "pde":
        return ps.PDELibrary(
            function_library=ps.PolynomialLibrary(degree=1), derivative_order=1,
            spatial_grid=np.linspace(0, 1, 10),
        )  # fmt: skip
    if kind == "weak-pde":
        return object.__new__(ps.WeakPDELibrary)  # its __init__ fails with numpy 2
    if kind == "sindy-pi":
        return ps.SINDyPILibrary(library_functions=[lambda x: x], t=np.linspace(0, 1, 10))
    if kind == "empty-custom":
        return ps.CustomLibrary(library_functions=[])
    if kind == "nan-feature":
        return ps.CustomLibrary(library_functions=[lambda x: jnp.log(x - 100.0)])
    if kind == "numpy-feature":
        return ps.CustomLibrary(library_functions=[lambda x: np.asarray(x) ** 2])
    if kind == "class":
        return ps.PolynomialLibrary
    if kind == "polynomial-empty":
        return ps.PolynomialLibrary(degree=0, include_bias=False)
    if kind == "scaler":
        from sklearn.preprocessing import StandardScaler

        return StandardScaler()
    if kind == "identity":
        return ps.IdentityLibrary()
    return {"string": "poly", "int": 3, "object": object()}[kind]


def library_cases() -> list[Case]:
    """The dictionaries a fit may be given. pysindy refuses ``GeneralizedLibrary([])`` and
    ``FourierLibrary(n_frequencies=0)`` in their constructors, before the package sees them,
    so they are no input of the package's and are not cases."""
    kinds = {
        "pde": "pysindy PDELibrary", "weak-pde": "pysindy WeakPDELibrary",
        "sindy-pi": "pysindy SINDyPILibrary", "empty-custom": "CustomLibrary([])",
        "nan-feature": "CustomLibrary([log(x - 100)]): NaN on the data",
        "numpy-feature": "CustomLibrary with np.asarray in a feature (not traceable)",
        "class": "the class PolynomialLibrary, not an instance",
        "polynomial-empty": "PolynomialLibrary(degree=0, include_bias=False): no terms",
        "scaler": "sklearn StandardScaler", "string": "library='poly'", "int": "library=3",
        "object": "library=object()",
    }  # fmt: skip
    cases = [
        refuse(f"fit.library.{kind}", FIT, what, _fit_library(kind), ("library", "Library"))
        for kind, what in kinds.items()
    ]
    cases.append(
        accept("fit.library.identity", FIT, "IdentityLibrary (valid)", _fit_library("identity"),
               recovers_truth, "the truth (the physics is exact)")
    )  # fmt: skip
    return cases


def _fit_library(kind):
    import warnings

    def run(c):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            library = _library(kind)
        return c.fit(library=library)

    return run


# ---------------------------------------------------------------------- Parameter, PhysicsModel
PARAMETER = "Parameter"
PHYSICS = "PhysicsModel"
FROM_ODE = "PhysicsModel.from_ode"


def _parameter(**kwargs):
    from sk_offwhite import Parameter

    return lambda c: Parameter(**kwargs)


def _physics_gain(spec):
    """A model whose parameter ``gain`` is ``spec`` (a Parameter's keyword arguments)."""

    def run(c):
        from sk_offwhite import Parameter, PhysicsModel

        def step(x, u, theta):
            return theta["gain"] * x + 0.5 * u

        parameters = {"gain": Parameter(**spec)}
        return c.fit(physics=PhysicsModel(step, [0], parameters, 1, 1))

    return run


def parameter_cases() -> list[Case]:
    refusals = [
        ("value.nan", {"value": math.nan}, "value"),
        ("value.inf", {"value": math.inf}, "value"),
        ("value.str-abc", {"value": "abc"}, "value"),
        ("value.none", {"value": None}, "value"),
        ("value.list", {"value": [1.0, 2.0]}, "value"),
        ("value.complex", {"value": 1 + 2j}, "value"),
        ("bounds.reversed", {"value": 0.5, "bounds": (1.0, 0.0)}, "bounds"),
        ("bounds.one", {"value": 0.5, "bounds": (0.0,)}, "bounds"),
        ("bounds.scalar", {"value": 0.5, "bounds": 5}, "bounds"),
        ("bounds.strings", {"value": 0.5, "bounds": ("a", 1.0)}, "bounds"),
        ("bounds.nan", {"value": 0.5, "bounds": (math.nan, 1.0)}, "bounds"),
        ("bounds.equal-outside", {"value": 0.5, "bounds": (1.0, 1.0)}, ("bounds", "value")),
        ("value.outside", {"value": 2.0, "bounds": (0.0, 1.0)}, ("bounds", "value")),
        ("fixed.str-yes", {"value": 0.5, "fixed": "yes"}, "fixed"),
        ("fixed.str-no", {"value": 0.5, "fixed": "no"}, "fixed"),
        ("relaxable.str", {"value": 0.5, "fixed": True, "relaxable": "no"}, "relaxable"),
        ("relaxable.free", {"value": 0.5, "relaxable": True}, "relaxable"),
    ]
    cases = [
        refuse(f"Parameter.{label}", PARAMETER, f"Parameter({_kwargs(kwargs)})",
               _parameter(**kwargs), names)
        for label, kwargs, names in refusals
    ]  # fmt: skip
    cases += [
        accept("Parameter.value.str-4", PARAMETER, "Parameter('4') fitted as the gain",
               _physics_gain({"value": "4"}), gain_fitted,
               "a refusal naming value, or the fitted gain 0.8 and a working repr",
               accept_class="harmless", names=("value",)),
        accept("Parameter.fixed.int", PARAMETER, "Parameter(0.5, fixed=0)",
               _parameter(value=0.5, fixed=0), lambda p, c: (not p.fixed, f"fixed={p.fixed!r}"),
               "a free parameter", accept_class="harmless"),
        accept("Parameter.value.numpy", PARAMETER, "Parameter(np.float32(0.5))",
               _parameter(value=np.float32(0.5)), returned, "accepted"),
        accept("Parameter.fixed.str-no-fit", PARAMETER,
               "Parameter(0.8, fixed='no') fitted: the gain stays fixed?",
               _physics_gain({"value": 0.5, "fixed": "no"}), gain_fitted,
               "a refusal naming fixed, or the gain fitted (0.8)", expected="clear",
               names=("fixed",)),
    ]  # fmt: skip
    return cases


def gain_fitted(est, ctx=None) -> tuple[bool, str]:
    gain = est.parameters_["gain"]
    try:
        text = repr(est.physics_)
    except Exception as error:  # a repr that fails is part of what is wrong
        return False, f"gain={gain:.6g}; repr(physics) raised {type(error).__name__}: {error}"
    return abs(gain - 0.8) < 1e-4, f"gain={gain:.6g}; {text[:60]}"


def _kwargs(kwargs) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in kwargs.items())


def _model(**changes):
    """``PhysicsModel(linear_step, [0], {...}, 1, 1)`` with ``changes``."""

    def run(c):
        from sk_offwhite import Parameter, PhysicsModel

        arguments = dict(
            step=linear_step, output=[0], parameters={"a": Parameter(0.5), "b": Parameter(0.1)},
            n_states=1, n_inputs=1,
        ) | changes  # fmt: skip
        return PhysicsModel(**arguments)

    return run


def physics_cases() -> list[Case]:
    refusals = [
        ("x0.str-abc", {"x0": "abc"}, "x0"),
        ("x0.nan", {"x0": [math.nan]}, "x0"),
        ("x0.inf", {"x0": [math.inf]}, "x0"),
        ("x0.length", {"x0": [0.0, 0.0]}, "x0"),
        ("x0.none-entry", {"x0": [None]}, "x0"),
        ("x0_fixed.str-yes", {"x0_fixed": "yes"}, "x0_fixed"),
        ("x0_fixed.length", {"x0_fixed": [True, False]}, "x0_fixed"),
        ("x0_fixed.int", {"x0_fixed": 2}, "x0_fixed"),
        ("x0_bounds.reversed", {"x0_bounds": (1.0, 0.0)}, "x0_bounds"),
        ("x0_bounds.excludes-x0", {"x0": [5.0], "x0_bounds": (0.0, 1.0)}, ("x0_bounds", "x0")),
        ("x0_bounds.string", {"x0_bounds": "ab"}, "x0_bounds"),
        ("n_states.zero", {"n_states": 0}, "n_states"),
        ("n_states.negative", {"n_states": -1}, "n_states"),
        ("n_states.float", {"n_states": 2.0}, "n_states"),
        ("n_states.str", {"n_states": "2"}, "n_states"),
        ("n_states.bool", {"n_states": True}, "n_states"),
        ("n_inputs.negative", {"n_inputs": -1}, "n_inputs"),
        ("n_inputs.float", {"n_inputs": 1.5}, "n_inputs"),
        ("step.string", {"step": "f"}, "step"),
        ("step.none", {"step": None}, "step"),
        ("output.index", {"output": [5]}, "output"),
        ("output.empty", {"output": []}, "output"),
        ("output.string", {"output": "x"}, "output"),
        ("output.fraction", {"output": [0.5]}, "output"),
        ("output.negative", {"output": [-1]}, "output"),
        ("parameters.list", {"parameters": [("a", 0.5), ("b", 0.1)]}, "parameters"),
        ("parameters.str-value", {"parameters": {"a": "abc", "b": 0.1}}, ("parameters", "a")),
        ("parameters.none-value", {"parameters": {"a": None, "b": 0.1}}, ("parameters", "a")),
        ("parameters.nan-value", {"parameters": {"gain": math.nan}}, ("gain",)),
        ("state_names.length", {"state_names": ["h1", "h2"]}, "state_names"),
        (
            "state_names.duplicate",
            {"n_states": 2, "output": [0], "x0": [0, 0], "state_names": ["h", "h"]},
            "state_names",
        ),
        ("input_names.length", {"input_names": ["u1", "u2"]}, "input_names"),
        ("output_names.length", {"output_names": ["y1", "y2"]}, "output_names"),
        ("state_kinds.unknown", {"state_kinds": ["liquid"]}, "state_kinds"),
        ("state_kinds.length", {"state_kinds": ["level", "level"]}, "state_kinds"),
        ("state_kinds.string", {"state_kinds": "level"}, "state_kinds"),
        ("input_kinds.unknown", {"input_kinds": ["pressure"]}, "input_kinds"),
        ("inequality.string", {"inequality": "x <= 10"}, "inequality"),
        ("equality.number", {"equality": 0.0}, "equality"),
    ]
    return [
        refuse(f"PhysicsModel.{label}", PHYSICS, f"PhysicsModel({_kwargs(kwargs)})",
               _fit_model(kwargs), names)
        for label, kwargs, names in refusals
    ] + [
        accept("PhysicsModel.n_states.too-many", PHYSICS,
               "n_states=2 for the 1-state step (it broadcasts to 2 copies)",
               _fit_model({"n_states": 2, "x0": [0.0, 0.0]}), recovers_truth,
               "a refusal naming n_states, or the truth", accept_class="harmless",
               names=("n_states",), expected="clear or harmless"),
        refuse("from_ode.n_states.too-few", FROM_ODE, "the two-tank rhs with n_states=1",
               lambda c: c.fit(*c.tanks(), physics=_tanks_states(1)), ("n_states", "step")),
    ]  # fmt: skip


def _tanks_states(n_states: int):
    from sk_offwhite import PhysicsModel

    parameters = dict.fromkeys(("k1", "k2", "k3", "k4"), 0.08)
    x0 = [5.0] * n_states
    return PhysicsModel.from_ode(tanks_rhs, 4.0, [0], parameters, n_states, 1, x0=x0)


def _fit_model(changes):
    """Build the model with ``changes`` and fit it (a refusal may come at either)."""
    build = _model(**changes)
    return lambda c: c.fit(physics=build(c))


def from_ode_cases() -> list[Case]:
    def ode(**changes):
        def run(c):
            physics = _tanks_at(changes.get("sampling_time", 4.0), changes)
            u, z = c.tanks()
            return c.fit(u, z, physics=physics)

        return run

    cases = [
        refuse(f"from_ode.{label}", FROM_ODE, what, ode(**changes), names)
        for label, what, changes, names in (
            ("sampling_time.str", "sampling_time='4'", {"sampling_time": "4"}, "sampling_time"),
            ("sampling_time.zero", "sampling_time=0", {"sampling_time": 0}, "sampling_time"),
            ("sampling_time.negative", "sampling_time=-4", {"sampling_time": -4.0},
             "sampling_time"),
            ("sampling_time.nan", "sampling_time=nan", {"sampling_time": math.nan},
             "sampling_time"),
            ("sampling_time.inf", "sampling_time=inf", {"sampling_time": math.inf},
             "sampling_time"),
            ("sampling_time.none", "sampling_time=None", {"sampling_time": None},
             "sampling_time"),
            ("method.unknown", "method='rk5'", {"method": "rk5"}, "method"),
            ("n_substeps.zero", "n_substeps=0", {"n_substeps": 0}, "n_substeps"),
            ("n_substeps.float", "n_substeps=2.5", {"n_substeps": 2.5}, "n_substeps"),
            ("x0.length", "x0 of 3 entries for 2 states", {"x0": [5.0, 6.0, 7.0]}, "x0"),
        )
    ]  # fmt: skip
    cases.append(
        accept("from_ode.sampling_time.numpy", FROM_ODE, "sampling_time=np.float32(4)",
               ode(sampling_time=np.float32(4.0)), tanks_fit_good, "a simulation R² > 0.999")
    )  # fmt: skip
    return cases


def _tanks_at(sampling_time, changes):
    from sk_offwhite import Parameter, PhysicsModel

    parameters = {k: Parameter(v, bounds=(0, None)) for k, v in
                  {"k1": 0.1, "k2": 0.075, "k3": 0.07}.items()}  # fmt: skip
    parameters["k4"] = Parameter(0.088, fixed=True)
    rest = {k: v for k, v in changes.items() if k != "sampling_time"}
    settings = dict(method="euler", x0=[5.0, 6.0]) | rest
    return PhysicsModel.from_ode(tanks_rhs, sampling_time, [1], parameters, 2, 1, **settings)


def tanks_fit_good(est, ctx) -> tuple[bool, str]:
    u, z = ctx.tanks()
    return good_score(est.score(u, z))


# ---------------------------------------------------------------------- the user's functions
def _step_reading_u3(x, u, theta):
    return theta["a"] * x + theta["b"] * u[3]


def _step_reading_x1(x, u, theta):
    return theta["a"] * x[1] + theta["b"] * u


def _tanks_reading_x5(x, u, theta):
    root = jnp.sqrt(jnp.maximum(x, 1e-6))
    return jnp.stack([-theta["k1"] * root[0] + theta["k4"] * u[0],
                      theta["k2"] * root[0] - theta["k3"] * root[5]])  # fmt: skip


def _step_numpy(x, u, theta):
    return np.asarray(x) * 0.5 + theta["b"] * u


def _step_python_if(x, u, theta):
    if x[0] > 0:
        return theta["a"] * x + theta["b"] * u
    return theta["b"] * u


def _step_float(x, u, theta):
    return 1.0


def _step_scalar(x, u, theta):
    return theta["a"] * x[0] + theta["b"] * u[0]


def _step_list(x, u, theta):
    return [theta["a"] * x[0] + theta["b"] * u[0]]


def _step_two(x, u, theta):
    return jnp.concatenate([theta["a"] * x, theta["b"] * u])


def _step_nan(x, u, theta):
    return jnp.log(x - 100.0) * theta["a"]


def _step_nan_later(x, u, theta):
    return theta["a"] * x + theta["b"] * u + 0.0 * jnp.sqrt(x + 0.2)


def _step_unknown_parameter(x, u, theta):
    return theta["c"] * x + theta["b"] * u


def _step_two_arguments(x, u):
    return 0.8 * x + 0.5 * u


def _step_complex(x, u, theta):
    return (theta["a"] * x + theta["b"] * u) * (1.0 + 0.0j)


def _step_bool(x, u, theta):
    return x > 0


def _step_tuple(x, u, theta):
    return theta["a"] * x + theta["b"] * u, x


def _step_dict(x, u, theta):
    return {"x": theta["a"] * x + theta["b"] * u}


def _output_wrong(x, u, theta):
    return jnp.concatenate([x, x])


def _output_nan(x, u, theta):
    return x * jnp.nan


def _output_reading_u3(x, u, theta):
    return x + 0.0 * u[3]


def _inequality_untraceable(x, u, theta):
    return np.asarray(x) - 10.0


def _inequality_nan(x, u, theta):
    return x * jnp.nan


def function_cases() -> list[Case]:
    def with_step(step, n_states=1, **kwargs):
        return lambda c: c.fit(physics=physics_with_step(step, n_states, **kwargs))

    refusals = [
        ("step.shape", "step returns shape (2,) for 1 state", with_step(_step_two), "step"),
        ("step.list", "step returns a one-element list", with_step(_step_list), "step"),
        (
            "step.nan",
            "step returns NaN at the initial guess (log(x - 100))",
            with_step(_step_nan),
            "step",
        ),
        (
            "step.reads-u3",
            "step reads u[3] with n_inputs=1 (JAX clamps the index)",
            with_step(_step_reading_u3),
            ("step", "u"),
        ),
        (
            "step.reads-x1",
            "step reads x[1] with 1 state (JAX clamps the index)",
            with_step(_step_reading_x1),
            ("step", "x"),
        ),
        ("step.numpy", "step uses np.asarray on a tracer", with_step(_step_numpy), "step"),
        (
            "step.python-if",
            "step branches with a Python if on a tracer",
            with_step(_step_python_if),
            "step",
        ),
        (
            "step.float",
            "step returns the Python float 1.0 (1 state)",
            with_step(_step_float),
            "step",
        ),
        (
            "step.float-2states",
            "step returns a float for 2 states",
            with_step(_step_float, 2, x0=[0.0, 0.0]),
            "step",
        ),
        (
            "step.unknown-parameter",
            "step reads theta['c'], not declared",
            with_step(_step_unknown_parameter),
            ("step", "c"),
        ),
        (
            "step.two-arguments",
            "step takes (x, u), not (x, u, theta)",
            with_step(_step_two_arguments),
            "step",
        ),
        ("step.complex", "step returns complex values", with_step(_step_complex), "step"),
        ("step.bool", "step returns booleans", with_step(_step_bool), "step"),
        ("step.tuple", "step returns a tuple (x_next, x)", with_step(_step_tuple), "step"),
        ("step.dict", "step returns a dict", with_step(_step_dict), "step"),
        (
            "output.shape",
            "output returns 2 values for 1 output",
            lambda c: c.fit(physics=_callable_output(_output_wrong)),
            "output",
        ),
        (
            "output.nan",
            "output returns NaN",
            lambda c: c.fit(physics=_callable_output(_output_nan)),
            "output",
        ),
        (
            "output.reads-u3",
            "output reads u[3] with n_inputs=1",
            lambda c: c.fit(physics=_callable_output(_output_reading_u3)),
            ("output", "u"),
        ),
        (
            "inequality.untraceable",
            "inequality uses np.asarray on a tracer",
            lambda c: c.fit(physics=linear_physics(inequality=_inequality_untraceable), lam=1.0),
            "inequality",
        ),
        (
            "inequality.nan",
            "inequality returns NaN (lam=1)",
            lambda c: c.fit(physics=linear_physics(inequality=_inequality_nan), lam=1.0),
            "inequality",
        ),
    ]
    cases = [refuse(f"physics.{label}", FIT, what, run, names)
             for label, what, run, names in refusals]  # fmt: skip
    cases += [
        refuse("physics.tanks.reads-x5", FIT, "two-tank rhs reads x[5] with 2 states",
               lambda c: c.fit(*c.tanks(), physics=tanks_physics(_tanks_reading_x5)),
               ("rhs", "step", "x")),
        accept("physics.step.scalar", FIT, "step returns a 0-d array for 1 state (documented)",
               with_step(_step_scalar), recovers_truth, "the truth"),
        accept("physics.step.nan-later", FIT,
               "step is NaN once x < -0.2 (reached on the record), finite at the guess",
               with_step(_step_nan_later), recovers_truth,
               "a refusal naming the step / the sample, or the truth where it stays finite",
               names=("step",), early=False, warn_words=("finite", "nan", "diverge")),
    ]  # fmt: skip
    return cases


def _callable_output(output):
    from sk_offwhite import Parameter, PhysicsModel

    parameters = {"a": Parameter(0.5), "b": Parameter(0.1)}
    return PhysicsModel(linear_step, output, parameters, 1, 1)


# ---------------------------------------------------------------------- useless or degenerate fits
def _saturating_input_step(x, u, theta):
    return theta["a"] * x + theta["b"] * jnp.tanh(theta["c"] * u)


def fit_quality_cases() -> list[Case]:
    def shooting(a_true):
        def run(c):
            u, _ = linear_record()
            z = linear_record_for_a(u, a_true)
            est = c.fit(u, z, physics=linear_physics(a=2.0), horizon=20)
            return est, u, z

        return run

    def saddle(c):
        from sk_offwhite import Parameter, PhysicsModel

        parameters = {"a": Parameter(0.5), "b": Parameter(0.0), "c": Parameter(0.0)}
        physics = PhysicsModel(_saturating_input_step, [0], parameters, 1, 1)
        return c.fit(physics=physics), c.u, c.z

    def at_bounds(c):
        from sk_offwhite import Parameter

        parameters = {"a": Parameter(0.05, bounds=(0, 0.1)), "b": Parameter(0.01, bounds=(0, 0.05))}
        return c.fit(physics=linear_physics(parameters=parameters)), c.u, c.z

    shooting_words = ("horizon", "diverg", "free run", "free-run", "simulation")
    input_words = ("input", "sensitiv", "depend", "identifiab", "gradient")
    return [
        accept("fit.shooting.a=0.8-from-2", FIT,
               "horizon=20, first guess a=2 (unstable), true a=0.8, noise-free",
               shooting(0.8), free_run_matches_windows,
               "converged_ and a free run as good as the windows, or a warning",
               warn_words=shooting_words),
        accept("fit.shooting.a=-0.2-from-2", FIT,
               "horizon=20, first guess a=2 (unstable), true a=-0.2, noise-free",
               shooting(-0.2), free_run_matches_windows,
               "converged_ and a free run as good as the windows, or a warning",
               warn_words=shooting_words),
        accept("fit.degenerate.saddle", FIT,
               "x+ = a x + b tanh(c u) started at b = c = 0: no gradient reaches the input",
               saddle, depends_on_input,
               "the output depends on u (the data do), or a warning that it does not",
               expected="clear (warned) or correct", warn_words=input_words),
        accept("fit.degenerate.at-bounds", FIT,
               "bounds a in [0, 0.1], b in [0, 0.05] (truth 0.8, 0.5): every parameter ends "
               "at a bound", at_bounds, not_all_at_bounds,
               "a warning that the parameters sit at their bounds", expected="clear (warned)",
               warn_words=("bound", "bounds")),
    ]  # fmt: skip


def linear_record_for_a(u, a):
    x = np.empty(len(u))
    x[0] = TRUE_X0
    for k in range(len(u) - 1):
        x[k + 1] = a * x[k] + TRUE["b"] * u[k, 0]
    return x[:, None]


def free_run_matches_windows(value, ctx=None) -> tuple[bool, str]:
    """Right: not converged (then judged by its warning), or a free run over the record
    from ``x0_`` within 10 times the windows' error (and 1e-6 output std)."""
    est, u, z = value
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        simulated = est.predict(u, x0=est.x0_).reshape(z.shape)
    error = float(np.sqrt(np.mean((simulated - z) ** 2)) / np.std(z))
    ok = np.isfinite(error) and error <= 10 * est.fit_error_ + 1e-6
    detail = (f"converged_={est.converged_}, windows' error {est.fit_error_:.2e}, free-run "
              f"error {error:.2e}, a={est.parameters_['a']:.4g}")  # fmt: skip
    return bool(ok or not est.converged_), detail


def depends_on_input(value, ctx=None) -> tuple[bool, str]:
    est, u, z = value
    change = float(np.max(np.abs(est.predict(u + 0.5) - est.predict(u))))
    return change > 1e-6, f"output change for u + 0.5: {change:.1e}; {est.parameters_}"


def not_all_at_bounds(value, ctx=None) -> tuple[bool, str]:
    est, u, z = value
    lower, upper = est.physics_.parameter_bounds()
    theta = est.theta_
    at = np.isclose(theta, lower) | np.isclose(theta, upper)
    return not bool(
        np.all(at)
    ), f"theta {theta} against bounds {list(zip(lower, upper, strict=True))}"


# ---------------------------------------------------------------------- cross-validation misuse
CV = "model_selection"


def cv_cases() -> list[Case]:
    from sklearn.model_selection import KFold, LeaveOneOut, TimeSeriesSplit

    from sk_offwhite import SequenceSplit

    def cross_val(cv, index=False, library=False):
        def run(c):
            from sklearn.model_selection import cross_val_score

            est = c.estimator(library=c.poly2() if library else None)
            params = {"sample_index": np.arange(len(c.u))} if index else None
            return cross_val_score(est, c.u, c.z, cv=cv, params=params)

        return run

    def grid(index=False):
        def run(c):
            from sklearn.model_selection import GridSearchCV

            search = GridSearchCV(
                c.estimator(library=c.poly2()), {"gamma": [1e-4, 1e-2]}, cv=KFold(3)
            )
            params = {"sample_index": np.arange(len(c.u))} if index else {}
            return search.fit(c.u, c.z, **params)

        return run

    words = ("sample_index", "contiguous", "gap", "SequenceSplit", "shuffle", "record")
    common = dict(names=("sample_index",), warn_words=words, limit=150.0)
    return [
        accept("cv.grid.kfold3-no-index", CV,
               "GridSearchCV(est, {'gamma': [1e-4, 1e-2]}, cv=KFold(3)) without sample_index",
               grid(), grid_scores_exact, "every fold's R² = 1, or a warning naming the gap",
               expected="clear (warned)", **common),
        accept("cv.grid.kfold3-index", CV, "the same search with sample_index (documented)",
               grid(True), grid_scores_exact, "every fold's R² = 1", **common),
        accept("cv.kfold3-no-index", CV, "cross_val_score, cv=KFold(3), no sample_index",
               cross_val(KFold(3)), all_cv_scores_exact, "R² = 1 on every fold, or a warning",
               expected="clear (warned)", **common),
        accept("cv.sequence-rest-no-index", CV,
               "cross_val_score, cv=SequenceSplit(3, train='rest'), no sample_index",
               cross_val(SequenceSplit(3, train="rest")), all_cv_scores_exact,
               "R² = 1 on every fold, or a warning", expected="clear (warned)", **common),
        accept("cv.sequence-rest-index", CV,
               "SequenceSplit(3, train='rest') with sample_index (documented)",
               cross_val(SequenceSplit(3, train="rest"), index=True), all_cv_scores_exact,
               "R² = 1 on every fold", **common),
        accept("cv.kfold-shuffled-no-index", CV,
               "cross_val_score, cv=KFold(3, shuffle=True), no sample_index",
               cross_val(KFold(3, shuffle=True, random_state=0)), all_cv_scores_exact,
               "a refusal or a warning that the folds are shuffled", expected="clear (warned)",
               **common),
        accept("cv.kfold-shuffled-index", CV,
               "cv=KFold(3, shuffle=True) with sample_index",
               cross_val(KFold(3, shuffle=True, random_state=0), index=True),
               all_cv_scores_exact, "a SequenceWarning", expected="clear (warned)", **common),
        accept("cv.time-series-split", CV, "cv=TimeSeriesSplit(3) (contiguous, valid)",
               cross_val(TimeSeriesSplit(3)), all_cv_scores_exact, "R² = 1 on every fold",
               **common),
        accept("cv.sequence-longer", CV, "cv=SequenceSplit(3) (default, valid)",
               cross_val(SequenceSplit(3)), all_cv_scores_exact, "R² = 1 on every fold",
               **common),
        accept("cv.leave-one-out", CV, "cv=LeaveOneOut() (one row per test fold)",
               cross_val(LeaveOneOut()), all_cv_scores_exact,
               "a refusal or a warning: a one-row fold cannot be scored", expected="clear",
               **common),
    ] + [
        refuse(f"SequenceSplit.{label}", "SequenceSplit", what, run, names)
        for label, what, run, names in (
            ("n_splits.one", "SequenceSplit(1)", lambda c: SequenceSplit(1), "n_splits"),
            ("n_splits.str", "SequenceSplit('3')", lambda c: SequenceSplit("3"), "n_splits"),
            ("n_splits.bool", "SequenceSplit(True)", lambda c: SequenceSplit(True), "n_splits"),
            ("n_splits.float", "SequenceSplit(2.5)", lambda c: SequenceSplit(2.5), "n_splits"),
            ("train.unknown", "SequenceSplit(3, train='all')",
             lambda c: SequenceSplit(3, train="all"), "train"),
            ("gap.negative", "SequenceSplit(3, gap=-1)", lambda c: SequenceSplit(3, gap=-1),
             "gap"),
            ("too-many", "SequenceSplit(200) on 300 rows",
             lambda c: list(SequenceSplit(200).split(c.u)), "n_splits"),
            ("gap-too-large", "SequenceSplit(3, gap=150) on 300 rows",
             lambda c: list(SequenceSplit(3, gap=150).split(c.u)), "gap"),
        )
    ]  # fmt: skip


# ---------------------------------------------------------------------- fit_gamma_path
PATH = "fit_gamma_path"


def path_cases() -> list[Case]:
    def path(given=True, estimator=None, **kwargs):
        def run(c):
            from sk_offwhite import fit_gamma_path

            est = c.estimator(library=c.poly2()) if estimator is None else estimator(c)
            if given:
                kwargs.setdefault("gammas", kwargs.get("gammas", [1e-2]))
            return fit_gamma_path(est, c.u, c.z, **kwargs)

        return run

    refusals = [
        ("gammas.str", "gammas=['a']", dict(gammas=["a"]), "gammas"),
        ("gammas.negative", "gammas=[-1.0]", dict(gammas=[-1.0]), "gammas"),
        ("gammas.empty", "gammas=[]", dict(gammas=[]), "gammas"),
        ("gammas.nan", "gammas=[nan]", dict(gammas=[math.nan]), "gammas"),
        ("gammas.string", "gammas='abc'", dict(gammas="abc"), "gammas"),
        ("cv.str-given-gammas", "cv='x' with gammas given", dict(cv="x"), "cv"),
        ("cv.one", "cv=1", dict(cv=1), "cv"),
        ("cv.too-many", "cv=1000 on 300 rows", dict(cv=1000), "cv"),
        (
            "init_window.negative",
            "init_window=-1 with cv=3",
            dict(cv=3, init_window=-1),
            "init_window",
        ),
        (
            "init_window.huge",
            "init_window=10**6 with cv=3",
            dict(cv=3, init_window=10**6),
            "init_window",
        ),
        ("n_jobs.str", "n_jobs='many' with cv=3", dict(cv=3, n_jobs="many"), "n_jobs"),
        ("min_improvement.one", "min_improvement=1", dict(min_improvement=1.0), "min_improvement"),
        (
            "min_improvement.nan",
            "min_improvement=nan",
            dict(min_improvement=math.nan),
            "min_improvement",
        ),
        (
            "one_standard_error.str",
            "one_standard_error='yes' with cv=3",
            dict(cv=3, one_standard_error="yes"),
            "one_standard_error",
        ),
        (
            "sample_index.nan",
            "sample_index with a NaN",
            dict(sample_index=_with_value(np.arange(300.0), 2, math.nan)),
            "sample_index",
        ),
    ]
    grid_refusals = [
        ("n_gammas.zero", "n_gammas=0", dict(n_gammas=0), "n_gammas"),
        ("n_gammas.negative", "n_gammas=-3", dict(n_gammas=-3), "n_gammas"),
        ("n_gammas.float", "n_gammas=2.5", dict(n_gammas=2.5), "n_gammas"),
        ("eps.negative", "eps=-1", dict(eps=-1.0), "eps"),
        ("eps.zero", "eps=0", dict(eps=0.0), "eps"),
        ("eps.one", "eps=1", dict(eps=1.0), "eps"),
        ("eps.nan", "eps=nan", dict(eps=math.nan), "eps"),
        ("cv.str", "cv='x' with the default grid", dict(cv="x"), "cv"),
    ]
    cases = [refuse(f"path.{label}", PATH, what, path(True, **kw), names)
             for label, what, kw, names in refusals]  # fmt: skip
    cases += [refuse(f"path.{label}", PATH, what, path(False, **kw), names)
              for label, what, kw, names in grid_refusals]  # fmt: skip
    cases += [
        refuse("path.no-library", PATH, "an estimator without a library",
               path(True, estimator=lambda c: c.estimator()), "library"),
        refuse("path.not-an-estimator", PATH, "estimator=None",
               path(True, estimator=lambda c: None), "estimator"),
        refuse("path.bad-estimator-param", PATH, "an estimator with gamma=-1",
               path(True, estimator=lambda c: c.estimator(library=c.poly2(), gamma=-1.0)),
               "gamma"),
        refuse("path.records", PATH, "u, z as lists of records",
               lambda c: _path_on(c, [c.u[:150], c.u[150:]], [c.z[:150], c.z[150:]]),
               ("u", "z")),
        refuse("path.u.nan", PATH, "u with a NaN",
               lambda c: _path_on(c, _with_value(c.u, 3, math.nan), c.z), "u"),
        accept("path.gammas.2d", PATH, "gammas=[[1e-2, 1e-3]] (2-D)",
               path(True, gammas=[[1e-2, 1e-3]]), path_of_length(2),
               "the path of the two values, or a refusal naming gammas",
               accept_class="harmless", names=("gammas",)),
        accept("path.n_gammas.str", PATH, "n_gammas='8' (a numeric string)",
               path(False, n_gammas="8"), path_of_length(8),
               "the path of 8 values, or a refusal naming n_gammas",
               accept_class="harmless", names=("n_gammas",)),
        accept("path.gammas.increasing", PATH, "gammas=[1e-4, 1e-2] (increasing, documented)",
               path(True, gammas=[1e-4, 1e-2]), lambda p, c: recovers_truth(p.estimator, c),
               "the truth at the last gamma"),
    ]  # fmt: skip
    return cases


def path_of_length(n: int):
    def check(path, ctx=None):
        return len(path.gammas) == n, f"a path of {len(path.gammas)} gammas"

    return check


def _path_on(c, u, z):
    from sk_offwhite import fit_gamma_path

    return fit_gamma_path(c.estimator(library=c.poly2()), u, z, gammas=[1e-2])


# ---------------------------------------------------------------------- the closed loop
LOOP = "close_the_loop"

LOOP_VALUES = {
    "gammas": (("str", ("a",)), ("negative", (-1.0,)), ("empty", ()), ("nan", (math.nan,)),
               ("scalar", 0.1), ("string", "abc")),
    "n_gammas": (("zero", 0), ("negative", -1), ("float", 2.5), ("str", "5"), ("bool", True)),
    "gamma_eps": (("negative", -1.0), ("zero", 0.0), ("one", 1.0), ("two", 2.0),
                  ("nan", math.nan), ("str", "x")),
    "n_folds": (("one", 1), ("zero", 0), ("str", "3"), ("bool", True), ("float", 2.5),
                ("none", None), ("huge", 1000)),
    "horizon": (("zero", 0), ("negative", -5), ("bool", True), ("float", 2.5), ("str", "128")),
    "cv_horizon": (("zero", 0), ("negative", -1), ("bool", True), ("str", "x")),
    "max_iter": (("zero", 0), ("negative", -1), ("bool", True), ("str", "300"),
                 ("float", 1.5)),
    "max_effects": (("negative", -1), ("float", 1.5), ("str", "3"), ("none", None)),
    "min_gain": (("nan", math.nan), ("negative", -1.0), ("inf", math.inf), ("str", "0.05"),
                 ("none", None)),
    "tolerance": (("nan", math.nan), ("negative", -1.0), ("str", "x")),
    "delta_states": (("index", (5,)), ("duplicate", (0, 0)), ("str", "0"), ("negative", (-1,))),
    "init_window": (("huge", 10**6), ("negative", -1), ("bool", True), ("nan", math.nan),
                    ("float", 1.5), ("record", 300)),
    "max_candidates": (("zero", 0), ("str", "3"), ("bool", True), ("float", 1.5)),
    "beam": (("zero", 0), ("negative", -1), ("bool", True), ("float", 1.5), ("str", "4")),
    "min_share": (("nan", math.nan), ("negative", -1.0), ("two", 2.0), ("str", "x")),
    "n_promoted": (("negative", -1), ("float", 1.5), ("str", "3")),
    "fit_delta": (("str-yes", "yes"), ("str-no", "no"), ("none", None)),
    "share_programs": (("str-no", "no"),),
    "selection": (("unknown", "bic"), ("none", None)),
    "tail_fraction": (("zero", 0.0), ("one", 1.0), ("nan", math.nan), ("str", "x")),
    "n_jobs": (("str", "many"), ("zero", 0), ("float", 1.5)),
    "lm_scaling": (("unknown", "x"), ("none", None)),
    "one_standard_error": (("str", "yes"),),
    "release_programs": (("str", "no"),),
    "fit_output_delta": (("str", "no"),),
    "output_bumps": (("one", 1), ("bool", True), ("float", 2.5), ("str", "7")),
}  # fmt: skip


def _loop(settings=None, physics=None, library=None, data=None):
    """``close_the_loop`` with the given pieces (callables of the context) or the clean ones."""

    def run(c):
        from sk_offwhite.loop import close_the_loop

        chosen_physics = c.physics if physics is None else physics(c)
        chosen_library = c.poly2() if library is None else library(c)
        u, z = (c.u, c.z) if data is None else data(c)
        chosen_settings = settings(c) if callable(settings) else settings
        return close_the_loop(chosen_physics, chosen_library, u, z, settings=chosen_settings)

    return run


def _settings(name, value):
    def build(c):
        from sk_offwhite.loop import LoopSettings

        return LoopSettings(**{name: value})

    return build


def loop_cases() -> list[Case]:
    slow = dict(on_timeout="silent")
    cases = [
        refuse(f"loop.{name}.{label}", LOOP, f"LoopSettings({name}={value!r})",
               _loop(_settings(name, value)), name, **slow)
        for name, values in LOOP_VALUES.items()
        for label, value in values
    ]  # fmt: skip
    cases += [
        refuse("loop.library.string", LOOP, "close_the_loop(physics, 'poly', u, z)",
               _loop(library=lambda c: "poly"), "library", **slow),
        refuse("loop.library.pde", LOOP, "library a pysindy PDELibrary",
               _loop(library=lambda c: _library("pde")), ("library", "PDELibrary"), **slow),
        refuse("loop.physics.none", LOOP, "physics=None", _loop(physics=lambda c: None),
               "physics", **slow),
        refuse("loop.physics.string", LOOP, "physics='tanks'",
               _loop(physics=lambda c: "tanks"), "physics", **slow),
        refuse("loop.physics.estimator", LOOP, "physics a GreyBoxSparseRegressor",
               _loop(physics=lambda c: c.estimator()), "physics", **slow),
        refuse("loop.settings.dict", LOOP, "settings={'beam': 2} (a dict)",
               _loop(lambda c: {"beam": 2}), "settings", **slow),
        refuse("loop.settings.string", LOOP, "settings='fast'", _loop(lambda c: "fast"),
               "settings", **slow),
        refuse("loop.settings.estimator", LOOP, "settings an estimator",
               _loop(lambda c: c.estimator()), "settings", **slow),
        refuse("loop.records.list", LOOP, "u, z as lists of two records",
               _loop(data=lambda c: ([c.u[:150], c.u[150:]], [c.z[:150], c.z[150:]])),
               ("u", "z"), **slow),
        refuse("loop.u.nan", LOOP, "u with a NaN",
               _loop(data=lambda c: (_with_value(c.u, 3, math.nan), c.z)), "u", **slow),
        refuse("loop.z.nan", LOOP, "z with a NaN",
               _loop(data=lambda c: (c.u, _with_value(c.z, 3, math.nan))), "z", **slow),
        refuse("loop.u.2cols", LOOP, "u with 2 columns (physics has 1 input)",
               _loop(data=lambda c: (np.hstack([c.u] * 2), c.z)), ("u", "n_inputs"), **slow),
        refuse("loop.z.shorter", LOOP, "z of 299 samples, u of 300",
               _loop(data=lambda c: (c.u, c.z[:-1])), ("u", "z"), **slow),
        refuse("loop.samples.2", LOOP, "a record of 2 samples",
               _loop(data=lambda c: (c.u[:2], c.z[:2])), ("u", "z", "samples"), **slow),
        refuse("loop.samples.40", LOOP, "a record of 40 samples (init_window 50, horizon 128)",
               _loop(data=lambda c: (c.u[:40], c.z[:40])),
               ("u", "z", "samples", "init_window"), **slow),
        accept("loop.valid.cheap", LOOP, "valid cheap settings (a control, not a bad input)",
               _loop(lambda c: cheap_loop()), loop_result_sane,
               "a LoopResult with finite CV errors, choosing the declared physics", limit=240.0),
    ]  # fmt: skip
    return cases


def loop_result_sane(result, ctx=None) -> tuple[bool, str]:
    errors = np.array(list(result.cv_errors.values()), float)
    ok = bool(errors.size and np.all(np.isfinite(errors)))
    return ok, f"chosen {result.chosen}, cv errors {np.round(errors, 6)}"


def scoring_cases() -> list[Case]:
    needs = ("loop_result",)

    def score(records_of, **kwargs):
        def run(c):
            from sk_offwhite.loop import score_models

            return score_models(c.loop_result(), records_of(c), **kwargs)

        return run

    def report(records_of):
        def run(c):
            from sk_offwhite.loop import score_models, write_report

            records = records_of(c)
            rows = score_models(c.loop_result(), {"estimation": (c.u, c.z)})
            with tempfile.TemporaryDirectory() as directory:
                return write_report(c.loop_result(), rows, records, directory, title="audit")

        return run

    limit = dict(limit=120.0, needs=needs)
    return [
        refuse("score_models.records.list", "score_models", "records a list, not a dict",
               score(lambda c: [(c.u, c.z)]), "records", **limit),
        refuse("score_models.records.nan", "score_models", "a record with a NaN in z",
               score(lambda c: {"estimation": (c.u, _with_value(c.z, 5, math.nan))}),
               ("z", "records"), **limit),
        refuse("score_models.records.width", "score_models", "a record with 2 input columns",
               score(lambda c: {"estimation": (np.hstack([c.u] * 2), c.z)}),
               ("u", "records"), **limit),
        refuse("score_models.records.pair", "score_models", "a record that is not a (u, z) pair",
               score(lambda c: {"estimation": c.u}), ("records", "u", "z"), **limit),
        refuse("score_models.result.none", "score_models", "result=None",
               lambda c: _score_none(c), "result"),
        refuse("score_models.init_window.negative", "score_models", "init_window=-1",
               score(lambda c: {"estimation": (c.u, c.z)}, init_window=-1), "init_window",
               **limit),
        refuse("write_report.no-estimation", "write_report",
               "records without an 'estimation' entry",
               report(lambda c: {"validation": (c.u, c.z)}), ("records", "estimation"), **limit),
    ]  # fmt: skip


def _score_none(c):
    from sk_offwhite.loop import score_models

    return score_models(None, {"estimation": (c.u, c.z)})


# ---------------------------------------------------------------------- helpers of the package
def helper_cases() -> list[Case]:
    def dataset(**kwargs):
        def run(c):
            from sk_offwhite.datasets import make_cascaded_tanks

            return make_cascaded_tanks(**kwargs)

        return run

    def diagnose(name, *args_of, **kwargs):
        def run(c):
            import sk_offwhite.diagnose as diagnose_module

            return getattr(diagnose_module, name)(*(a(c) for a in args_of), **kwargs)

        return run

    def certify_unfitted(c):
        from sk_offwhite.certify import identifiability

        return identifiability(c.estimator(), c.u, c.z)

    def certify_other_data(c):
        from sk_offwhite.certify import identifiability

        return identifiability(c.fitted(), c.u[:200], c.z[:200])

    def residual(c):  # a made-up residual: the diagnostics need no fit
        return 0.01 * np.sin(0.3 * np.arange(300)) + 0.001 * c.z[:, 0]

    def nan_z(c):
        return _with_value(c.z, 3, math.nan)

    return [
        refuse("datasets.n_samples.negative", "datasets", "make_cascaded_tanks(n_samples=-1)",
               dataset(n_samples=-1), "n_samples"),
        refuse("datasets.n_samples.str", "datasets", "make_cascaded_tanks(n_samples='300')",
               dataset(n_samples="300"), "n_samples"),
        refuse("datasets.n_samples.float", "datasets", "make_cascaded_tanks(n_samples=300.0)",
               dataset(n_samples=300.0), "n_samples"),
        refuse("datasets.noise_std.negative", "datasets", "make_cascaded_tanks(noise_std=-1)",
               dataset(n_samples=300, noise_std=-1.0), "noise_std"),
        refuse("datasets.noise_std.nan", "datasets", "make_cascaded_tanks(noise_std=nan)",
               dataset(n_samples=300, noise_std=math.nan), "noise_std"),
        refuse("datasets.noise_std.str", "datasets", "make_cascaded_tanks(noise_std='abc')",
               dataset(n_samples=300, noise_std="abc"), "noise_std"),
        refuse("datasets.overflow_fraction.two", "datasets",
               "make_cascaded_tanks(overflow_fraction=2)",
               dataset(n_samples=300, overflow_fraction=2.0), "overflow_fraction"),
        refuse("datasets.random_state.str", "datasets", "make_cascaded_tanks(random_state='x')",
               dataset(n_samples=300, random_state="x"), "random_state"),
        refuse("diagnose.metrics.nan", "diagnose", "simulation_metrics(z with a NaN, z_sim)",
               diagnose("simulation_metrics", nan_z, _z), "z"),
        refuse("diagnose.metrics.shapes", "diagnose", "simulation_metrics(z, z_sim[:-1])",
               diagnose("simulation_metrics", _z, lambda c: c.z[:-1]), ("z", "z_sim")),
        refuse("diagnose.metrics.skip", "diagnose", "simulation_metrics(skip=500) on 300 rows",
               diagnose("simulation_metrics", _z, _z, skip=500), "skip"),
        refuse("diagnose.whiteness.max_lag", "diagnose", "whiteness_test(max_lag=0)",
               diagnose("whiteness_test", residual, max_lag=0), "max_lag"),
        refuse("diagnose.whiteness.confidence", "diagnose", "whiteness_test(confidence=2)",
               diagnose("whiteness_test", residual, confidence=2.0), "confidence"),
        refuse("diagnose.whiteness.constant", "diagnose", "whiteness_test of a zero residual",
               diagnose("whiteness_test", lambda c: np.zeros(300)), "residual"),
        refuse("diagnose.whiteness.nan", "diagnose", "whiteness_test of a residual with a NaN",
               diagnose("whiteness_test", lambda c: _with_value(residual(c), 5, math.nan)),
               "residual"),
        refuse("diagnose.cross.u-length", "diagnose", "cross_correlation_test(residual, u[:-1])",
               diagnose("cross_correlation_test", residual, lambda c: c.u[:-1]), "u"),
        refuse("diagnose.ranges.nan", "diagnose", "range_violations(z with a NaN, z_sim)",
               diagnose("range_violations", nan_z, _z), "z"),
        refuse("diagnose.jumps.threshold", "diagnose", "output_jumps(threshold=-1)",
               diagnose("output_jumps", _z, _z, threshold=-1.0), "threshold"),
        refuse("diagnose.analyse.x_sim", "diagnose", "analyse_residuals(x_sim of 10 rows)",
               diagnose("analyse_residuals", _z, _z, _u, lambda c: np.zeros((10, 1))),
               "x_sim"),
        refuse("certify.identifiability.unfitted", "certify",
               "identifiability of an unfitted estimator", certify_unfitted, ("fit", "fitted")),
        refuse("certify.identifiability.other-data", "certify",
               "identifiability on data other than the fit's", certify_other_data,
               ("u", "z", "data"), needs=("fitted",)),
        refuse("baselines.delay-sindy.lags", "baselines", "DelaySINDyRegressor(n_output_lags=-1)",
               lambda c: _delay_sindy(c, n_output_lags=-1), "n_output_lags"),
        refuse("baselines.delay-sindy.optimizer", "baselines",
               "DelaySINDyRegressor(optimizer='adam')",
               lambda c: _delay_sindy(c, optimizer="adam"), "optimizer"),
        refuse("baselines.delay-sindy.u-nan", "baselines", "DelaySINDyRegressor.fit(u with NaN)",
               lambda c: _delay_sindy(c, u=_with_value(c.u, 2, math.nan)), "u"),
    ]  # fmt: skip


def _delay_sindy(c, u=None, **params):
    from sk_offwhite.baselines import DelaySINDyRegressor

    return DelaySINDyRegressor(**params).fit(c.u if u is None else u, c.z)


# ---------------------------------------------------------------------- classes being added
CV_ESTIMATOR_VALUES = {
    "gammas": (("str", ["a"]), ("negative", [-1.0]), ("empty", [])),
    "n_gammas": (("zero", 0), ("float", 2.5), ("str", "8"), ("bool", True)),
    "eps": (("negative", -1.0), ("one", 1.0), ("nan", math.nan)),
    "cv": (("str", "x"), ("one", 1), ("too-many", 1000)),
    "n_jobs": (("str", "many"), ("float", 1.5)),
    "gamma": (("negative", -1.0),),
    "horizon": (("bool", True), ("zero", 0)),
    "init_window": (("negative", -1),),
    "one_standard_error": (("str", "yes"),),
}
SEARCH_VALUES = {
    "cv": (("str", "x"), ("one", 1)),
    "n_folds": (("one", 1), ("str", "3")),
    "n_jobs": (("str", "many"), ("float", 1.5)),
    "settings": (("dict", {"beam": 2}), ("str", "fast")),
    "max_effects": (("negative", -1), ("str", "3")),
    "min_gain": (("nan", math.nan),),
    "beam": (("zero", 0),),
    "library": (("str", "poly"),),
}


def _parameters_of(cls) -> set[str]:
    try:
        return set(inspect.signature(cls).parameters)
    except (TypeError, ValueError):
        return set()


def new_class_cases() -> list[Case]:
    import sk_offwhite
    import sk_offwhite.loop

    cases = []
    cv_class = getattr(sk_offwhite, "GreyBoxSparseRegressorCV", None)
    if cv_class is not None:
        accepted = _parameters_of(cv_class)
        for name, values in CV_ESTIMATOR_VALUES.items():
            if name not in accepted:
                continue
            for label, value in values:
                cases.append(
                    refuse(f"regressor-cv.{name}.{label}", "GreyBoxSparseRegressorCV",
                           f"GreyBoxSparseRegressorCV({name}={value!r}).fit(u, z)",
                           _fit_cv_estimator(name, value), name)
                )  # fmt: skip
        cases.append(
            refuse("regressor-cv.u.nan", "GreyBoxSparseRegressorCV", "fit(u with a NaN)",
                   _fit_cv_estimator(None, None, nan_u=True), "u")
        )  # fmt: skip
    search_class = getattr(sk_offwhite.loop, "EffectSearchCV", None)
    if search_class is not None:
        accepted = _parameters_of(search_class)
        for name, values in SEARCH_VALUES.items():
            if name not in accepted:
                continue
            for label, value in values:
                cases.append(
                    refuse(f"effect-search.{name}.{label}", "EffectSearchCV",
                           f"EffectSearchCV(estimator, {name}={value!r}).fit(u, z)",
                           _fit_search(name, value), name, on_timeout="silent")
                )  # fmt: skip
        cases += [
            refuse("effect-search.estimator.string", "EffectSearchCV",
                   "EffectSearchCV('estimator').fit(u, z)", _fit_search("estimator", "x"),
                   "estimator", on_timeout="silent"),
            refuse("effect-search.estimator.no-physics", "EffectSearchCV",
                   "EffectSearchCV(GreyBoxSparseRegressor()) (no physics)",
                   _fit_search("estimator", "no-physics"), ("estimator", "physics"),
                   on_timeout="silent"),
            refuse("effect-search.u.nan", "EffectSearchCV", "fit(u with a NaN)",
                   _fit_search(None, None, nan_u=True), "u", on_timeout="silent"),
        ]  # fmt: skip
    return cases


def _fit_cv_estimator(name, value, nan_u=False):
    def run(c):
        import sk_offwhite

        params = {"physics": c.physics, "library": c.poly2()}
        accepted = _parameters_of(sk_offwhite.GreyBoxSparseRegressorCV)
        params = {k: v for k, v in params.items() if k in accepted}
        if name is not None:
            params[name] = value
        u = _with_value(c.u, 3, math.nan) if nan_u else c.u
        return sk_offwhite.GreyBoxSparseRegressorCV(**params).fit(u, c.z)

    return run


def _fit_search(name, value, nan_u=False):
    def run(c):
        from sk_offwhite.loop import EffectSearchCV

        estimator = c.estimator(library=c.poly2())
        params = {}
        if name == "estimator":
            estimator = "x" if value == "x" else c.estimator(physics=None)
        elif name == "library":
            params["library"] = value
        elif name is not None:
            params[name] = value
        u = _with_value(c.u, 3, math.nan) if nan_u else c.u
        return EffectSearchCV(estimator, **params).fit(u, c.z)

    return run


# ---------------------------------------------------------------------- the table
def build_cases() -> list[Case]:
    """Every case, in a fixed order; ids are unique."""
    groups = (
        array_cases, record_list_cases, sample_index_cases, prediction_cases, score_cases,
        number_parameter_cases, integer_parameter_cases, choice_parameter_cases,
        library_cases, parameter_cases, physics_cases, from_ode_cases, function_cases,
        fit_quality_cases, cv_cases, path_cases, loop_cases, scoring_cases, helper_cases,
        new_class_cases,
    )  # fmt: skip
    cases = [case for group in groups for case in group()]
    ids = [case.id for case in cases]
    duplicates = sorted({i for i in ids if ids.count(i) > 1})
    if duplicates:
        raise RuntimeError(f"duplicate case ids: {duplicates}")
    return cases
