"""Offline experiments for the data-driven observers: inputs and noisy outputs of a separate,
seeded run of the plant (Alanwar et al., ECC 2022, Sec. III-A).

``z(k) = C_train x(k) + gamma(k)``, ``gamma(k) in Gamma``, for ``k = 0..T`` and inputs
``u(0..T-1)`` drawn uniformly from an input set; the process noise is the system's ``W``.
The data-driven observers receive this record (``training=sc.training``) and never the
system matrices A and B.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from observers.sets import Interval, Zonotope

from .errors import ModelError
from .simulate import sample_unit_box, simulate


@dataclass(frozen=True)
class Training:
    """Record of an offline experiment.

    Attributes
    ----------
    u : (T, nu) ndarray
        Inputs ``u(0..T-1)``.
    z : (T+1, p) ndarray
        Noisy outputs ``z(0..T)``.
    C : (p, n) ndarray
        Output matrix of the experiment's sensors.
    Gamma : Zonotope
        Bound of the output noise ``gamma(k)``.
    description : str
        How the data were generated.
    """

    u: np.ndarray
    z: np.ndarray
    C: np.ndarray
    Gamma: Zonotope
    description: str = ""

    @property
    def T(self) -> int:
        """Number of transitions."""
        return self.u.shape[0]


def _frozen(a) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def offline_experiment(
    system,
    T: int,
    seed: int,
    input_set: Zonotope | Interval,
    C=None,
    Gamma: Zonotope | Interval | None = None,
    noise: str = "uniform",
) -> Training:
    """Simulate an offline experiment of ``T`` transitions (see the module docstring).

    Parameters
    ----------
    system : LinearSystem
        The plant (its ``W`` bounds the process noise; ``x(0)`` is drawn from ``X0``).
    T : int
        Number of transitions (``T + 1`` output samples).
    seed : int
        Seed; inputs, process noise and output noise are drawn from independent streams.
    input_set : Zonotope or Interval
        Inputs are drawn uniformly from its generator box.
    C : array_like, optional
        Sensors of the experiment (default: the system's ``C``).
    Gamma : Zonotope or Interval, optional
        Output-noise bound (default: the system's ``V``).
    noise : str
        Distribution of the noise factors (see :func:`systems.simulate`).
    """
    if int(T) < 1:
        raise ModelError(f"an offline experiment needs T >= 1 transitions, got {T}")
    T = int(T)
    C = system.C if C is None else np.atleast_2d(np.asarray(C, dtype=float))
    Gamma = system.V if Gamma is None else Gamma
    if isinstance(Gamma, Interval):
        Gamma = Zonotope.from_interval(Gamma)
    if isinstance(input_set, Interval):
        input_set = Zonotope.from_interval(input_set)
    if C.shape[1] != system.n or Gamma.dim != C.shape[0]:
        raise ModelError(f"experiment sensors C {C.shape} and Gamma (dim {Gamma.dim}) do not "
                         f"match a system with {system.n} states")
    if input_set.dim != system.nu:
        raise ModelError(f"input set has dimension {input_set.dim}, the system has "
                         f"{system.nu} inputs")
    s_u, s_sim, s_z = np.random.SeedSequence(seed).spawn(3)
    rng_u = np.random.default_rng(s_u)
    u = input_set.c + sample_unit_box(rng_u, (T + 1, input_set.num_generators),
                                      "uniform") @ input_set.G.T
    sim = simulate(system, u, steps=T + 1, seed=int(s_sim.generate_state(1)[0]), noise=noise)
    xi = sample_unit_box(np.random.default_rng(s_z), (T + 1, Gamma.num_generators), noise)
    z = sim.x_true @ C.T + Gamma.c + xi @ Gamma.G.T
    return Training(
        u=_frozen(u[:T]), z=_frozen(z), C=_frozen(C), Gamma=Gamma,
        description=(f"offline experiment: T={T}, seed {seed}, inputs uniform in the input "
                     f"set, {noise} noise"),
    )
