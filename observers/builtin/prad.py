"""P-radius strip-based observers with offline gains: PRad-A, PRad-B, PRad-C-I, PRad-C-II,
PRad-D (Althoff & Rath 2021, Table 2).

All five intersect the predicted zonotope with the measurement strips using a constant gain
designed offline by an SDP (:mod:`observers.numerics.prad`; cvxpy + Clarabel, verified in numpy,
cached on disk); ``gain=`` skips the design.  PRad-A uses intersection method I (strip by
strip, one gain column per output), the others method II (all strips at once).

Relation to CORA and to the papers
----------------------------------
* **PRad-B** (Le et al., ISIC 2013) and **PRad-A** (Le et al., Automatica 2013; in CORA the
  PRad-B design applied to each output with ``C_i`` and the box of ``V_i``) are CORA's SDPs
  unchanged: fixed weights ``E'E``, ``F'F``, objective ``max tau`` with
  ``(1 - beta) P / epsilon >= tau I``, ``epsilon = norm(W) + phi'phi`` (``norm(W)``: 2-norm of
  the vector ``max(|inf W|, |sup W|)``, ``phi``: the strip half-widths), at the ``beta`` where
  CORA's bisection ends (0.9921875; the SDP is feasible for every ``beta``, so CORA's loop,
  which moves up after each feasible solve, always ends there).  Clarabel reproduces CORA's
  stored SDPT3 gain of the 2-D vehicle to ~2e-7.  PRad-B's and PRad-A's designs are the
  SDP's largest optimal ``P`` from a Riccati equation at every size (option ``method``,
  default ``auto``; :func:`~observers.numerics.prad.le_riccati`, milliseconds instead of
  minutes): the optimum of the SDP pins only the smallest eigenvalue of P, so where it is not
  a single point (the 6-tank) the SDP's answer is wherever the solver stops, and it moved by
  2.4e-2 (PRad-B) and 394 % (PRad-A) in the radii between OpenBLAS kernels; the largest
  optimal ``P`` is one point, and equals the SDP's where the optimum is unique (the 2-D
  vehicle).  Above 12 states the SDP's weights ``E'E = 1e-6 I`` of the tank systems make
  Clarabel's feasibility tolerance a relative violation of order 1e-4 of the inequality
  (tank12: ``||P^1/2 N W^-1/2|| = 1.0003`` instead of at most 1), which the Riccati solution
  meets exactly.  It also decides PRad-A's ``noGain``: where a single output leaves a mode
  that decays more slowly than ``sqrt(beta)`` uncorrected (the first four outputs of the
  12-tank chain and every larger one; the first output of the 4- and 6-state vehicles) the
  Riccati equation has no stabilising solution, so no ``P > 0`` exists; CORA's SDP returns a
  point within its tolerance there (the published rows), with which our estimates diverged
  (ARCH Table 5 publishes PRad-A as diverged at 12 tanks, noGain above; the vehicle rows of
  Automatica Table 3 were not reproduced).
* **PRad-C** and **PRad-D** are ill-posed as CORA implements them: CORA's PRad-C
  SDP maximises ``tr P`` under constraints homogeneous in ``(P, Y, G, O)`` (unbounded: any
  feasible point can be scaled up), and its PRad-D constraint ``[[I, gamma P], [gamma P, P]]
  <= 0`` is infeasible (its (1,1) block is ``I > 0``); CORA's stored gains are the last
  iterates of SDPT3 on these problems and cannot be reproduced.  CORA also has a single
  PRad-C although the Automatica paper reports PRad-C-I and PRad-C-II.  The papers
  themselves are not available to this project; the designs below keep CORA's matrix
  inequality (the P-radius decay inequality of the papers, with CORA's choices ``T = I``,
  ``N = 0`` of the descriptor form) and fix the scale and the objective so that each problem
  has a bounded optimum and a meaningful certificate:

  - **PRad-C-I** (Wang, Puig, Cembrano, Automatica 93, 2018): per-generator diagonal weights
    ``Gamma_w``, ``Gamma_v`` as decision variables (CORA's ``G``, ``O``), normalisation
    ``P >= I``, objective ``min tr(Gamma_w) + tr(Gamma_v)``: the asymptotic bound
    ``(tr Gamma)/(1 - beta)`` of the P-radius, which with ``P >= I`` bounds the squared
    Euclidean radius of the estimates; ``beta`` minimises that bound (line search).
  - **PRad-C-II** (Wang, Alamo, Puig, Cembrano, CDC 2018; the variant CORA kept as PRad-C):
    the same inequality, normalisation ``tr(Gamma_w) + tr(Gamma_v) <= 1`` (the estimates then
    end up in ``{z : z' P z <= 1/(1 - beta)}``) and CORA's trace objective turned into a
    bounded one: ``min tr(P^-1)``, the sum of the squared semi-axes of that ellipsoid (``max
    tr P`` rewards a P that is huge in one direction and singular in others: it is unbounded
    without normalisation and numerically singular with it); ``beta`` minimises
    ``tr(P^-1)/(1 - beta)`` (line search), which is also the sum over the states of the
    squared bounds of their interval radii.  C-I bounds the largest semi-axis, C-II the
    squared sum.
  - **PRad-D** (Wang, Wang, Puig, Cembrano, IEEE TAC 64(5), 2019): CORA's fixed weights
    ``alpha P``, ``(1 - alpha) beta I``, ``(1 - alpha)(1 - beta) I`` (its ``E_new``/``F_new``
    blocks), for which the P-radius tends to at most ``r = beta n_w + (1 - beta) n_v``, and
    the size constraint read as ``[[I, gamma I], [gamma I, P]] >= 0`` (``P >= gamma^2 I``)
    instead of CORA's infeasible one; maximising ``gamma`` (CORA bisects on it upwards;
    ``gamma^2`` enters linearly, so one SDP gives the limit of the bisection) minimises the
    radius bound ``sqrt(r)/gamma``.  ``beta = 0.5`` as in CORA; ``alpha`` (0.5 in CORA) is by
    default chosen by the line search, since a fixed 0.5 is infeasible whenever a mode that
    the outputs cannot correct decays more slowly than ``sqrt(0.5)`` per step (e.g. the
    unobserved last tank of the n-tank systems).

  These certified-bound designs are the ``design`` options ``radius-bound`` (C-I),
  ``ellipsoid-trace`` (C-II) and ``max-gamma`` (D); the default, ``centre``, reproduces the
  published rows (see "Known behaviour").

  Every design is verified in numpy (``P > 0`` and the decay inequality at ``Y = P Lambda``
  for the returned ``Lambda``); an infeasible or unverifiable design raises
  :class:`~observers.errors.DesignFailed` (table status ``noGain``).  The estimates are sound
  for any gain; the design only shapes their size.

Known behaviour
---------------
* PRad-B's objective pins only the smallest eigenvalue of P.  Where the optimal set is not a
  single point (the 6-tank system), gains optimal to 1e-6 give RMS radii from 0.6x to 1.1x
  those of ARCH 2021 Table 3; the table's solver stopped at one optimal point, Clarabel stops
  at another (variant ``PRad-B[sdp]``), which moves with the BLAS kernel.  PRad-B takes the
  largest optimal ``P``, unique: its 6-tank radii are 0.92x-1.04x the table's (average of
  ``v`` 1.489 against 1.507).  On the 2-D vehicle the optimum is unique.
* PRad-A's first single-output design of the 6-tank is barely feasible: the mode of the
  unmeasured tanks decays at 0.996 per step, just faster than ``sqrt(beta) = 0.99609``, so
  the least ``X = P^-1`` is huge along it (condition number 3e13) and the SDP's objective
  ``tau`` at the optimum is of order 1e-16, below any solver's tolerance: the SDP returned
  whatever point it stopped at (a spread of 394 % in the radii between OpenBLAS kernels).
  The Riccati route returns the largest optimal ``P`` and its gain as a Kalman update,
  without inverting ``X`` (the same to 1e-10 under every kernel); its 6-tank radii are
  0.65x-1.0x the published ones (ARCH 2021 Table 3 publishes SDPT3's stopping point).
* **Default design of PRad-C-I/C-II/D (``design: centre``)**: the analytic centre of CORA's cone
  at its final rate 0.9921875 (:func:`~observers.numerics.prad.centre_gain`, a damped Newton
  method in numpy).  It reproduces the published rows: 6-tank average 1.331 over the paper's
  smallest radii, 1.342 over our run's (ARCH 2021 Table 3: PRad-C 1.326, PRad-D 1.298),
  absolute radii within 4 % of the published ones on every tank.
  The three observers share this gain (CORA has one PRad-C; the noise weights that distinguish
  CORA's PRad-D drop out of the centre).  The certified-bound designs (``radius-bound``,
  ``ellipsoid-trace``, ``max-gamma``) minimise one P-radius bound, which the unmeasured last
  tank (eigenvalue 0.996, forcing ``beta >= 0.992``) dominates: their radii of the measured
  tanks are about ten times the centre's (6-tank averages 5.9, 7.1, 7.3).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import DesignFailed
from ..families import AllStripsObserver, PerStripObserver
from ..kernels import StepKernel
from ..numerics.lmi import LinearDesignProblem, cora_bisection_end
from ..numerics.prad import (
    centre_gain,
    le_gain,
    le_method,
    wang_c1_gain,
    wang_c2_gain,
    wang_d_gain,
)
from ..offline import OfflineGain
from ..options import Choice, Number
from ..registry import register


def _plant(obs: OfflineGain) -> LinearDesignProblem:
    """The matrices ``A, C, E, F`` of an offline design of ``obs``."""
    return LinearDesignProblem(obs.A, obs.C, obs.E, obs.F)


def cora_epsilon(W, sigma: np.ndarray) -> float:
    """CORA's ``epsilon = norm(W) + phi'phi`` of the PRad-A/B design; it must be positive."""
    Wi = W.interval()
    eps = float(np.linalg.norm(np.maximum(np.abs(Wi.lo), np.abs(Wi.hi))) + sigma @ sigma)
    if not eps > 0:
        raise DesignFailed("the P-radius design needs epsilon = |W| + phi'phi > 0, but the "
                           "disturbance set W and the noise set V are both the point 0")
    return eps


class _BetaTol:
    """Option ``beta_tol`` of the CORA-style designs (tolerance of the bisection on beta)."""

    OPTIONS: dict[str, Any] = {
        "beta_tol": Number(0.01, low=0, high=1, low_open=True, high_open=True)}


class _LeMethod:
    """Option ``method`` of the Le et al. designs (PRad-A, PRad-B): SDP or Riccati equation."""

    OPTIONS: dict[str, Any] = {"method": Choice("auto", ("auto", "sdp", "riccati"))}
    #: ``method="auto"`` takes the Riccati route above this many states: at every size (the
    #: unique largest optimal ``P``; the SDP where the noise set is not full-dimensional)
    RICCATI_ABOVE = 0

    def resolved_method(self) -> str:
        """The route of the design: ``method``, with ``"auto"`` resolved by
        :func:`~observers.numerics.prad.le_method` at :attr:`RICCATI_ABOVE`."""
        return le_method(self.A.shape[0], self.F, self.options["method"],  # type: ignore[attr-defined]
                         self.RICCATI_ABOVE)

    def design_params(self) -> dict[str, Any]:
        """The resolved method in the cache key, and only when it is the Riccati route (an
        SDP design keeps the key it had before the option existed)."""
        params = super().design_params()  # type: ignore[misc]
        params.pop("method", None)
        if self.resolved_method() == "riccati":
            params["method"] = "riccati"
        return params


@register(
    "PRad-A", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Le, Stoica, Alamo, Camacho, Dumur, Automatica 49(11), 2013, Sec. 4.1",
)
class PRadA(_LeMethod, _BetaTol, OfflineGain, PerStripObserver):
    r"""Strip by strip with offline P-radius gains, one single-output design per output.

    Intersection method I (Sec. 3.1 of Althoff & Rath 2021, PRad-A of its Table 2) with the
    constant gain vectors :math:`\lambda^j`, the columns of :math:`\Lambda = [\lambda^1,
    \ldots, \lambda^{n_y}]`; column :math:`j` is the P-radius design of
    :func:`~observers.numerics.prad.le_gain` for the single output :math:`C_j` with the box
    of the noise on it:

    .. math::

        \hat{\mathcal{Z}}_j = (I - \lambda^jC_j)\,c + \lambda^jy_{k,j} \oplus
        [(I - \lambda^jC_j)\,G,\ \lambda^j\sigma_j]\,\mathcal{B}^{r+1}, \qquad
        \lambda^j = P_j^{-1}Y_j.

    Options
    -------
    method : {"auto", "sdp", "riccati"}
        How each single-output design is solved (:func:`~observers.numerics.prad.le_gain`):
        CORA's SDP, or its largest optimal ``P`` from a Riccati equation
        (:func:`~observers.numerics.prad.le_riccati`: milliseconds instead of about 35 s per
        output at 30 tanks).  ``"auto"`` (default): the Riccati equation (a unique point, the
        same on every machine) whenever the noise set is full-dimensional, else the SDP.
    beta_tol : float
        Tolerance of CORA's bisection on ``beta``.
    """

    KERNEL = StepKernel.PER_STRIP
    #: 2: the Riccati route at every size (a unique point; the SDP left the 6-tank's first
    #: output wherever it stopped)
    DESIGN_VERSION = "2"

    def design_gain(self) -> np.ndarray:
        cols = []
        for i in range(self.C.shape[0]):
            F_i = np.array([[np.abs(self.F[i]).sum()]])  # generator of box(project(V, i))
            phi = np.array([abs(self.V.c[i]) + F_i[0, 0]])
            d = le_gain(LinearDesignProblem(self.A, self.C[i:i + 1], self.E, F_i),
                        cora_epsilon(self.W, phi), self.options["beta_tol"],
                        what=f"PRad-A (output {i + 1})",
                        method=self.resolved_method())
            cols.append(d.L[:, 0])
        return np.column_stack(cols)

    def strip_gain(self, G: np.ndarray, i: int) -> np.ndarray:
        return self.L[:, i]


class _ConstantAllStrips(OfflineGain, AllStripsObserver):
    """Method II with the offline gain."""

    KERNEL = StepKernel.STRIP_GIVEN

    def gain(self, c: np.ndarray, G: np.ndarray) -> np.ndarray:
        return self.L


class _Centre:
    """PRad-C-I, PRad-C-II and PRad-D with ``design: centre`` share one design (the analytic
    centre of CORA's cone at ``centre_rate()``): one cache entry, solved once per system."""

    def centre_rate(self) -> float:
        """The decay rate of the centre: where CORA's bisection on beta ends."""
        return cora_bisection_end(0.0, 1.0, self.options["beta_tol"])

    def bound_gain(self) -> np.ndarray:
        """The gain of the certified-bound design (the other ``design`` choice)."""
        raise NotImplementedError

    def design_gain(self) -> np.ndarray:
        if self.options["design"] == "centre":
            return centre_gain(_plant(self), self.centre_rate(), what=self.name).L
        return self.bound_gain()

    def design_kind(self) -> str:
        return "PRad-centre" if self.options["design"] == "centre" else self.name

    def design_params(self) -> dict[str, Any]:
        if self.options["design"] == "centre":
            return {"design": "centre", "rate": self.centre_rate()}
        return super().design_params()


@register(
    "PRad-B", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Le, Stoica, Alamo, Camacho, Dumur, ISIC 2013",
)
class PRadB(_LeMethod, _BetaTol, _ConstantAllStrips):
    r"""All strips at once with the offline P-radius gain of Le et al. (CORA's SDP, solved
    at its unique largest optimal point).

    Intersection method II (Sec. 3.1 of Althoff & Rath 2021, PRad-B of its Table 2) with a
    constant :math:`\Lambda = P^{-1}Y` from the SDP of
    :func:`~observers.numerics.prad.le_gain` (:math:`W_x = \beta P`, :math:`W_w = E^TE`,
    :math:`W_v = F^TF`, :math:`\max \tau` with
    :math:`(1 - \beta)P/\epsilon \succeq \tau I`), at the largest optimal :math:`P` (Loewner
    order) from a Riccati equation (:func:`~observers.numerics.prad.le_riccati`):

    .. math::

        \mathcal{S}_k = (I - \Lambda C)\,c^p + \Lambda y_k \oplus
        \left[(I - \Lambda C)\,G^p,\ \Lambda\operatorname{diag}(\sigma)\right]
        \mathcal{B}^{r+n_y}.

    Options
    -------
    solver : {"clarabel", "clarabel-1e-6", "scs"}
        SDP solver strategy (:data:`observers.numerics.lmi.SOLVERS`) of ``method="sdp"``.  The
        SDP's optimum is degenerate on the 6-tank system (it pins only the smallest
        eigenvalue of P): solvers, tolerances and BLAS kernels return different optimal
        gains, whose radii the tank tables list as labelled variants ``PRad-B[sdp]``,
        ``PRad-B[scs]``, ``PRad-B[clarabel-1e-6]`` to show the spread.
    method : {"auto", "sdp", "riccati"}
        The SDP (with ``solver``) or its largest optimal ``P`` from a Riccati equation
        (:func:`~observers.numerics.prad.le_riccati`); ``"auto"`` (default): the Riccati
        equation whenever the noise set is full-dimensional (a unique point, the same on
        every machine; it equals the SDP's where the optimum is unique, e.g. CORA's 2-D
        vehicle gain to 3e-7), else the SDP.
    """

    OPTIONS = {"solver": Choice("clarabel", ("clarabel", "clarabel-1e-6", "scs"))}
    #: 2: the Riccati gain returned as the Kalman update itself (not P^-1 Y)
    DESIGN_VERSION = "2"

    def design_gain(self) -> np.ndarray:
        return le_gain(_plant(self), cora_epsilon(self.W, self.sigma),
                       self.options["beta_tol"], solver=self.options["solver"],
                       method=self.resolved_method()).L


@register(
    "PRad-C-I", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Wang, Puig, Cembrano, Automatica 93, 2018",
)
class PRadCI(_Centre, _BetaTol, _ConstantAllStrips):
    r"""All strips at once with an offline P-radius gain of CORA's PRad-C inequality.

    Intersection method II (PRad-C-I of Table 2 of Althoff & Rath 2021) with a constant
    :math:`\Lambda = P^{-1}Y`, where :math:`(P, Y)` satisfy the P-radius inequality
    :math:`\mathcal{D}(P, Y) \succeq 0` (:func:`~observers.numerics.prad.le_gain`) with
    :math:`W_x = \beta P` and free diagonal :math:`W_w, W_v`, so that the P-radius of the
    estimates obeys

    .. math::

        R_k \le \beta R_{k-1} + \operatorname{tr}W_w + \operatorname{tr}W_v, \qquad
        \limsup_{k \to \infty} R_k \le \frac{\operatorname{tr}W_w + \operatorname{tr}W_v}
        {1 - \beta};

    ``design`` chooses the point of that cone (its analytic centre, or the least bound with
    :math:`P \succeq I`).

    Options
    -------
    design : {"centre", "radius-bound", "radius-bound-cora-rate"}
        ``centre`` (default): the analytic centre of CORA's PRad-C cone at its final
        ``beta = 0.9921875``, normalised by ``tr P = 1``
        (:func:`~observers.numerics.prad.centre_gain`, a numpy Newton method); it reproduces
        the PRad-C rows of ARCH 2021 Table 3 (6-tank average 1.342 against 1.326) and the
        Automatica PRad-C-II row within 22 %.  ``radius-bound``: the gain of least certified
        asymptotic radius bound with ``P >= I`` (Wang, Puig, Cembrano's weights) and a line
        search on ``beta`` (:func:`~observers.numerics.prad.wang_c1_gain`, 17-22 SDP
        solves).  ``radius-bound-cora-rate``: the same objective at CORA's final ``beta``
        (two solves); it comes closest to the Automatica PRad-C-I row of the 6-state vehicle
        (average 3.09 against 3.89; x1 3.26 against 3.24, x5 5.22 against 5.02) but not to
        the tank row (4.84 against 1.33), which the centre reproduces: the two published
        rows come from different gains.
    beta_tol : float
        Tolerance of CORA's bisection on ``beta`` (``centre`` and ``radius-bound-cora-rate``).
    """

    OPTIONS = {"design": Choice("centre", ("centre", "radius-bound", "radius-bound-cora-rate"))}
    #: "6": dependent outputs refused (their cached Newton failures are not replayed)
    DESIGN_VERSION = "6"

    def bound_gain(self) -> np.ndarray:
        rate = self.centre_rate() if self.options["design"] == "radius-bound-cora-rate" else None
        return wang_c1_gain(_plant(self), rate=rate).L


@register(
    "PRad-C-II", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Wang, Alamo, Puig, Cembrano, CDC 2018",
)
class PRadCII(_Centre, _BetaTol, _ConstantAllStrips):
    r"""All strips at once with an offline P-radius gain of CORA's PRad-C inequality.

    Intersection method II (PRad-C-II of Table 2 of Althoff & Rath 2021) with a constant
    :math:`\Lambda = P^{-1}Y` from the inequality of PRad-C-I; the ``ellipsoid-trace`` design
    normalises the weights, so that the estimates end up in the ellipsoid
    :math:`\{z \mid (z - c_k)^TP(z - c_k) \le 1/(1 - \beta)\}`, and minimises the sum of its
    squared semi-axes:

    .. math::

        \min_{P,\,Y,\,W_w,\,W_v}\ \frac{\operatorname{tr}(P^{-1})}{1 - \beta} \quad
        \text{s.t.} \quad \mathcal{D}(P, Y) \succeq 0, \quad
        \operatorname{tr}W_w + \operatorname{tr}W_v \le 1.

    Options
    -------
    design : {"centre", "ellipsoid-trace"}
        ``centre`` (default): as PRad-C-I's default (CORA has one PRad-C; ARCH 2021 Table 3
        reports one row for both).  ``ellipsoid-trace``: the gain of least bounding ellipsoid
        (trace of ``P^-1``) with a line search on ``beta``
        (:func:`~observers.numerics.prad.wang_c2_gain`).
    beta_tol : float
        Tolerance of CORA's bisection on ``beta`` (``centre`` only).
    """

    OPTIONS = {"design": Choice("centre", ("centre", "ellipsoid-trace"))}
    DESIGN_VERSION = "6"  # as PRad-C-I's

    def bound_gain(self) -> np.ndarray:
        return wang_c2_gain(_plant(self)).L


@register(
    "PRad-D", family="strip", set_type="zonotope", ready_for_control=False,
    reference="Wang, Wang, Puig, Cembrano, IEEE TAC 64(5), 2019",
)
class PRadD(_Centre, _ConstantAllStrips):
    r"""All strips at once; offline gain maximising P >= gamma^2 I for fixed noise weights.

    Intersection method II (PRad-D of Table 2 of Althoff & Rath 2021) with a constant
    :math:`\Lambda = P^{-1}Y` from the P-radius inequality with fixed weights
    (:func:`~observers.numerics.prad.wang_d_gain`):

    .. math::

        W_x = \alpha P, \quad W_w = (1 - \alpha)\beta I, \quad
        W_v = (1 - \alpha)(1 - \beta)I, \qquad \max\ \gamma^2 \text{ s.t. }
        P \succeq \gamma^2 I.

    Options
    -------
    design : {"centre", "max-gamma"}
        ``centre`` (default): the analytic centre of the cone of CORA's PRad-D inequality
        (:func:`~observers.numerics.prad.centre_gain`, a numpy Newton method; ``beta`` drops
        out); it reproduces the PRad-D row of ARCH 2021 Table 3.  ``max-gamma``: the largest
        ``P >= gamma^2 I`` (least certified radius bound,
        :func:`~observers.numerics.prad.wang_d_gain`); with CORA's ``alpha = 0.5`` (CORA's
        own objective, ``SM2 <= 0``, is infeasible for every ``gamma``) it meets the average
        of the Automatica PRad-D row of the 6-state vehicle (2.38 against 2.32; variant
        ``PRad-D[cora-alpha]`` of that table) but not its pattern (x2 5.5 against 1.002, x6
        2.0 against 6.5), and has no gain on the 6-tank system (no ``P > 0`` at that rate),
        whose ARCH row the centre reproduces.
    alpha : float or None
        Decay weight in (0, 1); ``None`` (default): ``centre`` uses CORA's end-of-bisection
        rate 0.9921875, ``max-gamma`` a line search on the radius bound.
    beta : float
        Split of the noise weight between disturbance and measurement noise, in (0, 1).
    """

    OPTIONS = {"design": Choice("centre", ("centre", "max-gamma")),
               "alpha": Number(None, low=0, high=1, low_open=True, high_open=True, allow_none=True),
               "beta": Number(0.5, low=0, high=1, low_open=True, high_open=True)}
    DESIGN_VERSION = "6"  # as PRad-C-I's

    def centre_rate(self) -> float:
        alpha = self.options["alpha"]
        return cora_bisection_end() if alpha is None else float(alpha)

    def bound_gain(self) -> np.ndarray:
        o = self.options
        return wang_d_gain(_plant(self), alpha=o["alpha"], beta=o["beta"]).L
