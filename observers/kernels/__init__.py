"""Compiled kernels (numba) and the names by which an observer declares one.

Bottom room of :mod:`observers`: it imports nothing else of ours, and the rooms above use it
one way (``kernels`` <- :mod:`observers.lp` <- :mod:`observers.sets` <- the rest).

- :mod:`observers.kernels.catalogue`: :class:`StepKernel`, the names of the compiled one-step
  formulas an observer of :mod:`observers.families` declares (``KERNEL = StepKernel.ALAMO``),
  and :func:`by_option` for a kernel chosen by an option.
- :mod:`observers.kernels.step`: the compiled one-step kernels with the order reductions they
  call, in one file because numba's on-disk cache and its inlining work per file; its doorway
  :func:`~observers.kernels.step.prepare` is the only place that knows how the kernels number
  their formulas.
- :mod:`observers.kernels.propagation`: the interval constraint propagation behind the
  rescaling of constrained zonotopes (``implied_bounds``), and its rounding bound.
- :mod:`observers.kernels.exchange`: approximate scores, with error bounds, of the axis
  exchanges of ROPO's generator-axes search (a shortlist for the exact scores).
- :mod:`observers.kernels.switch`: whether numba is available and on (``SETOBS_NUMBA=0``
  turns it off), :func:`~observers.kernels.switch.set_compiled` for tests and timings.

The compiled twin of the hull LPs' dual simplex lives beside its numpy path in
:mod:`observers.lp`.
"""

from .catalogue import KernelByOption, StepKernel, by_option

__all__ = ["KernelByOption", "StepKernel", "by_option"]
