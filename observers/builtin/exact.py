"""Exact: the exact reference of a linear record (the floor every guaranteed observer sits on).

The set of states consistent with a record of a linear system with zonotopic ``X0``, ``W`` and
``V`` is a polytope; ``Exact`` keeps every measurement (nothing reduced, nothing dropped) and
returns, per step, its exact interval hull, sound by weak duality, from the incremental LPs
of :mod:`observers.numerics.exact`.  Two floors per step, because observers differ in what
they have seen when they return the set of step k:

* **filtered**: the states consistent with ``y[0..k]`` -- the floor of the strip-based and
  data-driven observers (their set of step k uses ``y[k]``); the set that ``step`` returns
  and whose hull ``observers.run`` records;
* **predicted**: the states consistent with ``y[0..k-1]`` -- the floor of the propagation
  and interval observers (FRad-C, PRad-E, Nom-G, ESO-C/D, Hinf-G: ready before ``y[k]``);
  :meth:`Exact.predicted_hull` (latest step), ``S.predicted`` on a returned set, or
  :meth:`Exact.hull_arrays` (all steps so far).

Which floor an observer is held against is its registry entry's ``floor``
(:class:`observers.ObserverInfo`).

Cache
-----
The hulls of a record are cached on disk like the offline designs
(:mod:`observers.offline`: ``$SETOBS_CACHE_DIR``, default ``~/.cache/setobs-bench/designs``;
``off`` disables it), keyed by the model (matrices and sets), the solver settings and the
first measurement; the entry holds the record (``u``, ``y``), the four hull arrays and which
steps had an LP that no strategy solved to optimality (``inexact``).  While
the record matches the entry step by step, ``step`` only reads the arrays; from the first
step that differs (or beyond the entry's end) the LPs are set up from the matching prefix
(with its cached hulls as the state bounds, no solve) and solved from there on, and the entry
is rewritten after every computed step (atomic replace), so an interrupted run keeps what it
computed.  Option ``cache=False`` bypasses it.

Inexact steps
-------------
A step whose LPs HiGHS did not solve to optimality by any strategy (warm, then the cold
chain of :data:`observers.numerics.exact.COLD_SOLVES`) keeps a sound but possibly loose
hull; :meth:`Exact.inexact_steps` lists them, and the benchmark's floor does not hold
observers to them (a loose floor would flag an observer for excluding a state that is in
fact inconsistent with the data).

Linear systems only: a nonlinear record has no polytope of consistent states, and ``Exact``
refuses it (:class:`~observers.errors.Unsupported`).
"""

from __future__ import annotations

import contextlib
import hashlib
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import EmptySet, ObserverError
from ..families import LinearModelObserver
from ..numerics import exact as ex
from ..offline import cache_dir, design_key, key_lock, load_entry, store_entry
from ..options import Bool
from ..registry import register
from ..sets import Interval

#: bump when the formulation or the bounds change, so that cached hulls are recomputed
CACHE_VERSION = "2"  # 2: entries record their inexact steps
#: the arrays of a cache entry
_HULLS = ("pred_lo", "pred_hi", "filt_lo", "filt_hi")


def _highspy_version() -> str:
    try:
        return metadata.version("highspy")
    except metadata.PackageNotFoundError:  # pragma: no cover - highspy is a dependency
        return "none"


@register(
    "Exact", family="reference", set_type="polytope", ready_for_control=False,
    floor="filtered",
    reference="exact consistent set (Schweppe 1968; Milanese & Vicino 1991; Scott et al. "
              "2016, unreduced); incremental LP, issue 24",
)
class Exact(LinearModelObserver):
    r"""Exact reference: the interval hulls of the states consistent with the whole record.

    ``step`` returns an :class:`~observers.numerics.exact.ExactSet` (the filtered set of step
    k: ``interval()`` its exact hull, ``predicted`` the exact hull before ``y[k]``,
    ``contains`` an LP over the record).  Linear systems only.

    Options
    -------
    cache : bool
        Read and write the on-disk cache of exact hulls (default True; see the module
        docstring).

    Notes
    -----
    The set of eq. (3) of Althoff & Rath (2021), unrolled over the whole record from
    :math:`\mathcal{S}_0 = \mathcal{X}_0`, with :math:`\mathcal{X}_0 = \langle c_0, G_0
    \rangle`, :math:`\mathcal{W} = \langle c_W, G_W \rangle`,
    :math:`\mathcal{V} = \langle c_V, G_V \rangle`, is the projection onto :math:`x_k` of
    the polytope

    .. math::

        \mathcal{F}_k = \left\{ (x_0, \ldots, x_k, \xi, \omega, \nu) \mid
        \begin{aligned}
        & x_0 = c_0 + G_0 \xi, \\
        & x_{j+1} = A x_j + B u_j + c_W + G_W \omega_j, && 0 \le j < k, \\
        & y_j = C x_j + c_V + G_V \nu_j, && 0 \le j \le k, \\
        & \|\xi\|_\infty, \|\omega_j\|_\infty, \|\nu_j\|_\infty \le 1
        \end{aligned} \right\}

    (the filtered set of step :math:`k`; the predicted set drops the measurement rows of
    :math:`y_k`).  Its interval hull is :math:`2n` linear programs per step,

    .. math::

        \underline{x}_{k,i} = \min_{\mathcal{F}_k} e_i^\top x_k, \qquad
        \overline{x}_{k,i} = \max_{\mathcal{F}_k} e_i^\top x_k, \qquad i = 1, \ldots, n,

    grown by one block of variables and rows per step and warm started from the previous
    step's bases (:mod:`observers.numerics.exact`).  Each returned bound is the
    weak-duality value :math:`b^\top \pi` of a dual point :math:`\pi` of the LP,
    evaluated with outward rounding, so it is sound whatever the solver returns; an empty
    :math:`\mathcal{F}_k` (a record inconsistent with the model) ends the run.
    """

    OPTIONS = {"cache": Bool(True)}
    #: A and B are checked in ``design``, after a nonlinear system is refused (``MODELS``)
    REQUIRES = ("C", "W", "V", "X0")
    SCENARIO_OPTIONS = ()  # no zonotope order or reduction: nothing is reduced
    MODELS = ("linear",)
    MODEL_NOTE = (": the states consistent with a nonlinear record form no polytope "
                  "(no exact reference)")

    def design(self) -> None:
        super().design()
        sets = tuple((S.c, S.G) for S in (self.X0, self.W, self.V))
        self._model = (self.A, self.B, self.C, *sets)
        self._key = None
        if self.options["cache"]:
            arrays = {"A": self.A, "B": self.B, "C": self.C}
            for name, (c, G) in zip(("X0", "W", "V"), sets, strict=True):
                arrays[f"{name}c"], arrays[f"{name}G"] = c, G
            params = {"highspy": _highspy_version(), "tol": ex.LP_TOLERANCE,
                      "margin": ex.MARGIN}
            self._key = design_key("Exact", CACHE_VERSION, arrays, params)

    def reset(self) -> None:
        super().reset()
        self._engine: ex.ExactHullLP | None = None
        self._u: list[np.ndarray] = []
        self._y: list[np.ndarray] = []
        self._hulls: list[ex.StepHulls] = []
        self._inexact: list[bool] = []  # per step: an LP not solved to optimality
        self._entry: dict[str, np.ndarray] | None = None  # cache entry being replayed
        self._path: Path | None = None
        #: steps read from the cache and steps computed since the last reset
        self.cached_steps = 0
        self.computed_steps = 0

    # -- the online step -----------------------------------------------------------------------
    def step(self, u_prev, y) -> ex.ExactSet:
        y = self._measurement(y)
        k = self.k
        u = None if k == 0 else self._input(u_prev)
        if k == 0:
            self._open_cache(y)
        hulls = self._replay(k, u, y)
        if hulls is None:
            hulls = self._compute(k, u, y)  # may raise EmptySet: the record stays as it was
            self.computed_steps += 1
            inexact = k in self._engine.inexact
        else:
            self.cached_steps += 1
            inexact = bool(self._entry["inexact"][k])
        self._inexact.append(inexact)
        if u is not None:
            self._u.append(u)
        self._y.append(y)
        self._hulls.append(hulls)
        if self._entry is None and self._path is not None:
            self._save()
        self.k += 1
        return ex.ExactSet(self._model, self._u, self._y, k, hulls)

    def _compute(self, k: int, u, y) -> ex.StepHulls:
        if self._engine is None:  # first computed step: set up the LPs of the prefix
            self._engine = ex.ExactHullLP(*self._model)
            for j, h in enumerate(self._hulls):
                if j == 0:
                    self._engine.first(self._y[0], h)
                else:
                    self._engine.advance(self._u[j - 1], self._y[j], h)
        if k == 0:
            return self._engine.first(y)
        return self._engine.advance(u, y)

    # -- results for the lead's tables ---------------------------------------------------------
    def predicted_hull(self) -> Interval:
        """The exact hull of the predicted set of the latest step (before its ``y[k]``)."""
        if not self._hulls:
            raise RuntimeError("Exact: no step taken yet")
        return self._hulls[-1].predicted

    def hull_arrays(self) -> dict[str, np.ndarray]:
        """The hulls of every step so far: ``pred_lo``, ``pred_hi``, ``filt_lo``, ``filt_hi``
        (each steps x n)."""
        n = self.A.shape[0]
        return {key: np.array([getattr(h, key) for h in self._hulls]).reshape(-1, n)
                for key in _HULLS}

    def inexact_steps(self) -> list[int]:
        """The steps so far whose hulls are sound but possibly loose (an LP that no strategy
        solved to optimality), computed or read from the cache."""
        return [k for k, flag in enumerate(self._inexact) if flag]

    @property
    def lp_stats(self) -> dict[str, Any]:
        """LP work of the steps computed since the last reset (HiGHS solves, simplex
        iterations, steps whose LPs were not solved to optimality) and the cached steps."""
        e = self._engine
        return {"solves": e.solves if e else 0, "iterations": e.iterations if e else 0,
                "inexact_steps": self.inexact_steps(),
                "computed_steps": self.computed_steps, "cached_steps": self.cached_steps}

    # -- cache -----------------------------------------------------------------------------------
    def _entry_path(self, y0) -> Path | None:
        """The cache entry of the record whose first measurement is ``y0`` (None: no cache)."""
        folder = cache_dir() if self._key is not None else None
        if folder is None:
            return None
        y0 = np.ascontiguousarray(np.asarray(y0, dtype=float).ravel())
        h = hashlib.sha256(y0.tobytes()).hexdigest()[:16]
        return folder / f"Exact-{self._key}-{h}.npz"

    @contextlib.contextmanager
    def sole_writer(self, y):
        """Hold the cache entry of the record ``y`` (found by its first measurement) for this
        process while the record is run: another process running the same record (two
        workers needing one floor) waits, then replays the whole entry instead of rebuilding
        the LPs from a partial prefix (an engine rebuilt from a prefix has no basis: its first
        solves are cold, the slow and fragile path).  No cache (or no measurement): no lock."""
        try:
            path = self._entry_path(np.asarray(y, dtype=float)[0])
        except (TypeError, ValueError, IndexError):  # bad input: run() reports it
            path = None
        if path is None:
            yield
            return
        with key_lock(path):
            yield

    def _open_cache(self, y0: np.ndarray) -> None:
        self._path = self._entry_path(y0)
        if self._path is None:
            return
        entry = load_entry(self._path)
        if entry is not None and all(k in entry for k in ("u", "y", "inexact", *_HULLS)):
            self._entry = entry

    def _replay(self, k: int, u, y) -> ex.StepHulls | None:
        """The cached hulls of step k if the record so far matches the entry, else None (and
        the entry is dropped: the steps from here on are computed)."""
        e = self._entry
        if e is None:
            return None
        ok = k < e["y"].shape[0] and np.array_equal(e["y"][k], y) and (
            k == 0 or np.array_equal(e["u"][k - 1], u))
        if not ok:
            self._entry = None
            return None
        return ex.StepHulls(*(e[key][k] for key in _HULLS))

    def _save(self) -> None:
        n, nu = self.A.shape[0], self.B.shape[1]
        arrays = {"u": np.array(self._u, float).reshape(-1, nu),
                  "y": np.array(self._y, float).reshape(len(self._y), -1),
                  "inexact": np.array(self._inexact, bool)}
        for key in _HULLS:
            arrays[key] = np.array([getattr(h, key) for h in self._hulls]).reshape(-1, n)
        store_entry(self._path, arrays)


def exact_hulls(system, u, y, *, cache: bool = True) -> dict[str, np.ndarray]:
    """The exact hulls of a linear record, both floors: ``pred_lo``, ``pred_hi``,
    ``filt_lo``, ``filt_hi`` (each N x n), via ``Exact`` and :func:`observers.run` (cached).

    Raises
    ------
    Unsupported
        For a nonlinear system.
    EmptySet
        If no state is consistent with the record (the message names the step).
    """
    from ..base import run
    from ..registry import create

    obs = create("Exact", system, cache=cache)
    with obs.sole_writer(y):
        res = run(obs, u, y, keep_sets=False)
    if res.status == "empty":
        raise EmptySet(res.message)
    if res.status != "ok":
        raise ObserverError(f"Exact: {res.message}")
    return obs.hull_arrays()
