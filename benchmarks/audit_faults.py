"""Faults the package must survive: a damaged compilation cache, processes sharing a cache,
an interrupt mid-fit, round trips through pickle, joblib and clone, bitwise determinism
across processes, inputs left as they were and JAX's global settings untouched.

Run: ``python benchmarks/audit_faults.py [--json PATH]``. Each fault prints ``held`` or
``BROKEN`` with what was seen; the results go to ``benchmarks/results/audit_faults.json``
and the exit status is 1 when any fault is broken.
"""

from __future__ import annotations

import argparse
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import write_results  # noqa: E402

FIT_SCRIPT = r"""
import sys, numpy as np
from sk_offwhite import GreyBoxSparseRegressor, enable_compilation_cache
from sk_offwhite.datasets import make_leaky_tank
if sys.argv[1] != "-":
    enable_compilation_cache(sys.argv[1])
tank = make_leaky_tank(n_samples=300, random_state=0)
est = GreyBoxSparseRegressor(tank.physics, max_iter=30).fit(tank.u, tank.z)
np.save(sys.argv[2], np.asarray(est.predict(tank.u)))
"""


def _fit_in_process(cache: str, out: Path) -> np.ndarray:
    """Predictions of a fit run in a fresh interpreter (``cache`` a folder or ``-``)."""
    subprocess.run([sys.executable, "-c", FIT_SCRIPT, cache, str(out)], check=True)
    return np.load(out)


def damaged_cache(tmp: Path, how: str) -> tuple[bool, str]:
    """A cache whose entries are overwritten with garbage or cut short still fits."""
    cache = tmp / f"cache-{how}"
    reference = _fit_in_process(str(cache), tmp / "first.npy")
    for entry in (p for p in cache.rglob("*") if p.is_file()):
        data = entry.read_bytes()
        entry.write_bytes(os.urandom(len(data)) if how == "corrupted" else data[: len(data) // 2])
    again = _fit_in_process(str(cache), tmp / "again.npy")
    same = np.array_equal(reference, again)
    return same, f"predictions after the damage {'equal' if same else 'differ'}"


def shared_fresh_cache(tmp: Path) -> tuple[bool, str]:
    """Two processes filling one empty cache at once both finish with equal results."""
    cache = str(tmp / "cache-shared")
    outs = [tmp / "p0.npy", tmp / "p1.npy"]
    procs = [subprocess.Popen([sys.executable, "-c", FIT_SCRIPT, cache, str(out)]) for out in outs]
    codes = [p.wait() for p in procs]
    ok = codes == [0, 0] and np.array_equal(np.load(outs[0]), np.load(outs[1]))
    return ok, f"exit codes {codes}"


def deterministic_processes(tmp: Path) -> tuple[bool, str]:
    """Two fresh processes without a cache give bitwise equal predictions."""
    a = _fit_in_process("-", tmp / "d0.npy")
    b = _fit_in_process("-", tmp / "d1.npy")
    return bool(np.array_equal(a, b)), f"max difference {np.max(np.abs(a - b)):.3g}"


def interrupted_fit(tank) -> tuple[bool, str]:
    """SIGINT during a fit raises KeyboardInterrupt and leaves the estimator unfitted."""
    from sk_offwhite import GreyBoxSparseRegressor

    est = GreyBoxSparseRegressor(tank.physics, max_iter=5000, tol=0.0)
    timer = threading.Timer(3.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        est.fit(tank.u, tank.z)
    except KeyboardInterrupt:
        fitted = hasattr(est, "theta_")
        return not fitted, f"KeyboardInterrupt raised; fitted state {'left' if fitted else 'none'}"
    finally:
        timer.cancel()
    return False, "the fit ended before the interrupt"


def round_trips(tank, tmp: Path) -> tuple[bool, str]:
    """pickle, joblib and a refit clone predict the same."""
    import joblib
    from sklearn.base import clone

    from sk_offwhite import GreyBoxSparseRegressor

    est = GreyBoxSparseRegressor(tank.physics, max_iter=30).fit(tank.u, tank.z)
    expected = np.asarray(est.predict(tank.u))
    joblib.dump(est, tmp / "est.joblib")
    copies = {
        "pickle": pickle.loads(pickle.dumps(est)),
        "joblib": joblib.load(tmp / "est.joblib"),
        "clone": clone(est).fit(tank.u, tank.z),
    }
    equal = {k: np.array_equal(expected, c.predict(tank.u)) for k, c in copies.items()}
    return all(equal.values()), ", ".join(
        f"{k} {'equal' if v else 'differs'}" for k, v in equal.items()
    )


def untouched_inputs_and_config(tank) -> tuple[bool, str]:
    """A fit leaves u, z and JAX's global settings as they were."""
    import jax

    from sk_offwhite import GreyBoxSparseRegressor

    u, z = tank.u.copy(), tank.z.copy()
    flags = {name: getattr(jax.config, name) for name in ("jax_enable_x64", "jax_platforms")}
    GreyBoxSparseRegressor(tank.physics, max_iter=10).fit(tank.u, tank.z)
    after = {name: getattr(jax.config, name) for name in flags}
    same = np.array_equal(u, tank.u) and np.array_equal(z, tank.z) and flags == after
    return same, f"arrays {'unchanged' if same else 'changed'}; JAX settings {after}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    from sk_offwhite.datasets import make_leaky_tank

    tank = make_leaky_tank(n_samples=300, random_state=0)
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        checks = {
            "corrupted cache": lambda: damaged_cache(tmp, "corrupted"),
            "truncated cache": lambda: damaged_cache(tmp, "truncated"),
            "two processes on one fresh cache": lambda: shared_fresh_cache(tmp),
            "SIGINT mid-fit": lambda: interrupted_fit(tank),
            "pickle, joblib, clone": lambda: round_trips(tank, tmp),
            "bitwise determinism across processes": lambda: deterministic_processes(tmp),
            "inputs and JAX settings untouched": lambda: untouched_inputs_and_config(tank),
        }
        rows = []
        for name, check in checks.items():
            held, detail = check()
            print(f"{'held' if held else 'BROKEN':7s} {name}: {detail}")
            rows.append([name, "held" if held else "broken", detail])
    table = {"title": "Faults", "columns": ["fault", "outcome", "detail"], "rows": rows}
    write_results("audit_faults", [table], path=args.json, argv=argv)
    return 0 if all(row[1] == "held" for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
