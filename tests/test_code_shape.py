"""The shape of the code a reader meets: no function longer than :data:`MAX_LINES` lines
(the compiled kernels numba needs in one piece, listed in :data:`COMPILED_IN_ONE_PIECE`,
aside) and at most :data:`MAX_MANY_PARAMETERS` functions with :data:`MANY_PARAMETERS` or more
parameters (``self``/``cls`` not counted): related values travel as one parameter object.

Read from the source with :mod:`ast`; ``python tests/test_code_shape.py`` lists the offenders.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("observers", "systems", "benchmarks")
MAX_LINES = 100
MANY_PARAMETERS = 8
MAX_MANY_PARAMETERS = 15
#: functions that numba compiles as one piece (a loop whose state lives in local arrays;
#: split, every part would pay a call with a dozen array arguments per pivot)
COMPILED_IN_ONE_PIECE = {("observers/lp/dual_simplex_jit.py", "_iterate_py")}


def functions() -> list[tuple[str, str, int, int]]:
    """``(path, name, parameters, lines)`` of every function and method of the packages."""
    out = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    a = node.args
                    k = (len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs)
                         + (a.vararg is not None) + (a.kwarg is not None))
                    first = (a.posonlyargs + a.args)[:1]
                    if first and first[0].arg in ("self", "cls"):
                        k -= 1
                    out.append((rel, node.name, k, node.end_lineno - node.lineno + 1))
    return out


def test_the_census_reads_parameters_and_lines():
    found = {(p, n): (k, lines) for p, n, k, lines in functions()}
    # def check_order(order: float) -> None: a docstring and four lines of body
    assert found[("observers/sets/reduction.py", "check_order")] == (1, 6)


def test_no_function_over_the_length_limit():
    long = [f"{p}:{n} ({lines} lines)" for p, n, _, lines in functions()
            if lines > MAX_LINES and (p, n) not in COMPILED_IN_ONE_PIECE]
    assert long == []


def test_few_functions_with_many_parameters():
    many = sorted(f"{p}:{n} ({k})" for p, n, k, _ in functions() if k >= MANY_PARAMETERS)
    assert len(many) <= MAX_MANY_PARAMETERS, "\n".join(many)


if __name__ == "__main__":  # pragma: no cover - a tool for a reader
    for p, n, k, lines in functions():
        if k >= MANY_PARAMETERS or lines > MAX_LINES:
            print(f"{p}:{n}: {k} parameters, {lines} lines")
