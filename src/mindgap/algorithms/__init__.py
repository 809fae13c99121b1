"""Implementation of the learners (GeReL, SAC, PEBBLE, DRLHP, PrefBias, EPS and their engine).

Internal: names here may change between versions. The public entry points are
:mod:`mindgap.sac`, :mod:`mindgap.pebble`, :mod:`mindgap.drlhp`, :mod:`mindgap.prefbias`,
:mod:`mindgap.eps` and the names exported by :mod:`mindgap`.
"""
