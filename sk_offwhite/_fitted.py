"""What a fitted model does: simulate records, predict, score, and print its equations.

`FittedModel` holds the methods that read a fitted
[`GreyBoxSparseRegressor`][sk_offwhite.GreyBoxSparseRegressor]'s state (its numpy blocks, its
physics, its compiled structure), so that the estimator's module is its fit alone.
"""

from __future__ import annotations

import warnings

import jax
import numpy as np
from sklearn.metrics import r2_score
from sklearn.utils import Bunch
from sklearn.utils.validation import _check_feature_names, check_is_fitted

from ._estimator_checks import _checked_z_init, _per_record, _record_weights
from ._validation import check_inputs, is_experiment_list
from ._warnings import DivergenceWarning, _warn_if_diverged
from .fitting._problem import initial_state_guess
from .model._equations import format_equations
from .runtime._backend import to_device
from .simulation._initial import estimate_initial_state
from .simulation._objective import CostWeights
from .simulation._rollout import free_run_record

__all__ = ["FittedModel"]


class FittedModel:
    """Simulation, prediction, scoring and read-out of a fitted estimator."""

    def _fitted_model(self):
        compiled = getattr(self, "_compiled", None)
        if compiled is None:
            compiled = self._compile(self.physics_)
        return compiled[1]

    def _fitted_cost_weights(self) -> CostWeights:
        """The weights and scales of the fitted cost (numpy), to rebuild it."""
        scales = {"output_scale": self.output_scale_, "state_scale": self._state_scale}
        if self.coef_.size:
            scales["penalty_scale"] = np.where(self.penalty_scale_ > 0, self.penalty_scale_, 1.0)
        return CostWeights(
            self.gamma, self.lam, self.nu, self.shooting_weight, self.l1_smoothing, **scales
        )

    def _fitted_blocks(self) -> dict:
        blocks = {"theta": self.theta_}
        if self.coef_.size:
            blocks["omega"] = self.coef_
        blocks.update(self.inner_params_)
        return blocks

    def _simulate_record(self, model, u, x0):
        """States, outputs and correction terms of a free run from ``x0``
        (`free_run_record`)."""
        params = {k: to_device(v) for k, v in self._fitted_blocks().items()}
        return free_run_record(model, params, x0, u)

    def _initial_state(self, model, u, z_init, x0):
        if x0 is not None:
            return _checked_x0(x0, self.x0_.shape[0])
        if z_init is None or len(z_init) == 0:
            return self.x0_
        n = len(z_init)
        guess = initial_state_guess(self.x0_, self.physics_, u[0], z_init[0], self.parameters_)
        return estimate_initial_state(
            model, self._fitted_blocks(), u[:n], z_init, guess, np.ones_like(self.x0_, bool)
        )

    def predict(self, u, *, x0=None, z_init=None):
        """Simulate the fitted model over the input sequence ``u``.

        Parameters
        ----------
        u : array-like of shape (n_samples, n_inputs) or list of such arrays
        x0 : array-like of shape (n_states,), default=None
            Initial state. ``None`` uses ``z_init`` if given, else ``x0_``.
        z_init : array-like of shape (n_init,) or (n_init, n_outputs), default=None
            First measured outputs; the initial state is estimated from them with the
            fitted parameters fixed. With a list of input records, a list with one entry
            (or ``None``) per record.

        Returns
        -------
        z_sim : ndarray of shape (n_samples,) or (n_samples, n_outputs), or list
            A simulation that diverges gives non-finite values after the sample where it
            does, with a [`DivergenceWarning`][sk_offwhite.DivergenceWarning] naming that sample.
        """
        if is_experiment_list(u):
            starts = _per_record("z_init", z_init, len(u))
            return [self.predict(ue, x0=x0, z_init=zi) for ue, zi in zip(u, starts, strict=True)]
        outputs = self.simulate(u, x0=x0, z_init=z_init).outputs
        return outputs.ravel() if self._z_was_1d else outputs

    def simulate(self, u, *, x0=None, z_init=None) -> Bunch:
        r"""Free-run simulation with everything a residual analysis needs.

        Same arguments as `predict` (one record).

        Returns
        -------
        result : sklearn.utils.Bunch
            ``outputs`` (n_samples, n_outputs), ``states`` (n_samples, n_states) with
            $\hat x_k$, ``correction`` (n_samples, n_states) with the black-box term
            $S\delta(\hat x_k, u_k)$ added to each state update, and ``x0``.
        """
        check_is_fitted(self)
        _check_feature_names(self, u, reset=False)
        u = check_inputs(u)
        self._check_widths(u.shape[1], reset=False)
        if z_init is not None:
            z_init = _checked_z_init(z_init, u.shape[0], self.n_outputs_)
        with jax.enable_x64(True):
            model = self._fitted_model()
            start = self._initial_state(model, u, z_init, x0)
            states, outputs, deltas = self._simulate_record(model, u, start)
        _warn_if_diverged(outputs)
        return Bunch(outputs=outputs, states=states, correction=deltas, x0=np.asarray(start))

    def _score_window(self, n_samples: int) -> int:
        if self.init_window is not None:
            return min(self.init_window, n_samples - 1)
        return min(50, n_samples // 5)

    def score(self, u, z, sample_index=None, sample_weight=None):
        """$R^2$ of the simulated output, after estimating each record's initial state.

        The first ``init_window`` samples of every contiguous record (see ``sample_index``)
        are used to estimate its initial state, as MATLAB's ``compare`` does, and are
        excluded from the score. With ``init_window=0`` records start from ``x0_``. A
        simulation that diverges scores ``-inf`` (with a ``RuntimeWarning``), so model
        selection never picks it.

        Parameters
        ----------
        u : array-like of shape (n_samples, n_inputs) or list of such arrays
        z : array-like of shape (n_samples,) or (n_samples, n_outputs), or list
        sample_index : array-like of shape (n_samples,), default=None
            Original time index of each row; a jump starts a new record.
        sample_weight : array-like of shape (n_samples,), default=None
            Weights of the scored samples in $R^2$ (all rows of a list of records,
            in order).

        Returns
        -------
        score : float
        """
        check_is_fitted(self)
        records = self._records(u, z, sample_index, reset=False)
        self._check_scored(records)
        measured, simulated, weights = [], [], []
        for (u_r, z_r), w_r in zip(records, _record_weights(sample_weight, records), strict=True):
            window = self._score_window(u_r.shape[0])
            with warnings.catch_warnings():  # one warning below, for the whole score
                warnings.simplefilter("ignore", DivergenceWarning)
                z_sim = self.predict(u_r, z_init=z_r[:window] if window else None)
            measured.append(z_r[window:])
            simulated.append(np.asarray(z_sim).reshape(len(u_r), -1)[window:])
            weights.append(w_r[window:])
        simulated = np.concatenate(simulated)
        if not np.all(np.isfinite(simulated)):
            warnings.warn(
                "The simulation diverged (non-finite outputs) on the scored data; score is -inf.",
                RuntimeWarning,
                stacklevel=2,
            )
            return -np.inf
        weight = None if sample_weight is None else np.concatenate(weights)
        return r2_score(np.concatenate(measured), simulated, sample_weight=weight)

    def _check_scored(self, records) -> None:
        """Refuse, before any simulation, outputs of another width than the fitted ones and
        records that leave fewer than 2 samples to score after their ``init_window``."""
        width = records[0][1].shape[1]
        if width != self.n_outputs_:
            raise ValueError(
                f"z has {width} output column(s), the model was fitted on {self.n_outputs_}."
            )
        scored = sum(len(u) - self._score_window(len(u)) for u, _ in records)
        if scored < 2:
            raise ValueError(
                f"score needs at least 2 samples after each record's init_window "
                f"(init_window={self.init_window}, records of {[len(r[0]) for r in records]} "
                "samples): score longer records or set a shorter init_window."
            )

    def equations(self, precision: int = 4) -> list[str]:
        """Identified state equations, one string per state (corrections written out), then
        one per corrected output."""
        check_is_fitted(self)
        rows = (self.delta_states_, self.delta_outputs_)
        return format_equations(self.physics_, self.coef_, self.feature_names_, rows, precision)

    def print(self, precision: int = 4) -> None:
        """Print the fitted parameters, initial state and equations (pysindy-style)."""
        for line in self.equations(precision):
            print(line)
        for name, value in self.parameters_.items():
            print(f"  {name} = {value:.{precision}g}")
        x0 = ", ".join(
            f"{n}={v:.{precision}g}"
            for n, v in zip(self.physics_.state_names, self.x0_, strict=True)
        )
        print(f"  x0: {x0}")


def _checked_x0(x0, n_states: int) -> np.ndarray:
    """``x0`` as ``n_states`` finite floats, or a ``ValueError`` naming it."""
    try:
        values = np.asarray(x0, float).reshape(-1)
    except (TypeError, ValueError) as error:
        raise ValueError(f"x0 must be {n_states} finite numbers, got {x0!r}.") from error
    if values.shape != (n_states,) or not np.all(np.isfinite(values)):
        raise ValueError(f"x0 must be {n_states} finite values, got {x0!r}.")
    return values
