"""The benchmark configurations shipped with the package, by name.

``benchmarks/configs/*.yaml`` (and ``configs/sweeps/*.yaml``) are package data: after a
non-editable ``pip install`` they live in site-packages, where nobody types their path.
:func:`resolve_config` lets every command take a shipped configuration by its name
(``setobs-bench run arch2021_table3``); a path to an existing file always wins, so a local
``arch2021_table3.yaml`` is used as given.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigError

#: the folder of the shipped configurations (inside the installed package)
CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"


def shipped_configs() -> dict[str, Path]:
    """Name -> path of every shipped configuration (``sweeps/NAME`` for the sweeps), sorted.

    Examples
    --------
    >>> "arch2021_table3" in shipped_configs()
    True
    """
    found = {p.relative_to(CONFIG_DIR).with_suffix("").as_posix(): p
             for p in CONFIG_DIR.rglob("*.yaml")}
    return dict(sorted(found.items()))


def resolve_config(name_or_path: str | Path) -> Path:
    """The configuration file meant by ``name_or_path``: the file itself if it exists, else
    the shipped configuration of that name (with or without ``.yaml``, e.g.
    ``arch2021_table3`` or ``sweeps/seeds_3x22x20``).

    Raises
    ------
    ConfigError
        Neither a file nor a shipped name; the message lists the shipped names.
    """
    path = Path(name_or_path)
    if path.is_file():
        return path
    shipped = shipped_configs()
    key = path.as_posix()
    key = key[: -len(".yaml")] if key.endswith(".yaml") else key
    for candidate in (key, key.removeprefix("benchmarks/configs/")):
        if candidate in shipped:
            return shipped[candidate]
    raise ConfigError(f"config file not found: {name_or_path} (and no shipped config of that "
                      f"name; shipped: {', '.join(shipped)}; `setobs-bench list configs`)")
