"""Preloaded by the server process from which local workers are forked
(:func:`benchmarks.run.executors._context`), so that every worker starts with what the jobs need.

Importing this module imports the harness (:mod:`benchmarks.run.runner`), every observer plugin
(with what they import: HiGHS, scipy.stats, numba, ...) and loads the compiled kernels
(:func:`benchmarks.run.warmup.warm`).  A worker forked from that server
then pays none of it: without this, each worker spent about 2.5 s of CPU importing the
plugins and loading the kernel at its first job (measured on the 3 x 22 x 20 sweep).
Nothing here changes a result: the same modules are imported, only earlier.
"""

from __future__ import annotations

from .warmup import warm

warm()
