"""LKF, EKF and UKF run on N realizations at once: filterpy's equations on stacked arrays.

The per-run filters of :mod:`~kfcal_helpers.coop.filters` are filterpy's classes, one run at a time;
they stay the reference and the path for a single log.  The truth-model Monte Carlo filters many
independent realizations with the *same* setup, so here every quantity carries a leading run axis:
states ``x`` (N, 6), covariances ``P`` (N, 6, 6), gains ``K`` (N, 6, m), the UKF's sigma points
(N, 13, 6).  The equations are the ones filterpy applies in ``filters.py`` (one difference of
rounding only: the EKF's and UKF's gain ``K = cross S^-1`` comes from one solve with S instead of
filterpy's ``inv(S)``):

* LKF (``KalmanFilter`` on ``dx = x - x_nom``): ``P- = F P F^T + Omega Q Omega^T``, ``S = H P H^T + R``,
  ``K = P H^T S^-1``, Joseph update ``P = (I - K H) P (I - K H)^T + K R K^T``; the innovation
  ``(y - y_nom) - H dx-`` with its bearings wrapped (``subtract_nominal=False``: the mistake
  ``y - H dx-``).  F and H come from the nominal trajectory, so P, S and K do not depend on the data:
  they are computed once, with (6, 6) matrices, and applied to every run.
* EKF (``ExtendedKalmanFilter``): ``F = I + dt A(x+)`` at the posterior, ``x- = phi(x+)`` (the exact
  one-step map), the same P prediction and Joseph update with ``H = C(x-)``, the wrapped innovation
  ``y - h(x-)`` (``wrap_innovations=False``: the mistake ``np.subtract``), headings wrapped after it.
* UKF (``UnscentedKalmanFilter`` with ``MerweScaledSigmaPoints``, filterpy's weights): sigma points
  ``x``, ``x + U_i``, ``x - U_i`` from the rows of the upper Cholesky factor of the symmetrized
  ``(n + lambda) P`` (with the jitter fallback of :func:`~kfcal_helpers.coop.filters.robust_sqrt`),
  circular means and wrapped residuals of :data:`~kfcal_helpers.coop.model.STATE` and of the
  measurement model, ``P = P - K S K^T``, P symmetrized after every predict and update.

Every filter starts at (x0, P0) at t_0 and, for k = 1..K-1, predicts to t_k and updates with ``y_k``
unless that row is NaN (predict only), with the rows of the setup's measurement model.  The NaN rows
must be the same in every run (the Monte Carlo thins all runs alike).

:func:`run_batch` is the entry; ``tests/test_coop_batch.py`` proves it equal to the per-run filterpy
filters on the same draws.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints

from ..batching import BatchArrays
from ..unscented import batch_sigma_points, gain_solve, mT, unscented_moments
from ..validation import checked, optional, require_array, require_bool, require_instance
from .filters import FilterSetup
from .model import N_MEAS, N_STATES, STATE, arc, jacobian_A, nominal_trajectory

__all__ = ["BatchResult", "run_batch", "run_lkf_batch", "run_ekf_batch", "run_ukf_batch", "batch_sigma_points"]


@dataclass(frozen=True, eq=False)
class BatchResult(BatchArrays):
    """Output of a filter run on N realizations over K samples.

    filter : "lkf", "ekf" or "ukf"; t : (K,) s; measurements : the rows of y used (the NIS has
    ``len(measurements)`` degrees of freedom)
    nis : (N, K) normalized innovation squared, NaN at steps without a measurement
    sigma2 : (N, K, 6) two-sigma bounds ``2 sqrt(diag P+)`` (m, rad)
    nees : (N, K) and errors : (N, K, 6) ``truth - x+`` (headings wrapped) when the truth was given,
    else None
    x : (N, K, 6) and P : (N, K, 6, 6) the estimates (``x_post``, ``P_post``) when kept
    (``keep_estimates=True``), else None
    """

    measurements: tuple = tuple(range(N_MEAS))


def _check_inputs(y, truth):
    y = np.asarray(y, dtype=float)
    if y.ndim != 3 or y.shape[2] != N_MEAS or y.shape[0] < 1 or y.shape[1] < 1:
        raise ValueError(f"y must have shape (n_runs, K, {N_MEAS}) with n_runs, K >= 1, got {y.shape}")
    nan = np.isnan(y)
    if (nan.any(axis=2) & ~nan.all(axis=2)).any() or np.isinf(y).any():
        raise ValueError("y rows must be all finite or all NaN (a NaN row means predict only)")
    rows = nan.all(axis=2)
    if (rows != rows[:1]).any():
        raise ValueError("y: the NaN rows (predict only) must be the same in every run")
    if truth is not None:
        truth = np.asarray(truth, dtype=float)
        if truth.shape != y.shape[:2] + (N_STATES,):
            raise ValueError(f"truth must have shape {y.shape[:2] + (N_STATES,)}, got {truth.shape}")
        if not np.all(np.isfinite(truth)):
            raise ValueError("truth must hold only finite numbers")
    return y, ~rows[0], truth


class _Store:
    """The per-run arrays kept at every step."""

    def __init__(self, n, K, truth, keep):
        self.truth = truth
        self.nis = np.full((n, K), np.nan)
        self.sigma2 = np.empty((n, K, N_STATES))
        self.nees = None if truth is None else np.empty((n, K))
        self.errors = None if truth is None else np.empty((n, K, N_STATES))
        self.x = np.empty((n, K, N_STATES)) if keep else None
        self.P = np.empty((n, K, N_STATES, N_STATES)) if keep else None

    def innovation(self, k, y, SIy):
        """NIS of the innovations ``y`` (N, m), given ``S^-1 y`` (N, m)."""
        self.nis[:, k] = (y * SIy).sum(axis=-1)

    def posterior(self, k, x, P):
        """Keep the posterior ``x`` (N, 6) and ``P`` (N, 6, 6) or (6, 6) at step k."""
        P = np.broadcast_to(P, x.shape[:1] + (N_STATES, N_STATES))
        self.sigma2[:, k] = 2.0 * np.sqrt(np.diagonal(P, axis1=-2, axis2=-1))
        if self.truth is not None:
            err = STATE.residual(self.truth[:, k], x)
            self.errors[:, k] = err
            self.nees[:, k] = (err * np.linalg.solve(P, err[..., None])[..., 0]).sum(axis=-1)
        if self.x is not None:
            self.x[:, k], self.P[:, k] = x, P

    def result(self, setup, K, has):
        bad = ~np.isfinite(self.sigma2).all(axis=(1, 2)) | ~np.isfinite(self.nis[:, has]).all(axis=1)
        if self.nees is not None:
            bad |= ~np.isfinite(self.nees).all(axis=1)
        if bad.any():
            raise ValueError(f"y: the {setup.filter.upper()} diverged (non-finite estimate) in run "
                             f"{int(np.argmax(bad))} of the batch")
        return BatchResult(setup.filter, setup.params.dt * np.arange(K), self.nis, self.sigma2, self.nees,
                           self.errors, self.x, self.P, setup.measurement.rows)


def _one_error(run):
    """``run`` without numpy's warnings: a diverging run ends in one ValueError (:meth:`_Store.result`)."""
    name = run.__name__[4:7].upper()

    @functools.wraps(run)
    def quiet(*args, **kwargs):
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            try:
                return run(*args, **kwargs)
            except np.linalg.LinAlgError:
                raise ValueError(f"y: the {name} diverged (a covariance became singular)") from None
    return quiet


# ---------------------------------------------------------------------------
# LKF
@_one_error
def run_lkf_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Linearized KF on measurements ``y`` (N, K, 5) of N runs, true states ``truth`` (N, K, 6) optional.

    filterpy's ``KalmanFilter`` equations (Joseph update) on the perturbation about the nominal; the
    covariances and gains, which do not depend on the data, are computed once for all runs.
    """
    s = require_instance("setup", setup, FilterSetup)
    y, has, truth = _check_inputs(y, truth)
    p, model = s.params, s.measurement
    n, K = y.shape[:2]
    rows = list(model.rows)
    xnom = nominal_trajectory(p, K)
    ynom = model.h(xnom)
    F = np.eye(N_STATES) + p.dt * jacobian_A(xnom, p.u0, p.L)
    H = model.jacobian(xnom)
    Q, R, eye = p.process_noise(s.Q), model.R, np.eye(N_STATES)
    out = _Store(n, K, truth, keep_estimates)
    dx = np.broadcast_to(STATE.residual(s.x0, p.x0), (n, N_STATES)).copy()
    P = s.P0.copy()
    for k in range(K):
        if k > 0:
            dx = dx @ F[k - 1].T
            P = F[k - 1] @ P @ F[k - 1].T + Q
        if has[k]:
            Hk = H[k]
            PHT = P @ Hk.T
            S = Hk @ PHT + R
            SI = np.linalg.inv(S)
            gain = PHT @ SI
            dz = dx @ Hk.T
            zk = model.wrap(ynom[k] + dz) if s.subtract_nominal else dz
            innov = model.residual(y[:, k, rows], zk)
            nu = (dz + innov) - dx @ Hk.T  # filterpy's z - H x, with z = H dx- + wrapped innovation
            dx = dx + nu @ gain.T
            I_KH = eye - gain @ Hk
            P = I_KH @ P @ I_KH.T + gain @ R @ gain.T
            out.innovation(k, nu, nu @ SI.T)
        out.posterior(k, STATE.wrap(xnom[k] + dx), P)
    return out.result(s, K, has)


# ---------------------------------------------------------------------------
# EKF
@_one_error
def run_ekf_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Extended KF on measurements ``y`` (N, K, 5) of N runs, true states ``truth`` (N, K, 6) optional.

    filterpy's ``ExtendedKalmanFilter`` equations as :class:`~kfcal_helpers.coop.filters.CoopEKF` uses
    them, on (N, 6) states and (N, 6, 6) covariances.
    """
    s = require_instance("setup", setup, FilterSetup)
    y, has, truth = _check_inputs(y, truth)
    p, model = s.params, s.measurement
    n, K = y.shape[:2]
    rows = list(model.rows)
    Q, R, eye = p.process_noise(s.Q), model.R, np.eye(N_STATES)
    out = _Store(n, K, truth, keep_estimates)
    x = np.broadcast_to(s.x0, (n, N_STATES)).copy()
    P = np.broadcast_to(s.P0, (n, N_STATES, N_STATES)).copy()
    for k in range(K):
        if k > 0:
            F = eye + p.dt * jacobian_A(x, p.u0, p.L)
            x = arc(x, p.u0, p.dt, p.L)
            P = F @ P @ mT(F) + Q
        if has[k]:
            H = model.jacobian(x)
            PHT = P @ mT(H)
            S = H @ PHT + R
            z = y[:, k, rows]
            nu = model.residual(z, model.h(x)) if s.wrap_innovations else z - model.h(x)
            gain, SInu = gain_solve(S, PHT, nu)
            x = x + (gain @ nu[..., None])[..., 0]
            I_KH = eye - gain @ H
            P = I_KH @ P @ mT(I_KH) + gain @ R @ mT(gain)
            x = STATE.wrap(x)
            out.innovation(k, nu, SInu)
        out.posterior(k, x, P)
    return out.result(s, K, has)


# ---------------------------------------------------------------------------
# UKF
def _merwe(setup):
    pts = setup.points
    return MerweScaledSigmaPoints(N_STATES, alpha=pts.alpha, beta=pts.beta, kappa=pts.kappa)


@_one_error
def run_ukf_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Unscented KF on measurements ``y`` (N, K, 5) of N runs, true states ``truth`` (N, K, 6) optional.

    filterpy's ``UnscentedKalmanFilter`` equations as :func:`~kfcal_helpers.coop.filters.make_ukf`
    configures them, on (N, 13, 6) sigma points.
    """
    s = require_instance("setup", setup, FilterSetup)
    y, has, truth = _check_inputs(y, truth)
    p, model = s.params, s.measurement
    n, K = y.shape[:2]
    rows = list(model.rows)
    Q, R = p.process_noise(s.Q), model.R
    points = _merwe(s)
    Wm, Wc = points.Wm, points.Wc
    out = _Store(n, K, truth, keep_estimates)
    x = np.broadcast_to(s.x0, (n, N_STATES)).copy()
    P = np.broadcast_to(s.P0, (n, N_STATES, N_STATES)).copy()
    sigmas_f = None
    for k in range(K):
        if k > 0:
            sigmas_f = arc(batch_sigma_points(x, P, points), p.u0, p.dt, p.L)
            x, _, P = unscented_moments(sigmas_f, STATE.mean, Wm, Wc, STATE.residual)
            P = P + Q
            sigmas_f = batch_sigma_points(x, P, points)
            P = 0.5 * (P + mT(P))
        elif has[0]:
            sigmas_f = batch_sigma_points(x, P, points)
        if has[k]:
            sigmas_h = model.h(sigmas_f)
            zp, dz, S = unscented_moments(sigmas_h, model.mean, Wm, Wc, model.residual)
            S = S + R
            dxs = STATE.residual(sigmas_f, x[:, None, :])
            Pxz = mT(dxs * Wc[:, None]) @ dz
            nu = model.residual(y[:, k, rows], zp)
            gain, SInu = gain_solve(S, Pxz, nu)
            x = STATE.add(x, (gain @ nu[..., None])[..., 0])
            P = P - gain @ S @ mT(gain)
            P = 0.5 * (P + mT(P))
            out.innovation(k, nu, SInu)
        out.posterior(k, x, P)
    return out.result(s, K, has)


_RUNNERS = {"lkf": run_lkf_batch, "ekf": run_ekf_batch, "ukf": run_ukf_batch}


@checked(y=require_array, setup=functools.partial(require_instance, cls=FilterSetup), truth=optional(require_array),
         keep_estimates=require_bool)
def run_batch(y, setup: FilterSetup, truth=None, *, keep_estimates: bool = False) -> BatchResult:
    """Run the filter ``setup.filter`` on the measurements ``y`` (N, K, 5) of N realizations.

    Parameters
    ----------
    y : array (N, K, 5) -- rows all finite or all NaN (predict only), the NaN rows the same in every run
    setup : FilterSetup -- filter, model, Q, measurement model (its rows of y), x0, P0, sigma points,
        the mistakes ``wrap_innovations`` (EKF) and ``subtract_nominal`` (LKF)
    truth : array (N, K, 6), optional -- true states, for the NEES and the errors
    keep_estimates : also keep ``x`` (N, K, 6) and ``P`` (N, K, 6, 6) (336 kB per run of 1001 steps)

    Returns
    -------
    BatchResult.  ValueError naming ``y`` if a run diverges (a non-finite estimate, NEES or NIS).
    """
    setup = require_instance("setup", setup, FilterSetup)
    return _RUNNERS[setup.filter](y, setup, truth, keep_estimates=keep_estimates)
