"""The cooperative-localization live demo (notebook 18): what one slider move recomputes, and the
figure it redraws.

:func:`compute_coop_demo` runs the EKF or UKF on a log with ``Q = q_scale * Qtrue`` and a chosen
subset of the five measurements (the lean single run of :mod:`~kfcal_helpers.coop.fast`, equal to
filterpy's filters of :func:`~kfcal_helpers.coop.filters.run_filter` to rounding), and tests the time-averaged NIS against its chi-square bounds
(dimension = number of measurements used); :class:`CoopDemoFigure` draws the six estimation errors
with their +-2 sigma bounds, built once so that :meth:`~CoopDemoFigure.update` only replaces the
data.  :func:`coop_controls` builds the controls; the shared :class:`kfcal_helpers.demos.LiveDemo`
puts them beside the figure's PNG (:func:`kfcal_helpers.demos.figure_png`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..consistency import chi2_bounds
from ..demos import CachedBackground, DemoFigure, error_lines, new_figure, show_errors
from ..validation import require_choice, require_instance, require_positive, require_probability
from .data import CoopLog
from .fast import run_filter_fast
from .filters import TUNED_Q_SCALE, measurement_subset
from .model import N_MEAS, STATE_LABELS

__all__ = ["COOP_DEMO_FILTERS", "MEASUREMENT_NAMES", "LIVE_FIGSIZE", "CoopDemo", "compute_coop_demo", "CoopDemoFigure",
           "draw_coop_demo", "coop_controls"]

COOP_DEMO_FILTERS = ("ekf", "ukf")
#: the five measurements, in the order of the rows of y
MEASUREMENT_NAMES = ("bearing UGV→UAV", "range", "bearing UAV→UGV", "UAV GPS east", "UAV GPS north")
#: figure size (inches, at the notebook style's 90 dpi: 819 x 378 px) of the live view: the width
#: JupyterLab gives a notebook's output in a 1280x800 browser window with the file browser open (833 px),
#: so the image is shown pixel for pixel, its smallest text (9 pt) 11 px; with the controls in two rows
#: above it and the two-line NIS summary under it the whole demo fits that window
#: (tests/test_browser_demos.py)
LIVE_FIGSIZE = (9.1, 4.2)


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

    #: the arrays that must be finite before the demo is drawn (:class:`kfcal_helpers.demos.LiveDemo`)
    finite_fields = ("errors", "sigma2", "P", "nis_mean", "nees_mean")

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

    @property
    def nis_verdict(self) -> str:
        """Where the time-averaged NIS lies against its bounds: "inside", "below" or "above"."""
        lo, hi = self.nis_bounds
        return "inside" if self.nis_inside else ("below" if self.nis_mean < lo else "above")

    def summary(self) -> str:
        """One line: filter, Q scale, measurements, time-averaged NIS against its bounds."""
        names = ", ".join(MEASUREMENT_NAMES[i] for i in self.measurements)
        lo, hi = self.nis_bounds
        verdict = self.nis_verdict
        return (f"{self.filter.upper()}, Q = {self.q_scale:.3g} Qtrue, {self.nis_dim} measurements ({names}): "
                f"time-averaged NIS {self.nis_mean:.3f}, {verdict} [{lo:.3f}, {hi:.3f}] "
                f"(chi-square, {self.nis_dim} x {self.n_nis} dof / {self.n_nis}); NEES {self.nees_mean:.2f}")


def compute_coop_demo(log: CoopLog, filter: str = "ekf", q_scale: float | None = None, measurements=None,
                      alpha: float = 0.05) -> CoopDemo:
    """Run the EKF or UKF on a simulated log and test its NIS, for one redraw of the demo.

    Parameters
    ----------
    log : CoopLog with its truth (``simulate().log()``); y (K, 5), truth (K, 6)
    filter : "ekf" or "ukf"
    q_scale : the filter's Q = q_scale * Qtrue, > 0 (default: the tuned ``TUNED_Q_SCALE[filter]``)
    measurements : rows of y to use, distinct integers in 0..4 (0 bearing UGV->UAV, 1 range,
        2 bearing UAV->UGV, 3 UAV GPS east, 4 UAV GPS north); default all five
    alpha : significance level of the NIS bounds, in (0, 1)

    Returns
    -------
    CoopDemo
    """
    require_instance("log", log, CoopLog)
    if log.truth is None:
        raise ValueError("log must carry its truth (a simulated log, simulate().log()) to draw the errors")
    filter = require_choice("filter", filter, COOP_DEMO_FILTERS)
    q_scale = TUNED_Q_SCALE[filter] if q_scale is None else require_positive("q_scale", q_scale)
    alpha = require_probability("alpha", alpha)
    idx = measurement_subset(measurements)
    idx = tuple(range(N_MEAS)) if idx is None else idx
    p = log.params()
    # the lean single run (kfcal_helpers.coop.fast), equal to filterpy's run_filter to rounding
    res = run_filter_fast(filter, log.y, p, Q=q_scale * p.Qtrue, truth=log.truth, measurements=idx)
    has = np.isfinite(res.nis)
    n_nis = int(has.sum())
    if n_nis == 0:
        raise ValueError("log must hold at least one measurement row")
    bounds = chi2_bounds(len(idx), n_nis, alpha)
    return CoopDemo(filter, float(q_scale), idx, res.t, res.errors(log.truth), res.sigma2, res.P, res.nis,
                    float(np.mean(res.nis[has])), n_nis, bounds, float(np.mean(res.nees)), float(alpha))


class CoopDemoFigure(DemoFigure):
    """The cooperative-localization demo's figure, built once; :meth:`update` puts a new
    :class:`CoopDemo` into the same lines.  Six panels (UGV in the top row, UAV in the bottom
    row): the estimation error and the filter's +-2 sigma bounds.  :meth:`draw` renders it onto its Agg
    canvas with the x axes and the legend kept from the first render (a :class:`kfcal_helpers.demos.CachedBackground`),
    the same image as ``fig.canvas.draw()``.  ``figure``: a matplotlib
    Figure to draw into (e.g. ``Figure(figsize=LIVE_FIGSIZE)`` for the live view), else a new
    pyplot figure.  Above the panels, outside them (so they never cover a curve): the figure's
    two-line title (filter, Q, measurements; the NIS against its bounds), then the legend in a row of
    its own, at the right.  The rows have fixed heights in inches, the same in the live view and a
    larger figure."""

    #: inches above the panels: the two-line title (10 pt) and the row of the legend (9 pt)
    HEADER_IN = 0.74
    #: inches under the panels: the tick labels and the time label
    FOOTER_IN = 0.5

    def __init__(self, figure=None):
        self.fig = new_figure(figure, (11.0, 5.4))
        self.axes = self.fig.subplots(2, 3, sharex=True)
        self.lines = []
        for i, ax in enumerate(self.axes.flat):
            self.lines.append(error_lines(ax))
            ax.set_ylabel(f"{'UGV' if i < 3 else 'UAV'} error {STATE_LABELS[i]}")
        for ax in self.axes[-1]:
            ax.set_xlabel("time $t$ [s]")
        height = self.fig.get_figheight()
        right, top = 0.98, 1 - self.HEADER_IN / height
        self.fig.subplots_adjust(left=0.08, right=right, bottom=self.FOOTER_IN / height, top=top, wspace=0.38,
                                 hspace=0.14)
        # the legend in a row of its own between the title and the panels: outside every panel, so no
        # setting of the controls (a large Q widens the bounds to the panel's edge) puts a curve under it
        self.legend = self.fig.legend(handles=list(self.lines[0][:2]), loc="lower right", bbox_to_anchor=(right, top),
                                      ncol=2, fontsize=9, frameon=False, borderaxespad=0.3, borderpad=0.1,
                                      columnspacing=1.2)
        self.title = self.fig.suptitle("", y=1 - 0.05 / height, va="top", fontsize=10)
        # the x axes (time, ticks, grid, label) only change with the log's time span, and the legend never:
        # drawn once
        self.background = CachedBackground(self.fig, [*(ax.xaxis for ax in self.axes.flat), self.legend],
                                           key=lambda: tuple(ax.get_xlim() for ax in self.axes.flat))

    def update(self, demo: CoopDemo):
        """Draw ``demo`` into the figure; returns the Figure."""
        require_instance("demo", demo, CoopDemo)
        skip = min(10, demo.t.size - 1)  # the y scale ignores the first second (prior sigma)
        for i, lines in enumerate(self.lines):
            show_errors(lines, demo.t, demo.errors[:, i], demo.sigma2[:, i], skip)
        self.axes[0, 0].set_xlim(demo.t[0], demo.t[-1])
        lo, hi = demo.nis_bounds
        names = ", ".join(MEASUREMENT_NAMES[i] for i in demo.measurements)
        # short lines: text is most of the cost of a redraw; the bounds are those of the average over the updates
        self.title.set_text(f"{demo.filter.upper()}, Q = {demo.q_scale:.3g} Qtrue, measurements: {names}\n"
                            f"errors with ±2σ; time-averaged NIS {demo.nis_mean:.2f} ({demo.nis_dim} dof per update, "
                            f"{demo.n_nis} updates): {demo.nis_verdict} [{lo:.2f}, {hi:.2f}]")
        return self.fig



def draw_coop_demo(demo: CoopDemo):
    """A new figure of ``demo`` (see :class:`CoopDemoFigure`); returns the Figure."""
    return CoopDemoFigure().update(demo)


def coop_controls() -> dict:
    """The cooperative-localization demo's controls (ipywidgets), by name: ``filter``
    (EKF/UKF toggle), ``q_scale`` (Q = q_scale Qtrue, log scale, default the EKF's truth-model-tuned scale)
    and one checkbox per measurement, ``m0`` .. ``m4`` (all ticked).  They update on release
    (each release runs the filter once and redraws)."""
    import ipywidgets as w

    # in rows above the figure (LiveDemo): two rows in the notebook's 833 px (a 1280x800 window with
    # the file browser open); descriptions and checkboxes at their natural width
    style = {"description_width": "initial"}
    controls = {
        "filter": w.ToggleButtons(options=[("EKF", "ekf"), ("UKF", "ukf")], value="ekf", description="filter",
                                  style={"description_width": "40px", "button_width": "70px"},
                                  layout=w.Layout(width="260px")),
        "q_scale": w.FloatLogSlider(value=TUNED_Q_SCALE["ekf"], base=10, min=-2, max=2, step=0.1,
                                    readout_format=".3g", continuous_update=False, description="Q / Qtrue",
                                    style=style, layout=w.Layout(width="330px")),
    }
    for i, name in enumerate(MEASUREMENT_NAMES):
        controls[f"m{i}"] = w.Checkbox(value=True, description=name, indent=False,
                                       layout=w.Layout(width="auto", margin="2px 14px 2px 2px"))
    return controls
