"""Markdown report with PNG figures of a closed-loop run."""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field
from numbers import Real
from pathlib import Path

import numpy as np

from ..certify import UnidentifiableWarning, identifiability
from ..effects import DictionaryTerm
from ._energy import power_sentence
from ._evidence import analyse_model
from ._hypotheses import _signals
from ._scoring import MODEL_LABELS, _protocol_metrics, checked_records

__all__ = ["write_report"]


@dataclass(frozen=True)
class _Units:
    """The units a report is written in: a unit per input or output name and the seconds
    per sample (``None``: time in samples)."""

    units: dict = field(default_factory=dict)
    sampling_time: float | None = None

    def times(self, n: int) -> np.ndarray:
        """The x-axis of a record of ``n`` samples: ``k * sampling_time``, or ``k``."""
        k = np.arange(n, dtype=float)
        return k if self.sampling_time is None else k * self.sampling_time

    @property
    def time_label(self) -> str:
        return "sample" if self.sampling_time is None else "time [s]"

    def label(self, text: str, name: str | None = None) -> str:
        """``text`` followed by the unit of ``name`` (``text`` itself by default), if any."""
        unit = self.units.get(text if name is None else name)
        return text if unit is None else f"{text} [{unit}]"

    def rmse(self, outputs: list[str]) -> str:
        """``" [unit]"`` when every output has that one unit (an RMSE's unit), else ``""``."""
        found = {self.units.get(name) for name in outputs}
        return f" [{found.pop()}]" if len(found) == 1 and None not in found else ""

    def outputs(self, result) -> str:
        """``"; output `x2` in V"`` for the outputs with a unit (``""`` for none)."""
        given = [f"`{n}` in {self.units[n]}" for n in _names(result) if n in self.units]
        return f"; output {', '.join(given)}" if given else ""

    def sentence(self, result) -> str:
        """The report's one statement of its units."""
        names = [*result.physics.input_names, *_names(result)]
        given = ", ".join(f"`{n}` in {self.units[n]}" for n in names if n in self.units)
        time = (
            "time in samples"
            if self.sampling_time is None
            else f"time in s (sampling time {self.sampling_time:g} s)"
        )
        return (
            f"Units: {given or 'none given for the inputs and outputs'}; {time}. Simulation "
            "errors (RMSE) are in the output's unit. States and fitted parameters are in the "
            "units of the declared physics: a state is in an output's unit only where the "
            "physics reads that output from it unscaled."
        )


def _checked_records(records) -> dict:
    """``records`` as a dict of validated ``(u, z)`` pairs holding ``"estimation"``
    (`checked_records`), or an error naming ``records`` and what is wrong."""
    checked = checked_records(records)
    if "estimation" not in checked:
        raise ValueError(
            "records must hold an 'estimation' entry, the (u, z) record the loop was fitted "
            f"on; got the entries {sorted(map(str, checked))}."
        )
    return checked


def _checked_units(units, physics) -> dict:
    """``units`` as a dict of input or output name to unit string (``{}`` for ``None``)."""
    if units is None:
        return {}
    if not isinstance(units, dict):
        raise TypeError(f"units must be a dict of name to unit, got {type(units).__name__}.")
    known = [*physics.input_names, *(physics.output_names or ())]
    unknown = [name for name in units if name not in known]
    if unknown:
        raise ValueError(
            f"units names {unknown}, which are neither inputs nor outputs of the physics; "
            f"known names: {known}."
        )
    bad = {name: unit for name, unit in units.items() if not isinstance(unit, str) or not unit}
    if bad:
        raise TypeError(f"units must map each name to a non-empty string, got {bad}.")
    return dict(units)


def _checked_sampling_time(sampling_time) -> float | None:
    """``sampling_time`` as a positive finite float (seconds per sample), or ``None``."""
    if sampling_time is None:
        return None
    if isinstance(sampling_time, bool) or not isinstance(sampling_time, Real):
        raise TypeError(
            f"sampling_time must be a number of seconds per sample, got {sampling_time!r}."
        )
    if not (math.isfinite(sampling_time) and sampling_time > 0):
        raise ValueError(f"sampling_time must be finite and > 0 seconds, got {sampling_time!r}.")
    return float(sampling_time)


def _table(rows: list[dict], unit: str = "") -> list[str]:
    """The scores of ``rows``; ``unit`` (``" [V]"`` or ``""``) follows the RMSE header."""
    lines = [f"| model | record | protocol | RMSE{unit} | fit % |", "|---|---|---|---|---|"]
    lines += [
        f"| {r['model']} | {r['record']} | {r['protocol']} | {_score_cells(r)} |" for r in rows
    ]
    return lines


def _score_cells(row: dict) -> str:
    """RMSE and fit of a row, or where its simulation diverged."""
    if row.get("diverged_at") is not None:
        return f"diverged from sample {row['diverged_at']} | — "
    return f"{row['rmse']:.4f} | {row['fit_percent']:.1f}"


def _json_rows(rows: list[dict]) -> list[dict]:
    """``rows`` with the scores of diverged simulations as ``null`` (strict JSON)."""
    return _finite(rows)


def _figure(figsize, **grid):
    """A matplotlib figure and its axes, without pyplot: no global backend or state is
    touched, and matplotlib is imported only when a report is written (not by the worker
    processes of the loop, which import this package)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(**grid)


def _figure_outputs(result, u, z, path: Path, title: str, axis: _Units) -> None:
    """The measured first output, each model's simulation of it and their residuals."""
    fig, axes = _figure((9, 5.5), nrows=2, ncols=1, sharex=True)
    z = np.asarray(z, float).reshape(len(u), -1)[:, 0]
    time = axis.times(len(z))
    axes[0].plot(time, z, "k", lw=1.2, label="measured")
    for key in dict.fromkeys(("baseline", "final", result.chosen)):
        z_sim = getattr(result, key).simulate(u).outputs[:, 0]
        axes[0].plot(time, z_sim, lw=1, label=MODEL_LABELS[key])
        axes[1].plot(time, z - z_sim, lw=1, label=MODEL_LABELS[key])
    axes[0].set_title(title)
    axes[0].legend(loc="best", fontsize=8)
    axes[0].set_ylabel(axis.label(_names(result)[0]))
    axes[1].set_ylabel(axis.label("residual", _names(result)[0]))
    axes[1].set_xlabel(axis.time_label)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _figure_correction(result, u, path: Path, axis: _Units) -> bool:
    """Each hypothesis' correction against the variable it concentrates on."""
    hypotheses = [h for h in result.hypotheses if h.correction is not None]
    if not hypotheses or result.evidence is None:
        return False
    est = result.evidence
    run = est.simulate(u)
    fig, axes = _figure((4.5 * len(hypotheses), 3.6), nrows=1, ncols=len(hypotheses))
    signals = _signals(est, run, u)
    for ax, hyp in zip(np.atleast_1d(axes), hypotheses, strict=True):
        variable = hyp.region[0] if hyp.region else (hyp.variables or list(signals))[0]
        ax.plot(signals[variable], hyp.correction, ".", ms=2)
        ax.set_xlabel(axis.label(f"{variable} (simulated)", variable))
        what = "linearised δ" if hyp.source == "evidence" else "fitted δ"
        ax.set_ylabel(f"{what}, {hyp.equation} equation")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True


BOUND_TOLERANCE = 1e-6
"""A free parameter within this relative distance of a bound is flagged as at it."""


def parameter_status(result, name: str, value: float) -> str:
    """``"fixed"`` (declared so), ``"held"`` (by the loop, on a direction the data leave
    undetermined), ``"at bound"`` or ``"free"``: how the final fit treats ``name``."""
    declared = {**result.physics.parameters}
    for effect in result.effects:
        declared.update(effect.parameters())
    final = result.final.physics_.parameters[name]
    if name in declared and declared[name].fixed:
        return "fixed"
    if final.fixed:
        return "held"
    scale = max(abs(value), 1.0)
    bounds = [b for b in final.bounds if b is not None and np.isfinite(b)]
    return "at bound" if any(abs(value - b) <= BOUND_TOLERANCE * scale for b in bounds) else "free"


def parameter_facts(result, u, z) -> tuple[dict, str]:
    """``{name: {value, standard_error, status}}`` of the final fit (Gauss-Newton standard
    errors, `None` where the parameter is not fitted) and the identifiability verdict."""
    est = result.final
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnidentifiableWarning)
        report = identifiability(est, u, z, include_omega=False)
    facts = {}
    for name, value in est.parameters_.items():
        status = parameter_status(result, name, float(value))
        error = report.standard_errors.get(name) if status in ("free", "at bound") else None
        facts[name] = {"value": float(value), "standard_error": error, "status": status}
    return facts, report.verdict


def _parameter_lines(facts: dict, verdict: str, outputs: str = "") -> list[str]:
    """Fitted parameters with their standard errors, status and the identifiability verdict;
    ``outputs`` names the outputs' units (see `_Units.outputs`)."""
    lines = [
        f"Values in the units of the declared physics{outputs}.",
        "",
        "| augmented physics | value | standard error | status |",
        "|---|---|---|---|",
    ]
    for name, fact in facts.items():
        error = fact["standard_error"]
        shown = "—" if error is None else f"{error:.3g}"
        lines.append(f"| {name} | {fact['value']:.6g} | {shown} | {fact['status']} |")
    notes = [
        "",
        "Status: *fixed* as declared; *held* by the loop at its fitted value on a direction "
        "the data leave undetermined; *at bound* where the fit ended on a bound.",
    ]
    return lines + notes + ["", f"Identifiability (Assumption 1): {verdict}.", ""]


def _hypothesis_lines(result) -> list[str]:
    lines = [
        "Each term's gain is the fraction of the declared physics' simulation cost it would "
        "remove alone once the declared parameters re-adjust (first order); terms the "
        "parameters can absorb carry none.",
        "",
    ]
    for hyp in result.hypotheses:
        if hyp.source == "evidence":
            head = f"(evidence; strongest term's gain {hyp.gain:.1%})"
            columns = "  | term | Ω̂ (linearised) | RMS contribution | share of the gain |"
        else:
            head = f"({hyp.source} on the declared physics)"
            columns = "  | term | Ω (fitted) | RMS contribution | share |"
        lines += [f"- **{hyp.sentence}** {head}", "", columns, "  |---|---|---|---|"]
        lines += [
            f"  | {t.feature} | {t.coefficient:.4g} | {t.contribution:.4g} | {t.share:.1%} |"
            for t in hyp.terms[:8]
        ]
        lines.append("")
    if not result.hypotheses:
        return ["- No dictionary term explains what the declared physics misses.", ""]
    return lines


def _alone_cell(alone: dict, name: str) -> str:
    return f"{alone[name]:.4g}" if name in alone else "not fitted (max_candidates, fit_top)"


def _candidate_lines(result, unit: str = "") -> list[str]:
    alone = dict(result.single_fits)
    head = f"| candidate effect | why | estimation RMSE{unit} fitted alone |"
    lines = [head, "|---|---|---|"]
    lines += [
        f"| `{c.effect.name}` | {c.reason} | {_alone_cell(alone, c.effect.name)} |"
        for c in result.candidates
    ]
    return lines


def _selection_lines(result, records: dict, units: _Units, trail: tuple) -> list[str]:
    """The CV trail of the effect sets, each also scored on the other records: ``trail`` is
    ``(window, scores)``, the ``init_window`` of the rows and `set_scores`. What every
    structural step did."""
    window, scores = trail
    others = [name for name in records if name != "estimation"]
    unit = units.rmse(_names(result))
    head = f"| model | cross-validated RMSE{unit} (estimation record) |"
    lines = [head + "".join(f" {n} RMSE{unit} (init_window={window}) |" for n in others)]
    lines += ["|---|---|" + "---|" * len(others)]
    for name, score in result.selection:
        cells = [_score_cell(scores[name].get(n)) for n in others]
        lines.append(f"| {name} | {score:.4f} |" + "".join(f" {c} |" for c in cells))
    chosen = _added_lines(result, records["estimation"][0])
    added = (
        f"Effects added (parameters in the units of the declared physics{units.outputs(result)}):"
    )
    return (
        lines
        + _set_parameter_lines(result)
        + ["", added, ""]
        + (chosen or ["- none improved the CV score"])
    )


def _added_lines(result, u) -> list[str]:
    """A line per added effect: what it states, its fitted parameters and, for a term in a
    velocity's equation, where its energy goes (`power_sentence`)."""
    if not result.effects:
        return []
    values = result.final.parameters_
    states = np.asarray(result.final.simulate(u).states, float)
    u = np.asarray(u, float).reshape(len(states), -1)
    lines = []
    for e in result.effects:
        parts = [
            e.describe(result.physics.state_names, _names(result), values),
            ", ".join(f"{k} = {values[k]:.4g}" for k in e.parameters() if k in values),
            power_sentence(e, result.physics, values, states, u),
            STAND_IN if isinstance(e, DictionaryTerm) else "",
        ]
        lines.append(f"- `{e.name}`: " + "; ".join(part for part in parts if part))
    return lines


STAND_IN = (
    "a dictionary term promoted as it is: it lowers the error but names no physical law "
    "(a stand-in for what the physics lacks)"
)
"""What the report says of an added dictionary term."""


def _set_parameter_lines(result) -> list[str]:
    """Each cross-validated set's fitted parameters: whether the physics it leaves is the
    plant's can only be judged from them."""
    lines = []
    for name, _ in result.selection:
        est = result.set_fits.get(name)
        values = getattr(est, "parameters_", None)
        if values:
            shown = ", ".join(f"{k} = {v:.4g}" for k, v in values.items())
            lines.append(f"- {name}: {shown}")
    return ["", "Fitted parameters of each set:", "", *lines] if lines else []


def set_scores(result, records: dict, window: int) -> dict[str, dict]:
    """``{set label: {record: overall metrics}}``: each set of the CV trail, its fit on the
    estimation record scored on every other record (``init_window`` protocol, ``window``
    samples); a set whose fit failed has no scores."""
    others = {name: pair for name, pair in records.items() if name != "estimation"}
    return {
        name: {
            record: _protocol_metrics(est, u, z, "init_window", window)["overall"]
            for record, (u, z) in others.items()
        }
        if (est := result.set_fits.get(name)) is not None
        else {}
        for name, _ in result.selection
    }


def _score_cell(overall: dict | None) -> str:
    """A set's RMSE on a record, where its simulation diverged, or a dash (no fit)."""
    if overall is None:
        return "—"
    if overall["diverged_at"] is not None:
        return f"diverged from sample {overall['diverged_at']}"
    return f"{overall['rmse']:.4f}"


def rows_window(rows: list[dict]) -> int:
    """The ``init_window`` of the rows' ``init_window`` protocol (50, that protocol's
    default, for rows that do not say)."""
    windows = (r.get("init_window") for r in rows if r.get("protocol") == "init_window")
    return next((w for w in windows if w is not None), 50)


def _validation_rmse(rows: list[dict], label: str) -> str:
    """The validation RMSE of the model ``label`` in ``rows`` (``init_window``), or a dash."""
    for row in rows:
        if (row["model"], row["record"], row["protocol"]) == (label, "validation", "init_window"):
            return "—" if row.get("rmse") is None else f"{row['rmse']:.4f}"
    return "—"


def _choice_lines(result, rows: list[dict], unit: str = "") -> list[str]:
    """Cross-validated error of every final model, its validation error beside it (only
    scored: the choice is the CV error's), and the one chosen."""
    lines = [
        f"| model | cross-validated RMSE{unit} (estimation record) "
        f"| validation RMSE{unit} (init_window) |",
        "|---|---|---|",
    ]
    for key, cv in result.cv_errors.items():
        label = MODEL_LABELS[key]
        chosen = " (chosen)" if key == result.chosen else ""
        lines.append(f"| {label}{chosen} | {cv:.4f} | {_validation_rmse(rows, label)} |")
    return lines + [""]


def _warning_lines(result) -> list[str]:
    """The warnings of the loop's internal fits, counted (the user's own are printed)."""
    if not result.warnings:
        return ["- none", ""]
    return [f"- {count} × {kind}" for kind, count in result.warnings.items()] + [""]


def _timing_lines(result) -> list[str]:
    """Wall time of each stage of the loop."""
    if not result.timings:
        return ["- not recorded", ""]
    lines = ["| stage | wall time (s) |", "|---|---|"]
    lines += [f"| {stage} | {seconds:.1f} |" for stage, seconds in result.timings.items()]
    return lines + [f"| total | {sum(result.timings.values()):.1f} |", ""]


def _failure_lines(result) -> list[str]:
    if not result.failures:
        return ["- none", ""]
    return [f"- {line}" for line in result.failures] + [""]


def _remaining_lines(result) -> list[str]:
    """The sparse δ fitted on the augmented physics, if it was fitted."""
    after, before = result.final_with_delta, result.with_delta
    if after is None:
        return ["Not fitted (`fit_delta=False`, or the fit failed: see above).", ""]
    lines = _gamma_lines(result.final_gamma_path, after.gamma)
    count = f"Non-zero δ terms: {int(after.support_.sum())}"
    if before is not None:
        count += f" (on the declared physics: {int(before.support_.sum())})"
    return lines + [count + ".", ""] + after.equations() + [""]


def _output_lines(result) -> list[str]:
    """The sparse correction of the output map on the augmented physics, if fitted."""
    est = result.final_with_output_delta
    if est is None:
        return ["Not fitted (`fit_output_delta=False`, outputs that do not read states, or a "
                "failed fit: see the notes and failures).", ""]  # fmt: skip
    lines = _gamma_lines(result.output_gamma_path, est.gamma)
    count = f"Non-zero terms: {int(est.support_.sum())} of {est.coef_.size}."
    return lines + [count, ""] + est.equations()[len(est.physics_.state_names) :] + [""]


def _gamma_lines(path, chosen: float) -> list[str]:
    """The support path as a table, or the single γ fitted."""
    if path is None:
        return [f"Single γ = {chosen:g} (no search).", ""]
    folds = path.cv_error.shape[1]
    how = f"{folds}-fold CV" if folds > 1 else "the held-out tail"
    return [
        f"Support path: γ from γ_max = {path.gamma_max:.4g} down, chosen by {how} on the "
        f"estimation record, before the first γ where a held-out fold diverges (errors in "
        f"output standard deviations; chosen γ = {chosen:.4g}):",
        "",
        "```",
        path.summary(),
        "```",
        "",
    ]


def _names(result) -> list[str]:
    return list(result.physics.output_names or ["z1"])


def _residual_section(result, records, label_key) -> list[str]:
    est = getattr(result, label_key)
    u, z = records["estimation"]
    report = analyse_model(
        est, u, z, result.augmented_physics if "final" in label_key else result.physics
    )
    return [f"### {MODEL_LABELS[label_key]}, estimation record", "", report.summary(), ""]


def write_report(
    result,
    rows,
    records: dict,
    directory,
    *,
    title: str,
    notes=(),
    units: dict[str, str] | None = None,
    sampling_time: float | None = None,
) -> Path:
    r"""Write ``report.md``, its figures and ``results.json`` into ``directory``.

    Parameters
    ----------
    result : LoopResult
        What [`close_the_loop`][sk_offwhite.loop.close_the_loop] found.
    rows : list of dict
        The scores of [`score_models`][sk_offwhite.loop.score_models] on ``records``; the
        effect sets the loop cross-validated are scored with the same ``init_window``.
    records : dict
        Record name to its ``(u, z)`` pair; it must hold ``"estimation"``, the record the
        loop was fitted on. Each record gets a figure of its outputs.
    directory : str or path
        Where the report goes (made if missing).
    title : str
        The report's title.
    notes : sequence of str, default=()
        Lines written under the title (data, protocol, anything the reader needs first).
    units : dict of str to str, default=None
        The unit of each input and output, by the physics' ``input_names`` and
        ``output_names`` (for example ``{"u": "V", "x2": "V"}``); names left out have none.
        The RMSE headers and the figures' axes name the outputs' unit. States and fitted
        parameters are in the units of the declared physics, which the report says once.
    sampling_time : float, default=None
        Seconds per sample: the figures' x-axis is then the time $k\,T_s$ in seconds,
        otherwise the sample index $k$.

    Returns
    -------
    Path
        The path of ``report.md``. ``results.json`` holds the report's facts, with
        ``units`` and ``sampling_time`` as given and ``set_scores``: each cross-validated
        effect set's fit scored on every record but the estimation one (`set_scores`).

    Raises
    ------
    TypeError, ValueError
        Naming ``records``, ``units`` or ``sampling_time`` when it is not what is said above,
        before anything is written.
    """
    records = _checked_records(records)
    axis = _Units(_checked_units(units, result.physics), _checked_sampling_time(sampling_time))
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    for name, (u, z) in records.items():
        figure = out / f"outputs_{name}.png"
        _figure_outputs(result, u, z, figure, f"{title}: {name} record", axis)
    u_est = records["estimation"][0]
    has_delta_fig = _figure_correction(result, u_est, out / "correction.png", axis)
    facts, verdict = parameter_facts(result, *records["estimation"])
    window = rows_window(rows)
    trail = (window, set_scores(result, records, window))
    lines = _report_lines(result, rows, records, axis, (facts, verdict, has_delta_fig, trail))
    head = [f"# {title}: closed-loop report", "", *notes, "", axis.sentence(result), ""]
    (out / "report.md").write_text("\n".join(head + lines), encoding="utf-8")
    facts = results_facts(result, rows, facts, verdict)
    facts.update(units=dict(axis.units), sampling_time=axis.sampling_time, set_scores=trail[1])
    table = json.dumps(_finite(facts), indent=2, allow_nan=False, default=_plain)
    (out / "results.json").write_text(table, encoding="utf-8")
    return out / "report.md"


def _report_lines(result, rows, records, axis: _Units, found) -> list[str]:
    """The report's sections under its title; ``found`` is ``(parameter facts,
    identifiability verdict, whether the correction figure was drawn, the trail's
    ``(init_window, set_scores)``)``."""
    facts, verdict, has_delta_fig, trail = found
    unit = axis.rmse(_names(result))
    lines = (
        ["## Simulation errors", ""] + _table(rows, unit) + ["", "## Residual before and after", ""]
    )
    lines += _residual_section(result, records, "baseline")
    lines += _residual_section(result, records, "final")
    lines += ["## What the declared physics cannot explain", ""]
    lines += _hypothesis_lines(result)
    lines += [f"- {note}" for note in result.notes] + ([""] if result.notes else [])
    lines += ["![correction](correction.png)", ""] if has_delta_fig else []
    lines += ["## Effects tried and added", ""] + _candidate_lines(result, unit) + [""]
    lines += _selection_lines(result, records, axis, trail) + [""]
    lines += ["## Parameters", ""] + _parameter_lines(facts, verdict, axis.outputs(result))
    if result.with_delta is not None:
        lines += ["## Sparse correction on the declared physics", ""]
        lines += _gamma_lines(result.gamma_path, result.with_delta.gamma)
    lines += ["## Remaining correction on the augmented physics", ""]
    lines += _remaining_lines(result)
    lines += ["## Correction of the output map on the augmented physics", ""]
    lines += _output_lines(result)
    lines += ["## Model chosen (lowest cross-validated error)", ""]
    lines += _choice_lines(result, rows, unit)
    lines += ["## Fits that failed", ""] + _failure_lines(result)
    lines += ["## Warnings of the search's internal fits", ""] + _warning_lines(result)
    lines += ["## Time per stage", ""] + _timing_lines(result)
    return lines + [f"![outputs {n}](outputs_{n}.png)" for n in records] + [""]


def results_facts(result, rows, parameters: dict, verdict: str) -> dict:
    """What the report says, as data (`_finite` makes it strict JSON): the scores, the
    chosen model, the effects with their descriptions, the parameters, the CV errors,
    failures, notes, warnings, timings."""
    values = result.final.parameters_
    effects = [
        {
            "name": effect.name,
            "description": effect.describe(result.physics.state_names, _names(result), values),
            "parameters": {k: float(values[k]) for k in effect.parameters() if k in values},
        }
        for effect in result.effects
    ]
    return {
        "rows": rows,
        "chosen": result.chosen,
        "effects": effects,
        "parameters": parameters,
        "identifiability": verdict,
        "cv_errors": dict(result.cv_errors),
        "selection": [list(row) for row in result.selection],
        "failures": list(result.failures),
        "notes": list(result.notes),
        "warnings": dict(result.warnings),
        "timings": dict(result.timings),
    }


def _finite(value):
    """``value`` with every non-finite float as ``None`` (strict JSON), nested."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if np.isfinite(value) else None
    return value


def _plain(value):
    """NumPy scalars and arrays as JSON values."""
    if isinstance(value, np.generic):
        return _finite(value.item())
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")
