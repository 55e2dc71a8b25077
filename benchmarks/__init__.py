"""Benchmark runner: YAML configs -> runs.csv / summary.csv -> Markdown report and figures.

Timings are single-threaded, as in the papers ("single thread executions"): unless the user
set them, the BLAS thread counts are pinned to 1 before numpy is loaded.  Multi-threaded BLAS
on small matrices (e.g. 30 x 3000 generator products) is slower and much noisier.

The thread counts are the one setting of the environment made here, and only by default (a
value the user set is kept): they are a measurement protocol of the harness, and BLAS reads
them once, when it is loaded, so they cannot wait for the command line.  The BLAS kernel
family (``OPENBLAS_CORETYPE``) is left to OpenBLAS and the user: the numbers of the
regression gate do not depend on it (see :mod:`benchmarks.gate.regression`).
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from .errors import ConfigError  # noqa: E402
from .metrics import add_relative_rms, rms_radius  # noqa: E402
from .report.markdown import write_report  # noqa: E402
from .run.config import BenchConfig, load_config, parse_config  # noqa: E402
from .run.runner import run_config  # noqa: E402

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
