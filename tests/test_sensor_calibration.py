"""A static nonlinearity of the sensor: the effect, its generator, and the loop finding it."""

import warnings

import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import SensorCalibration, augment
from sk_offwhite.datasets import make_nonlinear_sensor_tank, sensor_reading
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models


def test_the_calibration_adds_a_polynomial_of_the_centred_reading():
    effect = SensorCalibration(0, center=2.0, scale=0.5, degree=2, name="s")
    theta = {"s_c0": 0.1, "s_c1": 0.2, "s_c2": 0.3}
    z = effect.apply_output(None, None, jnp.array([3.0, 7.0]), theta)
    np.testing.assert_allclose(z, [3.0 + 0.1 + 0.2 * 2.0 + 0.3 * 4.0, 7.0])
    assert list(effect.parameters()) == ["s_c0", "s_c1", "s_c2"]
    assert all(p.value == 0.0 for p in effect.parameters().values())


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"center": 0.0, "scale": 0.0}, "scale"),
        ({"center": np.nan, "scale": 1.0}, "center"),
        ({"center": 0.0, "scale": 1.0, "degree": -1}, "degree"),
        ({"center": 0.0, "scale": 1.0, "degree": True}, "degree"),
    ],
)
def test_the_calibration_refuses_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SensorCalibration(0, **kwargs)


def _fit_protocols(monkeypatch, fit):
    """The shooting windows each fit of the three sets {leak}, {sensor}, {leak, sensor}
    was started over (through ``fit_continued``, which ends on the whole record), when
    fitted by ``fit(board, effects, u, z, settings)``."""
    from sk_offwhite import Leak
    from sk_offwhite.loop import _fits
    from sk_offwhite.loop._switchboard import effect_sets

    data = make_nonlinear_sensor_tank(n_samples=200, random_state=0)
    sensor, leak = SensorCalibration(0, 4.0, 2.0, name="sensor_x"), Leak(0)
    board = effect_sets(data.physics, [sensor, leak], False)
    horizons = []
    fit_continued = _fits.fit_continued

    def spied(est, u, z, horizon):
        horizons.append(horizon)
        return fit_continued(est, u, z, horizon)

    monkeypatch.setattr(_fits, "fit_continued", spied)
    settings = LoopSettings(horizon=50, max_iter=5, n_jobs=1, n_folds=2)
    for effects in [(leak,), (sensor,), (leak, sensor)]:
        assert np.isfinite(fit(board, effects, data.u, data.z, settings))
    return horizons


@pytest.mark.filterwarnings("ignore:.*did not converge")
def test_every_quick_fit_ends_on_the_whole_record_a_calibrated_set_starts_there(monkeypatch):
    """With free window starts the calibration can carry the record while the state does
    nothing (the Cascaded Tanks with ``max_iter=1000``): a set with an effect on the output
    map is fitted on the whole record; the other sets start over their shooting windows and
    end on the whole record too, the protocol all sets are ranked by."""
    from sk_offwhite.loop._fits import quick_fit
    from sk_offwhite.loop._search import Search

    def quick(board, effects, u, z, settings):
        return quick_fit(Search(u, z, settings), board, effects, {})[0]

    assert _fit_protocols(monkeypatch, quick) == [50, None, None]


@pytest.mark.filterwarnings("ignore:.*did not converge")
def test_a_set_and_the_final_physics_with_a_calibration_are_fitted_on_the_whole_record(
    monkeypatch,
):
    """The rule of the quick fits holds where a set is refitted before its CV and where the
    chosen set is fitted as the final physics (both through ``_fit_set``), and where a
    calibrated set is refitted with a parameter held on an undetermined direction."""
    from sk_offwhite.loop._search import Search
    from sk_offwhite.loop._sets import set_cv

    def cross_validated(board, effects, u, z, settings):
        search = Search(u, z, settings)
        score, fitted = set_cv(search, board, effects, {})
        assert fitted is not None, search.failures
        return score

    horizons = _fit_protocols(monkeypatch, cross_validated)
    assert horizons[0] == 50 and len(horizons) >= 3
    assert all(horizon is None for horizon in horizons[1:])


def test_a_zero_calibration_is_the_declared_output():
    data = make_nonlinear_sensor_tank(n_samples=200, random_state=0)
    model = augment(data.physics, SensorCalibration(0, 4.0, 2.0, name="sensor_x"))
    x = jnp.array([5.0])
    theta = {name: spec.value for name, spec in model.parameters.items()}
    assert float(model.output(x, jnp.array([1.0]), theta)[0]) == 5.0


@pytest.mark.slow
def test_the_loop_names_and_fits_an_uncalibrated_sensor():
    """The hidden effect is in the output map: the loop adds the calibration, the
    validation error falls by more than half, the outlet coefficient and the sensor's
    characteristic come back within 5 %."""
    data = make_nonlinear_sensor_tank(n_samples=400, random_state=1)
    settings = LoopSettings(fit_delta=False, n_folds=2, max_iter=100)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = close_the_loop(
            data.physics, data.suggested_library, data.u, data.z, settings=settings
        )
    assert [e.name for e in result.effects] == ["sensor_x"]
    assert result.chosen == "final"
    rows = score_models(result, {"validation": (data.u_val, data.z_val)}, init_window=50)
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    assert rmse["augmented physics"] < 0.5 * rmse["declared physics"]
    fitted = result.final.parameters_
    assert fitted["k"] == pytest.approx(data.true_parameters["k"], rel=0.05)
    effect = result.effects[0]
    levels = np.linspace(1.0, 10.0, 10)
    xi = (levels - effect.center) / effect.scale
    read = levels + sum(fitted[f"sensor_x_c{k}"] * xi**k for k in range(3))
    np.testing.assert_allclose(read, sensor_reading(levels), rtol=0.05)
