"""What the problems' batched filters return: :class:`BatchArrays`, the per-run arrays of a filter run on
N realizations at once (each problem's ``BatchResult`` adds what is its own)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BatchArrays"]


@dataclass(frozen=True, eq=False)
class BatchArrays:
    """A filter run on N realizations over K samples, n states.

    filter : which filter ran ("lkf", "ekf", "ukf"); t : (K,) sample times, s
    nis : (N, K) normalized innovation squared, NaN at steps without a measurement
    sigma2 : (N, K, n) two-sigma bounds ``2 sqrt(diag P_post)`` (the states' units)
    nees : (N, K) and errors : (N, K, n) ``truth - x_post`` when the truth was given, else None
    x : (N, K, n) and P : (N, K, n, n) the posterior estimates when kept, else None
    """

    filter: str
    t: np.ndarray
    nis: np.ndarray
    sigma2: np.ndarray
    nees: np.ndarray | None = None
    errors: np.ndarray | None = None
    x: np.ndarray | None = None
    P: np.ndarray | None = None
