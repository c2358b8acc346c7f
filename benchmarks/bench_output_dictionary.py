"""The dictionary of the loop's output correction on the Cascaded Tanks, setting by setting.

Runs the README's main job loop once (the same settings), then refits the augmented
physics it chose with a sparse correction of its output map (``delta_outputs=[0]``) on
Gaussian bumps of ``x2`` ([`RadialBasis`][sk_offwhite.RadialBasis]) for each setting: the number
of bumps, the span of their centres and their width (in standard deviations of the
simulated ``x2``; ``spacing``: the centres' spacing), with or without the constant and
``x2`` itself, and with ``x2`` clipped into its simulated range or not. γ is chosen on the
support path by 3-fold CV on the estimation record, as the loop does. Prints each
setting's CV RMSE (the loop's score), number of terms and the validation RMSE under both
protocols (only reported: no setting is chosen on it).

Run ``python benchmarks/bench_output_dictionary.py [--n-jobs N]`` (about 3-5 min on 2
cores with the compilation cache filled by a run of the main job).
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
import pysindy as ps

from sk_offwhite import (
    GreyBoxSparseRegressor,
    RadialBasis,
    enable_compilation_cache,
    enable_fused_loops,
    fit_gamma_path,
)
from sk_offwhite.datasets import cascaded_tanks_physics, load_cascaded_tanks
from sk_offwhite.loop import LoopSettings, close_the_loop, held_out_splits, warm_physics

SETTINGS = [  # (bumps, span, width, constant and x2)
    (7, 2.0, "spacing", True),
    (5, 1.6, "spacing", False),
    (7, 1.6, "spacing", False),
    (9, 1.6, "spacing", False),
    (5, 1.6, 0.4, False),
    (7, 1.6, 0.3, False),
    (7, 2.0, 0.3, False),
    (9, 2.0, 0.25, False),
    (7, 1.6, 0.5, False),
]


def dictionary(states, bumps, span, width, linear, clipped) -> RadialBasis:
    """Bumps of the simulated ``x2`` (``states``), clipped into its range or not."""
    width = None if width == "spacing" else width
    library = RadialBasis.from_data(
        states, ["x2"], n_bumps=bumps, span=span, width=width, linear=linear
    )
    return library if clipped else RadialBasis(library.centers, library.widths, linear=linear)


def rmse(est, u, z, init_window: int = 0) -> float:
    """Free-run RMSE (``init_window``: state from the first samples, which are not scored)."""
    outputs = est.simulate(u, z_init=z[:init_window] if init_window else None).outputs
    return float(np.sqrt(np.mean((outputs[init_window:] - z[init_window:]) ** 2)))


def fit_setting(physics, library, data, settings) -> tuple:
    """``(CV RMSE, estimator)`` of ``physics`` + the output correction on ``library``."""
    est = GreyBoxSparseRegressor(
        physics, library, delta_outputs=[0], max_iter=settings.max_iter, init_window=50
    )
    path = fit_gamma_path(
        est, data.u_est, data.z_est, n_gammas=settings.n_gammas, eps=settings.gamma_eps,
        cv=held_out_splits(settings, len(data.u_est)), init_window=settings.init_window,
        n_jobs=settings.n_jobs,
    )  # fmt: skip
    return float(np.mean(path.cv_rmse[path.best_index])), path.estimator


def main(argv=None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-jobs", type=int, default=2)
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args(argv)
    enable_fused_loops()
    enable_compilation_cache()
    warnings.simplefilter("ignore")
    data = load_cascaded_tanks()
    settings = LoopSettings(n_jobs=args.n_jobs, max_effects=4)  # as the main job
    physics = cascaded_tanks_physics(fixed={"k4": 0.05})
    library = ps.PolynomialLibrary(degree=2, include_bias=True)
    result = close_the_loop(physics, library, data.u_est, data.z_est, settings=settings)
    start = warm_physics(result.augmented_physics, result.final)
    states = result.final.simulate(data.u_est).states[:, [1]]
    print(f"augmented physics: CV {result.cv_errors['final']:.4f}, validation "
          f"{rmse(result.final, data.u_val, data.z_val):.4f} / "
          f"{rmse(result.final, data.u_val, data.z_val, 50):.4f}")  # fmt: skip
    rows = []
    for clipped in (True, False):
        for bumps, span, width, linear in SETTINGS:
            library = dictionary(states, bumps, span, width, linear, clipped)
            cv, est = fit_setting(start, library, data, settings)
            row = dict(clipped=clipped, bumps=bumps, span=span, width=width, linear=linear,
                       cv=cv, terms=est.n_nonzero_,
                       original=rmse(est, data.u_val, data.z_val),
                       init_window=rmse(est, data.u_val, data.z_val, 50))  # fmt: skip
            rows.append(row)
            print(" ".join(f"{k}={v:.4f}" if isinstance(v, float) else f"{k}={v}"
                           for k, v in row.items()), flush=True)  # fmt: skip
    from _results import records_table, write_results  # same folder: run as a script

    title = "The output correction's dictionary, setting by setting (validation RMSE, V)"
    notes = [f"augmented physics alone: CV {result.cv_errors['final']:.4f}"]
    tables = [records_table(title, rows, notes)]
    write_results("bench_output_dictionary", tables, path=args.json, argv=argv)
    return rows


if __name__ == "__main__":
    main()
