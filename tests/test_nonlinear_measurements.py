"""Nonlinear measurements y = h(x) + v: the system API, derivatives against finite
differences, the affine enclosures and polyhedral relaxations (sampled points of the graph
inside), the linear special case, the constrained-zonotope estimators of Rego et al. on
their example and the robot, and the refusals."""

from __future__ import annotations

import numpy as np
import pytest
import sympy

import observers
import systems
from observers.enclosures import ENCLOSURES, Smooth, dc_weights
from observers.errors import OptionError, Unsupported
from observers.numerics.relaxation import Factorable, lifted_set, relax
from observers.sets import ConZonotope, Zonotope
from systems import ModelError, NonlinearSystem, OutputNotLinear

CZ_ESTIMATORS = ["CZN-MV", "CZN-FO", "CZN-DC", "CZN-PR"]
STRIP_OBSERVERS = ["FRad-A", "FRad-B", "VolMin-A", "VolMin-B"]
NONLINEAR_CAPABLE = STRIP_OBSERVERS + ["CZN-A", "CZN-B"] + CZ_ESTIMATORS


def _options(name, sc, **extra):
    accepted = observers.get(name).option_defaults()
    return {k: v for k, v in {**sc.options, **extra}.items() if k in accepted}


def _run(name, sc, **extra):
    obs = observers.create(name, sc.system, **_options(name, sc, **extra))
    return obs, observers.run(obs, sc.u, sc.y)


def _contained(res, x_true):
    """Every true state inside its set (LP membership for constrained zonotopes, the set's own
    test for zonotopes) and inside the interval hull."""
    for S, x, lo, hi in zip(res.sets, x_true, res.lo, res.hi, strict=False):
        assert np.all(lo <= x + 1e-9) and np.all(x <= hi + 1e-9)
        assert S.contains(x, tol=1e-9)
    return True


# -- the system API -----------------------------------------------------------------------------
def test_output_api_of_linear_and_nonlinear_systems():
    lin = systems.scenario("rego2d-linear").system
    x = np.array([0.3, -1.2])
    np.testing.assert_array_equal(lin.h(x), lin.C @ x)
    np.testing.assert_array_equal(lin.h_jacobian(x), lin.C)
    np.testing.assert_array_equal(lin.outputs(np.array([x, 2 * x])), np.array([x, 2 * x]) @ lin.C.T)
    nl = systems.scenario("rego2d-nonlinear").system
    # y1 = x1 - sin(x2 / 2), y2 = (1 - x1) x2 by hand
    np.testing.assert_allclose(nl.h(x), [0.3 - np.sin(-0.6), 0.7 * -1.2], rtol=1e-15)
    assert nl.ny == 2 and not nl.output_is_linear and not hasattr(nl, "C")
    with pytest.raises(OutputNotLinear, match="nonlinear output"):
        nl.C  # noqa: B018
    vdp = systems.vanderpol()
    np.testing.assert_array_equal(vdp.h(x), [0.3])
    np.testing.assert_array_equal(vdp.h_jacobian(x), [[1.0, 0.0]])


def test_simulated_measurements_are_h_plus_bounded_noise():
    sc = systems.scenario("rego2d-nonlinear")
    v = sc.y - sc.system.outputs(sc.x_true)
    assert np.all(np.abs(v) <= 0.2 + 1e-12)
    assert np.abs(v).max() > 0.1  # the noise is there
    np.testing.assert_array_equal(sc.x_true[0], [5.2, 0.65])


@pytest.mark.parametrize("name", ["rego2d-nonlinear", "robot-range"])
def test_derivatives_of_f_and_h_agree_with_finite_differences(name):
    sc = systems.scenario(name)
    s = sc.system
    rng = np.random.default_rng(3)
    eps = 1e-6
    for k in rng.choice(sc.N, 5, replace=False):
        x, u = sc.x_true[k], sc.u[k]
        for value, jac, hess in (
                (lambda z, u=u: s.f(z, u), lambda z, u=u: s.jacobian(z, u)[0],
                 lambda lo, hi, u=u: s.hessian(lo, hi, u)),
                (s.h, s.h_jacobian, s.h_hessian)):
            J = jac(x)
            fd = np.column_stack([(value(x + eps * e) - value(x - eps * e)) / (2 * eps)
                                  for e in np.eye(s.n)])
            np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-7)
            # second derivatives: bounds over a small box contain the finite differences
            idx, lo, hi = hess(x - 1e-3, x + 1e-3)
            H = np.zeros((J.shape[0], s.n, s.n))
            for (i, j, kk), a, b in zip(idx, lo, hi, strict=True):
                H[i, j, kk] = H[i, kk, j] = 0.5 * (a + b)
                assert a <= b
            fd2 = np.stack([(jac(x + 1e-5 * e) - jac(x - 1e-5 * e)) / 2e-5 for e in np.eye(s.n)],
                           axis=2)
            np.testing.assert_allclose(H, fd2, rtol=1e-4, atol=1e-5)


# -- affine enclosures -------------------------------------------------------------------------
@pytest.mark.parametrize("how", sorted(ENCLOSURES))
@pytest.mark.parametrize("what", ["f", "h"])
def test_affine_enclosures_contain_sampled_values(how, what):
    s = systems.scenario("robot-range").system
    fn = Smooth(s, what)
    rng = np.random.default_rng(7)
    u = np.array([1.0, 0.4])
    for _ in range(5):
        c = np.array([4.0, 5.0, 1.0]) + rng.uniform(-1, 1, 3)
        r = rng.uniform(0.05, 0.6, 3)
        J, d, rad = ENCLOSURES[how](fn, c - r, c + r, u)
        X = c + r * rng.uniform(-1, 1, (2000, 3))
        X[:8] = c + r * np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T  # vertices
        vals = np.array([fn.value(x, u) for x in X])
        assert np.all(np.abs(vals - X @ J.T - d) <= rad)


def test_dc_weights_make_every_hessian_of_the_bounds_convex():
    rng = np.random.default_rng(1)
    idx = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 2]])
    lo = np.array([-2.0, -1.0, 0.5, -0.3])
    hi = lo + np.array([1.0, 2.0, 0.5, 0.6])
    a = dc_weights(idx, lo, hi, 1, 3)
    for _ in range(200):
        h = lo + (hi - lo) * rng.random(4)
        H = np.zeros((3, 3))
        for (_, j, k), v in zip(idx, h, strict=True):
            H[j, k] = H[k, j] = v
        assert np.linalg.eigvalsh(H + np.diag(a[0])).min() >= -1e-12


# -- polyhedral relaxations --------------------------------------------------------------------
def _graph_set(expr, symbols, c, G, tangents=1):
    """The lifted constrained zonotope of (x, phi(x)) over the zonotope (c, G): state
    coordinates first, then the function's value."""
    g = Factorable([expr], symbols, ())
    r = np.abs(G).sum(axis=1)
    rel = relax(g, c, G, (c - r, c + r), np.zeros(0), tangents)
    coef, A, b = lifted_set(rel, np.zeros((0, G.shape[1])), np.zeros(0))
    Gx = np.zeros((G.shape[0], coef.shape[1]))
    Gx[:, :G.shape[1]] = G
    return ConZonotope(np.r_[c, rel.const], np.vstack([Gx, coef]), A, b), g


x0, x1 = sympy.symbols("x0:2", real=True)
ELEMENTARY = {
    "sum": (x0 + 3 * x1 - 2, (-1, 1), (-2, 2)),
    "product": (x0 * x1, (-1, 2), (-3, 1)),
    "quotient": (x0 / x1, (-1, 2), (0.5, 3)),
    "square": (x0 ** 2, (-1, 2), (0, 1)),
    "cube": (x0 ** 3, (-1, 2), (0, 1)),
    "sqrt": (sympy.sqrt(x0), (0.1, 4), (0, 1)),
    "power 3/2": (x0 ** sympy.Rational(3, 2), (0.2, 3), (0, 1)),
    "exp": (sympy.exp(x0), (-1, 2), (0, 1)),
    "log": (sympy.log(x0), (0.2, 5), (0, 1)),
    "sin (concave)": (sympy.sin(x0), (0.2, 2.9), (0, 1)),
    "sin (convex)": (sympy.sin(x0), (-2.9, -0.2), (0, 1)),
    "sin (mixed)": (sympy.sin(x0), (-1.5, 2.5), (0, 1)),
    "cos (mixed)": (sympy.cos(x0), (-0.5, 3), (0, 1)),
    "cos (wide)": (sympy.cos(x0), (-4, 5), (0, 1)),
    "atan": (sympy.atan(x0), (-3, 2), (0, 1)),
    "composite": (x0 * sympy.sin(x1 / 2) - sympy.exp(x1) / (4 + x0), (-1, 2), (-1, 1)),
}


@pytest.mark.parametrize("tangents", [1, 3])
@pytest.mark.parametrize("case", sorted(ELEMENTARY))
def test_polyhedral_relaxation_contains_the_graph(case, tangents):
    expr, (a0, b0), (a1, b1) = ELEMENTARY[case]
    fn = sympy.lambdify((x0, x1), expr, "numpy")
    rng = np.random.default_rng(11)
    c = np.array([(a0 + b0) / 2, (a1 + b1) / 2])
    # a rotated zonotope inside the box of the case, and the box itself
    for G in (np.diag([(b0 - a0) / 2, (b1 - a1) / 2]),
              np.array([[(b0 - a0) / 4, (b0 - a0) / 4], [-(b1 - a1) / 4, (b1 - a1) / 4]])):
        Z, _ = _graph_set(expr, (x0, x1), c, G, tangents)
        xi = np.vstack([rng.uniform(-1, 1, (60, 2)), [[1, 1], [-1, -1], [1, -1], [-1, 1]]])
        for x in c + xi @ G.T:
            assert Z.contains(np.r_[x, fn(*x)], tol=1e-9), (case, x)


def test_polyhedral_relaxation_is_tighter_than_the_interval_of_a_product():
    # x0 x1 over [-1, 1]^2 at x0 = x1: McCormick's z >= x0 + x1 - 1 cuts z = -1 off near (1, 1)
    Z, _ = _graph_set(x0 * x1, (x0, x1), np.zeros(2), np.eye(2))
    assert not Z.contains(np.array([1.0, 1.0, -1.0]), tol=1e-6)
    assert Z.contains(np.array([1.0, 1.0, 1.0]), tol=1e-9)


def test_relaxation_refuses_unsupported_operations():
    with pytest.raises(Unsupported, match="tanh"):
        Factorable([sympy.tanh(x0)], (x0,), ())
    with pytest.raises(Unsupported, match="power"):
        Factorable([x0 ** sympy.Rational(1, 3)], (x0,), ())


# -- the linear special case ------------------------------------------------------------------
def _vanderpol_h_linear() -> NonlinearSystem:
    base = systems.vanderpol()
    return NonlinearSystem(base._f, 2, 1, None, W=base.W, V=base.V, X0=base.X0,
                           h=lambda x, m: np.array([x[0]], dtype=object), dt=base.dt)


@pytest.mark.parametrize("name", NONLINEAR_CAPABLE)
def test_h_linear_gives_exactly_the_sets_of_the_C_path(name):
    sc = systems.scenario("vanderpol-sim", steps=40)
    s_h = _vanderpol_h_linear()
    assert not s_h.output_is_linear and s_h.output_matrix is not None
    opts = _options(name, sc)
    ref = observers.run(observers.create(name, sc.system, **opts), sc.u, sc.y)
    got = observers.run(observers.create(name, s_h, **opts), sc.u, sc.y)
    assert ref.status == got.status == "ok"
    for A, B in zip(ref.sets, got.sets, strict=True):
        assert A == B


@pytest.mark.parametrize("name", ["CZN-FO", "CZN-DC", "CZN-PR"])
def test_new_estimators_are_czn_a_on_linear_systems(name):
    sc = systems.scenario("rego2d-linear")
    _, ref = _run("CZN-A", sc)
    _, got = _run(name, sc)
    for A, B in zip(ref.sets, got.sets, strict=True):
        assert A == B


def test_linear_toolbox_example_contains_the_true_states():
    sc = systems.scenario("rego2d-linear")
    assert sc.N == 30 and sc.x_true[0].tolist() == [1.0, -1.0]
    for name in NONLINEAR_CAPABLE + ["FRad-C", "PRad-A"]:
        _, res = _run(name, sc)
        assert res.status == "ok", name
        _contained(res, sc.x_true)


# -- Rego et al.'s nonlinear example and the robot ---------------------------------------------
@pytest.mark.parametrize("noise", ["uniform", "vertex"])
@pytest.mark.parametrize("name", CZ_ESTIMATORS)
def test_cz_estimators_on_rego2d_within_limits_and_sound(name, noise):
    sc = systems.scenario("rego2d-nonlinear", noise=noise, seed=0 if noise == "uniform" else 3)
    obs = observers.create(name, sc.system, **_options(name, sc))
    obs.reset()
    for k in range(sc.N):
        S = obs.step(sc.u[k - 1] if k else None, sc.y[k])
        assert S.num_generators <= 20 and S.num_constraints <= 8, (k, S)
        assert S.contains(sc.x_true[k], tol=1e-9), k
        I = S.interval()
        assert np.all(I.lo <= sc.x_true[k]) and np.all(sc.x_true[k] <= I.hi)
    assert obs.k == 100
    assert set(obs.phase_times) == {"prediction", "update", "reduction", "hull"}


@pytest.mark.parametrize("name", NONLINEAR_CAPABLE)
def test_nonlinear_observers_contain_the_robot(name):
    sc = systems.scenario("robot-range", steps=40, seed=2, noise="vertex")
    _, res = _run(name, sc)
    assert res.status == "ok", res.message
    _contained(res, sc.x_true)


def test_strip_observers_contain_the_rego2d_states():
    sc = systems.scenario("rego2d-nonlinear")
    for name in STRIP_OBSERVERS:
        _, res = _run(name, sc)
        assert res.status == "ok"
        _contained(res, sc.x_true)


# -- refusals ----------------------------------------------------------------------------------
def test_bad_output_definitions_are_refused():
    base = systems.vanderpol()
    kw = dict(W=base.W, V=base.V, X0=base.X0)
    with pytest.raises(ModelError, match="either as C or as h"):
        NonlinearSystem(base._f, 2, 1, [[1.0, 0.0]], h=lambda x, m: x[:1], **kw)
    with pytest.raises(ModelError, match="as a matrix C or as a function h"):
        NonlinearSystem(base._f, 2, 1, None, **kw)
    with pytest.raises(ModelError, match="h returns 2 values, but V has dimension 1"):
        NonlinearSystem(base._f, 2, 1, None, h=lambda x, m: x, **kw)


def test_observers_without_nonlinear_outputs_refuse_them():
    s = systems.scenario("robot-range").system
    with pytest.raises(Unsupported, match="linear output"):
        observers.create("FRad-C", s)
    with pytest.raises(Unsupported, match="missing: .*C"):
        observers.create("PRad-A", s)


def test_generator_limit_below_states_plus_constraints_is_refused():
    s = systems.scenario("rego2d-nonlinear").system
    with pytest.raises(OptionError, match="below n \\+ max_constraints"):
        observers.create("CZN-FO", s, max_generators=9, max_constraints=8)


def test_dc_refuses_large_state_dimensions():
    s = systems.tank(14, linear=False)
    with pytest.raises(Unsupported, match="2\\^n vertices"):
        observers.create("CZN-DC", s)


def test_relaxation_domain_error_ends_the_run_as_diverged():
    # a state next to x1 = -4, where 1 / (4 + x1) is not defined: the estimate reaches it
    base = systems.scenario("rego2d-nonlinear")
    s = NonlinearSystem(base.system._f, 2, 0, None, W=base.system.W, V=base.system.V,
                        X0=Zonotope.box([3.0, 1.0], [-2.0, 0.5]), h=base.system._h)
    sim = systems.simulate(s, np.zeros((2, 0)), seed=0, x0=[-3.8, 0.5])
    res = observers.run(observers.create("CZN-PR", s), sim.u, sim.y)
    assert res.status == "diverged" and "left its domain" in res.message


# -- the documentation's example (docs/guide/nonlinear.rst, "Nonlinear measurements") ----------
def test_docs_nonlinear_measurement_example_runs(capsys):
    import re
    from pathlib import Path

    page = (Path(__file__).parents[1] / "docs" / "guide" / "nonlinear.rst").read_text(
        encoding="utf-8")
    section = page.split("Nonlinear measurements\n", 1)[1]
    body = re.search(r"\.\. code-block:: python\n\n((?:   .*\n|\n)+)", section).group(1)
    code = "\n".join(ln[3:] for ln in body.splitlines())
    assert len(code.strip().splitlines()) <= 20
    exec(compile(code, "docs/guide/nonlinear.rst", "exec"), {"__name__": "docs"})
    lines = capsys.readouterr().out.strip().splitlines()
    assert [ln.split()[0] for ln in lines] == CZ_ESTIMATORS
    assert all(" ok contained: True " in ln for ln in lines)
