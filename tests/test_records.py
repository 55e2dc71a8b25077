"""Measured records as CSV files with a header row and named columns (issue 28: a header row
was refused with "could not convert string 'y1'"): the columns read are the named ones, the
run says which, and bad files end with one line naming the file, line and column."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import systems
from benchmarks import ConfigError, load_config, run_config
from benchmarks.cli import main
from benchmarks.run.records import read_csv, select
from observers.sets import Zonotope

SYSTEM = {"A": [[0.9, 0.1], [0.0, 0.8]], "B": [[0.0], [0.1]], "C": [[1.0, 0.0]],
          "W": {"box": [0.01, 0.01]}, "V": {"box": [0.05]}, "X0": {"box": [1.0, 1.0]}}


@pytest.fixture(scope="module")
def sim():
    system = systems.LinearSystem(SYSTEM["A"], SYSTEM["B"], SYSTEM["C"],
                                  W=Zonotope.box([0.01, 0.01]), V=Zonotope.box([0.05]),
                                  X0=Zonotope.box([1.0, 1.0]))
    return systems.simulate(system, np.sin(0.2 * np.arange(30)).reshape(-1, 1), seed=3)


def _write(path, head, cols, sep=","):
    lines = [sep.join(head)] + [sep.join(repr(float(v)) for v in row)
                                for row in np.column_stack(cols)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _config(tmp_path, **entries):
    cfg = {"name": "rec", "observers": ["FRad-A"], "containment": "hull",
           "scenarios": [{"name": "plant", "system": SYSTEM, **entries}]}
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_one_file_with_a_header_row_and_named_columns_runs(tmp_path, sim, capsys):
    # columns in another order than the signals, a time column that is not read
    _write(tmp_path / "rec.csv", ["x2", "t", "u1", "y1", "x1"],
           [sim.x_true[:, 1], 0.1 * np.arange(30), sim.u[:, 0], sim.y[:, 0], sim.x_true[:, 0]])
    cfg = load_config(_config(tmp_path, record="rec.csv"))
    sc = cfg.scenarios[0]
    np.testing.assert_array_equal(sc.y, sim.y)
    np.testing.assert_array_equal(sc.u, sim.u)
    np.testing.assert_array_equal(sc.x_true, sim.x_true)
    assert "y from rec.csv columns y1" in sc.source
    assert "x_true from rec.csv columns x1, x2" in sc.source
    result = run_config(cfg, progress=False)
    assert result.ok and (result.summary["contained_hull"] == "yes").all()
    assert main(["run", str(tmp_path / "cfg.yaml"), "--out", str(tmp_path / "out"),
                 "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "plant: read y from rec.csv columns y1 (header row); u from rec.csv columns u1" in err


def test_signals_from_separate_files_header_or_not(tmp_path, sim):
    _write(tmp_path / "y.csv", ["y_1"], [sim.y[:, 0]], sep=";")  # semicolons, y_1
    np.savetxt(tmp_path / "u.csv", sim.u, delimiter=",")  # no header: all columns
    _write(tmp_path / "x.csv", ["position", "speed"], [sim.x_true[:, 0], sim.x_true[:, 1]])
    cfg = load_config(_config(tmp_path, y={"file": "y.csv"}, u={"file": "u.csv"},
                              x_true={"file": "x.csv", "columns": ["position", "speed"]}))
    sc = cfg.scenarios[0]
    np.testing.assert_array_equal(sc.y, sim.y)
    np.testing.assert_allclose(sc.u, sim.u, rtol=1e-15)
    np.testing.assert_array_equal(sc.x_true, sim.x_true)
    assert "y from y.csv columns y_1 (header row)" in sc.source
    assert "u from u.csv: all 1 columns (no header)" in sc.source
    assert "x_true from x.csv columns position, speed" in sc.source


def test_a_header_without_signal_names_is_read_when_its_width_fits(tmp_path, sim):
    _write(tmp_path / "y.csv", ["t", "measured level"], [np.arange(30), sim.y[:, 0]])
    table = read_csv(tmp_path / "y.csv", "y")
    values, note = select(table, "y", "y", width=1)
    np.testing.assert_array_equal(values[:, 0], sim.y[:, 0])
    assert note == "y from y.csv columns measured level (header row)"
    _write(tmp_path / "y2.csv", ["a", "b"], [sim.y[:, 0], sim.y[:, 0]])
    with pytest.raises(ConfigError, match=r"header row \(a, b\) but no columns named y1, "
                                          r"y2, \.\.\. \(1 expected\)"):
        select(read_csv(tmp_path / "y2.csv", "y"), "y", "y", width=1)


@pytest.mark.parametrize(("text", "message"), [
    ("y1,u1\n1.0,abc\n", r"line 2 column 2 \(u1\): 'abc' is not a number"),
    ("y1,u1\n1.0\n", "line 2 has 1 columns, the first line 2"),
    ("y1,y3\n1,2\n", r"the y columns \['y1', 'y3'\] are not numbered consecutively"),
    ("y1,y_1\n1,2\n", "two columns for y 1"),
    ("t,u1\n0,1\n", "has no columns named y1, y2"),
])
def test_bad_record_files_one_line(tmp_path, text, message, capsys):
    (tmp_path / "rec.csv").write_text(text)
    path = _config(tmp_path, record="rec.csv")
    with pytest.raises(ConfigError, match=message):
        load_config(path)
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: scenario 'plant'")
