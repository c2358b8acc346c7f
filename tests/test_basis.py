"""Tests for sk_offwhite.dictionaries: compiling pysindy libraries and ridge bases to JAX."""

from __future__ import annotations

import copy
import pickle
import subprocess
import sys
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from pysindy.feature_library import (
    ConcatLibrary,
    CustomLibrary,
    FourierLibrary,
    GeneralizedLibrary,
    IdentityLibrary,
    ParameterizedLibrary,
    PDELibrary,
    PolynomialLibrary,
    SINDyPILibrary,
    TensoredLibrary,
    WeakPDELibrary,
)
from sklearn.exceptions import NotFittedError
from sklearn.preprocessing import PolynomialFeatures
from sklearn.utils.validation import check_is_fitted

from sk_offwhite.dictionaries import CompiledBasis, RidgeBasis, compile_basis, evaluate_matrix

FEATURES = ["x1", "x2", "u"]
ALL_ACTIVATIONS = ("sigmoid", "softplus", "tanh", "sin", "cos", "identity", "square", "cube")


def _softsign(x):
    return x / (1.0 + jnp.abs(x))


def _numpy_exp(x):
    return np.exp(x)


def _custom_pairs() -> CustomLibrary:
    return CustomLibrary(
        [_softsign, lambda x, y: x * y**2],
        function_names=[lambda x: f"ss({x})", lambda x, y: f"{x}*{y}^2"],
        interaction_only=False,
        include_bias=True,
    )


LIBRARIES = {
    "poly2": lambda: PolynomialLibrary(degree=2),
    "poly3_nobias": lambda: PolynomialLibrary(degree=3, include_bias=False),
    "poly3_no_interaction": lambda: PolynomialLibrary(degree=3, include_interaction=False),
    "poly3_interaction_only": lambda: PolynomialLibrary(degree=3, interaction_only=True),
    "poly0": lambda: PolynomialLibrary(degree=0),
    "identity": IdentityLibrary,
    "fourier": FourierLibrary,
    "fourier3_sin": lambda: FourierLibrary(n_frequencies=3, include_cos=False),
    "fourier2_cos": lambda: FourierLibrary(n_frequencies=2, include_sin=False),
    "custom_three_args": lambda: CustomLibrary(
        [lambda x: jnp.exp(-x * x), lambda x, y, z: x * y - z]
    ),
    "custom_jnp": lambda: CustomLibrary([lambda x: jnp.exp(x), lambda x, y: jnp.sin(x + y)]),
    "custom_pairs_bias_names": _custom_pairs,
    "custom_python_arith": lambda: CustomLibrary([lambda x: 1.0 + x * x, lambda x: 2.0]),
    "concat": lambda: PolynomialLibrary(degree=2) + FourierLibrary(),
    "concat3": lambda: ConcatLibrary([IdentityLibrary(), FourierLibrary(), _custom_pairs()]),
    "tensored": lambda: PolynomialLibrary(degree=1) * FourierLibrary(),
    "tensored_inputs": lambda: TensoredLibrary(
        [PolynomialLibrary(degree=2), FourierLibrary()], inputs_per_library=[[0, 1], [2]]
    ),
    "tensored3": lambda: (
        IdentityLibrary() * FourierLibrary() * CustomLibrary([lambda x: jnp.tanh(x)])
    ),
    "generalized": lambda: GeneralizedLibrary([PolynomialLibrary(degree=2), FourierLibrary()]),
    "generalized_inputs_tensor": lambda: GeneralizedLibrary(
        [PolynomialLibrary(degree=2), FourierLibrary(n_frequencies=2)],
        inputs_per_library=[[0, 1], [2, 2, 1]],
        tensor_array=[[1, 1]],
    ),
    "generalized_exclude": lambda: GeneralizedLibrary(
        [PolynomialLibrary(degree=2), FourierLibrary(), IdentityLibrary()],
        inputs_per_library=[[0, 1], [2], [0, 2]],
        tensor_array=[[1, 1, 0], [0, 1, 1]],
        exclude_libraries=[0],
    ),
    "nested": lambda: (
        (PolynomialLibrary(degree=1) * FourierLibrary())
        + GeneralizedLibrary(
            [CustomLibrary([lambda x: jnp.cos(x) * x]), IdentityLibrary() + FourierLibrary()],
            inputs_per_library=[[2], [0, 1]],
        )
    ),
}


def _data(n_samples: int = 25, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n_samples, len(FEATURES)))


def _finite_difference(fun, v: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of ``fun`` w.r.t. each entry of ``v`` (last axis)."""
    cols = []
    for k in range(v.size):
        step = np.zeros_like(v)
        step[k] = h
        cols.append((np.asarray(fun(v + step)) - np.asarray(fun(v - step))) / (2 * h))
    return np.stack(cols, axis=-1)


# ---------------------------------------------------------------------------
# pysindy libraries
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(LIBRARIES))
def test_pysindy_parity_with_transform_and_names(name):
    library = LIBRARIES[name]()
    X = _data()
    with jax.enable_x64(True):
        reference = copy.deepcopy(library).fit(X)
        expected = np.asarray(reference.transform(X))
        compiled = compile_basis(library, FEATURES, n_delta=2)
        Phi = np.asarray(evaluate_matrix(compiled, {}, X))
    m = expected.shape[1]
    assert isinstance(compiled, CompiledBasis)
    assert Phi.dtype == np.float64 and Phi.shape == (len(X), 2, m)
    np.testing.assert_allclose(Phi[:, 0, :], expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(Phi[:, 0, :], Phi[:, 1, :])
    assert compiled.names == tuple(reference.get_feature_names(FEATURES))
    assert compiled.init_params == {} and compiled.trainable == {}
    assert compiled.omega_trainable.shape == (2, m) and compiled.omega_trainable.all()
    assert compiled.input_features == tuple(FEATURES)


def test_n_output_features_is_not_trusted_for_excluded_libraries():
    # pysindy 2.1 counts excluded libraries in n_output_features_ (20 != 14).
    library = LIBRARIES["generalized_exclude"]()
    fitted = copy.deepcopy(library).fit(_data())
    assert fitted.n_output_features_ != fitted.transform(_data()).shape[1]
    compiled = compile_basis(library, FEATURES, n_delta=1)
    assert len(compiled.names) == fitted.transform(_data()).shape[1]


def test_inconsistent_generalized_library_is_rejected():
    # Excluding a *tensored* library drops its names but not its columns in pysindy 2.1.
    library = GeneralizedLibrary(
        [PolynomialLibrary(degree=2), FourierLibrary()],
        tensor_array=[[1, 1]],
        exclude_libraries=[2],
    )
    with pytest.raises(ValueError, match="GeneralizedLibrary is inconsistent"):
        compile_basis(library, FEATURES, n_delta=1)


def test_float32_evaluation_by_default():
    library = PolynomialLibrary(degree=2) + FourierLibrary()
    compiled = compile_basis(library, FEATURES, n_delta=1)
    X = _data().astype(np.float32)
    Phi = evaluate_matrix(compiled, {}, X)
    assert Phi.dtype == jnp.float32
    expected = copy.deepcopy(library).fit(_data()).transform(_data())
    np.testing.assert_allclose(np.asarray(Phi[:, 0]), expected, rtol=1e-5, atol=1e-5)


def _assert_unfitted(library) -> None:
    with pytest.raises(NotFittedError):
        check_is_fitted(library)


def test_user_library_is_not_modified():
    poly, fourier = PolynomialLibrary(degree=2), FourierLibrary()
    generalized = GeneralizedLibrary([poly, fourier], tensor_array=[[1, 1]])
    custom = CustomLibrary([lambda x: jnp.sin(x)])
    concat = IdentityLibrary() + custom
    before = {id(lib): dict(vars(lib)) for lib in (poly, fourier, generalized, custom, concat)}
    compile_basis(generalized, FEATURES, n_delta=2)
    compile_basis(concat, FEATURES, n_delta=2)
    for lib in (poly, fourier, generalized, custom, concat):
        _assert_unfitted(lib)
        assert vars(lib).keys() == before[id(lib)].keys()
        for key, value in before[id(lib)].items():
            assert getattr(lib, key) is value
    assert generalized.inputs_per_library is None and custom.function_names is None


def test_already_fitted_library_keeps_its_fit():
    library = PolynomialLibrary(degree=2).fit(np.ones((4, 5)))
    compiled = compile_basis(library, FEATURES, n_delta=1)
    assert library.n_features_in_ == 5 and library.transform(np.ones((2, 5))).shape == (2, 21)
    assert len(compiled.names) == 10


@pytest.mark.parametrize(
    ("factory", "match"),
    [
        (lambda: PDELibrary(function_library=PolynomialLibrary(), derivative_order=1,
                            spatial_grid=np.linspace(0, 1, 10)), "PDELibrary"),
        # WeakPDELibrary.__init__ is broken with numpy 2.x; rejection only needs the type.
        (lambda: object.__new__(WeakPDELibrary), "WeakPDELibrary"),
        (lambda: SINDyPILibrary(library_functions=[lambda x: x], t=np.linspace(0, 1, 10)),
         "SINDyPILibrary"),
        (lambda: ParameterizedLibrary(num_parameters=1, num_features=2), "ParameterizedLibrary"),
        (lambda: PolynomialLibrary() + PDELibrary(derivative_order=1, spatial_grid=np.ones(9)),
         "PDELibrary"),
        (lambda: PolynomialFeatures(degree=2), "PolynomialFeatures"),
        (lambda: "poly", "str"),
    ],
)  # fmt: skip
def test_unsupported_libraries_are_rejected(factory, match):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        library = factory()
    with pytest.raises(TypeError, match=match) as info:
        compile_basis(library, FEATURES, n_delta=1)
    assert "Supported:" in str(info.value) and "PolynomialLibrary" in str(info.value)


def test_custom_function_using_numpy_names_the_function():
    library = CustomLibrary(
        [lambda x: jnp.sin(x), _numpy_exp], function_names=[lambda x: f"s({x})", lambda x: "e"]
    )
    with pytest.raises(TypeError, match=r"function 1 \('_numpy_exp'.*jax\.numpy"):
        compile_basis(library, FEATURES, n_delta=1)


def test_custom_function_must_be_a_python_function():
    with pytest.raises(TypeError, match="function 0"):
        compile_basis(CustomLibrary([np.sin]), FEATURES, n_delta=1)


def test_custom_function_must_return_a_scalar():
    library = CustomLibrary([lambda x: jnp.stack([x, x])])
    with pytest.raises(TypeError, match="one scalar"):
        compile_basis(library, FEATURES, n_delta=1)


# ---------------------------------------------------------------------------
# Gradients
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["poly3_nobias", "poly2", "tensored", "nested"])
def test_pysindy_gradients_finite_at_zero_and_match_finite_differences(name):
    with jax.enable_x64(True):
        compiled = compile_basis(LIBRARIES[name](), FEATURES, n_delta=2)
        jac = jax.jit(jax.jacfwd(compiled.evaluate, argnums=1))
        assert np.all(np.isfinite(jac({}, jnp.zeros(3))))
        grad0 = jax.grad(lambda v: jnp.sum(compiled.evaluate({}, v) ** 2))
        assert np.all(np.isfinite(jax.jit(grad0)(jnp.zeros(3))))
        v = np.random.default_rng(3).normal(size=3)
        numeric = _finite_difference(jax.jit(lambda w: compiled.evaluate({}, w)), v)
        np.testing.assert_allclose(jac({}, v), numeric, rtol=1e-6, atol=1e-8)


def test_ridge_gradients_finite_at_zero_and_match_finite_differences():
    with jax.enable_x64(True):
        compiled = compile_basis(RidgeBasis(), FEATURES, n_delta=2, random_state=0)
        params = {k: jnp.asarray(a) for k, a in compiled.init_params.items()}
        jac_v = jax.jit(jax.jacfwd(compiled.evaluate, argnums=1))
        jac_p = jax.jit(jax.jacrev(compiled.evaluate, argnums=0))
        for leaf in jax.tree_util.tree_leaves(
            (jac_v(params, jnp.zeros(3)), jac_p(params, jnp.zeros(3)))
        ):
            assert np.all(np.isfinite(leaf))
        v = np.random.default_rng(4).normal(size=3)
        numeric = _finite_difference(jax.jit(lambda w: compiled.evaluate(params, w)), v)
        np.testing.assert_allclose(jac_v(params, v), numeric, rtol=1e-6, atol=1e-8)
        direction = jax.tree_util.tree_map(lambda a: jnp.ones_like(a) * 0.3, params)

        @jax.jit
        def along(t):
            shifted = jax.tree_util.tree_map(lambda a, d: a + t * d, params, direction)
            return compiled.evaluate(shifted, v)

        _, tangent = jax.jvp(along, (0.0,), (1.0,))
        numeric_t = (along(1e-6) - along(-1e-6)) / 2e-6
        np.testing.assert_allclose(tangent, numeric_t, rtol=1e-6, atol=1e-8)


# ---------------------------------------------------------------------------
# Ridge basis
# ---------------------------------------------------------------------------


def _numpy_ridge(W, B, v, activations):
    z = np.einsum("ikj,k->ij", W, v) + B
    table = {
        "sigmoid": lambda a: 1 / (1 + np.exp(-a)),
        "softplus": lambda a: np.log1p(np.exp(a)),
        "tanh": np.tanh,
        "sin": np.sin,
        "cos": np.cos,
        "identity": lambda a: a,
        "square": lambda a: a**2,
        "cube": lambda a: a**3,
    }
    return np.stack([table[a](z[:, j]) for j, a in enumerate(activations)], axis=1)


def test_ridge_shapes_names_and_values():
    activations = (
        "cube",
        "tanh",
        "sin",
        "tanh",
        "sigmoid",
        "softplus",
        "identity",
        "cos",
        "square",
    )
    with jax.enable_x64(True):
        compiled = compile_basis(RidgeBasis(activations), FEATURES, n_delta=2, random_state=1)
        W, B = compiled.init_params["W"], compiled.init_params["B"]
        assert W.shape == (2, 3, 9) and B.shape == (2, 9)
        assert compiled.names == tuple(f"{a}(r{j})" for j, a in enumerate(activations))
        assert compiled.omega_trainable.shape == (2, 9) and compiled.omega_trainable.all()
        assert compiled.trainable["W"].shape == W.shape and compiled.trainable["W"].all()
        v = np.random.default_rng(5).normal(size=3)
        Phi = compiled.evaluate(compiled.init_params, v)
        assert Phi.shape == (2, 9)
        np.testing.assert_allclose(Phi, _numpy_ridge(W, B, v, activations), rtol=1e-12)


def test_ridge_masks_are_returned():
    W_mask = np.zeros((2, 3, 4), dtype=bool)
    W_mask[0, 1, 2] = True
    omega = np.array([[True, False, True, False], [False, True, True, True]])
    basis = RidgeBasis(("tanh",) * 4, W_trainable=W_mask, B_trainable=False, omega_trainable=omega)
    compiled = compile_basis(basis, FEATURES, n_delta=2, random_state=0)
    np.testing.assert_array_equal(compiled.trainable["W"], W_mask)
    assert compiled.trainable["B"].shape == (2, 4) and not compiled.trainable["B"].any()
    np.testing.assert_array_equal(compiled.omega_trainable, omega)
    assert basis.W_trainable is W_mask  # stored as given


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"W_trainable": np.ones((2, 4), dtype=bool)}, ValueError, "W_trainable"),
        ({"B_trainable": np.ones((2, 4))}, TypeError, "B_trainable"),
        ({"omega_trainable": np.ones((4, 2), dtype=bool)}, ValueError, "omega_trainable"),
        ({"W_init": np.zeros((2, 4, 3))}, ValueError, r"W_init must have shape"),
        ({"B_init": np.zeros(4)}, ValueError, r"B_init must have shape"),
        ({"W_init": np.full((2, 3, 4), np.nan)}, ValueError, "W_init must contain only finite"),
        ({"scale": -1.0}, ValueError, "scale"),
    ],
)
def test_ridge_bad_arguments(kwargs, error, match):
    basis = RidgeBasis(("tanh", "sin", "cos", "cube"), **kwargs)
    with pytest.raises(error, match=match):
        compile_basis(basis, FEATURES, n_delta=2, random_state=0)


def test_ridge_unknown_activation():
    with pytest.raises(ValueError, match=r"relu.*valid names.*sigmoid"):
        RidgeBasis(("tanh", "relu"))
    with pytest.raises(TypeError, match="activations"):
        RidgeBasis("tanh")
    basis = RidgeBasis(("tanh",))
    basis.activations = ("gelu",)
    with pytest.raises(ValueError, match="gelu"):
        compile_basis(basis, FEATURES, n_delta=1)


def test_ridge_initialisation_is_deterministic_and_respects_inits():
    basis = RidgeBasis(ALL_ACTIVATIONS, scale=0.5)
    a = compile_basis(basis, FEATURES, n_delta=2, random_state=7).init_params
    b = compile_basis(basis, FEATURES, n_delta=2, random_state=np.random.RandomState(7)).init_params
    c = compile_basis(basis, FEATURES, n_delta=2, random_state=8).init_params
    unit = compile_basis(RidgeBasis(ALL_ACTIVATIONS), FEATURES, 2, random_state=7).init_params
    for key in ("W", "B"):
        np.testing.assert_array_equal(a[key], b[key])
        assert not np.allclose(a[key], c[key])
        np.testing.assert_allclose(a[key], 0.5 * unit[key])
    W_init = np.arange(2 * 3 * 8, dtype=float).reshape(2, 3, 8)
    given = compile_basis(RidgeBasis(ALL_ACTIVATIONS, W_init=W_init, scale=0.5), FEATURES, 2, 7)
    np.testing.assert_array_equal(given.init_params["W"], W_init)
    np.testing.assert_array_equal(given.init_params["B"], a["B"])  # B independent of W_init
    given.init_params["W"][0, 0, 0] = -1.0
    assert W_init[0, 0, 0] == 0.0  # a copy, not an alias


def test_ridge_fixed_entries_and_generator_seed():
    gen = np.random.default_rng(0)
    basis = RidgeBasis(("identity",), W_init=np.zeros((1, 3, 1)), W_trainable=False)
    compiled = compile_basis(basis, FEATURES, n_delta=1, random_state=gen)
    assert not compiled.trainable["W"].any()
    Phi = compiled.evaluate(compiled.init_params, jnp.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(Phi, compiled.init_params["B"], rtol=1e-6)


def test_ridge_is_a_plain_value_class():
    basis = RidgeBasis(("tanh", "sin"), W_init=np.zeros((1, 3, 2)), scale=0.1)
    text = repr(basis)
    assert text.startswith("RidgeBasis(") and "'tanh'" in text and "scale=0.1" in text
    assert "W_init=<array shape=(1, 3, 2)" in text and "B_init" not in text
    for clone in (pickle.loads(pickle.dumps(basis)), copy.deepcopy(basis)):
        assert clone.activations == basis.activations and clone.scale == 0.1
        np.testing.assert_array_equal(clone.W_init, basis.W_init)


# ---------------------------------------------------------------------------
# jit / vmap / validation
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("which", ["pysindy", "ridge"])
def test_evaluate_under_jit_and_vmap(which):
    library = LIBRARIES["nested"]() if which == "pysindy" else RidgeBasis()
    compiled = compile_basis(library, FEATURES, n_delta=3, random_state=0)
    params = compiled.init_params
    V = jnp.asarray(_data(7), dtype=jnp.float32)
    eager = np.stack([np.asarray(compiled.evaluate(params, v)) for v in V[:2]])
    jitted = jax.jit(compiled.evaluate)(params, V[0])
    vmapped = jax.vmap(compiled.evaluate, in_axes=(None, 0))(params, V)
    jit_vmapped = jax.jit(jax.vmap(compiled.evaluate, in_axes=(None, 0)))(params, V)
    np.testing.assert_allclose(jitted, eager[0], rtol=1e-5, atol=1e-6)
    for result in (vmapped, jit_vmapped, evaluate_matrix(compiled, params, V)):
        assert result.shape == (7, 3, len(compiled.names)) and result.dtype == jnp.float32
        np.testing.assert_allclose(result[:2], eager, rtol=1e-5, atol=1e-6)


def test_input_validation():
    compiled = compile_basis(PolynomialLibrary(), FEATURES, n_delta=1)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        compiled.evaluate({}, jnp.zeros(4))
    with pytest.raises(ValueError, match="V must have shape"):
        evaluate_matrix(compiled, {}, jnp.zeros((5, 2)))
    with pytest.raises(ValueError, match="n_delta"):
        compile_basis(PolynomialLibrary(), FEATURES, n_delta=0)
    with pytest.raises(TypeError, match="input_features"):
        compile_basis(PolynomialLibrary(), "x1", n_delta=1)
    ridge = compile_basis(RidgeBasis(("tanh",)), FEATURES, n_delta=1, random_state=0)
    with pytest.raises(KeyError, match="'W' and 'B'"):
        ridge.evaluate({"W": ridge.init_params["W"]}, jnp.zeros(3))


def test_pysindy_is_imported_on_the_first_dictionary_not_with_the_package_or_its_data():
    code = (
        "import sys, sk_offwhite, sk_offwhite.datasets as d; assert 'pysindy' not in sys.modules; "
        "d.load_cascaded_tanks(); d.cascaded_tanks_physics(); assert 'pysindy' not in sys.modules; "
        "d.make_cascaded_tanks(n_samples=50, random_state=0); assert 'pysindy' in sys.modules; "
        "import pysindy as ps; "
        "sk_offwhite.compile_basis(ps.PolynomialLibrary(degree=2), ['x', 'u'], 1)"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
