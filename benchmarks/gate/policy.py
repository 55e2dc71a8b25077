"""What passes and what fails: the verdicts of ``check``, ``baseline`` and ``audit``.

The mechanisms live beside this module (:mod:`.regression` compares golden files,
:mod:`~benchmarks.gate.blas` measures the BLAS-kernel sensitivity, :mod:`.audit` runs the
soundness audit, :mod:`benchmarks.store.stale` finds stale rows and reports); the rules
that turn their findings into an exit code are here, in one place:

* ``check`` fails (1) on a stale committed report, on a published cell claimed ``within`` in
  ``benchmarks/gate/fidelity.yaml`` whose committed value left its tolerance
  (:mod:`benchmarks.gate.fidelity`: one line per cell; checked with the stale reports, before
  the run), on a regression subset configuration that
  changed since the baseline, and on any value outside its tolerance (a third-party plugin not
  in the baseline is listed, and fails only with ``strict``, or if it crashed, was stopped or is
  unsound: then the last line names it; a job stopped by its time budget, :mod:`.budget`, is
  also named on a line of its own with that budget); a radius
  that got smaller is called *tighter* only once proven: no ``no`` in a soundness verdict
  column (:data:`benchmarks.verdicts.SOUNDNESS_COLUMNS`) and no violation in the short
  soundness audit of that observer (:data:`PROOF_SCENARIOS`, adversarial realisations);
* ``baseline --update`` refuses (1) a run with a crash, a stop (time or memory) or a
  containment violation of a guaranteed observer (hull, or ``no`` in any soundness verdict
  column) or a tighter observer that fails the short audit (never enshrined, not even with
  ``force``), and a status or containment count that depends on the BLAS kernel (unless
  ``force``);
* ``audit`` fails (1) when a guaranteed observer's set missed the true state of a realisation.

Each function returns an :class:`Outcome`: the exit code and the lines to print, in order,
each to standard output or standard error; the command line only prints them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from systems import edge

from ..errors import ConfigError
from ..io import atomic_write_csv, blas_corename
from ..store import bench as store_bench
from ..store import stale as store_stale
from ..verdicts import SOUNDNESS_COLUMNS
from . import audit as soundness
from . import audit_report, audit_store, blas, budget, dated, fidelity, regression

#: scenarios of the short soundness audit that a tighter observer must pass
PROOF_SCENARIOS: tuple[str, ...] = soundness.AUDIT_SCENARIOS


def prove_tighter(names: Sequence[str], progress: bool | None = None) -> dict[str, str]:
    """Run the short soundness audit (adversarial realisations) on observers ``names``;
    ``observer -> "N steps on S, ..."`` for those whose sets missed the true state."""
    if not names:
        return {}
    # worker processes know the project's observers; a plugin registered in this process
    # only (a notebook, a test) is audited here
    jobs = (soundness.default_jobs() if all(regression.is_project_observer(n) for n in names)
            else 1)
    df = soundness.run_audit(PROOF_SCENARIOS, list(names), soundness.SHORT, jobs,
                             progress=progress)
    agg = soundness.aggregate(df)
    bad = agg[(agg["violations"] > 0) | (agg["uncovered"] > 0)]
    return {o: ", ".join(f"{int(v)} steps{f' ({int(u)} missing the floor)' if u else ''} "
                         f"on {s}" for s, v, u in zip(g["scenario"], g["violations"],
                                                      g["uncovered"], strict=True))
            for o, g in bad.groupby("observer", sort=False)}


def _with_proof(diff: pd.DataFrame, progress: bool | None) -> pd.DataFrame:
    """``diff`` with an ``audit`` row for every tighter observer that fails the proof."""
    failing = set(diff.loc[~diff["ok"] & diff["metric"].isin(
        ("violations", *SOUNDNESS_COLUMNS)), "observer"])
    names = [o for o in regression.tighter_observers(diff) if o not in failing]
    proof = regression.proof_rows(prove_tighter(names, progress))
    return pd.concat([diff, proof], ignore_index=True) if len(proof) else diff


@dataclass
class Outcome:
    """The exit code of a gate command and its messages, in the order to print them."""

    code: int = 0
    #: ``(to_stderr, text)`` pairs
    messages: list[tuple[bool, str]] = field(default_factory=list)

    def say(self, text: str) -> None:
        """A line for standard output."""
        self.messages.append((False, text))

    def warn(self, text: str) -> None:
        """A line for standard error."""
        self.messages.append((True, text))


@dataclass(frozen=True)
class CheckOptions:
    """How ``check`` runs the regression subset and what it shows.

    Attributes
    ----------
    use_cache : bool
        Read the offline designs from their cache (else recomputed).
    progress : bool or None
        Progress bars (None: in a terminal).
    out : str or Path, optional
        Folder for the subset's results and ``diff.csv``.
    strict : bool
        A third-party plugin not in the baseline fails.
    show_all : bool
        Print every compared value, not just the failures.
    """

    use_cache: bool = False
    progress: bool | None = None
    out: str | Path | None = None
    strict: bool = False
    show_all: bool = False


def check(config: str | Path, baseline: str | Path, options: CheckOptions = CheckOptions(), *,
          reports: str | Path | None = None) -> Outcome:
    """``check``: nothing stale (``reports``: the stored rows and the committed reports of
    that folder, :func:`stale`), then the regression subset against the golden files of
    ``baseline`` (run as ``options`` say)."""
    res = Outcome()
    found = stale(reports=Path(reports)) if reports else []
    if found:  # cheap (no run): reported first, and the regression subset still runs
        res.warn("\n".join(map(str, found)))
    unfaithful = check_fidelity(res)[0] if reports else 0
    res.code = _check_regression(res, config, baseline, options)
    if found:
        res.warn(f"check FAILED: {len(found)} stale row(s) or report(s) (listed above): "
                 "`make bench` / `make audit` re-run the rows, `make reports` renders the "
                 "reports (timing reports are never stale)")
        res.code = 1
    if unfaithful:
        res.warn(f"check FAILED: {unfaithful} published cell(s) claimed within tolerance are "
                 f"not (listed above; {fidelity.REPORT_NAME}, {FIDELITY_FIX})")
        res.code = 1
    return res


#: what to do about a failing fidelity cell
FIDELITY_FIX = ("fix the row, or change its claim in benchmarks/gate/fidelity.yaml with the "
                "measured reason")


def check_fidelity(res: Outcome, results: Path | None = None,
                   claims: Path | None = None) -> tuple[int, pd.DataFrame]:
    """The fidelity gate (:mod:`benchmarks.gate.fidelity`) on the committed stores (default
    ``ROOT/results``) and the claims (default the shipped file): one warning per cell claimed
    ``within`` that is not; returns their number and the measured cells."""
    results = results if results is not None else store_stale.ROOT / store_bench.RESULTS
    cells = fidelity.measure(results, claims if claims is not None else fidelity.CLAIMS_FILE)
    lines = fidelity.failures(cells)
    for line in lines:
        res.warn(line)
    return len(lines), cells


def fidelity_gate(results: Path | None = None, claims: Path | None = None) -> Outcome:
    """``fidelity``: the fidelity gate alone (no run): exit 1 when a published cell claimed
    ``within`` left its tolerance, one line per cell; the count of average cells within
    tolerance per table, and a note on the explained or open cells that are within now."""
    res = Outcome()
    bad, cells = check_fidelity(res, results, claims)
    res.say(fidelity.summary(cells))
    better = fidelity.now_within(cells)
    if len(better):
        res.say(f"note: {len(better)} explained or open cell(s) are within their tolerance "
                "now (reports/fidelity.md: within now): "
                + ", ".join(f"{r.table} {r.row} {r.cell}" for r in better.itertuples()))
    if bad:
        res.warn(f"fidelity FAILED: {bad} published cell(s) claimed within tolerance are not "
                 f"({FIDELITY_FIX})")
        res.code = 1
    return res


def render_all(results: Path, reports: Path) -> list[Path]:
    """``make reports``: render every committed report from its store (the configurations',
    :func:`benchmarks.store.bench.render_all`, the audit's, and ``fidelity.md`` from the
    claims and the stores, :mod:`benchmarks.gate.fidelity`) and the dated block of every
    report of the second tier (:func:`.dated.refresh`); the files rewritten."""
    changed = store_bench.render_all(results, reports)
    if audit_store.rerender(results, reports):
        changed.append(reports / audit_store.REPORT.name)
    if fidelity.rerender(results, reports):
        changed.append(reports / fidelity.REPORT_NAME)
    changed += [p for p in dated.refresh(reports) if p not in changed]
    return changed


def make_fingerprinter() -> store_stale.Fingerprinter:
    """Fingerprints against one reading of the source tree (its module graph: the parse of
    every module, the larger part of a ``stale``), to share between :func:`stale` and
    :func:`changed_since`."""
    return store_stale.Fingerprinter(store_stale.ModuleGraph(store_stale.ROOT))


def stale(names: list[str] | None = None, reports: Path | None = None,
          prints: store_stale.Fingerprinter | None = None) -> list:
    """``setobs-bench stale``: the first tier, what every landing keeps current: every stale
    row and report of the configurations (:mod:`benchmarks.store.stale`) and, without
    ``names``, every dated block of a second-tier report that says less than the code now
    does (``make reports`` renders it again); ``prints``: a :func:`make_fingerprinter` to use."""
    fingerprinter = prints or make_fingerprinter()
    found = store_stale.find_stale(names, reports=reports, fingerprinter=fingerprinter)
    if not names:
        folder = Path(reports) if reports is not None else store_stale.ROOT / "reports"
        found += [store_stale.Line("report", name, f"reports/{name}.md: its dated block is "
                                   "out of date (`make reports` renders it)")
                  for name in dated.outdated_blocks(folder, fingerprinter=fingerprinter)]
        found += [line for line in audit_store.stale_lines(
            fingerprinter=fingerprinter, reports=reports) if line.kind != "row"]
        line = fidelity.stale_line(store_stale.ROOT / store_bench.RESULTS, folder)
        found += [store_stale.Line("report", "fidelity", line)] if line else []
    return found


def changed_since(reports: Path | None = None,
                  prints: store_stale.Fingerprinter | None = None) -> list[str]:
    """The second tier: one line per dated report with rows the code has changed since it
    was measured (:func:`.dated.changed_rows`); never a reason to block a landing;
    ``prints``: a :func:`make_fingerprinter` to use."""
    fingerprinter = prints or make_fingerprinter()
    folder = Path(reports) if reports is not None else store_stale.ROOT / "reports"
    out = []
    for name in dated.dated_reports(folder):
        rows = dated.changed_rows(name, fingerprinter)
        if rows is None:
            out.append(f"DATED {name}: no record of its rows")
        elif rows:
            shown = ", ".join(list(rows)[:4]) + (f" and {len(rows) - 4} more"
                                                 if len(rows) > 4 else "")
            target = dated.DATED[name].target if name in dated.DATED else dated.STORED[name]
            out.append(f"DATED {name}: {len(rows)} row(s) changed since measured: {shown} "
                       f"(`make {target}`)")
    return out


def _check_regression(res: Outcome, config, baseline, opts: CheckOptions) -> int:
    use_cache, progress, out = opts.use_cache, opts.progress, opts.out
    cfg = regression.subset_config(config)
    base, meta = regression.load_baseline(baseline)
    if regression.config_changed(cfg, meta):
        res.warn(f"REGRESSION: {config} changed since the baseline in {baseline} was written; "
                 "review and run `python -m benchmarks baseline --update`")
        return 1
    executor = _gate_executor(res, cfg, baseline)
    frame, cache_note = regression.run_subset(cfg, use_cache, progress, out, executor=executor)
    diff = _with_proof(regression.compare(base, frame, strict=opts.strict), progress)
    if out:
        atomic_write_csv(Path(out) / "diff.csv", diff)
    n, bad = len(diff), int((~diff["ok"]).sum())
    if bad or opts.show_all:
        res.say(regression.format_diff(diff, only_failures=not opts.show_all))
    plugins = diff[diff["ok"] & (diff["metric"] == "observer")]
    for r in plugins.itertuples(index=False):
        res.warn(f"note: {r.observer} on {r.scenario}: {r.note}")
    for line in budget.timeout_lines(executor.stopped):
        res.warn(line)
    where = (f"{frame['observer'].nunique()} observers x {frame['scenario'].nunique()} "
             f"scenarios; {cache_note}; baseline of {meta.get('created', '?')}")
    summary = regression.change_summary(diff)
    if bad:
        res.warn("if the change is intended, rewrite the golden files with "
                 "`python -m benchmarks baseline --update` and commit them")
        env = regression.environment_differences(meta)
        if env:
            res.warn("note: the environment differs from the baseline's (" + "; ".join(env)
                     + "); the tolerances cover the BLAS kernels measured when the baseline "
                     "was written (SENSITIVITY.md beside it), not other library versions")
        res.warn(f"check FAILED: {bad} of {n} values differ from the baseline ({where}); "
                 f"{summary}")
        return 1
    res.say(f"check passed: {n} values within tolerance ({where}); {summary}")
    return 0


def _gate_executor(res: Outcome, cfg, baseline) -> budget.GateExecutor:
    """The executor of ``check``: a budget per job from the costs recorded beside the golden
    files (:mod:`.budget`), unless the subset's configuration sets ``timeout:``; without a
    cost file every job gets :data:`.budget.GATE_TIMEOUT` (a note says so)."""
    if "timeout" in cfg.raw:
        return budget.GateExecutor(cfg, fixed="the timeout of the subset's configuration")
    budgets = budget.load_costs(baseline)  # a corrupted file: ConfigError, before the run
    if budgets is None:
        res.warn(f"note: no job costs in {Path(baseline) / budget.COST_FILE}: every job gets "
                 f"the fixed budget of {budget.GATE_TIMEOUT:g} s (record them with "
                 "`python -m benchmarks baseline --record-cost`)")
        return budget.GateExecutor(cfg, fixed=f"no {budget.COST_FILE}: the fixed budget")
    return budget.GateExecutor(cfg, budgets)


def _stopped_jobs(frame: pd.DataFrame) -> list[str]:
    per = frame.drop_duplicates(["scenario", "observer"])
    bad = per[per["status"].isin(["error", "timeout", "memory"])]
    return [f"{o} crashed on {s}" if st == "error" else f"{o} stopped on {s} ({st})"
            for s, o, st in zip(bad["scenario"], bad["observer"], bad["status"], strict=True)]


def record_cost(config: str | Path, baseline: str | Path, *, use_cache: bool = False,
                progress: bool | None = None) -> Outcome:
    """``baseline --record-cost``: run the subset once, serially as ``check`` runs it, and
    rewrite only the job costs beside the golden files (:mod:`.budget`; the golden files are
    not read or touched).  Refused (1) while a job crashes or is stopped: its time is not its
    cost."""
    res = Outcome()
    cfg = regression.subset_config(config, plugins=False)
    executor = budget.GateExecutor(cfg)
    load, t0 = budget.load_average(), time.perf_counter()
    frame, cache_note = regression.run_subset(cfg, use_cache, progress, executor=executor)
    elapsed = time.perf_counter() - t0
    stopped = _stopped_jobs(frame)
    if stopped:
        res.warn("job costs NOT written: " + "; ".join(stopped) + " (fix them first)")
        res.code = 1
        return res
    path = budget.write_costs(baseline, executor.seconds, "baseline --record-cost", cache_note,
                              (load, budget.load_average()))
    res.say(f"wrote {path}: {len(executor.seconds)} jobs in {elapsed:.0f} s "
            f"({budget.COST_EXECUTOR}; {cache_note}); the golden files are unchanged")
    return res


def show_baseline(baseline: str | Path) -> Outcome:
    """``baseline`` without ``--update``: an overview of the golden files."""
    frame, meta = regression.load_baseline(baseline)
    res = Outcome()
    res.say(regression.baseline_overview(frame, meta))
    res.say("(`--update` re-runs the subset and rewrites these files)")
    return res


def update_baseline(config: str | Path, baseline: str | Path, *, use_cache: bool = False,
                    progress: bool | None = None, coretypes: str = "auto",
                    force: bool = False, notify: Callable[[str], None] = lambda _: None
                    ) -> Outcome:
    """``baseline --update``: run the subset, measure its BLAS-kernel sensitivity
    (``coretypes``: the OpenBLAS core types compared, ``auto``, ``none`` or a comma-separated
    list) and write the golden files unless a rule of the module docstring refuses them;
    ``notify`` is told before the long re-runs under the other core types start."""
    res = Outcome()
    cfg = regression.subset_config(config, plugins=False)
    executor = budget.GateExecutor(cfg)  # the cost of each job, written with the golden files
    load = budget.load_average()
    frame, cache_note = regression.run_subset(cfg, use_cache, progress, executor=executor)
    load = (load, budget.load_average())
    unsound = regression.baseline_problems(frame)
    try:
        old, _ = regression.load_baseline(baseline)
    except ConfigError:  # no (readable) baseline yet: nothing got tighter
        old = None
    if old is not None and not unsound:
        proof = _with_proof(regression.compare(old, frame), progress)
        unsound = [f"{r.observer} got tighter but fails the short soundness audit "
                   f"({r.current})" for r in proof[proof["metric"] == "audit"].itertuples()]
    if unsound:  # never enshrined, not even with --force
        res.warn("baseline NOT written: " + "; ".join(unsound) + " (fix them first)")
        res.code = 1
        return res
    here = blas_corename()
    if coretypes == "auto":
        names = [k for k in blas.available_coretypes() if k.lower() != here.lower()]
    else:
        names = [k for k in coretypes.split(",") if k and k != "none"]
    problems: list[str] = []
    if names:
        notify(f"measuring the kernel sensitivity: re-running the subset with "
               f"OPENBLAS_CORETYPE={', '.join(names)} (here: {here})")
        others = blas.runs_under_coretypes(config, cfg, names, use_cache)
        frame, problems = blas.apply_coretype_spread(frame, others)
    if problems and not force:
        res.warn("baseline NOT written: " + "; ".join(problems) + " (pass --force to write it "
                 "anyway)")
        res.code = 1
        return res
    files = regression.write_baseline(frame, baseline, cfg, cache_note, names)
    blas.write_sensitivity(frame, baseline, names)
    budget.write_costs(baseline, executor.seconds, "baseline --update", cache_note, load)
    res.say(f"wrote {len(files)} golden files, SENSITIVITY.md and {budget.COST_FILE} to "
            f"{baseline} ({frame['observer'].nunique()} observers; {cache_note})")
    return res


@dataclass(frozen=True)
class AuditOptions:
    """How ``audit`` runs and where it writes.

    Attributes
    ----------
    jobs : int, optional
        Worker processes (default :func:`.audit.default_jobs`).
    short : bool
        The CI mode: adversarial realisations only, into ``results/audit-short/``.
    out, report : str, optional
        The folder of the CSV and the report file of a direct run.
    progress : bool or None
        Progress bars (None: in a terminal).
    cold : bool
        The full audit re-runs every pair, not just the stale ones.
    edge : bool
        The edge-case audit: the degenerate systems of :mod:`systems.edge` instead of the
        benchmark scenarios (long records into ``reports/edge_cases.md``; with ``short``,
        CI's, short records into ``results/edge-audit-short/``).
    """

    jobs: int | None = None
    short: bool = False
    edge: bool = False
    out: str | None = None
    report: str | None = None
    progress: bool | None = None
    cold: bool = False


def _direct_audit(scenarios: Sequence[str] | None, realisations: int, options: AuditOptions
                  ) -> tuple[soundness.Realisations, str, str, str, tuple[str, ...]]:
    """What a direct audit runs and where it writes: ``(realisations, command, csv folder,
    report, scenarios)`` for the short audit, the edge-case audits or chosen scenarios and
    observers (``scenarios``: None for the default ones of the mode)."""
    out, report = options.out, options.report
    if options.edge:
        short = options.short
        chosen = soundness.EDGE_SHORT if short else soundness.EDGE_FULL
        command = "python -m benchmarks audit --edge" + (" --short" if short else "")
        out = out or str(Path("results") / ("edge-audit-short" if short else "edge-audit"))
        report = report or (str(Path(out) / "soundness.md") if short
                            else str(Path("reports") / "edge_cases.md"))
        return chosen, command, out, report, tuple(
            scenarios or (edge.NAMES if short else edge.SCENARIOS))
    chosen = soundness.Realisations(realisations)
    command = f"python -m benchmarks audit --realisations {realisations}"
    if options.short:
        chosen = soundness.SHORT
        command = "python -m benchmarks audit --short"
        out = out or str(Path("results") / "audit-short")
        report = report or str(Path(out) / "soundness.md")
    out = out or str(Path("results") / "audit")
    report = report or str(Path(out) / "soundness.md")
    return chosen, command, out, report, tuple(scenarios or soundness.AUDIT_SCENARIOS)


def audit(scenarios: Sequence[str], observer_names: Sequence[str] | None, *,
          realisations: int, options: AuditOptions = AuditOptions()) -> Outcome:
    """``audit``: run the soundness audit and fail on a violation of a guaranteed observer.

    The full audit (default scenarios and observers, ``reports/soundness.md``) is a result
    store re-run where stale (:mod:`.audit_store`; ``options.cold``: every pair);
    ``options.short`` (the CI mode: adversarial realisations only, into
    ``results/audit-short/``) and an audit of chosen scenarios, observers or outputs are
    direct runs that write their CSV and report."""
    short, out, report = options.short, options.out, options.report
    progress, cold = options.progress, options.cold
    jobs = options.jobs if options.jobs is not None else soundness.default_jobs()
    default_scenarios = tuple(scenarios) == tuple(soundness.AUDIT_SCENARIOS)
    full = (not short and not options.edge and out is None and report is None
            and not observer_names and default_scenarios)
    t0 = time.perf_counter()
    if full:
        store, ran_rows, ran = audit_store.bench_audit(realisations, jobs, cold=cold,
                                                       progress=progress)
        elapsed = time.perf_counter() - t0
        if store is None:
            raise ConfigError("audit: no store and nothing to run")
        df = store.view()[0]
        lines = [f"wrote {audit_store.REPORT} from {audit_store.STORE} ({ran} pair(s) run in "
                 f"{elapsed:.0f} s, the others current)"]
    else:
        chosen, command, out, report, scenarios = _direct_audit(
            scenarios if not default_scenarios else None, realisations, options)
        df = soundness.run_audit(scenarios, observer_names, chosen, jobs, progress=progress)
        elapsed = time.perf_counter() - t0
        csv_path, report = audit_report.write_audit(df, out, report, chosen.count, elapsed,
                                                    jobs, command, edge=options.edge)
        lines = [f"wrote {report} and {csv_path}"]
    agg = soundness.aggregate(df)
    bad = agg[agg["guaranteed"] & ((agg["violations"] > 0) | (agg["uncovered"] > 0))]
    res = Outcome()
    res.say(f"{lines[0]} ({int(agg['runs'].sum())} runs, {int(agg['steps'].sum())} steps, "
            f"{elapsed:.0f} s)")
    undecided = int(agg["undecided"].sum())
    if undecided:
        res.say(f"note: {undecided} step(s) undecided at LP precision (see the report)")
    if len(bad):
        res.warn("SOUNDNESS VIOLATIONS: " + ", ".join(
            f"{r.observer} on {r.scenario} ({r.violations} steps missing the true state, "
            f"{r.uncovered} missing the floor)" for r in bad.itertuples(index=False)))
        res.code = 1
        return res
    res.say("zero violations for every guaranteed observer (true states and floors)")
    return res
