"""Typed option specs: each observer option declares its kind, range and default once.

An observer lists its options in ``OPTIONS`` as ``name -> spec``::

    class MyObserver(PropagationObserver):
        OPTIONS = {"gain_scale": Number(0.5, low=0, high=1, low_open=True),
                   "mode": Choice("fast", ("fast", "exact"))}

:class:`~observers.base.Observer` checks every option with its spec in the constructor, after
the defaults are filled in and before ``validate_options()`` and the design, so that a wrong
type or range raises one :class:`~observers.errors.OptionError` with a one-line message such
as ``FRad-A: order must be a finite number >= 1, got -3``.  A spec never converts a value:
``check`` returns it unchanged, so an option given as an ``int`` stays an ``int``.

Plain values in ``OPTIONS`` (``{"gain_scale": 0.5}``) remain accepted: they are untyped
defaults (:class:`Untyped`), as for third-party plugins written before the specs.

Kinds: :class:`Number`, :class:`Integer`, :class:`Bool`, :class:`Choice`, :class:`Matrix`,
:class:`Custom` (any predicate) and :class:`Untyped`; :func:`zonotope_order` and
:func:`reduction_method` are the specs of the zonotope options shared by several observers,
:func:`training_data` that of the offline experiment of the data-driven ones.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .errors import OptionError
from .sets import reduction_names

__all__ = [
    "Bool",
    "Choice",
    "Custom",
    "Integer",
    "Matrix",
    "Number",
    "OptionSpec",
    "Untyped",
    "as_spec",
    "reduction_method",
    "show_value",
    "training_data",
    "zonotope_order",
]

#: longest value representation quoted in an error message
_MAX_SHOWN = 60


def show_value(value: Any) -> str:
    """One-line, shortened ``repr`` of ``value`` for error messages.

    Parameters
    ----------
    value : object
        Any value (arrays are printed on one line).

    Returns
    -------
    str
        ``repr(value)`` with runs of whitespace collapsed, cut to 60 characters.
    """
    text = " ".join(repr(value).split())
    return text if len(text) <= _MAX_SHOWN else text[: _MAX_SHOWN - 3] + "..."


def _alternatives(main: str, special: Sequence[Any], allow_none: bool) -> str:
    """``"a number, 'auto' or None"``: the main description and the accepted literals."""
    extra = [repr(v) for v in special] + (["None"] if allow_none else [])
    if not extra:
        return main
    return ", ".join([main, *extra[:-1]]) + f" or {extra[-1]}"


def _same(value: Any, literal: Any) -> bool:
    """Whether ``value`` is the literal ``literal`` (no bool/number confusion, no arrays)."""
    if value is literal:
        return True
    if isinstance(value, (bool, np.bool_)) != isinstance(literal, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray):
        return False
    try:
        return bool(value == literal)
    except (TypeError, ValueError):
        return False


class OptionSpec(ABC):
    """Base class of the option specs: a default and the values accepted.

    Subclasses are immutable (frozen dataclasses) with a ``default`` field and implement
    :meth:`accepts` and :meth:`describe`.
    """

    default: Any

    @abstractmethod
    def accepts(self, value: Any) -> bool:
        """Whether ``value`` is an accepted value.

        Parameters
        ----------
        value : object
            The value to test.

        Returns
        -------
        bool
            True if the option may take this value.
        """

    @abstractmethod
    def describe(self) -> str:
        """What is accepted, as the end of the phrase "the option must be ...".

        Returns
        -------
        str
            E.g. ``"a number in (0, 1) or None"``.
        """

    def check(self, observer_name: str, option_name: str, value: Any) -> Any:
        """Return ``value`` unchanged if it is accepted, else raise :class:`OptionError`.

        Parameters
        ----------
        observer_name : str
            Name of the observer (first word of the message).
        option_name : str
            Name of the option.
        value : object
            The value given for the option.

        Returns
        -------
        object
            ``value`` itself (specs never convert values).

        Raises
        ------
        OptionError
            One line naming the observer, the option, what is accepted and the value, e.g.
            ``FRad-A: order must be a finite number >= 1, got -3``.
        """
        if self.accepts(value):
            return value
        raise OptionError(
            f"{observer_name}: {option_name} must be {self.describe()}, got {show_value(value)}"
        )


@dataclass(frozen=True)
class Number(OptionSpec):
    """A real number (int, float or numpy scalar; not bool) within optional bounds.

    Parameters
    ----------
    default : float, int or None
        Default value.
    low, high : float, optional
        Bounds of the accepted range (None: unbounded on that side).
    low_open, high_open : bool
        Exclude the bound itself (``(low, ...`` instead of ``[low, ...``).
    allow_none : bool
        Accept ``None`` as well (e.g. "choose automatically").
    finite : bool
        Reject ``inf`` even where the bounds would accept it (``nan`` is always rejected).
    special : tuple
        Further accepted literal values, e.g. ``("auto",)``.
    """

    default: Any
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    allow_none: bool = False
    finite: bool = False
    special: tuple[Any, ...] = ()

    #: the noun of :meth:`describe`
    KIND: ClassVar[str] = "number"

    def __post_init__(self) -> None:
        object.__setattr__(self, "special", tuple(self.special))
        if self.low is not None and self.high is not None and self.low > self.high:
            raise ValueError(f"empty range: low={self.low} > high={self.high}")

    def _is_kind(self, value: Any) -> bool:
        return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
            value, (bool, np.bool_))

    def _in_range(self, value: Any) -> bool:
        if isinstance(value, (float, np.floating)) and (
                math.isnan(value) or (self.finite and math.isinf(value))):
            return False
        if self.low is not None and not (value > self.low if self.low_open else value >= self.low):
            return False
        return self.high is None or (value < self.high if self.high_open else value <= self.high)

    def accepts(self, value: Any) -> bool:
        """Whether ``value`` is a number in range, ``None`` (if allowed) or a special literal."""
        if value is None:
            return self.allow_none
        if any(_same(value, s) for s in self.special):
            return True
        return self._is_kind(value) and self._in_range(value)

    def describe(self) -> str:
        """E.g. ``"a number in (0, 1]"``, ``"a positive integer"``, ``"a number >= 1 or None"``."""
        kind = f"finite {self.KIND}" if self.finite else self.KIND
        a_kind = f"{'an' if kind[0] in 'aeiou' else 'a'} {kind}"
        low, high = self.low, self.high
        if low is not None and high is not None:
            main = (f"{a_kind} in {'(' if self.low_open else '['}{low:g}, {high:g}"
                    f"{')' if self.high_open else ']'}")
        elif low is not None:
            if low == 0:
                main = f"a {'positive' if self.low_open else 'non-negative'} {kind}"
            elif self.KIND == "integer" and low == 1 and not self.low_open:
                main = f"a positive {kind}"
            else:
                main = f"{a_kind} {'>' if self.low_open else '>='} {low:g}"
        elif high is not None:
            main = f"{a_kind} {'<' if self.high_open else '<='} {high:g}"
        else:
            main = a_kind
        return _alternatives(main, self.special, self.allow_none)


@dataclass(frozen=True)
class Integer(Number):
    """An integer (int or numpy integer; not bool, not float) within optional bounds.

    Parameters
    ----------
    default : int or None
        Default value.
    low, high, low_open, high_open, allow_none, finite, special
        As for :class:`Number`.
    """

    KIND: ClassVar[str] = "integer"

    def _is_kind(self, value: Any) -> bool:
        return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


@dataclass(frozen=True)
class Bool(OptionSpec):
    """``True`` or ``False`` (Python or numpy booleans; not 0 or 1).

    Parameters
    ----------
    default : bool
        Default value.
    """

    default: bool

    def accepts(self, value: Any) -> bool:
        """Whether ``value`` is a boolean."""
        return isinstance(value, (bool, np.bool_))

    def describe(self) -> str:
        """``"True or False"``."""
        return "True or False"


@dataclass(frozen=True)
class Choice(OptionSpec):
    """One of a fixed set of literal values (usually strings; ``None`` may be one of them).

    Parameters
    ----------
    default : object
        Default value (one of ``choices``).
    choices : sequence
        The accepted values, in the order the error message lists them.
    """

    default: Any
    choices: tuple[Any, ...]

    def __post_init__(self) -> None:
        if isinstance(self.choices, str):
            raise TypeError("choices must be a sequence of values, not a string")
        object.__setattr__(self, "choices", tuple(self.choices))
        if not self.choices:
            raise ValueError("a Choice needs at least one choice")

    def accepts(self, value: Any) -> bool:
        """Whether ``value`` is one of the choices."""
        return any(_same(value, c) for c in self.choices)

    def describe(self) -> str:
        """E.g. ``"one of 'cora', 'textbook'"``."""
        return "one of " + ", ".join(map(repr, self.choices))


@dataclass(frozen=True)
class Matrix(OptionSpec):
    """A numeric vector or matrix with finite entries (nested lists or an array), or None.

    Only kind and finiteness are checked here; shapes usually depend on the system and are
    checked in ``design``.  The value is not converted.

    Parameters
    ----------
    default : array_like or None
        Default value (None: not given).
    allow_none : bool
        Accept ``None`` (default True: matrix options are optional).
    ndim : tuple of int
        Accepted numbers of dimensions (default: vectors and matrices).
    """

    default: Any = None
    allow_none: bool = True
    ndim: tuple[int, ...] = (1, 2)

    def __post_init__(self) -> None:
        object.__setattr__(self, "ndim", tuple(self.ndim))

    def accepts(self, value: Any) -> bool:
        """Whether ``value`` is a finite numeric array of an accepted dimension (or None)."""
        if value is None:
            return self.allow_none
        if isinstance(value, (str, bytes)):
            return False
        try:
            a = np.asarray(value)
        except (TypeError, ValueError):  # e.g. ragged nested lists
            return False
        return a.dtype.kind in "iuf" and a.ndim in self.ndim and bool(np.all(np.isfinite(a)))

    def describe(self) -> str:
        """E.g. ``"a numeric vector or matrix with finite entries or None"``."""
        names = {0: "scalar", 1: "vector", 2: "matrix"}
        shapes = " or ".join(names.get(d, f"{d}-D array") for d in self.ndim)
        return _alternatives(f"a numeric {shapes} with finite entries", (), self.allow_none)


@dataclass(frozen=True)
class Custom(OptionSpec):
    """Values accepted by a predicate, for options no other kind describes.

    Parameters
    ----------
    default : object
        Default value.
    test : callable
        ``test(value) -> bool``: whether the value is accepted.  It is called on every
        construction, so it may consult run-time state (e.g. registered reductions).
    accepted : str or callable
        What is accepted, as the end of "the option must be ..." (a callable is evaluated when
        the message is written).
    """

    default: Any
    test: Callable[[Any], bool]
    accepted: str | Callable[[], str]

    def accepts(self, value: Any) -> bool:
        """Whether ``test(value)`` holds."""
        return bool(self.test(value))

    def describe(self) -> str:
        """The ``accepted`` text."""
        return self.accepted() if callable(self.accepted) else self.accepted


@dataclass(frozen=True)
class Untyped(OptionSpec):
    """Any value: the spec of a plain default in ``OPTIONS`` (no declared kind).

    Parameters
    ----------
    default : object
        Default value.
    """

    default: Any

    def accepts(self, value: Any) -> bool:
        """Every value is accepted."""
        return True

    def describe(self) -> str:
        """``"anything"``."""
        return "anything"


def as_spec(entry: Any) -> OptionSpec:
    """The spec of an ``OPTIONS`` entry: the entry itself, or :class:`Untyped` for a plain value.

    Parameters
    ----------
    entry : OptionSpec or object
        A value of an ``OPTIONS`` dict.

    Returns
    -------
    OptionSpec
        The declared spec, or ``Untyped(entry)``.
    """
    return entry if isinstance(entry, OptionSpec) else Untyped(entry)


# -- specs shared by several observers ----------------------------------------------------
def zonotope_order(default: float) -> Number:
    """Spec of a zonotope order: a finite number >= 1 (the range of
    :func:`observers.sets.reduction.check_order`).

    Parameters
    ----------
    default : float
        Default order (kept as given: an int stays an int).

    Returns
    -------
    Number
        The spec.
    """
    return Number(default, low=1, finite=True)


def _is_reduction(value: Any) -> bool:
    if isinstance(value, str):
        return value in reduction_names()
    return value is not None and callable(getattr(value, "reduce", None))


def _reductions_accepted() -> str:
    names = ", ".join(map(repr, reduction_names()))
    return f"one of {names} or a strategy with .reduce(G, order)"


def reduction_method(default: str = "girard") -> Custom:
    """Spec of an order-reduction option: a registered reduction name (checked against the
    registry at construction time, so that strategies registered later are accepted) or a
    strategy object with ``reduce(G, order)``.

    Parameters
    ----------
    default : str
        Default strategy name.

    Returns
    -------
    Custom
        The spec.
    """
    return Custom(default, _is_reduction, _reductions_accepted)


#: attributes of an offline experiment (see :func:`observers.numerics.datadriven.check_training`)
TRAINING_ATTRIBUTES = ("u", "z", "C", "Gamma")


def _is_training(value: Any) -> bool:
    return value is None or all(hasattr(value, a) for a in TRAINING_ATTRIBUTES)


def training_data() -> Custom:
    """Spec of the ``training`` option: an offline experiment, i.e. an object with attributes
    ``u``, ``z``, ``C`` and ``Gamma`` (e.g. ``Scenario.training``), or None (not given; the
    observer then reports itself unsupported).  Shapes and values are checked by the design.

    Returns
    -------
    Custom
        The spec (default None).
    """
    return Custom(None, _is_training,
                  "an object with attributes " + ", ".join(TRAINING_ATTRIBUTES) + " or None")
