"""Truth, IMU and GPS simulation for the calibration problem, vectorised over realizations.

Shapes: ``n`` realizations, ``n_imu`` IMU samples (6001 for the defaults),
``n_gps`` GPS fixes (151).  Units: m, m/s, m/s^2, s.

Random draws, in this order from the ``numpy.random.Generator`` you pass:
``p0`` (n,), ``v0`` (n,), ``b`` (n,), IMU noise ``w`` (n, n_imu), GPS noise
``eta`` (n, n_gps, 2).  The same generator state therefore gives the same
realizations whatever the truth model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import require_choice, require_int
from .params import CalibrationParams

__all__ = [
    "TRUTH_MODELS",
    "acceleration",
    "analytic_truth",
    "integrate_left",
    "Simulation",
    "simulate",
]

TRUTH_MODELS = ("euler", "analytic")


def acceleration(t, params: CalibrationParams) -> np.ndarray:
    """True acceleration ``a(t) = A sin(omega t)``, m/s^2, same shape as ``t`` (s)."""
    return params.A * np.sin(params.omega * np.asarray(t, dtype=float))


def analytic_truth(t, p0, v0, params: CalibrationParams) -> tuple[np.ndarray, np.ndarray]:
    """Exact position and velocity for ``a(t) = A sin(omega t)``.

    ``v(t) = v0 + (A/omega)(1 - cos omega t)``,
    ``p(t) = p0 + (v0 + A/omega) t - (A/omega^2) sin omega t``.

    Parameters
    ----------
    t : array (n_t,), s
    p0, v0 : arrays (n,) or scalars, m and m/s

    Returns
    -------
    p, v : arrays (n, n_t) (or (n_t,) for scalar p0, v0), m and m/s
    """
    t = np.asarray(t, dtype=float)
    p0 = np.asarray(p0, dtype=float)[..., None]
    v0 = np.asarray(v0, dtype=float)[..., None]
    A, w = params.A, params.omega
    v = v0 + (A / w) * (1.0 - np.cos(w * t))
    p = p0 + (v0 + A / w) * t - (A / w**2) * np.sin(w * t)
    return p, v


def _exclusive_cumsum(x: np.ndarray) -> np.ndarray:
    """out[..., 0] = 0, out[..., j] = x[..., 0] + ... + x[..., j-1]."""
    out = np.empty(x.shape)
    out[..., 0] = 0.0
    np.cumsum(x[..., :-1], axis=-1, out=out[..., 1:])
    return out


def integrate_left(acc, p_init, v_init, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Left-Riemann (Euler) integration used by the IMU and by the Euler truth.

    ``v[j+1] = v[j] + acc[j] dt``, ``p[j+1] = p[j] + v[j] dt + acc[j] dt^2/2``.

    Parameters
    ----------
    acc : array (..., n_t), m/s^2
    p_init, v_init : arrays broadcastable to acc's leading axes, m and m/s
    dt : float, s

    Returns
    -------
    p, v : arrays (..., n_t), m and m/s
    """
    acc = np.asarray(acc, dtype=float)
    v_init = np.asarray(v_init, dtype=float)[..., None]
    p_init = np.asarray(p_init, dtype=float)[..., None]
    v = v_init + dt * _exclusive_cumsum(acc)
    p = p_init + _exclusive_cumsum(v * dt + acc * (0.5 * dt * dt))
    return p, v


@dataclass
class Simulation:
    """One batch of simulated realizations.

    Attributes (n realizations; n_imu samples; n_gps fixes)
    ----------
    params : CalibrationParams
    truth : "euler" or "analytic"
    t : (n_imu,) IMU sample times, s
    a : (n_imu,) true acceleration, m/s^2
    p, v : (n, n_imu) true position (m) and velocity (m/s)
    b : (n,) accelerometer bias, m/s^2
    w : (n, n_imu) IMU white noise, m/s^2
    a_c : (n, n_imu) IMU output a + b + w, m/s^2
    p_c, v_c : (n, n_imu) IMU dead reckoning from the prior means, m and m/s
    z : (n, n_gps, 2) GPS fixes [position m, velocity m/s]; NaN rows are missing fixes
    """

    params: CalibrationParams
    truth: str
    t: np.ndarray
    a: np.ndarray
    p: np.ndarray
    v: np.ndarray
    b: np.ndarray
    w: np.ndarray
    a_c: np.ndarray
    p_c: np.ndarray
    v_c: np.ndarray
    z: np.ndarray

    @property
    def n_runs(self) -> int:
        return self.p.shape[0]

    @property
    def dx(self) -> np.ndarray:
        """True error state ``[p - p_c, v - v_c, b]``, shape (n, n_imu, 3)."""
        return np.stack([self.p - self.p_c, self.v - self.v_c,
                         np.broadcast_to(self.b[:, None], self.p.shape)], axis=-1)

    @property
    def dx_at_fixes(self) -> np.ndarray:
        """True error state at the GPS fixes, shape (n, n_gps, 3)."""
        idx = self.params.fix_indices
        return np.stack([self.p[:, idx] - self.p_c[:, idx], self.v[:, idx] - self.v_c[:, idx],
                         np.broadcast_to(self.b[:, None], (self.n_runs, len(idx)))], axis=-1)

    @property
    def dz(self) -> np.ndarray:
        """Error-state measurement ``z - [p_c, v_c]`` at the fixes, shape (n, n_gps, 2)."""
        idx = self.params.fix_indices
        return self.z - np.stack([self.p_c[:, idx], self.v_c[:, idx]], axis=-1)


def simulate(params: CalibrationParams, n_runs: int, rng: np.random.Generator,
             truth: str = "euler", missing_fixes=None) -> Simulation:
    """Simulate ``n_runs`` realizations of truth, IMU and GPS.

    Parameters
    ----------
    params : CalibrationParams
    n_runs : int >= 1
    rng : numpy.random.Generator (e.g. ``numpy.random.default_rng(seed)``)
    truth : "euler" (the model the error-state filter assumes; default) or
        "analytic" (the exact kinematics, see notebook 7)
    missing_fixes : optional bool array (n_gps,), True where the GPS fix is
        missing (outage); those rows of ``z`` are NaN

    Returns
    -------
    Simulation
    """
    if not isinstance(params, CalibrationParams):
        raise ValueError(f"params must be a CalibrationParams, got {type(params).__name__}")
    n_runs = require_int("n_runs", n_runs, minimum=1)
    require_choice("truth", truth, TRUTH_MODELS)
    if not isinstance(rng, np.random.Generator):
        raise ValueError("rng must be a numpy.random.Generator, e.g. numpy.random.default_rng(seed)")
    t = params.t_imu
    dt = params.dt
    a = acceleration(t, params)

    p0 = params.p0_mean + np.sqrt(params.p0_var) * rng.standard_normal(n_runs)
    v0 = params.v0_mean + np.sqrt(params.v0_var) * rng.standard_normal(n_runs)
    b = params.bias_mean + np.sqrt(params.bias_var) * rng.standard_normal(n_runs)
    w = rng.standard_normal((n_runs, params.n_imu))
    w *= np.sqrt(params.W)
    eta = rng.standard_normal((n_runs, params.n_gps, 2))
    eta *= np.sqrt([params.gps_pos_var, params.gps_vel_var])

    if truth == "euler":
        # a(t) is the same for every realization: integrate it once, then add the
        # initial-condition terms p0 + v0 t (exactly what integrate_left would give).
        pa, va = integrate_left(a, 0.0, 0.0, dt)
        p = p0[:, None] + v0[:, None] * t + pa
        v = v0[:, None] + va
    else:
        p, v = analytic_truth(t, p0, v0, params)

    a_c = a + b[:, None] + w
    p_c, v_c = integrate_left(a_c, params.p0_mean, params.v0_mean, dt)

    idx = params.fix_indices
    z = np.stack([p[:, idx], v[:, idx]], axis=-1) + eta
    if missing_fixes is not None:
        missing = np.asarray(missing_fixes)
        if missing.shape != (params.n_gps,) or missing.dtype != bool:
            raise ValueError(f"missing_fixes must be a bool array of shape ({params.n_gps},), "
                             f"got {missing.dtype} {missing.shape}")
        z[:, missing, :] = np.nan
    return Simulation(params, truth, t, a, p, v, b, w, a_c, p_c, v_c, z)
