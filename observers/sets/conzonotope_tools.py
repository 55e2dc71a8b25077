"""Constrained-zonotope operations used by the data-driven observers (Scott et al. 2016).

Functions on :class:`~observers.sets.ConZonotope` values built only from its public API:

* :func:`intersect`: the exact intersection of two constrained zonotopes (Scott et al.,
  Automatica 69, 2016, eq. 13);
* :func:`eliminate_constraints`: drop equality constraints by the parameterised enclosure
  ``<c + L b, G - L A>`` (sound for *any* ``L``: a feasible ``xi`` has ``A xi = b``, so
  ``c + G xi = c + L b + (G - L A) xi``), keeping the last ``keep`` constraints;
* :func:`to_zonotope`: all constraints eliminated, an enclosing zonotope;
* :func:`reduce`: constraint elimination to at most ``max_constraints`` constraints, then
  generator reduction of the *lifted* zonotope ``<[c; -b], [G; A]>`` (Raghuraman & Koeln,
  Automatica 139, 2022, Sec. 4): if the lifted zonotope is enclosed by ``<[c'; -b'], [G'; A']>``
  then every ``x = c + G xi`` with ``A xi = b`` satisfies ``[x; 0]`` in the enclosure, i.e.
  ``x = c' + G' xi'`` with ``A' xi' = b'``.

The gain ``L`` of an elimination is the Frobenius-optimal one, ``L = G A' (A A')^+``, which
minimises ``||G - L A||_F``; no linear program is solved here.
"""

from __future__ import annotations

import numpy as np

from .conzonotope import ConZonotope
from .errors import SetError
from .reduction import Reduction, get_reduction
from .zonotope import Zonotope


def as_conzonotope(S) -> ConZonotope:
    """A zonotope (or constrained zonotope) as a :class:`ConZonotope`."""
    if isinstance(S, ConZonotope):
        return S
    if isinstance(S, Zonotope):
        return ConZonotope(S.c, S.G)
    raise SetError(f"expected a Zonotope or a ConZonotope, got {type(S).__name__}")


def intersect(S1, S2) -> ConZonotope:
    """Exact intersection ``S1 & S2`` (Scott et al. 2016, eq. 13).

    ``<c1, [G1, 0], [[A1, 0], [0, A2], [G1, -G2]], [b1; b2; c2 - c1]>``.
    """
    Z1, Z2 = as_conzonotope(S1), as_conzonotope(S2)
    if Z1.dim != Z2.dim:
        raise SetError(f"cannot intersect sets of dimensions {Z1.dim} and {Z2.dim}")
    r1, r2 = Z1.num_generators, Z2.num_generators
    n1, n2 = Z1.num_constraints, Z2.num_constraints
    A = np.block([
        [Z1.A, np.zeros((n1, r2))],
        [np.zeros((n2, r1)), Z2.A],
        [Z1.G, -Z2.G],
    ])
    b = np.concatenate([Z1.b, Z2.b, Z2.c - Z1.c])
    return ConZonotope(Z1.c, np.hstack([Z1.G, np.zeros((Z1.dim, r2))]), A, b)


def frobenius_gain(G: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``L = G A' (A A')^+``, the minimiser of ``||G - L A||_F``."""
    return np.linalg.lstsq(A @ A.T, A @ G.T, rcond=None)[0].T


def eliminate_constraints(S: ConZonotope, keep: int = 0) -> ConZonotope:
    """Enclosure with only the last ``keep`` constraints of ``S`` left (the oldest rows are
    eliminated with the Frobenius-optimal gain, see the module docstring)."""
    nc = S.num_constraints
    keep = max(0, min(int(keep), nc))
    if nc == keep:
        return S
    drop = nc - keep
    Ad, bd = S.A[:drop], S.b[:drop]
    L = frobenius_gain(S.G, Ad)
    return ConZonotope(S.c + L @ bd, S.G - L @ Ad, S.A[drop:], S.b[drop:])


def to_zonotope(S) -> Zonotope:
    """Enclosing zonotope of ``S`` (all constraints eliminated)."""
    S = as_conzonotope(S)
    E = eliminate_constraints(S, 0)
    return Zonotope(E.c, E.G)


def reduce(
    S: ConZonotope,
    order: float,
    max_constraints: int,
    method: str | Reduction = "girard",
) -> ConZonotope:
    """Enclosure with at most ``max_constraints`` constraints and at most
    ``order * (n + nc)`` generators (lifted-zonotope reduction with the named strategy)."""
    S = eliminate_constraints(S, max_constraints)
    nc = S.num_constraints
    if nc == 0:
        Z = Zonotope(S.c, S.G).reduce(order, method)
        return ConZonotope(Z.c, Z.G)
    # rows of A xi = b may be rescaled freely: unit rows make the reduction metric compare
    # constraint rows on one scale
    s = np.abs(S.A).max(axis=1)
    s = np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), 1.0)
    lifted = np.vstack([S.G, S.A * s[:, None]])
    G = get_reduction(method).reduce(lifted, order)
    return ConZonotope(S.c, G[: S.dim], G[S.dim:], S.b * s)
