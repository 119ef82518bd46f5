"""The orbit-determination lecture figures: the problem's entries of the figure registry.

:data:`FIGURES` holds one :class:`~kfcal_helpers.registry.LectureFigure` per figure, in lecture order;
``python -m kfcal_helpers figures`` writes them with the other problems' (1280 x 720 px PNG).  Each ``make``
takes an :class:`OrbitCase` (:func:`figure_data`), which computes its results once, lazily and seeded: the
generated observation log (seed :data:`~kfcal_helpers.orbit.simulation.DEFAULT_LOG_SEED`) and an
:data:`ORBIT_RUNS`-run EKF truth-model test.  Figures are drawn at the current rcParams size; the caller
(``save_figures``) sets the slides style and closes them.  matplotlib is imported inside the functions.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from ..registry import LectureFigure
from ..validation import require_int

__all__ = ["ORBIT_RUNS", "FIGURES", "OrbitCase", "figure_data"]

ORBIT_RUNS = 30  #: runs of the EKF truth-model test of the figures


class OrbitCase:
    """The orbit results of the slides, computed on first use.

    log_seed : seed of the generated log; n_runs, seed : of the EKF truth-model test.
    """

    def __init__(self, log_seed: int | None = None, n_runs: int = ORBIT_RUNS, seed: int = 0):
        from .params import OrbitParams
        from .simulation import DEFAULT_LOG_SEED

        self.params = OrbitParams()
        self.log_seed = DEFAULT_LOG_SEED if log_seed is None else require_int("log_seed", log_seed, minimum=0)
        self.n_runs = require_int("n_runs", n_runs, minimum=2)
        self.seed = require_int("seed", seed, minimum=0)

    @cached_property
    def log(self):
        """The generated observation log (OrbitLog with its truth)."""
        from .simulation import simulate

        return simulate(self.params, seed=self.log_seed).log()

    @cached_property
    def mc(self):
        """EKF truth-model test, ``n_runs`` runs."""
        from .montecarlo import truth_model_test

        return truth_model_test(self.params, self.n_runs, self.seed, filter="ekf")


def figure_data() -> OrbitCase:
    """The default, seeded figure data (nothing is computed before a figure needs it)."""
    return OrbitCase()


def _size():
    from ..style import figure_size

    return figure_size()


def _station_colours(n: int):
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("tab20")
    return [cmap(i % 20) for i in range(n)]


def orbit_geometry(data: OrbitCase):
    """The orbit, the Earth and the stations at t = 0 (they turn with the Earth)."""
    import matplotlib.pyplot as plt

    from .model import station_states

    p, log = data.params, data.log
    fig, ax = plt.subplots(figsize=_size(), layout="constrained")
    a = np.linspace(0.0, 2.0 * np.pi, 361)
    ax.fill(p.RE * np.cos(a), p.RE * np.sin(a), color="0.9", zorder=0)
    ax.plot(log.truth[:, 0], log.truth[:, 2], lw=1.5, color="C0", label=f"true orbit, 0-{log.t[-1]:.0f} s")
    st = station_states(0.0, p)
    ax.scatter(st[:, 0], st[:, 2], c=_station_colours(p.n_stations), s=45, zorder=3, edgecolors="k", linewidths=0.5,
               label="stations at t = 0")
    for i, (x, y) in enumerate(st[:, [0, 2]]):
        ax.annotate(str(i + 1), (x, y), xytext=(0.86 * x, 0.86 * y), ha="center", va="center", fontsize="small")
    turn = np.degrees(p.omegaE * log.t[-1])
    ax.plot([], [], " ", label=f"(turning {turn:.0f}° by {log.t[-1]:.0f} s)")
    ax.set_aspect("equal")
    ax.set_xlabel("X (km)")
    ax.set_ylabel("Y (km)")
    fig.suptitle(f"Orbit at {p.r0 - p.RE:.0f} km altitude, {p.n_stations} equatorial stations (inertial frame)")
    fig.legend(loc="outside right center")
    return fig


def orbit_measurements(data: OrbitCase):
    """The generated log's measurements against time, coloured by station."""
    import matplotlib.pyplot as plt

    log, p = data.log, data.params
    y = log.y
    colours = _station_colours(p.n_stations)
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=_size(), layout="constrained")
    labels = (r"$\rho$ (km)", r"$\dot\rho$ (km/s)", r"$\phi$ (rad)")
    for i in range(p.n_stations):
        seen = np.isfinite(y[:, i, 0])
        if not seen.any():
            continue
        for j, ax in enumerate(axes):
            ax.plot(log.t[seen], y[seen, i, j], ".", ms=2, color=colours[i], label=f"{i + 1}" if j == 0 else None)
    for ax, label in zip(axes, labels):
        ax.set_ylabel(label)
    axes[-1].set_xlabel("t (s)")
    axes[0].set_title(f"Generated log (seed {data.log_seed}): measurements by station")
    fig.legend(title="station", loc="outside right center", markerscale=4, fontsize="small", ncols=2)
    return fig


def orbit_nees_nis(data: OrbitCase):
    """The EKF truth-model test: run-averaged NEES and NIS per step against their per-step bands (the NIS
    band from the dof present at each step)."""
    import matplotlib.pyplot as plt

    mc = data.mc
    checks = mc.checks()
    has = (mc.dof > 0).any(axis=0)
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=_size(), layout="constrained")
    for ax, name, t in ((axes[0], "nees", mc.t), (axes[1], "nis", mc.t[has])):
        c = checks[name]
        ax.fill_between(t, c.lower, c.upper, step="mid", color="C1", alpha=0.3, lw=0,
                        label=f"{1 - mc.alpha:.0%} band per step")
        ax.plot(t, c.statistic, lw=0.8, color="C0", label=f"run average ({c.inside_fraction:.1%} inside)")
        ax.set_ylabel(name.upper())
        ax.legend(loc="upper right", fontsize="small")
    axes[1].set_xlabel("t (s)")
    axes[0].set_title(f"EKF truth-model test, N = {mc.n_runs} runs: NIS band from the dof present per step")
    return fig


#: the orbit lecture figures, in lecture order
FIGURES = (
    LectureFigure("orbit_geometry", "orbit: the orbit, the Earth and the 12 stations at t = 0",
                  orbit_geometry),
    LectureFigure("orbit_measurements", "orbit: the generated log's rho, rhodot, phi by station", orbit_measurements),
    LectureFigure("orbit_nees_nis", f"orbit: EKF truth-model test ({ORBIT_RUNS} runs), NEES and NIS with per-step "
                                    "bands", orbit_nees_nis),
)
