"""The orbit-determination live demo (notebook 24): the filter runs it draws from, and the figure it redraws.

A filterpy run of the EKF or UKF over the log's 1401 steps takes longer than a redraw may (roughly 0.2-0.3 s and
0.3-0.5 s on a quiet 2-core machine, ``benchmarks/bench_demos.py``), so the runs are done once, before the demo starts: :class:`OrbitDemoRuns`
(:func:`precompute_orbit_demo`) holds :func:`~kfcal_helpers.orbit.filters.run_filter`'s result of each
filter at each scale of a small grid, ``Q = q_scale * Qtrue`` with ``q_scale`` in :data:`Q_SCALES`, and the
per-step chi-square band of the NIS from the degrees of freedom present at each step (3 per station
seen).  :func:`compute_orbit_demo` picks one run and one time of the log (no filtering: a redraw only
selects and draws, at the sample time nearest the ``t`` asked for); :class:`OrbitDemoFigure` draws the orbit with the 12 stations, those whose
measurements the filter used at that time and their lines of sight, the four estimation errors with the
filter's +-2 sigma bounds and the NIS against its per-step band.  :func:`orbit_controls` builds the
controls; the shared :class:`kfcal_helpers.demos.LiveDemo` puts them beside the figure's PNG.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..consistency import chi2_sum_bounds
from ..demos import CachedBackground, DemoFigure, error_lines, new_figure, show_errors
from ..validation import require_choice, require_instance, require_probability
from .data import log_params
from .filters import FilterResult, run_filter
from .model import station_states
from .simulation import OrbitLog

__all__ = ["ORBIT_DEMO_FILTERS", "Q_SCALES", "LIVE_FIGSIZE", "LIVE_HINT", "ERROR_UNITS", "OrbitDemoRuns", "precompute_orbit_demo",
           "OrbitDemo", "compute_orbit_demo", "OrbitDemoFigure", "draw_orbit_demo", "orbit_controls"]

ORBIT_DEMO_FILTERS = ("ekf", "ukf")
#: the scales of Q = q_scale * Qtrue the demo runs in advance: the stops of its Q slider (10^-2 .. 10^3)
Q_SCALES = (0.01, 0.1, 1.0, 10.0, 100.0, 1000.0)
#: figure size (inches, at the notebook style's 90 dpi: 819 x 378 px) of the live view: the width JupyterLab
#: gives a notebook's output in a 1280x800 browser window with the file browser open (833 px), so the image is
#: shown pixel for pixel; with the controls in two rows above it and the two-line summary under it the whole
#: demo fits that window (tests/test_browser_demos.py)
LIVE_FIGSIZE = (9.1, 4.2)
#: what the live demo (:class:`kfcal_helpers.demos.LiveDemo`) adds to a failed redraw's message: what each control
#: accepts (a value typed into the Q readout between two stops has no run; a typed t is drawn at the nearest sample)
LIVE_HINT = "the Q / Qtrue slider has only its six precomputed stops; t snaps to the nearest sample time"
#: the four errors as drawn: state label, factor from the state's units (km, km/s) and the unit drawn
ERROR_UNITS = (("X", 1e3, "m"), (r"\dot X", 1e3, "m/s"), ("Y", 1e3, "m"), (r"\dot Y", 1e3, "m/s"))


def _q_key(q_scale) -> float:
    """The grid scale equal to ``q_scale`` (to a relative 1e-9, the rounding of a log slider), else ValueError."""
    if isinstance(q_scale, bool) or not isinstance(q_scale, (int, float, np.integer, np.floating)) \
            or not np.isfinite(q_scale):
        raise ValueError(f"q_scale must be one of the precomputed scales {', '.join(f'{q:g}' for q in Q_SCALES)}, "
                         f"got {q_scale!r}")
    for q in Q_SCALES:
        if abs(float(q_scale) - q) <= 1e-9 * q:
            return q
    raise ValueError(f"q_scale must be one of the precomputed scales {', '.join(f'{q:g}' for q in Q_SCALES)} "
                     f"(the filter runs are done in advance), got {float(q_scale):g}")


@dataclass(frozen=True, eq=False)
class OrbitDemoRuns:
    """The filter runs the demo draws from, made once (:func:`precompute_orbit_demo`).

    log : the OrbitLog, with its truth (K, 4); runs : {(filter, q_scale): FilterResult} for every filter of
    :data:`ORBIT_DEMO_FILTERS` and scale of :data:`Q_SCALES`; dof : (K,) the NIS's degrees of freedom per step
    (3 per station with a measurement, 0 without); nis_lower, nis_upper : (K,) its chi-square band at level
    ``alpha`` for the dof present (NaN where dof = 0)
    """

    log: OrbitLog
    runs: dict
    dof: np.ndarray
    nis_lower: np.ndarray
    nis_upper: np.ndarray
    alpha: float

    @property
    def default_time(self) -> float:
        """The time the demo shows first (s): the step whose measurements come from two or more stations (a pass
        seen from two places) nearest the middle of the log (the earlier of two as near), else the step with one
        station nearest it, else the log's start.  The middle keeps the time cursor away from the panels' left
        edge, where the prior's wide 2 sigma lines run."""
        t = self.log.t
        middle = 0.5 * (t[0] + t[-1])
        for least in (6, 3):
            steps = np.flatnonzero(self.dof >= least)
            if steps.size:
                return float(t[steps[np.argmin(np.abs(t[steps] - middle))]])
        return float(t[0])

    def result(self, filter: str, q_scale: float) -> FilterResult:
        """The run of ``filter`` ("ekf" or "ukf") with Q = ``q_scale`` Qtrue (a scale of :data:`Q_SCALES`)."""
        return self.runs[require_choice("filter", filter, ORBIT_DEMO_FILTERS), _q_key(q_scale)]


def precompute_orbit_demo(log: OrbitLog, alpha: float = 0.05) -> OrbitDemoRuns:
    """Run the EKF and the UKF (filterpy, :func:`~kfcal_helpers.orbit.filters.run_filter`) on ``log`` at every
    scale of :data:`Q_SCALES` (12 runs, some seconds) and build the NIS band of each step.

    log : OrbitLog with its truth (a simulated log, ``simulate().log()``); its Qtrue and Rtrue are the
    filters' (``log_params``); alpha : significance level of the NIS bands, in (0, 1).
    """
    require_instance("log", log, OrbitLog)
    if log.truth is None:
        raise ValueError("log must carry its truth (a simulated log, simulate().log()) to draw the errors")
    alpha = require_probability("alpha", alpha)
    p = log_params(log)
    y = log.y
    runs = {(f, q): run_filter(f, y, p, truth=log.truth, Q=q * p.Qtrue) for f in ORBIT_DEMO_FILTERS for q in Q_SCALES}
    dof = runs[ORBIT_DEMO_FILTERS[0], Q_SCALES[0]].dof.astype(int)
    if not np.any(dof > 0):
        raise ValueError("log must hold at least one station measurement")
    lower, upper = np.full(dof.shape, np.nan), np.full(dof.shape, np.nan)
    has = dof > 0
    lower[has], upper[has] = chi2_sum_bounds(dof[has], np.ones(int(has.sum()), dtype=int), alpha)
    return OrbitDemoRuns(log, runs, dof, lower, upper, float(alpha))


@dataclass(frozen=True, eq=False)
class OrbitDemo:
    """One redraw of the orbit-determination demo (K steps).

    filter : "ekf" or "ukf"; q_scale : the filter's Q = q_scale * Qtrue; t : (K,) s
    errors : (K, 4) truth - estimate (km, km/s); sigma2 : (K, 4) the filter's 2 sqrt(diag P) (km, km/s)
    nis : (K,) NIS (NaN at a step without a station); dof : (K,) its degrees of freedom, 3 per station seen
    nis_lower, nis_upper : (K,) the NIS's chi-square band at each step from its dof (NaN where dof = 0)
    nis_mean : the NIS averaged over the ``n_nis`` steps with a measurement; nis_bounds : its chi-square
        bounds (the sum of the dof present, over ``n_nis``); inside_share : share of those steps whose NIS
        lies in its band (about 1 - alpha for a consistent filter)
    step : the index of the time shown; track : (K, 2) the true orbit X, Y (km); satellite : (2,) its true
        X, Y at ``t[step]``; stations : (n_stations, 2) the stations' X, Y at ``t[step]`` (km);
        seen : int array, the stations (0-based) whose measurements the filter used at ``t[step]``
    """

    #: the arrays that must be finite before the demo is drawn (:class:`kfcal_helpers.demos.LiveDemo`)
    finite_fields = ("errors", "sigma2", "nis_mean", "satellite", "stations")

    filter: str
    q_scale: float
    t: np.ndarray
    errors: np.ndarray
    sigma2: np.ndarray
    nis: np.ndarray
    dof: np.ndarray
    nis_lower: np.ndarray
    nis_upper: np.ndarray
    nis_mean: float
    n_nis: int
    nis_bounds: tuple[float, float]
    inside_share: float
    alpha: float
    step: int
    track: np.ndarray
    satellite: np.ndarray
    stations: np.ndarray
    seen: np.ndarray

    @property
    def time(self) -> float:
        """The time shown, s."""
        return float(self.t[self.step])

    @property
    def nis_verdict(self) -> str:
        """Where the time-averaged NIS lies against its bounds: "inside", "below" or "above"."""
        lo, hi = self.nis_bounds
        return "inside" if lo <= self.nis_mean <= hi else ("below" if self.nis_mean < lo else "above")

    def seen_text(self) -> str:
        """Which stations (numbered 1..12, as in the course's logs) have a measurement in the log at the time shown:
        the ones the filter used (a station above its horizon may have none, e.g. at the log's first step)."""
        if self.seen.size == 0:
            return "no station measurement at this step"
        ids = ", ".join(str(i + 1) for i in self.seen)
        return f"station{'s' if self.seen.size > 1 else ''} {ids} measured"

    def summary(self) -> str:
        """One line: filter, Q scale, the time-averaged NIS and the share inside the per-step band, the stations
        seen at the time shown."""
        lo, hi = self.nis_bounds
        return (f"{self.filter.upper()}, Q = {self.q_scale:g} Qtrue (precomputed run): time-averaged NIS "
                f"{self.nis_mean:.2f}, {self.nis_verdict} [{lo:.2f}, {hi:.2f}]; per-step band: "
                f"{100 * self.inside_share:.1f} % of {self.n_nis} steps inside; t = {self.time:.0f} s: {self.seen_text()}")


def compute_orbit_demo(runs: OrbitDemoRuns, filter: str = "ekf", q_scale: float = 1.0, t: float | None = None) -> OrbitDemo:
    """One redraw of the demo from the precomputed ``runs``: no filtering, a selection.

    filter : "ekf" or "ukf"; q_scale : a scale of :data:`Q_SCALES` (Q = q_scale Qtrue); t : a time within the log
    (s, from its first to its last sample time), whose pass geometry is drawn at the nearest sample time (the
    earlier of two as near: a value typed into the t slider's readout, which ipywidgets keeps within the slider's
    range but does not round to its step); default ``runs.default_time``.  Returns an :class:`OrbitDemo`.
    """
    require_instance("runs", runs, OrbitDemoRuns)
    t = runs.default_time if t is None else t
    res = runs.result(filter, q_scale)
    times = res.t
    if isinstance(t, bool) or not isinstance(t, (int, float, np.integer, np.floating)) or not np.isfinite(t):
        raise ValueError(f"t must be a time within the log (s), got {t!r}")
    if not times[0] - 1e-6 <= float(t) <= times[-1] + 1e-6:
        raise ValueError(f"t must be a time within the log ({times[0]:g} to {times[-1]:g} s), got {float(t):g}")
    step = int(np.argmin(np.abs(times - float(t))))
    truth = runs.log.truth
    has = runs.dof > 0
    n_nis = int(has.sum())
    nis = res.nis
    bounds = chi2_sum_bounds(int(runs.dof[has].sum()), n_nis, runs.alpha)
    inside = (nis[has] >= runs.nis_lower[has]) & (nis[has] <= runs.nis_upper[has])
    st = station_states(times[step], log_params(runs.log))
    return OrbitDemo(res.filter, _q_key(q_scale), times, res.errors(truth), res.sigma2, nis, runs.dof, runs.nis_lower,
                     runs.nis_upper, float(np.mean(nis[has])), n_nis, (float(bounds[0]), float(bounds[1])),
                     float(inside.mean()), runs.alpha, step, truth[:, [0, 2]], truth[step, [0, 2]], st[:, [0, 2]],
                     np.asarray(res.stations[step], dtype=int))


class OrbitDemoFigure(DemoFigure):
    """The orbit demo's figure, built once; :meth:`update` puts a new :class:`OrbitDemo` into the same artists.

    Left: the true orbit (in 1000 km), the Earth and the 12 stations at the time shown, the stations whose measurements the
    filter used then (green) with their lines of sight to the satellite.  Right: the four estimation errors
    (m, m/s; each panel labelled with its state) with the filter's +-2 sigma bounds, and the NIS of each step (dots; red outside its band) with its
    chi-square band from the dof present at that step; a vertical line marks the time shown.  :meth:`draw`
    renders onto the Agg canvas with the time axes, the orbit panel's axes, the Earth and the legend kept from
    the first render (:class:`kfcal_helpers.demos.CachedBackground`).  ``figure``: a matplotlib Figure to draw
    into (e.g. ``Figure(figsize=LIVE_FIGSIZE)``), else a new pyplot figure.
    """

    #: inches above the panels: the two-line title and the legend's row
    HEADER_IN = 0.78
    #: inches under the panels: tick labels and the time label
    FOOTER_IN = 0.5
    #: height of the gap between the error panels and the NIS panel, for the time tick labels of the lower error
    #: row (a share of a panel's height)
    LABEL_GAP = 0.2

    def __init__(self, figure=None):
        from matplotlib.patches import Circle

        self.fig = fig = new_figure(figure, (11.0, 6.2))
        height = fig.get_figheight()
        right, top = 0.985, 1 - self.HEADER_IN / height
        # rows: two of error panels, a gap for the lower row's time tick labels, the NIS panel
        grid = fig.add_gridspec(4, 3, width_ratios=(1.3, 1, 1), height_ratios=(1, 1, self.LABEL_GAP, 1), left=0.06,
                                right=right, bottom=self.FOOTER_IN / height, top=top, wspace=0.42, hspace=0.16)
        self.orbit = fig.add_subplot(grid[:, 0])
        self.error_axes = [fig.add_subplot(grid[i // 2, 1 + i % 2]) for i in range(4)]
        self.nis_ax = fig.add_subplot(grid[3, 1:], sharex=self.error_axes[0])
        for ax in self.error_axes[1:]:
            ax.sharex(self.error_axes[0])
        self.time_axes = [*self.error_axes, self.nis_ax]
        self.lines = []
        for ax, (label, _, unit) in zip(self.error_axes, ERROR_UNITS):
            self.lines.append(error_lines(ax))
            ax.set_ylabel(f"${label}$ [{unit}]")
        for ax in self.error_axes[:2]:   # the lower row labels the error panels' time axis (half the NIS panel's)
            ax.tick_params(labelbottom=False)
        self.band_lo, = self.nis_ax.plot([], [], color="0.45", lw=0.8, drawstyle="steps-mid", label="NIS band")
        self.band_hi, = self.nis_ax.plot([], [], color="0.45", lw=0.8, drawstyle="steps-mid")
        self.nis_in, = self.nis_ax.plot([], [], ".", color="C0", ms=2.5, label="NIS")
        self.nis_out, = self.nis_ax.plot([], [], ".", color="C3", ms=3.5, label="NIS outside")
        self.nis_ax.set_ylabel("NIS")
        self.nis_ax.set_xlabel("time $t$ [s]")
        self.cursors = [ax.axvline(0.0, color="C2", lw=0.9) for ax in self.time_axes]

        ax = self.orbit
        self.earth = ax.add_patch(Circle((0, 0), 6.378, facecolor="#dde8f0", edgecolor="0.5", lw=0.8, zorder=0.5))
        self.track, = ax.plot([], [], color="0.3", lw=0.7)
        self.sight, = ax.plot([], [], color="C2", lw=1.0)
        self.hidden, = ax.plot([], [], "^", color="0.55", ms=5)
        self.visible, = ax.plot([], [], "^", color="C2", ms=7, label="station measured")
        self.satellite, = ax.plot([], [], "o", color="C3", ms=6, label="satellite")
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlim(-7.6, 7.6)
        ax.set_ylim(-7.6, 7.6)
        ax.set_xticks([-6, -3, 0, 3, 6])
        ax.set_yticks([-6, -3, 0, 3, 6])
        ax.set_xlabel("$X$ [1000 km]")
        ax.set_ylabel("$Y$ [1000 km]", labelpad=1)
        handles = [*self.lines[0][:2], self.nis_in, self.nis_out, self.band_lo, self.visible, self.satellite]
        self.legend = fig.legend(handles=handles, loc="lower right", bbox_to_anchor=(right, top), ncol=len(handles),
                                 fontsize=9, frameon=False, borderaxespad=0.3, borderpad=0.1, columnspacing=1.0,
                                 handlelength=1.5)
        self.title = fig.suptitle("", y=1 - 0.05 / height, va="top", fontsize=10)
        static = [*(a.xaxis for a in self.time_axes), ax.xaxis, ax.yaxis, self.earth, self.legend]
        self.background = CachedBackground(fig, static, key=lambda: tuple(a.get_xlim() for a in self.time_axes))

    def update(self, demo: OrbitDemo):
        """Draw ``demo`` into the figure; returns the Figure."""
        require_instance("demo", demo, OrbitDemo)
        t = demo.t
        skip = min(30, t.size - 1)  # the y scale leaves out the first 5 minutes (the prior's sigma)
        for i, (lines, (_, factor, _)) in enumerate(zip(self.lines, ERROR_UNITS)):
            show_errors(lines, t, factor * demo.errors[:, i], factor * demo.sigma2[:, i], skip)
        has = demo.dof > 0
        inside = has & (demo.nis >= demo.nis_lower) & (demo.nis <= demo.nis_upper)
        outside = has & ~inside
        self.band_lo.set_data(t, demo.nis_lower)
        self.band_hi.set_data(t, demo.nis_upper)
        self.nis_in.set_data(t[inside], demo.nis[inside])
        self.nis_out.set_data(t[outside], demo.nis[outside])
        top = max(np.nanmax(demo.nis_upper), np.quantile(demo.nis[has], 0.99))
        self.nis_ax.set_ylim(0.0, 1.1 * top)
        self.error_axes[0].set_xlim(t[0], t[-1])
        for c in self.cursors:
            c.set_xdata([demo.time, demo.time])

        km = 1e-3  # the orbit panel is in 1000 km
        self.track.set_data(km * demo.track[:, 0], km * demo.track[:, 1])
        seen = np.zeros(demo.stations.shape[0], dtype=bool)
        seen[demo.seen] = True
        stations = km * demo.stations
        self.hidden.set_data(stations[~seen, 0], stations[~seen, 1])
        self.visible.set_data(stations[seen, 0], stations[seen, 1])
        sx, sy = km * demo.satellite
        n = int(seen.sum())
        xs = np.column_stack([stations[seen, 0], np.full(n, sx), np.full(n, np.nan)]).ravel()
        ys = np.column_stack([stations[seen, 1], np.full(n, sy), np.full(n, np.nan)]).ravel()
        self.sight.set_data(xs, ys)
        self.satellite.set_data([sx], [sy])
        lo, hi = demo.nis_bounds
        self.title.set_text(f"{demo.filter.upper()}, Q = {demo.q_scale:g} Qtrue (precomputed); t = {demo.time:.0f} s: "
                            f"{demo.seen_text()}\nerrors with ±2σ; NIS {demo.nis_mean:.2f} on average "
                            f"({demo.nis_verdict} [{lo:.2f}, {hi:.2f}]), {100 * demo.inside_share:.1f} % of "
                            f"{demo.n_nis} steps in their band")
        return self.fig



def draw_orbit_demo(demo: OrbitDemo):
    """A new figure of ``demo`` (see :class:`OrbitDemoFigure`); returns the Figure."""
    return OrbitDemoFigure().update(demo)


def orbit_controls(runs: OrbitDemoRuns) -> dict:
    """The orbit demo's controls (ipywidgets), by name: ``filter`` (EKF/UKF toggle), ``q_scale`` (Q = q_scale
    Qtrue on a log slider whose stops are :data:`Q_SCALES`, default 1) and ``t`` (the time whose pass geometry
    is drawn, s, every sample of the log of ``runs``; default ``runs.default_time``).  They update on release."""
    import ipywidgets as w

    require_instance("runs", runs, OrbitDemoRuns)
    times = runs.log.t
    dt = float(times[1] - times[0]) if times.size > 1 else 1.0
    style = {"description_width": "initial"}
    exps = np.log10(Q_SCALES)
    return {
        "filter": w.ToggleButtons(options=[("EKF", "ekf"), ("UKF", "ukf")], value="ekf", description="filter",
                                  style={"description_width": "40px", "button_width": "70px"},
                                  layout=w.Layout(width="260px")),
        "q_scale": w.FloatLogSlider(value=1.0, base=10, min=float(exps[0]), max=float(exps[-1]), step=1.0,
                                    readout_format=".1r", continuous_update=False, description="Q / Qtrue",
                                    style=style, layout=w.Layout(width="300px")),
        "t": w.FloatSlider(value=runs.default_time, min=float(times[0]), max=float(times[-1]), step=dt,
                           readout_format=".0f", continuous_update=False, description="t [s]", style=style,
                           layout=w.Layout(width="560px")),
    }
