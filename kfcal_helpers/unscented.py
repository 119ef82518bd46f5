"""Sigma-point and gain machinery shared by the problems' UKFs, single-run (filterpy) and batched.

* :class:`VectorizedUKF` -- filterpy's ``UnscentedKalmanFilter`` with ``fx`` and ``hx`` called once on all
  sigma points (arrays (2n+1, n) in, (2n+1, .) out) instead of once per point: the same equations;
* :func:`robust_sqrt` -- the upper Cholesky factor filterpy's sigma points take, of the symmetrized
  matrix, with a growing diagonal jitter if rounding made it lose definiteness;
* on stacks of N estimates (a leading run axis): :func:`batch_sigma_points` (Merwe scaled points of
  ``x`` (N, n), ``P`` (N, n, n)), :func:`unscented_moments` (mean and weighted residual covariance of
  points), :func:`gain_solve` (Kalman gain and ``S^-1 nu`` from one solve) and :func:`mT` (transpose of
  the last two axes).
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter
from scipy.linalg import cholesky

__all__ = ["VectorizedUKF", "robust_sqrt", "batch_sigma_points", "unscented_moments", "gain_solve", "mT"]


class VectorizedUKF(UnscentedKalmanFilter):
    """filterpy's UKF with f and h evaluated on all sigma points in one vectorised call.

    The filter equations are filterpy's: only the per-sigma-point Python loops over ``fx`` and ``hx``
    are replaced by one array call each (same numbers).  ``fx(sigmas, dt, **fx_args)`` and
    ``hx(sigmas, **hx_args)`` take the points as rows, (2n+1, n).
    """

    def compute_process_sigmas(self, dt, fx=None, **fx_args):
        fx = self.fx if fx is None else fx
        self.sigmas_f = fx(self.points_fn.sigma_points(self.x, self.P), dt, **fx_args)

    def update(self, z, R=None, UT=None, hx=None, **hx_args):
        rows = iter((self.hx if hx is None else hx)(self.sigmas_f, **hx_args))
        super().update(z, R=R, UT=UT, hx=lambda _sigma: next(rows))


def robust_sqrt(M) -> np.ndarray:
    """Upper Cholesky factor ``U`` (``U^T U = M``) of the symmetrized ``M``, for the sigma points.

    filterpy's UKF updates ``P - K S K^T``, which can lose symmetry and, rarely, positive
    definiteness by rounding.  This symmetrizes ``M`` and, if the Cholesky factorization still
    fails, adds a jitter ``eps * I`` with ``eps`` growing from ``1e-12 * trace(M)/n`` by factors of
    10 (at most 10 tries); ValueError if ``M`` is not finite or no jitter helps.
    """
    M = np.asarray(M, dtype=float)
    if not np.all(np.isfinite(M)):
        raise ValueError("P: the UKF covariance holds non-finite numbers (the filter diverged)")
    M = 0.5 * (M + M.T)
    try:
        return cholesky(M, lower=False)
    except np.linalg.LinAlgError:
        pass
    n = M.shape[0]
    eps = 1e-12 * max(float(np.trace(M)) / n, 1e-300)
    for _ in range(10):
        try:
            return cholesky(M + eps * np.eye(n), lower=False)
        except np.linalg.LinAlgError:
            eps *= 10.0
    raise ValueError("P: the UKF covariance is not positive definite, even with a jitter of "
                     f"{eps / 10:.1e} on its diagonal (the filter diverged)")


def mT(a):
    """``a`` with its last two axes swapped (a stack of transposes)."""
    return np.swapaxes(a, -1, -2)


def gain_solve(S, cross, nu):
    """Kalman gains ``K = cross S^-1`` (N, n, m) and ``S^-1 nu`` (N, m) from one solve with S (N, m, m):
    ``cross`` (N, n, m) is ``P H^T`` (EKF) or ``Pxz`` (UKF), ``nu`` (N, m) the innovations.  (filterpy
    multiplies by ``inv(S)``: the same numbers to rounding, at half the cost for stacks of small S.)"""
    X = np.linalg.solve(S, np.concatenate([mT(cross), nu[..., None]], axis=-1))
    return mT(X[..., :-1]), X[..., -1]


def batch_sigma_points(x, P, points: MerweScaledSigmaPoints) -> np.ndarray:
    """Merwe scaled sigma points of N estimates: ``x`` (N, n), ``P`` (N, n, n) -> (N, 2n+1, n).

    Point 0 is ``x``, points 1..n are ``x + U_i`` and n+1..2n ``x - U_i`` with ``U_i`` the rows of the
    upper Cholesky factor of the symmetrized ``(n + lambda) P`` (filterpy's ``sigma_points`` with
    :func:`robust_sqrt`, whose jitter is used for any run whose plain factorization fails).  ValueError if
    a covariance is not finite or no jitter helps.
    """
    n = points.n
    lam = points.alpha ** 2 * (n + points.kappa) - n
    M = (lam + n) * np.asarray(P, dtype=float)
    if not np.all(np.isfinite(M)):
        raise ValueError("P: the UKF covariance holds non-finite numbers (the filter diverged)")
    M = 0.5 * (M + mT(M))
    try:
        U = mT(np.linalg.cholesky(M))  # upper factor: U^T U = M
    except np.linalg.LinAlgError:
        U = np.stack([robust_sqrt(m) for m in M])
    x = np.asarray(x, dtype=float)[:, None, :]
    return np.concatenate([x, x + U, x - U], axis=1)


def unscented_moments(points, mean, Wm, Wc, residual):
    """Mean (N, d), residuals (N, 2n+1, d) and weighted residual covariance (N, d, d) of ``points``
    (N, 2n+1, d), with the filter's ``mean(points, Wm)`` and ``residual(a, b)`` functions."""
    m = mean(points, Wm)
    r = residual(points, m[:, None, :])
    return m, r, mT(r * Wc[:, None]) @ r
