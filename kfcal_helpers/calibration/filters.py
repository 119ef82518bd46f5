"""The calibration Kalman filter: filterpy for single runs, a batch path for Monte Carlo.

Both run the same filter on the error-state measurements ``dz`` (see
:mod:`.error_model`): an update at every GPS fix (the first at t = 0, on the
prior M0) and ``steps_per_fix - 1`` predict-only steps between fixes (39 for
200 Hz / 5 Hz).  A missing fix (a NaN row of ``dz``) means predict-only at that
epoch.

* :func:`run_filterpy` wraps ``filterpy.kalman.KalmanFilter`` for one realization.
* :func:`batch_filter` runs many realizations at once.  Here the gains do not
  depend on the data (linear model, known noise), so the covariance/gain
  sequence is computed once (``engine.covariance_sequence``) and the estimates of
  all realizations are propagated together with numpy (:mod:`.engine`).  ``tests/`` prove both
  give the same numbers on the same draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter

from functools import partial

from ..validation import checked, optional, require_bool, require_instance, require_shape
from .engine import Covariances, between_fixes, covariance_sequence, estimate_between_fixes, filter_estimates, filter_model
from .error_model import ErrorStateModel
from .params import CalibrationParams

__all__ = ["FilterResult", "make_kalman_filter", "run_filterpy", "batch_filter",
           "between_fixes", "covariance_sequence"]  # the last two live in .engine


@dataclass
class FilterResult:
    """Filter output.  Leading axis ``n`` (realizations) only for the batch path.

    x : (n, n_imu, 3) or (n_imu, 3) estimate of dx at every IMU sample: a
        posteriori at fixes, predicted between fixes (None if not requested)
    P : (n_imu, 3, 3) covariance matching ``x`` (the same for every realization)
    x_prior, x_post : (n, n_gps, 3) or (n_gps, 3) estimate just before / after each fix
    P_prior, P_post : (n_gps, 3, 3)
    y : (n, n_gps, 2) or (n_gps, 2) innovation ``dz - H x_prior`` (NaN if missing), filterpy's ``y``
    S : (n_gps, 2, 2) innovation covariance ``H P_prior H^T + V``
    K : (n_gps, 3, 2) Kalman gain (zero where the fix is missing)
    """

    x: np.ndarray | None
    P: np.ndarray
    x_prior: np.ndarray
    x_post: np.ndarray
    P_prior: np.ndarray
    P_post: np.ndarray
    y: np.ndarray
    S: np.ndarray
    K: np.ndarray


def make_kalman_filter(params: CalibrationParams, model: ErrorStateModel | None = None) -> KalmanFilter:
    """A ``filterpy.kalman.KalmanFilter(dim_x=3, dim_z=2)`` set up for ``params``.

    F = Phi, Q = W Gamma Gamma^T, H, R = V, x = prior mean (3, 1), P = M0, all
    from ``model`` (default: ``error_state_model(params)``, the true model; pass
    another one to study a filter whose model differs from the truth).
    """
    m = filter_model(params, model)
    kf = KalmanFilter(dim_x=3, dim_z=2)
    kf.F = m.Phi.copy()
    kf.Q = m.Q.copy()
    kf.H = m.H.copy()
    kf.R = m.V.copy()
    kf.x = m.x0.reshape(3, 1).copy()
    kf.P = m.M0.copy()
    return kf


def _check_dz(params: CalibrationParams, dz, batch: bool) -> np.ndarray:
    shape = (None, params.n_gps, 2) if batch else (params.n_gps, 2)
    dz = require_shape("dz", dz, shape)
    rows_nan = np.isnan(dz).any(axis=-1)
    if np.isinf(dz).any() or (rows_nan != np.isnan(dz).all(axis=-1)).any():
        raise ValueError("dz must be finite, or NaN in both components of a missing fix")
    return dz


@checked(params=partial(require_instance, cls=CalibrationParams))
def run_filterpy(params: CalibrationParams, dz, model: ErrorStateModel | None = None) -> FilterResult:
    """Run filterpy's KalmanFilter over one realization.

    Parameters
    ----------
    params : CalibrationParams
    dz : array (n_gps, 2), error-state measurements [m, m/s]; a NaN row is a missing fix
    model : optional ErrorStateModel the filter assumes (default: the true one)

    Returns
    -------
    FilterResult without the realization axis.
    """
    dz = _check_dz(params, dz, batch=False)
    kf = make_kalman_filter(params, model)
    n_imu, n_gps, r = params.n_imu, params.n_gps, params.steps_per_fix
    x = np.empty((n_imu, 3))
    P = np.empty((n_imu, 3, 3))
    x_prior = np.empty((n_gps, 3))
    P_prior = np.empty((n_gps, 3, 3))
    y = np.full((n_gps, 2), np.nan)
    S = np.empty((n_gps, 2, 2))
    K = np.zeros((n_gps, 3, 2))
    for j in range(n_imu):
        i, k = divmod(j, r)
        if k == 0:
            x_prior[i] = kf.x[:, 0]
            P_prior[i] = kf.P
            if np.isnan(dz[i, 0]):
                S[i] = kf.H @ kf.P @ kf.H.T + kf.R
            else:
                kf.update(dz[i].reshape(2, 1))
                assert kf.x.shape == (3, 1)
                y[i] = kf.y[:, 0]
                S[i] = kf.S
                K[i] = kf.K
        x[j] = kf.x[:, 0]
        P[j] = kf.P
        if j < n_imu - 1:
            kf.predict()
    idx = params.fix_indices
    return FilterResult(x, P, x_prior, x[idx].copy(), P_prior, P[idx].copy(), y, S, K)


@checked(params=partial(require_instance, cls=CalibrationParams), full_rate=require_bool,
         covariances=optional(partial(require_instance, cls=Covariances)))
def batch_filter(params: CalibrationParams, dz, full_rate: bool = True, covariances=None,
                 model: ErrorStateModel | None = None) -> FilterResult:
    """Run the filter on many realizations at once (same gains for all).

    Parameters
    ----------
    params : CalibrationParams
    dz : array (n, n_gps, 2), error-state measurements; a missing fix must be
        NaN in every realization (the gains are shared)
    full_rate : bool, also return the estimate at every IMU sample (n, n_imu, 3)
    covariances : optional output of :func:`covariance_sequence` to reuse (same model)
    model : optional ErrorStateModel the filter assumes (default: the true one)

    Returns
    -------
    FilterResult with a leading realization axis on x, x_prior, x_post, y.
    """
    dz = _check_dz(params, dz, batch=True)
    missing_runs = np.isnan(dz[..., 0])
    missing = missing_runs.all(axis=0)
    if (missing_runs != missing).any():
        raise ValueError("dz: the batch filter needs the same missing fixes in every realization; "
                         "use run_filterpy for realization-specific dropouts")
    m = filter_model(params, model)
    if covariances is None:
        covariances = covariance_sequence(params, missing, m)
    P, P_prior, S, K = covariances
    x_prior, x_post, y = filter_estimates(params, dz, K, missing, m)
    # between fixes the estimate is only predicted: x(t_i + k dt) = Phi^k x_post(t_i)
    x = estimate_between_fixes(params, x_post, m) if full_rate else None
    return FilterResult(x, P, x_prior, x_post, P_prior, P[params.fix_indices].copy(), y, S, K)
