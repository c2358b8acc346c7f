"""Section 5.1 certificates swept over the noise bound and the rule for mu.

For each noise bound b (uniform output noise in [-b, b]) and seed, the vehicle lateral
dynamics (``make_vehicle_lateral``, 2000 samples, the 12-function dictionary, the
measured-input registers x3..x6 of the initial state known) are fitted along the default
support path (``fit_gamma_path``); the simulated output is linearised around the fit and
Theorem 5 is applied to the fit's own omega_hat (terms contributing less than 1 % of the
largest ||J_omega,j omega_j|| zeroed), under two noise bounds:

* ``b sqrt(T)``: the worst-case norm of the noise (Assumption 2 with |eta_k| <= b);
* ``refined``: 1.01 times the residual omega_hat leaves on the linearisation.

The certificate's sigma^2_n and ||e||_(Q,n) use n = min(||omega^v||_0 + M, m') (the
rigorous level, ``level='vertex'``); the verdict at the paper's literal n = 2M is reported
next to it for ``b sqrt(T)``.

Each run prints the verdict and the certificate's diagnosis (``certificate.explain()``):
whether a sparser support fits within mu, or the test is conservative. The tables at the
end give

1. the fraction certified per noise bound and rule;
2. Fig. 2 the paper's way: FPS and SFPS approximated by the convex hulls of the Monte Carlo
   estimates theta_hat (FPS: all runs; SFPS: the runs certified under each rule, or, for
   comparison and not a certificate, the runs whose fitted support is supp(omega_bar)),
   and for each estimate theta_i in a hull its worst-case error over that hull,
   max_j ||theta_j - theta_i||_2, as mean +- 1 sigma over the estimates in the hull
   (``sk_offwhite.certify.hull_errors``), in theta and in its first two principal
   components (axes of all the estimates at that noise bound);
3. Fig. 2 with the paper's populations: the paper's 7500 simulations are 5000 fits with
   delta and 2500 without, and its Fig. 2 shows both (the fits without delta "clearly
   biased"). Each run here also fits the physics alone on the same record; FPS is the hull
   of all the estimates, with and without delta, SFPS that of the certified fits with
   delta, both in the principal components of all of them (``--no-physics-only`` skips
   these fits);
4. Fig. 2 the exact way: the worst-case errors (19)/(20) of each record's linearisation at
   mu = b sqrt(T), FPS over the dictionary without ``x4 x6`` (the full dictionary leaves
   theta4 unbounded) and SFPS on supp(omega_bar) = {x1 x6, x2 x6, x2 x6^2} (box 2-norm),
   mean +- 1 sigma over all runs and over the runs certified under b sqrt(T).

``--process-noise-bound`` adds uniform noise eta^v to the yaw recursion
(``make_vehicle_lateral(process_noise_bound=...)``); mu = b sqrt(T) still bounds the
output noise only. ``--speed-range`` changes the range of the speed (default 12-28 m/s,
so p = 1/v in [0.036, 0.083]): a wider range makes the dictionary columns less collinear.
``--figures DIR`` writes the Fig. 2 scatter with its hulls (with delta only, and with the
paper's populations) and the certified fraction against the noise bound.

Usage::

    python benchmarks/certificates_sweep.py --seeds 10 --noise-bounds 2e-5 5e-5 2e-4 2e-3 \
        --figures reports/certificates_figures
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
    hull_errors,
    linearise_estimator,
    principal_components,
)
from sk_offwhite.datasets import (  # noqa: E402
    make_vehicle_lateral,
    vehicle_physics_known_registers,
)

RULES = ("b sqrt(T)", "refined")
PAPER = {"SFPS": "1.19 +- 0.19", "FPS": "1.79 +- 0.28"}
DELTA_TERMS = ("x1 x6", "x2 x6", "x2 x6^2")


def fit_and_linearise(noise_bound: float, seed: int, n_samples: int, **generator):
    """The data, and the linearisation of the fit at the end of the support path.

    ``generator``: further arguments of ``make_vehicle_lateral`` (``process_noise_bound``,
    ``speed_range``).
    """
    data = make_vehicle_lateral(
        n_samples=n_samples, noise_bound=noise_bound, random_state=seed, **generator
    )
    physics = vehicle_physics_known_registers(data)
    est = GreyBoxSparseRegressor(physics, data.suggested_library, delta_states=[0], max_iter=1000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = fit_gamma_path(est, data.u, data.z).estimator
    return data, linearise_estimator(est, data.u, data.z)


def physics_only_theta(data) -> list[float]:
    """The physical parameters of the physics fitted alone (no dictionary) on ``data``: the
    paper's estimates "without delta"."""
    est = GreyBoxSparseRegressor(vehicle_physics_known_registers(data), max_iter=1000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return est.fit(data.u, data.z).theta_.tolist()


def certify_run(lin, mu, level: str = "vertex", vertex: str = "search") -> dict:
    """Theorem 5 on the fit's omega_hat, with the diagnosis as data and as a sentence."""
    cert = certify_estimator(None, None, None, mu, linearisation=lin, level=level, vertex=vertex)
    d = cert.diagnosis
    support = [n for n, w in zip(lin.feature_names, cert.omega_hat, strict=True) if w != 0]
    return {
        "mu": cert.mu,
        "certified": cert.certified,
        "cause": d.cause,
        "support": support,
        "tau_over_eta": cert.threshold / cert.eta,
        "residual": d.residual,
        "unexplained": d.unexplained,
        "sparser_support": d.sparser_support,
        "sparser_residual": d.sparser_residual,
        "sigma2": d.sigma2,
        "sparsity_level": cert.sparsity_level,
        "vertex_size": cert.vertex_size,
        "vertex": cert.vertex,
        "l1_tau_over_eta": cert.l1_threshold / cert.eta,
        "why": cert.explain(),
    }


def exact_sets(lin, mu: float) -> dict:
    """Worst-case errors (19)/(20) of the linearisation at ``mu`` (box 2-norm, or status)."""
    names = np.array(lin.feature_names)
    supports = {"FPS": names != "x4 x6", "SFPS": np.isin(names, DELTA_TERMS)}
    sets = {k: estimator_feasible_set(None, None, None, mu, support=v, linearisation=lin)
            for k, v in supports.items()}  # fmt: skip
    return {k: v.worst_case_norm if v.solved else v.status for k, v in sets.items()}


def one_run(
    noise_bound: float, seed: int, n_samples: int, physics_only: bool = True, **generator
) -> dict:
    """Fit, linearise, certify under both rules for mu, and bound FPS/SFPS at b sqrt(T);
    with ``physics_only``, also fit the physics alone on the same record."""
    start = time.perf_counter()
    data, lin = fit_and_linearise(noise_bound, seed, n_samples, **generator)
    mu = noise_bound * np.sqrt(n_samples)
    result = {"noise_bound": noise_bound, "seed": seed, **generator}
    for rule, bound in zip(RULES, (mu, "refined"), strict=True):
        result[rule] = certify_run(lin, bound)
    result["b sqrt(T), n = 2M"] = certify_run(lin, mu, level="2M")
    result["b sqrt(T), (11)'s vertex"] = certify_run(lin, mu, vertex="l1")
    result["theta_hat"] = lin.theta_hat[: lin.n_physical].tolist()
    result["fit_support_exact"] = bool(
        np.array_equal(lin.omega_hat != 0, data.true_omega.reshape(-1) != 0)
    )
    result["exact_sets"] = exact_sets(lin, mu)
    if physics_only:
        result["theta_physics_only"] = physics_only_theta(data)
    result["seconds"] = time.perf_counter() - start
    return result


VERDICTS = (*RULES, "b sqrt(T), n = 2M", "b sqrt(T), (11)'s vertex")


def certified_fraction(rows: list[dict], rule: str) -> float:
    """Share of ``rows`` certified under ``rule`` (nan for no rows)."""
    return float(np.mean([r[rule]["certified"] is True for r in rows])) if rows else np.nan


def table(runs: list[dict], noise_bounds) -> str:
    """Markdown table: runs certified per noise bound and verdict, and exact fitted supports."""
    head = (
        "| b | mu = b sqrt(T) | mu refined | b sqrt(T), paper's n = 2M "
        "| b sqrt(T), (11)'s vertex only | fit support = true |"
    )
    lines = [head, "|---|---|---|---|---|---|"]
    for b in noise_bounds:
        rows = [r for r in runs if r["noise_bound"] == b]
        cells = [f"{sum(r[k]['certified'] is True for r in rows)}/{len(rows)}" for k in VERDICTS]
        exact = f"{sum(r['fit_support_exact'] for r in rows)}/{len(rows)}"
        lines.append(f"| {b:g} | {' | '.join(cells)} | {exact} |")
    return "\n".join(lines)


def hull_groups(rows: list[dict]) -> dict:
    """The estimates spanning each hull: FPS (all), SFPS per rule, runs with supp(omega_bar)."""
    groups = {"FPS (all runs)": rows}
    groups.update({f"SFPS (certified, {k})": [r for r in rows if r[k]["certified"] is True]
                   for k in RULES})  # fmt: skip
    groups["true support (not a certificate)"] = [r for r in rows if r["fit_support_exact"]]
    return {k: np.array([r["theta_hat"] for r in g]).reshape(-1, 4) for k, g in groups.items()}


def _cell(points: np.ndarray) -> str:
    mean, std = hull_errors(points) if len(points) else (np.nan, np.nan)
    return f"{mean:.3g} +- {std:.2g} ({len(points)})"


def hull_table(runs: list[dict], noise_bounds) -> str:
    """Markdown table of the Monte Carlo convex-hull worst-case errors (paper's Fig. 2).

    Per noise bound, one row in theta and one in its first two principal components (axes
    of all the estimates at that bound); the number of estimates in each hull in brackets.
    The paper's values head the table.
    """
    groups = list(hull_groups(runs[:1]))
    lines = ["| b | space | " + " | ".join(f"e^{g}" for g in groups) + " |"]
    lines.append("|---|---|" + "---|" * len(groups))
    lines.append(f"| paper | PCA | {PAPER['FPS']} | {PAPER['SFPS']} | - | - |")
    for b in noise_bounds:
        hulls = hull_groups([r for r in runs if r["noise_bound"] == b])
        everything = hulls["FPS (all runs)"]
        if len(everything) < 2:
            continue
        pca = {k: principal_components(v, everything) if len(v) else v for k, v in hulls.items()}
        for space, sets in (("theta", hulls), ("PCA", pca)):
            lines.append(f"| {b:g} | {space} | " + " | ".join(map(_cell, sets.values())) + " |")
    return "\n".join(lines)


def _populations(runs: list[dict], noise_bound: float):
    """``(with_delta, alone, certified)`` at ``noise_bound``, over the runs that fitted the
    physics alone: theta of the fits with delta and of the physics alone (``(n, 4)`` each),
    and which fits with delta are certified under b sqrt(T)."""
    rows = [r for r in runs if r["noise_bound"] == noise_bound and "theta_physics_only" in r]
    with_delta = np.array([r["theta_hat"] for r in rows]).reshape(-1, 4)
    alone = np.array([r["theta_physics_only"] for r in rows]).reshape(-1, 4)
    return with_delta, alone, np.array([r[RULES[0]]["certified"] is True for r in rows], bool)


def paper_populations_table(runs: list[dict], noise_bounds) -> str:
    """Markdown table of Fig. 2 with the paper's populations: FPS the hull of every estimate
    with and without delta, SFPS that of the fits with delta certified under b sqrt(T);
    worst-case errors over each hull (mean +- 1 sigma, estimates in brackets), in theta and
    in the first two principal components of all the estimates at that noise bound."""
    lines = [
        "| b | space | e^FPS (with and without delta) | e^SFPS (certified, b sqrt(T)) |",
        "|---|---|---|---|",
        f"| paper | PCA | {PAPER['FPS']} | {PAPER['SFPS']} |",
    ]
    for b in noise_bounds:
        with_delta, alone, ok = _populations(runs, b)
        certified, everything = with_delta[ok], np.vstack([with_delta, alone])
        if len(everything) < 2:
            continue
        pca = [principal_components(v, everything) if len(v) else v
               for v in (everything, certified)]  # fmt: skip
        for space, sets in (("theta", (everything, certified)), ("PCA", pca)):
            lines.append(f"| {b:g} | {space} | " + " | ".join(map(_cell, sets)) + " |")
    return "\n".join(lines)


def _stat(values) -> str:
    values = [v for v in values if isinstance(v, float)]
    return f"{np.mean(values):.3g} +- {np.std(values):.2g} ({len(values)})" if values else "-"


def exact_table(runs: list[dict], noise_bounds) -> str:
    """Markdown table of the exact (19)/(20) worst-case errors at mu = b sqrt(T)."""
    lines = ["| b | mu | e^FPS (19), all runs | e^SFPS (20), all runs | e^FPS, certified"
             " | e^SFPS, certified |", "|---|---|---|---|---|---|"]  # fmt: skip
    for b in noise_bounds:
        rows = [r for r in runs if r["noise_bound"] == b]
        certified = [r for r in rows if r[RULES[0]]["certified"] is True]
        cells = [_stat([r["exact_sets"][k] for r in g]) for g in (rows, certified)
                 for k in ("FPS", "SFPS")]  # fmt: skip
        mu = rows[0][RULES[0]]["mu"] if rows else np.nan
        lines.append(f"| {b:g} | {mu:.3g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot_hulls(runs: list[dict], noise_bounds, path: Path) -> None:
    """Fig. 2: estimates in the plane of their first two principal components, with the FPS
    hull (all runs) and the SFPS hull (runs certified under b sqrt(T)), one panel per b."""
    from sk_offwhite.certify import hull_polygon

    fig, axes = plt.subplots(1, len(noise_bounds), figsize=(4 * len(noise_bounds), 4))
    for ax, b in zip(np.atleast_1d(axes), noise_bounds, strict=True):
        rows = [r for r in runs if r["noise_bound"] == b]
        thetas = np.array([r["theta_hat"] for r in rows]).reshape(-1, 4)
        ok = np.array([r[RULES[0]]["certified"] is True for r in rows], bool)
        exact = np.array([r["fit_support_exact"] for r in rows], bool)
        if len(thetas) < 2:
            continue
        pcs = principal_components(thetas)
        ax.scatter(*pcs[~ok].T, marker="x", c="tab:red", label="not certified")
        ax.scatter(*pcs[ok].T, marker="o", c="tab:blue", label="certified (Thm 5)")
        hulls = [(np.ones_like(ok), "k--", "FPS hull (all)"), (ok, "b-", "SFPS hull (certified)")]
        if not np.array_equal(exact, ok):
            hulls.append((exact, "g:", "fit support = supp(omega_bar), not certified"))
        for mask, style, name in hulls:
            if mask.any():
                ax.plot(*hull_polygon(pcs[mask]).T, style, lw=1.5, label=name)
        ax.set_title(f"b = {b:g}, mu = b sqrt(T): {ok.sum()}/{len(ok)} certified")
        ax.set_xlabel("pca_1(theta)")
        ax.set_ylabel("pca_2(theta)")
    for ax in np.atleast_1d(axes):
        ax.legend(fontsize="x-small")
    fig.suptitle("Approximated FPS and SFPS (convex hulls of the Monte Carlo estimates)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_paper_populations(runs: list[dict], noise_bounds, path: Path) -> None:
    """Fig. 2 with the paper's populations: fits with delta (certified or not) and of the
    physics alone in the principal components of all of them, the FPS hull over all and
    the SFPS hull over the certified, one panel per b."""
    from sk_offwhite.certify import hull_polygon

    fig, axes = plt.subplots(1, len(noise_bounds), figsize=(4 * len(noise_bounds), 4))
    for ax, b in zip(np.atleast_1d(axes), noise_bounds, strict=True):
        with_delta, alone, ok = _populations(runs, b)
        if not len(with_delta):
            continue
        pcs = principal_components(np.vstack([with_delta, alone]))
        fits = pcs[: len(with_delta)]
        ax.scatter(*pcs[len(with_delta) :].T, marker="^", c="tab:gray", label="physics alone")
        ax.scatter(*fits[~ok].T, marker="x", c="tab:red", label="delta, not certified")
        ax.scatter(*fits[ok].T, marker="o", c="tab:blue", label="delta, certified")
        ax.plot(*hull_polygon(pcs).T, "k--", lw=1.5, label="FPS hull (all)")
        if ok.sum() > 2:
            ax.plot(*hull_polygon(fits[ok]).T, "b-", lw=1.5, label="SFPS hull")
        ax.set_title(f"b = {b:g}: {ok.sum()}/{len(ok)} certified")
        ax.set_xlabel("pca_1(theta)")
        ax.set_ylabel("pca_2(theta)")
        ax.legend(fontsize="x-small")
    fig.suptitle("FPS and SFPS with the paper's populations (fits with and without delta)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fraction(runs: list[dict], noise_bounds, path: Path) -> None:
    """Fraction of runs certified against the noise bound, per rule for mu."""
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for rule in VERDICTS:
        shares = [certified_fraction([r for r in runs if r["noise_bound"] == b], rule)
                  for b in noise_bounds]  # fmt: skip
        ax.semilogx(noise_bounds, shares, "o-", label=f"mu = {rule}")
    ax.set_xlabel("output noise bound b")
    ax.set_ylabel("fraction certified (Theorem 5)")
    ax.set_ylim(-0.05, 1.05)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--n-samples", type=int, default=2000)
    parser.add_argument("--noise-bounds", type=float, nargs="+", default=[2e-5, 5e-5, 2e-4, 2e-3])
    parser.add_argument("--process-noise-bound", type=float, default=0.0)
    parser.add_argument(
        "--speed-range",
        type=float,
        nargs=2,
        default=[12.0, 28.0],
        help="range of the speed v in m/s (p = 1/v; the default is the generator's)",
    )
    parser.add_argument(
        "--no-physics-only",
        action="store_true",
        help="skip the fit of the physics alone (the paper's estimates without delta)",
    )
    parser.add_argument("--out", type=Path, default=Path("reports/certificates_sweep.json"))
    parser.add_argument("--figures", type=Path, default=None, help="folder for the figures")
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    generator = dict(
        process_noise_bound=args.process_noise_bound, speed_range=tuple(args.speed_range)
    )
    runs = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        for b in args.noise_bounds:
            runs.append(one_run(b, seed, args.n_samples, not args.no_physics_only, **generator))
            r = runs[-1]
            for rule in VERDICTS:
                print(f"b={b:g} seed={seed} mu {rule}: certified={r[rule]['certified']} "
                      f"-- {r[rule]['why']}", flush=True)  # fmt: skip
            args.out.write_text(json.dumps(runs, indent=1, default=float))
    printed = {
        "Runs certified (Theorem 5)": table(runs, args.noise_bounds),
        "Convex hulls of the Monte Carlo estimates": hull_table(runs, args.noise_bounds),
        "The paper's populations": paper_populations_table(runs, args.noise_bounds),
        "The exact sets (19)/(20) at mu = b sqrt(T)": exact_table(runs, args.noise_bounds),
    }
    for text in printed.values():
        print(text)
    print(f"seconds per run: {np.mean([r['seconds'] for r in runs]):.1f}")
    from _results import markdown_tables, write_results  # same folder: run as a script

    tables = [t for title, text in printed.items() for t in markdown_tables(title, text)]
    write_results("certificates_sweep", tables, path=args.json, argv=argv)
    if args.figures is not None:
        args.figures.mkdir(parents=True, exist_ok=True)
        plot_hulls(runs, args.noise_bounds, args.figures / "fig2_hulls.png")
        plot_fraction(runs, args.noise_bounds, args.figures / "certified_fraction.png")
        plot_paper_populations(runs, args.noise_bounds, args.figures / "fig2_populations.png")
    return runs


if __name__ == "__main__":
    main()
