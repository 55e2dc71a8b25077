"""Linear programs of the set types: HiGHS objects, the hull LPs with bounds from dual points,
and the batched dual simplex with its compiled twin.

A room of its own between the compiled kernels and the set types (``kernels`` <- ``lp`` <-
:mod:`observers.sets` <- the rest):

- :mod:`observers.lp.highs`: :func:`new_highs`, a quiet ``highspy.Highs`` (the one way any
  module of ours makes a HiGHS solver);
- :mod:`observers.lp.feasible`: :func:`box_feasible`, whether equality constraints have a
  solution in the unit box (the membership test of the zonotope types; apart from the hull
  LPs, so that an edit of those stales only rows whose sets have an LP hull);
- :mod:`observers.lp.hull`: LPs over the unit box with equality constraints (the interval
  hull and support values of constrained zonotopes, :class:`HullLP`), every bound evaluated
  from a dual point by weak duality (:func:`dual_bound`, :func:`dual_bounds`), hence sound
  whatever the solver returns;
- :mod:`observers.lp.sifting`: the hull LPs with very many columns by sifting, working sets
  of columns priced against all of them, the restricted LPs by HiGHS
  (:func:`observers.lp.sifting.solve`); :mod:`observers.lp.sifting_jit`: the same scheme with
  the restricted LPs by a compiled dual simplex from one shared basis, which the hulls take
  where numba is;
- :mod:`observers.lp.dual_simplex` and :mod:`observers.lp.dual_simplex_jit`: the batched
  bounded dual simplex that solves the 2n hull LPs of one set together, numpy path and
  compiled twin side by side (same pivots); :mod:`observers.lp.batch_solve_jit`: the same
  solve (set-up, iterations, refactorisations, certificate) as one compiled call, which the
  hulls take where the kernels are compiled.
"""

from .feasible import box_feasible
from .highs import new_highs
from .hull import (
    BATCHED_MAX_ROWS,
    BoxLP,
    HullLP,
    HullLPStats,
    batched_is_cheaper,
    dual_bound,
    dual_bounds,
    sifting_is_cheaper,
    split_free,
)

__all__ = [
    "BATCHED_MAX_ROWS",
    "BoxLP",
    "HullLP",
    "HullLPStats",
    "batched_is_cheaper",
    "box_feasible",
    "dual_bound",
    "dual_bounds",
    "new_highs",
    "sifting_is_cheaper",
    "split_free",
]
