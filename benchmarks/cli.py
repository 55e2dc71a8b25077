"""Command line: ``setobs-bench`` (or ``python -m benchmarks``) with the sub-commands
``run, bench, reports, stale, report, index, history, list, check, fidelity, baseline, audit,
time, speed, designs, export, score``.

Bad input ends with a one-line ``error: ...`` on stderr and exit code 2 (nothing is
written); a regression (``check``) or a containment violation of a guaranteed observer
(``run``, ``audit``) with exit code 1; an observer that crashed (``run``: status ``error``,
after the other observers ran) with exit code 3 (:mod:`benchmarks.verdicts`).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
import warnings
from pathlib import Path

import observers
from systems import scenario_names

from . import verdicts
from .errors import USER_ERRORS, ConfigError
from .exchange import export as exchange_export
from .exchange import score as exchange_score
from .gate import audit, blas, dated, history, policy, regression, release
from .io import (
    atomic_write_json,
    blas_corename,
    check_output_dir,
    check_output_file,
    package_versions,
    path_component,
)
from .report import citation, freshness
from .report.html import write_html, write_index
from .report.latex import write_latex
from .report.markdown import write_report
from .report.tables import design_times_table
from .run import designs, executors
from .run.config import (
    DEFAULT_MEMORY_FRACTION,
    DEFAULT_TIMEOUT,
    inline_config,
    load_config,
    parse_memory,
    parse_timeout,
)
from .run.runner import run_config
from .run.shipped import shipped_configs
from .store import bench as store_bench
from .store import stale as store_stale
from .timing import speed
from .timing import steps as timing


def _only(cfg, names: list[str]):
    """``cfg`` restricted to the observers (or variant labels) ``names``; a variant
    ``NAME[tag]`` goes with ``NAME``."""
    unknown = [n for n in names if n not in cfg.observers]
    if unknown:
        raise ConfigError(f"run: {', '.join(unknown)} not in config '{cfg.name}' (its "
                          f"observers: {', '.join(cfg.observers)})")
    keep = [o for o in cfg.observers if o in names or cfg.observer_of(o) in names]
    return dataclasses.replace(cfg, observers=keep)


def _cmd_run(args) -> int:
    if args.add:
        return _cmd_run_add(args)
    if args.config and args.scenario:
        raise ConfigError("run: give either a YAML config or --scenario, not both")
    if args.out is not None:
        _not_a_store(args.out)
        check_output_dir(args.out)  # before any work (again in run_config for the default)
    # the executor first: local workers' server then starts while the config is read
    executor = executors.from_args(args.executor, args.jobs, args.address)
    try:
        if args.config:
            cfg = load_config(args.config)
            if args.observer:
                cfg = _only(cfg, args.observer)
            for sc in cfg.scenarios:  # which columns of the users' files were read
                if sc.source.startswith("config; read "):
                    print(f"{sc.name}: {sc.source[len('config; '):]}", file=sys.stderr)
        else:
            cfg = inline_config(args.scenario, args.observer, args.name)
        if args.timeout is not None:  # the command line over the config
            cfg.timeout = parse_timeout(args.timeout, "--timeout")
        if args.memory_limit is not None:
            cfg.memory_limit = parse_memory(args.memory_limit, "--memory-limit")
        out = Path(args.out) if args.out else Path("results") / path_component(cfg.name)
        if args.out is None and store_bench.is_store(out):  # a committed store: beside it
            out = out / "run"
        result = run_config(cfg, out, progress=False if args.no_progress else None,
                            executor=executor)
        summary = result.summary
    finally:
        executor.close()
    print(f"wrote {out / 'runs.csv'}, {out / 'summary.csv'}")
    pairs = summary.drop_duplicates(["scenario", "seed", "observer", "variant"])
    for r in pairs[pairs["status"] != "ok"].itertuples(index=False):
        print(f"note: {r.observer} on {r.scenario}: {r.status}: {r.message}", file=sys.stderr)
    statuses = pairs["status"].value_counts()
    print("status: " + ", ".join(f"{k} {v}" for k, v in statuses.items()))
    for line in result.problems:
        print(line, file=sys.stderr)
    return result.exit_code


def _not_a_store(folder: str | Path) -> None:
    """A run never writes into a result store (``make bench`` merges rows into it)."""
    if store_bench.is_store(Path(folder)):
        raise ConfigError(f"run: {folder} is a result store (committed rows: `setobs-bench "
                          f"bench` updates it); give --out another folder, e.g. {folder}/run")


def _cmd_run_add(args) -> int:
    """``run CONFIG --add NAME``: NAME's rows run, the others from the store."""
    if not args.config or args.scenario or args.observer:
        raise ConfigError("run --add NAME needs a configuration and no --scenario/--observer")
    cfg = load_config(args.config)
    out = Path(args.out) if args.out else Path("results") / path_component(
        f"{cfg.name}+{args.add}")
    if (out / "summary.csv").exists() and not store_bench.is_store(out):
        raise ConfigError(f"run --add: {out} holds another run's results; give a new or empty "
                          "folder")
    check_output_dir(out)
    executor = executors.from_args(args.executor, args.jobs, args.address)
    try:
        outcome, report = store_bench.add_observer(
            cfg, args.add, store_bench.shipped_results(), executor, out,
            progress=False if args.no_progress else None)
    finally:
        executor.close()
    print(f"ran {outcome.ran} of {outcome.total} rows; wrote {out / 'summary.csv'}, {report}")
    for line in outcome.problems:
        print(line, file=sys.stderr)
    return outcome.exit_code


def _cmd_bench(args) -> int:
    names = args.configs or store_bench.published()
    executor = executors.from_args(None, args.jobs, None)
    results, reports = Path(args.results), Path(args.reports)
    t0 = time.perf_counter()
    try:
        outcomes = store_bench.bench_all(names, results, reports, executor, cold=args.cold,
                                         progress=False if args.no_progress else None)
    finally:
        executor.close()
    for outcome in outcomes:
        for line in outcome.problems:
            print(f"{outcome.name}: {line}", file=sys.stderr)
        if args.html and outcome.ran:  # figures exist for the rows just run
            folder = results / outcome.name
            print(f"wrote {write_html(folder, data=store_bench.load_store(folder).view())}")
    ran = sum(o.ran for o in outcomes)
    print(f"bench: {ran} of {sum(o.total for o in outcomes)} rows run in {len(outcomes)} "
          f"configuration(s), {time.perf_counter() - t0:.0f} s")
    return max((o.exit_code for o in outcomes), default=0)


def _cmd_reports(args) -> int:
    changed = policy.render_all(Path(args.results), Path(args.reports))
    for path in changed:
        print(f"wrote {path}")
    print(f"reports: {len(changed)} rewritten")
    return 0


def _cmd_stale(args) -> int:
    if args.record:
        rec = dated.record(args.record)
        dated.refresh(Path(args.record).resolve().parent)  # its dated block says so
        print(f"recorded {args.record} as measured by {rec['version']} at commit "
              f"{rec['commit'] or '?'}")
        return 0
    prints = policy.make_fingerprinter()  # one parse of the source tree for both tiers
    lines = policy.stale(args.configs or None, prints=prints)
    for line in lines:
        print(line)
    later = [] if args.configs else policy.changed_since(prints=prints)
    for line in later:
        print(line)
    if lines:
        print(f"{len(lines)} stale (`make bench` re-runs the rows, `make reports` renders the "
              "reports)", file=sys.stderr)
    if later:
        print(f"{len(later)} dated report(s) with rows measured by older code (second tier: "
              "no landing waits for them; `make release` measures them again)",
              file=sys.stderr)
    return 1 if lines or (args.all and later) else 0


def _print(outcome: policy.Outcome) -> int:
    """Print a gate command's messages, each to its stream; return its exit code."""
    for to_err, text in outcome.messages:
        print(text, file=sys.stderr if to_err else sys.stdout)
    return outcome.code


def _progress(args) -> bool | None:
    return False if args.no_progress else None


def _cmd_check(args) -> int:
    options = policy.CheckOptions(use_cache=args.use_cache, progress=_progress(args),
                                  out=args.out, strict=args.strict, show_all=args.all)
    return _print(policy.check(args.config, args.baseline, options, reports=args.reports))


def _cmd_fidelity(args) -> int:
    return _print(policy.fidelity_gate(Path(args.results) if args.results else None,
                                       Path(args.claims) if args.claims else None))


def _cmd_baseline(args) -> int:
    if not args.update:
        return _print(policy.show_baseline(args.baseline))
    return _print(policy.update_baseline(args.config, args.baseline, use_cache=args.use_cache,
                                         progress=_progress(args), coretypes=args.kernels,
                                         force=args.force, notify=print))


def _cmd_audit(args) -> int:
    options = policy.AuditOptions(jobs=args.jobs, short=args.short, out=args.out,
                                  report=args.report, progress=_progress(args), cold=args.cold,
                                  edge=args.edge)
    return _print(policy.audit(args.scenarios, args.observers, realisations=args.realisations,
                               options=options))


def _cmd_time(args) -> int:
    if args.json is not None:
        check_output_file(args.json, "--json")  # before the timing, not after it
    plan = timing.TimingPlan(repeat=args.repeat, warmup=args.warmup, steps=args.steps,
                             steady=args.steady)
    sc, warmup, rows = timing.time_observers(args.names, args.scenario, plan)
    print(timing.format_table(sc, args.repeat, warmup, rows))
    if args.json:
        atomic_write_json(args.json, timing.to_json(sc, args.repeat, warmup, rows))
        print(f"wrote {args.json}")
    return 0


def _cmd_designs(args) -> int:
    jobs = args.jobs if args.jobs is not None else audit.default_jobs()
    t0 = time.perf_counter()
    done = designs.prewarm(args.configs, jobs, progress=False if args.no_progress else None)
    if not done:
        print("no design to compute (none of these observers has a cached offline design, "
              "or SETOBS_CACHE_DIR=off)")
        return 0
    print(design_times_table(done, top=args.top))
    failed = sum(status != "ok" for _, _, status, _ in done)
    print(f"{len(done)} designs in the cache ({failed} failed, reported by the runs) in "
          f"{time.perf_counter() - t0:.0f} s with {jobs} worker(s)")
    return 0


def _cmd_speed(args) -> int:
    check_output_file(args.out, "--out")  # before the timing, not after it
    check_output_file(args.json, "--json")
    path = speed.write_speed_report(args.out, args.json)
    print(f"wrote {path} and {args.json}")
    return 0


def _cmd_report(args) -> int:
    if args.out is not None:
        check_output_file(args.out, "--out")
    store = store_bench.load_store(args.dir)  # a result store, or None for a run's folder
    data = store.view() if store is not None else None
    path = write_report(args.dir, args.out, figures=not args.no_figures, data=data)
    print(f"wrote {path}")
    if args.latex:  # report.tex beside the Markdown report
        print(f"wrote {write_latex(args.dir, Path(path).with_suffix('.tex'), data=data)}")
    if args.out is None:  # DIR/index.html beside DIR/report.md
        print(f"wrote {write_html(args.dir, figures=not args.no_figures, data=data)}")
    return 0


def _cmd_export(args) -> int:
    cfg = load_config(args.config)
    for path in exchange_export.export_config(cfg, args.out, args.format):
        print(f"wrote {path}")
    return 0


def _cmd_score(args) -> int:
    outcome = exchange_score.score(args.results, load_config(args.config), args.out)
    for line in outcome.verdicts:
        print(line)
    for line in outcome.problems:
        print(line, file=sys.stderr)
    print(f"wrote {outcome.out / 'summary.csv'} (`setobs-bench report {outcome.out}` renders "
          "it)")
    return outcome.code


def _cmd_index(args) -> int:
    if args.committed:  # the committed page: the Markdown reports only, never local runs
        print(f"wrote {write_index(args.reports, None, args.out)}")
    else:
        print(f"wrote {write_index(args.reports, args.results, args.out)}")
    return 0


def _cmd_history(args) -> int:
    path, table = history.write_history(args.baseline, args.out)
    print(f"wrote {path} ({table['commit'].nunique()} commits, "
          f"{table['observer'].nunique()} observers)")
    return 0


def _cmd_list(args) -> int:
    if args.what in ("observers", "all"):
        print(f"{'name':<12} {'family':<12} {'set':<12} {'timing':<18} reference")
        for i in observers.available():
            flag = "" if i.guaranteed else " (not guaranteed)"
            print(f"{i.name:<12} {i.family:<12} {i.set_type:<12} {i.timing:<18} "
                  f"{i.reference}{flag}")
    if args.what in ("scenarios", "all"):
        print("\nscenarios: " + ", ".join(scenario_names()))
    if args.what in ("configs", "all"):
        print("\nshipped configs (setobs-bench run NAME):")
        for name, path in shipped_configs().items():
            print(f"  {name:<28} {_config_title(path)}")
    return 0


def _config_title(path: Path) -> str:
    """The ``title:`` line of a shipped configuration (read as text: no scenario is built)."""
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("title:"):
            return line[len("title:"):].strip().strip("\"'")
    return ""


#: the packages whose versions ``--version`` prints (numerics and solvers)
VERSION_PACKAGES = ("numpy", "scipy", "highspy", "clarabel", "cvxpy", "numba")


def _checkout_commit(root: Path) -> str:
    """The short commit of the git checkout whose top level is ``root``, with ``" (modified)"``
    if tracked files differ from it; ``""`` if ``root`` is not the top of a checkout (an
    installed copy) or git is missing (:func:`benchmarks.report.freshness.checkout_state`)."""
    head, modified = freshness.checkout_state(root, top_only=True)
    return head + (" (modified)" if modified else "")


def _version() -> str:
    """What ``setobs-bench --version`` prints, one item a line.

    Returns
    -------
    str
        ``setobs-bench VERSION``; ``commit HASH`` (with `` (modified)``) when the package runs
        from a git checkout; ``NAME VERSION`` of each of :data:`VERSION_PACKAGES`
        (``missing`` if not installed); ``BLAS OpenBLAS KERNEL`` (the kernel family in use,
        :func:`benchmarks.io.blas_corename`).
    """
    lines = [f"setobs-bench {citation.project_version()}"]
    commit = _checkout_commit(Path(__file__).resolve().parent.parent)
    if commit:
        lines.append(f"commit {commit}")
    lines += [f"{pkg} {v}" for pkg, v in package_versions(VERSION_PACKAGES).items()]
    kernel = blas_corename()
    lines.append(f"BLAS {'OpenBLAS ' + kernel if kernel != 'unknown' else 'unknown'}")
    return "\n".join(lines)


class _VersionAction(argparse.Action):
    """``--version``: print :func:`_version` (computed only when asked) and exit 0."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="print the version, the commit and the numerical libraries, and exit"):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(_version())
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (see the module docstring for the sub-commands)."""
    p = argparse.ArgumentParser(prog="setobs-bench", allow_abbrev=False,
                                description="Guaranteed state estimator benchmarks "
                                            "(also: python -m benchmarks)")
    p.add_argument("--version", action=_VersionAction)
    sub = p.add_subparsers(dest="command", required=True)
    _add_parser = sub.add_parser

    def add_parser(*a, **k):  # no abbreviated options (--add is not --address)
        return _add_parser(*a, allow_abbrev=False, **k)

    sub.add_parser = add_parser
    _add_run(sub)
    _add_bench(sub)
    _add_reports(sub)
    _add_stale(sub)
    _add_release(sub)
    _add_report(sub)
    _add_exchange(sub)
    _add_index(sub)
    _add_history(sub)
    _add_list(sub)
    subset = _subset_options()
    _add_check(sub, subset)
    _add_fidelity(sub)
    _add_baseline(sub, subset)
    _add_audit(sub)
    _add_time(sub)
    _add_designs(sub)
    _add_speed(sub)
    return p


def _add_run(sub) -> None:
    """The ``run`` sub-command."""
    r = sub.add_parser("run", help="run a YAML benchmark config, or observers on scenarios",
                       epilog=verdicts.EXIT_CODES_HELP,
                       description="Run every observer of a config (or the --observer names) on "
                                   "its scenarios (or the --scenario names) and write runs.csv, "
                                   "summary.csv and meta.json (one generation).")
    r.add_argument("config", nargs="?",
                   help="a YAML config: a path, or the name of a shipped one (`setobs-bench "
                        "list configs`, e.g. arch2021_table3); or use --scenario")
    r.add_argument("--observer", action="append", metavar="NAME",
                   help="an observer to run (repeatable; default all; with a config: only "
                        "these of its observers, with their labelled variants)")
    r.add_argument("--scenario", action="append", metavar="S",
                   help="without a config: a named scenario (repeatable)")
    r.add_argument("--name", help="without a config: the run's name (default cli)")
    r.add_argument("--out", help="output folder (default results/<config name>)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--jobs", type=int, nargs="?", const=0, metavar="N",
                   help="run the jobs in N local worker processes (no N: the number of cores); "
                        "timing columns are then marked parallel")
    r.add_argument("--executor", choices=executors.EXECUTORS,
                   help="serial (default), processes (as --jobs) or dask (a Dask cluster)")
    r.add_argument("--address", metavar="tcp://HOST:PORT",
                   help="Dask scheduler to use (default: start a LocalCluster on 127.0.0.1)")
    r.add_argument("--timeout", metavar="SECONDS",
                   help="job timeout, a hard stop per job (default: the config's 'timeout', "
                        f"else {DEFAULT_TIMEOUT:g} s; 'none': no timeout); a job over it "
                        "is stopped and reported as status 'timeout'")
    r.add_argument("--memory-limit", metavar="SIZE",
                   help="resident memory per job, e.g. 2G or 512M (default: the config's "
                        "'memory_limit', else "
                        f"{DEFAULT_MEMORY_FRACTION * 100:.0f} %% of the available memory "
                        "shared by the workers; 'none': no limit); a job over it is stopped "
                        "and reported as status 'memory' (third-party plugins and parallel "
                        "jobs; the project's own observers in a serial run keep the time "
                        "budget only)")
    r.add_argument("--add", metavar="NAME",
                   help="rank observer NAME (e.g. your plugin) in the configuration beside "
                        "its stored rows: only NAME's rows run, the others come from the "
                        "result store where their fingerprints are current")
    r.set_defaults(func=_cmd_run)


def _add_store_folders(parser: argparse.ArgumentParser) -> None:
    """``--results`` and ``--reports`` of the commands that read the stores and write the
    committed reports."""
    parser.add_argument("--results", default="results", help="folder of the stores")
    parser.add_argument("--reports", default="reports", help="folder of the committed reports")


def _add_bench(sub) -> None:
    """The ``bench`` sub-command."""
    be = sub.add_parser("bench", help="bring the result stores up to date (only stale or "
                                      "missing rows run) and render reports/<config>.md",
                        description=store_bench.__doc__.splitlines()[0])
    be.add_argument("configs", nargs="*", metavar="CONFIG",
                    help="shipped configuration names (default: every published one)")
    be.add_argument("--cold", action="store_true", help="run every row, stale or not")
    be.add_argument("--jobs", type=int, default=None, metavar="N",
                    help="worker processes (default: serial)")
    _add_store_folders(be)
    be.add_argument("--no-progress", action="store_true", help="no progress bar")
    be.add_argument("--html", action="store_true",
                    help="also write RESULTS/<config>/index.html with figures for each "
                         "configuration that ran rows (make report: every store)")
    be.set_defaults(func=_cmd_bench)


def _add_reports(sub) -> None:
    """The ``reports`` sub-command."""
    rr = sub.add_parser("reports", help="render every committed report from its store "
                                        "(no run; changes no byte when nothing changed)")
    _add_store_folders(rr)
    rr.set_defaults(func=_cmd_reports)


def _cmd_release(args) -> int:
    if args.plan:
        print(" ".join(release.plan()))
        return 0
    new = release.bump(args.bump)
    print(f"released {new} (commit and tag v{new})")
    return 0


def _add_release(sub) -> None:
    """The ``release`` sub-command (what ``make release`` calls)."""
    rl = sub.add_parser("release", help="the steps of `make release`: the make targets of "
                                        "the dated reports to measure again, or the bump",
                        description=release.__doc__.splitlines()[0])
    what = rl.add_mutually_exclusive_group(required=True)
    what.add_argument("--plan", action="store_true",
                      help="print the make targets of the dated reports with rows measured "
                           "by older code")
    what.add_argument("--bump", choices=release.PARTS,
                      help="bump this part of the version, open its CHANGELOG entry, commit "
                           "and tag (refused while a dated report is measured by older code)")
    rl.set_defaults(func=_cmd_release)


def _add_stale(sub) -> None:
    """The ``stale`` sub-command."""
    st = sub.add_parser("stale", help="name the stored rows and committed reports that are "
                                      "out of date (no run; exit 1 if any)",
                        description=store_stale.__doc__.splitlines()[0])
    st.add_argument("configs", nargs="*", metavar="CONFIG",
                    help="shipped configuration names (default: all, and the dated reports)")
    st.add_argument("--all", action="store_true",
                    help="also exit 1 if a dated report (a study, the audit, a timing "
                         "report) has rows measured by older code (what `make release` "
                         "requires)")
    st.add_argument("--record", metavar="REPORT",
                    help="record that the dated report REPORT (e.g. reports/robustness.md) "
                         "was just measured by this tree: its version, commit, date and "
                         "the fingerprint of each row")
    st.set_defaults(func=_cmd_stale)


def _add_report(sub) -> None:
    """The ``report`` sub-command."""
    rep = sub.add_parser("report", help="write the Markdown and HTML reports of a results dir")
    rep.add_argument("dir", help="folder with summary.csv (and runs.csv, meta.json)")
    rep.add_argument("--out", help="Markdown file to write (default DIR/report.md; without "
                                   "--out DIR/index.html is written too)")
    rep.add_argument("--no-figures", action="store_true", help="tables only")
    rep.add_argument("--latex", action="store_true",
                     help="also write the tables as LaTeX (booktabs) beside the Markdown "
                          "report (report.tex)")
    rep.set_defaults(func=_cmd_report)


def _add_exchange(sub) -> None:
    """The ``export`` and ``score`` sub-commands (tools outside the harness)."""
    ex = sub.add_parser("export", help="write the problems of a config (model, sets, record; "
                                       "no true states) for tools in other languages",
                        description=exchange_export.__doc__.splitlines()[0])
    ex.add_argument("config", help="a YAML config: a path or a shipped name")
    ex.add_argument("--out", required=True, help="output folder")
    ex.add_argument("--format", default="json", choices=list(exchange_export.FORMATS),
                    help="json (default), mat (MATLAB/Octave) or csv (a folder per scenario)")
    ex.set_defaults(func=_cmd_export)
    sc = sub.add_parser("score", help="score tools' result files as observers ext:<tool> "
                                      "beside a config's stored rows",
                        epilog=verdicts.EXIT_CODES_HELP,
                        description=exchange_score.__doc__.splitlines()[0])
    sc.add_argument("results", nargs="+", metavar="RESULT",
                    help="result files (setobs-result, .json or .mat)")
    sc.add_argument("--config", required=True, help="the config they answer (a path or a "
                                                    "shipped name)")
    sc.add_argument("--out", help="output folder (default scored/<config name>)")
    sc.set_defaults(func=_cmd_score)


def _add_index(sub) -> None:
    """The ``index`` sub-command."""
    ix = sub.add_parser("index", help="write RESULTS/index.html linking every report and the "
                                      "local HTML reports (--committed: REPORTS/index.html)",
                        description="Write an index of the reports. By default "
                                    "RESULTS/index.html: every Markdown report of REPORTS and "
                                    "the HTML report of each run in RESULTS; the repository "
                                    "is not touched. --committed rewrites REPORTS/index.html "
                                    "from the Markdown reports alone (its content depends on "
                                    "the committed reports only).")
    ix.add_argument("reports", nargs="?", default="reports", help="folder of the Markdown "
                    "reports (default reports)")
    ix.add_argument("--results", default="results",
                    help="folder of the runs whose DIR/index.html to link; the page goes there "
                         "(default results)")
    ix.add_argument("--committed", action="store_true",
                    help="rewrite REPORTS/index.html (the committed page: Markdown reports "
                         "only, no local runs)")
    ix.add_argument("--out", help="write the page to this file instead")
    ix.set_defaults(func=_cmd_index)


def _add_history(sub) -> None:
    """The ``history`` sub-command."""
    hi = sub.add_parser("history", help="relative RMS and violations of the golden summaries "
                                        "across the git history (HTML page)")
    hi.add_argument("--baseline", default=str(regression.DEFAULT_BASELINE),
                    help="folder of the golden files in the repository (default results/baseline)")
    hi.add_argument("--out", default=str(Path("results") / "history"),
                    help="output folder of index.html (default results/history)")
    hi.set_defaults(func=_cmd_history)


def _add_list(sub) -> None:
    """The ``list`` sub-command."""
    ls = sub.add_parser("list", help="list observers, scenarios and shipped configs")
    ls.add_argument("what", nargs="?", default="all",
                    choices=["observers", "scenarios", "configs", "all"])
    ls.set_defaults(func=_cmd_list)


def _subset_options() -> argparse.ArgumentParser:
    """The options ``check`` and ``baseline`` share (the regression subset and its golden
    files)."""
    subset = argparse.ArgumentParser(add_help=False)
    subset.add_argument("--config", default=str(regression.DEFAULT_CONFIG),
                        help="the regression subset (default benchmarks/configs/regression.yaml)")
    subset.add_argument("--baseline", default=str(regression.DEFAULT_BASELINE),
                        help="folder of the golden files (default results/baseline)")
    subset.add_argument("--use-cache", action="store_true",
                        help="use cached offline designs (default: recompute every design)")
    subset.add_argument("--no-progress", action="store_true", help="no progress bar")
    return subset


def _add_check(sub, subset: argparse.ArgumentParser) -> None:
    """The ``check`` sub-command."""
    ch = sub.add_parser("check", parents=[subset],
                        help="re-run the regression subset and compare with the golden files")
    ch.add_argument("--out", default=str(Path("results") / "check"),
                    help="where to write this run and diff.csv (default results/check)")
    ch.add_argument("--all", action="store_true", help="print every compared value")
    ch.add_argument("--reports", metavar="DIR",
                    help="also fail if a stored row or a committed report is stale "
                         "(`setobs-bench stale`: row fingerprints against the code, reports "
                         "against their stores; make check: reports) or a published cell "
                         "claimed within tolerance is not (`setobs-bench fidelity`)")
    ch.add_argument("--strict", action="store_true",
                    help="fail on installed third-party plugins that are not in the baseline "
                         "(default: list them)")
    ch.set_defaults(func=_cmd_check)


def _add_fidelity(sub) -> None:
    """The ``fidelity`` sub-command."""
    fi = sub.add_parser("fidelity", help="compare the committed stores with the published "
                                         "tables (no run; exit 1 if a cell claimed within "
                                         "tolerance is not)",
                        description="The fidelity gate of make check alone: every published "
                                    "cell of benchmarks/gate/fidelity.yaml against the "
                                    "committed result stores; one line per cell claimed "
                                    "within tolerance that is not.")
    fi.add_argument("--results", metavar="DIR",
                    help="folder of the result stores (default: the project's results/)")
    fi.add_argument("--claims", metavar="FILE",
                    help="claims file (default benchmarks/gate/fidelity.yaml)")
    fi.set_defaults(func=_cmd_fidelity)


def _add_baseline(sub, subset: argparse.ArgumentParser) -> None:
    """The ``baseline`` sub-command."""
    bl = sub.add_parser("baseline", parents=[subset],
                        help="show the golden files, or rewrite them with --update")
    bl.add_argument("--update", action="store_true", help="re-run the subset and rewrite them")
    bl.add_argument("--force", action="store_true",
                    help="write even if a status or containment count depends on the BLAS "
                         "kernel (never with a crash or a containment violation)")
    bl.add_argument("--kernels", default="auto", metavar="K1,K2|none",
                    help="OpenBLAS kernel families to measure the sensitivity with (default: "
                         "those of " + ",".join(blas.SPREAD_CORETYPES) + " this CPU runs)")
    bl.add_argument("--record-cost", dest="func", action="store_const",
                    const=lambda a: _print(policy.record_cost(
                        a.config, a.baseline, use_cache=a.use_cache, progress=_progress(a))),
                    help="instead of --update: run the subset once, serially as check does, and "
                         "rewrite only the cost of each job (cost.json beside the golden files, "
                         "check's time budget per job); the golden files are untouched")
    bl.set_defaults(func=_cmd_baseline)


def _add_audit(sub) -> None:
    """The ``audit`` sub-command."""
    au = sub.add_parser("audit", help="soundness audit on many seeded realisations")
    au.add_argument("--realisations", type=int, default=audit.DEFAULT_REALISATIONS,
                    help=f"realisations per observer and scenario "
                         f"(default {audit.DEFAULT_REALISATIONS})")
    au.add_argument("--scenarios", nargs="+", default=list(audit.AUDIT_SCENARIOS),
                    help="simulated scenarios (default: " + " ".join(audit.AUDIT_SCENARIOS) + ")")
    au.add_argument("--observers", nargs="+", help="observer names (default: all registered)")
    au.add_argument("--jobs", type=int, help="worker processes (default: cores, at most 2)")
    au.add_argument("--short", action="store_true",
                    help="CI mode: only the adversarial realisations ("
                         f"{', '.join(audit.ADVERSARIAL)}) among the first "
                         f"{audit.SHORT_REALISATIONS}; writes to "
                         "results/audit-short/ (soundness.csv, soundness.md)")
    au.add_argument("--edge", action="store_true",
                    help="the edge-case audit: the degenerate systems of systems/edge.py "
                         "(flat sets, repeated and dependent outputs, a known state, extreme "
                         "magnitudes and units), short and long records -> "
                         "reports/edge_cases.md; with --short (CI) the short records only -> "
                         "results/edge-audit-short/")
    au.add_argument("--out", help="a direct run: folder of soundness.csv (default: the full "
                                  "audit's store results/soundness/)")
    au.add_argument("--report", help="a direct run: its Markdown report (default: "
                                     "reports/soundness.md, rendered from the store)")
    au.add_argument("--no-progress", action="store_true", help="no progress bar")
    au.add_argument("--cold", action="store_true",
                    help="the full audit: run every observer x scenario pair, stale or not "
                         "(default: only the stale ones of results/soundness/)")
    au.set_defaults(func=_cmd_audit)


def _add_time(sub) -> None:
    """The ``time`` sub-command."""
    ti = sub.add_parser("time", help="per-step times of observers against a Kalman filter step",
                        description=timing.__doc__.splitlines()[0])
    ti.add_argument("names", nargs="+", metavar="NAME", help="observer names")
    ti.add_argument("--scenario", required=True, metavar="S",
                    help="scenario name (see `list scenarios`)")
    ti.add_argument("--repeat", type=int, default=timing.DEFAULT_REPEAT, metavar="N",
                    help=f"runs over the record per observer (default {timing.DEFAULT_REPEAT})")
    ti.add_argument("--warmup", type=int, metavar="K",
                    help="steps of each run not timed (default: as summary.csv, "
                         "min(5, N // 10))")
    ti.add_argument("--steps", type=int, metavar="M",
                    help="run only the first M steps of the record (default: all)")
    ti.add_argument("--steady", action="store_true",
                    help="time only the steady state: the steps from which the set size "
                         "(generators, constraints) stays constant")
    ti.add_argument("--json", metavar="F", help="also write every number to this JSON file")
    ti.set_defaults(func=_cmd_time)


def _add_designs(sub) -> None:
    """The ``designs`` sub-command."""
    de = sub.add_parser("designs", help="compute the offline designs of configs in parallel "
                        "into the design cache", description=designs.__doc__.splitlines()[0])
    de.add_argument("configs", nargs="+", metavar="CONFIG",
                    help="YAML configs (paths or shipped names)")
    de.add_argument("--jobs", type=int, help="worker processes (default: cores, at most 2)")
    de.add_argument("--no-progress", action="store_true", help="no progress bar")
    de.add_argument("--top", type=int, default=None,
                    help="list only the N slowest designs (default: all)")
    de.set_defaults(func=_cmd_designs)


def _add_speed(sub) -> None:
    """The ``speed`` sub-command."""
    sp = sub.add_parser("speed", help="time the cases of the speed table -> reports/speed.md",
                        description=speed.__doc__.splitlines()[0])
    sp.add_argument("--out", default=str(speed.DEFAULT_REPORT),
                    help=f"Markdown report (default {speed.DEFAULT_REPORT})")
    sp.add_argument("--json", default=str(speed.DEFAULT_JSON),
                    help=f"previous measurement, overwritten with this one "
                         f"(default {speed.DEFAULT_JSON})")
    sp.set_defaults(func=_cmd_speed)


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Show a warning as one line, ``warning: <message>`` on standard error (not Python's
    two lines with the source line that raised it, which means nothing to a user of the
    command line)."""
    print(f"warning: {message}", file=sys.stderr if file is None else file)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit code (2 for bad input; see
    :data:`benchmarks.verdicts.EXIT_CODES_HELP`)."""
    try:
        return _main(argv)
    except BrokenPipeError:  # the reader left (``setobs-bench list | head``): stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error when Python flushes stdout
        return 141  # 128 + SIGPIPE, as a shell reports a command killed by a closed pipe


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    warnings.showwarning = _one_line_warning
    try:
        return args.func(args)
    except BrokenPipeError:
        raise
    except USER_ERRORS as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # writing an output (a full disk, a folder removed meanwhile)
        print(f"error: {exc.strerror or type(exc).__name__}"
              + (f": {exc.filename}" if exc.filename else ""), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
