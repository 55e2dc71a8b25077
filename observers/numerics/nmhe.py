"""Nonlinear moving-horizon set estimation: a window of the last L steps, relaxed and bounded.

At step k the states ``x_s .. x_k`` of the window (``s = max(0, k - L)``) are tied by the
model ``x_{j+1} = f(x_j, u_j) + w_j`` and the measurements ``y_j = h(x_j) + v_j``
(``y_j = C x_j + v_j`` for a linear output), and ``x_s`` lies in a sound prior (``X0`` for
``s = 0``, else a box).  For a nonlinear model the consistent states form no polytope, so the
window is *enclosed*: over a sound box ``B_j`` of each ``x_j`` every nonlinear operation of
``f`` and ``h`` gets a variable bounded by linear inequalities on its graph (the lifted
polyhedral relaxations of :mod:`observers.numerics.relaxation`: McCormick envelopes, secants
and tangents, after Rego, Raffo, Terra & Scott, arXiv 2504.00130, 2025), and each inequality
becomes an equality with a slack factor.  The whole window is then *one* constrained zonotope
in the factors of the prior, the lifted variables and slacks of every step, the disturbances
and the noises (the exact recursion of Scott, Raimondo, Marseglia & Braatz, Automatica 69,
2016, over the window, nothing reduced), and the interval hull of any ``x_j`` in it is
``2 n`` LPs, each bounded by the weak-duality value of a dual point
(:meth:`observers.sets.ConZonotope.interval`).

Soundness.  Every trajectory consistent with the whole record passes through the boxes
``B_j`` (each is a sound hull), so it satisfies every relaxation, and its factors lie in the
window's set: the hull of ``x_k`` contains every consistent state.  The boxes are the
estimator's own hulls of earlier steps (and, for the newest state under a nonlinear output,
the hull of the window before ``y_k``); because every ``x_j`` of a window is bounded by the
same LPs, the hulls of the earlier states of the window, computed with the later
measurements, are *smoothed* boxes: tighter, and as sound, so they replace the stored ones.

Bound tightening.  A relaxation over a smaller box is tighter, and tighter relaxations give
smaller hulls: ``sweeps`` passes re-bound every state of the window and re-relax over the
intersected boxes before the final hull (optimisation-based bound tightening, the domain
reduction of global optimisation: Caprara & Locatelli, Math. Program. 125, 2010).  Each pass
only intersects sound boxes, so the estimate never grows from one pass to the next.

On a linear model the relaxations are the model itself (affine forms, no variable, no
inequality), and the window is the constrained zonotope of :func:`observers.numerics.mhe.
window_conzonotope` with the states of the window additionally bounded by their own sound
boxes: the estimator is ``MHE`` (formulation ``"czn"``), up to the solver's tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sets import ConZonotope, HullLP, Interval
from .mhe import box_factors
from .relaxation import Factorable, lifted_set, relax_checked

__all__ = ["Window", "box_factors", "build_window", "measure_newest", "window_hulls"]


@dataclass(frozen=True)
class Window:
    """A window as one constrained zonotope: the state ``x_j`` (``j`` counted from the first
    step of the window) is ``c[j] + G[j] @ xi[:G[j].shape[1]]`` for the factors ``xi`` with
    ``A xi = b``, ``|xi| <= 1`` (factors are appended step by step, so the generators of an
    earlier state are a prefix)."""

    c: tuple[np.ndarray, ...]
    G: tuple[np.ndarray, ...]
    A: np.ndarray
    b: np.ndarray

    def state(self, j: int) -> ConZonotope:
        """The set of ``x_j`` (the window's constraints, its generators padded with zeros)."""
        G = np.zeros((self.G[j].shape[0], self.A.shape[1]))
        G[:, : self.G[j].shape[1]] = self.G[j]
        return ConZonotope.trusted(self.c[j], G, self.A, self.b)

    def states(self, js) -> ConZonotope:
        """The states ``x_j`` (``j in js``) stacked into one set, for one batch of hull LPs."""
        R = self.A.shape[1]
        rows = []
        for j in js:
            Gj = np.zeros((self.G[j].shape[0], R))
            Gj[:, : self.G[j].shape[1]] = self.G[j]
            rows.append(Gj)
        return ConZonotope.trusted(np.concatenate([self.c[j] for j in js]), np.vstack(rows),
                                   self.A, self.b)


def build_window(f_graph: Factorable, output, start: tuple[np.ndarray, np.ndarray],
                 boxes: list[tuple[np.ndarray, np.ndarray]], u: np.ndarray, y: np.ndarray,
                 W: tuple[np.ndarray, np.ndarray], V: tuple[np.ndarray, np.ndarray],
                 tangents: int = 1, k: int | None = None) -> Window:
    """The window's constrained zonotope.

    Parameters
    ----------
    f_graph : Factorable
        The dynamics ``f(x, u)``.
    output : Factorable or ndarray
        The output: ``h(x)`` as a factorable graph, or the matrix ``C`` of a linear output.
    start : tuple of ndarray
        ``(centre, generators)`` of the prior of the window's first state.
    boxes : list of (lo, hi)
        A sound box of every state of the window (``T + 1`` of them; the last one is read
        only for a nonlinear output and a measurement of the newest state).
    u : ndarray
        ``T x nu`` inputs of the ``T`` transitions.
    y : ndarray
        ``(T + 1) x m`` measurements, or ``T x m``: the newest state then has no measurement
        yet (the prediction; :func:`measure_newest` adds it).
    W, V : tuple of ndarray
        ``(centre, generators)`` of the disturbance and the noise.
    tangents : {1, 3}
        Tangents of each convex or concave operation (:func:`relax_unary`).
    k : int, optional
        Step, for the message of a relaxation leaving its domain.

    Raises
    ------
    Diverged
        A box leaves the domain of ``f`` or ``h`` (``sqrt`` of a negative interval, ...).
    """
    cW, GW = W
    c, G = np.asarray(start[0], float), np.asarray(start[1], float)
    A, b = np.zeros((0, G.shape[1])), np.zeros(0)
    cs, Gs = [], []
    T = len(u)
    for j in range(T + 1):
        cs.append(c)
        Gs.append(G)
        if j < len(y):
            A, b = _measure(output, c, G, A, b, boxes[j], y[j], V, tangents, k)
        if j == T:
            break
        # x_{j+1} = f(x_j, u_j) + w_j over the lifted variables of f's relaxation on B_j
        rel = relax_checked(f_graph, c, _padded(G, A.shape[1]), boxes[j], u[j], k, tangents)
        coef, A, b = lifted_set(rel, A, b)
        A = np.hstack([A, np.zeros((A.shape[0], GW.shape[1]))])
        c = rel.const + cW
        G = np.hstack([coef, GW])
    return Window(tuple(cs), tuple(Gs), A, b)


def measure_newest(win: Window, output, box: tuple[np.ndarray, np.ndarray], y: np.ndarray,
                   V: tuple[np.ndarray, np.ndarray], tangents: int = 1,
                   k: int | None = None) -> Window:
    """The window with the measurement ``y`` of its newest state added (a window built by
    :func:`build_window` without it), ``h`` relaxed over ``box``."""
    A, b = _measure(output, win.c[-1], win.G[-1], win.A, win.b, box, y, V, tangents, k)
    return Window(win.c, win.G, A, b)


def _padded(G: np.ndarray, R: int) -> np.ndarray:
    """``G`` with zero columns up to ``R`` columns."""
    Gp = np.zeros((G.shape[0], R))
    Gp[:, : G.shape[1]] = G
    return Gp


def _measure(output, c, G, A, b, box, y, V, tangents, k) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` with the measurement ``y = h(x) + v`` of the state ``c + G xi`` appended
    (the noise's factors appended as new columns)."""
    cV, GV = V
    if isinstance(output, np.ndarray):  # C x + v = y
        rows = np.hstack([output @ G, np.zeros((output.shape[0], A.shape[1] - G.shape[1])),
                          GV])
        A = np.vstack([np.hstack([A, np.zeros((A.shape[0], GV.shape[1]))]), rows])
        return A, np.concatenate([b, y - output @ c - cV])
    # h(x) + v = y over the lifted variables of h's relaxation on the box
    rel = relax_checked(output, c, _padded(G, A.shape[1]), box, np.zeros(0), k, tangents)
    coef, A, b = lifted_set(rel, A, b)
    A = np.block([[A, np.zeros((A.shape[0], GV.shape[1]))], [coef, GV]])
    return A, np.concatenate([b, y - rel.const - cV])


def window_hulls(win: Window, js, solver: HullLP | None = None) -> list[Interval]:
    """Sound interval hulls of the states ``x_j`` (``j in js``) of a window, in one batch of
    ``2 n len(js)`` LPs."""
    js = list(js)
    S = win.states(js)
    if solver is not None:
        S = S.with_solver(solver)
    I = S.interval()
    n = win.c[0].size
    return [Interval(I.lo[i * n:(i + 1) * n], I.hi[i * n:(i + 1) * n]) for i in range(len(js))]
