"""``python -m kfcal_helpers calibrate``: the default scenario's Monte Carlo check table."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from ..validation import require_int
from .montecarlo import CHECK_NAMES, ENGINES, format_checks, run_monte_carlo
from .outages import outage_mask, parse_outage
from .params import CalibrationParams
from .simulation import TRUTH_MODELS

__all__ = ["add_parser", "run", "result_to_dict"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    d = CalibrationParams()
    p = subparsers.add_parser("calibrate", help="Monte Carlo of the accelerometer-calibration filter",
                              description="Simulate, filter and check the accelerometer calibration "
                                          "(SPEC defaults unless given).")
    p.add_argument("--runs", type=int, default=1000, help="realizations, at least 2 (default 1000)")
    p.add_argument("--seed", type=int, default=0, help="seed of numpy.random.default_rng (default 0)")
    p.add_argument("--engine", choices=ENGINES, default="batch", help="batch (fast) or filterpy (one filter per run)")
    p.add_argument("--omega", type=float, default=d.omega, help=f"rad/s (default {d.omega:g})")
    p.add_argument("--imu-rate", type=float, default=d.imu_rate, help=f"Hz (default {d.imu_rate:g})")
    p.add_argument("--gps-rate", type=float, default=d.gps_rate, help=f"Hz, divides the IMU rate (default {d.gps_rate:g})")
    p.add_argument("--duration", type=float, default=d.duration, help=f"s (default {d.duration:g})")
    p.add_argument("--truth", choices=TRUTH_MODELS, default="euler", help="truth model (default euler)")
    p.add_argument("--outage", action="append", default=[], metavar="START:END",
                   help="GPS outage in seconds, fixes with START <= t < END are missing (repeatable)")
    p.add_argument("--figures", metavar="DIR", help="also write the notebook-5 and notebook-6 figures as PNG")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.set_defaults(run=run)
    return p


def result_to_dict(mc) -> dict:
    """The JSON summary of a MonteCarloResult."""
    checks = mc.checks()
    out = {
        "runs": mc.n_runs,
        "engine": mc.engine,
        "truth": mc.truth,
        "seconds": mc.seconds,
        "alpha": mc.alpha,
        "sigma_final": mc.sigma_final.tolist(),
        "ensemble_sigma_final": mc.ensemble_sigma_final.tolist(),
        "checks": {},
    }
    for name in CHECK_NAMES:
        c = checks[name]
        entry = {"inside_fraction": c.inside_fraction, "worst": c.worst, "passed": c.passed}
        if name in ("nees", "nis"):
            entry["bounds"] = list(mc.nees_bounds if name == "nees" else mc.nis_bounds)
        out["checks"][name] = entry
    return out


def write_figures(mc, directory) -> list[Path]:
    """Write the notebook-5 (one realization) and notebook-6 (checks) figures as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .filters import run_filterpy
    from .plots import plot_checks, plot_covariance_sawtooth, plot_estimate_errors
    from .simulation import simulate

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    sim = simulate(mc.params, 1, np.random.default_rng(0), truth=mc.truth)
    fr = run_filterpy(mc.params, sim.dz[0])
    written = []
    for name, fig in (("calibration_errors.png", plot_estimate_errors(mc.params, sim.dx[0], fr)),
                      ("calibration_sigma_sawtooth.png", plot_covariance_sawtooth(mc.params, fr)),
                      ("calibration_checks.png", plot_checks(mc))):
        path = directory / name
        fig.savefig(path, dpi=150)
        plt.close(fig)
        written.append(path)
    return written


def run(args) -> int:
    require_int("--runs", args.runs, minimum=2)
    params = CalibrationParams(omega=args.omega, imu_rate=args.imu_rate, gps_rate=args.gps_rate,
                               duration=args.duration)
    windows = [parse_outage(text, "--outage") for text in args.outage]
    missing = outage_mask(params, windows, name="--outage") if windows else None
    mc = run_monte_carlo(params, n_runs=args.runs, seed=args.seed, engine=args.engine,
                         truth=args.truth, progress=None, missing_fixes=missing)
    written = write_figures(mc, args.figures) if args.figures else []
    if args.json:
        d = result_to_dict(mc)
        if written:
            d["figures"] = [str(p) for p in written]
        print(json.dumps(d))
        return 0
    s, es = mc.sigma_final, mc.ensemble_sigma_final
    print(f"{mc.n_runs} realizations, engine {mc.engine}, truth {mc.truth}, {mc.seconds:.2f} s")
    print(f"sigma at the last fix from P:        p {s[0]:.4g} m, v {s[1]:.4g} m/s, b {s[2]:.4g} m/s^2")
    print(f"sigma at the last fix from ensemble: p {es[0]:.4g} m, v {es[1]:.4g} m/s, b {es[2]:.4g} m/s^2")
    print(format_checks(mc))
    for p in written:
        print(f"wrote {p}")
    return 0
