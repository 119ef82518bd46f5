"""Figures of the calibration notebooks (also written by ``calibrate --figures``).

Every function draws on a new figure and returns it; units are on the axes.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from .filters import FilterResult
from .montecarlo import MonteCarloResult
from .params import CalibrationParams

__all__ = ["plot_estimate_errors", "plot_covariance_sawtooth", "plot_checks"]

STATE_LABELS = (r"$\delta p$ error [m]", r"$\delta v$ error [m/s]", r"bias error [m/s$^2$]")


def plot_estimate_errors(params: CalibrationParams, true_dx: np.ndarray, result: FilterResult,
                         title: str = "One realization: estimation errors with ±1σ and ±2σ from P"):
    """Errors ``dx - dx_hat`` of one realization at 200 Hz with the filter's ±1σ, ±2σ.

    true_dx : (n_imu, 3) true error state; result : a single-run FilterResult.
    """
    t = params.t_imu
    err = true_dx - result.x
    sig = np.sqrt(np.einsum("jaa->ja", result.P))
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    for k, ax in enumerate(axes):
        _ = ax.fill_between(t, -2 * sig[:, k], 2 * sig[:, k], color="C0", alpha=0.15, label="±2σ")
        _ = ax.fill_between(t, -sig[:, k], sig[:, k], color="C0", alpha=0.3, label="±1σ")
        _ = ax.plot(t, err[:, k], color="C3", lw=0.8, label="error")
        ax.set_ylabel(STATE_LABELS[k])
        ax.set_ylim(-5 * sig[len(t) // 6, k], 5 * sig[len(t) // 6, k])
    axes[0].legend(loc="upper right", ncol=3)
    axes[-1].set_xlabel("time t [s]")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_covariance_sawtooth(params: CalibrationParams, result: FilterResult, t_max: float = 2.0):
    """σ of position and velocity at 200 Hz over the first ``t_max`` seconds:
    growth during the 39 predict-only steps, drop at each update."""
    t = params.t_imu
    sel = t <= t_max
    sig = np.sqrt(np.einsum("jaa->ja", result.P))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for ax, k, unit in ((axes[0], 0, "m"), (axes[1], 1, "m/s")):
        _ = ax.plot(t[sel], sig[sel, k], lw=1)
        _ = ax.plot(params.t_gps[params.t_gps <= t_max], sig[params.fix_indices][params.t_gps <= t_max, k],
                    "o", ms=3, label="a posteriori at fixes")
        ax.set_yscale("log")
        ax.set_xlabel("time t [s]")
        ax.set_ylabel(f"σ [{unit}]")
        ax.set_title(("position", "velocity")[k] + " σ from P (200 Hz)")
        ax.legend()
    fig.tight_layout()
    return fig


def plot_checks(mc: MonteCarloResult):
    """The Monte Carlo checks at the fixes, each against its pointwise band."""
    checks = mc.checks()
    t = mc.t_gps
    n = len(t)
    fig, axes = plt.subplots(3, 2, figsize=(11, 9))
    ax = axes[0, 0]
    c = checks["mean_error"]
    s, hi = c.statistic.reshape(n, 3), c.upper.reshape(n, 3)
    for k, name in enumerate(("δp", "δv", "b")):
        _ = ax.plot(t, s[:, k] / hi[:, k], lw=0.8, label=name)
    _ = ax.axhline(1, color="k", ls="--", lw=0.8)
    _ = ax.axhline(-1, color="k", ls="--", lw=0.8)
    ax.set_title("1. mean error / its band half-width")
    ax.set_ylabel("normalized [-]")
    ax.legend(ncol=3)

    ax = axes[0, 1]
    c = checks["covariance"]
    st, lo, hi = (a.reshape(n, 6) for a in (c.statistic, c.lower, c.upper))
    for k, col, name in ((0, 0, "p"), (3, 1, "v"), (5, 2, "b")):
        _ = ax.plot(t, st[:, k] / c.expected.reshape(n, 6)[:, k], lw=0.8, label=f"var {name}")
    _ = ax.plot(t, lo[:, 0] / c.expected.reshape(n, 6)[:, 0], "k--", lw=0.8, label="χ² band")
    _ = ax.plot(t, hi[:, 0] / c.expected.reshape(n, 6)[:, 0], "k--", lw=0.8)
    ax.set_title("2. ensemble variance / P")
    ax.set_ylabel("ratio [-]")
    ax.legend(ncol=2)

    ax = axes[1, 0]
    c = checks["orthogonality"]
    st, hi = c.statistic.reshape(n, 9), c.upper.reshape(n, 9)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(hi > 0, st / hi, 0.0)
    _ = ax.plot(t, ratio, lw=0.5)
    _ = ax.axhline(1, color="k", ls="--", lw=0.8)
    _ = ax.axhline(-1, color="k", ls="--", lw=0.8)
    ax.set_title("3. orthogonality E[e x̂ᵀ] / band (9 entries)")
    ax.set_ylabel("normalized [-]")

    ax = axes[1, 1]
    rho = mc.residual_correlation()
    im = ax.imshow(np.abs(rho - np.diag(np.diag(rho))) * np.sqrt(mc.n_runs), vmin=0, vmax=3,
                   cmap="viridis", extent=(0, t[-1], t[-1], 0))
    fig.colorbar(im, ax=ax, label="|correlation| · √N")
    ax.set_title("4. residual correlation between fixes")
    ax.set_xlabel("fix time [s]")
    ax.set_ylabel("fix time [s]")

    for ax, name, dim in ((axes[2, 0], "nees", 3), (axes[2, 1], "nis", 2)):
        c = checks[name]
        tt = t if name == "nees" else t[~mc.missing]
        _ = ax.plot(tt, c.statistic, lw=0.8, label=f"run-averaged {name.upper()}")
        _ = ax.plot(tt, c.lower, "k--", lw=0.8, label=f"χ² bounds, α = {mc.alpha:g}")
        _ = ax.plot(tt, c.upper, "k--", lw=0.8)
        ax.set_title(f"{'5. NEES' if name == 'nees' else '6. NIS'} (expected {dim})")
        ax.set_xlabel("time t [s]")
        ax.legend()
    fig.suptitle(f"Monte Carlo checks, N = {mc.n_runs} realizations")
    fig.tight_layout()
    return fig
