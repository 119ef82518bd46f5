"""Sub-command ``orbit``: run a filter on an orbit observation log, or a truth-model Monte Carlo.

Examples::

    python -m kfcal_helpers orbit --filter ekf                  # the generated (seeded) log
    python -m kfcal_helpers orbit --filter ukf --log orbitdeterm_finalproj_KFdata.mat
    python -m kfcal_helpers orbit --filter ekf --runs 50 --json

On a log it prints the NIS of the run: its sum over the steps with a station against the chi-square
bounds of the dof present (3 per station measured), as the NIS per dof; and the time-averaged NEES when
the truth is known (the generated log).  A truth-model Monte Carlo (``--runs N``) prints the checks of
:meth:`~kfcal_helpers.orbit.montecarlo.MonteCarloResult.checks` (the run mean of the error, and the NEES
and NIS per step with the dof present) as a table or as JSON; it keeps 88 bytes per run and step (1401
steps), and one that would need more than 500 MB or an hour is refused with its estimate before it starts.
"""

from __future__ import annotations

import time

import numpy as np
from scipy import stats

from .. import montecarlo as core
from ..consistency import format_checks
from ..output import print_summary
from ..validation import MAX_SEED, MIN_ALPHA, check_every_option, cli_float, cli_int, require_int
from .data import load_log, log_params
from .filters import FILTERS, FilterSetup, run_filter
from .montecarlo import OrbitExperiment, truth_model_test
from .params import OrbitParams
from .simulation import DEFAULT_LOG_SEED, OrbitLog, simulate

__all__ = ["add_parser", "run", "log_summary", "every_log", "estimate_truth_model_test", "OUTPUT_BYTES",
           "MAX_RUNS"]

#: most runs of ``--runs``
MAX_RUNS = 10000
#: bytes the table or the JSON needs on top of the Monte Carlo's result (the checks' arrays are counted by
#: the experiment's final phase; this is the text), rounded up
OUTPUT_BYTES = 2e6


def add_parser(subparsers):
    """Register ``orbit`` on an argparse sub-parsers object."""
    p = subparsers.add_parser("orbit", help="orbit determination: LKF/EKF/UKF on a log or a truth-model Monte Carlo",
                              description=__doc__.splitlines()[0])
    p.add_argument("--filter", choices=FILTERS, default="ekf", help="which filter (default ekf)")
    p.add_argument("--log", metavar="PATH", help="the course's .mat log or a CSV folder (default: the generated log)")
    p.add_argument("--runs", type=cli_int(2, MAX_RUNS), metavar="N",
                   help=f"run an N-run truth-model Monte Carlo instead of a log (2 to {MAX_RUNS})")
    p.add_argument("--seed", type=cli_int(0, MAX_SEED), default=None,
                   help=f"seed of the generated log (default {DEFAULT_LOG_SEED}) or of the Monte Carlo (default 0)")
    p.add_argument("--every", type=cli_int(1), default=1, metavar="M",
                   help="use the measurements of every M-th step only")
    p.add_argument("--alpha", type=cli_float(MIN_ALPHA, 0.5, lower_open=False), default=0.05,
                   help="significance of the chi-square tests (default 0.05)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)
    return p


def every_log(log: OrbitLog, every: int) -> OrbitLog:
    """A copy of ``log`` that keeps the station measurements of every ``every``-th step (k = 0, M, 2M, ...)."""
    every = require_int("every", every, minimum=1)
    blocks = tuple(b if k % every == 0 else np.empty((4, 0)) for k, b in enumerate(log.ydata))
    return OrbitLog(log.t, blocks, log.Qtrue, log.Rtrue, log.n_stations, log.truth,
                    log.source if every == 1 else f"{log.source} (every {every})")


def log_summary(result, alpha: float = 0.05) -> dict:
    """The NIS of one filter run on a log: ``nis_sum`` over the steps with a station (``updates``), ``nis_dof``
    the dof present there (3 per station), ``nis_per_dof = nis_sum / nis_dof`` with its two-sided chi-square
    bounds ``chi2.ppf(alpha/2, D) / D``, ``chi2.ppf(1 - alpha/2, D) / D`` (a consistent filter's innovations
    are independent, so their NIS add up to chi-square with the summed dof); and ``nees_time_average`` when
    the truth is known (without bounds: one run's errors are correlated from step to step)."""
    has = result.dof > 0
    if not has.any():
        raise ValueError("log: it holds no measurement (no step has a station)")
    dof = int(result.dof[has].sum())
    total = float(result.nis[has].sum())
    lo, hi = (float(v) / dof for v in stats.chi2.ppf([alpha / 2, 1 - alpha / 2], dof))
    out = {"updates": int(has.sum()), "nis_dof": dof, "nis_sum": total, "nis_per_dof": total / dof,
           "nis_bounds": [lo, hi], "nis_inside": bool(lo <= total / dof <= hi)}
    if result.nees is not None:
        out["nees_time_average"] = float(result.nees.mean())
    return out


def estimate_truth_model_test(params: OrbitParams | None, n_runs: int, *, filter: str = "ekf", every: int = 1,
                              workers: int | None = None, runs_name: str = "n_runs",
                              extra_bytes: float = 0.0) -> core.Estimate:
    """The memory and time estimate of :func:`~kfcal_helpers.orbit.montecarlo.truth_model_test` with these
    arguments, before it runs (:func:`kfcal_helpers.montecarlo.estimate`): ValueError naming ``runs_name``
    when the test would need more than 500 MB or more than an hour."""
    exp = OrbitExperiment(FilterSetup(filter, params), every=every)
    return core.estimate(exp, n_runs, workers, extra_bytes=extra_bytes, runs_name=runs_name)


def _monte_carlo(args, every: int) -> tuple[dict, str]:
    if args.log is not None:
        raise ValueError("--runs: a truth-model Monte Carlo simulates its own data; do not give --log with it")
    runs = require_int("--runs", args.runs, minimum=2)
    params = OrbitParams()
    check_every_option(every, params.n_samples, "the truth model has")
    # refused before any work (one line, exit 2) when it would exceed 500 MB or an hour
    estimate_truth_model_test(params, runs, filter=args.filter, every=every, runs_name="--runs",
                              extra_bytes=OUTPUT_BYTES)
    mc = truth_model_test(params, runs, 0 if args.seed is None else args.seed, filter=args.filter,
                          alpha=args.alpha, every=every)
    checks = mc.checks()
    out = {"filter": mc.filter, "n_runs": mc.n_runs, "steps": int(mc.t.size), "alpha": mc.alpha, "every": every,
           "passed": all(c.passed for c in checks.values()),
           "checks": {name: {"inside_fraction": c.inside_fraction, "worst": c.worst, "passed": c.passed}
                      for name, c in checks.items()}}
    return out, format_checks(checks)


def _on_log(args, every: int) -> dict:
    if args.log is not None:
        log = load_log(args.log, argname="--log")
    else:
        log = simulate(seed=DEFAULT_LOG_SEED if args.seed is None else args.seed).log()
    if every > 1:
        check_every_option(every, len(log.ydata), "the log has")
        log = every_log(log, every)
        if not log.dof.any():
            raise ValueError(f"--every {every} keeps no measurement of this log (the steps it keeps have no station)")
    params = log_params(log)
    result = run_filter(args.filter, log.y, params, truth=log.truth)
    if not np.all(np.isfinite(result.x_post)):
        raise ValueError(f"log: the {args.filter.upper()} diverged (non-finite estimate)")
    return {"filter": args.filter, "steps": len(log.ydata), "source": log.source, "every": every,
            **log_summary(result, args.alpha)}


def run(args) -> int:
    """Run the sub-command; returns the exit code (ValueError for bad input)."""
    every = require_int("--every", args.every, minimum=1)
    t0 = time.perf_counter()
    table = None
    if args.runs is not None:
        out, table = _monte_carlo(args, every)
    else:
        out = _on_log(args, every)
    out["seconds"] = time.perf_counter() - t0
    if args.json or table is None:
        print_summary(out, args.json)
    else:
        print_summary({k: v for k, v in out.items() if k != "checks"}, tail=table)
    return 0
