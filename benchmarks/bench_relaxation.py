r"""Exact supports of the sparse relaxation (10) on an easy, incoherent problem.

Run with ``python benchmarks/bench_relaxation.py [--draws N]``. Each draw is
$y = \Phi_\theta\theta + \Phi\omega + \eta$ with 400 rows, 2 physical regressors,
40 i.i.d. Gaussian dictionary columns, a 3-sparse $\omega$ with coefficients of order
one (random sign, magnitude in [0.5, 2]) and noise uniform in $\pm b$,
$b = 10^{-3}$. Three noise bounds:

* $\mu = \|\eta\|_2$, the exact noise norm (the tightest valid bound: the
  $\ell_1$ solution then carries small spurious terms, up to about 2e-5 of the largest);
* $\mu = 1.05\|\eta\|_2$;
* $\mu = b\sqrt{T}$, Assumption 2 from the per-sample bound (about
  $1.7\|\eta\|_2$ for uniform noise).

Prints, for ``prune=False`` (the thresholded $\ell_1$ solution) and ``prune=True``
(pruned support, least-squares refit), how many draws return exactly the true support,
the mean support size, the largest ``residual_norm / mu`` and the mean time per call
(after one warm-up call).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sk_offwhite.certify import sparse_relaxation

N_ROWS, N_THETA, N_FEATURES, N_ACTIVE, NOISE_BOUND = 400, 2, 40, 3, 1e-3


def draw(seed: int):
    """One problem: ``(xi, phi, y, true support, noise)``."""
    rng = np.random.default_rng(seed)
    xi = rng.normal(size=(N_ROWS, N_THETA))
    phi = rng.normal(size=(N_ROWS, N_FEATURES))
    support = np.sort(rng.choice(N_FEATURES, N_ACTIVE, replace=False))
    omega = np.zeros(N_FEATURES)
    omega[support] = rng.choice([-1.0, 1.0], N_ACTIVE) * rng.uniform(0.5, 2.0, N_ACTIVE)
    noise = rng.uniform(-NOISE_BOUND, NOISE_BOUND, N_ROWS)
    return xi, phi, xi @ rng.normal(size=N_THETA) + phi @ omega + noise, support, noise


def measure(draws: int, mu_of, prune: bool) -> dict:
    """Exact-support count, mean |supp|, worst residual/mu and mean seconds per solve."""
    exact, sizes, ratios, seconds = 0, [], [], []
    for seed in range(draws):
        xi, phi, y, support, noise = draw(seed)
        mu = mu_of(noise)
        start = time.perf_counter()
        result = sparse_relaxation(xi, phi, y, mu, prune=prune)
        seconds.append(time.perf_counter() - start)
        found = np.flatnonzero(result.support)
        exact += int(np.array_equal(found, support))
        sizes.append(found.size)
        ratios.append(result.residual_norm / mu)
    return dict(exact=exact, size=np.mean(sizes), ratio=max(ratios), seconds=np.mean(seconds))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=10)
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args()
    draws = args.draws
    xi, phi, y, _, noise = draw(0)
    sparse_relaxation(xi, phi, y, 1.05 * np.linalg.norm(noise))  # warm-up: imports, caches
    bounds = {
        "mu = ||eta||": np.linalg.norm,
        "mu = 1.05 ||eta||": lambda noise: 1.05 * np.linalg.norm(noise),
        "mu = b sqrt(T)": lambda noise: NOISE_BOUND * np.sqrt(N_ROWS),
    }
    print(
        f"T = {N_ROWS}, n_theta = {N_THETA}, m = {N_FEATURES}, {N_ACTIVE}-sparse, "
        f"noise uniform +-{NOISE_BOUND:g}, {draws} draws"
    )
    rows = []
    for label, mu_of in bounds.items():
        for prune in (False, True):
            r = measure(draws, mu_of, prune)
            print(
                f"{label:18s} prune={prune!s:5s}: exact support {r['exact']}/{draws}, "
                f"mean |supp| {r['size']:.1f}, max residual/mu {r['ratio']:.9f}, "
                f"{1e3 * r['seconds']:.0f} ms per solve"
            )
            rows.append(
                [label, prune, f"{r['exact']}/{draws}", r["size"], r["ratio"], 1e3 * r["seconds"]]
            )
    from _results import table, write_results  # same folder: run as a script

    columns = [
        "noise bound",
        "prune",
        "exact support",
        "mean support size",
        "max residual / mu",
        "ms per solve",
    ]
    title = (
        f"T = {N_ROWS}, {N_THETA} physical regressors, {N_FEATURES} columns, "
        f"{N_ACTIVE}-sparse, noise uniform in +-{NOISE_BOUND:g}, {draws} draws"
    )
    write_results("bench_relaxation", [table(title, columns, rows)], path=args.json)


if __name__ == "__main__":
    main()
