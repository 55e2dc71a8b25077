"""Result output: the atomic writes, the output-folder check made before any work, the one
generation of ``runs.csv`` / ``summary.csv`` / ``meta.json`` and its verification on reading,
and the environment recorded with every result.

Single files are written to a temporary file in the target folder and renamed over the
target. The three result files of ``run`` are one *generation*: they are written into a
temporary folder beside the target folder, which is then swapped in with one atomic
``rename`` (``renameat2(RENAME_EXCHANGE)`` on Linux when the target exists), so that an
interrupted run leaves either the complete old set or the complete new one. Each file
carries the same run id (``run_id`` column; ``meta.json`` also records every file's size and
SHA-256), and :func:`load_results` refuses mixed, truncated or broken sets.

Files and folders are created with mode 0666 / 0777 reduced by the user's umask, as any
other program's output.
"""

from __future__ import annotations

import ctypes
import errno
import hashlib
import io
import json
import os
import platform
import re
import secrets
import shutil
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pandas as pd

from .errors import ConfigError

_UNSAFE = re.compile(r"[^A-Za-z0-9._+=,\[\]-]")


def path_component(name: str) -> str:
    """``name`` (a config, scenario or observer name) as one safe file or folder name: every
    character but letters, digits and ``._+=,[]-`` becomes ``_`` (so no ``/``, ``\\`` or
    NUL), and a leading dot too (no ``..``, no hidden files).

    Examples
    --------
    >>> path_component("../../x"), path_component("Acme/FRad"), path_component("ESO-C[cora]")
    ('_._.._x', 'Acme_FRad', 'ESO-C[cora]')
    """
    safe = _UNSAFE.sub("_", str(name))
    return "_" + safe[1:] if safe.startswith(".") else (safe or "_")


#: the files of one result generation, in the order they are written
RESULT_FILES = ("runs.csv", "summary.csv", "meta.json")
#: what ``report`` writes into a results folder: made from one generation, so a new
#: generation does not carry them over (``report`` regenerates them, with the new run id)
REPORT_ARTEFACTS = ("report.md", "index.html", "html_figures", "report_figures")


def _new_file(folder: Path, prefix: str, suffix: str = ".tmp") -> tuple[int, Path]:
    """Create a new, uniquely named file in ``folder`` with mode 0666 minus the umask (unlike
    :func:`tempfile.mkstemp`, which creates 0600)."""
    while True:
        path = folder / f"{prefix}{secrets.token_hex(4)}{suffix}"
        try:
            return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666), path
        except FileExistsError:  # pragma: no cover - 32 random bits collided
            continue


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (mode 0666 minus the umask)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _new_file(path.parent, f".{path.name}.")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def csv_text(df: pd.DataFrame) -> str:
    """A data frame as CSV text (full float precision), as every result file is written.

    A float is written the same whether its column is a float column or a column of mixed
    values (a store's merged rows: a seed ``0`` beside a record without one, read back as
    ``0.0``): ``%.17g`` either way, so a row's text does not depend on its neighbours."""
    def full_precision(v):
        return FLOAT_FORMAT % v if isinstance(v, float) and v == v else v

    mixed = {c: df[c].map(full_precision) for c in df.columns if df[c].dtype == object}
    return (df.assign(**mixed) if mixed else df).to_csv(index=False, float_format=FLOAT_FORMAT)


#: how a float is written in a result file (full precision, shortest for integral values)
FLOAT_FORMAT = "%.17g"


#: columns of the result tables that hold hex identifiers, read as text: ``pd.read_csv`` would
#: read the run id ``164025082e33`` as a float and ``0123456789012345`` without its zero
ID_COLUMNS = {"run_id": str, "fingerprint": str}


def read_table(source, **kwargs) -> pd.DataFrame:
    """A result table (``summary.csv``, ``runs.csv``, a study's table) as ``pd.read_csv``
    reads it, its :data:`ID_COLUMNS` kept as text (a ``dtype`` mapping in ``kwargs`` is merged
    with them)."""
    return pd.read_csv(source, dtype={**ID_COLUMNS, **kwargs.pop("dtype", {})}, **kwargs)


def atomic_write_csv(path: str | Path, df: pd.DataFrame) -> None:
    """Write a data frame as CSV atomically (full float precision)."""
    atomic_write_text(path, csv_text(df))


def json_text(obj) -> str:
    """``obj`` as indented JSON text with sorted keys."""
    return json.dumps(obj, indent=2, sort_keys=True, default=str) + "\n"


def atomic_write_json(path: str | Path, obj) -> None:
    """Write ``obj`` as indented JSON atomically."""
    atomic_write_text(path, json_text(obj))


def atomic_write_with(path: str | Path, write) -> None:
    """Write ``path`` atomically with ``write(tmp)``, a function that writes a file at the
    temporary path ``tmp`` beside it (e.g. a figure's ``savefig``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _new_file(path.parent, f".{path.stem}.", path.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def check_output_file(path: str | Path, what: str = "output file") -> Path:
    """Check, before any work, that file ``path`` can be written (atomically, by a
    temporary file beside it): it is not a folder, and its folder exists or can be made and
    is writable.

    Raises
    ------
    ConfigError
        With a one-line reason if it could not be written.
    """
    if str(path).strip() == "":
        raise ConfigError(f"{what}: an empty path")
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{what} {path} is a folder; give a file name")
    node = path.parent
    while not node.exists() and not node.is_symlink():
        node = node.parent
    if not node.is_dir():
        raise ConfigError(f"{what} {path}: {node} is not a folder")
    if not os.access(node, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)
                                                  and not os.access(node, os.W_OK)):
        raise ConfigError(f"{what} {path}: cannot write in {node} (permission denied)")
    return path


def write_error(exc: OSError, what: str) -> ConfigError:
    """A one-line error for an ``OSError`` while writing ``what`` (a full disk, ...)."""
    reason = exc.strerror or type(exc).__name__
    return ConfigError(f"cannot write {what}: {reason}"
                       + (f" ({exc.filename})" if exc.filename else ""))


# -- the output folder of `run` ------------------------------------------------------------
def _probe_writable(folder: Path, what: str) -> None:
    """Create and remove a folder in ``folder`` (what the generation swap will do)."""
    probe = folder / f".setobs-probe-{secrets.token_hex(4)}"
    try:
        probe.mkdir()
        probe.rmdir()
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise ConfigError(f"{what}: cannot write in {folder} ({reason})") from None


def check_output_dir(out: str | Path) -> Path:
    """Check, before any work, that the results of a run can be written to folder ``out``.

    ``out`` may not exist yet (it and its parents are created when the results are written);
    every existing part of the path must be a folder in which we may create and rename
    entries, and an existing non-empty ``out`` must be a results folder of an earlier run
    (it holds ``summary.csv`` or ``meta.json``), since the new generation replaces it.

    Parameters
    ----------
    out : str or Path
        The output folder.

    Returns
    -------
    Path
        ``out`` as an absolute path.

    Raises
    ------
    ConfigError
        With a one-line reason if the results could not be written there.
    """
    what = f"output folder {out}"
    if str(out).strip() == "":
        raise ConfigError("output folder: an empty path (give a folder, or leave --out out)")
    out = Path(os.path.realpath(out))  # a symlinked folder: work beside its target
    if out.parent == out:
        raise ConfigError(f"{what}: the root folder cannot be a results folder")
    node = out
    while not node.exists() and not node.is_symlink():
        node = node.parent
    if not node.is_dir():
        raise ConfigError(f"{what}: {node} is not a folder")
    if node == out:
        entries = {p.name for p in out.iterdir()}
        if entries and not entries & {"summary.csv", "meta.json"}:
            raise ConfigError(f"{what} exists and is not a results folder of `run` (it holds "
                              "no summary.csv); give a new or empty folder")
        _probe_writable(out, what)
        _probe_writable(out.parent, what)
    else:
        _probe_writable(node, what)
    return out


# -- one generation of result files ----------------------------------------------------------
def new_run_id() -> str:
    """A fresh random run id (12 hex digits)."""
    return secrets.token_hex(6)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _exchange(a: Path, b: Path) -> bool:
    """Atomically exchange the paths ``a`` and ``b`` (Linux ``renameat2``); False where the
    system does not offer it."""
    if not sys.platform.startswith("linux"):  # pragma: no cover - other systems
        return False
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):  # pragma: no cover - glibc < 2.28
        return False
    at_fdcwd, rename_exchange = -100, 2
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):  # pragma: no cover - e.g. some FS
        return False
    raise OSError(err, os.strerror(err), str(b))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # pragma: no cover - another user's process
        return True
    return True


def remove_stale_generations(out: Path) -> list[Path]:
    """Remove the temporary folders beside ``out`` left by writers that were killed (their
    process no longer exists); a writer still running keeps its folder.

    Returns
    -------
    list of Path
        The folders removed.
    """
    removed = []
    for tmp in out.parent.glob(f".{out.name}.new-*-*"):
        pid = tmp.name[len(f".{out.name}.new-"):].split("-")[0]
        if tmp.is_dir() and pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(tmp, ignore_errors=True)
            removed.append(tmp)
    return removed


def write_results(out: str | Path, frames: dict[str, pd.DataFrame], meta: dict) -> str:
    """Write ``runs.csv``, ``summary.csv`` and ``meta.json`` to folder ``out`` as one generation.

    Every CSV gets a ``run_id`` column and ``meta.json`` the keys ``run_id`` and ``files``
    (size and SHA-256 of each CSV). The files are written into a temporary folder beside
    ``out``; other entries of an existing ``out`` are moved into it, except the reports of
    the previous generation (:data:`REPORT_ARTEFACTS`: they describe the old CSVs, and go
    with them), and the folder is then swapped in atomically, so that a kill at any moment
    leaves either the old or the new generation in ``out``. Temporary folders of killed
    writers are removed the next time (:func:`remove_stale_generations`).

    Parameters
    ----------
    out : str or Path
        Target folder (checked with :func:`check_output_dir` first).
    frames : dict
        ``{"runs.csv": DataFrame, "summary.csv": DataFrame}``.
    meta : dict
        Content of ``meta.json`` (without ``run_id`` and ``files``).

    Returns
    -------
    str
        The run id.
    """
    out = check_output_dir(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_generations(out)
    run_id = new_run_id()
    tmp = out.parent / f".{out.name}.new-{os.getpid()}-{run_id}"
    tmp.mkdir()
    try:
        files = {}
        for name, df in frames.items():
            data = csv_text(df.assign(run_id=run_id)).encode("utf-8")
            (tmp / name).write_bytes(data)
            files[name] = {"bytes": len(data), "sha256": _sha256(data)}
        (tmp / "meta.json").write_text(json_text({**meta, "run_id": run_id, "files": files}),
                                       encoding="utf-8")
        for name in RESULT_FILES:
            with open(tmp / name, "rb") as fh:
                os.fsync(fh.fileno())
        if not out.exists():
            try:
                os.rename(tmp, out)
                return run_id
            except OSError as exc:  # another writer created it just now: swap as below
                if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                    raise
        # reports, figures: kept beside the new results
        tmp = swap_in(tmp, out, {*RESULT_FILES, *REPORT_ARTEFACTS}, run_id)
        return run_id
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def read_json_object(path: Path, what: str = "", fix: str = "") -> dict:
    """The JSON object in the file ``path``; a :class:`ConfigError` naming the file (``what``:
    its kind, e.g. ``baseline``) and ``fix`` (what to do) where it is not valid JSON or not an
    object."""
    name = f"{what} {path}" if what else str(path)
    tail = f"; {fix}" if fix else ""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        why = getattr(exc, "msg", None) or getattr(exc, "reason", "")
        raise ConfigError(f"{name} is not valid JSON ({why}){tail}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{name} is not a JSON object{tail}")
    return data


def swap_in(tmp: Path, out: Path, own: set[str] | tuple[str, ...], stamp: str) -> Path:
    """Put the new generation in folder ``tmp`` in place of the existing folder ``out``,
    atomically where the system can exchange two paths: the entries of ``out`` not named in
    ``own`` (the old generation's own files) move into ``tmp`` first, and back if the swap
    fails.  Returns the folder that now holds the old generation, for the caller to remove
    (``stamp`` names it where two renames replace the exchange)."""
    moved = [e.name for e in out.iterdir() if e.name not in own]
    try:
        for name in moved:
            os.rename(out / name, tmp / name)
        swapped = _exchange(tmp, out)
    except BaseException:
        for name in moved:  # put them back before the temporary folder goes
            if (tmp / name).exists():
                os.rename(tmp / name, out / name)
        raise
    if not swapped:  # pragma: no cover - no renameat2: two renames
        old = out.parent / f".{out.name}.old-{os.getpid()}-{stamp}"
        os.rename(out, old)
        os.rename(tmp, out)
        return old
    return tmp


def load_results(folder: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read ``summary.csv`` and ``meta.json`` of a results folder, after checking that the
    three result files are one complete generation.

    Parameters
    ----------
    folder : str or Path
        A folder written by ``run``.

    Returns
    -------
    summary : DataFrame
        ``summary.csv`` (without its ``run_id`` column).
    meta : dict
        ``meta.json``.

    Raises
    ------
    ConfigError
        With a one-line reason if a file is missing, broken, truncated or from another run.
    """
    folder = Path(folder)
    if not (folder / "summary.csv").is_file():
        raise ConfigError(f"no summary.csv in {folder} (run `python -m benchmarks run` first)")
    meta_path = folder / "meta.json"
    if not meta_path.is_file():
        raise ConfigError(f"{folder}: meta.json is missing; the result set is incomplete")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{meta_path} is not valid JSON: "
                          f"{getattr(exc, 'msg', None) or exc.reason}") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("files"), dict) or not isinstance(
            meta.get("run_id"), str):
        raise ConfigError(f"{meta_path} has no run id and file list (written by an older "
                          "version or by hand); re-run `python -m benchmarks run`")
    for name in RESULT_FILES[:2]:
        path = folder / name
        expected = meta["files"].get(name)
        if not isinstance(expected, dict):
            raise ConfigError(f"{meta_path} does not list {name}")
        if not path.is_file():
            raise ConfigError(f"{folder}: {name} is missing; the result set is incomplete")
        data = path.read_bytes()
        if len(data) != expected.get("bytes") or _sha256(data) != expected.get("sha256"):
            where = "truncated" if len(data) < expected.get("bytes", 0) else "changed"
            raise ConfigError(f"{path} is {where} or from another run than {meta_path} "
                              f"(run {meta['run_id']}); re-run `python -m benchmarks run`")
        if name == "summary.csv":
            try:
                summary = read_table(io.BytesIO(data))
            except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
                raise ConfigError(f"{path} is not readable CSV: "
                                  f"{str(exc).splitlines()[0]}") from None
    ids = set(summary.get("run_id", pd.Series(dtype=str)).astype(str))
    if ids != {meta["run_id"]}:
        raise ConfigError(f"{folder / 'summary.csv'} is not from run {meta['run_id']} of "
                          f"{meta_path}")
    check_columns(summary, folder / "summary.csv", SUMMARY_REQUIRED, SUMMARY_NUMERIC)
    return summary.drop(columns="run_id"), meta


#: columns a ``summary.csv`` must have, and those of them (where present) that are numbers
SUMMARY_REQUIRED = ("scenario", "observer", "state", "rel_rms", "status")
SUMMARY_NUMERIC = ("state", "rms_radius", "rel_rms", "step_ms", "hull_ms", "design_s",
                   "violations", "first_violation_step", "failed_step")
#: the same for ``runs.csv``
RUNS_REQUIRED = ("scenario", "observer", "step", "state", "lo", "hi", "x_true")
RUNS_NUMERIC = ("step", "t", "state", "lo", "hi", "radius", "x_true")


def check_columns(df: pd.DataFrame, path: Path, required: tuple[str, ...],
                  numeric: tuple[str, ...]) -> None:
    """Refuse a result table (edited by hand, its hashes recomputed) that lacks a column or
    has text in a numeric one: one line naming the file, the column and the row."""
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise ConfigError(f"{path} lacks column(s) {missing}; re-run `python -m benchmarks run`")
    for col in numeric:
        if col not in df.columns or pd.api.types.is_numeric_dtype(df[col]):
            continue
        values = pd.to_numeric(df[col], errors="coerce")
        bad = values.isna() & df[col].notna() & (df[col].astype(str).str.strip() != "")
        if bad.any():
            row = int(bad.to_numpy().nonzero()[0][0])
            raise ConfigError(f"{path}: column '{col}' holds text ({df[col].iloc[row]!r} in "
                              f"data row {row + 1}) where a number is expected")


def load_runs(folder: str | Path) -> pd.DataFrame:
    """``runs.csv`` of a results folder whose generation :func:`load_results` checked,
    with its columns checked (a missing column, text in a numeric one: one line)."""
    path = Path(folder) / "runs.csv"
    try:
        runs = read_table(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path} is not readable CSV: {str(exc).splitlines()[0]}") from None
    check_columns(runs, path, RUNS_REQUIRED, RUNS_NUMERIC)
    return runs


#: symbols of OpenBLAS builds that return the kernel family in use
_CORENAME_SYMBOLS = ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename",
                     "openblas_get_corename64_", "openblas_get_corename")


def blas_corename() -> str:
    """The OpenBLAS kernel family numpy runs here (``"Haswell"``, ``"SkylakeX"``, ...), as
    OpenBLAS chose it (by CPU, or by ``OPENBLAS_CORETYPE``); ``"unknown"`` for another BLAS."""
    import ctypes
    import glob

    import numpy as np

    root = Path(np.__file__).resolve().parent
    for lib in sorted(glob.glob(str(root.parent / "numpy.libs" / "*openblas*"))):
        try:
            handle = ctypes.CDLL(lib)
        except OSError:
            continue
        for symbol in _CORENAME_SYMBOLS:
            fn = getattr(handle, symbol, None)
            if fn is not None:
                fn.restype = ctypes.c_char_p
                return fn().decode().strip()
    return "unknown"


#: packages whose versions :func:`environment` records
ENVIRONMENT_PACKAGES = ("numpy", "scipy", "cvxpy", "clarabel", "highspy", "pandas")


def package_versions(packages: tuple[str, ...]) -> dict[str, str]:
    """The installed version of each of ``packages`` (``"missing"`` if not installed): the
    one reading of versions, for ``meta.json`` (:func:`environment`) and ``--version``."""
    out = {}
    for pkg in packages:
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "missing"
    return out


def environment() -> dict[str, str]:
    """Versions and platform of this process, as recorded in ``meta.json`` (``versions``).

    Returns
    -------
    dict of str to str
        ``python`` (version), ``platform``, ``blas_coretype`` (the OpenBLAS kernel family in
        use, :func:`blas_corename`), the version
        of each of :data:`ENVIRONMENT_PACKAGES` (``"missing"`` if not installed) and ``git``
        (the short commit of this checkout, ``""`` outside a git checkout).
    """
    out = {"python": sys.version.split()[0], "platform": platform.platform(),
           "blas_coretype": blas_corename(), **package_versions(ENVIRONMENT_PACKAGES)}
    try:
        out["git"] = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
            cwd=Path(__file__).resolve().parent, timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        out["git"] = ""
    return out

