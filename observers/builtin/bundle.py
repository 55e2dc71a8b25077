"""ZB-A: the zonotope-bundle observer (mathematics in :mod:`observers.numerics.bundle`)."""

from __future__ import annotations

from time import perf_counter

import numpy as np

from ..base import Observer
from ..enclosures import Smooth, first_order
from ..errors import Diverged
from ..families import as_zonotope
from ..numerics.bundle import MEMBER_STRATEGIES, member_gain
from ..options import Integer, zonotope_order
from ..registry import register
from ..sets import HullLP, Zonotope, ZonotopeBundle, get_reduction


@register(
    "ZB-A", family="strip", set_type="bundle", ready_for_control=False,
    reference="Althoff, Krogh, IEEE CDC-ECC 2011 (zonotope bundles); Alamo, Bravo, Camacho, "
              "Automatica 41(6), 2005 and Wang, Puig, Cembrano, Automatica 93, 2018 (gains)",
)
class ZonotopeBundleObserver(Observer):
    r"""Zonotope bundle: members with different gains and reductions, intersected (online).

    Prediction: ``f`` is enclosed over the interval hull of the bundle (by LP over the
    intersection, tighter than any member's box) as ``J x + d + [-rad, rad]``
    (:func:`observers.enclosures.first_order`: linearisation at the hull's midpoint, Lagrange
    remainder from the interval Hessian; ``A x + B u`` for a linear system), and every member
    ``Z_i`` becomes ``J Z_i + d + [-rad, rad] + W``: each contains ``f(x) + w`` for every ``x``
    of the intersection.  Update: the output (enclosed over the hull of the prediction if it
    is nonlinear) gives the strips ``|H x - y'| <= sigma``; each member is intersected with
    them by its own gain, then reduced by its own method (:data:`MEMBER_STRATEGIES`).

    Options
    -------
    members : int
        Number of members (1 to 4): girard + Alamo's strip-by-strip gain, PCA + the
        all-strips gain, PCA + Alamo's, girard + all-strips.
    order : float
        Zonotope order of every member after reduction.

    Notes
    -----
    The estimate is the intersection of its members
    :math:`\mathcal{Z}_i = \langle c_i, G_i \rangle` (Althoff & Krogh 2011),
    :math:`\mathcal{S}_k = \bigcap_i \mathcal{Z}_i`.  Prediction (Althoff & Rath 2021,
    Sec. 2.4, step 1), with :math:`f(x, u) \in J x + d \pm \rho` over the hull of
    :math:`\mathcal{S}_{k-1}` (:math:`J = A`, :math:`d = B u_{k-1}`, :math:`\rho = 0` on a
    linear system):

    .. math::

        c_i^p = J c_i + d + c_W, \qquad
        G_i^p = \begin{bmatrix} J G_i & G_W & \operatorname{diag}(\rho) \end{bmatrix} .

    Correction (eqs. (4)-(6)): every member is intersected with the strips
    :math:`|C x - (y_k - c_V)| \le \sigma`, :math:`\sigma = |G_V| \mathbf{1}`, by the
    parametrised enclosure of intersection method II (Sec. 3.1) with its own gain
    :math:`\Lambda_i` (:func:`~observers.numerics.bundle.member_gain`), then reduced by its
    own method:

    .. math::

        c_i^+ = c_i^p + \Lambda_i (y_k - c_V - C c_i^p), \qquad
        G_i^+ = \operatorname{reduce}_i\Bigl(\begin{bmatrix} (I - \Lambda_i C) G_i^p &
        \Lambda_i \operatorname{diag}(\sigma) \end{bmatrix}\Bigr) .

    Each member contains the intersection, hence so does the bundle; its interval hull is
    computed by LP over the intersection of the members.
    """

    REQUIRES = ("W", "V", "X0")
    OPTIONS = {"members": Integer(2, low=1, high=len(MEMBER_STRATEGIES)),
               "order": zonotope_order(20)}

    def design(self) -> None:
        s = self.system
        self.linear = bool(getattr(s, "is_linear", True))
        if self.linear:
            self.A, self.B = np.asarray(s.A, float), np.asarray(s.B, float)
        else:
            self._f = Smooth(s, "f")
        C = s.C if getattr(s, "output_is_linear", True) else getattr(s, "output_matrix", None)
        self.C = None if C is None else np.asarray(C, float)
        if self.C is None:
            self._h = Smooth(s, "h")
        self.X0 = as_zonotope(s.X0, "X0")
        self.W = as_zonotope(s.W, "W")
        V = as_zonotope(s.V, "V")
        self.cV = V.c
        self.sigma = np.abs(V.G).sum(axis=1)
        k = int(self.options["members"])
        self.strategies = MEMBER_STRATEGIES[:k]
        self.reductions = [get_reduction(r) for r, _ in self.strategies]
        self.order = float(self.options["order"])

    def reset(self) -> None:
        super().reset()
        self._bundle: ZonotopeBundle | None = None
        self._lp = HullLP()
        #: accumulated seconds per phase since the last reset
        self.phase_times = {"prediction": 0.0, "update": 0.0, "reduction": 0.0, "hull": 0.0}

    def _hull(self, B: ZonotopeBundle) -> tuple[np.ndarray, np.ndarray]:
        t0 = perf_counter()
        H = B.interval()
        self.phase_times["hull"] += perf_counter() - t0
        return np.asarray(H.lo), np.asarray(H.hi)

    def predict(self, B: ZonotopeBundle, u: np.ndarray) -> ZonotopeBundle:
        """Every member mapped by the enclosure of ``f`` over the bundle's hull, plus W."""
        if self.linear:
            J, d, rad = self.A, self.B @ u, np.zeros(self.A.shape[0])
        else:
            J, d, rad = first_order(self._f, *self._hull(B), u, self.k)
        nz = np.flatnonzero(rad > 0)
        R = np.zeros((rad.size, nz.size))
        R[nz, np.arange(nz.size)] = rad[nz]
        return J @ B + Zonotope(d + self.W.c, np.hstack([self.W.G, R]))

    def update(self, B: ZonotopeBundle, y: np.ndarray) -> ZonotopeBundle:
        """Every member intersected with the measurement strips by its own gain."""
        y = y - self.cV
        if self.C is not None:
            H, sigma = self.C, self.sigma
        else:
            H, d, rad = first_order(self._h, *self._hull(B), np.zeros(0), self.k)
            y, sigma = y - d, np.nextafter(self.sigma + rad, np.inf)
        gains = [member_gain(g, Z.G, H, sigma)
                 for Z, (_, g) in zip(B.members, self.strategies, strict=True)]
        return B.intersect_strips(H, y, sigma, gains)

    def step(self, u_prev, y) -> ZonotopeBundle:
        y = self._measurement(y)
        times = self.phase_times
        t0 = perf_counter()
        if self._bundle is None:
            B = ZonotopeBundle([self.X0] * len(self.strategies)).with_solver(self._lp)
        else:
            B = self.predict(self._bundle, self._input(u_prev))
        t1 = perf_counter()
        B = self.update(B, y)
        t2 = perf_counter()
        members = [Zonotope(Z.c, red.reduce(Z.G, self.order))
                   for Z, red in zip(B.members, self.reductions, strict=True)]
        if not all(np.all(np.isfinite(Z.G)) and np.all(np.isfinite(Z.c)) for Z in members):
            raise Diverged(f"{self.name}: non-finite member", step=self.k)
        B = ZonotopeBundle(members).with_solver(self._lp)
        times["prediction"] += t1 - t0
        times["update"] += t2 - t1
        times["reduction"] += perf_counter() - t2
        self._bundle = B
        self.k += 1
        return B
