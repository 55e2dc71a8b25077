"""Soundness audit: does the true state stay in every estimated set, on many realisations?

``python -m benchmarks audit`` runs every registered observer on ``R`` seeded realisations
(default 100) of each audit scenario and tests, at every step, whether the true state lies in
the estimated set with the exact membership tests of :mod:`benchmarks.run.membership`
(tolerance ``max(scenario tolerance, 1e-8 * max(1, |x_k|_inf))``).  Realisation ``i`` uses
seed ``i`` and the kind ``KINDS[i % 5]``:

``uniform``, ``gaussian``, ``vertex``
    the scenario's own simulation (``systems.scenario(name, seed=i, noise=...)``) with
    uniform, truncated-Gaussian, or random-vertex noise (``w_k``, ``v_k`` and ``x_0`` at
    random vertices of ``W``, ``V`` and ``X0``, drawn anew at every step).
``vertex-hold`` (adversarial noise)
    ``x_0`` at a random vertex of ``X0``; ``w_k`` and ``v_k`` at vertices of ``W`` and ``V``
    held for random dwell times (uniform in 1..N steps, so some runs keep one vertex all the
    way): a persistent extreme disturbance drives the state to the boundary of its reachable
    set, where the estimated sets are tight; the scenario's nominal input.
``worst-input`` (adversarial input and noise)
    the noise of ``vertex-hold`` and a bang-bang input at the bounds of the scenario's nominal
    input range (per channel; ``+-1`` around a channel the record keeps constant).  "Worst
    case" means the largest excursion of the state: for a random direction ``d`` and a random
    window of ``H`` steps (5..50), ``u_k = mid + amp * sign(B' (A')^(H-1-j) d_w)`` at position
    ``j`` of each window maximises ``d_w' x`` at the window's end, and ``d_w`` alternates
    between ``d`` and ``-d`` from window to window, so the state swings between extremes.

``python -m benchmarks audit --short`` (CI, after ``make check``) audits only the adversarial
kinds of the first :data:`SHORT_REALISATIONS` realisations (:data:`ADVERSARIAL`: one each of
``vertex``, ``vertex-hold`` and ``worst-input``) of every scenario, into ``results/audit-short``:
a few minutes, so that an unsound change cannot pass CI by re-baselining the gate.

A hull that misses an exact floor is a violation only if it also misses the floor solved again
from scratch: the floor's bounds are sound outer bounds from the dual points of its incremental
LPs and, on a degenerate record, can exceed the exact hull by more than the coverage slack
(vehicle6d-sim, vertex realisation 2, step 136: the floor's x6 upper bound 0.7281174 against
0.7281141 by an independent batch LP, and MHE's sound 0.7281149 in between).  Each such step
(at most :data:`FLOOR_RECHECKS` per realisation; beyond them a miss counts) is re-solved by
the explicit LP of the record (:func:`_reference_hull`: states and noise factors as
variables, each bound from scratch by HiGHS at its default tolerances; its optima are
consistent trajectories to those tolerances, which a sound hull must contain), and the hull is
held against them with the same slack.  (The references of
:mod:`observers.numerics.exact_reference`, at tolerance 1e-10, call that record's thin
consistent set infeasible at step 136.)

Failures are counted, not raised: ``noGain``, ``diverged`` (its steps before divergence are
still checked) and ``error`` runs are listed per observer.  The full audit's rows (observer x
scenario, a line per realisation kind) are a result store, ``results/soundness/``, re-run where
stale (:mod:`.audit_store`); ``reports/soundness.md`` is rendered from it
(:mod:`.audit_report`: runs, steps, violations, worst violation per observer and scenario;
non-guaranteed baselines in their own table).  A violation by a guaranteed observer makes the
command exit with status 1.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import time

import numpy as np
import pandas as pd

import observers
import systems
from systems import ModelError, Scenario, edge

from ..errors import ConfigError
from ..run.executors import run_tasks
from ..run.floor import EXACT, RecordFloor, floor_columns, misses_floor, observer_floor
from ..run.floors import compute_floor
from ..run.membership import MembershipTester
from ..run.progress import progress_bar
from ..run.rows import merge_options, run_observer

AUDIT_SCENARIOS = ("vehicle2d-sim", "vehicle6d-sim", "tank6-linear", "alamo2d-sim",
                   "tank6-nonlinear", "vanderpol-sim")
KINDS = ("uniform", "gaussian", "vertex", "vertex-hold", "worst-input")
NOISE_OF_KIND = {"uniform": "uniform", "gaussian": "gaussian-truncated", "vertex": "vertex"}
#: relative part of the membership tolerance: the LP resolves distances to ~1e-9 on the
#: ill-conditioned generator matrices of long runs, and below 1e-8 relative a "violation"
#: could not be told from the rounding of hundreds of floating-point steps
REL_TOL = 1e-8
DEFAULT_REALISATIONS = 100
#: the adversarial realisation kinds, and the realisations the short audit draws them from
ADVERSARIAL = ("vertex", "vertex-hold", "worst-input")
#: (5: one realisation of each adversarial kind per scenario, 3 runs per pair, about 3 min on
#: 2 workers; with 10, two of each, it was CI's last 6.4 min)
SHORT_REALISATIONS = 5
#: realisations per scenario (the first audited ones) whose sets are also held against the
#: record's floor (the exact consistent set, or the falsifier's verified consistent states on
#: a nonlinear record): a few, since the exact reference of a 350-step record costs ~30 s
FLOOR_REALISATIONS = 10
#: (1: the vertex realisation of each scenario; the second, vertex-hold, floor alone cost
#: 104 s of LPs on the 6-D vehicle, a third of the short audit's CPU time in CI)
SHORT_FLOOR_REALISATIONS = 1
#: steps per realisation whose miss of an exact floor is re-solved by the dense reference
#: before it counts (each costs 2n LPs over the whole record so far)
FLOOR_RECHECKS = 3


@dataclasses.dataclass(frozen=True)
class Realisations:
    """Which realisations of each scenario an audit runs: those among the first ``count``
    whose kind is in ``kinds``; the first ``floors`` of them are also held against the
    record's floor."""

    count: int = DEFAULT_REALISATIONS
    kinds: tuple[str, ...] = KINDS
    floors: int = FLOOR_REALISATIONS


#: the short audit's realisations (``audit --short``, the proof of a tighter observer)
SHORT = Realisations(SHORT_REALISATIONS, ADVERSARIAL, SHORT_FLOOR_REALISATIONS)
#: the edge-case audit's realisations (:mod:`systems.edge`): the ``vertex-hold`` realisation
#: (realisation 3; x0 at a vertex of X0, noise held at vertices) of every case, held against
#: the record's floor too; ``audit --edge`` on the short and the long records, CI's
#: ``--edge --short`` on the short ones
EDGE_FULL = Realisations(4, ("vertex-hold",), 1)
EDGE_SHORT = EDGE_FULL
RESULT_COLUMNS = ["observer", "guaranteed", "scenario", "kind", "runs", "steps", "violations",
                  "undecided", "worst_violation", "worst_at", "floor_steps", "uncovered",
                  "uncovered_at", "ok", "noGain", "unsupported", "diverged", "empty",
                  "error", "lp_tests", "seconds", "reasons"]
#: the characters of a failed run's message kept in ``reasons``
REASON_CHARS = 160


# -- realisations ---------------------------------------------------------------------------
def held_vertices(rng: np.random.Generator, steps: int, m: int) -> np.ndarray:
    """``steps x m`` sign vectors (vertices of the unit box), each held for a random dwell
    time uniform in ``1..steps``."""
    out = np.empty((steps, m))
    k = 0
    while k < steps:
        dwell = int(rng.integers(1, steps + 1))
        out[k:k + dwell] = rng.choice([-1.0, 1.0], size=m)
        k += dwell
    return out


def bang_bang_pattern(A, B, d: np.ndarray, H: int) -> np.ndarray:
    """Signs ``s_j = sign(B' (A')^(H-1-j) d)`` (H x nu): among inputs ``|u_j| <= 1`` the
    sequence that maximises ``d' x_H`` for ``x_{j+1} = A x_j + B u_j`` from ``x_0 = 0``."""
    A, B = np.asarray(A, float), np.asarray(B, float)
    pattern = np.empty((H, B.shape[1]))
    m = np.asarray(d, float)
    for j in reversed(range(H)):
        pattern[j] = np.where(B.T @ m >= 0, 1.0, -1.0)
        m = A.T @ m
    return pattern


def worst_case_input(system, u_nominal: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Bang-bang input at the bounds of the nominal input range that swings the state between
    extremes along a random direction (see the module docstring)."""
    u_nominal = np.asarray(u_nominal, float)
    N, nu = u_nominal.shape
    if nu == 0:
        return u_nominal.copy()
    lo, hi = u_nominal.min(axis=0), u_nominal.max(axis=0)
    flat = hi <= lo
    lo, hi = np.where(flat, lo - 1.0, lo), np.where(flat, hi + 1.0, hi)
    mid, amp = 0.5 * (lo + hi), 0.5 * (hi - lo)
    H = int(rng.integers(5, 51))
    if hasattr(system, "A"):
        d = rng.normal(size=system.n)
        pattern = bang_bang_pattern(system.A, system.B, d / np.linalg.norm(d), H)
    else:  # no linear model: a random sign pattern, switched the same way
        pattern = rng.choice([-1.0, 1.0], size=(H, nu))
    k = np.arange(N)
    window_sign = np.where((k // H) % 2 == 0, 1.0, -1.0)[:, None]
    return mid + amp * window_sign * pattern[k % H]


def simulate_factors(system, u: np.ndarray, xi0: np.ndarray, xi_w: np.ndarray,
                     xi_v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """True states and measurements for given generator factors of ``x0``, ``w_k``, ``v_k``
    (``x_{k+1} = f(x_k, u_k) + w_k``, ``y_k = h(x_k) + v_k``); returns ``(x_true, y)``."""
    N = xi_v.shape[0]
    X = np.empty((N, system.n))
    x = system.X0.c + system.X0.G @ xi0
    for k in range(N):
        X[k] = x
        x = system.dynamics(x, u[k]) + system.W.c + system.W.G @ xi_w[k]
    Y = system.outputs(X) + system.V.c + xi_v @ system.V.G.T
    return X, Y


def scenario(name: str, **kwargs) -> Scenario:
    """The audit's scenario ``name``: a named scenario of :mod:`systems`, or an edge case of
    :mod:`systems.edge` (the degenerate systems of ``audit --edge``)."""
    if name in edge.SCENARIOS:
        return edge.scenario(name, **kwargs)
    return systems.scenario(name, **kwargs)


def realisation(name: str, index: int) -> tuple[str, Scenario]:
    """Realisation ``index`` of scenario ``name``: ``(kind, scenario)`` (seed = index)."""
    kind = KINDS[index % len(KINDS)]
    if kind in NOISE_OF_KIND:
        return kind, scenario(name, seed=index, noise=NOISE_OF_KIND[kind])
    base = scenario(name, seed=index)
    s, N = base.system, base.N
    rng = np.random.default_rng([index, KINDS.index(kind)])
    u = np.asarray(base.u, float)
    if kind == "worst-input":
        u = worst_case_input(s, u, rng)
    xi0 = rng.choice([-1.0, 1.0], size=s.X0.num_generators)
    x_true, y = simulate_factors(s, u, xi0, held_vertices(rng, N, s.W.num_generators),
                                 held_vertices(rng, N, s.V.num_generators))
    return kind, dataclasses.replace(
        base, u=u, y=y, x_true=x_true,
        description=f"{base.description}; audit realisation {index} ({kind})")


@functools.lru_cache(maxsize=8)
def realisations(name: str, count: int) -> tuple[tuple[str, Scenario], ...]:
    """The first ``count`` realisations of ``name`` (cached per process)."""
    return tuple(realisation(name, i) for i in range(count))


def check_scenario(name: str) -> None:
    """Raise a one-line error unless ``name`` is a simulated scenario with true states."""
    try:
        sc = scenario(name)
    except ModelError as exc:
        raise ConfigError(f"audit: {exc}") from None
    if sc.x_true is None:
        raise ConfigError(f"audit: scenario '{name}' has no true states (use a simulated one, "
                          f"e.g. {', '.join(AUDIT_SCENARIOS)})")
    try:
        scenario(name, seed=0, noise="vertex")
    except ModelError:
        raise ConfigError(f"audit: scenario '{name}' is a fixed record; the audit needs a "
                          "simulated one (accepting seed and noise)") from None


# -- audit of one observer on one scenario --------------------------------------------------
#: run statuses counted per realisation kind (anything else counts as "error")
STATUSES = ("ok", "noGain", "unsupported", "diverged", "empty")


def tolerance(sc: Scenario, x: np.ndarray) -> float:
    """Membership tolerance at true state ``x``."""
    return max(sc.tolerance, REL_TOL * max(1.0, float(np.abs(x).max(initial=0.0))))


@functools.lru_cache(maxsize=16)
def _floor(scenario: str, index: int) -> RecordFloor:
    """The floor of realisation ``index`` of ``scenario`` (once per process; the exact hulls
    are also cached on disk, so the workers of the other observers read them)."""
    return compute_floor(realisation(scenario, index)[1])


def audit_pair(scenario: str, observer: str, count: int,
               kinds: tuple[str, ...] = KINDS, floors: int = 0) -> list[dict]:
    """Audit ``observer`` on those of the first ``count`` realisations of ``scenario`` whose
    kind is in ``kinds``; one row per kind.  The sets of the first ``floors`` audited
    realisations are also held against the record's floor (:mod:`benchmarks.run.floor`):
    ``uncovered`` counts the steps where the interval hull misses a state consistent with
    the data."""
    info = observers.get(observer)
    rows = {k: {"observer": observer, "guaranteed": info.guaranteed, "scenario": scenario,
                "kind": k, "runs": 0, "steps": 0, "violations": 0, "undecided": 0,
                "worst_violation": 0.0, "worst_at": "", "floor_steps": 0, "uncovered": 0,
                "uncovered_at": "", "ok": 0, "noGain": 0, "unsupported": 0,
                "diverged": 0, "empty": 0,
                "error": 0, "lp_tests": 0, "seconds": 0.0, "reasons": ""} for k in KINDS}
    reasons: dict[str, list[str]] = {k: [] for k in KINDS}
    audited = 0
    for index, (kind, sc) in enumerate(realisations(scenario, count)):
        if kind not in kinds:
            continue
        audited += 1
        t0 = time.perf_counter()
        row = rows[kind]
        row["runs"] += 1
        tester = MembershipTester()
        try:
            run = run_observer(observer, sc, merge_options(observer, sc), "hull",
                               keep_sets=True)
        except ConfigError as exc:  # an option rejected for this system: an error run
            row["error"] += 1
            _note_reason(reasons[kind], "error", str(exc))
            continue
        status = run.status if run.status in STATUSES else "error"
        row[status] += 1
        if status != "ok":
            _note_reason(reasons[kind], status, run.message)
        if run.status == "empty":  # the true state is in no empty set: a violation
            row["violations"] += 1
            row["worst_violation"] = np.inf
            row["worst_at"] = f"seed {index}, step {run.result.failed_step} (empty set)"
        res = run.result
        sets = res.sets if res is not None else []
        for k, S in enumerate(sets):
            x = sc.x_true[k]
            m = tester.test(S, x, tolerance(sc, x), hull=(res.lo[k], res.hi[k]))
            if m.inside is None:
                row["undecided"] += 1
            elif not m.inside:
                row["violations"] += 1
                if m.distance > row["worst_violation"]:
                    row["worst_violation"] = m.distance
                    row["worst_at"] = f"seed {index}, step {k}"
        row["steps"] += len(sets)
        row["lp_tests"] += tester.counts.get("lp", 0)
        row["seconds"] += time.perf_counter() - t0
        if (audited <= floors and res is not None and len(sets)
                and not (scenario in edge.SCENARIOS and edge.no_floor(scenario))):
            _hold_to_floor(row, _floor(scenario, index), observer, res, sc, run.status, index)
    for kind, row in rows.items():
        row["reasons"] = " | ".join(reasons[kind])
    return [r for r in rows.values() if r["runs"]]


def _note_reason(seen: list[str], status: str, message) -> None:
    """Add ``status: message`` (its first line, at most :data:`REASON_CHARS` characters) to
    ``seen`` unless it is there: why a run refused, failed or ended early."""
    text = str(message or "").strip().splitlines()
    line = f"{status}: {text[0][:REASON_CHARS] if text else 'no message'}"
    if line not in seen:
        seen.append(line)


def _hold_to_floor(row: dict, floor: RecordFloor, observer: str, res, sc: Scenario,
                   status: str, index: int) -> None:
    """Count the steps where ``res``'s hulls miss the record's floor into ``row``."""
    if not floor.usable:
        return
    N, n = sc.N, sc.system.n
    lo, hi = np.full((N, n), np.nan), np.full((N, n), np.nan)
    k = min(len(res.lo), N)
    lo[:k], hi[:k] = res.lo[:k], res.hi[:k]
    cols = floor_columns(floor, observer_floor(observer), lo, hi, status == "ok",
                         sc.tolerance)
    checked = N if floor.steps is None else len(floor.steps)
    row["floor_steps"] += checked
    missed = cols["uncovered_steps"] or 0
    if missed and floor.kind == EXACT:
        missed, first = recheck_exact_misses(observer_floor(observer), floor, lo, hi, sc)
        cols = {**cols, "first_uncovered_step": first}
    if missed:
        row["uncovered"] += missed
        if not row["uncovered_at"]:
            row["uncovered_at"] = (f"seed {index}, step {cols['first_uncovered_step']} "
                                   f"({floor.kind} floor)")


def _reference_hull(sc: Scenario, k: int, which: str) -> tuple[np.ndarray, np.ndarray] | None:
    """The hull of the states consistent with the record at step ``k`` (``which``: predicted
    or filtered), each bound the optimum of the explicit LP of the whole record so far
    (:func:`observers.numerics.exact_reference.explicit_lp`) solved from scratch by HiGHS at
    its default tolerances: an optimum is a trajectory consistent with the record to those
    tolerances (a thin consistent set stays feasible), so a sound hull contains it up to the
    coverage slack.  ``None`` if an LP fails."""
    from scipy.optimize import linprog

    from observers.numerics.exact_reference import explicit_lp

    s = sc.system
    model = (s.A, s.B, s.C, *((S.c, S.G) for S in (s.X0, s.W, s.V)))
    A_eq, b_eq, bounds, xk = explicit_lp(model, sc.u, sc.y, k,
                                         k if which == "predicted" else k + 1)
    n = len(xk)
    out = np.empty((2, n))
    for i in range(n):
        for j, sign in enumerate((1.0, -1.0)):
            c = np.zeros(A_eq.shape[1])
            c[xk[i]] = sign
            res = linprog(c, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method="highs")
            if res.status != 0:
                return None
            out[j, i] = sign * float(res.fun)
    return out[0], out[1]


def recheck_exact_misses(which: str, floor: RecordFloor, lo: np.ndarray, hi: np.ndarray,
                          sc: Scenario) -> tuple[int, int]:
    """The steps where the hulls ``lo``/``hi`` miss the exact floor (``which``: predicted or
    filtered) and also miss the reference hull solved from scratch at that step
    (:func:`_reference_hull`; the first :data:`FLOOR_RECHECKS` misses are re-solved, later
    ones count as they are, as does a step the reference cannot solve); returns the count and
    the first such step (-1 if none)."""
    N, n = lo.shape
    flo, fhi = floor.bounds(which, N, n)
    tol = sc.tolerance
    known = np.all(np.isfinite(flo) & np.isfinite(fhi) & np.isfinite(lo) & np.isfinite(hi),
                   axis=1)
    confirmed = []
    for i, k in enumerate(np.flatnonzero(misses_floor(flo, fhi, lo, hi, tol) & known)):
        ref = _reference_hull(sc, int(k), which) if i < FLOOR_RECHECKS else None
        if ref is None or misses_floor(ref[0], ref[1], lo[k], hi[k], tol):
            confirmed.append(int(k))
    return len(confirmed), (confirmed[0] if confirmed else -1)


def _audit_task(task: tuple[str, str, int, tuple[str, ...], int]) -> list[dict]:
    return audit_pair(*task)


def run_audit(scenarios=AUDIT_SCENARIOS, names=None,
              realisations: Realisations = Realisations(), jobs: int = 1,
              progress: bool | None = None,
              only: set[tuple[str, str]] | None = None) -> pd.DataFrame:
    """Audit every observer in ``names`` (default: every registered one but the exact
    reference, whose floor the others are held to) on every scenario, on the
    ``realisations`` (:class:`Realisations`).  ``only``: just these ``(scenario, observer)``
    pairs (the stale ones of the audit's store)."""
    count, kinds, floors = realisations.count, realisations.kinds, realisations.floors
    if not isinstance(count, int) or count < 1:
        raise ConfigError(f"audit: the number of realisations must be >= 1, got {count!r}")
    if jobs < 1:
        raise ConfigError(f"audit: jobs must be >= 1, got {jobs}")
    try:
        names = ([observers.get(n).name for n in names] if names else
                 [i.name for i in observers.available() if i.family != "reference"])
    except observers.UnknownObserver as exc:
        raise ConfigError(f"audit: {exc}") from None
    for sc in scenarios:
        check_scenario(sc)
    unknown = set(kinds) - set(KINDS)
    if unknown or not kinds:
        raise ConfigError(f"audit: unknown realisation kind(s) {sorted(unknown)} "
                          f"(known: {', '.join(KINDS)})")
    tasks = [(sc, name, count, tuple(kinds), floors) for sc in scenarios for name in names
             if only is None or (sc, name) in only]
    with progress_bar(len(tasks), "audit", progress) as bar:
        def done(task, _) -> None:
            bar.set_postfix_str(f"{task[0]}: {task[1]}", refresh=False)
            bar.update()

        outs = run_tasks(_audit_task, tasks, jobs, done)
    rows = [row for out in outs for row in out]
    return pd.DataFrame(rows, columns=RESULT_COLUMNS)


# -- report -----------------------------------------------------------------------------------
def aggregate(df: pd.DataFrame) -> pd.DataFrame:
    """Per observer and scenario: totals over the realisation kinds."""
    def worst_at(g: pd.DataFrame) -> str:
        if g["violations"].sum() == 0:
            return ""
        r = g.loc[g["worst_violation"].idxmax()]
        return f"{r['kind']}, {r['worst_at']}"

    out = []
    for (obs, sc), g in df.groupby(["observer", "scenario"], sort=False):
        out.append({
            "observer": obs, "guaranteed": bool(g["guaranteed"].iloc[0]), "scenario": sc,
            "runs": int(g["runs"].sum()), "steps": int(g["steps"].sum()),
            "violations": int(g["violations"].sum()), "undecided": int(g["undecided"].sum()),
            "worst_violation": float(g["worst_violation"].max()), "worst_at": worst_at(g),
            "floor_steps": int(g["floor_steps"].sum()), "uncovered": int(g["uncovered"].sum()),
            "uncovered_at": next((a for a in g["uncovered_at"] if isinstance(a, str) and a),
                                 ""),
            "failed": ", ".join(f"{s} {int(g[s].sum())}" for s in STATUSES[1:] + ("error",)
                                if g[s].sum()),
            "lp_tests": int(g["lp_tests"].sum()), "seconds": float(g["seconds"].sum()),
            "reasons": " | ".join(dict.fromkeys(
                part for text in g.get("reasons", pd.Series(dtype=object))
                if isinstance(text, str) for part in text.split(" | ") if part)),
        })
    return pd.DataFrame(out)


def default_jobs() -> int:
    """Worker processes by default: the number of cores, at most 2 (a shared machine)."""
    return max(1, min(2, os.cpu_count() or 1))
