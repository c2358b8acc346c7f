"""Section 5.1 of Donati et al.: Monte Carlo study of the Theorem 1 bound (Figs. 1 and 3).

Vehicle lateral dynamics (``make_vehicle_lateral``): theta_bar = [2, -1.087, -1.070, 3.715],
the unmodelled Delta = -9.625 x1 x6 + 10.69 x2 x6 - 11.52 x2 x6^2 in the yaw equation, the
12-function dictionary, T = --n-samples samples, bounded uniform output noise. Every run
draws new inputs and noise (seed = run index).

* Fig. 1: parametric error ||theta* - theta_bar||_2 against ||Delta~||_inf, with the
  correction delta and without (physics only), and the Theorem 1 bound of every fit.
* Fig. 3: parametric error (with delta) against the noise bound ||eta||_inf.

Run ``python examples/vehicle_montecarlo.py --runs 12 --out reports/vehicle_montecarlo``;
it writes ``fig1_error_vs_delta.png``, ``fig3_error_vs_noise.png`` and ``results.json``.

Choices (see docs/theory.md): the correction is fitted along the support path,
``fit_gamma_path`` with its default grid (8 values of the dimensionless gamma from gamma_max
of the record down to 1e-4 gamma_max, each fit warm-started from the previous one, no
cross-validation), and the estimator at the last gamma is used; ``gamma_max`` and ``gamma``
of every fit are in the JSON. The paper's gamma = 0.001 weighs the raw ||omega||_1 against
(1/T)||e||^2, while gamma here weighs each term by its effect on the output in output
standard deviations, so that value has no counterpart and is not fitted. The initial values
of the measured-input registers x3..x6 are measurements and are fixed; y0 and y_-1 are
fitted. H in the bound is taken over theta and the fitted initial states, with the weights
at their fitted values (Lemma 1); the identifiability of the weights too is reported
separately.
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
from sklearn.exceptions import ConvergenceWarning  # noqa: E402

from sk_offwhite import GreyBoxSparseRegressor, fit_gamma_path  # noqa: E402
from sk_offwhite.certify import (  # noqa: E402
    UnidentifiableWarning,
    identifiability,
    parameter_error_bound,
)
from sk_offwhite.datasets import (  # noqa: E402
    make_vehicle_lateral,
    vehicle_physics_known_registers,
)

PAPER = {"runs_fig1": 7500, "runs_per_noise_level_fig3": 5000, "n_samples": 2000}


def fit_with_delta(data, max_iter: int) -> GreyBoxSparseRegressor:
    """Physics + dictionary on the yaw equation, at the end of the default support path."""
    estimator = GreyBoxSparseRegressor(
        vehicle_physics_known_registers(data),
        data.suggested_library,
        delta_states=[0],
        max_iter=max_iter,
    )
    return fit_gamma_path(estimator, data.u, data.z).estimator


def fit_physics_only(data, max_iter: int) -> GreyBoxSparseRegressor:
    return GreyBoxSparseRegressor(
        vehicle_physics_known_registers(data), None, max_iter=max_iter
    ).fit(data.u, data.z)


def true_theta(data) -> np.ndarray:
    return np.array([data.true_parameters[n] for n in data.physics.parameter_names])


def model_error(data, estimator) -> np.ndarray:
    """Delta~_k = Delta(x_k, u_k) - delta(x^_k, u_k; omega) along the record (yaw equation)."""
    corrections = estimator.simulate(data.u, x0=estimator.x0_).correction[:, 0]
    return data.hidden_effect["function"](data.x, data.u) - corrections


def linearised_error(bound, data, delta_tilde) -> float:
    """||-(S_z eta_z + S_Delta Delta~)||_2: Lemma 1's first-order error for this realisation."""
    eta = data.noise["output_noise"].reshape(-1)
    return float(np.linalg.norm(bound.sensitivity_z @ eta + bound.sensitivity_delta @ delta_tilde))


def monte_carlo_point(data, estimator, noise_bound: float) -> dict:
    """Error, ||Delta~||_inf, the constants of Theorem 1 and the bound for one fit."""
    delta_tilde = model_error(data, estimator)
    delta_norm = float(np.max(np.abs(delta_tilde)))
    bound = parameter_error_bound(
        estimator,
        data.u,
        data.z,
        noise_z=noise_bound,
        delta_norm=delta_norm,
        disturbed_states=[0],
        include_omega=False,
    )
    return {
        "error": float(np.linalg.norm(estimator.theta_ - true_theta(data))),
        "delta_norm_inf": delta_norm,
        "m_z": bound.m_z,
        "m_delta": bound.m_delta,
        "bound": bound.bound,
        "h_regular": bound.identifiable,
        "linearised_error": linearised_error(bound, data, delta_tilde),
        "support": [
            n
            for n, s in zip(estimator.feature_names_, estimator.support_.ravel(), strict=True)
            if s
        ],
        "theta": estimator.theta_.tolist(),
    }


def path_end(estimator) -> dict:
    """gamma_max of the record and the gamma the estimator was left at (dimensionless)."""
    return {"gamma_max": estimator.gamma_max_, "gamma": estimator.gamma}


def weights_identifiable(data, estimator) -> bool:
    """Is H over theta, x0 and the support weights regular (x4 x6 duplicates theta4)?"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnidentifiableWarning)
        return identifiability(estimator, data.u, data.z).identifiable


def figure1_run(seed: int, args) -> dict:
    data = make_vehicle_lateral(args.n_samples, noise_bound=args.noise_bound, random_state=seed)
    with_delta = fit_with_delta(data, args.max_iter)
    point = {"seed": seed, "with": monte_carlo_point(data, with_delta, args.noise_bound)}
    point["with"]["h_regular_with_weights"] = weights_identifiable(data, with_delta)
    point["with"].update(path_end(with_delta))
    without = fit_physics_only(data, args.max_iter)
    point["without"] = monte_carlo_point(data, without, args.noise_bound)
    return point


def figure3_run(seed: int, noise_bound: float, args) -> dict:
    data = make_vehicle_lateral(args.n_samples, noise_bound=noise_bound, random_state=seed)
    with_delta = fit_with_delta(data, args.max_iter)
    point = monte_carlo_point(data, with_delta, noise_bound)
    return {"seed": seed, "noise_bound": noise_bound, **point, **path_end(with_delta)}


def _summary(values) -> dict:
    values = np.asarray(values, float)
    return {"mean": float(values.mean()), "std": float(values.std()), "max": float(values.max())}


def summarise_figure1(points) -> dict:
    summary = {}
    for case in ("with", "without"):
        rows = [p[case] for p in points]
        summary[case] = {
            "error": _summary([r["error"] for r in rows]),
            "delta_norm_inf": _summary([r["delta_norm_inf"] for r in rows]),
            "m_delta": _summary([r["m_delta"] for r in rows]),
            "bound": _summary([r["bound"] for r in rows]),
            "all_under_bound": all(r["error"] <= r["bound"] for r in rows),
            "share_h_regular": float(np.mean([r["h_regular"] for r in rows])),
            "linearised_over_actual": _summary([r["linearised_error"] / r["error"] for r in rows]),
        }
    summary["with"]["share_exact_support"] = float(
        np.mean([p["with"]["support"] == ["x1 x6", "x2 x6", "x2 x6^2"] for p in points])
    )
    summary["with"]["share_h_regular_with_weights"] = float(
        np.mean([p["with"]["h_regular_with_weights"] for p in points])
    )
    return summary


def summarise_figure3(points, levels) -> dict:
    by_level = {}
    for level in levels:
        rows = [p for p in points if p["noise_bound"] == level]
        errors = [r["error"] for r in rows]
        by_level[str(level)] = {
            "error_median": float(np.median(errors)),
            "error_iqr": [float(q) for q in np.percentile(errors, [25, 75])],
            "bound_median": float(np.median([r["bound"] for r in rows])),
            "all_under_bound": all(r["error"] <= r["bound"] for r in rows),
        }
    return by_level


def plot_figure1(points, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6, 4.2))
    styles = {"with": ("tab:cyan", "with $\\delta$"), "without": ("tab:red", "without $\\delta$")}
    for case, (color, label) in styles.items():
        x = [p[case]["delta_norm_inf"] for p in points]
        ax.scatter(x, [p[case]["error"] for p in points], c=color, s=18, label=label)
        ax.scatter(x, [p[case]["bound"] for p in points], c=color, marker="_", s=60)
    ax.set(xscale="log", yscale="log", xlabel=r"$\|\tilde\Delta\|_\infty$")
    ax.set(ylabel=r"$\|\theta^* - \bar\theta\|_2$ (dots), Theorem 1 bound (dashes)")
    ax.set_title("Parametric error vs model error (Fig. 1)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_figure3(points, levels, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6, 4.2))
    errors = [[p["error"] for p in points if p["noise_bound"] == lv] for lv in levels]
    bounds = [np.median([p["bound"] for p in points if p["noise_bound"] == lv]) for lv in levels]
    positions = np.arange(1, len(levels) + 1)
    ax.boxplot(errors, positions=positions, whis=1.5)
    ax.plot(positions, bounds, "k--", marker="o", label="Theorem 1 bound (median)")
    ax.set_xticks(positions, [f"{lv:g}" for lv in levels])
    ax.set(yscale="log", xlabel=r"noise bound $\|\eta\|_\infty$")
    ax.set(ylabel=r"$\|\theta^* - \bar\theta\|_2$", title="Parametric error vs noise (Fig. 3)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=12, help="Fig. 1 runs (each with/without)")
    parser.add_argument("--noise-runs", type=int, default=6, help="Fig. 3 runs per noise level")
    parser.add_argument("--n-samples", type=int, default=2000, help="T, samples per record")
    parser.add_argument("--noise-bound", type=float, default=5e-4, help="Fig. 1 noise bound")
    parser.add_argument("--noise-levels", type=float, nargs="+", default=[2.5e-4, 5e-4, 1e-3, 2e-3])
    parser.add_argument("--max-iter", type=int, default=1000)
    parser.add_argument("--out", type=Path, default=Path("reports/vehicle_montecarlo"))
    return parser.parse_args(argv)


def run_study(args) -> dict:
    start = time.perf_counter()
    figure1 = [figure1_run(seed, args) for seed in range(args.runs)]
    print(f"Fig. 1: {args.runs} runs in {time.perf_counter() - start:.0f} s", flush=True)
    figure3 = [
        figure3_run(1000 + seed, level, args)
        for level in args.noise_levels
        for seed in range(args.noise_runs)
    ]
    return {
        "settings": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
        "paper_scale": PAPER,
        "gamma": "fit_gamma_path default grid (gamma_max to 1e-4 gamma_max), last gamma",
        "figure1": {"summary": summarise_figure1(figure1), "points": figure1},
        "figure3": {"summary": summarise_figure3(figure3, args.noise_levels), "points": figure3},
        "seconds": time.perf_counter() - start,
    }


def main(argv=None) -> dict:
    args = parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        results = run_study(args)
    plot_figure1(results["figure1"]["points"], args.out / "fig1_error_vs_delta.png")
    plot_figure3(
        results["figure3"]["points"], args.noise_levels, args.out / "fig3_error_vs_noise.png"
    )
    (args.out / "results.json").write_text(json.dumps(results, indent=1))
    print(json.dumps({"figure1": results["figure1"]["summary"]}, indent=1))
    print(json.dumps({"figure3": results["figure3"]["summary"]}, indent=1))
    print(f"total {results['seconds']:.0f} s; written to {args.out}")
    return results


if __name__ == "__main__":
    main()
