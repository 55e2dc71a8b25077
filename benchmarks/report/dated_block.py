"""The dated block of a report of the second tier: its text between two markers, right under
the title (what it says is rendered by :mod:`benchmarks.gate.dated`)."""

from __future__ import annotations

import re

#: the markers of the block under a dated report's title
BEGIN, END = "<!-- dated -->", "<!-- /dated -->"
_BLOCK = re.compile(re.escape(BEGIN) + r".*?" + re.escape(END) + r"\n\n", re.S)


def with_block(text: str, new: str) -> str:
    """``text`` (a report) with its dated block replaced by ``new``, or ``new`` inserted after
    its title line (the first line) where it has none."""
    if _BLOCK.search(text):
        return _BLOCK.sub(lambda _: new, text, count=1)
    title, _, rest = text.partition("\n")
    return f"{title}\n\n{new}{rest.lstrip(chr(10))}"


def keep_block(old: str, new: str) -> str:
    """``new`` (a report rendered again) with the dated block of ``old`` (the file it
    replaces), if that has one: the block is re-rendered by :func:`refresh` alone."""
    found = _BLOCK.search(old)
    return with_block(new, found.group(0)) if found else new
