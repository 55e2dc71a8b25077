"""Parallelotope updates of the reduced-order parallelotopic observer (ROPO).

A parallelotope is ``P = {c + T xi : ||xi||_inf <= 1}`` with a square generator matrix ``T``
(n x n); for an invertible ``T`` it is the intersection of the n strips
``|h_j' (x - c)| <= 1`` with ``H = T^-1``.  Every computation below works in the coordinates
``xi`` of the current parallelotope, where ``P`` is the unit box, so ``T`` is never inverted
and may be singular (a flat parallelotope, e.g. after an exact sensor).

Measurement update (Vicino & Zappa, IEEE TAC 41(6), 1996; Chisci, Garulli & Zappa,
Automatica 32(7), 1996), one measured output after the other.  The output ``g' x`` of row
``g`` of ``C`` lies in ``[lo, hi] = [y - v_hi, y - v_lo]`` (``[v_lo, v_hi]``: that component of
the interval hull of ``V``).  In ``xi`` coordinates the strip is ``alpha <= q' xi <= beta``
with ``q = T' g`` and ``[alpha, beta] = [lo, hi] - g' c``, and ``P`` is the n strips
``-1 <= xi_j <= 1``: n + 1 strips in all.  Each strip is first tightened to the true extent
of its functional over the intersection ``Q`` (closed form, exact):

* the measurement strip: ``q' xi`` ranges over ``[-s, s]`` on the box, ``s = ||q||_1``, so
  its extent over ``Q`` is ``[max(alpha, -s), min(beta, s)]`` (empty if the two intervals do
  not meet: the measurement contradicts the estimate);
* strip ``j`` of ``P``: for fixed ``xi_j = t`` the other coordinates move ``q' xi`` over
  ``q_j t + [-s_j, s_j]`` with ``s_j = s - |q_j|``, so ``t`` is feasible if and only if
  ``alpha - s_j <= q_j t <= beta + s_j``: an interval ``[l_j, u_j]`` inside ``[-1, 1]``.

Dropping one of the n + 1 tightened strips leaves a parallelotope containing ``Q``.  Its
volume is ``prod(widths) / |det(normals)|`` (times ``|det T|``): dropping the measurement
strip gives the box ``prod_j (u_j - l_j)``; dropping strip ``j`` replaces ``u_j - l_j`` by
``(beta - alpha) / |q_j|`` (the normals ``{e_i, i != j} + {q}`` have determinant ``+-q_j``).
So the least volume drops the strip ``j`` of the largest ``|q_j| (u_j - l_j)`` if that
exceeds ``beta - alpha``, and the measurement strip otherwise: n + 1 candidates compared in
O(n), the chosen one built in O(n^2).

Time update: ``A P + B u + W`` is the zonotope with generators ``[A T, E]`` (``E``: those of
``W``), enclosed by a parallelotope with ``n`` axes ``B`` (columns): ``T+ = B diag(r)``,
``r = |B^-1 [A T, E]| 1`` (the tightest parallelotope with these axes).  Its volume is
``|det B| prod(r)``.  The candidate bases are the propagated axes ``A T`` (exact when
``W = {0}``); n of the generators as axes (Chisci et al.: the axes of the least-volume
parallelotope are sought among the generators), found by exchange from ``A T``
(:func:`generator_axes`); the principal axes of the generators
(:func:`observers.sets.reduction.jacobi_principal_axes`, the order-1 PCA reduction, its axes
from one-sided Jacobi up to 30 states: from LAPACK, ROPO's radii on 30 tanks moved by 2.5e-4
between BLAS kernels, now 3.5e-6); and the
coordinate axes (the order-1 Girard reduction, the interval hull).  The default takes the
one of least volume.

Least volume is a greedy criterion: it keeps thin parallelotopes, whose interval hulls can
be far larger than the set.  Measured on the linearised 6-tank record (seed 0) with least
volume alone: the condition number of ``T`` climbs from about 1e2 at step 70 to 9e9 at
step 136, and the radius of the unmeasured, slow x6 from 3.5 to 4.6e7 (then it decays with
the eigenvalue 0.996), while the other states stay close to the strip observers'.  So the
default ``min-volume`` keeps least volume as the criterion but considers only candidate axes
whose column-normalised condition number is at most :data:`MIN_VOLUME_COND_MAX` (100; the
principal and coordinate axes always qualify).  Measured (RMS radius averaged over the
states, least volume alone -> with the bound): 6-tank seeds 0-4 from 4e6-5e6 to 0.84-0.97
(x6 2.7), 12 tanks 1.8e6 -> 0.64, CORA's 30-tank record 6.8e5 -> 0.53, the 6-state vehicle
0.788 -> 0.808 (CORA's record; x6 4.23 -> 4.34), the 2-D systems unchanged.  Bounds of 150-300
gave 6-tank averages 0.93-1.09 and the vehicle unchanged; 30 was unstable (seed 2: 222).
"""

from __future__ import annotations

import math

import numpy as np

from observers.sets import EmptySet
from observers.sets.reduction import jacobi_principal_axes

from ..kernels import exchange, switch
from ..kernels.step import TIE_RTOL
from .linalg import first_best

#: candidate bases of the time update; "min-volume" tries them all and keeps the smallest
BASES = ("generators", "propagated", "pca", "box")
BASIS_CHOICES = ("min-volume", *BASES)
#: the candidates of "min-volume" ("generators" starts from "propagated" and only improves it)
MIN_VOLUME = ("generators", "pca", "box")
#: a candidate basis whose column-normalised condition number exceeds this is skipped
#: (``B^-1 G`` would be computed too inaccurately to bound the set)
COND_MAX = 1e10
#: the stricter bound of the "min-volume" choice: candidate axes (generators, propagated)
#: whose column-normalised condition number exceeds this are not considered there (the
#: principal and coordinate axes, condition 1, always are); see the module docstring
MIN_VOLUME_COND_MAX = 100.0
#: exchanges of the generator-axes search per time update, in units of n
MAX_EXCHANGES = 2
#: largest temporary array (elements) of the generator-axes search: its exchanges are
#: scored in blocks of generators of at most this size
CHUNK_ELEMENTS = 1 << 21
#: pivots of the generator-axes search below this fraction of their column's largest entry
#: are not tried (an ill-conditioned exchange)
PIVOT_RTOL = 1e-6
#: least work of the direct scoring of one exchange (``K n^2 r`` tableau entries) for which
#: the compiled shortlist (:func:`shortlist`) runs first: below it (up to about 15 states) the
#: direct scoring is cheaper than the shortlist's call (measured: 6-tank and vehicle steps
#: 20-30 % slower with it, the 30-tank step twice as fast)
SHORTLIST_MIN_WORK = 200_000
# TIE_RTOL (the project's tie tolerance, observers.kernels.step) is the relative margin of
# every choice between candidates here (strip to drop, axes, exchange): a later candidate must
# be better by more than it, so that near-ties (the identical tanks and box-shaped sets of the
# benchmarks give exact ones) are decided the same way whatever the rounding of the BLAS kernel
#: relative slack below which a measurement that misses the estimate counts as touching it
#: (rounding of the strip offsets), instead of as an empty intersection
TOUCH_RTOL = 1e-12


def touching_faces(alpha: float, beta: float, s: float, slack: float) -> tuple[float, float]:
    """The strip ``alpha <= q' xi <= beta`` of a parallelotope ``|xi|_inf <= 1`` (``s = |q|_1``),
    widened outward by its rounding ``slack`` where it only touches a face ``q' xi = +-s``.

    Where a strip meets the parallelotope in (a rounding-level sliver of) a face, that face
    would pin every ``xi_j`` with ``q_j != 0`` to ``sign(q_j)``, also those whose ``q_j`` is
    rounding (1e-17 where it is 0 in exact arithmetic): on a 3-state plant with two sensors of
    one quantity (their strips meet in a hyperplane) the true state was cut off by up to 0.04
    (the edge-case audit).  Only such strips are widened: a strip that crosses the interior is
    left as it is, so that the near-tied least-volume choices of the benchmarks (30 identical
    tanks) are not moved by a slack that differs between BLAS kernels.
    """
    if alpha > s - slack or beta < -s + slack:
        return alpha - slack, beta + slack
    return alpha, beta


def strip_cut(
    c: np.ndarray, T: np.ndarray, g: np.ndarray, lo: float, hi: float
) -> tuple[np.ndarray, np.ndarray]:
    """Least-volume parallelotope containing ``{c + T xi : |xi|_inf <= 1}`` cut by the strip
    ``lo <= g' x <= hi`` (see the module docstring; Vicino & Zappa 1996).

    Parameters
    ----------
    c, T : ndarray
        Centre (n,) and generator matrix (n x n) of the parallelotope.
    g : ndarray
        Normal of the strip (n,).
    lo, hi : float
        Bounds of ``g' x`` (``lo <= hi``; ``lo == hi`` is an exact measurement).

    Returns
    -------
    c, T : ndarray
        The new centre and generator matrix (the inputs themselves if the strip does not cut).

    Raises
    ------
    observers.sets.EmptySet
        If the strip misses the parallelotope (the measurement contradicts the estimate).
    """
    q = T.T @ g
    gc = g @ c
    alpha, beta = lo - gc, hi - gc
    aq = np.abs(q)
    s = float(aq.sum())
    slack = TOUCH_RTOL * (s + abs(alpha) + abs(beta) + abs(gc))
    if alpha > s + slack or beta < -s - slack:
        raise EmptySet(f"the measurement strip [{lo:.6g}, {hi:.6g}] of g'x misses the "
                       f"estimate ([{gc - s:.6g}, {gc + s:.6g}])")
    alpha, beta = touching_faces(alpha, beta, s, slack)
    alpha, beta = min(max(alpha, -s), s), max(min(beta, s), -s)
    if alpha <= -s and beta >= s:  # the strip contains P: nothing to cut
        return c, T
    # exact extent [l_j, u_j] of xi_j over the intersection
    sj = s - aq
    with np.errstate(all="ignore"):  # q_j = 0 (masked below) or tiny: +-inf, clipped
        t1, t2 = (alpha - sj) / q, (beta + sj) / q
    lo_j = np.where(q != 0, np.maximum(np.minimum(t1, t2), -1.0), -1.0)
    hi_j = np.where(q != 0, np.minimum(np.maximum(t1, t2), 1.0), 1.0)
    mid = 0.5 * (lo_j + hi_j)
    half = np.maximum(0.5 * (hi_j - lo_j), 0.0)
    score = aq * (2.0 * half)  # |q_j| (u_j - l_j): drop strip j beats the box if > beta-alpha
    j = first_best(-score)
    if score[j] <= (beta - alpha) * (1.0 + TIE_RTOL):  # drop the measurement strip: the box
        return c + T @ mid, T * half
    # drop strip j: xi_i = mid_i + half_i eta_i (i != j), q' xi = gamma + delta eta_0, and
    # xi_j = (q' xi - sum_{i != j} q_i xi_i) / q_j
    gamma, delta = 0.5 * (alpha + beta), 0.5 * (beta - alpha)
    qj, tj = q[j], T[:, j]
    others = q * mid
    others[j] = 0.0
    centre = mid.copy()
    centre[j] = (gamma - others.sum()) / qj
    coef = q * half / qj  # xi_j moves by -coef_i eta_i with eta_i
    T_new = T * half - np.outer(tj, coef)
    T_new[:, j] = tj * (delta / qj)
    return c + T @ centre, T_new


def measurement_update(
    c: np.ndarray, T: np.ndarray, C: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    r""":func:`strip_cut` for every row of ``C`` in turn (bounds ``lo <= C x <= hi``).

    Notes
    -----
    For the row :math:`g^\top` of :math:`C` and the parallelotope
    :math:`\{c + T \xi \mid \|\xi\|_\infty \le 1\}`, in the coordinates :math:`\xi` the
    strip is :math:`\alpha \le q^\top \xi \le \beta` with

    .. math::

        q = T^\top g, \qquad [\alpha, \beta] = [\mathit{lo} - g^\top c,\
        \mathit{hi} - g^\top c] \cap [-s, s], \qquad s = \|q\|_1 ,

    and each strip :math:`|\xi_j| \le 1` of the parallelotope is tightened to its exact
    extent over the intersection (:math:`s_j = s - |q_j|`):

    .. math::

        \xi_j \in [l_j, u_j] = [-1, 1] \cap
        \left\{ t \mid \alpha - s_j \le q_j t \le \beta + s_j \right\} .

    Dropping one of the :math:`n + 1` tightened strips leaves a parallelotope that contains
    the intersection; its volume is (up to the common factor :math:`|\det T|`)
    :math:`\prod_j (u_j - l_j)` without the measurement strip and
    :math:`\frac{\beta - \alpha}{|q_j|} \prod_{i \ne j} (u_i - l_i)` without strip
    :math:`j`, so the least volume drops the strip :math:`j` of largest
    :math:`|q_j| (u_j - l_j)` if that exceeds :math:`\beta - \alpha`, else the measurement
    strip (Vicino & Zappa 1996).
    """
    for i in range(C.shape[0]):
        c, T = strip_cut(c, T, C[i], float(lo[i]), float(hi[i]))
    return c, T


def outer_parallelotope(
    G: np.ndarray, B: np.ndarray, orthonormal: bool = False, cond_max: float = COND_MAX
) -> tuple[np.ndarray, float] | None:
    """Tightest parallelotope with axes ``B`` (columns) around the generators ``G``
    (``orthonormal=True``: ``B`` is known to be orthonormal, no conditioning check).

    Returns
    -------
    (T, log_volume) or None
        ``T = B diag(r)`` with ``r = |B^-1 G| 1`` and ``log(|det B| prod r)`` (``-inf`` for a
        flat result); ``None`` if ``B`` is (numerically) singular or its column-normalised
        condition number exceeds ``cond_max``.
    """
    if orthonormal:
        r = np.abs(B.T @ G).sum(axis=1)
        with np.errstate(divide="ignore"):
            return B * r, float(np.log(r).sum())
    norms = np.linalg.norm(B, axis=0)
    if not np.all(norms > 0) or not np.all(np.isfinite(B)):
        return None
    Bn = B / norms
    if np.linalg.cond(Bn) > cond_max:
        return None
    r = np.abs(np.linalg.solve(Bn, G)).sum(axis=1)
    with np.errstate(divide="ignore"):
        log_volume = float(np.linalg.slogdet(Bn)[1] + np.log(r).sum())
    return Bn * r, log_volume


def generator_axes(G: np.ndarray, n: int) -> np.ndarray | None:
    """Axes chosen among the generators (Chisci et al. 1996: a parallelotope whose axes are n
    of the generators), by exchange from the first ``n`` columns of ``G``.

    With the axes ``B`` (n columns of ``G``) and the tableau ``M = B^-1 G``, the volume is
    ``|det B| prod_i r_i``, ``r_i = sum_k |M_ik|``.  Exchanging axis ``i`` for generator ``k``
    multiplies ``det B`` by ``M_ik`` and pivots the tableau on ``(i, k)`` (as a simplex
    step), so every exchange is scored without a new solve; the best one is made while it
    lowers the volume, at most :data:`MAX_EXCHANGES` times n.  ``None`` if the first ``n``
    columns are numerically singular (column-normalised condition number above
    :data:`COND_MAX`).  The axes are returned in the order of their generators in ``G``.
    The caller recomputes the enclosure from the returned axes.

    Scoring all ``K n`` exchanges directly costs ``K n^2 r`` per exchange made (seconds at 200
    states); with numba the compiled approximate scores (``n^2 r log r``) and their error
    bounds first rule out the exchanges that cannot be chosen (:func:`shortlist`), and only
    the others are scored directly, so the axes are those of the direct scoring, bit for bit.
    """
    B0 = G[:, :n]
    norms = np.linalg.norm(B0, axis=0)
    # numerically singular as outer_parallelotope judges it (COND_MAX), not only where the LU
    # factorisation meets an exact zero: two columns parallel in exact arithmetic gave a
    # zero pivot on one BLAS kernel and a huge tableau on another (ROPO on the DC motor)
    if not np.all(norms > 0) or not np.linalg.cond(B0 / norms) <= COND_MAX:
        return None
    try:
        with np.errstate(all="ignore"):
            M = np.linalg.solve(B0, G)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(M)):
        return None
    idx = np.arange(n)
    with np.errstate(divide="ignore"):
        current = float(np.log(np.abs(M).sum(axis=1)).sum())  # log volume - log|det B0|
    rows = np.arange(n)
    for _ in range(MAX_EXCHANGES * n):
        out = np.setdiff1d(np.arange(G.shape[1]), idx)
        P = M[:, out].T  # (K, n): the pivot column of every generator outside the axes
        aP = np.abs(P)
        ok = aP > PIVOT_RTOL * aP.max(axis=1, keepdims=True)
        ok &= aP > 0
        if not ok.any():
            break
        aPv = np.where(ok, aP, 1.0)
        Pv = np.where(ok, P, 1.0)
        row_sums = np.abs(M).sum(axis=1)
        scores = np.full_like(P, np.inf)
        step = max(1, CHUNK_ELEMENTS // M.size // n)  # generators scored per block
        for b in _blocks(shortlist(M, out, ok), step):
            # tableau rows after pivoting on (i, k) for the generators k of this block:
            # row l -> M_l - (P_kl / P_ki) M_i (k x n_i x n_l x r), row i -> M_i / P_ki
            ratio = P[b, None, :] / Pv[b, :, None]
            sums = np.abs(M[None, None, :, :] - ratio[..., None] * M[None, :, None, :]).sum(3)
            sums[:, rows, rows] = row_sums[None, :] / aPv[b]
            with np.errstate(divide="ignore"):
                scores[b] = np.log(aPv[b]) + np.log(sums).sum(axis=2)
        scores[~ok] = np.inf
        if not np.isfinite(scores).any():
            break
        kk, i = np.unravel_index(first_best(scores.ravel()), scores.shape)
        if not scores[kk, i] < current - TIE_RTOL * max(1.0, abs(current)):
            break
        current, k = float(scores[kk, i]), int(out[kk])
        p, pivot_row = M[:, k].copy(), M[i].copy()
        M -= np.outer(p / p[i], pivot_row)
        M[i] = pivot_row / p[i]
        idx[i] = k
    # the axes in the order of the generators: two exchange sequences that reach the same
    # generators give the same axes (the order is the next step's starting basis)
    return G[:, np.sort(idx)]


def shortlist(M: np.ndarray, out: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The generators (positions in ``out``) whose exchanges :func:`generator_axes` scores
    directly: with numba and at least :data:`SHORTLIST_MIN_WORK` of work, only those with a
    pair that the compiled approximate scores and their error bounds
    (:mod:`observers.kernels.exchange`) cannot rule out of the band of
    :func:`~observers.numerics.linalg.first_best` around the least score (the others score
    more than the band above it whatever the rounding, so the choice is the direct
    scoring's); without numba, or where a bound fails, all of them."""
    everyone = np.arange(out.size)
    n, r = M.shape
    if (exchange.exchange_scores is None or not switch.use_compiled() or not ok.any()
            or out.size * n * n * r < SHORTLIST_MIN_WORK):
        return everyone
    approx, err = exchange.exchange_scores(np.ascontiguousarray(M), out.astype(np.int64),
                                           np.ascontiguousarray(ok))
    known = ok & np.isfinite(approx) & np.isfinite(err)
    if not known.any():
        return everyone
    lo, hi = approx - err, approx + err
    top = float(hi[known].min())  # the least direct score is at most this
    bottom = float(lo[known].min())
    # a pair is left out only if its score exceeds the least one by more than first_best's
    # band; a pair without a bound is always scored (the band is wide enough even where the
    # least score is such a pair's, below ``bottom``: see the module of the kernel)
    band = TIE_RTOL * max(abs(top), abs(bottom))
    keep = (ok & ~known) | (known & (lo <= top + band))
    return np.flatnonzero(keep.any(axis=1))


def _blocks(picked: np.ndarray, step: int):
    """The positions ``picked`` in blocks of at most ``step``."""
    for a in range(0, picked.size, step):
        yield picked[a:a + step]


def candidate_bases(basis: str, G: np.ndarray, propagated: np.ndarray | None) -> list:
    """The axes tried by the time update for the option ``basis`` (:data:`BASIS_CHOICES`):
    ``(B, orthonormal)`` pairs."""
    names = MIN_VOLUME if basis == "min-volume" else (basis,)
    out = []
    for name in names:
        if name == "propagated" and propagated is not None:
            out.append((propagated, False))
        elif name == "generators" and propagated is not None:
            B = generator_axes(G, propagated.shape[1])
            out.append((propagated if B is None else B, False))
        elif name == "pca":
            out.append((jacobi_principal_axes(G), True))
        elif name == "box":
            out.append((np.eye(G.shape[0]), True))
    return out


def enclose(G: np.ndarray, basis: str, propagated: np.ndarray | None = None) -> np.ndarray:
    r"""Least-volume parallelotope generator matrix (n x n) around the zonotope generators
    ``G`` among the candidate bases of ``basis`` (:func:`candidate_bases`).

    Flat candidates (volume zero) are compared by their squared Frobenius norm.  The
    principal axes are always invertible, so a singular propagated basis falls back to them
    (and, with ``basis="propagated"``, to the coordinate axes).  ``"min-volume"`` considers
    only axes of condition number up to :data:`MIN_VOLUME_COND_MAX`.

    Notes
    -----
    For candidate axes :math:`B` (columns), the tightest parallelotope with these axes
    around :math:`\langle 0, G \rangle` and its volume are

    .. math::

        T_B = B \operatorname{diag}(r), \qquad r = |B^{-1} G|\, \mathbf{1}, \qquad
        \operatorname{vol} = 2^n |\det B| \prod_i r_i ,

    and the candidate of least volume is returned (axes: propagated :math:`A T`, :math:`n`
    of the generators by exchange, principal axes, coordinate axes).
    """
    best = None
    cond_max = MIN_VOLUME_COND_MAX if basis == "min-volume" else COND_MAX
    for B, orthonormal in candidate_bases(basis, G, propagated):
        got = outer_parallelotope(G, B, orthonormal, cond_max)
        if got is None:
            continue
        T, logv = got
        frob = float(np.sum(T * T))
        if best is None or _better((logv, frob), best[0]):
            best = ((logv, frob), T)
    if best is None:  # only a singular propagated basis was asked for
        return outer_parallelotope(G, np.eye(G.shape[0]), True)[0]
    return best[1]


def _better(new: tuple[float, float], old: tuple[float, float]) -> bool:
    """Whether (log volume, squared Frobenius norm) ``new`` beats ``old`` by more than
    :data:`TIE_RTOL` (volume first; the norm decides between equal volumes, e.g. flat sets)."""
    (lv, f), (lv0, f0) = new, old
    if math.isinf(lv) or math.isinf(lv0):  # a flat candidate: volume zero
        if lv != lv0:
            return lv < lv0
    elif abs(lv - lv0) > TIE_RTOL * max(1.0, abs(lv0)):
        return lv < lv0
    return f < f0 * (1.0 - TIE_RTOL)


def time_update(
    c: np.ndarray, T: np.ndarray, A: np.ndarray, d: np.ndarray, E: np.ndarray, basis: str
) -> tuple[np.ndarray, np.ndarray]:
    r"""Parallelotope enclosing ``A P + d + {E w : |w|_inf <= 1}`` (``d``: ``B u`` plus the
    centre of ``W``), with axes chosen by :func:`enclose`.

    Notes
    -----
    .. math::

        c^p = A c + d, \qquad
        A \mathcal{P} \oplus d \oplus E \mathcal{B}^{n_w} \subseteq
        \{c^p + T^p \xi \mid \|\xi\|_\infty \le 1\}, \qquad
        T^p = \operatorname{enclose}\bigl([A T,\ E]\bigr) .
    """
    AT = A @ T
    G = np.hstack([AT, E]) if E.shape[1] else AT
    return A @ c + d, enclose(G, basis, AT)
