"""The cooperative-localization lecture figures: the problem's entries of the figure registry.

:data:`FIGURES` holds one :class:`~kfcal_helpers.registry.LectureFigure` (file stem, one-line
description, ``make(data)``) per figure, in lecture order; ``python -m kfcal_helpers figures``
writes them with the other problems' (1280 x 720 px PNG, optionally SVG).  Each ``make`` takes a
:class:`CoopCase` (what :func:`figure_data` returns), which computes its results once, lazily and
seeded: the simulated observation log (seed :data:`~kfcal_helpers.coop.simulation.DEFAULT_LOG_SEED`),
the three filters on it, and a :data:`COOP_RUNS`-run EKF truth-model test.  The figures are drawn by
:mod:`kfcal_helpers.coop.plots` at the current rcParams size; the caller (``save_figures``) sets the
slides style and closes them.

matplotlib is imported inside the functions: importing this module stays light.
"""

from __future__ import annotations

from functools import cached_property

from ..registry import LectureFigure
from ..validation import require_int

__all__ = ["COOP_RUNS", "FIGURES", "CoopCase", "figure_data"]

COOP_RUNS = 30  #: runs of the cooperative-localization truth-model test (EKF)


class CoopCase:
    """The cooperative-localization results of the slides, computed on first use.

    log_seed : seed of the simulated observation log; n_runs, seed : of the EKF truth-model test.
    """

    def __init__(self, log_seed: int | None = None, n_runs: int = COOP_RUNS, seed: int = 0):
        from .model import CoopParams
        from .simulation import DEFAULT_LOG_SEED

        self.params = CoopParams()
        self.log_seed = DEFAULT_LOG_SEED if log_seed is None else require_int("log_seed", log_seed, minimum=0)
        self.n_runs = require_int("n_runs", n_runs, minimum=1)
        self.seed = require_int("seed", seed, minimum=0)

    @cached_property
    def log(self):
        """The simulated observation log (CoopLog with its truth)."""
        from .simulation import simulate

        return simulate(self.params, seed=self.log_seed).log()

    @cached_property
    def nominal(self):
        """Nominal states (K, 6)."""
        from .model import nominal_trajectory

        return nominal_trajectory(self.params)

    @cached_property
    def results(self) -> dict:
        """``{"lkf"|"ekf"|"ukf": FilterResult}`` on the log, tuned Q, with the log's truth."""
        from .filters import FILTERS, run_filter

        return {name: run_filter(name, self.log.y, self.log.params(), truth=self.log.truth) for name in FILTERS}

    @cached_property
    def mc(self):
        """EKF truth-model test (tuned Q), ``n_runs`` runs."""
        from .montecarlo import truth_model_test

        return truth_model_test(self.params, self.n_runs, self.seed, filter="ekf")


def figure_data() -> CoopCase:
    """The default, seeded figure data (nothing is computed before a figure needs it)."""
    return CoopCase()


# ---------------------------------------------------------------------------
# The figure functions (each returns a Figure; sizes from rcParams, the slide size when saving)
def _size():
    from ..style import figure_size

    return figure_size()


def coop_paths(data: CoopCase):
    """Nominal paths of the two vehicles."""
    from .plots import plot_paths

    return plot_paths({"nominal": data.nominal}, f"Nominal paths over {data.params.duration:g} s (start: dots)",
                      figsize=_size())


def coop_measurements(data: CoopCase):
    """Noise-free measurements along the nominal."""
    from .model import measure
    from .plots import plot_measurements

    return plot_measurements(data.params.t, {r"noise-free $h(\bar{x})$": measure(data.nominal)},
                             "Noise-free measurements along the nominal (bearings wrapped to (−π, π])",
                             figsize=_size(), ncols=3)


def _coop_errors(name: str):
    def make(data: CoopCase):
        from .filters import TUNED_Q_SCALE
        from .plots import plot_errors

        r = data.results[name]
        return plot_errors(r.t, r.errors(data.log.truth), r.sigma2,
                           f"{name.upper()} on the simulated log (seed {data.log_seed}, Q = "
                           f"{TUNED_Q_SCALE[name]:g} Qtrue): errors and ±2σ", figsize=_size(), ncols=3)

    make.__name__ = f"coop_{name}_errors"
    make.__doc__ = f"{name.upper()} errors with their 2-sigma bounds on the simulated log."
    return make


coop_ekf_errors = _coop_errors("ekf")
coop_ukf_errors = _coop_errors("ukf")


def coop_nees_nis(data: CoopCase):
    """The EKF truth-model test: run-averaged NEES and NIS against their bounds."""
    from .plots import plot_consistency

    mc = data.mc
    return plot_consistency(mc, f"{mc.filter.upper()} truth-model test: N = {mc.n_runs} runs, α = {mc.alpha:g}",
                            figsize=_size())


def coop_nis_comparison(data: CoopCase):
    """Time-averaged NIS of the three filters on the simulated log against the one-run bounds."""
    from .filters import log_summary
    from .plots import plot_nis_comparison

    summaries = {name.upper(): log_summary(r) for name, r in data.results.items()}
    first = next(iter(summaries.values()))
    return plot_nis_comparison({n: s["nis_time_average"] for n, s in summaries.items()}, first["nis_bounds"],
                               f"Time-averaged NIS on the simulated log ({first['measurements']} updates, α = 0.05)",
                               figsize=_size())


#: the coop lecture figures, in lecture order
FIGURES = (
    LectureFigure("coop_paths", "coop: nominal paths of the UGV and the UAV in the east-north plane", coop_paths),
    LectureFigure("coop_measurements", "coop: noise-free measurements along the nominal, bearings wrapped",
                  coop_measurements),
    LectureFigure("coop_ekf_errors", "coop: EKF errors with ±2σ on the simulated log", coop_ekf_errors),
    LectureFigure("coop_ukf_errors", "coop: UKF errors with ±2σ on the simulated log", coop_ukf_errors),
    LectureFigure("coop_nees_nis", f"coop: EKF truth-model test ({COOP_RUNS} runs), NEES and NIS against χ² "
                                   "bounds", coop_nees_nis),
    LectureFigure("coop_nis_comparison", "coop: time-averaged NIS of LKF, EKF, UKF on the simulated log against "
                                         "χ² bounds", coop_nis_comparison),
)
