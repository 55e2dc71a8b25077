"""Discretised Van der Pol oscillator: a nonlinear benchmark that is not a tank.

Explicit Euler with step ``h`` of ``x1' = x2``, ``x2' = mu (1 - x1^2) x2 - x1 + u``; only the
position ``x1`` is measured.  It is a fair test of the nonlinear observers because, unlike the
tank (whose Hessian is diagonal and whose states stay near one operating point), its
nonlinearity couples the states (``d^2 f_2 / dx1 dx2 = -2 h mu x1``), it acts on the
unmeasured velocity, and the trajectory runs round a limit cycle through regions of very
different local linearisations, so the remainder enclosure is exercised at every step.  The
derivatives are not written by hand: they are derived from ``f`` (:mod:`systems.derivatives`),
as for a user's own model.
"""

from __future__ import annotations

import numpy as np

from observers.sets import Zonotope

from .model import NonlinearSystem


def vanderpol(mu: float = 1.0, h: float = 0.05) -> NonlinearSystem:
    """Van der Pol oscillator, Euler-discretised, position measured.

    Parameters
    ----------
    mu : float
        Damping parameter.
    h : float
        Euler step (s).
    """

    def f(x, u, m):
        return np.array([x[0] + h * x[1],
                         x[1] + h * (mu * (1 - x[0] ** 2) * x[1] - x[0] + u[0])], dtype=object)

    return NonlinearSystem(
        f, 2, 1, C=[[1.0, 0.0]],
        W=Zonotope.box([1e-3, 1e-3]), V=Zonotope.box([0.05]),
        X0=Zonotope.box([0.5, 0.5], [2.0, 0.0]), dt=h, name="vanderpol")
