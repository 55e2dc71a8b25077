"""Executors: named strategies that run the independent jobs of a benchmark.

A job is a picklable value, ``fn`` a module-level function; an executor yields
``(index, outcome)`` pairs as the jobs finish, where ``outcome`` is either ``fn(job)`` or a
:class:`JobFailure` (the job raised, its worker process died, or it exceeded its job timeout).
One failed job never stops the others.

Every executor keeps per-job *limits* (:meth:`set_limits`): a *job timeout* in seconds and a
memory limit in bytes (the resident memory the worker process running the job has gained
since it became ready for its first job, watched from the parent every :data:`POLL_S` seconds
and, when the job ends, its peak, so that a job that went over between two looks is caught
too; a ``MemoryError`` in the job counts as well).  A job over one is stopped from outside
(its worker ended; a job that ended over the memory limit loses its result) and reported as
``timeout`` or ``memory``.  What the worker holds when it is ready is not
the job's: the harness it imported, and the pages it shares with the server it was forked from
(with a cold numba cache that server compiled every kernel and holds about 1 GB of the
compiler's memory, which a fork counts as resident).  Three time limits
of the harness, not to be confused:

* the *job timeout* here, a hard stop: ``run --timeout`` or a configuration's ``timeout:``
  (default :data:`.config.DEFAULT_TIMEOUT`);
* the regression gate's *job budgets* (:mod:`benchmarks.gate.budget`): a job timeout per job,
  derived from the job's recorded cost, which ``check`` sets here job by job;
* the *projected stop* of a run (``observers.run(..., budget=...)``, :func:`.rows.execute_job`
  ``budget``): the observer's run itself ends early once its steps project it past the
  budget; only the scaling study passes it (its job timeout), ``run`` and ``check`` do not,
  so that a slow row there runs to its job timeout as before.

``serial``
    one job after the other (the default; the honest timing mode): the project's own
    observers in this process (their time budget by ``SIGALRM``), the jobs flagged
    ``isolate`` (third-party plugins) in one worker process, so that a plugin that ends its
    process, hangs or leaks memory is that job's row, never the end of the run.
``processes``
    a local pool of ``jobs`` worker processes (``run --jobs N``).  A worker is given a chunk
    of jobs but runs and reports them one at a time, so a worker that dies is attributed to
    the job it was running exactly (``error``, with the exit code), and a job running longer
    than ``timeout`` seconds is stopped by ending its worker (``timeout``); a new worker
    takes its place and the rest of the chunk.
``dask``
    a Dask cluster (``run --executor dask [--address tcp://HOST:PORT]``, needs the optional
    ``distributed`` package): the scheduler at ``address``, or a ``LocalCluster`` on the
    loopback interface started for the run.  Each task runs its job in a child process of
    its Dask worker (the same one-worker pool), which keeps the job timeout and the memory
    limit; where a worker may not start processes (a daemonic worker of a cluster not
    started by us) the job runs in the task itself, without them.  A task whose worker died
    (the scheduler's ``KilledWorker``) may only have shared the worker with the culprit:
    after the other jobs, each such task runs again alone on the cluster, and if its worker
    dies again it becomes that job's ``error``.

Local workers are forked from a server process that preloaded the harness, every observer
plugin and the compiled LP kernel (:mod:`benchmarks.run.workerinit`; the ``forkserver`` method,
``spawn`` where there is none).  Why not ``fork`` from the parent: the parent may hold
threads (a progress bar's monitor, a Dask client), which a fork does not carry over (locks
they hold stay locked in the child); and why not ``spawn``: each worker would import
everything again (about 3 s of CPU here).  The server is started when the executor is made
(:class:`ProcessExecutor`), so its imports overlap the reading of the config.  Workers take
the parent's environment when they start, and the BLAS thread counts are already pinned to 1
in the server (see :mod:`benchmarks`): no oversubscription by N workers.

Jobs are handed to local workers in chunks (:func:`chunks`): the jobs of one scenario
instance go to one worker together, so that it builds the scenario and what its observers
share (the data-driven observers' learned model, a quarter of the sweep's CPU) once, as the serial
run does, and a result travels back per job (its failure, limits and row stay per job).
"""

from __future__ import annotations

import importlib
import multiprocessing as mp
import os
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing.connection import wait
from typing import Any

from ..errors import ConfigError

EXECUTORS = ("serial", "processes", "dask")
_KILLED = object()  # a Dask task whose worker died
#: the scheduler options of a local Dask cluster: its HTTP server (which it starts even with
#: the dashboard off, on port 8787 by default, moving off it with a UserWarning where that is
#: taken) on a free port of the loopback interface
LOCAL_HTTP = {"dashboard_address": "127.0.0.1:0"}
#: the modules a local worker imports before its first job (the forkserver's preload, or a
#: spawned worker's first step): named, not imported here, so that the executors do not
#: depend on the harness they run (:mod:`benchmarks.run.workerinit` imports it)
PRELOAD = ("benchmarks.run.workerinit",)
#: the forkserver's preload: :mod:`benchmarks.run.serverguard` first (the server ends with the
#: process that started it, and its workers with it), then :data:`PRELOAD`
SERVER_PRELOAD = ("benchmarks.run.serverguard", *PRELOAD)
#: seconds between two looks at the workers' resident memory
POLL_S = 0.2
#: statuses of jobs stopped by their limits
BUDGET_STATUSES = ("timeout", "memory")


@dataclass(frozen=True)
class JobFailure:
    """A job that produced no result: ``status`` is ``error``, ``timeout`` or ``memory``."""

    status: str
    message: str


def _describe(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


def format_bytes(n: float) -> str:
    """``n`` bytes in the largest binary unit (``1.5 GiB``)."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(n) < 1024 or unit == "GiB":
            return f"{n:.3g} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.3g} TiB"  # pragma: no cover


def rss_bytes(pid: int) -> int | None:
    """Resident memory of process ``pid`` (Linux ``/proc``; None elsewhere or if gone)."""
    try:
        with open(f"/proc/{pid}/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def _own_memory() -> tuple[int | None, int | None]:  # pragma: no cover - in the worker
    """This process's resident memory now and its peak (``VmRSS``, ``VmHWM``; None where
    ``/proc`` does not say)."""
    now = peak = None
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    now = int(line.split()[1]) * 1024
                elif line.startswith("VmHWM:"):
                    peak = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return now, peak


def _reset_peak() -> int | None:  # pragma: no cover - in the worker
    """Set this process's peak resident memory to what it holds now (Linux ``clear_refs``,
    value 5) and return that: the base a job's peak is measured from.  Where the peak cannot
    be reset, the peak so far (a job is then charged only what goes beyond it)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        return _own_memory()[1]
    return _own_memory()[0]


def job_memory(w: _Worker) -> int | None:
    """Resident bytes worker ``w`` gained since it first started a job (None if unknown)."""
    used = rss_bytes(w.proc.pid)
    if used is None or w.base is None:
        return None
    return used - w.base


def _peak_over(w: _Worker, peak: int | None, limit: int | None) -> int | None:
    """The peak resident memory the job that just ended in ``w`` gained, if over ``limit``
    (None: within it, or not known).  The peak of a worker only grows and every job before
    this one ended within the limit (else its worker was ended), so a peak over it is this
    job's."""
    if limit is None or peak is None or w.base is None:
        return None
    return peak - w.base if peak - w.base > limit else None


def _timeout_message(timeout: float) -> str:
    return f"stopped after the budget of {timeout:g} s"


def _memory_message(limit: int, used: int | None = None, peak: bool = False) -> str:
    if peak:  # seen when the job ended: its result is not taken
        return (f"went over the memory limit of {format_bytes(limit)} (the job's peak "
                f"resident memory {format_bytes(used)}); its result is not taken")
    used_s = f" (the job's resident memory {format_bytes(used)})" if used else ""
    return f"stopped over the memory limit of {format_bytes(limit)}{used_s}"


class JobTimeout(BaseException):
    """Raised in a job run in this process when its job timeout is over (a BaseException, so
    that the observer loop's ``except Exception`` does not turn it into an ``error``)."""


@contextmanager
def _alarm(timeout: float | None) -> Iterator[None]:
    """Raise :class:`JobTimeout` in the block after ``timeout`` seconds (``SIGALRM``; only in
    the main thread of a POSIX process: elsewhere no timeout)."""
    usable = (timeout is not None and hasattr(signal, "setitimer")
              and threading.current_thread() is threading.main_thread())
    if not usable:
        yield
        return

    def _raise(signum, frame):
        raise JobTimeout(_timeout_message(timeout))

    old = signal.signal(signal.SIGALRM, _raise)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def default_jobs() -> int:
    """Worker processes by default: the number of cores."""
    return max(1, os.cpu_count() or 1)


class _Limited:
    """The per-job limits of an executor (see the module docstring)."""

    timeout: float | None = None
    memory_limit: int | None = None

    def set_limits(self, timeout: float | None, memory_limit: int | None) -> None:
        """Job timeout (seconds) and memory limit (bytes) per job; None: no limit."""
        if timeout is not None and not timeout > 0:
            raise ConfigError(f"the job time budget must be positive, got {timeout!r}")
        if memory_limit is not None and not memory_limit > 0:
            raise ConfigError(f"the job memory limit must be positive, got {memory_limit!r}")
        self.timeout, self.memory_limit = timeout, memory_limit


class SerialExecutor(_Limited):
    """Every job in order: in this process, or (``isolate``) in one worker process.

    Parameters
    ----------
    timeout, memory_limit : optional
        The per-job limits (:meth:`set_limits`).  In this process only the job timeout is
        kept (``SIGALRM`` in the main thread: it stops Python code, not a long call into
        compiled code); an isolated job keeps both, and cannot end this process.
    """

    name = "serial"
    workers = 1

    def __init__(self, timeout: float | None = None, memory_limit: int | None = None):
        self.set_limits(timeout, memory_limit)
        self._pool: ProcessExecutor | None = None

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any],
            keys: Sequence[Any] | None = None,
            isolate: Sequence[bool] | None = None) -> Iterator[tuple[int, Any]]:
        """Yield ``(index, fn(job) or JobFailure)`` in job order (``keys``: unused here);
        the jobs with ``isolate[i]`` true run in a worker process (one at a time)."""
        for i, job in enumerate(jobs):
            if isolate is not None and isolate[i]:
                if self._pool is None:
                    self._pool = ProcessExecutor(1, self.timeout, self.memory_limit)
                yield from ((i, out) for _, out in self._pool.map(fn, [job]))
                continue
            try:
                with _alarm(self.timeout):
                    out = fn(job)
            except ConfigError:
                raise
            except JobTimeout as exc:
                out = JobFailure("timeout", str(exc))
            except MemoryError as exc:
                out = JobFailure("memory", f"MemoryError: {exc}")
            except Exception as exc:
                out = JobFailure("error", _describe(exc))
            yield i, out

    def close(self) -> None:
        """End the worker process of the isolated jobs, if one was started."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None


def _die_with_parent() -> None:  # pragma: no cover - in the worker
    """Linux: this process is killed when its parent ends (``PR_SET_PDEATHSIG``), so that a
    job stuck in a loop does not outlive a run that was interrupted or killed."""
    parent = os.getppid()
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent ended before the call
        os._exit(1)


def _worker_loop(conn, env: dict[str, str],
                 preload: bool = False) -> None:  # pragma: no cover - in the worker
    _die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    if preload:  # a spawned worker: what the server would have preloaded, before any timeout
        try:
            for module in PRELOAD:
                importlib.import_module(module)
        except Exception:
            pass
    # the parent's environment now (the server forked from may have started with another one:
    # settings read when used, like SETOBS_CACHE_DIR, then follow the parent)
    os.environ.clear()
    os.environ.update(env)
    base = None
    while True:
        try:
            msg = conn.recv()
        except EOFError:
            return
        if msg is None:
            return
        fn, chunk = msg
        for _, job in chunk:
            # the timeout counts from here (not the worker start); the first job also sends
            # the memory the worker holds before any job, from which every job's peak counts
            if base is None:
                base = _reset_peak()
            conn.send(("started", base, None))  # every message: (kind, value, peak)
            try:
                out = ("ok", fn(job))
            except ConfigError as exc:  # bad input: ends the run in the parent (exit 2)
                out = ("config", str(exc))
            except MemoryError as exc:
                out = ("memory", _describe(exc))
            except Exception as exc:
                out = ("raised", _describe(exc))
            peak = _own_memory()[1]  # the job's peak: a job may end before a poll sees it
            try:
                conn.send((*out, peak))
            except Exception as exc:  # an unpicklable result
                conn.send(("raised", f"result not transferable: {_describe(exc)}", peak))


class _Worker:
    """One worker process and the chunk of jobs it holds (the first one is running)."""

    def __init__(self, ctx):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_loop, daemon=True, args=(
            child, dict(os.environ), ctx.get_start_method() == "spawn"))
        self.proc.start()
        child.close()
        self.chunk: deque = deque()
        self.started: float | None = None
        #: resident bytes when the worker first started a job (what it holds before any job)
        self.base: int | None = None

    @property
    def index(self) -> int:
        """The job the worker runs (or is about to start)."""
        return self.chunk[0][0]

    def give(self, fn, chunk: list) -> None:
        self.conn.send((fn, chunk))  # pickled first: a failure sends nothing
        self.chunk, self.started = deque(chunk), None

    def end(self, kill: bool = False) -> None:
        if kill:
            self.proc.kill()
        else:
            try:
                self.conn.send(None)
            except OSError:
                pass
        self.proc.join(timeout=5)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()


def chunks(keys: Sequence[Any] | None, n: int, workers: int) -> list[list[int]]:
    """Job indices ``0..n-1`` in chunks: contiguous runs of equal ``keys``, each cut into
    pieces of at most ``ceil(n / (4 workers))`` jobs (so that every worker gets several
    chunks and the last ones are short); without keys, one job per chunk.

    Examples
    --------
    >>> chunks(["a", "a", "a", "b"], 4, 1)
    [[0], [1], [2], [3]]
    >>> chunks(["a"] * 8 + ["b"] * 8, 16, 1)
    [[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11], [12, 13, 14, 15]]
    """
    if keys is None:
        return [[i] for i in range(n)]
    size = max(1, -(-n // (4 * workers)))
    out: list[list[int]] = []
    for i in range(n):
        if out and keys[i] == keys[out[-1][-1]] and len(out[-1]) < size:
            out[-1].append(i)
        else:
            out.append([i])
    return out


def _exit_reason(code: int | None) -> str:
    if code is not None and code < 0:
        return f"signal {-code}"
    return f"exit code {code}"


def _context(method: str | None = None):
    """``forkserver`` with the harness preloaded where available (a new worker is then a fork
    of a clean process that already imported numpy, cvxpy, ...: fast), else ``spawn``;
    ``method`` forces one."""
    if method is not None:
        return mp.get_context(method)
    if "forkserver" in mp.get_all_start_methods():
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(list(SERVER_PRELOAD))
        return ctx
    return mp.get_context("spawn")


class ProcessExecutor(_Limited):
    """A pool of ``jobs`` local worker processes, one job per worker at a time.

    Parameters
    ----------
    jobs : int
        Number of worker processes (>= 1).
    timeout : float, optional
        Budget in seconds per job; a job over it is stopped (its worker ended) and reported
        as ``timeout``.
    memory_limit : int, optional
        Bytes of resident memory a worker may gain, from the start of its first job, while it
        runs a job; a job over it is stopped (its worker ended) and reported as ``memory``,
        and so is a job whose peak, read when it ended, was over it (its result not taken).
    """

    name = "processes"

    def __init__(self, jobs: int, timeout: float | None = None,
                 memory_limit: int | None = None, start_method: str | None = None):
        if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
            raise ConfigError(f"--jobs must be an integer >= 1, got {jobs!r}")
        self.set_limits(timeout, memory_limit)
        self.workers = jobs
        self._ctx = _context(start_method)
        self._idle: list[_Worker] = []
        if self._ctx.get_start_method() == "forkserver":
            # start the server now: it preloads the harness while the caller reads its config
            from multiprocessing import forkserver
            forkserver.ensure_running()

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any],
            keys: Sequence[Any] | None = None,
            isolate: Sequence[bool] | None = None) -> Iterator[tuple[int, Any]]:
        """Yield ``(index, fn(job) or JobFailure)`` as the jobs finish (every job is isolated
        here: ``isolate`` is not used).

        ``keys`` (one per job): consecutive jobs with the same key go to one worker together
        (:func:`chunks`), so that what they share is built once in that worker (a scenario,
        a learned model).  A worker still reports each job on its own: if it dies or
        exceeds the job timeout, the job it was running gets the failure and the rest of its chunk
        goes to another worker.
        """
        pending = deque([(i, jobs[i]) for i in c] for c in chunks(keys, len(jobs), self.workers))
        busy: dict[Any, _Worker] = {}

        def fail(w: _Worker, status: str, message: str) -> tuple[int, JobFailure]:
            """End ``w`` (its job failed); the rest of its chunk goes back to the queue."""
            w.end(kill=True)
            index, _ = w.chunk.popleft()
            if w.chunk:
                pending.appendleft(list(w.chunk))
            return index, JobFailure(status, message)

        try:
            while pending or busy:
                while pending and len(busy) < self.workers:
                    w = self._idle.pop() if self._idle else _Worker(self._ctx)
                    chunk = pending.popleft()
                    try:
                        w.give(fn, chunk)
                    except Exception as exc:  # a job itself cannot be sent (pickling)
                        self._idle.append(w)
                        if len(chunk) > 1:  # find which one: send them one by one
                            pending.extendleft([job] for job in reversed(chunk))
                            continue
                        yield chunk[0][0], JobFailure(
                            "error", f"job not transferable: {_describe(exc)}")
                        continue
                    busy[w.conn] = w
                wait_s = POLL_S if self.memory_limit is not None else None
                running = [w.started for w in busy.values() if w.started is not None]
                if self.timeout is not None and running:
                    left = max(0.0, min(running) + self.timeout - time.monotonic())
                    wait_s = left if wait_s is None else min(wait_s, left)
                for conn in wait(list(busy), timeout=wait_s):
                    w = busy.pop(conn)
                    try:
                        kind, value, peak = conn.recv()
                    except (EOFError, OSError):
                        w.proc.join(timeout=5)
                        yield fail(w, "error", "worker process died while running this job "
                                               f"({_exit_reason(w.proc.exitcode)})")
                        continue
                    if kind == "started":  # value: the worker's base (one value per worker)
                        w.started = time.monotonic()
                        w.base = value
                        busy[conn] = w
                        continue
                    if kind == "memory":  # the worker may keep what the job took: end it
                        yield fail(w, "memory", value)
                        continue
                    over = _peak_over(w, peak, self.memory_limit)
                    if over is not None:  # the job went over between two polls
                        yield fail(w, "memory", _memory_message(self.memory_limit, over,
                                                                peak=True))
                        continue
                    index, _ = w.chunk.popleft()
                    w.started = None
                    if w.chunk:
                        busy[conn] = w
                    else:
                        self._idle.append(w)
                    if kind == "config":
                        raise ConfigError(value)
                    yield index, value if kind == "ok" else JobFailure("error", value)
                now = time.monotonic()
                for conn, w in list(busy.items()):
                    if w.started is None:
                        continue
                    if self.timeout is not None and now - w.started >= self.timeout:
                        del busy[conn]
                        yield fail(w, "timeout", _timeout_message(self.timeout))
                    elif self.memory_limit is not None:
                        used = job_memory(w)
                        if used is not None and used > self.memory_limit:
                            del busy[conn]
                            yield fail(w, "memory", _memory_message(self.memory_limit, used))
        finally:
            for w in busy.values():
                w.end(kill=True)

    def close(self) -> None:
        """End the idle workers."""
        while self._idle:
            self._idle.pop().end()


@contextmanager
def _no_sigint() -> Iterator[None]:
    """Ignore Ctrl-C (SIGINT) in the block: processes started in it inherit that (Python keeps
    an ignored SIGINT ignored), so they leave the interruption to this process."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


_TASK_POOLS: dict[tuple, ProcessExecutor] = {}


def _isolated_task(fn: Callable[[Any], Any], job: Any, timeout: float | None,
                   memory_limit: int | None) -> Any:
    """A Dask task: ``fn(job)`` in a child process of this Dask worker with the limits (one
    pool per worker process and limits, kept for the next tasks); ``fn(job)`` here where
    this process may not have children (a daemonic worker).  The child is spawned, not
    forked from a server: a direct child dies with its Dask worker (no orphan left running
    a hung job when the cluster closes)."""
    key = (timeout, memory_limit)
    try:
        pool = _TASK_POOLS.get(key) or _TASK_POOLS.setdefault(
            key, ProcessExecutor(1, timeout, memory_limit, start_method="spawn"))
        return next(iter(pool.map(fn, [job])))[1]
    except AssertionError:  # "daemonic processes are not allowed to have children"
        return fn(job)


class DaskExecutor(_Limited):
    """Jobs as tasks of a Dask cluster (``distributed``).

    Parameters
    ----------
    address : str, optional
        Scheduler address (``tcp://HOST:PORT``); without it a ``LocalCluster`` listening on
        127.0.0.1 only is started with ``jobs`` single-threaded worker processes.
    jobs : int
        Workers of the local cluster.
    """

    name = "dask"

    def __init__(self, address: str | None = None, jobs: int | None = None):
        try:
            import dask
            from distributed import Client, LocalCluster
        except ImportError:
            raise ConfigError("--executor dask needs the optional 'distributed' package "
                              "(pip install 'setobs-bench[dask]')") from None
        self.cluster = None
        if address is None:
            self.workers = jobs or default_jobs()
            # one task per worker thread at a time (no queued tasks on a worker that dies),
            # and a task whose worker died is not retried on another one: reported at once
            # (non-daemonic workers: each task runs its job in a child process, with the limits)
            # no HTTP routes (dashboard, /health, /metrics, /info): the HTTP server each Dask
            # node starts anyway then serves nothing, the scheduler's on a free loopback port
            # (LOCAL_HTTP: two clusters at once, e.g. parallel tests, do not both want 8787);
            # workers ignore Ctrl-C (the parent handles it and closes the cluster: no page of
            # worker tracebacks)
            with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                                  "distributed.scheduler.worker-saturation": 1.0,
                                  "distributed.worker.daemon": False,
                                  "distributed.scheduler.http.routes": [],
                                  "distributed.worker.http.routes": []}), _no_sigint():
                self.cluster = LocalCluster(
                    n_workers=self.workers, threads_per_worker=1, processes=True,
                    host="127.0.0.1", dashboard_address=None, scheduler_kwargs=LOCAL_HTTP,
                    silence_logs=50)
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(address, timeout="10s")
            except Exception as exc:  # unreachable, or not an address at all
                reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                raise ConfigError(f"cannot reach the Dask scheduler at {address}: "
                                  f"{reason}") from None
            self.workers = max(1, sum(self.client.nthreads().values()))
        self.address = self.client.scheduler.address

    def map(self, fn: Callable[[Any], Any], jobs: Sequence[Any],
            keys: Sequence[Any] | None = None,
            isolate: Sequence[bool] | None = None) -> Iterator[tuple[int, Any]]:
        """Yield ``(index, fn(job) or JobFailure)`` as the tasks finish.

        ``keys`` and ``isolate`` are not used: the scheduler places every job as a task of
        its own, which runs it in a child process (:func:`_isolated_task`).
        """
        from distributed import as_completed

        def submit(job):
            return self.client.submit(_isolated_task, fn, job, self.timeout, self.memory_limit,
                                      pure=False)

        futures = {submit(job): i for i, job in enumerate(jobs)}
        suspects = []
        try:
            for fut in as_completed(futures):
                i = futures.pop(fut)
                out = self._outcome(fut)
                if out is _KILLED:
                    suspects.append(i)
                else:
                    yield i, out
            # a task may only have shared its worker with the one that killed it: run each
            # suspect again, alone on the cluster; one that kills its worker then is the cause
            for i in suspects:
                fut = submit(jobs[i])
                futures[fut] = i
                out = self._outcome(fut)
                del futures[fut]
                yield i, (out if out is not _KILLED else JobFailure(
                    "error", "worker process died while running this job (twice, the second "
                             "time alone on the cluster)"))
        finally:
            self.client.cancel(list(futures))

    @staticmethod
    def _outcome(fut):
        try:
            return fut.result()
        except ConfigError:
            raise
        except Exception as exc:
            if type(exc).__name__ == "KilledWorker":
                return _KILLED
            return JobFailure("error", _describe(exc))

    def close(self) -> None:
        """Close the client (and the local cluster if this executor started it)."""
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def run_tasks(fn: Callable[[Any], Any], tasks: Sequence[Any], jobs: int,
              done: Callable[[Any, Any], None] | None = None) -> list[Any]:
    """``[fn(task) for task in tasks]`` in ``jobs`` local worker processes (in this process if
    ``jobs`` is 1), for commands whose tasks must all succeed (``audit``, ``designs``).

    ``done(task, result)`` is called as each task finishes (e.g. a progress bar).

    Raises
    ------
    RuntimeError
        At the first task that failed (raised, its worker died, ...): the others are stopped.
    """
    executor = make_executor("processes", jobs)
    out: list[Any] = [None] * len(tasks)
    try:
        for i, res in executor.map(fn, tasks):
            if isinstance(res, JobFailure):
                raise RuntimeError(f"task {tasks[i]!r} failed: {res.message}")
            out[i] = res
            if done is not None:
                done(tasks[i], res)
    finally:
        executor.close()
    return out


def from_args(kind: str | None, jobs: int | None, address: str | None):
    """The executor of ``run [--executor K] [--jobs [N]] [--address A]``.

    No option: serial.  ``--jobs`` alone: local processes (``--jobs`` without a number, i.e.
    ``jobs == 0``: one per core).  ``--address`` alone implies ``dask``.
    """
    if jobs == 0:
        jobs = default_jobs()
    if kind is None:
        kind = "dask" if address else ("processes" if jobs is not None else "serial")
    return make_executor(kind, jobs, address)


def make_executor(kind: str = "serial", jobs: int | None = None, address: str | None = None):
    """The executor named ``kind`` (one of :data:`EXECUTORS`).

    ``kind="processes"`` with ``jobs=1`` is the serial executor; ``address`` is only for
    ``dask``.
    """
    if kind not in EXECUTORS:
        raise ConfigError(f"unknown executor '{kind}' (known: {', '.join(EXECUTORS)})")
    if address is not None and kind != "dask":
        raise ConfigError("--address needs --executor dask")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ConfigError(f"--jobs must be an integer >= 1, got {jobs!r}")
    if kind == "dask":
        return DaskExecutor(address, jobs)
    if kind == "processes" and (jobs or default_jobs()) > 1:
        return ProcessExecutor(jobs or default_jobs())
    return SerialExecutor()
