"""Exchange with tools outside the harness, in any language: the problems go out as files
(:mod:`.export`), the tools' estimated sets come back as files (:mod:`.results`) and are scored
by the harness's own row computation (:mod:`.replay`, :mod:`.score`); :mod:`.schema` names the
formats.  The schema is documented in ``docs/guide/exchange.rst``."""
