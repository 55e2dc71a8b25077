"""Sphinx extension of the setobs-bench site: generates, at every build, one page per
registered observer (``observers/``) and the API reference (``api/``) from the code.

An observer page is assembled from what the code already declares: the registry entry
(family, set, timing, reference), the class docstring and those of its family loop (the step's
equations), the docstrings of the functions of :mod:`observers.numerics` the plugin module
calls (the gain's or update's equations), the option specs (kind, range, default), the shipped
configurations and published tables it appears in, and its measured speed in
``reports/speed.json`` where present.  The generated folders are not committed (.gitignore).
"""

from __future__ import annotations

import ast
import inspect
import json
import re
import types
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
#: packages of the API reference (the plugins' classes are on the observer pages)
API_PACKAGES = ("observers", "systems", "benchmarks")
API_SKIP = re.compile(r"(^|\.)_[a-z]|^observers\.builtin\.|__main__$")


def slug(name: str) -> str:
    """File name of an observer page (``PRad-C-I`` -> ``prad-c-i``)."""
    return re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")


def _write(path: Path, text: str) -> None:
    """Write ``text`` unless the file already holds it (keeps Sphinx's incremental build)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def _title(text: str, char: str = "=") -> str:
    return f"{text}\n{char * len(text)}\n"


def _list_table(head: list[str], rows: list[list[str]], widths: str | None = None) -> str:
    out = [".. list-table::", "   :header-rows: 1"]
    if widths:
        out.append(f"   :widths: {widths}")
    out.append("")
    for row in [head, *rows]:
        out.append("   * - " + (row[0] or " "))
        out += [f"     - {c or ' '}" for c in row[1:]]
    return "\n".join(out) + "\n"


# -- where an observer appears -------------------------------------------------------------

def config_appearances(name: str, guaranteed_names: list[str]) -> list[str]:
    """The shipped configurations that run ``name`` (directly or as a labelled variant)."""
    from benchmarks.run.shipped import shipped_configs

    found = []
    for cfg, path in shipped_configs().items():
        raw = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
        obs = raw.get("observers", "all")
        names = list(guaranteed_names) if obs == "all" else [str(o) for o in obs]
        names = [n for n in names if n not in set(map(str, raw.get("exclude") or []))]
        labels = [lab for lab, v in (raw.get("variants") or {}).items()
                  if isinstance(v, dict) and v.get("observer") == name]
        if name in names or labels:
            title = raw.get("title", cfg)
            extra = f" (also as {', '.join(labels)})" if labels and name in names else (
                f" (as {', '.join(labels)})" if labels else "")
            found.append(f"``{cfg}``: {title}{extra}")
    return found


def paper_appearances(name: str) -> list[str]:
    """The published tables with a row for ``name``."""
    from benchmarks.report.paper import ALIASES, load_table, paper_title

    folder = ROOT / "systems" / "data" / "paper_tables"
    out = []
    for path in sorted(folder.glob("*.yaml")):
        tab = load_table(path.stem)
        for variant, rows in (("linear", tab.get("rows")), ("linear", tab.get("linear")),
                              ("nonlinear", tab.get("nonlinear"))):
            for row in rows or {}:
                if name in ALIASES.get(row, (row,)):
                    out.append(paper_title(path.stem, variant) or path.stem)
    return list(dict.fromkeys(out))


def speed_rows(name: str) -> list[list[str]]:
    """The cases of ``reports/speed.json`` that time ``name``."""
    from benchmarks.report.numbers import fmt

    path = ROOT / "reports" / "speed.json"
    if not path.is_file():
        return []
    data = json.loads(path.read_text(encoding="utf-8"))
    rows = []
    for r in data.get("results", []):
        if r.get("observer") != name:
            continue
        unit = {"ratio": "x Kalman step", "ratio_hull": "x Kalman step",
                "ms": "ms", "ms_hull": "ms"}.get(r.get("metric"), "")
        rows.append([f"``{r.get('case', '')}``", r.get("status", ""), fmt(r.get("step_ms")),
                     fmt(r.get("hull_ms")), f"{fmt(r.get('value'))} {unit}".strip(),
                     fmt(r.get("target")), fmt(r.get("paper_ms"))])
    return rows


# -- the observer's code -----------------------------------------------------------------

def numerics_functions(cls: type) -> list[str]:
    """Dotted names of the :mod:`observers.numerics` functions the plugin module of ``cls``
    imports and the class (or its bases in that module) calls."""
    module = inspect.getmodule(cls)
    tree = ast.parse(inspect.getsource(module))
    imported = {}
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.module and "numerics" in node.module:
            target = "observers." + node.module.lstrip(".") if node.level else node.module
            for a in node.names:
                imported[a.asname or a.name] = f"{target}.{a.name}"
    used: list[str] = []
    for klass in cls.__mro__:
        if inspect.getmodule(klass) is not module:
            continue
        src = inspect.getsource(klass)
        for ident, dotted in imported.items():
            if re.search(rf"\b{re.escape(ident)}\b", src) and dotted not in used:
                obj = _resolve(dotted)
                if inspect.isfunction(obj) or inspect.isclass(obj):
                    used.append(dotted)
    return used


def _resolve(dotted: str):
    import importlib

    mod, _, attr = dotted.rpartition(".")
    try:
        return getattr(importlib.import_module(mod), attr)
    except (ImportError, AttributeError):
        return None


def family_classes(cls: type) -> list[type]:
    """The loop classes of ``cls`` (bases defined in :mod:`observers.families` or
    :mod:`observers.base`), most specific first."""
    return [k for k in cls.__mro__[1:]
            if k.__module__ in ("observers.families", "observers.base") and k.__doc__]


#: the set operations of the constrained-zonotope observers' step
CZN_METHODS = ("intersect_measurement", "reduce", "reduce_constraints")


def observer_page(info, guaranteed_names: list[str]) -> str:
    cls = info.cls
    target = f"{cls.__module__}.{cls.__qualname__}"
    parts = [f".. _observer-{slug(info.name)}:", "", _title(info.name),
             f"*{info.summary}*", "",
             _list_table(["family", "set", "timing", "guaranteed", "paper"],
                         [[info.family, info.set_type, info.timing,
                           "yes" if info.guaranteed else "no (its misses are counted)",
                           info.reference or "-"]]),
             _title("The observer", "-"),
             f".. autoclass:: {target}", "   :no-members:", "   :no-index:", ""]
    fams = family_classes(cls)
    if fams:
        parts += [_title("The step (family loop)", "-"),
                  "The loop it runs, from :mod:`observers.families`; the observer supplies "
                  "the gain or the update below.", ""]
        for k in fams:
            parts += [f".. autoclass:: {k.__module__}.{k.__qualname__}", "   :no-members:",
                      "   :no-index:", ""]
    funcs = numerics_functions(cls)
    if funcs:
        parts += [_title("Equations of the gain and update", "-"),
                  f"The functions of :mod:`observers.numerics` that ``{cls.__module__}`` calls "
                  f"for {info.name}:", ""]
        for f in funcs:
            kind = "autoclass" if inspect.isclass(_resolve(f)) else "autofunction"
            parts += [f".. {kind}:: {f}", "   :no-index:", ""]
    if info.set_type == "conzonotope" and info.family != "data-driven":
        parts += [_title("Set operations", "-"),
                  "The constrained-zonotope operations of the step (:mod:`observers.sets`):", ""]
        for meth in CZN_METHODS:
            parts += [f".. automethod:: observers.sets.conzonotope.ConZonotope.{meth}",
                      "   :no-index:", ""]
    specs = cls.option_specs() if hasattr(cls, "option_specs") else {}
    parts.append(_title("Options", "-"))
    if specs:
        parts += ["Checked before the design (``observers.create(name, system, **options)`` or "
                  "a config's ``options`` / ``observer_options``):", "",
                  _list_table(["option", "accepted values", "default"],
                              [[f"``{k}``", spec.describe().replace("|", "/"),
                                f"``{spec.default!r}``"] for k, spec in specs.items()],
                              "20 60 20")]
    else:
        parts += ["None.", ""]
    parts.append(_title("Where it appears", "-"))
    papers = paper_appearances(info.name)
    parts += ["Published tables with a row for it: " + ("; ".join(papers) if papers else
              "none (not part of the papers' comparison; its published average and time are "
              "``(n/a)`` in the reports)") + ".", ""]
    configs = config_appearances(info.name, guaranteed_names)
    parts += ["Shipped configurations that run it (``setobs-bench run NAME``):", ""]
    parts += [f"* {c}" for c in configs] if configs else ["* none"]
    parts.append("")
    parts.append(_title("Measured speed", "-"))
    rows = speed_rows(info.name)
    if rows:
        parts += ["From ``reports/speed.json`` (``make speed``, timed serially; the paper's time "
                  "is MATLAB + CORA on an i7-8565U):", "",
                  _list_table(["case", "status", "step ms", "hull ms", "value", "target",
                               "paper ms"], rows)]
    else:
        parts += ["Not in ``reports/speed.json``; ``setobs-bench time "
                  f"{info.name} --scenario S`` times it on any scenario (the reports' tables "
                  "list the per-step times of every run).", ""]
    return "\n".join(parts) + "\n"


def observers_index(infos) -> str:
    rows = [[f":ref:`{i.name} <observer-{slug(i.name)}>`", i.family, i.set_type, i.timing,
             i.reference or "-"] for i in infos]
    toc = "\n".join(f"   {slug(i.name)}" for i in infos)
    return (_title("Observers") + "\n"
            "One page per registered observer, generated from the registry, the docstrings and "
            "option specs, the shipped configurations, the published tables and "
            "``reports/speed.json``. ``setobs-bench list observers`` prints the same registry.\n\n"
            + _list_table(["observer", "family", "set", "timing", "paper"], rows,
                          "12 10 12 14 52")
            + "\n.. toctree::\n   :hidden:\n\n" + toc + "\n")


# -- API reference -----------------------------------------------------------------------

def api_modules() -> list[str]:
    """Every public module of the three packages (private ones and the plugins left out)."""
    out = []
    for pkg in API_PACKAGES:
        for p in sorted((ROOT / pkg).rglob("*.py")):
            if "__pycache__" in p.parts:
                continue
            rel = p.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            name = ".".join(parts)
            if not API_SKIP.search(name) and "configs" not in parts:
                out.append(name)
    return out


def _is_package(module: str) -> bool:
    return (ROOT.joinpath(*module.split(".")) / "__init__.py").is_file()


def api_pages(src: Path) -> None:
    mods = api_modules()
    for stale in (src / "api").glob("*.rst"):  # pages of modules that moved or went away
        if stale.stem not in mods and stale.stem != "index":
            stale.unlink()
    for m in mods:
        # a package page shows its docstring only: its members are re-exports of its modules,
        # documented there (and ``systems.simulate`` is both a module and a function)
        opts = ":no-members:" if _is_package(m) else ":members:"
        _write(src / "api" / f"{m}.rst", _title(f"``{m}``") + f"\n.. automodule:: {m}\n   {opts}\n")
    groups = {pkg: [m for m in mods if m == pkg or m.startswith(pkg + ".")]
              for pkg in API_PACKAGES}
    text = [_title("API reference"), "",
            "Generated from the numpydoc docstrings of every public module (the plugins' "
            "classes are documented on the :doc:`observer pages </observers/index>`).", ""]
    for pkg, ms in groups.items():
        text += [_title(f"``{pkg}``", "-"), ".. toctree::", "   :maxdepth: 1", ""]
        text += [f"   {m}" for m in ms] + [""]
    _write(src / "api" / "index.rst", "\n".join(text))


def generate(app) -> None:
    import observers

    src = Path(app.srcdir)
    infos = observers.available()
    guaranteed = [i.name for i in infos if i.family != "stochastic"]
    pages = {slug(info.name) for info in infos}
    for stale in (src / "observers").glob("*.rst"):  # observers no longer registered
        if stale.stem not in pages and stale.stem != "index":
            stale.unlink()
    for info in infos:
        _write(src / "observers" / f"{slug(info.name)}.rst", observer_page(info, guaranteed))
    _write(src / "observers" / "index.rst", observers_index(infos))
    api_pages(src)


def options_as_parameters(app, what, name, obj, options, lines) -> None:
    """Our docstrings list an observer's options in an ``Options`` section; numpydoc knows it
    as ``Other Parameters`` (run before numpydoc's own handler)."""
    for i in range(len(lines) - 1):
        if lines[i].strip() == "Options" and set(lines[i + 1].strip()) == {"-"}:
            indent = lines[i][: len(lines[i]) - len(lines[i].lstrip())]
            lines[i] = indent + "Other Parameters"
            lines[i + 1] = indent + "-" * len("Other Parameters")


def skip_aliases(app, what, name, obj, skip, options):
    """Type aliases (``Task = tuple[str, int, str]``) have no signature to document."""
    if isinstance(obj, types.GenericAlias):
        return True
    return None


def setup(app):
    app.connect("builder-inited", generate)
    app.connect("autodoc-process-docstring", options_as_parameters, priority=100)
    app.connect("autodoc-skip-member", skip_aliases)
    return {"version": "1", "parallel_read_safe": True}
