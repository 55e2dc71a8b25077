"""The one number formatter of every table and page, and the two table renderers.

Every number shown by the harness (Markdown reports, HTML pages, the speed and scaling reports,
the data-driven study, the plain-text tables of ``check`` and ``time``) goes through
:func:`fmt`, so that one value reads the same everywhere:

* a missing or non-finite value is :data:`MISSING` (``n/a``: nothing to show, or not
  measured);
* zero is ``0``;
* a magnitude in ``[1e-3, 1e4)`` is written with ``digits`` significant digits (``%g``);
* anything else in scientific notation with ``digits`` significant digits.

A table column is written in one notation (:func:`format_columns`): its number cells are
:class:`Num` values, and the column is plain (``0.0004970`` beside ``0.4353``) where every
magnitude lies in ``[PLAIN_LOW, PLAIN_HIGH)``, else scientific throughout (``4.970e-04``
beside ``4.353e-01``), published values in parentheses included.  :func:`markdown_table` and
:func:`text_table` accept such cells.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

#: the cell of a value that is missing, not finite, or was not measured
MISSING = "n/a"
#: significant digits of the report tables (eq. 9 ratios, radii, times)
DIGITS = 4
#: a column is written plainly if all its non-zero magnitudes lie in [PLAIN_LOW, PLAIN_HIGH)
PLAIN_LOW, PLAIN_HIGH = 1e-5, 1e6
#: the notations of :func:`fmt`
NOTATIONS = ("auto", "plain", "sci")


def _value(x) -> float | None:
    """``x`` as a finite float, or None (missing, NaN, infinite, not a number)."""
    if x is None or isinstance(x, bool):
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def fmt(x, digits: int = DIGITS, unit: str = "", notation: str = "auto") -> str:
    """The cell of a number (see the module docstring); ``unit`` is appended to a number.

    Parameters
    ----------
    x : float, int or None
        The value.
    digits : int
        Significant digits.
    unit : str
        Appended to the number (not to :data:`MISSING`), e.g. ``" ms"`` or ``"x"``.
    notation : {"auto", "plain", "sci"}
        ``"auto"``: plain in ``[1e-3, 1e4)``, else scientific (a value on its own);
        ``"plain"``: positional with ``digits`` significant digits (a column's choice,
        :func:`column_notation`); ``"sci"``: scientific.

    Returns
    -------
    str
        The formatted cell.

    Examples
    --------
    >>> fmt(0.43527), fmt(4.97e-4), fmt(float("nan")), fmt(12.5, 3, " ms")
    ('0.4353', '4.970e-04', 'n/a', '12.5 ms')
    >>> fmt(4.97e-4, notation="plain"), fmt(0.43527, notation="sci")
    ('0.000497', '4.353e-01')
    """
    if notation not in NOTATIONS:
        raise ValueError(f"notation must be one of {NOTATIONS}, got {notation!r}")
    v = _value(x)
    if v is None:
        return MISSING
    if v == 0:
        return "0" + unit
    sci = (abs(v) >= 1e4 or abs(v) < 1e-3) if notation == "auto" else notation == "sci"
    if sci:
        return f"{v:.{digits - 1}e}{unit}"
    return _plain(v, digits) + unit


def _plain(v: float, digits: int) -> str:
    """``v`` positionally with ``digits`` significant digits, trailing zeros dropped."""
    decimals = max(digits - 1 - math.floor(math.log10(abs(v))), 0)
    text = f"{v:.{decimals}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def column_notation(values: Iterable) -> str:
    """The notation of a column of numbers: ``"plain"`` if every finite non-zero magnitude
    lies in ``[PLAIN_LOW, PLAIN_HIGH)``, else ``"sci"``.

    Examples
    --------
    >>> column_notation([0.4353, 4.97e-4, None]), column_notation([0.4353, 4.97e-6])
    ('plain', 'sci')
    """
    mags = [abs(v) for v in map(_value, values) if v]
    return "plain" if all(PLAIN_LOW <= m < PLAIN_HIGH for m in mags) else "sci"


@dataclass(frozen=True)
class Num:
    """A number cell of a table, written in its column's notation (:func:`format_columns`).

    Parameters
    ----------
    value : float or None
        Our value (:data:`MISSING` where missing or not finite).
    paper : float or None
        A published value, shown in parentheses after ours (same notation).
    note : str or None
        Text in parentheses after ours instead of a published value (e.g. ``n/a``).
    unit : str
        Appended to the number.
    bold : bool
        Markdown bold (``**x**``).
    prefix : str
        Written before a number (not before :data:`MISSING`), e.g. ``"<= "`` for an upper
        bound.
    caveat : str or None
        Written in brackets right after our value (before a published value), e.g. the
        measured spread of a value that depends on the BLAS kernel
        (:mod:`benchmarks.report.spread`).
    """

    value: Any
    paper: Any = None
    note: str | None = None
    unit: str = ""
    bold: bool = False
    prefix: str = ""
    caveat: str | None = None

    def numbers(self) -> list[Any]:
        """The values that decide the column's notation."""
        return [self.value, self.paper]

    def render(self, notation: str, digits: int = DIGITS) -> str:
        """The cell text in ``notation``."""
        text = fmt(self.value, digits, self.unit, notation)
        if self.prefix and text != MISSING:
            text = self.prefix + text
        if self.caveat is not None and text != MISSING:
            text += f" [{self.caveat}]"
        if self.paper is not None:
            text += f" ({fmt(self.paper, digits, notation=notation)})"
        elif self.note is not None:
            text += f" ({self.note})"
        return f"**{text}**" if self.bold else text


def format_columns(rows: Sequence[Sequence[Any]], digits: int = DIGITS) -> list[list[str]]:
    """Cell strings of ``rows``: every :class:`Num` in the notation of its column
    (:func:`column_notation` over the column's numbers), strings unchanged.

    Examples
    --------
    >>> format_columns([["a", Num(0.4353)], ["b", Num(4.97e-6, paper=1.0)]])
    [['a', '4.353e-01'], ['b', '4.970e-06 (1.000e+00)']]
    """
    width = max((len(r) for r in rows), default=0)
    notations = [column_notation([x for r in rows if i < len(r) and isinstance(r[i], Num)
                                  for x in r[i].numbers()]) for i in range(width)]
    return [[c.render(notations[i], digits) if isinstance(c, Num) else str(c)
             for i, c in enumerate(r)] for r in rows]


def fmt_pair(ours, paper, digits: int = DIGITS) -> str:
    """Our value with the published one in parentheses (just ours where none is published)."""
    return fmt(ours, digits) if paper is None else f"{fmt(ours, digits)} ({fmt(paper, digits)})"


def markdown_table(head: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A header and rows of cells (strings or :class:`Num`) as a Markdown table."""
    rows = format_columns(rows)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return "\n".join(lines + ["| " + " | ".join(cells) + " |" for cells in rows])


def text_table(head: Sequence[str], rows: Sequence[Sequence[Any]],
               right: Sequence[bool] | None = None) -> str:
    """A fixed-width plain-text table (command output) of cells (strings or :class:`Num`):
    columns padded to their widest cell, left-aligned unless ``right[i]``; trailing blanks
    removed."""
    rows = format_columns(rows)
    right = list(right) if right is not None else [False] * len(head)
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(head)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.rjust(w) if r else c.ljust(w)
                         for c, w, r in zip(cells, widths, right, strict=True)).rstrip()

    return "\n".join([line(head), "  ".join("-" * w for w in widths)]
                     + [line(r) for r in rows])
