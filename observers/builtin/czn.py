"""Constrained-zonotope observers CZN-A (Scott et al. 2016) and CZN-B (Alanwar et al.).

Both predict ``A S + B u + W``, intersect *exactly* with the measurement set of ``y[k]``
(the constraints keep what a zonotope would lose), then reduce the order with CORA's lifted
reduction.  They differ only in the parametrisation of the intersection:

* CZN-A: generalised intersection with ``{x : y - C x in V}`` (Scott et al., Prop. 1);
* CZN-B: intersection with the strips ``|C x - y| <= sigma`` written with the F-radius gain
  of Wang et al. (Alanwar et al., arXiv 2010.11097), which shapes the generators that the
  later reductions act on.

Beyond CORA (which lets the number of constraints grow by m per step, so that the LPs of the
interval hull grow without bound), the option ``max_constraints`` bounds it (default: the
constraints of the last two measurements, ``2 m``): the prediction is reduced first, the
intersection with ``y[k]`` is exact, then the box of the generator variables is shrunk to the
bounds the constraints imply (exact), and the oldest surplus constraints are folded into the
generators and the newer constraints by a least-squares shear of the lifted zonotope and
dropped
(:func:`observers.sets.conzono_ops.fold_constraints`).  The newest measurements stay exact;
what an old measurement told is kept as far as a zonotope update with an F-radius gain keeps
it.  ``max_constraints=None`` gives CORA's behaviour (and order of operations: intersect,
then reduce), which the conformance tests use.

Interval hulls: every returned set carries the observer's :class:`~observers.sets.HullLP`,
so the runner's ``S.interval()`` solves its 2n LPs together with the batched dual simplex of
:mod:`observers.lp.dual_simplex` (compiled by numba when available; HiGHS, kept alive across
steps, for an LP it does not finish and for sets with more than
:data:`~observers.lp.hull.BATCHED_MAX_ROWS` constraints); every bound is the weak-duality
bound of a dual point, hence sound whatever the solver does.
"""

from __future__ import annotations

from abc import abstractmethod
from time import perf_counter

import numpy as np

from ..enclosures import DC_MAX_STATES, ENCLOSURES, Smooth
from ..errors import OptionError, Unsupported
from ..families import Linearised, ZonotopeObserver
from ..options import Choice, Integer, Number
from ..prediction import box_generators
from ..registry import register
from ..sets import ConZonotope, HullLP, HullLPStats, get_reduction
from ..sets import conzono_ops as ops
from .frad import WangGainVariant

#: relative half-width of the strip of an output measured without noise
#: (:meth:`ConZonotopeStripObserver._widen_noise_free_outputs`)
NOISE_FREE_MARGIN = 1e-9
#: default bound on the number of constraints, as a multiple of the number of outputs m
DEFAULT_CONSTRAINT_STEPS = 2
#: most generators whose box :meth:`ConZonotopeStripObserver.lp_rescale` computes by LPs (2 per
#: generator and step; beyond it the interval rescaling of the constraint folding alone)
LP_RESCALE_MAX_GENERATORS = 100
#: most constraints of a set rescaled by LPs (the batched simplex slows down with the rows)
LP_RESCALE_MAX_ROWS = 64
#: boxes of the nonlinear enclosures (option ``enclosure_box``)
ENCLOSURE_BOXES = ("zonotope", "hull")
#: the affine enclosure matching a prediction strategy, for ``enclosure_box="hull"``
_ENCLOSURE_OF = {"lagrange": "first-order", "mean-value": "mean-value"}


class ConZonotopeStripObserver(Linearised, ZonotopeObserver):
    """Shared loop: predict, intersect exactly, bound the constraints, lifted reduction.

    Nonlinear systems: by default (option ``enclosure_box="zonotope"``) the prediction
    linearises at the centre of the constrained zonotope and encloses the remainder over the
    interval hull of its zonotope ``(c, G)`` (a superset of the constrained zonotope, so the
    enclosure stays sound).  With ``enclosure_box="hull"`` (the estimators of Rego et al.)
    the enclosures are taken over the interval hull of the constrained zonotope itself (2n
    LPs; the hull of the previous estimate is the one the runner computes anyway) at its
    midpoint, and after each update the set is re-parametrised by the exact least-squares
    shear ``(c + L b, G - L A)``, ``L = G A' (A A')^+``, which keeps the zonotope part
    ``(c, G)`` close to the set, so that the later reductions and constraint eliminations
    lose little (with the zero gain of CZN-A the generators keep the predicted set's size and
    only the constraints carry the measurements).  A nonlinear output is used through the exact
    generalised intersection with the measurement set of its enclosure (see
    :meth:`update`).

    Each step is timed by phase in ``phase_times`` (seconds since :meth:`reset`):
    ``prediction``, ``update``, ``reduction`` and ``hull`` (the interval hulls computed
    inside the step, not counted in the other phases).

    Options
    -------
    order, reduction
        Order and zonotope strategy of the lifted reduction (as CORA).
    enclosure_box : {"zonotope", "hull"}
        Box of the nonlinear enclosures (see above); nonlinear systems only.
    max_constraints : int, "auto" or None
        Bound on the number of constraints kept after each step; ``"auto"`` is ``2 m`` (the
        measurements of the last two steps), ``None`` keeps all of them (CORA: m more per
        step, with CORA's order of intersection and reduction).
    max_generators : int or None
        Bound on the number of generators after each step (the generator limit of Rego et
        al.'s papers); ``None`` (default): the order alone bounds them.  With a bound, the
        prediction and the update are each followed by the constraint bound and then a lifted
        reduction to at most ``max_generators`` generators, which must be at least
        ``n + max_constraints``.
    hull_solver : {"auto", "batched", "highs", "sifting", "sifting-highs"}
        LP solver of the interval hulls and support values of the returned sets
        (:class:`~observers.sets.HullLP`; ``"auto"``: sifting for many generators per
        constraint, the batched dual simplex for few constraints, else HiGHS;
        ``"sifting-highs"``: sifting with HiGHS for the working sets); the bounds are sound
        with each of them.
    margin : float
        Relative enlargement of the noise set in the exact intersection (default 1e-7).  An
        exact intersection keeps the true state on the boundary of the estimate when the
        noise sits on the vertices of V and W (found by the adversarial soundness audit), and
        floating-point rounding (~1e-16 relative) of the constraint data can then cut it off
        or make the set empty.  With the margin the true state lies strictly inside every
        measurement set, by far more than the rounding.  ``0`` is CORA's exact behaviour.
    """

    NONLINEAR_OUTPUT = True
    #: affine enclosure of nonlinear dynamics (:data:`observers.enclosures.ENCLOSURES`);
    #: ``None``: the observer's prediction strategy (``LINEARISATION``)
    ENCLOSURE: str | None = None

    OPTIONS = {
        "enclosure_box": Choice("zonotope", ENCLOSURE_BOXES),
        "max_constraints": Integer("auto", low=0, allow_none=True, special=("auto",)),
        "max_generators": Integer(None, low=1, allow_none=True),
        "hull_solver": Choice("auto", HullLP.SOLVERS),
        "margin": Number(1e-7, low=0, high=1e-3, high_open=True),
    }

    def design(self) -> None:
        super().design()
        # every reduction here acts on the lifted zonotope (ops.lifted_reduce takes the
        # strategy's variant for it)
        self._reduction = get_reduction(self.options["reduction"])
        k = self.options["max_constraints"]
        m = self.V.dim
        self.max_constraints = DEFAULT_CONSTRAINT_STEPS * m if k == "auto" else k
        self.max_generators = self.options["max_generators"]
        who = self.name or type(self).__name__
        n = self.X0.dim
        if self.max_generators is not None:
            if self.max_constraints is None:
                raise OptionError(f"{who}: max_generators needs a bound on the constraints "
                                  "(max_constraints)")
            if self.max_generators < n + self.max_constraints:
                raise OptionError(
                    f"{who}: max_generators={self.max_generators} is below n + "
                    f"max_constraints = {n + self.max_constraints} (a lifted reduction keeps "
                    "at least one generator per state and constraint)")
        if self.ENCLOSURE == "dc" and not self.prediction.exact and n > DC_MAX_STATES:
            raise Unsupported(f"{who}: the DC enclosure enumerates the 2^n vertices of a box "
                              f"(n = {n} > {DC_MAX_STATES})")
        self._dynamics = Smooth(self.system, "f")
        self._hull_box = self.options["enclosure_box"] == "hull" and not (
            self.prediction.exact and self.output_linear)
        inflate = 1.0 + float(self.options["margin"])
        self._inflate = inflate
        self.F_meas = self.F * inflate  # noise generators of the measurement set
        self.sigma_meas = self.sigma * inflate  # strip half-widths
        if self.output_linear:
            self._widen_noise_free_outputs()
        self._F_meas0, self._sigma_meas0 = self.F_meas, self.sigma_meas

    def _widen_noise_free_outputs(self) -> None:
        """An output measured without noise (a strip of zero width) is an equality constraint
        that the hull LPs decided by the rounding of the set's data: on a 3-state plant every
        CZN observer ended ``empty`` at step 36 (the edge-case audit).  Its strip is widened
        outward to :data:`NOISE_FREE_MARGIN` times the output's magnitude over ``X0``
        (``|C_i| |x0| + |c_V,i|``), which keeps the set sound (a superset) and changes nothing
        for an output with noise."""
        flat = self.sigma_meas <= 0
        if not flat.any():
            return
        x0 = self.X0.interval()
        reach = np.maximum(np.abs(x0.lo), np.abs(x0.hi))
        scale = np.abs(self.C) @ reach + np.abs(self.V.c)
        floor = NOISE_FREE_MARGIN * np.where(scale > 0, scale, 1.0)
        self.sigma_meas = np.where(flat, floor, self.sigma_meas)
        self.F_meas = np.hstack([self.F_meas, np.diag(floor)[:, flat]])

    def reset(self) -> None:
        super().reset()
        self._state: tuple[np.ndarray, ...] | None = None
        self._set: ConZonotope | None = None
        self._lp = HullLP(self.options["hull_solver"])
        self.phase_times["hull"] = 0.0

    @property
    def hull_stats(self) -> HullLPStats:
        """Work of the interval-hull LPs of the sets returned since the last :meth:`reset`
        (a run): LPs solved, simplex iterations, LPs handed to HiGHS."""
        return self._lp.stats

    @abstractmethod
    def intersect(self, c, G, A, b, y):
        """Exact intersection of ``(c, G, A, b)`` with the measurement set of ``y``."""

    # -- phases -----------------------------------------------------------------------------
    def enclosure_box(self, c, G, A, b, S: ConZonotope | None = None):
        """``(lo, hi)``: the box over which nonlinear enclosures are taken (option
        ``enclosure_box``); ``S`` is the set ``(c, G, A, b)`` if already built (its hull is
        cached)."""
        if not self._hull_box or A.shape[0] == 0:
            r = np.abs(G).sum(axis=1)
            return c - r, c + r
        t0 = perf_counter()
        S = ConZonotope.trusted(c, G, A, b, self._lp) if S is None else S
        hull = S.interval()
        self.phase_times["hull"] += perf_counter() - t0
        return hull.lo, hull.hi

    def predict(self, c, G, A, b, u):
        """Enclosure of ``f(Z, u) + W`` for ``Z = (c, G, A, b)``, the estimate of the previous
        step."""
        if self.prediction.exact or (self.ENCLOSURE is None and not self._hull_box):
            # the prediction strategy linearises at the centre c (for a nonlinear system its
            # remainder box is taken over the interval hull of the zonotope (c, G), which
            # encloses the constrained zonotope)
            self.A, d, R = self.prediction(c, G, u, self.k)
        else:
            lo, hi = self.enclosure_box(c, G, A, b, self._set)
            how = self.ENCLOSURE or _ENCLOSURE_OF[self.LINEARISATION]
            self.A, d, rad = ENCLOSURES[how](self._dynamics, lo, hi, u, self.k)
            R = box_generators(rad)
        c = self.A @ c + d + self.W.c
        G = np.hstack([self.A @ G, self.E, R])
        A = np.hstack([A, np.zeros((A.shape[0], self.E.shape[1] + R.shape[1]))])
        return c, G, A, b

    def update(self, c, G, A, b, y):
        """Exact intersection with the measurement set of ``y``; for ``y = h(x) + v`` with the
        set of the enclosure ``h(x) in H x + d + [-rad, rad]`` over the box of the predicted
        set (``{x : y - d - H x in V + [-rad, rad]}``, which contains every state consistent
        with ``y``)."""
        if self.output_linear:
            return self.intersect(c, G, A, b, y)
        lo, hi = self.enclosure_box(c, G, A, b)
        H, d, rad = self.output_enclosure(lo, hi)
        self.C = H
        wide = np.nextafter(rad * self._inflate, np.inf)
        self.F_meas = np.hstack([self._F_meas0, np.diag(wide)])
        self.sigma_meas = np.nextafter(self._sigma_meas0 + wide, np.inf)
        self.F = np.hstack([self._F0, np.diag(rad)])
        return self.intersect(c, G, A, b, y - d)

    def reparametrise(self, c, G, A, b):
        """With ``enclosure_box="hull"``: the same set as ``(c + L b, G - L A)`` with the
        least-squares gain ``L = G A' (A A')^+`` (exact: ``A xi = b`` on the set)."""
        if not self._hull_box or A.shape[0] == 0:
            return c, G, A, b
        L = ops.regress(G, A)
        return c + L @ b, G - L @ A, A, b

    def lp_rescale(self, c, G, A, b):
        """The same set with the generator box shrunk to the bounds of each ``xi_j`` over the
        feasible set, from 2r LPs (Scott et al. 2016, Sec. 4.2; each bound is the sound
        weak-duality bound of a dual point, so the substitution keeps the set)."""
        nc, r = A.shape
        if nc == 0:
            return c, G, A, b
        t0 = perf_counter()
        eye = np.eye(r)
        ub = self._lp.maximize_many(np.vstack([eye, -eye]), A, b)
        self.phase_times["hull"] += perf_counter() - t0
        hi, lo = np.minimum(ub[:r], 1.0), np.maximum(-ub[r:], -1.0)
        if np.any(lo > hi):
            return c, G, A, b  # empty (or numerically so): the hull LPs will report it
        mid, rad = 0.5 * (hi + lo), np.nextafter(0.5 * (hi - lo), np.inf)
        rad = np.minimum(np.maximum(rad, np.maximum(hi - mid, mid - lo)), 1.0)
        return c + G @ mid, G * rad, A * rad, b - A @ mid

    def limit(self, c, G, A, b):
        """Bound the constraints (:func:`~observers.sets.conzono_ops.fold_constraints`, after
        :meth:`lp_rescale` with ``enclosure_box="hull"`` where the LPs are small: at most
        :data:`LP_RESCALE_MAX_ROWS` constraints and :data:`LP_RESCALE_MAX_GENERATORS`
        generators) and, with ``max_generators``, the
        generators (lifted reduction)."""
        nc, r = A.shape
        if (self._hull_box and nc > self.max_constraints and nc <= LP_RESCALE_MAX_ROWS
                and r <= LP_RESCALE_MAX_GENERATORS):
            c, G, A, b = self.lp_rescale(c, G, A, b)
        c, G, A, b = ops.fold_constraints(c, G, A, b, self.max_constraints)
        if self.max_generators is not None and G.shape[1] > self.max_generators:
            order = self.max_generators / (G.shape[0] + A.shape[0])
            c, G, A, b = ops.lifted_reduce(c, G, A, b, order, self._reduction, per="lifted")
        return c, G, A, b

    def _timed(self, phase: str, fn, *args):
        """``fn(*args)``, its time added to ``phase_times[phase]`` less the hulls inside."""
        times = self.phase_times
        h0, t0 = times["hull"], perf_counter()
        out = fn(*args)
        times[phase] += perf_counter() - t0 - (times["hull"] - h0)
        return out

    def _update(self, c, G, A, b, y):
        return self.reparametrise(*self.update(c, G, A, b, y))

    def step(self, u_prev, y) -> ConZonotope:
        y = self._measurement(y)
        timed = self._timed
        if self._state is None:  # X0 intersected with y[0], not reduced (as CORA) unless
            # there is a generator limit
            G0 = self.X0.G
            c, G, A, b = timed("update", self._update, self.X0.c, G0,
                               np.zeros((0, G0.shape[1])), np.zeros(0), y)
            if self.max_generators is not None:  # the limits hold at every step
                c, G, A, b = timed("reduction", self.limit, c, G, A, b)
        else:
            u = self._input(u_prev)
            c, G, A, b = timed("prediction", self.predict, *self._state, u)
            if self.max_constraints is None:  # CORA: intersect, then reduce
                c, G, A, b = timed("update", self._update, c, G, A, b, y)
                c, G, A, b = timed("reduction", ops.lifted_reduce, c, G, A, b, self.order,
                                   self._reduction)
            else:  # reduce the prediction, intersect exactly, fold the oldest constraints
                if self.max_generators is None:
                    c, G, A, b = timed("reduction", ops.lifted_reduce, c, G, A, b,
                                       self.order, self._reduction)
                else:
                    c, G, A, b = timed("reduction", self.limit, c, G, A, b)
                c, G, A, b = timed("update", self._update, c, G, A, b, y)
                c, G, A, b = timed("reduction", self.limit, c, G, A, b)
        self._state = (c, G, A, b)
        self.k += 1
        self._set = ConZonotope.trusted(c, G, A, b, self._lp)
        return self._set


@register(
    "CZN-A", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Scott, Raimondo, Marseglia, Braatz, Automatica 69, 2016",
)
class CZNA(ConZonotopeStripObserver):
    r"""Constrained zonotopes, exact generalised intersection with the measurement set.

    Notes
    -----
    The estimate is a constrained zonotope (Althoff & Rath 2021, Sec. 2.1; Scott et al. 2016)

    .. math::

        \langle c, G, A_c, b_c \rangle
        = \{c + G \xi \mid \|\xi\|_\infty \le 1,\ A_c \xi = b_c\},

    for the model of eq. (2), :math:`x_{k+1} = A x_k + B u_k + w_k`,
    :math:`y_k = C x_k + v_k`, with :math:`\mathcal{W} = \langle c_W, E \rangle` and
    :math:`\mathcal{V} = \langle c_V, F \rangle`.  One step:

    *Prediction* (Sec. 2.4, step 1:
    :math:`\mathcal{S}^p = A \mathcal{S}_{k-1} \oplus B u_{k-1} \oplus \mathcal{W}`), exact
    on constrained zonotopes; the generators of :math:`\mathcal{W}` are free of the constraints:

    .. math::

        c^p = A c + B u_{k-1} + c_W, \qquad
        G^p = \begin{bmatrix} A G & E & R \end{bmatrix}, \qquad
        A_c^p = \begin{bmatrix} A_c & 0 & 0 \end{bmatrix}, \qquad b_c^p = b_c .

    On a linear system :math:`R` is empty; on a nonlinear one :math:`A` and
    :math:`B u_{k-1}` are replaced by the affine enclosure :math:`J x + d` of :math:`f` (at the
    centre :math:`c`, or over the hull with ``enclosure_box="hull"``) and :math:`R` holds the
    generators of its remainder box.

    *Measurement update*: the correction of eq. (6) computed exactly, with the measurement set
    :math:`\{x \mid y_k - C x \in \mathcal{V}\}` of eq. (3) itself instead of the strips of
    eqs. (4)-(5) (Scott et al. 2016, Prop. 1, the generalised intersection with the output
    map :math:`C`): a noise factor :math:`\xi_v` joins :math:`\xi` and every output adds one
    constraint :math:`C (c^p + G^p \xi) + c_V + \tilde F \xi_v = y_k`,

    .. math::

        \mathcal{S}_k = \mathcal{S}^p \cap \{x \mid y_k - C x \in \tilde{\mathcal{V}}\}
        = \left\langle c^p,\
          \begin{bmatrix} G^p & 0 \end{bmatrix},\
          \begin{bmatrix} A_c^p & 0 \\ C G^p & \tilde F \end{bmatrix},\
          \begin{bmatrix} b_c^p \\ y_k - c_V - C c^p \end{bmatrix} \right\rangle,

    where :math:`\tilde F = (1 + \epsilon) F` and
    :math:`\tilde{\mathcal{V}} = \langle c_V, \tilde F \rangle` (option ``margin``,
    :math:`\epsilon = 10^{-7}`; :math:`\epsilon = 0` is the exact intersection of CORA).

    *Reduction* (set operations below): the lifted order reduction of
    :math:`\langle [c; -b_c], [G; A_c] \rangle` and, with ``max_constraints``, the folding of
    the oldest constraints.  With the default bound the prediction is reduced before the
    update and the constraints are folded after it; with ``max_constraints=None`` (CORA) the
    update comes first and the reduction after it.

    *Interval hull* of the returned set: :math:`2n` linear programs,

    .. math::

        \underline{x}_i = \min_{\xi} \{ e_i^\top (c + G \xi) \mid A_c \xi = b_c,\
        \|\xi\|_\infty \le 1 \}, \qquad
        \overline{x}_i = \max_{\xi} \{ e_i^\top (c + G \xi) \mid A_c \xi = b_c,\
        \|\xi\|_\infty \le 1 \},

    each bounded by the weak-duality value of a dual point (sound whatever the solver).
    """

    def design(self) -> None:
        super().design()
        self._y_shift = self.V.c  # y - C x in V  <=>  C x in (y - c_V) + (-F) xi_v

    def intersect(self, c, G, A, b, y):
        F = self.F_meas
        Y = (y - self._y_shift, -F, np.zeros((0, F.shape[1])), np.zeros(0))
        return ops.intersect((c, G, A, b), Y, self.C)


@register(
    "CZN-B", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Alanwar, Rath, Said, Johansson, Althoff, arXiv 2010.11097; Scott et al. 2016",
)
class CZNB(WangGainVariant, ConZonotopeStripObserver):
    r"""Constrained zonotopes, strip intersection parametrised by the F-radius gain.

    Options
    -------
    variant : {"cora", "textbook"}
        As for FRad-B (:class:`~observers.builtin.frad.WangGainVariant`): ``"cora"``
        (default) computes the gain from the predicted set's ``G G'`` with ``A`` applied once
        more, ``R = A G G' A' + E E'``; ``"textbook"`` uses ``R = G G'``.

    Notes
    -----
    Prediction and reduction as CZN-A (:class:`CZNA`): for the estimate
    :math:`\langle c, G, A_c, b_c \rangle`,
    :math:`c^p = A c + B u_{k-1} + c_W`, :math:`G^p = [A G,\ E]`,
    :math:`A_c^p = [A_c,\ 0]`, :math:`b_c^p = b_c` (Althoff & Rath 2021, Sec. 2.4).

    *Measurement update*: the predicted set intersected exactly with the strips of eq. (4),
    :math:`|C_j x - y_{k,j}| \le \sigma_j` with :math:`[-\sigma, \sigma] \supseteq
    \operatorname{BOX}(\mathcal{V})` (:math:`\sigma_j = \max(|\underline{v}_j|,
    |\overline{v}_j|)`), all at once (eqs. (5)-(6) with equality).  The intersection is
    written with the gain :math:`\Lambda_k` of intersection method II (Sec. 3.1) for the
    centre and generators, and the strips as constraints; every :math:`\Lambda_k` gives the
    same set (Alanwar et al. 2022, Prop. 3), the gain shapes the generators that the later
    reductions act on:

    .. math::

        \mathcal{S}_k = \left\langle c^p + \Lambda_k (y_k - C c^p),\
          \begin{bmatrix} (I - \Lambda_k C) G^p & \Lambda_k \operatorname{diag}(\tilde\sigma)
          \end{bmatrix},\
          \begin{bmatrix} A_c^p & 0 \\ C G^p & -\operatorname{diag}(\tilde\sigma) \end{bmatrix},\
          \begin{bmatrix} b_c^p \\ y_k - C c^p \end{bmatrix} \right\rangle,
        \qquad \tilde\sigma = (1 + \epsilon) \sigma .

    The gain is the F-radius gain of FRad-B (Wang, Puig, Cembrano 2018):

    .. math::

        \Lambda_k = R C^\top \left(C R C^\top + F F^\top\right)^{-1}, \qquad
        R = \begin{cases} A G^p G^{p\top} A^\top + E E^\top & \text{variant "cora"}, \\
        G^p G^{p\top} & \text{variant "textbook"}. \end{cases}
    """

    def intersect(self, c, G, A, b, y):
        return ops.intersect_strips((c, G, A, b), self.C, y, self.sigma_meas,
                                    self.wang_gain(c, G))


@register(
    "CZN-MV", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Rego, Raffo, Scott, Raimondo, Automatica 111, 108614, 2020 (mean-value "
              "extension); Scott et al. 2016",
)
class CZNMV(CZNA):
    r"""CZN-A with the mean-value extension of Rego et al. (2020) as prediction.

    Beyond CORA.  For a nonlinear system the prediction encloses ``f(x) - f(c)`` by the
    interval Jacobian over the box of the estimate, ``J(B) (x - c)``: its midpoint is applied
    to the set and its radius adds the box ``rad J(B) |x - c|``
    (:class:`observers.prediction.MeanValuePrediction`).  It needs first derivatives only
    (no Hessian), and is tighter than the second-order remainder when the curvature is large
    relative to the set; on linear systems it is CZN-A.

    Notes
    -----
    With :math:`\mathcal{B} = c \pm r`, :math:`r = |G| \mathbf{1}`, the box of the zonotope
    :math:`\langle c, G \rangle` (which contains the estimate
    :math:`\langle c, G, A_c, b_c \rangle`), and the interval Jacobian
    :math:`J(\mathcal{B}) \subseteq J_m \pm J_r` over it, the mean-value theorem gives for
    every :math:`x \in \mathcal{B}`

    .. math::

        f(x, u) \in f(c, u) + J(\mathcal{B}) (x - c)
        \subseteq f(c, u) + J_m (x - c) + [-J_r r,\ J_r r],

    so the prediction is CZN-A's with :math:`A = J_m`,
    :math:`B u_{k-1} = f(c, u_{k-1}) - J_m c` and the box generators
    :math:`R = \operatorname{diag}(J_r r)` (rounded outward):

    .. math::

        c^p = J_m c + \bigl(f(c, u_{k-1}) - J_m c\bigr) + c_W, \qquad
        G^p = \begin{bmatrix} J_m G & E & \operatorname{diag}(J_r r) \end{bmatrix},
        \qquad A_c^p = \begin{bmatrix} A_c & 0 & 0 \end{bmatrix}.

    A nonlinear output :math:`h` is enclosed the same way over the box of the prediction,
    :math:`h(x) \in H x + d \pm \rho`, and the update is CZN-A's exact intersection with
    :math:`C = H`, the measurement :math:`y_k - d` and the noise widened to
    :math:`\langle c_V, [\tilde F,\ \operatorname{diag}(\rho)] \rangle`.
    """

    LINEARISATION = "mean-value"
    OUTPUT_ENCLOSURE = "mean-value"


class _HullEnclosure(CZNA):
    """CZN-A's exact generalised intersection with enclosures over the interval hull of the
    constrained zonotope (Rego et al.): the base of CZN-FO and CZN-DC."""

    OPTIONS = {"enclosure_box": Choice("hull", ENCLOSURE_BOXES)}


@register(
    "CZN-FO", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Rego, Raffo, Scott, Raimondo, Automatica 111, 108614, 2020 (first-order "
              "Taylor extension); Scott et al. 2016",
)
class CZNFO(_HullEnclosure):
    r"""Constrained zonotopes with the first-order Taylor extension of Rego et al. (2020).

    The dynamics and a nonlinear output are expanded to first order at the midpoint of the
    interval hull of the estimate (prediction) or of the predicted set (update), with the
    Lagrange remainder enclosed by the interval Hessian over that hull
    (:func:`observers.enclosures.first_order`); the linear part is applied to the
    constrained zonotope exactly, the remainder adds a box.  On linear systems it is CZN-A.

    Notes
    -----
    With :math:`\mathcal{B} = [\underline{x}, \overline{x}]` the interval hull of the
    estimate (:math:`2n` LPs), :math:`p` its midpoint and :math:`H_i(\mathcal{B})` the
    interval Hessian of :math:`f_i` over it, Taylor's theorem gives for every
    :math:`x \in \mathcal{B}`

    .. math::

        f_i(x, u) \in f_i(p, u) + \nabla f_i(p, u)^\top (x - p)
        + \tfrac{1}{2} (x - p)^\top H_i(\mathcal{B}) (x - p),

    whose last term is bounded in interval arithmetic over :math:`\mathcal{B}` by
    :math:`d_i^R \pm \rho_i`.  With :math:`J = \partial f / \partial x (p, u_{k-1})` the
    prediction is CZN-A's with the affine part applied exactly:

    .. math::

        c^p = J c + f(p, u_{k-1}) - J p + d^R + c_W, \qquad
        G^p = \begin{bmatrix} J G & E & \operatorname{diag}(\rho) \end{bmatrix}, \qquad
        A_c^p = \begin{bmatrix} A_c & 0 & 0 \end{bmatrix}.

    A nonlinear output is enclosed the same way over the hull of the prediction,
    :math:`h(x) \in H x + d \pm \rho_h`, and intersected exactly as in CZN-A with
    :math:`C = H`, measurement :math:`y_k - d` and noise
    :math:`\langle c_V, [\tilde F,\ \operatorname{diag}(\rho_h)] \rangle`.  After each
    update the set is re-parametrised exactly by the least-squares shear
    :math:`\langle c + L b_c,\ G - L A_c,\ A_c,\ b_c \rangle`,
    :math:`L = G A_c^\top (A_c A_c^\top)^+`.
    """

    ENCLOSURE = "first-order"
    OUTPUT_ENCLOSURE = "first-order"


@register(
    "CZN-DC", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="DC-programming enclosure of Alamo, Bravo, Redondo, Camacho, Automatica 44(1), "
              "2008, on constrained zonotopes as in Rego et al.; Scott et al. 2016",
)
class CZNDC(_HullEnclosure):
    r"""Constrained zonotopes with a difference-of-convex (DC) enclosure of f and h.

    Each component is split over the interval hull of the set into a convex function minus a
    convex quadratic (:func:`observers.enclosures.dc`); tangent planes at the hull's midpoint
    minorise both parts and the vertices of the hull majorise them, which bounds the
    linearisation error one-sidedly per part (the principle of the DC-programming set-membership
    estimator of Alamo et al. 2008, used with constrained zonotopes in the comparisons of Rego,
    Raffo, Terra, Scott, arXiv 2504.00130).  The vertex enumeration costs ``2^n`` evaluations
    of f per step (refused beyond 12 states).  On linear systems it is CZN-A.

    Notes
    -----
    Over the interval hull :math:`\mathcal{B} = p \pm r` of the set, each component is split
    as :math:`f_i = g_i - q_i` with the convex quadratic
    :math:`q_i(x) = \tfrac{1}{2} \sum_j a_{ij} (x_j - p_j)^2`, the weights :math:`a_{ij}`
    making :math:`H_i(\mathcal{B}) + \operatorname{diag}(a_i)` diagonally dominant (Gershgorin),
    so that :math:`g_i` is convex on :math:`\mathcal{B}`.  Tangent planes at :math:`p` minorise
    both convex parts and a convex function is largest at a vertex :math:`v` of
    :math:`\mathcal{B}`, hence, with :math:`J = \partial f / \partial x (p)`,

    .. math::

        f_i(x) - f_i(p) - J_i (x - p) \in
        \Bigl[-\tfrac{1}{2} \sum_j a_{ij} r_j^2,\
        \max_{v} \bigl(g_i(v) - g_i(p) - J_i (v - p)\bigr)\Bigr]
        = d^R_i \pm \rho_i .

    The prediction is then CZN-A's with this affine enclosure:

    .. math::

        c^p = J c + f(p, u_{k-1}) - J p + d^R + c_W, \qquad
        G^p = \begin{bmatrix} J G & E & \operatorname{diag}(\rho) \end{bmatrix}, \qquad
        A_c^p = \begin{bmatrix} A_c & 0 & 0 \end{bmatrix},

    and a nonlinear output, enclosed the same way over the hull of the prediction as
    :math:`h(x) \in H x + d \pm \rho_h`, is intersected exactly as in CZN-A with
    :math:`C = H`, the measurement :math:`y_k - d` and the noise widened by
    :math:`\operatorname{diag}(\rho_h)`.
    """

    ENCLOSURE = "dc"
    OUTPUT_ENCLOSURE = "dc"


@register(
    "CZN-PR", family="strip", set_type="conzonotope", ready_for_control=False,
    reference="Rego, Raffo, Terra, Scott, arXiv 2504.00130, 2025 (polyhedral relaxations); "
              "Scott et al. 2016",
)
class CZNPR(_HullEnclosure):
    r"""Constrained zonotopes with lifted polyhedral relaxations (Rego, Raffo, Terra, Scott,
    arXiv 2504.00130).

    The dynamics and a nonlinear output are written as factorable functions (sums, products,
    quotients, powers, ``sqrt, exp, log, sin, cos, atan``); over the interval hull of the
    set every nonlinear operation gets a variable bounded by linear inequalities on its graph
    (McCormick envelopes, secants and tangents; :mod:`observers.numerics.relaxation`), which become
    equality constraints with one slack generator each.  Prediction: the image of the lifted
    set plus ``W``.  Update: the output expressions of the lifted predicted set are equated to
    ``y - v``, ``v in V``.  The relaxation keeps the link between the state and its image
    through the constraints, where a linearisation keeps only a box.  The generator and
    constraint limits of the paper are the options ``max_generators`` and
    ``max_constraints``.  On linear systems it is CZN-A.  With ``enclosure_box="zonotope"``
    the relaxations are taken over the box of the zonotope ``(c, G)`` instead.

    Options
    -------
    tangents : {1, 3}
        Tangents of each convex or concave operation: at the midpoint of its interval (1,
        default) or also at both ends (3: tighter, about twice the constraints, which the
        constraint limit then folds; on the rego2d example 2 % tighter, on the robot looser
        and three times slower).

    Notes
    -----
    Over the box :math:`\mathcal{B}` of the estimate :math:`\langle c, G, A_c, b_c \rangle`
    every nonlinear operation of :math:`f` gets a variable :math:`z` bounded by linear
    inequalities :math:`R_\ell\, (\xi, z) + \kappa_\ell \le 0` on its graph; for a
    product :math:`z = a b` with :math:`a \in [a^L, a^U]`, :math:`b \in [b^L, b^U]` these are
    the McCormick envelopes

    .. math::

        z \ge a^L b + a b^L - a^L b^L, \quad z \ge a^U b + a b^U - a^U b^U, \quad
        z \le a^U b + a b^L - a^U b^L, \quad z \le a^L b + a b^U - a^L b^U,

    and for a convex (concave) univariate operation the secant above (below) and tangents
    below (above).  Each inequality becomes an equality with a slack
    :math:`s_\ell = \tfrac{1}{2} s_\ell^{\max} (1 + \sigma_\ell)`,
    :math:`|\sigma_\ell| \le 1`, so that the graph of :math:`f` over the estimate lies in the
    lifted constrained zonotope over :math:`\eta = (\xi, z, \sigma)`; its image plus
    :math:`\mathcal{W}` is the prediction:

    .. math::

        c^p = f_0 + c_W, \qquad
        G^p = \begin{bmatrix} \Phi & E \end{bmatrix}, \qquad
        A_c^p = \begin{bmatrix} A_c & 0 & 0 & 0 \\ R_\xi & R_z &
        \tfrac{1}{2} \operatorname{diag}(s^{\max}) & 0 \end{bmatrix}, \qquad
        b_c^p = \begin{bmatrix} b_c \\ -\kappa - \tfrac{1}{2} s^{\max} \end{bmatrix},

    with :math:`f(x) = f_0 + \Phi \eta` the (affine) output expressions of the relaxation.
    Update: the output expressions :math:`h(x) = h_0 + \Psi \eta` of the relaxation of
    :math:`h` over the lifted predicted set are equated to :math:`y_k - v`,
    :math:`v = c_V + \tilde F \xi_v`:

    .. math::

        \Psi \eta + \tilde F \xi_v = y_k - h_0 - c_V,

    added as constraint rows (the centre and generators of the state are unchanged).
    """

    OPTIONS = {"tangents": Choice(1, (1, 3))}

    def design(self) -> None:
        super().design()
        from ..numerics.relaxation import Factorable

        s = self.system
        self._f_graph = self._h_graph = None
        if not self.prediction.exact:
            d = s.derived
            self._f_graph = Factorable(d.expressions, *d.symbols, what="f")
        if not self.output_linear:
            d = s.derived_h
            self._h_graph = Factorable(d.expressions, *d.symbols, what="h")

    def predict(self, c, G, A, b, u):
        if self._f_graph is None:
            return super().predict(c, G, A, b, u)
        from ..numerics.relaxation import lifted_set, relax_checked

        lo, hi = self.enclosure_box(c, G, A, b, self._set)
        rel = relax_checked(self._f_graph, c, G, (lo, hi), u, self.k, self.options["tangents"])
        coef, A_new, b_new = lifted_set(rel, A, b)
        re = self.E.shape[1]
        G_new = np.hstack([coef, self.E])
        A_new = np.hstack([A_new, np.zeros((A_new.shape[0], re))])
        return rel.const + self.W.c, G_new, A_new, b_new

    def update(self, c, G, A, b, y):
        if self._h_graph is None:
            return super().update(c, G, A, b, y)
        from ..numerics.relaxation import lifted_set, relax_checked

        lo, hi = self.enclosure_box(c, G, A, b)
        rel = relax_checked(self._h_graph, c, G, (lo, hi), np.zeros(0), self.k,
                            self.options["tangents"])
        coef, A_l, b_l = lifted_set(rel, A, b)
        n, r = G.shape
        nl, nf = coef.shape[1], self.F_meas.shape[1]
        G_new = np.zeros((n, nl + nf))
        G_new[:, :r] = G
        # h(x) + v = y with v = c_V + F xi_v:  coef v + F xi_v = y - const - c_V
        A_new = np.block([[A_l, np.zeros((A_l.shape[0], nf))], [coef, self.F_meas]])
        b_new = np.concatenate([b_l, y - rel.const - self.V.c])
        return c, G_new, A_new, b_new
