"""What a reader sees: ``tables`` (the cells of every report table), ``markdown``
(``report.md``), ``html`` (the HTML page and the index of reports), ``figures`` (every figure,
and the one save-as-PNG-and-PDF), ``numbers`` (the one number formatter), ``paper`` (published
tables), ``freshness`` (content-hash stamps of committed reports), ``aggregate`` (sweeps over
seeds).  Imports only the shared base modules of :mod:`benchmarks`."""
