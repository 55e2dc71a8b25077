"""A unicycle robot localised by range measurements to known beacons.

State ``(p_x, p_y, theta)`` (m, m, rad), known input ``(v, omega)`` (m/s, rad/s), explicit
Euler with step ``T``::

    p_x+   = p_x + T v cos(theta) + w1
    p_y+   = p_y + T v sin(theta) + w2
    theta+ = theta + T omega + w3
    y_i    = sqrt((p_x - b_xi)^2 + (p_y - b_yi)^2) + v_i      (one range per beacon)
    y_5    = arctan((b_y3 - p_y) / (b_x3 - p_x)) - theta + v_5  (bearing of beacon 3)

the sensor model of most mobile-robot localisation (ultra-wideband or acoustic ranging to
beacons at known positions), plus the bearing of one beacon relative to the heading (a camera
or an antenna array; unwrapped, and valid while the beacon stays at larger ``x``, as it does
on this loop).  With ranges alone the heading is known only through the motion, and the
F-radius observers then let its width grow without bound (measured: FRad-A and FRad-B end
``diverged``); the bearing prevents that.

Parameters' origin: they are chosen here, not taken from a paper: four beacons at the
corners of a 10 m x 10 m room, ``T = 0.1`` s, a range error of at most 0.1 m (the order of
the accuracy usually quoted for ultra-wideband ranging), a bearing error of at most 0.02 rad,
odometry disturbances of 1 cm and 0.005 rad per step and a 0.5 m x 0.5 m x 0.1 rad initial
uncertainty; the input drives the robot round a loop in the middle of the room at 1 m/s,
at least 2 m from every beacon.  The derivatives are derived from the equations
(:mod:`systems.derivatives`); a range is smooth away from its beacon.
"""

from __future__ import annotations

import numpy as np

from observers.sets import Zonotope

from .model import NonlinearSystem

#: beacon positions (m)
BEACONS = ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0))
#: index of the beacon whose bearing is measured (the last output)
BEARING_BEACON = 2
#: Euler step (s)
STEP = 0.1
#: initial state of the record: inside the room, heading along +x
X0_CENTRE = (2.5, 2.5, 0.0)


def robot(beacons=BEACONS, T: float = STEP) -> NonlinearSystem:
    """Unicycle with range measurements to ``beacons`` and the bearing of beacon
    :data:`BEARING_BEACON` (see the module docstring)."""
    beacons = tuple((float(a), float(b)) for a, b in beacons)

    def f(x, u, m):
        return np.array([x[0] + T * u[0] * m.cos(x[2]),
                         x[1] + T * u[0] * m.sin(x[2]),
                         x[2] + T * u[1]], dtype=object)

    bx, by = beacons[BEARING_BEACON]

    def h(x, m):
        ranges = [m.sqrt((x[0] - a) ** 2 + (x[1] - b) ** 2) for a, b in beacons]
        return np.array([*ranges, m.arctan((by - x[1]) / (bx - x[0])) - x[2]], dtype=object)

    return NonlinearSystem(
        f, 3, 2, None,
        W=Zonotope.box([0.01, 0.01, 0.005]),
        V=Zonotope.box([*np.full(len(beacons), 0.1), 0.02]),
        X0=Zonotope.box([0.5, 0.5, 0.1], X0_CENTRE), h=h, dt=T, name="robot-range")


def loop_input(steps: int, speed: float = 1.0, T: float = STEP) -> np.ndarray:
    """Inputs ``(v, omega)`` (steps x 2): straight runs of 3 s and quarter turns of 2 s, a
    loop inside the room that keeps at least 2 m from every beacon (where a range is not
    smooth)."""
    k = np.arange(steps)
    phase = (k * T) % 5.0
    omega = np.where(phase >= 3.0, (np.pi / 2) / 2.0, 0.0)
    return np.column_stack([np.full(steps, speed), omega])
