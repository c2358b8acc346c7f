"""The functions of the variables' kinds on every generator: do they name the missing law?

For each generator (seed 0) the declared physics is fitted to the estimation record, as
the loop's first stage does, and the loop's note on the functions of the variables' kinds
(``LoopSettings(kind_notes=True)``, the default) is read with the dictionary a user
starts with: the polynomials of degree 2 in every state and input. Printed per system:
the hidden effect, what the note names first in the hidden effect's equation (the
function, the share of the declared physics' cost it removes alone and what it is a sign
of), the dictionary's best term there, and, where the hidden law has a shape a physicist
would try first, whether that is the one named (``SYSTEMS``).

Run: ``python benchmarks/bench_kind_notes.py [NAME ...]``; writes
``benchmarks/results/bench_kind_notes.json``.
"""

from __future__ import annotations

import argparse
import re
import time
import warnings

import pysindy as ps
from _results import records_table, write_results

from sk_offwhite.datasets import (
    make_cascaded_tanks,
    make_clearance_coupling,
    make_convective_block,
    make_coulomb_drive,
    make_dead_zone_motor,
    make_diode_rc,
    make_duffing_oscillator,
    make_friction_oscillator,
    make_heated_block,
    make_lagged_drive,
    make_leaky_tank,
    make_pendulum_drag,
    make_saturating_actuator,
)
from sk_offwhite.loop import LoopSettings
from sk_offwhite.loop._evidence import fit_declared, read_kind_notes
from sk_offwhite.loop._search import Search

FASTER = "an effect that grows faster than linearly"
"""The reading of a hardening spring, a dead zone and a clearance: an effect that grows
faster than linearly in its variable."""

SYSTEMS = {
    "coulomb_drive": (make_coulomb_drive, {}, ("a Coulomb friction",)),
    "friction": (make_friction_oscillator, {}, ("a Coulomb friction",)),
    "stribeck": (make_friction_oscillator, {"stribeck": 0.5}, ("a Coulomb friction",)),
    "pendulum_drag": (make_pendulum_drag, {}, ("a drag",)),
    "power_drag": (make_pendulum_drag, {"exponent": 1.5}, ("a drag",)),
    "saturating_actuator": (make_saturating_actuator, {}, ("a saturation",)),
    "heater_limit": (make_heated_block, {}, ("a saturation",)),
    "convective_block": (make_convective_block, {}, ("a convective loss", "a radiative loss")),
    "duffing": (make_duffing_oscillator, {}, (FASTER,)),
    "dead_zone": (make_dead_zone_motor, {}, (FASTER,)),
    "diode_rc": (make_diode_rc, {}, None),
    "clearance": (make_clearance_coupling, {}, (FASTER,)),
    "lagged_drive": (make_lagged_drive, {}, None),
    "leaky_tank": (make_leaky_tank, {}, None),
    "cascaded_tanks": (make_cascaded_tanks, {}, None),
}
"""Name: (generator, its options, the meaning (or meanings) the note should give first
where the hidden law has a shape of the table in ``sk_offwhite.loop._kind_terms``, else
``None``)."""

NOTE = re.compile(
    r"In the (\S+) equation the functions of the variables' kinds explain more than the "
    r"dictionary: (.+) of the declared physics' cost, each alone \(the dictionary's best, "
    r"(.+): (\d+)%\)\."
)
FOUND = re.compile(r"(\S+) (\d+)% \(([^)]+)\)")


def read_notes(data) -> tuple[Search, float]:
    """The search whose ``notes`` hold the kinds' notes of ``data``'s declared physics
    (fitted first), and the seconds the note took."""
    search = Search(data.u, data.z, LoopSettings(n_jobs=1))
    _, start, run, _ = fit_declared(search, data.physics)
    began = time.perf_counter()
    read_kind_notes(search, start, ps.PolynomialLibrary(degree=2), run.states)
    return search, time.perf_counter() - began


def note_of(notes: list[str], equation: str) -> tuple[str, str]:
    """``(first function named, the dictionary's best)`` of ``equation``'s note, each with
    its share (``"none"`` where the note says nothing of it)."""
    for note in notes:
        match = NOTE.match(note)
        if match and match.group(1) == equation:
            name, share, meaning = FOUND.findall(match.group(2))[0]
            return f"{name} {share}% ({meaning})", f"{match.group(3)} {match.group(4)}%"
    return "none", "none"


def run(name: str) -> dict:
    """One generator's row, printed."""
    make, options, expected = SYSTEMS[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = make(random_state=0, **options)
        search, seconds = read_notes(data)
    equation = data.physics.state_names[data.hidden_effect["equation"]]
    first, best = note_of(search.notes, equation)
    row = {
        "system": name,
        "hidden effect": data.hidden_effect["description"],
        "equation": equation,
        "first function named": first,
        "dictionary's best": best,
        "expected": " or ".join(expected or ("-",)),
        "named": None if expected is None else any(meaning in first for meaning in expected),
        "failures": "; ".join(search.failures) or "none",
        "note (s)": seconds,
    }
    print({k: v for k, v in row.items() if k != "hidden effect"}, flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", choices=[*SYSTEMS, []], default=[])
    args = parser.parse_args()
    rows = [run(name) for name in args.names or SYSTEMS]
    title = (
        "The kinds' note on each generator (seed 0; dictionary: polynomials of degree 2; "
        "shares of the declared physics' cost each term removes alone)"
    )
    write_results("bench_kind_notes", [records_table(title, rows)], data={"rows": rows})


if __name__ == "__main__":
    main()
