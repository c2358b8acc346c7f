"""Every script in ``examples/`` runs (at reduced size), so the examples cannot rot.

Each example runs as a subprocess with the arguments below; a new example must be added to
``EXAMPLES`` (or to ``NOT_RUN`` with the reason) or `test_every_example_is_listed` fails.
The loop examples run in one process (``--n-jobs 1``) at their ``--quick`` sizes.
"""

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import marking_studies

from sk_offwhite.datasets._cascaded_tanks import cascaded_tanks_rhs

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = {
    "quickstart.py": ["--quick"],
    # one process: the suite's workers already hold the cores, and worker processes would
    # each compile the same programs again
    "cascaded_tanks_loop.py": "--quick --n-jobs 1 --out {tmp}".split(),
    "vehicle_montecarlo.py": (
        "--runs 1 --noise-runs 1 --noise-levels 1e-3 --n-samples 300 --max-iter 100 --out {tmp}"
    ).split(),
    "vehicle_certificates.py": "--runs 1 --n-samples 300 --normalize-columns --out {tmp}".split(),
    "emps_loop.py": "--quick --n-jobs 1 --out {tmp}".split(),
    "silverbox_loop.py": "--quick --n-jobs 1 --out {tmp}".split(),
}
NOT_RUN = {
    "cascaded_tanks_variants.py": (
        "a study of the main job's model: the whole loop and then 16 variants, each "
        "cross-validated, beyond the suite's budget; what it calls are the loop's own "
        "public functions (close_the_loop, fit_continued, held_out_rmse), exercised by "
        "test_loop.py"
    ),
    "cascaded_tanks_study.py": (
        "exploration of hand-built effects: even `--folds 2 --max-iter 5 --gammas 0.1` "
        "compiles once per effect structure and library, beyond the suite's budget; its "
        "effects are tested in test_tanks_effects.py"
    ),
}
TIMEOUT_S = 600


def _present() -> list[str]:
    """The example scripts (a module whose name starts with ``_`` is what they share)."""
    return sorted(p.name for p in (ROOT / "examples").glob("*.py") if not p.name.startswith("_"))


def test_every_example_is_listed():
    unlisted = set(_present()) - set(EXAMPLES) - set(NOT_RUN)
    assert not unlisted, f"add {sorted(unlisted)} to EXAMPLES (with quick arguments) or NOT_RUN"


STUDIES = {"vehicle_montecarlo.py", "emps_loop.py", "silverbox_loop.py"}
"""Examples run only with ``--run-slow`` (vehicle_certificates.py fits the same vehicle)."""


@pytest.mark.parametrize(
    "script", marking_studies([s for s in EXAMPLES if s in _present()], STUDIES)
)
def test_example_runs(script, tmp_path):
    args = [a.format(tmp=tmp_path) for a in EXAMPLES[script]]
    result = subprocess.run(
        [sys.executable, str(ROOT / "examples" / script), *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.strip(), f"{script} printed nothing"


def test_the_variants_physics_is_eq21_at_its_declared_constants():
    """The variants study's first row refits the loop's own model."""
    path = ROOT / "examples" / "cascaded_tanks_variants.py"
    spec = importlib.util.spec_from_file_location("cascaded_tanks_variants", path)
    variants = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(variants)
    physics = variants.relaxable_tanks_physics()
    theta = {name: parameter.value for name, parameter in physics.parameters.items()}
    relaxable = {name for name, parameter in physics.parameters.items() if parameter.relaxable}
    assert {"a1", "a2", "b", "c1", "c2"} <= relaxable
    for x, u in [([3.0, 5.0], [4.0]), ([0.2, 9.5], [0.5])]:
        expected = cascaded_tanks_rhs(np.array(x), np.array(u), theta)
        got = variants.tanks_rhs(np.array(x), np.array(u), theta)
        np.testing.assert_allclose(got, expected, rtol=1e-6)
