"""Validated discrete-time system models.

``x_{k+1} = A x_k + B u_k + w_k``, ``y_k = C x_k + v_k`` with ``w_k in W``, ``v_k in V``,
``x_0 in X0`` (:class:`LinearSystem`), and ``x_{k+1} = f(x_k, u_k) + w_k`` with the linear
output ``y_k = C x_k + v_k`` or a nonlinear one ``y_k = h(x_k) + v_k``
(:class:`NonlinearSystem`).  ``W`` and ``V`` are added directly in state and output space (no
E/F matrices, as in CORA's observers).

Every system answers the same output questions: ``h(x)`` (the output without noise),
``h_jacobian(x)`` (``C`` for a linear output), ``outputs(X)`` (one row per state of ``X``) and
``output_is_linear``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from observers.sets import Interval, SetError, Zonotope

from .errors import DomainError, ModelError, OutputNotLinear


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

    output_is_linear = True

    def dynamics(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Noise-free successor ``A x + B u``."""
        return self.A @ x + self.B @ u

    def h(self, x: np.ndarray) -> np.ndarray:
        """Output without noise, ``C x``."""
        return self.C @ np.asarray(x, dtype=float)

    def h_jacobian(self, x: np.ndarray) -> np.ndarray:
        """Jacobian of the output, ``C``."""
        return self.C

    def outputs(self, X: np.ndarray) -> np.ndarray:
        """Noise-free outputs of the states in the rows of ``X`` (N x n): ``X C'``."""
        return np.asarray(X, dtype=float) @ self.C.T

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
    """Nonlinear discrete-time system ``x+ = f(x, u) + w``, ``y = C x + v`` or ``y = h(x) + v``.

    Parameters
    ----------
    f : callable
        ``f(x, u, m) -> (n,) array``, explicit (e.g. Euler-discretised) dynamics written with
        the math namespace ``m`` (``m.sqrt``, ``m.sin``, ...: numpy when evaluated, sympy when
        derived, see :mod:`systems.derivatives`).
    n, nu : int
        State and input dimensions.
    C, W, V, X0
        Linear output matrix and the sets, as for :class:`LinearSystem`; ``C`` is ``None``
        when ``h`` is given (the number of outputs is then the dimension of ``V``).
    h : callable, optional
        Nonlinear output ``h(x, m) -> (ny,) array`` written with the math namespace ``m`` as
        ``f``; its Jacobian and second derivatives are derived symbolically as those of ``f``
        unless given.  Without ``h`` the output is linear (``C``), the fast special case.
    h_jacobian : callable, optional
        ``h_jacobian(x) -> (ny, n) array``.
    h_hessian : callable, optional
        ``h_hessian(lo, hi) -> (idx, Hlo, Hhi)``: sound bounds of the non-zero second
        derivatives ``d^2 h_i / dx_j dx_k`` (``j <= k``) over the box, as ``hessian``.
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
                 h: Callable | None = None, h_jacobian: Callable | None = None,
                 h_hessian: Callable | None = None,
                 jacobian: Callable | None = None, hessian: Callable | None = None,
                 domain=None, dt: float = 1.0, name: str = ""):
        if not callable(f):
            raise ModelError("f must be a callable f(x, u, m)")
        self._f = f
        self._n, self._nu = int(n), int(nu)
        if h is None:
            if C is None:
                raise ModelError("give the output as a matrix C or as a function h(x, m)")
            self._C = _matrix(C, "C", cols=self._n)
            ny = self._C.shape[0]
        else:
            if C is not None:
                raise ModelError("give the output either as C or as h, not both")
            if not callable(h):
                raise ModelError("h must be a callable h(x, m)")
            self._C = None
            ny = V.dim if isinstance(V, (Zonotope, Interval)) else None
            if ny is None:
                raise ModelError(f"V must be a Zonotope or an Interval, got {type(V).__name__}")
        self._h, self._h_jacobian, self._h_hessian = h, h_jacobian, h_hessian
        self._ny = ny
        self.W, self.V, self.X0 = _system_sets(W, V, X0, self._n, ny)
        self.dt = _sampling_time(dt)
        self.name = name
        if domain is None:
            domain = (np.full(self._n, -np.inf), np.full(self._n, np.inf))
        self.domain = tuple(np.broadcast_to(np.asarray(d, dtype=float), (self._n,)).copy()
                            for d in domain)
        self._derived = None
        self._derived_h = None
        self._jacobian = jacobian
        self._hessian = hessian
        if h is not None:
            try:
                y0 = self.h(self.X0.c)
            except (ArithmeticError, TypeError, ValueError) as exc:
                raise ModelError(f"h cannot be evaluated at the centre of X0 "
                                 f"({type(exc).__name__}: {exc})") from None
            if y0.shape != (ny,):
                raise ModelError(f"h returns {y0.size} values, but V has dimension {ny}")

    n = property(lambda self: self._n, doc="State dimension.")
    nu = property(lambda self: self._nu, doc="Input dimension.")
    ny = property(lambda self: self._ny, doc="Output dimension.")

    @property
    def output_is_linear(self) -> bool:
        """Whether the output is ``C x`` (else ``h(x)``)."""
        return self._h is None

    @property
    def output_matrix(self) -> np.ndarray | None:
        """``C`` if the output is linear: the matrix ``C``, or, for an output function ``h``
        without hand-given derivatives whose symbolic derivation shows ``h(x) = C x`` (no
        second derivative, a constant Jacobian, ``h(0) = 0``), that Jacobian; else ``None``.
        Observers use it to treat such an ``h`` exactly as the ``C`` path."""
        if self._h is None:
            return self._C
        if self._h_jacobian is not None or self._h_hessian is not None:
            return None
        if not hasattr(self, "_h_linear"):
            try:
                d = self.derived_h
            except ModelError:  # h cannot be traced symbolically: treat it as nonlinear
                self._h_linear = None
                return None
            Jx = d.jacobian_expressions[0]
            linear = not d.hessian_entries and not Jx.free_symbols
            C = np.array(Jx.tolist(), dtype=float) if linear else None
            if C is not None and np.any(self.h(np.zeros(self._n)) != 0.0):
                C = None
            if C is not None:
                C.setflags(write=False)
            self._h_linear = C
        return self._h_linear

    @property
    def C(self) -> np.ndarray:
        """Output matrix of a linear output; a nonlinear output raises
        :class:`~systems.errors.OutputNotLinear` (so ``hasattr(system, "C")`` is false)."""
        if self._C is None:
            raise OutputNotLinear(f"{self.name or 'this system'} has a nonlinear output "
                                  "y = h(x) + v and no matrix C (use h, h_jacobian, outputs)")
        return self._C

    @property
    def derived_h(self):
        """:class:`~systems.derivatives.SymbolicDerivatives` of ``h`` (nonlinear output
        only; built on first use)."""
        if self._h is None:
            raise OutputNotLinear("the output is linear (C): nothing to derive")
        if self._derived_h is None:
            from .derivatives import SymbolicDerivatives

            h = self._h
            self._derived_h = SymbolicDerivatives(lambda x, u, m: h(x, m), self._n, 0,
                                                  outputs=self._ny, what="h")
        return self._derived_h

    def h(self, x: np.ndarray) -> np.ndarray:
        """Output without noise, ``h(x)`` (or ``C x``)."""
        x = np.asarray(x, dtype=float)
        if self._h is None:
            return self._C @ x
        return np.asarray(self._h(x, np), dtype=float).reshape(-1)

    def h_jacobian(self, x: np.ndarray) -> np.ndarray:
        """Jacobian ``dh/dx`` at ``x`` (``C`` for a linear output; given by hand or derived)."""
        if self._h is None:
            return self._C
        if self._h_jacobian is not None:
            return np.asarray(self._h_jacobian(np.asarray(x, dtype=float)), dtype=float
                              ).reshape(self._ny, self._n)
        return self.derived_h.jacobian(np.asarray(x, dtype=float), np.zeros(0))[0]

    def outputs(self, X: np.ndarray) -> np.ndarray:
        """Noise-free outputs of the states in the rows of ``X`` (N x n)."""
        X = np.asarray(X, dtype=float)
        if self._h is None:
            return X @ self._C.T
        return np.array([self.h(x) for x in X]).reshape(X.shape[0], self._ny)

    def h_jacobian_bounds(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interval Jacobian ``(Jlo, Jhi)`` of ``dh/dx`` over ``[lo, hi]`` (derived, after
        :meth:`check_domain`; exact ``C`` for a linear output)."""
        if self._h is None:
            return self._C, self._C
        self.check_domain(lo, hi)
        try:
            return self.derived_h.jacobian_bounds(lo, hi, np.zeros(0))
        except SetError as exc:
            raise DomainError(f"{self.name or 'h'}: {exc} over the estimate's box") from None

    def h_hessian(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                  np.ndarray]:
        """Bounds of the non-zero second derivatives of ``h`` over ``[lo, hi]`` (after
        :meth:`check_domain`): ``(idx, Hlo, Hhi)`` as :meth:`hessian` (none for ``C``)."""
        if self._h is None:
            return np.zeros((0, 3), dtype=int), np.zeros(0), np.zeros(0)
        self.check_domain(lo, hi)
        if self._h_hessian is not None:
            return self._h_hessian(lo, hi)
        try:
            H = self.derived_h.hessian_bounds(lo, hi, np.zeros(0))
        except SetError as exc:
            raise DomainError(f"{self.name or 'h'}: {exc} over the estimate's box") from None
        return self.derived_h.hessian_index, H.lo, H.hi

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
        out = "" if self.output_is_linear else ", h(x)"
        return (f"NonlinearSystem({self.name or 'unnamed'}, n={self.n}, nu={self.nu}, "
                f"ny={self.ny}{out})")
