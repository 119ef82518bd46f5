"""The calibration Kalman filter: filterpy for single runs, a batch path for Monte Carlo.

Both run the same filter on the error-state measurements ``dz`` (see
:mod:`.error_model`): an update at every GPS fix (the first at t = 0, on the
prior M0) and ``steps_per_fix - 1`` predict-only steps between fixes (39 for
200 Hz / 5 Hz).  A missing fix (a NaN row of ``dz``) means predict-only at that
epoch.

* :func:`run_filterpy` wraps ``filterpy.kalman.KalmanFilter`` for one realization.
* :func:`batch_filter` runs many realizations at once.  Here the gains do not
  depend on the data (linear model, known noise), so the covariance/gain
  sequence is computed once (:func:`covariance_sequence`) and the estimates of
  all realizations are propagated together with numpy.  ``tests/`` prove both
  give the same numbers on the same draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter

from ..validation import require_shape
from .error_model import ErrorStateModel, error_state_model
from .params import CalibrationParams

__all__ = ["FilterResult", "make_kalman_filter", "run_filterpy", "between_fixes", "covariance_sequence", "batch_filter"]


@dataclass
class FilterResult:
    """Filter output.  Leading axis ``n`` (realizations) only for the batch path.

    x : (n, n_imu, 3) or (n_imu, 3) estimate of dx at every IMU sample: a
        posteriori at fixes, predicted between fixes (None if not requested)
    P : (n_imu, 3, 3) covariance matching ``x`` (the same for every realization)
    x_prior, x_post : (n, n_gps, 3) or (n_gps, 3) estimate just before / after each fix
    P_prior, P_post : (n_gps, 3, 3)
    residual : (n, n_gps, 2) or (n_gps, 2) innovation ``dz - H x_prior`` (NaN if missing)
    S : (n_gps, 2, 2) innovation covariance ``H P_prior H^T + V``
    K : (n_gps, 3, 2) Kalman gain (zero where the fix is missing)
    """

    x: np.ndarray | None
    P: np.ndarray
    x_prior: np.ndarray
    x_post: np.ndarray
    P_prior: np.ndarray
    P_post: np.ndarray
    residual: np.ndarray
    S: np.ndarray
    K: np.ndarray


def make_kalman_filter(params: CalibrationParams, model: ErrorStateModel | None = None) -> KalmanFilter:
    """A ``filterpy.kalman.KalmanFilter(dim_x=3, dim_z=2)`` set up for ``params``.

    F = Phi, Q = W Gamma Gamma^T, H, R = V, x = prior mean (3, 1), P = M0, all
    from ``model`` (default: ``error_state_model(params)``, the true model; pass
    another one to study a filter whose model differs from the truth).
    """
    m = _model(params, model)
    kf = KalmanFilter(dim_x=3, dim_z=2)
    kf.F = m.Phi.copy()
    kf.Q = m.Q.copy()
    kf.H = m.H.copy()
    kf.R = m.V.copy()
    kf.x = m.x0.reshape(3, 1).copy()
    kf.P = m.M0.copy()
    return kf


def _model(params: CalibrationParams, model: ErrorStateModel | None) -> ErrorStateModel:
    """The filter's model: ``model`` if given (validated), else the true one for ``params``."""
    if not isinstance(params, CalibrationParams):
        raise ValueError(f"params must be a CalibrationParams, got {type(params).__name__}")
    if model is None:
        return error_state_model(params)
    if not isinstance(model, ErrorStateModel):
        raise ValueError(f"model must be an ErrorStateModel, got {type(model).__name__}")
    return model


def _check_dz(params: CalibrationParams, dz, batch: bool) -> np.ndarray:
    shape = (None, params.n_gps, 2) if batch else (params.n_gps, 2)
    dz = require_shape("dz", dz, shape)
    rows_nan = np.isnan(dz).any(axis=-1)
    if np.isinf(dz).any() or (rows_nan != np.isnan(dz).all(axis=-1)).any():
        raise ValueError("dz must be finite, or NaN in both components of a missing fix")
    return dz


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
    residual = np.full((n_gps, 2), np.nan)
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
                residual[i] = kf.y[:, 0]
                S[i] = kf.S
                K[i] = kf.K
        x[j] = kf.x[:, 0]
        P[j] = kf.P
        if j < n_imu - 1:
            kf.predict()
    idx = params.fix_indices
    return FilterResult(x, P, x_prior, x[idx].copy(), P_prior, P[idx].copy(), residual, S, K)


def _matrix_powers(F: np.ndarray, n: int) -> np.ndarray:
    """``F^j`` for ``j = 0..n-1`` (any model's Phi, not only the true one), shape (n, 3, 3)."""
    out = np.empty((n, 3, 3))
    out[0] = np.eye(3)
    for j in range(1, n):
        out[j] = F @ out[j - 1]
    return out


def between_fixes(params: CalibrationParams, model: ErrorStateModel | None = None):
    """The ``r = steps_per_fix`` predict-only steps between two fixes, taken at once.

    Returns
    -------
    powers : (r + 1, 3, 3) ``Phi^k`` for k = 0..r
    Qk : (r + 1, 3, 3) ``Q_k = sum_{l<k} Phi^l Q Phi^l^T`` for k = 0..r (``Q_0 = 0``), so that
        k predict steps from ``(x, P)`` give ``(Phi^k x, Phi^k P Phi^k^T + Q_k)``; units of P
    For the model the filter assumes (default: the true one).
    """
    m = _model(params, model)
    r = params.steps_per_fix
    powers = _matrix_powers(m.Phi, r + 1)
    Qk = np.zeros((r + 1, 3, 3))
    np.cumsum(np.einsum("kab,bc,kdc->kad", powers[:r], m.Q, powers[:r]), axis=0, out=Qk[1:])
    return powers, Qk


def covariance_sequence(params: CalibrationParams, missing_fixes=None, model: ErrorStateModel | None = None):
    """The data-independent part of the filter: covariances and gains.

    The numbers of filterpy's formulas (predict ``F P F^T + Q``; update with
    ``K = P H^T S^-1`` and the Joseph form), with the ``r`` predict steps between fixes
    taken at once (:func:`between_fixes`): ``P(t_i + k dt) = Phi^k P_i Phi^k^T + Q_k``, so
    the Python loop runs over the fixes, not over the IMU samples.

    Parameters
    ----------
    params : CalibrationParams
    missing_fixes : optional bool array (n_gps,), True where no update happens
    model : optional ErrorStateModel the filter assumes (default: the true one)

    Returns
    -------
    P (n_imu, 3, 3), P_prior (n_gps, 3, 3), S (n_gps, 2, 2), K (n_gps, 3, 2)
    """
    m = _model(params, model)
    n_gps, r = params.n_gps, params.steps_per_fix
    missing = np.zeros(n_gps, bool) if missing_fixes is None else np.asarray(missing_fixes)
    if missing.shape != (n_gps,) or missing.dtype != bool:
        raise ValueError(f"missing_fixes must be a bool array of shape ({n_gps},), got {missing.dtype} {missing.shape}")
    powers, Qk = between_fixes(params, m)
    H, R = m.H, m.V
    I3 = np.eye(3)
    P_prior = np.empty((n_gps, 3, 3))
    P_post = np.empty((n_gps, 3, 3))
    S = np.empty((n_gps, 2, 2))
    K = np.zeros((n_gps, 3, 2))
    Pj = m.M0.copy()
    for i in range(n_gps):
        P_prior[i] = Pj
        PHT = Pj @ H.T
        S[i] = H @ PHT + R
        if not missing[i]:
            K[i] = PHT @ np.linalg.inv(S[i])
            I_KH = I3 - K[i] @ H
            Pj = I_KH @ Pj @ I_KH.T + K[i] @ R @ K[i].T
        P_post[i] = Pj
        Pj = powers[r] @ Pj @ powers[r].T + Qk[r]
    # every IMU sample: P(t_i + k dt) = Phi^k P_post[i] Phi^k^T + Q_k, k = 0..r-1
    P = np.einsum("kab,ibc,kdc->ikad", powers[:r], P_post, powers[:r], optimize=True) + Qk[None, :r]
    return P.reshape(n_gps * r, 3, 3)[: params.n_imu], P_prior, S, K


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
    FilterResult with a leading realization axis on x, x_prior, x_post, residual.
    """
    dz = _check_dz(params, dz, batch=True)
    missing_runs = np.isnan(dz[..., 0])
    missing = missing_runs.all(axis=0)
    if (missing_runs != missing).any():
        raise ValueError("dz: the batch filter needs the same missing fixes in every realization; "
                         "use run_filterpy for realization-specific dropouts")
    m = _model(params, model)
    if covariances is None:
        covariances = covariance_sequence(params, missing, m)
    P, P_prior, S, K = covariances
    n, n_gps, r = dz.shape[0], params.n_gps, params.steps_per_fix
    H = m.H
    powers = _matrix_powers(m.Phi, r + 1)
    Phi_r = powers[r]
    x_prior = np.empty((n, n_gps, 3))
    x_post = np.empty((n, n_gps, 3))
    residual = np.full((n, n_gps, 2), np.nan)
    xi = np.broadcast_to(m.x0, (n, 3)).copy()
    for i in range(n_gps):
        x_prior[:, i] = xi
        if not missing[i]:
            residual[:, i] = dz[:, i] - xi @ H.T
            xi = xi + residual[:, i] @ K[i].T
        x_post[:, i] = xi
        xi = xi @ Phi_r.T
    x = None
    if full_rate:
        # Between fixes the estimate is only predicted: x(t_i + k dt) = Phi^k x_post(t_i).
        x = np.einsum("kab,nib->nika", powers[:r], x_post).reshape(n, n_gps * r, 3)[:, : params.n_imu]
    idx = params.fix_indices
    return FilterResult(x, P, x_prior, x_post, P_prior, P[idx].copy(), residual, S, K)
