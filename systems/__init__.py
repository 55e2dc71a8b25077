"""System generators and named benchmark scenarios.

This package depends only on :mod:`observers.sets` (never on the observer plugins).
"""

from .alamo import alamo2d
from .derivatives import SYMBOLIC
from .errors import DomainError, ModelError, OutputNotLinear
from .memory import available_memory
from .model import LinearSystem, NonlinearSystem, observability_matrix
from .rotating import rotating_target
from .scenarios import Scenario, check_steps, register_scenario, scenario, scenario_names
from .simulate import NOISE_MODELS, Simulation, simulate
from .tank import tank, tank_input
from .training import Training, offline_experiment
from .vanderpol import vanderpol
from .vehicle import lane_change_input, vehicle

__all__ = [
    "DomainError",
    "NOISE_MODELS",
    "SYMBOLIC",
    "LinearSystem",
    "ModelError",
    "NonlinearSystem",
    "OutputNotLinear",
    "Scenario",
    "Simulation",
    "Training",
    "alamo2d",
    "available_memory",
    "check_steps",
    "lane_change_input",
    "observability_matrix",
    "offline_experiment",
    "register_scenario",
    "rotating_target",
    "scenario",
    "scenario_names",
    "simulate",
    "tank",
    "tank_input",
    "vanderpol",
    "vehicle",
]
