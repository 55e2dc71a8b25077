"""Running a benchmark configuration: ``config`` (YAML -> :class:`~.config.BenchConfig`) ->
``specs`` (scenario entries) -> ``runner`` (jobs, containment, result rows) -> ``executors``
(serial, local processes, Dask; ``workerinit`` is what local workers preload), and
``designs`` (offline designs in parallel into the cache), ``progress`` (bars), ``membership``
(exact membership tests).  Imports only the floor of :mod:`benchmarks`."""
