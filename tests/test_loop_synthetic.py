"""The closed loop on each synthetic system with an undeclared effect.

For each generator the loop must name the hidden effect (its equation and variables), add
an explicit effect of the right kind, cut the validation simulation error (init-window
protocol) and bring the physical parameters closer to the truth. Records are short and the
grids small (one γ, two folds) to keep the file to a few minutes on two cores.
"""

import numpy as np
import pytest

from sk_offwhite import Friction, InputSaturation, Overflow, Parameter
from sk_offwhite.datasets import (
    make_cascaded_tanks,
    make_friction_oscillator,
    make_saturating_actuator,
)
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models

SETTINGS = LoopSettings(n_folds=2, max_iter=100, max_effects=1, max_candidates=6, fit_delta=False)


def _tanks():
    """Synthetic tanks with ``k4`` fixed at its true value: only ``x2`` is measured, so the
    scale of ``x1`` (and ``k1, k2, k4``) is otherwise not identifiable."""
    data = make_cascaded_tanks(n_samples=500, random_state=0)
    k4 = Parameter(data.true_parameters["k4"], fixed=True)
    data.physics = data.physics.with_parameters(k4=k4)
    return data


SYSTEMS = {
    "friction": (lambda: make_friction_oscillator(n_samples=500, random_state=0), Friction),
    "actuator": (lambda: make_saturating_actuator(n_samples=500, random_state=0), InputSaturation),
    "tanks": (_tanks, Overflow),
}


@pytest.fixture(scope="module", params=sorted(SYSTEMS))
def run(request):
    make, kind = SYSTEMS[request.param]
    data = make()
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=SETTINGS)
    return data, kind, result


def _validation_rmse(result, data, model: str) -> float:
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    return next(r["rmse"] for r in rows if r["model"] == model and r["protocol"] == "init_window")


def _parameter_error(est, truth: dict) -> float:
    names = [k for k in truth if not est.physics_.parameters[k].fixed]
    values = np.array([est.parameters_[k] for k in names])
    true = np.array([truth[k] for k in names])
    return float(np.linalg.norm((values - true) / true))


def test_the_loop_names_the_hidden_effect(run):
    data, kind, result = run
    hidden = data.hidden_effect
    named = [
        h
        for h in result.hypotheses
        if h.equation_index == hidden["equation"]
        and h.sign == hidden["sign"]
        and set(h.variables) & set(hidden["variables"])
    ]
    assert named, [h.sentence for h in result.hypotheses]
    assert len(result.effects) == 1 and isinstance(result.effects[0], kind)


def test_validation_and_parameter_errors_drop(run):
    data, _, result = run
    assert _validation_rmse(result, data, "augmented physics") < 0.5 * _validation_rmse(
        result, data, "declared physics"
    )
    before = _parameter_error(result.baseline, data.true_parameters)
    after = _parameter_error(result.final, data.true_parameters)
    assert after < 0.5 * before
