"""Nonlinear falsifier: verified consistent trajectories that push each state to its extremes.

For a record ``(u, y)`` of ``x_{j+1} = f(x_j, u_j) + w_j``, ``y_j = h(x_j) + v_j`` with
``x_0 in X0``, ``w_j in W``, ``v_j in V`` (zonotopes ``c + G xi``, ``|xi|_inf <= 1``), the
*consistent* states of step ``k`` are the ``x_k`` of the trajectories that reproduce
``y_0 .. y_k`` exactly (``y_0 .. y_{k-1}`` for the *predicted* floor, the set before ``y_k``).
For a nonlinear model that set has no exact polytope description, so its interval hull is
not computable; this module bounds it from *inside*: for chosen steps and every state it
searches, in both directions, for a consistent trajectory making the state as small or as
large as possible, and keeps only trajectories that pass :func:`verify` (forward simulation
in the model with every noise factor checked against its bound).  The extremes found form an
*inner box* of the exact hull.  Any observer is sound only if its sets contain every
consistent state, so

* a verified consistent state outside an observer's interval hull (by more than a stated
  tolerance) is a *certified violation* (:class:`Violation`), and
* the observer's RMS radius divided by the inner box's is an *upper bound* of its gap to the
  exact hull (``gap <= ...``), since the inner box lies inside the exact hull.

The package, one module per part:

* :mod:`.verification`: a trajectory given by its noise factors, its forward simulation and the
  check of every factor against its bound (:func:`verify`; the tolerances and why);
* :mod:`.search`: the search itself, a trust-region SLP over the whole horizon (and why),
  from an anchor trajectory of the whole record;
* :mod:`.inner_box`: :func:`falsify` drives the search over the chosen steps and keeps the
  verified extremes (:class:`FalsifierResult`); :meth:`FalsifierResult.check` checks more
  hulls against a result;
* ``python -m benchmarks.run.falsifier SCENARIO`` (:mod:`.__main__`) measures it (observers
  run, violations, ``gap <=`` per state, cost).

>>> import systems
>>> sc = systems.scenario("vanderpol-sim", steps=30)
>>> res = falsify(sc.system, sc, steps=[10, 29], options=SearchOptions(starts=1))
>>> bool(np.all(res.inner_lo <= res.inner_hi))
True
"""

from __future__ import annotations

import numpy as np  # noqa: F401  (the doctest above)

from .inner_box import REL_TOL, FalsifierResult, SearchOptions, Violation, falsify, spread_steps
from .search import FACTOR_MARGIN, NOISE_MARGIN
from .verification import VERIFY_TOL, Trajectory, Verification, verify

__all__ = ["FACTOR_MARGIN", "NOISE_MARGIN", "REL_TOL", "VERIFY_TOL", "FalsifierResult",
           "SearchOptions", "Trajectory", "Verification", "Violation", "falsify", "spread_steps",
           "verify"]
