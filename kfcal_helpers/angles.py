"""Angles in state and measurement vectors, shared by the problems: wrapping, residuals, circular means.

An angle is wrapped to (-pi, pi] (rad).  A vector whose components at some evenly spaced positions are
angles is described by an :class:`AngleLayout` (its wrap, its residual ``a - b``, ``x + dx`` and the
weighted, circular-for-the-angles, mean of points, as filterpy's UKF takes them as ``residual_x``,
``state_add``, ``x_mean_fn``, ...).  The functions take arrays with leading axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .validation import MAX_SEED, checked, require_array, require_int, require_sequence, require_text

__all__ = ["TWO_PI", "wrap_angle", "angle_slice", "wrap_components", "weighted_mean", "AngleLayout"]

TWO_PI = 2.0 * np.pi


@checked(a=require_array)
def wrap_angle(a):
    """Wrap angles (rad) to (-pi, pi]; any shape; ValueError naming ``a`` for what is not numbers."""
    return np.pi - np.mod(np.pi - np.asarray(a, dtype=float), TWO_PI)


def _indices(name, value) -> list:
    return [require_int(name, i) for i in require_sequence(name, value)]


@checked(angles=_indices)
def angle_slice(angles) -> slice:
    """The angle components ``angles`` (sorted indices) as a basic slice (start, stop, step); ValueError
    unless they are evenly spaced."""
    if not angles:
        return slice(0, 0, 1)
    step = angles[1] - angles[0] if len(angles) > 1 else 1
    if any(b - a != step for a, b in zip(angles, angles[1:])):
        raise ValueError(f"angles must be evenly spaced indices, got {angles}")
    return slice(angles[0], angles[-1] + 1, step)


def wrap_components(v, sl: slice, copy: bool = True):
    """``v`` (..., n) with the components of the slice ``sl`` (explicit start, stop and step, as from
    :func:`angle_slice`) wrapped to (-pi, pi]; a copy unless ``copy=False`` (then ``v`` must be a float
    array, changed in place)."""
    v = np.array(v, dtype=float) if copy else v
    if v.ndim == 1:  # one vector (the UKF calls this ~50 times a step): Python floats are faster
        for i in range(sl.start, sl.stop, sl.step):
            v[i] = math.pi - (math.pi - float(v[i])) % TWO_PI
    elif sl.stop > sl.start:
        v[..., sl] = np.pi - np.mod(np.pi - v[..., sl], TWO_PI)
    return v


def weighted_mean(points, weights, sl: slice):
    """Weighted mean over axis -2 of ``points`` (..., m, n) with ``weights`` (m,); circular mean
    ``atan2(sum w sin, sum w cos)`` for the components of the slice ``sl``."""
    points = np.asarray(points, dtype=float)
    w = np.asarray(weights, dtype=float)
    mean = np.matmul(w, points)
    a = points[..., sl]
    mean[..., sl] = np.arctan2(np.matmul(w, np.sin(a)), np.matmul(w, np.cos(a)))
    return mean


@dataclass(frozen=True, eq=False)
class AngleLayout:
    """The layout of a vector whose components ``angles`` are angles (rad, wrapped to (-pi, pi]):
    its wrap, its residual ``a - b``, ``x + dx`` and the weighted (circular for the angles) mean of
    points, as the UKF needs them.

    n : int -- dimension; angles : sorted tuple of the angle components (evenly spaced);
    labels : plot labels with units, one per component
    """

    n: int
    angles: tuple = ()
    labels: tuple = ()

    def __post_init__(self):
        require_int("n", self.n, minimum=1, maximum=MAX_SEED)
        for label in require_sequence("labels", self.labels):
            require_text("labels", label)
        angles = tuple(_indices("angles", self.angles))
        if angles != tuple(sorted(set(angles))) or any(not 0 <= i < self.n for i in angles):
            raise ValueError(f"angles must be sorted distinct indices in 0..{self.n - 1}, got {self.angles}")
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "_slice", angle_slice(angles))

    def wrap(self, v):
        """Copy of ``v`` (..., n) with the angle components wrapped to (-pi, pi]."""
        return wrap_components(v, self._slice)

    def residual(self, a, b):
        """``a - b`` (..., n) with the angle differences wrapped."""
        return wrap_components(np.subtract(a, b, dtype=float), self._slice, copy=False)

    def add(self, x, dx):
        """``x + dx`` (..., n) with the angles wrapped (the UKF's ``state_add``)."""
        return wrap_components(np.add(x, dx, dtype=float), self._slice, copy=False)

    def mean(self, points, weights):
        """Weighted mean of ``points`` (..., m, n) with ``weights`` (m,): circular for the angles."""
        return weighted_mean(points, weights, self._slice)
