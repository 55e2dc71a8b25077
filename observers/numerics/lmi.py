"""The LMI toolbox of the offline designs: solve (cvxpy + Clarabel, or Newton), verify in numpy.

Every offline gain of the project (PRad-A..E, Nom-G, Hinf-G, ESO-C/D) is designed with the
pieces of this module, so that each step is written once:

* :func:`bmat` writes a block matrix once for cvxpy (the solver) and numpy (the verification);
* :func:`solve` is the one Clarabel call with one status policy (:data:`ACCEPTED`);
* :func:`gain_from` computes ``L = P^-1 Y`` from a positive definite ``P``;
* :func:`require_psd`, :func:`require_pd`, :func:`require_nsd` check the inequalities on the
  *returned numbers* with ``numpy.linalg.eigvalsh``: a solver's "optimal" status is not enough;
* :func:`cora_bisection_end` replays where CORA's bisections on a decay rate stop;
* :func:`analytic_centre` and :func:`decay_centre` (the same damped Newton method with a
  Hessian assembled from the structure of the decay LMI) compute analytic centres in numpy;
* :class:`GainDesign` is what every design returns; :class:`LinearDesignProblem` holds the
  matrices ``A, C, E, F`` a design starts from.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from ..errors import DesignFailed, Unsupported

#: solver statuses accepted; an "inaccurate" point is judged by the numpy verification that
#: follows every solve
ACCEPTED = ("optimal", "optimal_inaccurate")
#: Clarabel tolerances of rough evaluations inside a line search (the chosen point is solved
#: again with the defaults, 1e-8): they only rank decay rates and save about a third of the
#: iterations
ROUGH = {"tol_gap_abs": 1e-6, "tol_gap_rel": 1e-6, "tol_feas": 1e-7}
#: tolerances for problems with a unique optimum that is solved to high accuracy (PRad-E)
TIGHT = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10}


@dataclass(frozen=True)
class GainDesign:
    """A verified constant observer gain with the data that certify it.

    Attributes
    ----------
    L : ndarray
        The gain (n x ny): the strip-intersection gain ``Lambda`` of a strip-based observer or
        the Luenberger gain of a propagation or interval observer.
    P : ndarray
        The Lyapunov (or P-radius) matrix of the certificate.
    info : dict
        Figures of merit of the design: ``rate``, the decay rate of the P-radius certified by
        a P-radius design (``beta`` or ``alpha`` in the papers); ``rho``, the spectral radius
        of ``A - L C`` of a Luenberger design; bounds and solver settings.
    """

    L: np.ndarray
    P: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)


class LinearDesignProblem(NamedTuple):
    """The matrices of an offline design: ``x+ = A x + B u + E w``, ``y = C x + F v`` with the
    disturbance ``w`` and the noise ``v`` the generator factors of ``W`` and ``V``.

    Attributes
    ----------
    A : ndarray
        The dynamics (n x n).
    C : ndarray
        The outputs (m x n).
    E : ndarray
        The generator matrix of the disturbance set ``W`` (n x nw).
    F : ndarray
        The generator matrix of the noise set ``V`` (m x nv).
    """

    A: Any
    C: Any
    E: Any
    F: Any


#: solver settings of the named SDP solver strategies (PRad-B's ``solver`` option: the
#: spread of its degenerate optimum over solvers and tolerances)
SOLVERS = {
    "clarabel": {},
    "clarabel-1e-6": {"tol_gap_abs": 1e-6, "tol_gap_rel": 1e-6, "tol_feas": 1e-6},
    "scs": {"solver": "SCS", "eps": 1e-9, "max_iters": 100000},
}


def solve(problem, what: str, solver: str | None = None, **solver_options) -> str:
    """Solve a cvxpy problem with Clarabel; return the status or raise :class:`DesignFailed`.

    ``solver`` names a strategy of :data:`SOLVERS` (default Clarabel with its defaults).

    A solver exception or a status outside :data:`ACCEPTED` is a failed design.  cvxpy's
    "solution may be inaccurate" warning is silenced: the numpy verification that follows every
    solve accepts or rejects the point.
    """
    import cvxpy as cp

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            opts = dict(SOLVERS[solver or "clarabel"], **solver_options)
            problem.solve(solver=opts.pop("solver", cp.CLARABEL), **opts)
    except (cp.error.SolverError, ArithmeticError, ValueError) as exc:
        raise DesignFailed(f"{what}: solver failed ({exc})") from None
    status = problem.status
    if status not in ACCEPTED:
        raise DesignFailed(f"{what}: the SDP is {status}")
    return status


def solved(problem, rough: bool = False) -> bool:
    """:func:`solve` as a feasibility test: True if the problem was solved to an accepted
    status (``rough``: with the :data:`ROUGH` tolerances)."""
    try:
        solve(problem, "", **(ROUGH if rough else {}))
    except DesignFailed:
        return False
    return True


def bmat(blocks: list[list]):
    """Block matrix where ``None`` is a zero block (its size read from the other blocks).

    With numpy blocks only it is a numpy array; with any cvxpy expression among them, a cvxpy
    expression, so that each LMI is written once for the solver and for the verification.
    """
    rows = [next(b.shape[0] for b in row if b is not None) for row in blocks]
    cols = [next(row[j].shape[1] for row in blocks if row[j] is not None)
            for j in range(len(blocks[0]))]
    filled = [[np.zeros((rows[i], cols[j])) if b is None else b for j, b in enumerate(row)]
              for i, row in enumerate(blocks)]
    if all(isinstance(b, np.ndarray) for row in filled for b in row):
        return np.block(filled)
    import cvxpy as cp

    return cp.bmat(filled)


def psd_constraint(M):
    """cvxpy constraint ``M >= 0`` on the symmetric part of ``M`` (as cvxpy requires)."""
    return (M + M.T) / 2 >> 0


def sym(M: np.ndarray) -> np.ndarray:
    """Symmetric part ``(M + M') / 2``."""
    M = np.asarray(M, dtype=float)
    return 0.5 * (M + M.T)


def min_eig(M: np.ndarray) -> float:
    """Smallest eigenvalue of the symmetric part of ``M``."""
    return float(np.linalg.eigvalsh(sym(M))[0])


def require_psd(M: np.ndarray, what: str, tol: float = 1e-8) -> float:
    """Check ``M >= -tol * scale`` (``scale = max(1, |M|_max)``); returns the smallest
    eigenvalue."""
    lam = min_eig(M)
    scale = max(1.0, float(np.abs(M).max()))
    if not np.isfinite(lam) or lam < -tol * scale:
        raise DesignFailed(f"{what}: verification failed (smallest eigenvalue {lam:.3g})")
    return lam


def require_pd(M: np.ndarray, what: str, margin: float = 0.0) -> float:
    """Check ``M > margin`` strictly; returns the smallest eigenvalue."""
    lam = min_eig(M)
    if not np.isfinite(lam) or lam <= margin:
        raise DesignFailed(f"{what}: verification failed (smallest eigenvalue {lam:.3g})")
    return lam


def require_nsd(M: np.ndarray, what: str, tol: float = 1e-8) -> float:
    """Check ``M <= tol * scale``; returns the largest eigenvalue."""
    return -require_psd(-np.asarray(M, float), what, tol)


def spectral_radius(M: np.ndarray) -> float:
    """Largest absolute eigenvalue."""
    return float(np.max(np.abs(np.linalg.eigvals(M)))) if np.size(M) else 0.0


def gain_from(P: np.ndarray, Y: np.ndarray, what: str) -> np.ndarray:
    """``L = P^{-1} Y`` (the change of variables ``Y = P L`` of every design) after checking
    that the symmetric part of ``P`` is positive definite."""
    P = sym(P)
    lam = np.linalg.eigvalsh(P)
    if not np.all(np.isfinite(lam)) or lam[0] <= 1e-12 * max(1.0, lam[-1]):
        raise DesignFailed(f"{what}: P is not positive definite (eigenvalues "
                           f"{lam[0]:.3g} ... {lam[-1]:.3g}), so L = P^-1 Y is undefined")
    return np.linalg.solve(P, np.asarray(Y, dtype=float))


def cora_bisection_end(lo: float = 0.0, hi: float = 1.0, tol: float = 0.01) -> float:
    """Where CORA's bisection on a decay rate in ``[lo, hi]`` stops when every solve is feasible.

    CORA halves ``[lo, hi]`` until ``hi - lo <= tol``, moving *up* after every solve that is
    not certified infeasible, and keeps the values of the last solve.  Its PRad-A/B and PRad-E
    LMIs are non-strict and satisfied by ``P = Y = 0`` for every rate, so every step moves up
    and the loop ends at ``hi - (hi - lo) 2^-k`` (0.9921875 for ``[0, 1]`` and ``tol = 0.01``),
    where the gain is that of one solve.  Replaying the bracket arithmetic makes the earlier
    solves unnecessary.
    """
    if not hi > lo or not tol > 0:
        raise ValueError("bisection needs lo < hi and tol > 0")
    while hi - lo > tol:
        lo = 0.5 * (lo + hi)
    return lo


def range_factor(G: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """``U_r S_r`` from the thin SVD of ``G``: a full-column-rank factor with the same ``G G'``.

    LMIs in which ``G`` enters only through ``G' G`` and ``G' X`` keep their feasible set in
    the other variables when ``G`` is replaced by this factor (congruence with ``V_r'``).
    """
    G = np.asarray(G, dtype=float)
    if G.size == 0:
        return np.zeros((G.shape[0], 0))
    U, s, _ = np.linalg.svd(G, full_matrices=False)
    r = int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0
    return U[:, :r] * s[:r]


def unit_noise(plant: LinearDesignProblem) -> tuple[LinearDesignProblem, float]:
    """``plant`` with ``E`` and ``F`` divided by their common scale ``s`` (the larger of their
    largest singular values; 1 if both are zero), and ``s^2``.

    In the H-infinity LMIs (Hinf-G, ESO-C/D) ``E`` and ``F`` enter beside ``gamma^2 I``: the
    congruence ``diag(I, I/s, I)`` maps the LMI of ``(s E, s F, g)`` onto that of ``(E, F,
    g / s^2)``, with the same ``P`` and ``Y``.  The solver is therefore given the noise at unit
    scale and ``gamma^2`` is scaled back by ``s^2``: a problem stated in other units (the
    noise-level grid scales ``W`` and ``V`` together) gives the solver the same numbers, so
    its absolute tolerances and strictness margins act alike and the gain is the same."""
    A, C, E, F = plant
    E, F = np.atleast_2d(np.asarray(E, dtype=float)), np.atleast_2d(np.asarray(F, dtype=float))
    s = max((float(np.linalg.norm(G, 2)) for G in (E, F) if G.size), default=0.0)
    if not s > 0 or not np.isfinite(s):
        return plant, 1.0
    return LinearDesignProblem(A, C, E / s, F / s), s * s


def require_independent_outputs(C, who: str) -> None:
    """Refuse (:class:`~observers.errors.Unsupported`) an output matrix whose rows are linearly
    dependent (two sensors of one quantity, a rank-deficient ``C``): a gain ``L`` is then not
    determined by ``L C`` (``L`` and ``L + N`` with ``N C = 0`` act alike), so the feasible
    set of a gain LMI in ``Y = P L`` is unbounded along ``N`` and has no analytic centre
    (the Newton iteration diverged on the edge-case audit's repeated output)."""
    C = np.atleast_2d(np.asarray(C, float))
    m = C.shape[0]
    rank = int(np.linalg.matrix_rank(C)) if C.size else 0
    if rank < m:
        raise Unsupported(
            f"{who}: the {m} outputs are linearly dependent (C has rank {rank}; e.g. two "
            "sensors of one quantity), so its gain is not determined and the analytic centre "
            "of its LMI does not exist; merge or drop the dependent outputs")


def range_basis(G: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """Orthonormal basis of the range of ``G`` (n x rank)."""
    F = range_factor(G, rtol)
    return F / np.linalg.norm(F, axis=0) if F.shape[1] else F


def analytic_centre(
    blocks: list[np.ndarray],
    x0: np.ndarray,
    a_eq: np.ndarray,
    what: str,
    tol: float = 1e-13,
    max_iter: int = 200,
    linear: np.ndarray | None = None,
) -> np.ndarray:
    """Maximise ``sum_j log det F_j(x) [- linear' x]`` subject to ``a_eq' x = a_eq' x0`` by
    damped Newton (with ``linear``: a point of the central path of the SDP ``min linear' x``).

    ``F_j(x) = sum_i x_i blocks[j][i]`` are linear symmetric matrix functions (``blocks[j]``:
    an array of shape ``(N, k_j, k_j)``, one symmetric matrix per variable) and ``x0`` must be
    strictly feasible (every ``F_j(x0)`` positive definite).  The objective is self-concordant,
    so the damped Newton method (backtracking on the Armijo condition and on positive
    definiteness, checked by Cholesky factorisations) converges from any strictly feasible
    point, quadratically near the optimum; the iteration stops with a last full step when the
    squared Newton decrement falls below ``tol``.  Gradient and Hessian come from the whitened
    matrices
    ``K_i = L^-1 F_i L^-T`` (``F = L L'``): ``g_i = tr K_i``, ``H_ij = -<K_i, K_j>``.  Each
    block is factorised once per iteration: the factors of the accepted point of the line
    search give its value and the next gradient and Hessian.

    Returns the maximiser; raises :class:`DesignFailed` if the iteration does not converge
    within ``max_iter`` steps (the point returned by a caller is verified in numpy anyway).
    """
    x = np.asarray(x0, dtype=float).copy()
    a = np.asarray(a_eq, dtype=float)

    def factors(z: np.ndarray) -> list[np.ndarray] | None:
        """The Cholesky factors of every ``F_j(z)``, or ``None`` if one is not positive
        definite (``z`` infeasible)."""
        out = []
        for B in blocks:
            try:
                out.append(np.linalg.cholesky(np.tensordot(z, B, axes=1)))
            except np.linalg.LinAlgError:
                return None
        return out

    c = np.zeros(x.size) if linear is None else np.asarray(linear, dtype=float)

    def objective(z: np.ndarray):
        """``(factors, value)`` at ``z`` (``None`` if infeasible), for the line search."""
        chol_z = factors(z)
        return chol_z, (None if chol_z is None else value(chol_z) - float(c @ z))

    def value(chol: list[np.ndarray]) -> float:
        """``sum_j log det F_j`` from the factors of the ``F_j``."""
        total = 0.0
        for Lc in chol:
            total += 2.0 * float(np.log(np.diag(Lc)).sum())
        return total

    chol = factors(x)
    if chol is None:
        raise DesignFailed(f"{what}: the starting point of the analytic centre is infeasible")
    f = value(chol) - float(c @ x)
    N = x.size
    for _ in range(max_iter):
        g = -c.copy()
        H = np.zeros((N, N))
        for B, Lc in zip(blocks, chol, strict=True):
            Li = np.linalg.inv(Lc)
            K = (Li @ B @ Li.T).reshape(N, -1)
            k = B.shape[1]
            g += K[:, :: k + 1].sum(axis=1)
            H -= K @ K.T
        # Newton step on the hyperplane a' x = const: KKT system of -H (positive definite)
        kkt = np.block([[-H, a[:, None]], [a[None, :], np.zeros((1, 1))]])
        step = np.linalg.solve(kkt, np.concatenate([g, [0.0]]))[:N]
        decrement = float(g @ step)
        if not np.isfinite(decrement):
            break
        if decrement < tol:  # one last full step: quadratic convergence from here
            return x + step if factors(x + step) is not None else x
        found = _backtrack(x, step, f, decrement, factors,
                           value if linear is None else None, objective)
        if found is None:  # no progress at rounding level: accept a point near the optimum
            if decrement < 1e-8:
                return x
            break
        x, f, chol = found
    raise DesignFailed(f"{what}: the Newton iteration of the analytic centre did not converge")


# -- analytic centre of the decay cone, with a structured Hessian --------------------------------
def _backtrack(x: np.ndarray, step: np.ndarray, f: float, decrement: float, factors, value,
               objective=None):
    """Backtracking (Armijo) line search of the damped Newton methods of the analytic
    centres: the first ``t`` of 1, 1/2, 1/4, ... (down to 1e-12) at which the LMI still
    holds (``factors`` not None) and the concave objective rises by at least a quarter of the
    predicted ``t * decrement``; ``(x + t step, f_t, factors_t)``, or None if no such ``t``.
    ``objective(z) -> (factors, value)`` replaces ``factors`` and ``value`` where the
    objective also depends on ``z`` itself (a linear term)."""
    t = 1.0
    while t > 1e-12:
        if objective is None:
            chol_t = factors(x + t * step)
            f_t = None if chol_t is None else value(chol_t)
        else:
            chol_t, f_t = objective(x + t * step)
        if chol_t is not None:
            if f_t >= f + 0.25 * t * decrement:
                return x + t * step, f_t, chol_t
        t *= 0.5
    return None


def _decay_terms(A: np.ndarray, H: np.ndarray, rate: float) -> list[tuple[str, np.ndarray,
                                                                          np.ndarray]]:
    """The decay matrix ``D(P, Y) = [[rate P, M'], [M, P]]``, ``M = P A - Y H``, as a sum of
    terms ``L' Z R`` (``Z`` one of ``P``, ``Y``, ``Y'``): ``(kind, L, R)`` per term."""
    n = A.shape[0]
    J1 = np.hstack([np.eye(n), np.zeros((n, n))])
    J2 = np.hstack([np.zeros((n, n)), np.eye(n)])
    return [("P", J1, rate * J1), ("P", J2, J2), ("P", J2, A @ J1), ("P", A @ J1, J2),
            ("Y", J2, -H @ J1), ("Yt", -H @ J1, J2)]


def decay_matrix(A: np.ndarray, H: np.ndarray, rate: float, P: np.ndarray,
                 Y: np.ndarray) -> np.ndarray:
    """``[[rate P, M'], [M, P]]`` with ``M = P A - Y H`` (symmetrised), in numpy."""
    M = P @ A - Y @ H
    return sym(np.block([[rate * P, M.T], [M, P]]))


class DecayCone(NamedTuple):
    """The decay LMI ``D(P, Y) = [[rate P, M'], [M, P]] > 0``, ``M = P A - Y H``, whose
    analytic centre :func:`decay_centre` computes.

    Attributes
    ----------
    A : ndarray
        The dynamics (n x n).
    H : ndarray
        The matrix multiplying ``Y`` (m x n): ``C`` for Nom-G, ``C A`` for the PRad-C/D centre.
    rate : float
        The decay rate (the weight of ``P`` in the upper left block).
    with_logdet_P : bool
        Whether the objective also has the term ``log det P`` (the PRad-C/D centre).
    """

    A: Any
    H: Any
    rate: float
    with_logdet_P: bool = False


class _DecayNewton:
    """The pieces of the damped Newton method of :func:`decay_centre` for one
    :class:`DecayCone`: the reduced coordinates ``x`` (upper triangle of ``P``, then ``Y``
    row-major), the Cholesky factors of the LMIs at ``x``, the objective from them, and the
    gradient and Hessian assembled from the structure of ``D``."""

    def __init__(self, cone: DecayCone):
        A, H = np.asarray(cone.A, float), np.asarray(cone.H, float)
        self.A, self.H, self.rate = A, H, cone.rate
        self.with_logdet_P = cone.with_logdet_P
        self.n = n = A.shape[0]
        self.m = m = H.shape[0]
        self.terms = _decay_terms(A, H, cone.rate)
        nP2 = n * n
        self.Nf = Nf = nP2 + n * m  # full coordinates: P row-major, then Y row-major
        # where each kind of term sits in the full coordinates (``Yt``: Y, read transposed)
        self.where = {"P": (slice(0, nP2), False), "Y": (slice(nP2, Nf), False),
                      "Yt": (slice(nP2, Nf), True)}
        self.iu = iu = np.triu_indices(n)
        self.nP = iu[0].size
        # reduced coordinates: upper triangle of P (symmetric basis E_ij + E_ji), then Y; a
        # dummy full coordinate Nf (always zero) stands for the missing transpose of a
        # diagonal entry
        self.first = np.concatenate([iu[0] * n + iu[1], nP2 + np.arange(n * m)])
        self.second = np.concatenate([np.where(iu[0] == iu[1], Nf, iu[1] * n + iu[0]),
                                      np.full(n * m, Nf)])
        self.hess_full = np.empty((Nf + 1, Nf + 1))  # one buffer for every iteration

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(P, Y)`` of the reduced coordinates ``x``."""
        n = self.n
        P = np.zeros((n, n))
        P[self.iu] = x[:self.nP]
        return P + np.triu(P, 1).T, x[self.nP:].reshape(n, self.m)

    def factors(self, x: np.ndarray):
        """The Cholesky factors of ``D`` (and of ``P``) at ``x``, or ``None`` if one is not
        positive definite."""
        P, Y = self.unpack(x)
        try:
            out = [np.linalg.cholesky(decay_matrix(self.A, self.H, self.rate, P, Y))]
            if self.with_logdet_P:
                out.append(np.linalg.cholesky(P))
        except np.linalg.LinAlgError:
            return None
        return out

    @staticmethod
    def value(chol) -> float:
        """The objective (sum of the log-determinants) from the factors."""
        return sum(2.0 * float(np.log(np.diag(Lc)).sum()) for Lc in chol)

    def derivatives(self, chol) -> tuple[np.ndarray, np.ndarray]:
        """Gradient and Hessian in the reduced coordinates."""
        n, Nf, where = self.n, self.Nf, self.where
        g = np.zeros(Nf + 1)
        Hf = self.hess_full
        Hf.fill(0.0)
        blocks = [(chol[0], self.terms)]
        if self.with_logdet_P:
            blocks.append((chol[1], [("P", np.eye(n), np.eye(n))]))
        for Lc, ts in blocks:
            Li = np.linalg.inv(Lc)
            S = Li.T @ Li
            for kt, Lt, Rt in ts:
                st, tt = where[kt]
                G = Lt @ S @ Rt.T
                g[st] += (G.T if tt else G).ravel()
            kinds = sorted({t[0] for t in ts})
            for kt in kinds:
                st, tt = where[kt]
                for ku in kinds:
                    su, tu = where[ku]
                    pairs = [(Rt @ S @ Lu.T, Ru @ S @ Lt.T)
                             for k1, Lt, Rt in ts if k1 == kt for k2, Lu, Ru in ts if k2 == ku]
                    # sum over the pairs of M[j, k] N[l, i]: one matrix product
                    J, K = pairs[0][0].shape
                    Lq, Iq = pairs[0][1].shape
                    Ms = np.stack([M.ravel() for M, _ in pairs])
                    Ns = np.stack([Nm.ravel() for _, Nm in pairs])
                    C4 = (Ms.T @ Ns).reshape(J, K, Lq, Iq).transpose(3, 0, 1, 2)
                    if tt:  # dZ_t = dY': entry (i, j) is Y[j, i]
                        C4 = C4.transpose(1, 0, 2, 3)
                    if tu:
                        C4 = C4.transpose(0, 1, 3, 2)
                    Hf[st, su] -= C4.reshape(C4.shape[0] * C4.shape[1], -1)
        Hf[Nf, :] = 0.0
        Hf[:, Nf] = 0.0
        g[Nf] = 0.0
        first, second = self.first, self.second
        gr = g[first] + g[second]
        Hf[:, first] += Hf[:, second]  # columns, then rows, folded in place
        Hr = Hf[first][:, first]
        Hr += Hf[second][:, first]
        return gr, Hr


def decay_centre(
    cone: DecayCone,
    P0: np.ndarray,
    Y0: np.ndarray,
    what: str,
    tol: float = 1e-13,
    max_iter: int = 200,
) -> tuple[np.ndarray, np.ndarray]:
    """Analytic centre of the decay cone: maximise ``log det D(P, Y) [+ log det P]`` subject to
    ``tr P = tr P0`` by damped Newton, ``D(P, Y) = [[rate P, M'], [M, P]]``, ``M = P A - Y H``
    (``cone``: a :class:`DecayCone`, the ``log det P`` term with its ``with_logdet_P``).

    The problem of :func:`analytic_centre` for the LMIs of Nom-G (``H = C``) and of the
    PRad-C/D centre (``H = C A``, ``with_logdet_P``), with the gradient and the Hessian
    assembled from the structure of ``D`` instead of from a basis of matrices.  Writing ``D``
    as a sum of terms ``L_t' Z_t R_t`` (``Z_t`` is ``P``, ``Y`` or ``Y'``) and ``S = D^-1``,

    * the gradient of ``log det D`` in ``Z_t`` is ``L_t S R_t'``, and
    * the Hessian is ``-tr(S dD S dD) = -sum_{t,u} tr(dZ_t (R_t S L_u') dZ_u (R_u S L_t'))``,
      whose coefficient of ``dZ_t[i, j] dZ_u[k, l]`` is ``(R_t S L_u')[j, k] (R_u S L_t')[l, i]``
      (one outer product per pair of terms),

    so an iteration costs ``O(n^4)`` operations and an ``(n^2/2 + n m)``-dimensional linear
    solve, against ``O(n^6)`` for the basis form (:class:`_DecayNewton`).  The damped Newton
    iteration (backtracking on the Armijo condition and on positive definiteness, by
    Cholesky factorisations) is that of :func:`analytic_centre` (Boyd & Vandenberghe, Convex
    Optimization, Secs. 9.5-9.6 and 10.2: the objective is self-concordant, so it converges
    from any strictly feasible start, quadratically near the optimum).  ``(P0, Y0)`` must be
    strictly feasible.

    Returns ``(P, Y)``; raises :class:`DesignFailed` if the start is infeasible or the
    iteration does not converge.
    """
    import scipy.linalg as sla

    nt = _DecayNewton(cone)
    n, m, iu = nt.n, nt.m, nt.iu
    P0 = sym(P0)
    x = np.concatenate([P0[iu], np.asarray(Y0, float).ravel()])
    a = np.concatenate([(iu[0] == iu[1]).astype(float), np.zeros(n * m)])
    chol = nt.factors(x)
    if chol is None:
        raise DesignFailed(f"{what}: the starting point of the analytic centre is infeasible")
    f = nt.value(chol)
    for _ in range(max_iter):
        g, Hr = nt.derivatives(chol)
        # Newton step on the hyperplane a' x = const: with K = -H (positive definite),
        # step = K^-1 (g - nu a), nu chosen so that a' step = 0
        try:
            Kc = sla.cho_factor(-Hr, overwrite_a=True)
        except np.linalg.LinAlgError:
            break
        del Hr
        zg, za = sla.cho_solve(Kc, np.column_stack([g, a])).T
        step = zg - (a @ zg) / (a @ za) * za
        decrement = float(g @ step)
        if not np.isfinite(decrement):
            break
        if decrement < tol:  # one last full step: quadratic convergence from here
            return nt.unpack(x + step if nt.factors(x + step) is not None else x)
        found = _backtrack(x, step, f, decrement, nt.factors, nt.value)
        if found is None:  # no progress at rounding level: accept a point near the optimum
            if decrement < 1e-8:
                return nt.unpack(x)
            break
        x, f, chol = found
    raise DesignFailed(f"{what}: the Newton iteration of the analytic centre did not converge")


def cone_point(cone: DecayCone, solver: str, start: Callable[[], tuple[np.ndarray, np.ndarray]],
               clarabel: Callable[[], tuple[np.ndarray, np.ndarray]] | None, what: str
               ) -> tuple[np.ndarray, np.ndarray]:
    """A point ``(P, Y)`` of the decay ``cone`` by the route ``solver``: ``"newton"`` its
    analytic centre (:func:`decay_centre` from the strictly feasible point ``start()``),
    ``"start"`` that point itself, ``"clarabel"`` the point ``clarabel()`` (the centre as a
    cvxpy log-det problem); the routes of Nom-G and of the PRad-C/D centre."""
    if solver == "newton":
        P0, Y0 = start()
        return decay_centre(cone, P0, Y0, what)
    if solver == "start":
        return start()
    if solver == "clarabel" and clarabel is not None:
        return clarabel()
    raise DesignFailed(f"{what}: unknown solver {solver!r} (use 'newton', 'start' or "
                       "'clarabel')")
