"""FRad-A/B/C: conformance with CORA's stored results, the ARCH 2021 tank table, the textbook
variant, and containment of the true state on every shipped scenario with a trajectory."""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from benchmarks.metrics import rms_radius

from .conftest import paper_table

FRAD = ["FRad-A", "FRad-B", "FRad-C"]


@pytest.mark.parametrize("name", FRAD)
def test_vehicle2d_final_hull_matches_cora(name, cora_vehicle2d_refs):
    sc = systems.scenario("vehicle2d-cora")
    res = observers.run(observers.create(name, sc.system, order=100, reduction="pca"), sc.u,
                        sc.y)
    ref = cora_vehicle2d_refs[name]
    np.testing.assert_allclose(res.lo[-1], ref["lower"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(res.hi[-1], ref["upper"], rtol=0, atol=1e-6)


@pytest.mark.parametrize(("name", "rtol"), [("FRad-A", 0.01), ("FRad-B", 0.01),
                                            ("FRad-C", 0.02)])
def test_tank6_rms_radii_match_arch2021_table3(name, rtol):
    # F-radius gains depend only on the generators, so the radii do not depend on the noise
    # realisation: ARCH Table 3 (relative value x smallest absolute radius) is reproducible.
    # FRad-A/B land within 0.05 % of the table.  FRad-C's PCA reductions act on repeated
    # singular values here, where any basis of the repeated subspace is a set of principal
    # axes: CORA's came from MATLAB's LAPACK, ours is the deterministic basis of
    # observers/sets/reduction.py (the same on every BLAS kernel), which lands up to 1.5 %
    # below (tighter than) the table (x2, seed 0); kernel-chosen bases gave 0.75 % to 1.2 %.
    tab = paper_table("arch2021_table3_tank6_linear")
    expected = np.array(tab["rows"][name]["v"]) * np.array(tab["smallest_absolute_radii"])
    for seed in (0, 1):
        sc = systems.scenario("tank6-linear", seed=seed)
        res = observers.run(observers.create(name, sc.system, **sc.options), sc.u, sc.y)
        np.testing.assert_allclose(rms_radius(res.radius), expected, rtol=rtol)


def test_frad_b_textbook_equals_frad_a_for_one_output():
    # With a single output and V = sigma*B, Wang's all-strip gain on the predicted covariance
    # P = G G' is lambda = P c' / (c P c' + sigma^2): Alamo's per-strip F-radius gain.
    sc = systems.scenario("vehicle2d-cora")
    a = observers.run(observers.create("FRad-A", sc.system, **sc.options), sc.u, sc.y)
    b = observers.run(observers.create("FRad-B", sc.system, variant="textbook", **sc.options),
                      sc.u, sc.y)
    np.testing.assert_allclose(a.lo, b.lo, atol=1e-12)
    np.testing.assert_allclose(a.hi, b.hi, atol=1e-12)


def _containment(sc, name):
    res = observers.run(observers.create(name, sc.system, **sc.options), sc.u, sc.y)
    assert res.status == "ok"
    for k, S in enumerate(res.sets):
        assert S.contains(sc.x_true[k], tol=sc.tolerance), f"{name}: x_{k} outside"


@pytest.mark.parametrize("name", FRAD)
@pytest.mark.parametrize("scenario", ["vehicle6d-cora", "tank6-linear", "alamo2d-sim",
                                      "vehicle4d-sim"])
def test_true_state_inside_every_set(name, scenario):
    _containment(systems.scenario(scenario), name)


@pytest.mark.parametrize("name", FRAD)
def test_true_state_inside_hulls_on_cora_tank30(name):
    sc = systems.scenario("tank30-linear-cora")
    res = observers.run(observers.create(name, sc.system, **sc.options), sc.u, sc.y)
    assert np.all(sc.x_true >= res.lo - sc.tolerance)
    assert np.all(sc.x_true <= res.hi + sc.tolerance)
