"""The calibration lecture figures: the problem's entries of the figure registry.

:data:`FIGURES` holds one :class:`~kfcal_helpers.registry.LectureFigure` (file stem, one-line
description, ``make(data)``) per figure, in lecture order; ``python -m kfcal_helpers figures``
writes them with the other problems' (1280 x 720 px PNG, optionally SVG).  Each ``make`` takes a
:class:`CalibrationFigureData` (what :func:`figure_data` returns), which computes its results once,
lazily and seeded: one realization filtered by filterpy and a :data:`CALIBRATION_RUNS`-realization
batch Monte Carlo of the default scenario (:class:`CalibrationCase`), and the same realization with
the GPS outages :data:`OUTAGE_WINDOWS` (notebook 15).  The figures are drawn by
:mod:`kfcal_helpers.calibration.plots` at the current rcParams size; the caller (``save_figures``)
sets the slides style and closes them.

matplotlib is imported inside the functions: importing this module stays light.
"""

from __future__ import annotations

from functools import cached_property

from ..registry import LectureFigure
from ..validation import require_choice, require_instance, require_int, require_mask

__all__ = ["CALIBRATION_RUNS", "OUTAGE_WINDOWS", "FIGURES", "CalibrationCase", "CalibrationFigureData",
           "calibration_realization", "figure_data"]

CALIBRATION_RUNS = 1000  #: realizations of the calibration Monte Carlo of the figures (batch filter)
OUTAGE_WINDOWS = ((6.0, 11.0), (14.0, 29.0))  #: s, the GPS outages of the outage figure (notebook 15)


def _params(params):
    from .params import CalibrationParams

    return require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()


def calibration_realization(params=None, missing_fixes=None, truth: str = "euler", seed: int = 0):
    """One seeded realization of the calibration problem and filterpy's filter on it.

    Parameters
    ----------
    params : CalibrationParams (default: ``CalibrationParams()``)
    missing_fixes : optional bool array (n_gps,), fixes missing in the realization (outages):
        their GPS rows are NaN and the filter only predicts there, as in the Monte Carlo
    truth : "euler" or "analytic"
    seed : int >= 0, seed of ``numpy.random.default_rng``

    Returns
    -------
    (Simulation with one realization, FilterResult of :func:`~kfcal_helpers.calibration.run_filterpy`)
    """
    from .filters import run_filterpy
    from .simulation import simulate

    params = _params(params)
    seed = require_int("seed", seed, minimum=0)
    missing = require_mask("missing_fixes", missing_fixes, params.n_gps)
    if missing is not None and not missing.any():
        missing = None
    sim = simulate(params, 1, seed, truth=truth, missing_fixes=missing)
    return sim, run_filterpy(params, sim.dz[0])


class CalibrationCase:
    """A calibration scenario whose realization and Monte Carlo are computed on first use.

    params : CalibrationParams (default: ``CalibrationParams()``); missing_fixes : bool (n_gps,) or None;
    truth : "euler" or "analytic"; seed : seed of the realization and of the Monte Carlo;
    n_runs, engine : of the Monte Carlo (engine "batch" or "filterpy"; ``filter="batch"`` or ``"filterpy"``,
    the keyword of an earlier version, is read as ``engine``); mc : an existing MonteCarloResult to use instead.
    """

    def __init__(self, params=None, missing_fixes=None, truth: str = "euler", seed: int = 0,
                 n_runs: int = CALIBRATION_RUNS, engine: str = "batch", mc=None, *, filter: str | None = None):
        from .montecarlo import require_engine
        from .simulation import TRUTH_MODELS

        self.params = _params(params)
        missing = require_mask("missing_fixes", missing_fixes, self.params.n_gps)
        self.missing = missing if missing is not None else self._no_outage()
        self.truth = require_choice("truth", truth, TRUTH_MODELS)
        self.seed = require_int("seed", seed, minimum=0)
        self.n_runs = require_int("n_runs", n_runs, minimum=2)
        self.engine = require_engine(engine, filter)
        if mc is not None:
            self.mc = mc

    def _no_outage(self):
        import numpy as np

        return np.zeros(self.params.n_gps, bool)

    @classmethod
    def from_monte_carlo(cls, mc, seed: int = 0) -> "CalibrationCase":
        """The scenario of an existing MonteCarloResult (its params, truth and missing fixes)."""
        return cls(mc.params, mc.missing, truth=mc.truth, seed=seed, n_runs=mc.n_runs, engine=mc.engine, mc=mc)

    @cached_property
    def realization(self):
        """(Simulation, FilterResult) of :func:`calibration_realization` for this scenario."""
        return calibration_realization(self.params, self.missing, self.truth, self.seed)

    @cached_property
    def mc(self):
        """The seeded Monte Carlo of this scenario (MonteCarloResult)."""
        from .montecarlo import run_monte_carlo

        return run_monte_carlo(self.params, self.n_runs, self.seed, engine=self.engine, truth=self.truth,
                               missing_fixes=self.missing, progress=False)

    @cached_property
    def spans(self) -> list:
        """The outages as time spans in seconds (empty without outages)."""
        from .plots import outage_spans

        return outage_spans(self.params, self.missing)


class CalibrationFigureData:
    """The two scenarios the figure functions draw from: ``calibration`` (default: ``CalibrationParams()``,
    no outage) and ``outage`` (default: the same parameters, truth and seed with :data:`OUTAGE_WINDOWS`)."""

    def __init__(self, calibration: CalibrationCase | None = None, outage: CalibrationCase | None = None):
        self.calibration = require_instance("calibration", calibration, CalibrationCase, allow_none=True) \
            or CalibrationCase()
        if outage is not None:
            self.outage = require_instance("outage", outage, CalibrationCase)

    @cached_property
    def outage(self) -> CalibrationCase:
        """Default: the calibration scenario's parameters, truth and seed with :data:`OUTAGE_WINDOWS`."""
        from .outages import outage_mask

        p = self.calibration.params
        return CalibrationCase(p, outage_mask(p, OUTAGE_WINDOWS), truth=self.calibration.truth,
                               seed=self.calibration.seed)


def figure_data() -> CalibrationFigureData:
    """The default, seeded figure data (nothing is computed before a figure needs it)."""
    return CalibrationFigureData()


# ---------------------------------------------------------------------------
# The figure functions (each returns a Figure; sizes from rcParams, the slide size when saving)
def _size():
    from ..style import figure_size

    return figure_size()


def calib_truth_euler(data: CalibrationFigureData):
    """Analytic vs Euler-integrated truth and their difference."""
    from .plots import plot_truth_vs_euler

    return plot_truth_vs_euler(data.calibration.params, figsize=_size())


def calib_imu_drift(data: CalibrationFigureData):
    """The IMU dead-reckoning drift of one realization and the bias-only prediction."""
    from .plots import plot_dead_reckoning

    return plot_dead_reckoning(data.calibration.realization[0], figsize=_size())


def calib_gps_dz(data: CalibrationFigureData):
    """The measurement dz = GPS - IMU at the fixes against the true error state."""
    from .plots import plot_gps_measurement

    return plot_gps_measurement(data.calibration.realization[0], figsize=_size())


def _errors(case: CalibrationCase, title: str):
    from .plots import plot_estimate_errors

    sim, fr = case.realization
    return plot_estimate_errors(case.params, sim.dx[0], fr, title=title, outages=case.spans, figsize=_size())


def calib_errors(data: CalibrationFigureData):
    """One realization's estimation errors with ±1σ, ±2σ from P (filterpy)."""
    case = data.calibration
    title = "One realization: estimation errors with ±1σ and ±2σ from P"
    return _errors(case, title + (" (GPS outages shaded)" if case.spans else ""))


def calib_sigma_sawtooth(data: CalibrationFigureData):
    """σ from P over the first 2 s (or through the first outage): the predict/update sawtooth."""
    from .plots import plot_covariance_sawtooth

    case = data.calibration
    t_max = min(case.params.duration, case.spans[0][1] + 1.0) if case.spans else 2.0
    return plot_covariance_sawtooth(case.params, case.realization[1], t_max=t_max, outages=case.spans,
                                    figsize=_size())


def _check_panels(*panels):
    def make(data: CalibrationFigureData):
        from .plots import plot_check_panels

        mc = data.calibration.mc
        return plot_check_panels(mc, panels, ncols=2, figsize=_size(),
                                 title=f"Monte Carlo checks, N = {mc.n_runs} realizations ({mc.engine} engine)")

    return make


def calib_mc_sigma(data: CalibrationFigureData):
    """Ensemble σ vs filter σ, a priori and a posteriori."""
    from .plots import plot_ensemble_sigma

    return plot_ensemble_sigma(data.calibration.mc, figsize=_size())


def calib_outage(data: CalibrationFigureData):
    """One realization's errors and ±σ, ±2σ through the GPS outages."""
    spans = ", ".join(f"{a:g}–{b:g} s" for a, b in data.outage.spans)
    return _errors(data.outage, f"GPS outages {spans} (shaded): one realization's errors and ±σ, ±2σ")


def calib_rts_bias(data: CalibrationFigureData):
    """Bias error and σ_b, filtered vs RTS-smoothed, one realization."""
    from .batch_estimate import rts_smooth_fixes
    from .plots import plot_smoothed_bias

    case = data.calibration
    sim, fr = case.realization
    xs, Ps = rts_smooth_fixes(case.params, fr.x_prior, fr.x_post, fr.P_prior, fr.P_post)
    return plot_smoothed_bias(case.params, float(sim.b[0]), fr, xs, Ps, figsize=_size())


#: the calibration lecture figures, in lecture order
FIGURES = (
    LectureFigure("calib_truth_euler", "calibration: analytic vs Euler-integrated truth and their difference",
                  calib_truth_euler),
    LectureFigure("calib_imu_drift", "calibration: IMU dead-reckoning drift of one realization and the "
                                     "bias-only prediction", calib_imu_drift),
    LectureFigure("calib_gps_dz", "calibration: the measurement dz = GPS - IMU at the 5 Hz fixes against the "
                                  "true error state", calib_gps_dz),
    LectureFigure("calib_errors", "calibration: one realization's estimation errors with ±1σ, ±2σ from P "
                                  "(filterpy)", calib_errors),
    LectureFigure("calib_sigma_sawtooth", "calibration: σ from P over the first 2 s, the predict/update sawtooth",
                  calib_sigma_sawtooth),
    LectureFigure("calib_mc_mean_cov", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations, batch): "
                                       "mean error and ensemble variance / P against their bands",
                  _check_panels("mean_error", "covariance")),
    LectureFigure("calib_mc_sigma", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations): ensemble σ "
                                    "vs filter σ, a priori and a posteriori", calib_mc_sigma),
    LectureFigure("calib_mc_orth_resid", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations): "
                                         "orthogonality and residual independence",
                  _check_panels("orthogonality", "residual_independence")),
    LectureFigure("calib_mc_nees_nis", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations): NEES and "
                                       "NIS against χ² bounds", _check_panels("nees", "nis")),
    LectureFigure("calib_outage", "calibration: GPS outages 6-11 s and 14-29 s, errors and ±2σ through the gaps",
                  calib_outage),
    LectureFigure("calib_rts_bias", "calibration: bias error and σ_b, filtered vs RTS-smoothed, one realization",
                  calib_rts_bias),
)
