"""The calibration lecture demo (notebook 17): what one slider move recomputes, and the figure it redraws.

:func:`compute_calibration_demo` runs the batch filter for one parameter set and returns plain arrays
in a :class:`CalibrationDemo`: the covariances and gains once
(:func:`~kfcal_helpers.calibration.covariance_sequence`, propagated fix to fix), one 200 Hz
realization (``simulate``) and a 200-realization ensemble drawn at the fixes
(:func:`~kfcal_helpers.calibration.engine.sample_noise_at_fixes`; its standard normals are kept for
the next redraw with the same seed and GPS rate), whose errors come from the
filter's error recursion (:func:`~kfcal_helpers.calibration.engine.filter_errors_at_fixes`, the
numbers ``batch_filter`` gives on the same draws); the ensemble's spread is compared with the
filter's sigma at every GPS epoch (a 1/gps_rate time slot, its fix dropped during an outage).
:class:`CalibrationDemoFigure` draws the errors with their +-2 sigma bands; it builds its figure once and
:meth:`~CalibrationDemoFigure.update` only replaces the data, and :meth:`~CalibrationDemoFigure.draw`
renders it with the x axes and the legend (the same for every setting) kept from the first render, so a
redraw renders only what changed.  :func:`calibration_controls` builds the sliders; the notebook wires
them to the figure with the shared :class:`kfcal_helpers.demos.LiveDemo`.  The benchmark
(``benchmarks/bench_demos.py``) and the tests time and check the compute function on its own.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from typing import ClassVar

import numpy as np

from ..consistency import chi2_bounds
from ..demos import CachedBackground, DemoFigure, new_figure
from ..validation import (require_choice, require_finite, require_instance, require_int, require_positive,
                          require_probability)
from .engine import (covariance_sequence, estimate_between_fixes, filter_errors_time_major, noise_of_simulation,
                     scale_unit_noise, unit_noise_time_major)
from .outages import outage_mask
from .params import CalibrationParams
from .simulation import simulate

__all__ = ["ENSEMBLES", "LIVE_FIGSIZE", "W_STOPS", "valid_gps_rates", "CalibrationDemo", "compute_calibration_demo",
           "CalibrationDemoFigure", "draw_calibration_demo", "calibration_controls"]

#: how the demo's ensemble is drawn: at the fixes only, or by the full 200 Hz simulation
ENSEMBLES = ("fixes", "simulate")
#: figure size (inches, at the notebook style's 90 dpi: 819 x 423 px) of the live view: the width
#: JupyterLab gives a notebook's output in a 1280x800 browser window with the file browser open (833 px),
#: so the image is shown pixel for pixel, its smallest text (9 pt) 11 px; with the controls in two rows
#: above it the whole demo fits that window (tests/test_browser_demos.py)
LIVE_FIGSIZE = (9.1, 4.7)
#: the W slider's stops, (m/s²)²: the R10 preferred numbers (1, 1.25, 1.6, 2, 2.5, 3.15, 4, 5, 6.3, 8: ten
#: steps a decade, 10 ** (k / 10) rounded) from 1e-6 to 1e-2; the course's W = 4e-4 is one of them, exactly
#: (a log slider of base 10 has no stop at 4e-4: it would move the default to 10 ** -3.4 = 3.98e-4)
W_STOPS = tuple(float(f"{m}e{e}") for e in range(-6, -2) for m in ("1", "1.25", "1.6", "2", "2.5", "3.15", "4", "5",
                                                                     "6.3", "8")) + (1e-2,)


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



@lru_cache(maxsize=8)
def _unit_draws(seed_entropy: int, n_runs: int, n_gps: int):
    """The ensemble's standard normal draws for one seed, ensemble size and number of fixes (read-only
    arrays): a slider move that keeps the GPS rate draws nothing new (common random numbers)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed_entropy).spawn(2)[1])
    draws = unit_noise_time_major(n_gps, n_runs, rng)
    for a in draws:
        a.flags.writeable = False
    return draws


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

    #: the arrays that must be finite before the demo is drawn (read by kfcal_helpers.demos.LiveDemo)
    finite_fields: ClassVar[tuple] = ("error", "sigma", "ens_std", "P_post")

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
    base = require_instance("base", base, CalibrationParams, allow_none=True) or CalibrationParams()
    params = replace(base, gps_rate=gps_rate, W=W, gps_pos_var=gps_pos_var, bias_var=bias_var)
    n_runs = require_int("n_runs", n_runs, minimum=2)
    seed = require_int("seed", seed, minimum=0)
    require_choice("ensemble", ensemble, ENSEMBLES)
    alpha = require_probability("alpha", alpha)
    if outage is None:
        missing = np.zeros(params.n_gps, bool)
    else:
        missing = outage_mask(params, [outage], name="outage")
        outage = (float(outage[0]), float(outage[1]))

    cov = covariance_sequence(params, missing)
    rng_one, rng_ens = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))

    sim = simulate(params, 1, rng_one, missing_fixes=missing)  # the realization drawn at 200 Hz
    if ensemble == "fixes":
        # the draws of sample_noise_time_major(params, n_runs, rng_ens), their standard normals kept
        e0, w_t, eta_t = scale_unit_noise(params, *_unit_draws(seed, n_runs, params.n_gps))
    else:
        e0, w, eta = noise_of_simulation(simulate(params, n_runs, rng_ens, missing_fixes=missing))
        w_t, eta_t = w.transpose(1, 0, 2), eta.transpose(1, 0, 2)
    # the filter's errors at the fixes: the realization (column 0) and the ensemble in one loop
    one = noise_of_simulation(sim)
    e_post = filter_errors_time_major(params, cov, np.concatenate([one[0], e0]),
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


class CalibrationDemoFigure(DemoFigure):
    """The calibration demo's figure, built once; :meth:`update` puts a new
    :class:`CalibrationDemo` into the same lines (a redraw then only re-renders).

    Three panels (position, velocity, bias): one realization's error at 200 Hz, the filter's
    +-2 sigma, the ensemble's +-2 s at the GPS epochs, the outage shaded (above the grid, under the curves).
    Above the panels, outside them (so they never cover a curve): the figure's two-line title (the
    settings; the share of (GPS epoch, state) pairs, over all three panels, whose s/sigma is inside
    its pointwise band), then a row with the note on the y axes' scale at its left and the legend at
    its right.  The rows have fixed heights in inches, the same in the live view and a larger figure.
    :meth:`draw` renders it onto its Agg canvas with the x axes, the legend and the note kept from the first
    render (a :class:`kfcal_helpers.demos.CachedBackground`), the same image as ``fig.canvas.draw()``.
    ``figure``: a Figure to draw on (e.g. ``matplotlib.figure.Figure()`` for a widget, outside pyplot); default a new
    pyplot figure.  ``t_zoom`` (s): the y axes are scaled to the curves after ``t_zoom``: the filter's
    sigma is largest in the first seconds, most of all the bias's (at the defaults 2 sigma_b is 0.2 m/s^2
    at t = 0 and at most 0.0375 m/s^2 after 2 s; 2 sigma_p is 1.99 m just after the first fix and at most
    0.60 m after 2 s), which would flatten the rest of the curves.
    """

    #: inches above the panels: the two-line title (10 pt) and the row of the legend (9 pt)
    HEADER_IN = 0.74
    #: inches under the panels: the tick labels and the time label
    FOOTER_IN = 0.47

    def __init__(self, figure=None, t_zoom: float = 2.0):
        t_zoom = require_finite("t_zoom", t_zoom)
        if t_zoom < 0:
            raise ValueError(f"t_zoom must be a time >= 0 s (the y axes are scaled to the curves after it), "
                             f"got {t_zoom!r}")
        self.t_zoom = t_zoom
        self.fig = new_figure(figure, (9.0, 7.2))
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
        self.axes[-1].set_xlabel("time $t$ [s]")
        height = self.fig.get_figheight()
        left, right, top = 0.095, 0.985, 1 - self.HEADER_IN / height
        self.fig.subplots_adjust(left=left, right=right, bottom=self.FOOTER_IN / height, top=top, hspace=0.2)
        # the legend and the note on the y scale in a row of their own between the title and the panels: outside
        # every panel, so no setting of the sliders puts a curve under them
        self.legend = self.fig.legend(handles=[self.lines[0][i] for i in (0, 1, 3)], loc="lower right", bbox_to_anchor=(right, top),
                                      ncol=3, fontsize=9, frameon=False, borderaxespad=0.3, borderpad=0.1,
                                      columnspacing=1.2)
        self.note = self.fig.text(left, top + 0.04 / height, "", fontsize=9, ha="left", va="bottom")
        self.title = self.fig.suptitle("", y=1 - 0.05 / height, va="top", fontsize=10, fontweight="normal")
        # the outage shading, one per panel, moved by update (hidden without an outage); zorder between the
        # axes' grid (1.5) and the lines (2), so it is drawn after the kept x axes
        self._shades = [ax.axvspan(0.0, 0.0, color="C1", alpha=0.2, lw=0, zorder=1.6, visible=False)
                        for ax in self.axes]
        self.spans = []  #: the outage shading drawn (one per panel, or none without an outage)
        # the x axes (time, ticks, grid, label) only change with the time span, the legend and the note with
        # their texts: drawn once, again when these change
        self.background = CachedBackground(self.fig, [*(ax.xaxis for ax in self.axes), self.legend, self.note],
                                           key=self._background_key)

    def _background_key(self):
        """What the kept background depends on: the x limits, the legend's texts and the note."""
        return (tuple(ax.get_xlim() for ax in self.axes), tuple(t.get_text() for t in self.legend.get_texts()),
                self.note.get_text())

    def update(self, demo: CalibrationDemo):
        """Draw ``demo`` into the figure; returns the Figure."""
        if not isinstance(demo, CalibrationDemo):
            raise ValueError(f"demo must be a CalibrationDemo, got {type(demo).__name__}")
        p = demo.params
        late, late_fix = demo.t >= self.t_zoom, demo.t_gps >= self.t_zoom
        zoomed = bool(late_fix.any() and self.t_zoom > demo.t[0])
        if not late_fix.any():
            late, late_fix = np.ones_like(late), np.ones_like(late_fix)
        for shade in self._shades:
            shade.set_visible(demo.outage is not None)
            if demo.outage is not None:
                shade.set_x(demo.outage[0])
                shade.set_width(demo.outage[1] - demo.outage[0])
        self.spans = list(self._shades) if demo.outage is not None else []
        for k, (ax, (err, up, down, ens_up, ens_down)) in enumerate(zip(self.axes, self.lines)):
            s2, e2 = 2 * demo.sigma[:, k], 2 * demo.ens_std[:, k]
            err.set_data(demo.t, demo.error[:, k])
            up.set_data(demo.t, s2)
            down.set_data(demo.t, -s2)
            ens_up.set_data(demo.t_gps, e2)
            ens_down.set_data(demo.t_gps, -e2)
            top = max(s2[late].max(), e2[late_fix].max(), np.abs(demo.error[late, k]).max())
            ax.set_ylim(-1.15 * top, 1.15 * top)
        self.axes[0].set_xlim(demo.t[0], demo.t[-1])
        self.legend.get_texts()[2].set_text(f"ensemble $\\pm 2s$ ({demo.n_runs} realizations)")
        self.note.set_text(f"y axes scaled to t ≥ {self.t_zoom:g} s" if zoomed else "")
        lo, hi = demo.ratio_band
        gap = "" if demo.outage is None else f", outage {demo.outage[0]:g}–{demo.outage[1]:g} s"
        # short lines in normal weight: text is most of the cost of a redraw
        # the sigmas to 3 significant digits, as the sliders' readouts show them (10 ** 0.5 m: 3.16)
        self.title.set_text(f"Errors with ±2σ: GPS {p.gps_rate:g} Hz, W {p.W:.2e} (m/s²)², GPS σ "
                            f"{np.sqrt(p.gps_pos_var):.3g} m, bias prior σ {np.sqrt(p.bias_var):.3g} m/s²{gap}\n"
                            f"Ensemble, all three panels: s/σ inside [{lo:.3f}, {hi:.3f}] at "
                            f"{100 * demo.inside_fraction:.1f} % of (GPS epoch, state) pairs")
        return self.fig



def draw_calibration_demo(demo: CalibrationDemo, t_zoom: float = 2.0):
    """A new figure of ``demo`` (see :class:`CalibrationDemoFigure`); returns the Figure."""
    return CalibrationDemoFigure(t_zoom=t_zoom).update(demo)


def calibration_controls() -> dict:
    """The calibration demo's controls (ipywidgets), by name, at the default parameters.

    ``gps_rate`` (Hz, a selection slider of the rates that divide 200 Hz), ``W``
    ((m/s²)², a selection slider of :data:`W_STOPS`), ``gps_pos_sigma`` (m, log scale), ``bias_sigma``
    (prior σ of the bias, m/s², log scale), ``outage_on`` (checkbox) and ``outage`` (window, s).
    Every default is a stop of its slider (a log slider's stops are ``base ** (min + k * step)``): the
    browser moves a value that is not onto the nearest stop when it draws the slider, and the figure
    would then show other numbers than the defaults.
    """
    import ipywidgets as w

    # three controls a row above the figure (LiveDemo): two rows in the notebook's 833 px (a 1280x800
    # window with the file browser open); every description at its natural width
    style = {"description_width": "initial"}

    def width(px):
        return w.Layout(width=f"{px}px")

    return {
        "gps_rate": w.SelectionSlider(options=valid_gps_rates(), value=5.0, description="GPS rate [Hz]",
                                      style=style, layout=width(255)),
        "W": w.SelectionSlider(options=[(f"{v:.2e}", v) for v in W_STOPS], value=4e-4,
                               description="IMU noise W [(m/s²)²]", style=style, layout=width(320)),
        "gps_pos_sigma": w.FloatLogSlider(value=1.0, base=10, min=-1, max=1, step=0.05, readout_format=".2f",
                                          description="GPS σ [m]", style=style, layout=width(245)),
        "bias_sigma": w.FloatLogSlider(value=0.1, base=10, min=-3, max=0, step=0.1, readout_format=".3f",
                                       description="bias prior σ [m/s²]", style=style, layout=width(300)),
        "outage_on": w.Checkbox(value=True, description="GPS outage", indent=False, style=style, layout=width(115)),
        "outage": w.FloatRangeSlider(value=(12.0, 18.0), min=0.0, max=30.0, step=0.5, readout_format=".1f",
                                     description="outage window [s]", style=style, layout=width(380)),
    }
