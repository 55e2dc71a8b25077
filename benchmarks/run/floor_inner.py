"""The floor of a nonlinear record: an inner box of its consistent set, found by the falsifier.

No exact consistent set exists for a nonlinear record, so the falsifier
(:mod:`benchmarks.run.falsifier`) searches verified consistent trajectories that make each state
as large or as small as possible at :data:`FALSIFIER_STEPS` steps spread from
:data:`FALSIFIER_FIRST` of the record on; the extremes form an *inner* box of the filtered
consistent set (also inside the predicted one).  Its own module, so that the falsifier is part
of the code of the nonlinear rows only (:mod:`benchmarks.store.fingerprint`).
"""

from __future__ import annotations

import time

from systems import Scenario

from .falsifier import SearchOptions, falsify, spread_steps
from .floor import INNER, RecordFloor, guarded

#: steps the falsifier searches on a nonlinear record, spread from this share of it on
FALSIFIER_STEPS, FALSIFIER_FIRST = 10, 0.2


def inner_floor(sc: Scenario, budget: int | None = None) -> RecordFloor:
    """The falsifier's inner box of ``sc``'s filtered consistent set; never raises for a record
    it cannot handle (``kind = "none"`` with the reason).

    Parameters
    ----------
    sc : Scenario
        A record of a nonlinear system.
    budget : int, optional
        The falsifier's budget of simplex iterations (``SearchOptions.max_simplex_iterations``;
        None: none); the steps it leaves unsearched have no floor, and ``message`` says so.
    """
    def compute(t0: float) -> RecordFloor:
        steps = spread_steps(sc.N, FALSIFIER_STEPS, first=int(FALSIFIER_FIRST * sc.N))
        res = falsify(sc.system, sc, steps, options=SearchOptions(
            keep_trajectories=False, max_simplex_iterations=budget))
        done = res.stats["steps_searched"]
        note = (f"falsifier budget of {budget} simplex iterations spent: {done} of "
                f"{len(res.steps)} steps searched" if res.stats["budget_spent"] else "")
        if done == 0:
            return RecordFloor("none", message=f"no floor: {note}",
                               seconds=time.perf_counter() - t0)
        return RecordFloor(INNER, {"filtered": res.inner_lo}, {"filtered": res.inner_hi},
                           steps=res.steps, message=note, seconds=time.perf_counter() - t0)

    return guarded(compute)
