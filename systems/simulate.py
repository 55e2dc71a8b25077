"""Seeded simulation of a system with bounded disturbance and noise."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from observers.sets import Zonotope

from .errors import ModelError
from .memory import available_memory

NOISE_MODELS = ("uniform", "gaussian-truncated", "vertex")


@dataclass(frozen=True)
class Simulation:
    """Input (N x nu), measurements (N x ny) and true states (N x n) of one run."""

    u: np.ndarray
    y: np.ndarray
    x_true: np.ndarray


def sample_unit_box(rng: np.random.Generator, size: tuple[int, int], noise: str) -> np.ndarray:
    """Factors ``xi`` in the unit box for ``c + G xi``.

    ``uniform``: independent uniform; ``gaussian-truncated``: N(0, (1/3)^2) redrawn until
    inside [-1, 1]; ``vertex``: random signs (adversarial: noise on the vertices of the set).
    """
    if noise == "uniform":
        return rng.uniform(-1.0, 1.0, size=size)
    if noise == "vertex":
        return rng.choice([-1.0, 1.0], size=size)
    if noise == "gaussian-truncated":
        xi = rng.normal(0.0, 1.0 / 3.0, size=size)
        bad = np.abs(xi) > 1.0
        while np.any(bad):
            xi[bad] = rng.normal(0.0, 1.0 / 3.0, size=int(bad.sum()))
            bad = np.abs(xi) > 1.0
        return xi
    raise ModelError(f"unknown noise model '{noise}' (known: {', '.join(NOISE_MODELS)})")


def _draw(Z: Zonotope, xi: np.ndarray) -> np.ndarray:
    return Z.c + xi @ Z.G.T


def simulate(
    system,
    u,
    steps: int | None = None,
    seed: int | None = 0,
    noise: str = "uniform",
    x0=None,
) -> Simulation:
    """Simulate ``x_{k+1} = f(x_k, u_k) + w_k``, ``y_k = h(x_k) + v_k`` (``h(x) = C x`` for a
    linear output) for ``steps`` steps.

    Parameters
    ----------
    system : LinearSystem or NonlinearSystem
    u : array_like, shape (N, nu)
        Inputs; ``u[k]`` drives ``x_{k+1}``.
    steps : int, optional
        Number of samples N (default ``len(u)``).
    seed : int or None
        Seed of ``numpy.random.default_rng``.
    noise : {"uniform", "gaussian-truncated", "vertex"}
        Distribution of the generator factors of ``w``, ``v`` and (if ``x0`` is None) ``x0``;
        every sample lies in its set.
    x0 : array_like, optional
        Initial state (default: drawn from ``X0``).
    """
    if noise not in NOISE_MODELS:
        raise ModelError(f"unknown noise model '{noise}' (known: {', '.join(NOISE_MODELS)})")
    n, nu = system.n, system.nu
    u = np.asarray(u, dtype=float)
    if u.ndim == 1 and nu == 1:
        u = u.reshape(-1, 1)
    if u.ndim != 2 or u.shape[1] != nu:
        raise ModelError(f"u must have shape (N, {nu}), got {u.shape}")
    N = u.shape[0] if steps is None else int(steps)
    if N < 1 or u.shape[0] < N:
        raise ModelError(f"u has {u.shape[0]} rows, but {N} steps were requested")
    if not np.all(np.isfinite(u[:N])):
        raise ModelError("u contains non-finite values")
    need = 8 * N * (2 * n + system.ny + system.W.num_generators
                    + system.V.num_generators)
    have = available_memory()
    if have is not None and need > have:
        raise ModelError(f"simulating {N} steps of this {n}-state system needs about "
                         f"{need / 2**30:.3g} GiB of memory, {have / 2**30:.3g} GiB are "
                         "available")
    rng = np.random.default_rng(seed)
    if x0 is None:
        x = _draw(system.X0, sample_unit_box(rng, (1, system.X0.num_generators), noise)[0])
    else:
        x = np.asarray(x0, dtype=float).reshape(-1)
        if x.shape != (n,) or not np.all(np.isfinite(x)):
            raise ModelError(f"x0 must be a finite vector of length {n}")
    xi_w = sample_unit_box(rng, (N, system.W.num_generators), noise)
    xi_v = sample_unit_box(rng, (N, system.V.num_generators), noise)
    X = np.empty((N, n))
    for k in range(N):
        X[k] = x
        x = system.dynamics(x, u[k]) + _draw(system.W, xi_w[k])
    Y = system.outputs(X) + system.V.c + xi_v @ system.V.G.T
    return Simulation(u[:N].copy(), Y, X)
