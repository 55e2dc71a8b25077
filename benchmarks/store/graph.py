"""The module graph of the project, read from the source with :mod:`ast`, and the digest of each
module's code with its docstrings, comments and formatting left out.

A row of a result store is made of the code its computation imports: the observer's plugin, its
numerics, the set types, the family loops, the system and the metrics.  This module derives that
closure from the import statements, so that no list of dependencies is kept by hand:

- every ``import`` and ``from ... import`` statement counts, at module level and inside
  functions (a lazy import runs as part of the computation too), except those under
  ``if TYPE_CHECKING:`` (they never run);
- ``from P import name`` depends on the submodule ``P.name`` if there is one; else, if ``P``
  binds ``name`` by an import of its own (a package re-exporting a class, as
  ``observers.sets`` does), on the module that defines it, plus the text of ``P`` itself but not
  everything else ``P`` imports; else on ``P`` and what it imports;
- ``import a.b`` depends on ``a.b`` and what it imports;
- the implicit import of parent packages is no dependency (importing ``observers.sets.zonotope``
  does not make a row depend on every observer registered by ``observers``).

The digest of a module (:func:`code_digest`) is a SHA-256 of ``ast.dump`` of its syntax tree
without the docstrings of the module, its classes and functions: an edit of a docstring, a
comment or the layout changes no digest; any change of code does.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
from dataclasses import dataclass, field
from pathlib import Path

#: the project root (the folder holding observers/, systems/, benchmarks/)
ROOT = Path(__file__).resolve().parent.parent.parent
#: the project's packages, always in the graph
PACKAGES = ("observers", "systems", "benchmarks")


def _strip_docstrings(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                    and isinstance(body[0].value.value, str)):
                node.body = body[1:] or [ast.Pass()]
    return tree


def code_digest(source: str) -> str:
    """SHA-256 (hex) of the code of ``source``: its syntax tree without docstrings.

    Parameters
    ----------
    source : str
        Python source text.

    Returns
    -------
    str
        The hex digest; equal for two sources that differ only in docstrings, comments and
        formatting.
    """
    return tree_digest(ast.parse(source))


def tree_digest(tree: ast.AST) -> str:
    """:func:`code_digest` of a parsed module (its docstrings are removed from ``tree``)."""
    tree = _strip_docstrings(tree)
    return hashlib.sha256(ast.dump(tree, include_attributes=False).encode()).hexdigest()


@dataclass
class Module:
    """One module of the graph: its file, digest, dependencies and re-exported names."""

    name: str
    path: Path
    is_package: bool
    digest: str = ""
    #: modules whose code and whose own dependencies this one uses
    deep: set[str] = field(default_factory=set)
    #: modules whose text (digest) only this one uses (a package re-exporting a name)
    shallow: set[str] = field(default_factory=set)
    #: ``name -> (module, name there)`` for the names bound here by ``from M import x``
    reexports: dict[str, tuple[str, str]] = field(default_factory=dict)
    #: names defined here (functions, classes, assignments at module level)
    defined: set[str] = field(default_factory=set)


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


#: the fields of a node that hold statements (an import is a statement: no expression holds
#: one, so the walk does not descend into expressions)
_BODIES = ("body", "orelse", "finalbody", "handlers", "cases")


def _imports(tree: ast.Module):
    """Every import statement of ``tree`` that can run, with whether it is at module level."""
    def walk(nodes, top):
        for node in nodes:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                yield node, top
            elif isinstance(node, ast.If) and _is_type_checking(node.test):
                yield from walk(node.orelse, top)
            else:
                inner = top and not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                      ast.ClassDef))
                for name in _BODIES:
                    yield from walk(getattr(node, name, None) or (), inner)
    yield from walk(tree.body, True)


def _defined(tree: ast.Module) -> set[str]:
    out: set[str] = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                out.update(n.id for n in ast.walk(t) if isinstance(n, ast.Name))
    return out


class ModuleGraph:
    """The modules of the project (and of any outside package added), their digests and the
    dependencies between them (see the module docstring for what counts).

    Parameters
    ----------
    root : Path
        The project root.
    packages : sequence of str
        Top-level packages under ``root`` to read.
    """

    def __init__(self, root: Path = ROOT, packages: tuple[str, ...] = PACKAGES):
        self.root = root
        self.modules: dict[str, Module] = {}
        self._closure: dict[str, frozenset[str]] = {}
        for pkg in packages:
            self._add_tree(pkg, root / pkg)
        self._link()

    # -- reading ------------------------------------------------------------------------------
    def _add_tree(self, package: str, folder: Path) -> None:
        for path in sorted(folder.rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
            is_package = parts[-1] == "__init__"
            if is_package:
                parts.pop()
            name = ".".join(parts)
            self.modules[name] = Module(name, path, is_package)

    def add_package(self, package: str) -> bool:
        """Add an outside top-level package (a plugin's), located by the import system;
        False if it has no source files to read (then its rows depend on its name only)."""
        if package in self.modules:
            return True
        try:
            spec = importlib.util.find_spec(package)
        except (ImportError, ValueError):
            return False
        if spec is None or spec.origin in (None, "built-in", "frozen"):
            return False
        origin = Path(spec.origin)
        if spec.submodule_search_locations:
            self._add_tree(package, origin.parent)
        elif origin.suffix == ".py":
            self.modules[package] = Module(package, origin, False)
        else:
            return False
        self._link()
        return True

    def _resolve_base(self, mod: Module, node: ast.ImportFrom) -> str:
        base = node.module or ""
        if node.level:
            parts = mod.name.split(".")
            anchor = parts if mod.is_package else parts[:-1]
            anchor = anchor[: len(anchor) - (node.level - 1)]
            base = ".".join([*anchor, *([base] if base else [])])
        return base

    def _link(self) -> None:
        self._closure.clear()
        pending: list[tuple[Module, ast.Module]] = []
        for mod in self.modules.values():
            if mod.digest:
                continue
            tree = ast.parse(mod.path.read_text(encoding="utf-8"), filename=str(mod.path))
            mod.defined = _defined(tree)
            pending.append((mod, tree))
        for mod, tree in pending:  # re-exports first: ``from P import x`` resolves through them
            for node, top in _imports(tree):
                if top and isinstance(node, ast.ImportFrom):
                    base = self._resolve_base(mod, node)
                    for alias in node.names:
                        if alias.name != "*":
                            mod.reexports[alias.asname or alias.name] = (base, alias.name)
        for mod, tree in pending:
            for node, _ in _imports(tree):
                if isinstance(node, ast.Import):
                    for alias in node.names:
                        target = self._known(alias.name)
                        if target:
                            mod.deep.add(target)
                    continue
                base = self._resolve_base(mod, node)
                for alias in node.names:
                    self._depend(mod, base, alias.name)
            mod.deep.discard(mod.name)
            mod.shallow -= mod.deep | {mod.name}
            mod.digest = tree_digest(tree)  # last: it strips the docstrings of ``tree``

    def _known(self, name: str) -> str | None:
        """``name`` or its nearest enclosing package that is in the graph, None if outside."""
        parts = name.split(".")
        while parts:
            candidate = ".".join(parts)
            if candidate in self.modules:
                return candidate
            parts.pop()
        return None

    def _depend(self, mod: Module, base: str, name: str, seen: frozenset = frozenset()) -> None:
        """Record what ``from base import name`` in ``mod`` depends on."""
        if f"{base}.{name}" in self.modules:
            mod.deep.add(f"{base}.{name}")
            return
        if base not in self.modules:
            target = self._known(base)
            if target:
                mod.deep.add(target)
            return
        owner = self.modules[base]
        if name in owner.reexports and name not in owner.defined and base not in seen:
            mod.shallow.add(base)
            src, src_name = owner.reexports[name]
            self._depend(mod, src, src_name, seen | {base})
        else:
            mod.deep.add(base)

    # -- queries ------------------------------------------------------------------------------
    def closure(self, name: str) -> frozenset[str]:
        """Every module whose code ``name`` depends on, ``name`` included."""
        if name not in self._closure:
            deep: set[str] = set()
            stack = [name]
            while stack:
                cur = stack.pop()
                if cur in deep or cur not in self.modules:
                    continue
                deep.add(cur)
                stack.extend(self.modules[cur].deep)
            shallow = {s for m in deep for s in self.modules[m].shallow}
            self._closure[name] = frozenset(deep | shallow)
        return self._closure[name]

    def digests(self, names) -> dict[str, str]:
        """``{module: digest}`` for the modules of the graph among ``names``."""
        return {n: self.modules[n].digest for n in sorted(names) if n in self.modules}

    def source_path(self, name: str) -> str:
        """The module's file, relative to the project root where it is under it."""
        path = self.modules[name].path
        try:
            return path.relative_to(self.root).as_posix()
        except ValueError:
            return str(path)
