"""Offline gains: computed once by an LMI/SDP design, cached on disk, or passed by the user.

Observers with a constant gain mix in :class:`OfflineGain` before their family base class and
implement :meth:`OfflineGain.design_gain`; ``self.L`` is then available online::

    class PRadB(OfflineGain, AllStripsObserver):
        DESIGN_VERSION = "1"
        def design_gain(self) -> np.ndarray: ...   # solve, verify, return (n x ny) matrix
        def gain(self, c, G): return self.L

Passing ``gain=`` skips the design (e.g. to run with CORA's stored gains).

Design cache
------------
On-disk cache of offline designs (observer gains and other matrices).

A design is keyed by a SHA-256 hash of its kind, a design version string, the input arrays
(system matrices, set generators), the design parameters and the versions of cvxpy, Clarabel
and numpy.  ``make bench`` therefore re-solves a design only when something it depends on
changed.  Failed designs are cached too (as their failure message), so an infeasible LMI is
not re-attempted on every run.  Entries are written atomically (temporary file, then
rename), and a design is computed once per key even by concurrent processes (``run --jobs``,
Dask workers sharing a folder): the first takes an exclusive lock on ``<key>.lock`` and the
others wait for it, then load its result.

Entries are verified when loaded as a fresh design is checked when computed: each entry holds
a SHA-256 of its arrays (names, types, shapes and bytes), and the design's own check
(``verify``, e.g. the shape and finiteness of a gain) runs on the loaded arrays too.  An entry
that is unreadable (truncated, empty), lacks the hash (written by an older version), does not
match it or fails the check is recomputed, with a one-line warning naming the file.  The lock
file of a key is removed once its design is stored.

The folder is ``$SETOBS_CACHE_DIR`` if set, else ``~/.cache/setobs-bench/designs``; set
``SETOBS_CACHE_DIR=off`` to disable caching.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import sys
import tempfile
from collections.abc import Callable, Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from .errors import DesignFailed, OptionError
from .options import Matrix

# -- design cache ---------------------------------------------------------------------------
_FAILED = "__design_failed__"
#: the entry's content hash (SHA-256 of every other array)
_HASH = "__sha256__"
#: designs of this process loaded from the cache instead of computed, per kind (so that a
#: design time can be told apart from a cache read, e.g. by the scaling study)
CACHE_LOADS: dict[str, int] = {}


def cache_dir() -> Path | None:
    """The cache folder, or None if caching is disabled."""
    env = os.environ.get("SETOBS_CACHE_DIR")
    if env == "off":
        return None
    return Path(env) if env else Path.home() / ".cache" / "setobs-bench" / "designs"


def _versions() -> str:
    out = []
    for pkg in ("cvxpy", "clarabel", "numpy"):
        try:
            out.append(f"{pkg}={metadata.version(pkg)}")
        except metadata.PackageNotFoundError:
            out.append(f"{pkg}=none")
    return ";".join(out)


def design_key(
    kind: str, version: str, arrays: Mapping[str, Any], params: Mapping[str, Any]
) -> str:
    """Hash of everything a design depends on."""
    h = hashlib.sha256()
    h.update(f"{kind}|{version}|{_versions()}".encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(np.asarray(arrays[name], dtype=float))
        h.update(name.encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    h.update(json.dumps(dict(params), sort_keys=True, default=str).encode())
    return h.hexdigest()[:32]


def cached_design(
    kind: str,
    version: str,
    arrays: Mapping[str, Any],
    params: Mapping[str, Any],
    compute: Callable[[], dict[str, np.ndarray]],
    verify: Callable[[dict[str, np.ndarray]], None] | None = None,
) -> dict[str, np.ndarray]:
    """Return ``compute()`` (a dict of arrays), from the cache when possible.

    A :class:`~observers.errors.DesignFailed` raised by ``compute`` is cached and re-raised
    on later calls with the same key.  ``verify(result)`` (raising any exception if the
    arrays are not a valid design) is run on a loaded entry, after its content hash; an entry
    failing either is recomputed with a warning naming its file.
    """
    folder = cache_dir()
    if folder is None:
        return compute()
    path = folder / f"{kind}-{design_key(kind, version, arrays, params)}.npz"
    result = load_entry(path, verify)
    if result is not None:
        CACHE_LOADS[kind] = CACHE_LOADS.get(kind, 0) + 1
    else:
        # one writer per key: concurrent workers wanting the same design wait for the first
        # one and then load its result instead of solving the same SDP again
        with key_lock(path):
            result = load_entry(path, verify, warn=False)  # (warned above)
            if result is not None:
                CACHE_LOADS[kind] = CACHE_LOADS.get(kind, 0) + 1
            else:
                try:
                    result = compute()
                except DesignFailed as exc:
                    store_entry(path, {_FAILED: np.array(str(exc))})
                    raise
                store_entry(path, result)
    if _FAILED in result:
        raise DesignFailed(str(result[_FAILED]))
    return result


def content_hash(arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 of the arrays of a cache entry (names, dtypes, shapes and bytes)."""
    h = hashlib.sha256()
    for name in sorted(k for k in arrays if k != _HASH):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def load_entry(path: Path, verify: Callable[[dict[str, np.ndarray]], None] | None = None,
               warn: bool = True) -> dict[str, np.ndarray] | None:
    """The verified entry at ``path``, or None (missing; or invalid: warned, recomputed)."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            result = {k: data[k] for k in data.files}
        stored = str(result.pop(_HASH)) if _HASH in result else None
        if stored is None:
            raise ValueError("no content hash (written by an older version)")
        if stored != content_hash(result):
            raise ValueError("its content does not match its hash")
        if verify is not None and _FAILED not in result:
            verify(result)
    except Exception as exc:  # noqa: BLE001 - any broken entry is recomputed
        if warn:
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            print(f"warning: design cache entry {path} is invalid ({reason}); recomputing",
                  file=sys.stderr)
        return None
    return result


@contextlib.contextmanager
def key_lock(path: Path):
    """An exclusive advisory lock on ``path.lock`` (POSIX ``flock``; released if the holder
    dies); without ``fcntl`` or a writable folder, no lock (writes stay atomic)."""
    try:
        import fcntl

        path.parent.mkdir(parents=True, exist_ok=True)
        fh = open(path.with_suffix(".lock"), "a")  # noqa: SIM115 - closed below
    except (ImportError, OSError):
        yield
        return
    try:
        fcntl.flock(fh, fcntl.LOCK_EX)
        yield
        # no pile of empty lock files: a process still waiting on this one then finds the
        # stored design when it gets the lock (a late one may compute again: harmless)
        with contextlib.suppress(OSError):
            os.unlink(fh.name)
    finally:
        fh.close()  # closing releases the lock


def store_entry(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write the entry ``arrays`` at ``path`` atomically with its content hash (checked by
    :func:`load_entry`); an unwritable cache is silently skipped (the design is recomputed)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
        os.close(fd)
        np.savez(tmp, **arrays, **{_HASH: np.array(content_hash(arrays))})
        os.replace(tmp, path)
    except OSError:  # a read-only home must not break designs
        pass


# -- offline gain mixin ---------------------------------------------------------------------

class OfflineGain:
    """Mixin: ``design()`` sets ``self.L`` (n x ny) from ``gain=`` or the design."""

    OPTIONS: dict[str, Any] = {"gain": Matrix(None)}
    #: bump when the design code changes, so that cached gains are recomputed
    DESIGN_VERSION = "1"
    #: regression-gate tolerance: an SDP solution is accurate to the solver's tolerance
    #: (~1e-8) and may differ in its last digits between BLAS builds; 1e-4 still catches a
    #: 1 % change of the gain (see ``benchmarks/gate/regression.py``)
    REGRESSION_RTOL = 1e-4

    def design_gain(self) -> np.ndarray:
        """Solve the offline design; raise :class:`DesignFailed` if there is no gain."""
        raise NotImplementedError

    def design_params(self) -> dict[str, Any]:
        """Parameters the design depends on besides the system (part of the cache key)."""
        return {k: v for k, v in self.options.items() if k not in ("gain", "order", "reduction")}

    def design_kind(self) -> str:
        """Name of the design in the cache key (default: the observer's name); observers that
        share one design return the same kind and parameters, so it is solved once."""
        return self.name

    def design_arrays(self) -> dict[str, np.ndarray]:
        """Arrays the design depends on (part of the cache key)."""
        s = self.system
        arrays = {"A": s.A, "C": s.C, "E": s.W.G, "F": s.V.G, "cW": s.W.c, "cV": s.V.c}
        return {k: np.asarray(v, float) for k, v in arrays.items()}

    def design(self) -> None:
        super().design()  # type: ignore[misc]
        n, ny = self.system.C.shape[1], self.system.C.shape[0]
        given = self.options.get("gain")
        if given is not None:  # a finite numeric vector or matrix (its spec); the shape is ours
            L = np.array(given, dtype=float)
            if L.ndim == 1 and L.size == n * ny:
                L = L.reshape(n, ny)
            if L.shape != (n, ny):
                raise OptionError(f"{self.name}: gain must have shape ({n}, {ny}), got {L.shape}")
            self.L = L
            return
        def check(result: dict[str, np.ndarray]) -> None:
            L = np.asarray(result["gain"], dtype=float)
            if L.shape != (n, ny) or not np.all(np.isfinite(L)):
                raise DesignFailed(f"{self.name}: design returned an invalid gain of shape "
                                   f"{L.shape}")
            self.verify_gain(L)

        result = cached_design(self.design_kind(), self.DESIGN_VERSION, self.design_arrays(),
                               self.design_params(), lambda: {"gain": self.design_gain()},
                               verify=check)
        check(result)
        self.L = np.asarray(result["gain"], dtype=float)

    def verify_gain(self, L: np.ndarray) -> None:
        """Check a gain loaded from the cache (or just computed) as the design checks its own
        result; raise :class:`DesignFailed` if it is not valid.  Default: nothing beyond the
        shape and finiteness (the content hash of the cache entry guards the rest); a design
        whose gain must satisfy a property checkable without the design's other matrices
        overrides this."""
