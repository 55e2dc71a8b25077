"""Nonlinear estimation: conservative linearisation in the family loops, derived derivatives,
interval arithmetic, domain refusal, CORA conformance and the documentation's example."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

import observers
import systems
from observers.prediction import ConservativeLinearisation, MeanValuePrediction
from observers.sets import PCA, Girard, Zonotope
from observers.sets.interval_arith import IntervalDomainError, Ival, cos, sin, sqrt
from systems import DomainError, NonlinearSystem, tank

ROOT = Path(__file__).parents[1]
REF = yaml.safe_load((ROOT / "tests" / "data" / "cora_reference_results.yaml").read_text())
CORA_NL = REF["nonlinearSysDT/test_nonlinearSysDT_observe_01_tank.m"]
NONLINEAR_OBSERVERS = ["VolMin-B", "FRad-A", "FRad-B", "FRad-C", "CZN-A", "CZN-B", "CZN-MV"]


def _final_hull(name: str, **options):
    sc = systems.scenario("tank6-nonlinear-cora")
    res = observers.run(observers.create(name, sc.system, **{**sc.options, **options}),
                        sc.u, sc.y)
    assert res.status == "ok"
    return res.lo[-1], res.hi[-1]


# -- CORA conformance (CORA's stored results: independent numbers) ---------------------------
def test_frad_c_final_hull_matches_cora_to_1e_2():
    lo, hi = _final_hull("FRad-C")
    ref = CORA_NL["FRad-C"]["short"]
    np.testing.assert_allclose(lo, ref["lower"], atol=1e-2, rtol=0)
    np.testing.assert_allclose(hi, ref["upper"], atol=1e-2, rtol=0)


@pytest.mark.parametrize("name", ["FRad-A", "FRad-B", "FRad-C"])
def test_cora_remainder_zonotope_reproduces_cora(name):
    # CORA's own choice of remainder enclosure: agreement up to our outward-rounding margins
    # and to the generators our reductions drop as zero (1-norm at most 1e-13 of the largest,
    # ZERO_COLUMN_RTOL, which CORA keeps; 0.6.0): measured 1.0e-8 to 3.2e-8 on hulls of 14 to
    # 20 (about 2e-9 relative), 4e-10 before that rule
    lo, hi = _final_hull(name, remainder="zonotope")
    ref = CORA_NL[name]["short"]
    np.testing.assert_allclose(lo, ref["lower"], atol=5e-8, rtol=0)
    np.testing.assert_allclose(hi, ref["upper"], atol=5e-8, rtol=0)


def test_conformance_record_is_the_cora_unit_test_record():
    tm = yaml.safe_load((ROOT / "tests" / "data" / "cora_tank6.yaml").read_text())
    sc = systems.scenario("tank6-nonlinear-cora")
    np.testing.assert_array_equal(sc.y.T, tm["nonlinear_unit_test_y_20"])


# -- derivatives ------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [6, 30])
def test_tank_hand_derivatives_agree_with_the_derived_ones(n):
    s = tank(n, linear=False)
    rng = np.random.default_rng(n)
    x, u = 15 + 10 * rng.random(n), 0.1 + 0.1 * rng.random(s.nu)
    J, Bu = s.jacobian(x, u)
    Jd, Bud = s.derived.jacobian(x, u)
    np.testing.assert_allclose(J, Jd, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(Bu, Bud, rtol=1e-12, atol=1e-15)
    lo, hi = x - 3 * rng.random(n), x + 3 * rng.random(n)
    idx, Hlo, Hhi = s.hessian(lo, hi, u)
    H = s.derived.hessian_bounds(lo, hi, u)
    hand = {tuple(e): (a, b) for e, a, b in zip(idx.tolist(), Hlo, Hhi, strict=True)}
    auto = {tuple(e): (a, b) for e, a, b in
            zip(s.derived.hessian_index.tolist(), H.lo, H.hi, strict=True)}
    assert hand.keys() == auto.keys()
    for key, (a, b) in hand.items():
        np.testing.assert_allclose((a, b), auto[key], rtol=1e-12)


def _sample_box(rng, lo, hi, k):
    return lo + (hi - lo) * rng.random((k, lo.size))


@pytest.mark.parametrize("system", [tank(6, linear=False), systems.vanderpol()])
@pytest.mark.parametrize("strategy", ["box", "zonotope", "mean-value"])
def test_prediction_encloses_the_image_of_the_set(system, strategy):
    """f(x) lies in J S + d + R for points x of S, including vertices (random zonotopes)."""
    rng = np.random.default_rng(3)
    n = system.n
    c = system.X0.c + 0.5 * rng.standard_normal(n)
    G = rng.standard_normal((n, 3 * n)) * 0.3
    u = np.full(system.nu, 0.1)
    pred = (MeanValuePrediction(system) if strategy == "mean-value"
            else ConservativeLinearisation(system, PCA(), strategy))
    J, d, R = pred(c, G, u, 0)
    beta = np.vstack([rng.choice([-1.0, 1.0], size=(200, G.shape[1])),
                      rng.uniform(-1, 1, size=(200, G.shape[1]))])
    X = c + beta @ G.T
    err = np.array([system.f(x, u) for x in X]) - (X @ J.T + d)
    Rz = Zonotope(np.zeros(n), R)
    for e in err:
        assert Rz.contains(e, tol=1e-12)


def test_remainder_is_tight_for_a_quadratic():
    # f = x^2 (1-D): the remainder over [p - r, p + r] is (x - p)^2 in [0, r^2] exactly
    s = NonlinearSystem(lambda x, u, m: np.array([x[0] ** 2], dtype=object), 1, 0, C=[[1.0]],
                        W=Zonotope.box([0.1]), V=Zonotope.box([0.1]), X0=Zonotope.box([1.0]))
    J, d, R = ConservativeLinearisation(s, Girard(), "box")(np.array([2.0]), np.array([[0.5]]),
                                                              np.zeros(0), 0)
    assert J[0, 0] == pytest.approx(4.0)
    # enclosure [d + J x] + R: centre offset 0.125 = r^2 / 2, radius 0.125
    np.testing.assert_allclose(d + J[0] * 2.0 - 4.0, [0.125], rtol=1e-12)
    assert np.abs(R).sum() == pytest.approx(0.125, rel=1e-9)


def test_quadratic_forms_are_the_hand_formula_summed_entry_by_entry():
    # M_i = Gr' Q_i Gr with Q_i the symmetric matrix of the entries (i, j, k): a diagonal entry
    # fills (j, j), a mixed one (j, k) and (k, j) with the same value.  Issue 37: the sum went
    # through a BLAS product with a scatter matrix, whose fused multiply-adds differ between
    # kernels; it is now added entry after entry, so two entries of one output are summed in
    # their index order, exactly
    from observers.prediction import quadratic_forms

    rng = np.random.default_rng(3)
    n, r = 4, 3
    Gr = rng.standard_normal((n, r))
    idx = np.array([[0, 0, 0], [0, 1, 2], [2, 3, 3], [2, 0, 1], [3, 1, 1], [0, 2, 2]])
    Hm = rng.standard_normal(len(idx))
    M = quadratic_forms(Gr, idx, Hm)
    for i in range(n):
        Q = np.zeros((n, n))
        for (o, j, k), h in zip(idx, Hm, strict=True):
            if o == i:
                Q[j, k] += h
                if j != k:
                    Q[k, j] += h
        np.testing.assert_allclose(M[i], Gr.T @ Q @ Gr, rtol=0, atol=1e-13)
    # output 0 has three entries: their terms summed in index order, bit for bit
    w = np.where(idx[:, 1] != idx[:, 2], 1.0, 0.5) * Hm
    P0 = np.zeros((r, r))
    for e in np.flatnonzero(idx[:, 0] == 0):
        P0 = P0 + w[e] * (Gr[idx[e, 1]][:, None] * Gr[idx[e, 2]][None, :])
    np.testing.assert_array_equal(M[0], P0 + P0.T)


# -- interval arithmetic ---------------------------------------------------------------------
def test_interval_functions_enclose_sampled_values():
    rng = np.random.default_rng(0)
    for _ in range(200):
        a, b = np.sort(rng.uniform(0.01, 8, 2))
        X = Ival(a, b)
        xs = np.linspace(a, b, 101)
        for fn, F in ((np.sqrt, sqrt), (np.sin, sin), (np.cos, cos)):
            Y = F(X)
            assert Y.lo <= fn(xs).min() and fn(xs).max() <= Y.hi
        P = X ** -1.5
        assert P.lo <= (xs ** -1.5).min() and (xs ** -1.5).max() <= P.hi
        Q = (X - 3.0) * (X - 3.0)
        assert Q.lo <= ((xs - 3) ** 2).min() and ((xs - 3) ** 2).max() <= Q.hi


def test_interval_rounding_is_outward():
    third = Ival(1.0) / Ival(3.0)
    assert third.lo < 1 / 3 < third.hi
    s = Ival(0.1) + Ival(0.2)
    assert s.lo < 0.30000000000000004 and s.hi >= 0.30000000000000004


def test_interval_domain_is_refused():
    with pytest.raises(IntervalDomainError, match="sqrt"):
        sqrt(Ival(-1.0, 2.0))
    with pytest.raises(IntervalDomainError, match="division"):
        Ival(1.0) / Ival(-1.0, 1.0)


# -- domain refusal, unsupported observers -----------------------------------------------------
def test_tank_box_reaching_zero_is_refused_naming_state_and_step():
    s = tank(6, linear=False)
    wide = NonlinearSystem(s._f, 6, s.nu, s.C, W=s.W, V=s.V,
                           X0=Zonotope.box(np.full(6, 19.9), np.full(6, 20.0)),
                           jacobian=s.jacobian, hessian=s.hessian, domain=(0.0, np.inf),
                           name="tank6")
    sc = systems.scenario("tank6-nonlinear", steps=10)
    res = observers.run(observers.create("FRad-C", wide), sc.u, sc.y)
    assert res.status == "diverged"
    assert re.search(r"step \d+: the estimate of state x\d", res.message)
    assert "domain" in res.message and "nan" not in res.message.lower()
    with pytest.raises(DomainError, match="state x1"):
        s.hessian(np.array([-0.1, 1, 1, 1, 1, 1.0]), np.full(6, 2.0), np.zeros(3))


def test_offline_gain_observers_are_unsupported_on_nonlinear_systems():
    s = tank(6, linear=False)
    for name in ["PRad-B", "Nom-G", "Hinf-G", "ESO-A"]:
        with pytest.raises(observers.Unsupported):
            observers.create(name, s)


# -- the observers on the nonlinear scenarios --------------------------------------------------
@pytest.mark.parametrize("name", NONLINEAR_OBSERVERS)
def test_nonlinear_observers_contain_the_true_state(name):
    for scenario, steps in (("vanderpol-sim", 120), ("tank6-nonlinear", 60)):
        sc = systems.scenario(scenario, steps=steps, seed=2, noise="vertex")
        res = observers.run(observers.create(name, sc.system, **sc.options), sc.u, sc.y)
        assert res.status == "ok"
        x = sc.x_true
        assert np.all((res.lo <= x + 1e-9) & (x <= res.hi + 1e-9)), (scenario, name)


def test_scenario_names_cover_any_tank_count():
    sc = systems.scenario("tank9-nonlinear", steps=5)
    assert sc.system.n == 9 and not sc.system.is_linear


# -- the documentation's example (docs/guide/nonlinear.rst) ------------------------------------
def _doc_python_blocks(path) -> list[str]:
    """The ``.. code-block:: python`` bodies of an RST page, dedented."""
    text = path.read_text(encoding="utf-8")
    blocks = re.findall(r"\.\. code-block:: python\n\n((?:   .*\n|\n)+)", text)
    return ["\n".join(ln[3:] for ln in b.splitlines()) for b in blocks]


def test_docs_nonlinear_example_runs(capsys):
    code = _doc_python_blocks(ROOT / "docs" / "guide" / "nonlinear.rst")[0]
    assert len(code.strip().splitlines()) <= 16
    exec(compile(code, "docs-nonlinear", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 3
    assert all(" ok contained: True" in line for line in out)


def test_order_one_box_of_the_remainder_does_not_depend_on_rounding_in_a_repeated_cluster():
    """Bug: the deviation set of the Lagrange remainder was boxed in the eigenvectors of
    ``G G'`` as LAPACK returned them; where eigenvalues repeat (an initial box of equal radii,
    near-repeated ones on 18-30 tanks) any rotation inside the cluster is an eigenbasis, and
    the one returned depended on the BLAS kernel (ARCH Table 6 rows moved by up to 6 %
    between kernels).  The box is now the PCA strategy's own order-one reduction, in its
    deterministic principal axes (a function of the cluster's subspace): a perturbation at
    rounding level moves it by rounding only, and it encloses every generator."""
    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.standard_normal((4, 4)))
    D = np.diag([2.0, 1.0, 1.0, 1.0])
    G = Q @ np.hstack([D, 0.5 * D])  # 8 generators; singular values 2.5 and a triple 1.25
    lin = ConservativeLinearisation(tank(6, linear=False), PCA())
    B = lin._order_one(G)
    assert B.shape == (4, 4)
    for _ in range(5):
        noisy = G + 1e-15 * rng.standard_normal(G.shape)
        np.testing.assert_allclose(lin._order_one(noisy), B, rtol=0, atol=1e-12)
    # the zonotope G is the parallelotope Q D scaled by 1.5 (hand derivation): along the
    # distinct axis Q e1 its box has the half-width 1.5 * 2 = 3; inside the cluster no box is
    # thinner than the cube's half-width 1.5
    widths = np.sort(np.linalg.norm(B, axis=0))
    assert widths[-1] == pytest.approx(3.0, rel=1e-12)
    assert np.all(widths[:3] >= 1.5 * (1 - 1e-12))
    # the box encloses the zonotope: every vertex of G has coordinates in B's axes of at
    # most 1 in absolute value
    signs = np.array(np.meshgrid(*[[-1.0, 1.0]] * 8)).reshape(8, -1)
    coords = np.linalg.solve(B, G @ signs)
    assert np.abs(coords).max() <= 1 + 1e-12


def test_order_one_enclosure_keeps_a_deviation_set_of_at_most_n_generators_exact():
    """A deviation set with at most ``n`` generators is already of order one: the remainder
    takes it as it is (CORA's ``reduce`` to order 1 leaves it unchanged), no box around it."""
    rng = np.random.default_rng(4)
    G = rng.standard_normal((6, 5))
    lin = ConservativeLinearisation(tank(6, linear=False), PCA())
    np.testing.assert_array_equal(lin._order_one(G), G)
