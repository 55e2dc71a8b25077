"""The result store: the summary rows of every shipped configuration as committed data, each row
with the fingerprint of what produced it, and the reports rendered from them.

- :mod:`.graph`: the project's module graph, read from the source, and the AST digests;
- :mod:`.fingerprint`: what a row is made of (code closure, data, record, configuration entry);
- :mod:`.store`: reading, checking, merging and writing ``results/<config>/`` under a lock;
- :mod:`.stale`: which stored rows and committed reports are out of date (``setobs-bench stale``);
- :mod:`.bench`: the incremental ``make bench`` and ``run --add`` (run only what is stale).
"""
