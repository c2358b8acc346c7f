"""Long records and hard starts with default settings: time, accuracy and peak memory.

Run with ``python benchmarks/bench_long_records.py [--sizes 6000 7000 20000] [--loop]``. Each case
runs in a fresh process (so that its peak resident set size is its own) and prints one
line:

* **long multiple shooting** — the synthetic Cascaded Tanks without the hidden limits
  (``make_cascaded_tanks(overflow=False, saturation=False, random_state=0)``, exact
  physics, 2 % output noise), ``horizon=32`` and every other setting at its default:
  fit time (compilation included), training R², ``converged_`` and peak RSS. With more than
  100 free variables Levenberg-Marquardt uses the window-coloured Jacobian
  (``sk_offwhite.solvers._coloured``); before it, ``solver='auto'`` switched to Adam above 400
  free variables.
* **the loop at scale** (``--loop``) — ``close_the_loop`` on the Coulomb drive
  (``make_coulomb_drive``, SI units, 1 kHz) at 25 000 and 100 000 samples, without the
  sparse-δ fits (``fit_delta=False``, 3 folds, ``max_iter=100``): time, effects added,
  validation RMSE (``init_window``) of the declared and augmented physics, peak RSS.
* **exploding start** — x⁺ = −0.2x + u (white input, 1 % output noise) fitted from the
  unstable guess a = 2, single shooting and ``horizon=20``: the restart from short windows
  (``sk_offwhite.fitting._start``) and the fitted a.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

LONG = """
import resource, time, warnings
from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite.datasets import make_cascaded_tanks
warnings.simplefilter("ignore")
d = make_cascaded_tanks(n_samples={n}, overflow=False, saturation=False, random_state=0)
est = GreyBoxSparseRegressor(d.physics, horizon=32)
start = time.perf_counter()
est.fit(d.u, d.z)
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(f"long multiple shooting  N={n:6d}  fit {{seconds:6.1f}} s  "
      f"R2 {{est.score(d.u, d.z):.5f}}  converged {{est.converged_}}  peak RSS {{peak:5.0f}} MiB")
import json
print("JSON", json.dumps({{"case": "long multiple shooting", "n_samples": {n}, "seconds": seconds,
      "r2": est.score(d.u, d.z), "converged": bool(est.converged_), "peak_rss_mib": peak}}))
"""

LOOP = """
import resource, time, warnings
from sk_offwhite.datasets import make_coulomb_drive
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
warnings.simplefilter("ignore")
data = make_coulomb_drive(n_samples={n}, random_state=0)
settings = LoopSettings(n_folds=3, max_iter=100, fit_delta=False, max_candidates=6)
start = time.perf_counter()
result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
seconds = time.perf_counter() - start
rows = score_models(result, {{"validation": (data.u_val, data.z_val)}})
rmse = {{r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}}
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(f"loop on the Coulomb drive  N={n:6d}  {{seconds:5.0f}} s  effects "
      f"{{[e.name for e in result.effects]}}  validation RMSE declared "
      f"{{rmse['declared physics']:.3g}} -> augmented {{rmse['augmented physics']:.3g}}  "
      f"failures {{len(result.failures)}}  peak RSS {{peak:5.0f}} MiB")
import json
print("JSON", json.dumps({{"case": "loop on the Coulomb drive", "n_samples": {n},
      "seconds": seconds, "effects": [e.name for e in result.effects],
      "rmse_declared": rmse["declared physics"], "rmse_augmented": rmse["augmented physics"],
      "failures": len(result.failures), "peak_rss_mib": peak}}))
"""

EXPLODING = """
import time, warnings
import numpy as np, jax.numpy as jnp
from sk_offwhite import GreyBoxSparseRegressor, Parameter, PhysicsModel
warnings.simplefilter("ignore")
rng = np.random.default_rng(0)
u = rng.normal(size=({n}, 1))
x, z = 0.0, []
for u_k in u[:, 0]:
    z.append(x)
    x = -0.2 * x + u_k
z = np.asarray(z)[:, None] + 0.01 * rng.normal(size=({n}, 1))
step = lambda x, u, theta: jnp.array([theta["a"] * x[0] + u[0]])
physics = PhysicsModel(step, [0], {{"a": Parameter(2.0)}}, 1, 1, x0=[0.0])
est = GreyBoxSparseRegressor(physics, horizon={horizon})
start = time.perf_counter()
with np.errstate(over="ignore"):
    est.fit(u, z)
seconds = time.perf_counter() - start
print(f"exploding start  N={n:6d}  horizon={horizon!s:4}  fit {{seconds:5.1f}} s"
      f"  a = {{est.theta_[0]:+.4f}}  converged {{est.converged_}}  ({{est.solver_message_}})")
import json
print("JSON", json.dumps({{"case": "exploding start", "n_samples": {n}, "horizon": {horizon},
      "seconds": seconds, "a": float(est.theta_[0]), "converged": bool(est.converged_),
      "message": str(est.solver_message_)}}))
"""


def run(code: str, found: list | None = None) -> str:
    """Run ``code`` in a fresh process; its printed line (its results appended to ``found``)."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if done.returncode:
        return done.stderr.strip().splitlines()[-1]
    lines = done.stdout.strip().splitlines()
    if found is not None:
        found += [json.loads(line[5:]) for line in lines if line.startswith("JSON ")]
    return "\n".join(line for line in lines if not line.startswith("JSON "))


def tables(found: list) -> list:
    """The results as the documentation's tables, one per case."""
    from _results import table  # same folder: run as a script

    long = [r for r in found if r["case"] == "long multiple shooting"]
    loop = [r for r in found if r["case"] == "loop on the Coulomb drive"]
    exploding = [r for r in found if r["case"] == "exploding start"]
    keys = ("n_samples", "seconds", "r2", "converged", "peak_rss_mib")
    out = [
        table(
            "Long multiple shooting (synthetic tanks, horizon=32, defaults otherwise)",
            ["samples", "fit (s)", "R²", "converged", "peak RSS (MiB)"],
            [[r[k] for k in keys] for r in long],
        )
    ]
    if loop:
        keys = ("n_samples", "seconds", "effects", "rmse_declared", "rmse_augmented")
        out.append(
            table(
                "The loop on the Coulomb drive (fit_delta=False, max_iter=100)",
                ["samples", "loop (s)", "effects", "RMSE declared", "RMSE augmented"],
                [[", ".join(r[k]) if k == "effects" else r[k] for k in keys] for r in loop],
            )
        )
    keys = ("n_samples", "horizon", "seconds", "a", "converged", "message")
    out.append(
        table(
            "Exploding start (true a = -0.2, start a = 2)",
            ["samples", "horizon", "fit (s)", "fitted a", "converged", "solver stop"],
            [[r[k] for k in keys] for r in exploding],
        )
    )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[6000, 7000, 20000])
    parser.add_argument("--loop", action="store_true", help="also the loop at 25k and 100k")
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args()
    found = []
    for n in args.sizes:
        print(run(LONG.format(n=n), found), flush=True)
    for n in (25000, 100000) if args.loop else ():
        print(run(LOOP.format(n=n), found), flush=True)
    for n in (400, 20000):
        for horizon in (None, 20):
            print(run(EXPLODING.format(n=n, horizon=horizon), found), flush=True)
    from _results import write_results  # same folder: run as a script

    write_results("bench_long_records", tables(found), path=args.json, data=found)


if __name__ == "__main__":
    main()
