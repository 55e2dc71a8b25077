"""The one number formatter of every table and page, and the two table renderers.

Every number shown by the harness (Markdown reports, HTML pages, the speed and scaling reports,
the data-driven study, the plain-text tables of ``check`` and ``time``) goes through
:func:`fmt`, so that one value reads the same everywhere:

* a missing or non-finite value is :data:`MISSING` (``n/a``: nothing to show, or not
  measured);
* zero is ``0``;
* a magnitude in ``[1e-3, 1e4)`` is written with ``digits`` significant digits (``%g``);
* anything else in scientific notation with ``digits`` significant digits, so that a column
  never mixes ``0.4353`` with ``4.970e-04`` written by two rules.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

#: the cell of a value that is missing, not finite, or was not measured
MISSING = "n/a"
#: significant digits of the report tables (eq. 9 ratios, radii, times)
DIGITS = 4


def _value(x) -> float | None:
    """``x`` as a finite float, or None (missing, NaN, infinite, not a number)."""
    if x is None or isinstance(x, bool):
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def fmt(x, digits: int = DIGITS, unit: str = "") -> str:
    """The cell of a number (see the module docstring); ``unit`` is appended to a number.

    Parameters
    ----------
    x : float, int or None
        The value.
    digits : int
        Significant digits.
    unit : str
        Appended to the number (not to :data:`MISSING`), e.g. ``" ms"`` or ``"x"``.

    Returns
    -------
    str
        The formatted cell.

    Examples
    --------
    >>> fmt(0.43527), fmt(4.97e-4), fmt(float("nan")), fmt(12.5, 3, " ms")
    ('0.4353', '4.970e-04', 'n/a', '12.5 ms')
    """
    v = _value(x)
    if v is None:
        return MISSING
    if v == 0:
        return "0" + unit
    if abs(v) >= 1e4 or abs(v) < 1e-3:
        return f"{v:.{digits - 1}e}{unit}"
    return f"{v:.{digits}g}{unit}"


def fmt_pair(ours, paper, digits: int = DIGITS) -> str:
    """Our value with the published one in parentheses (just ours where none is published)."""
    return fmt(ours, digits) if paper is None else f"{fmt(ours, digits)} ({fmt(paper, digits)})"


def markdown_table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A header and rows of cell strings as a Markdown table."""
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return "\n".join(lines + ["| " + " | ".join(cells) + " |" for cells in rows])


def text_table(head: Sequence[str], rows: Sequence[Sequence[str]],
               right: Sequence[bool] | None = None) -> str:
    """A fixed-width plain-text table (command output): columns padded to their widest cell,
    left-aligned unless ``right[i]``; trailing blanks removed."""
    right = list(right) if right is not None else [False] * len(head)
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(head)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.rjust(w) if r else c.ljust(w)
                         for c, w, r in zip(cells, widths, right, strict=True)).rstrip()

    return "\n".join([line(head), "  ".join("-" * w for w in widths)]
                     + [line(r) for r in rows])
