"""Tests of a declared constant made a law of one variable (`VaryingParameter`), of the
loop's stand-in check (`sk_offwhite.loop._plausibility`) and of the loop proposing the law
that its fitted δ reads."""

from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest

from sk_offwhite import Bias, Stiffness, VaryingParameter, augment
from sk_offwhite.datasets._varying import (
    make_hardening_spring,
    make_piezoviscous_bearing,
    make_saturating_inductor,
    make_valve_tank,
)
from sk_offwhite.effects import DictionaryTerm
from sk_offwhite.loop import LoopSettings
from sk_offwhite.loop._plausibility import (
    chosen_index,
    dictionary_reasons,
    earns_every_effect,
    stand_in_reasons,
)
from sk_offwhite.loop._proposals import varying_effect
from sk_offwhite.loop._reading import read_varying_parameters
from sk_offwhite.loop._selection import physical_instead
from sk_offwhite.loop._switchboard import SeparateModels

N = 400


def _law_effect(data) -> VaryingParameter:
    """The generator's own law as an effect on its declared physics."""
    truth = data.varying
    physics = data.physics
    source = "state" if truth["variable"] in physics.state_names else "input"
    names = list(physics.state_names if source == "state" else physics.input_names)
    constants = truth["constants"]
    return VaryingParameter(
        truth["parameter"],
        names.index(truth["variable"]),
        truth["family"],
        abs(constants["x_s"]),
        exponent=constants.get("p", 1.0),
        rising=truth["sign"] in ("hardening", "rising") or constants["x_s"] > 0,
        source=source,
        stiffness=truth["sign"] in ("hardening", "softening"),
    )


def _rollout(physics, theta, x0, u) -> np.ndarray:
    with jax.enable_x64(True):
        step = jax.jit(physics.step)
        x, states = jnp.asarray(x0, float), []
        for uk in jnp.asarray(u):
            states.append(x)
            x = step(x, uk, theta)
    return np.asarray(states)


@pytest.mark.parametrize(
    "make",
    [make_hardening_spring, make_saturating_inductor, make_valve_tank, make_piezoviscous_bearing],
)
def test_the_law_substituted_is_the_true_plant(make):
    """The declared physics with the generator's law substituted (inside the right-hand
    side) runs the true plant's trajectory, to rounding."""
    data = make(n_samples=N, random_state=0)
    effect = _law_effect(data)
    model = augment(data.physics, effect)
    theta = {**data.true_parameters, f"{effect.name}_scale": effect.scale}
    if effect.family == "power":
        theta[f"{effect.name}_exponent"] = effect.exponent
    ours = _rollout(model, theta, data.true_x0, data.u_est)
    truth = _rollout(data.true_physics, data.true_parameters, data.true_x0, data.u_est)
    np.testing.assert_allclose(ours, truth, rtol=1e-9, atol=1e-12 * np.abs(truth).max())


def test_descriptions_say_the_law_and_its_sign():
    spring = VaryingParameter("k", 0, "polynomial", 0.04, stiffness=True)
    assert spring.sign() == "hardening"
    text = spring.describe(("q", "v"), ("q",), {"k": 20.0, "vary_k_x0_scale": 0.04})
    assert "k(q) = 20·(1 + (q/0.04)²)" in text and "hardening" in text
    soft = VaryingParameter("k", 0, "polynomial", 0.04, rising=False, stiffness=True)
    assert soft.sign() == "softening"
    valve = VaryingParameter("Cv", 0, "power", 0.5, exponent=1.5, source="input",
                             variable_name="a")  # fmt: skip
    assert valve.formula("a", {"Cv": 2.0, "vary_Cv_a_exponent": 1.5}) == "Cv(a) = 2·|(a/0.5)|^1.5"
    assert valve.sign({"vary_Cv_a_exponent": -0.5}) == "falling"
    assert (
        VaryingParameter("b", 1, "exponential", 4e7, source="input")
        .describe(("w",), ("w",))
        .startswith("the declared constant b depends on u1")
    )
    with pytest.raises(ValueError, match="family"):
        VaryingParameter("k", 0, "cubic", 1.0)
    with pytest.raises(ValueError, match="scale"):
        VaryingParameter("k", 0, "rational", -1.0)


def test_stand_ins_are_named_and_not_chosen_within_tolerance():
    declared = {"R": 2.0, "L": 0.5, "offset": 0.0}
    assert stand_in_reasons(declared, {"R": 2.4, "L": 0.45, "offset": 3.0}) == []
    reasons = stand_in_reasons(declared, {"R": 751.0, "L": -0.1})
    assert reasons == ["R moves from 2 to 751", "L changes sign (0.5 → -0.1)"]
    # the declared physics, a stand-in slightly better, a physical set within 2 %
    assert chosen_index([1.0, 0.50, 0.505], [True, False, True], 0.02) == 2
    assert chosen_index([1.0, 0.30, 0.505], [True, False, True], 0.02) == 1
    assert chosen_index([1.0, 0.50, 0.505], [True, True, True], 0.02) == 1


def test_a_set_is_adopted_only_when_each_of_its_effects_earns_min_gain():
    """{a, b} beats {a} by 4 %: b does not earn the 5 % it must, so {a} is chosen, though
    {a, b} is the best score and beyond the 2 % tolerance; {b, c} earns both."""
    a, b, c = "a", "b", "c"
    sets = [frozenset(), frozenset({a}), frozenset({a, b}), frozenset({b}), frozenset({b, c})]
    scores = [1.0, 0.50, 0.48, 0.70, 0.60]
    earned = earns_every_effect(sets, scores, 0.05)
    assert earned == [True, True, False, True, True]
    assert chosen_index(scores, [True] * 5, 0.02) == 2
    assert chosen_index(scores, [True] * 5, 0.02, earned) == 1
    assert earns_every_effect(sets, [1.0, 1.02, 0.9, 1.1, 0.8], 0.05)[1] is False  # worse


def test_a_chosen_dictionary_term_gives_way_to_named_effects_within_tolerance():
    """The refined set holds the term q^3; the cubic stiffness it equals scores within 2 %:
    the stiffness is chosen and a note says why. A named set 3 % worse, a larger one, or
    one that moves a declared parameter tenfold is not."""
    physics = make_hardening_spring(n_samples=50, random_state=0).physics
    term = DictionaryTerm(1, ps.PolynomialLibrary(degree=3), ["q", "v"], 6, name="term_v_q_3")
    spring, bias = Stiffness(1, 0, name="stiffness_q"), Bias(1, name="bias_v")
    board = SeparateModels.of(physics, [spring, bias, term])
    search = SimpleNamespace(settings=LoopSettings(tolerance=0.02), notes=[])
    chosen = ((term,), {"term_v_q_3_coefficient": -1.0})
    steps = [((spring,), {"stiffness_q_coefficient": 1.0}, 0.1), ((spring, bias), {}, 0.1)]
    trail = [("declared physics", 1.0), ("stiffness_q", 0.1015), ("stiffness_q + bias_v", 0.09),
             ("term_v_q_3", 0.1)]  # fmt: skip
    found = physical_instead(search, physics, board, trail, steps, chosen)
    assert found == ((spring,), {"stiffness_q_coefficient": 1.0})
    assert search.notes == [
        "stiffness_q replaces term_v_q_3: named effects within tolerance of the dictionary "
        "term's CV error."
    ]
    trail[1] = ("stiffness_q", 0.103)
    assert physical_instead(search, physics, board, trail, steps, chosen) == chosen
    trail[1] = ("stiffness_q", 0.1)
    k = next(iter(physics.parameters))
    moved = [((spring,), {k: 100 * physics.parameters[k].value}, 0.1)]
    assert physical_instead(search, physics, board, trail, moved, chosen) == chosen
    assert physical_instead(search, physics, board, trail, steps, ((spring,), {})) == (
        (spring,), {})  # fmt: skip


def test_a_set_with_a_promoted_term_is_a_stand_in():
    term = DictionaryTerm(1, ps.PolynomialLibrary(degree=3), ["q", "v"], 6, name="term_v_q_3")
    assert dictionary_reasons([Bias(1), term]) == [
        "term_v_q_3 is a dictionary term (no physical law)"
    ]
    assert dictionary_reasons([Bias(1)]) == []


def test_the_reading_becomes_the_effect_that_holds_it():
    """On the exact correction of the hardening spring, the reading's effect is the
    generator's law, its scale within 1 %."""
    data = make_hardening_spring(n_samples=N, random_state=0)
    with jax.enable_x64(True):
        steps = [jax.vmap(p.step, in_axes=(0, 0, None)) for p in (data.true_physics, data.physics)]
        nexts = [step(jnp.asarray(data.x_est), jnp.asarray(data.u_est), data.true_parameters)
                 for step in steps]  # fmt: skip
    correction = np.asarray(nexts[0] - nexts[1])
    reading = read_varying_parameters(
        data.physics, data.true_parameters, data.x_est, data.u_est, correction
    )[0]
    effect = varying_effect(data.physics, reading)
    assert (effect.parameter, effect.variable, effect.family, effect.source) == (
        "k", 0, "polynomial", "state"
    )  # fmt: skip
    assert effect.rising and effect.stiffness and effect.sign() == "hardening"
    assert effect.scale == pytest.approx(data.varying["constants"]["x_s"], rel=0.01)


@pytest.mark.slow
def test_the_loop_adds_the_law_its_correction_reads():
    """The whole loop on the hardening spring (minutes): the law is added as such, hardening,
    its scale and k within 5 %, the validation error cut by half or more.

    k (1 + (q/q_s)^2) q is k q plus a cubic spring of coefficient k / (m q_s^2): the varying
    stiffness and the cubic `Stiffness` are the same law, their CV errors equal to 1e-9 (the
    loop notes that the data cannot tell them apart), so either is the law, read with its
    scale."""
    import warnings

    import pysindy as ps

    from sk_offwhite import GreyBoxSparseRegressor
    from sk_offwhite.loop import EffectSearchCV

    data = make_hardening_spring(n_samples=600, random_state=0)
    est = GreyBoxSparseRegressor(data.physics, ps.PolynomialLibrary(degree=3), delta_states=[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = EffectSearchCV(est).fit(data.u_est, data.z_est)
    (law,) = search.effects_
    values = search.best_estimator_.parameters_
    if isinstance(law, VaryingParameter):
        assert (law.parameter, law.family, law.sign(values)) == ("k", "polynomial", "hardening")
        scale = values[f"{law.name}_scale"]
    else:
        assert isinstance(law, Stiffness) and law.power == 3
        assert "hardening" in law.describe(("q", "v"), ("q",), values)
        scale = np.sqrt(values["k"] / (values["m"] * values[f"{law.name}_coefficient"]))
    assert scale == pytest.approx(0.04, rel=0.05)
    assert values["k"] == pytest.approx(data.true_parameters["k"], rel=0.05)
    declared = search.result_.set_fits["declared physics"]
    errors = [
        np.sqrt(np.mean((np.reshape(m.predict(data.u_val), data.z_val.shape) - data.z_val) ** 2))
        for m in (declared, search)
    ]
    assert errors[1] <= 0.5 * errors[0]
