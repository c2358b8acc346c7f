"""Core performance figures of sk_offwhite on the Cascaded Tanks model.

Run with ``python benchmarks/bench_core.py [--repeats N]``. Prints:

* compile time of the jitted value-and-gradient of the multi-step cost;
* microseconds per simulated time step of one value-and-gradient (after compilation);
* total fit time of ``GreyBoxSparseRegressor`` on a 1024-sample record, single shooting
  and ``horizon=1024``, with and without a 20-feature dictionary.

The data are a noise-free simulation of the paper's eq. (21) (no overflow) with a
multisine input, so every fit solves the same problem on every machine.
"""

from __future__ import annotations

import argparse
import platform
import time

import jax
import pysindy as ps
from bench_scaling import value_and_grad_problem  # same folder: run as a script

from sk_offwhite import GreyBoxSparseRegressor, RidgeBasis
from sk_offwhite.datasets import cascaded_tanks_physics, make_cascaded_tanks

N_SAMPLES = 1024


def twenty_feature_library():
    """Polynomial degree 3 on (x1, x2, u) plus one sine: 20 features (with the bias)."""
    return ps.PolynomialLibrary(degree=3) + ps.FourierLibrary(n_frequencies=1, include_cos=False)


def tanks_problem(library, horizon):
    """The cost of the tanks fit as a jitted value-and-gradient of the free variables
    (built by `bench_scaling.value_and_grad_problem`); call under ``enable_x64``."""
    data = make_cascaded_tanks(
        n_samples=N_SAMPLES, overflow=False, saturation=False, noise_std=0.0, random_state=0
    )
    physics = cascaded_tanks_physics(fixed={"k4": data.true_parameters["k4"]})
    value_and_grad, free0 = value_and_grad_problem(data.u, data.z, physics, library, horizon)
    return value_and_grad, free0, data


def time_value_and_grad(library, horizon, repeats):
    """Compile time (s) and microseconds per time step of one value-and-gradient."""
    with jax.enable_x64(True):
        value_and_grad, free0, _ = tanks_problem(library, horizon)
        start = time.perf_counter()
        jax.block_until_ready(value_and_grad(free0))
        compile_s = time.perf_counter() - start
        start = time.perf_counter()
        for _ in range(repeats):
            jax.block_until_ready(value_and_grad(free0 + 1e-9))
        per_call = (time.perf_counter() - start) / repeats
    return compile_s, 1e6 * per_call / N_SAMPLES, free0.shape[0]


def time_fit(library, horizon):
    """Wall time of a first fit (includes compilation) and of a second, identical fit."""
    data = make_cascaded_tanks(
        n_samples=N_SAMPLES, overflow=False, saturation=False, noise_std=0.0, random_state=0
    )
    physics = cascaded_tanks_physics(fixed={"k4": data.true_parameters["k4"]})
    times = []
    for _ in range(2):
        est = GreyBoxSparseRegressor(physics, library=library, horizon=horizon, max_iter=200)
        start = time.perf_counter()
        est.fit(data.u, data.z)
        times.append(time.perf_counter() - start)
    return times, est


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args(argv)
    print(
        f"machine: {platform.machine()}, {jax.device_count()} {jax.devices()[0].platform} "
        f"device(s), jax {jax.__version__}, python {platform.python_version()}"
    )
    print(f"record: {N_SAMPLES} samples, Cascaded Tanks eq. (21), float64\n")
    cases = [
        ("physics only", None),
        ("20-feature dictionary", twenty_feature_library()),
        ("ridge basis, 8 units", RidgeBasis(["tanh", "sigmoid"] * 4)),
    ]
    print(
        "| model | horizon | free vars | compile (s) | value+grad (us/step) "
        "| fit, first (s) | fit, warm cache (s) | iterations | solver stop |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    rows = []
    for label, library in cases:
        for horizon in (None, N_SAMPLES):
            compile_s, us_step, n_free = time_value_and_grad(library, horizon, args.repeats)
            (first, second), est = time_fit(library, horizon)
            print(
                f"| {label} | {horizon} | {n_free} | {compile_s:.2f} | {us_step:.3f} "
                f"| {first:.2f} | {second:.2f} | {est.n_iter_} | {est.solver_message_} |"
            )
            rows.append(
                [label, horizon, n_free, compile_s, us_step, first, second, est.n_iter_]
                + [est.solver_message_]
            )
    from _results import table, write_results  # same folder: run as a script

    columns = ["model", "horizon", "free vars", "compile (s)", "value+grad (us/step)"]
    columns += ["fit, first (s)", "fit, again (s)", "iterations", "solver stop"]
    title = f"{N_SAMPLES} samples, Cascaded Tanks eq. (21), float64"
    write_results("bench_core", [table(title, columns, rows)], path=args.json, argv=argv)


if __name__ == "__main__":
    main()
