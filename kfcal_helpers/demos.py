"""Lecture demos (notebooks 17 and 18): what one slider move recomputes, and the figure it redraws.

Each demo is split into a *compute* function, which returns plain arrays in a small dataclass,
and a *draw* function, which turns that into a matplotlib figure.  The notebooks wire the two to
``ipywidgets`` sliders; the benchmark (``benchmarks/bench_demos.py``) and the tests time and check
the compute functions on their own.

* Calibration (notebook 17): :func:`compute_calibration_demo` runs the batch filter of
  :mod:`kfcal_helpers.calibration` for one parameter set: the covariances and gains once
  (:func:`~kfcal_helpers.calibration.covariance_sequence`, propagated fix to fix), one 200 Hz
  realization (``simulate``) and a 200-realization ensemble drawn at the fixes
  (:func:`sample_noise_at_fixes`), whose errors come from the filter's error recursion
  (:func:`filter_errors_at_fixes`, the numbers ``batch_filter`` gives on the same draws); the
  ensemble's spread is compared with the filter's sigma at every fix.
  :class:`CalibrationDemoFigure` draws the errors with their +-2 sigma bands.
* Cooperative localization (notebook 18): :func:`compute_coop_demo` runs the EKF or UKF on a
  log with ``Q = q_scale * Qtrue`` and a chosen subset of the five measurements, and tests the
  time-averaged NIS against its chi-square bounds (dimension = number of measurements used);
  :class:`CoopDemoFigure` draws the six estimation errors with their +-2 sigma bounds.

The figure classes build their figure once and :meth:`update` only replaces the data, so a
redraw costs one render; :func:`figure_png` turns it into the PNG an ``ipywidgets.Image``
shows, and :func:`calibration_controls` / :func:`coop_controls` build the sliders.
:class:`LiveDemo` puts the controls in a column beside the image (the whole demo fits a 1280x800
window) and redraws on every change; a setting that cannot be computed (e.g. the UKF's covariance
losing positive definiteness) shows a one-line message in the image's place, never a traceback.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .calibration import (CalibrationParams, Simulation, between_fixes, covariance_sequence, error_state_model,
                          outage_mask, phi_power, simulate)
from .calibration.error_model import ErrorStateModel
from .consistency import chi2_bounds
from .coop import N_MEAS, STATE_LABELS, TUNED_Q_SCALE, CoopLog, run_filter
from .coop.filters import measurement_subset
from .validation import require_choice, require_finite, require_int, require_positive, require_shape

__all__ = [
    "valid_gps_rates",
    "sample_noise_at_fixes",
    "noise_of_simulation",
    "filter_errors_at_fixes",
    "estimate_between_fixes",
    "CalibrationDemo",
    "compute_calibration_demo",
    "CalibrationDemoFigure",
    "draw_calibration_demo",
    "COOP_DEMO_FILTERS",
    "MEASUREMENT_NAMES",
    "CoopDemo",
    "compute_coop_demo",
    "CoopDemoFigure",
    "draw_coop_demo",
    "figure_png",
    "calibration_controls",
    "coop_controls",
    "LIVE_FIGSIZE",
    "DEMO_FAILURES",
    "failure_message",
    "describe_controls",
    "LiveDemo",
]

ENSEMBLES = ("fixes", "simulate")


# ---------------------------------------------------------------------------
# Calibration
def valid_gps_rates(imu_rate: float = 200.0, max_rate: float = 25.0) -> tuple[float, ...]:
    """GPS rates (Hz) that divide ``imu_rate`` (Hz), up to ``max_rate``: the slider's options.

    ``valid_gps_rates()`` is ``(1, 2, 4, 5, 8, 10, 20, 25)`` for the 200 Hz IMU.  The default
    ``max_rate`` stops at 25 Hz: the cost of a redraw grows with the number of fixes, and at
    40-50 Hz it passes 100 ms on a 2-core machine (``benchmarks/bench_demos.py``).
    """
    imu_rate = require_positive("imu_rate", imu_rate)
    max_rate = require_positive("max_rate", max_rate)
    n = int(round(imu_rate))
    if abs(imu_rate - n) > 1e-9 * imu_rate:
        raise ValueError(f"imu_rate must be a whole number of Hz, got {imu_rate!r}")
    return tuple(float(d) for d in range(1, n + 1) if n % d == 0 and d <= max_rate)


def _model(params: CalibrationParams) -> ErrorStateModel:
    if not isinstance(params, CalibrationParams):
        raise ValueError(f"params must be a CalibrationParams, got {type(params).__name__}")
    return error_state_model(params)


def sample_noise_at_fixes(params: CalibrationParams, n_runs: int, rng: np.random.Generator):
    """Random draws that drive the filter's error from fix to fix, for ``n_runs`` realizations.

    The error-state model (exact for the Euler truth, notebook 04) seen at the fixes only:
    ``dx_0 - x0 ~ N(0, M0)``; between fixes ``dx_{i+1} = Phi^r dx_i + w_i`` with
    ``w_i ~ N(0, Q_r)``, the IMU noise of the ``r`` steps summed exactly (zero for the bias,
    which has no process noise); GPS noise ``eta_i ~ N(0, V)``.

    Returns
    -------
    e0 : (n_runs, 3) initial error ``dx_0 - x0`` [m, m/s, m/s^2]
    w : (n_runs, n_gps - 1, 3) process noise between consecutive fixes
    eta : (n_runs, n_gps, 2) GPS noise [m, m/s]
    (``w`` and ``eta`` are views of time-major arrays.)
    """
    e0, w_t, eta_t = _sample_noise_time_major(params, n_runs, rng)
    return e0, w_t.transpose(1, 0, 2), eta_t.transpose(1, 0, 2)


def _sample_noise_time_major(params, n_runs, rng):
    m = _model(params)
    n_runs = require_int("n_runs", n_runs, minimum=1)
    if not isinstance(rng, np.random.Generator):
        raise ValueError("rng must be a numpy.random.Generator, e.g. numpy.random.default_rng(seed)")
    n_gps = params.n_gps
    Qr = between_fixes(params, m)[1][-1]
    L = np.linalg.cholesky(Qr[:2, :2])  # Q_r is zero in the bias row and column: factor the (p, v) block
    e0 = rng.standard_normal((n_runs, 3)) * np.sqrt(np.diag(m.M0))
    z = rng.standard_normal((n_gps - 1, n_runs, 2))
    w_t = np.zeros((n_gps - 1, n_runs, 3))
    w_t[..., 0] = L[0, 0] * z[..., 0]
    w_t[..., 1] = L[1, 0] * z[..., 0] + L[1, 1] * z[..., 1]
    eta_t = rng.standard_normal((n_gps, n_runs, 2)) * np.sqrt(np.diag(m.V))
    return e0, w_t, eta_t


def noise_of_simulation(sim: Simulation):
    """The same draws as :func:`sample_noise_at_fixes` returns, read off a 200 Hz simulation:
    ``e0 = dx_0 - x0``, ``w_i = dx_{i+1} - Phi^r dx_i``, ``eta_i = dz_i - H dx_i`` (0 at a missing
    fix, where no update uses it).  Shapes (n, 3), (n, n_gps - 1, 3), (n, n_gps, 2)."""
    if not isinstance(sim, Simulation):
        raise ValueError(f"sim must be a Simulation (from simulate), got {type(sim).__name__}")
    params = sim.params
    m = _model(params)
    Phi_r = phi_power(params, params.steps_per_fix)
    dx = sim.dx_at_fixes
    eta = sim.dz - dx @ m.H.T
    eta[np.isnan(eta)] = 0.0
    return dx[:, 0] - m.x0, dx[:, 1:] - dx[:, :-1] @ Phi_r.T, eta


def filter_errors_at_fixes(params: CalibrationParams, covariances, e0, w, eta):
    """The filter's estimation errors ``e = dx - dx_hat`` at every fix, for given noises.

    With data-independent gains ``K_i`` (``covariances[3]``, zero at a missing fix) the error of
    the linear filter obeys its own recursion, without the data:
    ``e-_0 = e0``, ``e+_i = (I - K_i H) e-_i - K_i eta_i``, ``e-_{i+1} = Phi^r e+_i + w_i``.
    These are the numbers ``dx - batch_filter(...).x_post`` gives on the same draws (the tests
    check it), from one short loop over the fixes: the Monte Carlo of the demo.

    Parameters
    ----------
    params : CalibrationParams
    covariances : output of ``covariance_sequence`` (the gains)
    e0 (n, 3), w (n, n_gps - 1, 3), eta (n, n_gps, 2) : as :func:`sample_noise_at_fixes` returns

    Returns
    -------
    e_prior, e_post : (n, n_gps, 3) errors just before and just after each fix [m, m/s, m/s^2]
    """
    _model(params)  # validates params
    n_gps = params.n_gps
    e0 = require_shape("e0", e0, (None, 3))
    n = e0.shape[0]
    w = require_shape("w", w, (n, n_gps - 1, 3))
    eta = require_shape("eta", eta, (n, n_gps, 2))
    e_prior, e_post = _filter_errors_time_major(params, covariances, e0, w.transpose(1, 0, 2), eta.transpose(1, 0, 2))
    return e_prior.transpose(1, 0, 2), e_post.transpose(1, 0, 2)


def _filter_errors_time_major(params, covariances, e0, w_t, eta_t):
    """:func:`filter_errors_at_fixes` on time-major arrays: w_t (n_gps - 1, n, 3), eta_t (n_gps, n, 2);
    returns e_prior, e_post of shape (n_gps, n, 3).  Every step's slice is contiguous."""
    m = _model(params)
    n_gps = params.n_gps
    K = require_shape("covariances[3] (the gains K)", covariances[3], (n_gps, 3, 2))
    # row vectors: e+_i = e-_i A_i - eta_i B_i with A_i = (I - K_i H)^T, B_i = K_i^T, and
    # e-_{i+1} = e+_i Phi_r^T + w_i = e-_i G_i + u_i with G_i = A_i Phi_r^T, u_i = w_i - eta_i B_i Phi_r^T:
    # the products that do not need the recursion are done for all fixes at once
    A = np.eye(3) - np.transpose(K @ m.H, (0, 2, 1))
    B = np.transpose(K, (0, 2, 1))
    Phi_rT = phi_power(params, params.steps_per_fix).T
    eta_t = np.ascontiguousarray(eta_t)
    G = A[:-1] @ Phi_rT
    u = w_t - eta_t[:-1] @ (B[:-1] @ Phi_rT)
    e_prior = np.empty((n_gps,) + e0.shape)
    e = e_prior[0] = e0
    for i in range(n_gps - 1):
        e = e_prior[i + 1] = e @ G[i] + u[i]
    return e_prior, e_prior @ A - eta_t @ B


def estimate_between_fixes(params: CalibrationParams, x_post) -> np.ndarray:
    """The filter's estimate at every IMU sample from its a posteriori estimates at the fixes:
    between fixes it is only predicted, ``x(t_i + k dt) = Phi^k x_post[i]``.

    x_post : (n_gps, 3) or (n, n_gps, 3); returns (n_imu, 3) or (n, n_imu, 3).
    (``batch_filter(..., full_rate=True)`` gives the same for all realizations at once.)
    """
    _model(params)  # validates params
    x_post = np.asarray(x_post, dtype=float)
    if x_post.ndim not in (2, 3) or x_post.shape[-2:] != (params.n_gps, 3):
        raise ValueError(f"x_post must have shape (..., {params.n_gps}, 3), got {x_post.shape}")
    powers = phi_power(params, np.arange(params.steps_per_fix))  # (r, 3, 3)
    x = (x_post[..., :, None, None, :] * powers[:, :, :]).sum(axis=-1)  # (..., n_gps, r, 3)
    return x.reshape(x.shape[:-3] + (-1, 3))[..., : params.n_imu, :]


@dataclass(frozen=True, eq=False)
class CalibrationDemo:
    """One redraw of the calibration demo (n_imu IMU samples, n_gps fixes).

    params : CalibrationParams used; outage : (start, end) s or None; missing : (n_gps,) bool
    t : (n_imu,) s; error : (n_imu, 3) one realization's error dx - dx_hat [m, m/s, m/s^2]
        (a posteriori at fixes, predicted in between); sigma : (n_imu, 3) the filter's sqrt(diag P)
    t_gps : (n_gps,) s; P_prior, P_post : (n_gps, 3, 3) the filter's covariances at the fixes
    ens_mean, ens_std : (n_gps, 3) mean and standard deviation (ddof 1) over ``n_runs``
        realizations of the a posteriori error at every fix
    ensemble : "fixes" or "simulate" (how the ensemble was drawn); alpha : level of the band
    """

    params: CalibrationParams
    outage: tuple[float, float] | None
    missing: np.ndarray
    t: np.ndarray
    error: np.ndarray
    sigma: np.ndarray
    t_gps: np.ndarray
    P_prior: np.ndarray
    P_post: np.ndarray
    ens_mean: np.ndarray
    ens_std: np.ndarray
    n_runs: int
    ensemble: str
    alpha: float

    @property
    def sigma_fix(self) -> np.ndarray:
        """The filter's a posteriori sigma at the fixes, (n_gps, 3)."""
        return np.sqrt(np.diagonal(self.P_post, axis1=1, axis2=2))

    @property
    def ratio(self) -> np.ndarray:
        """Ensemble std over the filter's sigma at every fix, (n_gps, 3); about 1 when P is right."""
        return self.ens_std / self.sigma_fix

    @property
    def ratio_band(self) -> tuple[float, float]:
        """Two-sided band of ``ratio`` at level ``alpha``: ``(N-1) s^2 / sigma^2 ~ chi2(N-1)``,
        so ``s / sigma`` lies in ``[sqrt(chi2(alpha/2)/(N-1)), sqrt(chi2(1-alpha/2)/(N-1))]``."""
        lo, hi = chi2_bounds(1, self.n_runs - 1, self.alpha)
        return float(np.sqrt(lo)), float(np.sqrt(hi))

    @property
    def inside_fraction(self) -> float:
        """Share of the (fix, component) ratios inside :attr:`ratio_band` (about 1 - alpha)."""
        lo, hi = self.ratio_band
        return float(np.mean((self.ratio >= lo) & (self.ratio <= hi)))


def compute_calibration_demo(gps_rate: float = 5.0, W: float = 0.0004, gps_pos_var: float = 1.0,
                             bias_var: float = 0.01, outage=None, n_runs: int = 200, seed: int = 17,
                             base: CalibrationParams | None = None, ensemble: str = "fixes",
                             alpha: float = 0.05) -> CalibrationDemo:
    """Everything one redraw of the calibration demo shows, on the batch path.

    Parameters
    ----------
    gps_rate : GPS fix rate, Hz; must divide the IMU rate (see :func:`valid_gps_rates`)
    W : IMU white-noise variance per sample, (m/s^2)^2
    gps_pos_var : GPS position noise variance, m^2
    bias_var : prior variance of the bias M_b, (m/s^2)^2
    outage : None or a GPS outage window (start, end), s, with 0 <= start < end <= duration
    n_runs : realizations in the ensemble, >= 2
    seed : int >= 0; the same seed gives the same noise draws (common random numbers, so a
        slider move changes the parameters, not the luck)
    base : the other parameters (default: ``CalibrationParams()``, the course problem's)
    ensemble : "fixes" (default: the ensemble's noises drawn at the fixes only,
        :func:`sample_noise_at_fixes`) or "simulate" (the full 200 Hz simulation, slower)
    alpha : significance level of the ensemble band, in (0, 1)

    What is computed: the covariances and gains once (``covariance_sequence``); one
    realization at 200 Hz (``simulate``) and the ensemble's noises; the filter's errors at the
    fixes of all of them in one loop (:func:`filter_errors_at_fixes`, the numbers
    ``batch_filter`` gives); the realization's estimate between fixes
    (:func:`estimate_between_fixes`); the ensemble's error statistics.

    Returns
    -------
    CalibrationDemo
    """
    base = CalibrationParams() if base is None else base
    if not isinstance(base, CalibrationParams):
        raise ValueError(f"base must be a CalibrationParams, got {type(base).__name__}")
    params = base.replace(gps_rate=gps_rate, W=W, gps_pos_var=gps_pos_var, bias_var=bias_var)
    n_runs = require_int("n_runs", n_runs, minimum=2)
    seed = require_int("seed", seed, minimum=0)
    require_choice("ensemble", ensemble, ENSEMBLES)
    alpha = require_finite("alpha", alpha)
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha!r}")
    if outage is None:
        missing = np.zeros(params.n_gps, bool)
    else:
        missing = outage_mask(params, [outage], name="outage")
        outage = (float(outage[0]), float(outage[1]))

    cov = covariance_sequence(params, missing)
    rng_one, rng_ens = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))

    sim = simulate(params, 1, rng_one, missing_fixes=missing)  # the realization drawn at 200 Hz
    if ensemble == "fixes":
        e0, w_t, eta_t = _sample_noise_time_major(params, n_runs, rng_ens)
    else:
        e0, w, eta = noise_of_simulation(simulate(params, n_runs, rng_ens, missing_fixes=missing))
        w_t, eta_t = w.transpose(1, 0, 2), eta.transpose(1, 0, 2)
    # the filter's errors at the fixes: the realization (column 0) and the ensemble in one loop
    one = noise_of_simulation(sim)
    e_post = _filter_errors_time_major(params, cov, np.concatenate([one[0], e0]),
                                       np.concatenate([one[1].transpose(1, 0, 2), w_t], axis=1),
                                       np.concatenate([one[2].transpose(1, 0, 2), eta_t], axis=1))[1]
    x_post = sim.dx_at_fixes[0] - e_post[:, 0]  # the realization's estimate at the fixes
    error = sim.dx[0] - estimate_between_fixes(params, x_post)
    e = np.ascontiguousarray(e_post[:, 1:].transpose(0, 2, 1))  # (n_gps, 3, n_runs): reduce the last axis
    P = cov[0]
    return CalibrationDemo(params, outage, missing, params.t_imu, error,
                           np.sqrt(np.diagonal(P, axis1=1, axis2=2)), params.t_gps, cov[1], P[params.fix_indices],
                           e.mean(axis=-1), e.std(axis=-1, ddof=1), n_runs, ensemble, alpha)


_CAL_LABELS = (r"position error [m]", r"velocity error [m/s]", r"bias error [m/s$^2$]")


def _new_figure(figure, figsize):
    """``figure`` if given (a matplotlib Figure; given an Agg canvas if it has none that can
    render), else a new pyplot figure of ``figsize`` inches."""
    if figure is None:
        return plt.figure(figsize=figsize)
    if not isinstance(figure, Figure):
        raise ValueError(f"figure must be a matplotlib Figure or None, got {type(figure).__name__}")
    if not isinstance(figure.canvas, FigureCanvasAgg):
        FigureCanvasAgg(figure)
    figure.clear()
    return figure


class CalibrationDemoFigure:
    """The calibration demo's figure, built once; :meth:`update` puts a new
    :class:`CalibrationDemo` into the same lines (a redraw then only re-renders).

    Three panels (position, velocity, bias): one realization's error at 200 Hz, the filter's
    +-2 sigma, the ensemble's +-2 s at the fixes, the outage shaded.  ``figure``: a Figure to
    draw on (e.g. ``matplotlib.figure.Figure()`` for a widget, outside pyplot); default a new
    pyplot figure.  ``t_zoom`` (s): the y axes are scaled to the curves after ``t_zoom`` (the
    first seconds, with the 10 m prior sigma of the position, would flatten everything else).
    """

    def __init__(self, figure=None, t_zoom: float = 2.0):
        t_zoom = require_finite("t_zoom", t_zoom)
        if t_zoom < 0:
            raise ValueError(f"t_zoom must be a time >= 0 s (the y axes are scaled to the curves after it), "
                             f"got {t_zoom!r}")
        self.t_zoom = t_zoom
        self.fig = _new_figure(figure, (9.0, 7.2))
        self.axes = self.fig.subplots(3, 1, sharex=True)
        self.lines = []
        for k, ax in enumerate(self.axes):
            err, = ax.plot([], [], color="C3", lw=0.7, label="error, one realization")
            up, = ax.plot([], [], color="k", lw=0.8, label=r"filter $\pm 2\sigma$")
            down, = ax.plot([], [], color="k", lw=0.8)
            ens_up, = ax.plot([], [], ".", color="C0", ms=3, label="ensemble $\\pm 2s$")
            ens_down, = ax.plot([], [], ".", color="C0", ms=3)
            self.lines.append((err, up, down, ens_up, ens_down))
            ax.set_ylabel(_CAL_LABELS[k], fontsize=9)
        self.legend = self.axes[0].legend(loc="upper right", ncol=3, fontsize=8)
        self.axes[-1].set_xlabel("time $t$ [s]")
        self.fig.subplots_adjust(left=0.1, right=0.98, bottom=0.08, top=0.94, hspace=0.3)
        self.spans = []

    def update(self, demo: CalibrationDemo):
        """Draw ``demo`` into the figure; returns the Figure."""
        if not isinstance(demo, CalibrationDemo):
            raise ValueError(f"demo must be a CalibrationDemo, got {type(demo).__name__}")
        p = demo.params
        late, late_fix = demo.t >= self.t_zoom, demo.t_gps >= self.t_zoom
        zoom = f"; y zoomed past t = {self.t_zoom:g} s" if late_fix.any() and self.t_zoom > demo.t[0] else ""
        if not late_fix.any():
            late, late_fix = np.ones_like(late), np.ones_like(late_fix)
        for span in self.spans:
            span.remove()
        self.spans = []
        for k, (ax, (err, up, down, ens_up, ens_down)) in enumerate(zip(self.axes, self.lines)):
            s2, e2 = 2 * demo.sigma[:, k], 2 * demo.ens_std[:, k]
            err.set_data(demo.t, demo.error[:, k])
            up.set_data(demo.t, s2)
            down.set_data(demo.t, -s2)
            ens_up.set_data(demo.t_gps, e2)
            ens_down.set_data(demo.t_gps, -e2)
            top = max(s2[late].max(), e2[late_fix].max(), np.abs(demo.error[late, k]).max())
            ax.set_ylim(-1.15 * top, 1.15 * top)
            if demo.outage is not None:
                self.spans.append(ax.axvspan(*demo.outage, color="C1", alpha=0.2, lw=0))
        self.axes[0].set_xlim(demo.t[0], demo.t[-1])
        self.legend.get_texts()[2].set_text(f"ensemble $\\pm 2s$ ({demo.n_runs} runs)")
        lo, hi = demo.ratio_band
        gap = "" if demo.outage is None else f", outage {demo.outage[0]:g}–{demo.outage[1]:g} s"
        # short titles in normal weight: text is most of the cost of a redraw
        self.axes[0].set_title(f"Errors with ±2σ: GPS {p.gps_rate:g} Hz, W {p.W:.1e} (m/s²)², GPS σ_p "
                               f"{np.sqrt(p.gps_pos_var):.2g} m, bias σ₀ {np.sqrt(p.bias_var):.2g} m/s²{gap}",
                               fontsize=10, fontweight="normal")
        self.axes[-1].set_title(f"s/σ inside [{lo:.3f}, {hi:.3f}] at {100 * demo.inside_fraction:.1f} % "
                                f"of (fix, state) pairs{zoom}",
                                fontsize=9, fontweight="normal")
        return self.fig


def draw_calibration_demo(demo: CalibrationDemo, t_zoom: float = 2.0):
    """A new figure of ``demo`` (see :class:`CalibrationDemoFigure`); returns the Figure."""
    return CalibrationDemoFigure(t_zoom=t_zoom).update(demo)


# ---------------------------------------------------------------------------
# Cooperative localization
COOP_DEMO_FILTERS = ("ekf", "ukf")
#: the five measurements, in the order of the rows of y
MEASUREMENT_NAMES = ("bearing UGV→UAV", "range", "bearing UAV→UGV", "UAV GPS east", "UAV GPS north")


@dataclass(frozen=True, eq=False)
class CoopDemo:
    """One redraw of the cooperative-localization demo (K samples).

    filter : "ekf" or "ukf"; q_scale : the filter's Q = q_scale * Qtrue
    measurements : tuple of the rows of y used; t : (K,) s
    errors : (K, 6) truth - estimate, headings wrapped; sigma2 : (K, 6) the filter's 2 sqrt(diag P)
    P : (K, 6, 6) the filter's covariances (m, rad)
    nis : (K,) NIS (NaN without a measurement); nis_mean : its time average over ``n_nis`` steps
    nis_bounds : (lower, upper) chi-square bounds of ``nis_mean`` at level ``alpha``, dimension
        ``len(measurements)``; nees_mean : time-averaged NEES (6 degrees of freedom)
    """

    filter: str
    q_scale: float
    measurements: tuple
    t: np.ndarray
    errors: np.ndarray
    sigma2: np.ndarray
    P: np.ndarray
    nis: np.ndarray
    nis_mean: float
    n_nis: int
    nis_bounds: tuple[float, float]
    nees_mean: float
    alpha: float

    @property
    def nis_dim(self) -> int:
        """Degrees of freedom of one NIS: the number of measurements used."""
        return len(self.measurements)

    @property
    def nis_inside(self) -> bool:
        """True when the time-averaged NIS lies inside its chi-square bounds."""
        return bool(self.nis_bounds[0] <= self.nis_mean <= self.nis_bounds[1])

    def summary(self) -> str:
        """One line: filter, Q scale, measurements, time-averaged NIS against its bounds."""
        names = ", ".join(MEASUREMENT_NAMES[i] for i in self.measurements)
        lo, hi = self.nis_bounds
        verdict = "inside" if self.nis_inside else ("below" if self.nis_mean < lo else "above")
        return (f"{self.filter.upper()}, Q = {self.q_scale:.3g} Qtrue, {self.nis_dim} measurements ({names}): "
                f"time-averaged NIS {self.nis_mean:.3f}, {verdict} [{lo:.3f}, {hi:.3f}] "
                f"(chi-square, {self.nis_dim} x {self.n_nis} dof / {self.n_nis}); NEES {self.nees_mean:.2f}")


def compute_coop_demo(log: CoopLog, filter: str = "ekf", q_scale: float | None = None, measurements=None,
                      alpha: float = 0.05) -> CoopDemo:
    """Run the EKF or UKF on a simulated log and test its NIS, for one redraw of the demo.

    Parameters
    ----------
    log : CoopLog with its truth (``generate_log()``); y (K, 5), truth (K, 6)
    filter : "ekf" or "ukf"
    q_scale : the filter's Q = q_scale * Qtrue, > 0 (default: the tuned ``TUNED_Q_SCALE[filter]``)
    measurements : rows of y to use, distinct integers in 0..4 (0 bearing UGV->UAV, 1 range,
        2 bearing UAV->UGV, 3 UAV GPS east, 4 UAV GPS north); default all five
    alpha : significance level of the NIS bounds, in (0, 1)

    Returns
    -------
    CoopDemo
    """
    if not isinstance(log, CoopLog):
        raise ValueError(f"log must be a CoopLog (e.g. generate_log()), got {type(log).__name__}")
    if log.truth is None:
        raise ValueError("log must carry its truth (a simulated log, generate_log()) to draw the errors")
    filter = require_choice("filter", filter, COOP_DEMO_FILTERS)
    q_scale = TUNED_Q_SCALE[filter] if q_scale is None else require_positive("q_scale", q_scale)
    idx = measurement_subset(measurements)
    idx = tuple(range(N_MEAS)) if idx is None else idx
    p = log.params()
    res = run_filter(filter, log.y, p, Q=q_scale * p.Qtrue, truth=log.truth, measurements=idx)
    has = np.isfinite(res.nis)
    n_nis = int(has.sum())
    if n_nis == 0:
        raise ValueError("log must hold at least one measurement row")
    bounds = chi2_bounds(len(idx), n_nis, alpha)
    return CoopDemo(filter, float(q_scale), idx, res.t, res.errors(log.truth), res.sigma2, res.P, res.nis,
                    float(np.mean(res.nis[has])), n_nis, bounds, float(np.mean(res.nees)), float(alpha))


class CoopDemoFigure:
    """The cooperative-localization demo's figure, built once; :meth:`update` puts a new
    :class:`CoopDemo` into the same lines.  Six panels (UGV in the top row, UAV in the bottom
    row): the estimation error and the filter's +-2 sigma bounds.  ``figure`` as in
    :class:`CalibrationDemoFigure`."""

    def __init__(self, figure=None):
        self.fig = _new_figure(figure, (11.0, 5.4))
        self.axes = self.fig.subplots(2, 3, sharex=True)
        self.lines = []
        for i, ax in enumerate(self.axes.flat):
            err, = ax.plot([], [], color="C3", lw=0.7, label="error")
            up, = ax.plot([], [], color="k", lw=0.8, label=r"$\pm 2\sigma$")
            down, = ax.plot([], [], color="k", lw=0.8)
            self.lines.append((err, up, down))
            ax.set_ylabel(f"error {STATE_LABELS[i]}")
        for ax in self.axes[-1]:
            ax.set_xlabel("time $t$ [s]")
        self.axes[0, 0].legend(loc="upper right", fontsize=8)
        self.fig.subplots_adjust(left=0.08, right=0.975, bottom=0.1, top=0.86, wspace=0.4, hspace=0.12)

    def update(self, demo: CoopDemo):
        """Draw ``demo`` into the figure; returns the Figure."""
        if not isinstance(demo, CoopDemo):
            raise ValueError(f"demo must be a CoopDemo, got {type(demo).__name__}")
        skip = min(10, demo.t.size - 1)  # the y scale ignores the first second (prior sigma)
        for i, (ax, (err, up, down)) in enumerate(zip(self.axes.flat, self.lines)):
            err.set_data(demo.t, demo.errors[:, i])
            up.set_data(demo.t, demo.sigma2[:, i])
            down.set_data(demo.t, -demo.sigma2[:, i])
            top = max(demo.sigma2[skip:, i].max(), np.abs(demo.errors[skip:, i]).max())
            ax.set_ylim(-1.15 * top, 1.15 * top)
        self.axes[0, 0].set_xlim(demo.t[0], demo.t[-1])
        lo, hi = demo.nis_bounds
        names = ", ".join(MEASUREMENT_NAMES[i] for i in demo.measurements)
        self.fig.suptitle(f"{demo.filter.upper()}, Q = {demo.q_scale:.3g} Qtrue, measurements: {names}\n"
                          f"errors with ±2σ; time-averaged NIS {demo.nis_mean:.2f}, bounds [{lo:.2f}, {hi:.2f}] "
                          f"({demo.nis_dim} dof)", fontsize=10)
        return self.fig


def draw_coop_demo(demo: CoopDemo):
    """A new figure of ``demo`` (see :class:`CoopDemoFigure`); returns the Figure."""
    return CoopDemoFigure().update(demo)


# ---------------------------------------------------------------------------
# Widgets
def figure_png(fig) -> bytes:
    """The figure rendered once by Agg and encoded as an RGB PNG with light compression, for an
    ``ipywidgets.Image`` (about twice as fast as ``savefig``, which renders again for the tight
    bounding box of this collection's style)."""
    from PIL import Image

    if not isinstance(fig, Figure):
        raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    rgba = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
    buf = io.BytesIO()
    rgba.convert("RGB").save(buf, format="png", compress_level=1)
    return buf.getvalue()


#: figure sizes (inches, at the notebook style's 90 dpi) of the live views: with the controls in a
#: column beside the image, the whole demo fits a 1280x800 browser window (tests/test_browser_demos.py)
LIVE_FIGSIZE = {"calibration": (7.8, 5.4), "coop": (8.4, 4.9)}
#: width of the controls' column
CONTROLS_WIDTH = "350px"

#: what a redraw turns into a one-line message instead of a traceback: ``numpy.linalg.LinAlgError``
#: (a ValueError: a covariance that is no longer positive definite), any other ValueError (a value
#: the filter or the draw cannot use), arithmetic faults, and warnings (raised as errors while a
#: redraw runs, so a RuntimeWarning of an overflow never reaches the notebook)
DEMO_FAILURES = (ValueError, ArithmeticError, Warning)

#: the arrays of a demo that must be finite before it is drawn
_FINITE_FIELDS = {CalibrationDemo: ("error", "sigma", "ens_std", "P_post"),
                  CoopDemo: ("errors", "sigma2", "P", "nis_mean", "nees_mean")}


def _require_finite_demo(demo) -> None:
    for name in _FINITE_FIELDS.get(type(demo), ()):
        if not np.all(np.isfinite(getattr(demo, name))):
            raise ValueError(f"the result is not finite ({name} holds inf or NaN): the filter diverged")


def failure_message(error: BaseException) -> str:
    """One line that says why a redraw failed, for the figure area of a live demo."""
    text = " ".join(str(error).split()) or type(error).__name__
    if len(text) > 80:
        text = text[:77] + "..."
    if isinstance(error, np.linalg.LinAlgError):
        return f"the filter failed: its covariance is no longer positive definite ({text})"
    if isinstance(error, Warning):
        return f"the computation overflowed or lost precision ({type(error).__name__}: {text})"
    return f"cannot compute these settings: {text}"


def _format_value(value) -> str:
    if isinstance(value, (float, np.floating)):
        return f"{value:.3g}"
    if isinstance(value, tuple) and all(isinstance(v, (int, float, np.number)) for v in value):
        return "–".join(f"{v:g}" for v in value)
    return str(value)


def describe_controls(controls: dict, values: dict | None = None) -> str:
    """Settings of ``controls`` in one line (``values`` by name, default the controls' own):
    ``description value`` for every control that is not a checkbox, then the descriptions of the
    ticked checkboxes (or "none ticked")."""
    import ipywidgets as w

    values = {} if values is None else values
    parts, ticked, boxes = [], [], 0
    for name, c in controls.items():
        value = values.get(name, c.value)
        if isinstance(c, w.Checkbox):
            boxes += 1
            if value:
                ticked.append(c.description)
            continue
        for option in getattr(c, "options", ()) if isinstance(c, (w.ToggleButtons, w.Dropdown)) else ():
            if isinstance(option, tuple) and option[1] == value:
                value = option[0]
        parts.append(f"{c.description} {_format_value(value)}")
    if boxes:
        parts.append("on: " + (", ".join(ticked) if ticked else "none ticked"))
    return "; ".join(parts)


class LiveDemo:
    """A live demo in the notebook: ``controls`` (a dict of ipywidgets, as
    :func:`calibration_controls` / :func:`coop_controls` return) in a column beside an
    ``ipywidgets.Image`` of ``view``'s figure, and one line of text under it.

    A change of any control calls ``compute(**values)`` (the control values by name; it returns
    a :class:`CalibrationDemo` or :class:`CoopDemo`, or None when there is nothing to draw),
    puts the result into ``view`` (a :class:`CalibrationDemoFigure` or :class:`CoopDemoFigure`)
    and shows its PNG; the line shows ``demo.summary()`` when the demo has one.  A redraw that
    fails (:data:`DEMO_FAILURES`, e.g. the UKF's covariance losing positive definiteness, or a
    result that is not finite) shows instead an image of the same size with the settings as its
    title and a one-line message, so the title always matches what is drawn and no traceback or
    warning appears.  ``empty`` is the message when ``compute`` returns None; ``hint`` (optional)
    is appended to a failure message.
    """

    def __init__(self, controls: dict, compute, view, empty: str = "nothing to draw for these settings",
                 hint: str = ""):
        import ipywidgets as w

        if not isinstance(controls, dict) or not controls:
            raise ValueError("controls must be a non-empty dict of ipywidgets, e.g. calibration_controls()")
        if not callable(compute):
            raise ValueError(f"compute must be callable (control values -> demo), got {type(compute).__name__}")
        if not isinstance(view, (CalibrationDemoFigure, CoopDemoFigure)):
            raise ValueError(f"view must be a CalibrationDemoFigure or CoopDemoFigure, got {type(view).__name__}")
        self.controls, self.compute, self.view, self.empty, self.hint = controls, compute, view, empty, hint
        self.message_fig = Figure(figsize=view.fig.get_size_inches(), dpi=view.fig.dpi)
        FigureCanvasAgg(self.message_fig)
        self.image = w.Image(format="png")
        self.line = w.HTML()
        self.failed = False
        column = w.VBox(list(controls.values()), layout=w.Layout(width=CONTROLS_WIDTH, flex="0 0 auto"))
        self.widget = w.HBox([column, w.VBox([self.image, self.line])],
                             layout=w.Layout(align_items="flex-start"))
        for c in controls.values():
            c.observe(self._changed, names="value")
        self.refresh()

    def values(self) -> dict:
        """The controls' current values, by name."""
        return {name: c.value for name, c in self.controls.items()}

    def render(self, **values) -> tuple[bytes, str, bool]:
        """One redraw for ``values`` (default: the controls' current values), without touching the
        widgets: returns ``(png, line, ok)``; ``ok`` is False when the PNG shows a message."""
        import warnings

        values = {**self.values(), **values}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                demo = self.compute(**values)
                if demo is None:
                    return self._message_png(values, self.empty), self.empty, False
                _require_finite_demo(demo)
                png = figure_png(self.view.update(demo))
        except DEMO_FAILURES as error:
            text = failure_message(error)
            return self._message_png(values, text), text + (f"; {self.hint}" if self.hint else ""), False
        return png, demo.summary() if hasattr(demo, "summary") else "", True

    def refresh(self):
        """Redraw for the controls' current values and show the result."""
        import html

        try:
            png, line, ok = self.render()
        except Exception as error:  # a live demo never shows a traceback; say what happened in one line
            text = " ".join(str(error).split())[:80]
            line = f"unexpected error, nothing drawn: {type(error).__name__}: {text}"
            png, ok = self._message_png(self.values(), line), False
        self.failed = not ok
        self.image.value = png
        self.line.value = f"<span style='font-size: 12px'>{html.escape(line)}</span>"

    def _changed(self, change):
        self.refresh()

    def _message_png(self, values, text) -> bytes:
        fig = self.message_fig
        fig.clear()
        fig.suptitle(f"{describe_controls(self.controls, values)}\nnot drawn", fontsize=9)
        fig.text(0.5, 0.5, text, ha="center", va="center", fontsize=9, color="C3", wrap=True)
        return figure_png(fig)


def calibration_controls() -> dict:
    """The calibration demo's controls (ipywidgets), by name, at the default parameters.

    ``gps_rate`` (Hz, a selection slider of the rates that divide 200 Hz), ``W``
    ((m/s²)², log scale), ``gps_pos_sigma`` (m, log scale), ``bias_sigma`` (prior σ of the
    bias, m/s², log scale), ``outage_on`` (checkbox) and ``outage`` (window, s).
    """
    import ipywidgets as w

    style = {"description_width": "140px"}
    layout = w.Layout(width="340px")
    return {
        "gps_rate": w.SelectionSlider(options=valid_gps_rates(), value=5.0, description="GPS rate [Hz]",
                                      style=style, layout=layout),
        "W": w.FloatLogSlider(value=4e-4, base=10, min=-6, max=-2, step=0.1, readout_format=".1e",
                              description="IMU noise W [(m/s²)²]", style=style, layout=layout),
        "gps_pos_sigma": w.FloatLogSlider(value=1.0, base=10, min=-1, max=1, step=0.05, readout_format=".2f",
                                          description="GPS σ_p [m]", style=style, layout=layout),
        "bias_sigma": w.FloatLogSlider(value=0.1, base=10, min=-3, max=0, step=0.1, readout_format=".3f",
                                       description="bias prior σ [m/s²]", style=style, layout=layout),
        "outage_on": w.Checkbox(value=True, description="GPS outage", style=style),
        "outage": w.FloatRangeSlider(value=(12.0, 18.0), min=0.0, max=30.0, step=0.5, readout_format=".1f",
                                     description="outage window [s]", style=style, layout=layout),
    }


def coop_controls() -> dict:
    """The cooperative-localization demo's controls (ipywidgets), by name: ``filter``
    (EKF/UKF toggle), ``q_scale`` (Q = q_scale Qtrue, log scale, default the EKF's truth-model-tuned scale)
    and one checkbox per measurement, ``m0`` .. ``m4`` (all ticked).  They update on release
    (a UKF run takes a few tenths of a second)."""
    import ipywidgets as w

    style = {"description_width": "120px"}
    controls = {
        "filter": w.ToggleButtons(options=[("EKF", "ekf"), ("UKF", "ukf")], value="ekf", description="filter",
                                  style={**style, "button_width": "80px"}),
        "q_scale": w.FloatLogSlider(value=TUNED_Q_SCALE["ekf"], base=10, min=-2, max=2, step=0.1,
                                    readout_format=".3g", continuous_update=False, description="Q / Qtrue",
                                    style=style, layout=w.Layout(width="340px")),
    }
    for i, name in enumerate(MEASUREMENT_NAMES):
        controls[f"m{i}"] = w.Checkbox(value=True, description=name, indent=False, layout=w.Layout(width="300px"))
    return controls
