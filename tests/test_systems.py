"""System generators against CORA's printed matrices, validation, simulation and scenarios."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

import systems
from observers.sets import Zonotope
from systems import LinearSystem, ModelError, simulate, tank, vehicle

from .conftest import DATA


@pytest.fixture(scope="module")
def cora_vehicle():
    return yaml.safe_load((DATA / "cora_vehicle_matrices.yaml").read_text())


@pytest.mark.parametrize("dim", [2, 6])
def test_vehicle_matches_cora_printed_matrices(cora_vehicle, dim):
    ref = cora_vehicle[f"dim{dim}"]
    s = vehicle(dim)
    np.testing.assert_allclose(s.A, ref["A"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.B, ref["B"], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(s.C, ref["C"])


def test_vehicle_coefficients_match_cora(cora_vehicle):
    from systems.vehicle import continuous_matrices

    Ac, Bc, _ = continuous_matrices(6)
    p = cora_vehicle["derived_parameter_values"]
    np.testing.assert_allclose(
        [Ac[0, 0], Ac[0, 1], Ac[1, 0], Ac[1, 1], Ac[0, 4], Ac[1, 4], Ac[5, 0], Ac[5, 1],
         Ac[5, 4], Ac[5, 5], Bc[5, 0]],
        [p[k] for k in ("a11", "a12", "a21", "a22", "b11", "b12", "a61", "a62", "a65", "a66",
                        "b16")], rtol=1e-13)


def test_vehicle4_and_sets():
    s = vehicle(4)
    assert (s.n, s.nu, s.ny) == (4, 1, 3)
    np.testing.assert_allclose(s.W.interval().hi, [0.005, 0.055, 0.005, 0.04])
    with pytest.raises(ModelError, match="2, 4 or 6"):
        vehicle(3)


def test_tank6_linearisation_equals_cora():
    ref = yaml.safe_load((DATA / "cora_tank6.yaml").read_text())
    s = tank(6)
    np.testing.assert_array_equal(s.A, ref["A"])
    np.testing.assert_array_equal(s.B, ref["B"])
    np.testing.assert_array_equal(s.C, ref["C"])


def test_tank30_structure_equals_cora_example():
    cora = systems.scenario("tank30-linear-cora").system
    s = tank(30)
    np.testing.assert_array_equal(s.C, cora.C)  # measured tanks of ARCH Table 2
    np.testing.assert_array_equal(s.B != 0, cora.B != 0)  # inflow pattern
    np.testing.assert_array_equal(s.B, cora.B)  # 0.5, 0.033 and 1.0 entries
    np.testing.assert_array_equal(s.A != 0, cora.A != 0)


def test_tank_any_n_ignores_indices_beyond_n():
    s = tank(12)
    assert s.nu == 6 and s.ny == 7  # inflow 1,4,5,7,9,10; measured 2,4,5,7,8,10,11
    assert tank(40).n == 40


def test_nonlinear_tank_jacobian_matches_finite_differences():
    s = tank(6, linear=False)
    x, u = np.full(6, 20.0) + np.arange(6), np.full(3, 0.1)
    J, Bu = s.jacobian(x, u)
    eps = 1e-6
    Jn = np.column_stack([(s.f(x + eps * e, u) - s.f(x - eps * e, u)) / (2 * eps)
                          for e in np.eye(6)])
    np.testing.assert_allclose(J, Jn, atol=1e-8)


def test_cora_nonlinear_tank_record_is_consistent_with_the_model():
    # CORA's 20-step unit-test measurements must be explainable by our nonlinear model:
    # y = C x + v with |v| <= 0.2 for a state trajectory started in X0 -> check levels ~ 20
    ref = yaml.safe_load((DATA / "cora_tank6.yaml").read_text())
    y = np.array(ref["nonlinear_unit_test_y_20"])
    assert y.shape == (3, 20) and np.all(np.abs(y - 20) < 4.5)


def test_linear_system_validation_messages():
    Z2 = Zonotope.box([1.0, 1.0])
    with pytest.raises(ModelError, match="A must be square"):
        LinearSystem(np.ones((2, 3)), np.ones((2, 1)), np.ones((1, 2)), Z2,
                     Zonotope.box([1.0]), Z2)
    with pytest.raises(ModelError, match=r"B has shape \(3, 1\)"):
        LinearSystem(np.eye(2), np.ones((3, 1)), np.ones((1, 2)), Z2, Zonotope.box([1.0]), Z2)
    with pytest.raises(ModelError, match="C has shape"):
        LinearSystem(np.eye(2), np.ones((2, 1)), np.ones((1, 3)), Z2, Zonotope.box([1.0]), Z2)
    with pytest.raises(ModelError, match="A contains non-finite"):
        LinearSystem(np.array([[np.nan, 0], [0, 1]]), np.ones((2, 1)), np.ones((1, 2)), Z2,
                     Zonotope.box([1.0]), Z2)
    with pytest.raises(ModelError, match="W must contain the origin"):
        LinearSystem(np.eye(2), np.ones((2, 1)), np.ones((1, 2)), Zonotope.box([1, 1], [3, 0]),
                     Zonotope.box([1.0]), Z2)
    with pytest.raises(ModelError, match="V has dimension 2, expected 1"):
        LinearSystem(np.eye(2), np.ones((2, 1)), np.ones((1, 2)), Z2, Z2, Z2)


def test_observability_and_detectability():
    s = tank(6)  # tank 6 is neither measured nor feeds a measured tank
    assert not s.is_observable() and s.is_detectable()
    np.testing.assert_allclose(s.unobservable_modes(), [0.996])
    assert vehicle(6).is_observable()
    unstable = s.replace(A=np.diag([1.0, 1.0, 1.0, 1.0, 1.0, 1.01]))
    with pytest.raises(ModelError, match="not detectable"):
        unstable.require_detectable("Nom-G")


def test_simulation_is_seeded_and_noise_stays_in_its_sets():
    s = vehicle(2)
    u = np.zeros((50, 1))
    a, b = simulate(s, u, seed=3), simulate(s, u, seed=3)
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.array_equal(a.y, simulate(s, u, seed=4).y)
    for noise in ("uniform", "gaussian-truncated", "vertex"):
        sim = simulate(s, u, seed=1, noise=noise)
        w = sim.x_true[1:] - sim.x_true[:-1] @ s.A.T - u[:-1] @ s.B.T
        v = sim.y - sim.x_true @ s.C.T
        assert np.all(np.abs(w) <= s.W.interval().hi + 1e-12)
        assert np.all(np.abs(v) <= 0.1 + 1e-12)
        assert s.X0.contains(sim.x_true[0])
    with pytest.raises(ModelError, match="unknown noise model"):
        simulate(s, u, noise="laplace")


@pytest.mark.parametrize("name", systems.scenario_names())
def test_scenarios_have_consistent_shapes(name):
    sc = systems.scenario(name)
    s = sc.system
    assert sc.y.shape == (sc.N, s.ny) and sc.u.shape[1] == s.nu
    if sc.x_true is not None:
        assert sc.x_true.shape == (sc.N, s.n)
    assert len(sc.state_names) == s.n


def test_shipped_records_are_consistent_with_their_models():
    for name in ("vehicle6d-cora", "tank30-linear-cora"):
        sc = systems.scenario(name)
        s = sc.system
        v = sc.y - sc.x_true @ s.C.T
        w = sc.x_true[1:] - sc.x_true[:-1] @ s.A.T - sc.u[: sc.N - 1] @ s.B.T
        rounding = 1e-3 * (1 + np.abs(s.A).sum(axis=1).max())
        assert np.all(np.abs(v) <= s.V.interval().hi + 1e-3 * np.abs(s.C).sum(axis=1).max())
        assert np.all(np.abs(w) <= s.W.interval().hi + rounding)


def test_unknown_scenario_lists_the_known_ones():
    with pytest.raises(ModelError, match="unknown scenario 'vehicel6d-cora'.*vehicle6d-cora"):
        systems.scenario("vehicel6d-cora")


def test_systems_never_imports_observer_plugins():
    code = ("import sys, systems; systems.scenario('vehicle2d-cora'); "
            "bad = [m for m in sys.modules if m.startswith('observers.') and "
            "not m.startswith(('observers.sets', 'observers.lp', 'observers.kernels')) and "
            "m not in ('observers.base', 'observers.errors', 'observers.options', "
            "'observers.registry')]; "
            "print(bad); assert not bad")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
