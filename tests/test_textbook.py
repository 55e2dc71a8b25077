"""The six textbook plants (systems/textbook.py) against properties derived by hand from their
equations (CTMS parameters), and the open-loop poles the CTMS bus-suspension page prints."""

from __future__ import annotations

import numpy as np
import pytest

import systems
from systems.textbook import PLANTS, lqr_gain, plant, square_wave, zoh

NAMES = list(PLANTS)


def _dc_gain_continuous(Ac, Bc, C):
    return -C @ np.linalg.solve(Ac, Bc)


@pytest.mark.parametrize(("name", "n", "nu", "ny"), [
    ("aircraft-pitch", 3, 1, 1), ("cruise-control", 1, 1, 1), ("inverted-pendulum", 4, 1, 2),
    ("dc-motor-position", 3, 1, 1), ("dc-motor-speed", 2, 1, 1), ("bus-suspension", 4, 1, 1),
])
def test_dimensions_and_the_scenario(name, n, nu, ny):
    s = plant(name).system()
    assert (s.n, s.nu, s.ny) == (n, nu, ny)
    assert s.is_observable()
    sc = systems.scenario(name, seed=3, steps=50)
    assert name in systems.scenario_names()
    assert sc.y.shape == (50, ny) and sc.x_true.shape == (50, n) and sc.training is not None
    # the record lies in the sets it claims: y - C x in V
    resid = sc.y - sc.x_true @ s.C.T
    assert np.all(np.abs(resid - s.V.c) <= s.V.interval().hi - s.V.c + 1e-12)


def test_cruise_control_first_order_by_hand():
    # m v' = -b v + u: pole -b/m = -0.05; ZOH over dt: a = exp(-b dt / m),
    # b_d = (1 - a) / b; steady-state gain v/u = 1/b = 0.02 (m/s)/N
    p = plant("cruise-control")
    assert np.linalg.eigvals(p.Ac) == pytest.approx([-0.05])
    s = p.system()
    a = np.exp(-50.0 * 0.1 / 1000.0)
    assert s.A[0, 0] == pytest.approx(a, rel=1e-14)
    assert s.B[0, 0] == pytest.approx((1.0 - a) / 50.0, rel=1e-12)
    assert (s.C @ np.linalg.solve(np.eye(1) - s.A, s.B)).item() == pytest.approx(0.02, rel=1e-12)


def test_dc_motor_speed_poles_and_gain_by_hand():
    # (J s + b)(L s + R) + K^2 = 0.005 s^2 + 0.06 s + 0.1001: s = (-0.06 +- sqrt(0.06^2 -
    # 4 * 0.005 * 0.1001)) / 0.01 = -2.0025..., -9.9975...; speed / voltage at s = 0:
    # K / (b R + K^2) = 0.01 / 0.1001
    p = plant("dc-motor-speed")
    disc = np.sqrt(0.06**2 - 4 * 0.005 * 0.1001)
    want = sorted([(-0.06 + disc) / 0.01, (-0.06 - disc) / 0.01])
    assert sorted(np.linalg.eigvals(p.Ac).real) == pytest.approx(want, rel=1e-12)
    assert want[1] == pytest.approx(-2.0025, abs=1e-4) and want[0] == pytest.approx(-9.9975,
                                                                                    abs=1e-4)
    s = p.system()
    gain = (s.C @ np.linalg.solve(np.eye(2) - s.A, s.B)).item()  # ZOH keeps the DC gain
    assert gain == pytest.approx(0.01 / 0.1001, rel=1e-10)


def test_dc_motor_position_poles_by_hand():
    # an integrator (theta' = w) and the roots of J L s^2 + (J R + b L) s + (b R + K^2)
    J, b, K, R, L = 3.2284e-6, 3.5077e-6, 0.0274, 4.0, 2.75e-6
    want = sorted([0.0, *np.roots([J * L, J * R + b * L, b * R + K**2]).real])
    got = sorted(np.linalg.eigvals(plant("dc-motor-position").Ac).real)
    assert got[2] == pytest.approx(0.0, abs=1e-9)
    assert got[:2] == pytest.approx(want[:2], rel=1e-9)
    assert want[1] == pytest.approx(-59.2, abs=0.1)  # the mechanical pole


def test_aircraft_pitch_transfer_function_by_hand():
    # det(sI - A) = s [(s + 0.313)(s + 0.426) + 56.7 * 0.0139] = s^3 + 0.739 s^2 + 0.921468 s;
    # theta / delta = 56.7 [0.0203 (s + 0.313) - 0.0139 * 0.232] / det-factor
    #               = (1.15101 s + 0.17742...) / (s^3 + 0.739 s^2 + 0.921468 s)
    p = plant("aircraft-pitch")
    assert np.poly(p.Ac) == pytest.approx([1.0, 0.739, 0.313 * 0.426 + 56.7 * 0.0139, 0.0],
                                          abs=1e-12)
    for s0 in (0.7j, 1.3, -2.0 + 0.5j):
        tf = (p.C @ np.linalg.solve(s0 * np.eye(3) - p.Ac, p.Bc))[0, 0]
        num = 56.7 * (0.0203 * (s0 + 0.313) - 0.0139 * 0.232)
        den = s0**3 + 0.739 * s0**2 + (0.313 * 0.426 + 56.7 * 0.0139) * s0
        assert tf == pytest.approx(num / den, rel=1e-12)


def test_inverted_pendulum_characteristic_polynomial_by_hand():
    # with p = I (M + m) + M m l^2, det(sI - A) = s^4 + ((I + m l^2) b / p) s^3
    #   - (m g l (M + m) / p) s^2 - (m g l b / p) s  (one unstable pole: upright)
    M, m, b, ell, inertia, g = 0.5, 0.2, 0.1, 0.3, 0.006, 9.8
    p = inertia * (M + m) + M * m * ell**2
    want = [1.0, (inertia + m * ell**2) * b / p, -m * g * ell * (M + m) / p,
            -m * g * ell * b / p, 0.0]
    pl = plant("inverted-pendulum")
    assert np.poly(pl.Ac) == pytest.approx(want, abs=1e-10)
    assert max(np.linalg.eigvals(pl.Ac).real) > 5.0
    # the benchmark estimates the LQR loop: every closed-loop pole inside the unit circle
    assert np.abs(np.linalg.eigvals(pl.system().A)).max() < 1.0


def test_bus_suspension_poles_from_the_force_balance():
    # the denominator of the tutorial's transfer functions, from the two force balances:
    # Delta = (m1 s^2 + b1 s + k1)(m2 s^2 + (b1 + b2) s + (k1 + k2)) - (b1 s + k1)^2;
    # CTMS prints its roots -23.9758 +- 35.1869i and -0.1098 +- 5.2504i
    m1, m2, k1, k2, b1, b2 = 2500.0, 320.0, 80000.0, 500000.0, 350.0, 15020.0
    delta = np.polysub(np.polymul([m1, b1, k1], [m2, b1 + b2, k1 + k2]),
                       np.polymul([b1, k1], [b1, k1]))
    pl = plant("bus-suspension")
    assert np.poly(pl.Ac) == pytest.approx(delta / delta[0], rel=1e-9)
    poles = sorted(np.linalg.eigvals(pl.Ac), key=lambda z: (z.real, z.imag))
    printed = [-23.9758 - 35.1869j, -23.9758 + 35.1869j, -0.1098 - 5.2504j,
               -0.1098 + 5.2504j]
    assert np.allclose(poles, printed, atol=1e-4)
    # deflection / force at s = 0: G1(0) = k2 / (k1 k2) = 1 / k1
    assert _dc_gain_continuous(pl.Ac, pl.Bc[:, :1], pl.C).item() == pytest.approx(1 / k1,
                                                                                 rel=1e-9)


@pytest.mark.parametrize("name", NAMES)
def test_zero_order_hold_against_the_integral(name):
    # Bd = int_0^dt expm(Ac s) ds Bc, by the trapezoid rule on 2001 points
    from scipy.linalg import expm
    p = plant(name)
    dt = p.dt
    A, B = zoh(p.Ac, p.Bc, dt)
    np.testing.assert_allclose(A, expm(p.Ac * dt), rtol=1e-12, atol=1e-14)
    if name == "dc-motor-position":  # a pole at -1.5e6: the trapezoid rule cannot resolve it
        return
    s = np.linspace(0.0, dt, 2001)
    vals = np.array([expm(p.Ac * t) @ p.Bc for t in s])
    integral = np.trapezoid(vals, s, axis=0)
    np.testing.assert_allclose(B, integral, rtol=1e-5, atol=1e-12 * np.abs(B).max())


def test_lqr_gain_satisfies_the_riccati_equation():
    A, B = zoh(plant("inverted-pendulum").Ac, plant("inverted-pendulum").Bc, 0.01)
    K = lqr_gain(A, B, (1.0, 0.0, 1.0, 0.0), 1.0)
    # K is optimal: the closed loop is stable and K = (R + B'PB)^-1 B'PA for the P that
    # solves P = A'PA - A'PB K + Q
    from scipy.linalg import solve_discrete_are
    Q = np.diag([1.0, 0.0, 1.0, 0.0])
    P = solve_discrete_are(A, B, Q, np.eye(1))
    np.testing.assert_allclose(A.T @ P @ A - A.T @ P @ B @ K + Q, P, rtol=1e-8, atol=1e-8)
    assert np.abs(np.linalg.eigvals(A - B @ K)).max() < 1.0


def test_square_wave_and_unknown_plant():
    u = square_wave(6, 2.0, 4, offset=1.0)
    assert u.ravel().tolist() == [3.0, 3.0, -1.0, -1.0, 3.0, 3.0]
    with pytest.raises(systems.ModelError, match="unknown textbook plant 'boat'"):
        plant("boat")
