"""A tool's result replayed as an observer, so that its rows come from the harness's own row
computation (:func:`benchmarks.run.rows.execute_job`): containment, exact membership, the
floor, ``covers_exact``, the gap, the memory and the ratios, exactly as for a native observer.

:func:`replay_observer` registers ``ext:<tool>`` (family ``external``); its option ``result``
is the path of the checked result file (:func:`~.results.read_result`), ``scenario`` the label
it answers; ``step`` returns the stored set of step k.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import observers
from observers import Observer

from .results import ExternalResult, read_result

#: checked results by path (the scoring reads each file once, the replay finds it here)
_RESULTS: dict[str, ExternalResult] = {}


def remember(result: ExternalResult) -> None:
    """Keep a checked result for its replay (by its path)."""
    _RESULTS[str(Path(result.path).resolve())] = result


class Replay(Observer):
    """A tool's estimated sets, read from its result file and returned step by step."""

    OPTIONS = {"result": "", "scenario": ""}
    SCENARIO_OPTIONS = ()
    REQUIRES = ()
    REGRESSION_RTOL = 0.0

    def design(self) -> None:
        """Read the result file (once per process; :func:`remember` may have read it)."""
        key = str(Path(self.options["result"]).resolve())
        if key not in _RESULTS:
            n, N = getattr(self.system, "n", None), None
            _RESULTS[key] = read_result(self.options["result"], n, N)
        self.result = _RESULTS[key]

    def step(self, u_prev: Any, y: Any):
        """The stored set of this step (``u_prev`` and ``y`` are the tool's business)."""
        S = self.result.sets[self.k]
        self.k += 1
        return S


def replay_observer(result: ExternalResult) -> str:
    """Register (or register again) the replay of ``result``'s tool as ``ext:<tool>``.

    Each tool gets its own subclass of :class:`Replay` (the registry keeps the name and the
    entry on the class); it is defined in this function, so the runner runs it in this
    process (:func:`benchmarks.run.runner.isolatable`).

    Returns
    -------
    str
        The registered name.
    """
    name = result.observer
    tool = result.tool

    class ToolReplay(Replay):
        __doc__ = (f"{tool['name']} {tool['version']}".strip() + " (" +
                   (tool["language"] or "external tool") + "), replayed from its result file")

    ToolReplay.__qualname__ = f"replay_observer.<locals>.Replay[{name}]"
    reference = ", ".join(v for v in (f"{tool['name']} {tool['version']}".strip(),
                                      tool["language"], tool["machine"]) if v)
    observers.register(name, family="external", set_type=result.set_type,
                       ready_for_control=False, guaranteed=result.guaranteed,
                       reference=reference)(ToolReplay)
    return name
