"""Running a benchmark configuration: ``config`` (YAML -> :class:`~.config.BenchConfig`) ->
``specs`` (scenario entries) -> ``rows`` (what one job computes: its rows, a pure function of
the job; the root of every row's fingerprint) <- ``runner`` (makes the jobs, has them run,
writes the tables) -> ``executors`` (serial, local processes, Dask; ``workerinit`` is what
local workers preload), and ``designs`` (offline designs in parallel into the cache),
``progress`` (bars), ``membership`` (exact membership tests), ``floor`` (the exact floor of a
linear record and the floor columns of a row), ``floor_inner`` (with ``falsifier``, the inner
box of a nonlinear record), ``floors`` (which floor each record gets, computed by the
executor).  Imports only the shared base modules of :mod:`benchmarks`."""
