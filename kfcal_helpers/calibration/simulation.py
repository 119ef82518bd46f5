"""Truth, IMU and GPS simulation for the calibration problem, vectorised over realizations.

Shapes: ``n`` realizations, ``n_imu`` IMU samples (6001 for the defaults),
``n_gps`` GPS fixes (151).  Units: m, m/s, m/s^2, s.

Random draws (:func:`draw_realizations`), in this order from the generator of ``seed``
(an int, or a ``numpy.random.Generator`` that is advanced): ``p0`` (n,), ``v0`` (n,), ``b`` (n,),
IMU noise ``w`` (n, n_imu), GPS noise ``eta`` (n, n_gps, 2).  The same seed therefore gives the
same realizations whatever the truth model.

:func:`simulate` builds the 200 Hz truth, IMU and GPS from the draws.  The Monte Carlo needs only
the error state at the fixes, which is linear in the draws: :func:`error_state_at_fixes` computes
it from the sums of the IMU noise over each GPS period, without the 200 Hz arrays (the same numbers
as ``simulate(...).dx_at_fixes`` to rounding, see ``tests/test_calibration_engine.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from functools import partial

from ..validation import (MAX_SEED, as_generator, checked, require_choice, require_finite_array, require_instance,
                          require_int, require_mask, require_positive)
from .params import CalibrationParams

__all__ = [
    "TRUTH_MODELS",
    "acceleration",
    "analytic_truth",
    "integrate_left",
    "Simulation",
    "simulate",
    "Draws",
    "draw_realizations",
    "error_state_at_fixes",
    "error_state_full",
    "mean_error_state",
]

TRUTH_MODELS = ("euler", "analytic")

#: argument checks (validation.checked): the parameters; a start value, a scalar or one per realization (n,)
_PARAMS = partial(require_instance, cls=CalibrationParams)


def _start_value(name, value):
    arr = require_finite_array(name, value)
    if arr.ndim > 1:
        raise ValueError(f"{name} must be a number or a vector (n,), got shape {arr.shape}")
    return arr


@checked(t=require_finite_array, params=_PARAMS)
def acceleration(t, params: CalibrationParams) -> np.ndarray:
    """True acceleration ``a(t) = A sin(omega t)``, m/s^2, same shape as ``t`` (s)."""
    return params.A * np.sin(params.omega * np.asarray(t, dtype=float))


@checked(t=partial(require_finite_array, shape=(None,)), p0=_start_value, v0=_start_value, params=_PARAMS)
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
    p0, v0 = p0[..., None], v0[..., None]
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


@checked(acc=partial(require_finite_array, shape=(..., None)), p_init=require_finite_array,
         v_init=require_finite_array, dt=require_positive)
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
    for name, start in (("p_init", p_init), ("v_init", v_init)):
        if np.broadcast_shapes(start.shape, acc.shape[:-1]) != acc.shape[:-1]:
            raise ValueError(f"{name} must broadcast to acc's leading axes {acc.shape[:-1]}, got shape {start.shape}")
    v_init = v_init[..., None]
    p_init = p_init[..., None]
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


@dataclass
class Draws:
    """The random draws of ``n`` realizations (see the module docstring for their order).

    p0 (n,) m, v0 (n,) m/s, b (n,) m/s^2: initial position, velocity and bias;
    w (n, n_imu) m/s^2: IMU white noise; eta (n, n_gps, 2) [m, m/s]: GPS noise.
    """

    p0: np.ndarray
    v0: np.ndarray
    b: np.ndarray
    w: np.ndarray
    eta: np.ndarray


def draw_realizations(params: CalibrationParams, n_runs: int, seed) -> Draws:
    """The random draws of ``n_runs`` realizations from ``seed`` (int or numpy.random.Generator)."""
    require_instance("params", params, CalibrationParams)
    n_runs = require_int("n_runs", n_runs, minimum=1)
    rng = as_generator("seed", seed)
    p0 = params.p0_mean + np.sqrt(params.p0_var) * rng.standard_normal(n_runs)
    v0 = params.v0_mean + np.sqrt(params.v0_var) * rng.standard_normal(n_runs)
    b = params.bias_mean + np.sqrt(params.bias_var) * rng.standard_normal(n_runs)
    w = rng.standard_normal((n_runs, params.n_imu))
    w *= np.sqrt(params.W)
    eta = rng.standard_normal((n_runs, params.n_gps, 2))
    eta *= np.sqrt([params.gps_pos_var, params.gps_vel_var])
    return Draws(p0, v0, b, w, eta)


def _truth_minus_reckoning(params: CalibrationParams, draws: Draws, truth: str, idx) -> tuple[np.ndarray, np.ndarray]:
    """``(p - p_c, v - v_c)`` at the samples ``idx`` without the IMU error ``b + w``: the truth minus
    the dead reckoning of the true acceleration from the prior means, (n, len(idx)) each."""
    t = params.t_imu[idx]
    dp0 = draws.p0 - params.p0_mean
    dv0 = draws.v0 - params.v0_mean
    if truth == "euler":  # both integrate a(t) the same way: only the initial conditions differ
        return dp0[:, None] + dv0[:, None] * t, np.broadcast_to(dv0[:, None], (len(dp0), len(t)))
    p, v = analytic_truth(t, draws.p0, draws.v0, params)
    pa, va = integrate_left(acceleration(params.t_imu, params), params.p0_mean, params.v0_mean, params.dt)
    return p - pa[idx], v - va[idx]


def error_state_at_fixes(params: CalibrationParams, draws: Draws, truth: str = "euler") -> np.ndarray:
    """The true error state ``[p - p_c, v - v_c, b]`` at the GPS fixes, (n, n_gps, 3), from the draws.

    The dead reckoning's error is the IMU error ``c_l = b + w_l`` integrated twice (Euler):
    ``dv_j = dv_0 - dt sum_{l<j} c_l`` and ``dp_j = dp_0 + j dt dv_0 - dt^2 sum_{l<j} c_l (j - l - 1/2)``.
    At the fix ``j = r i`` these sums need only, for every GPS period ``m``, ``s_m = sum_q w_{rm+q}``
    and ``u_m = sum_q w_{rm+q} (r - q - 1/2)`` (q = 0..r-1): ``sum_{l<ri} w_l = S_i = sum_{m<i} s_m`` and
    ``sum_{l<ri} w_l (ri - l - 1/2) = r sum_{k<i} S_k + sum_{m<i} u_m``.  The same numbers as
    ``simulate(...).dx_at_fixes`` on the same draws, to rounding, from one small matrix product.
    """
    require_instance("params", params, CalibrationParams)
    require_instance("draws", draws, Draws)
    require_choice("truth", truth, TRUTH_MODELS)
    n, n_gps, r, dt = len(draws.b), params.n_gps, params.steps_per_fix, params.dt
    idx = params.fix_indices
    weights = np.empty((r, 2))
    weights[:, 0] = 1.0
    weights[:, 1] = r - np.arange(r) - 0.5
    su = np.zeros((n, n_gps, 2))  # [S_i, U_i]: the exclusive cumulative sums of [s_m, u_m]
    blocks = draws.w[:, : (n_gps - 1) * r].reshape(n, n_gps - 1, r)  # a view: row-contiguous periods
    np.cumsum(blocks @ weights, axis=1, out=su[:, 1:])
    T = np.zeros((n, n_gps))  # r sum_{k<i} S_k
    np.cumsum(su[:, :-1, 0], axis=1, out=T[:, 1:])
    j = idx.astype(float)
    dp, dv = _truth_minus_reckoning(params, draws, truth, idx)
    b = draws.b[:, None]
    out = np.empty((n, n_gps, 3))
    out[..., 0] = dp - dt * dt * (b * (0.5 * j * j) + r * T + su[..., 1])
    out[..., 1] = dv - dt * (b * j + su[..., 0])
    out[..., 2] = b
    return out


def error_state_full(params: CalibrationParams, draws: Draws, truth: str = "euler") -> np.ndarray:
    """The true error state at every IMU sample, (n, n_imu, 3), by the formulas of
    :func:`error_state_at_fixes` with running sums over all samples (``simulate(...).dx`` to rounding)."""
    require_instance("params", params, CalibrationParams)
    require_instance("draws", draws, Draws)
    require_choice("truth", truth, TRUTH_MODELS)
    n, n_imu, dt = len(draws.b), params.n_imu, params.dt
    S = _exclusive_cumsum(draws.w)  # sum_{l<j} w_l
    j = np.arange(n_imu, dtype=float)
    dp, dv = _truth_minus_reckoning(params, draws, truth, np.arange(n_imu))
    b = draws.b[:, None]
    out = np.empty((n, n_imu, 3))
    out[..., 1] = dv - dt * (b * j + S)
    S2 = _exclusive_cumsum(S)  # sum_{l<j} w_l (j - l - 1) = sum_{k<j} S_k
    S2 += 0.5 * S
    del S
    out[..., 0] = dp - dt * dt * (b * (0.5 * j * j) + S2)
    out[..., 2] = b
    return out


def mean_error_state(params: CalibrationParams, truth: str = "euler") -> np.ndarray:
    """The true error state ``[p - p_c, v - v_c, b]`` at every IMU sample of the realization whose draws
    are all zero (initial conditions at their prior means, no bias, no IMU noise), (n_imu, 3) in m, m/s,
    m/s^2: zero for the Euler truth, the deterministic mismatch of the dead reckoning for the analytic
    truth.  The error state of any realization is this plus a part linear in its draws."""
    require_instance("params", params, CalibrationParams)
    require_choice("truth", truth, TRUTH_MODELS)
    out = np.zeros((params.n_imu, 3))
    if truth != "euler":  # the Euler truth integrates a(t) as the IMU does: no deterministic part
        zero = Draws(np.array([params.p0_mean]), np.array([params.v0_mean]), np.zeros(1), None, None)
        dp, dv = _truth_minus_reckoning(params, zero, truth, np.arange(params.n_imu))
        out[:, 0], out[:, 1] = dp[0], dv[0]
    return out


@checked(n_runs=partial(require_int, minimum=1, maximum=MAX_SEED))
def simulate(params: CalibrationParams, n_runs: int, seed, truth: str = "euler", missing_fixes=None) -> Simulation:
    """Simulate ``n_runs`` realizations of truth, IMU and GPS.

    Parameters
    ----------
    params : CalibrationParams
    n_runs : int >= 1
    seed : int seed of ``numpy.random.default_rng``, or a numpy.random.Generator (advanced by the draws)
    truth : "euler" (the model the error-state filter assumes; default) or
        "analytic" (the exact kinematics, see notebook 7)
    missing_fixes : optional bool array (n_gps,), True where the GPS fix is
        missing (outage); those rows of ``z`` are NaN

    Returns
    -------
    Simulation
    """
    require_instance("params", params, CalibrationParams)
    n_runs = require_int("n_runs", n_runs, minimum=1)
    require_choice("truth", truth, TRUTH_MODELS)
    missing = require_mask("missing_fixes", missing_fixes, params.n_gps)
    d = draw_realizations(params, n_runs, seed)
    p0, v0, b, w, eta = d.p0, d.v0, d.b, d.w, d.eta
    t = params.t_imu
    dt = params.dt
    a = acceleration(t, params)

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
    if missing is not None:
        z[:, missing, :] = np.nan
    return Simulation(params, truth, t, a, p, v, b, w, a_c, p_c, v_c, z)
