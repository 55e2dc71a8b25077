"""Time: ``steps`` (per-step times against a numpy Kalman step on the same record,
``setobs-bench time``) and ``speed`` (the speed table ``reports/speed.md``).  Imports
:mod:`benchmarks.run`, :mod:`benchmarks.report` and the shared base modules."""
