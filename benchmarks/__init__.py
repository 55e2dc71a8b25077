"""Benchmark runner: YAML configs -> runs.csv / summary.csv -> Markdown report and figures."""

from .config import BenchConfig, load_config, parse_config
from .errors import ConfigError
from .metrics import add_relative_rms, rms_radius
from .report import write_report
from .runner import run_config

__all__ = [
    "BenchConfig",
    "ConfigError",
    "add_relative_rms",
    "load_config",
    "parse_config",
    "rms_radius",
    "run_config",
    "write_report",
]
