"""Shared fixtures: reference data, and an isolated design cache per test session; the
``--order-seed`` option that runs the suite in a shuffled order (``make test`` passes a new
seed every run and the header prints it, so that a failure that depends on the order is
seen, and can be repeated with the same seed)."""

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


def pytest_report_header(config):
    seed = config.getoption("order_seed")
    return f"test order: shuffled with --order-seed {seed}" if seed is not None else None


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
