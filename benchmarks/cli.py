"""Command line: ``python -m benchmarks {run,report,list} ...``.

Bad input ends with a one-line ``error: ...`` on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import observers
from observers.errors import ObserverError
from observers.sets import SetError
from systems import ModelError, scenario_names

from .config import load_config
from .errors import ConfigError
from .report import write_report
from .runner import run_config

USER_ERRORS = (ConfigError, ModelError, ObserverError, SetError)


def _cmd_run(args) -> int:
    cfg = load_config(args.config)
    out = Path(args.out) if args.out else Path("results") / cfg.name
    _, summary = run_config(cfg, out, progress=False if args.no_progress else None)
    bad = summary[(summary["status"] == "ok") & (summary["violations"].fillna(0) > 0)
                  & summary["guaranteed"].astype(bool)]
    print(f"wrote {out / 'runs.csv'}, {out / 'summary.csv'}")
    statuses = summary.drop_duplicates(["scenario", "observer"])["status"].value_counts()
    print("status: " + ", ".join(f"{k} {v}" for k, v in statuses.items()))
    if len(bad):
        names = sorted(set(zip(bad["scenario"], bad["observer"], strict=True)))
        print("CONTAINMENT VIOLATIONS: " + ", ".join(f"{o} on {s}" for s, o in names),
              file=sys.stderr)
        return 1
    return 0


def _cmd_report(args) -> int:
    path = write_report(args.dir, args.out, figures=not args.no_figures)
    print(f"wrote {path}")
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
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (sub-commands run, report, list)."""
    p = argparse.ArgumentParser(prog="python -m benchmarks",
                                description="Guaranteed state estimator benchmarks")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a YAML benchmark config")
    r.add_argument("config", help="path to a YAML config (see benchmarks/configs/)")
    r.add_argument("--out", help="output folder (default results/<config name>)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.set_defaults(func=_cmd_run)
    rep = sub.add_parser("report", help="write the Markdown report and figures of a results dir")
    rep.add_argument("dir", help="folder with summary.csv (and runs.csv, meta.json)")
    rep.add_argument("--out", help="Markdown file to write (default DIR/report.md)")
    rep.add_argument("--no-figures", action="store_true", help="tables only")
    rep.set_defaults(func=_cmd_report)
    ls = sub.add_parser("list", help="list observers and scenarios")
    ls.add_argument("what", nargs="?", default="all", choices=["observers", "scenarios", "all"])
    ls.set_defaults(func=_cmd_list)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit code (2 for bad input)."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except USER_ERRORS as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
