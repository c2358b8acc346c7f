"""A reproducible audit of bad inputs to sk_offwhite's public entry points.

Run with::

    python benchmarks/audit_bad_inputs.py [--only PATTERN] [--limit-seconds S] [--jobs N]

It runs every case of the table in ``benchmarks/audit_cases.py`` (over 320 bad, or
hostile-but-fair, inputs to ``GreyBoxSparseRegressor``, ``Parameter``, ``PhysicsModel``,
``fit_gamma_path``, the scikit-learn searches, ``close_the_loop``, ``LoopSettings``,
``score_models`` and the ``datasets``, ``diagnose`` and ``certify`` helpers) in ``N`` worker
processes (default 2), each case under a time limit, classifies its outcome, prints a tally by
class and by entry point and the list of every case in the classes ``silent``, ``obscure``,
``hang`` and ``crash``, and writes every case to ``benchmarks/results/audit_bad_inputs.json``
(with ``--only``, only to the file ``--out`` names). ``--list`` prints the table without
running it. The whole table takes 15-20 minutes with two workers on a 2-core machine.

Outcome classes, and the rules that assign them automatically
-------------------------------------------------------------
Each case states what is wrong with its input, the outcome it expects (``expected``, for a
person to review; it is not used to classify), the words a clear message must hold (the
offending argument's name, ``names``), and, for an input that may be accepted, what "right"
is (``right``, checked by its ``check`` function against the truth of the noise-free data or a
fit on clean data).

``clear``
    The case raised ``ValueError`` or ``TypeError`` (scikit-learn's ``InvalidParameterError``
    and ``NotFittedError`` are both) whose message names the argument (one of ``names``
    appears in it as a word) from a frame that is not inside numpy, scipy, JAX, pysindy or
    Python's own modules, *before the fitting core started* where the case says an earlier
    check is possible. Also ``clear`` (subclass ``warned``): the input was accepted, the
    result is not right, and a warning raised while the case ran names the problem (one of
    ``names`` or ``warn_words`` appears in it), which is what cross-validation misuse should
    get when it cannot be refused.
``correct``
    Accepted, and ``check`` says the result is right (its ``right`` says what that is).
``harmless``
    Accepted, and ``check`` says the result is unaffected by the oddity.
``obscure``
    Raised, but not as ``clear`` says: another exception type (``AttributeError``,
    ``KeyError``, ``IndexError``, ...), a message that does not name the argument, or a raise
    from deep inside numpy / JAX / scipy / pysindy / Python.
``silent``
    Accepted, and the result is wrong, NaN or misleading (``check`` fails, or the case has no
    ``check`` because the input should have been refused) with no warning that names the
    problem (subclass ``accepted``). Also ``silent``: a refusal that comes only after the
    fitting core has run (the package's ``fit_records`` was entered) where the case says an
    earlier check was possible, or, for the closed loop, after more than 1 s (subclass
    ``late``); and a case whose ``on_timeout`` is ``silent`` (an invalid loop setting that is
    accepted and fitted) still running at its limit (subclass ``slow-accept``).
``hang``
    Still running at the per-case limit (``--limit-seconds``, default 60 s; a few long cases,
    the searches and the loop's control run, have their own; the loop's cases use
    ``--loop-limit-seconds``, default 6 s, and are ``slow-accept`` instead).
``crash``
    The worker process died while running the case (segfault, abort, out of memory), and
    died again when the case was run once more in a fresh worker (a death after the case's
    limit counts as running past it: the timer's exception may have been raised inside
    compiled code).

Every case runs in a worker process (``--worker``) that imports the package once and runs
cases one after the other, each under ``signal.setitimer``; the parent kills and restarts a
worker that does not answer within the limit plus a grace period (``hang``) or that dies
(``crash``, after the retry above). Results do not depend on which worker ran a case, but
times include the JAX compilation a case triggers, which depends on what that worker compiled
before, and the load of the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import audit_cases  # noqa: E402 (the case table, next to this script)

CLASSES = ("clear", "correct", "harmless", "obscure", "silent", "hang", "crash")
REPORTED = ("silent", "obscure", "hang", "crash")
RESULTS = HERE / "results" / "audit_bad_inputs.json"
LATE_LOOP_SECONDS = 1.0
GRACE_SECONDS = 30.0
PREPARE_SECONDS = 300.0
RELEASE_EVERY = 25
DEEP_MODULES = ("numpy", "scipy", "jax", "jaxlib", "pysindy", "optax", "joblib", "cvxpy")
CLEAR_TYPES = (ValueError, TypeError)


# ---------------------------------------------------------------------- what a case did
class CaseTimeout(BaseException):
    """Raised by the timer inside a case (a ``BaseException``: no ``except Exception`` in
    the package swallows it)."""


@dataclass
class Outcome:
    """What running one case produced, before classification."""

    value: object = None
    error: BaseException | None = None
    error_module: str = ""
    warnings: list = field(default_factory=list)
    seconds: float = 0.0
    fit_started: bool = False
    timed_out: bool = False
    crashed: bool = False
    returncode: int | None = None


class FitWatch:
    """Whether the package's fitting core (``_estimator.fit_records``) ran since ``started``
    was last reset (``install`` wraps it, ``uninstall`` puts it back)."""

    def __init__(self):
        self.started = False
        self.original = None

    def install(self) -> None:
        import sk_offwhite._estimator as estimator_module

        original = getattr(estimator_module, "fit_records", None)
        if original is None or self.original is not None:
            return

        def watched(*args, **kwargs):
            self.started = True
            return original(*args, **kwargs)

        self.original = original
        estimator_module.fit_records = watched

    def uninstall(self) -> None:
        import sk_offwhite._estimator as estimator_module

        if self.original is not None:
            estimator_module.fit_records = self.original
            self.original = None


WATCH = FitWatch()


def _on_alarm(signum, frame):
    raise CaseTimeout()


def innermost_module(error: BaseException) -> str:
    """Module of the frame that raised ``error`` (the last of its traceback)."""
    tb = error.__traceback__
    if tb is None:
        return ""
    while tb.tb_next is not None:
        tb = tb.tb_next
    return str(tb.tb_frame.f_globals.get("__name__", ""))


def execute(case, context, limit: float) -> Outcome:
    """Run ``case`` against ``context`` under a ``limit`` in seconds (in this process)."""
    outcome = Outcome()
    try:
        for need in case.needs:  # cached fixtures, built before the clock starts
            getattr(context, need)()
    except Exception as error:  # the audit's own fixture failed: shown as such
        outcome.error = RuntimeError(f"fixture {case.needs} failed: {error!r}")
        outcome.error_module = "fixture"
        return outcome
    WATCH.started = False
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        start = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, limit)
        try:
            outcome.value = case.run(context)
        except CaseTimeout:
            outcome.timed_out = True
        except Exception as error:  # the case's outcome, classified below
            outcome.error, outcome.error_module = error, innermost_module(error)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            outcome.seconds = time.perf_counter() - start
            signal.signal(signal.SIGALRM, previous)
    outcome.warnings = [(w.category.__name__, str(w.message)) for w in caught]
    outcome.fit_started = WATCH.started
    return outcome


# ---------------------------------------------------------------------- classification
def names_any(words, text: str, prefix: bool = False) -> bool:
    """Whether any of ``words`` appears in ``text`` as a word, or with ``prefix`` as the
    start of one (case-insensitive)."""
    end = "" if prefix else r"(?![\w])"
    for word in words:
        if re.search(rf"(?<![\w]){re.escape(word)}{end}", text, flags=re.IGNORECASE):
            return True
    return False


def scrub(text: str) -> str:
    """``text`` without this machine's paths or object addresses."""
    for path, shown in ((str(HERE.parent), "<repo>"), (sys.prefix, "<python>")):
        text = text.replace(path, shown)
    return re.sub(r" at 0x[0-9a-fA-F]+", " at 0x...", text)


def first_line(text: str) -> str:
    lines = str(text).strip().splitlines()
    return scrub(lines[0][:300] if lines else "")


@dataclass
class Verdict:
    """A case's class, its subclass (``late``, ``warned``, ``slow-accept``, ...) and why."""

    outcome: str
    subclass: str
    detail: str


def is_late(case, outcome: Outcome) -> bool:
    """A refusal after fitting work had started, where the case says it could come before."""
    if not case.early:
        return False
    loop_late = case.entry in audit_cases.LOOP_ENTRIES and outcome.seconds > LATE_LOOP_SECONDS
    return outcome.fit_started or loop_late


def classify_error(case, outcome: Outcome) -> Verdict:
    """The class of a case that raised."""
    error = outcome.error
    message = str(error)
    deep = outcome.error_module.startswith(DEEP_MODULES) or outcome.error_module == "builtins"
    named = names_any(case.names, message)
    fitting = "fitting core ran" if outcome.fit_started else f"{outcome.seconds:.1f} s"
    if is_late(case, outcome):
        return Verdict("silent", "late", f"refused only after fitting work ({fitting})")
    if not isinstance(error, CLEAR_TYPES):
        return Verdict("obscure", "type", f"{type(error).__name__} is not ValueError/TypeError")
    if deep:
        return Verdict("obscure", "deep", f"raised inside {outcome.error_module}")
    if not named:
        return Verdict("obscure", "unnamed", f"message does not name {', '.join(case.names)}")
    return Verdict("clear", "raised", "")


def warned(case, outcome: Outcome) -> str | None:
    """The first warning raised by the case that names its problem, if any."""
    for category, message in outcome.warnings:
        if names_any(case.names, message) or names_any(case.warn_words, message, prefix=True):
            return f"{category}: {first_line(message)}"
    return None


def classify_accepted(case, outcome: Outcome, context) -> Verdict:
    """The class of a case that returned."""
    if case.check is None:
        ok, detail = False, "accepted an input that should be refused"
    else:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ok, detail = case.check(outcome.value, context)
        except Exception as error:  # the result is not even usable
            ok, detail = False, f"checking the result raised {type(error).__name__}: {error}"
    if ok:
        return Verdict(case.accept_class, "", detail)
    warning = warned(case, outcome)
    if warning is not None:
        return Verdict("clear", "warned", f"{detail}; warned: {warning}")
    return Verdict("silent", "accepted", detail)


def classify(case, outcome: Outcome, context=None) -> Verdict:
    """Apply the module docstring's rules to ``outcome``."""
    if outcome.crashed:
        return Verdict("crash", "", f"worker died (return code {outcome.returncode})")
    if outcome.timed_out:
        if case.on_timeout == "silent":
            return Verdict("silent", "slow-accept", f"still running after {outcome.seconds:.0f} s")
        return Verdict("hang", "", f"still running after {outcome.seconds:.0f} s")
    if outcome.error is not None:
        return classify_error(case, outcome)
    return classify_accepted(case, outcome, context)


def record(case, outcome: Outcome, verdict: Verdict) -> dict:
    """The JSON row of one case."""
    error = outcome.error
    return {
        "id": case.id,
        "entry": case.entry,
        "what": case.what,
        "expected": case.expected,
        "right": case.right,
        "outcome": verdict.outcome,
        "subclass": verdict.subclass,
        "detail": scrub(verdict.detail),
        "exception": None if error is None else type(error).__name__,
        "message": None if error is None else first_line(str(error)),
        "raised_in": outcome.error_module or None,
        "warnings": sorted({f"{c}: {first_line(m)}" for c, m in outcome.warnings})[:6],
        "fit_started": outcome.fit_started,
        "seconds": round(outcome.seconds, 3),
    }


def limit_for(case, limit: float, loop_limit: float) -> float:
    """The time limit of ``case``: its own, else the loop's (an accepted invalid loop setting)
    or the general one."""
    if case.limit is not None:
        return case.limit
    return loop_limit if case.on_timeout == "silent" else limit


def run_in_process(case, context, limit: float, loop_limit: float) -> dict:
    """Execute and classify one case here (the workers' and the tests' way)."""
    outcome = execute(case, context, limit_for(case, limit, loop_limit))
    return record(case, outcome, classify(case, outcome, context))


# ---------------------------------------------------------------------- worker process
def _protocol_stream():
    """The real stdout for answers; fd 1 then goes to stderr, so that what the package
    prints (progress, ``print()``) does not mix with them."""
    answers = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    return answers


def worker_main() -> None:
    """Answer ``{"id", "limit", "loop_limit"}`` lines on stdin with case rows on stdout."""
    answers = _protocol_stream()
    import sk_offwhite

    cache = os.environ.get("AUDIT_CACHE_DIR")
    if cache:
        sk_offwhite.enable_compilation_cache(cache)
    WATCH.install()
    context = audit_cases.Context()
    audit_cases.warm_up(context)
    cases = {case.id: case for case in audit_cases.build_cases()}
    answers.write(json.dumps({"ready": True}) + "\n")
    for count, line in enumerate(sys.stdin):
        request = json.loads(line)
        case = cases[request["id"]]
        row = run_in_process(case, context, request["limit"], request["loop_limit"])
        answers.write(json.dumps(row) + "\n")
        if (count + 1) % RELEASE_EVERY == 0:
            sk_offwhite.release_compiled_programs()


class Worker:
    """One worker process and the pipe to it (restarted after a hang or a crash)."""

    def __init__(self, env: dict):
        self.env = env
        self.process = None
        self.log = None

    def start(self) -> None:
        self.log = tempfile.TemporaryFile(mode="w+")
        command = [sys.executable, str(Path(__file__).resolve()), "--worker"]
        self.process = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
            text=True,
            bufsize=1,
            env=self.env,
        )
        ready = self._read(PREPARE_SECONDS)
        if ready is None or not ready.get("ready"):
            raise RuntimeError(f"an audit worker did not start: {self.log_tail()}")

    def _read(self, timeout: float) -> dict | None:
        """One answer line, or ``None`` on a timeout or the worker's death."""
        import select

        readable, _, _ = select.select([self.process.stdout], [], [], timeout)
        if not readable:
            return None
        line = self.process.stdout.readline()
        return json.loads(line) if line else None

    def log_tail(self) -> str:
        self.log.seek(0)
        return " | ".join(self.log.read().strip().splitlines()[-3:])[-400:]

    def run(self, case, limit: float, loop_limit: float, retry: bool = True) -> dict:
        """The row of ``case``. A worker that dies within the case's limit is restarted
        and the case run once more there: the death may be left over from the case before
        (one stopped by the timer), and only a case that kills a fresh worker is a crash."""
        row = self._run_once(case, limit, loop_limit)
        if retry and row["outcome"] == "crash":
            first = row["detail"]
            row = self._run_once(case, limit, loop_limit)
            crashed = row["outcome"] == "crash"
            again = "it killed a fresh worker too" if crashed else f"run again ({first})"
            row["detail"] = f"{row['detail']}; {again}" if row["detail"] else again
        return row

    def _run_once(self, case, limit: float, loop_limit: float) -> dict:
        if self.process is None:
            self.start()
        own_limit = limit_for(case, limit, loop_limit)
        request = {"id": case.id, "limit": limit, "loop_limit": loop_limit}
        started = time.perf_counter()
        self.process.stdin.write(json.dumps(request) + "\n")
        self.process.stdin.flush()
        answer = self._read(own_limit + GRACE_SECONDS + PREPARE_SECONDS * bool(case.needs))
        if answer is not None:
            return answer
        return self._lost(case, time.perf_counter() - started, own_limit)

    def _lost(self, case, seconds: float, own_limit: float) -> dict:
        """The row of a case the worker did not answer: it died, or it ran on. A death
        after the case's limit may be the timer's doing (its exception raised inside
        compiled code), so it counts as running past the limit, not as a crash."""
        try:
            self.process.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            pass  # still running: it ran past the limit
        died = self.process.returncode is not None
        crashed = died and seconds < own_limit
        outcome = Outcome(seconds=seconds, timed_out=not crashed, crashed=crashed)
        outcome.returncode = self.process.returncode
        row = record(case, outcome, classify(case, outcome))
        if crashed:
            row["detail"] += f"; worker log: {scrub(self.log_tail())}"
        elif died:
            row["detail"] += f"; the worker died (return code {outcome.returncode}) after it"
        self.stop()
        return row

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self.process = None


def worker_environment(cache_dir: str) -> dict:
    """The workers' environment: CPU only, one XLA thread each, a shared program cache."""
    env = dict(os.environ)
    env.setdefault("JAX_PLATFORMS", "cpu")
    env.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")
    env["AUDIT_CACHE_DIR"] = cache_dir
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(HERE.parent), env.get("PYTHONPATH")]))
    return env


def run_cases(cases, jobs: int, limit: float, loop_limit: float, progress=None) -> list[dict]:
    """Run ``cases`` in ``jobs`` worker processes; rows in the order of ``cases``."""
    queue = sorted(enumerate(cases), key=lambda item: item[1].limit is None)  # long ones first
    rows: dict[int, dict] = {}
    lock = threading.Lock()
    with tempfile.TemporaryDirectory(prefix="audit_xla_") as cache_dir:
        env = worker_environment(cache_dir)

        def serve() -> None:
            worker = Worker(env)
            try:
                while True:
                    with lock:
                        if not queue:
                            return
                        index, case = queue.pop(0)
                    row = worker.run(case, limit, loop_limit)
                    with lock:
                        rows[index] = row
                        if progress is not None:
                            progress(len(rows), len(cases), row)
            finally:
                worker.stop()

        threads = [threading.Thread(target=serve) for _ in range(max(1, jobs))]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    return [rows[i] for i in range(len(cases))]


# ---------------------------------------------------------------------- report
def tally(rows: list[dict]) -> dict:
    """Counts by class, and by entry point and class."""
    by_class = Counter(row["outcome"] for row in rows)
    by_entry: dict[str, Counter] = {}
    for row in rows:
        by_entry.setdefault(row["entry"], Counter())[row["outcome"]] += 1
    return {"by_class": {c: by_class.get(c, 0) for c in CLASSES}, "by_entry": by_entry}


def format_tally(rows: list[dict]) -> str:
    counts = tally(rows)
    lines = [f"{len(rows)} cases", "", "class     count"]
    lines += [f"{c:<9} {n:>5}" for c, n in counts["by_class"].items()]
    header = f"{'entry point':<31}" + "".join(f"{c[:8]:>9}" for c in CLASSES) + f"{'total':>7}"
    lines += ["", header]
    for entry, counter in sorted(counts["by_entry"].items()):
        cells = "".join(f"{counter.get(c, 0):>9}" for c in CLASSES)
        lines.append(f"{entry:<31}{cells}{sum(counter.values()):>7}")
    subclasses = Counter((r["outcome"], r["subclass"]) for r in rows if r["outcome"] == "silent")
    if subclasses:
        shown = ", ".join(f"{s or '-'}: {n}" for (_, s), n in sorted(subclasses.items()))
        lines += ["", f"silent by subclass: {shown}"]
    return "\n".join(lines)


def happened(row: dict) -> str:
    """One line on what a case did."""
    parts = []
    if row["exception"]:
        parts.append(f"{row['exception']}: {row['message']}")
    if row["detail"]:
        parts.append(row["detail"])
    if row["warnings"] and row["outcome"] == "silent":
        parts.append("warnings: " + " / ".join(row["warnings"][:2]))
    return "; ".join(parts)[:400]


def format_listing(rows: list[dict]) -> str:
    lines = []
    for cls in REPORTED:
        chosen = [row for row in rows if row["outcome"] == cls]
        lines += ["", f"== {cls} ({len(chosen)}) =="]
        for row in chosen:
            sub = f" [{row['subclass']}]" if row["subclass"] else ""
            lines.append(f"{row['id']}{sub} ({row['seconds']:.1f} s): {row['what']}")
            lines.append(f"    -> {happened(row)}")
    return "\n".join(lines)


def write_results(rows: list[dict], path: Path, settings: dict, wall: float) -> None:
    import sk_offwhite

    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "sk_offwhite": sk_offwhite.__version__,
        "python": platform.python_version(),
        "settings": settings,
        "wall_seconds": round(wall, 1),
        "tally": tally(rows),
        "cases": rows,
    }
    path.write_text(json.dumps(payload, indent=1, default=str) + "\n")


def print_table(cases) -> None:
    for case in cases:
        print(f"{case.id:<48} {case.entry:<24} expected {case.expected}: {case.what}")


def parse_arguments(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="run the cases whose id matches this regular expression")
    parser.add_argument("--limit-seconds", type=float, default=60.0, help="per-case limit")
    parser.add_argument(
        "--loop-limit-seconds",
        type=float,
        default=6.0,
        help="limit of a loop case that was accepted (then slow-accept, counted silent)",
    )
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    parser.add_argument("--out", type=Path, help=f"results file (default {RESULTS.name})")
    parser.add_argument("--list", action="store_true", help="print the case table and stop")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    return parser.parse_args(argv)


def select(cases, pattern: str | None) -> list:
    if pattern is None:
        return list(cases)
    return [case for case in cases if re.search(pattern, case.id)]


def main(argv=None) -> int:
    args = parse_arguments(argv)
    if args.worker:
        worker_main()
        return 0
    cases = select(audit_cases.build_cases(), args.only)
    if args.list:
        print_table(cases)
        return 0
    started = time.perf_counter()

    def progress(done, total, row):
        line = f"[{done}/{total}] {row['outcome']:<8} {row['seconds']:6.1f} s  {row['id']}"
        print(line, flush=True)

    rows = run_cases(cases, args.jobs, args.limit_seconds, args.loop_limit_seconds, progress)
    wall = time.perf_counter() - started
    print()
    print(format_tally(rows))
    print(format_listing(rows))
    print(f"\nwall time {wall:.0f} s with {args.jobs} worker(s)")
    out = args.out or (RESULTS if args.only is None else None)
    if out is not None:
        settings = {k: getattr(args, k) for k in ("only", "limit_seconds", "loop_limit_seconds")}
        write_results(rows, out, dict(settings, jobs=args.jobs), wall)
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
