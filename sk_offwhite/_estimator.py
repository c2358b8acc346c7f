"""``GreyBoxSparseRegressor``: the scikit-learn estimator over the pure fitting core."""

from __future__ import annotations

import hashlib
import warnings
from numbers import Integral, Real

import jax
import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, _fit_context, clone
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils import metadata_routing
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import _check_feature_names

from ._estimator_checks import (
    _check_counts,
    _indices,
    check_enough_data,
    records_digest,
    warn_if_constant,
)
from ._fitted import FittedModel
from ._sklearn_glue import _nested_params, _safe_clone, _short_repr
from ._validation import (
    as_records,
    check_input_width,
    check_pair,
    check_physics,
    is_experiment_list,
)
from ._warnings import (
    _warn_if_runaway,
)
from .dictionaries import compile_basis
from .effects._hidden import n_declared_states
from .fitting._checks import bound_reason, edge_reason, fit_problems, non_finite_feature
from .fitting._problem import SolverOptions, build_model, fit_records
from .fitting._sparsity import SparseOptions
from .model._physics import PhysicsModel
from .model_selection._split import check_fold_rows, check_sample_index, warn_if_fragmented
from .runtime._backend import to_device
from .simulation._rollout import free_run_record
from .simulation._segments import split_at_gaps
from .solvers import LevenbergMarquardt, Optax
from .solvers._rules import LM_SCALINGS, OUTCOMES

__all__ = ["GreyBoxSparseRegressor"]


class GreyBoxSparseRegressor(FittedModel, RegressorMixin, BaseEstimator):
    r"""Physics model + sparse black-box correction, fitted on its multi-step simulation error.

    The model (Donati et al., eq. 2) is

    $$
    \hat x_{k+1} = f(\hat x_k, u_k; \theta) + S\,\delta(\hat x_k, u_k; \omega), \qquad
    \hat z_k = h(\hat x_k, u_k; \theta) + R\,\delta(\hat x_k, u_k; \omega),
    $$

    $$
    \delta_i(\hat x_k, u_k; \omega) = \sum_j \Omega_{ij}\, \varphi_j(\hat x_k, u_k),
    $$

    and ``fit`` minimises over $\theta$, $\hat x_0$ and $\omega$ the cost

    $$
    \begin{aligned}
    C_T = {}& \frac{1}{N n_z}\sum_{k,o} \frac{(\hat z_{ko} - z_{ko})^2}{\sigma_o^2}
        + \gamma \sum_{ij} s_{ij} |\Omega_{ij}|_\beta \\
      & + \frac{\lambda}{N}\sum_k \|\max(p(\hat x_k), 0)\|^2
        + \frac{\nu}{N}\sum_k \|q(\hat x_k)\|^2,
    \end{aligned}
    $$

    where $\hat z$ is the *simulated* output (the model feeds back its own state),
    $\sigma_o$ the standard deviation of output $o$ and $s_{ij}$ the RMS
    change of the normalised simulated output per unit $\Omega_{ij}$, measured on the
    physics-only fit. Every term is dimensionless: rescaling ``u``, ``z``, the states or a
    dictionary column leaves the fitted model unchanged. With a dictionary the fit has three
    stages (see `sk_offwhite.fitting._sparsity`): the physics alone, which gives
    $s_{ij}$ and ``gamma_max_``; the penalised fit; pruning of the terms that do not
    matter and a refit of the support without the penalty, so ``coef_`` has exact zeros.
    $S$ and $R$ pick the corrected state equations (``delta_states``) and
    outputs (``delta_outputs``, empty by default: a correction of the output map is a
    static nonlinearity of the sensor, such as an uncalibrated gauge's curve).

    Parameters
    ----------
    physics : PhysicsModel, default=None
        The physical model. ``None`` uses [`PhysicsModel.linear`][sk_offwhite.PhysicsModel.linear],
        a black-box linear state-space model with one state per output.
    library : pysindy feature library or RidgeBasis, default=None
        Dictionary $\varphi$ of the correction, evaluated on $[x; u]$ with the
        physics' state and input names; $x$ holds the declared states only (not the
        hidden states of an [`augment`][sk_offwhite.augment]-ed effect with memory). ``None``
        fits the physics alone.
    gamma : float, default=0.01
        $\gamma$, weight of the scaled (smoothed) L1 norm of $\Omega$;
        dimensionless. A term is worth keeping when the RMS change it makes in the simulated
        output exceeds about ``gamma`` output standard deviations; above ``gamma_max_`` the
        correction is empty. [`fit_gamma_path`][sk_offwhite.fit_gamma_path] fits a grid relative to
        ``gamma_max_`` and chooses by cross-validation.
    lam : float, default=0.0
        $\lambda$, weight of the violation of ``physics.inequality`` ($p\le 0$).
    nu : float, default=0.0
        $\nu$, weight of the squared ``physics.equality`` ($q = 0$).
    horizon : int, default=None
        $T$. ``None`` simulates each record whole from its initial state. An int cuts
        records into windows of ``horizon`` steps with their own initial states, linked by a
        continuity penalty of weight ``shooting_weight`` (multiple shooting).
    delta_states : sequence of int, default=None
        State equations that receive the correction; ``None`` means every declared state
        (the hidden states of an effect with memory are left out), or none when
        ``delta_outputs`` is given.
    delta_outputs : sequence of int, default=None
        Outputs that receive the correction (a static correction of the output map,
        evaluated on the same dictionary of $[x; u]$); ``None`` means none.
    prune_tol : float, default=0.01
        Relative tolerance of the pruning stage: a term is removed when its contribution
        $s_{ij}|\Omega_{ij}|$ is below ``prune_tol`` times the largest, or when zeroing
        it raises the simulation error $F$ by less than the fraction ``prune_tol``.
        ``0`` keeps every term.
    refit : bool, default=True
        Refit the pruned support without the penalty (removes the shrinkage of the L1
        term); ``False`` keeps the penalised weights of the support.
    l1_smoothing : float, default=100.0
        $\beta$ of the softplus surrogate of $|s_{ij}\Omega_{ij}|$ (larger is
        closer to L1); dimensionless like ``gamma``.
    shooting_weight : float, default=10.0
        Weight of the window-continuity penalty when ``horizon`` is set.
    solver : {'auto', 'lm', 'optax'} or solver object, default='auto'
        A [`LevenbergMarquardt`][sk_offwhite.solvers.LevenbergMarquardt] or an
        [`Optax`][sk_offwhite.solvers.Optax] object, or the name of one: ``'lm'`` is
        ``LevenbergMarquardt(scaling=lm_scaling)``, ``'optax'`` is
        ``Optax(optimizer=optimizer)``, and ``'auto'`` Levenberg-Marquardt with a ``horizon``
        or up to 400 free variables, the optax loop above.
    lm_scaling : {'per-variable', 'global'}, default='per-variable'
        The scaling of the Levenberg-Marquardt that ``solver='auto'`` or ``'lm'`` builds (see
        [`LevenbergMarquardt`][sk_offwhite.solvers.LevenbergMarquardt]): with
        ``'per-variable'`` rescaling a state, an input or a dictionary column leaves the
        iterates the same up to rounding.
    optimizer : optax.GradientTransformation, default=None
        The optimizer of the optax loop that ``solver='auto'`` or ``'optax'`` builds; ``None``
        is Adam (cosine-decayed from 1e-2) behind global norm clipping at 1.
    max_iter : int, default=200
        Maximum number of solver iterations.
    tol : float, default=1e-10
        Relative cost decrease under which the solver stops.
    init_window : int, default=None
        Samples used by `score` to estimate the initial state of the scored record
        (excluded from the score). ``None``: ``min(50, n_samples // 5)``; ``0``: simulate
        from the fitted initial state ``x0_``.
    warm_start : bool, default=False
        Start ``fit`` from the previous solution (parameters of the same name,
        $\Omega$ and inner weights of the same shape and, for the same number of
        records, initial states) instead of the physics' guesses, e.g. to refine a
        short-``horizon`` fit with ``horizon=None``.
    verbose : int, default=0
        Print solver progress every 10 iterations (every iteration if > 1); the fit is the
        same either way.
    random_state : int, RandomState instance or None, default=None
        Seeds the initial inner weights of a ridge basis.

    Attributes
    ----------
    parameters_ : dict
        Fitted physical parameters by name.
    theta_ : ndarray of shape (n_parameters,)
        The same values, in ``physics.parameter_names`` order.
    x0_ : ndarray of shape (n_states,)
        Fitted initial state of the first record; ``initial_states_`` holds all records'.
    coef_ : ndarray of shape (n_delta_states + n_delta_outputs, n_features)
        $\Omega$ with exact zeros off the support (empty without a library): the
        rows of ``delta_states_``, then those of ``delta_outputs_``.
    support_ : ndarray of bool, same shape as ``coef_``
        Where ``coef_`` is non-zero; ``n_nonzero_`` counts them.
    penalty_scale_ : ndarray, same shape as ``coef_``
        $s_{ij}$; ``penalty_scale_ * abs(coef_)`` is each term's contribution to the
        simulated output in output standard deviations (0 for a term that cannot move it).
    gamma_max_ : float
        Smallest ``gamma`` for which $\Omega = 0$ is optimal (``nan`` without a
        library).
    term_gain_, term_absorbed_, term_estimate_, term_conditional_gain_ : ndarray
        Shape (n_delta, n_features). What each dictionary term could explain at the
        physics-only fit once the physics re-adjusts (first order): the fraction of the
        cost it removes alone, the fraction of its effect the physics already produces,
        its linearised weight, and its gain beyond the stronger terms (matching pursuit)
        (`TermEvidence`); ``nan`` without a library.
    output_scale_ : ndarray of shape (n_outputs,)
        $\sigma_o$ of the training data.
    feature_names_ : list of str
        Names of the dictionary terms (from the pysindy library).
    delta_states_, delta_outputs_ : tuple of int
        The corrected state equations and outputs, one row of ``coef_`` each.
    inner_params_ : dict
        Fitted inner weights of a ridge basis (``W``, ``B``), empty otherwise.
    loss_history_ : ndarray
        Cost after each accepted step. ``cost_``, ``n_iter_``, ``converged_`` and
        ``solver_message_`` describe the end of the fit.
    fit_error_ : float
        $\sqrt{F}$, the RMS of the multi-step fit residuals in output standard
        deviations at the solution (without the penalty and constraint terms).
    n_features_in_ : int
        Number of inputs. ``n_outputs_``: number of outputs.

    Notes
    -----
    Rows of ``u`` and ``z`` are consecutive samples. Pass ``sample_index`` (the original time
    index of each row) when rows come from non-adjacent blocks, e.g. to
    ``GridSearchCV.fit(u, z, sample_index=np.arange(n))``: every gap then starts a new record
    with its own initial state instead of being simulated through.
    [`SequenceSplit`][sk_offwhite.SequenceSplit] makes folds whose training rows are contiguous,
    which need no ``sample_index``. A ``sample_index`` that cuts out records of a single
    row, as shuffled folds do, issues a [`SequenceWarning`][sk_offwhite.SequenceWarning]. With
    metadata routing enabled, request ``sample_index`` with ``set_fit_request(sample_index=True)``
    (and ``set_score_request``); ``clone`` keeps these requests.
    """

    # u and z are the data (X and y), not metadata to route: only sample_index is.
    __metadata_request__fit = {"u": metadata_routing.UNUSED, "z": metadata_routing.UNUSED}
    __metadata_request__score = {"u": metadata_routing.UNUSED, "z": metadata_routing.UNUSED}
    __metadata_request__predict = {"u": metadata_routing.UNUSED}

    _parameter_constraints: dict = {
        "physics": [PhysicsModel, None],
        "library": "no_validation",
        "gamma": [Interval(Real, 0, None, closed="left")],
        "lam": [Interval(Real, 0, None, closed="left")],
        "nu": [Interval(Real, 0, None, closed="left")],
        "horizon": [Interval(Integral, 1, None, closed="left"), None],
        "delta_states": ["array-like", None],
        "delta_outputs": ["array-like", None],
        "prune_tol": [Interval(Real, 0, 1, closed="left")],
        "refit": ["boolean"],
        "l1_smoothing": [Interval(Real, 0, None, closed="neither")],
        "shooting_weight": [Interval(Real, 0, None, closed="left")],
        "solver": [StrOptions({"auto", "lm", "optax"}), LevenbergMarquardt, Optax],
        "lm_scaling": [StrOptions(set(LM_SCALINGS))],
        "optimizer": "no_validation",
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        "tol": [Interval(Real, 0, None, closed="left")],
        "init_window": [Interval(Integral, 0, None, closed="left"), None],
        "warm_start": ["boolean"],
        "verbose": ["verbose"],
        "random_state": ["random_state"],
    }

    def __init__(
        self,
        physics: PhysicsModel | None = None,
        library=None,
        gamma: float = 0.01,
        lam: float = 0.0,
        nu: float = 0.0,
        horizon: int | None = None,
        *,
        delta_states=None,
        delta_outputs=None,
        prune_tol: float = 0.01,
        refit: bool = True,
        l1_smoothing: float = 100.0,
        shooting_weight: float = 10.0,
        solver: str | LevenbergMarquardt | Optax = "auto",
        lm_scaling: str = "per-variable",
        optimizer=None,
        max_iter: int = 200,
        tol: float = 1e-10,
        init_window: int | None = None,
        warm_start: bool = False,
        verbose: int = 0,
        random_state=None,
    ):
        self.physics = physics
        self.library = library
        self.gamma = gamma
        self.lam = lam
        self.nu = nu
        self.horizon = horizon
        self.delta_states = delta_states
        self.delta_outputs = delta_outputs
        self.prune_tol = prune_tol
        self.refit = refit
        self.l1_smoothing = l1_smoothing
        self.shooting_weight = shooting_weight
        self.solver = solver
        self.lm_scaling = lm_scaling
        self.optimizer = optimizer
        self.max_iter = max_iter
        self.tol = tol
        self.init_window = init_window
        self.warm_start = warm_start
        self.verbose = verbose
        self.random_state = random_state

    # ------------------------------------------------------------------ scikit-learn glue
    def get_params(self, deep: bool = True) -> dict:
        """Estimator parameters; nested ones of the library where it exposes them."""
        params = super().get_params(deep=False)
        if deep:
            for name, value in list(params.items()):
                params.update({f"{name}__{k}": v for k, v in _nested_params(value).items()})
        return params

    def __repr__(self, N_CHAR_MAX: int = 700) -> str:
        try:
            return super().__repr__(N_CHAR_MAX)
        except AttributeError:  # a library whose get_params is broken (CustomLibrary)
            changed = {k: v for k, v in self.get_params(deep=False).items() if v is not None}
            shown = ", ".join(f"{k}={_short_repr(v)}" for k, v in changed.items())
            return f"{type(self).__name__}({shown})"

    def __sklearn_clone__(self):
        params = {k: _safe_clone(v) for k, v in self.get_params(deep=False).items()}
        new = type(self)(**params)
        if hasattr(self, "_metadata_request"):  # set_fit_request & co., as sklearn.clone
            new._metadata_request = clone(self._metadata_request)
        return new

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = True
        tags.non_deterministic = False
        return tags

    def __getstate__(self):
        state = dict(super().__getstate__())  # a copy: the live estimator keeps its caches
        state.pop("_compiled", None)
        state.pop("_reference", None)
        return state

    def __setstate__(self, state):
        state = dict(state)
        state.setdefault("delta_outputs", None)  # pickled before outputs could be corrected
        if "delta_states_" in state:
            state.setdefault("delta_outputs_", ())
        super().__setstate__(state)

    # ------------------------------------------------------------------ data
    def _records(self, u, z, sample_index, reset: bool):
        """Validated list of contiguous ``(u, z)`` records."""
        if is_experiment_list(u):
            records = as_records(u, z)
            self._check_widths(records[0][0].shape[1], reset)
            self._z_was_1d = False if reset else self._z_was_1d
            return records
        _check_feature_names(self, u, reset=reset)
        u, z = check_pair(u, z)
        self._check_widths(u.shape[1], reset)
        if reset:
            self._z_was_1d = z.ndim == 1
        records = split_at_gaps(u, z.reshape(z.shape[0], -1), check_sample_index(sample_index))
        if sample_index is not None:
            warn_if_fragmented(records, stacklevel=5 if reset else 3)  # from fit / score
        return records

    def _check_widths(self, n_inputs: int, reset: bool) -> None:
        if reset:
            self.n_features_in_ = n_inputs
        else:
            check_input_width(self, n_inputs)

    def _resolved_physics(self, n_inputs: int, n_outputs: int) -> PhysicsModel:
        if self.physics is None:
            return PhysicsModel.linear(n_inputs, n_outputs)
        return self.physics

    def _delta_states(self, physics: PhysicsModel) -> tuple[int, ...]:
        if self.delta_states is None:
            every = tuple(range(n_declared_states(physics)))
            return () if self.delta_outputs is not None else every
        allow_empty = self.delta_outputs is not None
        return _indices(self.delta_states, physics.n_states, "delta_states", allow_empty)

    def _delta_outputs(self, n_outputs: int | None) -> tuple[int, ...]:
        if self.delta_outputs is None:
            return ()
        n_outputs = self.n_outputs_ if n_outputs is None else n_outputs
        return _indices(self.delta_outputs, n_outputs, "delta_outputs", allow_empty=False)

    # ------------------------------------------------------------------ fit
    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, u, z, sample_index=None):
        """Fit parameters, initial state(s) and correction on the simulation error.

        Parameters
        ----------
        u : array-like of shape (n_samples, n_inputs) or list of such arrays
            Input sequence(s); a list holds several experiments fitted jointly, each with
            its own initial state.
        z : array-like of shape (n_samples,) or (n_samples, n_outputs), or list
            Measured output sequence(s).
        sample_index : array-like of shape (n_samples,), default=None
            Original time index of each row; a jump starts a new record (see Notes).

        Returns
        -------
        self : GreyBoxSparseRegressor

        Warns
        -----
        ConvergenceWarning
            The solver stopped before its convergence rule was met, or at no model
            (``converged_`` is then ``False``; the message says why).
        RunawayParameterWarning
            A free parameter ended more than $10^6$ times its declared start away,
            where the data do not determine it.
        """
        _check_counts(self)
        if sample_index is None:
            check_fold_rows()
        return self._fit(u, z, sample_index, reference_only=False)

    def _fit(self, u, z, sample_index, reference_only: bool):
        """``fit``; ``reference_only`` stops after the physics-only stage (``coef_`` zero,
        ``gamma_max_`` computed), which is how [`fit_gamma_path`][sk_offwhite.fit_gamma_path]
        starts."""
        records = self._records(u, z, sample_index, reset=True)
        n_inputs, n_outputs = records[0][0].shape[1], records[0][1].shape[1]
        self._check_record_lengths(records, sample_index)
        physics = self._resolved_physics(n_inputs, n_outputs)
        check_enough_data(physics, records)
        warn_if_constant(records)
        with jax.enable_x64(True):
            check_physics(physics, n_inputs, n_outputs, records[0][0][0])
            basis, model = self._compile(physics, n_outputs)
            guess = {"theta": physics.parameter_values()}
            _raise_for_features(physics, basis, guess, records, [physics.x0] * len(records))
            outcome = self._solve(physics, basis, model, records, reference_only)
        self._store(physics, basis, model, outcome, n_outputs)
        self._fitted_data = records_digest(records)
        _warn_if_runaway(physics, self.theta_)
        return self

    def _check_record_lengths(self, records, sample_index=None) -> None:
        longest = max(u.shape[0] for u, _ in records)
        if longest < 2:
            cut = "" if sample_index is None else " (sample_index cuts the rows there)"
            raise ValueError(f"fit needs at least 2 consecutive samples, got 1 sample{cut}.")
        if self.init_window is not None and self.init_window > longest - 2:
            raise ValueError(
                f"init_window={self.init_window} leaves fewer than 2 samples to score in the "
                f"longest record ({longest} samples): set a shorter init_window."
            )
        if self.horizon is not None and longest < self.horizon:
            raise ValueError(
                f"horizon={self.horizon} is longer than the data ({longest} samples); "
                "use a shorter horizon or horizon=None."
            )

    def _compile(self, physics, n_outputs: int | None = None):
        """The compiled dictionary and model structure (``n_outputs`` defaults to the fitted
        one; only a correction of the outputs needs it)."""
        delta_states, delta_outputs = self._delta_states(physics), self._delta_outputs(n_outputs)
        basis = None
        if self.library is not None:
            states = physics.state_names[: n_declared_states(physics)]
            features = list(states) + list(physics.input_names)
            n_rows = len(delta_states) + len(delta_outputs)
            basis = _compiled_library(self.library, features, n_rows, self.random_state)
        return basis, build_model(physics, basis, delta_states, delta_outputs)

    def _solve(self, physics, basis, model, records, reference_only=False):
        weights = (self.gamma, self.lam, self.nu, self.shooting_weight, self.l1_smoothing)
        options = SolverOptions(
            self.solver, self._optimizer(), self.max_iter, self.tol, self.verbose, self.lm_scaling
        )
        outcome = fit_records(
            physics,
            basis,
            model,
            records,
            self.horizon,
            weights,
            options,
            self._warm_blocks(),
            SparseOptions(self.prune_tol, self.refit, reference_only),
            self._cached_reference(key := self._reference_key(physics, records), physics),
        )
        outcome = self._judged(physics, basis, model, records, outcome)
        self._warn_if_unfinished(outcome.result)
        cache = (key, physics, self.library, outcome.reference)
        self._reference = None if outcome.reference is None else cache
        return outcome

    def _reference_key(self, physics, records) -> str:
        """Fingerprint of what the physics-only stage depends on: data and structure."""
        digest = hashlib.sha1(records_digest(records).encode())
        settings = (
            id(physics), id(self.library), physics.parameter_values().tobytes(),
            np.asarray(physics.x0, float).tobytes(), self.horizon, self._delta_states(physics),
            self.delta_outputs, self.lam, self.nu, self.shooting_weight, self.solver,
            self.lm_scaling, self.max_iter, self.tol, self.random_state,
        )  # fmt: skip
        digest.update(repr(settings).encode())
        return digest.hexdigest()

    def _cached_reference(self, key: str, physics):
        """The physics-only stage of the previous fit if it had the same data and structure
        (the same physics and library objects, held so that their ids are not reused)."""
        cached = getattr(self, "_reference", None)
        if cached is None or cached[0] != key or cached[2] is not self.library:
            return None
        return cached[3] if cached[1] is physics else None

    def _warm_blocks(self) -> dict | None:
        """The previous solution as starting blocks (``warm_start``), else ``None``."""
        if not self.warm_start or not hasattr(self, "theta_"):
            return None
        return dict(self._fitted_blocks(), theta=self.parameters_, starts=self.initial_states_)

    def _optimizer(self):
        """The user's optimizer, checked, or ``None``: the optax loop then builds its
        default (`default_optimizer`), and a fit that never runs
        it never imports optax."""
        if self.optimizer is not None and not callable(getattr(self.optimizer, "update", None)):
            raise TypeError(
                "optimizer must be an optax.GradientTransformation (for example "
                f"optax.adam(1e-2)), got {self.optimizer!r}."
            )
        return self.optimizer

    def _judged(self, physics, basis, model, records, outcome):
        """``outcome`` with ``converged`` false and the reason when its fit is no model
        although the solver converged (`fit_problems`, `bound_reason`); a cost that is not
        finite because of a dictionary term raises, naming the term."""
        result, blocks = outcome.result, outcome.blocks
        first = np.asarray(blocks["x0"])[np.asarray(outcome.segments.linked) == 0]
        if not np.isfinite(result.cost):
            _raise_for_features(physics, basis, blocks, records, first)
            return outcome
        if not result.converged:
            return outcome
        scale = np.asarray(outcome.weights.output_scale, float)
        reason = fit_problems(model, blocks, records, first, scale, result.fit, self.horizon)
        reason = reason or bound_reason(physics, blocks["theta"])
        if reason is None and result.message == OUTCOMES[3]:
            reason = edge_reason(model, blocks, records, first, physics)
        if reason is None:
            return outcome
        judged = result._replace(converged=False, message=f"{reason} (solver: {result.message})")
        return outcome._replace(result=judged)

    def _warn_if_unfinished(self, result) -> None:
        if not np.isfinite(result.cost):
            raise ValueError(
                "the simulation is not finite from the initial guess nor after a restart "
                "from fits over short windows (the model diverges); change physics.x0 or "
                "the parameter values."
            )
        if not result.converged:
            unfinished = result.message.endswith("max_iter reached")
            advice = f"increase max_iter (now {self.max_iter})" if unfinished else None
            warnings.warn(
                f"The fit did not converge: {result.message}" + (f"; {advice}." if advice else "."),
                ConvergenceWarning,
                stacklevel=3,
            )

    def _store(self, physics, basis, model, outcome, n_outputs) -> None:
        blocks, result, segments = outcome.blocks, outcome.result, outcome.segments
        self.physics_ = physics
        self.n_outputs_ = n_outputs
        self.theta_ = np.asarray(blocks["theta"], float)
        self.parameters_ = dict(zip(physics.parameter_names, self.theta_.tolist(), strict=True))
        self.initial_states_ = np.asarray(blocks["x0"], float)[segments.linked == 0]
        self.x0_ = self.initial_states_[0].copy()
        omega = np.asarray(blocks.get("omega", np.zeros((0, 0))), float)
        self.coef_ = omega
        self.support_ = self.coef_ != 0
        self.n_nonzero_ = int(np.sum(self.support_))
        self.penalty_scale_ = np.asarray(outcome.penalty_scale, float)
        self.gamma_max_ = float(outcome.gamma_max)
        self._store_evidence(outcome.evidence, omega.shape)
        self.output_scale_ = np.asarray(outcome.weights.output_scale, float)
        self._state_scale = np.asarray(outcome.weights.state_scale, float)
        self.feature_names_ = [] if basis is None else list(basis.names)
        self.delta_states_, self.delta_outputs_ = model.delta_states, model.delta_outputs
        self.inner_params_ = {k: np.asarray(blocks[k], float) for k in model.inner_names}
        self.loss_history_ = np.asarray(result.history, float)
        self.cost_, self.n_iter_ = float(result.cost), int(result.n_iter)
        self.fit_error_ = float(np.sqrt(result.fit))
        self.converged_, self.solver_message_ = bool(result.converged), result.message
        self._compiled = (basis, model)

    def _store_evidence(self, evidence, shape) -> None:
        """The ``term_*_`` evidence attributes (nan without evidence)."""
        names = ("term_gain_", "term_absorbed_", "term_estimate_", "term_conditional_gain_")
        for name, values in zip(names, evidence or (None,) * 4, strict=True):
            setattr(self, name, np.full(shape, np.nan) if values is None else np.asarray(values))


def _compiled_library(library, features, n_rows: int, random_state):
    """[`compile_basis`][sk_offwhite.compile_basis] of the estimator's ``library``, its errors
    naming the argument (a library that cannot be compiled at all is a ``ValueError``)."""
    try:
        return compile_basis(library, features, n_rows, random_state)
    except (TypeError, ValueError) as error:
        raise type(error)(f"library: {error}") from error
    except Exception as error:  # noqa: BLE001 - pysindy's and numpy's own failures
        raise ValueError(
            f"library: {type(library).__name__} cannot be compiled into features of "
            f"{list(features)} ({type(error).__name__}: {error})."
        ) from error


def _raise_for_features(physics, basis, blocks, records, first_states) -> None:
    """Raise, naming the term, when a dictionary feature is not finite along the declared
    physics' free run from the fit's point (what made the cost not finite)."""
    if basis is None:
        return
    declared = build_model(physics, None, ())
    params = {"theta": to_device(np.asarray(blocks["theta"], float))}
    n_declared = n_declared_states(physics)
    for (u, _), x0 in zip(records, first_states, strict=True):
        states = free_run_record(declared, params, x0, u)[0][:, :n_declared]
        problem = non_finite_feature(basis, states, u)
        if problem:
            raise ValueError(problem + ".")
