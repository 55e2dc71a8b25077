"""Vehicle side-slip model (single-track model with steering-column dynamics).

Althoff & Rath, Automatica 2021, Sec. 4.2; parameters and structure as in CORA's generator
``simulateVehicle.m`` (CommonRoad parameters, mu = 1, 15 m/s).  States of the 6-D model:
``[beta, yaw rate, yaw, s_y, delta, delta_dot]``; the 4-D model keeps the first four, the 2-D
model the first two.  Discretisation is exact for piecewise-impulse inputs, as MATLAB's
``c2d(..., 'impulse')`` used by CORA: ``Ad = expm(Ac T)``, ``Bd = T expm(Ac T) Bc`` (the
paper's text says Euler; CORA's data are not Euler).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from observers.sets import Zonotope

from .errors import ModelError
from .model import LinearSystem

PARAMETERS = dict(
    mu=1.0, Vx=15.0, lr=1.508, lf=0.883, m=1.225e3, g=9.81, Iz=1.538e3, Cf=45000.0,
    Cr=57000.0, Bs=0.5, Js=0.05, etat=0.010, Rs=16.0,
)
#: disturbance half-widths per state (the first ``dim`` entries are used)
W_RADII = (0.005, 0.055, 0.005, 0.04, 0.02, 0.2)
V_RADIUS = 0.1
STATES = ("beta", "yaw_rate", "yaw", "s_y", "delta", "delta_dot")


def continuous_matrices(dim: int, **overrides: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous-time ``(Ac, Bc, C)`` of the 2-, 4- or 6-state model."""
    p = {**PARAMETERS, **overrides}
    mu, Vx, lr, lf, m, g, Iz = (p[k] for k in ("mu", "Vx", "lr", "lf", "m", "g", "Iz"))
    Fzf = m * g * lr / (lf + lr)
    Fzr = m * g * lf / (lf + lr)
    Csf = p["Cf"] / (mu * Fzf)
    Csr = p["Cr"] / (mu * Fzr)
    C1 = mu / (Vx * (lr + lf))
    C2 = mu * m / (Iz * (lr + lf))
    a11 = -C1 * g * (Csr * lf - Csf * lr)
    a12 = C1 * (g * lf * lr / Vx) * (Csr - Csf) - 1
    a21 = C2 * g * lr * lf * (Csr - Csf)
    a22 = -C2 * (g / Vx) * (lf * lf * lr * Csf + lr * lr * lf * Csr)
    b11 = C1 * g * lr * Csf
    b12 = C2 * g * lf * lr * Csf
    etat, Js = p["etat"], p["Js"]
    a61 = etat * mu * Csf * Fzf / Js
    a62 = etat * mu * Csf * Fzf * lf / (Js * Vx)
    a65 = -etat * mu * Csf * Fzf / Js
    a66 = -p["Rs"] * p["Bs"] / Js
    b16 = p["Rs"] / Js
    if dim == 2:
        A = [[a11, a12], [a21, a22]]
        B = [[b11], [b12]]
        C = [[0, Vx]]
    elif dim == 4:
        A = [[a11, a12, 0, 0], [a21, a22, 0, 0], [0, 1, 0, 0], [Vx, Vx, 0, 0]]
        B = [[b11], [b12], [0], [0]]
        C = [[0, Vx, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    elif dim == 6:
        # row 4 is Vx*(beta + yaw rate) as in CORA's generator
        A = [
            [a11, a12, 0, 0, b11, 0],
            [a21, a22, 0, 0, b12, 0],
            [0, 1, 0, 0, 0, 0],
            [Vx, Vx, 0, 0, 0, 0],
            [0, 0, 0, 0, 0, 1],
            [a61, a62, 0, 0, a65, a66],
        ]
        B = [[0], [0], [0], [0], [0], [b16]]
        C = [[0, Vx, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0]]
    else:
        raise ModelError(f"vehicle dimension must be 2, 4 or 6, got {dim!r}")
    return np.array(A, float), np.array(B, float), np.array(C, float)


def discretize_impulse(Ac: np.ndarray, Bc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``Ad = expm(Ac dt)``, ``Bd = dt expm(Ac dt) Bc`` (MATLAB ``c2d(..., 'impulse')``)."""
    Ad = expm(Ac * dt)
    return Ad, dt * Ad @ Bc


def vehicle(dim: int = 6, dt: float = 0.01, **parameters: float) -> LinearSystem:
    """Discrete vehicle side-slip model with CORA's sets.

    ``X0`` is the unit box, ``W`` the box with half-widths ``W_RADII[:dim]`` and ``V`` the box
    of half-width 0.1 per output.  Keyword arguments override physical parameters.
    """
    unknown = set(parameters) - set(PARAMETERS)
    if unknown:
        raise ModelError(f"unknown vehicle parameter(s): {', '.join(sorted(unknown))}")
    Ac, Bc, C = continuous_matrices(dim, **parameters)
    A, B = discretize_impulse(Ac, Bc, dt)
    return LinearSystem(
        A, B, C,
        W=Zonotope.box(W_RADII[:dim]),
        V=Zonotope.box(np.full(C.shape[0], V_RADIUS)),
        X0=Zonotope.box(np.ones(dim)),
        dt=dt,
        name=f"vehicle{dim}d",
    )


def lane_change_input(steps: int = 350, magnitude: float = 0.1) -> np.ndarray:
    """CORA's double-lane-change steering torque (steps x 1): 0, +m, -m, 0, -m, +m, 0 in
    blocks of 50 samples (repeating the last block beyond 350 steps)."""
    pattern = np.repeat([0.0, 1.0, -1.0, 0.0, -1.0, 1.0, 0.0], 50) * magnitude
    if steps > pattern.size:
        pattern = np.concatenate([pattern, np.zeros(steps - pattern.size)])
    return pattern[:steps].reshape(-1, 1)
