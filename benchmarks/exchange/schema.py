"""The names, versions and conventions of the exchange files (``docs/guide/exchange.rst``).

A *problem* file (``setobs-problem``) describes one scenario of a configuration: the model,
the sets and the record, never the true states.  A *result* file (``setobs-result``) holds a
tool's estimated set of every step of one scenario.
"""

from __future__ import annotations

from typing import Any

#: schema name and version of a problem file
PROBLEM_SCHEMA, PROBLEM_VERSION = "setobs-problem", 1
#: schema name and version of a result file
RESULT_SCHEMA, RESULT_VERSION = "setobs-result", 1
#: the formats of ``export`` (and the file suffix of each; ``csv`` is a folder)
FORMATS = {"json": ".json", "mat": ".mat", "csv": ""}
#: the set representations of a result, with the fields each step's set has
SET_FIELDS = {"interval": ("lo", "hi"), "zonotope": ("c", "G"),
              "conzonotope": ("c", "G", "A", "b"), "ellipsoid": ("q", "Q")}

#: the time-index convention of every exchanged record (that of :mod:`observers.base`)
STEP_CONVENTION = (
    "x[k+1] = f(x[k], u[k]) + w[k] (linear: A x[k] + B u[k] + w[k]) and y[k] = C x[k] + v[k] "
    "(or h(x[k]) + v[k]), with x[0] in X0, w[k] in W, v[k] in V; rows are steps k = 0..N-1. "
    "The set of step k must contain x[k]; it may use y[0..k] and u[0..k-1] (u[k] drives "
    "x[k+1] and is not known at step k). Step 0 has no input; its set may be X0 intersected "
    "with what y[0] allows, or X0 itself.")


def problem_label(name: str, seed: int | None) -> str:
    """The label of one scenario instance of a configuration: its name, with ``-seed<S>`` for
    a seeded instance (a sweep over seeds has one instance per seed).

    Parameters
    ----------
    name : str
        The scenario's name (its configuration ``label`` where one is given).
    seed : int or None
        The instance's seed.

    Returns
    -------
    str
        The label that problem and result files name.

    Examples
    --------
    >>> problem_label("alamo2d-sim", None), problem_label("alamo2d-sim", 3)
    ('alamo2d-sim', 'alamo2d-sim-seed3')
    """
    return name if seed is None else f"{name}-seed{seed}"


def instance_labels(cfg: Any) -> dict[str, Any]:
    """The scenario instances of a configuration by their :func:`problem_label`."""
    return {problem_label(i.scenario.name, i.seed): i for i in cfg.instances}
