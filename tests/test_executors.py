"""Parallel and distributed runs: identical results, per-job failures, a shared design cache."""

from __future__ import annotations

import importlib
import multiprocessing as mp
import os
import socket
import time
import warnings

import numpy as np
import pandas as pd
import pytest
import yaml

from benchmarks import load_config, write_report
from benchmarks.cli import main
from benchmarks.errors import ConfigError
from benchmarks.metrics import TIMING_COLUMNS
from benchmarks.run.executors import (
    LOCAL_HTTP,
    JobFailure,
    ProcessExecutor,
    SerialExecutor,
    chunks,
    from_args,
    run_tasks,
)
from benchmarks.verdicts import EXIT_CRASH
from observers import registry
from observers.offline import cached_design

TIMING = list(TIMING_COLUMNS)
RUN_ID = ["run_id"]  # the identifier of each run's generation of result files
SWEEP = {
    "name": "sweep",
    "scenarios": [{"name": "alamo2d-sim", "steps": 12}, {"name": "tank{n}-linear", "steps": 15}],
    "observers": ["FRad-A", "FRad-C", "PRad-B", "CZN-A", "Hinf-G"],
    "containment": "hull",
    "sweep": {"seeds": [0, 1], "sizes": [4], "grid": {"FRad-A": {"order": [5, 20]}}},
}


@pytest.fixture(scope="module")
def cluster():
    """A real Dask LocalCluster on the loopback interface, two single-threaded workers."""
    distributed = pytest.importorskip("distributed")
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=None,
                                     scheduler_kwargs=LOCAL_HTTP, silence_logs=40) as c:
        yield c


def _run(tmp_path, name, cfg, *extra, code=0) -> pd.DataFrame:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / name
    assert main(["run", str(path), "--out", str(out), "--no-progress", *extra]) == code
    return pd.read_csv(out / "summary.csv")


def test_serial_jobs2_and_dask_give_the_identical_summary(tmp_path):
    pytest.importorskip("distributed")
    serial = _run(tmp_path, "serial", SWEEP)
    # the tidy table: every scenario x seed x observer x variant x state
    assert len(serial) == 2 * (2 + 4) * 6
    assert set(serial["variant"].fillna("")) == {"", "order=5", "order=20"}
    assert (serial["status"] == "ok").all() and (serial["timed"] == "serial").all()
    jobs2 = _run(tmp_path, "jobs2", SWEEP, "--jobs", "2")
    dask = _run(tmp_path, "dask", SWEEP, "--executor", "dask", "--jobs", "2")  # LocalCluster
    assert (jobs2["timed"] == "parallel").all() and (dask["timed"] == "parallel").all()
    pd.testing.assert_frame_equal(serial.drop(columns=TIMING + RUN_ID),
                                  jobs2.drop(columns=TIMING + RUN_ID))
    pd.testing.assert_frame_equal(serial.drop(columns=TIMING + RUN_ID),
                                  dask.drop(columns=TIMING + RUN_ID))
    runs = [pd.read_csv(tmp_path / d / "runs.csv").drop(columns=RUN_ID, errors="ignore")
            for d in ("serial", "jobs2", "dask")]
    pd.testing.assert_frame_equal(runs[0], runs[1])
    pd.testing.assert_frame_equal(runs[0], runs[2])
    # the reports say which times were measured with jobs running concurrently
    texts = {d: write_report(tmp_path / d, figures=False).read_text() for d in ("serial", "jobs2")}
    assert "step ms (parallel)" in texts["jobs2"] and "measured while 2 jobs ran" in texts["jobs2"]
    assert "(parallel)" not in texts["serial"] and "| step ms |" in texts["serial"]


@pytest.fixture
def crash_observer():
    import tests.plugins.crash

    importlib.reload(tests.plugins.crash)  # (re-)registers Test-Crash
    yield "Test-Crash"
    registry.unregister("Test-Crash", missing_ok=True)


@pytest.mark.heavy
@pytest.mark.parametrize("executor", ["processes", "dask"])
def test_a_worker_that_dies_is_that_jobs_error_and_the_run_completes(
        tmp_path, crash_observer, executor, capsys, request):
    """A job that kills its worker process mid-sweep: that job is an error row, the rest ok
    (Dask: a running LocalCluster, reached by its address)."""
    args = ["--jobs", "2"] if executor == "processes" else [
        "--address", request.getfixturevalue("cluster").scheduler_address]
    cfg = {"name": "crash", "scenarios": [{"name": "alamo2d-sim", "steps": 10}],
           "observers": ["FRad-A", crash_observer, "FRad-C"], "containment": "hull",
           "sweep": {"seeds": [0, 1]}}
    summary = _run(tmp_path, "crash", cfg, *args, code=EXIT_CRASH)  # complete, one crashed
    jobs = summary.drop_duplicates(["seed", "observer"]).set_index(["observer", "seed"])
    assert len(jobs) == 6
    crashed = jobs.loc[crash_observer]
    assert (crashed["status"] == "error").all()
    assert crashed["message"].str.contains("worker process died").all()
    others = jobs.drop(index=crash_observer, level=0)
    assert (others["status"] == "ok").all()
    assert "Test-Crash on alamo2d-sim: error: worker process died" in capsys.readouterr().err


def _sleepy(seconds):
    time.sleep(seconds)
    return seconds


def test_a_job_over_its_budget_is_stopped_and_reported_as_timeout():
    ex = ProcessExecutor(2, timeout=1.0)
    try:
        t0 = time.monotonic()
        out = dict(ex.map(_sleepy, [0.0, 60.0, 0.1]))
        assert time.monotonic() - t0 < 30  # stopped, not waited for
    finally:
        ex.close()
    assert out[0] == 0.0 and out[2] == 0.1
    assert out[1] == JobFailure("timeout", "stopped after the budget of 1 s")


def _raises(x):
    raise ValueError(f"bad {x}")


@pytest.mark.parametrize("ex", [SerialExecutor(), ProcessExecutor(1)], ids=["serial", "proc"])
def test_a_job_that_raises_is_an_error_outcome(ex):
    try:
        out = dict(ex.map(_raises, [3]))
    finally:
        ex.close()
    assert out == {0: JobFailure("error", "ValueError: bad 3")}


def test_executor_options_are_checked():
    with pytest.raises(ConfigError, match="--jobs must be an integer >= 1"):
        from_args(None, -1, None)
    with pytest.raises(ConfigError, match="--address needs --executor dask"):
        from_args("processes", 2, "tcp://127.0.0.1:1")
    assert isinstance(from_args(None, None, None), SerialExecutor)
    assert from_args(None, 0, None).workers >= 1  # --jobs without N: the cores


def test_sweep_config_errors(tmp_path):
    bad = dict(SWEEP, sweep={"seeds": [0, 0]})
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(ConfigError, match="seeds: a value appears twice"):
        load_config(path)
    path.write_text(yaml.safe_dump(dict(SWEEP, sweep={"grid": {"FRad-A": {"nope": [1]}}})))
    with pytest.raises(ConfigError, match=r"grid: FRad-A has no option\(s\) \['nope'\]"):
        load_config(path)
    path.write_text(yaml.safe_dump(dict(SWEEP, sweep={"seeds": [1]})))
    with pytest.raises(ConfigError, match=r"has \{n\} but the sweep gives no sizes"):
        load_config(path)


# -- design cache under concurrent writers --------------------------------------------------
def _design_in_process(args):
    cache, log = args
    import os

    os.environ["SETOBS_CACHE_DIR"] = cache

    def compute():
        with open(log, "a") as fh:
            fh.write("computed\n")
        time.sleep(0.5)  # long enough for the other process to ask for the same key
        return {"gain": np.arange(4.0)}

    return cached_design("Test", "1", {"A": np.eye(2)}, {"p": 1}, compute)["gain"].tolist()


def test_design_is_computed_once_by_concurrent_processes(tmp_path):
    log = tmp_path / "log.txt"
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["observers.offline"])
    with ctx.Pool(3) as pool:
        results = pool.map(_design_in_process, [(str(tmp_path / "cache"), str(log))] * 3)
    assert results == [[0.0, 1.0, 2.0, 3.0]] * 3
    assert log.read_text().count("computed") == 1
    assert not list((tmp_path / "cache").glob("*.tmp"))


def test_bad_option_value_in_a_worker_ends_the_run_without_results(tmp_path, capsys):
    """Bad input found in a worker is a one-line error (exit 2), and no partial results."""
    cfg = {"name": "bad", "scenarios": [{"name": "alamo2d-sim", "steps": 5}],
           "observers": ["FRad-A", "FRad-C"], "options": {"order": -3}}
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "bad"
    assert main(["run", str(path), "--out", str(out), "--no-progress", "--jobs", "2"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "order" in err
    assert not (out / "summary.csv").exists() and not (out / "runs.csv").exists()


# -- chunks of jobs per worker -------------------------------------------------------------
def test_chunks_follow_the_keys_and_are_capped():
    # 16 jobs, 2 workers: at most ceil(16 / 8) = 2 per chunk, never across a key change
    keys = ["a"] * 5 + ["b"] * 3 + ["c"] * 8
    assert chunks(keys, 16, 2) == [[0, 1], [2, 3], [4], [5, 6], [7], [8, 9], [10, 11],
                                   [12, 13], [14, 15]]
    assert chunks(None, 3, 2) == [[0], [1], [2]]  # no keys: one job each
    assert chunks(["a"] * 3, 3, 8) == [[0], [1], [2]]


def _die_on(x):
    if x == "die":
        import os

        os._exit(3)
    return x


def test_a_worker_that_dies_mid_chunk_fails_only_its_job():
    # one worker, 12 jobs with one key: chunks of 3; the worker dies at the chunk's 2nd job
    jobs = ["a", "die", "b"] + [f"x{i}" for i in range(9)]
    ex = ProcessExecutor(1)
    try:
        out = dict(ex.map(_die_on, jobs, keys=["k"] * len(jobs)))
    finally:
        ex.close()
    assert out.pop(1) == JobFailure("error",
                                    "worker process died while running this job (exit code 3)")
    assert out == {i: j for i, j in enumerate(jobs) if i != 1}  # the rest of its chunk too


def test_a_job_over_its_budget_mid_chunk_fails_only_itself():
    ex = ProcessExecutor(1, timeout=1.0)
    try:
        out = dict(ex.map(_sleepy, [60.0] + [0.0] * 7, keys=["k"] * 8))  # chunks of 2
    finally:
        ex.close()
    assert out.pop(0) == JobFailure("timeout", "stopped after the budget of 1 s")
    assert out == {i: 0.0 for i in range(1, 8)}


_HELD: list = []


def _hold_then_raise(x):
    """Keep something in this worker; ``"raise"`` then raises ``MemoryError``."""
    if x == "raise":
        _HELD.append(x)
        raise MemoryError("no room")
    return len(_HELD)


def test_a_memory_error_ends_its_worker_and_the_rest_of_the_chunk_runs_in_a_fresh_one():
    """Bug: a job that raised ``MemoryError`` left its worker running the rest of its chunk
    with what the job had kept (a leaking plugin's arrays), so the next job in that worker
    was charged for it."""
    ex = ProcessExecutor(1, memory_limit=1 << 40)
    try:
        out = dict(ex.map(_hold_then_raise, ["a", "raise", "b", "c"], keys=["k"] * 4))
    finally:
        ex.close()
    assert out.pop(1) == JobFailure("memory", "MemoryError: no room")
    assert out == {0: 0, 2: 0, 3: 0}  # nothing held: a fresh worker ran "b" and "c"


_FORKED_WORKERS = """
import sys
import numpy as np
from benchmarks.run.executors import ProcessExecutor
from tests.test_executors import _hold, _sleepy

held = np.ones(50_000_000)  # 400 MB, written: resident in every worker forked from here
# the hang: a job that sleeps far past its timeout, at any speed of the machine
ex = ProcessExecutor(1, timeout=3.0, memory_limit=300_000_000, start_method="fork")
try:
    out = dict(ex.map(_sleepy, [60.0]))
finally:
    ex.close()
# the leak: a timeout far beyond the time to write 500 MB on a loaded machine, so that the
# memory limit, not the clock, ends it (with 3 s, a loaded CI machine ended it by timeout)
ex = ProcessExecutor(1, timeout=600.0, memory_limit=300_000_000, start_method="fork")
try:
    out.update({1: o for _, o in ex.map(_hold, [500_000_000])})
finally:
    ex.close()
print(out[0].status, out[1].status, out[1].message)
"""


def _hold(nbytes):
    kept = np.ones(nbytes // 8)  # written: resident
    time.sleep(900)  # never reached: the memory limit ends the job (its timeout is 600 s)
    return kept.size


def test_memory_a_worker_holds_before_its_first_job_is_not_charged_to_the_job(tmp_path):
    """Bug (CI, a cold numba cache): the server that workers are forked from compiled every
    kernel and kept about 1 GB of the compiler's memory, which each fork counts as resident,
    so a plugin that hung under a 1 GB limit was reported as ``memory`` instead of
    ``timeout``.  Here the parent of a forked worker holds 400 MB under a 300 MB limit (in a
    fresh single-threaded interpreter, where ``fork`` is safe)."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, "-c", _FORKED_WORKERS], cwd=root, text=True,
                          capture_output=True, timeout=300)
    assert done.returncode == 0, done.stderr
    hung, leaked, message = done.stdout.split(maxsplit=2)
    assert hung == "timeout"  # not "memory": the 400 MB are not the job's
    assert leaked == "memory" and message.startswith(
        "stopped over the memory limit of 286 MiB (the job's resident memory "), message


def test_run_tasks_keeps_the_task_order_and_raises_on_a_failed_task():
    seen = []
    assert run_tasks(_sleepy, [0.3, 0.0, 0.1], 2, lambda t, r: seen.append(t)) == [0.3, 0.0, 0.1]
    assert sorted(seen) == [0.0, 0.1, 0.3]
    with pytest.raises(RuntimeError, match=r"task 5 failed: ValueError: bad 5"):
        run_tasks(_raises, [5], 1)
    with pytest.raises(RuntimeError, match=r"task 'die' failed: worker process died"):
        run_tasks(_die_on, ["a", "die"], 2)


def test_worker_server_preloads_the_plugins_and_the_compiled_kernel():
    """What the local workers are forked from: every observer plugin imported, and (numba
    installed) the compiled simplex and one-step kernels loaded, so no worker pays for them
    per job: one signature per step kernel, the one every observer uses."""
    import subprocess
    import sys

    code = ("import sys; import benchmarks.run.workerinit; "
            "from observers.lp import batch_solve_jit; from observers.kernels import step as ks; "
            "print('observers.builtin.czn' in sys.modules, 'highspy' in sys.modules, "
            "not batch_solve_jit.AVAILABLE or min(len(batch_solve_jit._solve_jit.signatures), "
            "len(batch_solve_jit._hull_jit.signatures)) > 0, "
            "all(k is None or len(k.signatures) == 1 "
            "for k in (ks.strip_step, ks.propagate_step, ks.predict_linearised, "
            "ks.strip_predicted, ks.propagate_linearised)))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert res.stdout.split() == ["True", "True", "True", "True"]
    from benchmarks.run.executors import _context

    if _context().get_start_method() == "forkserver":
        from multiprocessing import forkserver

        assert "benchmarks.run.workerinit" in forkserver._forkserver._preload_modules


def _leak_and_return(nbytes):
    """Keep ``nbytes`` in this worker (written: resident) and return at once."""
    _HELD.append(np.ones(nbytes // 8))
    return len(_HELD)


def test_a_job_that_ends_over_the_memory_limit_between_two_polls_is_memory_not_ok(
        monkeypatch):
    """Bug (CI, the Dask run of the misbehaving plugins): a job that gained more than the
    limit and ended before the parent's next look at its worker was ``ok``, and the next job
    in that worker was charged the memory it kept (``Test-Leak`` ok, ``Test-Exit`` memory
    with 2.24 GiB, the leak's 12 x 200 MB).  No poll here during the job: its peak, read
    when it ends, must catch it, and the next job runs in a fresh worker."""
    from benchmarks.run import executors

    monkeypatch.setattr(executors, "POLL_S", 600.0)
    ex = ProcessExecutor(1, memory_limit=300_000_000)
    try:
        out = dict(ex.map(_leak_and_return, [500_000_000, 8, 8], keys=["k"] * 3))
    finally:
        ex.close()
    first = out.pop(0)
    assert first.status == "memory", first
    assert first.message.startswith("went over the memory limit of 286 MiB (the job's peak "
                                    "resident memory "), first.message
    assert out == {1: 1, 2: 2}  # a fresh worker: the 500 MB are not the next jobs'


def test_two_local_dask_clusters_at_once_take_free_loopback_ports_without_a_warning():
    """Noticed in the parallel tests: the second of two LocalClusters at once found the
    scheduler's HTTP port 8787 taken and moved off it with a UserWarning.  Each now asks for
    a free port of the loopback interface (even when something else holds 8787)."""
    pytest.importorskip("distributed")
    from benchmarks.run.executors import DaskExecutor

    with socket.socket() as held:  # 8787 taken, as by another cluster
        try:
            held.bind(("127.0.0.1", 8787))
            held.listen()
        except OSError:  # already taken by something else: the same situation
            pass
        executors = []
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                executors = [DaskExecutor(jobs=1), DaskExecutor(jobs=1)]
            servers = [ex.cluster.scheduler.http_server for ex in executors]
            assert all(srv.address == "127.0.0.1" and srv.port != 8787 for srv in servers)
            assert servers[0].port != servers[1].port
        finally:
            for ex in executors:
                ex.close()


def test_a_worker_with_no_memory_base_charges_no_memory():
    """A worker whose "started" message carried no base (no ``/proc``): its job's memory is
    not known (no base of 0 that would charge the job the worker's whole resident memory)."""
    from benchmarks.run.executors import _Worker, job_memory

    w = _Worker.__new__(_Worker)
    w.proc, w.base = type("P", (), {"pid": os.getpid()})(), None
    assert job_memory(w) is None
    if os.path.exists(f"/proc/{os.getpid()}/statm"):
        w.base = 0
        assert job_memory(w) > 0  # with a base, this process's resident memory is read


def _write_pid_and_sleep(path):
    """Write this worker's pid to ``path``, then sleep far past any test (a long job)."""
    with open(path, "w") as f:
        f.write(str(os.getpid()))
    time.sleep(900)


_STOPPED_RUN = """
import sys
from multiprocessing import forkserver
from benchmarks.run.executors import ProcessExecutor
from tests.test_executors import _write_pid_and_sleep

ex = ProcessExecutor(1)
print(getattr(forkserver._forkserver, "_forkserver_pid", None), flush=True)
for _ in ex.map(_write_pid_and_sleep, [sys.argv[1]]):
    pass
"""


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False


@pytest.mark.skipif(not os.path.isdir("/proc") or "forkserver" not in mp.get_all_start_methods(),
                    reason="needs Linux's /proc and the forkserver start method")
def test_a_run_stopped_by_sigterm_ends_its_worker_server_and_its_worker(tmp_path):
    """Bug: stopping an audit (``SIGTERM`` to the command) left the server its workers are
    forked from waiting for them, and a worker running its job on (an exact floor held a core
    for 57 min): the workers hold the server's "alive" pipe, so the server never saw its
    parent end, and a worker dies only with the server.  The server now ends with its parent."""
    import signal
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    pid_file = tmp_path / "worker.pid"
    proc = subprocess.Popen([sys.executable, "-c", _STOPPED_RUN, str(pid_file)], cwd=root,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        server = int(proc.stdout.readline())
        while not pid_file.exists() or not pid_file.read_text():  # the job has started
            assert proc.poll() is None, proc.stderr.read()
            time.sleep(0.1)
        worker = int(pid_file.read_text())
        assert _alive(server) and _alive(worker)
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
        # both end within a look of the guard (0.5 s); the bound only ends a failing test
        deadline = time.monotonic() + 60
        while (_alive(server) or _alive(worker)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(server), "the worker server outlived the stopped run"
        assert not _alive(worker), "the worker outlived the stopped run"
    finally:
        proc.kill()
        proc.wait()
        for pid in (locals().get("server"), locals().get("worker")):
            if pid and _alive(pid):
                os.kill(pid, signal.SIGKILL)
