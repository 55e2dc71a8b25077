"""PRad-E, Nom-G and Hinf-G gain designs: CORA's stored gain, the closed-form PRad-E optimum,
independent checks of what each returned gain certifies, caching and bad input."""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from observers.errors import DesignFailed, OptionError
from observers.numerics import luenberger as lg
from observers.numerics.lmi import cora_bisection_end
from observers.sets import Zonotope


def test_cora_bisection_ends_at_one_minus_two_to_the_minus_seven():
    # hand derivation: bracket widths 1/2, 1/4, ..., 1/128 < 0.01 after 7 feasible steps
    assert cora_bisection_end(0.0, 1.0, 0.01) == 1 - 2.0**-7 == 0.9921875
    assert cora_bisection_end(0.0, 1.0, 0.1) == 1 - 2.0**-4
    # why every step is feasible: (P, Y) = (0, 0) satisfies CORA's non-strict LMI for any beta
    s = systems.vehicle(2)
    n, m = s.n, s.ny
    for beta in (0.01, 0.5):
        SM = lg.prad_e_lmi(s.A, s.C, s.W.G, s.V.G, beta, np.zeros((n, n)), np.zeros((n, m)))
        assert np.linalg.eigvalsh(SM).max() <= 0


@pytest.mark.parametrize("solver", ["sdp", "auto"])
def test_prad_e_design_matches_cora_vehicle2d_gain(solver, cora_refs):
    # "sdp": our Clarabel solve; "auto" (default): the closed-form Riccati optimum here
    sc = systems.scenario("vehicle2d-cora")
    obs = observers.create("PRad-E", sc.system, solver=solver, **sc.options)
    expected = cora_refs["gains_vehicle2D_sdpt3"]["PRad-E"]  # SDPT3 via YALMIP in CORA
    np.testing.assert_allclose(obs.L.ravel(), expected, rtol=0, atol=1e-5)


@pytest.mark.parametrize("name", ["vehicle2d-cora", "vehicle4d-sim", "alamo2d-sim"])
def test_prad_e_riccati_optimum_equals_sdp_optimum(name):
    # two independent routes to the max-trace P: Clarabel on the LMI, and the stabilising
    # Riccati solution (alamo2d has a rank-1 disturbance set W)
    s = systems.scenario(name).system
    beta = cora_bisection_end()
    sdp = lg.prad_e_design(s.A, s.C, s.W.G, s.V.G, beta, "sdp")
    ric = lg.prad_e_design(s.A, s.C, s.W.G, s.V.G, beta, "riccati")
    np.testing.assert_allclose(sdp.L, ric.L, rtol=1e-4, atol=1e-6)
    assert sdp.info["trace_P"] == pytest.approx(ric.info["trace_P"], rel=1e-6)
    # the Riccati P dominates (Loewner order) the SDP's: it is the largest feasible P
    assert np.linalg.eigvalsh(ric.P - sdp.P).min() > -1e-6 * np.abs(ric.P).max()


def test_prad_e_depends_on_w_and_v_only_through_their_ranges():
    s = systems.vehicle(4)
    beta = cora_bisection_end()
    a = lg.prad_e_design(s.A, s.C, s.W.G, s.V.G, beta, "riccati")
    b = lg.prad_e_design(s.A, s.C, 7.0 * s.W.G @ np.diag([1, 2, 3, 4]), 0.1 * s.V.G, beta,
                         "riccati")
    np.testing.assert_allclose(a.L, b.L, rtol=1e-8, atol=1e-12)


def _closed_loop_hinf_norm(M, Bd, n_freq=2000):
    """max over the unit circle of the largest singular value of (zI - M)^{-1} Bd."""
    n = M.shape[0]
    out = 0.0
    for w in np.linspace(0, np.pi, n_freq):
        T = np.linalg.solve(np.exp(1j * w) * np.eye(n) - M, Bd)
        out = max(out, np.linalg.svd(T, compute_uv=False)[0])
    return out


@pytest.mark.parametrize("name", ["vehicle2d-cora", "vehicle4d-sim", "alamo2d-sim"])
def test_returned_gains_certify_what_their_lmis_promise(name):
    s = systems.scenario(name).system
    A, C, E, F = s.A, s.C, s.W.G, s.V.G
    # PRad-E: (A - LC)' P (A - LC) <= beta P
    d = lg.prad_e_design(A, C, E, F, 0.9, "sdp")
    M = A - d.L @ C
    assert np.linalg.eigvalsh(M.T @ d.P @ M - 0.9 * d.P).max() <= 1e-7 * np.abs(d.P).max()
    # Nom-G: decay rate mu of the nominal error, a point well inside the LMI
    d = lg.nom_g_design(A, C, mu=1.0)
    M = A - d.L @ C
    assert np.linalg.eigvalsh(M.T @ d.P @ M - d.P).max() < 0
    assert np.trace(d.P) == pytest.approx(s.n, rel=1e-6)
    assert d.info["rho"] < 1
    # Hinf-G: the H-infinity norm from (w~, v~) to e is at most gamma (frequency sweep),
    # gamma is within the slack of the minimum, and the minimum is not above it
    d = lg.hinf_g_design(A, C, E, F, gamma_slack=0.1)
    assert d.info["gamma"] == pytest.approx(1.1 * d.info["gamma_min"], rel=1e-9)
    Bd = np.hstack([lg.range_factor(E), -d.L @ lg.range_factor(F)])
    norm = _closed_loop_hinf_norm(A - d.L @ C, Bd)
    assert norm <= d.info["gamma"]
    assert d.info["rho"] < 1


def test_cached_design_is_reused_without_solving(monkeypatch, tmp_path):
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path))
    s = systems.vehicle(2)
    first = observers.create("Hinf-G", s)

    def fail(*args, **kwargs):
        raise AssertionError("design solved again")

    monkeypatch.setattr("observers.builtin.luenberger.hinf_g_design", fail)
    again = observers.create("Hinf-G", s, convention="cora-lagged")  # online option: same key
    np.testing.assert_array_equal(first.L, again.L)
    with pytest.raises(AssertionError, match="solved again"):
        observers.create("Hinf-G", s, gamma_slack=0.2)  # design option: new key


def test_non_detectable_system_gives_a_clear_error():
    A = np.diag([0.5, 1.2])  # the second state is unstable and not measured
    s = systems.LinearSystem(A, np.zeros((2, 1)), [[1.0, 0.0]], W=Zonotope.box([0.1, 0.1]),
                             V=Zonotope.box([0.1]), X0=Zonotope.box([1.0, 1.0]))
    for name in ("PRad-E", "Nom-G", "Hinf-G"):
        with pytest.raises(systems.ModelError, match=f"{name}: the pair .A, C. is not detectable"):
            observers.create(name, s)


def test_prad_e_beta_below_the_slowest_unobservable_mode_is_no_gain():
    s = systems.tank(6, linear=True)  # tank 6 is unobservable with eigenvalue 0.996
    with pytest.raises(DesignFailed, match="0.996 decay slower than the required rate"):
        observers.create("PRad-E", s, beta=0.9)


@pytest.mark.parametrize(("name", "options", "message"), [
    ("PRad-E", {"beta": 1.0}, r"beta must be a number in \(0, 1\)"),
    ("PRad-E", {"solver": "mosek"}, "solver must be one of 'auto', 'sdp', 'riccati'"),
    ("Nom-G", {"mu": 0}, r"mu must be a number in \(0, 1\]"),
    ("Hinf-G", {"gamma_slack": -1}, "gamma_slack must be a positive number"),
    ("Hinf-G", {"convention": "cora"}, "convention must be one of 'aligned', 'cora-lagged'"),
    ("Hinf-G", {"order": 100}, "unknown option"),
])
def test_bad_options_are_one_line_errors(name, options, message):
    with pytest.raises(OptionError, match=message):
        observers.create(name, systems.vehicle(2), **options)


# -- Nom-G by the damped Newton method (issue 30) ---------------------------------------------
def test_decay_centre_of_a_hand_solved_scalar_problem():
    from observers.numerics.lmi import DecayCone, decay_centre

    # n = m = 1, tr P = 1 pins p = 1; det D = rate - (a - y h)^2 is largest at y = a / h
    cone = DecayCone(np.array([[0.5]]), np.array([[2.0]]), 0.9)
    P, Y = decay_centre(cone, np.array([[1.0]]), np.array([[0.1]]), "test")
    assert P[0, 0] == pytest.approx(1.0, abs=1e-12)
    assert Y[0, 0] == pytest.approx(0.25, abs=1e-10)
    with pytest.raises(DesignFailed, match="infeasible"):  # |a - y h| = 1.5 > sqrt(0.9)
        decay_centre(cone, np.array([[1.0]]), np.array([[1.0]]), "test")


@pytest.mark.parametrize("name", ["vehicle2d-cora", "vehicle6d-cora"])
def test_nom_g_newton_is_the_centre_that_clarabel_approaches(name):
    s = systems.scenario(name).system
    A, C = s.A, s.C

    def objective(d):
        D = lg.nom_g_lmi(A, C, 1.0, d.P, d.P @ d.L)
        return np.linalg.slogdet(0.5 * (D + D.T))[1]

    newton = lg.nom_g_design(A, C)
    clarabel = lg.nom_g_design(A, C, solver="clarabel")
    assert np.trace(newton.P) == pytest.approx(s.n, rel=1e-12)
    # the same point up to Clarabel's accuracy, and the Newton point is not worse
    assert objective(newton) >= objective(clarabel) - 1e-9
    np.testing.assert_allclose(newton.L, clarabel.L, atol=1e-3 * np.abs(clarabel.L).max())


def test_nom_g_solver_option_is_part_of_the_design_key(monkeypatch, tmp_path):
    monkeypatch.setenv("SETOBS_CACHE_DIR", str(tmp_path))
    s = systems.vehicle(2)
    a = observers.create("Nom-G", s)
    b = observers.create("Nom-G", s, solver="clarabel")
    assert len(list(tmp_path.glob("Nom-G-*.npz"))) == 2
    assert 0 < np.abs(a.L - b.L).max() < 1e-3 * np.abs(b.L).max()
    with pytest.raises(OptionError, match="solver must be one of"):
        observers.create("Nom-G", s, solver="scs")


def test_hinf_g_riccati_route_keeps_the_least_gamma_and_the_bound():
    s = systems.scenario("vehicle6d-cora").system
    A, C, E, F = s.A, s.C, s.W.G, s.V.G
    sdp = lg.hinf_g_design(A, C, E, F, 0.1, "sdp")
    ric = lg.hinf_g_design(A, C, E, F, 0.1, "riccati")
    assert ric.info["gamma_min"] == pytest.approx(sdp.info["gamma_min"], rel=1e-3)
    # the H-infinity norm from (w~, v~) to e is within the bound (frequency sweep)
    Bd = np.hstack([lg.range_factor(E), -ric.L @ lg.range_factor(F)])
    assert _closed_loop_hinf_norm(A - ric.L @ C, Bd) <= ric.info["gamma"]
    assert ric.info["rho"] < 1
    with pytest.raises(DesignFailed, match="unknown method"):
        lg.hinf_g_design(A, C, E, F, 0.1, "scs")


def test_nom_g_above_the_newton_limit_is_the_verified_kalman_start(monkeypatch):
    from observers.numerics import luenberger

    s = systems.scenario("vehicle6d-cora").system
    monkeypatch.setattr(luenberger, "NEWTON_MAX_VARIABLES", 10)
    d = luenberger.nom_g_design(s.A, s.C)
    assert d.info["solver"] == "start" and d.info["rho"] < 1
    P0, Y0 = luenberger.nom_g_start(s.A, s.C, 1.0)
    np.testing.assert_allclose(d.L, np.linalg.solve(P0, Y0), rtol=1e-10)


def test_h_infinity_gains_do_not_depend_on_the_units_of_the_noise():
    # Congruence with diag(I, I/s, I/s, I): the Hinf-G LMI of (s E, s F, g) is that of
    # (E, F, g / s^2) with the same P and Y, so the gain is the same and gamma scales by s;
    # likewise the H-infinity LMI of ESO-C/D (step 1, Q = I).  The solvers see the noise at
    # unit scale (lmi.unit_noise), so the computed points agree to the solver's tolerance
    # (measured: 1e-5 in the gain), where before its absolute tolerances moved Hinf-G's radii
    # by 0.26 % at s = 0.1 (the noise-level grid).
    from observers.numerics.ellipsoidal import first_gain, hinf_gain
    from observers.numerics.lmi import LinearDesignProblem

    s = systems.scenario("vehicle6d-cora").system
    A, C, E, F = s.A, s.C, s.W.G, s.V.G
    base = lg.hinf_g_design(A, C, E, F, 0.1, "sdp")
    for k in (0.1, 8.0):
        other = lg.hinf_g_design(A, C, k * E, k * F, 0.1, "sdp")
        np.testing.assert_allclose(other.L, base.L, rtol=1e-4, atol=1e-6 * np.abs(base.L).max())
        # gamma to the solver's tolerance (1.07e-6 apart on an AMD EPYC, below 1e-6 on an
        # Intel Xeon: the same measured tolerance as the gain's)
        assert other.info["gamma"] == pytest.approx(k * base.info["gamma"], rel=1e-5)
    plant = LinearDesignProblem(A, C, E, F)
    scaled = LinearDesignProblem(A, C, 0.1 * E, 0.1 * F)
    # the units-free design (ESO-C's default); 'cora' takes CORA's absolute gamma grid, so it
    # depends on the units by construction (docs/guide/papers.rst)
    L1 = first_gain(plant, design="least-gamma")
    np.testing.assert_allclose(first_gain(scaled, design="least-gamma"), L1, rtol=1e-4,
                               atol=1e-6 * np.abs(L1).max())
    g = hinf_gain(plant, np.eye(A.shape[0]), "test")[2]
    assert hinf_gain(scaled, np.eye(A.shape[0]), "test")[2] == pytest.approx(0.01 * g,
                                                                            rel=1e-6)
