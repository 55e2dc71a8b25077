"""Offline phase: the set of models ``M_Sigma`` consistent with noisy input-output data.

Data (Alanwar et al., ECC 2022, eqs. 4-5): inputs ``u(0..T-1)``, outputs ``z(0..T)`` with
``z(k) = C x(k) + gamma(k)``, ``gamma(k) in Gamma``, from ``x(k+1) = A x(k) + B u(k) + w(k)``,
``w(k) in W``.  Two constructions are provided:

:func:`paper_model_set` (Lemma 1 as published)
    ``M_Sigma = (M+_{x|z} - M_w) [M-_{x|z}; U-]^dagger``, with the state sets of Prop. 1 (the
    null space of C covered by a generator ``M V2``, ``M >= ||x||``) and the pseudo-inverse of
    the interval matrix ``[M-_{x|z}; U-]`` obtained by "adapting" the Hansen-Bliek-Rohn inverse
    enclosure (Fiedler et al. 2006, Thm. 2.40) with ``inv`` replaced by ``pinv``.  That
    adaptation is *not* a proven enclosure of the pseudo-inverses of the members (it is only
    proven for the inverse of square matrices when ``rho(|A_c^-1| Delta) < 1``), and the
    condition is not checked; the result is an interval matrix.

:func:`sound_model_set` (our construction; theorem below)
    Let ``C`` have full column rank, so that ``x(k) = C^+ (z(k) - gamma(k))`` exactly.  Write
    ``x(k) = xh(k) + e(k)`` with ``xh(k) = C^+ (z(k) - c_gamma)`` (known) and
    ``e(k) = -C^+ G_gamma beta_k`` (unknown, ``|beta_k| <= 1``).  For every ``[A B]``
    consistent with the data, ``A X- + B U- = X+ - W-`` gives
    ``[A B] D = Xh+ + E+ - W- - A E-`` with the known data matrix ``D = [Xh-; U-]``.  If ``D``
    has full row rank, multiplying by ``P = D^+`` (``D P = I``) yields the *identity*

        ``[A B] = (Xh+ - C_W) P + [(E+ - A_c E-) - G_W(beta_w)] P - (A - A_c) E- P``

    for any fixed ``A_c``.  The middle term is linear in the noise factors (a matrix zonotope
    ``L`` whose generators keep the correlation of ``gamma(k)`` entering both ``E+`` and
    ``E-``); the last term is bilinear and is bounded entry-wise by ``|A - A_c| Nb`` with
    ``Nb = e_bar (sum_k |P_k|)`` (``e_bar = sum |C^+ G_gamma|``).  With ``R = sum |L_i|`` the
    deviation ``Delta = |A - A_c|`` satisfies ``Delta <= R_A + Delta Nb_A``; if the spectral
    radius of the non-negative ``Nb_A`` is below one, ``(I - Nb_A)^-1 = sum Nb_A^k >= 0`` and
    ``Delta <= R_A (I - Nb_A)^-1`` (an a-priori bound on every consistent A).  Hence every
    consistent ``[A B]`` lies in

        ``M_Sigma = (Xh+ - C_W) P + L + [-Delta Nb, Delta Nb]``,

    a matrix zonotope.  No assumption on the true system is used beyond the noise bounds.
    Experiment sensors ``C`` without full column rank are rejected (the paper's null-space
    generator ``M V2`` makes ``D`` rank deficient or ``rho(Nb_A) >= 1``: single scalar
    outputs do not determine [A B]).  All bounds are widened by a few ulps for rounding.

:func:`refined_model_set`
    The interval hull of the sound set tightened by the linear constraints that each sample
    imposes on each row of ``[A B]`` (LP bounds made sound by weak duality,
    :mod:`observers.numerics.datadriven.polytope`); unlike the pseudo-inverse bound it shrinks
    as the experiment grows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import DesignFailed, Unsupported
from ...sets import IntervalMatrix, MatrixZonotope, Zonotope

_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class TrainingData:
    """Validated offline experiment: ``u`` (T x m), ``z`` (T+1 x p), ``C`` (p x n), ``Gamma``
    (output-noise zonotope of dimension p)."""

    u: np.ndarray
    z: np.ndarray
    C: np.ndarray
    Gamma: Zonotope

    @property
    def T(self) -> int:
        """Number of transitions (columns of ``U-``)."""
        return self.u.shape[0]


def check_training(training, n: int, nu: int, who: str) -> TrainingData:
    """Validate a training record (any object with ``u``, ``z``, ``C``, ``Gamma``)."""
    if training is None:
        raise Unsupported(f"{who} needs offline training data (training=...): this scenario "
                          "provides none")
    missing = [a for a in ("u", "z", "C", "Gamma") if not hasattr(training, a)]
    if missing:
        raise DesignFailed(f"{who}: training data lacks {', '.join(missing)} (needs u, z, C, "
                           "Gamma)")
    try:
        C = np.atleast_2d(np.asarray(training.C, dtype=float))
        u = np.asarray(training.u, dtype=float)
        z = np.asarray(training.z, dtype=float)
    except (TypeError, ValueError):
        raise DesignFailed(f"{who}: training data must be numeric arrays") from None
    if u.ndim == 1:
        u = u.reshape(-1, 1) if nu == 1 else u.reshape(-1, nu)
    if z.ndim == 1:
        z = z.reshape(-1, 1)
    p = C.shape[0]
    Gamma = training.Gamma
    if C.shape[1] != n:
        raise DesignFailed(f"{who}: training C has {C.shape[1]} columns, the state has {n}")
    if u.ndim != 2 or u.shape[1] != nu:
        raise DesignFailed(f"{who}: training inputs must have shape (T, {nu}), got {u.shape}")
    if z.shape != (u.shape[0] + 1, p):
        raise DesignFailed(f"{who}: training outputs must have shape ({u.shape[0] + 1}, {p}) "
                           f"(T+1 samples), got {z.shape}")
    if not isinstance(Gamma, Zonotope) or Gamma.dim != p:
        raise DesignFailed(f"{who}: training Gamma must be a Zonotope of dimension {p}")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(z)) and np.all(np.isfinite(C))):
        raise DesignFailed(f"{who}: training data contain non-finite values")
    if u.shape[0] < n + nu:
        raise DesignFailed(f"{who}: {u.shape[0]} training samples cannot determine "
                           f"{n + nu} columns of [A B]")
    return TrainingData(u, z, C, Gamma)


def output_inverse(C: np.ndarray, tol: float = 1e-10):
    """``(V1 Sigma^-1 P1', V2)`` from the SVD of ``C`` (Lemma 1, eq. 12): the map from
    outputs to the range-space part of the state, and a basis of ``ker C``."""
    P, s, Vt = np.linalg.svd(C)
    r = int(np.sum(s > tol * max(1.0, s.max(initial=0.0))))
    V1, V2 = Vt[:r].T, Vt[r:].T
    return V1 @ np.diag(1.0 / s[:r]) @ P[:, :r].T, V2


def _state_sets(data: TrainingData, state_bound: float):
    """Centres ``xh(k)`` (T+1 x n) and the common error generators ``H`` (n x s) of
    ``x(k) in xh(k) + H [-1, 1]^s`` (Prop. 1 applied to every sample)."""
    Cinv, V2 = output_inverse(data.C)
    xh = (data.z - data.Gamma.c) @ Cinv.T
    H = np.hstack([-Cinv @ data.Gamma.G, state_bound * V2])
    return xh, H[:, np.any(H != 0.0, axis=0)]


def hbr_pinv(D: IntervalMatrix) -> IntervalMatrix:
    """The paper's "pseudo-inverse of an interval matrix": the Hansen-Bliek-Rohn inverse
    formula in transposed form with every inverse replaced by a pseudo-inverse.

    Not a proven enclosure (see the module docstring); kept to reproduce Lemma 1.
    """
    Ac, Delta = D.center(), D.radius()
    Pc = np.linalg.pinv(Ac)
    absP = np.abs(Pc)
    k = Ac.shape[0]
    Mm = np.linalg.pinv(np.eye(k) - Delta @ absP)
    Tmu = np.diag(np.diag(Mm))
    Tnu = np.linalg.pinv(2 * Tmu - np.eye(k))
    lo = -absP @ Mm + (Pc + absP) @ Tmu
    hi = absP @ Mm + (Pc - absP) @ Tmu
    a, b = np.minimum(lo, lo @ Tnu), np.maximum(hi, hi @ Tnu)
    # far from its validity condition the formula can give a > b: keep the interval between
    return IntervalMatrix(np.minimum(a, b), np.maximum(a, b))


def paper_model_set(data: TrainingData, W: Zonotope, state_bound: float = 100.0) -> IntervalMatrix:
    """``M_Sigma`` of Lemma 1 as published (an interval matrix; not guaranteed)."""
    xh, H = _state_sets(data, state_bound)
    T = data.T
    e = np.abs(H).sum(axis=1)  # every column's state set boxed, as the interval conversion does
    Mw = MatrixZonotope.from_sequence(W, T).interval_matrix()
    Xp = IntervalMatrix(xh[1:].T - e[:, None], xh[1:].T + e[:, None]) - Mw
    Dc = np.vstack([xh[:-1].T, data.u.T])
    Dr = np.vstack([np.tile(e[:, None], (1, T)), np.zeros_like(data.u.T)])
    return Xp @ hbr_pinv(IntervalMatrix(Dc - Dr, Dc + Dr))


@dataclass(frozen=True)
class SoundModelSet:
    """Result of :func:`sound_model_set`: the set and the quantities of the theorem."""

    M: MatrixZonotope
    rho: float  # spectral radius of Nb_A (must be < 1)
    delta_A: np.ndarray  # a-priori bound on |A - A_c|
    cond_D: float  # condition number of the data matrix D


def sound_model_set(data: TrainingData, W: Zonotope, state_bound: float = 100.0) -> SoundModelSet:
    """``M_Sigma`` containing every ``[A B]`` consistent with the data (module docstring)."""
    n = data.C.shape[1]
    if np.linalg.matrix_rank(data.C) < n:
        raise DesignFailed(
            f"the sound set of models needs experiment sensors of full column rank (rank "
            f"{np.linalg.matrix_rank(data.C)} < {n} states): single outputs do not determine "
            "the state, and the null-space bound ||x|| <= M leaves [A B] unbounded")
    xh, H = _state_sets(data, state_bound)
    T, m = data.T, data.u.shape[1]
    D = np.vstack([xh[:-1].T, data.u.T])  # (n+m) x T
    sv = np.linalg.svd(D, compute_uv=False)
    if sv[-1] <= 1e-10 * sv[0]:
        raise DesignFailed("the training data are not informative: [X-; U-] does not have "
                           f"full row rank (singular values {sv[0]:.3g} ... {sv[-1]:.3g})")
    P = np.linalg.pinv(D)  # T x (n+m), D P = I
    Theta_c = (xh[1:].T - W.c[:, None]) @ P
    Ac = Theta_c[:, :n]
    # generators of L: sample j (0..T) enters E+ at column j-1 and E- at column j
    Pp = np.vstack([np.zeros((1, n + m)), P])  # row j: P[j-1] (zero for j = 0)
    Pm = np.vstack([P, np.zeros((1, n + m))])  # row j: P[j]   (zero for j = T)
    AH = Ac @ H
    Lg = (np.einsum("is,jc->jsic", H, Pp) - np.einsum("is,jc->jsic", AH, Pm)).reshape(
        -1, n, n + m)
    Lw = -np.einsum("ig,jc->jgic", W.G, P).reshape(-1, n, n + m)
    R = np.abs(Lg).sum(axis=0) + np.abs(Lw).sum(axis=0)
    e_bar = np.abs(H).sum(axis=1)
    Nb = np.outer(e_bar, np.abs(P).sum(axis=0))
    NbA = Nb[:, :n]
    rho = float(np.max(np.abs(np.linalg.eigvals(NbA)))) if n else 0.0
    if not rho < 1.0 - 1e-9:
        raise DesignFailed(
            f"no bounded sound set of models from these data: the state-reconstruction error "
            f"is too large for the excitation (rho = {rho:.3g} >= 1; use a longer or more "
            "exciting experiment, or less output noise)")
    # Delta_A <= R_A (I - Nb_A)^-1, computed as R_A sum_k Nb_A^k with outward rounding
    delta = np.linalg.solve((np.eye(n) - NbA).T, R[:, :n].T).T
    delta = np.maximum(delta, R[:, :n]) * (1 + 1e-9) + 64 * _EPS * (np.abs(Theta_c[:, :n]) + 1)
    box = delta @ Nb
    scale = np.abs(xh[1:].T) @ np.abs(P) + R
    box = box * (1 + 1e-9) + 64 * _EPS * (scale + np.abs(Theta_c)) * T
    Mbox = IntervalMatrix(Theta_c - box, Theta_c + box).to_matrix_zonotope()
    M = MatrixZonotope(Theta_c, np.concatenate([Lg, Lw])) + (Mbox - Theta_c)
    return SoundModelSet(M, rho, delta, float(sv[0] / sv[-1]))


def refined_model_set(data: TrainingData, W: Zonotope, prior: MatrixZonotope,
                      rounds: int = 2) -> IntervalMatrix:
    """The interval hull of ``prior`` tightened by the per-sample linear constraints (LPs with
    dual-checked bounds, :mod:`observers.numerics.datadriven.polytope`); sound whenever
    ``prior`` is."""
    from .polytope import refine_box

    xh, H = _state_sets(data, 0.0)
    I = prior.interval_matrix()
    Wi = W.interval()
    lo, hi = refine_box(xh, data.u, np.abs(H).sum(axis=1), (Wi.center(), Wi.radius()),
                        (I.lo.copy(), I.hi.copy()), rounds)
    if np.any(lo > hi):
        raise DesignFailed("the training data are inconsistent with a linear model and the "
                           "noise bounds (the set of consistent models is empty)")
    return IntervalMatrix(lo, hi)
