"""Planar geometry in pure array functions (spatialmath style: one ``rot2``).

Conventions (SPEC §2): poses are ``(x, y, theta)`` of the platform reference point P with
``theta`` counter-clockwise in radians; platform points are ``B_i = P + Rot(theta) b_i``.
Every function broadcasts over leading axes.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["rot2", "rotate", "platform_points", "fit_pose", "wrap_angle", "wrap_to_pi", "cross2"]

TWO_PI = 2.0 * math.pi


def rot2(angle: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix (or stack of matrices, shape ``angle.shape + (2, 2)``) for ``angle`` (rad)."""
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def rotate(v: ArrayLike, angle: ArrayLike) -> NDArray[np.float64]:
    """Vectors ``v`` (..., 2) rotated by ``angle`` (broadcast over the leading axes)."""
    v = np.asarray(v, dtype=float)
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], -1)


def platform_points(attach: ArrayLike, pose: ArrayLike) -> NDArray[np.float64]:
    """World attach points ``B_i = P + Rot(theta) b_i``.

    Parameters
    ----------
    attach : array_like, shape (k, 2)
        Attach points ``b_i`` in the platform frame.
    pose : array_like, shape (..., 3)
        Platform pose(s) ``(x, y, theta)``.

    Returns
    -------
    ndarray, shape (..., k, 2)
    """
    pose = np.asarray(pose, dtype=float)
    if pose.shape[-1:] != (3,):
        raise ValueError(f"pose must have shape (..., 3), got {pose.shape}")
    b = np.asarray(attach, dtype=float)
    return pose[..., None, :2] + rotate(b, pose[..., None, 2])


def fit_pose(attach: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
    """Least-squares rigid pose placing the attach points ``b_i`` on ``points`` (..., k, 2)
    (the 2-D Procrustes/Kabsch solution), shape (..., 3)."""
    b = np.asarray(attach, dtype=float)
    p = np.asarray(points, dtype=float)
    bc = b - b.mean(0)
    pbar = p.mean(-2)
    pc = p - pbar[..., None, :]
    s = np.sum(bc[:, 0] * pc[..., 1] - bc[:, 1] * pc[..., 0], axis=-1)
    c = np.sum(bc[:, 0] * pc[..., 0] + bc[:, 1] * pc[..., 1], axis=-1)
    th = np.arctan2(s, c)
    P = pbar - rotate(b.mean(0), th)
    return np.concatenate([P, th[..., None]], axis=-1)


def wrap_angle(a):
    """``a`` (rad) wrapped into ``(-pi, pi]``: flexkin's one angle-wrap convention.

    ``pi`` stays ``pi`` and ``-pi`` becomes ``pi``; every other angle goes to the representative
    of its class modulo ``2 pi`` strictly above ``-pi``.  The body is plain arithmetic, so it
    serves floats, numpy arrays and compiled kernels alike (the kernels compile it with
    ``flexkin.core.jit.njit``: see :mod:`flexkin.core.geometry2d_kernels`).
    """
    return math.pi - ((math.pi - a) % TWO_PI)


def wrap_to_pi(angle: ArrayLike) -> NDArray[np.float64] | float:
    """Angles (array or scalar) wrapped into ``(-pi, pi]`` (:func:`wrap_angle`)."""
    out = wrap_angle(np.asarray(angle, dtype=float))
    return float(out) if out.ndim == 0 else out


def cross2(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """z component of the cross product of 2-D vectors (broadcast)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


TWO_PI = 2.0 * math.pi
