"""Published results tables (``systems/data/paper_tables/*.yaml``) keyed by observer name."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import resources

import yaml

#: one published row stands for several of our observers (CORA has a single PRad-C)
ALIASES = {"PRad-C": ("PRad-C-I", "PRad-C-II")}

#: the short name of each published table (per variant where one file holds two tables)
TITLES = {
    "arch2021_table3_tank6_linear": "Althoff, ARCH 2021, Table 3",
    "arch2021_table4_tank6_nonlinear": "Althoff, ARCH 2021, Table 4",
    "arch2021_table5_6_tank_scaling": {"linear": "Althoff, ARCH 2021, Table 5",
                                       "nonlinear": "Althoff, ARCH 2021, Table 6"},
    "automatica2021_table3_vehicle6": "Althoff & Rath, Automatica 2021, Table 3",
    "alanwar2022_datadriven": "Alanwar et al., 2022, Sec. IV",
}


def paper_title(key: str | None, variant: str = "linear") -> str | None:
    """The short name of published table ``key`` (e.g. ``"Althoff, ARCH 2021, Table 3"``),
    ``None`` without a table."""
    if not key:
        return None
    title = TITLES.get(key, key)
    return title.get(variant, key) if isinstance(title, dict) else title


@dataclass(frozen=True)
class PaperRow:
    """Published values of one observer: relative RMS per state, average, ms per step."""

    v: tuple[float, ...] | None
    avg: float | None
    t_ms: float | None
    absolute: tuple[float, ...] | None
    source: str


@cache
def load_table(key: str) -> dict:
    """Raw YAML of a paper table (``{}`` if there is none of that name)."""
    path = resources.files("systems") / "data" / "paper_tables" / f"{key}.yaml"
    if not path.is_file():
        return {}
    with path.open() as fh:
        return yaml.safe_load(fh)


def _value(x) -> float | None:
    if x is None:
        return None
    if isinstance(x, str):  # e.g. "noGain"
        return None
    return float(x)


def paper_rows(key: str | None, n_states: int | None = None,
               variant: str = "linear") -> dict[str, PaperRow]:
    """Our observer name -> published row for table ``key``.

    For the tank scaling table (ARCH Tables 5/6) ``n_states`` selects the column and
    ``variant`` the linear or nonlinear table; only averages and times exist there.
    """
    if not key:
        return {}
    tab = load_table(key)
    if not tab:
        return {}
    out: dict[str, PaperRow] = {}
    src = tab.get("source", key)
    if "tanks" in tab:
        if n_states not in tab["tanks"]:
            return {}
        j = tab["tanks"].index(n_states)
        for name, row in (tab.get(variant) or {}).items():
            for ours in ALIASES.get(name, (name,)):
                out[ours] = PaperRow(None, _value(row["avg"][j]), _value(row["t_comp_ms"][j]), None,
                                     src)
        return out
    smallest = tab.get("smallest_absolute_radii")
    for name, row in tab.get("rows", {}).items():
        v = tuple(float(x) for x in row["v"]) if "v" in row else None
        avg = _value(row.get("avg")) if "avg" in row else (sum(v) / len(v) if v else None)
        absolute = (tuple(a * b for a, b in zip(v, smallest, strict=True))
                    if v and smallest else None)
        for ours in ALIASES.get(name, (name,)):
            out[ours] = PaperRow(v, avg, _value(row.get("t_comp_ms")), absolute, src)
    for name, t_s in (tab.get("time_per_step_s") or {}).items():  # timings-only tables
        out.setdefault(name, PaperRow(None, None, 1e3 * float(t_s), None, src))
    return out


def paper_status(key: str | None, n_states: int | None, observer: str,
                 variant: str = "linear") -> str | None:
    """Non-numeric entries of the scaling table (``noGain``, ``inf``, ``nan``) for an observer."""
    tab = load_table(key) if key else {}
    if "tanks" not in tab or n_states not in tab["tanks"]:
        return None
    j = tab["tanks"].index(n_states)
    for name, row in (tab.get(variant) or {}).items():
        if observer in ALIASES.get(name, (name,)):
            val = row["avg"][j]
            if isinstance(val, str):
                return val
            if isinstance(val, float) and (val != val or val in (float("inf"), float("-inf"))):
                return "diverged"
    return None
