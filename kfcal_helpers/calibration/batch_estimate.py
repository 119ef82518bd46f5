"""Minimum variance without recursion: the filter's P as one Gaussian conditioning,
and the Rauch-Tung-Striebel smoother for an offline calibration.

:func:`batch_conditioning_covariance` builds the joint Gaussian of
``[x(t_i), dz_0, ..., dz_i]`` straight from the model,

    x(t_m) = Phi^{k_m} x_0 + sum_{j < k_m} Phi^{k_m - 1 - j} Gamma w_j,     k_m = m * steps_per_fix
    dz_m   = H x(t_m) + eta_m,

whose covariances are (no filter recursion; the noise sum in closed form)

    Pi_m         = Cov(x(t_m)) = Phi^{k_m} M0 Phi^{k_m T} + sum_{j=0}^{k_m - 1} Phi^j Q Phi^{j T}
    Cov(x(t_n), x(t_m)) = Phi^{k_n - k_m} Pi_m                      (n >= m)

and conditions ``x(t_i)`` on all ``dz_0..dz_i`` at once:
``P = Sigma_xx - Sigma_xz Sigma_zz^{-1} Sigma_zx``.  :func:`batch_conditioning` also gives
the conditional mean ``E[x(t_i) | dz] = mu_i + Sigma_xz Sigma_zz^{-1} (dz - H mu)`` of one
realization's data, with the prior means ``mu_m = Phi^{k_m} x0``.

:func:`rts_smooth_fixes` is the fix-to-fix RTS smoother for many realizations
at once (the gains do not depend on the data).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from functools import partial

from ..validation import checked, optional, require_array, require_finite_array, require_int
from .error_model import ErrorStateModel
from .engine import accumulated_noise, between_fixes, filter_model, matrix_powers
from .params import CalibrationParams

__all__ = ["prior_covariances_at_fixes", "batch_conditioning_covariance", "batch_conditioning", "rts_smooth_fixes"]


#: argument checks (validation.checked): covariances at the fixes (n_gps, 3, 3)
_COVARIANCES = partial(require_finite_array, shape=(None, 3, 3))


def prior_covariances_at_fixes(params: CalibrationParams, model: ErrorStateModel | None = None) -> np.ndarray:
    """Unconditional covariance ``Pi_m = Cov(x(t_m))`` of the error state at every fix.

    Closed form ``Phi^k M0 Phi^kT + sum_{j<k} Phi^j Q Phi^jT`` (a cumulative sum over the
    closed-form powers of Phi, no filter recursion).  Returns (n_gps, 3, 3) in
    m^2, (m/s)^2, (m/s^2)^2 and their products.
    """
    m = filter_model(params, model)
    powers = matrix_powers(m.Phi, params.n_imu)  # (n_imu, 3, 3), Phi^j
    cum = accumulated_noise(powers, m.Q)  # cum[k] = sum_{j<k} Phi^j Q Phi^jT
    k = params.fix_indices
    Pk = powers[k]
    return np.einsum("kab,bc,kdc->kad", Pk, m.M0, Pk) + cum[k]


@checked(Pi=optional(_COVARIANCES))
def batch_conditioning_covariance(params: CalibrationParams, i: int, model: ErrorStateModel | None = None,
                                  Pi: np.ndarray | None = None) -> np.ndarray:
    """Covariance of ``x(t_i)`` given all fixes ``dz_0..dz_i`` by one Gaussian conditioning.

    Parameters
    ----------
    params : CalibrationParams
    i : int, fix index, 0 <= i < n_gps
    model : optional ErrorStateModel (default: ``error_state_model(params)``)
    Pi : optional output of :func:`prior_covariances_at_fixes` to reuse

    Returns
    -------
    (3, 3) array: ``Sigma_xx - Sigma_xz Sigma_zz^{-1} Sigma_zx`` with ``Sigma_zz``
    of size ``2(i+1)``, solved by Cholesky (``scipy.linalg.cho_factor``/``cho_solve``).
    Equal to the Kalman filter's a posteriori P at fix ``i`` (every fix present).
    """
    _, P = batch_conditioning(params, i, None, model, Pi)
    return P


@checked(dz=optional(require_array), Pi=optional(_COVARIANCES))
def batch_conditioning(params: CalibrationParams, i: int, dz=None, model: ErrorStateModel | None = None,
                       Pi: np.ndarray | None = None):
    """Mean and covariance of ``x(t_i)`` given the fixes ``dz_0..dz_i``, by one Gaussian conditioning.

    Parameters
    ----------
    params : CalibrationParams
    i : int, fix index, 0 <= i < n_gps
    dz : optional array (n_gps, 2) or (n, n_gps, 2), the error-state measurements (m, m/s) of one
        or many realizations (only rows 0..i are used; every fix present); None: covariance only
    model : optional ErrorStateModel (default: ``error_state_model(params)``)
    Pi : optional output of :func:`prior_covariances_at_fixes` to reuse

    Returns
    -------
    mean : (3,) or (n, 3) ``mu_i + Sigma_xz Sigma_zz^{-1} (dz - H mu)`` (None without ``dz``),
        equal to the Kalman filter's a posteriori estimate at fix ``i``
    P : (3, 3) ``Sigma_xx - Sigma_xz Sigma_zz^{-1} Sigma_zx``, the filter's a posteriori P
    """
    m = filter_model(params, model)
    i = require_int("i", i, minimum=0)
    if i >= params.n_gps:
        raise ValueError(f"i must be below n_gps = {params.n_gps}, got {i}")
    if Pi is None:
        Pi = prior_covariances_at_fixes(params, m)
    r = params.steps_per_fix
    H, V = m.H, m.V
    n = i + 1
    lag = np.arange(n)[:, None] - np.arange(n)[None, :]  # n - m
    # C[a, b] = Cov(x(t_a), x(t_b)) = Phi^{(a-b) r} Pi_b for a >= b
    F = matrix_powers(between_fixes(params, m)[0][r], int(np.abs(lag).max()) + 1)  # (Phi^r)^k
    C = F[np.abs(lag)] @ Pi[:n][None, :, :, :]
    lower = lag >= 0
    C = np.where(lower[:, :, None, None], C, np.swapaxes(C, 0, 1).swapaxes(2, 3))
    Szz = (H @ C @ H.T).transpose(0, 2, 1, 3).reshape(2 * n, 2 * n)
    Szz += np.kron(np.eye(n), V)
    Sxz = (C[i] @ H.T).transpose(1, 0, 2).reshape(3, 2 * n)  # Cov(x_i, z_b) = C[i, b] H^T
    factor = scipy.linalg.cho_factor(Szz, lower=True)
    P = Pi[i] - Sxz @ scipy.linalg.cho_solve(factor, Sxz.T)
    mean = None
    if dz is not None:
        dz = np.asarray(dz, float)
        if dz.shape[-2:] != (params.n_gps, 2) or dz.ndim not in (2, 3) or not np.all(np.isfinite(dz[..., :n, :])):
            raise ValueError(f"dz must be a finite array of shape ({params.n_gps}, 2) or (n, {params.n_gps}, 2), "
                             f"got {dz.shape}")
        mu = F[:n] @ m.x0                                   # prior means at fixes 0..i, (n, 3)
        innov = (dz[..., :n, :] - mu @ H.T).reshape(*dz.shape[:-2], 2 * n)
        mean = mu[i] + scipy.linalg.cho_solve(factor, innov.T).T @ Sxz.T
    return mean, (P + P.T) / 2


@checked(x_prior=require_array, x_post=require_array, P_prior=_COVARIANCES, P_post=_COVARIANCES)
def rts_smooth_fixes(params: CalibrationParams, x_prior, x_post, P_prior, P_post,
                     model: ErrorStateModel | None = None):
    """Rauch-Tung-Striebel smoother on the fix-to-fix model, many realizations at once.

    Between fixes there are no measurements, so smoothing the 200 Hz sequence and
    reading it at the fixes equals smoothing the fix-to-fix model with
    ``F = Phi^steps_per_fix``: ``C_i = P_post[i] F^T P_prior[i+1]^{-1}``,
    ``xs_i = x_post[i] + C_i (xs_{i+1} - x_prior[i+1])``,
    ``Ps_i = P_post[i] + C_i (Ps_{i+1} - P_prior[i+1]) C_i^T``.

    Parameters
    ----------
    x_prior, x_post : (n, n_gps, 3) or (n_gps, 3) filter estimates before / after each fix
    P_prior, P_post : (n_gps, 3, 3) filter covariances
    model : optional ErrorStateModel (default: the true one)

    Returns
    -------
    xs : same shape as ``x_post``, smoothed estimates at the fixes
    Ps : (n_gps, 3, 3) smoothed covariances (the last equals ``P_post[-1]``)
    """
    m = filter_model(params, model)
    x_post = np.asarray(x_post, float)
    x_prior = np.asarray(x_prior, float)
    if x_post.shape != x_prior.shape or x_post.shape[-2:] != (params.n_gps, 3):
        raise ValueError(f"x_prior and x_post must have the same shape (..., {params.n_gps}, 3), "
                         f"got {x_prior.shape} and {x_post.shape}")
    F = between_fixes(params, m)[0][-1]  # Phi^steps_per_fix
    xs = x_post.copy()
    Ps = np.array(P_post, float, copy=True)
    for i in range(params.n_gps - 2, -1, -1):
        C = P_post[i] @ F.T @ np.linalg.inv(P_prior[i + 1])
        xs[..., i, :] = x_post[..., i, :] + (xs[..., i + 1, :] - x_prior[..., i + 1, :]) @ C.T
        Ps[i] = P_post[i] + C @ (Ps[i + 1] - P_prior[i + 1]) @ C.T
    return xs, Ps
