"""The closed loop on systems outside the tanks: mechanics and electronics, in SI units.

For each generator the declared physics misses one effect (Coulomb friction with a force
offset, a cubic stiffness, a quadratic drag, an input dead zone). The loop must name it
(equation, variables and sign), add an effect of the right kind whose parameter matches the
truth within 5 %, recover the declared parameters within 5 %, cut the validation error by
at least half, and choose a final model no worse under CV than the declared physics.
Records are short and the sparse-δ fits are skipped (``fit_delta=False``); the four loops
still take minutes, so the module runs with ``--run-slow`` only (the friction oscillator's
loop in tests/test_loop_synthetic.py stands for mechanics in the default run).
"""

from dataclasses import replace

import numpy as np
import pytest

from sk_offwhite import DeadZone, Friction, QuadraticDrag, Stiffness
from sk_offwhite.datasets import (
    make_coulomb_drive,
    make_dead_zone_motor,
    make_duffing_oscillator,
    make_pendulum_drag,
)
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models, write_report

pytestmark = pytest.mark.slow

SETTINGS = LoopSettings(n_folds=2, max_iter=100, fit_delta=False, max_candidates=6)
HIDDEN_EFFECTS = {"drive": 2}
"""Effects each generator hides (1 if not listed): the drive's friction comes with a
constant force. The loop may add no more (the duffing's loop took 159 s with three
allowed, 73 s with one, and chose the same model), so only the choice among the
candidates is tested here; tests/test_loop_thresholds.py and tests/test_backlash.py
test that a loop allowed three adds the hidden effect alone."""

SYSTEMS = {
    "drive": (make_coulomb_drive, 2000, Friction, "coulomb", "coulomb"),
    "duffing": (make_duffing_oscillator, 1500, Stiffness, "coefficient", "cubic"),
    "pendulum": (make_pendulum_drag, 1500, QuadraticDrag, "coefficient", "quadratic_drag"),
    "dead_zone": (make_dead_zone_motor, 800, DeadZone, "width", "dead_zone"),
}
"""Generator, record length, the effect's kind, the fitted parameter (``{effect}_{suffix}``)
and the generator's rate it must match."""


@pytest.fixture(scope="module", params=sorted(SYSTEMS))
def run(request):
    make, n, kind, suffix, rate = SYSTEMS[request.param]
    data = make(n_samples=n, random_state=0)
    settings = replace(SETTINGS, max_effects=HIDDEN_EFFECTS.get(request.param, 1))
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
    return data, result, kind, _parameter_of(result, kind, suffix), rate


def _parameter_of(result, kind, suffix: str) -> str | None:
    """The name of the fitted parameter ``suffix`` of the added effect of ``kind`` (a
    refinement, such as the Stribeck friction, keeps its effect's kind under a longer name)."""
    added = [effect for effect in result.effects if isinstance(effect, kind)]
    return f"{added[0].name}_{suffix}" if added else None


def test_the_hidden_effect_is_named_and_added(run):
    data, result, kind, _, _ = run
    hidden = data.hidden_effect
    named = [h for h in result.hypotheses if h.equation_index == hidden["equation"]]
    assert named and set(named[0].variables) & set(hidden["variables"])
    if kind is not DeadZone:
        # the dead zone's sign is relative to the re-fitted gain b, which absorbs part of it
        assert named[0].sign == hidden["sign"]
    assert any(isinstance(effect, kind) for effect in result.effects), result.effects
    assert result.failures == []


def test_parameters_are_recovered_within_five_percent(run):
    data, result, _, parameter, rate = run
    fitted = result.final.parameters_
    np.testing.assert_allclose(fitted[parameter], data.hidden_effect["rates"][rate], rtol=0.05)
    for name, value in data.true_parameters.items():
        np.testing.assert_allclose(fitted[name], value, rtol=0.05, err_msg=name)
    # a Stribeck refinement of the friction is the truth only if its peak over the Coulomb
    # level is small (the generator has none); which of the two wins is a near tie in CV
    stribeck = parameter.replace("_coulomb", "_stribeck")
    if stribeck != parameter and stribeck in fitted:
        assert fitted[stribeck] < 0.05 * fitted[parameter]


def test_validation_error_is_cut_and_the_choice_is_never_worse(run):
    data, result, _, _, _ = run
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    assert rmse["augmented physics"] < 0.5 * rmse["declared physics"]
    assert result.cv_errors[result.chosen] == min(result.cv_errors.values())
    assert result.chosen == "final"


def test_the_report_is_written_without_the_sparse_fits(run, tmp_path):
    data, result, _, parameter, _ = run
    records = {"estimation": (data.u, data.z), "validation": (data.u_val, data.z_val)}
    path = write_report(result, score_models(result, records), records, tmp_path, title="t")
    text = path.read_text()
    assert parameter in text and "(chosen)" in text and "## Fits that failed" in text
    assert "Not fitted (`fit_delta=False`" in text
