"""Rotating target of Alanwar, Berndt, Johansson, Sandberg (ECC 2022, Sec. IV, eq. 31).

``x+ = A_tr x + B_tr u + w`` with three sensors ``C1 = [1 0.4]``, ``C2 = [0.9 -1.2]``,
``C3 = [[-0.8 0.2], [0 0.7]]`` (stacked into one 4 x 2 ``C``; their noise sets
``<0, 1>, <0, 1>, <0, I2>`` combine into the box of radius 1), ``W = <0, 0.02 I2>``,
``X0 = <0, 15 I2>``, ``x(0) = [-10, 10]`` and inputs uniform in ``U = <0, 10>``.

The offline experiment has ``T = 500`` transitions with output noise
``Z_gamma = <0, 0.02 I2>``.  The paper gives ``Z_gamma`` in R^2, which fits a full-state
measurement ``z = x + gamma`` (the published code generates its N4SID data this way); we use
that experiment for both the data-driven observers and the N4SID baseline.
"""

from __future__ import annotations

import numpy as np

from observers.sets import Zonotope

from .model import LinearSystem
from .simulate import sample_unit_box, simulate
from .training import offline_experiment

A_TR = [[0.9455, -0.2426], [0.2486, 0.9455]]
B_TR = [[0.1], [0.0]]
SENSORS = ([[1.0, 0.4]], [[0.9, -1.2]], [[-0.8, 0.2], [0.0, 0.7]])
SENSOR_SIZES = [1, 1, 2]
X0_TRUE = (-10.0, 10.0)
INPUT_SET = Zonotope([0.0], [[10.0]])
GAMMA = Zonotope.box([0.02, 0.02])
TRAINING_T = 500


def rotating_target() -> LinearSystem:
    """The rotating-target system with the three sensors stacked."""
    return LinearSystem(
        A_TR, B_TR, np.vstack([np.array(c, dtype=float) for c in SENSORS]),
        W=Zonotope.box([0.02, 0.02]), V=Zonotope.box(np.ones(4)),
        X0=Zonotope([0.0, 0.0], 15.0 * np.eye(2)), dt=1.0, name="rotating-target",
    )


def rotating_target_record(seed: int = 0, steps: int = 50, noise: str = "uniform",
                           training_steps: int = TRAINING_T):
    """Online record (u, y, x_true) and the offline experiment, from independent streams."""
    system = rotating_target()
    s_u, s_sim, s_train = np.random.SeedSequence([seed, 31]).spawn(3)
    u = INPUT_SET.c + sample_unit_box(np.random.default_rng(s_u), (steps, 1), "uniform") * 10.0
    sim = simulate(system, u, steps=steps, seed=int(s_sim.generate_state(1)[0]), noise=noise,
                   x0=np.array(X0_TRUE))
    training = offline_experiment(
        system, training_steps, int(s_train.generate_state(1)[0]), INPUT_SET,
        C=np.eye(2), Gamma=GAMMA, noise=noise)
    return system, sim, training
