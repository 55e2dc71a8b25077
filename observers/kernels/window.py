"""Compiled (numba) arrays of a moving-horizon window as a constrained zonotope.

:func:`observers.numerics.mhe.window_conzonotope` writes the states consistent with a window
of ``T`` transitions as ``{c + G xi : Acon xi = b, |xi| <= 1}``: per step the state's
generators are mapped by ``A`` and the disturbance's appended, and a block of rows
``C G = y - C c - c_V`` (with the noise's generators) is added.  In numpy that is about ten
calls per step of the window on matrices of a few dozen entries, most of an MHE step's set-up
on the 6-state records; :func:`window_arrays` runs the same recursion in plain loops (each
product summed in index order), so the arrays are those of the numpy path up to rounding.
"""

from __future__ import annotations

import numpy as np

from .switch import njit


def _window_arrays_py(A, B, C, c0, G0, cW, GW, cV, GV, u, y):
    n = A.shape[0]
    m = C.shape[0]
    nu = B.shape[1]
    T = u.shape[0]
    rs, rw, rv = G0.shape[1], GW.shape[1], GV.shape[1]
    R = rs + T * rw + (T + 1) * rv
    G = np.zeros((n, R))
    G[:, :rs] = G0
    c = c0.copy()
    Acon = np.zeros(((T + 1) * m, R))
    b = np.empty((T + 1) * m)
    tmp = np.empty(n)
    col = rs
    for j in range(T + 1):
        if j:  # x_j = A x_{j-1} + B u_{j-1} + W (only the columns used so far are nonzero)
            for i in range(n):
                s = 0.0
                for k in range(n):
                    s += A[i, k] * c[k]
                t = 0.0
                for k in range(nu):
                    t += B[i, k] * u[j - 1, k]
                tmp[i] = s + t + cW[i]
            c[:] = tmp
            for q in range(col):
                for i in range(n):
                    s = 0.0
                    for k in range(n):
                        s += A[i, k] * G[k, q]
                    tmp[i] = s
                G[:, q] = tmp
            G[:, col:col + rw] = GW
            col += rw
        for i in range(m):  # C x_j + v_j = y_j
            row = j * m + i
            for q in range(col):
                s = 0.0
                for k in range(n):
                    s += C[i, k] * G[k, q]
                Acon[row, q] = s
            for q in range(rv):
                Acon[row, col + q] = GV[i, q]
            s = 0.0
            for k in range(n):
                s += C[i, k] * c[k]
            b[row] = y[j, i] - s - cV[i]
        col += rv
    return c, G, Acon, b


#: ``window_arrays(A, B, C, c0, G0, cW, GW, cV, GV, u, y) -> (c, G, Acon, b)`` (C-contiguous
#: float arrays; ``None`` without numba)
window_arrays = njit(_window_arrays_py, error_model="numpy")
