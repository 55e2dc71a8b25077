"""The compiled one-step kernels an observer of the zonotopic families can declare.

An observer of :mod:`observers.families` names the compiled kernel that computes exactly its
step with the class attribute ``KERNEL`` (default ``None``: the numpy path only), e.g.
``KERNEL = StepKernel.ALAMO`` for FRad-A.  On a linear system with a built-in reduction the
family then runs the whole step (prediction, intersection or propagation with the observer's
gain, reduction) as one compiled call of :mod:`observers.kernels.step`, whose doorway
(:func:`~observers.kernels.step.prepare`) is the only place that knows how the kernels
number their formulas.

A kernel that depends on an option (FRad-B's ``variant``) is declared with
:func:`by_option`: the family picks the kernel once, at construction.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any


class StepKernel(Enum):
    """A compiled one-step formula (the value is the kernel module's name of it)."""

    #: strip-based, all strips at once with the observer's gain ``L`` (PRad-B/C-I/C-II/D)
    STRIP_GIVEN = "strip-given"
    #: strip-based, strip ``i`` with column ``i`` of the observer's ``L`` (PRad-A)
    PER_STRIP = "per-strip"
    #: strip-based, Alamo's F-radius gains strip by strip
    #: (:func:`observers.numerics.frad.alamo_frad_strips`; FRad-A)
    ALAMO = "alamo"
    #: strip-based, Wang's F-radius gain on the predicted set (``R = G G'``;
    #: :func:`observers.numerics.frad.wang_frad_gain` with ``A = None``; FRad-B textbook)
    WANG = "wang"
    #: as :attr:`WANG` with ``A`` applied once more, ``R = A G G' A' + E E'`` (FRad-B, CORA)
    WANG_CORA = "wang-cora"
    #: strip-based, Bravo's least ``det(T T')`` candidate strip by strip
    #: (:mod:`observers.numerics.volmin`; VolMin-B)
    BRAVO = "bravo"
    #: set propagation with the observer's gain ``L`` (Nom-G, PRad-E)
    PROPAGATION_GIVEN = "propagation-given"
    #: set propagation with Combastel's gain (:func:`observers.numerics.frad.combastel_gain`;
    #: FRad-C)
    COMBASTEL = "combastel"

    @property
    def given_gain(self) -> bool:
        """Whether the kernel takes the observer's constant gain ``L``."""
        return self in (StepKernel.STRIP_GIVEN, StepKernel.PER_STRIP,
                        StepKernel.PROPAGATION_GIVEN)

    def select(self, options: Mapping[str, Any]) -> StepKernel:
        """This kernel (whatever the options)."""
        return self


@dataclass(frozen=True)
class KernelByOption:
    """A kernel chosen by the value of one option (see :func:`by_option`)."""

    option: str
    choices: tuple[tuple[Any, StepKernel], ...]

    def select(self, options: Mapping[str, Any]) -> StepKernel | None:
        """The kernel of the option's value in ``options`` (``None``: no kernel for it)."""
        value = options[self.option]
        return next((kernel for v, kernel in self.choices if v == value), None)


def by_option(option: str, **choices: StepKernel) -> KernelByOption:
    """A kernel declaration that depends on the (string) value of ``option``, e.g.
    ``by_option("variant", cora=StepKernel.WANG_CORA, textbook=StepKernel.WANG)``."""
    return KernelByOption(option, tuple(choices.items()))
