"""Worlds: the environment interface (:mod:`.interface`), the terrain, grid and coffee worlds, gymnasium adapters.

A user's own world needs only :class:`~mindgap.World`, :class:`~mindgap.Env`,
:class:`~mindgap.Box`, :class:`~mindgap.Discrete` and :class:`~mindgap.Step`, exported by
:mod:`mindgap`; the rest of this package is internal.
"""
