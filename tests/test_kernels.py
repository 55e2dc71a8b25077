"""Compiled (numba) kernels of the zonotope observers give the sets of the numpy path.

:mod:`observers.sets._step_jit` runs the order reductions and the one-step formulas of the
strip and propagation families in one compiled call; ``SETOBS_NUMBA=0`` (or
:func:`observers.sets._jit.set_compiled`) selects the numpy path.  Girard's reduction is
bit-equal (same selection, the box summed in numpy's pairwise order); PCA and the step kernels
agree to rounding (numba's LAPACK/BLAS is SciPy's, numpy's its own).
"""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from observers.sets import _jit, get_reduction
from observers.sets import _step_jit as kernels

needs_numba = pytest.mark.skipif(not _jit.AVAILABLE, reason="numba not installed or disabled")
pytestmark = needs_numba


def both_paths(fn):
    """``fn()`` with the compiled kernels and with the numpy path (switch restored)."""
    old = _jit.set_compiled(True)
    try:
        compiled = fn()
        _jit.set_compiled(False)
        plain = fn()
    finally:
        _jit.set_compiled(old)
    return compiled, plain


def random_generators(seed: int) -> tuple[np.ndarray, float]:
    rng = np.random.default_rng(seed)
    n, r = int(rng.integers(1, 8)), int(rng.integers(0, 80))
    G = rng.standard_normal((n, r))
    G[:, rng.random(r) < 0.2] = 0.0  # zero columns
    if seed % 3 == 1:
        G = np.round(G)  # ties of the metric, repeated singular values
    if seed % 3 == 2:
        G = np.hstack([G, np.eye(n), 2 * np.eye(n)])  # boxes: clusters of singular values
    return G, float(rng.choice([1.0, 1.5, 2.0, 3.0, 5.0]))


@pytest.mark.parametrize("seed", range(30))
def test_girard_kernel_is_bit_equal_to_numpy(seed):
    G, order = random_generators(seed)
    red = get_reduction("girard")
    compiled, plain = both_paths(lambda: red.reduce(G, order))
    assert np.array_equal(compiled, plain)


@pytest.mark.parametrize("seed", range(30))
def test_pca_kernel_equals_numpy_to_rounding(seed):
    G, order = random_generators(seed)
    red = get_reduction("pca")
    compiled, plain = both_paths(lambda: red.reduce(G, order))
    assert compiled.shape == plain.shape
    np.testing.assert_allclose(compiled, plain, rtol=0, atol=1e-11 * max(1.0, abs(G).max()))


@pytest.mark.parametrize("seed", range(30))
def test_jacobi_principal_axes_equal_lapacks(seed):
    G, _ = random_generators(seed)
    if G.shape[1] == 0 or not np.abs(G).max() > 0:
        return
    lapack = kernels._principal_axes(G, 1e-9, 1e-6, 0)
    jacobi = kernels._principal_axes(G, 1e-9, 1e-6, 12)
    np.testing.assert_allclose(jacobi, lapack, rtol=0, atol=1e-9)
    np.testing.assert_allclose(jacobi.T @ jacobi, np.eye(G.shape[0]), atol=1e-13)


def test_reduction_kernel_leaves_non_finite_matrices_to_numpy():
    G = np.array([[1.0, np.nan, 2.0, 0.5], [0.0, 1.0, 1.0, 3.0]])
    out, ok = kernels.reduce(G, 1.0, kernels.GIRARD, 1e-9, 1e-6, 0)
    assert not ok and out.shape == (2, 0)
    compiled, plain = both_paths(lambda: get_reduction("girard").reduce(G, 1.0))
    np.testing.assert_array_equal(compiled, plain)  # the numpy path decided both


def test_pairwise_sum_is_numpys():
    rng = np.random.default_rng(3)
    for m in [*range(0, 140), 255, 256, 1000, 4099]:
        a = rng.random(m) * 10.0 ** rng.uniform(-8, 8, size=m)
        assert kernels._pairwise_sum(a, m) == a.sum()


# observer, options: every gain mode of the two kernels (GIVEN, PER_STRIP, ALAMO, WANG with
# and without the extra A, COMBASTEL, GIVEN propagation, BRAVO), both reductions
CASES = [
    ("FRad-A", {"reduction": "pca", "order": 5}),
    ("FRad-A", {"reduction": "girard", "order": 3}),
    ("FRad-B", {"reduction": "pca", "order": 5}),
    ("FRad-B", {"reduction": "girard", "order": 5, "variant": "textbook"}),
    ("FRad-C", {"reduction": "pca", "order": 5}),
    ("PRad-A", {"reduction": "girard", "order": 5}),
    ("PRad-B", {"reduction": "pca", "order": 5}),
    ("Nom-G", {"reduction": "pca", "order": 5}),
    ("VolMin-B", {"reduction": "pca", "order": 5}),
    ("VolMin-B", {"reduction": "girard", "order": 3}),
]


@pytest.mark.parametrize("scenario", ["vehicle2d-cora", "tank6-linear"])
@pytest.mark.parametrize(("name", "options"), CASES, ids=[f"{n}-{o['reduction']}"
                                                          for n, o in CASES])
def test_step_kernels_give_the_sets_of_the_numpy_path(scenario, name, options):
    sc = systems.scenario(scenario)
    try:
        obs = observers.create(name, sc.system, **options)
    except observers.DesignFailed:
        pytest.skip(f"{name} has no gain on {scenario}")
    u, y = sc.u[:25], sc.y[:26]
    compiled, plain = both_paths(lambda: observers.run(obs, u, y, on_error="status"))
    old = _jit.set_compiled(True)
    try:
        assert obs._kernel() is not None  # the compiled path really ran
    finally:
        _jit.set_compiled(old)
    assert compiled.status == plain.status
    assert len(compiled.sets) == len(plain.sets) > 1
    for Sc, Sp in zip(compiled.sets, plain.sets, strict=True):
        assert Sc.G.shape == Sp.G.shape
        scale = max(1.0, float(np.abs(Sp.G).max()), float(np.abs(Sp.c).max()))
        np.testing.assert_allclose(Sc.c, Sp.c, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(Sc.G, Sp.G, rtol=0, atol=1e-10 * scale)


def test_nonlinear_systems_and_other_reductions_keep_the_numpy_path():
    sc = systems.scenario("tank6-nonlinear")
    obs = observers.create("FRad-A", sc.system)
    obs.reset()
    assert obs._kernel() is None
