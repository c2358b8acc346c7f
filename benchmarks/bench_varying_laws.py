"""The closed loop on plants whose declared constant is in truth a law of a state or input.

For each generator of `sk_offwhite.datasets._varying` (seed 0, ``--n-samples`` samples per
record) the loop (`EffectSearchCV`, default settings, the cubic polynomial dictionary)
runs from the declared physics with the constant. Written per plant: the effect the loop
added and its description, whether it is the generator's law (the same parameter,
variable, family and sign, or a named effect it equals), the fitted scale against the
truth, the largest relative error of the true declared parameters, the validation RMSE
of the declared physics and of the chosen model (the validation record only scored), and
the wall time.

Run: ``python benchmarks/bench_varying_laws.py [--n-samples N] [NAME ...]``; writes
``benchmarks/results/bench_varying_laws.json``.
"""

from __future__ import annotations

import argparse
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
from _results import write_results

from sk_offwhite import GreyBoxSparseRegressor, Stiffness, VaryingParameter
from sk_offwhite.datasets._varying import (
    make_hardening_spring,
    make_piezoviscous_bearing,
    make_saturating_inductor,
    make_valve_tank,
)
from sk_offwhite.loop import EffectSearchCV

GENERATORS = {
    "hardening spring": (make_hardening_spring, {"delta_states": [1]}),
    "saturating inductor": (make_saturating_inductor, {}),
    "valve tank": (make_valve_tank, {}),
    "piezoviscous bearing": (make_piezoviscous_bearing, {}),
}
COLUMNS = ["plant", "added", "true law", "scale error", "parameter error", "declared val RMSE",
           "chosen val RMSE", "cut", "seconds"]  # fmt: skip


def rmse(model, u, z) -> float:
    return float(np.sqrt(np.mean((np.reshape(model.predict(u), z.shape) - z) ** 2)))


def law_scale(data, search, values) -> tuple[str | bool, float | None]:
    r"""Whether the loop added the generator's law, and its fitted scale $x_s$: a
    `VaryingParameter` of the same parameter, variable, family and sign, or, for a
    stiffness $k(q) = k (1 + (q/q_s)^2)$, the cubic `Stiffness` it equals
    (`"equivalent"`; $q_s = \sqrt{-k\, \partial_k r / c}$ with $r$ the velocity's rate
    per unit deflection and $c$ the cubic coefficient)."""
    truth = data.varying
    for law in (e for e in search.effects_ if isinstance(e, VaryingParameter)):
        if (law.parameter, law.family, law.variable_name, law.sign(values)) == (
            truth["parameter"], truth["family"], truth["variable"], truth["sign"]):  # fmt: skip
            return True, values[f"{law.name}_scale"]
    springs = [e for e in search.effects_ if isinstance(e, Stiffness) and e.power == 3]
    names = data.physics.state_names
    if truth["family"] != "polynomial" or not springs or names[springs[0].position] != (
        truth["variable"]):  # fmt: skip
        return False, None
    spring, k = springs[0], truth["parameter"]
    if spring.describe(names, (), values).find(truth["sign"]) < 0:
        return False, None

    def rate(theta_k):
        theta = {**values, k: theta_k}
        x = jnp.zeros(len(names)).at[spring.position].set(1.0)
        return data.physics.rhs(x, jnp.zeros(data.physics.n_inputs), theta)[spring.state]

    slope = float(jax.grad(rate)(float(values[k])))
    return "equivalent", float(np.sqrt(-slope * values[k] / values[f"{spring.name}_coefficient"]))


def law_row(name: str, data, search, seconds: float) -> list:
    """One table row of a loop's run on ``data``."""
    truth, best = data.varying, search.best_estimator_
    values = best.parameters_
    same, scale = law_scale(data, search, values)
    scale_error = None if scale is None else abs(scale / abs(truth["constants"]["x_s"]) - 1.0)
    errors = [abs(values[k] / v - 1.0) for k, v in data.true_parameters.items() if v != 0]
    declared = search.result_.set_fits["declared physics"]
    before, after = rmse(declared, data.u_val, data.z_val), rmse(search, data.u_val, data.z_val)
    added = "; ".join(e.describe(data.physics.state_names, (), values) for e in search.effects_)
    return [name, added or "nothing", same, scale_error, max(errors), before, after,
            1.0 - after / before, seconds]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", choices=[[], *GENERATORS], default=[])
    parser.add_argument("--n-samples", type=int, default=600)
    args = parser.parse_args()
    rows = []
    for name in args.names or GENERATORS:
        make, settings = GENERATORS[name]
        data = make(n_samples=args.n_samples, random_state=0)
        library = ps.PolynomialLibrary(degree=3)
        search = EffectSearchCV(GreyBoxSparseRegressor(data.physics, library, **settings))
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            search.fit(data.u_est, data.z_est)
        rows.append(law_row(name, data, search, time.perf_counter() - start))
        print(dict(zip(COLUMNS, rows[-1], strict=True)), flush=True)
    table = {
        "title": "Declared constants that are laws: what the loop adds",
        "columns": COLUMNS,
        "rows": rows,
        "notes": [
            "scale and parameter errors relative to the generator's truth; validation RMSE "
            "of the free run on the validation record (initial state from the fit)."
        ],
    }
    write_results("bench_varying_laws", [table])


if __name__ == "__main__":
    main()
