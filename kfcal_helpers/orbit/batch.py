"""LKF, EKF and UKF on N realizations at once: filterpy's equations on stacked arrays, for the Monte Carlo.

The per-run filters of :mod:`~kfcal_helpers.orbit.filters` (filterpy's classes) stay the reference; here
every quantity has a leading run axis: states (N, 4), covariances (N, 4, 4), the UKF's sigma points
(N, 9, 4).  The stations with a measurement differ between runs (each truth passes over its own
stations at its own times), so at step k every run's measurement is laid out in ``M_k`` slots, ``M_k``
the most stations any run has at that step: run r's stations first, in increasing order, then padding.
A padded slot is masked so that it changes nothing: its rows of H (or of the sigma points' h) and its
innovation are zero and its block of R is ``R`` itself, so S is block diagonal, the gain's columns of
the padded slots are zero, and the update, the Joseph form and the NIS equal those of the stations
present alone (filterpy with ``dim_z = 3 m_k``), to rounding.  A step where no run has a station is
predict only.

The equations are those of ``filters.py``; the EKF's and UKF's gain ``K = cross S^-1`` comes from one
solve with S instead of filterpy's ``inv(S)`` (rounding only).  ``tests/test_orbit_batch.py`` proves the
batch equal to the per-run filterpy filters on the same draws to 1e-9.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints

from ..batching import BatchArrays
from ..unscented import batch_sigma_points, gain_solve, mT, unscented_moments
from ..validation import checked, require_array, require_bool, require_instance
from .filters import FilterSetup, check_measurements
from .model import jacobian_relative, measure_relative, measurement_layout, nominal_trajectory, require_states, station_states
from .params import N_STATES, N_STATION_MEAS

__all__ = ["BatchResult", "run_batch", "run_lkf_batch", "run_ekf_batch", "run_ukf_batch"]


@dataclass(frozen=True, eq=False)
class BatchResult(BatchArrays):
    """A filter run on N realizations over K samples.

    filter : "lkf", "ekf" or "ukf"; t : (K,) s
    nis : (N, K) NIS, NaN where a run had no station; dof : (N, K) its degrees of freedom, 3 per station
    sigma2 : (N, K, 4) two-sigma bounds ``2 sqrt(diag P_post)`` (km, km/s)
    nees : (N, K) and errors : (N, K, 4) ``truth - x_post`` when the truth was given, else None
    x : (N, K, 4) and P : (N, K, 4, 4) the posterior estimates when kept (``keep_estimates``), else None
    """

    dof: np.ndarray | None = None


def _inputs(y, setup, truth):
    s = require_instance("setup", setup, FilterSetup)
    y = require_array("y", y)
    if y.ndim != 4:
        raise ValueError(f"y must have shape (n_runs, K, n_stations, 3), got {y.shape}")
    for run in y:  # the per-run checks, run by run
        check_measurements(run, s.params)
    if truth is not None:
        truth = require_states("truth", truth)
        if truth.shape != y.shape[:2] + (N_STATES,):
            raise ValueError(f"truth must have shape {y.shape[:2] + (N_STATES,)}, got {truth.shape}")
    return s, y, truth


class _Slots:
    """The stations of step k laid out in M slots per run: ``order`` (N, M) station indices (the run's
    stations first, increasing), ``valid`` (N, M), ``z`` (N, 3M) their measurements (0 in padding),
    ``at`` (N, M, 4) the slots' station states, ``R`` (3M, 3M) block diagonal."""

    _R = {}  # (M, R bytes) -> the block-diagonal R

    def __init__(self, yk, R, stations_k):
        have = np.isfinite(yk[..., 0])  # (N, n_stations): rows are all finite or all NaN (checked)
        self.count = have.sum(axis=1)
        self.M = M = int(self.count.max())
        if not M:
            return
        n = len(yk)
        self.order = np.argsort(~have, axis=1, kind="stable")[:, :M]
        rows = np.arange(n)[:, None]
        self.valid = have[rows, self.order]
        self.z = np.where(self.valid[..., None], yk[rows, self.order], 0.0).reshape(n, N_STATION_MEAS * M)
        self.at = stations_k[self.order]  # (N, M, 4)
        self.mask = np.repeat(self.valid, N_STATION_MEAS, axis=1)  # (N, 3M)
        key = (M, R.tobytes())
        if key not in self._R:
            self._R[key] = np.kron(np.eye(M), R)
        self.R = self._R[key]
        self.layout = measurement_layout(M)

    def h(self, x):
        """The slots' measurements (N, [points,] 3M) of states ``x`` (N, [points,] 4), zero in padding."""
        extra = x.ndim - 2
        at = self.at.reshape(self.at.shape[:1] + (1,) * extra + self.at.shape[1:])
        m = measure_relative(x[..., None, :] - at)  # (N, [points,] M, 3)
        m = m.reshape(m.shape[:-2] + (N_STATION_MEAS * self.M,))
        return np.where(self.mask.reshape(self.mask.shape[:1] + (1,) * extra + self.mask.shape[1:]), m, 0.0)

    def H(self, x):
        """The slots' rows of the Jacobian (N, 3M, 4) at states ``x`` (N, 4), zero in padding."""
        C = jacobian_relative(x[:, None, :] - self.at).reshape(len(x), N_STATION_MEAS * self.M, N_STATES)
        return np.where(self.mask[..., None], C, 0.0)


class _Store:
    def __init__(self, n, K, truth, keep):
        self.truth = truth
        self.nis = np.full((n, K), np.nan)
        self.dof = np.zeros((n, K), dtype=int)
        self.sigma2 = np.empty((n, K, N_STATES))
        self.nees = None if truth is None else np.empty((n, K))
        self.errors = None if truth is None else np.empty((n, K, N_STATES))
        self.x = np.empty((n, K, N_STATES)) if keep else None
        self.P = np.empty((n, K, N_STATES, N_STATES)) if keep else None

    def innovation(self, k, slots, nu, SInu):
        has = slots.count > 0
        self.nis[has, k] = (nu * SInu).sum(axis=-1)[has]
        self.dof[:, k] = N_STATION_MEAS * slots.count

    def posterior(self, k, x, P):
        self.sigma2[:, k] = 2.0 * np.sqrt(np.diagonal(P, axis1=-2, axis2=-1))
        if self.truth is not None:
            err = self.truth[:, k] - x
            self.errors[:, k] = err
            self.nees[:, k] = (err * np.linalg.solve(P, err[..., None])[..., 0]).sum(axis=-1)
        if self.x is not None:
            self.x[:, k], self.P[:, k] = x, P

    def result(self, setup, K):
        bad = ~np.isfinite(self.sigma2).all(axis=(1, 2))
        if self.nees is not None:
            bad |= ~np.isfinite(self.nees).all(axis=1)
        if bad.any():
            raise ValueError(f"y: the {setup.filter.upper()} diverged (non-finite estimate) in run "
                             f"{int(np.argmax(bad))} of the batch")
        return BatchResult(setup.filter, setup.params.dt * np.arange(K), self.nis, self.sigma2, self.nees, self.errors,
                           self.x, self.P, self.dof)


def _common(s, y, truth, keep):
    """What every batched filter sets up: params, K, the per-step process noise, the station states (K,
    n_stations, 4) and the store of the per-run arrays."""
    p, K = s.params, y.shape[1]
    return p, K, p.process_noise(s.Q), station_states(p.dt * np.arange(K), p), _Store(len(y), K, truth, keep)


def _joseph(P, gain, H, R):
    I_KH = np.eye(N_STATES) - gain @ H
    return I_KH @ P @ mT(I_KH) + gain @ R @ mT(gain)


# ---------------------------------------------------------------------------
def run_lkf_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Linearized KF about the nominal on ``y`` (N, K, n_stations, 3), ``truth`` (N, K, 4) optional:
    filterpy's ``KalmanFilter`` equations (Joseph update) on ``dx = x - x_nom``, per run."""
    s, y, truth = _inputs(y, setup, truth)
    p = s.params
    n, K = y.shape[:2]
    t = p.dt * np.arange(K)
    xnom = nominal_trajectory(p, K)
    F, Q = s.F(xnom), p.process_noise(s.Q)
    stations = station_states(t, p)  # (K, n_stations, 4)
    out = _Store(n, K, truth, keep_estimates)
    dx, P = np.tile(s.x0 - xnom[0], (n, 1)), np.tile(s.P0, (n, 1, 1))
    for k in range(K):
        if k > 0:
            dx = dx @ F[k - 1].T
            P = F[k - 1] @ P @ F[k - 1].T + Q
        slots = _Slots(y[:, k], s.R, stations[k])
        if slots.M:
            at_nominal = np.broadcast_to(xnom[k], (n, N_STATES))
            H, ynom = slots.H(at_nominal), slots.h(at_nominal)
            dz = (H @ dx[..., None])[..., 0]
            innov = slots.layout.residual(slots.z, slots.layout.wrap(ynom + dz))
            nu = (dz + innov) - (H @ dx[..., None])[..., 0]  # filterpy's z - H x with z = H dx- + innovation
            PHT = P @ mT(H)
            gain, SInu = gain_solve(H @ PHT + slots.R, PHT, nu)
            dx = dx + (gain @ nu[..., None])[..., 0]
            P = _joseph(P, gain, H, slots.R)
            out.innovation(k, slots, nu, SInu)
        out.posterior(k, xnom[k] + dx, P)
    return out.result(s, K)


def run_ekf_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Extended KF on ``y`` (N, K, n_stations, 3), ``truth`` (N, K, 4) optional: filterpy's
    ``ExtendedKalmanFilter`` equations as :class:`~kfcal_helpers.orbit.filters.OrbitEKF` uses them."""
    s, y, truth = _inputs(y, setup, truth)
    p, K, Q, stations, out = _common(s, y, truth, keep_estimates)
    x, P = np.tile(s.x0, (len(y), 1)), np.tile(s.P0, (len(y), 1, 1))  # (x0, P0) of every run
    for k in range(K):
        if k > 0:
            F = s.F(x)
            x = s.fx(x)
            P = F @ P @ mT(F) + Q
        slots = _Slots(y[:, k], s.R, stations[k])
        if slots.M:
            H = slots.H(x)
            nu = np.where(slots.mask, slots.layout.residual(slots.z, slots.h(x)), 0.0)
            PHT = P @ mT(H)
            gain, SInu = gain_solve(H @ PHT + slots.R, PHT, nu)
            x = x + (gain @ nu[..., None])[..., 0]
            P = _joseph(P, gain, H, slots.R)
            out.innovation(k, slots, nu, SInu)
        out.posterior(k, x, P)
    return out.result(s, K)


def _plain_mean(points, weights):
    return np.matmul(weights, points)


def run_ukf_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Unscented KF on ``y`` (N, K, n_stations, 3), ``truth`` (N, K, 4) optional: filterpy's
    ``UnscentedKalmanFilter`` equations as :func:`~kfcal_helpers.orbit.filters.make_ukf` sets them up, on
    (N, 9, 4) sigma points; P symmetrized after every predict and update."""
    s, y, truth = _inputs(y, setup, truth)
    p, K, Q, stations, out = _common(s, y, truth, keep_estimates)
    points = MerweScaledSigmaPoints(N_STATES, alpha=s.alpha, beta=s.beta, kappa=s.kappa)
    Wm, Wc = points.Wm, points.Wc
    x, P = np.tile(s.x0, (len(y), 1)), np.tile(s.P0, (len(y), 1, 1))
    sigmas_f = None
    for k in range(K):
        slots = _Slots(y[:, k], s.R, stations[k])
        if k > 0:
            x, _, P = unscented_moments(s.fx(batch_sigma_points(x, P, points)), _plain_mean, Wm, Wc, np.subtract)
            P = P + Q
            sigmas_f = batch_sigma_points(x, P, points)
            P = 0.5 * (P + mT(P))
        elif slots.M:
            sigmas_f = batch_sigma_points(x, P, points)
        if slots.M:
            sigmas_h = slots.h(sigmas_f)  # (N, 9, 3M), zero in padding
            zp, dz, S = unscented_moments(sigmas_h, slots.layout.mean, Wm, Wc, slots.layout.residual)
            Pxz = mT((sigmas_f - x[:, None, :]) * Wc[:, None]) @ dz
            nu = np.where(slots.mask, slots.layout.residual(slots.z, zp), 0.0)
            gain, SInu = gain_solve(S + slots.R, Pxz, nu)
            x = x + (gain @ nu[..., None])[..., 0]
            P = P - gain @ (S + slots.R) @ mT(gain)
            P = 0.5 * (P + mT(P))
            out.innovation(k, slots, nu, SInu)
        out.posterior(k, x, P)
    return out.result(s, K)


_RUNNERS = {"lkf": run_lkf_batch, "ekf": run_ekf_batch, "ukf": run_ukf_batch}


@checked(keep_estimates=require_bool)
def run_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Run the filter ``setup.filter`` on the measurements ``y`` (N, K, n_stations, 3) of N realizations
    (NaN where a station has no measurement; the stations may differ between runs), with ``truth``
    (N, K, 4) for the NEES and errors if given; ``keep_estimates`` also keeps x (N, K, 4) and P (N, K, 4, 4).
    ValueError naming ``y`` if a run diverges."""
    s = require_instance("setup", setup, FilterSetup)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        try:
            return _RUNNERS[s.filter](y, s, truth, keep_estimates=keep_estimates)
        except np.linalg.LinAlgError:
            raise ValueError(f"y: the {s.filter.upper()} diverged (a covariance became singular)") from None
