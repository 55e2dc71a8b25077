"""Degenerate systems a user meets and the benchmark plants do not have: the edge-case family
of the soundness audit (``setobs-bench audit --edge``).

Each case is one small plant with one degenerate property, simulated with a seeded record as
every other scenario (``systems.scenario("edge-repeated-output", seed=3, noise="vertex")``).
The base plant is a stable, observable 3-state system with one input and two outputs::

    A = [[0.95, 0.10, 0.00],      B = [0.0, 0.1, 0.05]'     C = [[1, 0, 0],
         [-0.10, 0.90, 0.05],                                     [0, 0, 1]]
         [0.00, 0.05, 0.85]]

with ``W`` the box of radius 0.02 per state, ``V`` the box of radius 0.05 per output, ``X0``
the box of radius 0.5 about the origin and the input ``u_k = sin(0.05 k)``.  Its
parameters are chosen here (a slowly rotating, lightly damped mode and a decaying one, the
shape of most sampled mechanical plants), not taken from a paper.  The cases
(:data:`CASES`):

``edge-flat-w``
    ``W`` of zero width along ``x3`` (a disturbance that enters two states only).
``edge-zero-v``
    the first output measured without noise (``V`` of zero width in it).
``edge-repeated-output``
    two sensors of ``x1`` with independent noise (``C`` with a repeated row).
``edge-dependent-outputs``
    ``C = [[1, 1, 0], [2, 2, 0]]``: linearly dependent outputs, ``C`` of rank 1.
``edge-known-state``
    ``X0`` of zero width along ``x3`` (one initial state known exactly).
``edge-magnitudes``
    ``x3`` in units 1e9 times smaller than ``x1`` and ``x2`` (the base plant under
    ``x' = T x``, ``T = diag(1, 1, 1e-9)``): magnitudes 1e-9 beside 1.
``edge-units-micro`` and ``edge-units-mega``
    every state and output in units scaled by 1e-6 and 1e6 (``T = s I``, ``V`` scaled too).
``edge-unicycle-known-heading``
    the unicycle of :mod:`systems.robot` with its heading known exactly at the start and no
    heading disturbance (``X0`` and ``W`` of zero width along ``theta``): a nonlinear model
    with a state known exactly all along.

Long records are the same cases with ``steps=``: the edge audit runs them at
:data:`LONG_STEPS` (``audit --edge``) and at :data:`SHORT_STEPS` (``audit --edge --short``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from observers.sets import Zonotope

from .errors import ModelError
from .model import LinearSystem
from .robot import X0_CENTRE, loop_input, robot
from .simulate import simulate

#: the base plant (see the module docstring)
A = np.array([[0.95, 0.10, 0.00], [-0.10, 0.90, 0.05], [0.00, 0.05, 0.85]])
B = np.array([[0.0], [0.1], [0.05]])
C = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
W_RADIUS, V_RADIUS, X0_RADIUS = 0.02, 0.05, 0.5
#: record lengths of the edge audit: the full audit's long records and CI's short ones
LONG_STEPS = 2000
SHORT_STEPS = 200
#: length of the offline experiment of the linear cases (full-state sensors, noise 0.1 times
#: W's radii, inputs uniform in [-1, 1]), for the data-driven observers
TRAINING_STEPS = 500


@dataclass(frozen=True)
class EdgeCase:
    """One degenerate property: the scenario's name, what is degenerate about it and, where
    the audit cannot hold the estimates to the record's exact floor, why (measured)."""

    name: str
    property: str
    no_floor: str = ""


CASES = (
    EdgeCase("edge-flat-w", "W of zero width along x3"),
    EdgeCase("edge-zero-v", "the first output measured without noise"),
    EdgeCase("edge-repeated-output", "two sensors of x1 (a repeated row of C)"),
    EdgeCase("edge-dependent-outputs", "linearly dependent outputs (C of rank 1)"),
    EdgeCase("edge-known-state", "X0 of zero width along x3"),
    EdgeCase("edge-magnitudes", "x3 1e9 times smaller than x1 and x2",
             no_floor="the exact reference's LPs did not end in 7 min on 200 steps (its "
                      "simplex tolerances are absolute: 1e-9 is x3's whole range here)"),
    EdgeCase("edge-units-micro", "every state and output scaled by 1e-6"),
    EdgeCase("edge-units-mega", "every state and output scaled by 1e6"),
    EdgeCase("edge-unicycle-known-heading", "a nonlinear model whose heading is known exactly"),
)
#: the names of :data:`CASES`
NAMES = tuple(case.name for case in CASES)


#: why a ``-long`` record is not held to its exact floor (measured)
LONG_FLOOR_COST = ("the exact reference's LPs grow with the record; on "
                   "edge-repeated-output-long it had reached step 568 of 2,000 after 20 min")
#: what the audit says of a ``-long`` record's floor
LONG_NO_FLOOR = f"a long record: its floor is held on the short one ({LONG_FLOOR_COST})"


def no_floor(name: str) -> str:
    """Why the audit does not hold the estimates on scenario ``name`` to its exact floor
    (``""``: it does): the case's own reason, or :data:`LONG_NO_FLOOR` for a ``-long`` name."""
    reason = case(name).no_floor
    if reason or not name.endswith("-long"):
        return reason
    return LONG_NO_FLOOR


def case(name: str) -> EdgeCase:
    """The :class:`EdgeCase` of the scenario ``name`` (a ``-long`` name: its case)."""
    base = name.removesuffix("-long")
    for c in CASES:
        if c.name == base:
            return c
    raise ModelError(f"unknown edge case '{name}' (known: {', '.join(NAMES)})")


def _box(radii, centre=None) -> Zonotope:
    """The box of ``radii`` (zeros allowed: a flat set keeps a zero generator column out)."""
    radii = np.asarray(radii, float)
    keep = radii > 0
    G = np.diag(radii)[:, keep]
    c = np.zeros(radii.size) if centre is None else np.asarray(centre, float)
    return Zonotope(c, G if G.size else np.zeros((radii.size, 0)))


def _linear(name: str, *, C_=C, w=(W_RADIUS,) * 3, v=None, x0=(X0_RADIUS,) * 3,
            scale=(1.0, 1.0, 1.0), output_scale: float = 1.0) -> LinearSystem:
    """The base plant with the case's sets and output matrix, in the state units
    ``x' = diag(scale) x`` (outputs in units ``output_scale`` times the base ones)."""
    T = np.diag(np.asarray(scale, float))
    Ti = np.diag(1.0 / np.asarray(scale, float))
    v = (V_RADIUS,) * C_.shape[0] if v is None else v
    return LinearSystem(T @ A @ Ti, T @ B, output_scale * (C_ @ Ti),
                        _box(np.asarray(w, float) * np.diag(T)),
                        _box(np.asarray(v, float) * output_scale),
                        _box(np.asarray(x0, float) * np.diag(T)), dt=1.0, name=name)


def system(name: str):
    """The system of the edge case ``name`` (one of :data:`NAMES`)."""
    if name == "edge-flat-w":
        return _linear(name, w=(W_RADIUS, W_RADIUS, 0.0))
    if name == "edge-zero-v":
        return _linear(name, v=(0.0, V_RADIUS))
    if name == "edge-repeated-output":
        return _linear(name, C_=np.array([[1.0, 0, 0], [1.0, 0, 0], [0, 0, 1.0]]))
    if name == "edge-dependent-outputs":
        return _linear(name, C_=np.array([[1.0, 1.0, 0], [2.0, 2.0, 0]]))
    if name == "edge-known-state":
        return _linear(name, x0=(X0_RADIUS, X0_RADIUS, 0.0))
    if name == "edge-magnitudes":
        return _linear(name, scale=(1.0, 1.0, 1e-9))
    if name in ("edge-units-micro", "edge-units-mega"):
        s = 1e-6 if name == "edge-units-micro" else 1e6
        return _linear(name, scale=(s, s, s), output_scale=s)
    if name == "edge-unicycle-known-heading":
        base = robot()
        base.W = _box([0.01, 0.01, 0.0])
        base.X0 = _box([0.5, 0.5, 0.0], X0_CENTRE)
        base.name = name
        return base
    raise ModelError(f"unknown edge case '{name}' (known: {', '.join(NAMES)})")


#: the scenario names of the edge audit: each case on a short record (:data:`SHORT_STEPS`)
#: and, with ``-long``, on a long one (:data:`LONG_STEPS`)
SCENARIOS = NAMES + tuple(f"{name}-long" for name in NAMES)


def scenario(name: str, seed: int = 0, noise: str = "uniform", steps: int | None = None):
    """The :class:`~systems.scenarios.Scenario` of the edge case ``name`` (one of
    :data:`SCENARIOS`): a seeded record from a state drawn in ``X0``, ``steps`` long
    (default :data:`SHORT_STEPS`, :data:`LONG_STEPS` for a ``-long`` name)."""
    from .scenarios import _make, _with_training  # how every scenario is checked and trained

    if name not in SCENARIOS:
        raise ModelError(f"unknown edge case '{name}' (known: {', '.join(SCENARIOS)})")
    base = name.removesuffix("-long")
    if steps is None:
        steps = LONG_STEPS if name.endswith("-long") else SHORT_STEPS
    s = system(base)
    what = case(base)
    if base == "edge-unicycle-known-heading":
        sim = simulate(s, loop_input(steps), seed=seed, noise=noise, x0=X0_CENTRE)
        options = {"order": 10, "reduction": "girard", "max_generators": 30,
                   "max_constraints": 8, "enclosure_box": "hull"}
    else:
        sim = simulate(s, np.sin(0.05 * np.arange(steps))[:, None], seed=seed, noise=noise)
        options = {"order": 20, "reduction": "girard"}
    sc = _make(name=name, system=s, u=sim.u, y=sim.y, x_true=sim.x_true, options=options,
               description=f"edge case: {what.property}; {steps} steps simulated ({noise} "
                           f"noise, seed {seed})",
               source="systems/edge.py (parameters chosen here); record simulated here",
               state_names=("px", "py", "theta") if base.startswith("edge-unicycle")
               else ("x1", "x2", "x3"))
    if getattr(s, "is_linear", False):  # an offline experiment for the data-driven observers
        sc = _with_training(sc, seed, TRAINING_STEPS, 1.0, 0.1)
    return sc
