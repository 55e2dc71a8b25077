"""The verdicts of a run: containment per observer (``yes`` / ``no`` / ``n/a``), which rows
may serve as the reference of eq. (9), and the exit code of ``run`` with its meaning
(:func:`exit_code`; in Python :class:`BenchResult`, what ``run_config`` returns).

A table never claims more than was checked: containment is ``yes`` only where the true state
is known and was found in every set of a complete run, ``no`` where it was outside at least
one set, and ``n/a`` everywhere else (no true state, no set produced, a run cut short, a set
whose exact membership could not be tested).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

YES, NO, NA = "yes", "no", "n/a"

#: the soundness verdict columns of ``summary.csv`` (``yes`` / ``no`` / ``n/a``): a row of a
#: guaranteed observer with ``no`` in any of them present is unsound: never the reference of
#: eq. (9), never called tighter by ``check``, never written by ``baseline --update``.
#: ``contained``: exact membership of the true state in every set (the gate computes it beside
#: the hull test of its subset); ``covers_exact``: every set's interval hull contains the
#: record's exact floor, the set of states consistent with the data (or, on a nonlinear
#: record, no verified consistent state found outside it; :mod:`benchmarks.run.floor`).
#: Extend this tuple with a new verdict column and every rule above applies to it.
SOUNDNESS_COLUMNS: tuple[str, ...] = ("contained", "covers_exact")

#: the containment mode of the regression gate: the hull test decides ``violations`` and
#: ``contained_hull`` (as the golden files hold them); exact membership gives ``contained``
HULL_AND_EXACT = "hull+exact"

#: exit codes of ``python -m benchmarks run``
EXIT_OK, EXIT_VIOLATION, EXIT_BAD_INPUT, EXIT_CRASH, EXIT_BAD_DATA = 0, 1, 2, 3, 4

#: the meaning of each exit code of ``run``
EXIT_MEANINGS = {
    EXIT_OK: "every observer ran and no guaranteed observer missed the true state or a state "
             "consistent with the data",
    EXIT_VIOLATION: "a guaranteed observer's set missed the true state or a state consistent "
                    "with the data (or became empty)",
    EXIT_BAD_INPUT: "bad input (config, scenario, options, output folder), nothing written",
    EXIT_CRASH: "an observer crashed (status 'error') or was stopped ('timeout', 'memory'), "
                "after the others ran",
    EXIT_BAD_DATA: "a record contradicts its model (status 'inconsistent'): bad data, no "
                   "observer blamed",
}

EXIT_CODES_HELP = (
    "exit status: 0 every observer ran and no guaranteed observer missed the true state or a "
    "state consistent with the data; 1 a guaranteed observer's set missed the true state or a "
    "state consistent with the data (covers_exact = no), or became empty; "
    "2 bad input (config, scenario, options, output folder), nothing written; "
    "3 an observer crashed (status 'error', its failing step in summary.csv) or was stopped "
    "over its time budget or memory limit (status 'timeout' or 'memory'), after the "
    "others ran; 4 a record contradicts its model (status 'inconsistent' on every row of "
    "that scenario: no initial state and noise in their sets reproduce its measurements), "
    "the results written. 1 takes precedence over 4, 4 over 3."
)


def contained_column(containment: str) -> str:
    """Name of the containment column of ``summary.csv``: ``contained`` for the exact
    membership test, ``contained_hull`` where the configuration asks for the interval-hull
    test only."""
    return "contained" if containment == "exact" else "contained_hull"


def containment_verdict(status: str, steps: int, in_set: np.ndarray | None,
                        decided: bool) -> str:
    """Containment verdict of one observer on one scenario.

    Parameters
    ----------
    status : str
        The run's status (``"ok"``, ``"diverged"``, ...).
    steps : int
        Number of steps of the scenario.
    in_set : ndarray of bool or None
        Per produced set, whether the true state lies in it; None if not checked (no true
        state).
    decided : bool
        Whether every test was of the kind the run promises (exact membership, or the hull
        where the configuration asks for it).

    Returns
    -------
    str
        ``"no"`` if the true state was outside a set; ``"yes"`` if the run is complete
        (status ``ok``, every step checked) and every test decided it inside; else ``"n/a"``.
    """
    if in_set is None:
        return NA
    if not np.all(in_set):
        return NO
    return YES if status == "ok" and len(in_set) == steps and decided else NA


def unsound(summary: pd.DataFrame) -> pd.Series:
    """Rows with ``no`` in a :data:`SOUNDNESS_COLUMNS` column (any observer)."""
    bad = pd.Series(False, index=summary.index)
    for col in SOUNDNESS_COLUMNS:
        if col in summary.columns:
            bad = bad | (summary[col].astype(str) == NO)
    return bad


def violating(summary: pd.DataFrame) -> pd.Series:
    """Rows of guaranteed observers whose sets missed the true state or a state consistent
    with the data (``no`` in a :data:`SOUNDNESS_COLUMNS` column), or became empty."""
    bad = (summary["status"] == "empty") | unsound(summary)
    for col in (contained_column("exact"), contained_column("hull")):
        if col in summary.columns:
            bad = bad | (summary[col] == NO)
    return bad & summary["guaranteed"].astype(bool)


def reference_rows(summary: pd.DataFrame) -> pd.Series:
    """Rows that may serve as the reference (the minimum) of eq. (9): successful guaranteed
    observers that violate containment on no scenario of the run (one proven unsound on one
    record is no reference on a record without true states either); never the exact reference
    ``Exact`` (family ``reference``: the floor, shown beside eq. 9 as the ``gap``)."""
    bad = violating(summary)
    keys = [c for c in ("observer", "variant") if c in summary.columns]
    who = pd.Series(list(zip(*(summary[k].astype(object).where(summary[k].notna(), "")
                               for k in keys), strict=True)), index=summary.index)
    unsound_anywhere = who.isin(set(who[bad]))
    reference = (summary["family"] == "reference") if "family" in summary.columns else False
    return ((summary["status"] == "ok") & summary["guaranteed"].astype(bool)
            & ~bad & ~unsound_anywhere & ~reference)


def exit_code(summary: pd.DataFrame) -> tuple[int, list[str]]:
    """Exit code of ``run`` and the lines that explain it (for stderr).

    Returns
    -------
    code : int
        :data:`EXIT_VIOLATION` if a guaranteed observer violates containment, else
        :data:`EXIT_CRASH` if an observer crashed or was stopped by its budget, else
        :data:`EXIT_OK`.
    lines : list of str
        One line per kind of failure.
    """
    # one row per run (a sweep: per seed and option variant too)
    pairs = summary.drop_duplicates([c for c in ("scenario", "seed", "observer", "variant")
                                     if c in summary.columns])
    bad = pairs[violating(pairs)]
    crashed = pairs[pairs["status"] == "error"]
    stopped = pairs[pairs["status"].isin(["timeout", "memory"])]
    bad_data = pairs[pairs["status"] == "inconsistent"]
    lines = []
    if len(bad):
        lines.append("CONTAINMENT VIOLATIONS: " + ", ".join(
            f"{o} on {s}{_how(r)}" for s, o, r in sorted(
                {(r.scenario, r.observer, r) for r in bad.itertuples(index=False)},
                key=lambda t: (t[0], t[1]))))
    if len(crashed):
        lines.append("CRASHED: " + ", ".join(
            f"{r.observer} on {r.scenario} ({_where(r.failed_step, r.message)})"
            for r in crashed.itertuples(index=False)))
    if len(stopped):
        lines.append("STOPPED: " + ", ".join(
            f"{r.observer} on {r.scenario} ({r.status}: {r.message})"
            for r in stopped.itertuples(index=False)))
    if len(bad_data):
        lines.append("RECORD INCONSISTENT WITH THE MODEL (bad data, no observer blamed): "
                     + ", ".join(sorted(set(bad_data["scenario"].astype(str)))))
    code = (EXIT_VIOLATION if len(bad) else EXIT_BAD_DATA if len(bad_data)
            else EXIT_CRASH if len(crashed) or len(stopped) else EXIT_OK)
    return code, lines


def _how(row) -> str:
    """`` (misses consistent states at k steps, first at step j)`` for a row that failed the
    exact floor, else ``""``."""
    if str(getattr(row, "covers_exact", "")) != NO:
        return ""
    k, j = getattr(row, "uncovered_steps", None), getattr(row, "first_uncovered_step", None)
    steps = f"{int(k)} step(s), " if pd.notna(k) else ""
    first = f"first at step {int(j)}" if pd.notna(j) and int(j) >= 0 else ""
    return f" (misses states consistent with the data: {steps}{first})"


def _where(step, message="") -> str:
    if isinstance(message, str) and message.startswith("worker process died"):
        return message
    return "in its design" if pd.isna(step) else f"at step {int(step)}"


class BenchResult(tuple):
    """What :func:`benchmarks.run_config` returns: the pair ``(runs, summary)`` (so
    ``runs, summary = run_config(...)`` works) with the verdict of the run, the same as the
    exit code of ``setobs-bench run``.

    Attributes
    ----------
    runs, summary : pandas.DataFrame
        The per-step rows and the per-state summary (``runs.csv``, ``summary.csv``).
    exit_code : int
        :data:`EXIT_OK`, :data:`EXIT_VIOLATION`, :data:`EXIT_BAD_DATA` or :data:`EXIT_CRASH`
        (:func:`exit_code`).
    meaning : str
        What the exit code means (:data:`EXIT_MEANINGS`).
    problems : list of str
        One line per kind of failure (the lines ``run`` prints on stderr); empty when ok.
    ok : bool
        Whether the exit code is :data:`EXIT_OK`.
    meta : dict
        The run's description (configuration, scenarios, executor, versions: what
        ``meta.json`` holds), empty where none was given.

    Examples
    --------
    >>> import pandas as pd
    >>> s = pd.DataFrame({"scenario": ["s"], "observer": ["o"], "status": ["error"],
    ...                   "guaranteed": [True], "failed_step": [3], "message": [""]})
    >>> r = BenchResult(pd.DataFrame(), s)
    >>> r.exit_code, r.ok, r.problems
    (3, False, ['CRASHED: o on s (at step 3)'])
    >>> r.meaning.startswith("an observer crashed")
    True
    """

    def __new__(cls, runs: pd.DataFrame, summary: pd.DataFrame,
                meta: dict | None = None) -> BenchResult:
        self = super().__new__(cls, (runs, summary))
        self.meta = meta or {}
        self.exit_code, self.problems = exit_code(summary)
        self.meaning = EXIT_MEANINGS[self.exit_code]
        return self

    @property
    def runs(self) -> pd.DataFrame:
        return self[0]

    @property
    def summary(self) -> pd.DataFrame:
        return self[1]

    @property
    def ok(self) -> bool:
        return self.exit_code == EXIT_OK

    def __repr__(self) -> str:
        return (f"BenchResult(exit_code={self.exit_code}: {self.meaning}; "
                f"{len(self.summary)} summary rows)")
