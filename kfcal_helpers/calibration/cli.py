"""``python -m kfcal_helpers calibrate``: the default scenario's Monte Carlo check table."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from ..consistency import format_checks
from ..validation import MAX_SEED, cli_float, cli_int, require_int
from .montecarlo import ENGINES, MEMORY_LIMIT, estimate_run, run_monte_carlo
from .outages import outage_mask, parse_outage
from .params import CalibrationParams
from .simulation import TRUTH_MODELS

__all__ = ["add_parser", "run", "result_to_dict", "output_bytes", "plan_between_fixes", "write_figures", "figure_case",
           "FIGURE_FILES", "COLUMNS_LEGEND", "MISMATCH_NOTE"]

#: the lines under the check table that say what its columns mean
COLUMNS_LEGEND = (
    "inside: share of the check's entries (fixes, components, pairs) inside their 95% band; "
    "about 0.95 for a consistent filter\n"
    "worst:  the largest deviation as a multiple of the simultaneous band (all entries of the seven checks "
    "together; between_fixes a family of its own); pass when <= 1, FAIL when > 1")
#: printed with --truth analytic when a check fails
MISMATCH_NOTE = (
    "FAIL rows are the intended model-mismatch demonstration: --truth analytic simulates the exact "
    "kinematics, which the filter's Euler model does not match (notebook 07)")
#: bytes the --figures drawing needs on top of the Monte Carlo's result: matplotlib, and per GPS fix
#: squared for the check panels (measured, rounded up)
FIGURES_BYTES, FIGURES_BYTES_PER_FIX2 = 60e6, 80.0
#: bytes the table or the JSON needs on top of the Monte Carlo's last phase (measured with tracemalloc,
#: rounded up).  Both compute the checks again once the run's own computation of them is freed (about
#: 200 bytes per GPS fix squared, less than the run's last phase counts), and keep the between-fixes
#: check (its entries, bands and temporaries: about 250 bytes per IMU sample, of which the run's last
#: phase frees about 100); then the JSON text (small)
OUTPUT_BYTES, OUTPUT_BYTES_PER_SAMPLE = 2e6, 250.0
#: CalibrationParams field -> its option, for error messages
_FLAGS = {"omega": "--omega", "imu_rate": "--imu-rate", "gps_rate": "--gps-rate", "duration": "--duration"}


def add_parser(subparsers) -> argparse.ArgumentParser:
    d = CalibrationParams()
    p = subparsers.add_parser("calibrate", help="Monte Carlo of the accelerometer-calibration filter",
                              description="Simulate, filter and check the accelerometer calibration "
                                          "(the course's default scenario unless given).")
    p.add_argument("--runs", type=cli_int(2), default=1000,
                   help="realizations, at least 2 (default 1000); runs estimated to need more than 500 MB "
                        "or 1 h are refused")
    p.add_argument("--seed", type=cli_int(0, MAX_SEED), default=0,
                   help="seed of numpy.random.default_rng, an integer >= 0 (default 0)")
    p.add_argument("--engine", choices=ENGINES, default="batch",
                   help="how the Kalman filter runs: batch (fast) or filterpy (one filter per run); JSON key "
                        "'engine' (key 'filter' is the algorithm, 'kf')")
    p.add_argument("--omega", type=cli_float(0, unit="rad/s"), default=d.omega,
                   help=f"rad/s, at most pi * IMU rate (default {d.omega:g})")
    p.add_argument("--imu-rate", type=cli_float(0, unit="Hz"), default=d.imu_rate, help=f"Hz (default {d.imu_rate:g})")
    p.add_argument("--gps-rate", type=cli_float(0, unit="Hz"), default=d.gps_rate,
                   help=f"Hz, divides the IMU rate (default {d.gps_rate:g})")
    p.add_argument("--duration", type=cli_float(0, unit="s"), default=d.duration,
                   help=f"s, a whole number of IMU periods (default {d.duration:g})")
    p.add_argument("--truth", choices=TRUTH_MODELS, default="euler", help="truth model (default euler)")
    p.add_argument("--outage", action="append", default=[], metavar="START:END",
                   help="GPS outage in seconds, fixes with START <= t < END are missing (repeatable); "
                        "at least 2 fixes must remain")
    p.add_argument("--figures", metavar="DIR",
                   help="also write the notebook-5 and notebook-6 figures as PNG in the slides style (one "
                        "realization with the same outages, and the Monte Carlo checks)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.set_defaults(run=run)
    return p


def result_to_dict(mc, outages=(), checks=None, skipped=None) -> dict:
    """The JSON summary of a MonteCarloResult.

    outages : the GPS outage windows ``(start, end)`` in seconds the run used (key ``outages``,
    a list of ``[start, end]``, empty without outages).
    checks : the checks to write (default ``mc.all_checks()``: the seven, and ``between_fixes`` when
    the run summed the 200 Hz error), the same the table prints.
    skipped : ``{check: reason}`` of checks not run (key ``skipped_checks``, written when not empty).
    """
    checks = mc.all_checks() if checks is None else checks
    out = {
        "n_runs": mc.n_runs,
        "filter": mc.filter,
        "engine": mc.engine,
        "truth": mc.truth,
        "seconds": mc.seconds,
        "alpha": mc.alpha,
        "outages": [[float(start), float(end)] for start, end in outages],
        "sigma_final": mc.sigma_final.tolist(),
        "ensemble_sigma_final": mc.ensemble_sigma_final.tolist(),
        "checks": {},
    }
    for name, c in checks.items():
        entry = {"inside_fraction": c.inside_fraction, "worst": c.worst, "passed": c.passed}
        if name in ("nees", "nis"):
            entry["bounds"] = list(mc.nees_bounds if name == "nees" else mc.nis_bounds)
        out["checks"][name] = entry
    if skipped:
        out["skipped_checks"] = dict(skipped)
    return out


def output_bytes(params: CalibrationParams, figures: bool = False, between_fixes: bool = False) -> float:
    """Bytes the command line's output (table or JSON, and ``--figures``) needs while the Monte Carlo's
    result is alive: counted by the estimate before the run (:data:`OUTPUT_BYTES`, :data:`FIGURES_BYTES`)."""
    out = OUTPUT_BYTES + (OUTPUT_BYTES_PER_SAMPLE * params.n_imu if between_fixes else 0.0)
    if figures:
        out += FIGURES_BYTES + FIGURES_BYTES_PER_FIX2 * params.n_gps**2
    return out


def plan_between_fixes(params: CalibrationParams, n_runs: int, engine: str, figures: bool = False,
                       runs_name: str = "--runs", params_name: str = "--duration, --imu-rate, --gps-rate"):
    """``(between, skipped)``: whether the run also checks the 200 Hz error between fixes, and why not.

    It does when IMU samples lie between the fixes and the run with its 200 Hz sums fits in
    :data:`MEMORY_LIMIT`; otherwise ``skipped`` says why (``{"between_fixes": reason}``).  Raises the
    estimate's ValueError when even the run without them does not fit, or takes too long."""
    names = {"runs_name": runs_name, "params_name": params_name}
    if params.n_imu <= params.n_gps:
        estimate_run(params, n_runs, engine, extra_bytes=output_bytes(params, figures), **names)
        return False, {"between_fixes": "every IMU sample is a GPS fix (GPS rate = IMU rate): nothing between fixes"}
    try:
        estimate_run(params, n_runs, engine, extra_bytes=output_bytes(params, figures, True), between_fixes=True,
                     **names)
        return True, {}
    except ValueError:
        estimate_run(params, n_runs, engine, extra_bytes=output_bytes(params, figures), **names)
        return False, {"between_fixes": f"not run: its 200 Hz sums over {params.n_imu} IMU samples would take the "
                                        f"run over the {MEMORY_LIMIT / 1e6:.0f} MB allowed"}


#: file stem of each ``--figures`` file -> the lecture figure (:data:`.figures.FIGURES`) it draws
FIGURE_FILES = {"calib_errors": "calib_errors", "calib_sigma_sawtooth": "calib_sigma_sawtooth",
                "calib_checks": None}


def figure_case(mc, seed: int = 0):
    """The scenario ``--figures`` draws: ``mc``'s parameters, truth model and missing fixes (outages),
    and one realization seeded with ``seed`` whose fixes inside the outages are missing, as in the
    Monte Carlo (a :class:`~kfcal_helpers.calibration.figures.CalibrationCase`)."""
    from .figures import CalibrationCase

    return CalibrationCase.from_monte_carlo(mc, seed=seed)


def _all_checks(data):
    """The six checks in one figure: slide width, 1.5 slide heights (1280 x 1080 px), for three rows."""
    import matplotlib as mpl

    from .plots import plot_checks

    width, height = mpl.rcParams["figure.figsize"]
    return plot_checks(data.calibration.mc, figsize=(width, 1.5 * height))


def write_figures(mc, directory, seed: int = 0) -> list[Path]:
    """Write the notebook-5 figures of one realization (errors with ±1σ/±2σ, the σ sawtooth;
    1280 x 720 px) and the notebook-6 Monte Carlo checks (1280 x 1080 px) as PNG in the slides
    style into ``directory`` (created if needed; ValueError naming ``--figures`` if it is a file).

    The realization (seeded with ``seed``) has the same missing fixes as ``mc`` (its outages,
    shaded in the figures).  The first two are the lecture figures ``calib_errors`` and
    ``calib_sigma_sawtooth`` of :mod:`kfcal_helpers.calibration.figures`.  Returns the paths written.
    """
    from ..slides import save_figures
    from ..registry import LectureFigure
    from .figures import FIGURES, CalibrationFigureData

    by_name = {f.name: f for f in FIGURES}
    entries = [LectureFigure(stem, by_name[name].description, by_name[name].make) if name else
               LectureFigure(stem, "the six Monte Carlo checks", _all_checks)
               for stem, name in FIGURE_FILES.items()]
    data = CalibrationFigureData(calibration=figure_case(mc, seed))
    return save_figures(entries, directory, data, argname="--figures")


def _params(args):
    """CalibrationParams from the options; ValueError naming the option (``--omega``, not ``omega``)."""
    try:
        return CalibrationParams(omega=args.omega, imu_rate=args.imu_rate, gps_rate=args.gps_rate,
                                 duration=args.duration)
    except ValueError as exc:
        text = re.sub(r"\b(" + "|".join(_FLAGS) + r")\b", lambda m: _FLAGS[m.group(1)], str(exc))
        raise ValueError(text) from None


def run(args) -> int:
    from ..output import dumps_json, path_text

    require_int("--runs", args.runs, minimum=2)
    if args.figures is not None:
        from ..slides import check_directory, check_targets, use_agg_backend

        # before the Monte Carlo, not after it
        check_targets(check_directory(args.figures, "--figures"), FIGURE_FILES, argname="--figures")
        use_agg_backend()
    params = _params(args)
    # before anything of the scenario's size is allocated: refuse what cannot fit or would take hours, and
    # check the 200 Hz error between fixes when it fits (the same checks in the table and in the JSON)
    between, skipped = plan_between_fixes(
        params, args.runs, args.engine, figures=args.figures is not None,
        params_name="--duration, --imu-rate, --gps-rate" + (", --figures" if args.figures else ""))
    windows = [parse_outage(text, "--outage") for text in args.outage]
    missing = outage_mask(params, windows, name="--outage") if windows else None
    for start, end in windows:  # a window between two fixes would change nothing: say so, not run silently
        if not outage_mask(params, [(start, end)], name="--outage").any():
            raise ValueError(f"--outage: the window {start:g}:{end:g} s removes no GPS fix (the fixes are "
                             f"{1 / params.gps_rate:g} s apart, the first at 0 s)")
    if missing is not None and (~missing).sum() < 2:
        raise ValueError(f"--outage: the outages leave {int((~missing).sum())} of the {params.n_gps} GPS fixes; "
                         f"at least 2 must remain")
    mc = run_monte_carlo(params, args.runs, args.seed, engine=args.engine, truth=args.truth, progress=None,
                         missing_fixes=missing, between_fixes=between,
                         extra_bytes=output_bytes(params, args.figures is not None, between))
    written = write_figures(mc, args.figures, seed=args.seed) if args.figures else []
    checks = mc.all_checks()
    if args.json:
        d = result_to_dict(mc, windows, checks, skipped)
        del checks
        if written:
            d["figures"] = [str(p) for p in written]
        print(dumps_json(d))
        return 0
    s, es = mc.sigma_final, mc.ensemble_sigma_final
    print(f"{mc.n_runs} realizations, filter {mc.filter}, engine {mc.engine}, truth {mc.truth}, {mc.seconds:.2f} s")
    print(f"sigma at the last fix from P:        p {s[0]:.4g} m, v {s[1]:.4g} m/s, b {s[2]:.4g} m/s^2")
    print(f"sigma at the last fix from ensemble: p {es[0]:.4g} m, v {es[1]:.4g} m/s, b {es[2]:.4g} m/s^2")
    print(format_checks(checks))
    for name, reason in skipped.items():
        print(f"{name}: {reason}")
    print(COLUMNS_LEGEND)
    if mc.truth == "analytic" and not all(c.passed for c in checks.values()):
        print(MISMATCH_NOTE)
    for p in written:
        print(f"wrote {path_text(p)}")
    return 0
