"""What else the Cascaded Tanks model could have been: variants of the loop's final model.

Runs the README's closed loop (the same settings as ``cascaded_tanks_loop.py``), then refits
variants of the structure it chose (the declared physics with its effects), each
started from the chosen fit, and scores every variant as the loop scores an effect set:
the RMSE of the 3-fold cross-validation on the estimation record (the loop's choice;
a parameter held on each direction of the fit the data do not determine, as on the
loop's final model),
next to the estimation RMSE and, only reported, the validation RMSE under both protocols.

Variants:

* Torricelli's exponents freed (``a1``, ``a2``, both): the laws the loop may relax when
  they are declared relaxable (``--relax-exponents`` in the main job);
* the pump's flow a power of its voltage (``k4 u^b``, ``b`` freed from 1), and tanks
  whose cross-section grows with the level (each level's rate divided by ``1 + c_i x_i``,
  ``c1``, ``c2`` or both freed from 0): constants of the declared laws, freed as the loop
  frees a relaxable one;
* the sensor calibration of one and two degrees more than the chosen one (the loop's
  refinement tries one more);
* the pump acting 1, 2 or 3 samples late (the input delayed, on both records);
* the same ODE integrated more accurately than eq. (21)'s one Euler step per sample (4
  Euler sub-steps, one RK4 step): is the discretisation part of what the model misses?
* the overflows' corners fitted (``Overflow(..., fit_corner=True)``) instead of fixed at
  2.5 % of each level's spread;
* a dead zone of the pump ([`DeadZone`][sk_offwhite.DeadZone]: no flow below a voltage, as a
  pump that must lift the water to the upper tank's inlet), its width started at 2 % of
  the voltage's RMS (next to the model without it, where the loop's candidate starts)
  and at 25 % (where it started before), alone and with the overflows' corners fitted;
* a term in ``x2`` in the upper tank's equation (the pump lifting from a reservoir that
  the lower tank's water is taken from), alone and with the dead zone;
* multiple starts of the effects' levels and fraction (``--starts``): does the fit end in
  the best optimum the estimation record has?

Run ``python examples/cascaded_tanks_variants.py [--folds K [K ...]] [--tail] [--starts]
[--n-jobs N]`` (a few minutes on two CPU cores with the default 3 folds; ``--folds 3 4 5
6 --tail`` scores every variant with each fold count and on the held-out tail as well,
``--starts`` adds the multiple starts: 17 min in all).
"""

from __future__ import annotations

import argparse
import itertools
import warnings
from dataclasses import replace

import jax.numpy as jnp
import numpy as np
import pysindy as ps

from sk_offwhite import (
    DeadZone,
    DictionaryTerm,
    GreyBoxSparseRegressor,
    Overflow,
    Parameter,
    PhysicsModel,
    RelaxedLaw,
    SensorCalibration,
    augment,
    enable_fused_loops,
)
from sk_offwhite.datasets import cascaded_tanks_physics, load_cascaded_tanks
from sk_offwhite.loop import (
    LoopSettings,
    close_the_loop,
    cross_validated_rmse,
    fit_continued,
    hold_undetermined_directions,
    warm_physics,
)

FREED_CONSTANTS = {"b": (1.0, (0.2, 3.0)), "c1": (0.0, (-0.05, 1.0)), "c2": (0.0, (-0.05, 1.0))}
"""The constants of `tanks_rhs` beyond Torricelli's exponents: declared value, bounds
(the slopes' in 1/V, the units of this record's levels)."""


def tanks_rhs(x, u, theta):
    r"""Eq. (21) with every constant a variant frees:

    $$
    \dot x_1 = \frac{k_4 u^b - k_1 x_1^{a_1}}{1 + c_1 x_1}, \qquad
    \dot x_2 = \frac{k_2 x_1^{a_1} - k_3 x_2^{a_2}}{1 + c_2 x_2},
    $$

    eq. (21) itself at $a_i = 1/2$, $b = 1$, $c_i = 0$ (levels floored as
    in [`safe_sqrt`][sk_offwhite.datasets.safe_sqrt])."""
    flow1 = jnp.maximum(x[0], 1e-6) ** theta["a1"]
    flow2 = jnp.maximum(x[1], 1e-6) ** theta["a2"]
    inflow = theta["k4"] * jnp.maximum(u[0], 1e-6) ** theta["b"]
    area1 = 1.0 + theta["c1"] * jnp.maximum(x[0], 0.0)
    area2 = 1.0 + theta["c2"] * jnp.maximum(x[1], 0.0)
    upper = (inflow - theta["k1"] * flow1) / area1
    return jnp.stack([upper, (theta["k2"] * flow1 - theta["k3"] * flow2) / area2])


def relaxable_tanks_physics(method: str | None = None, n_substeps: int = 1) -> PhysicsModel:
    """The main job's physics written with `tanks_rhs`, every constant fixed at its
    declared value and relaxable; integrated by one explicit-Euler step per sample as eq.
    (21), or by ``n_substeps`` steps of ``method`` (``"euler"`` or ``"rk4"``)."""
    base = cascaded_tanks_physics(fixed={"k4": 0.05}, relaxable_exponents=True)
    constants = {name: Parameter(value, bounds, fixed=True, relaxable=True)
                 for name, (value, bounds) in FREED_CONSTANTS.items()}  # fmt: skip
    return PhysicsModel.from_ode(
        tanks_rhs, base.sampling_time, output=1, parameters={**base.parameters, **constants},
        n_states=2, n_inputs=1, method=method or base.method, n_substeps=n_substeps,
        x0=base.x0, x0_bounds=(0.0, None),
        state_names=base.state_names, input_names=base.input_names,
        output_names=base.output_names, state_kinds=base.state_kinds,
        input_kinds=base.input_kinds,
    )  # fmt: skip


def started_from(physics, fitted: GreyBoxSparseRegressor, **values):
    """``physics`` started from ``fitted`` ([`warm_physics`][sk_offwhite.loop.warm_physics]), then
    from those of ``values`` it has."""
    starts = {
        k: Parameter(float(v), physics.parameters[k].bounds)
        for k, v in values.items()
        if k in physics.parameters
    }
    return warm_physics(physics, fitted).with_parameters(**starts)


def estimator(physics, settings: LoopSettings) -> GreyBoxSparseRegressor:
    """An estimator of ``physics`` with the loop's fit settings."""
    return GreyBoxSparseRegressor(
        physics,
        max_iter=settings.max_iter,
        init_window=settings.init_window,
        lm_scaling=settings.lm_scaling,
    )


def rmse(est, u, z, init_window: int = 0) -> float:
    """Free-run RMSE; with ``init_window`` the state is estimated from the first samples,
    which are not scored (the ``init_window`` protocol)."""
    if init_window == 0:
        return float(np.sqrt(np.mean((est.simulate(u).outputs - z) ** 2)))
    outputs = est.simulate(u, z_init=z[:init_window]).outputs
    return float(np.sqrt(np.mean((outputs[init_window:] - z[init_window:]) ** 2)))


def delayed(u: np.ndarray, samples: int) -> np.ndarray:
    """``u`` delayed by ``samples`` (the first value held)."""
    if samples == 0:
        return u
    return np.vstack([np.repeat(u[:1], samples, axis=0), u[:-samples]])


def held_out_scores(physics, u, z, settings: LoopSettings, folds, tail: bool) -> dict:
    """The loop's held-out score of ``physics`` with each number of ``folds`` (key ``k``)
    and, with ``tail``, on the estimation record's last quarter (key ``"tail"``)."""
    rules = [dict(n_folds=k) for k in folds] + ([dict(selection="tail")] if tail else [])
    return {
        rule.get("n_folds", "tail"): cross_validated_rmse(physics, u, z, replace(settings, **rule))
        for rule in rules
    }


def score(label, physics, fitted, data, settings, folds=(3,), tail=False, delay=0) -> dict:
    """Refit ``physics`` from ``fitted``, hold a parameter on each direction of the fit the
    data do not determine, as the loop does on its final model
    ([`hold_undetermined_directions`][sk_offwhite.loop.hold_undetermined_directions]; ``held``:
    their names), and score it (held-out scores, estimation, validation)."""
    u_est, u_val = delayed(data.u_est, delay), delayed(data.u_val, delay)
    template = estimator(started_from(physics, fitted), settings)
    est = fit_continued(template, u_est, data.z_est, settings.horizon)
    held, est, _, _ = hold_undetermined_directions(
        physics, est, u_est, data.z_est, settings=settings
    )
    scores = held_out_scores(warm_physics(held, est), u_est, data.z_est, settings, folds, tail)
    was_free = {n for n, spec in physics.parameters.items() if not spec.fixed}
    fixed = [n for n in was_free if held.parameters[n].fixed]
    row = dict(variant=label, held_out=scores, held=fixed)
    row.update(estimation=rmse(est, u_est, data.z_est), original=rmse(est, u_val, data.z_val))
    row.update(init_window=rmse(est, u_val, data.z_val, 50), parameters=est.parameters_)
    return row


def variants(result, declared, voltage_rms: float):
    """``(label, physics, delay)`` of each variant of the chosen structure
    (``voltage_rms``: the RMS of the estimation record's pump voltage)."""
    laws = {name: RelaxedLaw(name, spec.value, spec.bounds)
            for name, spec in declared.parameters.items() if spec.relaxable}  # fmt: skip
    effects = list(result.effects)
    sensors = [e for e in effects if isinstance(e, SensorCalibration)]
    yield "chosen (the loop's final model)", augment(declared, *effects), 0
    for names in (("a1",), ("a2",), ("a1", "a2")):
        relaxed = augment(declared, *effects, *(laws[n] for n in names))
        yield "+ exponent " + " and ".join(names) + " freed", relaxed, 0
    freed = {"pump exponent b": ("b",), "cross-section slope c1": ("c1",),
             "cross-section slope c2": ("c2",), "both slopes": ("c1", "c2")}  # fmt: skip
    for label, names in freed.items():
        yield f"+ {label} freed", augment(declared, *effects, *(laws[n] for n in names)), 0
    for sensor, more in itertools.product(sensors, (1, 2)):
        degree = sensor.degree + more
        others = [e for e in effects if e is not sensor]
        calibration = SensorCalibration(
            sensor.output, sensor.center, sensor.scale, degree=degree, name=sensor.name
        )
        yield f"sensor calibration of degree {degree}", augment(declared, *others, calibration), 0
    for delay in (1, 2, 3):
        yield f"pump {delay} sample(s) late", augment(declared, *effects), delay
    for label, method, n_substeps in (("4 Euler sub-steps", "euler", 4), ("an RK4 step", "rk4", 1)):
        integrated = relaxable_tanks_physics(method, n_substeps)
        yield f"the ODE integrated by {label}", augment(integrated, *effects), 0
    sharp = [e.replace(fit_corner=True) if isinstance(e, Overflow) else e for e in effects]
    yield "overflows' corners fitted", augment(declared, *sharp), 0
    yield from _pump_and_reservoir(declared, effects, sharp, voltage_rms)


def _pump_and_reservoir(declared, effects, sharp, voltage_rms: float):
    """The variants with a dead zone of the pump (its width started at 2 % and 25 % of
    the voltage's RMS) and with a term in ``x2`` in the upper tank's equation."""

    def dead_zone(share):
        return DeadZone(0, share * voltage_rms, name="dead_zone_u")

    linear = ps.PolynomialLibrary(degree=1, include_bias=False)
    reservoir = DictionaryTerm(0, linear, ("x1", "x2", "u"), 1, name="term_x1_x2")
    for share in (0.02, 0.25):
        label = f"+ pump dead zone (from {share:.0%} of the RMS)"
        yield label, augment(declared, *effects, dead_zone(share)), 0
    yield (
        "+ pump dead zone, overflows' corners fitted",
        augment(declared, *sharp, dead_zone(0.02)),
        0,
    )
    yield "+ x2 in the x1 equation", augment(declared, *effects, reservoir), 0
    both = augment(declared, *effects, dead_zone(0.02), reservoir)
    yield "+ pump dead zone and x2 in the x1 equation", both, 0


def multiple_starts(result, declared, data, settings) -> list[tuple]:
    """Estimation RMSE of the chosen structure from a grid of starts of the overflow
    levels and fraction: ``(starts, rmse)``, best first."""
    physics = augment(declared, *result.effects)
    grid = itertools.product((9.0, 12.5, 16.0, 20.0), (7.0, 9.5, 14.0, 20.0), (0.3, 0.7, 1.0))
    rows = []
    for level, cap, fraction in grid:
        starts = dict(overflow_x1_to_x2_level=level, overflow_x2_level=cap,
                      overflow_x1_to_x2_fraction=fraction)  # fmt: skip
        template = estimator(started_from(physics, result.final, **starts), settings)
        est = fit_continued(template, data.u_est, data.z_est, settings.horizon)
        value = rmse(est, data.u_est, data.z_est)
        rows.append((starts, value if np.isfinite(value) else np.inf))
    return sorted(rows, key=lambda row: row[1])


def main(argv=None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", action="store_true", help="also the multiple starts")
    parser.add_argument("--n-jobs", type=int, default=2, help="processes of the loop's CV")
    parser.add_argument(
        "--folds", type=int, nargs="+", default=[3], help="CV fold counts to score with"
    )
    parser.add_argument("--tail", action="store_true", help="also score on the held-out tail")
    args = parser.parse_args(argv)
    enable_fused_loops()
    warnings.simplefilter("ignore")
    data = load_cascaded_tanks()
    declared = relaxable_tanks_physics()
    settings = LoopSettings(n_jobs=args.n_jobs, max_effects=4)  # as the main job
    library = ps.PolynomialLibrary(degree=2, include_bias=True)
    physics = cascaded_tanks_physics(fixed={"k4": 0.05})
    result = close_the_loop(physics, library, data.u_est, data.z_est, settings=settings)
    print("effects chosen:", ", ".join(e.name for e in result.effects))
    keys = [*args.folds] + (["tail"] if args.tail else [])
    names = [f"{k}-fold CV" if k != "tail" else "tail" for k in keys]
    print("| variant | " + " | ".join(names) + " | estimation | validation, original "
          "| init_window |", "|---|" + "---|" * (len(keys) + 3), sep="\n")  # fmt: skip
    rows = []
    voltage_rms = float(np.sqrt(np.mean(data.u_est**2)))
    for label, model, delay in variants(result, declared, voltage_rms):
        rows.append(score(label, model, result.final, data, settings, args.folds, args.tail,
                          delay))  # fmt: skip
        r = rows[-1]
        held_out = " | ".join(f"{r['held_out'][k]:.4f}" for k in keys)
        print(f"| {label} | {held_out} | {r['estimation']:.4f} | {r['original']:.4f} "
              f"| {r['init_window']:.4f} |", flush=True)  # fmt: skip
    for r in rows:
        print(f"{r['variant']}: held {', '.join(r['held']) or 'nothing'}")
    if args.starts:
        ranked = multiple_starts(result, declared, data, settings)
        best = ranked[0][1]
        reach = sum(abs(value - best) <= 1e-6 * best for _, value in ranked)
        chosen = rmse(result.final, data.u_est, data.z_est)
        print(f"multiple starts: {len(ranked)}, best estimation RMSE {best:.6f} (reached by "
              f"{reach}); the loop's fit: {chosen:.6f}")  # fmt: skip
    return rows


if __name__ == "__main__":
    main()
