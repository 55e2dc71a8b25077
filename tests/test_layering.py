"""The import structure of ``observers``, ``systems`` and ``benchmarks``: no module-level import
cycle; the bottom rooms of ``observers`` importing one way (``observers.kernels`` <-
``observers.lp`` <- ``observers.sets`` <- the rest; no solver in ``sets``, numba only in
``lp`` and ``kernels``); no private module or name taken from another room; the wings of
``benchmarks`` importing one way (``cli`` -> wings; ``gate``, ``timing``, ``studies`` ->
``run``, ``report``; ``studies`` also -> ``timing``, ``gate``; ``run``, ``report`` -> the
shared base modules ``errors``,
``io``, ``metrics``, ``verdicts``), matplotlib only in ``benchmarks/report/figures.py``, one
number formatter (``benchmarks/report/numbers.py``), through which every number of a report
table cell goes; and no import cycle even counting the imports inside functions.

The graph is read from the source with :mod:`ast`: an edge for every import statement at module
level (also inside ``try``/``if`` blocks, but not under ``if TYPE_CHECKING:``, which never
runs), none for imports inside functions (they run after every module is loaded; the
``anywhere`` graph counts them too).  ``from P
import x`` is an edge to the submodule ``P.x`` if there is one, else to the package ``P``;
the implicit import of parent packages is not an edge (a package that imports its submodules
in ``__init__`` is the normal layout).  ``python tests/test_layering.py`` prints the cycles.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("observers", "systems", "benchmarks")
#: the shared base of ``benchmarks/`` (top-level modules every wing may import)
BASE = {"errors", "io", "metrics", "verdicts"}
#: the wings of ``benchmarks/`` and the other wings each may import (besides the base)
WINGS = {"run": set(), "report": set(), "store": {"run", "report"},
         "gate": {"run", "report", "store"},
         "timing": {"run", "report"}, "studies": {"run", "report", "timing", "gate"},
         "exchange": {"run", "store"}}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _module_level(body: list[ast.stmt]):
    """The import statements that run when the module is imported."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, ast.If):
            test = node.test
            is_type_checking = (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
                isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")
            if not is_type_checking:
                yield from _module_level(node.body)
            yield from _module_level(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody,
                          *(h.body for h in node.handlers)):
                yield from _module_level(block)
        elif isinstance(node, ast.With):
            yield from _module_level(node.body)


def imports_of(name: str, path: Path, modules: dict[str, Path],
               anywhere: bool = False) -> set[str]:
    """The modules of ours that ``name`` imports at module level (``anywhere``: also inside
    functions)."""
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    tree = ast.parse(path.read_text())
    nodes = (n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))) \
        if anywhere else _module_level(tree.body)
    for node in nodes:
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        else:
            base = node.module or ""
            if node.level:
                parts = name.split(".")
                anchor = parts if is_package else parts[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, *([base] if base else [])])
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                       for a in node.names]
        out.update(t for t in targets if t in modules)
    return out - {name}


def import_graph() -> dict[str, set[str]]:
    modules = all_modules()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_graph_reads_the_imports():
    graph = import_graph()
    assert "observers.kernels.step" in graph["observers.sets.reduction"]
    assert "observers.base" in graph["observers.families"]
    assert "observers.registry" not in graph["observers.base"]  # annotation only
    assert "observers.sets" in graph["observers.families"]  # ``from .sets import Interval``
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_module_level_import_cycle():
    assert cycles(import_graph()) == []


def test_no_import_cycle_even_inside_functions():
    """An import inside a function is an edge too: a circle through one (a module that
    needs another that needs it back, only later) is still a circle a reader must untie."""
    modules = all_modules()
    graph = {name: imports_of(name, path, modules, anywhere=True)
             for name, path in modules.items()}
    assert cycles(graph) == []


#: the bottom rooms of ``observers`` and what each may import of ours (besides itself), every
#: import counted, also those inside functions: kernels <- lp <- sets <- the rest
ROOMS_BELOW = {
    "observers.kernels": set(),
    "observers.lp": {"observers.kernels", "observers.errors"},
    "observers.sets": {"observers.lp", "observers.kernels", "observers.errors"},
}


def _room_of(module: str) -> str | None:
    return next((room for room in ROOMS_BELOW
                 if module == room or module.startswith(room + ".")), None)


def test_sets_lp_kernels_import_one_way():
    modules = all_modules()
    bad = []
    for name, path in modules.items():
        room = _room_of(name)
        if room is None:
            continue
        allowed = ROOMS_BELOW[room] | {room}
        for target in imports_of(name, path, modules, anywhere=True):
            troom = _room_of(target) or target
            if not (troom in allowed or (troom == "observers" and target == "observers")):
                bad.append(f"{name} -> {target}")
    assert bad == []


def _third_party_imports(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            out.add(node.module.split(".")[0])
    return out


def test_sets_hold_no_solver_and_no_compiled_kernel():
    for name, path in all_modules().items():
        if _room_of(name) != "observers.sets":
            continue
        solvers = _third_party_imports(path) & {"highspy", "numba", "cvxpy", "clarabel"}
        assert not solvers, f"{name} imports {sorted(solvers)}"
        calls = {n.func.attr if isinstance(n.func, ast.Attribute) else getattr(n.func, "id", "")
                 for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.Call)}
        assert not calls & {"njit", "jit", "linprog", "milp", "Highs", "new_highs"}, name
    for name, path in all_modules().items():  # numba only in the rooms of compiled code
        if "numba" in _third_party_imports(path):
            assert _room_of(name) in ("observers.lp", "observers.kernels"), \
                f"{name} imports numba outside observers/lp and observers/kernels"


def _room(module: str) -> str:
    """The room of a module: ``observers.X`` for a subpackage ``X`` of ``observers`` (the core
    modules at its top are one room, ``observers``), ``benchmarks.X`` for a wing or base module
    of ``benchmarks``, else the top package."""
    parts = module.split(".")
    if parts[0] in ("observers", "benchmarks") and len(parts) > 1:
        sub = ROOT / parts[0] / parts[1]
        if parts[0] == "benchmarks" or sub.is_dir():
            return ".".join(parts[:2])
    return parts[0]


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def private_reach_ins() -> list[str]:
    """Private modules or names (a leading underscore) taken from another room: imported, or
    read as an attribute of a module or class imported from another room."""
    modules = all_modules()
    found = []
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        foreign: set[str] = set()  # local names bound to modules / objects of other rooms
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom):
                continue
            base = node.module or ""
            if node.level:
                parts = name.split(".")
                anchor = parts if path.name == "__init__.py" else parts[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, *([base] if base else [])])
            if base.split(".")[0] not in PACKAGES:
                continue
            for alias in node.names:
                full = f"{base}.{alias.name}"
                target = full if full in modules else base
                if _room(target) == _room(name):
                    continue
                if any(_private(part) for part in full.split(".")):
                    found.append(f"{name}:{node.lineno} imports {full}")
                foreign.add(alias.asname or alias.name)
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in foreign and _private(node.attr)):
                found.append(f"{name}:{node.lineno} reads {node.value.id}.{node.attr}")
    return found


def test_no_private_reach_ins_across_rooms():
    assert private_reach_ins() == []


def test_registry_imports_base_not_the_reverse():
    graph = import_graph()
    assert "observers.base" in graph["observers.registry"]
    assert "observers.registry" not in graph["observers.base"]


def _benchmarks_part(module: str) -> str | None:
    """The wing (``run``, ``report``, ...) or base module of a ``benchmarks`` module."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "benchmarks" else None


def test_benchmarks_imports_run_one_way():
    modules = all_modules()
    bad = []
    for name, path in modules.items():
        part = _benchmarks_part(name)
        if part is None or part in ("cli", "__main__"):
            continue  # the entry points may import every wing
        for target in imports_of(name, path, modules, anywhere=True):
            tpart = _benchmarks_part(target)
            if tpart is None:
                continue  # observers, systems, or the package itself
            if part in BASE:
                ok = tpart in BASE
            elif part in WINGS:
                ok = tpart in BASE or tpart == part or tpart in WINGS[part]
            else:
                ok = name == "benchmarks"  # the package re-exports the public API
            if not ok:
                bad.append(f"{name} -> {target}")
    assert bad == []


def test_top_level_of_benchmarks_is_the_base_and_the_entry_points():
    top = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py"))
    assert len(top) <= 8, top
    assert set(top) <= BASE | {"__init__", "__main__", "cli"}


def test_matplotlib_only_in_the_figures_module():
    users = sorted(path.relative_to(ROOT).as_posix() for path in all_modules().values()
                   if any(isinstance(n, (ast.Import, ast.ImportFrom))
                          and "matplotlib" in ((n.module or "") if isinstance(n, ast.ImportFrom)
                                               else " ".join(a.name for a in n.names))
                          for n in ast.walk(ast.parse(path.read_text()))))
    assert users == ["benchmarks/report/figures.py"]


def test_one_number_formatter():
    defs = sorted(f"{path.relative_to(ROOT).as_posix()}:{n.name}"
                  for path in all_modules().values()
                  for n in ast.walk(ast.parse(path.read_text()))
                  if isinstance(n, ast.FunctionDef) and n.name in ("_fmt", "_num", "fmt"))
    assert defs == ["benchmarks/report/numbers.py:fmt"]


#: a format spec that writes a number (``.3g``, ``.4f``, ``.2e``, ``g``, ``%``, ``,``)
_NUMBER_SPEC = re.compile(r"[eEfFgG%]$|,")
_PERCENT_SPEC = re.compile(r"%[-+ #0]*\d*(\.\d+)?[eEfFgG]")
_BRACE_SPEC = re.compile(r"\{[^}]*:[^}]*[eEfFgG%]\}")


def own_number_formats(source: str) -> list[str]:
    """Where ``source`` writes a number itself instead of through ``numbers.fmt``: an
    f-string field with a number format spec (``f"{v:.3g}"``), ``format(v, spec)``,
    ``"{:.3g}".format(v)`` or ``"%.3g" % v`` (``line: what``)."""
    found = []
    for n in ast.walk(ast.parse(source)):
        if isinstance(n, ast.FormattedValue) and n.format_spec is not None:
            spec = "".join(v.value if isinstance(v, ast.Constant) else "{}"
                           for v in n.format_spec.values)
            if _NUMBER_SPEC.search(spec):
                found.append(f"{n.lineno}: f-string :{spec}")
        elif (isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
              and n.func.id == "format" and len(n.args) > 1):
            found.append(f"{n.lineno}: format()")
        elif (isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
              and n.func.attr == "format" and isinstance(n.func.value, ast.Constant)
              and isinstance(n.func.value.value, str)
              and _BRACE_SPEC.search(n.func.value.value)):
            found.append(f"{n.lineno}: str.format")
        elif (isinstance(n, ast.BinOp) and isinstance(n.op, ast.Mod)
              and isinstance(n.left, ast.Constant) and isinstance(n.left.value, str)
              and _PERCENT_SPEC.search(n.left.value)):
            found.append(f"{n.lineno}: % formatting")
    return found


def test_the_number_format_check_sees_every_way():
    src = ('a = f"{x:.3g}"\nb = f"{x:{w}.{d}f}"\nc = format(x, ".2e")\n'
           'd = "{:.4f}".format(x)\ne = "%.1f %%" % x\nf = f"{name!r:>12}"\n')
    assert sorted(s.split(":")[0] for s in own_number_formats(src)) == ["1", "2", "3", "4", "5"]


def test_report_table_cells_use_the_one_formatter():
    """The modules that make the reports' table cells and the notes beside them
    (``benchmarks/report/``) write no number themselves: every one goes through
    ``numbers.fmt`` (numbers.py is the formatter; figures.py draws axis ticks and legend
    text, no table cell)."""
    bad = {path.name: own_number_formats(path.read_text())
           for path in sorted((ROOT / "benchmarks" / "report").glob("*.py"))
           if path.name not in ("numbers.py", "figures.py")}
    assert {name: found for name, found in bad.items() if found} == {}


if __name__ == "__main__":  # pragma: no cover - a tool for a reader
    found = cycles(import_graph())
    print("\n".join(" -> ".join(c) for c in found) or "no module-level import cycle")


#: what orchestrates a run, reports or gates it: in no stored row's code
ORCHESTRATION = ("benchmarks.run.runner", "benchmarks.run.executors", "benchmarks.run.progress",
                 "benchmarks.run.config", "benchmarks.run.floors", "benchmarks.run.designs",
                 "benchmarks.run.workerinit", "benchmarks.run.warmup", "benchmarks.run.describe",
                 "benchmarks.io", "benchmarks.cli")
ORCHESTRATION_WINGS = ("benchmarks.store", "benchmarks.gate", "benchmarks.report",
                       "benchmarks.timing", "benchmarks.studies")


def _row_closures():
    from benchmarks.store.fingerprint import HARNESS, INNER_FLOOR
    from benchmarks.store.graph import ModuleGraph

    graph = ModuleGraph(ROOT)
    return graph, {root: graph.closure(root) for root in (*HARNESS, INNER_FLOOR)}


def test_orchestration_is_in_no_rows_closure():
    """A row is a pure function of its job: the runner, the executors, Dask, progress bars,
    input/output, the store, the gate and the reports are outside the code of every row, so
    an edit there stales none (the issue: every row's closure held 62 modules, the executors
    and the falsifier among them)."""
    _, closures = _row_closures()
    for root, closure in closures.items():
        inside = sorted(m for m in closure if m in ORCHESTRATION
                        or m.startswith(ORCHESTRATION_WINGS))
        assert not inside, f"{root} depends on orchestration: {inside}"


def test_the_falsifier_is_in_the_nonlinear_rows_closure_only():
    from benchmarks.store.fingerprint import HARNESS, INNER_FLOOR

    _, closures = _row_closures()
    for root in HARNESS:
        assert not any(m.startswith("benchmarks.run.falsifier") for m in closures[root]), root
    assert "benchmarks.run.falsifier.search" in closures[INNER_FLOOR]
