"""Typed option specs (observers/options.py) and their use by Observer and the built-ins."""

from __future__ import annotations

import numpy as np
import pytest

import observers
import systems
from observers import OptionError
from observers.families import PropagationObserver
from observers.options import (
    Bool,
    Choice,
    Custom,
    Integer,
    Matrix,
    Number,
    OptionSpec,
    Untyped,
    as_spec,
    reduction_method,
    show_value,
    training_data,
    zonotope_order,
)
from observers.sets import reduction as reduction_module

UNIT_OPEN = Number(0.5, low=0, high=1, low_open=True, high_open=True)


def _message(spec: OptionSpec, value) -> str:
    with pytest.raises(OptionError) as info:
        spec.check("Obs-X", "opt", value)
    return str(info.value)


# -- each kind: accepted values, rejected values, exact one-line messages -------------------
@pytest.mark.parametrize("value", [0.5, 1e-9, np.float64(0.25), np.float32(0.75), np.float16(0.5)])
def test_number_accepts_numbers_in_range_including_numpy_scalars(value):
    assert UNIT_OPEN.check("Obs-X", "opt", value) is value


@pytest.mark.parametrize(("spec", "value", "message"), [
    (UNIT_OPEN, 0, "Obs-X: opt must be a number in (0, 1), got 0"),
    (UNIT_OPEN, 1.0, "Obs-X: opt must be a number in (0, 1), got 1.0"),
    (UNIT_OPEN, True, "Obs-X: opt must be a number in (0, 1), got True"),
    (UNIT_OPEN, np.bool_(True),
     f"Obs-X: opt must be a number in (0, 1), got {np.bool_(True)!r}"),  # numpy 1.x: True
    (UNIT_OPEN, "0.5", "Obs-X: opt must be a number in (0, 1), got '0.5'"),
    (UNIT_OPEN, None, "Obs-X: opt must be a number in (0, 1), got None"),
    (UNIT_OPEN, float("nan"), "Obs-X: opt must be a number in (0, 1), got nan"),
    (Number(1.0, low=0, high=1, low_open=True), 0,
     "Obs-X: opt must be a number in (0, 1], got 0"),
    (Number(1e-7, low=0, high=1e-3, high_open=True), 1e-3,
     "Obs-X: opt must be a number in [0, 0.001), got 0.001"),
    (Number(0.1, low=0, low_open=True), -1, "Obs-X: opt must be a positive number, got -1"),
    (Number(0.0, low=0), -0.5, "Obs-X: opt must be a non-negative number, got -0.5"),
    (Number(100, low=1, finite=True), -3, "Obs-X: opt must be a finite number >= 1, got -3"),
    (Number(100, low=1, finite=True), float("inf"),
     "Obs-X: opt must be a finite number >= 1, got inf"),
    (Number(2.0, high=5, high_open=True), 5, "Obs-X: opt must be a number < 5, got 5"),
    (Number(0.0), float("nan"), "Obs-X: opt must be a number, got nan"),
    (Number(None, low=0, high=1, low_open=True, high_open=True, allow_none=True), 2,
     "Obs-X: opt must be a number in (0, 1) or None, got 2"),
])
def test_number_rejections_are_one_line_messages(spec, value, message):
    assert _message(spec, value) == message


def test_number_bounds_none_and_infinity():
    assert Number(1.0, low=1).check("Obs-X", "opt", 1) == 1  # closed bound included
    assert Number(0.5, low=0, low_open=True).check("Obs-X", "opt", float("inf")) == np.inf
    spec = Number(None, low=0, high=1, low_open=True, high_open=True, allow_none=True)
    assert spec.check("Obs-X", "opt", None) is None
    with pytest.raises(ValueError, match="empty range"):
        Number(0.0, low=2, high=1)


def test_integer_accepts_ints_only():
    spec = Integer(4, low=1)
    for v in (1, 4, np.int64(7), np.int32(2)):
        assert spec.check("Obs-X", "opt", v) is v
    assert _message(spec, 0) == "Obs-X: opt must be a positive integer, got 0"
    assert _message(spec, 4.0) == "Obs-X: opt must be a positive integer, got 4.0"
    assert _message(spec, True) == "Obs-X: opt must be a positive integer, got True"
    assert _message(Integer(3, low=2, high=9), 10) == (
        "Obs-X: opt must be an integer in [2, 9], got 10")
    assert _message(Integer(2, low=2), 1) == "Obs-X: opt must be an integer >= 2, got 1"
    assert _message(Integer(0), 0.0) == "Obs-X: opt must be an integer, got 0.0"


def test_integer_with_special_values_and_none():
    spec = Integer("auto", low=0, allow_none=True, special=("auto",))
    for v in ("auto", None, 0, 12):
        assert spec.check("Obs-X", "opt", v) is v
    expected = "Obs-X: opt must be a non-negative integer, 'auto' or None, got "
    assert _message(spec, -2) == expected + "-2"
    assert _message(spec, "many") == expected + "'many'"
    assert _message(spec, 2.5) == expected + "2.5"
    assert _message(Integer(None, low=0, allow_none=True), -1) == (
        "Obs-X: opt must be a non-negative integer or None, got -1")


def test_choice():
    spec = Choice("cora", ("cora", "textbook"))
    assert spec.check("Obs-X", "opt", "textbook") == "textbook"
    assert _message(spec, "paper") == "Obs-X: opt must be one of 'cora', 'textbook', got 'paper'"
    assert _message(spec, np.array(["cora"])) == (
        "Obs-X: opt must be one of 'cora', 'textbook', got array(['cora'], dtype='<U4')")
    with_none = Choice(None, (None, 1, 2))
    assert with_none.check("Obs-X", "opt", None) is None
    assert _message(with_none, True) == "Obs-X: opt must be one of None, 1, 2, got True"
    assert Choice("a", ["a", "b"]).choices == ("a", "b")  # lists are frozen into tuples
    with pytest.raises(TypeError):
        Choice("ab", "ab")
    with pytest.raises(ValueError):
        Choice("a", ())


def test_bool():
    spec = Bool(False)
    assert spec.check("Obs-X", "opt", True) is True
    assert spec.check("Obs-X", "opt", np.False_) is np.False_
    assert _message(spec, 1) == "Obs-X: opt must be True or False, got 1"
    assert _message(spec, "yes") == "Obs-X: opt must be True or False, got 'yes'"


def test_matrix():
    spec = Matrix()
    assert spec.default is None and spec.check("Obs-X", "opt", None) is None
    for v in ([0.5, 0.6], [[1, 2], [3, 4]], np.eye(3), np.arange(4)):
        assert spec.check("Obs-X", "opt", v) is v  # not converted
    expected = "Obs-X: opt must be a numeric vector or matrix with finite entries or None, got "
    assert _message(spec, [np.nan, 1.0]) == expected + "[nan, 1.0]"
    assert _message(spec, "abc") == expected + "'abc'"
    assert _message(spec, [[1.0], [2.0, 3.0]]) == expected + "[[1.0], [2.0, 3.0]]"
    assert _message(spec, np.ones((2, 2, 2))).startswith(expected + "array([[[1., 1.], [1., 1.]],")
    assert _message(spec, np.array([True, False])) == expected + "array([ True, False])"
    assert _message(spec, 3.0) == expected + "3.0"
    big = _message(spec, np.full((40, 40), np.inf))
    assert "\n" not in big and big.endswith("...") and len(big) < 200
    assert _message(Matrix(allow_none=False), None) == (
        "Obs-X: opt must be a numeric vector or matrix with finite entries, got None")


def test_custom_and_untyped():
    even = Custom(2, lambda v: isinstance(v, int) and v % 2 == 0, "an even integer")
    assert even.check("Obs-X", "opt", 4) == 4
    assert _message(even, 3) == "Obs-X: opt must be an even integer, got 3"
    dynamic = Custom("a", lambda v: False, lambda: "computed when the message is written")
    assert _message(dynamic, "b") == (
        "Obs-X: opt must be computed when the message is written, got 'b'")
    anything = Untyped(object())
    for v in (None, "x", -1, [1, 2], anything):
        assert anything.check("Obs-X", "opt", v) is v
    assert as_spec(0.5) == Untyped(0.5) and as_spec(UNIT_OPEN) is UNIT_OPEN


def test_specs_are_immutable():
    with pytest.raises(AttributeError):
        UNIT_OPEN.low = 2  # type: ignore[misc]


def test_shared_specs():
    order = zonotope_order(100)
    assert order.default == 100 and isinstance(order.default, int)
    assert _message(order, 0.5) == "Obs-X: opt must be a finite number >= 1, got 0.5"
    red = reduction_method("girard")
    assert red.check("Obs-X", "opt", "pca") == "pca"
    girard = reduction_module.Girard()
    assert red.check("Obs-X", "opt", girard) is girard  # a strategy object
    assert _message(red, "best") == (
        "Obs-X: opt must be one of 'girard', 'pca', 'pca-cora' or a strategy with "
        ".reduce(G, order), got 'best'")
    training = training_data()
    assert training.check("Obs-X", "opt", None) is None
    sc = systems.scenario("rotating-target", steps=5)
    assert training.check("Obs-X", "opt", sc.training) is sc.training
    assert _message(training, 3) == (
        "Obs-X: opt must be an object with attributes u, z, C, Gamma or None, got 3")


def test_reductions_registered_at_run_time_are_accepted():
    class Halving:
        name = "test-girard-too"

        def reduce(self, G, order):
            return reduction_module.Girard().reduce(G, order)

    s = systems.vehicle(2)
    with pytest.raises(OptionError, match="reduction must be one of 'girard', 'pca'"):
        observers.create("FRad-A", s, reduction="test-girard-too")
    reduction_module.register_reduction(Halving())
    try:
        obs = observers.create("FRad-A", s, reduction="test-girard-too")
        assert obs.options["reduction"] == "test-girard-too"
    finally:
        reduction_module._REDUCTIONS.pop("test-girard-too")


def test_show_value_is_one_short_line():
    assert show_value("abc") == "'abc'"
    assert show_value(np.eye(2)) == "array([[1., 0.], [0., 1.]])"
    assert len(show_value(list(range(100)))) == 60


# -- Observer integration --------------------------------------------------------------------
class _TypedObserver(PropagationObserver):
    """Typed options; the design must not run when an option is bad."""

    name = "Test-Typed"
    OPTIONS = {"scale": Number(0.5, low=0, high=1, low_open=True),
               "mode": Choice("fast", ("fast", "exact")),
               "lo": Integer(0, low=0), "hi": Integer(10, low=0)}
    designed = 0

    def validate_options(self) -> None:  # involves two options: stays a hook
        if self.options["lo"] > self.options["hi"]:
            raise OptionError(f"{self.name}: lo must not exceed hi")

    def design(self) -> None:
        type(self).designed += 1
        super().design()
        self.L = self.options["scale"] * np.linalg.pinv(self.C)

    def gain(self, c, G):
        return self.L


def test_typed_observer_rejects_bad_values_before_the_design():
    s = systems.vehicle(2)
    before = _TypedObserver.designed
    with pytest.raises(OptionError) as info:
        _TypedObserver(s, scale=2)
    assert str(info.value) == "Test-Typed: scale must be a number in (0, 1], got 2"
    with pytest.raises(OptionError, match="Test-Typed: mode must be one of 'fast', 'exact', "
                                          "got 'slow'"):
        _TypedObserver(s, mode="slow")
    with pytest.raises(OptionError, match="order must be a finite number >= 1, got '3'"):
        _TypedObserver(s, order="3")  # inherited from ZonotopeObserver
    with pytest.raises(OptionError, match="Test-Typed: hi must be a non-negative integer"):
        _TypedObserver(s, lo=20, hi=-1)  # the spec speaks first, then validate_options
    with pytest.raises(OptionError, match="lo must not exceed hi"):
        _TypedObserver(s, lo=20)
    assert _TypedObserver.designed == before
    obs = _TypedObserver(s, scale=1, order=3)
    assert _TypedObserver.designed == before + 1
    assert obs.options["scale"] == 1 and type(obs.options["scale"]) is int  # kept as given
    assert type(obs.options["order"]) is int


def test_option_specs_merge_along_the_mro():
    class Sub(_TypedObserver):
        OPTIONS = {"order": zonotope_order(7), "extra": 3}

    specs = Sub.option_specs()
    assert list(specs)[:2] == ["order", "reduction"]
    assert specs["order"].default == 7 and specs["scale"] is _TypedObserver.OPTIONS["scale"]
    assert specs["extra"] == Untyped(3)
    assert Sub.option_defaults() == {"order": 7, "reduction": "girard", "scale": 0.5,
                                     "mode": "fast", "lo": 0, "hi": 10, "extra": 3}


def test_plain_value_options_of_plugins_still_work():
    class Plain(PropagationObserver):
        """A third-party plugin written before the specs."""

        name = "Test-Plain"
        OPTIONS = {"gain_scale": 0.5, "label": None}

        def design(self):
            super().design()
            self.L = self.options["gain_scale"] * np.linalg.pinv(self.C)

        def gain(self, c, G):
            return self.L

    assert Plain.option_defaults() == {"order": 100, "reduction": "girard", "gain_scale": 0.5,
                                       "label": None}
    assert Plain.option_specs()["gain_scale"] == Untyped(0.5)
    sc = systems.scenario("vehicle2d-cora")
    obs = Plain(sc.system, gain_scale=0.25, label=["anything", 1])  # untyped: not checked
    assert obs.options["label"] == ["anything", 1]
    assert observers.run(obs, sc.u, sc.y).status == "ok"
    with pytest.raises(OptionError, match="Test-Plain: order must be a finite number >= 1"):
        Plain(sc.system, order=0)  # the inherited typed options are still checked


# -- the built-ins --------------------------------------------------------------------------
@pytest.mark.parametrize("name", observers.names())
def test_every_builtin_option_is_typed_and_its_default_passes(name):
    cls = observers.get(name).cls
    specs = cls.option_specs()
    untyped = [k for k, spec in specs.items() if isinstance(spec, Untyped)]
    assert not untyped, f"{name}: untyped options {untyped}"
    for key, spec in specs.items():
        assert spec.check(name, key, spec.default) is spec.default
        assert "\n" not in spec.describe()
    assert cls.option_defaults() == {k: spec.default for k, spec in specs.items()}


@pytest.mark.parametrize(("name", "options", "message"), [
    ("FRad-A", {"order": -3}, "FRad-A: order must be a finite number >= 1, got -3"),
    ("FRad-B", {"variant": "matlab"},
     "FRad-B: variant must be one of 'cora', 'textbook', got 'matlab'"),
    ("PRad-A", {"beta_tol": 1}, "PRad-A: beta_tol must be a number in (0, 1), got 1"),
    ("PRad-B", {"gain": "L"},
     "PRad-B: gain must be a numeric vector or matrix with finite entries or None, got 'L'"),
    ("PRad-D", {"alpha": 0}, "PRad-D: alpha must be a number in (0, 1) or None, got 0"),
    ("PRad-D", {"beta": None}, "PRad-D: beta must be a number in (0, 1), got None"),
    ("PRad-E", {"beta": True}, "PRad-E: beta must be a number in (0, 1) or None, got True"),
    ("Nom-G", {"mu": 1.5}, "Nom-G: mu must be a number in (0, 1], got 1.5"),
    ("Hinf-G", {"gamma_slack": 0}, "Hinf-G: gamma_slack must be a positive number, got 0"),
    ("Hinf-G", {"convention": "late"},
     "Hinf-G: convention must be one of 'aligned', 'cora-lagged', got 'late'"),
    ("CZN-A", {"margin": -1e-9}, "CZN-A: margin must be a number in [0, 0.001), got -1e-09"),
    ("CZN-A", {"max_constraints": True},
     "CZN-A: max_constraints must be a non-negative integer, 'auto' or None, got True"),
    ("CZN-B", {"hull_solver": "cplex"},
     "CZN-B: hull_solver must be one of 'auto', 'batched', 'highs', 'sifting', 'sifting-highs', "
     "got 'cplex'"),
    ("VolMin-A", {"max_subsets": 1e6},
     "VolMin-A: max_subsets must be a positive integer, got 1000000.0"),
    ("ESO-A", {"alpha": 1.0}, "ESO-A: alpha must be a number in (0, 1), got 1.0"),
    ("ESO-B", {"conversion": "i:norm"},
     "ESO-B: conversion must be one of 'inner:norm', 'outer:norm', got 'i:norm'"),
    ("ESO-C", {"quantile": 2}, "ESO-C: quantile must be a number in (0, 1), got 2"),
    ("DD-Z-A1", {"model": "exact"},
     "DD-Z-A1: model must be one of 'sound-lp', 'sound', 'paper', got 'exact'"),
    ("DD-Z-A2", {"model_order": 0}, "DD-Z-A2: model_order must be a finite number >= 1, got 0"),
    ("DD-Z-A2", {"state_bound": -1}, "DD-Z-A2: state_bound must be a positive number, got -1"),
    ("DD-Z-A2", {"sensors": [1, 0, 3]},
     "DD-Z-A2: sensors must be a list of positive integers or None, got [1, 0, 3]"),
    ("DD-CZ-A1", {"constraints": -1},
     "DD-CZ-A1: constraints must be a non-negative integer or None, got -1"),
    ("KF-N4SID", {"block_rows": 0}, "KF-N4SID: block_rows must be a positive integer, got 0"),
    ("KF-N4SID", {"sigma": 0}, "KF-N4SID: sigma must be a positive number, got 0"),
    ("KF-N4SID", {"tuning": "cora"},
     "KF-N4SID: tuning must be one of 'uniform', 'paper', got 'cora'"),
])
def test_builtin_bad_options_are_rejected_at_construction(name, options, message):
    with pytest.raises(OptionError) as info:
        observers.create(name, systems.vehicle(2), **options)
    assert str(info.value) == message
