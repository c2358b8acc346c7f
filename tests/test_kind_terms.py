"""The evidence's functions by declared kind: which variables get which, how they join the
user's dictionary, what they name on plants with a known missing law (a friction, a
saturating actuator, a convective loss, a hardening spring) and how their fitted signs
read."""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest
from conftest import driven_mass, driven_record, free_run

from sk_offwhite import Friction, PhysicsModel, RidgeBasis, augment
from sk_offwhite.datasets import (
    make_convective_block,
    make_duffing_oscillator,
    make_lagged_drive,
)
from sk_offwhite.dictionaries import compile_basis
from sk_offwhite.loop import LoopSettings
from sk_offwhite.loop._candidates import promoted_terms
from sk_offwhite.loop._evidence import read_evidence, read_kind_notes
from sk_offwhite.loop._kind_terms import (
    DISSIPATIVE,
    SATURATING,
    KindColumn,
    column_meaning,
    declared_slopes,
    kind_groups,
    sign_of,
    with_kind_terms,
)
from sk_offwhite.loop._search import Search

DT = 0.01


def drive(state_kinds=("position", "velocity"), hold="zero") -> PhysicsModel:
    return driven_mass(2.0, 4.0, state_kinds=state_kinds, hold=hold)


def read_notes(search: Search, physics, library) -> None:
    """`read_kind_notes` on the free run of ``physics`` at its own values."""
    read_kind_notes(search, physics, library, free_run(physics, search.u)[0])


def group_names(physics, u, states) -> list[tuple[list[str], list[int]]]:
    """``(names, columns of v = [x; u])`` of each group, the variable named ``x``."""
    groups = kind_groups(physics, u, states)
    return [([f("x") for f in group.names], group.columns) for group in groups]


def test_each_variable_gets_the_functions_of_its_kind_and_where_it_is_seen():
    u = np.linspace(-1.0, 1.0, 20)[:, None]
    states = np.column_stack([np.linspace(0.0, 2.0, 20), np.linspace(-3.0, 3.0, 20)])
    assert group_names(drive(), u, states) == [
        (["sign(x)", "x|x|"], [1]),
        (["|x|"], [1]),  # the velocity and the input change sign, the position does not
        (["|x|"], [2]),
        (["x/(1.17+|x|)"], [0]),  # the measured position: its knee at its RMS
        (["x/(0.607+|x|)"], [2]),
    ]
    tank = PhysicsModel.from_ode(
        lambda x, u, theta: jnp.stack([u[0] - theta["k"] * x[0]]), DT, output=0,
        parameters={"k": 1.0}, n_states=1, n_inputs=1, state_kinds=("level",),
    )  # fmt: skip
    names = group_names(tank, np.abs(u), states[:, :1])
    assert names == [(["sqrt|x|"], [0]), (["x/(1.17+|x|)"], [0]), (["x/(0.607+|x|)"], [1])]


def test_a_temperature_gets_powers_of_its_excess_over_its_lowest_value():
    heater = make_convective_block(n_samples=50, random_state=0).physics
    temperatures = np.linspace(300.0, 310.0, 20)[:, None]
    excess = kind_groups(heater, np.ones((20, 1)), temperatures)[0]
    assert [f("T") for f in excess.names] == ["(T-300)^1.25", "(T-300)^2"]
    np.testing.assert_allclose(excess.functions[1](np.array([300.0, 316.0])), [0.0, 256.0])
    assert excess.meanings == ("a convective loss", "a radiative loss")
    assert excess.reading == DISSIPATIVE


def test_the_kind_columns_come_after_the_dictionary_s_own():
    library = ps.PolynomialLibrary(degree=2)
    u, states = np.linspace(-1, 1, 20)[:, None], np.ones((20, 2))
    combined = with_kind_terms(library, drive(), kind_groups(drive(), u, states))
    names = compile_basis(combined, ("q", "v", "tau"), 1).names
    own = len(compile_basis(library, ("q", "v", "tau"), 1).names)
    assert own == 10 and names[:own] == compile_basis(library, ("q", "v", "tau"), 1).names
    assert names[own:] == ("sign(v)", "v|v|", "|tau|", "q/(1+|q|)", "tau/(0.607+|tau|)")
    assert library.get_params() == ps.PolynomialLibrary(degree=2).get_params()  # untouched
    ridge = RidgeBasis()
    assert with_kind_terms(ridge, drive(), kind_groups(drive(), u, states)) is None
    assert with_kind_terms(library, drive(), []) is None


def test_the_functions_are_the_same_in_numpy_and_in_jax():
    x = np.array([-2.0, -0.5, 0.0, 0.5, 2.0])
    states = np.column_stack([np.zeros(5), x])  # an unmeasured velocity, a position at rest
    groups = kind_groups(drive(), x[:, None], states)
    combined = with_kind_terms(ps.PolynomialLibrary(degree=1), drive(), groups)
    own = 4  # 1, q, v, tau
    v = np.column_stack([x, x, x])
    with jax.enable_x64(True):
        jax_rows = np.asarray(
            jax.vmap(lambda row: compile_basis(combined, ("q", "v", "tau"), 1).evaluate({}, row))(
                jnp.asarray(v)
            )
        )[:, 0, own:]
    knee = np.sqrt(np.mean(x**2))
    expected = [np.sign(x), x * np.abs(x), np.abs(x), np.abs(x), x / (knee + np.abs(x))]
    np.testing.assert_allclose(jax_rows, np.column_stack(expected))


def friction_record(n: int = 600, seed: int = 0):
    """The drive with a Coulomb friction the declared physics lacks."""
    friction = Friction(1, coulomb=1.0, width=1e-3, fit_width=False, name="friction")
    return driven_record(augment(drive(), friction), n, seed)


def test_a_missing_friction_shows_up_as_an_odd_function_of_the_velocity_not_as_v2():
    """The polynomial dictionary offers only sign-blind or mixed terms for a Coulomb
    friction (``v^2``, ``q tau``); the velocity's kind adds the odd shapes, which explain
    more, in a note. The hypotheses and the promoted terms are the dictionary's alone."""
    u, z = friction_record()
    search = Search(u, z, LoopSettings(n_jobs=1))
    library = ps.PolynomialLibrary(degree=2)
    read_notes(search, drive(), library)
    _, hypotheses = read_evidence(search, drive(), library)
    (note,) = search.notes
    assert note.startswith("In the v equation the functions of the variables' kinds")
    shares = kind_shares(note)
    assert sorted(list(shares)[:2]) == ["sign(v)", "v|v|"]
    assert re.search(r"sign\(v\) \d+% \(a Coulomb friction\)", note)
    assert "|tau|" not in shares  # the force's size explains less than the dictionary
    assert all(0 <= t.column < 10 for h in hypotheses for t in h.terms)
    promoted = promoted_terms(hypotheses, library, ("q", "v", "tau"), DT)
    assert promoted and all(isinstance(c.effect.column, int) for c in promoted)


def test_no_note_without_the_setting():
    u, z = friction_record()
    search = Search(u, z, LoopSettings(n_jobs=1, kind_notes=False))
    read_notes(search, drive(), ps.PolynomialLibrary(degree=2))
    assert search.notes == [] and search.failures == []


def test_a_function_that_explains_little_is_not_noted():
    """A drive whose command reaches it through a lag: the drag shape beats the
    dictionary's terms at 2 % of the declared physics' cost, under ``min_gain`` (5 %):
    the note would be noise."""
    data = make_lagged_drive(random_state=0)
    notes = {}
    for floor in (0.0, LoopSettings.min_gain):
        search = Search(data.u, data.z, LoopSettings(n_jobs=1, min_gain=floor))
        read_notes(search, data.physics, ps.PolynomialLibrary(degree=2))
        notes[floor] = [note for note in search.notes if note.startswith("In the omega")]
    assert len(notes[0.0]) == 1 and max(kind_shares(notes[0.0][0]).values()) < 5
    assert notes[LoopSettings.min_gain] == []


def test_no_note_where_no_kind_function_beats_the_dictionary():
    u, z = friction_record()
    search = Search(u, z, LoopSettings(n_jobs=1))
    with_sign = ps.GeneralizedLibrary(
        [ps.PolynomialLibrary(degree=1), ps.CustomLibrary([sign_of], [lambda x: f"s({x})"])],
        inputs_per_library=[[0, 1, 2], [1]],
    )
    read_notes(search, drive(), with_sign)
    assert not any("sign(v)" in note for note in search.notes)


def saturated_drive_rhs(x, u, theta):
    """The drive of `driven_mass`, its force saturating at 6 N: ``6 tanh(tau / 6)``."""
    return jnp.stack([x[1], (6.0 * jnp.tanh(u[0] / 6.0) - theta["Fv"] * x[1]) / theta["M"]])


def kind_shares(note: str) -> dict[str, float]:
    """``{function: share}`` of a note's functions."""
    found = note.split("dictionary: ")[1].split(" of the")[0]
    return {name: float(share) for name, share in re.findall(r"(\S+) (\d+)%", found)}


@pytest.fixture(scope="module")
def saturated_record():
    """The drive of `saturated_drive_rhs`, its output measured with noise."""
    settings = dict(state_names=("q", "v"), input_names=("tau",), n_states=2, n_inputs=1)
    truth = PhysicsModel.from_ode(
        saturated_drive_rhs, DT, output=0, parameters={"M": 2.0, "Fv": 4.0}, **settings
    )
    return driven_record(truth, 600, 0)


def test_a_saturating_actuator_shows_up_as_a_saturation_in_any_units(saturated_record):
    """The force saturates as ``tanh``, a law none of the functions is; the rational
    saturation of the force still explains more than any polynomial term of degree 2 (odd
    in the force where ``tau^2`` is even), and rescaling the force (N to mN) leaves every
    share as it is."""
    u, z = saturated_record
    notes = {}
    for unit in (1.0, 1e3):
        search = Search(u * unit, z, LoopSettings(n_jobs=1))
        physics = drive().with_parameters(M=2.0 * unit, Fv=4.0 * unit)
        read_notes(search, physics, ps.PolynomialLibrary(degree=2))
        (notes[unit],) = [note for note in search.notes if note.startswith("In the v equation")]
    shares = kind_shares(notes[1.0])
    assert next(iter(shares)).startswith("tau/(")
    best = re.search(r"the dictionary's best, (.+): (\d+)%", notes[1.0])
    assert best.group(1) != "tau" and shares[next(iter(shares))] > float(best.group(2)) + 5
    assert list(kind_shares(notes[1e3]).values()) == list(shares.values())


def test_a_convective_loss_shows_up_as_a_power_of_the_temperature_excess():
    """The heated block loses heat as the power 4/3 of its excess over the ambient; the
    physics declares Newton's linear law. A linear dictionary (absorbed by the physics)
    explains nothing; the powers of the temperature's excess explain what is missing."""
    data = make_convective_block(n_samples=2000, random_state=0)
    search = Search(data.u, data.z, LoopSettings(n_jobs=1))
    read_notes(search, data.physics, ps.PolynomialLibrary(degree=1))
    (note,) = search.notes
    shares = kind_shares(note)
    assert {name for name in shares if name.startswith("(T-")} == {
        name for name in list(shares)[:2]
    }
    powers, others = list(shares.values())[:2], list(shares.values())[2:]
    assert min(powers) >= 10 and min(powers) > max(others, default=0)


def test_a_fitted_sign_reads_as_a_saturation_a_hardening_or_a_source():
    """Against the declared slope a saturation levels the effect off, with it the effect
    grows faster than linearly; a friction that pushes its own velocity is a source."""
    saturation = KindColumn("a saturation", 2, SATURATING)
    slopes = np.array([0.0, -4.0, 0.5])  # the v equation: -Fv/M v + tau/M
    assert column_meaning(saturation, 1, 0.3, slopes) == "a saturation"
    assert "faster than linearly" in column_meaning(saturation, 1, -0.3, slopes)
    on_q = KindColumn("a saturation", 0, SATURATING)
    assert column_meaning(on_q, 1, 0.3, slopes) == "a law that levels off"
    friction = KindColumn("a Coulomb friction", 1, DISSIPATIVE)
    assert column_meaning(friction, 1, -0.3, slopes) == "a Coulomb friction"
    assert "source" in column_meaning(friction, 1, 0.3, slopes)
    assert column_meaning(friction, 0, 0.3, slopes) == "a Coulomb friction"  # not its own


def test_the_declared_slopes_are_the_step_s_own():
    """The drive at 100 Hz: q' = v, v' = (tau - Fv v) / M, one RK4 step."""
    states = np.zeros((3, 2))
    for hold in ("zero", "linear"):
        slopes = declared_slopes(drive(hold=hold), states, np.zeros((3, 1)))
        np.testing.assert_allclose(slopes[1], [0.0, -DT * 2.0, DT / 2.0], rtol=0.02)
        assert slopes[0, 1] == pytest.approx(DT, rel=0.02)


def test_a_hardening_spring_is_read_as_an_effect_that_grows_faster_than_linearly():
    data = make_duffing_oscillator(n_samples=1000, random_state=0)
    search = Search(data.u, data.z, LoopSettings(n_jobs=1))
    read_notes(search, data.physics, ps.PolynomialLibrary(degree=2))
    (note,) = [note for note in search.notes if note.startswith("In the v equation")]
    assert re.search(r"y/\(\S+\) \d+% \(an effect that grows faster than linearly\)", note)
