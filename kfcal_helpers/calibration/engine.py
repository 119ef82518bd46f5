"""The calibration batch engine: the one implementation of ``Phi^k`` and of the filter's covariances.

The gains of the calibration filter do not depend on the data (linear model, known noise), so
everything data-independent is computed once here and shared by every fast path:

* :func:`matrix_powers` (``Phi^k`` of any model's Phi) and :func:`accumulated_noise`
  (``Q_k = sum_{l<k} Phi^l Q Phi^lT``), used by :func:`between_fixes`,
  :func:`covariance_sequence` and ``batch_estimate.prior_covariances_at_fixes``;
* :func:`covariance_sequence`: filterpy's covariance recursion (predict ``F P F^T + Q``, Joseph
  update), fix to fix, giving ``P`` at every IMU sample and ``P_prior``, ``S``, ``K`` at the fixes
  (``P_post`` is ``P`` at the fixes);
* :func:`filter_estimates`: the estimates of many realizations with those gains (``batch_filter``
  and the Monte Carlo); :func:`estimate_between_fixes`: the estimate predicted between fixes,
  ``Phi^k x_post``;
* the error recursion of the live demo (:func:`filter_errors_at_fixes`) and its random draws at
  the fixes (:func:`sample_noise_at_fixes`, :func:`noise_of_simulation`).

``tests/test_calibration_filters.py`` and ``tests/test_calibration_engine.py`` prove these equal
filterpy's ``KalmanFilter`` on the same draws.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..validation import as_generator, require_instance, require_int, require_mask, require_shape
from .error_model import ErrorStateModel, error_state_model
from .params import CalibrationParams
from .simulation import Simulation

__all__ = ["filter_model", "matrix_powers", "accumulated_noise", "between_fixes", "Covariances",
           "covariance_sequence", "filter_estimates", "estimate_between_fixes", "sample_noise_at_fixes",
           "sample_noise_time_major", "unit_noise_time_major", "scale_unit_noise", "noise_of_simulation",
           "filter_errors_at_fixes", "filter_errors_time_major"]


def filter_model(params: CalibrationParams, model: ErrorStateModel | None = None) -> ErrorStateModel:
    """The model the filter assumes: ``model`` if given (validated), else ``error_state_model(params)``."""
    require_instance("params", params, CalibrationParams)
    if model is None:
        return error_state_model(params)
    return require_instance("model", model, ErrorStateModel)


def matrix_powers(F: np.ndarray, n: int) -> np.ndarray:
    """``F^k`` for ``k = 0..n-1`` by repeated multiplication (any square ``F``, e.g. a mistaken
    model's Phi), shape (n, d, d)."""
    F = np.asarray(F, dtype=float)
    out = np.empty((n,) + F.shape)
    out[0] = np.eye(F.shape[0])
    for k in range(1, n):
        np.matmul(F, out[k - 1], out=out[k])
    return out


def accumulated_noise(powers: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """``Q_k = sum_{l<k} Phi^l Q Phi^lT`` for ``k = 0..len(powers)`` (``Q_0 = 0``), from
    ``powers = Phi^l`` (l = 0..n-1), shape (n + 1, d, d): the noise ``k`` predict steps add."""
    out = np.zeros((len(powers) + 1,) + Q.shape)
    np.cumsum(powers @ Q @ np.swapaxes(powers, 1, 2), axis=0, out=out[1:])
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
    m = filter_model(params, model)
    powers = matrix_powers(m.Phi, params.steps_per_fix + 1)
    return powers, accumulated_noise(powers[:-1], m.Q)


class Covariances(NamedTuple):
    """The data-independent part of the filter (a tuple: ``P, P_prior, S, K = covariance_sequence(...)``).

    P : (n_imu, 3, 3) at every IMU sample, a posteriori at fixes, predicted between them
    P_prior : (n_gps, 3, 3) just before each fix; S : (n_gps, 2, 2) ``H P_prior H^T + V``;
    K : (n_gps, 3, 2) gains (zero at a missing fix).  ``P_post = P[params.fix_indices]``.
    """

    P: np.ndarray
    P_prior: np.ndarray
    S: np.ndarray
    K: np.ndarray


def covariance_sequence(params: CalibrationParams, missing_fixes=None,
                        model: ErrorStateModel | None = None) -> Covariances:
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
    Covariances ``(P (n_imu, 3, 3), P_prior (n_gps, 3, 3), S (n_gps, 2, 2), K (n_gps, 3, 2))``
    """
    m = filter_model(params, model)
    n_gps, r = params.n_gps, params.steps_per_fix
    missing = require_mask("missing_fixes", missing_fixes, n_gps)
    missing = np.zeros(n_gps, bool) if missing is None else missing
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
    # every IMU sample: P(t_i + k dt) = Phi^k P_post[i] Phi^k^T + Q_k, k = 0..r-1, written in place
    # (a loop over the shorter of the two axes: no temporary of the full size)
    P = np.empty((n_gps, r, 3, 3))
    if r <= n_gps:
        for k in range(r):
            np.add(powers[k] @ P_post @ powers[k].T, Qk[k], out=P[:, k])
    else:
        powers_T = np.swapaxes(powers[:r], 1, 2)
        for i in range(n_gps):
            np.add(powers[:r] @ P_post[i] @ powers_T, Qk[:r], out=P[i])
    return Covariances(P.reshape(n_gps * r, 3, 3)[: params.n_imu], P_prior, S, K)


def filter_estimates(params: CalibrationParams, dz: np.ndarray, K: np.ndarray, missing: np.ndarray,
                     model: ErrorStateModel | None = None):
    """The estimates of many realizations with shared gains: ``x_prior`` just before each fix,
    ``y = dz - H x_prior`` (NaN at a missing fix), ``x_post = x_prior + K y``, and
    ``x_prior`` of the next fix ``= Phi^r x_post``.

    dz : (n, n_gps, 2) checked by the caller; K : (n_gps, 3, 2) from :func:`covariance_sequence`;
    missing : (n_gps,) bool.  Returns x_prior (n, n_gps, 3), x_post (n, n_gps, 3), y (n, n_gps, 2).
    """
    m = filter_model(params, model)
    n, n_gps = dz.shape[0], params.n_gps
    HT = m.H.T
    Phi_rT = between_fixes(params, m)[0][-1].T
    # fix-major arrays, so that every step reads and writes contiguous (n, 3) slices
    x_prior = np.empty((n_gps, n, 3))
    x_post = np.empty((n_gps, n, 3))
    y = np.full((n_gps, n, 2), np.nan)
    dz_t = np.ascontiguousarray(dz.transpose(1, 0, 2))
    KT = np.ascontiguousarray(K.transpose(0, 2, 1))
    xi = np.broadcast_to(m.x0, (n, 3)).copy()
    for i in range(n_gps):
        x_prior[i] = xi
        if not missing[i]:
            np.subtract(dz_t[i], xi @ HT, out=y[i])
            xi = xi + y[i] @ KT[i]
        x_post[i] = xi
        xi = xi @ Phi_rT
    return x_prior.transpose(1, 0, 2), x_post.transpose(1, 0, 2), y.transpose(1, 0, 2)


def estimate_between_fixes(params: CalibrationParams, x_post, model: ErrorStateModel | None = None) -> np.ndarray:
    """The filter's estimate at every IMU sample from its a posteriori estimates at the fixes:
    between fixes it is only predicted, ``x(t_i + k dt) = Phi^k x_post[i]``.

    x_post : (n_gps, 3) or (n, n_gps, 3); returns (n_imu, 3) or (n, n_imu, 3).
    ``batch_filter(..., full_rate=True)`` calls this function.
    """
    m = filter_model(params, model)
    x_post = np.asarray(x_post, dtype=float)
    if x_post.ndim not in (2, 3) or x_post.shape[-2:] != (params.n_gps, 3):
        raise ValueError(f"x_post must have shape (..., {params.n_gps}, 3), got {x_post.shape}")
    r = params.steps_per_fix
    powers = between_fixes(params, m)[0][:r]
    x = np.einsum("kab,...ib->...ika", powers, x_post)  # (..., n_gps, r, 3)
    return x.reshape(x.shape[:-3] + (-1, 3))[..., : params.n_imu, :]


# --- the live demo's Monte Carlo: the error recursion at the fixes ----------------------------------

def sample_noise_at_fixes(params: CalibrationParams, n_runs: int, seed):
    """Random draws that drive the filter's error from fix to fix, for ``n_runs`` realizations.

    The error-state model (exact for the Euler truth, notebook 04) seen at the fixes only:
    ``dx_0 - x0 ~ N(0, M0)``; between fixes ``dx_{i+1} = Phi^r dx_i + w_i`` with
    ``w_i ~ N(0, Q_r)``, the IMU noise of the ``r`` steps summed exactly (zero for the bias,
    which has no process noise); GPS noise ``eta_i ~ N(0, V)``.  ``seed``: int or Generator.

    Returns
    -------
    e0 : (n_runs, 3) initial error ``dx_0 - x0`` [m, m/s, m/s^2]
    w : (n_runs, n_gps - 1, 3) process noise between consecutive fixes
    eta : (n_runs, n_gps, 2) GPS noise [m, m/s]
    (``w`` and ``eta`` are views of time-major arrays.)
    """
    e0, w_t, eta_t = sample_noise_time_major(params, n_runs, seed)
    return e0, w_t.transpose(1, 0, 2), eta_t.transpose(1, 0, 2)


def sample_noise_time_major(params: CalibrationParams, n_runs: int, seed):
    """:func:`sample_noise_at_fixes` with time-major ``w_t`` (n_gps - 1, n, 3) and ``eta_t`` (n_gps, n, 2):
    :func:`scale_unit_noise` of :func:`unit_noise_time_major`."""
    require_instance("params", params, CalibrationParams)
    return scale_unit_noise(params, *unit_noise_time_major(params.n_gps, n_runs, seed))


def unit_noise_time_major(n_gps: int, n_runs: int, seed):
    """The standard normal draws behind :func:`sample_noise_time_major`, in its order: ``z0``
    (n_runs, 3), ``z`` (n_gps - 1, n_runs, 2), ``zeta`` (n_gps, n_runs, 2), from ``seed`` (int or
    Generator).  They do not depend on the noise levels, only on the number of fixes ``n_gps`` (>= 1)
    and of realizations, so a caller may keep them across parameter changes (the live demo does)."""
    n_gps = require_int("n_gps", n_gps, minimum=1)
    n_runs = require_int("n_runs", n_runs, minimum=1)
    rng = as_generator("seed", seed)
    return (rng.standard_normal((n_runs, 3)), rng.standard_normal((n_gps - 1, n_runs, 2)),
            rng.standard_normal((n_gps, n_runs, 2)))


def scale_unit_noise(params: CalibrationParams, z0, z, zeta):
    """The draws of :func:`sample_noise_time_major` from its standard normals
    (:func:`unit_noise_time_major`): ``e0 = z0 sqrt(diag M0)``, ``w_t = L z`` with ``L L^T`` the
    (p, v) block of ``Q_r`` (zero bias part), ``eta_t = zeta sqrt(diag V)``.  Returns
    ``e0`` (n_runs, 3), ``w_t`` (n_gps - 1, n_runs, 3), ``eta_t`` (n_gps, n_runs, 2), new arrays."""
    m = filter_model(params)
    n_gps = params.n_gps
    z0 = require_shape("z0", z0, (None, 3))
    n_runs = z0.shape[0]
    z = require_shape("z", z, (n_gps - 1, n_runs, 2))
    zeta = require_shape("zeta", zeta, (n_gps, n_runs, 2))
    Qr = between_fixes(params, m)[1][-1]
    L = np.linalg.cholesky(Qr[:2, :2])  # Q_r is zero in the bias row and column: factor the (p, v) block
    e0 = z0 * np.sqrt(np.diag(m.M0))
    w_t = np.zeros((n_gps - 1, n_runs, 3))
    np.multiply(z[..., 0], L[0, 0], out=w_t[..., 0])
    w_t[..., 1] = L[1, 0] * z[..., 0] + L[1, 1] * z[..., 1]
    eta_t = zeta * np.sqrt(np.diag(m.V))
    return e0, w_t, eta_t


def noise_of_simulation(sim: Simulation):
    """The same draws as :func:`sample_noise_at_fixes` returns, read off a 200 Hz simulation:
    ``e0 = dx_0 - x0``, ``w_i = dx_{i+1} - Phi^r dx_i``, ``eta_i = dz_i - H dx_i`` (0 at a missing
    fix, where no update uses it).  Shapes (n, 3), (n, n_gps - 1, 3), (n, n_gps, 2)."""
    require_instance("sim", sim, Simulation)
    params = sim.params
    m = filter_model(params)
    Phi_r = between_fixes(params, m)[0][-1]
    dx = sim.dx_at_fixes
    eta = sim.dz - dx @ m.H.T
    eta[np.isnan(eta)] = 0.0
    return dx[:, 0] - m.x0, dx[:, 1:] - dx[:, :-1] @ Phi_r.T, eta


def filter_errors_at_fixes(params: CalibrationParams, covariances, e0, w, eta):
    """The filter's estimation errors ``e = dx - dx_hat`` at every fix, for given noises.

    With data-independent gains ``K_i`` (``covariances[3]``, zero at a missing fix) the error of
    the linear filter obeys its own recursion, without the data:
    ``e-_0 = e0``, ``e+_i = (I - K_i H) e-_i - K_i eta_i``, ``e-_{i+1} = Phi^r e+_i + w_i``.
    These are the numbers ``dx - batch_filter(...).x_post`` gives on the same draws (the tests
    check it), from one short loop over the fixes: the Monte Carlo of the demo.

    Parameters
    ----------
    params : CalibrationParams
    covariances : output of :func:`covariance_sequence` (the gains)
    e0 (n, 3), w (n, n_gps - 1, 3), eta (n, n_gps, 2) : as :func:`sample_noise_at_fixes` returns

    Returns
    -------
    e_prior, e_post : (n, n_gps, 3) errors just before and just after each fix [m, m/s, m/s^2]
    """
    filter_model(params)  # validates params
    n_gps = params.n_gps
    e0 = require_shape("e0", e0, (None, 3))
    n = e0.shape[0]
    w = require_shape("w", w, (n, n_gps - 1, 3))
    eta = require_shape("eta", eta, (n, n_gps, 2))
    e_prior, e_post = filter_errors_time_major(params, covariances, e0, w.transpose(1, 0, 2), eta.transpose(1, 0, 2))
    return e_prior.transpose(1, 0, 2), e_post.transpose(1, 0, 2)


def filter_errors_time_major(params: CalibrationParams, covariances, e0, w_t, eta_t):
    """:func:`filter_errors_at_fixes` on time-major arrays: w_t (n_gps - 1, n, 3), eta_t (n_gps, n, 2);
    returns e_prior, e_post of shape (n_gps, n, 3).  Every step's slice is contiguous."""
    m = filter_model(params)
    n_gps = params.n_gps
    K = require_shape("covariances[3] (the gains K)", covariances[3], (n_gps, 3, 2))
    # row vectors: e+_i = e-_i A_i - eta_i B_i with A_i = (I - K_i H)^T, B_i = K_i^T, and
    # e-_{i+1} = e+_i Phi_r^T + w_i = e-_i G_i + u_i with G_i = A_i Phi_r^T, u_i = w_i - eta_i B_i Phi_r^T:
    # the products that do not need the recursion are done for all fixes at once
    A = np.eye(3) - np.transpose(K @ m.H, (0, 2, 1))
    B = np.transpose(K, (0, 2, 1))
    Phi_rT = between_fixes(params, m)[0][-1].T
    eta_t = np.ascontiguousarray(eta_t)
    G = A[:-1] @ Phi_rT
    u = w_t - eta_t[:-1] @ (B[:-1] @ Phi_rT)
    e_prior = np.empty((n_gps,) + e0.shape)
    e = e_prior[0] = e0
    for i in range(n_gps - 1):
        e = e_prior[i + 1] = e @ G[i] + u[i]
    return e_prior, e_prior @ A - eta_t @ B
