"""The loop's refinement of a chosen effect into its richer variant (a calibration of one
degree more, a drag or a spring of fitted exponent, a Stribeck friction)."""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import (
    Friction,
    Leak,
    Parameter,
    PowerDrag,
    PowerLoss,
    PowerStiffness,
    QuadraticDrag,
    RelaxedLaw,
    SensorCalibration,
    Stiffness,
)
from sk_offwhite.datasets import (
    make_duffing_oscillator,
    make_friction_oscillator,
    make_nonlinear_sensor_tank,
    make_pendulum_drag,
    sensor_reading,
)
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
from sk_offwhite.loop._candidates import Candidate
from sk_offwhite.loop._loop import (
    _additions_and_exchanges,
    _refinements,
    _set_cv,
    _size,
    _swap,
    _with_richer,
)
from sk_offwhite.loop._switchboard import effect_sets
from sk_offwhite.loop._variants import mechanism, richer, richer_start

CALIBRATION = SensorCalibration(0, center=4.0, scale=2.0, name="sensor_x")


def test_the_richer_calibration_has_one_degree_more_and_the_same_mechanism():
    variant = richer(CALIBRATION)
    assert (variant.degree, variant.name) == (3, "sensor_x_degree3")
    assert (variant.center, variant.scale, variant.output) == (4.0, 2.0, 0)
    assert mechanism(variant) == mechanism(CALIBRATION)
    assert richer(variant).name == "sensor_x_degree4"
    assert richer(Leak(0)) is None


def test_the_richer_calibration_starts_where_it_reads_as_the_fitted_one():
    values = {"sensor_x_c0": 0.3, "sensor_x_c1": -0.2, "sensor_x_c2": 0.05}
    start = richer_start(CALIBRATION, values)
    assert start["sensor_x_degree3_c3"].value == 0.0
    theta = {k: getattr(v, "value", v) for k, v in start.items()}
    z = jnp.array([7.5])
    variant = richer(CALIBRATION).apply_output(None, None, z, theta)
    assert float(variant[0]) == pytest.approx(
        float(CALIBRATION.apply_output(None, None, z, values)[0])
    )


def test_refinements_exchange_each_effect_that_has_a_richer_variant():
    leak = Leak(0)
    warm = {
        "leak_x_rate": 0.1,
        "sensor_x_c0": 0.3,
        "sensor_x_c1": 1.0,
        "sensor_x_c2": 0.0,
        "k": 2.0,
    }
    physics = make_nonlinear_sensor_tank(n_samples=50, random_state=0).physics
    board = effect_sets(physics, _with_richer([leak, CALIBRATION]), shared=False)
    moves = list(_refinements((leak, CALIBRATION), warm, 0.5, board))
    assert len(moves) == 1
    effects, starts, bar = moves[0]
    assert effects == (leak, richer(CALIBRATION)) and bar == 0.5
    assert starts[0]["k"] == 2.0 and starts[0]["sensor_x_degree3_c1"] == 1.0
    assert not any(name.startswith("sensor_x_c") for name in starts[0])
    assert _with_richer([leak, CALIBRATION]) == [leak, CALIBRATION, richer(CALIBRATION)]
    without = effect_sets(physics, [leak, CALIBRATION], shared=False)
    assert list(_refinements((leak, CALIBRATION), warm, 0.5, without)) == []


def _loop(data):
    settings = LoopSettings(fit_delta=False, n_folds=2, max_iter=100)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return close_the_loop(
            data.physics, data.suggested_library, data.u, data.z, settings=settings
        )


@pytest.mark.slow
def test_the_loop_refines_a_quadratic_calibration_where_the_sensor_is_cubic():
    """The loop proposes a calibration of degree 2; where the sensor's characteristic is
    cubic, the refinement replaces it with degree 3, whose CV RMSE is lower by more than
    ``min_gain``, and the validation error falls to the noise (0.02). The quadratic
    sensor's loop keeps degree 2 (tests/test_sensor_calibration.py)."""
    data = make_nonlinear_sensor_tank(n_samples=400, random_state=1, cubic=0.004)
    result = _loop(data)
    assert [e.name for e in result.effects] == ["sensor_x_degree3"]
    trail = dict(result.selection)
    assert trail["sensor_x_degree3"] < (1 - LoopSettings().min_gain) * trail["sensor_x"]
    rows = score_models(result, {"validation": (data.u_val, data.z_val)}, init_window=50)
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    assert rmse["augmented physics"] < 1.5 * data.noise["output"]["std"]


def test_the_cubic_sensor_reads_its_characteristic_and_refuses_a_non_finite_coefficient():
    data = make_nonlinear_sensor_tank(n_samples=50, random_state=0, cubic=0.004)
    reading = data.z - data.noise["output_noise"]
    np.testing.assert_allclose(reading, sensor_reading(data.x, cubic=0.004))
    assert data.hidden_effect["rates"] == {"curvature": 0.04, "cubic": 0.004}
    plain = make_nonlinear_sensor_tank(n_samples=50, random_state=0)
    np.testing.assert_array_equal(plain.x, data.x)
    with pytest.raises(ValueError, match="cubic"):
        make_nonlinear_sensor_tank(n_samples=50, cubic=np.nan)


DRAG = QuadraticDrag(1, reference=2.0, name="drag_omega")


def _drag_term(effect, v, theta):
    return float(effect.term(jnp.array([0.0, v]), None, theta))


def test_the_richer_drag_has_a_fitted_exponent_on_the_same_reference_and_mechanism():
    variant = richer(DRAG)
    assert isinstance(variant, PowerDrag) and variant.name == "drag_omega_power"
    assert (variant.state, variant.reference, mechanism(variant)) == (1, 2.0, mechanism(DRAG))
    assert richer(variant) is None and richer_start(variant, {}) == {}
    start = richer_start(DRAG, {"drag_omega_coefficient": 0.7})
    assert start["drag_omega_power_exponent"].value == 2.0
    theta = {k: getattr(v, "value", v) for k, v in start.items()}
    for v in (-3.0, -0.2, 0.0, 0.5, 4.0):  # the quadratic drag itself
        assert _drag_term(variant, v, theta) == pytest.approx(
            _drag_term(DRAG, v, {"drag_omega_coefficient": 0.7})
        )


def test_the_power_drag_follows_its_law_and_has_finite_derivatives_at_rest():
    drag = PowerDrag(0, reference=2.0, name="d")
    theta = {"d_coefficient": 0.5, "d_exponent": 1.5}
    expected = -0.5 * 2.0**0.5 * np.sign(-3.0) * 3.0**1.5
    assert _drag_term(PowerDrag(1, reference=2.0, name="d"), -3.0, theta) == pytest.approx(expected)
    gradient = jax.grad(lambda v, a: drag.term(jnp.stack([v]), None, {**theta, "d_exponent": a}),
                        argnums=(0, 1))(0.0, 1.5)  # fmt: skip
    assert all(np.isfinite(float(g)) for g in gradient)
    names = ("theta", "omega")
    assert "power 1.5" in drag.describe(names, ("theta",), {"d_exponent": 1.5})
    assert "power 2" in drag.describe(names, ("theta",))  # the start, before a fit
    with pytest.raises(ValueError, match="exponent"):
        PowerDrag(0, exponent=0.5)
    with pytest.raises(ValueError, match="reference"):
        QuadraticDrag(0, reference=0.0)


@pytest.mark.parametrize("factor", [1e-3, 1.0, 250.0])
def test_the_power_drags_coefficient_converts_with_the_velocitys_units_alone(factor):
    """In units where v reads ``factor`` times larger (the reference with it), the term
    (a rate of v) reads ``factor`` times larger with the coefficient divided by ``factor``,
    whatever the exponent: the fit of the exponent does not trade off with the units."""
    for exponent in (1.2, 2.0, 2.7):
        theta = {"d_coefficient": 0.5, "d_exponent": exponent}
        scaled = {"d_coefficient": 0.5 / factor, "d_exponent": exponent}
        base = _drag_term(PowerDrag(1, reference=2.0, name="d"), -1.3, theta)
        other = _drag_term(PowerDrag(1, reference=2.0 * factor, name="d"), -1.3 * factor, scaled)
        assert other == pytest.approx(factor * base, rel=1e-5)  # float32 terms


def test_the_pendulums_drag_of_another_power_and_its_checks():
    quadratic = make_pendulum_drag(n_samples=300, random_state=0)
    power = make_pendulum_drag(n_samples=300, random_state=0, exponent=1.5)
    assert power.hidden_effect["rates"] == {"quadratic_drag": 0.3, "exponent": 1.5}
    assert "exponent" not in quadratic.hidden_effect["rates"]
    x = np.array([[0.1, -2.0]])
    drag = power.hidden_effect["state_function"](x, np.zeros((1, 1)))
    assert drag[0, 1] == pytest.approx(0.005 * 0.3 * 2.0**1.5)
    assert not np.allclose(power.z, quadratic.z)
    with pytest.raises(ValueError, match="exponent"):
        make_pendulum_drag(n_samples=300, exponent=0.9)


SPRING = Stiffness(1, 0, reference=0.5, name="stiffness_y")


def _spring_term(effect, q, theta):
    return float(effect.term(jnp.array([q, 0.0]), None, theta))


def test_the_richer_spring_has_a_fitted_exponent_started_at_its_power():
    variant = richer(SPRING)
    assert isinstance(variant, PowerStiffness) and variant.name == "stiffness_y_power"
    assert (variant.state, variant.position, variant.power) == (1, 0, 3)
    assert (variant.reference, mechanism(variant)) == (0.5, mechanism(SPRING))
    assert richer(variant) is None and richer_start(variant, {}) == {}
    start = richer_start(SPRING, {"stiffness_y_coefficient": -0.4})
    assert start["stiffness_y_power_exponent"].value == 3.0
    theta = {k: getattr(v, "value", v) for k, v in start.items()}
    for q in (-1.5, -0.1, 0.0, 0.3, 2.0):  # the cubic spring itself
        assert _spring_term(variant, q, theta) == pytest.approx(
            _spring_term(SPRING, q, {"stiffness_y_coefficient": -0.4})
        )


def test_the_power_spring_follows_its_law_and_converts_with_the_positions_units():
    theta = {"s_coefficient": 2.0, "s_exponent": 2.5}
    spring = PowerStiffness(1, 0, reference=0.5, name="s")
    expected = -2.0 * 0.5**0.5 * np.sign(-0.8) * 0.8**2.5
    assert _spring_term(spring, -0.8, theta) == pytest.approx(expected, rel=1e-6)
    for factor in (1e-3, 40.0):  # k converts by factor**(1 - power) whatever the exponent
        other = PowerStiffness(1, 0, reference=0.5 * factor, name="s")
        scaled = {**theta, "s_coefficient": 2.0 * factor ** (1 - 3)}
        assert _spring_term(other, -0.8 * factor, scaled) == pytest.approx(
            factor * _spring_term(spring, -0.8, theta), rel=1e-5
        )
    gradient = jax.grad(lambda q, a: spring.term(jnp.stack([q, 0.0]), None,
                                                 {**theta, "s_exponent": a}),
                        argnums=(0, 1))(0.0, 2.5)  # fmt: skip
    assert all(np.isfinite(float(g)) for g in gradient)
    at_rest = np.array([[0.0, 0.0], [-0.8, 0.0]])
    basis = PowerStiffness(1, 0, exponent=2.5, reference=0.5, name="s").basis(at_rest, None)
    np.testing.assert_allclose(basis, [0.0, expected / 2.0])  # the term at k = 1
    assert "y to the power 2.5" in spring.describe(("y", "v"), ("y",), {"s_exponent": 2.5})
    with pytest.raises(ValueError, match="exponent"):
        PowerStiffness(1, 0, exponent=5.5)  # beyond power + 2
    with pytest.raises(ValueError, match="reference"):
        Stiffness(1, 0, reference=-1.0)


def test_the_oscillators_spring_of_another_power_and_its_checks():
    cubic = make_duffing_oscillator(n_samples=300, random_state=0)
    power = make_duffing_oscillator(n_samples=300, random_state=0, exponent=2.5)
    assert power.hidden_effect["rates"] == {"cubic": 1.5, "exponent": 2.5}
    assert "exponent" not in cubic.hidden_effect["rates"]
    x = np.array([[-0.6, 0.1]])
    force = power.hidden_effect["state_function"](x, np.zeros((1, 1)))
    assert force[0, 1] == pytest.approx(0.02 * 1.5 * 0.6**2.5)
    assert not np.allclose(power.z, cubic.z)
    with pytest.raises(ValueError, match="exponent"):
        make_duffing_oscillator(n_samples=300, exponent=5.5)


def _refined_spring(data, millimetres: bool):
    """The cubic stiffness's refinement on ``data`` (in mm when ``millimetres``: the
    positions and the physics' parameters converted); ``(kept, CV, trail rows, fits)``."""
    scale = 1000.0 if millimetres else 1.0
    z = data.z * scale
    physics = data.physics.with_parameters(
        **{name: Parameter(p.value / scale, (p.bounds[0] / scale, None))
           for name, p in data.physics.parameters.items()}
    )  # fmt: skip
    settings = LoopSettings(n_folds=2, max_iter=100, fit_delta=False)
    spring = Stiffness(1, 0, reference=float(np.sqrt(np.mean(z**2))), name="stiffness_y")
    board = effect_sets(physics, _with_richer([spring]), shared=False)
    failures, fits = [], {}
    cv, _ = _set_cv(board, (spring,), {}, data.u, z, settings, failures)
    kept, _, rows = _swap(board, [], ((spring,), {}, cv), data.u, z, settings, failures, fits)
    assert failures == []
    return kept, cv, dict(rows), fits["stiffness_y_power"].parameters_


@pytest.mark.slow
def test_the_refinement_frees_the_exponent_of_a_spring_that_is_not_cubic_in_any_units():
    """On the oscillator whose spring force goes with the power 2.5 of the deflection, the
    cubic stiffness is exchanged for its richer variant, whose exponent comes back near
    2.5, and which cross-validates better by far. In millimetres the same: the exponent
    to rounding, the coefficient converted by 1000^(1 - 3), the CV errors by 1000."""
    data = make_duffing_oscillator(n_samples=1000, random_state=0, exponent=2.5)
    kept, cv, rows, fitted = _refined_spring(data, millimetres=False)
    assert kept == (richer(Stiffness(1, 0, reference=kept[0].reference, name="stiffness_y")),)
    assert list(rows) == ["stiffness_y_power"] and rows["stiffness_y_power"] < 0.7 * cv
    assert fitted["stiffness_y_power_exponent"] == pytest.approx(2.5, abs=0.05)
    kept_mm, cv_mm, rows_mm, fitted_mm = _refined_spring(data, millimetres=True)
    assert [e.name for e in kept_mm] == ["stiffness_y_power"]
    assert (cv_mm, rows_mm["stiffness_y_power"]) == pytest.approx(
        (1000.0 * cv, 1000.0 * rows["stiffness_y_power"]), rel=1e-6
    )
    exponent, coefficient = "stiffness_y_power_exponent", "stiffness_y_power_coefficient"
    assert fitted_mm[exponent] == pytest.approx(fitted[exponent], rel=1e-6)
    assert fitted_mm[coefficient] == pytest.approx(1e-6 * fitted[coefficient], rel=1e-6)


COULOMB = Friction(1, coulomb=0.2, width=0.02, name="friction_v")


def _friction_term(effect, v, theta):
    return float(effect.term(jnp.array([0.0, v]), None, theta))


def test_the_richer_friction_adds_a_stribeck_level_and_velocity_both_fitted():
    variant = richer(COULOMB)
    assert variant.name == "friction_v_stribeck" and mechanism(variant) == mechanism(COULOMB)
    assert variant.stribeck_velocity == pytest.approx(Friction.STRIBECK_START * 0.02)
    assert variant.min_width == COULOMB.min_width and richer(variant) is None
    params = variant.parameters()
    assert params["friction_v_stribeck_stribeck"].value == 0.0
    assert params["friction_v_stribeck_stribeck_velocity"].bounds == (COULOMB.min_width, None)
    fitted = {"friction_v_coulomb": Parameter(0.35, (0.0, None)),
              "friction_v_width": Parameter(0.03, (2e-4, None))}  # fmt: skip
    start = richer_start(COULOMB, {**COULOMB.parameters(), **fitted})
    assert start["friction_v_stribeck_width"] == fitted["friction_v_width"]
    theta = {k: p.value for k, p in start.items()}
    values = {k: p.value for k, p in fitted.items()}
    for v in (-2.0, -0.01, 0.0, 0.05, 1.5):  # the Coulomb friction itself
        assert _friction_term(variant, v, theta) == pytest.approx(
            _friction_term(COULOMB, v, values)
        )
    stribeck = {**theta, "friction_v_stribeck_stribeck": 0.5}
    near_rest = _friction_term(variant, 0.5, stribeck) - _friction_term(variant, 0.5, theta)
    assert near_rest == pytest.approx(-0.5 * np.exp(-((0.5 / 1.0) ** 2)) * np.tanh(0.5 / 0.03))
    sharp = {**fitted, "friction_v_width": Parameter(3e-4, (2e-4, None))}  # below its start
    restarted = richer_start(COULOMB, {**COULOMB.parameters(), **sharp})[
        "friction_v_stribeck_width"
    ]
    assert restarted.value == 0.02 and restarted.bounds == (2e-4, None)
    with pytest.raises(ValueError, match="stribeck_velocity"):
        Friction(1, width=0.02, stribeck_velocity=1e-5)


def test_the_stribeck_oscillator_and_its_checks():
    coulomb = make_friction_oscillator(n_samples=300, random_state=0)
    stribeck = make_friction_oscillator(n_samples=300, random_state=0, stribeck=0.5)
    assert stribeck.hidden_effect["rates"] == {
        "coulomb": 0.5, "stribeck": 0.5, "stribeck_velocity": 0.3
    }  # fmt: skip
    assert "rates" not in coulomb.hidden_effect
    x = np.array([[0.0, 0.3]])
    force = stribeck.hidden_effect["state_function"](x, np.zeros((1, 1)))
    assert force[0, 1] == pytest.approx(-0.05 * (0.5 + 0.5 * np.exp(-1.0)) * np.tanh(3.0))
    assert not np.allclose(stribeck.z, coulomb.z)
    with pytest.raises(ValueError, match="stribeck"):
        make_friction_oscillator(n_samples=300, stribeck=-0.1)


def test_an_exchange_for_an_effect_of_fewer_parameters_has_the_bar_of_a_lighter_set():
    """An exchange that lowers the parameter count is judged as a removal is (the lighter
    set's bar), any other exchange must fit better than the set."""
    loss = PowerLoss(0, level=300.0, name="loss_T")  # 3 parameters
    law = RelaxedLaw("loss_exponent", 1.0, (0.5, 3.0))  # 1 parameter
    leak = Leak(0, name="leak_T")  # 1 parameter
    settings = LoopSettings(beam=4, max_effects=1)
    ranked = [(0.02, Candidate(e, ""), {}) for e in (law, leak)]
    moves = list(_additions_and_exchanges((loss,), {}, ranked, 0.0197, 0.0203, settings))
    bars = {trial[0].name: bar for trial, _, bar in moves}
    assert bars == {law.name: 0.0203, "leak_T": 0.0203}
    heavier = list(_additions_and_exchanges((leak,), {}, [(0.02, Candidate(loss, ""), {})],
                                            0.0197, 0.0203, settings))  # fmt: skip
    assert [bar for _, _, bar in heavier] == [0.0197]
    assert _size((loss,)) == 3 and _size((law, leak)) == 2
