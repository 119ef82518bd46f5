"""Orbit-determination model: two-body dynamics, the circular nominal, the stations, measurements,
their Jacobians and the DT model.

State ``x = [X, Xdot, Y, Ydot]`` (km, km/s, km, km/s), inertial frame centred on the Earth.  Dynamics
(point-mass gravity, ``r = sqrt(X^2 + Y^2)``)::

    Xddot = -mu X / r^3 + w1,   Yddot = -mu Y / r^3 + w2,   xdot = f(x) + Gamma w,

``Gamma = [[0, 0], [1, 0], [0, 0], [0, 1]]``, ``w`` (km/s^2) the acceleration noise.  Station ``i``
(0-based here, ``i = 0 .. n_stations - 1``; the course numbers them 1..12) sits on the equator at angle
``theta_i(t) = omegaE t + i 2 pi / n_stations``, with the state ``[Xi, Xidot, Yi, Yidot]`` of the same
layout.  It measures, when it sees the satellite,

* ``rho = sqrt((X - Xi)^2 + (Y - Yi)^2)`` (km),
* ``rhodot = ((X - Xi)(Xdot - Xidot) + (Y - Yi)(Ydot - Yidot)) / rho`` (km/s),
* ``phi = atan2(Y - Yi, X - Xi)`` (rad, wrapped to (-pi, pi]),

and it sees the satellite when the line of sight is above its horizon: ``(r - r_i) . r_i > 0`` (positions),
which is ``phi`` within pi/2 of ``theta_i``.  Every function takes arrays with leading axes.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.linalg import expm

from ..angles import AngleLayout, wrap_angle
from ..validation import checked, require_array, require_choice, require_finite_array, require_int, require_positive
from .params import MAX_STEPS, N_STATES, N_STATION_MEAS, OrbitParams

__all__ = [
    "PHI",
    "TRANSITIONS",
    "PROPAGATION_SUBSTEPS",
    "MAX_SUBSTEPS",
    "require_states",
    "params_or_default",
    "dynamics",
    "jacobian_A",
    "nominal_state",
    "nominal_trajectory",
    "station_angles",
    "station_states",
    "visible",
    "horizon",
    "relative_states",
    "measure",
    "measure_relative",
    "jacobian_relative",
    "jacobian_C",
    "discretize",
    "rk4_flow",
    "propagate",
    "wrap_phi",
    "measurement_layout",
    "stacked_measurement",
    "stacked_jacobian",
]

PHI = 2  #: position of phi in a station's [rho, rhodot, phi]
#: how F comes from A: "euler" ``I + dt A`` (the filters' default) or "expm" ``expm(dt A)``
TRANSITIONS = ("euler", "expm")
#: RK4 substeps per sample interval of :func:`propagate` (the filters' nonlinear one-step map)
PROPAGATION_SUBSTEPS = 2
#: the most RK4 substeps per sample interval accepted (:func:`propagate`, the filters' ``substeps``)
MAX_SUBSTEPS = 10_000


def require_states(name: str, x) -> np.ndarray:
    """``x`` as a float array of shape (..., 4) with finite entries; ValueError naming ``name`` otherwise."""
    arr = require_array(name, x)
    if arr.ndim == 0 or arr.shape[-1] != N_STATES:
        raise ValueError(f"{name} must have shape (..., {N_STATES}) [X, Xdot, Y, Ydot], got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must hold only finite numbers")
    return arr


def params_or_default(params) -> OrbitParams:
    """``params``, or the course's :class:`OrbitParams` for None; ValueError naming ``params`` otherwise."""
    if params is None:
        return OrbitParams()
    if not isinstance(params, OrbitParams):
        raise ValueError(f"params must be an OrbitParams or None, got {type(params).__name__}")
    return params


# ---------------------------------------------------------------------------
# Dynamics
def _gravity(x, mu):
    X, Y = x[..., 0], x[..., 2]
    r2 = X * X + Y * Y
    return X, Y, r2, mu / (r2 * np.sqrt(r2))


def _f(x, mu, push=None):
    """f(x) (+ push) without checks: ``x`` (..., 4) float array, ``push`` (..., 4) or None."""
    X, Y = x[..., 0], x[..., 2]
    r2 = X * X + Y * Y
    g = -mu / (r2 * np.sqrt(r2))
    out = np.empty(x.shape) if push is None else push.copy()
    if push is None:
        out[..., 0], out[..., 2] = x[..., 1], x[..., 3]
        out[..., 1], out[..., 3] = g * X, g * Y
    else:
        out[..., 0] += x[..., 1]
        out[..., 2] += x[..., 3]
        out[..., 1] += g * X
        out[..., 3] += g * Y
    return out


def dynamics(x, params: OrbitParams | None = None, w=None) -> np.ndarray:
    """CT dynamics ``f(x) + Gamma w`` (..., 4), [km/s, km/s^2, km/s, km/s^2].

    x : (..., 4) states; w : (..., 2) or (2,) acceleration noise or thrust, km/s^2 (default none).
    ValueError for another shape, a non-finite entry or a state at the centre of the Earth.
    """
    p = params_or_default(params)
    x = require_states("x", x)
    if np.any(x[..., 0] ** 2 + x[..., 2] ** 2 == 0):
        raise ValueError("x: a position is at r = 0, where gravity is undefined")
    out = _f(x, p.mu)
    if w is not None:
        w = require_array("w", w)
        if w.ndim == 0 or w.shape[-1] != 2 or not np.isfinite(w).all():
            raise ValueError(f"w must have shape (..., 2) with finite entries (km/s^2), got {w.shape}")
        out = out + w @ p.Gamma.T
    return out


def jacobian_A(x, params: OrbitParams | None = None) -> np.ndarray:
    """CT state Jacobian ``A = df/dx`` at ``x`` (..., 4), shape (..., 4, 4) (1/s and 1/s^2).

    Rows 0 and 2 are the kinematics (``dX/dt = Xdot``); rows 1 and 3 the gravity gradient
    ``d(-mu X / r^3)/dX = mu (3 X^2 - r^2) / r^5``, ``d(-mu X / r^3)/dY = 3 mu X Y / r^5`` and the same with
    X and Y exchanged.
    """
    p = params_or_default(params)
    x = require_states("x", x)
    X, Y, r2, g = _gravity(x, p.mu)
    g5 = g / r2  # mu / r^5
    A = np.zeros(x.shape[:-1] + (N_STATES, N_STATES))
    A[..., 0, 1] = 1.0
    A[..., 2, 3] = 1.0
    A[..., 1, 0] = g5 * (3.0 * X * X - r2)
    A[..., 1, 2] = A[..., 3, 0] = 3.0 * g5 * X * Y
    A[..., 3, 2] = g5 * (3.0 * Y * Y - r2)
    return A


@checked(t=require_finite_array)
def nominal_state(t, params: OrbitParams | None = None) -> np.ndarray:
    """The circular nominal orbit at times ``t`` (s, any shape), in closed form, shape t.shape + (4,):
    ``X = r0 cos nt``, ``Xdot = -r0 n sin nt``, ``Y = r0 sin nt``, ``Ydot = r0 n cos nt``,
    ``n = sqrt(mu / r0^3)``."""
    p = params_or_default(params)
    t = np.asarray(t, dtype=float)
    a = p.n * t
    c, s = np.cos(a), np.sin(a)
    return np.stack([p.r0 * c, -p.r0 * p.n * s, p.r0 * s, p.r0 * p.n * c], axis=-1)


def nominal_trajectory(params: OrbitParams | None = None, n_samples: int | None = None) -> np.ndarray:
    """The nominal at the samples t_k = k dt, (K, 4); ``K = params.n_samples`` unless given."""
    p = params_or_default(params)
    K = p.n_samples if n_samples is None else require_int("n_samples", n_samples, minimum=1, maximum=MAX_STEPS + 1)
    return nominal_state(p.dt * np.arange(K), p)


# ---------------------------------------------------------------------------
# Stations
@checked(t=require_finite_array)
def station_angles(t, params: OrbitParams | None = None) -> np.ndarray:
    """Angles ``theta_i(t) = omegaE t + i 2 pi / n_stations`` (rad, not wrapped) of the stations
    i = 0..n_stations-1 at times ``t`` (s, any shape), shape t.shape + (n_stations,)."""
    p = params_or_default(params)
    t = np.asarray(t, dtype=float)
    return p.omegaE * t[..., None] + 2.0 * np.pi * np.arange(p.n_stations) / p.n_stations


@checked(t=require_finite_array)
def station_states(t, params: OrbitParams | None = None) -> np.ndarray:
    """States ``[Xi, Xidot, Yi, Yidot]`` (km, km/s) of the stations at times ``t`` (s, any shape), shape
    t.shape + (n_stations, 4): ``Xi = RE cos theta_i``, ``Xidot = -RE omegaE sin theta_i``, and so on."""
    p = params_or_default(params)
    th = station_angles.__wrapped__(t, p)  # t is checked already
    c, s = np.cos(th), np.sin(th)
    return np.stack([p.RE * c, -p.RE * p.omegaE * s, p.RE * s, p.RE * p.omegaE * c], axis=-1)


def relative_states(x, t, params: OrbitParams | None = None):
    """Satellite minus stations, ``d = x - x_i`` (..., n_stations, 4), and the station states, for states
    ``x`` (..., 4) at times ``t`` (s) broadcast with x's leading axes (neither checked: the filters' inner loop):
    the stations are computed once per distinct time (shape t.shape + (n_stations, 4)) and broadcast."""
    p = params_or_default(params)
    st = station_states.__wrapped__(t, p)
    return np.asarray(x, dtype=float)[..., None, :] - st, st


@checked(t=require_finite_array)
def visible(x, t, params: OrbitParams | None = None) -> np.ndarray:
    """Which stations see the satellite: bool (..., n_stations), ``(r - r_i) . r_i > 0`` (the line of
    sight above station i's horizon).  ``x`` (..., 4) states at times ``t`` (s, broadcast with x's
    leading axes)."""
    p = params_or_default(params)
    x = require_states("x", x)
    d, st = relative_states(x, t, p)
    return horizon(d, st)


def horizon(d, st) -> np.ndarray:
    """``(r - r_i) . r_i > 0`` from relative states ``d`` (..., n_stations, 4) and station states ``st``
    (broadcast with d): bool (..., n_stations)."""
    return d[..., 0] * st[..., 0] + d[..., 2] * st[..., 2] > 0.0


def measure_relative(d):
    """``[rho, rhodot, phi]`` (..., 3) of relative states ``d = x - x_i`` (..., 4) (satellite minus station),
    without checks (the core of :func:`measure`)."""
    dX, dVX, dY, dVY = d[..., 0], d[..., 1], d[..., 2], d[..., 3]
    rho = np.sqrt(dX * dX + dY * dY)
    out = np.empty(d.shape[:-1] + (N_STATION_MEAS,))
    out[..., 0] = rho
    out[..., 1] = (dX * dVX + dY * dVY) / rho
    out[..., 2] = np.arctan2(dY, dX)
    return out


@checked(t=require_finite_array)
def measure(x, t, params: OrbitParams | None = None) -> np.ndarray:
    """Noise-free measurements ``[rho, rhodot, phi]`` (km, km/s, rad; phi in (-pi, pi]) of every station,
    visible or not, shape (..., n_stations, 3).  ``x`` (..., 4) states at times ``t`` (s, broadcast with
    x's leading axes)."""
    p = params_or_default(params)
    x = require_states("x", x)
    d, _ = relative_states(x, t, p)
    return measure_relative(d)


@checked(t=require_finite_array)
def jacobian_C(x, t, params: OrbitParams | None = None) -> np.ndarray:
    """Measurement Jacobians ``C_i = d[rho_i, rhodot_i, phi_i]/dx`` of every station, shape
    (..., n_stations, 3, 4), at states ``x`` (..., 4) and times ``t`` (s)::

        drho/dX = dX/rho, drho/dY = dY/rho,
        drhodot/dX = (dXdot - rhodot dX/rho)/rho, drhodot/dXdot = dX/rho  (and the same in Y),
        dphi/dX = -dY/rho^2, dphi/dY = dX/rho^2,

    with ``dX = X - Xi`` and so on; stack the rows of the visible stations for the measurement matrix.
    """
    p = params_or_default(params)
    x = require_states("x", x)
    d, _ = relative_states(x, t, p)
    return jacobian_relative(d)


def jacobian_relative(d):
    """``C_i`` (..., 3, 4) at relative states ``d = x - x_i`` (..., 4), without checks (the core of
    :func:`jacobian_C`)."""
    dX, dVX, dY, dVY = d[..., 0], d[..., 1], d[..., 2], d[..., 3]
    r2 = dX * dX + dY * dY
    rho = np.sqrt(r2)
    rhodot = (dX * dVX + dY * dVY) / rho
    C = np.zeros(d.shape[:-1] + (N_STATION_MEAS, N_STATES))
    C[..., 0, 0] = dX / rho
    C[..., 0, 2] = dY / rho
    C[..., 1, 0] = (dVX - rhodot * dX / rho) / rho
    C[..., 1, 1] = dX / rho
    C[..., 1, 2] = (dVY - rhodot * dY / rho) / rho
    C[..., 1, 3] = dY / rho
    C[..., 2, 0] = -dY / r2
    C[..., 2, 2] = dX / r2
    return C


# ---------------------------------------------------------------------------
# DT model
def discretize(A, dt: float = 10.0, transition: str = "euler") -> np.ndarray:
    """DT state-transition matrix from the CT Jacobian ``A`` (..., 4, 4): ``I + dt A`` ("euler", the
    filters' choice) or ``expm(dt A)`` ("expm", its check).  The noise enters as ``Omega = dt Gamma``
    (:attr:`OrbitParams.Omega`).  dt in s."""
    dt = require_positive("dt", dt)
    transition = require_choice("transition", transition, TRANSITIONS)
    A = require_array("A", A)
    if A.ndim < 2 or A.shape[-2:] != (N_STATES, N_STATES) or not np.isfinite(A).all():
        raise ValueError(f"A must have shape (..., 4, 4) with finite entries, got {A.shape}")
    if transition == "euler":
        return np.eye(N_STATES) + dt * A
    flat = (dt * A).reshape(-1, N_STATES, N_STATES)  # one call per matrix: faster than scipy's stacked expm here
    return np.stack([expm(a) for a in flat]).reshape(A.shape)


def rk4_flow(x, dt: float, mu: float, substeps: int, push=None):
    """The RK4 map over ``dt`` (s) in ``substeps`` equal substeps of ``xdot = f(x) + push``, without checks:
    ``x`` (..., 4) float array, ``push`` (..., 4) a constant added to the derivative (``Gamma u``, an
    acceleration such as a thrust held over the step; default none).  The fast core of :func:`propagate`."""
    h = dt / substeps
    for _ in range(substeps):
        k1 = _f(x, mu, push)
        k2 = _f(x + (0.5 * h) * k1, mu, push)
        k3 = _f(x + (0.5 * h) * k2, mu, push)
        k4 = _f(x + h * k3, mu, push)
        x = x + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
    return x


def propagate(x, params: OrbitParams | None = None, dt: float | None = None,
              substeps: int = PROPAGATION_SUBSTEPS) -> np.ndarray:
    """The filters' noise-free one-step map ``f_d``: classical RK4 over ``dt`` (s, default ``params.dt``)
    in ``substeps`` substeps, on states ``x`` (..., 4); returns (..., 4).

    Deterministic and vectorised over leading axes (so batched and per-run filters agree to rounding).
    With the defaults (5 s substeps) it agrees with the closed-form nominal to better than 1e-7 km per step
    (``tests/test_orbit_model.py``), far below the process noise's 1e-3 km per step.
    """
    p = params_or_default(params)
    x = require_states("x", x)
    dt = p.dt if dt is None else require_positive("dt", dt)
    return rk4_flow(x, dt, p.mu, require_int("substeps", substeps, minimum=1, maximum=MAX_SUBSTEPS))


def wrap_phi(z) -> np.ndarray:
    """Copy of station measurements ``z`` (..., 3) with phi wrapped to (-pi, pi]."""
    z = np.array(require_finite_array("z", z, shape=(..., N_STATION_MEAS), allow_nan=True))
    z[..., PHI] = wrap_angle(z[..., PHI])
    return z


@functools.lru_cache(maxsize=None)
def measurement_layout(m: int) -> AngleLayout:
    """The layout of ``m`` stations' measurements stacked, ``[rho_1, rhodot_1, phi_1, rho_2, ...]`` (3m,):
    phi at positions 2, 5, ... (its wrap, residual ``a - b`` and circular mean, for the filters)."""
    return AngleLayout(N_STATION_MEAS * m, tuple(range(PHI, N_STATION_MEAS * m, N_STATION_MEAS)))


def stacked_measurement(x, t, stations, params: OrbitParams | None = None) -> np.ndarray:
    """Noise-free measurements of the stations ``stations`` (0-based indices, in that order) stacked,
    shape (..., 3m) (km, km/s, rad; phi wrapped), at states ``x`` (..., 4) and time ``t`` (s)."""
    ids = np.asarray(stations, dtype=int)
    return measure(x, t, params)[..., ids, :].reshape(np.shape(x)[:-1] + (N_STATION_MEAS * ids.size,))


def stacked_jacobian(x, t, stations, params: OrbitParams | None = None) -> np.ndarray:
    """Jacobian (..., 3m, 4) of :func:`stacked_measurement`: the rows ``C_i`` of the stations
    ``stations`` in that order."""
    ids = np.asarray(stations, dtype=int)
    C = jacobian_C(x, t, params)[..., ids, :, :]
    return C.reshape(np.shape(x)[:-1] + (N_STATION_MEAS * ids.size, N_STATES))
