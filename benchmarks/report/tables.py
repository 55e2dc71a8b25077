"""The cells of the report tables, rendered by both the Markdown report
(:mod:`.markdown`) and the HTML page (:mod:`.html`): one source of the cells, two renderers.

* :func:`scenario_table_data` -- relative RMS per state (eq. 9, the published value beside it),
  average, times and the containment verdict of every observer on one scenario, observers that
  do not apply as status rows; :func:`scenario_table_caption` names its reference;
* :func:`relative_values` -- the ratios of that table (and of the heat map) with the sentence
  naming their reference;
* :func:`absolute_table_data` -- absolute RMS radii with the published ones
  (:func:`absolute_table_caption`);
* :func:`scenario_facts` -- the record length and the bounds of the noise and initial sets;
* :func:`scenario_notes` -- failures with their messages;
* :data:`INTRO` -- the paragraph that opens both reports;
* :func:`design_times_table` -- the offline designs' times (``setobs-bench designs``).

Every number cell is a :class:`~.numbers.Num`, written in its column's notation
(:func:`~.numbers.format_columns`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from observers.registry import table_order

from ..metrics import PHASE_COLUMNS, timed_in_parallel
from ..verdicts import NA, NO, contained_column, reference_rows, violating
from .numbers import Num, fmt, format_columns, markdown_table, text_table
from .paper import PaperRow, paper_rows, paper_status, paper_title
from .spread import row_spread_note, spread_note

#: the paragraph that opens the Markdown and the HTML report
INTRO = ("Relative RMS interval radius v_i (eq. 9 of Althoff & Rath 2021) per state: the RMS "
         "over the record of the radius of the interval hull of state i, divided by the "
         "smallest such RMS among a reference set of observers, named above every table and "
         "figure. Where a paper table exists the reference is the observers that table "
         "compares (so our ratios and the published ones, in parentheses, share their "
         "reference; observers the paper did not run, e.g. CZN in ARCH 2021, can be below 1); "
         "elsewhere it is every guaranteed observer of the run. `rel_rms` in summary.csv is "
         "always against all observers of the run. Times are medians per step on this "
         "machine; the papers' times (MATLAB, i7-8565U) are in parentheses where published. "
         "`contained`: `yes` if the true state lies in every estimated set (exact membership "
         "test; `contained (hull only)`: in every interval hull), `no` with the number of "
         "violating steps, `n/a` where it was not checked (no true state in the record); "
         "observers that do not apply to a scenario are rows with the reason. A row marked "
         "(unsound) violates containment and is never the reference of a ratio. `(n/a)` after "
         "the average and the time: the observer is not part of the published comparison "
         "(the paper has no row for it, e.g. ROPO, CZN, the data-driven observers), so there "
         "is no published value to deviate from. `gap`: how far an observer is from the best "
         "any guaranteed observer could do, its RMS radius over the RMS radius of the set of "
         "states consistent with the data (the exact floor, computed by the reference "
         "estimator `Exact`, first row; the filtered floor after y_k for observers that use "
         "y_k, the predicted one before it for those ready before it), averaged over the "
         "states (per state in the table below); on a nonlinear record an upper bound "
         "(`<=`, against an inner box of verified consistent states). `gap steady`: the same "
         "after the first 20 % of the record (the gap in operation: the first steps, where "
         "the initial set makes every observer and the floor alike, left out). `memory`: the "
         "floating-point values of the estimated set at steady state (median over the same "
         "steps; its peak is `memory_peak` in summary.csv). `covers exact`: `yes` "
         "if every interval hull contains the exact floor, `no` with the steps where a state "
         "consistent with the data lies outside it (unsound, whatever the true state did), "
         "`n/a` where nothing could prove it.")


def _by_observer(df: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """The rows of each observer of ``df`` sorted by state, in :func:`table_order` (one
    grouping per table: a mask per observer cost a report 2/3 of its rendering time)."""
    groups = {obs: g.sort_values("state") for obs, g in df.groupby("observer", sort=False)}
    return [(obs, groups[obs]) for obs in table_order(list(groups))]


def _contained_col(df: pd.DataFrame) -> str:
    hull = contained_column("hull")
    return hull if hull in df.columns else contained_column("exact")


def _status_cell(g: pd.DataFrame) -> str:
    """The ``contained`` cell: ``yes``, ``n/a`` (nothing to check it against, or not
    checked to the end), the number of violations, or the failure status; a row that is not
    guaranteed (a labelled CORA variant) says so, with its violations counted; an observer
    that does not apply says why."""
    status, verdict = g["status"].iloc[0], g[_contained_col(g)].iloc[0]
    if status == "unsupported":
        msg = str(g["message"].iloc[0]) if pd.notna(g["message"].iloc[0]) else ""
        obs = str(g["observer"].iloc[0])
        msg = msg[len(obs):].strip() if msg.startswith(obs) else msg
        return "unsupported" + (f": {msg}" if msg else "")
    if not bool(g["guaranteed"].iloc[0]) and status == "ok":
        viol = g["violations"].iloc[0]
        return "not guaranteed" + ("" if pd.isna(viol) else f": {int(viol)} violations")
    if verdict == NO:
        return f"**no: {int(g['violations'].iloc[0])} violations**"
    if status == "ok":
        return NA if pd.isna(verdict) else str(verdict)
    step = g["failed_step"].iloc[0]
    return f"{status}" + (f" (step {int(step)})" if pd.notna(step) else "")


def _gap_values(g: pd.DataFrame, column: str = "gap") -> np.ndarray:
    """The per-state gap of one observer's rows (``column``: ``gap`` over the whole record,
    ``gap_steady`` after its first 20 %; NaN where none: no floor, a failed run)."""
    if column not in g.columns or g["status"].iloc[0] != "ok":
        return np.full(len(g), np.nan)
    return pd.to_numeric(g[column], errors="coerce").to_numpy(float)


def _upper(g: pd.DataFrame) -> bool:
    return "gap_kind" in g.columns and str(g["gap_kind"].iloc[0]).startswith("upper")


def _gap_cell(g: pd.DataFrame, column: str = "gap") -> Num:
    """The ``gap`` (or ``gap steady``) cell: the mean over the states (``<=`` for an upper
    bound)."""
    gap = _gap_values(g, column)
    avg = float(np.mean(gap)) if np.isfinite(gap).all() else None
    return Num(avg, prefix="<= " if _upper(g) else "")


def _memory_cell(g: pd.DataFrame) -> Num:
    """The ``memory`` cell: the values of the estimated set at steady state (NaN: unknown)."""
    value = g["memory"].iloc[0] if "memory" in g.columns else None
    return Num(None if value is None or pd.isna(value) else float(value))


def _covers_cell(g: pd.DataFrame) -> str:
    """The ``covers exact`` cell (:data:`benchmarks.verdicts.SOUNDNESS_COLUMNS`)."""
    if "covers_exact" not in g.columns:
        return NA
    verdict = str(g["covers_exact"].iloc[0])
    if verdict != NO:
        return verdict if verdict in ("yes", NA) else NA
    k, j = g["uncovered_steps"].iloc[0], g["first_uncovered_step"].iloc[0]
    steps = f"{int(k)} steps" if pd.notna(k) else "consistent states outside"
    first = f", first {int(j)}" if pd.notna(j) and int(j) >= 0 else ""
    return f"**no: {steps}{first}**"


def gap_table_data(df: pd.DataFrame, meta: dict) -> tuple[list[str], list[list[Any]]] | None:
    """Header and rows of the gap to the floor per state (observer x state, the floor it is
    held against, the mean); ``None`` where no row has a gap (no floor)."""
    if "gap" not in df.columns or not pd.to_numeric(df["gap"], errors="coerce").notna().any():
        return None
    sc = df["scenario"].iloc[0]
    info = meta.get("scenarios", {}).get(sc, {})
    n = int(df["state"].max()) + 1
    names = info.get("state_names") or [f"x{i + 1}" for i in range(n)]
    show = list(range(n)) if n <= 12 else []
    head = ["Observer", "floor"] + [f"g{i + 1} {names[i]}" for i in show] + ["mean",
                                                                              "steady mean"]
    rows: list[list[Any]] = []
    for obs, g in _by_observer(df):
        if g["status"].iloc[0] == "unsupported":
            continue
        gap = _gap_values(g)
        pre = "<= " if _upper(g) else ""
        rows.append([obs, str(g["floor"].iloc[0])] + [Num(gap[i], prefix=pre) for i in show]
                    + [Num(float(np.mean(gap)) if np.isfinite(gap).all() else None,
                           prefix=pre), _gap_cell(g, "gap_steady")])
    return head, rows


def phase_table_data(df: pd.DataFrame) -> tuple[list[str], list[list[Any]]] | None:
    """Header and rows of the time per phase of a step, for the observers that time their
    phases (the numpy path of the family loops: nonlinear models, constrained zonotopes);
    ``None`` where no observer does."""
    phases = list(PHASE_COLUMNS.values())
    if not set(phases) <= set(df.columns):
        return None
    per = df.drop_duplicates("observer").set_index("observer")
    timed = per[phases].apply(pd.to_numeric, errors="coerce")
    keep = timed.notna().any(axis=1) & (per["status"] == "ok")
    if not keep.any():
        return None
    head = ["Observer", "prediction", "update", "reduction", "LPs in the step",
            "step (median)", "interval hull (median)"]
    rows = [[obs] + [Num(timed.loc[obs, c]) for c in phases]
            + [Num(per.loc[obs, "step_ms"]), Num(per.loc[obs, "hull_ms"])]
            for obs in table_order(per.index[keep])]
    return head, rows


PHASE_CAPTION = ("Time per phase of a step, in ms: the mean over the record of the "
                 "prediction, the measurement update, the order or constraint reduction and "
                 "the linear programs inside a step, as the observer times them (the numpy "
                 "path of the family loops; steps taken by a compiled kernel are not split); "
                 "beside them the median step and the median interval hull of the returned set.")


def gap_table_caption(df: pd.DataFrame) -> str:
    """What the gap table shows and against what."""
    upper = bool(df.get("gap_kind", pd.Series(dtype=str)).astype(str).str.startswith(
        "upper").any())
    if upper:
        return ("Gap to the floor, per state: RMS radius over the RMS radius of an inner box of "
                "the consistent set (verified consistent states found by the falsifier at the "
                "searched steps), an upper bound of the gap to the exact set; 1 would be "
                "optimal.")
    return ("Gap to the exact floor, per state: RMS radius over the RMS radius of the set of "
            "states consistent with the data (reference estimator `Exact`; `filtered`: after "
            "y_k, `predicted`: before it); 1 is optimal: no guaranteed observer can be "
            "tighter.")


def paper_relative(df: pd.DataFrame, paper_names) -> pd.Series:
    """Eq. (9) with the minimum taken over the observers the published table compares (so
    that our ratios and the paper's share their reference); NaN where none of them ran."""
    ok = reference_rows(df) & df["observer"].isin(list(paper_names))
    best = df[ok].groupby("state")["rms_radius"].min()
    return df["rms_radius"] / df["state"].map(best)


def _paper(df: pd.DataFrame, meta: dict) -> tuple[str | None, str, dict[str, PaperRow]]:
    """The published table of the scenario of ``df``: its key, variant and rows."""
    sc = df["scenario"].iloc[0]
    info = meta.get("scenarios", {}).get(sc, {})
    n = int(df["state"].max()) + 1
    key = info.get("paper_table")
    variant = "nonlinear" if "nonlinear" in sc else "linear"
    return key, variant, paper_rows(key, n, variant)


def published_table(df: pd.DataFrame, meta: dict) -> str | None:
    """The key of the published table whose values the scenario table of ``df`` (one
    scenario) shows in parentheses, ``None`` if it shows none (cited at the end of a report,
    :mod:`.citation`)."""
    key, _, paper = _paper(df, meta)
    return key if paper else None


def relative_values(df: pd.DataFrame, meta: dict) -> tuple[pd.Series, str]:
    """The ratios v_i of the scenario table (and of the heat map) for the rows of ``df`` (one
    scenario), and the sentence naming their reference.

    Where a paper table exists the minimum of eq. (9) is taken over the observers that table
    compares (:func:`paper_relative`), like the paper's own; otherwise over all guaranteed
    observers of the run without a violation (``rel_rms``).
    """
    key, variant, paper = _paper(df, meta)
    if paper:
        title = paper_title(key, variant)
        return paper_relative(df, paper), (
            f"reference: the smallest RMS radius of each state among the observers compared "
            f"in {title} that ran here without a violation (the paper's own reference)")
    return df["rel_rms"], ("reference: the smallest RMS radius of each state among all "
                           "guaranteed observers of this run without a violation")


def scenario_table(df: pd.DataFrame, meta: dict) -> str:
    """Markdown table of one scenario (:func:`scenario_table_data`)."""
    return markdown_table(*scenario_table_data(df, meta))


def scenario_table_caption(df: pd.DataFrame, meta: dict) -> str:
    """The sentence above a scenario table: what v_i is relative to, where the published
    values and times come from, and how the times were measured."""
    key, variant, paper = _paper(df, meta)
    _, reference = relative_values(df, meta)
    parts = [f"v_i = RMS radius of state i / {reference[len('reference: '):]}."]
    if paper:
        title = paper_title(key, variant)
        times = any(p.t_ms for p in paper.values())
        parts.append(f"In parentheses: {title}" + (" (its times: MATLAB, i7-8565U)."
                                                   if times else "."))
    else:
        parts.append("No published table for this scenario.")
    if _any_spread(df, meta):
        parts.append("In brackets: how far a value moves across the OpenBLAS kernels of one "
                     "machine, where more than 1e-4 (reports/kernels.md; results/baseline/"
                     "SENSITIVITY.md for an observer whose published design is undetermined).")
    if paper:
        parts.append("Every other value is the same on every OpenBLAS kernel to 1e-4 "
                     "(reports/kernels.md). A row labelled [pca-cora] runs CORA's PCA basis "
                     "(LAPACK's singular vectors, whatever its rounding makes them where "
                     "singular values repeat) for comparison with the published row; the "
                     "others run the deterministic basis.")
    par = timed_in_parallel(df)
    parts.append("Times: median per step on this machine" + (
        ", measured while jobs ran in parallel (indicative only)." if par else "."))
    return " ".join(parts)


def _config(meta: dict) -> str | None:
    """The name of the configuration of a result store's ``meta``."""
    cfg = meta.get("config")
    return cfg.get("name") if isinstance(cfg, dict) else None


def _any_spread(df: pd.DataFrame, meta: dict) -> bool:
    """Whether a cell of the scenario table ``df`` carries a measured kernel spread."""
    sc = df["scenario"].iloc[0]
    ok = df[df["status"] == "ok"]
    return any(spread_note(o, sc, int(i), _config(meta)) is not None
               for o, i in zip(ok["observer"], ok["state"], strict=True))


def scenario_table_data(df: pd.DataFrame, meta: dict) -> tuple[list[str], list[list[str]]]:
    """Header and rows (cell strings) of one scenario's table: relative RMS per state (paper
    value in parentheses), average, per-step time, design time and containment; an observer
    that does not apply (``unsupported``) is a row with the reason.

    The ratios are :func:`relative_values` (their reference: :func:`scenario_table_caption`).
    Each number column is written in one notation. The Markdown and the HTML report both
    render these cells (the LaTeX tables the cells of :func:`scenario_table_cells`)."""
    head, rows = scenario_table_cells(df, meta)
    return head, format_columns(rows)


def scenario_table_cells(df: pd.DataFrame, meta: dict) -> tuple[list[str], list[list[Any]]]:
    """The header and the unformatted cells (:class:`~.numbers.Num` or strings) of
    :func:`scenario_table_data`."""
    key, variant, paper = _paper(df, meta)
    sc = df["scenario"].iloc[0]
    info = meta.get("scenarios", {}).get(sc, {})
    n = int(df["state"].max()) + 1
    names = info.get("state_names") or [f"x{i + 1}" for i in range(n)]
    show = list(range(n)) if n <= 8 else []
    contained = "contained" if _contained_col(df) == contained_column("exact") else (
        "contained (hull only)")
    # times of jobs that ran concurrently (``run --jobs``) are marked in the header itself
    par = " (parallel)" if timed_in_parallel(df) else ""
    head = (["Observer"] + [f"v{i + 1} {names[i]}" for i in show]
            + ["avg", "gap", "gap steady", f"step ms{par}", f"hull ms{par}", f"design s{par}",
               "memory", contained, "covers exact"])
    rows: list[list[Any]] = []
    rel, _ = relative_values(df, meta)
    df = df.assign(_rel=rel, _bad=violating(df))
    for obs, g in _by_observer(df):
        if g["status"].iloc[0] == "unsupported":
            rows.append([obs] + [Num(None)] * (len(show) + 7) + [_status_cell(g), NA])
            continue
        p = paper.get(obs.split("[")[0])  # a labelled variant NAME[tag]: NAME's published row
        r = g["_rel"].to_numpy(float)
        cells: list[Any] = [f"**{obs}** (unsound)" if g["_bad"].any() else obs]
        ok = g["status"].iloc[0] == "ok"
        for i in show:
            cells.append(Num(r[i], p.v[i] if p and p.v else None,
                             caveat=spread_note(obs, sc, i, _config(meta)) if ok else None))
        avg = float(np.mean(r)) if g["status"].iloc[0] == "ok" else float("nan")
        pstat = paper_status(key, n, obs, variant)
        # the states of a wide table are not shown: its average carries their spread
        row_note = row_spread_note(obs, sc, n, _config(meta)) if ok and not show else None
        if paper and p is None and not pstat:  # not part of the published comparison
            cells += [Num(avg, note=NA, caveat=row_note), _gap_cell(g),
                      _gap_cell(g, "gap_steady"), Num(g["step_ms"].iloc[0], note=NA)]
        else:
            cells.append(Num(avg, p.avg if p else None, caveat=row_note) if not pstat
                         else Num(avg, note=pstat, caveat=row_note))
            cells += [_gap_cell(g), _gap_cell(g, "gap_steady")]
            cells.append(Num(g["step_ms"].iloc[0], p.t_ms if p else None))
        cells += [Num(g["hull_ms"].iloc[0]), Num(g["design_s"].iloc[0]), _memory_cell(g),
                  _status_cell(g), _covers_cell(g)]
        rows.append(cells)
    return head, rows


def absolute_table(df: pd.DataFrame, meta: dict) -> str:
    """Markdown table of absolute RMS radii (:func:`absolute_table_data`); ``""`` if none."""
    data = absolute_table_data(df, meta)
    return markdown_table(*data) if data else ""


def absolute_table_caption(df: pd.DataFrame, meta: dict) -> str:
    """The sentence above the absolute table: what its published values are."""
    key, variant, paper = _paper(df, meta)
    text = "Absolute RMS radii r_i (no ratio: every observer on its own)"
    if any(p.absolute for p in paper.values()):
        return (text + f"; in parentheses {paper_title(key, variant)}'s v_i times its "
                "smallest absolute radius of state i (the table's own reference).")
    return text + "."


def absolute_table_data(df: pd.DataFrame, meta: dict) -> tuple[list[str], list[list[str]]] | None:
    """Header and rows of the absolute RMS radii (paper: relative value times its smallest
    absolute radius); ``None`` above 8 states."""
    data = absolute_table_cells(df, meta)
    return None if data is None else (data[0], format_columns(data[1]))


def absolute_table_cells(df: pd.DataFrame, meta: dict
                         ) -> tuple[list[str], list[list[Any]]] | None:
    """The header and the unformatted cells of :func:`absolute_table_data`."""
    sc = df["scenario"].iloc[0]
    info = meta.get("scenarios", {}).get(sc, {})
    n = int(df["state"].max()) + 1
    if n > 8:
        return None
    paper = paper_rows(info.get("paper_table"), n)
    head = ["Observer"] + [f"r{i + 1}" for i in range(n)]
    rows: list[list[Any]] = []
    for obs, g in _by_observer(df):
        p = paper.get(obs)
        r = g["rms_radius"].to_numpy(float)
        ok = g["status"].iloc[0] == "ok"
        rows.append([obs] + [Num(r[i], p.absolute[i] if p and p.absolute else None,
                                 caveat=spread_note(obs, sc, i, _config(meta)) if ok else None)
                             for i in range(n)])
    return head, rows


def _vector(values: list[float], term: str) -> str:
    """``|term| <= r`` for a vector of radii (one value if all are equal, a range if long)."""
    v = np.asarray(values, float)
    if v.size and np.all(v == v[0]):
        return f"|{term}| ≤ {fmt(v[0])}" + (f" (i = 1..{v.size})" if v.size > 1 else "")
    if v.size <= 8:
        return f"|{term}| ≤ (" + ", ".join(fmt(x) for x in v) + ")"
    return f"|{term}| ≤ {fmt(v.min())} .. {fmt(v.max())} (i = 1..{v.size})"


def scenario_facts(info: dict) -> str:
    """One sentence on a scenario's record and sets (from ``meta.json``): its length and time
    step, and per set (W, V, X0) its interval-hull radii, its centre when not zero and whether
    it is that box. ``""`` where ``meta.json`` has none of these."""
    parts = []
    if info.get("N"):
        dt = info.get("dt")
        parts.append(f"record: {int(info['N'])} steps" + (
            f" of {fmt(dt)} s (t = 0 .. {fmt(dt * (int(info['N']) - 1))} s)" if dt else ""))
    sets = info.get("sets") or {}
    terms = {"W": ("process noise W", "w_i"), "V": ("measurement noise V", "v_i"),
             "X0": ("initial set X0", "x0_i - c_i")}
    for name, (label, term) in terms.items():
        s = sets.get(name)
        if not s:
            continue
        text = f"{label}: {_vector(s['radius'], term)}"
        centre = np.asarray(s.get("center", []), float)
        if name != "X0" and centre.size and np.any(centre != 0):
            text += " around (" + ", ".join(fmt(x) for x in centre) + ")"
        if name == "X0" and centre.size:
            text += (" with c = (" + ", ".join(fmt(x) for x in centre[:8])
                     + (", ..." if centre.size > 8 else "") + ")")
        if not s.get("box"):
            k = s.get("generators")
            text += f" (interval hull of a zonotope with {k} generator{'s' if k != 1 else ''})"
        parts.append(text)
    return ("; ".join(parts) + ".") if parts else ""


def scenario_notes(full: pd.DataFrame) -> list[str]:
    """One line per observer that failed on a scenario (status and reason); observers that do
    not apply are status rows of the table (:func:`scenario_table_data`), not notes."""
    failures = full[~full["status"].isin(["ok", "unsupported"])].drop_duplicates("observer")
    return [f"{r['observer']}: {r['status']}: {r['message']}" for _, r in failures.iterrows()]


def design_times_table(done: list[tuple[str, str, str, float]], top: int | None = None) -> str:
    """The per-design times of :func:`benchmarks.run.designs.prewarm`, slowest first, as a
    plain-text table.

    A design shared by several observers (e.g. the PRad-C/D centre) is computed by the first
    worker that needs it; the others wait for it on the cache lock, so their time is the
    wait.  A cached design shows the time of loading it.
    """
    rows = sorted(done, key=lambda r: -r[3])[:top]
    return text_table(["design", "status", "seconds"],
                      [[f"{s}: {o}", st, fmt(t, 3)] for s, o, st, t in rows],
                      right=[False, False, True])
