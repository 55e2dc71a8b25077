"""Named benchmark scenarios: a system plus one input/measurement record (and, where known,
the true trajectory) and the observer options the papers used for it.

>>> import systems
>>> sc = systems.scenario("vehicle6d-cora")
>>> sc.y.shape, sc.x_true.shape, sc.options
((350, 4), (350, 6), {'order': 100, 'reduction': 'pca'})
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import partial
from importlib import resources
from typing import Any

import numpy as np
import yaml

from observers.sets import Zonotope

from . import textbook
from .alamo import alamo2d
from .errors import ModelError
from .memory import available_memory
from .model import LinearSystem
from .rego import X0_LINEAR, X0_NONLINEAR, rego2d_linear, rego2d_nonlinear
from .robot import X0_CENTRE, loop_input, robot
from .rotating import SENSOR_SIZES, rotating_target_record
from .simulate import simulate
from .tank import tank, tank_input
from .training import offline_experiment
from .vanderpol import vanderpol
from .vehicle import STATES as VEHICLE_STATES
from .vehicle import W_RADII, lane_change_input, vehicle

ROUNDED_TRUTH_TOL = 1e-3  # true states shipped with 3 decimals


@dataclass(frozen=True)
class Scenario:
    """A system with one record; ``u[k]`` drives ``x_{k+1}``, ``y[k]`` measures ``x_k``."""

    name: str
    system: Any
    u: np.ndarray
    y: np.ndarray
    x_true: np.ndarray | None
    options: dict = field(default_factory=dict)
    description: str = ""
    source: str = ""
    tolerance: float = 1e-9
    paper_table: str | None = None
    state_names: tuple[str, ...] = ()
    training: Any = None

    @property
    def N(self) -> int:
        """Number of time steps."""
        return self.y.shape[0]


def _data_path(name: str):
    return resources.files("systems") / "data" / name


def _csv(name: str) -> np.ndarray:
    with _data_path(name).open() as fh:
        return np.loadtxt(fh, delimiter=",", comments="#", ndmin=2)


def _yaml(name: str) -> dict:
    with _data_path(name).open() as fh:
        return yaml.safe_load(fh)


def _frozen(a: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return None
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _make(**kw) -> Scenario:
    for key in ("u", "y", "x_true"):
        kw[key] = _frozen(kw.get(key))
    sc = Scenario(**kw)
    s = sc.system
    if sc.y.shape != (sc.N, s.ny) or sc.u.shape[1] != s.nu or sc.u.shape[0] < sc.N - 1:
        raise ModelError(f"scenario {sc.name}: record shapes do not match the system")
    if sc.x_true is not None and sc.x_true.shape != (sc.N, s.n):
        raise ModelError(f"scenario {sc.name}: x_true has shape {sc.x_true.shape}")
    return sc


def _with_training(sc: Scenario, seed: int, T: int, input_radius: float,
                   gamma_scale: float) -> Scenario:
    """Attach a separate seeded offline experiment for the data-driven observers: full-state
    sensors whose noise box is ``gamma_scale`` times the disturbance radii, inputs uniform in
    ``[-input_radius, input_radius]``."""
    s = sc.system
    gamma_radius = gamma_scale * s.W.interval().hi
    exp_seed = int(np.random.SeedSequence([seed, 7]).generate_state(1)[0])
    training = offline_experiment(
        s, T, exp_seed, Zonotope.box(np.full(s.nu, input_radius)), C=np.eye(s.n),
        Gamma=Zonotope.box(gamma_radius))
    return replace(sc, training=training)


def _tank_states(n: int) -> tuple[str, ...]:
    return tuple(f"x{i + 1}" for i in range(n))


# -- CORA data sets ---------------------------------------------------------------------------
def _vehicle_cora(dim: int) -> LinearSystem:
    d = _yaml("vehicle_cora.yaml")[f"dim{dim}"]
    return LinearSystem(
        d["A"], d["B"], d["C"],
        W=Zonotope.box(d["W_radius"]),
        V=Zonotope.box(d["V_radius"]),
        X0=Zonotope.box(np.ones(dim)),
        dt=d["dt"],
        name=f"vehicle{dim}d-cora",
    )


def vehicle2d_cora() -> Scenario:
    uy = _csv("vehicle2d_cora_u_y.csv")
    sc = _make(
        name="vehicle2d-cora", system=_vehicle_cora(2), u=uy[0:1].T, y=uy[1:2].T, x_true=None,
        options={"order": 100, "reduction": "pca"},
        description="2-state vehicle side-slip model, CORA unit-test record (100 steps)",
        source="CORA testLong_linearSysDT_observe_01_vehicle.m", state_names=VEHICLE_STATES[:2],
    )
    return _with_training(sc, 0, 500, 0.5, 0.1)


def vehicle6d_cora() -> Scenario:
    x = _csv("vehicle6d_cora_x_true.csv")[:, 1:]
    return _make(
        name="vehicle6d-cora", system=_vehicle_cora(6), u=_csv("vehicle6d_cora_u.csv").T,
        y=_csv("vehicle6d_cora_y.csv").T, x_true=x, options={"order": 100, "reduction": "pca"},
        description="6-state vehicle side-slip model, double lane change, CORA example record",
        source="CORA example_linearSysDT_observe_01_vehicle.m", tolerance=ROUNDED_TRUTH_TOL,
        paper_table="automatica2021_table3_vehicle6", state_names=VEHICLE_STATES,
    )


def tank30_linear_cora() -> Scenario:
    d = _yaml("tank30_lin_cora.yaml")
    n, ny = 30, len(d["C"])
    system = LinearSystem(
        d["A"], d["B"], d["C"],
        W=Zonotope.box(np.full(n, d["W_radius"])),
        V=Zonotope.box(np.full(ny, d["V_radius"])),
        X0=Zonotope.box(np.full(n, d["X0_radius"])),
        dt=d["dt"], name="tank30-linear-cora",
    )
    return _make(
        name="tank30-linear-cora", system=system, u=_csv("tank30_lin_cora_u.csv").T,
        y=_csv("tank30_lin_cora_y.csv").T, x_true=_csv("tank30_lin_cora_x_true.csv")[:, 1:],
        options={"order": 100, "reduction": "pca"},
        description="linearised 30-tank system, CORA example record (235 steps)",
        source="CORA example_linearSysDT_observe_03_tank.m", tolerance=ROUNDED_TRUTH_TOL,
        state_names=_tank_states(n),
    )


def alamo2d_published() -> Scenario:
    d = _yaml("alamo2d.yaml")
    y = np.array(d["y"], dtype=float).reshape(-1, 1)
    return _make(
        name="alamo2d", system=alamo2d(), u=np.zeros((y.shape[0], 2)), y=y, x_true=None,
        options={"order": d["order"], "reduction": d["reduction"]},
        description="2-D example of Alamo et al. 2005 with its published measurements",
        source="Alamo, Bravo, Camacho, Automatica 2005, Sec. 7.1", state_names=("x1", "x2"),
    )


# -- simulated scenarios -----------------------------------------------------------------------
def tank_linear(n: int, seed: int = 0, noise: str = "uniform", steps: int = 261) -> Scenario:
    """Linearised n-tank system with a seeded simulated record."""
    system = tank(n, linear=True)
    if n == 6:
        u = _csv("tank6_lin_u.csv").T[:steps]
        src = "input of CORA simulateTank_lin.m; noise simulated here (seeded)"
    else:
        u = tank_input(system.nu, steps)
        src = "linearisation of CORA's tank model; input and noise generated here (seeded)"
    sim = simulate(system, u, steps=steps, seed=seed, noise=noise)
    table = {6: "arch2021_table3_tank6_linear"}.get(n, "arch2021_table5_6_tank_scaling")
    sc = _make(
        name=f"tank{n}-linear", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 100, "reduction": "pca"},
        description=f"linearised {n}-tank system, simulated ({noise} noise, seed {seed})",
        source=src, paper_table=table, state_names=_tank_states(n),
    )
    if n == 6:  # offline experiment for the data-driven observers
        sc = _with_training(sc, seed, 2000, 0.5, 0.1)
    return sc


def tank_nonlinear(n: int, seed: int = 0, noise: str = "uniform", steps: int = 263) -> Scenario:
    """Nonlinear n-tank system (Torricelli) with a seeded simulated record."""
    system = tank(n, linear=False)
    u = _csv("tank6_nonlin_u.csv").T[:steps] if n == 6 else tank_input(system.nu, steps) + 0.1
    sim = simulate(system, u, steps=steps, seed=seed, noise=noise)
    return _make(
        name=f"tank{n}-nonlinear", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 100, "reduction": "pca"},
        description=f"nonlinear {n}-tank system, simulated ({noise} noise, seed {seed})",
        source="CORA tank model equations; record simulated here",
        paper_table=("arch2021_table4_tank6_nonlinear" if n == 6
                     else "arch2021_table5_6_tank_scaling"),
        state_names=_tank_states(n),
    )


def tank6_nonlinear_cora() -> Scenario:
    """CORA's 20-step record of the nonlinear 6-tank system (unit test, no true states)."""
    d = _yaml("tank6_nonlin_cora_u_y.yaml")
    return _make(
        name="tank6-nonlinear-cora", system=tank(6, linear=False), u=np.array(d["u"]).T,
        y=np.array(d["y"]).T, x_true=None, options={"order": 100, "reduction": "pca"},
        description="nonlinear 6-tank system, CORA's 20-step unit-test record",
        source="CORA unitTests/contDynamics/nonlinearSysDT/test_nonlinearSysDT_observe_01_tank.m",
        state_names=_tank_states(6),
    )


def vanderpol_sim(seed: int = 0, noise: str = "uniform", steps: int = 200) -> Scenario:
    """Van der Pol oscillator (Euler, position measured) with a seeded simulated record."""
    system = vanderpol()
    u = np.zeros((steps, 1))
    sim = simulate(system, u, steps=steps, seed=seed, noise=noise)
    return _make(
        name="vanderpol-sim", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 20, "reduction": "pca"},
        description=f"Van der Pol oscillator (mu = 1, h = 0.05), simulated ({noise} noise, "
                    f"seed {seed})",
        source="systems/vanderpol.py; record simulated here", state_names=("x1", "x2"),
    )


def vehicle_sim(dim: int, seed: int = 0, noise: str = "uniform", steps: int = 350) -> Scenario:
    """Vehicle model with the double-lane-change input and a seeded simulated record."""
    system = vehicle(dim)
    sim = simulate(system, lane_change_input(steps), steps=steps, seed=seed, noise=noise)
    sc = _make(
        name=f"vehicle{dim}d-sim", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 100, "reduction": "pca"},
        description=(f"{dim}-state vehicle model, simulated lane change "
                     f"({noise} noise, seed {seed})"),
        source=f"vehicle model of CORA's generator; W radii {W_RADII[:dim]}",
        paper_table="automatica2021_table3_vehicle6" if dim == 6 else None,
        state_names=VEHICLE_STATES[:dim],
    )
    if dim == 2:  # offline experiment for the data-driven observers
        sc = _with_training(sc, seed, 500, 0.5, 0.1)
    return sc


def alamo2d_sim(seed: int = 0, noise: str = "uniform", steps: int = 20) -> Scenario:
    """The Alamo et al. 2-D example with a seeded simulated record (true states known)."""
    system = alamo2d()
    sim = simulate(system, np.zeros((steps, 2)), seed=seed, noise=noise)
    return _make(
        name="alamo2d-sim", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 20, "reduction": "girard"},
        description=f"2-D example of Alamo et al., simulated ({noise} noise, seed {seed})",
        source="Alamo et al. 2005 model; record simulated here", state_names=("x1", "x2"),
    )


def rotating_target_scenario(seed: int = 0, noise: str = "uniform", steps: int = 50) -> Scenario:
    """Rotating target of Alanwar et al. (ECC 2022, Sec. IV) with its offline experiment."""
    system, sim, training = rotating_target_record(seed=seed, steps=steps, noise=noise)
    return _make(
        name="rotating-target", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 5, "reduction": "girard", "sensors": SENSOR_SIZES},
        description=(f"rotating target, 3 sensors stacked, simulated ({noise} noise, seed "
                     f"{seed}); offline experiment T={training.T}, z = x + gamma"),
        source="Alanwar, Berndt, Johansson, Sandberg, ECC 2022, Sec. IV",
        paper_table="alanwar2022_datadriven", state_names=("x1", "x2"), training=training,
    )


def rego2d_nonlinear_sim(seed: int = 0, noise: str = "uniform", steps: int = 100) -> Scenario:
    """The nonlinear example of Rego et al. (nonlinear dynamics and measurements) from
    ``x0 = (5.2, 0.65)``, with the papers' generator and constraint limits (20 and 8) and
    their enclosures over the interval hull of the constrained zonotope (option
    ``enclosure_box``; over the box of the zonotope part CZN-A and CZN-MV diverge within three
    steps here)."""
    system = rego2d_nonlinear()
    sim = simulate(system, np.zeros((steps, 0)), seed=seed, noise=noise, x0=X0_NONLINEAR)
    return _make(
        name="rego2d-nonlinear", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 10, "reduction": "girard", "max_generators": 20,
                 "max_constraints": 8, "enclosure_box": "hull"},
        description=f"2-state example of Rego et al. with nonlinear measurements, simulated "
                    f"({noise} noise, seed {seed})",
        source="Rego, Raffo, Scott, Raimondo, Automatica 2020; Rego, Raffo, Terra, Scott, "
               "arXiv 2504.00130; record simulated here", state_names=("x1", "x2"),
    )


def rego2d_linear_sim(seed: int = 0, noise: str = "uniform", steps: int = 30) -> Scenario:
    """The linear sanity example of Rego et al.'s toolbox from ``x0 = (1, -1)``, generator
    and constraint limits 20 and 5."""
    system = rego2d_linear()
    sim = simulate(system, np.zeros((steps, 0)), seed=seed, noise=noise, x0=X0_LINEAR)
    return _make(
        name="rego2d-linear", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 10, "reduction": "girard", "max_generators": 20,
                 "max_constraints": 5},
        description=f"linear 2-state example of Rego et al.'s toolbox, simulated ({noise} "
                    f"noise, seed {seed})",
        source="linear example of the ZETA toolbox (Rego et al., arXiv 2504.06467); record "
               "simulated here", state_names=("x1", "x2"),
    )


def robot_range_sim(seed: int = 0, noise: str = "uniform", steps: int = 150) -> Scenario:
    """Unicycle localised by ranges to four beacons and one bearing (:mod:`systems.robot`),
    driven round a loop from ``(2.5, 2.5, 0)``."""
    system = robot()
    sim = simulate(system, loop_input(steps), seed=seed, noise=noise, x0=X0_CENTRE)
    return _make(
        name="robot-range", system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 10, "reduction": "girard", "max_generators": 30,
                 "max_constraints": 8, "enclosure_box": "hull"},
        description=f"unicycle with 4 beacon ranges and 1 bearing, simulated ({noise} "
                    f"noise, seed {seed})",
        source="systems/robot.py (parameters chosen here); record simulated here",
        state_names=("px", "py", "theta"),
    )


def textbook_sim(name: str, seed: int = 0, noise: str = "uniform", steps: int = 200) -> Scenario:
    """A textbook plant of :mod:`systems.textbook` (CTMS parameters, zero-order hold) with its
    known square-wave input and a seeded simulated record."""
    p = textbook.plant(name)
    system = p.system()
    sim = simulate(system, p.input(steps), steps=steps, seed=seed, noise=noise)
    sc = _make(
        name=name, system=system, u=sim.u, y=sim.y, x_true=sim.x_true,
        options={"order": 20, "reduction": "pca"},
        description=f"{p.title} (CTMS), zero-order hold at {p.dt:g} s, simulated ({noise} "
                    f"noise, seed {seed})",
        source=textbook.SOURCE, state_names=p.states,
    )
    # offline experiment for the data-driven observers: inputs within the square wave's swing
    return _with_training(sc, seed, 500, p.wave[0], 0.1)


_FIXED: dict[str, Callable[..., Scenario]] = {
    "vehicle2d-cora": vehicle2d_cora,
    "vehicle6d-cora": vehicle6d_cora,
    "tank30-linear-cora": tank30_linear_cora,
    "tank6-nonlinear-cora": tank6_nonlinear_cora,
    "vanderpol-sim": vanderpol_sim,
    "alamo2d": alamo2d_published,
    "alamo2d-sim": alamo2d_sim,
    "rotating-target": rotating_target_scenario,
    "rego2d-nonlinear": rego2d_nonlinear_sim,
    "rego2d-linear": rego2d_linear_sim,
    "robot-range": robot_range_sim,
    **{name: partial(textbook_sim, name) for name in textbook.PLANTS},
}
_PATTERNS: list[tuple[re.Pattern, Callable[..., Scenario]]] = [
    (re.compile(r"vehicle([246])d-sim"), lambda m, **kw: vehicle_sim(int(m.group(1)), **kw)),
    (re.compile(r"tank(\d+)-linear"), lambda m, **kw: tank_linear(int(m.group(1)), **kw)),
    (re.compile(r"tank(\d+)-nonlinear"), lambda m, **kw: tank_nonlinear(int(m.group(1)), **kw)),
]
_LISTED = [
    "vehicle2d-cora", "vehicle6d-cora", "tank30-linear-cora", "tank6-linear", "alamo2d",
    "vehicle2d-sim", "vehicle4d-sim", "vehicle6d-sim", "alamo2d-sim", "tank12-linear",
    "tank18-linear", "tank24-linear", "tank30-linear", "tank6-nonlinear", "tank12-nonlinear",
    "tank30-nonlinear", "tank6-nonlinear-cora", "vanderpol-sim", "rotating-target",
    "rego2d-nonlinear", "rego2d-linear", "robot-range", *textbook.PLANTS,
]


def register_scenario(name: str, factory: Callable[..., Scenario]) -> None:
    """Add a named scenario (e.g. from a plugin); ``factory(**kwargs)`` builds it."""
    _FIXED[name] = factory
    if name not in _LISTED:
        _LISTED.append(name)


def scenario_names() -> list[str]:
    """Names of the ready-made scenarios (``tank<n>-linear`` works for any n >= 2)."""
    return list(_LISTED)


#: bytes per simulated step of the smallest system (x, y, u and the noise factors), a lower
#: bound of what a record of ``steps`` steps allocates
RECORD_BYTES_PER_STEP = 48


def check_steps(name: str, steps: Any) -> None:
    """``steps`` must be an integer >= 1 whose record fits in the memory available."""
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ModelError(f"scenario '{name}': steps must be an integer >= 1, got {steps!r}")
    have = available_memory()
    if have is not None and steps * RECORD_BYTES_PER_STEP > have:
        raise ModelError(f"scenario '{name}': {steps} steps need at least "
                         f"{steps * RECORD_BYTES_PER_STEP / 2**30:.3g} GiB of memory, "
                         f"{have / 2**30:.3g} GiB are available")


def scenario(name: str, **kwargs: Any) -> Scenario:
    """Build the scenario ``name``; simulated ones accept ``seed``, ``noise`` and ``steps``
    (an integer >= 1 whose record fits in memory, checked before anything is allocated)."""
    if "steps" in kwargs:
        check_steps(name, kwargs["steps"])
    try:
        if name in _FIXED:
            return _FIXED[name](**kwargs)
        for pattern, factory in _PATTERNS:
            m = pattern.fullmatch(name)
            if m:
                return factory(m, **kwargs)
    except TypeError as exc:
        raise ModelError(f"scenario '{name}': {exc}") from None
    raise ModelError(f"unknown scenario '{name}' (available: {', '.join(scenario_names())}; "
                     "tank<n>-linear and tank<n>-nonlinear for any n >= 2)")
