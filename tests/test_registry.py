"""Registry, plugin discovery, options and the step/run interface."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import observers
import systems
from observers import registry
from observers.families import PropagationObserver


def test_available_lists_names_with_family_set_and_timing():
    infos = {i.name: i for i in observers.available()}
    assert {"FRad-A", "FRad-B", "FRad-C"} <= set(infos)
    assert infos["FRad-A"].family == "strip" and infos["FRad-A"].timing == "in time"
    assert infos["FRad-C"].family == "propagation"
    assert infos["FRad-C"].timing == "ready for control"
    assert infos["FRad-B"].set_type == "zonotope"
    names = observers.names()
    assert names.index("FRad-A") < names.index("FRad-B") < names.index("FRad-C")


def test_unknown_observer_suggests_close_names():
    with pytest.raises(observers.UnknownObserver, match="did you mean 'FRad-A'"):
        observers.get("frad-a")
    with pytest.raises(observers.UnknownObserver, match="'FRad-B'"):
        observers.get("FRad-BB")


def test_unknown_and_invalid_options():
    s = systems.vehicle(2)
    with pytest.raises(observers.OptionError, match="unknown option.*ordr.*accepted: order"):
        observers.create("FRad-A", s, ordr=3)
    with pytest.raises(observers.OptionError, match="order must be a finite number >= 1, got -2"):
        observers.create("FRad-A", s, order=-2)
    with pytest.raises(observers.OptionError, match="reduction must be one of 'girard', 'pca'"):
        observers.create("FRad-A", s, reduction="best")
    with pytest.raises(observers.OptionError, match="variant"):
        observers.create("FRad-B", s, variant="matlab")


def test_step_interface_and_measurement_checks():
    sc = systems.scenario("vehicle2d-cora")
    obs = observers.create("FRad-A", sc.system, **sc.options)
    S0 = obs.step(None, sc.y[0])
    S1 = obs.step(sc.u[0], sc.y[1])
    assert S0.dim == 2 and S1.num_generators >= 2
    with pytest.raises(observers.MeasurementError, match="non-finite measurement"):
        obs.step(sc.u[1], [np.nan])
    with pytest.raises(observers.MeasurementError, match="2 entries, expected 1"):
        obs.step(sc.u[1], [0.0, 1.0])
    with pytest.raises(observers.MeasurementError, match=r"y\[3, 0\] is not finite"):
        y = sc.y.copy()
        y[3, 0] = np.inf
        observers.run(obs, sc.u, y)
    with pytest.raises(observers.MeasurementError, match=r"inputs u must have shape"):
        observers.run(obs, sc.u[:10], sc.y)


def test_run_restarts_and_is_deterministic():
    sc = systems.scenario("vehicle2d-cora")
    obs = observers.create("FRad-B", sc.system, **sc.options)
    a = observers.run(obs, sc.u, sc.y)
    b = observers.run(obs, sc.u, sc.y)
    np.testing.assert_array_equal(a.lo, b.lo)
    assert a.status == "ok" and len(a.sets) == sc.N and np.all(a.step_times > 0)


def test_divergence_is_reported_not_raised():
    sc = systems.scenario("vehicle2d-cora")

    @observers.register("Test-Unstable", family="propagation", set_type="zonotope",
                        ready_for_control=True)
    class Unstable(PropagationObserver):
        """Propagation with a destabilising gain (test only)."""

        def gain(self, c, G):
            return np.array([[-50.0], [-50.0]])

    try:
        res = observers.run(observers.create("Test-Unstable", sc.system), sc.u, sc.y)
        assert res.status == "diverged" and res.failed_step is not None
        assert np.isnan(res.lo[-1]).all()
    finally:
        registry.unregister("Test-Unstable")


def test_an_exploding_hull_diverges_at_the_growth_bound_before_1e12():
    # a set doubling every step from radius 1 (bounds far below 1e12 when it passes 1e7): the
    # run stops at the first step whose radius exceeds GROWTH_BOUND = 1e7 times the first,
    # 2^k > 1e7 <=> k >= 24 (2^23 = 8.4e6, 2^24 = 1.7e7)
    from observers.base import GROWTH_BOUND
    from observers.sets import Interval

    class Doubling:
        def step(self, u_prev, y):
            self.k = getattr(self, "k", -1) + 1
            return Interval([-(2.0 ** self.k)], [2.0 ** self.k])

    res = observers.run(Doubling(), np.zeros((40, 0)), np.zeros((40, 1)))
    assert GROWTH_BOUND == 1e7
    assert res.status == "diverged" and res.failed_step == 24, res.message
    assert "grew" in res.message and np.isnan(res.lo[24:]).all() and res.lo[23, 0] == -2.0**23


def test_a_pinned_first_estimate_is_no_scale_of_growth():
    # bug: a vertex realisation pins the first estimate to 1e-13 (X0's vertex seen by an
    # exact-looking measurement); the next hulls grow to the noise level, 0.1, which is 1e12
    # times the first but a hundredth of X0's radius 10: not a divergence.  The scale is the
    # larger of X0's largest radius and the first hull's
    from types import SimpleNamespace

    from observers.sets import Interval, Zonotope

    class Pinned:
        system = SimpleNamespace(X0=Zonotope([0.0], [[10.0]]))

        def step(self, u_prev, y):
            self.k = getattr(self, "k", -1) + 1
            r = 1e-13 if self.k == 0 else 0.1
            return Interval([-r], [r])

    res = observers.run(Pinned(), np.zeros((10, 0)), np.zeros((10, 1)))
    assert res.status == "ok", res.message


def test_entry_point_plugins_are_discovered(monkeypatch):
    class FakeEP:
        name = "my-plugin"
        value = "my_plugin"

        def load(self):
            @observers.register("Plugin-Obs", family="strip", set_type="zonotope",
                                ready_for_control=False, reference="test")
            class PluginObs(observers.Observer):
                """A plugin observer returning X0."""

                def step(self, u_prev, y):
                    return self.system.X0

            return PluginObs

    class BrokenEP:
        name = "broken"
        value = "nothing"

        def load(self):
            raise ImportError("no module named nothing")

    groups = {registry.ENTRY_POINT_GROUP: [FakeEP(), BrokenEP()]}
    monkeypatch.setattr(registry, "entry_points", lambda group: groups.get(group, []))
    monkeypatch.setattr(registry, "_loaded", False)
    try:
        with pytest.warns(UserWarning, match="broken"):
            names = observers.names()
        assert "Plugin-Obs" in names
        sc = systems.scenario("vehicle2d-cora")
        res = observers.run(observers.create("Plugin-Obs", sc.system), sc.u, sc.y)
        assert res.status == "ok"
    finally:
        registry.unregister("Plugin-Obs", missing_ok=True)


def test_duplicate_names_are_rejected():
    with pytest.raises(observers.ObserverError, match="already registered"):
        @observers.register("FRad-A", family="strip", set_type="zonotope",
                            ready_for_control=False)
        class Other(observers.Observer):
            def step(self, u_prev, y):
                return None


def test_system_attributes_are_checked():
    with pytest.raises(observers.Unsupported, match="missing: A, B"):
        observers.create("FRad-A", SimpleNamespace(C=1, W=1, V=1, X0=1))


def test_an_empty_estimate_ends_the_run_with_status_empty():
    from observers.sets import ConZonotope

    sc = systems.scenario("vehicle2d-cora")

    @observers.register("Test-Empty", family="strip", set_type="conzonotope",
                        ready_for_control=False)
    class EmptyObs(observers.Observer):
        """Returns an infeasible constrained zonotope from step 3 on (test only)."""

        def step(self, u_prev, y):
            self.k += 1
            b = [0.0] if self.k < 4 else [2.0]  # xi = 2 is outside the unit box
            return ConZonotope([0.0, 0.0], np.eye(2), [[1.0, 0.0]], b)

    try:
        res = observers.run(observers.create("Test-Empty", sc.system), sc.u, sc.y)
        assert res.status == "empty" and res.failed_step == 3
        assert "empty" in res.message and np.isnan(res.lo[3:]).all()
    finally:
        registry.unregister("Test-Empty")


def test_unregister_removes_a_name_and_frees_it():
    from observers.builtin.frad import FRadA

    @observers.register("Test-Gone", family="strip", set_type="zonotope",
                        ready_for_control=False)
    class Gone(FRadA):
        """FRad-A under another name (test only)."""

    assert "Test-Gone" in observers.names()
    info = observers.unregister("Test-Gone")
    assert info.cls is Gone and "Test-Gone" not in observers.names()
    with pytest.raises(observers.UnknownObserver, match="unknown observer 'Test-Gone'"):
        observers.unregister("Test-Gone")
    assert observers.unregister("Test-Gone", missing_ok=True) is None

    @observers.register("Test-Gone", family="strip", set_type="zonotope",
                        ready_for_control=False)
    class Other(FRadA):  # the name is free for another class
        """Another class under the freed name (test only)."""

    try:
        assert observers.get("Test-Gone").cls is Other
    finally:
        observers.unregister("Test-Gone")
