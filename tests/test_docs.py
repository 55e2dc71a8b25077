"""The documentation site builds without a warning (``sphinx -W``, as ``make docs``), every
observer page shows its step as typeset equations (MathML made at build time, no script from the
network), and every code example of the site and of the README is executed:

* Python blocks run, page by page, in a fresh interpreter in an empty folder (each block in its
  own namespace, in the order of the page); the "your own system" example must run every
  registered observer with no containment violation;
* YAML blocks are loaded, and those that are configurations are validated and their scenarios
  built (:func:`benchmarks.parse_config`);
* TOML blocks are parsed, CSV samples read as records;
* shell blocks: every ``setobs-bench`` line is parsed by the real argument parser, and the cheap
  ones (``--version``, ``list``, ``index``) are run; ``make`` targets must exist in the Makefile,
  ``python -m`` modules must be importable, other tools (``pip``, ``dask``) must be installed.
  Commands that take many minutes (``make bench``, a paper table) are not run here: CI runs
  ``make test``, ``make check`` and ``make audit-short``, the lead ``make bench``.
"""

from __future__ import annotations

import doctest
import importlib
import importlib.util
import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import tomllib
import yaml

import observers
from benchmarks import parse_config
from benchmarks.cli import build_parser, main
from benchmarks.run.records import read_csv, select
from tests.conftest import site_build

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: pages written by hand (the observer pages and the API reference are generated at build time)
PAGES = sorted(p for p in DOCS.rglob("*.rst")
               if p.relative_to(DOCS).parts[0] not in ("observers", "api", "_build"))
SOURCES = [*PAGES, ROOT / "README.md"]
#: setobs-bench sub-commands cheap enough to run for real
CHEAP = {"--version", "list", "index"}


def _rst_blocks(text: str) -> list[tuple[str, str]]:
    """``(language, code)`` of every ``.. code-block::`` of an RST page."""
    out = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = re.match(r"^(\s*)\.\. code-block:: *(\S+)", lines[i])
        if not m:
            i += 1
            continue
        indent, lang = len(m.group(1)), m.group(2)
        i += 1
        while i < len(lines) and (not lines[i].strip() or lines[i].lstrip().startswith(":")):
            i += 1
        body = []
        while i < len(lines) and (not lines[i].strip() or
                                  len(lines[i]) - len(lines[i].lstrip()) > indent):
            body.append(lines[i])
            i += 1
        code = "\n".join(body).rstrip()
        pad = min(len(x) - len(x.lstrip()) for x in body if x.strip())
        out.append((lang, "\n".join(x[pad:] for x in code.splitlines()) + "\n"))
    return out


def _md_blocks(text: str) -> list[tuple[str, str]]:
    return [(m.group(1) or "text", m.group(2))
            for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, re.S | re.M)]


def blocks(path: Path) -> list[tuple[str, str]]:
    text = path.read_text(encoding="utf-8")
    return _md_blocks(text) if path.suffix == ".md" else _rst_blocks(text)


def _ids(paths):
    return [p.relative_to(ROOT).as_posix() for p in paths]


def test_every_page_is_in_the_site_and_has_examples_parsed():
    found = {lang for p in SOURCES for lang, _ in blocks(p)}
    assert {"python", "sh", "yaml"} <= found
    assert sum(len(blocks(p)) for p in SOURCES) > 25  # the parser found the examples
    index = (DOCS / "index.rst").read_text()
    for page in PAGES:
        rel = page.relative_to(DOCS).with_suffix("").as_posix()
        assert rel == "index" or rel in index, f"{rel} is not in the table of contents"


def test_readme_is_a_front_page_whose_links_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text) < 8000  # the rest lives in the site
    first = text.split("```sh", 1)[1].split("```", 1)[0]
    assert "make bench-quick" in first and "make test" in first  # the two commands first
    links = re.findall(r"\]\(([^)#]+)\)", text)
    assert links and all((ROOT / link).exists() for link in links), links


# -- the build ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """``(exit code, html folder)`` of one build of the site with ``-W`` (as ``make docs``),
    shared by the tests of the built pages: the one the session started in the background
    (``tests/conftest.py``), else one built here."""
    built = site_build()
    if built is not None:
        return built
    sphinx = pytest.importorskip("sphinx.cmd.build",
                                 reason="Sphinx is not installed (pip install -e '.[docs]')")
    pytest.importorskip("numpydoc", reason="numpydoc is not installed (pip install -e '.[docs]')")
    tmp = tmp_path_factory.mktemp("site")
    out = tmp / "html"
    code = sphinx.build_main(["-W", "--keep-going", "-q", "-b", "html", str(DOCS), str(out),
                              "-d", str(tmp / "doctrees")])
    return code, out


@pytest.mark.slow
def test_site_builds_without_warnings(site):
    code, out = site
    assert code == 0
    infos = observers.available()
    for info in infos:  # one page per observer, with its options and where it appears
        page = (out / "observers" / f"{re.sub(r'[^a-z0-9]+', '-', info.name.lower())}.html")
        text = page.read_text(encoding="utf-8")
        assert info.name in text and "Options" in text and "Where it appears" in text
    frad_a = (out / "observers" / "frad-a.html").read_text(encoding="utf-8")
    assert "alamo_frad_gain" in frad_a and "Althoff, ARCH 2021, Table 3" in frad_a
    assert "reports/speed.json" in frad_a and "arch2021_table3" in frad_a
    assert (out / "api" / "benchmarks.report.numbers.html").is_file()
    assert "pca-cora" in (out / "guide" / "papers.html").read_text(encoding="utf-8")


#: a typeset equation of the built site: a MathML element made by docs/_ext/mathml.py (raw
#: LaTeX in a page, as MathJax would leave it for the browser to typeset, does not count)
MATH = re.compile(r'<math xmlns="http://www.w3.org/1998/Math/MathML"[^>]*>(.*?)</math>', re.S)


def typeset_equations(html: str) -> int:
    """Number of MathML formulas of a page that hold at least one token (identifier, number,
    operator): an empty ``<math>`` is not an equation."""
    return sum(1 for m in MATH.finditer(html) if re.search(r"<m[ino][ >]", m.group(1)))


def test_typeset_equations_are_counted_from_the_markup_not_the_latex():
    assert typeset_equations(r'<div class="math">\[x_{k+1} = A x_k\]</div>') == 0
    assert typeset_equations('<math xmlns="http://www.w3.org/1998/Math/MathML"></math>') == 0
    assert typeset_equations('<math xmlns="http://www.w3.org/1998/Math/MathML" display="block">'
                             "<mi>x</mi><mo>=</mo><mn>1</mn></math> and "
                             '<math xmlns="http://www.w3.org/1998/Math/MathML"><mi>A</mi>'
                             "</math>") == 2


@pytest.mark.slow
def test_every_observer_page_shows_its_step_as_typeset_equations(site):
    """Every observer page holds at least one equation typeset as MathML, no page refers to
    a script or style sheet on the network (MathJax from a CDN), and no formula failed to
    convert (it would be printed as LaTeX in a ``math-error`` code span)."""
    _, out = site
    pages = sorted(p for p in (out / "observers").glob("*.html") if p.stem != "index")
    assert len(pages) == len(observers.available())
    counts = {p.stem: typeset_equations(p.read_text(encoding="utf-8")) for p in pages}
    missing = sorted(name for name, n in counts.items() if n == 0)
    assert not missing, f"observer pages without a typeset equation: {', '.join(missing)}"
    for page in out.rglob("*.html"):
        html = page.read_text(encoding="utf-8")
        assert not re.search(r"<(script|link)[^>]+(src|href)=\"(https?:)?//", html), page
        assert not re.search(r"<script[^>]*mathjax", html, re.I), page
        assert 'class="math-error"' not in html, page


# -- Python examples ------------------------------------------------------------------------

RUNNER = r"""
import json, sys, traceback
blocks = json.loads(open(sys.argv[1]).read())
for i, code in enumerate(blocks):
    try:
        where = f"{sys.argv[2]} [python block {i + 1}]"
        exec(compile(code, where, "exec"), {"__name__": "__docs__"})
    except BaseException:
        traceback.print_exc()
        print(f"FAILED python block {i + 1} of {sys.argv[2]}", file=sys.stderr)
        sys.exit(1)
print(f"ran {len(blocks)} blocks")
"""

PY_SOURCES = [p for p in SOURCES if any(lang == "python" for lang, _ in blocks(p))]


@pytest.mark.slow
@pytest.mark.parametrize("path", PY_SOURCES, ids=_ids(PY_SOURCES))
def test_python_examples_run(path, tmp_path):
    code = [c for lang, c in blocks(path) if lang == "python"]
    (tmp_path / "blocks.json").write_text(json.dumps(code))
    (tmp_path / "runner.py").write_text(RUNNER)
    done = subprocess.run([sys.executable, "runner.py", "blocks.json", path.name],
                          cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stderr[-4000:]
    assert f"ran {len(code)} blocks" in done.stdout
    own = tmp_path / "results" / "my-plant"
    if own.is_dir():  # the "your own system" example: every observer, none unsound
        summary = pd.read_csv(own / "summary.csv")
        assert set(summary["observer"]) == {i.name for i in observers.available()}
        ok = summary[summary["guaranteed"] & (summary["status"] == "ok")]
        assert len(ok) and (ok["violations"] == 0).all()
        assert (own / "report.md").is_file() and (own / "index.html").is_file()


# -- configuration, TOML and CSV examples ---------------------------------------------------

DATA_SOURCES = [p for p in SOURCES
                if any(lang in ("yaml", "toml", "text") for lang, _ in blocks(p))]


@pytest.mark.parametrize("path", DATA_SOURCES, ids=_ids(DATA_SOURCES))
def test_data_examples_are_valid(path, tmp_path):
    for lang, code in blocks(path):
        if lang == "yaml":
            raw = yaml.safe_load(code)
            if isinstance(raw, dict) and "scenarios" in raw:
                cfg = parse_config(raw, raw.get("name", "example"), tmp_path)
                assert cfg.scenarios and cfg.observers
        elif lang == "toml":
            tomllib.loads(code)
        elif lang == "text" and "y1" in code.splitlines()[0]:
            (tmp_path / "sample.csv").write_text(code)
            values, note = select(read_csv(tmp_path / "sample.csv", "sample"), "y", "sample")
            assert values.shape[0] >= 2 and "header row" in note


# -- shell examples -------------------------------------------------------------------------

def _make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    return set(re.findall(r"^([a-z][\w-]*):", text, re.M))


def _commands(code: str) -> list[list[str]]:
    out = []
    for line in code.splitlines():
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        words = shlex.split(line, comments=True)
        while words and re.match(r"^[A-Z_]+=", words[0]):  # VAR=value prefixes
            words = words[1:]
        if words:
            out.append(words)
    return out


SH_SOURCES = [p for p in SOURCES if any(lang in ("sh", "bash", "console")
                                        for lang, _ in blocks(p))]


@pytest.mark.parametrize("path", SH_SOURCES, ids=_ids(SH_SOURCES))
def test_shell_examples_are_valid_and_the_cheap_ones_run(path, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports" / "x.md").write_text("# A report\n")
    parser = build_parser()
    targets = _make_targets()
    for lang, code in blocks(path):
        if lang not in ("sh", "bash", "console"):
            continue
        for words in _commands(code):
            cmd, args = words[0], words[1:]
            if cmd == "setobs-bench":
                try:
                    parser.parse_args(args)
                except SystemExit as exc:  # --version and --help exit 0
                    assert exc.code == 0, f"{path.name}: {' '.join(words)}"
                if args and args[0] in CHEAP:
                    try:
                        code_ = main(args)
                    except SystemExit as exc:  # --version
                        code_ = exc.code
                    assert code_ == 0, " ".join(words)
            elif cmd == "make":
                assert set(args) <= targets, f"{path.name}: no make target {args}"
            elif cmd in ("python", "python3") and args[:1] == ["-m"]:
                assert importlib.util.find_spec(args[1]) is not None, " ".join(words)
            elif cmd == "pip":
                assert args[:1] == ["install"]
            elif cmd == "dask":
                pytest.importorskip("distributed")
            else:
                raise AssertionError(f"{path.name}: unknown command in an example: {words}")
    capsys.readouterr()


# -- the docstrings' examples (the API reference) -------------------------------------------

def _api_modules() -> list[str]:
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        import setobs_docs
    finally:
        sys.path.pop(0)
    return [m for m in setobs_docs.api_modules()
            if ">>>" in (ROOT.joinpath(*m.split(".")).with_suffix(".py").read_text()
                         if ROOT.joinpath(*m.split(".")).with_suffix(".py").is_file()
                         else (ROOT.joinpath(*m.split(".")) / "__init__.py").read_text())]


@pytest.mark.parametrize("module", _api_modules())
def test_docstring_examples_run(module):
    mod = importlib.import_module(module)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0 and result.attempted > 0
