"""The error-state model of the calibration filter.

State ``dx = [dp, dv, b]`` (m, m/s, m/s^2) with ``dp = p - p_c``, ``dv = v - v_c``:

    dx[j+1] = Phi dx[j] + Gamma w[j],      w[j] ~ N(0, W)
    dz[i]   = H dx(t_i) + eta[i],          eta[i] ~ N(0, V)
    dx[0]   ~ N([0, 0, b_mean], M0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import require_instance
from .params import CalibrationParams

__all__ = ["ErrorStateModel", "error_state_model", "phi_power"]


@dataclass(frozen=True)
class ErrorStateModel:
    """Matrices of the error-state model (all float arrays).

    Phi (3, 3), Gamma (3,), H (2, 3), W (scalar, (m/s^2)^2),
    Q = W Gamma Gamma^T (3, 3), V (2, 2), M0 (3, 3), x0 (3,) prior mean of dx.
    """

    Phi: np.ndarray
    Gamma: np.ndarray
    H: np.ndarray
    W: float
    Q: np.ndarray
    V: np.ndarray
    M0: np.ndarray
    x0: np.ndarray


def error_state_model(params: CalibrationParams) -> ErrorStateModel:
    """Build Phi, Gamma, H, Q, V, M0 and the prior mean for ``params``."""
    require_instance("params", params, CalibrationParams)
    dt = params.dt
    Phi = np.array([[1.0, dt, -dt**2 / 2], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
    Gamma = np.array([-dt**2 / 2, -dt, 0.0])
    H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    Q = params.W * np.outer(Gamma, Gamma)
    V = np.diag([params.gps_pos_var, params.gps_vel_var])
    M0 = np.diag([params.p0_var, params.v0_var, params.bias_var])
    x0 = np.array([0.0, 0.0, params.bias_mean])
    return ErrorStateModel(Phi, Gamma, H, params.W, Q, V, M0, x0)


def phi_power(params: CalibrationParams, k) -> np.ndarray:
    """Closed-form ``Phi^k = [[1, k dt, -(k dt)^2/2], [0, 1, -k dt], [0, 0, 1]]``.

    ``k`` int or int array (m,); returns (3, 3) or (m, 3, 3).
    """
    require_instance("params", params, CalibrationParams)
    k_in = np.asarray(k)
    if k_in.dtype == bool or not (np.issubdtype(k_in.dtype, np.integer) or np.issubdtype(k_in.dtype, np.floating)) \
            or not np.all(np.isfinite(k_in)) or np.any(k_in != np.round(k_in)):
        raise ValueError(f"k must be an integer or an array of integers (numbers of IMU steps), got {k!r}")
    k = k_in.astype(float)
    s = k * params.dt
    out = np.zeros(k.shape + (3, 3))
    out[..., 0, 0] = out[..., 1, 1] = out[..., 2, 2] = 1.0
    out[..., 0, 1] = s
    out[..., 0, 2] = -s**2 / 2
    out[..., 1, 2] = -s
    return out
