"""One EKF or UKF run without filterpy's object overhead: the lean path of the live demo (notebook 18).

The filters of :mod:`~kfcal_helpers.coop.filters` are filterpy's classes and stay the reference; the
demo runs one filter over the 1001-sample log on every redraw, and the per-step overhead of the
classes (attribute copies, argument checks, generic callbacks, ``numpy.linalg`` on 6x6 matrices)
costs most of its time.  Here the same equations run in a plain loop:

* everything that does not change over a run is computed once: ``Omega Q Omega^T``, R of the rows
  used, the chord ``v dt sinc(w dt / 2)`` and half-turn ``w dt / 2`` of each vehicle's arc (the control
  is constant), the sigma-point weights, where the bearings sit among the rows used;
* the EKF's mean, its Jacobian ``F = I + dt A(x+)`` (four entries) and ``h``, ``H = C(x-)`` of the rows
  used are written out for the one state, with Python floats;
* the gain comes from one LAPACK solve with S (``scipy.linalg.lapack.dgesv``) instead of
  ``inv(S)``, and the UKF's Cholesky factor from ``dpotrf`` (the jitter fallback of
  :func:`~kfcal_helpers.coop.filters.robust_sqrt` if it fails);
* only what the demo shows is kept per step (``x+``, ``P+``, the innovation and S); the NIS, NEES,
  errors and two-sigma bounds are computed afterwards for all steps at once.

The results equal filterpy's (:func:`~kfcal_helpers.coop.filters.run_filter`) to rounding:
``tests/test_coop_fast.py`` checks x, P, NIS, NEES, errors and two-sigma bounds to 1e-9 for both
filters, several Q scales and measurement subsets.  Same conventions as there: start at (x0, P0) at
t_0, update with a finite ``y_0``, and for k = 1..K-1 predict to t_k and update with ``y_k`` unless
that row is NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints
from scipy.linalg import lapack

from ..consistency import nees as _nees
from ..consistency import nis as _nis
from ..validation import require_choice, require_instance, require_shape
from .filters import EstimateViews, FilterSetup, check_measurements, robust_sqrt
from .model import MEAS_ANGLES, N_MEAS, N_STATES, STATE

__all__ = ["FAST_FILTERS", "FastResult", "run_ekf_fast", "run_ukf_fast", "run_fast", "run_filter_fast"]

#: the filters of the lean path
FAST_FILTERS = ("ekf", "ukf")

_PI = math.pi
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, eq=False)
class FastResult(EstimateViews):
    """One lean filter run over K samples (filterpy's names where they apply).

    filter : "ekf" or "ukf"; t : (K,) s; measurements : the rows of y used
    x_post, P_post : (K, 6), (K, 6, 6) the estimate after each update (the prior without a
        measurement), headings wrapped; ``x`` and ``P`` are the same arrays
    y : (K, 5) wrapped innovations, NaN at steps without a measurement and in the rows not used
    S : (K, 5, 5) innovation covariances, NaN likewise
    nis : (K,) NIS (``len(measurements)`` degrees of freedom), NaN without a measurement
    nees : (K,) NEES (6 degrees of freedom, headings wrapped), or None without truth
    """

    filter: str
    t: np.ndarray
    x_post: np.ndarray
    P_post: np.ndarray
    y: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    nees: np.ndarray | None
    measurements: tuple


def _arc_constants(p):
    """Chord ``d = v dt sinc(w dt / 2)`` and half-turn ``w dt / 2`` of each vehicle's arc (UGV, UAV),
    as :func:`~kfcal_helpers.coop.model.arc` computes them for the constant control."""
    vg, phi, va, wa = (float(v) for v in p.u0)
    wg = vg * np.tan(phi) / p.L
    out = []
    for v, w in ((vg, wg), (va, wa)):
        half = 0.5 * w * p.dt
        out.append((float(v * p.dt * np.sinc(half / np.pi)), float(half)))
    return out


def _wrap(a: float) -> float:
    return _PI - (_PI - a) % _TWO_PI


def _wrap_into(v):
    """Wrap the angles ``v`` (an array view) to (-pi, pi] in place, as ``pi - mod(pi - v, 2 pi)``."""
    t = _PI - v
    np.mod(t, _TWO_PI, out=t)
    np.subtract(_PI, t, out=v)


def _solve(S, B, name):
    """``S^-1 B`` for the innovation covariance S (m, m) and B (m, n): one LAPACK solve."""
    _, _, X, info = lapack.dgesv(S, B)
    if info != 0:
        raise ValueError(f"y: the {name} diverged (the innovation covariance S became singular)")
    return X


def _finish(name, s, x, P, Y, S, has, truth) -> FastResult:
    K = x.shape[0]
    if not (np.isfinite(x).all() and np.isfinite(P).all()):
        raise ValueError(f"y: the {name.upper()} diverged (non-finite estimate)")
    rows = list(s.measurement.rows)
    nis = np.full(K, np.nan)
    if has.any():
        y_used, S_used = Y[has], S[has]
        if len(rows) < N_MEAS:
            y_used, S_used = y_used[:, rows], S_used[:, rows][:, :, rows]
        nis[has] = _nis(y_used, S_used)
    nees = None
    if truth is not None:
        truth = require_shape("truth", truth, (K, N_STATES))
        nees = _nees(STATE.residual(truth, x), P)
    return FastResult(name, s.params.dt * np.arange(K), x, P, Y, S, nis, nees, tuple(rows))


def _expand(Yc, Sc, rows):
    """Innovations (K, m) and their covariances (K, m, m) of the rows used into the (K, 5) and (K, 5, 5)
    arrays of all rows, NaN in the rows not used."""
    if len(rows) == N_MEAS:
        return Yc, Sc
    K = Yc.shape[0]
    Y, S = np.full((K, N_MEAS), np.nan), np.full((K, N_MEAS, N_MEAS), np.nan)
    Y[:, rows] = Yc
    S[:, np.array(rows)[:, None], np.array(rows)] = Sc
    return Y, S


def _setup(setup, filter) -> FilterSetup:
    s = require_instance("setup", setup, FilterSetup)
    if s.filter != filter:
        raise ValueError(f"setup must be a setup of the {filter.upper()}, got filter={s.filter!r}")
    return s


# ---------------------------------------------------------------------------
# EKF
def run_ekf_fast(y, setup: FilterSetup, truth=None) -> FastResult:
    """The EKF of :func:`~kfcal_helpers.coop.filters.run_ekf` in a plain loop, on measurements ``y``
    (K, 5), with the true states ``truth`` (K, 6) for the NEES if given.

    Per step: ``F = I + dt A(x+)`` (four entries), ``x- = phi(x+)`` (the exact arc),
    ``P- = F P F^T + Omega Q Omega^T``; ``h(x-)`` and ``H = C(x-)`` of the rows used, the wrapped
    innovation (``setup.wrap_innovations=False``: unwrapped, the mistake), ``K = P H^T S^-1`` and
    filterpy's Joseph update ``P = (I - K H) P (I - K H)^T + K R K^T``, headings wrapped.
    """
    s = _setup(setup, "ekf")
    y = check_measurements(y)
    p, model = s.params, s.measurement
    K = y.shape[0]
    rows = model.rows
    wrap = s.wrap_innovations
    bearings = [j for j, i in enumerate(rows) if i in MEAS_ANGLES]
    Qd, R, eye = p.process_noise(s.Q), np.array(model.R), np.eye(N_STATES)
    (dg, hg), (da, ha) = _arc_constants(p)
    dt, vg, va = float(p.dt), float(p.u0[0]), float(p.u0[2])
    has = ~np.isnan(y[:, 0])
    ys = y.tolist()
    xs = np.empty((K, N_STATES))
    Ps = np.empty((K, N_STATES, N_STATES))
    Yc = np.full((K, len(rows)), np.nan)
    Sc = np.full((K, len(rows), len(rows)), np.nan)
    F = np.eye(N_STATES)
    x = [float(v) for v in s.x0]
    P = np.array(s.P0, dtype=float)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        try:
            xs, Ps, Yc, Sc = _ekf_loop(K, has, ys, rows, bearings, wrap, x, P, F, eye, Qd, R, dt, vg, va, dg, hg, da, ha,
                                       xs, Ps, Yc, Sc)
        except ValueError as e:
            if "math domain" not in str(e):
                raise
            raise ValueError("y: the EKF diverged (non-finite estimate)") from None
    Y, Ss = _expand(Yc, Sc, rows)
    return _finish("ekf", s, xs, Ps, Y, Ss, has, truth)


def _ekf_loop(K, has, ys, rows, bearings, wrap, x, P, F, eye, Qd, R, dt, vg, va, dg, hg, da, ha, xs, Ps, Yc, Sc):
    """The EKF's steps (:func:`run_ekf_fast`): fills and returns xs, Ps, Yc, Sc."""
    for k in range(K):
        if k > 0:
            xg, eg, tg, xa, ea, ta = x
            F[0, 2] = dt * (-vg * math.sin(tg))
            F[1, 2] = dt * (vg * math.cos(tg))
            F[3, 5] = dt * (-va * math.sin(ta))
            F[4, 5] = dt * (va * math.cos(ta))
            mg, ma = tg + hg, ta + ha
            x = [xg + dg * math.cos(mg), eg + dg * math.sin(mg), _wrap(mg + hg),
                 xa + da * math.cos(ma), ea + da * math.sin(ma), _wrap(ma + ha)]
            P = F.dot(P).dot(F.T) + Qd
        if has[k]:
            xg, eg, tg, xa, ea, ta = x
            dxi, deta = xa - xg, ea - eg
            r2 = dxi * dxi + deta * deta
            if r2 == 0:
                raise ValueError("x: the two vehicles are at the same position (range 0): bearings and their "
                                 "Jacobian are undefined")
            r = math.sqrt(r2)
            b = math.atan2(deta, dxi)
            a, c, e, f = deta / r2, -dxi / r2, -dxi / r, -deta / r
            full_h = (_wrap(b - tg), r, _wrap(b + _PI - ta), xa, ea)
            full_H = ((a, c, -1.0, -a, -c, 0.0), (e, f, 0.0, -e, -f, 0.0), (a, c, 0.0, -a, -c, -1.0),
                      (0.0, 0.0, 0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0, 1.0, 0.0))
            zk = ys[k]
            nu = [zk[i] - full_h[i] for i in rows]
            if wrap:
                for j in bearings:
                    nu[j] = _wrap(nu[j])
            H = np.array([full_H[i] for i in rows])
            PHT = P.dot(H.T)
            S = H.dot(PHT) + R
            gain = _solve(S, PHT.T, "EKF").T
            nu = np.array(nu)
            xn = (np.array(x) + gain.dot(nu)).tolist()
            xn[2], xn[5] = _wrap(xn[2]), _wrap(xn[5])
            x = xn
            I_KH = eye - gain.dot(H)
            P = I_KH.dot(P).dot(I_KH.T) + gain.dot(R).dot(gain.T)
            Yc[k] = nu
            Sc[k] = S
        xs[k] = x
        Ps[k] = P
    return xs, Ps, Yc, Sc


# ---------------------------------------------------------------------------
# UKF
def _upper_factor(M):
    """Upper Cholesky factor U (``U^T U = M``) of the symmetric ``M`` (6, 6): LAPACK's ``dpotrf``, the
    jitter fallback of :func:`~kfcal_helpers.coop.filters.robust_sqrt` if it fails."""
    U, info = lapack.dpotrf(M, lower=0, clean=1)
    if info == 0:
        return U
    half = 0.5 * M
    M = half + half.T  # symmetrized without overflow
    diverged = "P: the UKF covariance holds non-finite numbers (the UKF diverged)"
    if not np.isfinite(M).all():
        raise ValueError(diverged)
    try:
        return robust_sqrt(M)
    except ValueError as e:  # its jitter overflowed (scipy's "array must not contain infs or NaNs")
        if str(e).startswith("P:"):
            raise
        raise ValueError(diverged) from None


def _angle_slice(positions):
    """The positions of the bearings among the rows used (at most two) as a basic slice."""
    if not positions:
        return None
    if len(positions) == 1:
        return slice(positions[0], positions[0] + 1)
    return slice(positions[0], positions[1] + 1, positions[1] - positions[0])


def run_ukf_fast(y, setup: FilterSetup, truth=None) -> FastResult:
    """The UKF of :func:`~kfcal_helpers.coop.filters.run_ukf` in a plain loop, on measurements ``y``
    (K, 5), with the true states ``truth`` (K, 6) for the NEES if given.

    filterpy's ``UnscentedKalmanFilter`` with ``MerweScaledSigmaPoints`` (the setup's ``points``) as
    :func:`~kfcal_helpers.coop.filters.make_ukf` configures it: sigma points ``x``, ``x + U_i``,
    ``x - U_i`` from the rows of the upper Cholesky factor of ``(n + lambda) P``; the exact arcs on all
    13 at once; circular means of the headings and bearings, wrapped residuals; the sigma points of the
    prior (filterpy recomputes them after its predict) enter the update; ``P = P - K S K^T``.

    Three shortcuts, each equal to filterpy's step to rounding: the Cholesky factor reads one triangle
    of P, so P is symmetrized (as ``run_ukf`` does after every step) only where it is stored; the
    sigma points' state residuals ``wrap(sig - x)`` are the offsets ``+-U_i`` themselves while
    ``(n + lambda) P`` keeps its heading variances below pi^2; and the residuals of the moved sigma
    points are wrapped by one shift of the mean by a multiple of 2 pi while their headings lie within
    pi / 2 of the moved centre point (otherwise the general wraps run).  Two vehicles at the same
    position give the bearing of ``arctan2(0, 0) = 0`` here (filterpy's h raises).
    """
    s = _setup(setup, "ukf")
    y = check_measurements(y)
    p, model, pts = s.params, s.measurement, s.points
    K = y.shape[0]
    rows = list(model.rows)
    m = len(rows)
    all_rows = m == N_MEAS
    bearings = [j for j, i in enumerate(rows) if i in MEAS_ANGLES]
    bsl = _angle_slice(bearings)
    Qd, R = p.process_noise(s.Q), np.array(model.R)
    points = MerweScaledSigmaPoints(N_STATES, alpha=pts.alpha, beta=pts.beta, kappa=pts.kappa)
    Wm, Wc = points.Wm, points.Wc
    Wc_col = Wc[:, None]
    scale = points.alpha ** 2 * (N_STATES + points.kappa)  # n + lambda
    (dg, hg), (da, ha) = _arc_constants(p)
    d2, h2 = np.array([dg, da]), np.array([hg, ha])
    zero_pi = np.array([0.0, _PI])
    has = ~np.isnan(y[:, 0])
    yr = np.ascontiguousarray(y[:, rows])
    xs = np.empty((K, N_STATES))
    Ps = np.empty((K, N_STATES, N_STATES))
    Yc = np.full((K, m), np.nan)
    Sc = np.full((K, m, m), np.nan)
    n_sig = 2 * N_STATES + 1
    # work buffers, and views of them made once (the loop writes into them in place)
    sig = np.empty((n_sig, N_STATES))  # the sigma points
    offsets = np.zeros((n_sig, N_STATES))  # sigma points - x: 0, U_i, -U_i
    off_plus, off_minus = offsets[1:N_STATES + 1], offsets[N_STATES + 1:]
    step = np.empty((n_sig, N_STATES))  # the arc's increments: chords and turns w dt
    step[:, 2::3] = 2.0 * h2
    step_c, step_s = step[:, 0::3], step[:, 1::3]
    fs = np.empty((n_sig, N_STATES))  # the sigma points moved by the arcs
    fs_th = fs[:, 2::3]
    mid = np.empty((n_sig, 2))
    trig = np.empty((n_sig, 4))  # sin and cos of two angles of every sigma point, for circular means
    trig_s, trig_c = trig[:, :2], trig[:, 2:]
    r = np.empty((n_sig, N_STATES))
    rel = np.empty((n_sig, 2))  # UAV - UGV position
    rel_e, rel_n = rel[:, 0], rel[:, 1]
    bearing = np.empty((n_sig, 1))
    hz = np.empty((n_sig, N_MEAS))  # h of every sigma point (bearings unwrapped)
    hz_b, hz_r, hz_gps = hz[:, 0:3:2], hz[:, 1], hz[:, 3:5]
    Z = hz if all_rows else np.empty((n_sig, m))  # the rows used
    dz = np.empty((n_sig, m))
    nb = len(bearings)
    if nb:
        Z_b, dz_b = Z[:, bsl], dz[:, bsl]
        Zs, Zc = trig[:, :nb], trig[:, 2:2 + nb]
    sig_th, sig_g, sig_a = sig[:, 2::3], sig[:, 0:2], sig[:, 3:5]
    x = np.array(s.x0, dtype=float)
    P = np.array(s.P0, dtype=float)
    pi2 = _PI ** 2

    def sigma_points(x, P):  # filterpy's sigma_points (dpotrf reads the upper triangle of (n + lambda) P)
        U = _upper_factor(scale * P)
        off_plus[...] = U
        np.negative(U, out=off_minus)
        np.add(x, offsets, out=sig)

    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        if has[0]:
            sigma_points(x, 0.5 * (P + P.T))
        for k in range(K):
            if k > 0:
                sigma_points(x, P)
                # bounds of |U| in the headings (NaN, hence the general path below, if P lost its diagonal)
                reach = [math.sqrt(max(scale * P[2, 2], 0.0)), math.sqrt(max(scale * P[5, 5], 0.0))]
                # the arc of every sigma point (model.arc): chord d along theta + w dt / 2, turn w dt; the
                # headings stay unwrapped: only their sines and cosines and wrapped residuals are used
                np.add(sig_th, h2, out=mid)
                np.cos(mid, out=step_c)
                step_c *= d2
                np.sin(mid, out=step_s)
                step_s *= d2
                np.add(sig, step, out=fs)
                # the mean, circular in the headings (STATE.mean)
                np.sin(fs_th, out=trig_s)
                np.cos(fs_th, out=trig_c)
                sg, sa, cg, ca = Wm.dot(trig).tolist()
                x = Wm.dot(fs)
                x[2], x[5] = math.atan2(sg, cg), math.atan2(sa, ca)
                # residuals wrap(fs - x): the heading of sigma point 0 (the moved mean) sets the branch;
                # the others lie within ``reach`` of it, so a shift of x by a multiple of 2 pi wraps them all
                shift = x.copy()
                wrapped = True
                for j, i in enumerate((2, 5)):
                    c = float(fs[0, i])
                    w = _wrap(c - x[i])
                    shift[i] = c - w
                    wrapped = wrapped and reach[j] + abs(w) < 0.5 * _PI
                np.subtract(fs, shift, out=r)
                if not wrapped:
                    np.subtract(fs, x, out=r)
                    _wrap_into(r[:, 2::3])
                P = (r.T * Wc).dot(r) + Qd
                sigma_points(x, P)  # filterpy's sigma points of the prior
            if has[k]:
                # h of every sigma point (model.measure), then the rows used
                np.subtract(sig_a, sig_g, out=rel)
                np.arctan2(rel[:, 1:2], rel[:, 0:1], out=bearing)
                np.hypot(rel_e, rel_n, out=hz_r)
                np.add(bearing, zero_pi, out=hz_b)
                np.subtract(hz_b, sig_th, out=hz_b)
                hz_gps[...] = sig_a
                if not all_rows:
                    np.take(hz, rows, axis=1, out=Z)
                zp = Wm.dot(Z)
                if nb:  # circular mean and wrapped residuals of the bearings (model.mean, .residual)
                    np.sin(Z_b, out=Zs)
                    np.cos(Z_b, out=Zc)
                    sc = Wm.dot(trig).tolist()
                    for j, col in enumerate(bearings):
                        zp[col] = math.atan2(sc[j], sc[2 + j])
                np.subtract(Z, zp, out=dz)
                if nb:
                    _wrap_into(dz_b)
                dzw = dz * Wc_col  # Wc-weighted, for S and Pxz
                S = dz.T.dot(dzw) + R
                # the state residuals of the sigma points, wrap(sig - x) = +-U: no heading wraps while the
                # heading entries of U stay below pi, i.e. while (n + lambda) P_theta,theta < pi^2
                dX = offsets
                if P[2, 2] * scale >= pi2 or P[5, 5] * scale >= pi2:
                    dX = sig - x
                    _wrap_into(dX[:, 2::3])
                Pxz = dX.T.dot(dzw)
                gain = _solve(S, Pxz.T, "UKF").T
                nu = yr[k] - zp
                for j in bearings:
                    nu[j] = _wrap(float(nu[j]))
                x = x + gain.dot(nu)
                x[2], x[5] = _wrap(float(x[2])), _wrap(float(x[5]))
                P = P - Pxz.dot(gain.T)  # K S K^T = Pxz K^T
                Yc[k] = nu
                Sc[k] = S
            xs[k] = x
            Ps[k] = P
        # filterpy symmetrizes P after every step; here only the stored ones (the sigma points read one triangle)
        Ps = 0.5 * (Ps + np.swapaxes(Ps, 1, 2))
    Y, Ss = _expand(Yc, Sc, rows)
    return _finish("ukf", s, xs, Ps, Y, Ss, has, truth)


_RUNNERS = {"ekf": run_ekf_fast, "ukf": run_ukf_fast}


def run_fast(y, setup: FilterSetup, truth=None) -> FastResult:
    """Run the lean filter ``setup.filter`` ("ekf" or "ukf") on measurements ``y`` (K, 5), with the true
    states ``truth`` (K, 6) for the NEES if given."""
    setup = require_instance("setup", setup, FilterSetup)
    require_choice("filter", setup.filter, FAST_FILTERS)
    return _RUNNERS[setup.filter](y, setup, truth)


def run_filter_fast(filter: str, y, params=None, *, truth=None, **settings) -> FastResult:
    """The lean run of ``filter`` ("ekf" or "ukf"), with the arguments of
    :func:`~kfcal_helpers.coop.filters.run_filter` (``settings``: ``Q``, ``R``, ``x0``, ``P0``,
    ``measurements``, ``points``, ``wrap_innovations``)."""
    filter = require_choice("filter", filter, FAST_FILTERS)
    return run_fast(y, FilterSetup.build(filter, params, **settings), truth)
