"""Shared fixtures: reference data, and an isolated design cache per test session; the
``--order-seed`` option that runs the suite in a shuffled order (``make test`` passes a new
seed every run and the header prints it, so that a failure that depends on the order is
seen, and can be repeated with the same seed); the compiled kernels loaded once before the
tests start (compiled on a cold numba cache, as in a fresh CI checkout), so that no test's
budget and no worker pays for their compilation; and the documentation site built in a
background process from the start of the session (:func:`site_build`), on the core the
kernels' compilation leaves idle."""

from __future__ import annotations

import importlib.util
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from itertools import groupby
from pathlib import Path

import pytest
import yaml

import benchmarks  # noqa: F401  (pins the BLAS threads and kernels before tests load numpy)

DATA = Path(__file__).parent / "data"


def pytest_addoption(parser):
    parser.addoption("--order-seed", type=int, default=None, metavar="N",
                     help="run the test modules, and the tests within each module, in an "
                          "order shuffled by seed N (default: the order of the files)")


#: seconds the kernels took to load (or compile) before the tests, for the header
_WARM_SECONDS: list[float] = []


#: the environment variable naming the folder of the site built in the background
SITE_ENV = "SETOBS_TEST_SITE"
#: the site's build: ``-W`` as ``make docs``; writes ``exit-code`` (the build's exit code, or
#: the exception that ended it) when it ends, whatever happened
_SITE_BUILD = """
import sys
from pathlib import Path
root, docs = Path(sys.argv[1]), sys.argv[2]
try:
    from sphinx.cmd.build import build_main
    code = build_main(["-W", "--keep-going", "-q", "-b", "html", docs, str(root / "html"),
                       "-d", str(root / "doctrees")])
except BaseException as exc:
    code = repr(exc)
(root / "exit-code").write_text(str(code))
"""
_SITE: list = []


def _wants_site(config) -> bool:
    """Whether the session runs the built-site tests (``tests/test_docs.py``, or a folder
    holding it): only then is the site built in the background."""
    docs = Path(__file__).resolve().parent / "test_docs.py"
    for arg in config.args:
        path = Path(config.invocation_params.dir, arg.split("::")[0]).resolve()
        if path == docs or path in docs.parents:
            return True
    return False


def _start_site_build(config) -> None:
    """Start building the documentation site in a background process (controller only);
    its folder is passed to the workers in :data:`SITE_ENV` (set before they start)."""
    if not _wants_site(config) or any(importlib.util.find_spec(m) is None
                                      for m in ("sphinx", "numpydoc")):
        return  # test_docs builds it itself, or skips the built-site tests and says why
    root = Path(tempfile.mkdtemp(prefix="setobs-test-site-"))
    log = (root / "build.log").open("w")
    proc = subprocess.Popen([sys.executable, "-c", _SITE_BUILD, str(root),
                             str(Path(__file__).resolve().parents[1] / "docs")],
                            stdout=log, stderr=subprocess.STDOUT)
    log.close()
    os.environ[SITE_ENV] = str(root)
    _SITE.append((proc, root))


def site_build() -> tuple[int | str, Path] | None:
    """``(exit code, html folder)`` of the site built in the background since the start of
    the session (waiting for it to end), or None where none was started (no ``make test``
    controller: the caller builds it itself).  A failed build prints its log's tail."""
    root = os.environ.get(SITE_ENV)
    if not root:
        return None
    marker = Path(root) / "exit-code"
    while not marker.exists():  # the builder always writes it (a crash too)
        time.sleep(0.5)
    text = marker.read_text().strip()
    code: int | str = int(text) if text.lstrip("-").isdigit() else text
    if code != 0:
        print((Path(root) / "build.log").read_text(errors="replace")[-4000:])
    return code, Path(root) / "html"


def pytest_sessionfinish(session):
    """The controller ends the site's build if it still runs and removes its folder."""
    for proc, root in _SITE:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        shutil.rmtree(root, ignore_errors=True)


def pytest_sessionstart(session):
    """Load the compiled kernels (:func:`benchmarks.run.warmup.warm`) once, in the
    controller before the xdist workers start (or in the only process): on a cold numba cache
    they are compiled here, once, into the cache every worker and every subprocess then
    loads, instead of by each worker under a test's budget (a 20-step FRad-A job took
    137 s cold on the 2-core machine, and a test's fixed 300 s budget was once exceeded)."""
    if hasattr(session.config, "workerinput"):  # an xdist worker: its controller did it
        return
    _start_site_build(session.config)  # on the other core meanwhile
    from benchmarks.run.warmup import warm

    # one process: the documentation site is built beside it (with the two shares of
    # warm(parallel=True) as well, three processes on two cores, the warm-up took 4.5 min in
    # CI instead of 3.5)
    _WARM_SECONDS.append(warm())


def pytest_report_header(config):
    lines = [f"compiled kernels ready in {_WARM_SECONDS[0]:.1f} s (minutes: a cold numba cache)"
             ] if _WARM_SECONDS else []
    seed = config.getoption("order_seed")
    if seed is not None:
        lines.append(f"test order: shuffled with --order-seed {seed}")
    return lines


def shuffled(items: list, seed: int) -> list:
    """``items`` (collected tests) in an order drawn from ``seed``: the modules shuffled,
    and the tests within each module (a module's tests stay together, so that its fixtures
    of module scope are built once, as in file order)."""
    rng = random.Random(seed)
    modules = [list(group) for _, group in groupby(items, key=lambda i: i.nodeid.split("::")[0])]
    rng.shuffle(modules)
    for tests in modules:
        rng.shuffle(tests)
    return [item for tests in modules for item in tests]


def heavy_first(items: list) -> list:
    """``items`` with the tests marked ``heavy`` (30 s or more) first, each part in its own
    order: under xdist's work stealing the heavy tests then run while the light ones fill the
    other worker, and the session does not end with one worker running a heavy test alone
    (a 2-minute test drawn last idled a core of CI for its whole length)."""
    heavy = [i for i in items if i.get_closest_marker("heavy")]
    return heavy + [i for i in items if not i.get_closest_marker("heavy")]


def pytest_collection_modifyitems(config, items):
    seed = config.getoption("order_seed")
    if seed is not None:  # every xdist worker gets the same seed: the same order
        items[:] = shuffled(items, seed)
    items[:] = heavy_first(items)


@pytest.fixture(autouse=True, scope="session")
def _isolated_design_cache(tmp_path_factory):
    """Never read designs cached by earlier runs or by `make bench`."""
    mp = pytest.MonkeyPatch()
    mp.setenv("SETOBS_CACHE_DIR", str(tmp_path_factory.mktemp("design-cache")))
    yield
    mp.undo()


@pytest.fixture(autouse=True)
def _small_proof_audit(monkeypatch):
    """The gate proves an observer that got tighter by the short audit, which holds it to the
    exact floor of long records (a minute of LPs on the 6-D vehicle); a test of the gate's
    mechanism proves it on the small 2-D record only (CI's ``make check`` and
    ``make audit-short`` run the real scenario list)."""
    from benchmarks.gate import policy

    monkeypatch.setattr(policy, "PROOF_SCENARIOS", ("alamo2d-sim",))


@pytest.fixture(scope="session")
def cora_refs() -> dict:
    """CORA's stored reference results."""
    return yaml.safe_load((DATA / "cora_reference_results.yaml").read_text())


@pytest.fixture(scope="session")
def cora_vehicle2d_refs(cora_refs) -> dict:
    """Final interval hulls of CORA's 2-D vehicle unit test (testLong + testSDPT3)."""
    out = dict(cora_refs["linearSysDT/testLong_linearSysDT_observe_01_vehicle.m"])
    out.update(cora_refs["linearSysDT/testSDPT3_linearSysDT_observe_01_vehicle.m"])
    return out


def paper_table(key: str) -> dict:
    """A shipped paper table."""
    from importlib import resources

    path = resources.files("systems") / "data" / "paper_tables" / f"{key}.yaml"
    return yaml.safe_load(path.read_text())
