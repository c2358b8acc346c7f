"""The evidence's functions by declared kind: which variables get which, how they join the
user's dictionary, and a friction that shows up as the sign of the velocity."""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
from conftest import driven_mass, driven_record

from sk_offwhite import Friction, PhysicsModel, RidgeBasis, augment
from sk_offwhite.dictionaries import compile_basis
from sk_offwhite.loop import LoopSettings
from sk_offwhite.loop._candidates import promoted_terms
from sk_offwhite.loop._evidence import read_evidence
from sk_offwhite.loop._kind_terms import kind_groups, sign_of, with_kind_terms
from sk_offwhite.loop._search import Search

DT = 0.01


def drive(state_kinds=("position", "velocity")) -> PhysicsModel:
    return driven_mass(2.0, 4.0, state_kinds=state_kinds)


def test_each_kind_gets_its_functions_and_a_one_signed_input_none():
    u = np.linspace(-1.0, 1.0, 20)[:, None]
    groups = [([f("x") for f in names], columns) for _, names, columns in kind_groups(drive(), u)]
    assert groups == [(["sign(x)", "x|x|"], [1]), (["|x|"], [2])]
    tank = PhysicsModel.from_ode(
        lambda x, u, theta: jnp.stack([u[0] - theta["k"] * x[0]]), DT, output=0,
        parameters={"k": 1.0}, n_states=1, n_inputs=1, state_kinds=("level",),
    )  # fmt: skip
    groups = [([f("h") for f in names], columns) for _, names, columns in kind_groups(tank, u)]
    assert groups == [(["sqrt|h|"], [0]), (["|h|"], [1])]
    assert [columns for *_, columns in kind_groups(tank, np.abs(u))] == [[0]]


def test_the_kind_columns_come_after_the_dictionary_s_own():
    library = ps.PolynomialLibrary(degree=2)
    combined = with_kind_terms(library, drive(), np.linspace(-1, 1, 20)[:, None])
    names = compile_basis(combined, ("q", "v", "tau"), 1).names
    own = len(compile_basis(library, ("q", "v", "tau"), 1).names)
    assert own == 10 and names[:own] == compile_basis(library, ("q", "v", "tau"), 1).names
    assert names[own:] == ("sign(v)", "v|v|", "|tau|")
    assert library.get_params() == ps.PolynomialLibrary(degree=2).get_params()  # untouched
    ridge = RidgeBasis()
    assert with_kind_terms(ridge, drive(), np.ones((20, 1))) is None


def test_the_functions_are_the_same_in_numpy_and_in_jax():
    x = np.array([-2.0, -0.5, 0.0, 0.5, 2.0])
    combined = with_kind_terms(ps.PolynomialLibrary(degree=1), drive(), x[:, None])
    own = 4  # 1, q, v, tau
    v = np.column_stack([x, x, x])
    with jax.enable_x64(True):
        jax_rows = np.asarray(
            jax.vmap(lambda row: compile_basis(combined, ("q", "v", "tau"), 1).evaluate({}, row))(
                jnp.asarray(v)
            )
        )[:, 0, own:]
    expected = np.column_stack([np.sign(x), x * np.abs(x), np.abs(x)])
    np.testing.assert_allclose(jax_rows, expected)


def friction_record(n: int = 600, seed: int = 0):
    """The drive with a Coulomb friction the declared physics lacks."""
    friction = Friction(1, coulomb=1.0, width=1e-3, fit_width=False, name="friction")
    return driven_record(augment(drive(), friction), n, seed)


def test_a_missing_friction_shows_up_as_an_odd_function_of_the_velocity_not_as_v2():
    """The polynomial dictionary offers only sign-blind or mixed terms for a Coulomb
    friction (``v^2``, ``q tau``); the velocity's kind adds the odd shapes, which explain
    more, in a note. The hypotheses and the promoted terms are the dictionary's alone."""
    u, z = friction_record()
    search = Search(u, z, LoopSettings(n_jobs=1, kind_notes=True))
    library = ps.PolynomialLibrary(degree=2)
    _, hypotheses = read_evidence(search, drive(), library)
    (note,) = search.notes
    assert note.startswith("In the v equation the functions of the variables' kinds")
    found = note.split("dictionary: ")[1].split(" of the")[0]
    assert sorted(re.sub(r" \d+%", "", found).split(", ")) == ["sign(v)", "v|v|"]
    assert "|tau|" not in found
    assert all(0 <= t.column < 10 for h in hypotheses for t in h.terms)
    promoted = promoted_terms(hypotheses, library, ("q", "v", "tau"), DT)
    assert promoted and all(isinstance(c.effect.column, int) for c in promoted)


def test_no_note_without_the_setting():
    u, z = friction_record()
    search = Search(u, z, LoopSettings(n_jobs=1))
    read_evidence(search, drive(), ps.PolynomialLibrary(degree=2))
    assert search.notes == []


def test_no_note_where_no_kind_function_beats_the_dictionary():
    u, z = friction_record()
    search = Search(u, z, LoopSettings(n_jobs=1, kind_notes=True))
    with_sign = ps.GeneralizedLibrary(
        [ps.PolynomialLibrary(degree=1), ps.CustomLibrary([sign_of], [lambda x: f"s({x})"])],
        inputs_per_library=[[0, 1, 2], [1]],
    )
    read_evidence(search, drive(), with_sign)
    assert not any("sign(v)" in note for note in search.notes)
