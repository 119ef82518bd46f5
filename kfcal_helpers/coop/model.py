"""Cooperative-localization model: parameters, dynamics, measurements, Jacobians.

State ``x = [xi_g, eta_g, theta_g, xi_a, eta_a, theta_a]`` (m, m, rad, m, m, rad):
east, north and heading of the ground vehicle (UGV) and of the aerial vehicle
(UAV).  Control ``u = [v_g, phi_g, v_a, omega_a]`` (m/s, rad, m/s, rad/s).
Measurement ``y = [bearing UGV->UAV - theta_g, range, bearing UAV->UGV - theta_a,
xi_a, eta_a]`` (rad, m, rad, m, m), angles wrapped to (-pi, pi].

Headings in states returned by this module are wrapped to (-pi, pi] as well.
Every function accepts arrays with leading axes: ``x`` of shape (..., 6),
``u`` of shape (..., 4) or (4,).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ..angles import AngleLayout, weighted_mean, wrap_angle, wrap_components
from ..montecarlo import BASE_BYTES, MEMORY_LIMIT
from ..validation import (checked, describe, optional, require_array, require_choice, require_covariance, require_finite_array, require_instance, require_int,
                          require_positive, require_shape)

__all__ = [
    "N_STATES",
    "N_MEAS",
    "STATE_ANGLES",
    "MEAS_ANGLES",
    "STATE_LABELS",
    "StateDescriptor",
    "STATE",
    "MeasurementModel",
    "require_indices",
    "MEAS_LABELS",
    "NOISE_MODELS",
    "MAX_MEASUREMENT",
    "RUN_BYTES_PER_STEP",
    "BASE_BYTES",
    "MAX_STEPS",
    "MAX_PARAMS_STEPS",
    "run_bytes",
    "too_many_steps",
    "CoopParams",
    "require_last_axis",
    "wrap_angle",
    "wrap_state",
    "wrap_measurement",
    "state_add",
    "state_mean",
    "measurement_mean",
    "state_residual",
    "measurement_residual",
    "dynamics",
    "arc",
    "step",
    "nominal_trajectory",
    "measure",
    "jacobian_A",
    "jacobian_B",
    "jacobian_C",
    "jacobian_step",
    "discretize",
    "observability_matrix",
]

N_STATES = 6
N_MEAS = 5
#: indices of the angle components of the state (headings) and of the measurement (bearings)
STATE_ANGLES = (2, 5)
MEAS_ANGLES = (0, 2)
#: plot labels with units
STATE_LABELS = (r"$\xi_g$ [m]", r"$\eta_g$ [m]", r"$\theta_g$ [rad]",
                r"$\xi_a$ [m]", r"$\eta_a$ [m]", r"$\theta_a$ [rad]")
MEAS_LABELS = (r"bearing UGV$\to$UAV [rad]", "range [m]", r"bearing UAV$\to$UGV [rad]",
               r"UAV east $\xi_a$ [m]", r"UAV north $\eta_a$ [m]")


#: how the DT process noise w_k ~ N(0, Q) enters the state, x_{k+1} = f_d(x_k, u_k) + Omega w_k:
#: "dt" -- Omega = dt * I (the course's model: w_k is a noise on the rates held constant over the step, so
#: the Euler step x_k + dt (f(x_k, u_k) + w_k) gives Omega = dt I and per-step state noise dt^2 Q);
#: "identity" -- Omega = I (per-step state noise Q itself, a known mistake kept as a named variant)
NOISE_MODELS = ("dt", "identity")

#: largest magnitude accepted in measurements (m, rad): beyond it the filters' squares overflow
MAX_MEASUREMENT = 1e6
#: largest variance accepted in Qtrue and Rtrue (a standard deviation of MAX_MEASUREMENT): beyond it the NIS
#: of any log is a vanishing number (1e300 * I gave 1e-296), not a test
MAX_VARIANCE = MAX_MEASUREMENT ** 2

#: bytes one filter run keeps per step (float64 counts): the stored x_prior, x_post (6 + 6), P_prior,
#: P_post (36 + 36), z_pred, y (5 + 5), S (25) and K (30); the result's NIS, NEES, t and the copies of
#: y and S at the steps with a measurement (3 + 30); the log's t and y (6); the LKF's nominal states,
#: F and H (6 + 36 + 30).  (Measured with ``coop --log``: 1475 bytes per step for the EKF and UKF,
#: 2075 for the LKF.)
RUN_BYTES_PER_STEP = 8 * (149 + 33 + 6 + 72)
#: bytes a single filter run (``coop --log``) counts beside its steps: the interpreter (the Monte Carlo
#: core's BASE_BYTES) and 20 MB more, the margin of the measurement that set this budget (so MAX_STEPS,
#: which the refusals of a long log quote, is unchanged)
_RUN_BASE_BYTES = BASE_BYTES + 20e6
#: the most steps (samples) a run may have: one filter run of them fits in the 500 MB memory limit
#: (kfcal_helpers.montecarlo.MEMORY_LIMIT) after _RUN_BASE_BYTES
MAX_STEPS = int((MEMORY_LIMIT - _RUN_BASE_BYTES) // RUN_BYTES_PER_STEP)


#: the most steps a CoopParams may describe (duration / dt): beyond it the states of one run alone would
#: take more than 48 GB, and the step count is no longer an exact integer in float arithmetic far beyond
MAX_PARAMS_STEPS = 10**9


def run_bytes(n_steps: int) -> float:
    """Estimated peak memory (bytes) of one filter run over ``n_steps`` samples, interpreter included."""
    return _RUN_BASE_BYTES + RUN_BYTES_PER_STEP * float(n_steps)


def too_many_steps(name: str, n_steps) -> str:
    """The message refusing a run of ``n_steps`` samples (> MAX_STEPS), naming ``name``."""
    return (f"{name}: {n_steps:.0f} steps, more than the {MAX_STEPS} allowed: one filter run of them would need "
            f"about {run_bytes(n_steps) / 1e6:.0f} MB ({RUN_BYTES_PER_STEP} bytes per step), more than the "
            f"{MEMORY_LIMIT / 1e6:.0f} MB memory limit; use fewer steps")


def _diag(*values):
    return field(default_factory=lambda: np.diag(np.array(values, dtype=float)))


def _vector(*values):
    return field(default_factory=lambda: np.array(values, dtype=float))


@dataclass(frozen=True, eq=False)
class CoopParams:
    """All inputs of the cooperative-localization problem, validated on construction.

    Defaults are the course's: ``L = 0.5 m``, ``dt = 0.1 s``, 100 s, nominal
    ``x0 = [10, 0, pi/2, -60, 0, -pi/2]``, ``u0 = [2, -pi/18, 12, pi/25]``,
    noise covariances ``Qtrue`` (6x6, of the DT process noise ``w_k``) and ``Rtrue`` (5x5).

    ``Qtrue`` is the covariance of ``w_k``, a noise on the rates ((m/s)^2 in the positions, (rad/s)^2
    in the headings), ``xdot = f(x, u) + Gamma w`` with ``Gamma = I``, held constant over each step; it
    is not the covariance of the state's noise per step.  ``noise_model`` says how ``w_k`` enters the
    state, ``x_{k+1} = f_d(x_k, u_k) + Omega w_k``: ``"dt"`` (default, the course's model) has
    ``Omega = dt * Gamma`` -- the Euler step ``x_k + dt (f(x_k, u_k) + Gamma w_k)`` of the held noise --
    so the state receives noise of covariance ``Omega Qtrue Omega^T = dt^2 Qtrue`` per step;
    ``"identity"`` has ``Omega = I`` (a state noise of covariance ``Qtrue`` itself per step, a named
    variant for the mistake of notebook 14).  The truth simulation and
    every filter use the same ``Omega`` (:meth:`process_noise`).
    ``P0`` (6x6) is the covariance of the initial state about ``x0``: the truth-model
    tests draw the true initial state from N(x0, P0) and every filter starts at
    (x0, P0).  Arrays are stored read-only.  ``duration / dt`` must be a whole number of steps, at most
    :data:`MAX_PARAMS_STEPS` (1e9); runs refuse far fewer by their memory estimates (a filter run: more
    than :data:`MAX_STEPS`; the Monte Carlo: its own estimate).
    """

    L: float = 0.5  #: UGV wheelbase, m
    dt: float = 0.1  #: sampling interval, s
    duration: float = 100.0  #: length of a run, s
    x0: np.ndarray = _vector(10.0, 0.0, np.pi / 2, -60.0, 0.0, -np.pi / 2)  #: nominal initial state
    u0: np.ndarray = _vector(2.0, -np.pi / 18, 12.0, np.pi / 25)  #: nominal (constant) control
    #: covariance of w_k, the rate noise held over a step, (m/s)^2 and (rad/s)^2 (state per step: Omega Qtrue Omega^T)
    Qtrue: np.ndarray = _diag(0.001, 0.001, 0.01, 0.001, 0.001, 0.01)
    Rtrue: np.ndarray = _diag(0.0225, 64.0, 0.04, 36.0, 36.0)  #: measurement noise
    P0: np.ndarray = _diag(1.0, 1.0, 0.01, 1.0, 1.0, 0.01)  #: initial covariance (m^2, rad^2)
    noise_model: str = "dt"  #: how w_k enters the state: "dt" (Omega = dt I) or "identity" (Omega = I)

    def __post_init__(self):
        require_choice("noise_model", self.noise_model, NOISE_MODELS)
        for name in ("L", "dt", "duration"):
            object.__setattr__(self, name, require_positive(name, getattr(self, name)))
        steps = self.duration / self.dt
        if not steps <= MAX_PARAMS_STEPS:  # also inf (dt = 5e-324)
            raise ValueError(f"duration / dt must be at most {MAX_PARAMS_STEPS:.0e} steps, got {self.duration:g} s / "
                             f"{self.dt:g} s = {steps:.3g} steps")
        if abs(steps - round(steps)) > 1e-9 * max(steps, 1.0) or round(steps) < 1:
            raise ValueError(f"duration must be a whole number (>= 1) of dt = {self.dt:g} s, got {self.duration:g} s")
        arrays = {
            "x0": require_shape("x0", self.x0, (N_STATES,)),
            "u0": require_shape("u0", self.u0, (4,)),
            "Qtrue": require_covariance("Qtrue", self.Qtrue, N_STATES, MAX_VARIANCE),
            "Rtrue": require_covariance("Rtrue", self.Rtrue, N_MEAS, MAX_VARIANCE),
            "P0": require_covariance("P0", self.P0, N_STATES),
        }
        for name in ("x0", "u0"):
            if not np.all(np.isfinite(arrays[name])):
                raise ValueError(f"{name} must hold only finite numbers")
        if abs(np.cos(arrays["u0"][1])) < 1e-9:
            raise ValueError("u0 steering angle phi_g must not be +-pi/2 (tan is infinite)")
        for name, arr in arrays.items():
            arr = arr.copy()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n_samples(self) -> int:
        """Number of samples t_k = k dt, k = 0..n_samples-1 (1001 for the defaults)."""
        return int(round(self.duration / self.dt)) + 1

    @property
    def t(self) -> np.ndarray:
        """Sample times, s, shape (n_samples,)."""
        return self.dt * np.arange(self.n_samples)

    @property
    def Omega(self) -> np.ndarray:
        """Noise input matrix ``Omega`` (6x6): ``dt * I`` for ``noise_model="dt"``, ``I`` for "identity"."""
        scale = self.dt if self.noise_model == "dt" else 1.0
        return scale * np.eye(N_STATES)

    def process_noise(self, Q=None) -> np.ndarray:
        """Per-step state-noise covariance ``Omega Q Omega^T`` (6x6) for the covariance ``Q`` of
        ``w_k`` (default ``Qtrue``)."""
        Q = self.Qtrue if Q is None else require_covariance("Q", Q, N_STATES)
        Om = self.Omega
        return Om @ Q @ Om.T


def require_last_axis(name: str, array, n: int) -> np.ndarray:
    """Return ``array`` as a float ndarray; raise unless its shape is (..., n) with finite entries."""
    arr = require_array(name, array)
    if arr.ndim < 1 or arr.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must hold only finite numbers")
    return arr


#: argument checks of the public functions (validation.checked): states (..., 6),
#: controls (..., 4), sigma points (..., m, 6) or (..., m, 5) and their weights (m,), finite numbers; matrices
_STATES = partial(require_finite_array, shape=(..., 6))
_CONTROLS = partial(require_finite_array, shape=(..., 4))
_STATE_POINTS = partial(require_finite_array, shape=(..., None, 6))
_MEASUREMENT_POINTS = partial(require_finite_array, shape=(..., None, 5))
_WEIGHTS = partial(require_finite_array, shape=(None,))
#: elementwise arithmetic (wrapping, residuals, sums) lets NaN through as NaN: a missing value stays missing
_STATES_OR_NAN = partial(require_finite_array, shape=(..., 6), allow_nan=True)
_ANGLES_OR_NAN = require_array
_MATRICES = partial(require_finite_array, shape=(..., None, None))


def _pair_shape(a, b, n: int, what: str, exact: bool, names=("a", "b")) -> None:
    """Raise naming ``a`` or ``b`` (as ``names``) unless the two arrays broadcast to (..., n) (``exact``) or
    (..., m), m <= n (the first m components: a residual of the bearings and the range alone is one)."""
    try:
        shape = np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise ValueError(f"{names[0]} and {names[1]} must broadcast together, got shapes {a.shape} and "
                         f"{b.shape}") from None
    if len(shape) >= 1 and (shape[-1] == n if exact else 1 <= shape[-1] <= n):
        return
    first = a.shape == shape or not b.shape
    want = f"(..., {n})" if exact else f"(..., m) with m <= {n}"
    raise ValueError(f"{names[0 if first else 1]} must be {what} of shape {want}, got shape "
                     f"{(a if first else b).shape}")


# ---------------------------------------------------------------------------
# Angles
# the angle components as basic slices (much faster than index lists in the filters' inner loops)
_STATE_ANGLE_SLICE = slice(2, 6, 3)  # STATE_ANGLES
_MEAS_ANGLE_SLICE = slice(0, 3, 2)  # MEAS_ANGLES


@checked(x=_STATES_OR_NAN)
def wrap_state(x):
    """Copy of states ``x`` (..., 6) with the headings wrapped to (-pi, pi]; ValueError for another shape."""
    x = np.asarray(x, dtype=float)
    if x.ndim < 1 or x.shape[-1] != N_STATES:
        raise ValueError(f"x must have shape (..., {N_STATES}), got {x.shape}")
    return wrap_components(x, _STATE_ANGLE_SLICE)


@checked(y=partial(require_finite_array, shape=(..., 5), allow_nan=True))
def wrap_measurement(y):
    """Copy of measurements ``y`` (..., 5) with the bearings wrapped to (-pi, pi]."""
    return wrap_components(y, _MEAS_ANGLE_SLICE)


@checked(x=_ANGLES_OR_NAN, dx=_ANGLES_OR_NAN)
def state_add(x, dx):
    """``x + dx`` for states (..., 6), headings wrapped (the UKF's ``state_add``); ``dx`` may be anything
    that broadcasts against ``x``."""
    _pair_shape(x, dx, N_STATES, "states", exact=True, names=("x", "dx"))
    return wrap_components(np.add(x, dx, dtype=float), _STATE_ANGLE_SLICE, copy=False)


@checked(sigmas=_STATE_POINTS, weights=_WEIGHTS)
def state_mean(sigmas, weights):
    """Weighted mean of state points (..., m, 6) with weights (m,); headings by circular mean."""
    return weighted_mean(sigmas, weights, _STATE_ANGLE_SLICE)


@checked(sigmas=_MEASUREMENT_POINTS, weights=_WEIGHTS)
def measurement_mean(sigmas, weights):
    """Weighted mean of measurement points (..., m, 5); bearings by circular mean."""
    return weighted_mean(sigmas, weights, _MEAS_ANGLE_SLICE)


@checked(a=_ANGLES_OR_NAN, b=_ANGLES_OR_NAN)
def state_residual(a, b):
    """``a - b`` for states (..., 6) with the heading differences wrapped (rad); ``b`` may be anything that
    broadcasts against ``a``."""
    _pair_shape(a, b, N_STATES, "states", exact=True)
    return wrap_components(np.subtract(a, b, dtype=float), _STATE_ANGLE_SLICE, copy=False)


@checked(a=_ANGLES_OR_NAN, b=_ANGLES_OR_NAN)
def measurement_residual(a, b):
    """``a - b`` for measurements (..., 5) (or their first m components) with the bearing differences
    wrapped (rad); ``b`` may be a scalar or anything that broadcasts against ``a``."""
    _pair_shape(a, b, N_MEAS, "measurements", exact=False)
    return wrap_components(np.subtract(a, b, dtype=float), _MEAS_ANGLE_SLICE, copy=False)


#: the layout of a vector with angle components (its wrap, residual, add and circular mean), shared with
#: the other problems
StateDescriptor = AngleLayout


#: the coop state [xi_g, eta_g, theta_g, xi_a, eta_a, theta_a]: headings 2 and 5 are angles
STATE = StateDescriptor(N_STATES, STATE_ANGLES, STATE_LABELS)


# ---------------------------------------------------------------------------
# Dynamics
def _controls(u, L):
    u = np.asarray(u, dtype=float)
    vg, phi, va, wa = u[..., 0], u[..., 1], u[..., 2], u[..., 3]
    return vg, vg * np.tan(phi) / L, va, wa


def dynamics(x, u, L: float = 0.5):
    """Continuous-time dynamics ``f(x, u)`` without noise, shape (..., 6) (m/s, rad/s).
    ValueError unless x is (..., 6) and u (..., 4) with finite entries."""
    x = require_last_axis("x", x, N_STATES)
    u = require_last_axis("u", u, 4)
    L = require_positive("L", L)
    vg, wg, va, wa = _controls(u, L)
    return np.stack(np.broadcast_arrays(vg * np.cos(x[..., 2]), vg * np.sin(x[..., 2]), wg,
                                        va * np.cos(x[..., 5]), va * np.sin(x[..., 5]), wa), axis=-1)


@checked(x=_STATES, u=_CONTROLS, dt=require_finite_array, L=require_positive)
def arc(x, u, dt, L):
    """Closed-form flow of f over ``dt`` (s, scalar or array broadcast with x's leading axes), without
    checks: ``x`` (..., 6) and ``u`` (..., 4) float arrays, ``L > 0`` (the fast core of :func:`step`)."""
    vg, wg, va, wa = _controls(u, L)
    shape = np.broadcast_shapes(x.shape[:-1], np.shape(dt), np.shape(vg))
    out = np.empty(shape + (N_STATES,))
    for i, v, w in ((0, vg, wg), (3, va, wa)):
        th = x[..., i + 2]
        half = 0.5 * w * dt
        # chord of the arc: v dt sinc(w dt / 2) along the mean heading th + w dt / 2;
        # np.sinc(z) = sin(pi z)/(pi z) is exact for the straight line w = 0.
        d = v * dt * np.sinc(half / np.pi)
        mid = th + half
        out[..., i] = x[..., i] + d * np.cos(mid)
        out[..., i + 1] = x[..., i + 1] + d * np.sin(mid)
        out[..., i + 2] = mid + half
    return wrap_components(out, _STATE_ANGLE_SLICE, copy=False)


def step(x, u, dt: float = 0.1, L: float = 0.5):
    """Exact noise-free one-step map for a control held constant over ``dt`` (s).

    Each vehicle moves on a circular arc (yaw rate ``v_g tan(phi_g)/L`` for the UGV,
    ``omega_a`` for the UAV), or on a straight line when its yaw rate is zero.

    Parameters
    ----------
    x : array (..., 6)   states at t
    u : array (..., 4) or (4,)   controls held over [t, t + dt]
    dt, L : float > 0   step, s; wheelbase, m

    Returns
    -------
    array (..., 6): states at t + dt, headings wrapped.
    """
    return arc(require_last_axis("x", x, N_STATES), require_last_axis("u", u, 4),
                require_positive("dt", dt), require_positive("L", L))


@checked(params=optional(partial(require_instance, cls=CoopParams)))
def nominal_trajectory(params: CoopParams | None = None, n_samples: int | None = None) -> np.ndarray:
    """Nominal states at t_k = k dt from the closed-form arcs (no integration), shape (K, 6).

    ``K = params.n_samples`` unless ``n_samples`` is given.
    """
    p = params if params is not None else CoopParams()
    K = p.n_samples if n_samples is None else require_int("n_samples", n_samples, minimum=1, maximum=MAX_STEPS)
    t = p.dt * np.arange(K)
    out = arc(np.broadcast_to(p.x0, (t.size, N_STATES)), p.u0, t, p.L)
    out[0] = wrap_state(p.x0)
    return out


# ---------------------------------------------------------------------------
# Measurements
def _relative(x):
    x = np.asarray(x, dtype=float)
    dxi, deta = x[..., 3] - x[..., 0], x[..., 4] - x[..., 1]
    r2 = dxi * dxi + deta * deta
    if np.any(r2 == 0):
        raise ValueError("x: the two vehicles are at the same position (range 0): bearings and their Jacobian are undefined")
    return x, dxi, deta, r2


@checked(x=_STATES)
def measure(x) -> np.ndarray:
    """Noise-free measurement ``h(x)``, shape (..., 5): rad, m, rad, m, m (bearings wrapped)."""
    x, dxi, deta, r2 = _relative(x)
    y = np.empty(x.shape[:-1] + (N_MEAS,))
    bearing = np.arctan2(deta, dxi)
    y[..., 0] = bearing - x[..., 2]
    y[..., 1] = np.sqrt(r2)
    y[..., 2] = bearing + np.pi - x[..., 5]  # atan2(-deta, -dxi) = atan2(deta, dxi) + pi (mod 2 pi)
    y[..., 3:5] = x[..., 3:5]
    return wrap_components(y, _MEAS_ANGLE_SLICE, copy=False)


# ---------------------------------------------------------------------------
# Jacobians
@checked(x=_STATES, u=_CONTROLS, L=require_positive)
def jacobian_A(x, u, L: float = 0.5) -> np.ndarray:
    """CT state Jacobian ``A = df/dx`` at (x, u), shape (..., 6, 6) (1/s and m/(s rad))."""
    x = np.asarray(x, dtype=float)
    vg, _, va, _ = _controls(u, require_positive("L", L))
    A = np.zeros(np.broadcast_shapes(x.shape[:-1], np.shape(vg)) + (6, 6))
    A[..., 0, 2] = -vg * np.sin(x[..., 2])
    A[..., 1, 2] = vg * np.cos(x[..., 2])
    A[..., 3, 5] = -va * np.sin(x[..., 5])
    A[..., 4, 5] = va * np.cos(x[..., 5])
    return A


@checked(x=_STATES, u=_CONTROLS, L=require_positive)
def jacobian_B(x, u, L: float = 0.5) -> np.ndarray:
    """CT input Jacobian ``B = df/du`` at (x, u), shape (..., 6, 4)."""
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    L = require_positive("L", L)
    vg, phi = u[..., 0], u[..., 1]
    B = np.zeros(np.broadcast_shapes(x.shape[:-1], u.shape[:-1]) + (6, 4))
    B[..., 0, 0] = np.cos(x[..., 2])
    B[..., 1, 0] = np.sin(x[..., 2])
    B[..., 2, 0] = np.tan(phi) / L
    B[..., 2, 1] = vg / (L * np.cos(phi) ** 2)
    B[..., 3, 2] = np.cos(x[..., 5])
    B[..., 4, 2] = np.sin(x[..., 5])
    B[..., 5, 3] = 1.0
    return B


def jacobian_C(x) -> np.ndarray:
    """Measurement Jacobian ``C = dh/dx`` at x (..., 6), shape (..., 5, 6); ValueError for another
    shape, a non-finite entry, or at range 0."""
    x, dxi, deta, r2 = _relative(require_last_axis("x", x, N_STATES))
    r = np.sqrt(r2)
    C = np.zeros(x.shape[:-1] + (N_MEAS, N_STATES))
    for row in (0, 2):  # both bearings have the same position derivatives
        C[..., row, 0] = deta / r2
        C[..., row, 1] = -dxi / r2
        C[..., row, 3] = -deta / r2
        C[..., row, 4] = dxi / r2
    C[..., 0, 2] = -1.0
    C[..., 2, 5] = -1.0
    C[..., 1, 0] = -dxi / r
    C[..., 1, 1] = -deta / r
    C[..., 1, 3] = dxi / r
    C[..., 1, 4] = deta / r
    C[..., 3, 3] = 1.0
    C[..., 4, 4] = 1.0
    return C


def require_indices(name: str, value, n: int, what: str = "") -> tuple[int, ...]:
    """``value`` as a sorted tuple of distinct integers in 0..n-1 (a non-empty sequence, in any order);
    ValueError naming ``name`` (and ``what`` they index, if given) otherwise."""
    allowed = f"{name} must be a non-empty sequence of distinct integers in 0..{n - 1}{what}"
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{allowed}, got {describe(value)}")
    try:
        items = list(value)
    except TypeError:
        raise ValueError(f"{allowed}, got {describe(value)}") from None
    ok = all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) and 0 <= i < n for i in items)
    if not items or not ok or len({int(i) for i in items}) != len(items):
        raise ValueError(f"{allowed}, got {describe(value)}")
    return tuple(sorted(int(i) for i in items))


@dataclass(frozen=True, eq=False)
class MeasurementModel:
    """The measurement model of a filter: ``h``, its Jacobian, which components are bearings, and ``R``.

    ``rows`` are the rows of the full measurement ``y = [bearing UGV->UAV, range, bearing UAV->UGV,
    UAV east, UAV north]`` (0..4) this model measures, in that order; the default is all five.
    :meth:`subset` gives the model of some of its rows (the matching rows of h and of its Jacobian,
    the block of R).  Every method takes states with leading axes, ``x`` of shape (..., 6).

    R : (m, m) measurement-noise covariance of the rows used (m = ``len(rows)``)
    rows : sorted tuple of distinct integers in 0..4
    """

    R: np.ndarray
    rows: tuple = tuple(range(N_MEAS))

    def __post_init__(self):
        rows = self.rows
        ok = (not isinstance(rows, (str, bytes)) and hasattr(rows, "__len__") and len(rows) > 0
              and all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) and 0 <= i < N_MEAS
                      for i in rows))
        if not ok or list(rows) != sorted({int(i) for i in rows}):
            raise ValueError(f"rows must be a sorted non-empty tuple of distinct integers in 0..4, got {describe(rows)}")
        rows = tuple(int(i) for i in rows)
        R = require_covariance("R", self.R, len(rows)).copy()
        R.setflags(write=False)
        object.__setattr__(self, "rows", rows)
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "_all", rows == tuple(range(N_MEAS)))
        object.__setattr__(self, "_angles", StateDescriptor(len(rows), self.angles))

    @property
    def dim(self) -> int:
        """Number of measured components m."""
        return len(self.rows)

    @property
    def angles(self) -> tuple:
        """Positions (within ``rows``) of the bearings, which are wrapped."""
        return tuple(j for j, i in enumerate(self.rows) if i in MEAS_ANGLES)

    @property
    def labels(self) -> tuple:
        """Plot labels of the components measured."""
        return tuple(MEAS_LABELS[i] for i in self.rows)

    def subset(self, idx) -> "MeasurementModel":
        """The model of the components ``idx`` (positions in this model's ``rows``, e.g. ``(0, 1, 2)``
        for the two bearings and the range of the full model); ValueError if malformed."""
        idx = list(require_indices("idx", idx, self.dim))
        return MeasurementModel(self.R[np.ix_(idx, idx)], tuple(self.rows[i] for i in idx))

    def h(self, x) -> np.ndarray:
        """Noise-free measurement of the rows used, shape (..., m), bearings wrapped."""
        return measure(x) if self._all else measure(x)[..., self.rows]

    def jacobian(self, x) -> np.ndarray:
        """Jacobian of :meth:`h`, shape (..., m, 6)."""
        return jacobian_C(x) if self._all else jacobian_C(x)[..., self.rows, :]

    def wrap(self, z) -> np.ndarray:
        """Copy of measurements ``z`` (..., m) with the bearings wrapped."""
        return self._angles.wrap(z)

    def residual(self, a, b) -> np.ndarray:
        """``a - b`` for measurements (..., m) with the bearing differences wrapped."""
        return self._angles.residual(a, b)

    def mean(self, points, weights) -> np.ndarray:
        """Weighted mean of measurement points (..., k, m): circular for the bearings (the UKF's ``z_mean_fn``)."""
        return self._angles.mean(points, weights)


def jacobian_step(x, u, dt: float = 0.1, L: float = 0.5) -> np.ndarray:
    """Exact DT state Jacobian ``d step(x, u) / dx`` of the closed-form one-step map, shape (..., 6, 6).

    The identity plus, for each vehicle, the heading column ``d [-sin(m), cos(m)]`` with ``d`` the
    chord ``v dt sinc(w dt / 2)`` and ``m = theta + w dt / 2`` its direction.  ``I + dt A`` is the
    Jacobian of the Euler map ``x + dt f(x)`` (chord ``v dt`` along ``theta``): both agree to first order
    in ``dt``.  Along the arcs of :func:`step` (the nominal of :func:`nominal_trajectory`) only this one
    is the derivative of the map that generated the trajectory: it carries a rotation of the scene at
    ``x_k`` into the rotation at ``x_{k+1}`` exactly, while ``I + dt A`` carries it to the rotation at the
    Euler point ``x_k + dt f(x_k)``, which misses ``x_{k+1}`` by O(dt^2).
    """
    x = require_last_axis("x", x, N_STATES)
    u = require_last_axis("u", u, 4)
    dt, L = require_positive("dt", dt), require_positive("L", L)
    vg, wg, va, wa = _controls(u, L)
    J = np.zeros(np.broadcast_shapes(x.shape[:-1], np.shape(vg)) + (6, 6))
    J[...] = np.eye(N_STATES)
    for i, v, w in ((0, vg, wg), (3, va, wa)):
        half = 0.5 * w * dt
        d = v * dt * np.sinc(half / np.pi)
        mid = x[..., i + 2] + half
        J[..., i, i + 2] = -d * np.sin(mid)
        J[..., i + 1, i + 2] = d * np.cos(mid)
    return J


@checked(A=partial(require_finite_array, shape=(N_STATES, N_STATES)),
         B=partial(require_finite_array, shape=(N_STATES, 4)),
         C=partial(require_finite_array, shape=(None, N_STATES)), dt=require_positive)
def discretize(A, B, C, dt: float = 0.1):
    """DT matrices ``F = I + dt A``, ``G = dt B``, ``H = C`` (A^2 = 0 for this model, so F = expm(A dt)):
    A (6, 6), B (6, 4), C (m, 6) finite."""
    dt = require_positive("dt", dt)
    A = np.asarray(A, dtype=float)
    return np.eye(A.shape[-1]) + dt * A, dt * np.asarray(B, dtype=float), np.asarray(C, dtype=float)


@checked(F=_MATRICES, H=_MATRICES)
def observability_matrix(F, H) -> np.ndarray:
    """Stacked observability matrix of a time-varying model over a window of m steps.

    ``O = [H_0; H_1 F_0; H_2 F_1 F_0; ...; H_{m-1} F_{m-2} ... F_0]``.

    Parameters
    ----------
    F : array (m-1, n, n) or (m, n, n)   transition matrices F_k (the last one unused if m)
    H : array (m, p, n)                   measurement matrices H_k

    Returns
    -------
    array (m p, n)
    """
    F = np.asarray(F, dtype=float)
    H = np.asarray(H, dtype=float)
    if H.ndim != 3 or F.ndim != 3 or F.shape[1:] != (H.shape[2], H.shape[2]) or F.shape[0] < H.shape[0] - 1:
        raise ValueError(f"F must have shape (m-1, n, n) and H (m, p, n); got F {F.shape}, H {H.shape}")
    Phi = np.eye(H.shape[2])
    blocks = []
    for k in range(H.shape[0]):
        blocks.append(H[k] @ Phi)
        if k < H.shape[0] - 1:
            Phi = F[k] @ Phi
    return np.vstack(blocks)
