"""Argument checks shared by every public function.

Each check raises ``ValueError`` whose message names the argument and what is
allowed, so a student sees at once which input was wrong.  The command line
turns these errors into one line on stderr and exit status 2.
"""

from __future__ import annotations

import math
from numbers import Integral, Real

import numpy as np

__all__ = [
    "require_finite",
    "require_positive",
    "require_nonnegative",
    "require_int",
    "require_choice",
    "require_shape",
    "require_covariance",
]


def require_finite(name: str, value) -> float:
    """Return ``value`` as a float; raise if it is not a finite real number."""
    if isinstance(value, bool) or not isinstance(value, (Real, np.floating, np.integer)):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    return value


def require_positive(name: str, value) -> float:
    """Return ``value`` as a float; raise unless it is finite and > 0."""
    value = require_finite(name, value)
    if value <= 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return value


def require_nonnegative(name: str, value) -> float:
    """Return ``value`` as a float; raise unless it is finite and >= 0."""
    value = require_finite(name, value)
    if value < 0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return value


def require_int(name: str, value, minimum: int | None = None) -> int:
    """Return ``value`` as an int; raise unless it is an integer >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, (Integral, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value}")
    return value


def require_choice(name: str, value, choices) -> str:
    """Return ``value``; raise unless it is one of ``choices``."""
    if value not in choices:
        allowed = ", ".join(repr(c) for c in choices)
        raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
    return value


def require_shape(name: str, array, shape: tuple) -> np.ndarray:
    """Return ``array`` as a float ndarray; raise unless its shape matches.

    ``shape`` may hold ``None`` for an axis of any length.
    """
    arr = np.asarray(array, dtype=float)
    ok = arr.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, arr.shape))
    if not ok:
        want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    return arr


def require_covariance(name: str, matrix, n: int | None = None) -> np.ndarray:
    """Return ``matrix`` as a float array; raise unless it is a finite, symmetric,
    positive-definite square matrix (of size ``n`` when given)."""
    arr = np.asarray(matrix, dtype=float)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or (n is not None and arr.shape[0] != n):
        size = f"{n}x{n}" if n is not None else "square"
        raise ValueError(f"{name} must be a {size} matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must hold only finite numbers")
    if not np.allclose(arr, arr.T, rtol=1e-10, atol=1e-12 * max(1.0, float(np.abs(arr).max()))):
        raise ValueError(f"{name} must be symmetric")
    try:
        np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        raise ValueError(f"{name} must be positive definite") from None
    return arr
