"""The opt-in fused loops: XLA_FLAGS edited as asked, loops compiled into one kernel, the
same fit as with XLA's default, and a clear answer when it comes too late."""

import json
import os
import subprocess
import sys

import pytest

from sk_offwhite import enable_fused_loops
from sk_offwhite.runtime._backend import with_backend_option

OPTION = "xla_cpu_small_while_loop_byte_threshold"

KERNEL = """
import jax, jax.numpy as jnp
jax.config.update("jax_enable_x64", True)
def body(x, u):
    s = jnp.stack([jnp.sin(x[i % 2] * (i + 1.0) + u) for i in range(40)])
    return x + 1e-3 * jnp.array([s.sum(), s[::2].sum()]), x[0]
f = jax.jit(lambda x0, u: jax.lax.scan(body, x0, u)[1])
print("xla_cpu_small_call" in f.lower(jnp.ones(2), jnp.ones(1000)).compile().as_text())
"""
"""Prints whether a scan of 1000 steps with a 40-operation body (in a child process, 64-bit)
is compiled into one kernel."""

FIT = (
    "import json, numpy as np, pysindy as ps, sk_offwhite;"
    "from sk_offwhite.datasets import make_cascaded_tanks;"
    "d = make_cascaded_tanks(n_samples=300, random_state=0);"
    "est = sk_offwhite.GreyBoxSparseRegressor(d.physics, library=ps.PolynomialLibrary(degree=2),"
    " gamma=1e-3, max_iter=30).fit(d.u, d.z);"
    "print(json.dumps([est.theta_.tolist(), est.coef_.ravel().tolist(), est.score(d.u, d.z)]))"
)


def _run(code: str, flags: str | None, setup: str = "") -> str:
    environment = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    if flags is not None:
        environment["XLA_FLAGS"] = flags
    out = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", setup + code],
        env=environment,
        capture_output=True,
        text=True,
        check=True,
    )
    return out.stdout.strip().splitlines()[-1]


@pytest.mark.parametrize(
    "flags, expected",
    [
        ("", "--xla_backend_extra_options=a=1"),
        ("--xla_cpu_ftz=true", "--xla_cpu_ftz=true --xla_backend_extra_options=a=1"),
        (
            "--xla_backend_extra_options=b=2 --xla_cpu_ftz=true",
            "--xla_backend_extra_options=b=2,a=1 --xla_cpu_ftz=true",
        ),
        ("--xla_backend_extra_options= --x=1", "--xla_backend_extra_options=a=1 --x=1"),
    ],
)
def test_with_backend_option_adds_to_the_list(flags, expected):
    assert with_backend_option(flags, "a=1") == expected


def test_xla_default_runs_large_loops_op_by_op():
    assert _run(KERNEL, "") == "False"


def test_enabled_before_jax_starts_compiles_the_loop_into_one_kernel():
    setup = "import sk_offwhite\nassert sk_offwhite.enable_fused_loops()\n"
    assert _run(KERNEL, "", setup) == "True"


def test_enabled_after_jax_started_warns_and_reaches_child_processes():
    setup = (
        "import warnings, subprocess, sys, jax, jax.numpy as jnp, sk_offwhite\n"
        "jnp.ones(1).block_until_ready()\n"
        "warnings.simplefilter('error')\n"
        "late = None\n"
        "try:\n    sk_offwhite.enable_fused_loops()\n"
        "except RuntimeWarning as w:\n    late = str(w)\n"
        "assert 'already started' in late, late\n"
        f"print(subprocess.run([sys.executable, '-c', {KERNEL!r}], capture_output=True, "
        "text=True).stdout.strip())\n"
    )
    assert _run("", "", setup) == "True"


@pytest.mark.parametrize(
    "setup, expected",
    [
        ("", "False"),
        ("sk_offwhite.enable_fused_loops()\n", "True"),
        ("jax.numpy.ones(1).block_until_ready()\nsk_offwhite.enable_fused_loops()\n", "False"),
    ],
    ids=["xla-default", "enabled-before-start", "enabled-too-late"],
)
def test_the_process_knows_whether_its_loops_are_fused(setup, expected):
    code = "print(sk_offwhite.runtime._backend.fused_loops())"
    assert _run(code, "", "import jax, sk_offwhite\n" + setup) == expected


def test_an_application_value_is_left_as_it_is(monkeypatch):
    monkeypatch.setenv("XLA_FLAGS", f"--xla_backend_extra_options={OPTION}=5")
    assert enable_fused_loops() is True
    assert os.environ["XLA_FLAGS"] == f"--xla_backend_extra_options={OPTION}=5"


def test_byte_limit_must_be_positive():
    with pytest.raises(ValueError, match="byte_limit"):
        enable_fused_loops(0)


def test_the_fit_is_the_same_with_and_without_fused_loops():
    fused = json.loads(_run(FIT, f"--xla_backend_extra_options={OPTION}=1000000000"))
    default = json.loads(_run(FIT, ""))
    for a, b in zip(fused, default, strict=True):
        assert a == pytest.approx(b, rel=1e-6, abs=1e-9)


COMPILED = (
    "import json, logging, io, jax, sk_offwhite;"
    "from sk_offwhite.datasets import make_cascaded_tanks;"
    "d = make_cascaded_tanks(n_samples=200, random_state=0);"
    "log = io.StringIO(); logging.getLogger('jax').addHandler(logging.StreamHandler(log));"
    "jax.config.update('jax_log_compiles', True);"
    "names = lambda: [line.split(' of ')[1].split(' ')[0] for line in log.getvalue()"
    ".splitlines() if line.startswith('Finished XLA compilation')];"
    "est = sk_offwhite.GreyBoxSparseRegressor(d.physics, max_iter=20).fit(d.u, d.z);"
    "est.predict(d.u); first = names(); log.seek(0); log.truncate();"
    "sk_offwhite.GreyBoxSparseRegressor(d.physics, max_iter=20).fit(d.u_val, d.z_val);"
    "print(json.dumps([first, names()]))"
)
"""Prints the names of the XLA programs that a first fit and predict compile, then those a
second fit of the same physics on a record of the same length compiles (fresh process)."""


@pytest.fixture(scope="module")
def compiled() -> list[list[str]]:
    return json.loads(_run(COMPILED, None))


def test_a_first_fit_compiles_no_single_operation_programs(compiled):
    names = compiled[0]
    assert {"jit(_run_on_device)", "jit(free_run)"} <= set(names), names
    single = {"jit(stage)", "jit(convert_element_type)", "jit(broadcast_in_dim)", "jit(sqrt)"}
    assert not single & set(names), names
    assert len(names) <= 6, names


def test_a_second_fit_of_the_same_physics_compiles_nothing(compiled):
    """The checks of the physics at its initial guess included (one program per physics)."""
    assert compiled[1] == []
