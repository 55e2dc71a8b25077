"""Numeric kernels of the volume-minimising strip intersections (VolMin-A, VolMin-B).

Both act on one measurement strip ``|c x - y| <= sigma`` (``c`` a row of ``C``) and a zonotope
``(c0, G)`` with ``G`` of shape n x r.

* :func:`bravo_choice` / :func:`bravo_update` (Bravo, Alamo, Camacho, IEEE TAC 51(7), 2006,
  Sec. III.B; intersection method III of Althoff & Rath 2021): choose, among the r + 1
  candidate zonotopes, the one of least ``det(T T')``.  Candidate ``j >= 1`` eliminates
  generator ``g_j``: with ``a = c G`` and ``lambda_j = g_j / a_j``,
  ``T_j = [(I - lambda_j c) G  with column j replaced by  sigma lambda_j]``; candidate 0 (and
  every ``j`` with ``|a_j| <= 1e10 eps``, CORA's rule) is the unchanged zonotope.
* :func:`volume_lp_gain` (Alamo, Bravo, Camacho, Automatica 41(6), 2005, Sec. 6.2): the gain
  ``lambda`` minimising the exact volume of the enclosure ``strip_update(c0, G, lambda)``, a
  linear program over the volume expression (exponential in the generator count).

Scoring all Bravo candidates at once
------------------------------------
Because ``(I - lambda_j c) g_j = 0``, ``T_j T_j' = P_j M P_j' + sigma^2 lambda_j lambda_j'``
with ``M = G G'`` and the oblique projector ``P_j = I - lambda_j c``.  Let ``B`` (n x n-1) be an
orthonormal basis of the null space of ``c``.  In the coordinates ``R_j = [c; B' P_j]``
(``R_j = [lambda_j, B]^-1``, ``det(R_j)^2 = ||c||^2``) the matrix ``T_j T_j'`` is
block-diagonal with blocks ``sigma^2`` and ``B' P_j M P_j' B``.  Since
``B' P_j G = B'G - (B' g_j / a_j) a'``, and writing ``Gt = B' G (I - a a' / a'a)``
((n-1) x r, independent of j) with columns ``t_j``, the second block is
``S0 + (a'a / a_j^2) t_j t_j'`` with ``S0 = Gt Gt'``.  The matrix determinant lemma in its
adjugate form (valid for singular ``S0`` too) then gives all scores at once:

    det(T_j T_j') = sigma^2 / ||c||^2 * (det S0 + (a'a / a_j^2) * t_j' adj(S0) t_j),

at a cost of O(n^2 r) per strip instead of r determinants of n x r products.  It is also
more accurate than forming ``T_j T_j'``, which cancels badly when ``|a_j|`` is small.
VolMin-B's step uses the same scores from the Gram matrix ``G G'`` (:func:`bravo_scores_gram`,
one ``n x n`` by ``n x r`` product per strip instead of about four), formed once per step and
carried from strip to strip by a rank-two update (:func:`gram_update`); measured on the
regression records and on 12 and 30 tanks, it chooses the same candidates as
:func:`bravo_scores` at every strip (identical hulls).

Scores from leverages, O(n r) per strip
---------------------------------------
Where ``M`` is positive definite the scores simplify.  In the orthogonal coordinates
``[c / ||c||, B]`` the matrix ``S0 = B' (M - u u' / q) B`` (``u = M c'``, ``q = c M c'``)
is the Schur complement of the first entry of ``M``, so ``S0^-1 = B' M^-1 B`` and
``det S0 = det(M) ||c||^2 / q``; ``t_j`` and the projected ``g_j - (a_j / q) u`` have the same
quadratic form, ``t_j' adj(S0) t_j = det(S0) (h_j - a_j^2 / q)`` with the *leverage*
``h_j = g_j' M^-1 g_j``.  Hence

    det(T_j T_j') / det(G G') = sigma^2 h_j / a_j^2        (candidate 0: 1),

and ``h_j >= a_j^2 / q`` (Cauchy-Schwarz in the metric of ``M``) bounds the ratio below by
``sigma^2 / q``.  After candidate ``j`` is taken, ``G G'`` changes by a rank-two term and
Woodbury's identity gives, with ``w = M^-1 g_j`` and ``v = G' w``,

    M^-1 <- M^-1 - w w' / h_j + c' c / sigma^2,    h_o <- h_o - v_o^2 / h_j  (o != j),    h_j <- 1,

so a strip costs two products with ``G`` (``a = c G`` and ``v``) and ``O(n^2)`` more
(:func:`leverages`, :func:`bravo_ratios`, :func:`leverage_update`), instead of the ``n^2 r`` of
the Gram scores; ``M^-1`` and ``h`` are computed afresh at every step.  The two ways choose
the same candidates up to the ties of :func:`~observers.numerics.linalg.first_best`.

The projections of all strips at once
-------------------------------------
Most strips keep their zonotope (candidate 0; on 200 tanks about 5 of 163 strips per step
take a candidate), and then ``a = c G`` is the only product with ``G`` a strip needs.  VolMin-B
therefore forms ``P = C G`` for all strips of a step in one matrix product and carries its
rows to the later strips by the exact rank-one change of :func:`projections_update`: after
candidate ``j`` of strip ``i``, row ``k`` of ``C G(j)`` is ``P_k - (c_k lambda_j) a_i'`` with
entry ``j`` equal to ``sigma (c_k lambda_j)``.  One product ``C G`` per step is cheaper than
one ``c G`` per strip (a matrix product reads ``G`` once, the strips read it 163 times).
"""

from __future__ import annotations

import math
from functools import lru_cache
from itertools import combinations

import highspy
import numpy as np
import scipy.linalg
import scipy.sparse as sp

from observers.kernels.step import CHOLESKY_MIN_PIVOT
from observers.lp import new_highs

from .linalg import first_best

#: CORA's threshold below which ``c g_j`` counts as zero (candidate j = unchanged zonotope;
#: VolMin-B passes it to its compiled step too)
ZERO_PROJECTION = 1e10 * np.finfo(float).eps


def null_basis(c_row: np.ndarray) -> np.ndarray:
    """Orthonormal basis (n x n-1) of the null space of the row vector ``c_row``."""
    c_row = np.asarray(c_row, dtype=float).reshape(1, -1)
    _, _, Vt = np.linalg.svd(c_row)
    return Vt[1:].T


def psd_inverse(S: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(L, S^-1)`` of a symmetric positive definite ``S = L L'`` (the inverse from the
    Cholesky factor, ``L^-T L^-1``, symmetrised), or None where ``S`` is not positive definite
    or badly conditioned: the least diagonal entry of ``L`` at most ``CHOLESKY_MIN_PIVOT``
    (1e-6) times the largest, a condition number above about 1e12."""
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return None
    d = np.diag(L)
    if not d.min() > CHOLESKY_MIN_PIVOT * d.max():
        return None
    Li = scipy.linalg.solve_triangular(L, np.eye(S.shape[0]), lower=True)
    N = Li.T @ Li
    return L, 0.5 * (N + N.T)


def _adjugate_psd(S: np.ndarray) -> tuple[float, np.ndarray]:
    """``(det S, adj S)`` of a symmetric positive semidefinite matrix (S may be singular).

    Well-conditioned S (the usual case) goes through Cholesky and ``adj = det * inv``
    (:func:`psd_inverse`); a singular or badly conditioned one through the
    eigendecomposition, where the adjugate is ``U diag(prod_{k != i} mu_k) U'`` without any
    division.  (LAPACK's threaded symmetric eigensolver is also far slower than Cholesky on
    a loaded machine.)
    """
    k = S.shape[0]
    if k == 0:
        return 1.0, np.zeros((0, 0))
    inverse = psd_inverse(S)
    if inverse is not None:
        L, N = inverse
        det = float(np.prod(np.diag(L))) ** 2
        return det, det * N
    mu, U = np.linalg.eigh(S)
    # product of all eigenvalues except the i-th, without dividing by (possibly zero) mu_i
    others = np.where(np.eye(k, dtype=bool), 1.0, mu[None, :])
    cof = np.prod(others, axis=1)
    return float(np.prod(mu)), (U * cof) @ U.T


def bravo_scores(
    G: np.ndarray, c_row: np.ndarray, sigma: float, basis: np.ndarray | None = None
) -> np.ndarray:
    """``det(T_j T_j')`` of Bravo's candidates ``j = 0..r`` (index 0: unchanged zonotope).

    Parameters
    ----------
    G : (n, r) array
        Generators of the zonotope to intersect.
    c_row : (n,) array
        Row of the output matrix defining the strip.
    sigma : float
        Half-width of the strip.
    basis : (n, n-1) array, optional
        :func:`null_basis` of ``c_row`` (precomputed by callers that reuse it).
    """
    c_row = np.asarray(c_row, dtype=float).reshape(-1)
    n, r = G.shape
    B = null_basis(c_row) if basis is None else basis
    scores = np.empty(r + 1)
    scores[0] = np.linalg.det(G @ G.T)
    a = c_row @ G
    q = float(a @ a)
    valid = np.abs(a) > ZERO_PROJECTION
    scores[1:] = scores[0]
    if q == 0.0 or not np.any(valid):
        return scores
    BG = B.T @ G
    Gt = BG - np.outer(BG @ a, a / q)
    det_S0, adj_S0 = _adjugate_psd(Gt @ Gt.T)
    quad = np.einsum("ij,ij->j", Gt, adj_S0 @ Gt)
    scale = sigma**2 / float(c_row @ c_row)
    av = a[valid]
    scores[1:][valid] = scale * (det_S0 + (q / av**2) * quad[valid])
    return scores


def bravo_scores_gram(
    G: np.ndarray, M: np.ndarray, c_row: np.ndarray, sigma: float, basis: np.ndarray,
    a: np.ndarray | None = None,
) -> np.ndarray:
    r""":func:`bravo_scores` from the Gram matrix ``M = G G'`` (kept up to date across the
    strips of a step by :func:`gram_update`), at ``n^2 r`` flops per strip instead of about
    ``4 n^2 r``.

    The scores of Bravo's candidates (intersection method III of Althoff & Rath 2021,
    Sec. 3.1) through the matrix determinant lemma, with :math:`a = cG`,
    :math:`q = a^Ta`, :math:`B` an orthonormal basis of the null space of :math:`c`,
    :math:`S_0 = \tilde G\tilde G^T` and :math:`t_j` the columns of
    :math:`\tilde G = B^TG(I - aa^T/q)`:

    .. math::

        \det\left(T_jT_j^T\right) = \frac{\sigma^2}{\|c\|^2}\left(\det S_0 +
        \frac{q}{a_j^2}\,t_j^T\operatorname{adj}(S_0)\,t_j\right),
        \qquad j = 1, \ldots, r.

    With ``u = M c'``, ``q = c M c' = a'a`` and the basis ``B`` of :func:`bravo_scores`,
    ``S0 = Gt Gt' = B' (M - u u' / q) B`` and ``t_j = B' (g_j - u a_j / q)``, so with
    ``K = B adj(S0) B'``::

        t_j' adj(S0) t_j = g_j' K g_j - 2 (a_j / q) g_j' K u + (a_j / q)^2 u' K u,

    one product ``K G`` for all candidates; and ``det(G G') = q det(S0) / ||c||^2`` (the
    determinant of ``M`` in the coordinates ``[c; B']``).  The same scores as
    :func:`bravo_scores` up to rounding (the choice can differ only between candidates whose
    scores tie to rounding).  ``a``: the projections ``c G`` where the caller has them
    (:func:`projections_update`), else computed here.
    """
    c_row = np.asarray(c_row, dtype=float).reshape(-1)
    r = G.shape[1]
    a = c_row @ G if a is None else a
    u = M @ c_row
    q = float(c_row @ u)
    valid = np.abs(a) > ZERO_PROJECTION
    if not q > 0.0 or not np.any(valid):
        return np.full(r + 1, np.linalg.det(M))
    Bu = basis.T @ u
    S0 = basis.T @ M @ basis - np.outer(Bu, Bu) / q
    det_S0, adj_S0 = _adjugate_psd(0.5 * (S0 + S0.T))
    K = basis @ adj_S0 @ basis.T
    KG = K @ G
    Ku = K @ u
    f = a / q
    quad = np.einsum("ij,ij->j", G, KG) - 2.0 * f * (KG.T @ u) + f**2 * float(u @ Ku)
    cc = float(c_row @ c_row)
    scores = np.full(r + 1, q * det_S0 / cc)
    av = a[valid]
    scores[1:][valid] = sigma**2 / cc * (det_S0 + (q / av**2) * quad[valid])
    return scores




def leverages(G: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(M^-1, h)`` with the leverages ``h_j = g_j' M^-1 g_j`` of the columns of ``G``
    (``M = G G'``), or None where ``M`` is not positive definite or badly conditioned
    (:func:`psd_inverse`; the Gram scores serve there)."""
    inverse = psd_inverse(M)
    if inverse is None:
        return None
    N = inverse[1]
    return N, np.einsum("ij,ij->j", G, N @ G)


def bravo_ratios(a: np.ndarray, h: np.ndarray, q: float, sigma: float) -> np.ndarray:
    """``det(T_j T_j') / det(G G')`` of Bravo's candidates ``j = 0..r`` from the leverages
    ``h`` (see the module docstring): 1 for ``j = 0`` and where ``|a_j| <= ZERO_PROJECTION``,
    else ``sigma^2 max(h_j, a_j^2 / q) / a_j^2`` (the rounding of ``h`` never takes a ratio
    below its exact lower bound ``sigma^2 / q``); all 1 unless ``q = c M c' > 0``."""
    out = np.ones(a.size + 1)
    valid = np.abs(a) > ZERO_PROJECTION
    if not q > 0.0 or not valid.any():
        return out
    av = a[valid]
    out[1:][valid] = sigma**2 * np.maximum(h[valid], av**2 / q) / av**2
    return out


def leverage_update(N: np.ndarray, h: np.ndarray, G: np.ndarray, c_row: np.ndarray,
                    sigma: float, j: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(M^-1, h)`` of Bravo's candidate ``j`` (1-based; 0: unchanged) from those of ``G``
    (Woodbury's identity, see the module docstring), or None where the candidate's ``G G'``
    has no inverse: a strip of zero width (``sigma = 0``) leaves column ``j`` zero."""
    if j == 0:
        return N, h
    if not sigma > 0.0:
        return None
    c_row = np.asarray(c_row, dtype=float).reshape(-1)
    w = N @ G[:, j - 1]
    hj = float(h[j - 1])
    v = G.T @ w
    h = h - v * v / hj
    h[j - 1] = 1.0
    N = N - np.outer(w, w) / hj + np.outer(c_row, c_row) / sigma**2
    return 0.5 * (N + N.T), h


def gram_update(
    M: np.ndarray, G: np.ndarray, c_row: np.ndarray, sigma: float, j: int
) -> np.ndarray:
    r"""``G_j G_j'`` of Bravo's candidate ``j`` (:func:`bravo_update`) from ``M = G G'``:
    ``M - lam u' - u lam' + (q + sigma^2) lam lam'`` with ``lam = g_j / a_j``, ``u = M c'``,
    ``q = c M c'`` (column ``j`` of ``(I - lam c) G`` is zero and is replaced by
    ``sigma lam``); ``O(n^2)`` instead of ``O(n^2 r)``.

    .. math::

        G(j)\,G(j)^T = M - \lambda u^T - u\lambda^T + (q + \sigma^2)\,\lambda\lambda^T,
        \qquad \lambda = \frac{g_j}{a_j},\ u = Mc^T,\ q = cMc^T.
    """
    if j == 0:
        return M
    c_row = np.asarray(c_row, dtype=float).reshape(-1)
    lam = G[:, j - 1] / float(c_row @ G[:, j - 1])
    u = M @ c_row
    q = float(c_row @ u)
    out = M - np.outer(lam, u) - np.outer(u, lam) + (q + sigma**2) * np.outer(lam, lam)
    return 0.5 * (out + out.T)


def bravo_choice(
    G: np.ndarray, c_row: np.ndarray, sigma: float, basis: np.ndarray | None = None
) -> int:
    """Index of Bravo's best candidate (0 = unchanged; near-ties: the first index,
    :func:`~observers.numerics.linalg.first_best`)."""
    return first_best(bravo_scores(G, c_row, sigma, basis))


def projections_update(P: np.ndarray, C: np.ndarray, g_j: np.ndarray, a: np.ndarray,
                       sigma: float, j: int) -> np.ndarray:
    r"""The projections ``C G(j)`` of Bravo's candidate ``j`` (1-based; 0: ``P`` itself) from
    ``P = C G``, where ``a = c G`` is the projection of the strip taking the candidate and
    ``g_j`` column ``j`` of ``G`` (see the module docstring):

    .. math::

        C\,G(j) = P - (C\lambda)\,a^T \text{ with column } j \text{ replaced by }
        \sigma\,C\lambda, \qquad \lambda = g_j / a_j,

    the exact algebra of :func:`bravo_update` on the rows of ``C`` in ``O(m r)`` instead of
    the ``O(m n r)`` of forming ``C G(j)`` again.
    """
    if j == 0:
        return P
    Cl = C @ (g_j / a[j - 1])
    out = P - np.outer(Cl, a)
    out[:, j - 1] = sigma * Cl
    return out


def bravo_update(
    c: np.ndarray, G: np.ndarray, c_row: np.ndarray, y: float, sigma: float, j: int,
    a: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    r"""Bravo's candidate ``j`` (1-based generator index; 0 returns ``(c, G)`` unchanged).

    With :math:`a = cG` and :math:`\lambda = g_j / a_j` (intersection method III of
    Althoff & Rath 2021, Sec. 3.1):

    .. math::

        c(j) = c_0 + \lambda\,(y - c\,c_0), \qquad
        G(j) = \left[\tilde g_1, \ldots, \tilde g_r\right], \quad
        \tilde g_o = \begin{cases} g_o - \lambda a_o, & o \ne j,\\
        \sigma\lambda, & o = j. \end{cases}

    ``a``: the projections ``c G`` where the caller has them (:func:`projections_update`),
    else computed here.
    """
    if j == 0:
        return c, G
    c_row = np.asarray(c_row, dtype=float).reshape(-1)
    a = c_row @ G if a is None else a
    lam = G[:, j - 1] / a[j - 1]
    c_new = c + lam * (y - c_row @ c)
    G_new = G - np.outer(lam, a)
    G_new[:, j - 1] = sigma * lam
    return c_new, G_new


# -- Alamo's volume LP ---------------------------------------------------------------------------
def subset_count(r: int, n: int) -> int:
    """Number of generator subsets the volume LP enumerates: ``C(r, n) + C(r, n-1)``."""
    return math.comb(r, n) + math.comb(r, n - 1)


@lru_cache(maxsize=64)
def _subsets(r: int, k: int) -> np.ndarray:
    """All k-subsets of ``range(r)`` as an array of shape (C(r, k), k) (cached, read-only)."""
    idx = np.fromiter(
        (i for comb in combinations(range(r), k) for i in comb), dtype=np.intp,
        count=math.comb(r, k) * k,
    ).reshape(-1, k)
    idx.setflags(write=False)
    return idx


def _abs_dets(G: np.ndarray, idx: np.ndarray, chunk: int = 50_000) -> float:
    """Sum of ``|det G[:, J]|`` over the rows J of ``idx``."""
    total = 0.0
    for s in range(0, idx.shape[0], chunk):
        blocks = np.moveaxis(G[:, idx[s:s + chunk]], 1, 0)  # (m, n, n)
        total += float(np.abs(np.linalg.det(blocks)).sum())
    return total


def _cofactor_normals(G: np.ndarray, idx: np.ndarray, chunk: int = 50_000) -> np.ndarray:
    """For every (n-1)-subset B (rows of ``idx``) the vector ``nu_B`` with
    ``det([G_B, x]) = nu_B' x`` for all x (generalised cross product); shape (m, n)."""
    n = G.shape[0]
    out = np.empty((idx.shape[0], n))
    rows = [np.delete(np.arange(n), k) for k in range(n)]
    signs = np.array([(-1.0) ** (k + n - 1) for k in range(n)])
    for s in range(0, idx.shape[0], chunk):
        blocks = G[:, idx[s:s + chunk]]  # (n, m, n-1)
        for k in range(n):
            minor = np.moveaxis(blocks[rows[k]], 1, 0)  # (m, n-1, n-1)
            out[s:s + chunk, k] = signs[k] * np.linalg.det(minor)
    return out


def volume_lp_gain(G: np.ndarray, c_row: np.ndarray, sigma: float) -> np.ndarray:
    r"""Gain ``lambda`` of least volume of ``strip_update(c0, G, lambda)`` (Alamo et al. 2005).

    The enclosure has generators ``[(I - lambda c) G, sigma lambda]`` and, up to the factor
    ``2^n``, volume ``a |1 - c lambda| + sigma * sum_B |nu_B' lambda|`` with
    ``a = sum_J |det G_J|`` over the n-subsets J of the generators and ``nu_B`` the generalised
    cross product of every (n-1)-subset B.  Minimising it is the LP::

        min a t + sigma sum_B ||nu_B|| z_B   s.t.  t >= |1 - c lambda|,  z_B >= |v_B' lambda|

    that is, typeset:

    .. math::

        \frac{\operatorname{vol}}{2^n} = a\,|1 - c\lambda| + \sigma\sum_B |\nu_B^T\lambda|,
        \qquad
        \min_{\lambda,\,t,\,z}\ a\,t + \sigma\sum_B \|\nu_B\|\,z_B
        \quad \text{s.t.} \quad t \ge |1 - c\lambda|,\ z_B \ge |v_B^T\lambda|

    with unit normals ``v_B = nu_B / ||nu_B||`` (subsets of rank < n-1 drop out), solved by
    HiGHS.  Any gain yields a sound enclosure (``strip_update`` is exact for the family), so
    the LP optimum needs no certificate: an inaccurate optimum only costs volume.
    """
    c_row = np.asarray(c_row, dtype=float).reshape(-1)
    n, r = G.shape
    G = G[:, np.any(G != 0.0, axis=0)]
    r = G.shape[1]
    a_vol = _abs_dets(G, _subsets(r, n)) if r >= n else 0.0
    if n == 1:
        normals = np.ones((1, 1))
    else:
        normals = _cofactor_normals(G, _subsets(r, n - 1)) if r >= n - 1 else np.zeros((0, n))
    norms = np.linalg.norm(normals, axis=1)
    keep = norms > 1e-12 * max(1.0, float(norms.max(initial=0.0)))
    v, b = normals[keep] / norms[keep, None], sigma * norms[keep]
    scale = max(a_vol, float(b.max(initial=0.0)))
    if scale == 0.0:
        return np.zeros(n)
    return _solve_volume_lp(c_row, v, a_vol / scale, b / scale)


def _solve_volume_lp(c_row: np.ndarray, v: np.ndarray, a: float, b: np.ndarray) -> np.ndarray:
    """HiGHS solve of ``min a t + b'z`` s.t. ``|1 - c lam| <= t``, ``|v_i' lam| <= z_i``."""
    n, m = c_row.shape[0], v.shape[0]
    nvar = n + 1 + m
    # rows: [c, -1, 0] x <= 1 ; [-c, -1, 0] x <= -1 ; [v_i, 0, -e_i] x <= 0 ; [-v_i, 0, -e_i] x <= 0
    top = sp.csr_matrix(np.hstack([np.vstack([c_row, -c_row]), -np.ones((2, 1)),
                                   np.zeros((2, m))]))
    eye = sp.identity(m, format="csr")
    lower = sp.vstack([sp.hstack([sp.csr_matrix(v), sp.csr_matrix((m, 1)), -eye]),
                       sp.hstack([sp.csr_matrix(-v), sp.csr_matrix((m, 1)), -eye])])
    A = sp.vstack([top, lower]).tocsc()
    rhs = np.concatenate([[1.0, -1.0], np.zeros(2 * m)])
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = nvar, A.shape[0]
    lp.col_cost_ = np.concatenate([np.zeros(n), [a], b])
    lp.col_lower_ = np.concatenate([np.full(n, -highspy.kHighsInf), np.zeros(1 + m)])
    lp.col_upper_ = np.full(nvar, highspy.kHighsInf)
    lp.row_lower_ = np.full(A.shape[0], -highspy.kHighsInf)
    lp.row_upper_ = rhs
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = A.indptr
    lp.a_matrix_.index_ = A.indices
    lp.a_matrix_.value_ = A.data
    h = new_highs()
    h.passModel(lp)
    h.run()
    if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
        return np.zeros(n)  # lambda = 0 is always a valid (if poor) choice
    return np.asarray(h.getSolution().col_value[:n], dtype=float)
