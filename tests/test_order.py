"""The shuffled order of ``make test`` (``--order-seed``, tests/conftest.py)."""

from __future__ import annotations

from dataclasses import dataclass

from tests.conftest import shuffled


@dataclass
class _Item:
    nodeid: str


def _items() -> list[_Item]:
    return [_Item(f"tests/test_{m}.py::test_{t}") for m in "abcde" for t in range(6)]


def test_a_seed_gives_one_order_and_keeps_every_test():
    items = _items()
    first, again = shuffled(items, 7), shuffled(list(items), 7)
    assert [i.nodeid for i in first] == [i.nodeid for i in again]  # every xdist worker agrees
    assert sorted(i.nodeid for i in first) == sorted(i.nodeid for i in items)
    orders = {tuple(i.nodeid for i in shuffled(items, seed)) for seed in range(20)}
    assert len(orders) > 1  # the seed changes the order


def test_the_tests_of_a_module_stay_together():
    for seed in range(20):
        modules = [i.nodeid.split("::")[0] for i in shuffled(_items(), seed)]
        runs = [m for k, m in enumerate(modules) if k == 0 or modules[k - 1] != m]
        assert len(runs) == len(set(modules)), seed
