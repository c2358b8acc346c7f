"""The closed loop on a thermal plant in SI units (kelvin, watts): a heater with a hard
power limit that the declared physics does not know.

The loop must name the missing effect (the temperature equation, the power, sign -1), add
a saturation of the power with the hard-limit shape (not the soft ``tanh`` one, which the
data argue against), recover the limit and the declared parameters within 2 %, and bring
the validation error down to the sensor's noise. Temperatures are absolute (about 305-317
K), so every scale the loop derives from the data works on an offset record.

A study of the whole loop (about a minute): it runs with ``--run-slow``. In the default run
the diode (test_loop_thresholds.py) stands for the loops that must pick a threshold's shape.
"""

import numpy as np
import pytest

from sk_offwhite import InputSaturation
from sk_offwhite.datasets import make_heated_block
from sk_offwhite.datasets._thermal import _heated_block_physics
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models

pytestmark = pytest.mark.slow

SETTINGS = LoopSettings(
    n_folds=2, max_iter=100, fit_delta=False, max_candidates=6, max_effects=1
)  # one effect hidden: what is tested is the choice among the candidates


@pytest.fixture(scope="module")
def run():
    data = make_heated_block(n_samples=1000, random_state=0)
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=SETTINGS)
    return data, result


def test_the_heater_limit_is_named_and_added_with_its_shape(run):
    data, result = run
    hidden = data.hidden_effect
    top = result.hypotheses[0]
    assert top.equation_index == hidden["equation"] and top.sign == hidden["sign"] == -1
    assert "P" in top.variables
    saturations = [e for e in result.effects if isinstance(e, InputSaturation)]
    assert [e.shape for e in saturations] == ["clip"], result.effects
    alone = dict(result.single_fits)
    assert alone["actuator_limit_P"] < 0.5 * alone["actuator_P"]  # the hard limit fits far better
    assert result.failures == []


def test_the_limit_and_the_declared_parameters_are_recovered(run):
    data, result = run
    fitted = result.final.parameters_
    np.testing.assert_allclose(
        fitted["actuator_limit_P_level"], data.hidden_effect["rates"]["limit"], rtol=0.02
    )
    for name, value in data.true_parameters.items():
        np.testing.assert_allclose(fitted[name], value, rtol=0.02, err_msg=name)


def test_validation_error_falls_to_the_sensor_noise(run):
    data, result = run
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    noise = data.noise["output"]["std"]
    assert rmse["augmented physics"] < 1.2 * noise < 0.1 * rmse["declared physics"]
    assert result.chosen == "final"


def test_the_same_model_in_other_units(run):
    """Degrees Celsius (an offset of the output) and kilowatts (a scale of the input and of
    two parameters), both at once (one loop, not two: each alone was its own 50 s loop):
    the loop adds the same effect with the same values in the new units and the same
    validation error."""
    data, kelvin = run
    offset, power = -273.15, 1e-3
    guess = {"capacity": 600.0 * power, "conductance": 2.0 * power, "ambient": 290.0 + offset}
    physics = _heated_block_physics(guess, (313.0 + offset,))
    u, z = data.u * power, data.z + offset
    result = close_the_loop(physics, data.suggested_library, u, z, settings=SETTINGS)
    assert [e.name for e in result.effects] == [e.name for e in kelvin.effects]
    expected = dict(kelvin.final.parameters_)
    expected["ambient"] += offset
    for name in ("capacity", "conductance", "actuator_limit_P_level"):
        expected[name] *= power
    for name, value in result.final.parameters_.items():
        np.testing.assert_allclose(value, expected[name], rtol=1e-4, err_msg=name)
    rows = score_models(result, {"validation": (data.u_val * power, data.z_val + offset)})
    same = score_models(kelvin, {"validation": (data.u_val, data.z_val)})
    np.testing.assert_allclose([r["rmse"] for r in rows], [r["rmse"] for r in same], rtol=1e-4)
