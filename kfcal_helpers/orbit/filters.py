"""LKF, EKF and UKF for orbit determination, on filterpy's classes, with a measurement whose size changes
from step to step.

The measurements of a run are dense, ``y`` of shape (K, n_stations, 3): station i's ``[rho, rhodot, phi]``
(km, km/s, rad) at t_k, or NaN where it has none.  At step k the filter uses the stations with a
measurement, ``ids_k`` (0-based, increasing), stacked: ``z_k`` (3 m_k,) with ``R_k = blockdiag(R, ..., R)``
(3 m_k, 3 m_k) and the rows ``C_i`` stacked.  A step without a station is predict only (``m_k = 0``).
Every filter starts at (x0, P0) at t_0 and, for k = 1..K-1, predicts to t_k and then updates with the
stations of step k (a measurement at t_0 updates the initial estimate).  The process noise ``w_k``
(covariance Q, (km/s^2)^2) enters as ``P- = F P F^T + Omega Q Omega^T``, ``Omega = dt Gamma``.

* LKF -- ``filterpy.kalman.KalmanFilter`` on ``dx = x - x_nom`` about the circular nominal, with
  ``F_k = I + dt A(x_nom_k)`` (or ``expm``) and ``H_k`` the stacked ``C_i(x_nom_k, t_k)``; the innovation
  ``(y - y_nom) - H dx-`` has its phi wrapped (fed as ``z = H dx- + wrapped innovation``, so filterpy's
  ``z - H x`` is the wrapped one); ``update(z, R=R_k, H=H_k)`` takes the size of step k.
* EKF -- ``filterpy.kalman.ExtendedKalmanFilter`` (:class:`OrbitEKF`) whose ``predict_x`` sets
  ``F = I + dt A(x+)`` at the posterior and moves the mean with the RK4 map
  (:func:`~kfcal_helpers.orbit.model.propagate`); ``update(z, HJacobian, Hx, R=R_k, args=(t, ids),
  hx_args=(t, ids), residual=...)`` with phi wrapped.
* UKF -- ``filterpy.kalman.UnscentedKalmanFilter`` (vectorised over sigma points,
  :class:`~kfcal_helpers.unscented.VectorizedUKF`) with ``MerweScaledSigmaPoints``; the size is per call:
  ``update(z, R=R_k, hx=h of the stations of step k)``, with ``ukf._dim_z`` set to ``3 m_k`` (filterpy
  2.0's UKF reads ``_dim_z`` only when ``z`` is None or R a scalar, and rebuilds ``sigmas_h`` on every
  update); ``z_mean_fn`` (circular for phi) and ``residual_z`` (phi wrapped) take any stacked length.
  P is symmetrized after every predict and update.

Results (:class:`FilterResult`) carry filterpy's names per step: ``x_prior, P_prior, x_post, P_post``
arrays and, as tuples of K arrays of the step's size, ``y`` (3 m_k,), ``S`` (3 m_k, 3 m_k), ``K`` (4, 3 m_k);
with ``nis`` (K,) (NaN without a measurement), ``nees`` (K,) and ``dof`` (K,) = 3 m_k.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter, MerweScaledSigmaPoints

from ..consistency import nees as _nees
from ..unscented import VectorizedUKF, robust_sqrt
from ..validation import require_choice, require_covariance, require_finite, require_instance, require_int, require_shape
from .model import (
    MAX_SUBSTEPS,
    PROPAGATION_SUBSTEPS,
    TRANSITIONS,
    discretize,
    jacobian_A,
    measurement_layout,
    nominal_trajectory,
    params_or_default,
    require_states,
    rk4_flow,
    stacked_jacobian,
    stacked_measurement,
)
from .params import N_NOISE, N_STATES, N_STATION_MEAS, OrbitParams
from .simulation import OrbitLog

__all__ = ["FILTERS", "MAX_MEASUREMENT", "FilterSetup", "FilterResult", "check_measurements", "stations_at",
           "OrbitEKF", "make_lkf", "make_ekf", "make_ukf", "run_lkf", "run_ekf", "run_ukf", "run", "run_filter"]

FILTERS = ("lkf", "ekf", "ukf")
#: largest magnitude accepted in a measurement (km, km/s, rad)
MAX_MEASUREMENT = 1e6


@dataclass(frozen=True, eq=False)
class FilterSetup:
    """Everything a filter run needs besides the measurements, validated on construction.

    filter : "lkf", "ekf" or "ukf"; params : OrbitParams (default the course's)
    Q : (2, 2) the filter's covariance of w_k, (km/s^2)^2 (default ``params.Qtrue``)
    R : (3, 3) one station's measurement-noise covariance [km^2, (km/s)^2, rad^2] (default ``params.Rtrue``)
    x0, P0 : initial estimate (4,) and covariance (4, 4) (default ``params.x0``, ``params.P0``)
    transition : how F comes from A: "euler" (``I + dt A``, default) or "expm"
    substeps : RK4 substeps of the EKF's and UKF's one-step map (default 2: 5 s each)
    alpha, beta, kappa : the UKF's Merwe scaled sigma points (default 1, 2, 0)
    """

    filter: str = "ekf"
    params: OrbitParams | None = None
    Q: np.ndarray | None = None
    R: np.ndarray | None = None
    x0: np.ndarray | None = None
    P0: np.ndarray | None = None
    transition: str = "euler"
    substeps: int = PROPAGATION_SUBSTEPS
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0

    def __post_init__(self):
        p = params_or_default(self.params)
        values = {
            "filter": require_choice("filter", self.filter, FILTERS),
            "params": p,
            "Q": np.array(p.Qtrue if self.Q is None else require_covariance("Q", self.Q, N_NOISE)),
            "R": np.array(p.Rtrue if self.R is None else require_covariance("R", self.R, N_STATION_MEAS)),
            "x0": p.x0 if self.x0 is None else require_shape("x0", require_states("x0", self.x0), (N_STATES,)),
            "P0": np.array(p.P0 if self.P0 is None else require_covariance("P0", self.P0, N_STATES)),
            "transition": require_choice("transition", self.transition, TRANSITIONS),
            "substeps": require_int("substeps", self.substeps, minimum=1, maximum=MAX_SUBSTEPS),
        }
        for name in ("alpha", "beta", "kappa"):
            values[name] = require_finite(name, getattr(self, name))
        if not 0 < values["alpha"] <= 1 or N_STATES + values["kappa"] <= 0:
            raise ValueError(f"alpha must be in (0, 1] and kappa > -{N_STATES}, got alpha={values['alpha']:g}, "
                             f"kappa={values['kappa']:g}")
        for name, value in values.items():
            object.__setattr__(self, name, value)

    def F(self, x) -> np.ndarray:
        """The DT transition ``F`` (..., 4, 4) at states ``x`` (..., 4) by the setup's ``transition``."""
        return discretize(jacobian_A(x, self.params), self.params.dt, self.transition)

    def fx(self, x, dt: float | None = None) -> np.ndarray:
        """The one-step map (RK4, ``substeps``) of states ``x`` (..., 4) over ``dt`` (s, default params.dt)."""
        p = self.params
        return rk4_flow(np.asarray(x, dtype=float), p.dt if dt is None else dt, p.mu, self.substeps)

    def station_R(self, m: int) -> np.ndarray:
        """``R`` of m stations stacked, (3m, 3m)."""
        return np.kron(np.eye(m), self.R)


@dataclass(frozen=True, eq=False)
class FilterResult:
    """One filter run over K samples (filterpy's names).

    filter : str; t : (K,) s
    x_prior, P_prior : (K, 4), (K, 4, 4) the prediction at t_k (at t_0: x0, P0)
    x_post, P_post : (K, 4), (K, 4, 4) after the update (the prior at a predict-only step)
    stations : tuple of K int arrays, the stations (0-based) whose measurements step k used
    y, S, K : tuples of K arrays: innovations (3 m_k,) (phi wrapped), their covariances (3 m_k, 3 m_k),
        the gains (4, 3 m_k); of size 0 at a predict-only step
    nis : (K,) NIS, NaN at a predict-only step; dof : (K,) its degrees of freedom 3 m_k
    nees : (K,) NEES (4 dof) against the truth, or None without one
    """

    filter: str
    t: np.ndarray
    stations: tuple
    dof: np.ndarray
    x_prior: np.ndarray
    P_prior: np.ndarray
    x_post: np.ndarray
    P_post: np.ndarray
    y: tuple
    S: tuple
    K: tuple
    nis: np.ndarray
    nees: np.ndarray | None = None

    @property
    def sigma2(self) -> np.ndarray:
        """Two-sigma bounds ``2 sqrt(diag P_post)``, (K, 4)."""
        return 2.0 * np.sqrt(np.diagonal(self.P_post, axis1=-2, axis2=-1))

    def errors(self, truth) -> np.ndarray:
        """Estimation errors ``truth - x_post``, (K, 4)."""
        return require_shape("truth", truth, self.x_post.shape) - self.x_post


def check_measurements(y, params: OrbitParams | None = None) -> np.ndarray:
    """Validate dense measurements ``y`` (K, n_stations, 3) (or take an :class:`OrbitLog`'s): a station's
    row all finite or all NaN (no measurement), values at most :data:`MAX_MEASUREMENT` in magnitude."""
    p = params_or_default(params)
    if isinstance(y, OrbitLog):
        y = y.y
    y = require_shape("y", y, (None, p.n_stations, N_STATION_MEAS))
    if y.shape[0] < 1:
        raise ValueError("y must hold at least one step")
    missing = np.isnan(y).sum(axis=2)  # per station and step: 0 (a measurement) or 3 (none)
    if np.any((missing != 0) & (missing != N_STATION_MEAS)) or np.isinf(y).any():
        raise ValueError("y: a station's [rho, rhodot, phi] must be all finite or all NaN (no measurement)")
    biggest = float(np.nanmax(np.abs(y), initial=0.0))
    if biggest > MAX_MEASUREMENT:
        raise ValueError(f"y values must be at most {MAX_MEASUREMENT:g} in magnitude (km, km/s, rad), got {biggest:.3g}")
    return y


def stations_at(y) -> list:
    """The stations (0-based, increasing) with a measurement at each step of ``y`` (K, n_stations, 3)."""
    have = np.isfinite(np.asarray(y, dtype=float)).all(axis=-1)
    return [np.flatnonzero(row) for row in have]


class _Steps:
    """The per-step results of a run."""

    def __init__(self, K):
        self.x_prior, self.x_post = np.empty((K, N_STATES)), np.empty((K, N_STATES))
        self.P_prior, self.P_post = np.empty((K, N_STATES, N_STATES)), np.empty((K, N_STATES, N_STATES))
        self.y = [np.empty(0)] * K
        self.S = [np.empty((0, 0))] * K
        self.K = [np.empty((N_STATES, 0))] * K
        self.nis = np.full(K, np.nan)

    def update(self, k, y, S, K):
        y, S = np.array(y, dtype=float).ravel(), np.array(S, dtype=float)
        self.y[k], self.S[k], self.K[k] = y, S, np.array(K, dtype=float)
        self.nis[k] = float(y @ np.linalg.solve(S, y))

    def finish(self, setup, stations, truth) -> FilterResult:
        K = len(stations)
        nees = None
        if truth is not None:
            truth = require_shape("truth", require_states("truth", truth), (K, N_STATES))
            nees = _nees(truth - self.x_post, self.P_post)
        dof = np.array([N_STATION_MEAS * ids.size for ids in stations])
        return FilterResult(setup.filter, setup.params.dt * np.arange(K), tuple(stations), dof, self.x_prior,
                            self.P_prior, self.x_post, self.P_post, tuple(self.y), tuple(self.S), tuple(self.K),
                            self.nis, nees)


def _begin(setup, filter, y):
    """The run's setup (``FilterSetup(filter)`` for None), its params and the checked measurements."""
    s = FilterSetup(filter) if setup is None else require_instance("setup", setup, FilterSetup)
    return s, s.params, check_measurements(y, s.params)


def _drive(y, setup, truth, predict, update, estimate) -> FilterResult:
    """The loop every filter shares: at step k, ``predict(k)`` (to t_k for k > 0; at k = 0 only before an
    update at t_0, to prepare it), keep ``estimate(k)`` -> (x, P) as the prior, ``update(k, ids)`` ->
    (y, S, K) if any station has a measurement, keep the posterior."""
    stations = stations_at(y)
    out = _Steps(len(stations))
    for k, ids in enumerate(stations):
        if k > 0 or ids.size:
            predict(k)
        out.x_prior[k], out.P_prior[k] = estimate(k)
        if ids.size:
            out.update(k, *update(k, ids))
        out.x_post[k], out.P_post[k] = estimate(k)
    return out.finish(setup, stations, truth)


# ---------------------------------------------------------------------------
# LKF
def make_lkf(setup: FilterSetup) -> KalmanFilter:
    """filterpy KalmanFilter on ``dx = x - x_nom`` at ``dx0 = x0 - x_nom(0)``, P0 and ``Omega Q Omega^T``
    (``dim_z`` is set per step)."""
    kf = KalmanFilter(dim_x=N_STATES, dim_z=N_STATION_MEAS)
    kf.x = (setup.x0 - nominal_trajectory(setup.params, 1)[0]).reshape(N_STATES, 1)
    kf.P = setup.P0.copy()
    kf.Q = setup.params.process_noise(setup.Q)
    return kf


def run_lkf(y, setup: FilterSetup | None = None, truth=None) -> FilterResult:
    """Linearized KF about the circular nominal on measurements ``y`` (K, n_stations, 3) (module docstring)."""
    s, p, y = _begin(setup, "lkf", y)
    K = y.shape[0]
    t = p.dt * np.arange(K)
    xnom = nominal_trajectory(p, K)
    F = s.F(xnom)  # F[k] maps k -> k + 1
    kf = make_lkf(s)

    def predict(k):
        if k > 0:
            kf.predict(F=F[k - 1])  # F[k - 1] carries step k - 1 to k

    def update(k, ids):
        layout = measurement_layout(ids.size)
        H = stacked_jacobian(xnom[k], t[k], ids, p)
        dz = H @ kf.x[:, 0]
        innov = layout.residual(y[k, ids].ravel(), layout.wrap(stacked_measurement(xnom[k], t[k], ids, p) + dz))
        kf.dim_z = layout.n
        kf.update((dz + innov).reshape(-1, 1), R=s.station_R(ids.size), H=H)  # filterpy's z - H x: the innovation
        return kf.y, kf.S, kf.K

    def estimate(k):
        return xnom[k] + kf.x[:, 0], kf.P

    return _drive(y, s, truth, predict, update, estimate)


# ---------------------------------------------------------------------------
# EKF
class OrbitEKF(ExtendedKalmanFilter):
    """filterpy's ExtendedKalmanFilter with the nonlinear RK4 propagation of the mean.

    ``predict()`` calls :meth:`predict_x`, then ``P = F P F^T + Q``: here ``predict_x`` sets
    ``F = I + dt A(x+)`` (or ``expm``) at the posterior and moves the mean with the setup's RK4 map.
    :meth:`hx`, :meth:`H_jacobian` and :meth:`residual_z` take filterpy's column vectors and the step's
    ``(t, stations)``, for ``update(z, HJacobian=ekf.H_jacobian, Hx=ekf.hx, args=(t, ids), hx_args=(t, ids),
    residual=ekf.residual_z, R=R_k)``.
    """

    def __init__(self, setup: FilterSetup):
        self.setup = require_instance("setup", setup, FilterSetup)
        super().__init__(dim_x=N_STATES, dim_z=N_STATION_MEAS)

    def predict_x(self, u=0):
        x = self.x[:, 0]
        self.F = self.setup.F(x)
        self.x = self.setup.fx(x).reshape(N_STATES, 1)

    def hx(self, x, t, stations):
        """The stacked measurement (3m, 1) of the stations at the state column x (4, 1), time t (s)."""
        return stacked_measurement(x[:, 0], t, stations, self.setup.params).reshape(-1, 1)

    def H_jacobian(self, x, t, stations):
        """Its Jacobian (3m, 4)."""
        return stacked_jacobian(x[:, 0], t, stations, self.setup.params)

    @staticmethod
    def residual_z(a, b):
        """``a - b`` for stacked measurement columns (3m, 1), phi wrapped."""
        return measurement_layout(a.shape[0] // N_STATION_MEAS).residual(a[:, 0], b[:, 0]).reshape(-1, 1)


def make_ekf(setup: FilterSetup) -> OrbitEKF:
    """An :class:`OrbitEKF` at (x0, P0) with ``Omega Q Omega^T``."""
    ekf = OrbitEKF(setup)
    ekf.x = setup.x0.reshape(N_STATES, 1).copy()
    ekf.P = setup.P0.copy()
    ekf.Q = setup.params.process_noise(setup.Q)
    return ekf


def run_ekf(y, setup: FilterSetup | None = None, truth=None) -> FilterResult:
    """Extended KF on measurements ``y`` (K, n_stations, 3) (module docstring)."""
    s, p, y = _begin(setup, "ekf", y)
    ekf = make_ekf(s)

    def predict(k):
        if k > 0:
            ekf.predict()

    def update(k, ids):
        step = (p.dt * k, ids)
        ekf.dim_z = N_STATION_MEAS * ids.size
        ekf.update(y[k, ids].reshape(-1, 1), HJacobian=ekf.H_jacobian, Hx=ekf.hx, R=s.station_R(ids.size),
                   args=step, hx_args=step, residual=ekf.residual_z)
        return ekf.y, ekf.S, ekf.K

    return _drive(y, s, truth, predict, update, lambda k: (ekf.x[:, 0], ekf.P))


# ---------------------------------------------------------------------------
# UKF
def _z_mean(points, weights):
    """Weighted mean of stacked measurement points (..., 2n+1, 3m): circular for every phi."""
    return measurement_layout(np.shape(points)[-1] // N_STATION_MEAS).mean(points, weights)


def _z_residual(a, b):
    """``a - b`` for stacked measurements (..., 3m), phi wrapped."""
    return measurement_layout(np.shape(a)[-1] // N_STATION_MEAS).residual(a, b)


def make_ukf(setup: FilterSetup) -> VectorizedUKF:
    """filterpy UnscentedKalmanFilter (f and h on all sigma points at once) at (x0, P0) with the setup's Merwe
    scaled sigma points (their square root :func:`~kfcal_helpers.unscented.robust_sqrt`), the RK4 map,
    ``Omega Q Omega^T`` and the stacked measurements' circular mean and wrapped residual; h and R are
    given per step."""
    p = setup.params
    points = MerweScaledSigmaPoints(N_STATES, alpha=setup.alpha, beta=setup.beta, kappa=setup.kappa)
    points.sqrt = robust_sqrt
    ukf = VectorizedUKF(dim_x=N_STATES, dim_z=N_STATION_MEAS, dt=p.dt, fx=lambda sig, dt: setup.fx(sig, dt),
                        hx=lambda sig: np.empty((sig.shape[0], 0)), points=points,
                        z_mean_fn=_z_mean, residual_z=_z_residual)
    ukf.x = setup.x0.copy()
    ukf.P = setup.P0.copy()
    ukf.Q = p.process_noise(setup.Q)
    return ukf


def run_ukf(y, setup: FilterSetup | None = None, truth=None) -> FilterResult:
    """Unscented KF on measurements ``y`` (K, n_stations, 3) (module docstring)."""
    s, p, y = _begin(setup, "ukf", y)
    ukf = make_ukf(s)

    def predict(k):
        if k > 0:
            ukf.predict()
            ukf.P = 0.5 * (ukf.P + ukf.P.T)
        else:  # an update at t_0: the sigma points of (x0, P0)
            ukf.sigmas_f = ukf.points_fn.sigma_points(ukf.x, ukf.P)

    def update(k, ids):
        t = p.dt * k
        ukf._dim_z = N_STATION_MEAS * ids.size  # filterpy 2.0 keeps the size here (see the module docstring)
        ukf.update(y[k, ids].ravel(), R=s.station_R(ids.size), hx=lambda sig: stacked_measurement(sig, t, ids, p))
        ukf.P = 0.5 * (ukf.P + ukf.P.T)
        return ukf.y, ukf.S, ukf.K

    return _drive(y, s, truth, predict, update, lambda k: (ukf.x.copy(), ukf.P.copy()))


_RUNNERS = {"lkf": run_lkf, "ekf": run_ekf, "ukf": run_ukf}


def run(y, setup: FilterSetup, truth=None) -> FilterResult:
    """Run the filter ``setup.filter`` on measurements ``y`` (K, n_stations, 3) or an :class:`OrbitLog`,
    with the true states ``truth`` (K, 4) for the NEES if given."""
    setup = require_instance("setup", setup, FilterSetup)
    return _RUNNERS[setup.filter](y, setup, truth)


def run_filter(filter: str, y, params: OrbitParams | None = None, *, truth=None, **settings) -> FilterResult:
    """Run filter ``filter`` ("lkf", "ekf", "ukf") on ``y`` (K, n_stations, 3) or an :class:`OrbitLog`: the
    short entry; ``settings`` are :class:`FilterSetup`'s fields (Q, R, x0, P0, transition, substeps, alpha,
    beta, kappa)."""
    allowed = set(FilterSetup.__dataclass_fields__) - {"filter", "params"}
    unknown = sorted(set(settings) - allowed)
    if unknown:
        raise ValueError(f"{unknown[0]} is not a filter setting; the settings are {', '.join(sorted(allowed))}")
    return run(y, FilterSetup(filter, params, **settings), truth)
