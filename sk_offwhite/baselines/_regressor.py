r"""``DelaySINDyRegressor``: a pysindy ``DiscreteSINDy`` baseline as a scikit-learn estimator.

pysindy 2.x fits with ``fit(x, t, x_next=None, u=None)``: time sits where scikit-learn puts
the target, and ``score`` is the one-step $R^2$. This estimator wraps the same pysindy
model behind the contract of [`GreyBoxSparseRegressor`][sk_offwhite.GreyBoxSparseRegressor]:
``fit(u, z)``, ``predict(u)`` simulates from the start of the record, ``score(u, z)`` is the $R^2$
of that free run, so ``GridSearchCV`` tunes lags, threshold and optimiser on the simulation
error, exactly as it tunes ``gamma`` of the grey-box model.
"""

from __future__ import annotations

import warnings
from numbers import Integral, Real

import numpy as np
import pysindy as ps
from sklearn.base import BaseEstimator, RegressorMixin, _fit_context
from sklearn.metrics import r2_score
from sklearn.utils import metadata_routing
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from .._validation import check_input_width, check_inputs, check_pair
from ..simulation._segments import split_at_gaps
from ._embedding import Embedding, embed_record, history_length, variable_names
from ._simulate import FreeRun, output_box, simulate_free_run

__all__ = ["DelaySINDyRegressor"]


def make_optimizer(name: str, threshold: float, alpha: float, max_iter: int):
    r"""pysindy optimiser ``'stlsq'`` or ``'sr3'`` whose hard threshold is ``threshold``.

    STLSQ zeroes coefficients below ``threshold`` with ridge weight ``alpha``; SR3 with the
    L0 regulariser thresholds at $\sqrt{2\lambda\nu}$, so
    $\lambda = \text{threshold}^2 / (2\nu)$ with $\nu$ = ``alpha``.
    """
    if name == "stlsq":
        return ps.STLSQ(threshold=threshold, alpha=alpha, max_iter=max_iter)
    return ps.SR3(
        reg_weight_lam=threshold**2 / (2 * alpha),
        relax_coeff_nu=alpha,
        regularizer="L0",
        max_iter=max_iter,
        unbias=True,
    )


def _column_names(prefix: str, n: int) -> list[str]:
    return [prefix] if n == 1 else [f"{prefix}{i + 1}" for i in range(n)]


class DelaySINDyRegressor(RegressorMixin, BaseEstimator):
    r"""Discrete-time SINDy on a delay embedding of the measured outputs, scored in free run.

    The model is $z_{k+1} = \Xi\, \varphi(w_k)$ with $w_k$ the delay embedding of
    `_embedding` (``n_output_lags`` outputs, their square roots
    if ``sqrt_outputs``, ``n_input_lags`` inputs) and $\varphi$ a polynomial library of
    ``degree``. $\Xi$ is fitted by pysindy's ``DiscreteSINDy`` (state $z_k$, the
    other variables passed as its control input ``u``) with STLSQ or SR3; it sees only the
    fitting records' inputs and outputs, never unmeasured states or physical parameters.

    Parameters
    ----------
    n_output_lags : int, default=2
        Past outputs in the regressor (``1``: only $z_k$).
    n_input_lags : int, default=2
        Past inputs in the regressor (``0``: no input).
    degree : int, default=2
        Degree of the polynomial library on the regressor variables.
    sqrt_outputs : bool, default=False
        Add $\sqrt{\max(z, 0)}$ of each output lag (physics-informed, e.g. tanks).
    optimizer : {'stlsq', 'sr3'}, default='stlsq'
        Sparse regression of pysindy (SR3 with the L0 regulariser).
    threshold : float, default=0.01
        Hard threshold on the coefficients (see
        [`make_optimizer`][sk_offwhite.baselines.make_optimizer]).
    alpha : float, default=0.05
        Ridge weight of STLSQ, relaxation $\nu$ of SR3.
    max_iter : int, default=20
        Iterations of the optimiser.
    include_bias : bool, default=True
        Constant term in the library.
    clip_margin : float, default=1.0
        Free runs are kept within the fitted output range widened by ``clip_margin`` spans
        each side; reaching it flags the run as diverged.
    init_window : int, default=None
        Samples `score` takes as the known history of each scored record (excluded from
        the score). ``None``: ``max(min(50, n_samples // 5), history)``.

    Attributes
    ----------
    coef_ : ndarray of shape (n_outputs, n_features)
        $\Xi$.
    support_ : ndarray of bool, same shape as ``coef_``
    feature_names_ : list of str
        Library terms, from pysindy's ``get_feature_names``.
    powers_ : ndarray of shape (n_features, n_variables)
        Exponents of every term in the regressor variables.
    history_ : ndarray of shape (n_history, n_outputs)
        First outputs of the first fitting record: the default start of `predict`.
    output_box_ : tuple of ndarray
        Bounds of the free run (see ``clip_margin``).
    embedding_ : Embedding
        Lags and square roots of the fitted model.
    n_features_in_, n_outputs_ : int
        Numbers of inputs and outputs.
    n_iter_ : int
        Thresholding (STLSQ) or relaxation (SR3) iterations pysindy ran, at most ``max_iter``.
    """

    # u and z are the data (X and y), not metadata to route: only sample_index is.
    __metadata_request__fit = {"u": metadata_routing.UNUSED, "z": metadata_routing.UNUSED}
    __metadata_request__score = {"u": metadata_routing.UNUSED, "z": metadata_routing.UNUSED}
    __metadata_request__predict = {"u": metadata_routing.UNUSED}

    _parameter_constraints: dict = {
        "n_output_lags": [Interval(Integral, 1, None, closed="left")],
        "n_input_lags": [Interval(Integral, 0, None, closed="left")],
        "degree": [Interval(Integral, 1, None, closed="left")],
        "sqrt_outputs": ["boolean"],
        "optimizer": [StrOptions({"stlsq", "sr3"})],
        "threshold": [Interval(Real, 0, None, closed="left")],
        "alpha": [Interval(Real, 0, None, closed="neither")],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        "include_bias": ["boolean"],
        "clip_margin": [Interval(Real, 0, None, closed="neither")],
        "init_window": [Interval(Integral, 0, None, closed="left"), None],
    }

    def __init__(
        self,
        n_output_lags: int = 2,
        n_input_lags: int = 2,
        degree: int = 2,
        sqrt_outputs: bool = False,
        optimizer: str = "stlsq",
        threshold: float = 0.01,
        alpha: float = 0.05,
        *,
        max_iter: int = 20,
        include_bias: bool = True,
        clip_margin: float = 1.0,
        init_window: int | None = None,
    ):
        self.n_output_lags = n_output_lags
        self.n_input_lags = n_input_lags
        self.degree = degree
        self.sqrt_outputs = sqrt_outputs
        self.optimizer = optimizer
        self.threshold = threshold
        self.alpha = alpha
        self.max_iter = max_iter
        self.include_bias = include_bias
        self.clip_margin = clip_margin
        self.init_window = init_window

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        return tags

    def _embedded(self, records):
        embedding = self.embedding_
        need = history_length(embedding) + 1
        usable = [(u, z) for u, z in records if u.shape[0] > need]
        if not usable:
            longest = max(u.shape[0] for u, _ in records)
            raise ValueError(
                f"every record is shorter than the {need + 1} samples the lags need "
                f"(n_output_lags={self.n_output_lags}, n_input_lags={self.n_input_lags}); "
                f"the longest has n_samples={longest}."
            )
        return [embed_record(u, z, embedding) for u, z in usable], usable

    def _pysindy_model(self) -> ps.DiscreteSINDy:
        optimizer = make_optimizer(self.optimizer, self.threshold, self.alpha, self.max_iter)
        library = ps.PolynomialLibrary(degree=self.degree, include_bias=self.include_bias)
        return ps.DiscreteSINDy(optimizer=optimizer, feature_library=library)

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, u, z, sample_index=None):
        """Fit $\\Xi$ on the one-step targets of every record (pysindy).

        Parameters
        ----------
        u : array-like of shape (n_samples, n_inputs)
        z : array-like of shape (n_samples,) or (n_samples, n_outputs)
        sample_index : array-like of shape (n_samples,), default=None
            Original time index of each row; a jump starts a new record (no regressor row
            spans it), as in [`GreyBoxSparseRegressor.fit`][sk_offwhite.GreyBoxSparseRegressor.fit].

        Returns
        -------
        self : DelaySINDyRegressor
        """
        u, z = check_pair(u, z)
        self._z_was_1d = z.ndim == 1
        z = z.reshape(len(z), -1)
        self.n_features_in_, self.n_outputs_ = u.shape[1], z.shape[1]
        self.embedding_ = Embedding(self.n_output_lags, self.n_input_lags, self.sqrt_outputs)
        embedded, records = self._embedded(split_at_gaps(u, z, sample_index))
        self._fit_pysindy(embedded)
        self.history_ = records[0][1][: history_length(self.embedding_)].copy()
        self.output_box_ = output_box(z, self.clip_margin)
        return self

    def _fit_pysindy(self, embedded) -> None:
        n_z = self.n_outputs_
        names = variable_names(
            _column_names("z", n_z), _column_names("u", self.n_features_in_), self.embedding_
        )
        model = self._pysindy_model()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # STLSQ "all coefficients zero"
            model.fit(
                [w[:, :n_z] for w, _ in embedded],
                t=1,
                x_next=[target for _, target in embedded],
                u=[w[:, n_z:] for w, _ in embedded],
                feature_names=names,
            )
        self.coef_ = np.asarray(model.optimizer.coef_, float)
        self.n_iter_ = len(model.optimizer.history_) - 1  # history_[0] is the least squares
        self.support_ = self.coef_ != 0
        self.powers_ = np.asarray(model.feature_library.powers_)
        self.feature_names_ = list(model.feature_library.get_feature_names(names))

    def _history(self, z_init) -> np.ndarray:
        if z_init is None:
            return self.history_
        z_init = np.asarray(z_init, float).reshape(len(z_init), -1)
        need = history_length(self.embedding_)
        if z_init.shape[0] < need or z_init.shape[1] != self.n_outputs_:
            raise ValueError(
                f"z_init must hold at least {need} rows of {self.n_outputs_} outputs (the lags "
                f"of the model), got shape {z_init.shape}."
            )
        return z_init

    def simulate(self, u, *, z_init=None) -> FreeRun:
        """Free run over ``u`` from ``z_init`` (default: the fitted record's first outputs).

        Returns
        -------
        FreeRun
            ``outputs``, ``diverged`` and ``first_divergence``.
        """
        check_is_fitted(self)
        u = check_inputs(u)
        check_input_width(self, u.shape[1])
        history = self._history(z_init)
        args = (self.embedding_, self.coef_, self.powers_, self.output_box_)
        return simulate_free_run(u, history, *args)

    def predict(self, u, *, z_init=None):
        """Simulated outputs (a ``RuntimeWarning`` if the free run diverged).

        Parameters
        ----------
        u : array-like of shape (n_samples, n_inputs)
        z_init : array-like of shape (n_init, n_outputs), default=None
            Known first outputs (at least the model's lags); they are returned unchanged and
            the simulation continues from them. ``None`` starts from ``history_``.

        Returns
        -------
        z_sim : ndarray of shape (n_samples,) or (n_samples, n_outputs)
        """
        run = self.simulate(u, z_init=z_init)
        if run.diverged:
            _warn_diverged(run.first_divergence, "outputs are clipped to output_box_")
        return run.outputs.ravel() if self._z_was_1d else run.outputs

    def _score_window(self, n_samples: int) -> int:
        need = history_length(self.embedding_)
        window = self.init_window if self.init_window is not None else min(50, n_samples // 5)
        return min(max(window, need), n_samples - 1)

    def score(self, u, z, sample_index=None) -> float:
        """$R^2$ of the free run of every record after its first ``init_window`` samples.

        A diverged run scores ``-inf`` with a ``RuntimeWarning``, so model selection never
        picks it.
        """
        check_is_fitted(self)
        u, z = check_pair(u, z)
        measured, simulated, diverged = [], [], -1
        for u_r, z_r in split_at_gaps(u, z.reshape(len(z), -1), sample_index):
            window = self._score_window(u_r.shape[0])
            run = self.simulate(u_r, z_init=z_r[:window])
            diverged = run.first_divergence if run.diverged else diverged
            measured.append(z_r[window:])
            simulated.append(run.outputs[window:])
        if diverged >= 0:
            _warn_diverged(diverged, "score is -inf")
            return -np.inf
        return r2_score(np.concatenate(measured), np.concatenate(simulated))

    def equations(self, precision: int = 4) -> list[str]:
        """The identified one-step maps, one string per output."""
        check_is_fitted(self)
        return [
            " + ".join(
                f"{c:.{precision}g} {name}"
                for c, name in zip(row, self.feature_names_, strict=True)
                if c != 0
            )
            or "0"
            for row in self.coef_
        ]


def _warn_diverged(index: int, consequence: str) -> None:
    warnings.warn(
        f"The free-run simulation diverged (left the output box at sample {index}); "
        f"{consequence}. Try fewer lags, a larger threshold or sqrt_outputs.",
        RuntimeWarning,
        stacklevel=3,
    )
