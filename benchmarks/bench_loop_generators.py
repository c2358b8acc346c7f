"""The closed loop on every synthetic generator: is the hidden effect named and added?

For each generator (seed 0, default record lengths unless ``--short``) the loop runs with
its default settings except ``fit_delta`` (off unless ``--delta``). Printed per system:
the effects added, whether one of them is of the hidden effect's kind, the fitted effect
parameter against the truth (``hidden_effect["rates"]`` where the generator gives it), the
largest relative error of the declared parameters, the validation RMSE of the declared and
augmented physics (``init_window`` protocol, 50 samples), the model the loop chose by CV,
the failures, the wall time, and the Ljung-Box p-value of the declared and augmented
physics' simulation residuals on the estimation record (25 lags: a p-value below 0.01
says the residual is not white, something is left to explain), then the loop's notes on
candidates that fit as well as a chosen effect (the data may not tell them apart).
Everything is chosen on the estimation record; the validation record is only scored.

With ``--again`` the loop then runs a second time on the physics it returned (the
augmented physics, started at its fitted values) and prints what it adds there, the CV
RMSE of that physics and of the second loop's final model, and the validation RMSE of
both: with the missing effect in the physics, a loop that adds more is making a false
discovery.

Run: ``python benchmarks/bench_loop_generators.py [--short] [--delta] [--again]
[--lm-scaling {per-variable,global}] [--max-iter N] [NAME ...]``; ``--max-iter`` sets
every fit's iteration limit (``LoopSettings.max_iter``, default 300): a loop whose choice
changes with it depends on where its fits stop rather than on the data.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import jax

from sk_offwhite import (
    Backlash,
    DeadZone,
    DifferenceDeadZone,
    Friction,
    InputDelay,
    InputLag,
    InputSaturation,
    Leak,
    Overflow,
    Parameter,
    PowerDrag,
    PowerLoss,
    PowerStiffness,
    QuadraticDrag,
    RelaxedLaw,
    SensorCalibration,
    SensorLag,
    SensorStep,
    Stiffness,
)
from sk_offwhite.datasets import (
    make_backlash_servo,
    make_cascaded_tanks,
    make_clearance_coupling,
    make_convective_block,
    make_coulomb_drive,
    make_dead_zone_motor,
    make_delayed_drive,
    make_delayed_heater,
    make_diode_rc,
    make_duffing_oscillator,
    make_friction_oscillator,
    make_heated_block,
    make_lagged_drive,
    make_lagged_heater,
    make_leaky_tank,
    make_nonlinear_sensor_tank,
    make_pendulum_drag,
    make_saturating_actuator,
    make_slow_sensor_tank,
    make_stepped_sensor_tank,
)
from sk_offwhite.loop import (
    LoopSettings,
    analyse_model,
    close_the_loop,
    score_models,
    warm_physics,
)


def _tanks(**kwargs):
    """Synthetic tanks with k4 fixed (only x2 is measured: the scale of x1 is otherwise
    not identifiable)."""
    data = make_cascaded_tanks(**kwargs)
    k4 = Parameter(data.true_parameters["k4"], fixed=True)
    data.physics = data.physics.with_parameters(k4=k4)
    return data


def _cubic_sensor(**kwargs):
    """The tank whose level sensor reads ``x + 0.04 x^2 + 0.004 x^3``: the loop's quadratic
    calibration must be refined into the cubic one."""
    return make_nonlinear_sensor_tank(cubic=0.004, **kwargs)


def _power_drag(**kwargs):
    """The pendulum whose drag grows with the power 1.5 of its rate: the loop's quadratic
    drag must be refined into the drag of fitted exponent."""
    return make_pendulum_drag(exponent=1.5, **kwargs)


def _power_spring(**kwargs):
    """The oscillator whose spring force grows with the power 2.5 of its deflection: the
    loop's cubic stiffness must be refined into the spring of fitted exponent."""
    return make_duffing_oscillator(exponent=2.5, **kwargs)


def _stribeck(**kwargs):
    """The oscillator whose friction rises by 0.5 near rest (a Stribeck friction): the
    loop's Coulomb friction must be refined into the Stribeck one."""
    return make_friction_oscillator(stribeck=0.5, **kwargs)


def _long_delayed_heater(**kwargs):
    """The block whose heat arrives 24 s (12 samples) late: beyond a reach of eight
    samples, with which the loop's dead time stopped at its bound and the loop added a
    lag, a dead zone and a saturation instead (``_candidates.DELAY_REACH``)."""
    return make_delayed_heater(delay=24.0, **kwargs)


def _convection_relaxable(**kwargs):
    """The block that loses heat by natural convection (power 4/3), its declared loss law
    written with a relaxable exponent (fixed at 1): the loop may free it, or add a loss of
    fitted power (either is of the hidden effect's kind)."""
    return make_convective_block(relaxable=True, **kwargs)


# name: (generator, short length, effect kind(s), (fitted parameter, rates key) or None)
SYSTEMS = {
    "drive": (make_coulomb_drive, 2000, Friction, ("friction_v_coulomb", "coulomb")),
    "duffing": (make_duffing_oscillator, 1500, Stiffness, ("stiffness_y_coefficient", "cubic")),
    "power_spring": (
        _power_spring,
        1500,
        PowerStiffness,
        ("stiffness_y_power_exponent", "exponent"),
    ),
    "pendulum": (
        make_pendulum_drag,
        1500,
        QuadraticDrag,
        ("drag_omega_coefficient", "quadratic_drag"),
    ),
    "power_drag": (
        _power_drag,
        1500,
        PowerDrag,
        ("drag_omega_power_exponent", "exponent"),
    ),
    "dead_zone": (make_dead_zone_motor, 800, DeadZone, ("dead_zone_u_width", "dead_zone")),
    "backlash": (make_backlash_servo, 1000, Backlash, ("backlash_u_width", "backlash")),
    "lagged_drive": (make_lagged_drive, 800, InputLag, ("lag_u_time_constant", "time_constant")),
    "lagged_heater": (make_lagged_heater, 1000, InputLag, ("lag_P_time_constant", "time_constant")),
    "delayed_drive": (make_delayed_drive, 800, InputDelay, ("delay_u_delay", "delay")),
    "delayed_heater": (make_delayed_heater, 1000, InputDelay, ("delay_P_delay", "delay")),
    "delayed_heater_long": (_long_delayed_heater, 1000, InputDelay, ("delay_P_delay", "delay")),
    "leaky_tank": (make_leaky_tank, 600, Leak, None),
    "friction": (make_friction_oscillator, 500, Friction, None),
    "stribeck": (_stribeck, 500, Friction, ("friction_v_stribeck_stribeck", "stribeck")),
    "actuator": (make_saturating_actuator, 500, InputSaturation, None),
    "tanks": (_tanks, 500, Overflow, None),
    "sensor": (make_nonlinear_sensor_tank, 400, SensorCalibration, None),
    "cubic_sensor": (_cubic_sensor, 400, SensorCalibration, None),
    "stepped_sensor": (
        make_stepped_sensor_tank,
        400,
        SensorStep,
        ("step_x_height", "step_height"),
    ),
    "slow_sensor": (
        make_slow_sensor_tank,
        400,
        SensorLag,
        ("sensor_lag_x_time_constant", "time_constant"),
    ),
    "heater": (make_heated_block, 1000, InputSaturation, ("actuator_limit_P_level", "limit")),
    "convection": (make_convective_block, 1000, PowerLoss, None),
    "convection_relaxable": (
        _convection_relaxable,
        1000,
        (RelaxedLaw, PowerLoss),
        ("loss_exponent", "exponent"),
    ),
    "diode": (make_diode_rc, 600, DifferenceDeadZone, ("drop_e_v_width", "drop")),
    "clearance": (
        make_clearance_coupling,
        600,
        DifferenceDeadZone,
        ("dead_zone_u_theta_width", "gap"),
    ),
}


def _validation(result, data) -> dict:
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    return {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}


def _whiteness(est, data) -> str:
    """Ljung-Box p-value (25 lags) of ``est``'s simulation residual on the estimation
    record, per output: is anything left for another effect to explain?"""
    report = analyse_model(est, data.u, data.z, est.physics_)
    return ", ".join(f"{w.p_value:.2g}" for w in report.whiteness.values() if w is not None)


def _parameter_error(result, data) -> float:
    fitted = result.final.parameters_
    return max(
        abs(fitted[k] - v) / abs(v)
        for k, v in data.true_parameters.items()
        if k in fitted and not result.final.physics_.parameters[k].fixed
    )


def run(
    name: str,
    short: bool,
    delta: bool,
    lm_scaling: str = "per-variable",
    max_iter: int = LoopSettings.max_iter,
) -> tuple:
    """The loop on one generator's record, printed; ``(data, result, settings)``."""
    make, length, kind, parameter = SYSTEMS[name]
    data = make(random_state=0, **({"n_samples": length} if short else {}))
    settings = LoopSettings(fit_delta=delta, lm_scaling=lm_scaling, max_iter=max_iter)
    result, seconds = _timed_loop(data.physics, data, settings)
    row = _print_run(name, data, result, kind, parameter, seconds)
    return data, result, settings, row


def _timed_loop(physics, data, settings) -> tuple:
    """[`close_the_loop`][sk_offwhite.loop.close_the_loop] of ``physics`` on ``data``'s estimation
    record, its warnings silenced, and its wall time in seconds."""
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = close_the_loop(physics, data.suggested_library, data.u, data.z, settings=settings)
    return result, time.perf_counter() - start


def _print_run(name, data, result, kind, parameter, seconds) -> dict:
    """Print one generator's line; return it as a results row."""
    rmse = _validation(result, data)
    effect, fitted = "", None
    if parameter is not None and parameter[0] in result.final.parameters_:
        truth = data.hidden_effect["rates"][parameter[1]]
        effect = f"; {parameter[0]} {result.final.parameters_[parameter[0]]:.4g} (true {truth:.4g})"
        fitted = f"{parameter[0]} {result.final.parameters_[parameter[0]]:.4g} (true {truth:.4g})"
    hidden = data.hidden_effect
    named = [h for h in result.hypotheses if h.equation_index == hidden["equation"]]
    sign = "no hypothesis" if not named else f"sign {named[0].sign} (true {hidden['sign']})"
    print(
        f"{name}: n={len(data.u)}; hypothesis on {hidden['equation']}: {sign}; "
        f"effects {[e.name for e in result.effects]}; right kind "
        f"{any(isinstance(e, kind) for e in result.effects)}{effect}; declared parameters "
        f"within {_parameter_error(result, data):.2%}; validation RMSE "
        f"{rmse['declared physics']:.4g} -> {rmse['augmented physics']:.4g} "
        f"({1 - rmse['augmented physics'] / rmse['declared physics']:.0%} cut); chosen "
        f"{result.chosen}; failures {len(result.failures)}; {seconds:.0f} s; residual "
        f"Ljung-Box p declared {_whiteness(result.baseline, data)}, augmented "
        f"{_whiteness(result.final, data)}"
    )
    for note in result.notes:
        if "tell them apart" in note:
            print(f"  {note}")
    return {
        "system": name,
        "samples": len(data.u),
        "effects": ", ".join(e.name for e in result.effects),
        "right kind": any(isinstance(e, kind) for e in result.effects),
        "hidden effect's parameter": fitted,
        "declared parameters within": _parameter_error(result, data),
        "val RMSE declared": rmse["declared physics"],
        "val RMSE augmented": rmse["augmented physics"],
        "chosen": result.chosen,
        "failures": len(result.failures),
        "loop (s)": seconds,
    }


def again(name: str, data, result, settings, row=None) -> dict:
    """The loop run on the physics ``result`` returned, started at its fitted values."""
    physics = warm_physics(result.final.physics_, result.final)
    second, seconds = _timed_loop(physics, data, settings)
    rmse, cv = _validation(second, data), second.cv_errors
    nan = float("nan")
    print(
        f"{name} again: effects added {[e.name for e in second.effects]}; CV RMSE "
        f"{cv.get('baseline', nan):.4g} -> {cv.get('final', nan):.4g}; validation RMSE "
        f"{rmse.get('declared physics', nan):.4g} -> {rmse.get('augmented physics', nan):.4g}; "
        f"chosen {second.chosen}; failures {len(second.failures)}; {seconds:.0f} s; "
        f"residual Ljung-Box p {_whiteness(second.final, data)}"
    )
    for failure in second.failures:
        print(f"  failure: {failure}")
    return {
        "system": name,
        "effects added": ", ".join(e.name for e in second.effects),
        "CV RMSE before": cv.get("baseline", nan),
        "CV RMSE after": cv.get("final", nan),
        "val RMSE before": rmse.get("declared physics", nan),
        "val RMSE after": rmse.get("augmented physics", nan),
        "chosen": second.chosen,
        "failures": len(second.failures),
    }


def write_json(rows: list, again_rows: list, args) -> None:
    """The results so far, merged with earlier rows of the same file for other systems."""
    import json

    from _results import default_path, records_table, write_results  # run as a script

    name = "bench_loop_generators_short" if args.short else "bench_loop_generators"
    path = default_path(name) if args.json is None else args.json
    if args.names and os.path.exists(path):
        earlier = json.load(open(path, encoding="utf-8"))["data"]
        done = {r["system"] for r in rows}
        rows = [r for r in earlier["rows"] if r["system"] not in done] + rows
        again_rows = [r for r in earlier["again"] if r["system"] not in done] + again_rows
    title = "The loop on each generator (seed 0; validation RMSE, init_window protocol)"
    tables = [records_table(title, rows)]
    if again_rows:
        tables.append(records_table("The loop run again on the physics it returned", again_rows))
    data = {"rows": rows, "again": again_rows}
    write_results(name, tables, path=path, data=data)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", choices=[*SYSTEMS, []], default=[])
    parser.add_argument("--short", action="store_true", help="the test suite's lengths")
    parser.add_argument("--delta", action="store_true", help="also fit the sparse corrections")
    parser.add_argument(
        "--again", action="store_true", help="run the loop again on the physics it returned"
    )
    parser.add_argument(
        "--lm-scaling", choices=("global", "per-variable"), default="per-variable",
        help="Levenberg-Marquardt's scaling in every fit (LoopSettings.lm_scaling)",
    )  # fmt: skip
    parser.add_argument(
        "--max-iter", type=int, default=LoopSettings.max_iter,
        help="every fit's iteration limit (LoopSettings.max_iter)",
    )  # fmt: skip
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args(argv)
    rows, again_rows = [], []
    for name in args.names or SYSTEMS:
        outcome = run(name, args.short, args.delta, args.lm_scaling, args.max_iter)
        rows.append(outcome[-1])
        if args.again:
            again_rows.append(again(name, *outcome))
        jax.clear_caches()  # each candidate compiles its own program: release them
        write_json(rows, again_rows, args)


if __name__ == "__main__":
    main()
