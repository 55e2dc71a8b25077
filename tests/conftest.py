"""Shared fixtures: reference data, and an isolated design cache per test session; the
``--order-seed`` option that runs the suite in a shuffled order (``make test`` passes a new
seed every run and the header prints it, so that a failure that depends on the order is
seen, and can be repeated with the same seed); the compiled kernels loaded once before the
tests start (compiled on a cold numba cache, as in a fresh CI checkout), so that no test's
budget and no worker pays for their compilation."""

from __future__ import annotations

import random
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


def pytest_sessionstart(session):
    """Load the compiled kernels (:func:`benchmarks.run.workerinit.warm`) once, in the
    controller before the xdist workers start (or in the only process): on a cold numba cache
    they are compiled here, once, into the cache every worker and every subprocess then
    loads, instead of by each worker under a test's budget (a 20-step FRad-A job took
    137 s cold on the 2-core machine, and a test's fixed 300 s budget was once exceeded)."""
    if hasattr(session.config, "workerinput"):  # an xdist worker: its controller did it
        return
    from benchmarks.run.workerinit import warm

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


def pytest_collection_modifyitems(config, items):
    seed = config.getoption("order_seed")
    if seed is not None:  # every xdist worker gets the same seed: the same order
        items[:] = shuffled(items, seed)


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
