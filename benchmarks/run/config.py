"""Benchmark configurations (one YAML file per published table).

::

    name: automatica2021-table3          # default: the file name
    title: Vehicle, 6 states (Althoff & Rath 2021, Table 3)
    scenarios: [vehicle6d-cora]          # names, {name, seed, ...} or inline systems
    observers: all                       # or a list of names
    exclude: [VolMin-A]                  # optional
    options: {order: 100}                # optional, for every observer that accepts them
    observer_options:                    # optional, per observer
      FRad-B: {variant: textbook}
    containment: exact                   # exact (LP membership) | hull (interval hull only)
    timeout: 600                         # seconds per job (default 1800; none: no budget)
    memory_limit: 4G                     # per job (default: 80 % of the available memory
                                         # shared by the workers; none: no limit)
    sweep:                               # optional: a grid of runs, one tidy table
      seeds: [0, 1, 2]                   # or {count: 20} (seeds 0..19) for simulated scenarios
      sizes: [6, 12, 30]                 # substituted for {n} in scenario names (tank{n}-linear)
      grid:                              # per observer: every combination of these values
        FRad-A: {order: [20, 50]}
    variants:                            # optional: an observer again, other options, own label
      ESO-C[cora]: {observer: ESO-C, options: {variant: cora}, guaranteed: false}

A labelled variant runs beside the listed observers under its label (``NAME[tag]``), with the
scenario and global options and its own ``options`` (not the observer's ``observer_options``);
``guaranteed: false`` (default: the observer's) reports it as not guaranteed: excluded from the
eq. (9) minima, its containment violations counted but not failing the run.

Everything is validated when the file is loaded, before any observer runs.  A sweep runs
every scenario x size x seed x observer x option combination; ``summary.csv`` then has one row
per combination and state, keyed by ``scenario``, ``seed``, ``observer`` and ``variant`` (the
grid options, e.g. ``order=20``), and the report aggregates over the seeds.
"""

from __future__ import annotations

import itertools
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

import observers
from systems import Scenario, available_memory

from ..errors import ConfigError
from .rows import merge_options
from .shipped import resolve_config
from .specs import build_scenario

TOP_KEYS = {"name", "title", "scenarios", "observers", "exclude", "options", "observer_options",
            "containment", "description", "sweep",
            "variants", "timeout", "memory_limit", "exact", "floors"}
#: the job timeout by default (seconds; a configuration's ``timeout``, ``run --timeout``):
#: above the slowest legitimate job (an SDP design on 30 tanks with a cold design cache takes
#: minutes), far below "for ever"
DEFAULT_TIMEOUT = 1800.0
#: memory limit per job by default: this fraction of the memory available when the run
#: starts, shared by the workers running at once
DEFAULT_MEMORY_FRACTION = 0.8
_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def default_memory_limit(workers: int = 1) -> int | None:
    """The memory limit per job by default: :data:`DEFAULT_MEMORY_FRACTION` of the memory
    available now, divided among ``workers`` (None where it is not known)."""
    have = available_memory()
    return None if have is None else int(DEFAULT_MEMORY_FRACTION * have / max(1, workers))


def parse_timeout(value: Any, where: str) -> float | None:
    """A time budget in seconds: a positive number, or ``none``/``null`` for no budget."""
    if value is None or (isinstance(value, str) and value.strip().lower() in ("none", "off")):
        return None
    try:
        seconds = float(value) if not isinstance(value, bool) else math.nan
    except (TypeError, ValueError):
        seconds = math.nan
    if not (math.isfinite(seconds) and seconds > 0):
        raise ConfigError(f"{where}: the time budget must be a positive number of seconds "
                          f"or 'none', got {value!r}")
    return seconds


def parse_memory(value: Any, where: str) -> int | str | None:
    """A memory limit: bytes as an integer or with a binary unit (``512M``, ``4G``,
    ``1.5GiB``), ``auto`` (the default share of the available memory) or ``none``."""
    if value is None or (isinstance(value, str) and value.strip().lower() in ("none", "off")):
        return None
    if isinstance(value, str) and value.strip().lower() == "auto":
        return "auto"
    text = str(value).strip().upper().removesuffix("IB").removesuffix("B")
    unit = text[-1:] if text[-1:] in _UNITS and text[-1:] else ""
    try:
        number = float(text[:-1] if unit else text) if not isinstance(value, bool) else math.nan
    except ValueError:
        number = math.nan
    size = number * _UNITS[unit]
    if not (math.isfinite(size) and size >= 1):
        raise ConfigError(f"{where}: the memory limit must be a size such as 512M or 4G, "
                          f"'auto' or 'none', got {value!r}")
    return int(size)
SWEEP_KEYS = {"seeds", "sizes", "grid"}


@dataclass(frozen=True)
class Instance:
    """One scenario of a (possibly swept) config: its built value, the config entry that
    rebuilds it (in a worker process) and its seed (``None`` if the entry sets none)."""

    scenario: Scenario
    spec: dict
    seed: int | None = None


@dataclass
class BenchConfig:
    """A validated benchmark configuration with its scenarios built."""

    name: str
    title: str
    scenarios: list[Scenario]
    observers: list[str]
    options: dict[str, Any] = field(default_factory=dict)
    observer_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    containment: str = "exact"
    description: str = ""
    raw: dict = field(default_factory=dict, repr=False)
    #: the scenarios with their config entries (a sweep: one per size and seed)
    instances: list[Instance] = field(default_factory=list)
    #: per observer, the option combinations of the sweep grid as (label, options)
    variants: dict[str, list[tuple[str, dict[str, Any]]]] = field(default_factory=dict)
    base: Path | None = None
    #: per-job time budget (seconds) and memory limit (bytes, ``"auto"``); None: no limit
    timeout: float | None = DEFAULT_TIMEOUT
    memory_limit: int | str | None = "auto"
    #: compute every record's accuracy floor (:mod:`.floor`: the exact consistent set of a
    #: linear record, the falsifier's inner box of a nonlinear one)
    exact: bool = True
    #: observer (or label) -> the floor it is held against, over its registry entry's
    floors: dict[str, str] = field(default_factory=dict)

    def job_memory_limit(self, workers: int) -> int | None:
        """The memory limit per job in bytes (``auto``: the default share for ``workers``
        workers running at once, :func:`default_memory_limit`)."""
        if self.memory_limit == "auto":
            return default_memory_limit(workers)
        return self.memory_limit  # type: ignore[return-value]

    def __post_init__(self):
        if not self.instances:  # built in code from scenario values: their names as entries
            self.instances = [Instance(sc, {"name": sc.name}) for sc in self.scenarios]

    def variants_of(self, observer: str) -> list[tuple[str, dict[str, Any]]]:
        """The sweep variants of ``observer`` (``[("", {})]`` if the grid has none)."""
        return self.variants.get(observer) or [("", {})]
    #: label -> (observer name, options, guaranteed) of the labelled variants
    labelled: dict[str, tuple[str, dict[str, Any], bool]] = field(default_factory=dict)

    def observer_of(self, label: str) -> str:
        """The registered observer behind a label (a variant's, or the name itself)."""
        return self.labelled[label][0] if label in self.labelled else label

    def guaranteed(self, label: str) -> bool:
        """Whether the observer run under ``label`` is reported as guaranteed."""
        if label in self.labelled:
            return self.labelled[label][2]
        return observers.get(label).guaranteed

    def options_for(self, observer: str, scenario: Scenario) -> dict[str, Any]:
        """The options of ``observer`` (a name or a label) on ``scenario``
        (:func:`merge_options` of this config's options)."""
        own = (self.labelled[observer][1] if observer in self.labelled
               else self.observer_options.get(observer, {}))
        return merge_options(self.observer_of(observer), scenario, self.options, own)


def _yaml_error(path: Path, exc: yaml.YAMLError) -> ConfigError:
    mark = getattr(exc, "problem_mark", None)
    where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return ConfigError(f"{path}: malformed YAML{where}: {problem}")


def _check_keys(value: Any, allowed: set[str], where: str, shape: str) -> None:
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a mapping {shape}")
    unknown = set(value) - allowed
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)} "
                          f"(allowed: {', '.join(sorted(allowed))})")


def _check_values(name: str, info: observers.ObserverInfo, opts: dict[str, Any]) -> None:
    """Check option values against the observer's declared specs (kind and range)."""
    specs = getattr(info.cls, "option_specs", None)
    if not callable(specs):
        return
    declared = specs()
    for key, value in opts.items():
        try:
            declared[key].check(info.name, key, value)
        except observers.OptionError as exc:
            raise ConfigError(f"config '{name}': observer_options: {exc}") from None


def parse_config(raw: Any, name: str, base: Path | None = None) -> BenchConfig:
    """Validate a config mapping (as loaded from YAML) and build its scenarios."""
    _check_keys(raw, TOP_KEYS, f"config '{name}'", "at the top level")
    scen = raw.get("scenarios")
    if not isinstance(scen, list) or not scen:
        raise ConfigError(f"config '{name}': 'scenarios' must be a non-empty list")
    obs = raw.get("observers", "all")
    try:
        if obs == "all":
            names = [i.name for i in observers.available()
                     if i.family not in observers.registry.OUTSIDE_ALL]
        elif isinstance(obs, list) and obs:
            names = [observers.get(str(o)).name for o in obs]
        else:
            raise ConfigError(f"config '{name}': 'observers' must be 'all' or a non-empty list")
        exclude = raw.get("exclude", []) or []
        if not isinstance(exclude, list):
            raise ConfigError(f"config '{name}': 'exclude' must be a list")
        for o in exclude:
            observers.get(str(o))
    except observers.UnknownObserver as exc:
        raise ConfigError(f"config '{name}': {exc}") from None
    names = [n for n in names if n not in set(map(str, exclude))]
    if len(set(names)) != len(names):
        raise ConfigError(f"config '{name}': an observer is listed twice")
    options = raw.get("options", {}) or {}
    if not isinstance(options, dict):
        raise ConfigError(f"config '{name}': 'options' must be a mapping")
    accepted_any = set().union(*(observers.get(n).option_defaults() for n in names))
    bad = set(options) - accepted_any
    if bad:
        raise ConfigError(f"config '{name}': option(s) {sorted(bad)} are accepted by none of "
                          "the selected observers")
    per = raw.get("observer_options", {}) or {}
    if not isinstance(per, dict):
        raise ConfigError(f"config '{name}': 'observer_options' must be a mapping")
    for oname, opts in per.items():
        try:
            info = observers.get(str(oname))
        except observers.UnknownObserver as exc:
            raise ConfigError(f"config '{name}': observer_options: {exc}") from None
        if not isinstance(opts, dict):
            raise ConfigError(f"config '{name}': observer_options of {oname} must be a mapping")
        bad = set(opts) - set(info.option_defaults())
        if bad:
            raise ConfigError(
                f"config '{name}': {oname} has no option(s) {sorted(bad)} (accepted: "
                f"{', '.join(sorted(info.option_defaults())) or 'none'})"
            )
        _check_values(name, info, opts)  # also for an observer not in this run
    containment = raw.get("containment", "exact")
    if containment not in ("exact", "hull"):
        raise ConfigError(f"config '{name}': containment must be 'exact' or 'hull'")
    seeds, sizes, variants = _parse_sweep(raw.get("sweep"), name, names)
    instances = []
    for spec in _expand(scen, seeds, sizes, name):
        seed = spec.get("seed", (spec.get("simulate") or {}).get("seed"))
        instances.append(Instance(build_scenario(spec, base), spec, seed))
    # a scenario's own options are defaults for any observer: a key no registered observer
    # accepts is a typo (the top level's options are checked against this run's observers)
    known = accepted_any.union(*(i.option_defaults() for i in observers.available()))
    for inst in instances:
        own = inst.spec.get("options") or {}
        bad = set(own) - known if isinstance(own, dict) else set()
        if bad:
            raise ConfigError(f"config '{name}': scenario '{inst.scenario.name}': option(s) "
                              f"{sorted(bad)} are accepted by no observer")
    seen = [(i.scenario.name, i.seed) for i in instances]
    if len(set(seen)) != len(seen):
        raise ConfigError(f"config '{name}': a scenario appears twice with the same seed: "
                          f"{[s for s, _ in seen]}")
    labelled = _variants(raw.get("variants"), name)
    clash = [v for v in labelled if v in names]
    if clash:
        raise ConfigError(f"config '{name}': variant label(s) {clash} are observer names")
    return BenchConfig(
        labelled=labelled,
        name=str(raw.get("name", name)), title=str(raw.get("title", name)),
        scenarios=[i.scenario for i in instances], observers=names + list(labelled),
        options=options,
        observer_options={str(k): dict(v) for k, v in per.items()},
        containment=containment, description=str(raw.get("description", "")), raw=raw,
        instances=instances, variants=variants, base=base,
        timeout=parse_timeout(raw.get("timeout", DEFAULT_TIMEOUT), f"config '{name}': timeout"),
        memory_limit=parse_memory(raw.get("memory_limit", "auto"),
                                  f"config '{name}': memory_limit"),
        exact=_flag(raw.get("exact", True), f"config '{name}': exact"),
        floors=_floors(raw.get("floors"), name, names + list(labelled)),
    )


def _flag(value: Any, where: str) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(f"{where} must be true or false, got {value!r}")
    return value


def _floors(raw: Any, name: str, known: list[str]) -> dict[str, str]:
    """Validate ``floors``: observer (or label) -> ``filtered`` or ``predicted``."""
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise ConfigError(f"config '{name}': floors must be a mapping observer -> "
                          "filtered|predicted")
    out = {}
    for obs, floor in raw.items():
        if str(obs) not in known:
            raise ConfigError(f"config '{name}': floors: {obs} is not an observer of this "
                              "configuration")
        if floor not in ("filtered", "predicted"):
            raise ConfigError(f"config '{name}': floors: {obs} must be 'filtered' or "
                              f"'predicted', got {floor!r}")
        out[str(obs)] = floor
    return out


def _variants(raw: Any, name: str) -> dict[str, tuple[str, dict[str, Any], bool]]:
    """Validate the ``variants`` mapping: label -> {observer, options, guaranteed}."""
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise ConfigError(f"config '{name}': 'variants' must be a mapping label -> "
                          "{observer, options, guaranteed}")
    out = {}
    for label, spec in raw.items():
        where = f"config '{name}': variant {label}"
        if not isinstance(spec, dict) or "observer" not in spec:
            raise ConfigError(f"{where} must be a mapping with an 'observer' key")
        bad = set(spec) - {"observer", "options", "guaranteed"}
        if bad:
            raise ConfigError(f"{where}: unknown key(s) {sorted(bad)} "
                              "(allowed: guaranteed, observer, options)")
        try:
            info = observers.get(str(spec["observer"]))
        except observers.UnknownObserver as exc:
            raise ConfigError(f"{where}: {exc}") from None
        opts = spec.get("options") or {}
        if not isinstance(opts, dict):
            raise ConfigError(f"{where}: 'options' must be a mapping")
        unknown = set(opts) - set(info.cls.option_defaults())
        if unknown:
            raise ConfigError(f"{where}: {info.name} has no option(s) {sorted(unknown)}")
        guaranteed = spec.get("guaranteed", info.guaranteed)
        if not isinstance(guaranteed, bool):
            raise ConfigError(f"{where}: 'guaranteed' must be true or false")
        out[str(label)] = (info.name, dict(opts), guaranteed)
    return out


def _int_list(value: Any, what: str, minimum: int) -> list[int]:
    if isinstance(value, dict) and set(value) == {"count"}:
        count = value["count"]
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ConfigError(f"{what}: count must be an integer >= 1, got {count!r}")
        return list(range(count))
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{what} must be a non-empty list of integers (or {{count: N}})")
    for v in value:
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            raise ConfigError(f"{what}: {v!r} is not an integer >= {minimum}")
    if len(set(value)) != len(value):
        raise ConfigError(f"{what}: a value appears twice: {value}")
    return list(value)


def _parse_sweep(sweep: Any, name: str, names: list[str]):
    """Seeds, sizes and per-observer option variants of a ``sweep:`` block."""
    if sweep is None:
        return None, None, {}
    where = f"config '{name}': sweep"
    _check_keys(sweep, SWEEP_KEYS, where, f"with keys {sorted(SWEEP_KEYS)}")
    seeds = _int_list(sweep["seeds"], f"{where}: seeds", 0) if "seeds" in sweep else None
    sizes = _int_list(sweep["sizes"], f"{where}: sizes", 1) if "sizes" in sweep else None
    grid = sweep.get("grid") or {}
    if not isinstance(grid, dict):
        raise ConfigError(f"{where}: grid must be a mapping of observer -> {{option: [values]}}")
    variants: dict[str, list[tuple[str, dict[str, Any]]]] = {}
    for oname, opts in grid.items():
        if str(oname) not in names:
            raise ConfigError(f"{where}: grid: '{oname}' is not one of the selected observers")
        info = observers.get(str(oname))
        if not isinstance(opts, dict) or not opts:
            raise ConfigError(f"{where}: grid of {oname} must be a non-empty mapping "
                              "{option: [values]}")
        bad = set(opts) - set(info.cls.option_defaults())
        if bad:
            raise ConfigError(f"{where}: grid: {oname} has no option(s) {sorted(bad)}")
        keys = sorted(opts)
        values = []
        for k in keys:
            if not isinstance(opts[k], list) or not opts[k]:
                raise ConfigError(f"{where}: grid: {oname}.{k} must be a non-empty list of "
                                  "values")
            values.append(opts[k])
        variants[info.name] = [
            (",".join(f"{k}={json.dumps(v)}" for k, v in zip(keys, combo, strict=True)),
             dict(zip(keys, combo, strict=True)))
            for combo in itertools.product(*values)]
    return seeds, sizes, variants


def _expand(entries: list, seeds: list[int] | None, sizes: list[int] | None,
            name: str) -> list[dict]:
    """Config scenario entries for every size (``{n}`` in the name) and seed."""
    out = []
    for entry in entries:
        spec = {"name": entry} if isinstance(entry, str) else entry
        if not isinstance(spec, dict) or "name" not in spec:
            raise ConfigError(f"a scenario must be a name or a mapping with 'name', got "
                              f"{entry!r}")
        templated = "{n}" in str(spec["name"])
        if templated and not sizes:
            raise ConfigError(f"config '{name}': scenario '{spec['name']}' has {{n}} but the "
                              "sweep gives no sizes")
        for n in (sizes if templated else [None]):
            sized = dict(spec, name=str(spec["name"]).replace("{n}", str(n)))
            for seed in (seeds if seeds is not None else [None]):
                if seed is None:
                    out.append(sized)
                elif "system" in sized:  # inline: the seed of its simulation
                    if not isinstance(sized.get("simulate"), dict):
                        raise ConfigError(f"config '{name}': sweep seeds need a simulated "
                                          f"scenario; '{sized['name']}' has a fixed record")
                    out.append(dict(sized, simulate=dict(sized["simulate"], seed=seed)))
                else:
                    out.append(dict(sized, seed=seed))
    return out


def inline_config(scenarios: list[str] | None, observer_names: list[str] | None = None,
                  name: str | None = None) -> BenchConfig:
    """The configuration of a run given by names (``run --scenario S --observer NAME``):
    every observer (default: all) on every named scenario."""
    if not scenarios:
        raise ConfigError("run: give a YAML config or at least one --scenario")
    raw = {"name": name or "cli", "title": "Command-line run: " + ", ".join(scenarios),
           "scenarios": list(scenarios),
           "observers": list(observer_names) if observer_names else "all"}
    return parse_config(raw, raw["name"])


def load_config(path: str | Path) -> BenchConfig:
    """Load and validate a YAML benchmark configuration: a file, or the name of a shipped one
    (``arch2021_table3``, :func:`benchmarks.run.shipped.resolve_config`)."""
    path = resolve_config(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except OSError as exc:
        raise ConfigError(f"cannot read config {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    try:
        raw = yaml.load(text, Loader=StrictLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as exc:
        raise _yaml_error(path, exc) from None
    return parse_config(raw, path.stem, path.parent)


class StrictLoader(yaml.SafeLoader):
    """YAML's safe loader, refusing a key given twice in one mapping (plain YAML keeps the
    last one silently) and reading ``1e3``, ``-2.5E-4`` as numbers (YAML 1.1, which PyYAML
    follows, reads a float without a dot as text; YAML 1.2 and every user read a number)."""

    def construct_mapping(self, node, deep=False):
        seen: dict = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                first = seen.setdefault(key, key_node.start_mark)
            except TypeError:  # an unhashable key: SafeLoader reports it
                continue
            if first is not key_node.start_mark:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} appears twice in one mapping (first on line "
                    f"{first.line + 1})", key_node.start_mark)
        return super().construct_mapping(node, deep=deep)


StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))
