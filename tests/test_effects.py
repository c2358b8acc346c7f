"""Named effects added to a physics model: structure, semantics and what they buy on data."""

import pickle
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import tanks_physics

from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite.datasets import cascaded_tanks_physics, make_cascaded_tanks, make_coulomb_drive
from sk_offwhite.effects import (
    AdditiveEffect,
    Backlash,
    Bias,
    DeadZone,
    DifferenceDeadZone,
    Friction,
    InputLag,
    InputSaturation,
    Leak,
    OutputSaturation,
    Overflow,
    PowerStiffness,
    RelaxedLaw,
    Stiffness,
    augment,
    switched,
)
from sk_offwhite.effects._switched import switches
from sk_offwhite.fitting._problem import build_model
from sk_offwhite.loop import LoopSettings
from sk_offwhite.loop._fits import quick_fit
from sk_offwhite.loop._search import Search
from sk_offwhite.loop._selection import candidate_models, rank_alone
from sk_offwhite.loop._switchboard import SeparateModels, Switchboard, single_effect_models
from sk_offwhite.loop._variants import mechanism
from sk_offwhite.simulation._rollout import free_run
from sk_offwhite.solvers._device import _run_on_device


def _theta(physics):
    return {k: jnp.asarray(p.value) for k, p in physics.parameters.items()}


def test_augment_appends_named_parameters_and_leaves_the_model_alone():
    physics = tanks_physics()
    before = dict(physics.parameters)
    augmented = augment(physics, Overflow(0, 9.0, sink=1), OutputSaturation(0, 10.0))
    assert physics.parameters == before and physics.step is not augmented.step
    assert list(augmented.parameters)[-3:] == [
        "overflow_level",
        "overflow_fraction",
        "saturation_level",
    ]
    assert augmented.parameters["overflow_fraction"].bounds == (0.0, 1.0)


def test_parameter_clash_and_wrong_types_are_rejected():
    with pytest.raises(ValueError, match="'leak_rate' clashes"):
        augment(tanks_physics(), Leak(0), Leak(1))
    with pytest.raises(TypeError, match="effects must be Effect instances"):
        augment(tanks_physics(), "overflow")


def test_effects_compare_by_value_and_pickle():
    effect = Overflow(0, 9.0, sink=1)
    assert effect == Overflow(0, 9.0, sink=1) and hash(effect) == hash(Overflow(0, 9.0, sink=1))
    assert effect != Overflow(0, 9.5, sink=1)
    augmented = augment(tanks_physics(), effect)
    restored = pickle.loads(pickle.dumps(augmented))
    assert restored.step == augmented.step


def test_sharp_overflow_caps_the_level_and_spills_the_fraction():
    physics = augment(tanks_physics(), Overflow(0, 5.0, sink=1, fraction=0.25, corner=1e-4))
    x, u = jnp.array([4.9, 2.0]), jnp.array([10.0])
    theta = _theta(physics)
    plain = tanks_physics().step(x, u, theta)
    capped = physics.step(x, u, theta)
    assert float(plain[0]) > 5.0
    np.testing.assert_allclose(capped[0], 5.0, atol=1e-3)
    np.testing.assert_allclose(capped[1] - plain[1], 0.25 * (plain[0] - 5.0), rtol=1e-3)


def test_a_fitted_corner_is_a_parameter_that_sets_the_hinge():
    """``fit_corner=True``: the corner is ``{name}_corner`` (floor 1e-6 of its start), and
    the value in theta, not the constructor's, rounds the hinge."""
    effect = Overflow(0, 5.0, sink=1, fraction=0.25, corner=0.5, fit_corner=True)
    spec = effect.parameters()["overflow_corner"]
    assert spec.value == 0.5 and spec.bounds == (pytest.approx(5e-7), None)
    assert "overflow_corner" not in Overflow(0, 5.0, corner=0.5).parameters()
    saturation = OutputSaturation(0, 3.0, fit_corner=True)
    assert set(saturation.parameters()) == {"saturation_level", "saturation_corner"}
    physics = augment(tanks_physics(), effect)
    x, u = jnp.array([4.9, 2.0]), jnp.array([10.0])
    theta = _theta(physics)
    plain = tanks_physics().step(x, u, theta)
    sharp = physics.step(x, u, {**theta, "overflow_corner": jnp.asarray(1e-4)})
    np.testing.assert_allclose(sharp[0], 5.0, atol=1e-3)
    np.testing.assert_allclose(sharp[1] - plain[1], 0.25 * (plain[0] - 5.0), rtol=1e-3)
    rounded = physics.step(x, u, theta)  # corner 0.5: the excess is larger than the hard one
    assert float(rounded[0]) < float(sharp[0]) - 0.01


def test_output_saturation_leak_and_friction_act_as_described():
    physics = augment(
        tanks_physics(),
        OutputSaturation(0, 3.0, corner=1e-4),
        Leak(0, rate=0.1),
        Friction(1, coulomb=0.2, width=1e-3),
    )
    x, u = jnp.array([4.0, 5.0]), jnp.array([1.0])
    theta = _theta(physics)
    np.testing.assert_allclose(physics.output(x, u, theta), [3.0], atol=1e-3)
    plain = tanks_physics().step(x, u, theta)
    np.testing.assert_allclose(physics.step(x, u, theta) - plain, [-0.4, -0.2], atol=1e-6)
    assert jnp.all(jnp.isfinite(jax.grad(lambda a: physics.step(a, u, theta).sum())(x)))


@pytest.mark.parametrize("scale", [1e-9, 1.0, 1e9])
def test_positive_levels_and_widths_have_floors_in_their_own_scale(scale):
    """A saturation level or a width in any units (a heater in GW, a play in nm) keeps a
    floor at 1e-6 of its start: an absolute floor would bind in some units only."""
    effects = [
        InputSaturation(0, 60.0 * scale),
        DeadZone(0, 0.3 * scale),
        DifferenceDeadZone(0, 0, 0.6 * scale),
        Backlash(0, 0.05 * scale),
    ]
    for effect in effects:
        ((name, spec),) = effect.parameters().items()
        assert spec.bounds == (pytest.approx(1e-6 * spec.value, rel=1e-12), None), name
    with pytest.raises(ValueError, match="level must be positive"):
        InputSaturation(0, 0.0)


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e4])
def test_a_threshold_on_the_difference_passes_only_its_excess(scale):
    """A diode (one-sided) and a clearance (two-sided) on the drive d = e - v: the physics
    sees e' with e' - v = max(d - w, 0), resp. sign(d) max(|d| - w, 0), away from the
    rounded corners, the same curve in any units of the voltages."""
    level, width = 2.0 * scale, 0.6 * scale
    drives = np.array([-5.0, -1.0, -0.3, 0.0, 0.3, 1.0, 5.0]) * scale
    theta = {"drop_width": jnp.asarray(width)}
    seen = {}
    with jax.enable_x64(True):
        for one_sided in (True, False):
            effect = DifferenceDeadZone(0, 0, 0.6, one_sided=one_sided, name="drop")
            x = jnp.array([level])
            seen[one_sided] = np.array(
                [effect.apply_input(x, jnp.array([level + d]), theta)[0] - level for d in drives]
            )
    beyond = np.maximum(np.abs(drives) - width, 0.0)
    np.testing.assert_allclose(seen[True], np.where(drives > 0, beyond, 0.0), atol=1e-3 * width)
    np.testing.assert_allclose(seen[False], np.sign(drives) * beyond, atol=1e-3 * width)
    diode = DifferenceDeadZone(0, 0, 1.0, one_sided=True, name="a")
    clearance = DifferenceDeadZone(0, 0, 1.0, name="b")
    assert mechanism(diode) == mechanism(clearance)  # one mechanism: a set holds one shape
    with pytest.raises(ValueError, match="width must be positive"):
        DifferenceDeadZone(0, 0, 0.0)


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e4])
def test_a_hard_input_limit_passes_the_input_below_it_and_clips_above(scale):
    """The clip shape: unchanged up to half the level (to 1e-9), within 1e-3 at 92 % of
    it, at the level beyond it, odd, and the same curve in any units of the input
    (sharpness relative to the level)."""
    effect = InputSaturation(0, 60.0 * scale, shape="clip")
    values = np.array([-200.0, -55.0, -30.0, 0.0, 20.0, 55.0, 66.0, 200.0]) * scale
    with jax.enable_x64(True):
        theta = {"actuator_level": jnp.asarray(60.0 * scale)}
        out = np.array([effect.apply_input(None, jnp.array([v]), theta)[0] for v in values])
    inside = np.abs(values) <= 30.0 * scale
    np.testing.assert_allclose(out[inside], values[inside], rtol=1e-9)
    np.testing.assert_allclose(out[[1, 5]], values[[1, 5]], rtol=1e-3)  # rounded corner
    np.testing.assert_allclose(out[[0, -1]], [-60.0 * scale, 60.0 * scale], rtol=1e-9)
    np.testing.assert_allclose(out[-2], 60.0 * scale, rtol=2e-3)  # 10 % beyond the level
    soft = InputSaturation(0, 60.0 * scale)  # tanh: 3.6 % low at a third of the level
    with jax.enable_x64(True):
        low = float(soft.apply_input(None, jnp.array([20.0 * scale]), theta)[0])
    assert low < 0.97 * 20.0 * scale


def test_the_two_saturation_shapes_are_one_mechanism_and_differ_as_effects():
    soft, hard = InputSaturation(0, 1.0), InputSaturation(0, 1.0, shape="clip")
    assert mechanism(soft) == mechanism(hard) != mechanism(InputSaturation(1, 1.0))
    assert soft != hard and pickle.loads(pickle.dumps(hard)) == hard
    assert "clipped" in hard.describe(["x"], ["z"]) and "tanh" in soft.describe(["x"], ["z"])
    with pytest.raises(ValueError, match="shape must be one of"):
        InputSaturation(0, 1.0, shape="hard")


def test_the_missing_overflow_added_as_an_effect_cuts_the_validation_error():
    data = make_cascaded_tanks(n_samples=1024, noise_std=0.02, random_state=0)
    physics = cascaded_tanks_physics(
        fixed={"k4": data.true_parameters["k4"]}, x0=[data.z[0, 0]] * 2
    )

    def validation_rmse(model):
        est = GreyBoxSparseRegressor(model, max_iter=300).fit(data.u, data.z)
        z_sim = est.predict(data.u_val, z_init=data.z_val[:50])
        return np.sqrt(np.mean((z_sim[50:] - data.z_val[50:]) ** 2)), est

    before, _ = validation_rmse(physics)
    after, est = validation_rmse(augment(physics, Overflow(0, 9.0, sink=1)))
    assert after < 0.5 * before
    assert 0.0 < est.parameters_["overflow_fraction"] < 1.0


def _outputs(physics, u):
    model = build_model(physics, None, ())
    with jax.enable_x64(True):
        params = {"theta": jnp.asarray(physics.parameter_values())}
        outputs = free_run(model, params, jnp.asarray(physics.x0), jnp.asarray(u))[1]
        return np.asarray(outputs)


@pytest.mark.parametrize("continuous", [False, True])
def test_a_switched_effect_is_the_effect_when_on_and_nothing_when_off(continuous):
    data = make_coulomb_drive(n_samples=300, random_state=0)
    physics = data.physics if continuous else cascaded_tanks_physics()
    u = data.u if continuous else make_cascaded_tanks(n_samples=300, random_state=0).u
    effect = Friction(1, coulomb=2.0) if continuous else Overflow(0, 3.0, sink=1)
    other = Bias(1, value=1.0)
    board = augment(physics, switched(effect), switched(other))
    on = board.with_parameters(**switches(board.effects, [effect]))
    off = board.with_parameters(**switches(board.effects, []))
    # equal to rounding (XLA may fuse the two programs differently)
    np.testing.assert_allclose(_outputs(on, u), _outputs(augment(physics, effect), u), rtol=1e-13)
    np.testing.assert_allclose(_outputs(off, u), _outputs(physics, u), rtol=1e-13)
    assert build_model(on, None, ()) == build_model(off, None, ())  # one jit structure


def test_switched_effects_compare_by_value_and_refuse_non_effects():
    assert switched(Leak(0)) == switched(Leak(0)) and switched(Leak(0)) != switched(Leak(1))
    assert isinstance(switched(Leak(0)), AdditiveEffect)
    assert not isinstance(switched(Overflow(0, 1.0)), AdditiveEffect)
    with pytest.raises(TypeError, match="Switched takes an Effect"):
        switched(switched(Leak(0)))
    restored = pickle.loads(pickle.dumps(switched(Leak(0))))
    assert restored == switched(Leak(0)) and restored.switch == "leak_on"


def test_effect_sets_on_one_switchboard_compile_the_solver_once():
    data = make_cascaded_tanks(n_samples=200, random_state=1)
    effects = [Overflow(0, 4.0, sink=1, name="spill"), Leak(1), Bias(0)]
    board = Switchboard.of(cascaded_tanks_physics(), effects)
    sizes = []
    # free: 6 declared + 2 (spill), 6 + 1 + 1, 6 + 4, each padded to the board's 8
    # parameters and 2 states, 12
    for on in ([effects[0]], [effects[1], effects[2]], effects):
        GreyBoxSparseRegressor(board.model(on), max_iter=3).fit(data.u, data.z)
        sizes.append(_run_on_device._cache_size())
    assert 0 < sizes[0] == sizes[1] == sizes[2]
    held = board.model([effects[1]]).parameters
    assert held["spill_level"].fixed and held["bias_value"].fixed
    assert not held["leak_rate"].fixed
    with pytest.raises(ValueError, match="not among the candidates"):
        board.model([Leak(0)])


def test_separate_models_compose_the_candidates_in_their_order():
    first, second = Overflow(0, 4.0, sink=1, name="spill"), Leak(1)
    separate = SeparateModels.of(cascaded_tanks_physics(), [first, second])
    model = separate.model([second, first], {"leak_rate": 0.02})
    assert model.effects == (first, second) and model.parameters["leak_rate"].value == 0.02
    board = Switchboard.of(cascaded_tanks_physics(), [first, second])
    assert board.ordered([second, first]) == separate.ordered([second, first]) == (first, second)
    with pytest.raises(ValueError, match="not among the candidates"):
        separate.model([Leak(0)])


def test_friction_width_keeps_a_floor_so_a_bad_start_still_finds_the_friction():
    assert Friction(1, width=0.05).parameters()["friction_width"].bounds == (5e-4, None)
    with pytest.raises(ValueError, match="min_width"):
        Friction(1, width=0.05, min_width=0.1)
    data = make_coulomb_drive(random_state=0, n_samples=2000)
    rates = data.hidden_effect["rates"]
    # 10x too wide and a Coulomb level 300x too small: this start used to end at width 1e-12
    start = Friction(1, coulomb=0.01, width=0.05, name="friction_v")
    model = augment(data.physics, start, Bias(1, name="bias_v"))
    fitted = GreyBoxSparseRegressor(model, horizon=128).fit(data.u, data.z).parameters_
    assert fitted["friction_v_coulomb"] == pytest.approx(rates["coulomb"], rel=0.05)
    assert fitted["friction_v_width"] == pytest.approx(rates["width"], rel=0.1)
    assert fitted["bias_v_value"] == pytest.approx(rates["offset"], rel=0.05)


def test_single_effects_share_a_board_unless_they_carry_memory_or_relax_a_law():
    spill, leak, bias = Overflow(0, 4.0, sink=1, name="spill"), Leak(1), Bias(0)
    lag, law = InputLag(0, 0.1), RelaxedLaw("k1", 0.1)
    models = single_effect_models(cascaded_tanks_physics(), [spill, lag, leak, law, bias])
    board, separate = models[0], models[1]
    assert isinstance(board, Switchboard) and isinstance(separate, SeparateModels)
    assert models == [board, separate, board, separate, board]
    assert [switch.effect for switch in board.board] == [spill, leak, bias]
    alone = single_effect_models(cascaded_tanks_physics(), [spill, lag])
    assert all(isinstance(model, SeparateModels) for model in alone)


@pytest.mark.filterwarnings("ignore:.*max_iter reached")
def test_single_effects_on_a_board_fit_as_alone_on_one_program_per_layout():
    data = make_cascaded_tanks(n_samples=200, random_state=1)
    physics = cascaded_tanks_physics()
    effects = [Overflow(0, 4.0, sink=1, name="spill"), Leak(1), Bias(0)]
    candidates = [SimpleNamespace(effect=effect) for effect in effects]
    settings = LoopSettings(horizon=64, max_iter=30)
    jax.clear_caches()
    search = Search(data.u, data.z, settings)
    on_board = rank_alone(search, candidates, candidate_models(physics, candidates, False))
    # windows and whole record: two layouts; the three sets pad to one size on each
    assert _run_on_device._cache_size() == 2
    separate = SeparateModels.of(physics, effects)
    for rmse, candidate, fitted in on_board:
        alone = quick_fit(search, separate, (candidate.effect,), {})
        assert rmse == pytest.approx(alone[0], rel=1e-6)
        assert fitted.keys() == alone[1].keys()


@pytest.mark.parametrize(
    ("coefficient", "word"), [(2.0, "hardening"), (-2.0, "softening"), (None, "nonlinear")]
)
def test_a_stiffness_says_whether_it_hardens_by_its_fitted_sign(coefficient, word):
    values = {} if coefficient is None else {"k3_coefficient": coefficient, "k3_exponent": 3.0}
    for spring in (Stiffness(1, 0, name="k3"), PowerStiffness(1, 0, name="k3")):
        assert f"(a {word} stiffness)" in spring.describe(("q", "v"), ("q",), values)
