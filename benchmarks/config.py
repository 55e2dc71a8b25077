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

Everything is validated when the file is loaded, before any observer runs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

import observers
from systems import Scenario

from .errors import ConfigError
from .specs import build_scenario

TOP_KEYS = {"name", "title", "scenarios", "observers", "exclude", "options", "observer_options",
            "containment", "description"}


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

    def options_for(self, observer: str, scenario: Scenario) -> dict[str, Any]:
        """Scenario defaults < config options < per-observer options, restricted to the
        options the observer accepts (scenario and global ones) or all (per-observer ones);
        scenario defaults only for the options listed in the observer's ``SCENARIO_OPTIONS``;
        observers with a ``training`` option also get the scenario's offline experiment."""
        info = observers.get(observer)
        accepted = info.option_defaults()
        from_scenario = accepted if info.scenario_options is None else info.scenario_options
        merged = {k: v for k, v in scenario.options.items() if k in from_scenario}
        merged.update({k: v for k, v in self.options.items() if k in accepted})
        merged.update(self.observer_options.get(observer, {}))
        if "training" in accepted and "training" not in merged and scenario.training is not None:
            merged["training"] = scenario.training  # offline data for data-driven observers
        return merged


def _yaml_error(path: Path, exc: yaml.YAMLError) -> ConfigError:
    mark = getattr(exc, "problem_mark", None)
    where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return ConfigError(f"{path}: malformed YAML{where}: {problem}")


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
    if not isinstance(raw, dict):
        raise ConfigError(f"config '{name}' must be a mapping at the top level")
    unknown = set(raw) - TOP_KEYS
    if unknown:
        raise ConfigError(f"config '{name}': unknown key(s) {sorted(unknown)} "
                          f"(allowed: {', '.join(sorted(TOP_KEYS))})")
    scen = raw.get("scenarios")
    if not isinstance(scen, list) or not scen:
        raise ConfigError(f"config '{name}': 'scenarios' must be a non-empty list")
    obs = raw.get("observers", "all")
    try:
        if obs == "all":
            names = [i.name for i in observers.available() if i.family != "stochastic"]
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
    scenarios = [build_scenario(s, base) for s in scen]
    seen = [s.name for s in scenarios]
    if len(set(seen)) != len(seen):
        raise ConfigError(f"config '{name}': a scenario name appears twice: {seen}")
    return BenchConfig(
        name=str(raw.get("name", name)), title=str(raw.get("title", name)),
        scenarios=scenarios, observers=names, options=options,
        observer_options={str(k): dict(v) for k, v in per.items()},
        containment=containment, description=str(raw.get("description", "")), raw=raw,
    )


def load_config(path: str | Path) -> BenchConfig:
    """Load and validate a YAML benchmark configuration."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except OSError as exc:
        raise ConfigError(f"cannot read config {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    try:
        raw = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise _yaml_error(path, exc) from None
    return parse_config(raw, path.stem, path.parent)
