"""Where the loop's later fits start: from the declared physics' fit, except for the
parameters that fit does not determine, which start from their declared values."""

import numpy as np
import pytest

from sk_offwhite import RunawayParameterWarning
from sk_offwhite.datasets import make_diode_rc, make_leaky_tank
from sk_offwhite.loop import LoopSettings, fit_continued
from sk_offwhite.loop._evidence import reset_notes, start_of_later_fits
from sk_offwhite.loop._search import Search


def _declared_fit(data):
    settings = LoopSettings(n_jobs=1)
    est = Search(data.u, data.z, settings).estimator(data.physics)
    return fit_continued(est, data.u, data.z, settings.horizon)


@pytest.mark.filterwarnings("ignore:.*did not converge")
def test_a_parameter_the_declared_fit_runs_off_with_starts_from_its_declared_value():
    """The RC circuit behind a diode: the declared model's charging path discharges the
    capacitor too, so its fit drives the load's time constant toward infinity, where the
    curve no longer depends on it."""
    data = make_diode_rc(n_samples=600, random_state=0)
    with pytest.warns(RunawayParameterWarning, match="'tau_load' ran from 0.075"):
        baseline = _declared_fit(data)
    assert baseline.parameters_["tau_load"] > 1e6 * data.physics.parameters["tau_load"].value
    start, reset = start_of_later_fits(data.physics, baseline, data.u, data.z)
    assert list(reset) == ["tau_load"]
    assert start.parameters["tau_load"].value == data.physics.parameters["tau_load"].value
    assert start.parameters["tau"].value == pytest.approx(baseline.parameters_["tau"])
    (note,) = reset_notes(reset, data.physics)
    assert "tau_load" in note and "declared value 0.075" in note


def test_a_determined_declared_fit_is_where_the_later_fits_start():
    data = make_leaky_tank(n_samples=300, random_state=0)
    baseline = _declared_fit(data)
    start, reset = start_of_later_fits(data.physics, baseline, data.u, data.z)
    assert reset == {}
    for name, value in baseline.parameters_.items():
        assert start.parameters[name].value == pytest.approx(value)
    np.testing.assert_allclose(start.x0, baseline.initial_states_[0])
