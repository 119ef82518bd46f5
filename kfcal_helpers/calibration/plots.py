"""Figures of the calibration notebooks and lecture slides (``calibrate --figures``,
``python -m kfcal_helpers figures``).

Every function draws on a new figure and returns it; units are on the axes.  Fonts,
line widths and marker sizes follow the current rcParams (see :mod:`kfcal_helpers.style`),
so the same function serves a notebook and a 1280x720 slide.  ``figsize`` (inches) is the
function's notebook default unless given; the slide figures pass the rcParams size.
"""

from __future__ import annotations

import matplotlib as mpl
import matplotlib.pyplot as plt
import numpy as np
from scipy import stats

from ..style import line_width, marker_size
from .filters import FilterResult
from .montecarlo import MonteCarloResult
from .params import CalibrationParams
from .simulation import Simulation, acceleration, analytic_truth, integrate_left

__all__ = ["CHECK_PANELS", "outage_spans", "shade_outages", "plot_estimate_errors", "plot_covariance_sawtooth",
           "plot_checks", "plot_check_panels", "plot_ensemble_sigma", "plot_truth_vs_euler",
           "plot_dead_reckoning", "plot_gps_measurement", "plot_smoothed_bias"]

STATE_LABELS = ("position [m]", "velocity [m/s]", "bias [m/s²]")  #: y labels of the error panels
_STATES = (("position", "m"), ("velocity", "m/s"), ("bias", "m/s²"))

#: the panels of :func:`plot_check_panels`, in the order of the checks (notebook 06)
CHECK_PANELS = ("mean_error", "covariance", "orthogonality", "residual_independence", "residual_variance", "nees",
                "nis")




def outage_spans(params: CalibrationParams, missing) -> list[tuple[float, float]]:
    """Time spans (s) of the runs of consecutive missing fixes: ``[(start, end), ...]``,
    from the first missing fix to the first fix back (the end of the run for the last one).

    missing : bool array (n_gps,) (e.g. ``MonteCarloResult.missing``) or None.
    """
    if missing is None:
        return []
    m = np.asarray(missing, bool)
    if m.shape != (params.n_gps,):
        raise ValueError(f"missing must be a bool array of shape ({params.n_gps},), got {m.shape}")
    edges = np.diff(np.concatenate([[0], m.astype(int), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    period = 1.0 / params.gps_rate
    return [(float(params.t_gps[i]), min(float(params.t_gps[j - 1]) + period, params.duration))
            for i, j in zip(starts, ends)]


def shade_outages(axes, spans, label: str | None = "GPS outage") -> None:
    """Shade the time spans (s) on every axes of ``axes`` (one label on the first)."""
    for n, ax in enumerate(np.ravel(axes)):
        for k, (start, end) in enumerate(spans):
            ax.axvspan(start, end, color="C1", alpha=0.2, lw=0,
                       label=label if (n == 0 and k == 0 and label) else None)


def _sigma(P: np.ndarray) -> np.ndarray:
    """Standard deviations ``sqrt(diag P)``, (..., 3, 3) -> (..., 3)."""
    return np.sqrt(np.einsum("...aa->...a", P))


def plot_estimate_errors(params: CalibrationParams, true_dx: np.ndarray, result: FilterResult,
                         title: str = "One realization: estimation errors with ±1σ and ±2σ from P",
                         outages=(), figsize=None):
    """Errors ``dx - dx_hat`` of one realization at 200 Hz with the filter's ±1σ, ±2σ.

    true_dx : (n_imu, 3) true error state; result : a single-run FilterResult;
    outages : time spans (s) to shade (see :func:`outage_spans`); figsize : inches (default 9 x 7.5).
    The y range is ±5σ at t = T/6, widened to show ±3σ wherever P grows later (outages).
    """
    t = params.t_imu
    err = true_dx - result.x
    sig = _sigma(result.P)
    fig, axes = plt.subplots(3, 1, figsize=figsize or (9, 7.5), sharex=True)
    late = len(t) // 6
    for k, ax in enumerate(axes):
        _ = ax.fill_between(t, -2 * sig[:, k], 2 * sig[:, k], color="C0", alpha=0.15, label="±2σ")
        _ = ax.fill_between(t, -sig[:, k], sig[:, k], color="C0", alpha=0.3, label="±1σ")
        _ = ax.plot(t, err[:, k], color="C3", lw=line_width(0.6), label="error")
        ax.set_ylabel(STATE_LABELS[k])
        lim = max(5 * sig[late, k], 3 * sig[late:, k].max())
        ax.set_ylim(-lim, lim)
    shade_outages(axes, outages)
    axes[0].legend(loc="upper right", ncol=4 if len(outages) else 3)
    axes[-1].set_xlabel("time t [s]")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_covariance_sawtooth(params: CalibrationParams, result: FilterResult, t_max: float = 2.0,
                             outages=(), figsize=None):
    """σ of position and velocity at 200 Hz over the first ``t_max`` seconds:
    growth during the 40 predict-only steps between fixes (39 samples strictly between), drop at each update.

    outages : time spans (s) to shade; figsize : inches (default 10 x 3.6).
    """
    t = params.t_imu
    sel = t <= t_max
    sig = _sigma(result.P)
    fig, axes = plt.subplots(1, 2, figsize=figsize or (10, 3.6))
    at_fix = params.t_gps <= t_max
    for ax, k, unit in ((axes[0], 0, "m"), (axes[1], 1, "m/s")):
        _ = ax.plot(t[sel], sig[sel, k], lw=line_width(0.7), label="σ at every IMU sample")
        _ = ax.plot(params.t_gps[at_fix], sig[params.fix_indices][at_fix, k],
                    "o", ms=marker_size(0.5), label="a posteriori at fixes")
        ax.set_yscale("log")
        ax.set_xlabel("time t [s]")
        ax.set_ylabel(f"σ [{unit}]")
        ax.set_title(("position", "velocity")[k] + " σ from P (200 Hz)")
    shade_outages(axes, [(a, min(b, t_max)) for a, b in outages if a < t_max])
    for ax in axes:
        ax.legend()
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------------------
# Monte Carlo checks, one panel each
def _bands_lines(ax, point, simul, lw=0.7, symmetric=True):
    """Pointwise (dashed) and simultaneous (solid) band lines at the given levels (arrays over time
    or scalars); the simultaneous band is the one the verdict uses."""
    for level, style, label in ((point, "--", "pointwise 95 % band"), (simul, "-", "simultaneous band (verdict)")):
        for sign in ((1, -1) if symmetric else (1,)):
            lines = ax.plot(*level(sign), color="k", ls=style, lw=line_width(lw))
            if sign == 1:
                lines[0].set_label(label)


_TOP_LEGEND_NCOL = "_kfcal_top_legend_ncol"  # attribute of an axes: the ncol its legend on top asks for
_TOP_LEGEND_DATA = "_kfcal_top_legend_data"  # and its y limits before the room for the legend


def _legend_on_top(ax, ncol=2):
    """Room above the curves and bands for the legend, so it covers neither.  A first guess (45 %
    more height); :func:`_fit_legends_on_top` fits the columns and the room once the figure is laid out."""
    lo, hi = ax.get_ylim()
    setattr(ax, _TOP_LEGEND_NCOL, ncol)
    setattr(ax, _TOP_LEGEND_DATA, (lo, hi))
    ax.set_ylim(lo, hi + 0.45 * (hi - lo))
    legend = ax.legend(ncol=ncol, fontsize="small", loc="upper center")
    legend.set_in_layout(False)  # the layout makes room for the axes' texts; the legend sits inside


def _fit_legends_on_top(fig, renderer) -> None:
    """Each legend of :func:`_legend_on_top` in as many of its columns as fit the axes' width (one at
    least), and the axes' top raised just enough that the legend sits above the data."""
    for ax in fig.axes:
        ncol = getattr(ax, _TOP_LEGEND_NCOL, None)
        if ncol is None:
            continue
        lo, hi = getattr(ax, _TOP_LEGEND_DATA)
        width = ax.get_window_extent(renderer).width
        for n in range(ncol, 0, -1):
            legend = ax.legend(ncol=n, fontsize="small", loc="upper center")
            legend.set_in_layout(False)
            box = legend.get_window_extent(renderer)
            if box.width <= width:
                break
        # the legend's height and its padding to the axes' top, as a share of the axes' height
        share = (ax.get_window_extent(renderer).y1 - box.y0) / ax.get_window_extent(renderer).height
        ax.set_ylim(lo, lo + (hi - lo) / max(1.0 - share - 0.04, 0.3))


def _layout(fig) -> None:
    """``tight_layout``, with the legends on top fitted to the panels it gives (twice: fitting can
    change the tick labels, and with them the layout)."""
    fig.tight_layout()
    get_renderer = getattr(fig.canvas, "get_renderer", None)
    if get_renderer is None:  # a canvas that cannot measure text: keep the first guess
        return
    for _ in range(2):
        _fit_legends_on_top(fig, get_renderer())
        fig.tight_layout()


def _normalized_band(ax, t, ratio, sim, title, ylabel, labels=None, lw=0.6):
    """Statistics divided by their pointwise band half-width, with the pointwise (±1) and the
    simultaneous (±sim) lines."""
    lines = ax.plot(t, ratio, lw=line_width(lw))
    if labels:
        for line, name in zip(lines, labels):
            line.set_label(name)
    _bands_lines(ax, lambda s: (t, s * np.ones_like(t)), lambda s: (t, s * sim * np.ones_like(t)))
    ax.set_title(title)
    ax.set_ylabel(ylabel)
    ax.set_xlabel("time t [s]")


def _panel_mean_error(fig, ax, mc, checks):
    c = checks["mean_error"]
    n = len(mc.t_gps)
    hi = c.upper.reshape(n, 3)
    sim = float(np.nanmax(c.sim_upper.reshape(n, 3) / hi))  # the same ratio at every entry (t quantiles)
    _normalized_band(ax, mc.t_gps, c.statistic.reshape(n, 3) / hi, sim,
                     "1. mean error / pointwise half-width", "normalized [-]", ("δp", "δv", "b"))
    _legend_on_top(ax, ncol=3)


def _panel_covariance(fig, ax, mc, checks):
    c = checks["covariance"]
    n = len(mc.t_gps)
    st, lo, hi, ex, slo, shi = (a.reshape(n, 6) for a in (c.statistic, c.lower, c.upper, c.expected,
                                                           c.sim_lower, c.sim_upper))
    for k, name in ((0, "p"), (3, "v"), (5, "b")):
        _ = ax.plot(mc.t_gps, st[:, k] / ex[:, k], lw=line_width(0.6), label=f"var {name}")
    t = mc.t_gps
    _bands_lines(ax, lambda s: (t, (hi if s > 0 else lo)[:, 0] / ex[:, 0]),
                 lambda s: (t, (shi if s > 0 else slo)[:, 0] / ex[:, 0]))
    ax.set_title("2. ensemble variance / P")
    ax.set_ylabel("ratio [-]")
    ax.set_xlabel("time t [s]")
    _legend_on_top(ax, ncol=3)


def _panel_orthogonality(fig, ax, mc, checks):
    c = checks["orthogonality"]
    n = len(mc.t_gps)
    st, hi, shi = c.statistic.reshape(n, 9), c.upper.reshape(n, 9), c.sim_upper.reshape(n, 9)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(hi > 0, np.abs(st) / hi, 0.0)
        sim = float(np.nanmax(np.where(hi > 0, shi / hi, np.nan)))
    t = mc.t_gps
    # the largest of 9 entries: each entry at 1 - (1 - alpha)^(1/9) keeps it inside with probability
    # at least 1 - alpha (Sidak, for jointly Gaussian entries)
    a9 = 1 - (1 - mc.alpha) ** (1 / 9)
    max9 = stats.norm.ppf(1 - a9 / 2) / stats.norm.ppf(1 - mc.alpha / 2)
    _ = ax.plot(t, ratio.max(axis=1), lw=line_width(0.6), color="C0", label="largest of the 9 entries (k, m)")
    _ = ax.plot(t, max9 * np.ones_like(t), color="k", ls="--", lw=line_width(0.7), label="95 % band of the largest of 9")
    _ = ax.plot(t, sim * np.ones_like(t), color="k", ls="-", lw=line_width(0.7), label="simultaneous band (verdict)")
    ax.set_ylim(bottom=0)
    ax.set_title("3. |(1/N) Σ (e_k − ē_k) x̂_m|\n/ 1-entry half-width")
    ax.set_ylabel("normalized [-]")
    ax.set_xlabel("time t [s]")
    _legend_on_top(ax, ncol=2)


def _panel_residual_independence(fig, ax, mc, checks):
    """One pixel per pair of fixes (i, m): the largest of the four component pairs (pp, pv, vp, vv) of
    the check's |rho|, over the simultaneous half-width; the diagonal (i = m, not judged) is blank."""
    t = mc.t_gps
    c = checks["residual_independence"]
    half = float(c.sim_upper[0])  # the same simultaneous half-width for every pair
    fixes = np.flatnonzero(~mc.missing)
    i, m = np.triu_indices(len(fixes), k=1)  # the order of the check's pairs
    worst = np.abs(c.statistic).reshape(len(i), 4).max(axis=1) / half
    image = np.full((len(t), len(t)), np.nan)
    image[fixes[i], fixes[m]] = worst
    image[fixes[m], fixes[i]] = worst
    cmap = mpl.colormaps["viridis"].with_extremes(over="red", bad="white")
    im = ax.imshow(image, vmin=0, vmax=1, cmap=cmap, extent=(0, t[-1], t[-1], 0))
    ax.set_aspect("auto")  # the map fills its panel, so the colour bar stays within the panel's height
    cbar = fig.colorbar(im, ax=ax, extend="max", shrink=0.85)
    cbar.set_label("max |ρ| / simult. band (red: outside)", fontsize="small")
    ax.set_title("4a. residual correlation, fix pairs\n(largest of pp, pv, vp, vv)")
    ax.set_xlabel("fix time [s]")
    ax.set_ylabel("fix time [s]")
    ax.grid(False)


def _panel_residual_variance(fig, ax, mc, checks):
    c = checks["residual_variance"]
    t = mc.t_gps[~mc.missing]
    st, ex, lo, hi, slo, shi = (a.reshape(len(t), 2) for a in (c.statistic, c.expected, c.lower, c.upper,
                                                               c.sim_lower, c.sim_upper))
    for k, name in ((0, "p"), (1, "v")):
        _ = ax.plot(t, st[:, k] / ex[:, k], lw=line_width(0.6), label=f"residual {name}")
    _bands_lines(ax, lambda s: (t, (hi if s > 0 else lo)[:, 0] / ex[:, 0]),
                 lambda s: (t, (shi if s > 0 else slo)[:, 0] / ex[:, 0]))
    ax.set_title("4b. (1/N) Σ r² / S (residual variance)")
    ax.set_ylabel("ratio [-]")
    ax.set_xlabel("time t [s]")
    _legend_on_top(ax, ncol=2)


def _panel_chi2(ax, mc, checks, name):
    c = checks[name]
    dim = 3 if name == "nees" else 2
    stat = np.full(len(mc.t_gps), np.nan)  # NIS: a gap (no line) at missing fixes
    stat[slice(None) if name == "nees" else ~mc.missing] = c.statistic
    t = mc.t_gps
    _ = ax.plot(t, stat, lw=line_width(0.6), label=f"run-averaged {name.upper()}")
    _bands_lines(ax, lambda s: (t, np.full_like(t, c.upper[0] if s > 0 else c.lower[0])),
                 lambda s: (t, np.full_like(t, c.sim_upper[0] if s > 0 else c.sim_lower[0])))
    ax.set_title(f"{'5. NEES' if name == 'nees' else '6. NIS'} (expected {dim})")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(f"mean {name.upper()} [-]")
    _legend_on_top(ax, ncol=2)


_PANELS = {
    "mean_error": _panel_mean_error,
    "covariance": _panel_covariance,
    "orthogonality": _panel_orthogonality,
    "residual_independence": _panel_residual_independence,
    "residual_variance": _panel_residual_variance,
    "nees": lambda fig, ax, mc, checks: _panel_chi2(ax, mc, checks, "nees"),
    "nis": lambda fig, ax, mc, checks: _panel_chi2(ax, mc, checks, "nis"),
}


def plot_check_panels(mc: MonteCarloResult, panels=CHECK_PANELS, ncols: int = 2, figsize=None,
                      title: str | None = None):
    """Some of the Monte Carlo checks at the fixes, each against its pointwise band (dashed) and
    the simultaneous band of the verdict (solid; panel 4a: colour scale up to it, red beyond).

    panels : names from :data:`CHECK_PANELS`; ncols : panels per row;
    figsize : inches (default 5.5 per column x 3 per row); title : default names N.
    Outages (``mc.missing``) are shaded on the time axes.
    """
    panels = tuple(panels)
    bad = [p for p in panels if p not in _PANELS]
    if not panels or bad:
        raise ValueError(f"panels must be a non-empty sequence of {', '.join(CHECK_PANELS)}, got {panels!r}")
    ncols = min(ncols, len(panels))
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=figsize or (5.5 * ncols, 3 * nrows), squeeze=False)
    checks = mc.checks()
    spans = outage_spans(mc.params, mc.missing)
    for ax, name in zip(axes.flat, panels):
        _PANELS[name](fig, ax, mc, checks)
        if name != "residual_independence":
            shade_outages([ax], spans, label=None)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    fig.suptitle(title or f"Monte Carlo checks, N = {mc.n_runs} realizations")
    _layout(fig)
    return fig


def plot_checks(mc: MonteCarloResult, figsize=None):
    """The seven Monte Carlo checks at the fixes, each against its pointwise and simultaneous bands
    (default 11 x 12 in)."""
    return plot_check_panels(mc, CHECK_PANELS, ncols=2, figsize=figsize or (11, 12))


def plot_ensemble_sigma(mc: MonteCarloResult, figsize=None, title: str | None = None):
    """Filter σ (a priori and a posteriori, from P) against the ensemble std of the errors at the
    fixes, one panel per state (default 12 x 3.6 in); outages shaded."""
    fig, axes = plt.subplots(1, 3, figsize=figsize or (12, 3.6))
    for k, (ax, (name, unit)) in enumerate(zip(axes, _STATES)):
        for P, ens, color, when in ((mc.P_prior, mc.e_prior_cov, "C0", "a priori"),
                                    (mc.P_post, mc.e_cov, "C3", "a posteriori")):
            _ = ax.plot(mc.t_gps, np.sqrt(P[:, k, k]), color=color, lw=line_width(0.8), label=f"filter σ, {when}")
            _ = ax.plot(mc.t_gps, np.sqrt(ens[:, k, k]), ".", color=color, ms=marker_size(0.8),
                        label=f"ensemble std, {when}")
        ax.set_yscale("log")
        ax.set_xlabel("time t [s]")
        ax.set_ylabel(f"σ [{unit}]")
        ax.set_title(name)
    shade_outages(axes, outage_spans(mc.params, mc.missing), label=None)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="lower center", ncol=4)
    fig.suptitle(title or f"Ensemble std of the errors vs the filter's σ, N = {mc.n_runs} realizations")
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    return fig


# ---------------------------------------------------------------------------
# Models: truth, IMU, GPS (notebooks 1-3)
def plot_truth_vs_euler(params: CalibrationParams, p0: float | None = None, v0: float | None = None,
                        figsize=None):
    """Analytic truth against the Euler-integrated truth the error model assumes.

    p0, v0 : initial position (m) and velocity (m/s), default the prior means.  Panels: position,
    ``v - v_E`` with ``(dt/2)(a(t) - a(0))``, ``p - p_E``.  figsize : inches (default 9 x 7.5).
    """
    p0 = params.p0_mean if p0 is None else float(p0)
    v0 = params.v0_mean if v0 is None else float(v0)
    t = params.t_imu
    a = acceleration(t, params)
    p, v = analytic_truth(t, p0, v0, params)
    p_e, v_e = integrate_left(a, p0, v0, params.dt)
    fig, axes = plt.subplots(3, 1, figsize=figsize or (9, 7.5), sharex=True)
    _ = axes[0].plot(t, p, label="analytic $p(t)$")
    _ = axes[0].plot(t, p_e, "--", label="Euler $p_E(t)$")
    axes[0].set_ylabel("position [m]")
    _ = axes[1].plot(t, v - v_e, label="$v - v_E$")
    _ = axes[1].plot(t, params.dt / 2 * (a - a[0]), "k:", label=r"$(\Delta t/2)(a(t) - a(0))$")
    axes[1].set_ylabel("$v - v_E$ [m/s]")
    _ = axes[2].plot(t, p - p_e, label="$p - p_E$")
    axes[2].set_ylabel("$p - p_E$ [m]")
    axes[2].set_xlabel("time t [s]")
    for ax in axes:
        ax.legend(loc="upper left")
    fig.suptitle(f"Analytic vs Euler truth, a(t) = {params.A:g} sin({params.omega:g} t) m/s², "
                 f"Δt = {params.dt:g} s")
    fig.tight_layout()
    return fig


def plot_dead_reckoning(sim: Simulation, run: int = 0, figsize=None):
    """IMU dead-reckoning drift ``dv = v - v_c``, ``dp = p - p_c`` of realization ``run`` with the
    bias-only prediction ``dv0 - b t``, ``dp0 + dv0 t - b t^2/2`` (default 9 x 6 in)."""
    t = sim.t
    dx = sim.dx[run]
    b = sim.b[run]
    fig, axes = plt.subplots(2, 1, figsize=figsize or (9, 6), sharex=True)
    _ = axes[0].plot(t, dx[:, 1], label=r"$\delta v = v - v_c$")
    _ = axes[0].plot(t, dx[0, 1] - b * t, "k--", label=r"$\delta v_0 - b\,t$")
    axes[0].set_ylabel("velocity drift [m/s]")
    _ = axes[1].plot(t, dx[:, 0], label=r"$\delta p = p - p_c$")
    _ = axes[1].plot(t, dx[0, 0] + dx[0, 1] * t - b * t**2 / 2, "k--",
                     label=r"$\delta p_0 + \delta v_0 t - b t^2/2$")
    axes[1].set_ylabel("position drift [m]")
    axes[1].set_xlabel("time t [s]")
    for ax in axes:
        ax.legend(loc="lower left")
    fig.suptitle(f"IMU dead reckoning drifts: one realization, bias b = {b:.3f} m/s²")
    fig.tight_layout()
    return fig


def plot_gps_measurement(sim: Simulation, run: int = 0, figsize=None):
    """The filter's measurement ``dz = GPS - IMU`` at the fixes against the true error state
    ``dx`` at 200 Hz, realization ``run`` (default 9 x 6 in); missing fixes are not drawn."""
    params = sim.params
    dz = sim.dz[run]
    dx = sim.dx[run]
    fig, axes = plt.subplots(2, 1, figsize=figsize or (9, 6), sharex=True)
    for k, (ax, (name, unit)) in enumerate(zip(axes, _STATES[:2])):
        _ = ax.plot(params.t_gps, dz[:, k], ".", ms=marker_size(0.7), color="C1", label=r"$\delta z$ = GPS − IMU")
        _ = ax.plot(sim.t, dx[:, k], "k", lw=line_width(0.7), label=[r"$\delta p = p - p_c$", r"$\delta v = v - v_c$"][k])
        ax.set_ylabel(f"{name} [{unit}]")
        ax.legend(loc="lower left")
    axes[1].set_xlabel("time t [s]")
    fig.suptitle(rf"The filter's measurement $\delta z = H\,\delta x + \eta$ at {params.gps_rate:g} Hz "
                 "(one realization)")
    fig.tight_layout()
    return fig


def plot_smoothed_bias(params: CalibrationParams, true_bias: float, result: FilterResult, xs: np.ndarray,
                       Ps: np.ndarray, figsize=None):
    """Bias error and σ_b at the fixes: filtered (online) against RTS-smoothed (offline).

    true_bias : m/s^2; result : the single-run FilterResult; xs (n_gps, 3), Ps (n_gps, 3, 3) :
    the smoothed estimates and covariances at the fixes (:func:`~.batch_estimate.rts_smooth_fixes`).
    figsize : inches (default 9 x 7).
    """
    t = params.t_gps
    sf, ss = _sigma(result.P_post)[:, 2], _sigma(Ps)[:, 2]
    fig, axes = plt.subplots(2, 1, figsize=figsize or (9, 7), sharex=True)
    ax = axes[0]
    _ = ax.plot(t, true_bias - result.x_post[:, 2], color="C0", label="filtered error")
    _ = ax.plot(t, true_bias - xs[:, 2], color="C3", label="smoothed error")
    for s, color, name in ((sf, "C0", "filtered"), (ss, "C3", "smoothed")):
        style = ":" if name == "filtered" else "--"
        _ = ax.plot(t, 2 * s, style, color=color, label=rf"{name} $\pm 2\sigma_b$")
        _ = ax.plot(t, -2 * s, style, color=color)
    lim = 4 * sf[len(t) // 10]
    ax.set_ylim(-lim, lim)
    ax.set_ylabel("bias error [m/s²]")
    ax.legend(ncol=2, loc="upper right")
    ax = axes[1]
    _ = ax.semilogy(t, sf, color="C0", label=r"filtered $\sigma_b$")
    _ = ax.semilogy(t, ss, color="C3", label=r"smoothed $\sigma_b$")
    ax.set_ylabel(r"$\sigma_b$ [m/s²]")
    ax.set_xlabel("time t [s]")
    ax.legend(loc="upper right")
    fig.suptitle("Bias calibration: filtered (online) vs RTS-smoothed (offline), one realization")
    fig.tight_layout()
    return fig
