"""The opt-in persistent compilation cache: off unless asked for, then filled by a fit."""

import logging
import os
import subprocess
import sys

FIT = (
    "import numpy as np, jax, sk_offwhite;"
    "from sk_offwhite.datasets import make_leaky_tank;"
    "d = make_leaky_tank(n_samples=100, random_state=0);"
    "{setup}"
    "sk_offwhite.GreyBoxSparseRegressor(d.physics, max_iter=5).fit(d.u, d.z);"
    "print(jax.config.jax_compilation_cache_dir)"
)
CHILD = (
    "import subprocess, sys;"
    "child = subprocess.run([sys.executable, '-c', {inner!r}], capture_output=True, text=True);"
    "print(child.stdout.strip())"
)
"""A child process started after the cache is enabled, printing what ``inner`` prints."""


def _run(setup: str, environment: dict) -> str:
    out = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", FIT.format(setup=setup)],
        env=environment,
        capture_output=True,
        text=True,
        check=True,
    )
    return out.stdout.strip().splitlines()[-1]


def _environment(**extra) -> dict:
    environment = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    return environment | extra


def test_the_package_leaves_the_cache_off():
    assert _run("", _environment()) == "None"


def test_enable_compilation_cache_keeps_the_fit_programs(tmp_path):
    used = _run(
        "sk_offwhite.enable_compilation_cache();", _environment(SK_OFFWHITE_CACHE=str(tmp_path))
    )
    assert used == str(tmp_path.resolve())
    assert len(list(tmp_path.iterdir())) >= 2  # at least the two solver programs


def test_processes_started_afterwards_share_the_cache(tmp_path):
    inner = "import jax; print(jax.config.jax_compilation_cache_dir)"
    setup = (
        f"sk_offwhite.enable_compilation_cache({str(tmp_path)!r});"
        + CHILD.format(inner=inner)
        + ";"
    )
    out = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", FIT.format(setup=setup)],
        env=_environment(),
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip().splitlines()[0] == str(tmp_path.resolve())


def test_release_drops_the_compiled_programs_of_a_fit():
    import numpy as np

    from sk_offwhite import GreyBoxSparseRegressor, release_compiled_programs
    from sk_offwhite.datasets import make_leaky_tank
    from sk_offwhite.solvers._device import _run_on_device

    tank = make_leaky_tank(n_samples=100, random_state=0)
    est = GreyBoxSparseRegressor(tank.physics, max_iter=5).fit(tank.u, tank.z)
    before = est.predict(tank.u)
    assert _run_on_device._cache_size() > 0
    release_compiled_programs()
    assert _run_on_device._cache_size() == 0
    np.testing.assert_array_equal(est.predict(tank.u), before)  # compiled again on demand


def test_releasing_the_package_programs_keeps_the_applications_own():
    import jax
    import jax.numpy as jnp

    from sk_offwhite import GreyBoxSparseRegressor, release_package_programs
    from sk_offwhite.datasets import make_leaky_tank
    from sk_offwhite.solvers._device import _run_on_device

    data = make_leaky_tank(n_samples=100, random_state=0)
    GreyBoxSparseRegressor(data.physics, max_iter=5).fit(data.u, data.z)
    mine = jax.jit(lambda x: 2.0 * x)
    mine(jnp.ones(3))
    assert _run_on_device._cache_size() > 0
    assert release_package_programs() >= 5
    assert _run_on_device._cache_size() == 0 and mine._cache_size() == 1


def test_a_fit_with_a_dictionary_runs_all_its_stages_on_one_program():
    import numpy as np
    import pysindy as ps

    from sk_offwhite import GreyBoxSparseRegressor, release_package_programs
    from sk_offwhite.datasets import make_leaky_tank
    from sk_offwhite.solvers._device import _run_on_device

    data = make_leaky_tank(n_samples=100, random_state=0)
    release_package_programs()
    est = GreyBoxSparseRegressor(data.physics, ps.PolynomialLibrary(), gamma=1e-3, max_iter=20)
    est.fit(data.u, data.z)
    # the physics-only stage (unit penalty scales), the penalised stage and the refit
    assert len(est.loss_history_) > 1 and np.isfinite(est.gamma_max_)
    assert _run_on_device._cache_size() == 1


def test_records_of_nearby_lengths_share_one_prediction_program():
    import jax
    import numpy as np

    from sk_offwhite import GreyBoxSparseRegressor, release_package_programs
    from sk_offwhite._rollout import free_run
    from sk_offwhite.datasets import make_leaky_tank

    data = make_leaky_tank(n_samples=400, random_state=0)
    est = GreyBoxSparseRegressor(data.physics, max_iter=20).fit(data.u, data.z)
    release_package_programs()
    x0 = est.x0_
    shorter = est.simulate(data.u[:341], x0=x0)
    longer = est.simulate(data.u[:342], x0=x0)
    assert free_run._cache_size() == 1  # both padded to 352 samples
    np.testing.assert_array_equal(longer.outputs[:341], shorter.outputs)
    model = est._fitted_model()
    with jax.enable_x64(True):
        params = {k: jax.numpy.asarray(v) for k, v in est._fitted_blocks().items()}
        _, unpadded, _ = free_run(model, params, jax.numpy.asarray(x0), data.u[:341])
    np.testing.assert_array_equal(shorter.outputs, np.asarray(unpadded))


def test_the_residual_count_needs_no_trace_when_the_record_outnumbers_the_variables(caplog):
    import jax

    from sk_offwhite import GreyBoxSparseRegressor, release_package_programs
    from sk_offwhite.datasets import make_leaky_tank

    data = make_leaky_tank(n_samples=100, random_state=0)
    release_package_programs()  # whatever this process fitted before
    with jax.log_compiles(True), caplog.at_level(logging.WARNING, logger="jax"):
        for n_samples in (100, 80):
            GreyBoxSparseRegressor(data.physics, max_iter=5).fit(
                data.u[:n_samples], data.z[:n_samples]
            )
    messages = [r.getMessage() for r in caplog.records]
    assert any("tracing _run_on_device" in m for m in messages)  # the log is read
    assert not [m for m in messages if "tracing free_residuals" in m]


def test_the_loop_releases_programs_after_each_stage_when_asked(monkeypatch):
    from sk_offwhite.loop import LoopSettings, _loop
    from sk_offwhite.loop._progress import StageClock

    calls = []
    monkeypatch.setattr(_loop, "release_package_programs", lambda: calls.append(1))
    for release, expected in ((True, 2), (False, 0)):
        settings, clock = LoopSettings(release_programs=release), StageClock()
        with _loop._stage(clock, "one", settings):
            pass
        assert _loop._released(settings, "value") == "value"
        assert len(calls) == expected and "one" in clock.seconds
        calls.clear()
