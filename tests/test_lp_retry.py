"""Membership LPs that HiGHS ends without a verdict are retried (observed on the 30-tank
record, where presolve + dual simplex stopped with status "Not Set" on generators spanning
1e-39 to 3 and a true state inside the set was reported outside)."""

from __future__ import annotations

import highspy
import numpy as np

from observers.sets import Zonotope


def test_undecided_membership_lp_is_retried(monkeypatch):
    real = highspy.Highs.getModelStatus
    calls = []

    def first_undecided(self):
        calls.append(1)
        return highspy.HighsModelStatus.kNotset if len(calls) == 1 else real(self)

    monkeypatch.setattr(highspy.Highs, "getModelStatus", first_undecided)
    Z = Zonotope([0.0, 0.0], [[1.0, 1.0, 0.0], [0.0, 1.0, 1.0]])
    assert Z.contains([1.5, 1.5])
    assert len(calls) == 2
    calls.clear()
    assert not Z.contains([2.0, -2.0])  # inside the hull, outside the zonotope
    assert len(calls) == 2


def test_membership_is_unchanged_on_ordinary_sets():
    rng = np.random.default_rng(0)
    Z = Zonotope([1.0, -1.0], rng.normal(size=(2, 6)))
    inside = Z.sample(50, rng)
    assert all(Z.contains(x, tol=1e-9) for x in inside)
    far = Z.c + 1.01 * np.abs(Z.G).sum(axis=1)
    assert not Z.contains(far)
