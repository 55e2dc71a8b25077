"""MHE-PR, the nonlinear moving-horizon set estimator (issue 40)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import observers
import systems
from observers.errors import Unsupported
from observers.sets import Zonotope
from systems import NonlinearSystem


def _tank_as_nonlinear() -> tuple[systems.Scenario, NonlinearSystem]:
    """The linear 6-tank record and the same model written as a nonlinear one."""
    sc = systems.scenario("tank6-linear", steps=40)
    s = sc.system
    A, B = np.asarray(s.A), np.asarray(s.B)
    nl = NonlinearSystem(lambda x, u, m: A @ x + B @ u, s.n, s.nu, s.C, W=s.W, V=s.V,
                         X0=s.X0, dt=s.dt)
    return sc, nl


@pytest.mark.parametrize("window", [1, 3])
def test_on_a_linear_model_written_as_a_nonlinear_one_it_is_mhe(window):
    """Affine forms need no relaxation: the window is MHE's constrained zonotope, so the hulls
    agree to the solver's tolerance (1e-9 of the radius; no sweep, which would smooth the
    priors beyond MHE's)."""
    sc, nl = _tank_as_nonlinear()
    mhe = observers.run(observers.create("MHE", sc.system, window=window), sc.u, sc.y)
    pr = observers.run(observers.create("MHE-PR", nl, window=window, sweeps=0), sc.u, sc.y)
    assert mhe.status == pr.status == "ok"
    rad = mhe.radius
    assert np.abs(pr.radius - rad).max() <= 1e-9 * rad.max()
    assert np.abs(pr.center - mhe.center).max() <= 1e-9 * rad.max()


def _quadratic_measurement(X0=(1.0, 3.0)) -> NonlinearSystem:
    """x+ = x + w, y = x^2 + v: |w| <= 0.1, |v| <= 0.5, x0 in X0."""
    lo, hi = X0
    return NonlinearSystem(lambda x, u, m: x, 1, 0, None, W=Zonotope.box([0.1]),
                           V=Zonotope.box([0.5]),
                           X0=Zonotope.box([(hi - lo) / 2], [(hi + lo) / 2]),
                           h=lambda x, m: np.array([x[0] ** 2], dtype=object))


def test_hull_of_a_quadratic_measurement_matches_the_hand_derivation():
    """y0 = 4 with x0 in [1, 3]: over the box [1, 3] the square lies below its secant 4x - 3
    and above its tangent at 2, 4x - 4; with x^2 = 4 - v in [3.5, 4.5] the relaxation gives
    x >= 6.5 / 4 = 1.625 and x <= 8.5 / 4 = 2.125.  A second pass over [1.625, 2.125]
    (secant 3.75 x - 3.453125, tangent at 1.875: 3.75 x - 3.515625) gives
    x >= 6.953125 / 3.75 and x <= 2.125 (its own bound 8.015625 / 3.75 is looser).  The
    lower bound's fixed point a = (3.5 + a b) / (a + b) is sqrt(3.5) exactly; a tangent at
    the midpoint m bounds x by (4.5 + m^2) / (2 m) >= sqrt(4.5) (equal only at m = sqrt 4.5),
    so the upper bound stays 2.125 with one tangent, and with the tangents at the ends too
    (``tangents=3``) it approaches sqrt(4.5): many passes approach the exact set
    [sqrt(3.5), sqrt(4.5)] from outside."""
    s = _quadratic_measurement()
    y = np.array([[4.0]])
    tol = 1e-6  # the noise's margin (1e-7, relative) and the relaxations' (1e-12)
    I = observers.create("MHE-PR", s, sweeps=0).step(None, y[0]).interval()
    assert float(I.lo[0]) == pytest.approx(1.625, abs=tol)
    assert float(I.hi[0]) == pytest.approx(2.125, abs=tol)
    I = observers.create("MHE-PR", s, sweeps=1, shrink=0.0).step(None, y[0]).interval()
    assert float(I.lo[0]) == pytest.approx(6.953125 / 3.75, abs=tol)
    assert float(I.hi[0]) == pytest.approx(2.125, abs=tol)
    exact = (math.sqrt(3.5), math.sqrt(4.5))
    I = observers.create("MHE-PR", s, sweeps=10, shrink=0.0).step(None, y[0]).interval()
    assert float(I.lo[0]) <= exact[0] and float(I.hi[0]) >= exact[1]
    assert float(I.lo[0]) == pytest.approx(exact[0], abs=1e-3)
    assert float(I.hi[0]) == pytest.approx(2.125, abs=tol)
    I = observers.create("MHE-PR", s, sweeps=10, shrink=0.0, tangents=3).step(
        None, y[0]).interval()
    assert float(I.lo[0]) <= exact[0] and float(I.hi[0]) >= exact[1]
    assert float(I.lo[0]) == pytest.approx(exact[0], abs=1e-3)
    assert float(I.hi[0]) == pytest.approx(exact[1], abs=1e-3)


def test_the_window_carries_the_measurements_forward():
    """Two steps, y0 = y1 = 4 with |w| <= 0.1: x1 = x0 + w with x0 in [sqrt 3.5, sqrt 4.5]
    and x1 in the same interval, so the exact hull of x1 is [sqrt 3.5, sqrt 4.5] again (the
    disturbance cannot leave it); the estimate contains it and, with sweeps, is close."""
    s = _quadratic_measurement()
    obs = observers.create("MHE-PR", s, window=2, sweeps=10, shrink=0.0, tangents=3)
    obs.step(None, np.array([4.0]))
    I = obs.step(np.zeros(0), np.array([4.0])).interval()
    exact = (math.sqrt(3.5), math.sqrt(4.5))
    assert float(I.lo[0]) <= exact[0] and float(I.hi[0]) >= exact[1]
    assert float(I.hi[0] - I.lo[0]) <= (exact[1] - exact[0]) * 1.01


def test_the_newest_box_is_the_hull_of_the_prediction():
    """Window 2, no sweeps, y0 = y1 = 4.  Step 0 stores x0's box [1.625, 2.125] (the test
    above).  At step 1 the window relaxes y0 over that box (the box shapes the relaxation, it
    is no constraint): x0 >= 6.953125 / 3.75 = 89/48 (secant) and x0 <= 8.015625 / 3.75 =
    171/80 (tangent at 1.875), so the prediction x1 = x0 + w has the hull
    [89/48 - 1/10, 171/80 + 1/10] = [421/240, 179/80]: the box over which y1 is relaxed.
    With a = 421/240, b = 179/80, m = (a + b)/2: x1 >= (7/2 + a b) / (a + b) (secant) and
    x1 <= (9/2 + m^2) / (2 m) (tangent at m); the window's own x1 <= 179/80 is looser.  A
    box taken from anywhere else (X0 carried forward, or the stored box plus w) gives other
    numbers."""
    from fractions import Fraction as F

    obs = observers.create("MHE-PR", _quadratic_measurement(), window=2, sweeps=0)
    obs.step(None, np.array([4.0]))
    I = obs.step(np.zeros(0), np.array([4.0])).interval()
    a, b = F(421, 240), F(179, 80)
    m = (a + b) / 2
    tol = 1e-6  # the noise's margin (1e-7, relative) and the relaxations' (1e-12)
    assert float(I.lo[0]) == pytest.approx(float((F(7, 2) + a * b) / (a + b)), abs=tol)
    assert float(I.hi[0]) == pytest.approx(float((F(9, 2) + m * m) / (2 * m)), abs=tol)


@pytest.mark.parametrize("name", ["tank6-nonlinear", "rego2d-nonlinear", "robot-range",
                                  "vanderpol-sim"])
def test_contains_the_true_state_on_every_nonlinear_record(name):
    sc = systems.scenario(name, steps=25)
    res = observers.run(observers.create("MHE-PR", sc.system, window=3), sc.u, sc.y)
    assert res.status == "ok", res.message
    x = sc.x_true[: len(res.lo)]
    assert np.all(res.lo <= x) and np.all(x <= res.hi)


def test_sweeps_never_loosen_the_estimate():
    """Each pass only intersects sound boxes, and smoothed boxes make later priors tighter."""
    sc = systems.scenario("tank6-nonlinear", steps=20)
    r0 = observers.run(observers.create("MHE-PR", sc.system, sweeps=0), sc.u, sc.y).radius
    r2 = observers.run(observers.create("MHE-PR", sc.system, sweeps=2, shrink=0.0),
                       sc.u, sc.y).radius
    assert np.all(r2 <= r0 * (1 + 1e-9))


def test_refuses_a_linear_system_in_one_line():
    sc = systems.scenario("tank6-linear", steps=5)
    with pytest.raises(Unsupported, match="MHE-PR needs a nonlinear system"):
        observers.create("MHE-PR", sc.system)
