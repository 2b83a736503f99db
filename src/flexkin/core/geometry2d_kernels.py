"""Compiled twins of :mod:`flexkin.core.geometry2d`'s scalar helpers, for use inside kernels.

numba's kernels cannot call plain Python functions; these are the same functions compiled
with :func:`flexkin.core.jit.njit` (one body each, in :mod:`flexkin.core.geometry2d`, which is
kept free of numba so that loading a mechanism stays light).
"""

from __future__ import annotations

from .geometry2d import wrap_angle as _wrap_angle
from .jit import njit

__all__ = ["wrap_angle"]

#: :func:`flexkin.core.geometry2d.wrap_angle` compiled: ``a`` wrapped into ``(-pi, pi]``
wrap_angle = njit(_wrap_angle)
