"""The on-disk design cache and the offline-gain mixin."""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from observers import registry
from observers.errors import DesignFailed
from observers.families import ConstantGainPropagationObserver
from observers.offline import OfflineGain, cached_design, design_key


def test_cache_hits_and_remembers_failures(tmp_path, monkeypatch):
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path))
    calls = []

    def compute():
        calls.append(1)
        return {"gain": np.array([[1.0], [2.0]])}

    a = cached_design("K", "1", {"A": np.eye(2)}, {"beta": 0.5}, compute)
    b = cached_design("K", "1", {"A": np.eye(2)}, {"beta": 0.5}, compute)
    np.testing.assert_array_equal(a["gain"], b["gain"])
    assert len(calls) == 1
    cached_design("K", "1", {"A": 2 * np.eye(2)}, {"beta": 0.5}, compute)  # new key
    cached_design("K", "2", {"A": np.eye(2)}, {"beta": 0.5}, compute)  # new version
    assert len(calls) == 3

    def infeasible():
        calls.append(1)
        raise DesignFailed("LMI infeasible")

    for _ in range(2):
        with pytest.raises(DesignFailed, match="LMI infeasible"):
            cached_design("K", "1", {"A": np.eye(3)}, {}, infeasible)
    assert len(calls) == 4
    assert design_key("K", "1", {"A": np.eye(2)}, {}) != design_key("K", "1", {"A": np.eye(2)},
                                                                        {"x": 1})


def test_offline_gain_mixin_uses_given_gain_or_design():
    @observers.register("Test-Offline", family="propagation", set_type="zonotope",
                        ready_for_control=True)
    class TestOffline(OfflineGain, ConstantGainPropagationObserver):
        """Constant gain from a trivial 'design' (test only)."""

        def design_gain(self):
            return np.array([[0.01], [0.02]])

    try:
        s = systems.vehicle(2)
        np.testing.assert_array_equal(observers.create("Test-Offline", s).L,
                                      [[0.01], [0.02]])
        np.testing.assert_array_equal(
            observers.create("Test-Offline", s, gain=[0.5, 0.6]).L, [[0.5], [0.6]])
        with pytest.raises(observers.OptionError, match=r"gain must have shape \(2, 1\)"):
            observers.create("Test-Offline", s, gain=np.ones((3, 1)))
        with pytest.raises(observers.OptionError,
                           match="gain must be a numeric vector or matrix with finite entries"):
            observers.create("Test-Offline", s, gain=[np.nan, 1.0])
    finally:
        registry.unregister("Test-Offline")
