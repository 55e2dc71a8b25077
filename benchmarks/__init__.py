"""Benchmark runner: YAML configs -> runs.csv / summary.csv -> Markdown report and figures.

Timings are single-threaded, as in the papers ("single thread executions"): unless the user
set them, the BLAS thread counts are pinned to 1 before numpy is loaded.  Multi-threaded BLAS
on small matrices (e.g. 30 x 3000 generator products) is slower and much noisier.

Reproducibility: on x86-64 the OpenBLAS kernel family is pinned to ``Haswell`` (AVX2, on every
x86-64 server since 2015) unless ``OPENBLAS_CORETYPE`` is set.  OpenBLAS otherwise picks its
kernels by CPU, and their different rounding is amplified by several observers (PCA
reductions with repeated singular values on the tank system, near-divergent PRad-A): its
AVX-512 (SkylakeX) and AVX2 (Haswell) kernels gave RMS radii up to 1.4 % (FRad-C) and 5x
(PRad-A) apart on the 6-tank record, which the regression gate's near-rounding tolerances
report as regressions.
"""

import os
import platform

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
#: OpenBLAS kernel family pinned on x86-64 (see the module docstring)
BLAS_CORETYPE = "Haswell"
if platform.machine().lower() in ("x86_64", "amd64"):
    os.environ.setdefault("OPENBLAS_CORETYPE", BLAS_CORETYPE)

from .config import BenchConfig, load_config, parse_config  # noqa: E402
from .errors import ConfigError  # noqa: E402
from .metrics import add_relative_rms, rms_radius  # noqa: E402
from .report import write_report  # noqa: E402
from .runner import run_config  # noqa: E402

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
