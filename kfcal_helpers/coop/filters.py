"""LKF, EKF and UKF for cooperative localization, on filterpy's classes.

* LKF -- ``filterpy.kalman.KalmanFilter`` on the perturbation ``dx = x - x_nom`` about
  the nominal trajectory, with ``F_k = I + dt A(x_nom_k)`` and ``H_k = C(x_nom_k)``.
  Its innovation ``(y - y_nom) - H dx-`` is angle-wrapped (fed to filterpy as
  ``z = H dx- + wrapped innovation``, so that filterpy's ``z - H x`` is the wrapped one).
* EKF -- ``filterpy.kalman.ExtendedKalmanFilter`` whose ``predict_x`` is the exact
  nonlinear one-step map (filterpy's own is linear), ``F = I + dt A(x_hat)`` at the
  posterior, and ``update(..., residual=...)`` with bearings wrapped.
* UKF -- ``filterpy.kalman.UnscentedKalmanFilter`` with ``MerweScaledSigmaPoints`` and
  angle-aware ``residual_x``, ``residual_z``, ``x_mean_fn``, ``z_mean_fn`` (circular
  means) and ``state_add``.

Every filter starts at (x0, P0) at t_0 and, for k = 1..K-1, predicts to t_k and updates
with ``y_k`` unless that row is NaN (predict only).  A finite ``y_0`` is used at t_0.
All return a :class:`FilterResult` (filterpy's names: ``x_prior, P_prior, x_post, P_post, y, S, K``).

A run is ``run_xkf(y, setup, truth=None)``: the measurements, a :class:`FilterSetup` holding
everything else (the model ``params``, the filter's ``Q``, the :class:`~.model.MeasurementModel`
with its ``R``, the initial estimate, the sigma points of the UKF, the mistakes of notebook 14), and
optionally the true states for the NEES.  ``Q`` is the filter's covariance of the DT process noise
``w_k``; it enters through the model's ``Omega`` (``params.Omega``, ``dt * I`` by default), as in the
truth model: ``P- = F P F^T + Omega Q Omega^T``.  A measurement model of some rows of ``y`` (e.g.
``(0, 1, 2)``, the two bearings and the range without the UAV's GPS: ``measurements=`` of
:func:`run_filter`) updates with only those components, and the NIS has that many degrees of
freedom.  :func:`run_filter` is the short entry: it builds the setup from keywords.
"""

from __future__ import annotations

from dataclasses import dataclass

from functools import partial

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

from ..consistency import chi2_bounds as _chi2_bounds
from ..consistency import nees as _nees
from ..consistency import nis as _nis
from ..unscented import VectorizedUKF, robust_sqrt
from ..validation import (checked, optional, require_array, require_bool, require_choice, require_covariance, require_instance,
                          require_positive, require_shape)
from .model import (
    MAX_MEASUREMENT,
    MAX_STEPS,
    N_MEAS,
    N_STATES,
    STATE,
    CoopParams,
    MeasurementModel,
    arc,
    too_many_steps,
    jacobian_A,
    nominal_trajectory,
    require_indices,
    require_last_axis,
)

__all__ = [
    "FILTERS",
    "TUNED_Q_SCALE",
    "UKF_POINTS",
    "SigmaPoints",
    "FilterResult",
    "EstimateViews",
    "check_measurements",
    "tuned_Q",
    "FilterSetup",
    "SETTINGS",
    "CoopEKF",
    "make_lkf",
    "make_ekf",
    "make_ukf",
    "run_lkf",
    "run_ekf",
    "run_ukf",
    "run",
    "run_filter",
    "log_summary",
    "measurement_subset",
    "robust_sqrt",
    "QScaleFit",
    "fit_q_scale",
]

FILTERS = ("lkf", "ekf", "ukf")

#: filter Q = scale * Qtrue (covariance of the rate noise w_k, entering through Omega = dt I), chosen by the
#: truth-model tests, NEES and NIS together (notebooks 10-12); never tuned on a log.  No scale makes
#: the LKF's NEES consistent (notebook 10), so it keeps Qtrue.
TUNED_Q_SCALE = {"lkf": 1.0, "ekf": 1.0, "ukf": 1.0}


@dataclass(frozen=True)
class SigmaPoints:
    """Merwe scaled sigma points of the UKF: ``alpha`` in (0, 1], ``beta``, ``kappa > -6``."""

    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0

    def __post_init__(self):
        alpha = require_positive("alpha", self.alpha)
        beta, kappa = float(self.beta), float(self.kappa)
        if alpha > 1 or N_STATES + kappa <= 0 or not np.isfinite(beta + kappa):
            raise ValueError(f"alpha must be in (0, 1], beta finite and kappa > -6, got alpha={alpha:g}, "
                             f"beta={beta:g}, kappa={kappa:g}")
        object.__setattr__(self, "alpha", alpha)
        object.__setattr__(self, "beta", beta)
        object.__setattr__(self, "kappa", kappa)


#: the UKF's sigma points (notebook 12)
UKF_POINTS = SigmaPoints()


@checked(params=optional(partial(require_instance, cls=CoopParams)))
def tuned_Q(filter: str, params: CoopParams | None = None) -> np.ndarray:
    """The tuned filter process noise of ``filter``: the covariance (6x6) of ``w_k`` (the rate noise held
    over a step), which enters the state as ``Omega Q Omega^T`` (``dt^2 Q``) per step."""
    filter = require_choice("filter", filter, FILTERS)
    p = params if params is not None else CoopParams()
    return TUNED_Q_SCALE[filter] * p.Qtrue


class EstimateViews:
    """What a filter run's result derives from its ``x_post`` (K, 6) and ``P_post`` (K, 6, 6): ``x``, ``P``,
    ``sigma2`` and ``errors(truth)`` (shared by :class:`FilterResult` and the lean results of
    :mod:`~kfcal_helpers.coop.fast`)."""

    @property
    def x(self) -> np.ndarray:
        """The estimate at every step, (K, 6): ``x_post``."""
        return self.x_post

    @property
    def P(self) -> np.ndarray:
        """Its covariance, (K, 6, 6): ``P_post``."""
        return self.P_post

    @property
    def sigma2(self) -> np.ndarray:
        """Two-sigma bounds ``2 sqrt(diag P)``, shape (K, 6)."""
        return 2.0 * np.sqrt(np.diagonal(self.P, axis1=-2, axis2=-1))

    def errors(self, truth) -> np.ndarray:
        """Estimation errors ``truth - x`` with the headings wrapped, shape (K, 6)."""
        return STATE.residual(truth, self.x)


@dataclass(frozen=True, eq=False)
class FilterResult(EstimateViews):
    """Output of one filter run over K samples (filterpy's names).

    Attributes
    ----------
    filter : str -- "lkf", "ekf" or "ukf"
    t : (K,) s
    x_prior, P_prior : (K, 6), (K, 6, 6) predicted estimate and covariance at t_k (at t_0: x0, P0)
    x_post, P_post : (K, 6), (K, 6, 6) after the update (the prior where there was no measurement);
        ``x`` and ``P`` are the same arrays (the estimate at every step); headings wrapped
    z_pred : (K, 5) predicted measurements h(x-) (UKF: the sigma-point mean)
    y : (K, 5) wrapped innovations (residuals) ``z - z_pred``
    S : (K, 5, 5) innovation covariances; K : (K, 6, 5) Kalman gains
    nis : (K,) normalized innovation squared
    nees : (K,) normalized estimation error squared (headings wrapped), or None without truth
    measurements : tuple of the rows of the measurements the filter used (default all five)

    ``z_pred``, ``y``, ``S``, ``K`` and ``nis`` are NaN at steps without a measurement, and the first four
    in the components of the rows not used; ``nis`` has ``len(measurements)`` degrees of freedom.
    """

    filter: str
    t: np.ndarray
    x_prior: np.ndarray
    P_prior: np.ndarray
    x_post: np.ndarray
    P_post: np.ndarray
    z_pred: np.ndarray
    y: np.ndarray
    S: np.ndarray
    K: np.ndarray
    nis: np.ndarray
    nees: np.ndarray | None = None
    measurements: tuple = tuple(range(N_MEAS))

    def time_average_nis(self) -> float:
        """Mean NIS over the steps that had a measurement."""
        return float(np.nanmean(self.nis))

    def log_likelihood(self) -> float:
        """Gaussian log-likelihood of the innovations, ``sum_k -(NIS_k + log det S_k + m log 2 pi) / 2``
        over the steps with a measurement (m = number of measurements used)."""
        has = np.isfinite(self.nis)
        idx = list(self.measurements)
        S = self.S[has][:, idx][:, :, idx]
        _, logdet = np.linalg.slogdet(S)
        m = len(idx)
        return float(-0.5 * np.sum(self.nis[has] + logdet + m * np.log(2.0 * np.pi)))


def measurement_subset(measurements) -> tuple[int, ...] | None:
    """Validate ``measurements=``: None (all five rows of y) or a non-empty sequence of
    distinct integers in 0..4 (0 bearing UGV->UAV, 1 range, 2 bearing UAV->UGV, 3 UAV GPS east,
    4 UAV GPS north).  Returns None for all five, else the sorted tuple; ValueError otherwise."""
    if measurements is None:
        return None
    idx = require_indices("measurements", measurements, N_MEAS,
                          " (rows of y: 0 bearing UGV->UAV, 1 range, 2 bearing UAV->UGV, 3 UAV GPS east, 4 UAV GPS north)")
    return None if idx == tuple(range(N_MEAS)) else idx


#: the keyword settings of :meth:`FilterSetup.build` besides ``R`` and ``measurements`` (its fields)
SETTINGS = ("Q", "x0", "P0", "points", "wrap_innovations", "subtract_nominal")


@dataclass(frozen=True, eq=False)
class FilterSetup:
    """Everything a filter run needs besides the measurements, validated on construction.

    filter : "lkf", "ekf" or "ukf" -- the filter :func:`run` runs (and whose tuned Q is the default)
    params : CoopParams -- model, nominal, dt, noise model (default: the course's)
    Q : (6, 6) filter covariance of w_k (default :func:`tuned_Q`)
    measurement : MeasurementModel -- h, its Jacobian, the rows of y used and R (default: all five
        rows, ``params.Rtrue``)
    x0, P0 : initial estimate (6,) and covariance (6, 6) (default ``params.x0``, ``params.P0``)
    points : SigmaPoints -- the UKF's (default :data:`UKF_POINTS`)
    wrap_innovations : EKF; False passes filterpy's default ``residual=np.subtract`` (the mistake of
        notebooks 11 and 14: bearing innovations jump by 2 pi across +-pi)
    subtract_nominal : LKF; False compares ``H dx-`` with the total y (the mistake of notebook 14)

    :meth:`build` takes ``R`` and ``measurements`` (rows of y) instead of a measurement model.
    """

    filter: str = "ekf"
    params: CoopParams | None = None
    Q: np.ndarray | None = None
    measurement: MeasurementModel | None = None
    x0: np.ndarray | None = None
    P0: np.ndarray | None = None
    points: SigmaPoints = UKF_POINTS
    wrap_innovations: bool = True
    subtract_nominal: bool = True

    def __post_init__(self):
        name = require_choice("filter", self.filter, FILTERS)
        p = require_instance("params", self.params, CoopParams, allow_none=True) or CoopParams()
        Q = tuned_Q(name, p) if self.Q is None else require_covariance("Q", self.Q, N_STATES)
        model = require_instance("measurement", self.measurement, MeasurementModel, allow_none=True)
        x0 = p.x0 if self.x0 is None else require_last_axis("x0", require_shape("x0", self.x0, (N_STATES,)),
                                                               N_STATES)
        P0 = p.P0 if self.P0 is None else require_covariance("P0", self.P0, N_STATES)
        require_instance("points", self.points, SigmaPoints)
        for flag in ("wrap_innovations", "subtract_nominal"):
            require_bool(flag, getattr(self, flag))
        values = {"filter": name, "params": p, "Q": np.array(Q),
                  "measurement": model if model is not None else MeasurementModel(p.Rtrue),
                  "x0": STATE.wrap(x0), "P0": np.array(P0)}
        for key, value in values.items():
            object.__setattr__(self, key, value)

    @classmethod
    def build(cls, filter: str = "ekf", params: CoopParams | None = None, *, R=None, measurements=None,
              **settings) -> "FilterSetup":
        """A setup with the measurement model of ``R`` (5x5, default ``params.Rtrue``) restricted to the
        rows ``measurements`` of y (default all five; see :func:`measurement_subset`); the other
        settings (Q, x0, P0, points, wrap_innovations, subtract_nominal) as in the class."""
        unknown = sorted(set(settings) - set(SETTINGS))
        if unknown:
            raise ValueError(f"{unknown[0]} is not a filter setting; the settings are "
                             f"{', '.join(('R', 'measurements', *SETTINGS))}")
        p = require_instance("params", params, CoopParams, allow_none=True) or CoopParams()
        model = MeasurementModel(p.Rtrue if R is None else require_covariance("R", R, N_MEAS))
        idx = measurement_subset(measurements)
        if idx is not None:
            model = model.subset(idx)
        return cls(filter, p, measurement=model, **settings)


def check_measurements(y) -> np.ndarray:
    """Validate the measurements ``y`` (K, 5): rows all finite or all NaN (NaN: predict only), values at
    most MAX_MEASUREMENT (1e6 m or rad) in magnitude, at most MAX_STEPS rows."""
    y = require_shape("y", y, (None, N_MEAS))
    if y.shape[0] < 1:
        raise ValueError("y must hold at least one row")
    if y.shape[0] > MAX_STEPS:
        raise ValueError(too_many_steps("y", y.shape[0]))
    nan = np.isnan(y)
    if (nan.any(axis=1) & ~nan.all(axis=1)).any() or np.isinf(y).any():
        raise ValueError("y rows must be all finite or all NaN (a NaN row means predict only)")
    largest = float(np.abs(y[~nan]).max(initial=0.0))
    if largest > MAX_MEASUREMENT:
        raise ValueError(f"y values must be at most {MAX_MEASUREMENT:g} in magnitude (m, rad; beyond it the "
                         f"filters' squares overflow), got {largest:.3g}")
    return y


def _setup(setup, filter) -> FilterSetup:
    if setup is None:
        return FilterSetup(filter)
    return require_instance("setup", setup, FilterSetup)


class _Storage:
    """The per-step arrays of a run, NaN where a step or a component has no measurement."""

    def __init__(self, K, rows):
        self.used = list(rows)
        if len(self.used) == N_MEAS:  # basic slices: faster than index lists in the per-step loop
            self.rows, self.block = slice(None), (slice(None), slice(None))
        else:
            self.rows, self.block = self.used, np.ix_(self.used, self.used)
        self.x_prior, self.x_post = np.empty((K, N_STATES)), np.empty((K, N_STATES))
        self.P_prior, self.P_post = np.empty((K, N_STATES, N_STATES)), np.empty((K, N_STATES, N_STATES))
        self.z_pred, self.y = np.full((K, N_MEAS), np.nan), np.full((K, N_MEAS), np.nan)
        self.S, self.K = np.full((K, N_MEAS, N_MEAS), np.nan), np.full((K, N_STATES, N_MEAS), np.nan)

    def update(self, k, z_pred, y, S, K):
        """Keep the update at step k (arrays of the rows used)."""
        self.z_pred[k, self.rows], self.y[k, self.rows] = z_pred, y
        self.S[k][self.block] = S
        self.K[k][:, self.rows] = K

    def finish(self, setup, truth) -> FilterResult:
        K = self.y.shape[0]
        idx = self.used
        nis = np.full(K, np.nan)
        has = np.isfinite(self.y[:, idx]).all(axis=1)
        y_used, S_used = self.y[has], self.S[has]
        if len(idx) < N_MEAS:  # the components of the rows used
            y_used, S_used = y_used[:, idx], S_used[:, idx][:, :, idx]
        nis[has] = _nis(y_used, S_used)
        nees = None
        if truth is not None:
            truth = require_shape("truth", truth, (K, N_STATES))
            nees = _nees(STATE.residual(truth, self.x_post), self.P_post)
        return FilterResult(setup.filter, setup.params.dt * np.arange(K), self.x_prior, self.P_prior, self.x_post,
                            self.P_post, self.z_pred, self.y, self.S, self.K, nis, nees, tuple(idx))


# ---------------------------------------------------------------------------
# LKF
@checked(setup=partial(require_instance, cls=FilterSetup))
def make_lkf(setup: FilterSetup) -> KalmanFilter:
    """filterpy KalmanFilter on dx = x - x_nom, initialised at dx0 = x0 - x_nom_0, with the setup's
    Q (entering as ``Omega Q Omega^T``) and R (``dim_z`` = the measurement model's rows)."""
    kf = KalmanFilter(dim_x=N_STATES, dim_z=setup.measurement.dim)
    kf.x = STATE.residual(setup.x0, setup.params.x0).reshape(N_STATES, 1)
    kf.P = setup.P0.copy()
    kf.Q = setup.params.process_noise(setup.Q)
    kf.R = setup.measurement.R.copy()
    return kf


def run_lkf(y, setup: FilterSetup | None = None, truth=None) -> FilterResult:
    """Linearized KF about the nominal trajectory on measurements ``y`` (K, 5) (see :func:`run_filter`).

    With ``setup.subtract_nominal=False`` a known mistake (notebook 14): the innovation
    ``y - H dx-`` without the nominal measurement ``y*`` subtracted.
    """
    y = check_measurements(y)
    s = _setup(setup, "lkf")
    p, model, K = s.params, s.measurement, y.shape[0]
    xnom = nominal_trajectory(p, K)
    ynom = model.h(xnom)
    F = np.eye(N_STATES) + p.dt * jacobian_A(xnom, p.u0, p.L)  # (K, 6, 6), F[k] maps k -> k+1
    H = model.jacobian(xnom)  # (K, m, 6)
    kf = make_lkf(s)
    out = _Storage(K, model.rows)
    rows = out.rows
    for k in range(K):
        if k > 0:
            kf.predict(F=F[k - 1])
        out.x_prior[k], out.P_prior[k] = kf.x[:, 0], kf.P
        if not np.isnan(y[k, 0]):
            dz = H[k] @ kf.x[:, 0]
            zk = model.wrap(ynom[k] + dz) if s.subtract_nominal else dz  # the mistake: H dx- against the total y
            innov = model.residual(y[k, rows], zk)
            kf.update((dz + innov).reshape(model.dim, 1), H=H[k])  # filterpy's z - H x is the wrapped innovation
            assert kf.x.shape == (N_STATES, 1) and kf.y.shape == (model.dim, 1)
            out.update(k, zk, kf.y[:, 0], kf.S, kf.K)
        out.x_post[k], out.P_post[k] = kf.x[:, 0], kf.P
    out.x_prior[:] = STATE.wrap(xnom + out.x_prior)
    out.x_post[:] = STATE.wrap(xnom + out.x_post)
    return out.finish(s, truth)


# ---------------------------------------------------------------------------
# EKF
class CoopEKF(ExtendedKalmanFilter):
    """filterpy's ExtendedKalmanFilter with the nonlinear closed-form propagation.

    ``predict()`` calls :meth:`predict_x` and then ``P = F P F^T + Q``: here
    ``predict_x`` first sets ``F = I + dt A(x_hat_k, u)`` at the posterior and then
    moves the mean with the exact map ``x_hat_{k+1}^- = phi(x_hat_k, u)``.
    :meth:`hx`, :meth:`H_jacobian` and :meth:`residual_z` are the setup's measurement model on
    filterpy's column vectors, for ``update(z, HJacobian=ekf.H_jacobian, Hx=ekf.hx, residual=ekf.residual_z)``.
    """

    def __init__(self, setup: FilterSetup):
        self.setup = require_instance("setup", setup, FilterSetup)
        super().__init__(dim_x=N_STATES, dim_z=setup.measurement.dim)
        self.params = setup.params

    def predict_x(self, u=0):
        p = self.params
        xk = self.x[:, 0]
        self.F = np.eye(N_STATES) + p.dt * jacobian_A(xk, p.u0, p.L)
        self.x = arc(xk, p.u0, p.dt, p.L).reshape(N_STATES, 1)

    def hx(self, x):
        """h of the state column x (6, 1), a column (m, 1)."""
        return self.setup.measurement.h(x[:, 0]).reshape(-1, 1)

    def H_jacobian(self, x):
        """Jacobian (m, 6) of h at the state column x (6, 1)."""
        return self.setup.measurement.jacobian(x[:, 0])

    def residual_z(self, a, b):
        """``a - b`` for measurement columns (m, 1), bearings wrapped."""
        return self.setup.measurement.residual(a[:, 0], b[:, 0]).reshape(-1, 1)


@checked(setup=partial(require_instance, cls=FilterSetup))
def make_ekf(setup: FilterSetup) -> CoopEKF:
    """A :class:`CoopEKF` initialised at (x0, P0) with the setup's Q and R."""
    ekf = CoopEKF(setup)
    ekf.x = setup.x0.reshape(N_STATES, 1).copy()
    ekf.P = setup.P0.copy()
    ekf.Q = setup.params.process_noise(setup.Q)
    ekf.R = setup.measurement.R.copy()
    return ekf


def run_ekf(y, setup: FilterSetup | None = None, truth=None) -> FilterResult:
    """Extended KF on measurements ``y`` (K, 5) (see :func:`run_filter`).

    With ``setup.wrap_innovations=False`` filterpy's default ``residual=np.subtract``: only to
    demonstrate the pitfall (bearing innovations jump by 2 pi across +-pi).
    """
    y = check_measurements(y)
    s = _setup(setup, "ekf")
    model, K = s.measurement, y.shape[0]
    ekf = make_ekf(s)
    residual = ekf.residual_z if s.wrap_innovations else np.subtract
    out = _Storage(K, model.rows)
    rows = out.rows
    for k in range(K):
        if k > 0:
            ekf.predict()
        out.x_prior[k], out.P_prior[k] = ekf.x[:, 0], ekf.P
        if not np.isnan(y[k, 0]):
            yk = y[k, rows]
            ekf.update(yk.reshape(model.dim, 1), HJacobian=ekf.H_jacobian, Hx=ekf.hx, residual=residual)
            assert ekf.x.shape == (N_STATES, 1) and ekf.y.shape == (model.dim, 1)
            ekf.x = STATE.wrap(ekf.x[:, 0]).reshape(N_STATES, 1)
            out.update(k, model.residual(yk, ekf.y[:, 0]), ekf.y[:, 0], ekf.S, ekf.K)  # h(x-) from y - nu
        out.x_post[k], out.P_post[k] = ekf.x[:, 0], ekf.P
    return out.finish(s, truth)


# ---------------------------------------------------------------------------
# UKF
@checked(setup=partial(require_instance, cls=FilterSetup))
def make_ukf(setup: FilterSetup) -> UnscentedKalmanFilter:
    """filterpy UnscentedKalmanFilter with the setup's Merwe scaled sigma points, its measurement
    model (h, circular z mean, wrapped residual, R) and the state's angle functions."""
    p, model, pts = setup.params, setup.measurement, setup.points
    # sigma points x +- columns of sqrt((n+lambda) P) need no wrapping: f and h are 2 pi-periodic in the headings
    points = MerweScaledSigmaPoints(N_STATES, alpha=pts.alpha, beta=pts.beta, kappa=pts.kappa)
    points.sqrt = robust_sqrt  # symmetrize P, Cholesky with jitter if needed

    def fx(sigmas, dt):  # all sigma points at once, shape (13, 6)
        return arc(sigmas, p.u0, dt, p.L)

    ukf = VectorizedUKF(dim_x=N_STATES, dim_z=model.dim, dt=p.dt, hx=model.h, fx=fx, points=points,
                   x_mean_fn=STATE.mean, z_mean_fn=model.mean,
                   residual_x=STATE.residual, residual_z=model.residual, state_add=STATE.add)
    ukf.x = setup.x0.copy()
    ukf.P = setup.P0.copy()
    ukf.Q = setup.params.process_noise(setup.Q)
    ukf.R = model.R.copy()
    return ukf


def run_ukf(y, setup: FilterSetup | None = None, truth=None) -> FilterResult:
    """Unscented KF on measurements ``y`` (K, 5) (see :func:`run_filter`)."""
    y = check_measurements(y)
    s = _setup(setup, "ukf")
    model, K = s.measurement, y.shape[0]
    ukf = make_ukf(s)
    out = _Storage(K, model.rows)
    rows = out.rows
    for k in range(K):
        if k > 0:
            ukf.predict()
            ukf.P = 0.5 * (ukf.P + ukf.P.T)
        elif not np.isnan(y[0, 0]):  # update at t_0: sigma points of the initial (x0, P0)
            ukf.sigmas_f = ukf.points_fn.sigma_points(ukf.x, ukf.P)
        out.x_prior[k], out.P_prior[k] = ukf.x, ukf.P
        if not np.isnan(y[k, 0]):
            yk = y[k, rows]
            ukf.update(yk)
            assert ukf.x.shape == (N_STATES,) and ukf.y.shape == (model.dim,)
            ukf.P = 0.5 * (ukf.P + ukf.P.T)
            out.update(k, model.residual(yk, ukf.y), ukf.y, ukf.S, ukf.K)  # the sigma-point mean z-
        out.x_post[k], out.P_post[k] = ukf.x, ukf.P
    return out.finish(s, truth)


_RUNNERS = {"lkf": run_lkf, "ekf": run_ekf, "ukf": run_ukf}


def run(y, setup: FilterSetup, truth=None) -> FilterResult:
    """Run the filter ``setup.filter`` on measurements ``y`` (K, 5), with the true states ``truth``
    (K, 6) for the NEES if given."""
    setup = require_instance("setup", setup, FilterSetup)
    return _RUNNERS[setup.filter](y, setup, truth)


@checked(params=optional(partial(require_instance, cls=CoopParams)), truth=optional(require_array))
def run_filter(filter: str, y, params: CoopParams | None = None, *, truth=None, **settings) -> FilterResult:
    """Run filter ``filter`` ("lkf", "ekf", "ukf") on measurements ``y``: the short entry.

    Parameters
    ----------
    y : array (K, 5) -- one row per t_k = k dt; an all-NaN row means predict only
    params : CoopParams -- model, nominal, dt; defaults to the course's
    truth : (K, 6), optional -- true states, for the NEES
    settings : keywords of :meth:`FilterSetup.build`: ``Q`` (6, 6) (default :func:`tuned_Q`), ``R`` (5, 5)
        (default ``params.Rtrue``), ``x0``, ``P0`` (default ``params.x0``, ``params.P0``),
        ``measurements`` (rows of y to use: distinct integers in 0..4, 0 bearing UGV->UAV, 1 range,
        2 bearing UAV->UGV, 3 UAV GPS east, 4 UAV GPS north; default all five), ``points`` (UKF:
        :class:`SigmaPoints`), ``wrap_innovations`` (EKF), ``subtract_nominal`` (LKF)

    Returns
    -------
    FilterResult
    """
    return run(y, FilterSetup.build(filter, params, **settings), truth)


def log_summary(result, alpha: float = 0.05) -> dict:
    """Time-averaged NIS of one run with its bounds (and the time-averaged NEES when the truth is known,
    without bounds).

    The NIS has as many degrees of freedom per update as the filter used measurements
    (``result.measurements``); a consistent filter's innovations are white, so the time average of K
    of them lies in the chi-square(mK)/K band.  The NEES gets no band: one run's estimation errors are
    correlated from step to step, so its time average scatters more than chi-square(6K)/K allows
    (:mod:`kfcal_helpers.consistency`); judge the NEES over runs at each step instead.
    """
    n_meas = int(np.isfinite(result.nis).sum())
    if n_meas == 0:
        raise ValueError("log: it holds no measurement (every ydata column is NaN)")
    lo, hi = _chi2_bounds(len(result.measurements), n_meas, alpha)
    nis = result.time_average_nis()
    out = {"nis_time_average": nis, "nis_bounds": [lo, hi], "nis_inside": bool(lo <= nis <= hi),
           "measurements": n_meas}
    if result.nees is not None:
        out["nees_time_average"] = float(result.nees.mean())
    return out


@dataclass(frozen=True, eq=False)
class QScaleFit:
    """A fit of ``Q = s * Qtrue`` to one log over a ladder of scales (:func:`fit_q_scale`).

    This is a fit to the data, not a test: the NIS of the fitted filter on the same log is not an
    independent check of it.

    Attributes
    ----------
    filter : str; scales : (n,) the ladder; log_likelihood : (n,) innovation log-likelihood per scale
    nis_averages : (n,) time-averaged NIS per scale; nis_bounds : (lower, upper) of one run's average
    best : float -- the maximum-likelihood scale of the ladder
    """

    filter: str
    scales: np.ndarray
    log_likelihood: np.ndarray
    nis_averages: np.ndarray
    nis_bounds: tuple
    best: float

    @property
    def inside(self) -> np.ndarray:
        """Scales of the ladder whose time-averaged NIS lies inside ``nis_bounds``."""
        lo, hi = self.nis_bounds
        return self.scales[(self.nis_averages >= lo) & (self.nis_averages <= hi)]


@checked(params=optional(partial(require_instance, cls=CoopParams)))
def fit_q_scale(filter: str, y, scales, params: CoopParams | None = None, *, alpha: float = 0.05,
                **settings) -> QScaleFit:
    """Maximum-likelihood fit of the scale s of ``Q = s * Qtrue`` to the log ``y`` over ``scales``.

    Runs the filter once per scale and keeps the innovation log-likelihood
    (:meth:`FilterResult.log_likelihood`) and the time-averaged NIS; ``best`` maximizes the
    likelihood.  ``inside`` lists the scales whose NIS falls inside the one-run bounds at ``alpha``
    (often many: the NIS alone cannot pick Q).  settings go to :func:`run_filter`.
    """
    filter = require_choice("filter", filter, FILTERS)
    p = params if params is not None else CoopParams()
    scales = np.array([require_positive("scales", s) for s in np.atleast_1d(scales)], dtype=float)
    if scales.size == 0:
        raise ValueError("scales must hold at least one value")
    if not np.isfinite(require_array("y", y)).any():
        raise ValueError("y holds no measurement (every row is NaN)")
    ll, nis = np.empty(scales.size), np.empty(scales.size)
    for i, s in enumerate(scales):  # one run in memory at a time
        r = run_filter(filter, y, p, Q=s * p.Qtrue, **settings)
        ll[i], nis[i] = r.log_likelihood(), r.time_average_nis()
        n, used = int(np.isfinite(r.nis).sum()), len(r.measurements)
        del r
    bounds = _chi2_bounds(used, n, alpha)
    return QScaleFit(filter, scales, ll, nis, bounds, float(scales[int(np.argmax(ll))]))

