"""Section 5.1, Fig. 2 of Donati et al.: worst-case parameter errors over FPS and SFPS.

Monte Carlo over input and noise realisations of the vehicle lateral dynamics
(``make_vehicle_lateral``: theta_bar = [2, -1.087, -1.070, 3.715], the three-term Delta, the
12-function dictionary). Each run fits the grey-box model with the sparse correction,
linearises the simulated output around the fit (J_theta with the initial state, J_omega)
and computes, on that linearisation,

* the relaxation (15) on that linearisation (min ||omega||_1 within the noise bound mu),
  whose solution omega_hat gives the support (the fit's own support, after pruning, is
  also recorded as ``fit_support``);
* the local maximal-sparsity certificate of Theorem 5 for omega_hat;
* the worst-case error (19) over FPS and (20) over SFPS (support of omega_hat), from the
  per-parameter extremes of the four physical parameters (box 2-norm and inf-norm).

The dictionary term ``x4 x6`` equals the physical regressor of theta4, so the FPS over the
full dictionary is unbounded in theta4 (reported); "FPS" numbers use the dictionary without
that column, the smallest finite FPS.

gamma: the correction is fitted along the support path (``fit_gamma_path`` with its
default grid: 8 values of the dimensionless gamma from gamma_max of the record down to
1e-4 gamma_max, each fit warm-started from the previous one, no cross-validation), and the
estimator at the last gamma is linearised. The paper's gamma = 0.001 (raw ||omega||_1
against (1/T)||e||^2) has no counterpart in this dimensionless gamma and is not used. The
noise bound mu on ||eta||_2 over the record is noise_bound * sqrt(T) (uniform output noise
in [-noise_bound, noise_bound]).

``--normalize-columns`` solves (15) and the certificate on unit-norm columns of J_omega
(min sum_j ||J_omega,j|| |omega_j|), so that no term is cheap only because its regressor is
large.

Usage::

    python examples/vehicle_certificates.py --runs 20 --n-samples 2000 [--normalize-columns]
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sk_offwhite import GreyBoxSparseRegressor, fit_gamma_path  # noqa: E402
from sk_offwhite.certify import (  # noqa: E402
    certify_estimator,
    estimator_feasible_set,
    linearise_estimator,
    multistep_relaxation,
)
from sk_offwhite.datasets import make_vehicle_lateral  # noqa: E402

PAPER = {"sfps": (1.19, 0.19), "fps": (1.79, 0.28)}


def fit(data) -> GreyBoxSparseRegressor:
    """Physics + dictionary on equation 0, at the end of the default support path."""
    est = GreyBoxSparseRegressor(
        data.physics, data.suggested_library, delta_states=[0], max_iter=1000
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_gamma_path(est, data.u, data.z).estimator


def identifiable_fps(est, lin, mu: float):
    """FPS without the dictionary columns confounded with the physics (``x4 x6``)."""
    keep = np.array([name != "x4 x6" for name in lin.feature_names])
    return estimator_feasible_set(est, None, None, mu, support=keep, linearisation=lin)


def one_run(seed: int, n_samples: int, noise_bound: float, normalize: bool = False) -> dict:
    """Fit, certify and bound one realisation (``normalize``: unit-norm columns of J_omega)."""
    start = time.perf_counter()
    data = make_vehicle_lateral(n_samples=n_samples, noise_bound=noise_bound, random_state=seed)
    est = fit(data)
    lin = linearise_estimator(est, data.u, data.z)
    mu = noise_bound * np.sqrt(n_samples) or 2.0 * float(np.linalg.norm(lin.residual))
    options = dict(linearisation=lin, normalize_columns=normalize)
    relaxation = multistep_relaxation(est, None, None, mu, **options)
    omega_hat = relaxation.omega if relaxation.solved else lin.omega_hat
    cert = certify_estimator(est, None, None, mu, omega_hat=omega_hat, **options)
    full = estimator_feasible_set(est, None, None, mu, linearisation=lin)
    fps = identifiable_fps(est, lin, mu)
    support = omega_hat != 0
    sfps = estimator_feasible_set(est, None, None, mu, support=support, linearisation=lin)
    theta_bar = np.array([data.true_parameters[n] for n in est.physics_.parameter_names])
    return {
        "seed": seed,
        "mu": mu,
        "residual_norm": float(np.linalg.norm(lin.residual)),
        "theta_hat": est.theta_.tolist(),
        "theta_error": float(np.linalg.norm(est.theta_ - theta_bar)),
        "gamma_max": est.gamma_max_,
        "gamma": est.gamma,
        "fit_support": _names(lin, lin.omega_hat != 0),
        "relaxation_status": relaxation.status,
        "support": _names(lin, support),
        "support_exact": bool(np.array_equal(support, data.true_omega != 0)),
        "certified": cert.certified,
        "certificate": cert.reason,
        "margin": cert.margin,
        "fps_full_status": full.status,
        "fps": _bounds(fps),
        "sfps": _bounds(sfps),
        "truth_in_sfps": bool(sfps.solved and sfps.contains(theta_bar)),
        "seconds": time.perf_counter() - start,
    }


def _names(lin, mask) -> list[str]:
    return [n for n, keep in zip(lin.feature_names, mask, strict=True) if keep]


def _bounds(result) -> dict:
    if not result.solved:
        return {"status": result.status}
    return {
        "status": result.status,
        "worst_case": result.worst_case.tolist(),
        "norm2": result.worst_case_norm,
        "norm_inf": result.worst_case_inf,
    }


def _stats(values) -> list[float]:
    values = np.asarray([v for v in values if v is not None], float)
    return [float(np.mean(values)), float(np.std(values))] if values.size else [np.nan, np.nan]


def summarise(runs: list[dict], args) -> dict:
    """Means and standard deviations over the runs, next to the paper's numbers."""

    def column(kind, key):
        return [r[kind].get(key) for r in runs]

    return {
        "runs": len(runs),
        "n_samples": args.n_samples,
        "noise_bound": args.noise_bound,
        "normalize_columns": args.normalize_columns,
        "share_certified": float(np.mean([r["certified"] is True for r in runs])),
        "share_support_exact": float(np.mean([r["support_exact"] for r in runs])),
        "share_truth_in_sfps": float(np.mean([r["truth_in_sfps"] for r in runs])),
        "fps_norm2": _stats(column("fps", "norm2")),
        "sfps_norm2": _stats(column("sfps", "norm2")),
        "fps_norm_inf": _stats(column("fps", "norm_inf")),
        "sfps_norm_inf": _stats(column("sfps", "norm_inf")),
        "theta_error": _stats([r["theta_error"] for r in runs]),
        "seconds_per_run": _stats([r["seconds"] for r in runs]),
        "paper": PAPER,
    }


def plot(runs: list[dict], path: Path) -> None:
    """Box plot of the worst-case errors and the per-run pairs, certified runs marked."""
    fps = np.array([r["fps"].get("norm2", np.nan) for r in runs])
    sfps = np.array([r["sfps"].get("norm2", np.nan) for r in runs])
    ok = np.array([r["certified"] is True for r in runs])
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    left.boxplot([sfps[np.isfinite(sfps)], fps[np.isfinite(fps)]])
    left.set_xticks([1, 2], ["SFPS (20)", "FPS (19)"])
    left.set_ylabel("worst-case parameter error ||e||_2")
    right.scatter(fps[ok], sfps[ok], label="certified (Thm 5)", marker="o")
    right.scatter(fps[~ok], sfps[~ok], label="not certified", marker="x")
    top = np.nanmax(np.concatenate([fps, sfps, [0.0]]))
    right.plot([0, top], [0, top], "k:", lw=1)
    right.set_xlabel("FPS worst-case error")
    right.set_ylabel("SFPS worst-case error")
    right.legend()
    fig.suptitle("Vehicle lateral dynamics: FPS vs SFPS (local linearisation of each fit)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--n-samples", type=int, default=2000)
    parser.add_argument("--noise-bound", type=float, default=0.002)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--normalize-columns",
        action="store_true",
        help="relaxation (15) and certificate on unit-norm columns of J_omega",
    )
    parser.add_argument("--out", type=Path, default=Path("reports/vehicle_certificates"))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    runs = []
    for k in range(args.runs):
        runs.append(
            one_run(args.seed + k, args.n_samples, args.noise_bound, args.normalize_columns)
        )
        r = runs[-1]
        print(
            f"run {k}: certified={r['certified']} support={r['support']} "
            f"FPS={r['fps'].get('norm2')} SFPS={r['sfps'].get('norm2')} ({r['seconds']:.1f} s)",
            flush=True,
        )
    summary = summarise(runs, args)
    (args.out / "vehicle_certificates.json").write_text(
        json.dumps({"summary": summary, "runs": runs}, indent=2, default=float)
    )
    plot(runs, args.out / "vehicle_certificates.png")
    print(json.dumps(summary, indent=2))
    return summary


if __name__ == "__main__":
    main()
