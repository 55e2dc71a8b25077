"""The n-tank benchmark of ARCH 2021 (Althoff, "Guaranteed state estimation in CORA 2021").

Tanks in a cascade with Torricelli outflow, explicit Euler with ``h = 0.5`` s,
``k = 0.015``, ``g = 9.81``, as in CORA's ``tank6EqDT_inflow4.m`` / ``tank30EqDT_inflow15.m``:

* tank 1: ``x1+ = x1 + h (-k sqrt(2g) sqrt(x1) + u)``;
* "head" tanks (2, 7, 13, 19, 25): ``xi+ = xi + h sqrt(2g) (sqrt(x_{i-1}) - sqrt(xi))`` (no k,
  as coded in CORA), an inflow of tanks 7, 13, 19, 25 is added outside ``h``;
* all others: ``xi+ = xi + h k sqrt(2g) (sqrt(x_{i-1}) - sqrt(xi) + u)`` for an inflow tank.

Measured tanks and inflow tanks follow ARCH Table 2 (indices beyond n ignored).  For n > 30
the pattern of tanks 25-30 repeats every 6 tanks (our extension; no published model).

The paper's text differs from these equations (it states ``k = 0.015`` for every tank and
``(B u + w)_i / A_i``); CORA's published numbers come from the code, so we follow it.

The nonlinear model (``linear=False``) ships hand-derived derivatives: the Jacobian
(diagonal ``1 - c_i / (2 sqrt(x_i))``, sub-diagonal ``c_i / (2 sqrt(x_{i-1}))``, with ``c_i``
the coefficient of tank i's square-root difference) and the non-zero second derivatives
``d^2 f_i / dx_i^2 = c_i x_i^(-3/2) / 4`` and ``d^2 f_i / dx_{i-1}^2 = -c_i x_{i-1}^(-3/2) / 4``,
bounded over a box with outward rounding; ``tests/test_nonlinear.py`` checks them against
the symbolic derivation of ``f`` (:mod:`systems.derivatives`).  Its domain is ``x > 0``: an
estimate whose box reaches a non-positive level is refused (``DomainError``).

The linear model is the Jacobian at ``x = 20`` (the centre of X0), rounded to 3 decimals as in
CORA's printed matrices; it acts on deviations (``X0`` is centred at 0 with radius 4).
"""

from __future__ import annotations

import numpy as np

from observers.sets import Zonotope

from .errors import ModelError
from .model import LinearSystem, NonlinearSystem

H, K, G = 0.5, 0.015, 9.81
MEASURED_30 = (2, 4, 5, 7, 8, 10, 11, 13, 14, 16, 17, 19, 20, 21, 22, 23, 25, 26, 27, 28, 29)
INFLOW_30 = (1, 4, 5, 7, 9, 10, 13, 15, 16, 19, 21, 22, 25, 27, 28)
HEAD_30 = (2, 7, 13, 19, 25)


def _extend(pattern: tuple[int, ...], n: int) -> list[int]:
    """1-based tank indices of ``pattern`` up to n; beyond 30 the block 25-30 repeats."""
    out = [i for i in pattern if i <= n]
    block = [i - 24 for i in pattern if i >= 25]  # offsets within tanks 25..30
    start = 30
    while start < n:
        out += [start + b for b in block if start + b <= n]
        start += 6
    return out


def layout(n: int) -> dict[str, list[int]]:
    """0-based indices of measured tanks, inflow tanks (one input each) and head tanks."""
    if not isinstance(n, (int, np.integer)) or n < 2:
        raise ModelError(f"the tank system needs an integer number of tanks >= 2, got {n!r}")
    return {
        "measured": [i - 1 for i in _extend(MEASURED_30, n)],
        "inflow": [i - 1 for i in _extend(INFLOW_30, n)],
        "head": [i - 1 for i in _extend(HEAD_30, n)],
    }


def _sets(n: int, ny: int, center: float) -> dict[str, Zonotope]:
    return dict(
        W=Zonotope.box(np.full(n, 0.001)),
        V=Zonotope.box(np.full(ny, 0.2)),
        X0=Zonotope.box(np.full(n, 4.0), np.full(n, center)),
    )


def _model(n: int):
    lay = layout(n)
    s2g = np.sqrt(2 * G)
    head = np.zeros(n, dtype=bool)
    head[lay["head"]] = True
    coef = np.where(head, H * s2g, H * K * s2g)  # coefficient of the sqrt-difference term
    coef[0] = H * K * s2g
    nu = len(lay["inflow"])
    Bu = np.zeros((n, nu))  # how each input enters (constant: the model is affine in u)
    for j, i in enumerate(lay["inflow"]):
        Bu[i, j] = H if i == 0 else (1.0 if head[i] else H * K * s2g)

    def f(x, u, m=np):
        r = m.sqrt(x)
        xn = x - coef * r
        xn[1:] = xn[1:] + coef[1:] * r[:-1]
        return xn + Bu @ u

    def jacobian(x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = coef / (2 * np.sqrt(np.maximum(x, 1e-12)))
        J = np.diag(1.0 - d)
        J[np.arange(1, n), np.arange(n - 1)] = d[:-1] * coef[1:] / coef[:-1]
        return J, Bu.copy()

    # non-zero second derivatives: d^2 f_i / dx_i^2 = coef_i x_i^(-3/2) / 4 (own outflow) and
    # d^2 f_i / dx_{i-1}^2 = -coef_i x_{i-1}^(-3/2) / 4 (inflow from the tank above)
    i_own = np.arange(n)
    i_up = np.arange(1, n)
    hess_idx = np.vstack([np.column_stack([i_own, i_own, i_own]),
                          np.column_stack([i_up, i_up - 1, i_up - 1])])
    q = np.concatenate([0.25 * coef, -0.25 * coef[1:]])

    def hessian(lo, hi, u):
        # x^(-3/2) is decreasing: its range over [lo, hi] is [hi^-1.5, lo^-1.5]; numpy's pow
        # is within 1 ulp, the product with q adds one more: 3 ulps outward cover both
        lo_x = lo[hess_idx[:, 1]]
        hi_x = hi[hess_idx[:, 1]]
        a, b = q * hi_x**-1.5, q * lo_x**-1.5
        Hlo, Hhi = np.minimum(a, b), np.maximum(a, b)
        for _ in range(3):
            Hlo, Hhi = np.nextafter(Hlo, -np.inf), np.nextafter(Hhi, np.inf)
        return hess_idx, Hlo, Hhi

    C = np.zeros((len(lay["measured"]), n))
    C[np.arange(C.shape[0]), lay["measured"]] = 1.0
    return f, jacobian, hessian, Bu, C


def tank(n: int = 6, linear: bool = True, x_op: float = 20.0, decimals: int | None = 3):
    """The n-tank system, linearised (``LinearSystem``) or nonlinear (``NonlinearSystem``).

    Parameters
    ----------
    n : int
        Number of tanks (>= 2).
    linear : bool
        Return the Jacobian linearisation at ``x_op`` (deviation coordinates) if True.
    x_op : float
        Operating level of every tank for the linearisation.
    decimals : int or None
        Rounding of the linear matrices (CORA prints and uses 3 decimals); None keeps them exact.
    """
    f, jacobian, hessian, Bu, C = _model(n)
    if not linear:
        return NonlinearSystem(f, n, Bu.shape[1], C, jacobian=jacobian, hessian=hessian,
                               domain=(0.0, np.inf), dt=H, name=f"tank{n}",
                               **_sets(n, C.shape[0], 20.0))
    A, B = jacobian(np.full(n, float(x_op)), np.zeros(Bu.shape[1]))
    if decimals is not None:
        A, B = np.round(A, decimals), np.round(B, decimals)
    return LinearSystem(A, B, C, dt=H, name=f"tank{n}-linear", **_sets(n, C.shape[0], 0.0))


def tank_input(nu: int, steps: int) -> np.ndarray:
    """Deviation input for the n-tank scenarios (steps x nu), following CORA's rule for the
    30-tank system: ramps of 20 steps with slopes ``0.5 * 5e-3 * uDiff``, started at zero."""
    udiff = 5e-3 * np.array(
        [[1, 2, 3, 2, 1, 0, -1, -3, -3, 0, -1],
         [1, 1, 1, 0, 0, 0, -1, -1, -1, 0, -1],
         [2, 1, 1, 1, 0, -1, -1, 0, -1, 0, 0]], dtype=float)
    rows = np.tile(udiff, (int(np.ceil(nu / 3)), 1))[:nu]
    slopes = np.repeat(rows, 20, axis=1)
    reps = int(np.ceil(max(steps - 1, 0) / slopes.shape[1])) + 1
    slopes = np.tile(slopes, reps)[:, : max(steps - 1, 0)]
    u = np.hstack([np.zeros((nu, 1)), np.cumsum(0.5 * slopes, axis=1)])
    return u[:, :steps].T
