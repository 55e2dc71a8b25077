"""Pure numeric kernels of the built-in observers, one module per plugin.

``observers/builtin/X.py`` (the plugin: options, registration, the online state) finds its
mathematics in ``observers/numerics/X.py``:

===================  ===================================================================
module               contents
===================  ===================================================================
``frad``             F-radius gains (Alamo et al. 2005, Wang et al. 2018, Combastel 2015)
``prad``             P-radius gain designs of PRad-A..D (Le et al. 2013, Wang et al. 2018/2019)
``volmin``           volume-minimising strip gains of VolMin-A/B (Bravo et al. 2006)
``luenberger``       Luenberger gain designs of PRad-E, Nom-G and Hinf-G
``ellipsoidal``      ESO-A/B bounding-ellipsoid updates, ESO-C/D invariant-set designs
``datadriven``       reachability from data (Alanwar, Berndt et al. 2022)
``ropo``             least-volume parallelotope updates of ROPO (Vicino & Zappa 1996)
``lmi``              the LMI toolbox shared by every offline design
``exact``            exact hulls of the consistent set by incremental LPs (``Exact``)
``exact_reference``  independent from-scratch LP formulations of the same hulls (checks)
===================  ===================================================================

This package imports nothing of :mod:`observers` but :mod:`observers.sets` and
:mod:`observers.errors`.
"""
