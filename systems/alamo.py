"""The 2-D example of Alamo, Bravo & Camacho (Automatica 2005, Sec. 7.1)."""

from __future__ import annotations

import numpy as np

from observers.sets import Zonotope

from .model import LinearSystem


def alamo2d() -> LinearSystem:
    """``A = [0 -0.5; 1 1]``, ``B = I``, ``C = [-2 1]``, ``X0 = 3 B^2``, ``V = 0.2 B``,
    ``W = 0.02 [-6; 1] B`` (one generator), ``dt = 1``."""
    return LinearSystem(
        A=[[0.0, -0.5], [1.0, 1.0]],
        B=np.eye(2),
        C=[[-2.0, 1.0]],
        W=Zonotope([0.0, 0.0], [[-0.12], [0.02]]),
        V=Zonotope([0.0], [[0.2]]),
        X0=Zonotope.box([3.0, 3.0]),
        dt=1.0,
        name="alamo2d",
    )
