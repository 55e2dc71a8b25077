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

#: exit codes of ``python -m benchmarks run``
EXIT_OK, EXIT_VIOLATION, EXIT_BAD_INPUT, EXIT_CRASH = 0, 1, 2, 3

#: the meaning of each exit code of ``run``
EXIT_MEANINGS = {
    EXIT_OK: "every observer ran and no guaranteed observer missed the true state",
    EXIT_VIOLATION: "a guaranteed observer's set missed the true state (or became empty)",
    EXIT_BAD_INPUT: "bad input (config, scenario, options, output folder), nothing written",
    EXIT_CRASH: "an observer crashed (status 'error'), after the others ran",
}

EXIT_CODES_HELP = (
    "exit status: 0 every observer ran and no guaranteed observer missed the true state; "
    "1 a guaranteed observer's set missed the true state (or became empty); "
    "2 bad input (config, scenario, options, output folder), nothing written; "
    "3 an observer crashed (status 'error', its failing step in summary.csv), after the "
    "others ran. 1 takes precedence over 3."
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


def violating(summary: pd.DataFrame) -> pd.Series:
    """Rows of guaranteed observers whose sets missed the true state (or became empty)."""
    bad = summary["status"] == "empty"
    for col in (contained_column("exact"), contained_column("hull")):
        if col in summary.columns:
            bad = bad | (summary[col] == NO)
    return bad & summary["guaranteed"].astype(bool)


def reference_rows(summary: pd.DataFrame) -> pd.Series:
    """Rows that may serve as the reference (the minimum) of eq. (9): successful guaranteed
    observers without a containment violation."""
    return ((summary["status"] == "ok") & summary["guaranteed"].astype(bool)
            & ~violating(summary))


def exit_code(summary: pd.DataFrame) -> tuple[int, list[str]]:
    """Exit code of ``run`` and the lines that explain it (for stderr).

    Returns
    -------
    code : int
        :data:`EXIT_VIOLATION` if a guaranteed observer violates containment, else
        :data:`EXIT_CRASH` if an observer crashed, else :data:`EXIT_OK`.
    lines : list of str
        One line per kind of failure.
    """
    # one row per run (a sweep: per seed and option variant too)
    pairs = summary.drop_duplicates([c for c in ("scenario", "seed", "observer", "variant")
                                     if c in summary.columns])
    bad = pairs[violating(pairs)]
    crashed = pairs[pairs["status"] == "error"]
    lines = []
    if len(bad):
        lines.append("CONTAINMENT VIOLATIONS: " + ", ".join(
            f"{o} on {s}" for s, o in sorted(set(zip(bad["scenario"], bad["observer"],
                                                     strict=True)))))
    if len(crashed):
        lines.append("CRASHED: " + ", ".join(
            f"{r.observer} on {r.scenario} ({_where(r.failed_step)})"
            for r in crashed.itertuples(index=False)))
    code = EXIT_VIOLATION if len(bad) else EXIT_CRASH if len(crashed) else EXIT_OK
    return code, lines


def _where(step) -> str:
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
        :data:`EXIT_OK`, :data:`EXIT_VIOLATION` or :data:`EXIT_CRASH` (:func:`exit_code`).
    meaning : str
        What the exit code means (:data:`EXIT_MEANINGS`).
    problems : list of str
        One line per kind of failure (the lines ``run`` prints on stderr); empty when ok.
    ok : bool
        Whether the exit code is :data:`EXIT_OK`.

    Examples
    --------
    >>> import pandas as pd
    >>> s = pd.DataFrame({"scenario": ["s"], "observer": ["o"], "status": ["error"],
    ...                   "guaranteed": [True], "failed_step": [3]})
    >>> r = BenchResult(pd.DataFrame(), s)
    >>> r.exit_code, r.ok, r.problems
    (3, False, ['CRASHED: o on s (at step 3)'])
    >>> r.meaning
    "an observer crashed (status 'error'), after the others ran"
    """

    def __new__(cls, runs: pd.DataFrame, summary: pd.DataFrame) -> BenchResult:
        self = super().__new__(cls, (runs, summary))
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
