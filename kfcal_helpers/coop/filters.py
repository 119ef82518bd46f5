"""LKF, EKF and UKF for cooperative localization, on filterpy's classes.

* LKF -- ``filterpy.kalman.KalmanFilter`` on the perturbation ``dx = x - x_nom`` about
  the nominal trajectory, with ``F_k = I + dT A(x_nom_k)`` and ``H_k = C(x_nom_k)``.
  Its innovation ``(y - y_nom) - H dx-`` is angle-wrapped (fed to filterpy as
  ``z = H dx- + wrapped innovation``, so that filterpy's ``z - H x`` is the wrapped one).
* EKF -- ``filterpy.kalman.ExtendedKalmanFilter`` whose ``predict_x`` is the exact
  nonlinear one-step map (filterpy's own is linear), ``F = I + dT A(x_hat)`` at the
  posterior, and ``update(..., residual=...)`` with bearings wrapped.
* UKF -- ``filterpy.kalman.UnscentedKalmanFilter`` with ``MerweScaledSigmaPoints`` and
  angle-aware ``residual_x``, ``residual_z``, ``x_mean_fn``, ``z_mean_fn`` (circular
  means) and ``state_add``.

Every filter starts at (x0, P0) at t_0 and, for k = 1..K-1, predicts to t_k and updates
with ``y_k`` unless that row is NaN (predict only).  A finite ``y_0`` is used at t_0.
All return a :class:`FilterResult`.  ``Q`` is the filter's covariance of the DT process noise
``w_k``; it enters through the model's ``Omega`` (``params.Omega``, ``dT * I`` by default), as in the
truth model: ``P- = F P F^T + Omega Q Omega^T``.

Every filter accepts ``measurements=`` (indices of the rows of ``y`` it uses, e.g. ``(0, 1, 2)``
for the two bearings and the range without the UAV's GPS): the update then uses only those
components of ``y``, the matching rows of ``h`` and of its Jacobian and the block of ``R``, and the
NIS has that many degrees of freedom.  The default (all five) is the full filter, unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cholesky
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

from ..consistency import nees as _nees
from ..consistency import nis as _nis
from ..validation import require_choice, require_covariance, require_positive, require_shape
from .model import (
    MEAS_ANGLES,
    N_MEAS,
    N_STATES,
    CoopParams,
    _arc,
    jacobian_A,
    jacobian_C,
    measure,
    measurement_mean,
    measurement_residual,
    nominal_trajectory,
    require_last_axis,
    state_add,
    state_mean,
    state_residual,
    wrap_angle,
    wrap_measurement,
    wrap_state,
)

__all__ = [
    "FILTERS",
    "TUNED_Q_SCALE",
    "UKF_POINTS",
    "FilterResult",
    "tuned_Q",
    "FilterSetup",
    "CoopEKF",
    "make_lkf",
    "make_ekf",
    "make_ukf",
    "run_lkf",
    "run_ekf",
    "run_ukf",
    "run_filter",
    "measurement_subset",
    "robust_sqrt",
    "QScaleFit",
    "fit_q_scale",
]

FILTERS = ("lkf", "ekf", "ukf")

#: filter Q = scale * Qtrue (covariance of w_k, entering through Omega = dT I), chosen by the
#: truth-model tests, NEES and NIS together (notebooks 10-12); never tuned on a log.  No scale makes
#: the LKF's NEES consistent (notebook 10), so it keeps Qtrue.
TUNED_Q_SCALE = {"lkf": 1.0, "ekf": 1.0, "ukf": 1.0}

#: Merwe scaled sigma points (alpha, beta, kappa) of the UKF (notebook 12)
UKF_POINTS = {"alpha": 1.0, "beta": 2.0, "kappa": 0.0}


def tuned_Q(name: str, params: CoopParams | None = None) -> np.ndarray:
    """The tuned filter process noise for filter ``name``: the covariance (6x6) of ``w_k``, which
    enters the state as ``Omega Q Omega^T`` per step."""
    name = require_choice("filter", name, FILTERS)
    p = params if params is not None else CoopParams()
    return TUNED_Q_SCALE[name] * p.Qtrue


@dataclass(frozen=True, eq=False)
class FilterResult:
    """Output of one filter run over K samples.

    Attributes
    ----------
    name : str -- "lkf", "ekf" or "ukf"
    t : (K,) s
    x : (K, 6) posterior estimates (prior where there was no measurement), headings wrapped
    P : (K, 6, 6) their covariances
    z_pred : (K, 5) predicted measurements h(x-) (UKF: the sigma-point mean); NaN without a measurement
    innovations : (K, 5) wrapped innovations y - z_pred; NaN without a measurement
    S : (K, 5, 5) innovation covariances; NaN without a measurement
    nis : (K,) normalized innovation squared; NaN without a measurement
    nees : (K,) normalized estimation error squared (headings wrapped), or None without truth
    measurements : tuple of the rows of y the filter used (default all five); with fewer,
        ``z_pred``, ``innovations`` and ``S`` are NaN in the unused components and ``nis``
        has ``len(measurements)`` degrees of freedom
    """

    name: str
    t: np.ndarray
    x: np.ndarray
    P: np.ndarray
    z_pred: np.ndarray
    innovations: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    nees: np.ndarray | None = None
    measurements: tuple = tuple(range(N_MEAS))

    @property
    def sigma2(self) -> np.ndarray:
        """Two-sigma bounds ``2 sqrt(diag P)``, shape (K, 6)."""
        return 2.0 * np.sqrt(np.diagonal(self.P, axis1=-2, axis2=-1))

    def errors(self, truth) -> np.ndarray:
        """Estimation errors ``truth - x`` with the headings wrapped, shape (K, 6)."""
        return state_residual(truth, self.x)

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


@dataclass(frozen=True, eq=False)
class FilterSetup:
    """Validated inputs of a filter run (see :func:`run_filter`)."""

    params: CoopParams
    y: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    x0: np.ndarray
    P0: np.ndarray

    @classmethod
    def build(cls, name, y, params=None, Q=None, R=None, x0=None, P0=None) -> "FilterSetup":
        p = params if params is not None else CoopParams()
        y = require_shape("y", y, (None, N_MEAS))
        if y.shape[0] < 1:
            raise ValueError("y must hold at least one row")
        nan = np.isnan(y)
        if (nan.any(axis=1) & ~nan.all(axis=1)).any() or np.isinf(y).any():
            raise ValueError("y rows must be all finite or all NaN (a NaN row means predict only)")
        Q = tuned_Q(name, p) if Q is None else require_covariance("Q", Q, N_STATES)
        R = p.Rtrue if R is None else require_covariance("R", R, N_MEAS)
        x0 = p.x0 if x0 is None else require_last_axis("x0", require_shape("x0", x0, (N_STATES,)), N_STATES)
        P0 = p.P0 if P0 is None else require_covariance("P0", P0, N_STATES)
        return cls(p, y, np.array(Q), np.array(R), wrap_state(x0), np.array(P0))


def measurement_subset(measurements) -> tuple[int, ...] | None:
    """Validate ``measurements=``: None (all five rows of y) or a non-empty sequence of
    distinct integers in 0..4 (0 bearing UGV->UAV, 1 range, 2 bearing UAV->UGV, 3 UAV GPS east,
    4 UAV GPS north).  Returns None for all five, else the sorted tuple; ValueError otherwise."""
    if measurements is None:
        return None
    allowed = ("measurements must be a non-empty sequence of distinct integers in 0..4 (rows of y: "
               "0 bearing UGV->UAV, 1 range, 2 bearing UAV->UGV, 3 UAV GPS east, 4 UAV GPS north)")
    if isinstance(measurements, (str, bytes)):
        raise ValueError(f"{allowed}, got {measurements!r}")
    try:
        items = list(measurements)
    except TypeError:
        raise ValueError(f"{allowed}, got {measurements!r}") from None
    ok = all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) and 0 <= i < N_MEAS for i in items)
    if not items or not ok or len({int(i) for i in items}) != len(items):
        raise ValueError(f"{allowed}, got {measurements!r}")
    idx = tuple(sorted(int(i) for i in items))
    return None if idx == tuple(range(N_MEAS)) else idx


class _Subset:
    """The measurement functions restricted to the rows ``idx`` of y (bearings still wrapped)."""

    def __init__(self, idx, R):
        self.idx = list(idx)
        self.m = len(self.idx)
        self.angles = [j for j, i in enumerate(self.idx) if i in MEAS_ANGLES]
        self.R = R[np.ix_(self.idx, self.idx)]

    def residual(self, a, b):
        d = np.subtract(a, b, dtype=float)
        if self.angles:
            d[..., self.angles] = wrap_angle(d[..., self.angles])
        return d

    def mean(self, sigmas, weights):  # the UKF's z_mean_fn: circular mean of the bearings
        sigmas = np.asarray(sigmas, dtype=float)
        w = np.asarray(weights, dtype=float)
        mean = np.matmul(w, sigmas)
        if self.angles:
            a = sigmas[..., self.angles]
            mean[..., self.angles] = np.arctan2(np.matmul(w, np.sin(a)), np.matmul(w, np.cos(a)))
        return mean

    def h(self, x):
        return measure(x)[..., self.idx]

    def h_column(self, x):
        return measure(x[:, 0])[self.idx].reshape(self.m, 1)

    def C_column(self, x):
        return jacobian_C(x[:, 0])[self.idx]

    def residual_column(self, a, b):
        return self.residual(a[:, 0], b[:, 0]).reshape(self.m, 1)


def _finish(name, setup, x, P, zp, nu, S, truth, measurements=None) -> FilterResult:
    K = setup.y.shape[0]
    nis = np.full(K, np.nan)
    if measurements is None:
        idx = list(range(N_MEAS))
        has = np.isfinite(nu).all(axis=1)
        nis[has] = _nis(nu[has], S[has])
    else:  # the NIS of the rows used: len(measurements) degrees of freedom
        idx = list(measurements)
        has = np.isfinite(nu[:, idx]).all(axis=1)
        nis[has] = _nis(nu[has][:, idx], S[has][:, idx][:, :, idx])
    nees = None
    if truth is not None:
        truth = require_shape("truth", truth, (K, N_STATES))
        nees = _nees(state_residual(truth, x), P)
    return FilterResult(name, setup.params.dT * np.arange(K), x, P, zp, nu, S, nis, nees, tuple(idx))


def _storage(K):
    return (np.empty((K, N_STATES)), np.empty((K, N_STATES, N_STATES)), np.full((K, N_MEAS), np.nan),
            np.full((K, N_MEAS), np.nan), np.full((K, N_MEAS, N_MEAS), np.nan))


# ---------------------------------------------------------------------------
# LKF
def make_lkf(setup: FilterSetup, measurements=None) -> KalmanFilter:
    """filterpy KalmanFilter on dx = x - x_nom, initialised at dx0 = x0 - x_nom_0.

    ``measurements`` (optional, see :func:`measurement_subset`): a filter for that subset
    of the rows of y (``dim_z = len(measurements)``, R the matching block).
    """
    idx = measurement_subset(measurements)
    kf = KalmanFilter(dim_x=N_STATES, dim_z=N_MEAS if idx is None else len(idx))
    kf.x = state_residual(setup.x0, setup.params.x0).reshape(N_STATES, 1)
    kf.P = setup.P0.copy()
    kf.Q = setup.params.process_noise(setup.Q)
    kf.R = setup.R.copy() if idx is None else setup.R[np.ix_(idx, idx)].copy()
    return kf


def run_lkf(y, params=None, Q=None, R=None, x0=None, P0=None, truth=None,
            subtract_nominal: bool = True, measurements=None) -> FilterResult:
    """Linearized KF about the nominal trajectory; arguments as in :func:`run_filter`.

    ``subtract_nominal=False`` builds a known mistake (notebook 14): the innovation
    ``y - H dx-`` without the nominal measurement ``y*`` subtracted.
    """
    s = FilterSetup.build("lkf", y, params, Q, R, x0, P0)
    idx = measurement_subset(measurements)
    p, K = s.params, s.y.shape[0]
    xnom = nominal_trajectory(p, K)
    ynom = measure(xnom)
    F = np.eye(N_STATES) + p.dT * jacobian_A(xnom, p.u0, p.L)  # (K, 6, 6), F[k] maps k -> k+1
    H = jacobian_C(xnom)  # (K, 5, 6)
    kf = make_lkf(s, idx)
    x, P, zp, nu, S = _storage(K)
    for k in range(K):
        if k > 0:
            kf.predict(F=F[k - 1])
        if not np.isnan(s.y[k, 0]):
            zk = wrap_measurement(ynom[k] + H[k] @ kf.x[:, 0])  # predicted measurement, bearings wrapped
            if not subtract_nominal:
                zk = H[k] @ kf.x[:, 0]  # the mistake: the perturbation model compared with the total y
            innov = measurement_residual(s.y[k], zk)
            if idx is None:
                kf.update((H[k] @ kf.x[:, 0] + innov).reshape(N_MEAS, 1), H=H[k])
                assert kf.x.shape == (N_STATES, 1) and kf.y.shape == (N_MEAS, 1)
                zp[k], nu[k], S[k] = zk, kf.y[:, 0], kf.S
            else:  # only the rows idx of y, H and R
                rows = list(idx)
                kf.update((H[k][rows] @ kf.x[:, 0] + innov[rows]).reshape(len(rows), 1), H=H[k][rows])
                assert kf.x.shape == (N_STATES, 1) and kf.y.shape == (len(rows), 1)
                zp[k, rows], nu[k, rows] = zk[rows], kf.y[:, 0]
                S[k][np.ix_(rows, rows)] = kf.S
        x[k], P[k] = kf.x[:, 0], kf.P
    x = wrap_state(xnom + x)
    return _finish("lkf", s, x, P, zp, nu, S, truth, idx)


# ---------------------------------------------------------------------------
# EKF
class CoopEKF(ExtendedKalmanFilter):
    """filterpy's ExtendedKalmanFilter with the nonlinear closed-form propagation.

    ``predict()`` calls :meth:`predict_x` and then ``P = F P F^T + Q``: here
    ``predict_x`` first sets ``F = I + dT A(x_hat_k, u)`` at the posterior and then
    moves the mean with the exact map ``x_hat_{k+1}^- = phi(x_hat_k, u)``.
    """

    def __init__(self, params: CoopParams):
        super().__init__(dim_x=N_STATES, dim_z=N_MEAS)
        self.params = params

    def predict_x(self, u=0):
        p = self.params
        xk = self.x[:, 0]
        self.F = np.eye(N_STATES) + p.dT * jacobian_A(xk, p.u0, p.L)
        self.x = _arc(xk, p.u0, p.dT, p.L).reshape(N_STATES, 1)


def _h_column(x):
    return measure(x[:, 0]).reshape(N_MEAS, 1)


def _C_column(x):
    return jacobian_C(x[:, 0])


def _residual_column(a, b):
    return measurement_residual(a[:, 0], b[:, 0]).reshape(N_MEAS, 1)


def make_ekf(setup: FilterSetup) -> CoopEKF:
    """A :class:`CoopEKF` initialised at (x0, P0) with the setup's Q and R."""
    ekf = CoopEKF(setup.params)
    ekf.x = setup.x0.reshape(N_STATES, 1).copy()
    ekf.P = setup.P0.copy()
    ekf.Q = setup.params.process_noise(setup.Q)
    ekf.R = setup.R.copy()
    return ekf


def run_ekf(y, params=None, Q=None, R=None, x0=None, P0=None, truth=None,
            wrap_innovations: bool = True, measurements=None) -> FilterResult:
    """Extended KF; arguments as in :func:`run_filter`.

    ``wrap_innovations=False`` passes filterpy's default ``residual=np.subtract``: only
    to demonstrate the pitfall (bearing innovations jump by 2 pi across +-pi).
    """
    s = FilterSetup.build("ekf", y, params, Q, R, x0, P0)
    idx = measurement_subset(measurements)
    K = s.y.shape[0]
    ekf = make_ekf(s)
    x, P, zp, nu, S = _storage(K)
    if idx is None:
        rows, m, Hj, hx, res, R_used = slice(None), N_MEAS, _C_column, _h_column, _residual_column, None
    else:  # only the rows idx of y, h, its Jacobian and R
        sub = _Subset(idx, s.R)
        rows, m, Hj, hx, res, R_used = list(idx), len(idx), sub.C_column, sub.h_column, sub.residual_column, sub.R
    for k in range(K):
        if k > 0:
            ekf.predict()
        if not np.isnan(s.y[k, 0]):
            yk = s.y[k, rows]
            ekf.update(yk.reshape(m, 1), HJacobian=Hj, Hx=hx, R=R_used,
                       residual=res if wrap_innovations else np.subtract)
            assert ekf.x.shape == (N_STATES, 1) and ekf.y.shape == (m, 1)
            ekf.x = wrap_state(ekf.x[:, 0]).reshape(N_STATES, 1)
            if idx is None:
                nu[k], S[k] = ekf.y[:, 0], ekf.S
                zp[k] = measurement_residual(s.y[k], nu[k])  # h(x-), from y - nu
            else:
                nu[k, rows], S[k][np.ix_(rows, rows)] = ekf.y[:, 0], ekf.S
                zp[k, rows] = sub.residual(yk, ekf.y[:, 0])  # h(x-) on the rows used
        x[k], P[k] = ekf.x[:, 0], ekf.P
    return _finish("ekf", s, x, P, zp, nu, S, truth, idx)


# ---------------------------------------------------------------------------
# UKF
class _CoopUKF(UnscentedKalmanFilter):
    """filterpy's UKF with f and h evaluated on all 13 sigma points in one vectorised call.

    The filter equations are filterpy's: only the per-sigma-point Python loops over
    ``fx`` and ``hx`` are replaced by one array call each (same numbers, ~2x faster).
    """

    def compute_process_sigmas(self, dt, fx=None, **fx_args):
        fx = self.fx if fx is None else fx
        self.sigmas_f = fx(self.points_fn.sigma_points(self.x, self.P), dt, **fx_args)

    def update(self, z, R=None, UT=None, hx=None, **hx_args):
        rows = iter((self.hx if hx is None else hx)(self.sigmas_f, **hx_args))
        super().update(z, R=R, UT=UT, hx=lambda _sigma: next(rows))


def robust_sqrt(M) -> np.ndarray:
    """Upper Cholesky factor ``U`` (``U^T U = M``) of the symmetrized ``M``, for the sigma points.

    filterpy's UKF updates ``P - K S K^T``, which can lose symmetry and, rarely, positive
    definiteness by rounding.  This symmetrizes ``M`` and, if the Cholesky factorization still
    fails, adds a jitter ``eps * I`` with ``eps`` growing from ``1e-12 * trace(M)/n`` by factors of
    10 (at most 10 tries); ValueError if ``M`` is not finite or no jitter helps.
    """
    M = np.asarray(M, dtype=float)
    if not np.all(np.isfinite(M)):
        raise ValueError("P: the UKF covariance holds non-finite numbers (the filter diverged)")
    M = 0.5 * (M + M.T)
    try:
        return cholesky(M, lower=False)
    except np.linalg.LinAlgError:
        pass
    n = M.shape[0]
    eps = 1e-12 * max(float(np.trace(M)) / n, 1e-300)
    for _ in range(10):
        try:
            return cholesky(M + eps * np.eye(n), lower=False)
        except np.linalg.LinAlgError:
            eps *= 10.0
    raise ValueError("P: the UKF covariance is not positive definite, even with a jitter of "
                     f"{eps / 10:.1e} on its diagonal (the filter diverged)")


def make_ukf(setup: FilterSetup, alpha=None, beta=None, kappa=None) -> UnscentedKalmanFilter:
    """filterpy UnscentedKalmanFilter with Merwe scaled sigma points and the angle functions."""
    p = setup.params
    alpha = require_positive("alpha", UKF_POINTS["alpha"] if alpha is None else alpha)
    beta = float(UKF_POINTS["beta"] if beta is None else beta)
    kappa = float(UKF_POINTS["kappa"] if kappa is None else kappa)
    if alpha > 1 or N_STATES + kappa <= 0:
        raise ValueError(f"alpha must be in (0, 1] and kappa > -6, got alpha={alpha:g}, kappa={kappa:g}")
    # sigma points x +- columns of sqrt((n+lambda) P) need no wrapping: f and h are 2 pi-periodic in the headings
    points = MerweScaledSigmaPoints(N_STATES, alpha=alpha, beta=beta, kappa=kappa)
    points.sqrt = robust_sqrt  # symmetrize P, Cholesky with jitter if needed

    def fx(sigmas, dt):  # all sigma points at once, shape (13, 6)
        return _arc(sigmas, p.u0, dt, p.L)

    ukf = _CoopUKF(dim_x=N_STATES, dim_z=N_MEAS, dt=p.dT, hx=measure, fx=fx, points=points,
                   x_mean_fn=state_mean, z_mean_fn=measurement_mean,
                   residual_x=state_residual, residual_z=measurement_residual, state_add=state_add)
    ukf.x = setup.x0.copy()
    ukf.P = setup.P0.copy()
    ukf.Q = setup.params.process_noise(setup.Q)
    ukf.R = setup.R.copy()
    return ukf


def run_ukf(y, params=None, Q=None, R=None, x0=None, P0=None, truth=None,
            alpha=None, beta=None, kappa=None, measurements=None) -> FilterResult:
    """Unscented KF; arguments as in :func:`run_filter`, plus the sigma-point parameters."""
    s = FilterSetup.build("ukf", y, params, Q, R, x0, P0)
    idx = measurement_subset(measurements)
    K = s.y.shape[0]
    ukf = make_ukf(s, alpha, beta, kappa)
    rows, m = slice(None), N_MEAS
    if idx is not None:  # h, the z mean and residual (bearings still circular) and R on the rows idx
        sub = _Subset(idx, s.R)
        rows, m = list(idx), len(idx)
        ukf.hx, ukf.z_mean, ukf.residual_z, ukf.R = sub.h, sub.mean, sub.residual, sub.R
    x, P, zp, nu, S = _storage(K)
    for k in range(K):
        if k > 0:
            ukf.predict()
            ukf.P = 0.5 * (ukf.P + ukf.P.T)
        elif not np.isnan(s.y[0, 0]):  # update at t_0: sigma points of the initial (x0, P0)
            ukf.sigmas_f = ukf.points_fn.sigma_points(ukf.x, ukf.P)
        if not np.isnan(s.y[k, 0]):
            yk = s.y[k, rows]
            ukf.update(yk)
            assert ukf.x.shape == (N_STATES,) and ukf.y.shape == (m,)
            ukf.P = 0.5 * (ukf.P + ukf.P.T)
            if idx is None:
                nu[k], S[k] = ukf.y, ukf.S
                zp[k] = measurement_residual(s.y[k], ukf.y)  # the sigma-point mean z-
            else:
                nu[k, rows], S[k][np.ix_(rows, rows)] = ukf.y, ukf.S
                zp[k, rows] = sub.residual(yk, ukf.y)  # the sigma-point mean z- on the rows used
        x[k], P[k] = ukf.x, ukf.P
    return _finish("ukf", s, x, P, zp, nu, S, truth, idx)


_RUNNERS = {"lkf": run_lkf, "ekf": run_ekf, "ukf": run_ukf}


def run_filter(name: str, y, params: CoopParams | None = None, Q=None, R=None, x0=None, P0=None,
               truth=None, measurements=None, **kwargs) -> FilterResult:
    """Run filter ``name`` ("lkf", "ekf", "ukf") on measurements ``y``.

    Parameters
    ----------
    y : array (K, 5) -- one row per t_k = k dT; an all-NaN row means predict only
    params : CoopParams -- model, nominal, dT; defaults to the course's
    Q : (6, 6) filter process noise per step (default :func:`tuned_Q`)
    R : (5, 5) measurement noise (default ``params.Rtrue``)
    x0, P0 : initial estimate (6,) and covariance (6, 6) (default ``params.x0``, ``params.P0``)
    truth : (K, 6), optional -- true states, for the NEES
    measurements : optional sequence of the rows of y to use (distinct integers in 0..4: 0 bearing
        UGV->UAV, 1 range, 2 bearing UAV->UGV, 3 UAV GPS east, 4 UAV GPS north); default all five.
        The update uses only those components (rows of h and its Jacobian, block of R) and the
        NIS has ``len(measurements)`` degrees of freedom.  ValueError if malformed.
    kwargs : UKF only: alpha, beta, kappa; EKF only: wrap_innovations; LKF only: subtract_nominal

    Returns
    -------
    FilterResult
    """
    name = require_choice("filter", name, FILTERS)
    return _RUNNERS[name](y, params, Q, R, x0, P0, truth, measurements=measurements, **kwargs)


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


def fit_q_scale(name: str, y, scales, params: CoopParams | None = None, alpha: float = 0.05,
                **kwargs) -> QScaleFit:
    """Maximum-likelihood fit of the scale s of ``Q = s * Qtrue`` to the log ``y`` over ``scales``.

    Runs the filter once per scale and keeps the innovation log-likelihood
    (:meth:`FilterResult.log_likelihood`) and the time-averaged NIS; ``best`` maximizes the
    likelihood.  ``inside`` lists the scales whose NIS falls inside the one-run bounds at ``alpha``
    (often many: the NIS alone cannot pick Q).  kwargs go to :func:`run_filter`.
    """
    from ..consistency import chi2_bounds

    name = require_choice("filter", name, FILTERS)
    p = params if params is not None else CoopParams()
    scales = np.array([require_positive("scales", s) for s in np.atleast_1d(scales)], dtype=float)
    if scales.size == 0:
        raise ValueError("scales must hold at least one value")
    results = [run_filter(name, y, p, Q=s * p.Qtrue, **kwargs) for s in scales]
    ll = np.array([r.log_likelihood() for r in results])
    nis = np.array([r.time_average_nis() for r in results])
    n = int(np.isfinite(results[0].nis).sum())
    bounds = chi2_bounds(len(results[0].measurements), n, alpha)
    return QScaleFit(name, scales, ll, nis, bounds, float(scales[int(np.argmax(ll))]))

