"""Shared synthetic systems for the tests (noise-free unless stated)."""

import os
import shutil
import tempfile

# Set before JAX starts, for this process and every process it spawns (xdist workers,
# example scripts, joblib and Dask workers): one XLA thread per process, since the two
# workers already use both cores, and one compilation cache for the whole run, so a
# program compiled by one process is loaded, not compiled again, by the others. The cache
# keeps every program, as `enable_compilation_cache` does: JAX's default keeps only those
# that take over 1 s to compile, and most of the solver's take less.
os.environ.setdefault(
    "XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
)
CREATED_CACHE = None
if "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    CREATED_CACHE = tempfile.mkdtemp(prefix="sk_offwhite_jax_")
    os.environ["JAX_COMPILATION_CACHE_DIR"] = CREATED_CACHE
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES", "0")

from sk_offwhite import enable_fused_loops  # noqa: E402 (imports JAX, starts no backend)

enable_fused_loops()  # as the examples do; test_backend.py compares with XLA's default

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from sk_offwhite import Parameter, PhysicsModel  # noqa: E402

LONGEST_FIRST = (
    "test_loop_mechanical.py",
    "test_loop.py",
    "test_examples.py",
    "test_vehicle.py",
    "test_sklearn.py",
    "test_loop_thresholds.py",
    "test_sparsity.py",
    "test_estimator.py",
    "test_loop_synthetic.py",
    "test_output_correction.py",
    "test_structured.py",
    "test_loop_thermal.py",
)
"""Modules by decreasing run time, scheduled first (measured without the studies: 190 s
to 44 s of a worker's time on a 2-core machine; the first holds only studies)."""

STUDY_REASON = "a study of the whole loop on one system (minutes): run with --run-slow"


def marking_studies(values, studies) -> list:
    """``values`` as the parameters of a test, those in ``studies`` marked ``slow``."""
    return [pytest.param(v, marks=pytest.mark.slow) if v in studies else v for v in values]


def pytest_addoption(parser):
    parser.addoption(
        "--run-slow",
        action="store_true",
        help="also run the tests marked slow, the closed loop on every generator (alone, "
        "about 11 minutes on 2 cores)",
    )


def pytest_unconfigure(config):
    """The process that created the compilation cache removes it at the end of the run."""
    if CREATED_CACHE is not None:
        shutil.rmtree(CREATED_CACHE, ignore_errors=True)


@pytest.fixture(scope="module", autouse=True)
def _release_compiled_programs():
    """Drop every compiled program after a module (they reload from the disk cache).

    One worker runs many modules; each fit of a new physics compiles its own programs, and
    their executable memory maps add up until the kernel's limit on memory maps (65 530
    here) crashes the compiler.
    """
    yield
    jax.clear_caches()


def pytest_collection_modifyitems(config, items):
    """Run the longest modules first (stable: the order inside a module is kept), and skip
    the studies marked ``slow`` unless ``--run-slow`` is given.

    With ``--dist loadscope --no-loadscope-reorder`` (pyproject) each module runs whole on
    one worker, in this order, so no worker is left alone with a long module at the end.
    """
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
    if config.getoption("--run-slow"):
        return
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(pytest.mark.skip(reason=STUDY_REASON))


TANKS_TRUE = {"k1": 0.076, "k2": 0.027, "k3": 0.042, "k4": 0.039}
TANKS_X0 = np.array([3.5, 5.2])


def safe_sqrt(x):
    return jnp.sqrt(jnp.maximum(x, 1e-6))


def tanks_step(x, u, theta):
    """Cascaded tanks, eq. (21) of the paper without noise, Ts = 4 s."""
    ts = 4.0
    return jnp.stack(
        [
            x[0] + ts * (-theta["k1"] * safe_sqrt(x[0]) + theta["k4"] * u[0]),
            x[1] + ts * (theta["k2"] * safe_sqrt(x[0]) - theta["k3"] * safe_sqrt(x[1])),
        ]
    )


def multisine(n_samples, rng, band=0.0144, ts=4.0, mean=2.8, std=1.0):
    freqs = np.fft.rfftfreq(n_samples, ts)
    excited = (freqs > 0) & (freqs < band)
    spectrum = np.zeros(freqs.shape, complex)
    spectrum[excited] = np.exp(1j * rng.uniform(0, 2 * np.pi, excited.sum()))
    signal = np.fft.irfft(spectrum, n_samples)
    return (mean + std * signal / signal.std())[:, None]


def simulate_numpy(step, theta, x0, u):
    with jax.enable_x64(True):
        theta = {k: jnp.asarray(v) for k, v in theta.items()}
        x, outputs = jnp.asarray(x0, float), []
        for u_k in u:
            outputs.append(np.asarray(x))
            x = step(x, jnp.asarray(u_k), theta)
    return np.asarray(outputs)


def tanks_physics(init=0.05, x0=None):
    bounds = (1e-6, None)
    return PhysicsModel(
        tanks_step,
        [1],
        {
            "k1": Parameter(init, bounds),
            "k2": Parameter(init, bounds),
            "k3": Parameter(init, bounds),
            "k4": Parameter(TANKS_TRUE["k4"], fixed=True),
        },
        n_states=2,
        n_inputs=1,
        x0=x0,
        x0_bounds=(0.0, None),
        state_names=("x1", "x2"),
    )


@pytest.fixture(scope="session")
def tanks_data():
    """Noise-free cascaded-tanks record (u, z, states) from the true parameters."""
    u = multisine(1024, np.random.default_rng(0))
    states = simulate_numpy(tanks_step, TANKS_TRUE, TANKS_X0, u)
    return u, states[:, 1:2], states


def solver_problem(physics, records, horizon, with_library: bool, omega_start: float):
    """What the solvers take for ``physics`` fitted to ``records`` (cut into windows of
    ``horizon`` samples, if given), with a degree-2 dictionary whose weights all start at
    ``omega_start`` (off the L1 kink) or none: ``(problem, free0, model, layout)``."""
    import pysindy as ps

    from sk_offwhite.dictionaries import compile_basis
    from sk_offwhite.fitting._problem import (
        bound_blocks,
        build_model,
        free_blocks,
        initial_blocks,
        make_problem,
    )
    from sk_offwhite.simulation._layout import Layout
    from sk_offwhite.simulation._objective import CostWeights
    from sk_offwhite.simulation._segments import make_segments

    library = ps.PolynomialLibrary(degree=2) if with_library else None
    basis = None if library is None else compile_basis(library, ["x1", "x2", "u0"], 2)
    model = build_model(physics, basis, (0, 1))
    segments = make_segments(records, horizon)
    blocks = initial_blocks(physics, basis, model, records, segments, horizon)
    blocks["omega"] = blocks.get("omega", np.zeros(0)) + omega_start
    blocks = {k: v for k, v in blocks.items() if np.size(v) or k != "omega"}
    layout = Layout.from_arrays(blocks)
    weights = CostWeights(1e-3, 1.0, 0.0, 10.0, 1e3)
    free = free_blocks(physics, basis, model, segments)
    problem, free0 = make_problem(
        layout, blocks, free, bound_blocks(physics, blocks, records, segments), segments, weights
    )
    return problem, free0, model, layout


def driven_mass_rhs(x, u, theta):
    """A mass driven by a force against a viscous friction: q' = v, M v' = tau - Fv v."""
    return jnp.stack([x[1], (u[0] - theta["Fv"] * x[1]) / theta["M"]])


def driven_mass(M=1.0, Fv=1.0, **options) -> PhysicsModel:
    """`driven_mass_rhs` at 100 Hz: states ``(q, v)`` of kinds position and velocity, the
    input ``tau`` a force; ``options`` go to `PhysicsModel.from_ode` (``x0``, kinds)."""
    settings = dict(state_names=("q", "v"), input_names=("tau",),
                    state_kinds=("position", "velocity"), input_kinds=("force",))  # fmt: skip
    parameters = {"M": Parameter(M, (0.01, None)), "Fv": Fv}
    return PhysicsModel.from_ode(
        driven_mass_rhs, 0.01, output=0, parameters=parameters, n_states=2, n_inputs=1,
        **{**settings, **options},
    )  # fmt: skip


def driven_record(truth: PhysicsModel, n: int, seed: int, x0=(0.0, 0.0)):
    """``truth`` driven from ``x0`` by a band-limited force, its output measured with noise
    of a thousandth of its spread: ``(force, z)``."""
    rng = np.random.default_rng(seed)
    force = np.convolve(rng.normal(0, 6.0, n + 50), np.ones(25) / 5, "same")[:n, None]
    z = free_run(truth, force, x0)[1]
    return force, z + rng.normal(0, 1e-3 * np.std(z), z.shape)


def free_run(physics: PhysicsModel, u, x0=None) -> tuple[np.ndarray, np.ndarray]:
    """``(states, outputs)`` of ``physics`` driven by ``u`` from ``x0`` (``None``: its
    own), at its parameters' values."""
    from sk_offwhite.fitting._problem import build_model
    from sk_offwhite.simulation._rollout import simulate

    start = physics.x0 if x0 is None else x0
    with jax.enable_x64(True):
        params = {"theta": jnp.asarray(physics.parameter_values())}
        model = build_model(physics, None, ())
        states, outputs, _ = simulate(model, params, jnp.asarray(start), jnp.asarray(u))
    return np.asarray(states), np.asarray(outputs)
