"""Compiled (numba) kernels of the zonotope observers give the sets of the numpy path.

:mod:`observers.kernels.step` runs the order reductions and the one-step formulas of the
strip and propagation families in one compiled call; ``SETOBS_NUMBA=0`` (or
:func:`observers.kernels.switch.set_compiled`) selects the numpy path.  Girard's reduction is
bit-equal (same selection, the box summed in numpy's pairwise order); PCA and the step kernels
agree to rounding (numba's LAPACK/BLAS is SciPy's, numpy's its own).  Each compiled formula
carries the name of its numpy twin, and the twins are compared one to one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import observers
import systems
from observers import families
from observers.kernels import KernelByOption, StepKernel, switch
from observers.kernels import step as kernel_step
from observers.numerics import frad, volmin
from observers.sets import get_reduction

needs_numba = pytest.mark.skipif(not switch.AVAILABLE, reason="numba not installed or disabled")
pytestmark = needs_numba


def both_paths(fn):
    """``fn()`` with the compiled kernels and with the numpy path (switch restored)."""
    old = switch.set_compiled(True)
    try:
        compiled = fn()
        switch.set_compiled(False)
        plain = fn()
    finally:
        switch.set_compiled(old)
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
    lapack = kernel_step._principal_axes(G, 1e-9, 1e-6, 0)
    jacobi = kernel_step._principal_axes(G, 1e-9, 1e-6, 12)
    np.testing.assert_allclose(jacobi, lapack, rtol=0, atol=1e-9)
    np.testing.assert_allclose(jacobi.T @ jacobi, np.eye(G.shape[0]), atol=1e-13)


def test_reduction_kernel_leaves_non_finite_matrices_to_numpy():
    G = np.array([[1.0, np.nan, 2.0, 0.5], [0.0, 1.0, 1.0, 3.0]])
    out, ok = kernel_step.reduce(G, 1.0, kernel_step.REDUCTIONS["girard"], 1e-9, 1e-6, 0)
    assert not ok and out.shape == (2, 0)
    compiled, plain = both_paths(lambda: get_reduction("girard").reduce(G, 1.0))
    np.testing.assert_array_equal(compiled, plain)  # the numpy path decided both


def test_pairwise_sum_is_numpys():
    rng = np.random.default_rng(3)
    for m in [*range(0, 140), 255, 256, 1000, 4099]:
        a = rng.random(m) * 10.0 ** rng.uniform(-8, 8, size=m)
        assert kernel_step._pairwise_sum(a, m) == a.sum()


# -- the compiled formulas against their numpy twins, one to one ------------------------------
def _problem(seed: int, m: int = 2):
    """A random zonotope ``(c, G)``, strips ``(C, y, sigma)``, ``A``, ``E``, ``F``, a gain."""
    rng = np.random.default_rng(seed)
    n, r = 4, 9
    c, G = rng.standard_normal(n), rng.standard_normal((n, r))
    C = rng.standard_normal((m, n))
    y = C @ c + 0.3 * rng.standard_normal(m)
    sigma = 0.1 + rng.random(m)
    A = np.eye(n) + 0.2 * rng.standard_normal((n, n))
    E, F = 0.1 * rng.standard_normal((n, 3)), np.diag(sigma)
    L = 0.3 * rng.standard_normal((n, m))
    return c, G, C, y, sigma, A, E, F, L


def _close(compiled, plain):
    scale = max(1.0, float(np.abs(plain).max(initial=0.0)))
    np.testing.assert_allclose(compiled, plain, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("seed", range(5))
def test_strip_update_twin(seed):
    c, G, C, y, sigma, _, _, _, L = _problem(seed)
    for got, want in zip(kernel_step.strip_update(c, G, L, C, y, sigma),
                         families.strip_update(c, G, L, C, y, sigma), strict=True):
        _close(got, want)


@pytest.mark.parametrize("seed", range(5))
def test_propagate_twin(seed):
    c, G, C, y, sigma, A, E, F, L = _problem(seed)
    d, V, W = np.arange(4.0), (0.1 * np.ones(2), F), (0.2 * np.ones(4), E)
    for got, want in zip(kernel_step.propagate((c, G), (A, d), C, L, y, V, W),
                         families.propagate((c, G), (A, d, None), C, L, y, V, W), strict=True):
        _close(got, want)


@pytest.mark.parametrize(("seed", "m"), [(0, 1), (1, 2), (2, 3), (3, 2)])
def test_alamo_frad_strips_twin(seed, m):
    c, G, C, y, sigma, *_ = _problem(seed, m)
    for got, want in zip(kernel_step.alamo_frad_strips(c, G, C, y, sigma),
                         frad.alamo_frad_strips(c, G, C, y, sigma), strict=True):
        _close(got, want)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("cora", [True, False], ids=["A", "A=None"])
def test_wang_frad_gain_twin(seed, cora):
    _, G, C, _, _, A, E, F, _ = _problem(seed)
    P = G @ G.T
    got, ok = kernel_step.wang_frad_gain(P, A if cora else None, C, E, F)
    assert ok
    _close(got, frad.wang_frad_gain(P, A if cora else None, C, E, F))


@pytest.mark.parametrize("seed", range(5))
def test_combastel_gain_twin(seed):
    _, G, C, _, _, A, _, F, _ = _problem(seed)
    P = G @ G.T
    got, ok = kernel_step.combastel_gain(P, A, C, F)
    assert ok
    _close(got, frad.combastel_gain(P, A, C, F))


def test_compiled_gains_decline_what_the_numpy_path_must_decide():
    _, G, C, _, _, A, E, F, _ = _problem(0)
    P = G @ G.T
    P[0, 0] = np.nan
    assert not kernel_step.wang_frad_gain(P, A, C, E, F)[1]
    assert not kernel_step.combastel_gain(P, A, C, F)[1]
    zero = np.zeros((4, 4))  # S = C 0 C' + 0: singular, numpy takes the pseudo-inverse
    assert not kernel_step.combastel_gain(zero, A, C, np.zeros((2, 2)))[1]


@pytest.mark.parametrize("seed", range(8))
def test_bravo_choice_and_update_twins(seed):
    c, G, C, y, sigma, *_ = _problem(seed, 1)
    row = C[0]
    basis = volmin.null_basis(row)
    j = kernel_step.bravo_choice(G, row.copy(), sigma[0], basis, volmin.ZERO_PROJECTION)
    assert j == volmin.bravo_choice(G, row, sigma[0], basis)
    for jj in {0, j, 1 + seed % G.shape[1]}:
        for got, want in zip(kernel_step.bravo_update(c, G, row @ G, row, y[0], sigma[0], jj),
                             volmin.bravo_update(c, G, row, y[0], sigma[0], jj), strict=True):
            _close(got, want)


def test_every_kernel_is_compiled_and_declared_by_an_observer():
    assert set(kernel_step.KERNEL_NAMES) == {k.value for k in StepKernel}
    declared = set()
    for name in observers.names():
        kernel = getattr(observers.get(name).cls, "KERNEL", None)
        if isinstance(kernel, KernelByOption):
            declared.update(k for _, k in kernel.choices)
        elif kernel is not None:
            declared.add(kernel)
    assert declared == set(StepKernel)


# observer, options: every kernel (strip with a given gain, per strip, Alamo, Wang with and
# without the extra A, Combastel, propagation with a given gain, Bravo), both reductions
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
    compiled, plain = _both_runs(obs, sc.u[:25], sc.y[:26])
    assert compiled.status == plain.status
    assert len(compiled.sets) == len(plain.sets) > 1


def _both_runs(obs, u, y):
    """The runs of ``obs`` by the compiled kernels and by the numpy path, after checking
    that the kernels really ran in the first and not in the second, and that their sets agree
    to 1e-10 of their scale."""
    runs = []

    def run():
        res = observers.run(obs, u, y, on_error="status")
        runs.append(obs._kernel_run)
        return res

    compiled, plain = both_paths(run)
    assert runs[0] is not None and runs[1] is None  # the compiled path really ran, then not
    for Sc, Sp in zip(compiled.sets, plain.sets, strict=True):
        assert Sc.G.shape == Sp.G.shape
        scale = max(1.0, float(np.abs(Sp.G).max()), float(np.abs(Sp.c).max()))
        np.testing.assert_allclose(Sc.c, Sp.c, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(Sc.G, Sp.G, rtol=0, atol=1e-10 * scale)
    return compiled, plain


ONE_SIGNATURE = """
import observers, systems
from observers.kernels import step as ks
from systems import NonlinearSystem
from tests.test_kernels import CASES, NONLINEAR_CASES


def frozen_jacobian(x, u):  # a user's Jacobian that returns read-only arrays
    J, Bu = base.jacobian(x, u)
    J.setflags(write=False)
    return J, Bu


for scenario, cases in (("vehicle2d-cora", CASES), ("tank6-nonlinear", NONLINEAR_CASES),
                        ("vanderpol-sim", NONLINEAR_CASES)):
    sc = systems.scenario(scenario)
    for name, options in cases:
        observers.run(observers.create(name, sc.system, **options), sc.u[:4], sc.y[:4])
sc = systems.scenario("tank6-nonlinear")
base = sc.system
user = NonlinearSystem(base._f, base.n, base.nu, base.C, W=base.W, V=base.V, X0=base.X0,
                       jacobian=frozen_jacobian, hessian=base.hessian, domain=(0.0, float("inf")),
                       name="user-tank6")
for name, options in NONLINEAR_CASES:
    observers.run(observers.create(name, user, **options), sc.u[:4], sc.y[:4])
for k in (ks.strip_step, ks.propagate_step, ks.strip_first, ks.predict_linearised,
          ks.strip_predicted, ks.propagate_linearised):
    print(k.py_func.__name__, len(k.signatures))
"""


def test_each_kernel_is_compiled_once():
    """Every observer passes arguments of the same types (one signature per kernel), on a
    linear and on nonlinear systems, also a user's system whose Jacobian returns read-only
    arrays (bug: passed as they were, they compiled the linearised kernels once more).  In a
    process of its own: the count covers only the systems above."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", ONE_SIGNATURE], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).parents[1]).stdout.split()
    counts = dict(zip(out[::2], out[1::2], strict=True))
    assert len(counts) == 6 and set(counts.values()) == {"1"}, counts


def test_the_kernel_follows_the_option_it_depends_on():
    sc = systems.scenario("vehicle2d-cora")
    cora = observers.create("FRad-B", sc.system)
    textbook = observers.create("FRad-B", sc.system, variant="textbook")
    assert (cora._step_kernel, textbook._step_kernel) == (StepKernel.WANG_CORA, StepKernel.WANG)


# observer, options on a nonlinear system: every kernel of an observer that linearises
# (Alamo, Wang with and without the extra A, Combastel, Bravo), both reductions
NONLINEAR_CASES = [
    ("FRad-A", {"reduction": "pca", "order": 5}),
    ("FRad-A", {"reduction": "girard", "order": 6}),
    ("FRad-B", {"reduction": "pca", "order": 5}),
    ("FRad-B", {"reduction": "girard", "order": 5, "variant": "textbook"}),
    ("FRad-C", {"reduction": "pca", "order": 5}),
    ("FRad-C", {"reduction": "girard", "order": 10, "remainder": "zonotope"}),
    ("VolMin-B", {"reduction": "pca", "order": 5}),
]


@pytest.mark.parametrize("scenario", ["tank6-nonlinear", "vanderpol-sim"])
@pytest.mark.parametrize(("name", "options"), NONLINEAR_CASES,
                         ids=[f"{n}-{o['reduction']}-{o.get('remainder', 'box')}"
                              for n, o in NONLINEAR_CASES])
def test_step_kernels_on_a_linearisation_give_the_sets_of_the_numpy_path(
        scenario, name, options):
    # issue 37: on a nonlinear system every step ran in numpy (BLAS products, LAPACK solves),
    # and ARCH Table 6's 18-30-tank rows moved by up to 7.6 % between OpenBLAS kernels; the
    # kernels now run the update and the reduction on each step's linearisation
    sc = systems.scenario(scenario)
    obs = observers.create(name, sc.system, **options)
    compiled, plain = _both_runs(obs, sc.u[:30], sc.y[:31])
    assert compiled.status == plain.status == "ok"
    assert len(compiled.sets) == len(plain.sets) == 31


def test_the_linearised_kernels_run_every_step_after_the_first(monkeypatch):
    # the numpy update and reduction never run on a nonlinear system with a linear output
    sc = systems.scenario("tank6-nonlinear")

    def numpy_path(*args, **kwargs):
        raise AssertionError("a step went to the numpy path")

    old = switch.set_compiled(True)
    try:
        for name in ("FRad-A", "FRad-B", "VolMin-B"):
            cls = observers.get(name).cls
            with monkeypatch.context() as m:
                m.setattr(cls, "intersect", numpy_path)
                obs = observers.create(name, sc.system, reduction="pca", order=5)
                m.setattr(obs, "_reduce", numpy_path)
                assert observers.run(obs, sc.u[:12], sc.y[:13]).status == "ok"
        obs = observers.create("FRad-C", sc.system, reduction="pca", order=5)
        monkeypatch.setattr(obs, "gain", numpy_path)
        assert observers.run(obs, sc.u[:12], sc.y[:13]).status == "ok"
    finally:
        switch.set_compiled(old)


def test_other_reductions_and_nonlinear_outputs_keep_the_numpy_path():
    sc = systems.scenario("tank6-nonlinear")
    assert observers.create("FRad-A", sc.system)._step_kernel is StepKernel.ALAMO
    sc = systems.scenario("robot-range")  # a nonlinear output: C changes at every step
    assert observers.create("FRad-A", sc.system)._step_kernel is None

    class Halve:
        name = "halve"

        def reduce(self, G, order):
            return get_reduction("girard").reduce(G, order)

    sc = systems.scenario("vehicle2d-cora")
    assert observers.create("FRad-A", sc.system, reduction=Halve())._step_kernel is None
    assert observers.create("FRad-A", sc.system)._step_kernel is StepKernel.ALAMO


def test_near_ties_go_by_index_in_both_paths():
    # issue 37: scores that tie in exact arithmetic differ in the last bits by the BLAS
    # kernel (VolMin-B's best two on the 2-state vehicle: 4e-16 relative); within 1e-9 the
    # first index wins, beyond it the least value, in the numpy and the compiled rule alike
    from observers.numerics.linalg import first_best

    for scores, want in (([2.0, 1.0 + 4e-16, 1.0, 3.0], 1), ([2.0, 1.0 + 1e-6, 1.0], 2),
                         ([5.0, 5.0], 0), ([3.0, -2.0, -2.0 - 1e-15], 1)):
        assert first_best(np.array(scores)) == want, scores
        assert kernel_step._least(np.array(scores)) == want, scores


def test_reduction_ignores_the_rounding_noise_of_axis_aligned_generators():
    # issue 37: an axis-aligned generator has ||g||_1 - ||g||_inf = 0, and where its other
    # entry is the rounding noise of a zero (1e-18 on one BLAS kernel, 0 on another) that
    # noise used to pick the generators to reduce (VolMin-B, 2-state vehicle, order 4: 1.6 %);
    # the band is now floored by the largest generator, so the noise cannot order them
    base = np.array([[1.0, 0.5, 2.0, 0.3, 1.5, 0.7, 3.0, 0.6],
                     [0.0, 0.4, 0.0, 0.2, 0.0, 0.9, 0.0, 0.5]])
    aligned = [0, 2, 4, 6]  # order 3.5 in 2-D: 5 kept, the 3 least metrics reduced (3 of these)
    noises = ([8.7e-19, 0.0, 6.9e-18, 0.0], [0.0, 6.9e-18, 8.7e-19, 1e-18],
              [0.0, 0.0, 0.0, 0.0])
    outs = {}
    for path in ("numpy", "compiled") if switch.AVAILABLE else ("numpy",):
        previous = switch.set_compiled(path == "compiled")
        try:
            for i, noise in enumerate(noises):
                G = base.copy()
                G[1, aligned] = noise
                outs[path, i] = get_reduction("girard").reduce(G, 3.5)
        finally:
            switch.set_compiled(previous)
    # the first three aligned columns (by index) are boxed, the fourth kept, whatever the noise
    want = np.hstack([base[:, [1, 3, 5, 6, 7]], np.diag([1.0 + 2.0 + 1.5, 0.0])])
    for out in outs.values():
        np.testing.assert_allclose(out, want, atol=1e-15)


def _index_order(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A @ B`` with every entry summed term by term in index order, in Python floats."""
    out = np.zeros((A.shape[0], B.shape[1]))
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            acc = 0.0
            for s in range(A.shape[1]):
                acc += float(A[i, s]) * float(B[s, j])
            out[i, j] = acc
    return out


def test_products_of_the_kernels_are_summed_in_index_order_up_to_their_bound():
    # issue 37: the kernels' products went to BLAS, whose kernels order the sums by CPU, and
    # FRad-A/B on 30 tanks moved by up to 1.7e-2 between kernels.  Up to FIXED_ORDER_MAX_DIM
    # every entry is the plain left-to-right sum, exactly (no reordering, no fused
    # multiply-add: the same bits on every machine); above it BLAS, equal to rounding
    rng = np.random.default_rng(37)
    bound = kernel_step.FIXED_ORDER_MAX_DIM
    for m, k, q in [(6, 40, 5), (bound, 3 * bound, bound), (1, 200, 3), (bound, bound, 700)]:
        A, B = rng.standard_normal((m, k)), rng.standard_normal((k, q))
        want, b = _index_order(A, B), np.ascontiguousarray(B[:, 0])
        assert np.array_equal(kernel_step._mm(A, B), want)
        gram = kernel_step._gram(A)
        assert np.array_equal(gram, _index_order(A, A.T)) and np.array_equal(gram, gram.T)
        assert np.array_equal(kernel_step._mv(A, b), want[:, 0])
        assert np.array_equal(kernel_step._vm(A[0], B), want[0])
        assert kernel_step._vv(A[0], b) == want[0, 0]
        assert np.array_equal(kernel_step.matvec(A, b), want[:, 0])
    A, B = rng.standard_normal((bound + 1, bound + 2)), rng.standard_normal((bound + 2, 40))
    A2 = rng.standard_normal((bound + 1, bound + 1))
    np.testing.assert_allclose(kernel_step._mm(A, B), A @ B, rtol=0, atol=1e-12)
    np.testing.assert_allclose(kernel_step._mm(A2, A2), A2 @ A2, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["FRad-A", "FRad-B", "PRad-B", "VolMin-B"])
def test_the_first_set_of_a_strip_observer_is_the_kernels_update_of_x0(name, monkeypatch):
    # the first set (X0 intersected with y[0]) went to the numpy path and its BLAS products
    # while every later step ran in the kernel; now the kernel's update makes it too, and it
    # is the numpy path's set up to rounding
    sc = systems.scenario("tank6-linear")

    def first_set():
        return observers.create(name, sc.system, reduction="pca", order=5).step(
            np.zeros(sc.u.shape[1]), sc.y[0])

    compiled, plain = both_paths(first_set)
    scale = max(1.0, float(np.abs(plain.G).max()), float(np.abs(plain.c).max()))
    assert compiled.G.shape == plain.G.shape
    np.testing.assert_allclose(compiled.c, plain.c, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(compiled.G, plain.G, rtol=0, atol=1e-12 * scale)

    def numpy_path(*args, **kwargs):
        raise AssertionError("the first set went to the numpy path")

    cls = observers.get(name).cls
    monkeypatch.setattr(cls, "intersect", numpy_path)
    old = switch.set_compiled(True)
    try:
        first_set()  # made by the kernel alone: the numpy intersection never runs
    finally:
        switch.set_compiled(old)


@pytest.mark.parametrize("shape", [(3, 10), (6, 50), (5, 5), (30, 900)])
def test_householder_factor_has_the_gram_matrix_and_the_axes_of_the_columns(shape):
    """The Jacobi axes of a wide deviation set run on the ``n x n`` Householder factor (the
    order-one reduction of a nonlinear remainder has ``k`` near ``100 n`` columns): ``L`` is
    lower triangular with ``L L' = red red'`` (also with a zero row and a tiny one), and the
    axes span the SVD's singular subspaces."""
    from observers.sets.reduction import CLUSTER_RTOL, PIVOT_RTOL

    rng = np.random.default_rng(7)
    red = rng.standard_normal(shape)
    red[1] *= 1e-9
    if shape[0] > 3:
        red[2] = 0.0
    L = kernel_step._householder_lower(red)
    gram = red @ red.T
    assert np.array_equal(L, np.tril(L))
    np.testing.assert_allclose(L @ L.T, gram, rtol=0, atol=1e-14 * np.abs(gram).max())
    U = kernel_step.principal_axes(red, CLUSTER_RTOL, PIVOT_RTOL, kernel_step.JACOBI_MAX_DIM)
    np.testing.assert_allclose(U.T @ U, np.eye(shape[0]), atol=1e-13)
    V, s, _ = np.linalg.svd(red)
    big = s > 1e-6 * s[0]  # well-separated singular values: each axis is one of the SVD's
    np.testing.assert_allclose(np.abs(U[:, big].T @ V[:, big]).max(axis=0), 1.0, atol=1e-10)
