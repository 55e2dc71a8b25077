"""The layout of the code, checked: import directions, no module-level import circle, one
figures module, one number formatter, no private set module imported by a plugin.

Run alone with ``python -m pytest tests/test_layout.py -q``; the graph it checks is printed by
``python tests/test_layout.py`` (module -> its module-level imports of our packages).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("observers", "systems", "benchmarks")
#: the shared floor of ``benchmarks/`` (top-level modules every wing may import)
FLOOR = {"errors", "io", "metrics", "verdicts"}
#: the wings and the wings (besides themselves and the floor) each may import
WINGS = {"run": set(), "report": set(), "gate": {"run", "report"},
         "timing": {"run", "report"}, "studies": {"run", "report"}}


def _module(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _resolve(module: str, is_package: bool, level: int, target: str | None) -> str:
    if level == 0:
        return target or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def _ours(name: str) -> bool:
    return name.split(".")[0] in PACKAGES


def module_imports(path: Path, top_level_only: bool = True) -> set[str]:
    """The modules of ours that ``path`` imports (at module level only, by default; a name
    imported from a package is taken as its submodule where one exists)."""
    module = _module(path)
    tree = ast.parse(path.read_text(encoding="utf-8"))
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    found: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if _ours(a.name)}
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, path.name == "__init__.py", node.level, node.module)
            if not _ours(target):
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                found.add(sub if _exists(sub) else target)
    return found


def _exists(module: str) -> bool:
    p = ROOT.joinpath(*module.split("."))
    return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()


def _files(package: str) -> list[Path]:
    return sorted(p for p in (ROOT / package).rglob("*.py") if "__pycache__" not in p.parts)


def import_graph() -> dict[str, set[str]]:
    """Module -> module-level imports of ours, over the three packages."""
    return {_module(p): module_imports(p) for pkg in PACKAGES for p in _files(pkg)}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Import circles among modules (a package importing its own submodules, the usual
    ``__init__`` re-export, is not a circle through the package)."""
    edges = {m: {t for t in ts if t in graph and not m.startswith(t + ".")
                 and not t.startswith(m + ".")} for m, ts in graph.items()}
    found, state = [], {}

    def visit(m: str, stack: list[str]) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(edges[m]):
            if state.get(t) == 1:
                found.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t, stack)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m, [])
    return found


def _wing(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 2 and parts[1] in WINGS else None


def test_no_module_level_import_circle():
    assert cycles(import_graph()) == []


def test_benchmarks_imports_run_one_way():
    bad = []
    for path in _files("benchmarks"):
        module = _module(path)
        parts = module.split(".")
        for target in module_imports(path, top_level_only=False):
            if not target.startswith("benchmarks.") or target == "benchmarks":
                continue
            tparts = target.split(".")
            twing = tparts[1] if tparts[1] in WINGS else None
            if len(parts) == 2 and parts[1] in FLOOR:  # the floor imports only the floor
                ok = twing is None and tparts[1] in FLOOR
            elif (wing := _wing(module) or (parts[1] if len(parts) > 1 and parts[1] in WINGS
                                             else None)):
                ok = twing in (None, wing) or twing in WINGS[wing]
                ok = ok and (twing is not None or tparts[1] in FLOOR)
            else:  # cli, __init__, __main__
                ok = True
            if not ok:
                bad.append(f"{module} -> {target}")
    assert bad == []


def test_top_level_of_benchmarks_is_the_floor_and_the_entry_points():
    top = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py"))
    assert len(top) <= 8, top
    assert set(top) <= FLOOR | {"__init__", "__main__", "cli"}


def test_matplotlib_only_in_the_figures_module():
    users = [p.relative_to(ROOT).as_posix() for p in _files("benchmarks")
             if "matplotlib" in p.read_text(encoding="utf-8").split('"""', 2)[-1]]
    assert users == ["benchmarks/report/figures.py"]


def test_one_number_formatter():
    defs = []
    for pkg in PACKAGES:
        for p in _files(pkg):
            for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
                if isinstance(node, ast.FunctionDef) and node.name in ("_fmt", "_num", "fmt"):
                    defs.append(f"{p.relative_to(ROOT).as_posix()}:{node.name}")
    assert defs == ["benchmarks/report/numbers.py:fmt"]


def test_plugins_import_no_private_set_module():
    bad = [f"{_module(p)} -> {t}" for p in _files("observers/builtin")
           for t in module_imports(p, top_level_only=False)
           if t.startswith("observers.sets.") and t.split(".")[2].startswith("_")]
    assert bad == []


if __name__ == "__main__":  # pragma: no cover - prints the graph
    for mod, targets in sorted(import_graph().items()):
        print(f"{mod} -> {', '.join(sorted(targets)) or '-'}")
    circles = cycles(import_graph())
    print("import circles:", circles or "none")
    sys.exit(1 if circles else 0)
