"""Small validation helpers shared by the set classes (kept private to the leaf package)."""

from __future__ import annotations

import numpy as np

from ..errors import SetError


def frozen(a: np.ndarray) -> np.ndarray:
    """Return ``a`` as a read-only float array (copying only when needed)."""
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def _numeric(x, name: str) -> np.ndarray:
    """``x`` as a float array, or a :class:`SetError` naming ``name``."""
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SetError(f"{name} must be numeric, got {type(x).__name__}") from exc


def _finite(a: np.ndarray, name: str) -> np.ndarray:
    """``a`` if every entry is finite, else a :class:`SetError` naming ``name``."""
    if not np.all(np.isfinite(a)):
        raise SetError(f"{name} contains non-finite values")
    return a


def vector(x, name: str, dim: int | None = None) -> np.ndarray:
    """Validate ``x`` as a finite 1-D float vector (scalars become length-1 vectors)."""
    a = _numeric(x, name)
    if a.ndim == 0:
        a = a.reshape(1)
    elif a.ndim == 2 and 1 in a.shape:
        a = a.reshape(-1)
    if a.ndim != 1:
        raise SetError(f"{name} must be a vector, got an array of shape {a.shape}")
    if dim is not None and a.shape[0] != dim:
        raise SetError(f"{name} must have length {dim}, got {a.shape[0]}")
    return _finite(a, name)


def matrix(M, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """Validate ``M`` as a finite 2-D float matrix with optional fixed row/column counts."""
    a = _numeric(M, name)
    if a.ndim == 0:
        a = a.reshape(1, 1)
    elif a.ndim == 1:
        # a 1-D array is a column when it matches the row count, else a row when it matches
        # the column count (or a single row is required), else a column
        if rows is not None and a.shape[0] == rows and rows != 1:
            a = a.reshape(-1, 1)
        elif rows == 1 or (cols is not None and a.shape[0] == cols):
            a = a.reshape(1, -1)
        else:
            a = a.reshape(-1, 1)
    if a.ndim != 2:
        raise SetError(f"{name} must be a matrix, got an array of shape {a.shape}")
    if rows is not None and a.shape[0] != rows:
        raise SetError(f"{name} must have {rows} rows, got shape {a.shape}")
    if cols is not None and a.shape[1] != cols:
        raise SetError(f"{name} must have {cols} columns, got shape {a.shape}")
    return _finite(a, name)


def linear_map_matrix(M, dim: int) -> np.ndarray:
    """Validate the matrix of a linear map ``M @ S`` applied to a set of dimension ``dim``."""
    if np.isscalar(M):
        return float(M) * np.eye(dim)
    a = np.asarray(M, dtype=float)
    if a.ndim == 1 and dim == 1:
        a = a.reshape(-1, 1)
    if a.ndim != 2 or a.shape[1] != dim:
        raise SetError(f"cannot map a set of dimension {dim} with a matrix of shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SetError("linear map matrix contains non-finite values")
    return a


def direction(d, dim: int) -> np.ndarray:
    """Validate a direction vector (or an n x k matrix of directions) for support functions."""
    a = np.asarray(d, dtype=float)
    if a.ndim == 1:
        if a.shape[0] != dim:
            raise SetError(f"direction must have length {dim}, got {a.shape[0]}")
    elif a.ndim != 2 or a.shape[0] != dim:
        raise SetError(f"directions must be a vector or a {dim} x k matrix, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SetError("direction contains non-finite values")
    return a


def strips(C, y, sigma, dim: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate the strips ``|C x - y| <= sigma`` of sets of dimension ``dim``: ``C`` (m x dim),
    ``y`` and ``sigma`` (m, ``sigma >= 0``)."""
    C = matrix(C, "strip normals C", cols=dim)
    m = C.shape[0]
    y = vector(y, "strip centres y", dim=m)
    sigma = vector(sigma, "strip half-widths sigma", dim=m)
    if np.any(sigma < 0):
        raise SetError("strip half-widths sigma must be non-negative")
    return C, y, sigma


class CentreGenerators:
    """The shape queries of a set given by a centre ``_c`` (n) and generators ``_G`` (n x r):
    :attr:`dim`, :attr:`num_generators` and :meth:`center` (zonotopes and constrained
    zonotopes; no state of its own)."""

    __slots__ = ()

    @property
    def dim(self) -> int:
        """Dimension n of the ambient space."""
        return self._c.shape[0]

    @property
    def num_generators(self) -> int:
        """Number r of generators."""
        return self._G.shape[1]

    def center(self) -> np.ndarray:
        """Centre ``c`` (of a constrained zonotope not necessarily a point of the set)."""
        return self._c
