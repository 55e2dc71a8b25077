"""Bad input of every kind ends with a clear one-line error (exit code 2 on the CLI) and leaves
the previous results untouched; an infeasible design is a table status, not an error.

The cases already covered in ``test_benchmarks.py`` (unknown observer or scenario, wrong B
shape, NaN in y, empty V box, unknown top-level key, order -1, malformed YAML, missing file)
are not repeated here.
"""

from __future__ import annotations

import copy
import re
import warnings

import numpy as np
import pandas as pd
import pytest
import yaml

import observers
import systems
from benchmarks import load_config
from benchmarks.cli import main
from benchmarks.run.rows import run_observer
from observers import registry
from observers.builtin.frad import FRadA
from observers.errors import DesignFailed
from observers.sets import Zonotope

SYSTEM = {"A": [[0.9, 0.1], [0.0, 0.8]], "B": [[0.0], [1.0]], "C": [[1.0, 0.0]],
          "W": {"box": [0.01, 0.01]}, "V": {"box": [0.1]},
          "X0": {"center": [0, 0], "generators": [[1, 0], [0, 1]]}}
TOY = {"name": "toy", "system": SYSTEM, "simulate": {"steps": 20, "seed": 1},
       "options": {"order": 10}}


def cfg_with(**changes) -> dict:
    """The good config with some scenario/system fields changed (``system__X`` for system
    keys, ``cfg__X`` for top-level keys, ``None`` removes a key)."""
    scen = copy.deepcopy(TOY)
    top = {"scenarios": [scen], "observers": ["FRad-A"]}
    for key, value in changes.items():
        where, _, name = key.partition("__")
        target = {"system": scen["system"], "scen": scen, "cfg": top}[where]
        if value is None:
            target.pop(name)
        else:
            target[name] = value
    return top


@pytest.fixture
def previous(tmp_path):
    """An output folder holding the results of a good run, and their bytes."""
    out = tmp_path / "res"
    good = tmp_path / "good.yaml"
    good.write_text(yaml.safe_dump(cfg_with()))
    assert main(["run", str(good), "--out", str(out), "--no-progress"]) == 0
    return out, {p.name: p.read_bytes() for p in out.iterdir()}


def run_bad(tmp_path, capsys, previous, text: str) -> str:
    """Run the config text into the previous results folder; return the error line."""
    out, before = previous
    path = tmp_path / "bad.yaml"
    path.write_text(text) if isinstance(text, str) else path.write_bytes(text)
    capsys.readouterr()
    assert main(["run", str(path), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # untouched, no temp files
    return err


BAD_CONFIGS = [
    # malformed YAML / wrong structure
    ("top-level list", "- vehicle2d-cora\n- alamo2d\n", "must be a mapping at the top level"),
    ("empty file", "", "must be a mapping at the top level"),
    ("not UTF-8", b"scenarios: [\xff\xfe]\n", "not UTF-8 text"),
    ("scenarios not a list", "scenarios: vehicle2d-cora\n", "'scenarios' must be a non-empty"),
    # wrong shapes
    ("C columns", cfg_with(system__C=[[1.0, 0.0, 0.0]]), r"C has shape \(1, 3\)"),
    ("A not square", cfg_with(system__A=[[0.9, 0.1]]), "A must be square"),
    ("X0 dimension", cfg_with(system__X0={"box": [1, 1, 1]}), "X0: box has 3 radii, expected 2"),
    ("y columns", cfg_with(scen__simulate=None, scen__y=[[0.1, 0.2], [0.0, 0.1]]),
     r"y has shape \(2, 2\), expected \(N, 1\)"),
    ("u rows", cfg_with(scen__simulate=None, scen__y=[[0.1], [0.2], [0.3]],
                        scen__u=[[0.0]] * 7), "u has 7 rows, expected 3"),
    # non-finite values
    ("NaN in A", cfg_with(system__A=[[float("nan"), 0.1], [0.0, 0.8]]),
     "A contains non-finite values"),
    ("inf in W", cfg_with(system__W={"box": [float("inf"), 0.01]}), "W: .*non-finite"),
    ("inf in u", cfg_with(scen__simulate=None, scen__y=[[0.1], [0.2]],
                          scen__u=[[0.0], [float("inf")]]), r"u\[1, 0\] is not finite"),
    ("NaN in x_true", cfg_with(scen__simulate=None, scen__y=[[0.1], [0.2]],
                               scen__x_true=[[0, 0], [0, float("nan")]]),
     r"x_true\[1, 1\] is not finite"),
    ("text as dt", cfg_with(system__dt="fast"), "dt must be a positive number"),
    ("negative tolerance", cfg_with(scen__tolerance=-1e-3), "tolerance must be a non-negative"),
    # unobservable and not detectable: no observer can bound x2 (an unstable, unseen mode)
    ("undetectable", cfg_with(system__A=[[0.9, 0.0], [0.0, 1.2]]), "not detectable"),
    # empty noise sets
    ("empty W generators", cfg_with(system__W={"generators": []}), "W: the generator matrix"),
    ("empty V interval", cfg_with(system__V={"lo": [0.1], "hi": [-0.1]}),
     "V: empty interval"),
    ("empty W box", cfg_with(system__W={"box": []}), "W: the box is empty"),
    # W or V not containing the origin
    ("W off the origin", cfg_with(system__W={"box": [0.01, 0.01], "center": [1.0, 0.0]}),
     "W must contain the origin"),
    ("V off the origin", cfg_with(system__V={"lo": [0.1], "hi": [0.2]}),
     "V must contain the origin"),
    # negative orders, steps, seeds
    ("order 0 for one observer", cfg_with(cfg__observer_options={"FRad-A": {"order": 0}}),
     "FRad-A: order must be a finite number >= 1, got 0"),
    ("negative box radius", cfg_with(system__V={"box": [-0.1]}), "non-negative"),
    ("negative steps", cfg_with(scen__simulate={"steps": -5}), "steps must be an integer >= 1"),
    ("named negative seed", cfg_with(cfg__scenarios=[{"name": "tank6-linear", "seed": -1}]),
     "seed must be an integer >= 0"),
    ("named steps text", cfg_with(cfg__scenarios=[{"name": "tank6-linear", "steps": "many"}]),
     "steps must be an integer >= 1"),
    # unknown names
    ("unknown noise", cfg_with(cfg__scenarios=[{"name": "alamo2d-sim", "noise": "pink"}]),
     "unknown noise model 'pink'"),
    ("unknown reduction", cfg_with(cfg__options={"reduction": "best"}),
     "reduction must be one of 'girard', 'pca'.*, got 'best'"),
    ("unknown excluded observer", cfg_with(cfg__exclude=["FRad-Q"]), "unknown observer 'FRad-Q'"),
    ("unknown observer options", cfg_with(cfg__observer_options={"Kalman-X": {}}),
     "unknown observer 'Kalman-X'"),
    ("unknown system key", cfg_with(system__D=[[0.0]]), r"unknown system key\(s\) \['D'\]"),
    # values of an observer that is not in the run are checked too
    ("option value of an absent observer",
     cfg_with(cfg__observer_options={"FRad-B": {"variant": "nonsense"}}),
     "observer_options: FRad-B: variant must be one of"),
    # records too large for memory: refused before anything is allocated
    ("named steps beyond memory",
     cfg_with(cfg__scenarios=[{"name": "vehicle2d-sim", "steps": 10**12}]),
     r"scenario 'vehicle2d-sim': 1000000000000 steps need at least .* GiB of memory"),
    ("empty y", cfg_with(scen__simulate=None, scen__y=[]), r"scenario 'toy': y is empty"),
    ("inline steps beyond memory", cfg_with(scen__simulate={"steps": 10**12}),
     "steps need at least .* GiB of memory"),
    ("unknown scenario key", cfg_with(scen__colour="red"), r"unknown key\(s\) \['colour'\]"),
]


@pytest.mark.parametrize(("label", "cfg", "message"), BAD_CONFIGS, ids=[c[0] for c in BAD_CONFIGS])
def test_bad_config_one_line_error_and_results_untouched(tmp_path, capsys, previous, label, cfg,
                                                         message):
    text = cfg if isinstance(cfg, (str, bytes)) else yaml.safe_dump(cfg)
    err = run_bad(tmp_path, capsys, previous, text)
    assert re.search(message, err), err


def test_unobservable_but_detectable_systems_are_legitimate(tmp_path):
    """The linear 6-tank system is unobservable (tank 6) but detectable: a fine benchmark."""
    tank = systems.tank(6, linear=True)
    assert not tank.is_observable() and tank.is_detectable()
    # the same situation inline: x2 is never seen but decays (|0.5| < 1)
    cfg = cfg_with(system__A=[[0.9, 0.0], [0.0, 0.5]])
    path = tmp_path / "detectable.yaml"
    path.write_text(yaml.safe_dump(cfg))
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    summary = pd.read_csv(tmp_path / "o" / "summary.csv")
    assert (summary["status"] == "ok").all() and (summary["violations"] == 0).all()


def test_observers_that_need_detectability_report_no_gain_on_the_python_api():
    """Through the Python API an undetectable system reaches the observers; one whose design
    needs detectability (any constant-gain design) checks it and is reported as noGain."""
    @observers.register("Test-NeedsDetectable", family="propagation", set_type="zonotope",
                        ready_for_control=True)
    class NeedsDetectable(FRadA):
        """FRad-A that insists on a detectable pair (test only)."""

        def design(self):
            self.system.require_detectable(self.name)
            super().design()

    try:
        s = systems.LinearSystem([[0.9, 0.0], [0.0, 1.2]], np.zeros((2, 1)), [[1.0, 0.0]],
                                 W=Zonotope.box([0.01, 0.01]), V=Zonotope.box([0.1]),
                                 X0=Zonotope.box([1.0, 1.0]))
        sim = systems.simulate(s, np.zeros((10, 1)), seed=0)
        sc = systems.Scenario("undetectable", s, sim.u, sim.y, sim.x_true)
        run = run_observer("Test-NeedsDetectable", sc, {}, "exact")
        assert run.status == "noGain" and "not detectable" in run.message
        # FRad-A needs no detectability: its sets stay sound, they only grow along x2
        run = run_observer("FRad-A", sc, {}, "exact")
        assert run.status == "ok" and run.violations == 0
    finally:
        registry.unregister("Test-NeedsDetectable")


@pytest.fixture
def infeasible_observer():
    """An observer whose offline design is infeasible (raises DesignFailed)."""
    @observers.register("Test-Infeasible", family="propagation", set_type="zonotope",
                        ready_for_control=True)
    class Infeasible(FRadA):
        """Design always infeasible (test only)."""

        def design(self):
            raise DesignFailed(f"{self.name}: the LMI is infeasible (test)")

    yield "Test-Infeasible"
    registry.unregister("Test-Infeasible")


def test_infeasible_design_is_a_nogain_row_and_the_run_goes_on(tmp_path, capsys,
                                                               infeasible_observer):
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(cfg_with(cfg__observers=["FRad-A", infeasible_observer])))
    out = tmp_path / "res"
    assert main(["run", str(path), "--out", str(out), "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "note: Test-Infeasible on toy: noGain: Test-Infeasible: the LMI is infeasible" in err
    summary = pd.read_csv(out / "summary.csv")
    status = summary.drop_duplicates("observer").set_index("observer")["status"]
    assert status["Test-Infeasible"] == "noGain" and status["FRad-A"] == "ok"
    assert main(["report", str(out), "--no-figures"]) == 0
    assert "Test-Infeasible: noGain: Test-Infeasible: the LMI is infeasible" in (
        out / "report.md").read_text()


def test_configs_are_validated_before_anything_runs(tmp_path):
    """A bad second scenario is reported before the first one runs (nothing is written)."""
    cfg = cfg_with()
    cfg["scenarios"].append({"name": "bad", "system": dict(SYSTEM, V={"box": [0.1, 0.1]}),
                             "simulate": {"steps": 5}})
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(cfg))
    with pytest.raises(Exception, match="V: box has 2 radii, expected 1"):
        load_config(path)
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("argv", "message"), [
    (["check", "--baseline", "{tmp}/nowhere"], "no baseline in"),
    (["baseline", "--baseline", "{tmp}/nowhere"], "no baseline in"),
    (["audit", "--observers", "FRad-Z", "--realisations", "1"], "unknown observer 'FRad-Z'"),
    (["audit", "--scenarios", "tank6-linaer", "--realisations", "1"],
     "unknown scenario 'tank6-linaer'"),
    (["audit", "--scenarios", "vehicle2d-cora", "--realisations", "1"], "has no true states"),
    (["audit", "--realisations", "0"], "realisations must be >= 1"),
    (["audit", "--jobs", "0", "--realisations", "1"], "jobs must be >= 1"),
])
def test_new_commands_reject_bad_arguments_in_one_line(tmp_path, capsys, argv, message):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    argv += ["--no-progress"]
    if argv[0] == "audit":
        argv += ["--out", str(tmp_path / "a"), "--report", str(tmp_path / "a" / "s.md")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    assert message in err
    assert not (tmp_path / "a").exists()


# -- the Python API ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def toy():
    s = systems.LinearSystem([[0.9, 0.1], [0.0, 0.8]], [[0.0], [1.0]], [[1.0, 0.0]],
                             W=Zonotope.box([0.01, 0.01]), V=Zonotope.box([0.1]),
                             X0=Zonotope.box([1.0, 1.0]))
    return s, systems.simulate(s, np.zeros((10, 1)), seed=0)


def test_empty_record_is_refused(toy):
    s, sim = toy
    obs = observers.create("FRad-A", s)
    with pytest.raises(observers.MeasurementError, match=r"y are empty \(0 steps\)"):
        observers.run(obs, np.zeros((0, 1)), np.zeros((0, 1)))


@pytest.mark.parametrize("bad", [["a"], [object()], "0.1"])
def test_non_numeric_measurement_is_a_measurement_error(toy, bad):
    s, sim = toy
    obs = observers.create("FRad-A", s)
    obs.step(None, sim.y[0])
    with pytest.raises(observers.MeasurementError, match="measurement at step 1 is not numeric"):
        obs.step(sim.u[0], bad if bad != "0.1" else [{"y": 0.1}])
    with pytest.raises(observers.MeasurementError, match="measurements y is not numeric"):
        observers.run(obs, sim.u, [["x"]] * len(sim.y))
    with pytest.raises(observers.MeasurementError, match="input at step 1 is not numeric"):
        obs.reset()
        obs.step(None, sim.y[0])
        obs.step(["u"], sim.y[1])


def test_u_prev_none_only_on_the_first_step(toy):
    s, sim = toy
    for name in ("FRad-A", "FRad-C", "CZN-A", "ESO-B", "Hinf-G"):
        obs = observers.create(name, s)
        obs.step(None, sim.y[0])
        with pytest.raises(observers.MeasurementError, match="u_prev is None at step 1"):
            obs.step(None, sim.y[1])
        obs.reset()
        obs.step(None, sim.y[0])  # after reset() the first step again


@pytest.mark.parametrize("name", ["vehicle2d-sim", "alamo2d-sim", "tank6-linear",
                                  "rotating-target"])
@pytest.mark.parametrize("steps", [-5, 0, 2.5, True])
def test_bad_steps_of_a_named_scenario(name, steps):
    with pytest.raises(systems.ModelError,
                       match=rf"scenario '{name}': steps must be an integer >= 1, got"):
        systems.scenario(name, steps=steps)


def test_steps_beyond_memory_are_refused_before_allocating():
    with pytest.raises(systems.ModelError, match="GiB of memory"):
        systems.scenario("vehicle2d-sim", steps=10**12)


# -- zero-width noise sets -----------------------------------------------------------------------
def _zero_width_systems():
    """A 2-state, 2-output system with W = {0}, V = {0}, both, one zero component of W, and
    one of V (an exact sensor)."""
    A, B, C = [[0.9, 0.2], [-0.1, 0.8]], [[0.0], [1.0]], [[1.0, 0.0], [0.5, 1.0]]
    W, V = np.diag([0.02, 0.01]), np.diag([0.1, 0.05])
    out = {}
    for label, (Wg, Vg) in {"W={0}": (np.zeros((2, 0)), V), "V={0}": (W, np.zeros((2, 0))),
                            "W=V={0}": (np.zeros((2, 2)), np.zeros((2, 2))),
                            "W1=0": (np.diag([0.0, 0.01]), V),
                            "V1=0": (W, np.diag([0.0, 0.05]))}.items():
        out[label] = systems.LinearSystem(A, B, C, W=Zonotope(np.zeros(2), Wg),
                                          V=Zonotope(np.zeros(2), Vg),
                                          X0=Zonotope.box([1.0, 1.0]))
    return out


ZERO_WIDTH = _zero_width_systems()


@pytest.mark.slow
@pytest.mark.parametrize("label", list(ZERO_WIDTH))
def test_zero_width_noise_sets_are_handled_or_refused_by_name(label):
    """Every observer either runs soundly (exact membership at every step) or refuses at
    construction with a message naming W or V; no warning, no other exception.  An observer
    of nonlinear models only (``MODELS``) gets the same model written as a nonlinear one."""
    from benchmarks.run.membership import MembershipTester

    s_linear = ZERO_WIDTH[label]
    A, B = np.asarray(s_linear.A), np.asarray(s_linear.B)
    s_nonlinear = systems.NonlinearSystem(lambda x, u, m: A @ x + B @ u, 2, 1, s_linear.C,
                                          W=s_linear.W, V=s_linear.V, X0=s_linear.X0)
    s = s_linear
    sim = systems.simulate(s, 0.1 * np.sin(np.arange(25)).reshape(-1, 1), seed=3)
    training = systems.offline_experiment(s, 120, 5, Zonotope.box([0.5]), C=np.eye(2),
                                          Gamma=Zonotope.box([0.001, 0.001]))
    tester = MembershipTester()
    for info in observers.available():
        accepted = info.cls.option_defaults()
        opts = {"training": training} if "training" in accepted else {}
        if "max_subsets" in accepted:
            opts["order"] = 4  # VolMin-A: keep its LP enumeration small
        s = s_linear if "linear" in info.cls.MODELS else s_nonlinear
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                obs = observers.create(info.name, s, **opts)
            except (DesignFailed, observers.Unsupported) as exc:
                assert re.search(r"\b[WV]\b", str(exc)), (label, info.name, str(exc))
                continue
            res = observers.run(obs, sim.u, sim.y)
        assert res.status == "ok", (label, info.name, res.message)
        if info.guaranteed:
            for k, S in enumerate(res.sets):
                m = tester.test(S, sim.x_true[k], 1e-9)
                assert m.inside is not False, (label, info.name, k, m.distance)


@pytest.mark.parametrize("name", ["FRad-A", "FRad-B", "FRad-C", "CZN-B"])
def test_frad_gains_handle_exact_models(name):
    """No noise at all: FRad-A's strip gain was 0/0, FRad-C's (and FRad-B's, CZN-B's)
    innovation matrix C P C' + F F' singular; the F-radius gains are exact there."""
    from benchmarks.run.membership import MembershipTester

    s = ZERO_WIDTH["W=V={0}"]
    sim = systems.simulate(s, 0.1 * np.sin(np.arange(25)).reshape(-1, 1), seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = observers.run(observers.create(name, s), sim.u, sim.y)
    assert res.status == "ok", res.message
    tester = MembershipTester()
    assert all(tester.test(S, x, 1e-9).inside for S, x in zip(res.sets, sim.x_true,
                                                               strict=True))


def test_memory_estimates_before_simulating_and_before_running(tmp_path, monkeypatch):
    """A record or a run that would not fit is refused with its estimate, before the arrays
    are allocated (here with 1 MiB and 64 KiB of "available" memory)."""
    import sys

    import benchmarks.run.runner

    monkeypatch.setattr(sys.modules["systems.simulate"], "available_memory", lambda: 2**20)
    s = systems.tank(50)
    with pytest.raises(systems.ModelError, match=r"simulating 2000 steps of this 50-state "
                                                 r"system needs about .* GiB"):
        systems.simulate(s, np.zeros((2000, s.nu)))
    monkeypatch.undo()
    monkeypatch.setattr(benchmarks.run.runner, "available_memory", lambda: 2**16)
    cfg = load_config(_write(tmp_path, cfg_with(cfg__scenarios=["tank6-linear"],
                                                cfg__observers=["FRad-A", "FRad-B"])))
    with pytest.raises(benchmarks.errors.ConfigError, match="results need about"):
        benchmarks.run.runner.run_config(cfg, progress=False)


def _write(tmp_path, cfg) -> str:
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return str(path)
