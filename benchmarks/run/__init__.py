"""Running a benchmark configuration: ``config`` (YAML -> :class:`~.config.BenchConfig`) ->
``specs`` (scenario entries) -> ``runner`` (jobs, containment, result rows) -> ``executors``
(serial, local processes, Dask; ``workerinit`` is what local workers preload), and
``designs`` (offline designs in parallel into the cache), ``progress`` (bars), ``membership``
(exact membership tests), ``floor`` (the exact floor of every record, with ``falsifier``, the
inner box of a nonlinear one).  Imports only the shared base modules of :mod:`benchmarks`."""
