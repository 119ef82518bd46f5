"""Lecture figures of both course problems, written as slide-ready files.

``python -m kfcal_helpers figures DIR [--svg] [--only NAME ...] [--list]`` writes every figure
of :data:`FIGURES` as ``DIR/<name>.png`` (1280 x 720 px: ``SLIDE_SIZE`` at ``SLIDE_DPI``), and
also ``DIR/<name>.svg`` with ``--svg``, and prints each path written, one per line.

:data:`FIGURES` is the registry: one :class:`LectureFigure` (file stem, one-line description,
function) per figure, in lecture order (calibration, then cooperative localization).  Each
function takes a :class:`FigureData`, which computes the shared results once, lazily and seeded
(one calibration realization, a :data:`CALIBRATION_RUNS`-realization batch Monte Carlo, the
seeded cooperative-localization log and a :data:`COOP_RUNS`-run EKF truth-model test), and
returns a matplotlib Figure drawn by :mod:`kfcal_helpers.calibration.plots` or
:mod:`kfcal_helpers.coop.plots`.  The figures are drawn and saved inside
``matplotlib.rc_context(style_params("slides"))``, so the caller's rcParams are unchanged,
and every figure is closed after saving.
"""

from __future__ import annotations

import os
import sys
from functools import cached_property
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np

from .style import SLIDE_DPI, style_params
from .validation import require_choice, require_int

__all__ = ["CALIBRATION_RUNS", "COOP_RUNS", "OUTAGE_WINDOWS", "FIGURES", "LectureFigure", "CalibrationCase",
           "CoopCase", "FigureData", "calibration_realization", "check_directory", "save_atomic", "save_figures", "write_figures",
           "use_agg_backend", "add_parser", "run"]

CALIBRATION_RUNS = 1000  #: realizations of the calibration Monte Carlo (batch engine)
COOP_RUNS = 30  #: runs of the cooperative-localization truth-model test (EKF)
OUTAGE_WINDOWS = ((6.0, 11.0), (14.0, 29.0))  #: s, the GPS outages of the outage figure (notebook 15)


class LectureFigure(NamedTuple):
    """One registry entry: ``name`` (file stem), ``description`` (one line), ``make(data) -> Figure``."""

    name: str
    description: str
    make: Callable


# ---------------------------------------------------------------------------
# Shared, lazily computed results
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
    from .calibration import CalibrationParams, run_filterpy, simulate

    params = CalibrationParams() if params is None else params
    seed = require_int("seed", seed, minimum=0)
    if missing_fixes is not None and not np.any(missing_fixes):
        missing_fixes = None
    sim = simulate(params, 1, np.random.default_rng(seed), truth=truth, missing_fixes=missing_fixes)
    return sim, run_filterpy(params, sim.dz[0])


class CalibrationCase:
    """A calibration scenario whose realization and Monte Carlo are computed on first use.

    params : CalibrationParams (default: ``CalibrationParams()``); missing_fixes : bool (n_gps,) or None;
    truth : "euler" or "analytic"; seed : seed of the realization and of the Monte Carlo;
    n_runs, engine : of the Monte Carlo; mc : an existing MonteCarloResult to use instead.
    """

    def __init__(self, params=None, missing_fixes=None, truth: str = "euler", seed: int = 0,
                 n_runs: int = CALIBRATION_RUNS, engine: str = "batch", mc=None):
        from .calibration import CalibrationParams

        self.params = CalibrationParams() if params is None else params
        if not isinstance(self.params, CalibrationParams):
            raise ValueError(f"params must be a CalibrationParams, got {type(self.params).__name__}")
        missing = np.zeros(self.params.n_gps, bool) if missing_fixes is None else np.asarray(missing_fixes)
        if missing.shape != (self.params.n_gps,) or missing.dtype != bool:
            raise ValueError(f"missing_fixes must be a bool array of shape ({self.params.n_gps},)")
        self.missing = missing
        self.truth, self.seed, self.n_runs, self.engine = truth, seed, n_runs, engine
        if mc is not None:
            self.mc = mc

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
        from .calibration import run_monte_carlo

        return run_monte_carlo(self.params, n_runs=self.n_runs, seed=self.seed, engine=self.engine,
                               truth=self.truth, missing_fixes=self.missing, progress=False)

    @cached_property
    def spans(self) -> list:
        """The outages as time spans in seconds (empty without outages)."""
        from .calibration.plots import outage_spans

        return outage_spans(self.params, self.missing)


class CoopCase:
    """The cooperative-localization results of the slides, computed on first use.

    log_seed : seed of the simulated observation log; n_runs, seed : of the EKF truth-model test.
    """

    def __init__(self, log_seed: int | None = None, n_runs: int = COOP_RUNS, seed: int = 0):
        from .coop import DEFAULT_LOG_SEED, CoopParams

        self.params = CoopParams()
        self.log_seed = DEFAULT_LOG_SEED if log_seed is None else require_int("log_seed", log_seed, minimum=0)
        self.n_runs = require_int("n_runs", n_runs, minimum=1)
        self.seed = require_int("seed", seed, minimum=0)

    @cached_property
    def log(self):
        from .coop import generate_log

        return generate_log(self.params, seed=self.log_seed)

    @cached_property
    def nominal(self) -> np.ndarray:
        from .coop import nominal_trajectory

        return nominal_trajectory(self.params)

    @cached_property
    def results(self) -> dict:
        """``{"lkf"|"ekf"|"ukf": FilterResult}`` on the log, tuned Q, with the log's truth."""
        from .coop import FILTERS, run_filter

        return {name: run_filter(name, self.log.y, self.log.params(), truth=self.log.truth) for name in FILTERS}

    @cached_property
    def mc(self):
        """EKF truth-model test (tuned Q), ``n_runs`` runs."""
        from .coop import truth_model_test

        return truth_model_test("ekf", self.n_runs, seed=self.seed, params=self.params)


class FigureData:
    """The three scenarios the figure functions draw from: ``calibration`` (``CalibrationParams()`` defaults, no
    outage), ``outage`` (the same seed with :data:`OUTAGE_WINDOWS`) and ``coop``."""

    def __init__(self, calibration: CalibrationCase | None = None, outage: CalibrationCase | None = None,
                 coop: CoopCase | None = None):
        self.calibration = calibration or CalibrationCase()
        if outage is not None:
            self.outage = outage
        self.coop = coop or CoopCase()

    @cached_property
    def outage(self) -> CalibrationCase:
        """Default: the calibration scenario's parameters and seed with :data:`OUTAGE_WINDOWS`."""
        from .calibration import outage_mask

        p = self.calibration.params
        return CalibrationCase(p, outage_mask(p, OUTAGE_WINDOWS), truth=self.calibration.truth,
                               seed=self.calibration.seed)


# ---------------------------------------------------------------------------
# The figure functions (each returns a Figure; sizes from rcParams, the slide size when saving)
def _size():
    import matplotlib as mpl

    return tuple(mpl.rcParams["figure.figsize"])


def _calib_truth(data: FigureData):
    from .calibration.plots import plot_truth_vs_euler

    return plot_truth_vs_euler(data.calibration.params, figsize=_size())


def _calib_imu_drift(data: FigureData):
    from .calibration.plots import plot_dead_reckoning

    return plot_dead_reckoning(data.calibration.realization[0], figsize=_size())


def _calib_gps_dz(data: FigureData):
    from .calibration.plots import plot_gps_measurement

    return plot_gps_measurement(data.calibration.realization[0], figsize=_size())


def _errors(case: CalibrationCase, title: str):
    from .calibration.plots import plot_estimate_errors

    sim, fr = case.realization
    return plot_estimate_errors(case.params, sim.dx[0], fr, title=title, outages=case.spans, figsize=_size())


def _calib_errors(data: FigureData):
    case = data.calibration
    title = "One realization: estimation errors with ±1σ and ±2σ from P"
    return _errors(case, title + (" (GPS outages shaded)" if case.spans else ""))


def _calib_sawtooth(data: FigureData):
    from .calibration.plots import plot_covariance_sawtooth

    case = data.calibration
    t_max = min(case.params.duration, case.spans[0][1] + 1.0) if case.spans else 2.0
    return plot_covariance_sawtooth(case.params, case.realization[1], t_max=t_max, outages=case.spans,
                                    figsize=_size())


def _check_panels(*panels):
    def make(data: FigureData):
        from .calibration.plots import plot_check_panels

        mc = data.calibration.mc
        return plot_check_panels(mc, panels, ncols=2, figsize=_size(),
                                 title=f"Monte Carlo checks, N = {mc.n_runs} realizations ({mc.engine} engine)")

    return make


def _calib_mc_sigma(data: FigureData):
    from .calibration.plots import plot_ensemble_sigma

    return plot_ensemble_sigma(data.calibration.mc, figsize=_size())


def _calib_outage(data: FigureData):
    spans = ", ".join(f"{a:g}–{b:g} s" for a, b in data.outage.spans)
    return _errors(data.outage, f"GPS outages {spans} (shaded): one realization's errors and ±σ, ±2σ")


def _calib_rts(data: FigureData):
    from .calibration import rts_smooth_fixes
    from .calibration.plots import plot_smoothed_bias

    case = data.calibration
    sim, fr = case.realization
    xs, Ps = rts_smooth_fixes(case.params, fr.x_prior, fr.x_post, fr.P_prior, fr.P_post)
    return plot_smoothed_bias(case.params, float(sim.b[0]), fr, xs, Ps, figsize=_size())


def _coop_paths(data: FigureData):
    from .coop.plots import plot_paths

    c = data.coop
    return plot_paths({"nominal": c.nominal}, f"Nominal paths over {c.params.duration:g} s (start: dots)",
                      figsize=_size())


def _coop_measurements(data: FigureData):
    from .coop import measure
    from .coop.plots import plot_measurements

    c = data.coop
    return plot_measurements(c.params.t, {r"noise-free $h(\bar{x})$": measure(c.nominal)},
                             "Noise-free measurements along the nominal (bearings wrapped to (−π, π])",
                             figsize=_size(), ncols=3)


def _coop_errors(name: str):
    def make(data: FigureData):
        from .coop import TUNED_Q_SCALE
        from .coop.plots import plot_errors

        c = data.coop
        r = c.results[name]
        return plot_errors(r.t, r.errors(c.log.truth), r.sigma2,
                           f"{name.upper()} on the simulated log (seed {c.log_seed}, Q = "
                           f"{TUNED_Q_SCALE[name]:g} Qtrue): errors and ±2σ", figsize=_size(), ncols=3)

    return make


def _coop_nees_nis(data: FigureData):
    from .coop.plots import plot_consistency

    mc = data.coop.mc
    return plot_consistency(mc, f"{mc.filter.upper()} truth-model test: N = {mc.runs} runs, α = {mc.alpha:g}",
                            figsize=_size())


def _coop_nis_comparison(data: FigureData):
    from .coop.cli import log_summary
    from .coop.plots import plot_nis_comparison

    c = data.coop
    summaries = {name.upper(): log_summary(r) for name, r in c.results.items()}
    first = next(iter(summaries.values()))
    return plot_nis_comparison({n: s["nis_time_average"] for n, s in summaries.items()}, first["nis_bounds"],
                               f"Time-averaged NIS on the simulated log ({first['measurements']} updates, α = 0.05)",
                               figsize=_size())


#: the registry of lecture figures, in lecture order
FIGURES = (
    LectureFigure("calib_truth_euler", "calibration: analytic vs Euler-integrated truth and their difference",
                  _calib_truth),
    LectureFigure("calib_imu_drift", "calibration: IMU dead-reckoning drift of one realization and the "
                                     "bias-only prediction", _calib_imu_drift),
    LectureFigure("calib_gps_dz", "calibration: the measurement dz = GPS - IMU at the 5 Hz fixes against the "
                                  "true error state", _calib_gps_dz),
    LectureFigure("calib_errors", "calibration: one realization's estimation errors with ±1σ, ±2σ from P "
                                  "(filterpy)", _calib_errors),
    LectureFigure("calib_sigma_sawtooth", "calibration: σ from P over the first 2 s, the predict/update sawtooth",
                  _calib_sawtooth),
    LectureFigure("calib_mc_mean_cov", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations, batch): "
                                       "mean error and ensemble variance / P against their bands",
                  _check_panels("mean_error", "covariance")),
    LectureFigure("calib_mc_sigma", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations): ensemble σ "
                                    "vs filter σ, a priori and a posteriori", _calib_mc_sigma),
    LectureFigure("calib_mc_orth_resid", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations): "
                                         "orthogonality and residual independence",
                  _check_panels("orthogonality", "residual_independence")),
    LectureFigure("calib_mc_nees_nis", f"calibration Monte Carlo ({CALIBRATION_RUNS} realizations): NEES and "
                                       "NIS against χ² bounds", _check_panels("nees", "nis")),
    LectureFigure("calib_outage", "calibration: GPS outages 6-11 s and 14-29 s, errors and ±2σ through the gaps",
                  _calib_outage),
    LectureFigure("calib_rts_bias", "calibration: bias error and σ_b, filtered vs RTS-smoothed, one realization",
                  _calib_rts),
    LectureFigure("coop_paths", "coop: nominal paths of the UGV and the UAV in the east-north plane", _coop_paths),
    LectureFigure("coop_measurements", "coop: noise-free measurements along the nominal, bearings wrapped",
                  _coop_measurements),
    LectureFigure("coop_ekf_errors", "coop: EKF errors with ±2σ on the simulated log", _coop_errors("ekf")),
    LectureFigure("coop_ukf_errors", "coop: UKF errors with ±2σ on the simulated log", _coop_errors("ukf")),
    LectureFigure("coop_nees_nis", f"coop: EKF truth-model test ({COOP_RUNS} runs), NEES and NIS against χ² "
                                   "bounds", _coop_nees_nis),
    LectureFigure("coop_nis_comparison", "coop: time-averaged NIS of LKF, EKF, UKF on the simulated log against "
                                         "χ² bounds", _coop_nis_comparison),
)
_BY_NAME = {f.name: f for f in FIGURES}


# ---------------------------------------------------------------------------
# Writing
def check_directory(directory, argname: str = "directory") -> Path:
    """``directory`` as a Path; ValueError naming ``argname`` unless it is a non-empty path that is
    an existing writable directory, or can be created (its nearest existing ancestor is a writable
    directory).  Nothing is created here: the callers check before their long work starts."""
    if isinstance(directory, bool) or not isinstance(directory, (str, Path)) or str(directory) == "":
        raise ValueError(f"{argname} must be a directory path, got {directory!r}")
    path = Path(directory)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{argname} must be a directory (existing or to create), got the existing file {str(path)!r}")
    existing = path.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{argname}: cannot create {str(path)!r}, {str(existing)!r} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{argname}: cannot write into {str(existing)!r} (permission denied)")
    return path


def save_atomic(fig, out: Path, fmt: str, dpi: float, argname: str = "directory") -> Path:
    """Save ``fig`` to ``out`` under a temporary name in the same directory, then rename it, so an
    interrupted or failed save leaves no partial file (ValueError naming ``argname`` if the file
    cannot be written)."""
    from .output import PARTIAL_FILES

    out = Path(out)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.part")
    PARTIAL_FILES.add(str(tmp))  # removed by the command line's Ctrl-C handler
    try:
        fig.savefig(tmp, format=fmt, dpi=dpi)
        os.replace(tmp, out)
    except OSError as exc:
        raise ValueError(f"{argname}: cannot write {str(out)!r}: {exc.strerror or exc}") from None
    finally:
        PARTIAL_FILES.discard(str(tmp))
        if tmp.exists():
            try:
                tmp.unlink()
            except OSError:
                pass
    return out


def _select(names, argname: str) -> tuple:
    if names is None:
        return FIGURES
    if isinstance(names, str):
        names = [names]
    try:
        names = list(names)
    except TypeError:
        raise ValueError(f"{argname} must be a sequence of figure names, got {names!r}") from None
    if not names:
        raise ValueError(f"{argname} must name at least one figure, one of {', '.join(_BY_NAME)}")
    for n in names:
        require_choice(argname, n, tuple(_BY_NAME))
    return tuple(_BY_NAME[n] for n in dict.fromkeys(names))


def save_figures(figures, directory, data: FigureData | None = None, svg: bool = False,
                 argname: str = "directory") -> list[Path]:
    """Draw ``figures`` (LectureFigure entries) in the slides style and save each as
    ``directory/<name>.png`` (and ``.svg`` when ``svg``) at SLIDE_DPI, uncropped, so a PNG is
    SLIDE_SIZE x SLIDE_DPI pixels (1280 x 720); closes every figure; returns the paths written.
    ``data`` defaults to a new :class:`FigureData`; ``argname`` names ``directory`` in errors."""
    import matplotlib
    import matplotlib.pyplot as plt

    path = check_directory(directory, argname)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{argname}: cannot create directory {str(path)!r}: {exc.strerror}") from None
    data = FigureData() if data is None else data
    formats = ("png", "svg") if svg else ("png",)
    written = []
    # "standard": the whole canvas, not the style's tight crop, so every PNG is exactly the slide size
    with matplotlib.rc_context({**style_params("slides"), "savefig.bbox": "standard"}):
        for entry in figures:
            fig = entry.make(data)
            try:
                for fmt in formats:
                    written.append(save_atomic(fig, path / f"{entry.name}.{fmt}", fmt, SLIDE_DPI, argname))
            finally:
                plt.close(fig)
    return written


def write_figures(directory, svg: bool = False, names=None, data: FigureData | None = None) -> list[Path]:
    """Write the lecture figures of :data:`FIGURES` to ``directory`` (created if needed).

    Parameters
    ----------
    directory : str or Path, a directory (not an existing file)
    svg : also write SVG next to each PNG
    names : optional sequence of registry names (default: all, in registry order)
    data : optional FigureData to draw from (default: a new, seeded one)

    Returns
    -------
    list of Path, the files written (PNG 1280 x 720 px; with ``svg`` each PNG followed by its SVG)

    Raises
    ------
    ValueError naming ``directory`` or ``names`` and what is allowed.
    """
    selected = _select(names, "names")
    return save_figures(selected, directory, data, svg=bool(svg))


# ---------------------------------------------------------------------------
# Command line
def use_agg_backend() -> None:
    """Select matplotlib's Agg backend (files only, no display) unless pyplot is already in use,
    as in a notebook, whose backend is left alone.  For the command-line entry points."""
    if "matplotlib.pyplot" not in sys.modules:
        import matplotlib

        matplotlib.use("Agg")


def add_parser(subparsers):
    """Register ``figures`` on an argparse sub-parsers object."""
    p = subparsers.add_parser("figures", help="write the lecture figures of both problems (PNG, optionally SVG)",
                              description="Write the lecture figures of both problems as 1280x720 PNG "
                                          "(and SVG with --svg) and print each path written.")
    p.add_argument("directory", nargs="?", metavar="DIR", help="output directory (created if needed)")
    p.add_argument("--svg", action="store_true", help="also write SVG")
    p.add_argument("--only", nargs="+", metavar="NAME", help="write only these figures (see --list)")
    p.add_argument("--list", action="store_true", help="list the figure names and descriptions, write nothing")
    p.set_defaults(run=run)
    return p


def run(args) -> int:
    """Run the sub-command; returns the exit code (ValueError for bad input)."""
    selected = _select(args.only, "--only")
    if args.list:
        width = max(len(f.name) for f in selected)
        for f in selected:
            print(f"{f.name:<{width}}  {f.description}")
        return 0
    if args.directory is None:
        raise ValueError("DIR is required (or give --list)")
    check_directory(args.directory, "DIR")
    use_agg_backend()
    for path in save_figures(selected, args.directory, svg=args.svg, argname="DIR"):
        print(path)
    return 0
