"""Verification of the falsifier (:mod:`benchmarks.run.falsifier`): a candidate trajectory,
given by its noise factors, is simulated forward in the model and each factor checked against
its bound (:func:`verify`, :class:`Model`).

:func:`verify` re-simulates ``x_0 = c_0 + G_0 xi_0``, ``x_{j+1} = f(x_j, u_j) + c_W + G_W
omega_j`` in floating point, requires ``|xi_0|_inf <= 1`` and ``|omega_j|_inf <= 1`` exactly
(they are the trajectory's own numbers) and recomputes the measurement factors ``nu_j`` of
``y_j - h(x_j) - c_V`` (``G_V^+`` applied to the residual of the trajectory's own ``nu_j``,
so for a non-square ``G_V`` a trajectory is judged by the factors it carries, corrected),
requiring ``|nu_j|_inf <= 1 + 1e-9``: the measurements and the simulated outputs carry
rounding, and a record with noise on the vertices of V (the audit's adversarial kinds) has
``|v_j| = r_V`` exactly.  The search keeps the factors of ``X0`` and ``W`` inside ``1 - 1e-9``
and those of ``V`` inside ``1 - 1e-7`` (the LP's tolerance, accumulated along the dynamics,
and the linearisation error of the last step), so that its points verify with room to spare;
where the anchor itself lies in those margins (noise on the vertices of the sets, whose
consistent set has no interior) the margins are dropped and a candidate that misses by a
hair is polished by a least-norm Gauss-Newton step on the measurement factors at or beyond
their bound (:meth:`.search.Search.polish`).  The simulated states carry the rounding of ``k``
floating-point steps (~1e-14 relative), so a state is called a violation only when it lies
outside a hull by more than ``rel_tol * max(1, |x|)`` (``rel_tol = 1e-9``) plus the hull's
own tolerance.  On a record without interior the extremes are ill-conditioned: a reference
LP's own tolerance moves them by up to ~1 % of the thinnest radii (see the tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from systems.errors import ModelError

__all__ = ["EQ_TOL", "VERIFY_TOL", "Model", "Trajectory", "Verification", "verify"]

#: rounding allowance of the verification on the factors of V (those of X0 and W are the
#: trajectory's own numbers and are checked exactly): the measurements and the simulated
#: outputs carry the rounding of the simulation (a record with noise on the vertices of V,
#: e.g. the audit's, has ``|v| = r_V`` exactly and no consistent trajectory strictly inside)
VERIFY_TOL = 1e-9
#: tolerance of the measurement equation residual after G_V^+ (non-square G_V only)
EQ_TOL = 1e-12


def _output(system: Any, x: np.ndarray) -> np.ndarray:
    """``h(x)`` where the system has an output function, else ``C x``."""
    h = getattr(system, "h", None)
    if callable(h):
        return np.asarray(h(x), dtype=float).reshape(-1)
    return system.C @ x


def _output_jacobian(system: Any, x: np.ndarray, ny: int) -> np.ndarray:
    """``dh/dx`` where the system has an output function (central differences if it has no
    ``h_jacobian``: the Jacobian only steers the search), else ``C``."""
    hj = getattr(system, "h_jacobian", None)
    if callable(hj):
        return np.asarray(hj(x), dtype=float).reshape(ny, x.size)
    if callable(getattr(system, "h", None)):
        step = 1e-7 * np.maximum(1.0, np.abs(x))
        cols = [(_output(system, x + e) - _output(system, x - e)) / (2 * e[i])
                for i, e in enumerate(np.diag(step))]
        return np.column_stack(cols).reshape(ny, x.size)
    return np.asarray(system.C, dtype=float)


# -- trajectories and their verification -------------------------------------------------
@dataclass(frozen=True)
class Trajectory:
    """A candidate trajectory given by its noise factors.

    Attributes
    ----------
    xi0 : (p0,) array
        Factors of ``x_0 = c_0 + G_0 xi0``.
    omega : (k, pW) array
        Factors of ``w_j = c_W + G_W omega_j``, ``j = 0 .. k-1`` (``k`` is the final step).
    nu : (m, pV) array
        Factors of ``v_j`` for the ``m`` measurements reproduced; :func:`verify` recomputes
        them from the simulated states (they only seed ``G_V^+`` where ``G_V`` is not square).
    """

    xi0: np.ndarray
    omega: np.ndarray
    nu: np.ndarray

    @property
    def step(self) -> int:
        """The final step ``k`` of the trajectory."""
        return int(self.omega.shape[0])

    @property
    def measured(self) -> int:
        """Number of measurements ``y_0 .. y_{m-1}`` the trajectory reproduces."""
        return int(self.nu.shape[0])

    def truncated(self, k: int, m: int) -> Trajectory:
        """The first ``k`` steps reproducing ``m`` measurements."""
        return Trajectory(self.xi0, self.omega[:k], self.nu[:m])


@dataclass(frozen=True)
class Verification:
    """Verdict of :func:`verify`.

    Attributes
    ----------
    consistent : bool
        Every factor within its bound and the simulation finite.
    x : (k + 1, n) array
        Simulated states ``x_0 .. x_k``.
    nu : (m, pV) array
        Measurement factors recomputed from the simulated states.
    worst : float
        Largest ``|factor|`` over ``X0``, ``W`` and ``V`` (``<= 1`` when consistent).
    reason : str
        Why the trajectory is inconsistent (``""`` when consistent).
    """

    consistent: bool
    x: np.ndarray
    nu: np.ndarray
    worst: float
    reason: str = ""


class Model:
    """The system, its record and the zonotope data the falsifier needs."""

    def __init__(self, system: Any, u: np.ndarray, y: np.ndarray):
        for key in ("W", "V", "X0"):
            if not hasattr(system, key):
                raise ModelError(f"falsifier: the system has no attribute {key}")
        if not (hasattr(system, "dynamics") or hasattr(system, "f")):
            raise ModelError("falsifier: the system has neither dynamics(x, u) nor f(x, u)")
        # every model of ours has h(x); a linear one says so (output_is_linear) and has C
        self.nonlinear_output = (callable(getattr(system, "h", None))
                                 and not getattr(system, "output_is_linear", False))
        if not (self.nonlinear_output or hasattr(system, "C")):
            raise ModelError("falsifier: the system has neither h(x) nor C")
        self.system = system
        self.n = int(np.size(system.X0.c))
        self.ny = int(np.size(system.V.c))
        y = np.asarray(y, dtype=float)
        if y.ndim == 1:
            y = y.reshape(-1, 1)
        N = y.shape[0]
        u = np.zeros((N, 0)) if u is None else np.asarray(u, dtype=float)
        if u.ndim == 1:
            u = u.reshape(-1, 1)
        if y.shape[1] != self.ny or u.shape[0] < N - 1:
            raise ModelError(f"falsifier: record shapes u {u.shape}, y {y.shape} do not match "
                             f"the system (ny = {self.ny})")
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(u[:N - 1]))):
            raise ModelError("falsifier: the record contains non-finite values")
        self.u, self.y, self.N = u, y, N
        self.c0, self.G0 = np.asarray(system.X0.c, float), np.asarray(system.X0.G, float)
        self.cW, self.GW = np.asarray(system.W.c, float), np.asarray(system.W.G, float)
        self.cV, self.GV = np.asarray(system.V.c, float), np.asarray(system.V.G, float)
        self.GV_pinv = np.linalg.pinv(self.GV)
        self.square_V = self.GV.shape[0] == self.GV.shape[1] and np.linalg.matrix_rank(
            self.GV) == self.GV.shape[0]
        self.p0, self.pW, self.pV = self.G0.shape[1], self.GW.shape[1], self.GV.shape[1]
        self._f = system.dynamics if hasattr(system, "dynamics") else system.f

    def f(self, x: np.ndarray, j: int) -> np.ndarray:
        return np.asarray(self._f(x, self.u[j]), dtype=float)

    def jacobian(self, x: np.ndarray, j: int) -> np.ndarray:
        s = self.system
        if hasattr(s, "jacobian"):
            return np.asarray(s.jacobian(x, self.u[j])[0], dtype=float)
        return np.asarray(s.A, dtype=float)

    def H(self, x: np.ndarray) -> np.ndarray:
        """Output Jacobian at ``x``."""
        if not self.nonlinear_output:
            return np.asarray(self.system.C, dtype=float)
        return _output_jacobian(self.system, x, self.ny)

    def outputs(self, X: np.ndarray) -> np.ndarray:
        if not self.nonlinear_output:
            return X @ self.system.C.T
        return np.array([_output(self.system, x) for x in X]).reshape(X.shape[0], self.ny)

    def simulate(self, xi0: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """States ``x_0 .. x_k`` (rows after a non-finite state are NaN)."""
        k = omega.shape[0]
        X = np.full((k + 1, self.n), np.nan)
        x = self.c0 + self.G0 @ xi0
        W = self.cW + omega @ self.GW.T
        with np.errstate(all="ignore"):
            for j in range(k + 1):
                if not np.all(np.isfinite(x)):
                    break
                X[j] = x
                if j < k:
                    x = self.f(x, j) + W[j]
        return X

    def noise_factors(self, X: np.ndarray, nu_ref: np.ndarray) -> tuple[np.ndarray, float]:
        """Measurement factors of the simulated states and the worst equation residual."""
        m = nu_ref.shape[0]
        with np.errstate(all="ignore"):
            R = self.y[:m] - self.outputs(X[:m]) - self.cV
            nu = nu_ref + (R - nu_ref @ self.GV.T) @ self.GV_pinv.T
            res = 0.0 if self.square_V else float(np.abs(R - nu @ self.GV.T).max(initial=0.0))
        return nu, res

    def check(self, traj: Trajectory) -> Verification:
        """:func:`verify` on this model."""
        xi0, omega = np.asarray(traj.xi0, float), np.asarray(traj.omega, float)
        nu_ref = np.asarray(traj.nu, float).reshape(-1, self.pV)
        k, m = omega.shape[0], nu_ref.shape[0]
        if xi0.shape != (self.p0,) or omega.shape[1:] != (self.pW,):
            raise ModelError(f"trajectory factors have shapes {xi0.shape}, {omega.shape}; "
                             f"expected ({self.p0},), (k, {self.pW})")
        if not (k + 1 >= m >= k and k < self.N):
            raise ModelError(f"a trajectory to step {k} must reproduce {k} or {k + 1} "
                             f"measurements of the {self.N}, got {m}")
        X = self.simulate(xi0, omega)
        if not np.all(np.isfinite(X)):
            return Verification(False, X, nu_ref, math.inf, "the simulation is not finite")
        nu, res = self.noise_factors(X, nu_ref)
        worst = {"X0": np.abs(xi0).max(initial=0.0), "W": np.abs(omega).max(initial=0.0),
                 "V": np.abs(nu).max(initial=0.0)}
        bound = {"X0": 1.0, "W": 1.0, "V": 1.0 + VERIFY_TOL}
        reasons = [f"|factor of {key}| = {v!r} > {bound[key]!r}" for key, v in worst.items()
                   if not v <= bound[key]]
        scale = max(1.0, float(np.abs(self.y[:m]).max(initial=0.0)))
        if not res <= EQ_TOL * scale:
            reasons.append(f"measurement residual {res:.3g} after G_V^+")
        return Verification(not reasons, X, nu, float(max(worst.values())), "; ".join(reasons))


def verify(system: Any, u, y, traj: Trajectory) -> Verification:
    """Whether ``traj`` is a trajectory consistent with the record ``(u, y)``.

    Forward simulation ``x_0 = c_0 + G_0 xi0``, ``x_{j+1} = f(x_j, u_j) + c_W + G_W omega_j``;
    the factors of ``X0`` and ``W`` must satisfy ``|.|_inf <= 1`` exactly and the measurement
    factors ``nu_j`` of ``y_j - h(x_j) - c_V`` too, for the ``traj.measured`` measurements.

    Parameters
    ----------
    system : LinearSystem or NonlinearSystem
    u, y : array_like
        The record (``u[j]`` drives ``x_{j+1}``, ``y[j]`` measures ``x_j``).
    traj : Trajectory
    """
    return Model(system, u, y).check(traj)
