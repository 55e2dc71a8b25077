"""Planar geometry of 2-D sets for figures and areas (zonotopes exactly, constrained zonotopes
by an outer polygon from support values, ellipsoids by a fine polygon)."""

from __future__ import annotations

import numpy as np

from .conzonotope import ConZonotope
from .ellipsoid import Ellipsoid
from .zonotope import Zonotope


def zonotope_vertices(c: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Vertices (counter-clockwise) of a 2-D zonotope: generators sorted by angle."""
    G = G[:, np.any(G != 0, axis=0)]
    flip = (G[1] < 0) | ((G[1] == 0) & (G[0] < 0))  # every generator in the upper half-plane
    G = np.where(flip, -G, G)
    G = G[:, np.argsort(np.arctan2(G[1], G[0]))]
    start = c - G.sum(axis=1)
    return start + np.cumsum(np.hstack([2 * G, -2 * G]), axis=1).T


def polygon(S, directions: int = 120) -> np.ndarray:
    """Vertices (k x 2) of ``S`` or of a polygon enclosing it."""
    if isinstance(S, Zonotope):
        return zonotope_vertices(S.c, S.G)
    if isinstance(S, Ellipsoid):
        t = np.linspace(0, 2 * np.pi, directions, endpoint=False)
        L = np.linalg.cholesky(S.Q + 1e-15 * np.eye(2))
        return S.q + (L @ np.vstack([np.cos(t), np.sin(t)])).T
    if isinstance(S, ConZonotope):  # outer polygon: intersect the supporting half-planes
        t = np.linspace(0, 2 * np.pi, directions, endpoint=False)
        D = np.vstack([np.cos(t), np.sin(t)])
        h = np.atleast_1d(S.support(D))
        pts = []
        for i in range(directions):
            j = (i + 1) % directions
            M = np.vstack([D[:, i], D[:, j]])
            pts.append(np.linalg.solve(M, [h[i], h[j]]))
        return np.array(pts)
    raise TypeError(f"no polygon for {type(S).__name__}")


def set_area(S) -> float:
    """Area of the polygon of :func:`polygon` (shoelace formula)."""
    P = polygon(S)
    x, y = P[:, 0], P[:, 1]
    return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
