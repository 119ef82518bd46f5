"""Matplotlib figures of the cooperative-localization notebooks.

Every function returns the ``Figure``; axes carry units, figures a title.
Time axes are in seconds.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from .model import MEAS_LABELS, STATE_LABELS

__all__ = ["plot_series", "plot_states", "plot_errors", "plot_measurements", "plot_consistency"]


def plot_series(t, series: dict, labels, title: str, styles: dict | None = None, ncols: int = 2):
    """One panel per component: ``series`` maps a legend name to an array (K, n).

    ``labels`` are the n y-axis labels (with units); ``styles`` maps a legend name to
    keyword arguments of ``Axes.plot``.
    """
    n = len(labels)
    nrows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(11, 2.3 * nrows), sharex=True, squeeze=False)
    styles = styles or {}
    for i, ax in enumerate(axes.flat):
        if i >= n:
            ax.set_visible(False)
            continue
        for name, arr in series.items():
            ax.plot(t, np.asarray(arr)[:, i], label=name, **styles.get(name, {"lw": 1}))
        ax.set_ylabel(labels[i])
        ax.grid(True, alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time $t$ [s]")
    axes.flat[0].legend(loc="best", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_states(t, x, sigma2=None, truth=None, title: str = "States"):
    """States (K, 6) with an optional +-2 sigma band (K, 6) and the truth (K, 6)."""
    series = {"estimate": x}
    styles = {"estimate": {"lw": 1, "color": "C0"}, "truth": {"lw": 1, "color": "k", "ls": "--"}}
    if truth is not None:
        series["truth"] = truth
    fig = plot_series(t, series, STATE_LABELS, title, styles)
    if sigma2 is not None:
        for i, ax in enumerate(fig.axes[:6]):
            ax.fill_between(t, x[:, i] - sigma2[:, i], x[:, i] + sigma2[:, i], color="C0", alpha=0.2,
                            label=r"$\pm 2\sigma$")
        fig.axes[0].legend(loc="best", fontsize=8)
    return fig


def plot_errors(t, errors, sigma2, title: str = r"Estimation errors with $\pm 2\sigma$ bounds"):
    """Errors (K, 6) (headings wrapped) against +-2 sigma (K, 6)."""
    styles = {"error": {"lw": 1, "color": "C3"}, r"$+2\sigma$": {"lw": 1, "color": "k", "ls": "--"},
              r"$-2\sigma$": {"lw": 1, "color": "k", "ls": "--"}}
    labels = [f"error {lab}" for lab in STATE_LABELS]
    return plot_series(t, {"error": errors, r"$+2\sigma$": sigma2, r"$-2\sigma$": -np.asarray(sigma2)},
                       labels, title, styles)


def plot_measurements(t, series: dict, title: str = "Measurements"):
    """Measurements: ``series`` maps a legend name to an array (K, 5) (NaN rows are gaps)."""
    styles = {name: ({"lw": 0, "marker": ".", "ms": 2} if i == 0 else {"lw": 1}) for i, name in enumerate(series)}
    return plot_series(t, series, MEAS_LABELS, title, styles)


def plot_consistency(mc, title: str | None = None):
    """Run-averaged NEES and NIS of a :class:`~kfcal_helpers.coop.montecarlo.MonteCarloResult`
    against their chi-square bounds."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.2))
    for ax, mean, bounds, name in ((axes[0], mc.nees_mean, mc.nees_bounds, "NEES"),
                                   (axes[1], mc.nis_mean, mc.nis_bounds, "NIS")):
        ok = np.isfinite(mean)
        ax.plot(mc.t[ok], mean[ok], ".", ms=2, label=f"{name}, mean of {mc.runs} runs")
        for b in bounds:
            ax.axhline(b, color="k", ls="--", lw=1)
        ax.set_xlabel("time $t$ [s]")
        ax.set_ylabel(f"mean {name} [-]")
        frac = mc.nees_inside_fraction if name == "NEES" else mc.nis_inside_fraction
        ax.set_title(f"{name}: {100 * frac:.1f}% of steps inside [{bounds[0]:.2f}, {bounds[1]:.2f}]", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    fig.suptitle(title or f"{mc.filter.upper()} truth-model test, alpha = {mc.alpha:g}")
    fig.tight_layout()
    return fig
