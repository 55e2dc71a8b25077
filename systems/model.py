"""Validated discrete-time system models.

``x_{k+1} = A x_k + B u_k + w_k``, ``y_k = C x_k + v_k`` with ``w_k in W``, ``v_k in V``,
``x_0 in X0`` (:class:`LinearSystem`), and ``x_{k+1} = f(x_k, u_k) + w_k`` with the same linear
output (:class:`NonlinearSystem`).  ``W`` and ``V`` are added directly in state and output
space (no E/F matrices, as in CORA's observers).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from observers.sets import Interval, SetError, Zonotope

from .errors import DomainError, ModelError


def _matrix(M, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    try:
        a = np.array(M, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be a numeric matrix") from None
    if a.ndim == 0:
        a = a.reshape(1, 1)
    if a.ndim == 1:
        a = a.reshape(1, -1) if rows == 1 else a.reshape(-1, 1)
    if a.ndim != 2:
        raise ModelError(f"{name} must be a matrix, got shape {a.shape}")
    if (rows is not None and a.shape[0] != rows) or (cols is not None and a.shape[1] != cols):
        want = f"({'n' if rows is None else rows}, {'*' if cols is None else cols})"
        raise ModelError(f"{name} has shape {a.shape}, expected {want}")
    if not np.all(np.isfinite(a)):
        raise ModelError(f"{name} contains non-finite values")
    a.setflags(write=False)
    return a


def _set(S, name: str, dim: int, *, must_contain_origin: bool) -> Zonotope:
    if isinstance(S, Interval):
        S = Zonotope.from_interval(S)
    if not isinstance(S, Zonotope):
        raise ModelError(f"{name} must be a Zonotope or an Interval, got {type(S).__name__}")
    if S.dim != dim:
        raise ModelError(f"{name} has dimension {S.dim}, expected {dim}")
    if must_contain_origin and not S.contains(np.zeros(dim), tol=1e-12):
        raise ModelError(f"{name} must contain the origin (bounded noise around zero)")
    return S


def _system_sets(W, V, X0, n: int, ny: int) -> tuple[Zonotope, Zonotope, Zonotope]:
    """Validated disturbance, noise and initial sets of a system."""
    try:
        return (
            _set(W, "W", n, must_contain_origin=True),
            _set(V, "V", ny, must_contain_origin=True),
            _set(X0, "X0", n, must_contain_origin=False),
        )
    except SetError as exc:
        raise ModelError(str(exc)) from None


def _sampling_time(dt) -> float:
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise ModelError(f"dt must be a positive number, got {dt!r}") from None
    if not (np.isfinite(dt) and dt > 0):
        raise ModelError(f"dt must be a positive number, got {dt}")
    return dt


def observability_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``[C; C A; ...; C A^{n-1}]``."""
    blocks, M = [], C
    for _ in range(A.shape[0]):
        blocks.append(M)
        M = M @ A
    return np.vstack(blocks)


class LinearSystem:
    """Linear discrete-time system with bounded disturbance and noise sets.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, nu) array_like
        ``nu`` may be 0 (pass ``np.zeros((n, 0))``).
    C : (ny, n) array_like
    W : Zonotope or Interval
        Disturbance set in state space (must contain the origin).
    V : Zonotope or Interval
        Measurement-noise set in output space (must contain the origin).
    X0 : Zonotope or Interval
        Initial set.
    dt : float
        Sampling time in seconds (metadata; the model is already discrete).
    name : str
        Label used in reports.
    """

    def __init__(self, A, B, C, W, V, X0, dt: float = 1.0, name: str = ""):
        A = _matrix(A, "A")
        n = A.shape[0]
        if A.shape[1] != n:
            raise ModelError(f"A must be square, got shape {A.shape}")
        self.A = A
        self.B = _matrix(B, "B", rows=n) if np.size(B) else np.zeros((n, 0))
        self.C = _matrix(C, "C", cols=n)
        self.W, self.V, self.X0 = _system_sets(W, V, X0, n, self.C.shape[0])
        self.dt = _sampling_time(dt)
        self.name = name

    n = property(lambda self: self.A.shape[0], doc="State dimension.")
    nu = property(lambda self: self.B.shape[1], doc="Input dimension.")
    ny = property(lambda self: self.C.shape[0], doc="Output dimension.")
    is_linear = True

    def dynamics(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Noise-free successor ``A x + B u``."""
        return self.A @ x + self.B @ u

    def observability_rank(self) -> int:
        """Rank of the observability matrix of (A, C)."""
        return int(np.linalg.matrix_rank(observability_matrix(self.A, self.C)))

    def is_observable(self) -> bool:
        """Whether (A, C) is observable."""
        return self.observability_rank() == self.n

    def unobservable_modes(self, tol: float = 1e-9) -> np.ndarray:
        """Distinct eigenvalues of A that fail the PBH test ``rank [A - lam I; C] = n``."""
        distinct: list[complex] = []
        for lam in np.linalg.eigvals(self.A):
            if all(abs(lam - d) > 1e-9 * max(1.0, abs(d)) for d in distinct):
                distinct.append(lam)
        bad = []
        for lam in distinct:
            M = np.vstack([self.A - lam * np.eye(self.n), self.C])
            if np.linalg.matrix_rank(M, tol=tol * max(1.0, np.abs(M).max())) < self.n:
                bad.append(lam)
        return np.real_if_close(np.array(bad))

    def is_detectable(self) -> bool:
        """Whether every unobservable mode is strictly stable (``|lambda| < 1``)."""
        return bool(np.all(np.abs(self.unobservable_modes()) < 1.0))

    def require_detectable(self, who: str) -> None:
        """Raise a :class:`ModelError` naming ``who`` if (A, C) is not detectable."""
        modes = self.unobservable_modes()
        unstable = modes[np.abs(modes) >= 1.0]
        if unstable.size:
            raise ModelError(
                f"{who}: the pair (A, C) is not detectable (unobservable eigenvalue(s) "
                f"{', '.join(f'{m:.4g}' for m in unstable)} with |lambda| >= 1)"
            )

    def replace(self, **changes) -> LinearSystem:
        """Copy with some fields replaced (``A, B, C, W, V, X0, dt, name``)."""
        fields = dict(A=self.A, B=self.B, C=self.C, W=self.W, V=self.V, X0=self.X0,
                      dt=self.dt, name=self.name)
        unknown = set(changes) - set(fields)
        if unknown:
            raise ModelError(f"unknown system field(s): {', '.join(sorted(unknown))}")
        fields.update(changes)
        return LinearSystem(**fields)

    def __repr__(self) -> str:
        return f"LinearSystem({self.name or 'unnamed'}, n={self.n}, nu={self.nu}, ny={self.ny})"


class NonlinearSystem:
    """Nonlinear discrete-time system ``x+ = f(x, u) + w``, ``y = C x + v``.

    Parameters
    ----------
    f : callable
        ``f(x, u, m) -> (n,) array``, explicit (e.g. Euler-discretised) dynamics written with
        the math namespace ``m`` (``m.sqrt``, ``m.sin``, ...: numpy when evaluated, sympy when
        derived, see :mod:`systems.derivatives`).
    n, nu : int
        State and input dimensions.
    C, W, V, X0
        Linear output matrix and the sets, as for :class:`LinearSystem`.
    jacobian : callable, optional
        ``jacobian(x, u) -> (df/dx, df/du)``; derived symbolically from ``f`` if omitted.
    hessian : callable, optional
        ``hessian(lo, hi, u) -> (idx, Hlo, Hhi)``: the non-zero second derivatives
        ``d^2 f_i / dx_j dx_k`` as rows ``idx = (i, j, k)`` with ``j <= k`` and bounds
        ``Hlo <= H <= Hhi`` valid over the box ``[lo, hi]`` (they must be sound, i.e. round
        outward); derived symbolically from ``f`` if omitted.
    domain : (lo, hi) of array_like, optional
        Open box on which ``f`` is smooth (e.g. ``x > 0`` under a square root); a box of
        states reaching its boundary is refused by :meth:`check_domain`.
    dt, name
        As for :class:`LinearSystem`.
    """

    is_linear = False

    def __init__(self, f: Callable, n: int, nu: int, C, W, V, X0, *,
                 jacobian: Callable | None = None, hessian: Callable | None = None,
                 domain=None, dt: float = 1.0, name: str = ""):
        if not callable(f):
            raise ModelError("f must be a callable f(x, u, m)")
        self._f = f
        self._n, self._nu = int(n), int(nu)
        self.C = _matrix(C, "C", cols=self._n)
        self.W, self.V, self.X0 = _system_sets(W, V, X0, self._n, self.C.shape[0])
        self.dt = _sampling_time(dt)
        self.name = name
        if domain is None:
            domain = (np.full(self._n, -np.inf), np.full(self._n, np.inf))
        self.domain = tuple(np.broadcast_to(np.asarray(d, dtype=float), (self._n,)).copy()
                            for d in domain)
        self._derived = None
        self._jacobian = jacobian
        self._hessian = hessian

    n = property(lambda self: self._n, doc="State dimension.")
    nu = property(lambda self: self._nu, doc="Input dimension.")
    ny = property(lambda self: self.C.shape[0], doc="Output dimension.")

    @property
    def derived(self):
        """:class:`~systems.derivatives.SymbolicDerivatives` of ``f`` (built on first use)."""
        if self._derived is None:
            from .derivatives import SymbolicDerivatives

            self._derived = SymbolicDerivatives(self._f, self._n, self._nu)
        return self._derived

    def f(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Noise-free successor ``f(x, u)`` (numpy)."""
        return np.asarray(self._f(np.asarray(x, dtype=float), np.asarray(u, dtype=float), np),
                          dtype=float)

    dynamics = f

    def jacobian(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(df/dx, df/du)`` at ``(x, u)`` (given by hand or derived)."""
        if self._jacobian is not None:
            return self._jacobian(x, u)
        return self.derived.jacobian(x, u)

    def check_domain(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Raise :class:`DomainError` naming the first state whose box leaves the domain."""
        dlo, dhi = self.domain
        bad = np.flatnonzero((lo <= dlo) | (hi >= dhi) | ~np.isfinite(lo) | ~np.isfinite(hi))
        if bad.size:
            i = int(bad[0])
            raise DomainError(
                f"the estimate of state x{i + 1} spans [{lo[i]:.6g}, {hi[i]:.6g}], which reaches "
                f"the boundary of the domain ({dlo[i]:.6g}, {dhi[i]:.6g}) of {self.name or 'f'}",
                state=i)

    def jacobian_bounds(self, lo: np.ndarray, hi: np.ndarray,
                        u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interval Jacobian ``(Jlo, Jhi)`` of ``df/dx`` over ``[lo, hi]`` (derived; after
        :meth:`check_domain`), for the mean-value extension."""
        self.check_domain(lo, hi)
        try:
            return self.derived.jacobian_bounds(lo, hi, u)
        except SetError as exc:
            raise DomainError(f"{self.name or 'f'}: {exc} over the estimate's box") from None

    def hessian(self, lo: np.ndarray, hi: np.ndarray,
                u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bounds of the non-zero second derivatives over ``[lo, hi]`` (after
        :meth:`check_domain`): ``(idx, Hlo, Hhi)``, see the class parameters."""
        self.check_domain(lo, hi)
        if self._hessian is not None:
            return self._hessian(lo, hi, u)
        try:
            H = self.derived.hessian_bounds(lo, hi, u)
        except SetError as exc:  # interval evaluation left the domain of f
            raise DomainError(f"{self.name or 'f'}: {exc} over the estimate's box") from None
        return self.derived.hessian_index, H.lo, H.hi

    def __repr__(self) -> str:
        return f"NonlinearSystem({self.name or 'unnamed'}, n={self.n}, nu={self.nu}, ny={self.ny})"
