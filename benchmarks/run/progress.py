"""Progress bars (tqdm) for the runner and the audit, on stderr.

Shown on a terminal and in a Jupyter notebook (tqdm's widget where ``ipywidgets`` is
installed, else its text bar); hidden in pipes, CI logs and files unless asked for, so that
redirected output stays clean.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator
from typing import TypeVar

from tqdm.auto import tqdm

T = TypeVar("T")


def progress_enabled(progress: bool | None) -> bool:
    """``progress`` if given, else whether stderr is a terminal or we run in a notebook."""
    if progress is not None:
        return bool(progress)
    return sys.stderr.isatty() or "ipykernel" in sys.modules


def announced(items: Iterable[T], progress: bool, line: Callable[[T], str]) -> Iterator[T]:
    """``items``, each announced on standard output by ``line(item)`` before it is used
    (where ``progress``): the one-line progress of the timing reports' measurements."""
    for item in items:
        if progress:
            print(line(item), flush=True)
        yield item


def progress_bar(total: int, desc: str, progress: bool | None = None) -> tqdm:
    """A tqdm bar of ``total`` runs; use ``bar.set_postfix_str(note)`` and ``bar.update()``."""
    return tqdm(total=total, desc=desc, unit="run", file=sys.stderr, dynamic_ncols=True,
                disable=not progress_enabled(progress))
