"""What fails CI: ``regression`` (golden files and their comparison), ``blas`` (the golden
numbers' sensitivity to the BLAS kernel, OpenBLAS's core type), ``policy`` (the verdicts of
``check``, ``baseline`` and ``audit``), ``audit`` (the soundness audit), ``history`` (the golden
summaries over the commits).  Imports :mod:`benchmarks.run`, :mod:`benchmarks.report` and the
shared base modules."""
