"""Six textbook plants as linear estimation benchmarks.

The continuous-time models and parameters of the *Control Tutorials for MATLAB and Simulink*
(CTMS; Messner, Tilbury, Hill, Taylor; University of Michigan, Carnegie Mellon University,
University of Detroit Mercy), the plants on which ReachTool (Silvestre 2023) compares set
representations for estimation: aircraft pitch, cruise control, the inverted pendulum on a
cart, DC motor position, DC motor speed and the bus suspension.  Each is discretised by
zero-order hold (:func:`zoh`: the input held over a sample, exact for the model) at the sample
time stated in :data:`PLANTS`; disturbance, noise and initial sets are boxes (the bus
suspension's road profile is an unknown disturbance along its input column), chosen here and
stated in ``systems/data/ORIGIN.md``.

The equations, in the tutorials' states (``'`` is the time derivative):

* **cruise control** (speed ``v``): ``m v' = -b v + u``, ``m = 1000`` kg, ``b = 50`` N s/m;
  the speed is measured.
* **DC motor speed** (``[w, i]``, ``w`` the shaft speed, ``i`` the armature current):
  ``J w' = -b w + K i``, ``L i' = -K w - R i + V``; ``J = 0.01`` kg m^2, ``b = 0.1`` N m s,
  ``K = 0.01`` (``K_t = K_e``), ``R = 1`` Ohm, ``L = 0.5`` H; ``w`` measured.
* **DC motor position** (``[theta, w, i]``): the same equations with ``theta' = w``,
  ``J = 3.2284e-6``, ``b = 3.5077e-6``, ``K = 0.0274``, ``R = 4``, ``L = 2.75e-6``; ``theta``
  measured.
* **aircraft pitch** (``[alpha, q, theta]``: angle of attack, pitch rate, pitch angle),
  the tutorial's linearised longitudinal model of a Boeing airliner in cruise:
  ``alpha' = -0.313 alpha + 56.7 q + 0.232 delta``, ``q' = -0.0139 alpha - 0.426 q +
  0.0203 delta``, ``theta' = 56.7 q``; ``theta`` measured, ``delta`` the elevator angle.
* **inverted pendulum** (``[x, x', phi, phi']``, ``phi`` the deviation from upright),
  linearised about the upright position: with ``p = I (M + m) + M m l^2``,
  ``x'' = (-(I + m l^2) b x' + m^2 g l^2 phi + (I + m l^2) F) / p`` and
  ``phi'' = (-m l b x' + m g l (M + m) phi + m l F) / p``; ``M = 0.5`` kg, ``m = 0.2`` kg,
  ``b = 0.1`` N s/m, ``l = 0.3`` m, ``I = 0.006`` kg m^2, ``g = 9.8``; ``x`` and ``phi``
  measured.  The upright position is unstable, so the benchmark runs the plant under the
  discrete LQR state feedback ``F = r - K x`` (``Q = diag(1, 0, 1, 0)``, ``R = 1``; the
  unique stabilising solution of the Riccati equation): the observer estimates the closed
  loop driven by the known reference force ``r``.
* **bus suspension** (``[X1, X1', Y1, Y2]``: body position, its speed, suspension deflection
  ``Y1 = X1 - X2`` and the integral state of the tutorial's derivation), a quarter bus with
  ``m1 = 2500`` kg, ``m2 = 320`` kg, ``k1 = 80000`` N/m, ``k2 = 500000`` N/m, ``b1 = 350``
  N s/m, ``b2 = 15020`` N s/m; inputs the control force ``u`` (known) and the road height
  ``W`` (an unknown disturbance here, at most 1 cm); ``Y1`` measured.

Every input is a known square wave (:func:`square_wave`), the same for every seed; the seed
draws the initial state, the disturbance and the noise (:func:`systems.simulate.simulate`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm, solve_discrete_are

from observers.sets import Zonotope

from .errors import ModelError
from .model import LinearSystem

SOURCE = ("Control Tutorials for MATLAB and Simulink (CTMS, Messner, Tilbury, Hill, Taylor), "
          "System Modeling pages; zero-order hold, sets and input chosen here")


def zoh(Ac: np.ndarray, Bc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation: ``Ad = expm(Ac dt)``, ``Bd = int_0^dt expm(Ac s) ds Bc``,
    both read off ``expm([[Ac, Bc], [0, 0]] dt)`` (Van Loan's block exponential)."""
    n, m = Bc.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = Ac, Bc
    E = expm(M * dt)
    return E[:n, :n], E[:n, n:]


def square_wave(steps: int, amplitude: float, period: int, offset: float = 0.0) -> np.ndarray:
    """``offset + amplitude`` for the first half of every ``period`` samples and ``offset -
    amplitude`` for the second half (``steps`` x 1)."""
    k = np.arange(steps)
    return (offset + amplitude * np.where(k % period < period // 2, 1.0, -1.0)).reshape(-1, 1)


@dataclass(frozen=True)
class Plant:
    """A textbook plant: its continuous model, sample time, sets and input.

    ``w_radii``, ``v_radii``: half-widths of the boxes ``W`` (per state, per sample) and ``V``
    (per output); ``x0_centre``, ``x0_radii``: the box ``X0``; ``wave``: the known input, a
    :func:`square_wave` ``(amplitude, period, offset)``; ``road``: the half-width of an
    unknown input along the last column of ``Bc`` (the bus suspension's road), added to
    ``W``; ``feedback``: the LQR weights ``(Q diagonal, R)`` of a state feedback closing the
    loop (the pendulum).
    """

    name: str
    title: str
    Ac: np.ndarray
    Bc: np.ndarray
    C: np.ndarray
    dt: float
    states: tuple[str, ...]
    w_radii: tuple[float, ...]
    v_radii: tuple[float, ...]
    x0_centre: tuple[float, ...]
    x0_radii: tuple[float, ...]
    wave: tuple[float, int, float]
    road: float = 0.0
    feedback: tuple[tuple[float, ...], float] | None = None
    parameters: dict = field(default_factory=dict)

    def input(self, steps: int) -> np.ndarray:
        """The known input record (``steps`` x ``nu``): the plant's square wave."""
        amplitude, period, offset = self.wave
        return square_wave(steps, amplitude, period, offset)

    def discrete(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(A, B, E_road)``: the ZOH model of the known inputs (closed by the feedback where
        there is one) and the discretised column of the unknown road input (or ``None``)."""
        known = self.Bc[:, :-1] if self.road else self.Bc
        A, B = zoh(self.Ac, known, self.dt)
        E_road = zoh(self.Ac, self.Bc[:, -1:], self.dt)[1] if self.road else None
        if self.feedback is not None:
            A = A - B @ lqr_gain(A, B, *self.feedback)
        return A, B, E_road

    def system(self) -> LinearSystem:
        """The discrete :class:`~systems.model.LinearSystem` of the benchmark."""
        A, B, E_road = self.discrete()
        W = Zonotope.box(np.asarray(self.w_radii, float))
        if E_road is not None:
            W = W + Zonotope(np.zeros(A.shape[0]), self.road * E_road)
        return LinearSystem(
            A, B, self.C, W=W, V=Zonotope.box(np.asarray(self.v_radii, float)),
            X0=Zonotope(np.asarray(self.x0_centre, float), np.diag(self.x0_radii)),
            dt=self.dt, name=self.name)


def lqr_gain(A: np.ndarray, B: np.ndarray, q: tuple[float, ...], r: float) -> np.ndarray:
    """The discrete LQR gain ``K = (R + B'PB)^-1 B'PA`` with ``P`` the stabilising solution of
    the discrete algebraic Riccati equation for ``Q = diag(q)``, ``R = r I`` (unique for a
    stabilisable ``(A, B)`` and detectable ``(Q^1/2, A)``)."""
    Q = np.diag(np.asarray(q, float))
    R = r * np.eye(B.shape[1])
    P = solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)


# -- the six plants ---------------------------------------------------------------------------
def _cruise() -> Plant:
    m, b = 1000.0, 50.0
    return Plant(
        "cruise-control", "Cruise control", np.array([[-b / m]]), np.array([[1.0 / m]]),
        np.array([[1.0]]), dt=0.1, states=("v",), w_radii=(0.02,), v_radii=(0.1,),
        x0_centre=(10.0,), x0_radii=(2.0,),
        wave=(200.0, 100, 500.0),
        parameters=dict(m=m, b=b))


def _motor(J: float, b: float, K: float, R: float, L: float, position: bool):
    """Continuous ``(Ac, Bc)`` of the DC motor: ``[w, i]``, or ``[theta, w, i]``."""
    core = np.array([[-b / J, K / J], [-K / L, -R / L]])
    Bc = np.array([[0.0], [1.0 / L]])
    if not position:
        return core, Bc
    Ac = np.zeros((3, 3))
    Ac[0, 1] = 1.0
    Ac[1:, 1:] = core
    return Ac, np.vstack([[0.0], Bc])


def _motor_speed() -> Plant:
    p = dict(J=0.01, b=0.1, K=0.01, R=1.0, L=0.5)
    Ac, Bc = _motor(**p, position=False)
    return Plant(
        "dc-motor-speed", "DC motor speed", Ac, Bc, np.array([[1.0, 0.0]]), dt=0.05,
        states=("w", "i"), w_radii=(2e-4, 1e-3), v_radii=(2e-3,),
        x0_centre=(0.0, 0.0), x0_radii=(0.05, 0.1),
        wave=(1.0, 80, 0.0), parameters=p)


def _motor_position() -> Plant:
    p = dict(J=3.2284e-6, b=3.5077e-6, K=0.0274, R=4.0, L=2.75e-6)
    Ac, Bc = _motor(**p, position=True)
    return Plant(
        "dc-motor-position", "DC motor position", Ac, Bc, np.array([[1.0, 0.0, 0.0]]),
        dt=0.001, states=("theta", "w", "i"), w_radii=(1e-4, 0.05, 1e-3), v_radii=(1e-3,),
        x0_centre=(0.0, 0.0, 0.0), x0_radii=(0.1, 0.5, 0.05),
        wave=(0.1, 100, 0.0), parameters=p)


def _aircraft_pitch() -> Plant:
    Ac = np.array([[-0.313, 56.7, 0.0], [-0.0139, -0.426, 0.0], [0.0, 56.7, 0.0]])
    Bc = np.array([[0.232], [0.0203], [0.0]])
    return Plant(
        "aircraft-pitch", "Aircraft pitch", Ac, Bc, np.array([[0.0, 0.0, 1.0]]), dt=0.1,
        states=("alpha", "q", "theta"), w_radii=(1e-3, 1e-4, 1e-3), v_radii=(5e-3,),
        x0_centre=(0.0, 0.0, 0.0), x0_radii=(0.05, 0.01, 0.05),
        wave=(0.1, 60, 0.0))


def _pendulum() -> Plant:
    M, m, b, ell, inertia, g = 0.5, 0.2, 0.1, 0.3, 0.006, 9.8
    p = inertia * (M + m) + M * m * ell**2
    Ac = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [0.0, -(inertia + m * ell**2) * b / p, m**2 * g * ell**2 / p, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [0.0, -m * ell * b / p, m * g * ell * (M + m) / p, 0.0],
    ])
    Bc = np.array([[0.0], [(inertia + m * ell**2) / p], [0.0], [m * ell / p]])
    return Plant(
        "inverted-pendulum", "Inverted pendulum (LQR loop)", Ac, Bc,
        np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]), dt=0.01,
        states=("x", "x_dot", "phi", "phi_dot"), w_radii=(1e-4, 1e-3, 1e-4, 1e-3),
        v_radii=(2e-3, 2e-3), x0_centre=(0.0, 0.0, 0.0, 0.0),
        x0_radii=(0.05, 0.05, 0.05, 0.05), wave=(0.5, 200, 0.0),
        feedback=((1.0, 0.0, 1.0, 0.0), 1.0),
        parameters=dict(M=M, m=m, b=b, l=ell, I=inertia, g=g))


def _bus_suspension() -> Plant:
    m1, m2, k1, k2, b1, b2 = 2500.0, 320.0, 80000.0, 500000.0, 350.0, 15020.0
    s = b1 / m1 + b1 / m2 + b2 / m2
    Ac = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [-(b1 * b2) / (m1 * m2), 0.0, (b1 / m1) * s - k1 / m1, -b1 / m1],
        [b2 / m2, 0.0, -s, 1.0],
        [k2 / m2, 0.0, -(k1 / m1 + k1 / m2 + k2 / m2), 0.0],
    ])
    Bc = np.array([
        [0.0, 0.0],
        [1.0 / m1, (b1 * b2) / (m1 * m2)],
        [0.0, -b2 / m2],
        [1.0 / m1 + 1.0 / m2, -k2 / m2],
    ])
    return Plant(
        "bus-suspension", "Bus suspension", Ac, Bc, np.array([[0.0, 0.0, 1.0, 0.0]]),
        dt=0.01, states=("X1", "X1_dot", "Y1", "Y2"), w_radii=(1e-5, 1e-4, 1e-5, 1e-4),
        v_radii=(2e-4,), x0_centre=(0.0, 0.0, 0.0, 0.0),
        x0_radii=(0.01, 0.01, 0.01, 0.01), wave=(500.0, 200, 0.0),
        road=0.01, parameters=dict(m1=m1, m2=m2, k1=k1, k2=k2, b1=b1, b2=b2))


#: the plants by scenario name, in the order of the report
PLANTS: dict[str, Callable[[], Plant]] = {
    "aircraft-pitch": _aircraft_pitch,
    "cruise-control": _cruise,
    "inverted-pendulum": _pendulum,
    "dc-motor-position": _motor_position,
    "dc-motor-speed": _motor_speed,
    "bus-suspension": _bus_suspension,
}


def plant(name: str) -> Plant:
    """The textbook plant ``name`` (a key of :data:`PLANTS`)."""
    try:
        return PLANTS[name]()
    except KeyError:
        raise ModelError(f"unknown textbook plant '{name}' (known: {', '.join(PLANTS)})") \
            from None
