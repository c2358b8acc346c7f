"""Quick start: fit a grey-box model whose physics misses an effect, and read the correction.

Synthetic Cascaded Tanks data (the paper's eq. 21) with an upper-tank overflow and a lower-
tank sensor saturation that the declared physics does not know about. We fit

1. the physics alone (parameters and initial state, on the simulation error);
2. the physics plus a sparse correction from a small pysindy dictionary, with the sparsity
   weight ``gamma`` chosen by cross-validation on the estimation record only;

and compare both on a separate validation record. Run: ``python examples/quickstart.py``
(``--quick``: a short record, one γ and short fits, to check that the script runs).
"""

from __future__ import annotations

import argparse

import numpy as np
import pysindy as ps
from sklearn.model_selection import GridSearchCV, KFold

from sk_offwhite import GreyBoxSparseRegressor, enable_fused_loops
from sk_offwhite.datasets import cascaded_tanks_physics, make_cascaded_tanks


def rmse(z, z_sim):
    """Root-mean-square simulation error."""
    return float(np.sqrt(np.mean((np.ravel(z) - np.ravel(z_sim)) ** 2)))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short run (for CI)")
    quick = parser.parse_args(argv).quick
    enable_fused_loops()  # before anything runs on JAX: one kernel per simulation loop
    n_samples, gammas, max_iter = (300, [1e-3], 40) if quick else (1024, [1e-4, 1e-3, 1e-2], 300)
    horizon = 64 if quick else 256
    data = make_cascaded_tanks(n_samples=n_samples, noise_std=0.02, random_state=0)
    physics = cascaded_tanks_physics(
        fixed={"k4": data.true_parameters["k4"]}, x0=[data.z[0, 0]] * 2
    )
    print(data.hidden_effect["description"] if data.hidden_effect else "no hidden effect")

    plain = GreyBoxSparseRegressor(physics, max_iter=max_iter).fit(data.u, data.z)
    print("\nphysics only:", {k: round(v, 4) for k, v in plain.parameters_.items()})

    library = ps.PolynomialLibrary(degree=2, include_bias=False)
    model = GreyBoxSparseRegressor(
        physics, library=library, delta_states=[0], horizon=horizon, max_iter=max_iter
    )
    search = GridSearchCV(model, {"gamma": gammas}, cv=KFold(3))
    search.fit(data.u, data.z, sample_index=np.arange(len(data.u)))
    best = search.best_estimator_
    print(f"\nwith a sparse correction (gamma={search.best_params_['gamma']:g} by 3-fold CV):")
    best.print()

    print("\nvalidation simulation RMSE (initial state from the first 50 samples):")
    for label, est in (("physics only", plain), ("physics + delta", best)):
        z_sim = est.predict(data.u_val, z_init=data.z_val[:50])
        print(f"  {label:16s} {rmse(data.z_val[50:], z_sim[50:]):.4f}")


if __name__ == "__main__":
    main()
