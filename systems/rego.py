"""The two-state examples of Rego et al.'s constrained-zonotope estimation papers.

* :func:`rego2d_nonlinear`: the nonlinear example of Rego, Raffo, Scott, Raimondo
  (Automatica 111, 108614, 2020) and of Rego, Raffo, Terra, Scott (arXiv 2504.00130, 2025),
  also the nonlinear demo of their MATLAB toolbox ZETA (arXiv 2504.06467)::

      x1+ = x1 (3 - x1 / 7 - 4 x2 / (4 + x1)) + w1
      x2+ = x2 (-2 + 3 x1 / (4 + x1)) + w2
      y1  = x1 - sin(x2 / 2) + v1
      y2  = (1 - x1) x2 + v2

  with ``W = 0.5 [-1, 1]^2``, ``V = 0.2 [-1, 1]^2`` and the initial set, a zonotope with three
  generators, ``c = (5, 0.5)``, ``G = [[0.5, 1, -0.5], [0.5, 0.5, 0]]``.  Both the dynamics
  (products and a quotient) and the measurement (a sine and a product) are nonlinear; the
  derivatives are derived from the equations (:mod:`systems.derivatives`).  The model is
  smooth where ``x1 > -4``.
* :func:`rego2d_linear`: the linear sanity example of the same toolbox, ``A = [[0, -1], [1,
  1]]``, ``C = [[1, -1], [0, 1]]``, ``W = 0.1 [-1, 1]^2``, ``V = 0.3 [-1, 1]^2``, ``X0 = Z((-1,
  1), [[2, 4, 2], [2, 0, 2]])`` (no input).

The numbers are those stated in the project's issue (taken from the papers' examples); the
records are simulated here (:mod:`systems.scenarios`) from ``x0 = (5.2, 0.65)`` and ``x0 =
(1, -1)``.
"""

from __future__ import annotations

import numpy as np

from observers.sets import Zonotope

from .model import LinearSystem, NonlinearSystem

#: initial states of the records (the papers' simulations)
X0_NONLINEAR = (5.2, 0.65)
X0_LINEAR = (1.0, -1.0)


def _f(x, u, m):
    return np.array([x[0] * (3 - x[0] / 7 - 4 * x[1] / (4 + x[0])),
                     x[1] * (-2 + 3 * x[0] / (4 + x[0]))], dtype=object)


def _h(x, m):
    return np.array([x[0] - m.sin(x[1] / 2), (1 - x[0]) * x[1]], dtype=object)


def rego2d_nonlinear() -> NonlinearSystem:
    """The nonlinear two-state example (nonlinear dynamics and measurements, no input)."""
    return NonlinearSystem(
        _f, 2, 0, None,
        W=Zonotope.box([0.5, 0.5]), V=Zonotope.box([0.2, 0.2]),
        X0=Zonotope([5.0, 0.5], [[0.5, 1.0, -0.5], [0.5, 0.5, 0.0]]),
        h=_h, domain=([-4.0, -np.inf], [np.inf, np.inf]), name="rego2d-nonlinear")


def rego2d_linear() -> LinearSystem:
    """The linear two-state example (no input)."""
    return LinearSystem(
        [[0.0, -1.0], [1.0, 1.0]], np.zeros((2, 0)), [[1.0, -1.0], [0.0, 1.0]],
        W=Zonotope.box([0.1, 0.1]), V=Zonotope.box([0.3, 0.3]),
        X0=Zonotope([-1.0, 1.0], [[2.0, 4.0, 2.0], [2.0, 0.0, 2.0]]), name="rego2d-linear")
