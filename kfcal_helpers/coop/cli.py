"""Sub-command ``coop``: run a filter on an observation log, or a truth-model Monte Carlo.

Examples::

    python -m kfcal_helpers coop --filter ekf                   # the generated (seeded) log
    python -m kfcal_helpers coop --filter ukf --log ../shared/data/coop_localization
    python -m kfcal_helpers coop --filter lkf --runs 50 --seed 1 --json

A truth-model Monte Carlo (``--runs N``) keeps per-run arrays of 112 kB per run of 1001 steps; one
that would need more than 500 MB (about 2,300 runs of 100 s) is refused with its estimate.

The filter's process noise is ``Q = S * Qtrue`` (covariance of the DT noise ``w_k``, a rate noise held
over each step, which enters the state through ``Omega = dt * I``: ``dt^2 Q`` per step).  By default S is the filter's scale tuned by the truth-model
tests (``TUNED_Q_SCALE``, ``q_scale_source: "truth-model test"``), for a course log too: the NIS
reported on the log is then a test of that Q.  ``--q-scale auto`` (opt-in) instead fits S to the
log: the maximum-likelihood scale of ``Q_SCALE_LADDER``, reported with the range of ladder scales
whose NIS falls inside the bounds; that is a fit, not a test.
"""

from __future__ import annotations

import time

import numpy as np

from ..output import print_summary
from ..validation import MAX_SEED, MIN_ALPHA, check_every_option, cli_float, cli_int, require_int, require_positive
from .data import load_log
from .filters import FILTERS, TUNED_Q_SCALE, fit_q_scale, log_summary, run_filter
from .model import CoopParams
from .montecarlo import estimate_truth_model_test, truth_model_test
from .simulation import DEFAULT_LOG_SEED, simulate

__all__ = ["add_parser", "run", "log_summary", "Q_SCALE_LADDER", "parse_q_scale", "SOURCE_TEST", "SOURCE_FIT",
           "SOURCE_GIVEN"]

#: candidate scales S of Q = S * Qtrue for ``--q-scale auto`` (a 1-2-5 ladder)
Q_SCALE_LADDER = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)

#: the values of ``q_scale_source``
SOURCE_TEST = "truth-model test"
SOURCE_FIT = "fit to this log (maximum likelihood over the ladder), not a test"
SOURCE_GIVEN = "given"


#: the range of a given --q-scale (beyond it the filters' covariances lose precision)
Q_SCALE_RANGE = (1e-6, 1e6)


def parse_q_scale(text):
    """``None`` (the default), ``"auto"`` or a number in Q_SCALE_RANGE; raise ValueError otherwise."""
    if text is None or text == "auto":
        return text
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"--q-scale must be a positive number or 'auto', got {text!r}") from None
    value = require_positive("--q-scale", value)
    if not Q_SCALE_RANGE[0] <= value <= Q_SCALE_RANGE[1]:
        raise ValueError(f"--q-scale must be from {Q_SCALE_RANGE[0]:g} to {Q_SCALE_RANGE[1]:g} or 'auto', got {text}")
    return value


def add_parser(subparsers):
    """Register ``coop`` on an argparse sub-parsers object."""
    p = subparsers.add_parser("coop", help="cooperative localization: LKF/EKF/UKF on a log or a truth-model Monte Carlo",
                              description=__doc__.splitlines()[0])
    p.add_argument("--filter", choices=FILTERS, default="ekf", help="which filter (default ekf)")
    p.add_argument("--log", metavar="PATH", help="course log: a folder of CSVs or a .mat (default: the generated log)")
    p.add_argument("--runs", type=cli_int(1, 10000), metavar="N", help="run an N-run truth-model Monte Carlo instead of a log (1 to 10000)")
    p.add_argument("--seed", type=cli_int(0, MAX_SEED), default=None,
                   help=f"seed of the generated log (default {DEFAULT_LOG_SEED}) or of the Monte Carlo (default 0)")
    p.add_argument("--q-scale", default=None, metavar="S",
                   help="filter Q = S * Qtrue: a number from 1e-6 to 1e6, or 'auto' to fit S to the log by maximum "
                        "likelihood over a ladder (a fit, not a test; default: the filter's truth-model-tuned scale)")
    p.add_argument("--every", type=cli_int(1), default=1, metavar="M", help="use the measurements of every M-th step only")
    p.add_argument("--alpha", type=cli_float(MIN_ALPHA, 0.5, lower_open=False), default=0.05, help="significance of the chi-square tests (default 0.05)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)
    return p


def run(args) -> int:
    """Run the sub-command; returns the exit code (ValueError for bad input)."""
    every = require_int("--every", args.every, minimum=1)
    q_scale = parse_q_scale(args.q_scale)
    t0 = time.perf_counter()
    if args.runs is not None:
        if args.log is not None:
            raise ValueError("--runs: a truth-model Monte Carlo simulates its own data; do not give --log with it")
        runs = require_int("--runs", args.runs, minimum=1)
        if q_scale == "auto":
            raise ValueError("q-scale 'auto' fits Q to a log; a truth-model Monte Carlo needs a number or the default")
        params = CoopParams()
        check_every_option(every, params.n_samples, "the truth model has")
        scale = TUNED_Q_SCALE[args.filter] if q_scale is None else q_scale
        # refused before any work (one line, exit 2) when the per-run arrays would exceed 500 MB
        estimate_truth_model_test(params, runs, filter=args.filter, every=every, runs_name="--runs",
                                  Q=scale * params.Qtrue)
        mc = truth_model_test(params, runs, 0 if args.seed is None else args.seed, filter=args.filter,
                              alpha=args.alpha, every=every, Q=scale * params.Qtrue)
        out = mc.summary()
        out["q_scale"] = scale
        out["q_scale_source"] = SOURCE_TEST if q_scale is None else SOURCE_GIVEN
    else:
        if args.log is not None:
            log = load_log(args.log, argname="--log")
        else:
            log = simulate(seed=DEFAULT_LOG_SEED if args.seed is None else args.seed).log()
        if every > 1:
            check_every_option(every, log.n_samples, "the log has")
            log = log.every(every)
            if not np.isfinite(log.y).any():
                raise ValueError(f"--every {every} keeps no measurement of this log (the steps it keeps are NaN)")
        params = log.params()
        fit = None
        if q_scale == "auto":
            fit = fit_q_scale(args.filter, log.y, Q_SCALE_LADDER, params, alpha=args.alpha)
            scale, source = fit.best, SOURCE_FIT
        elif q_scale is None:
            scale, source = TUNED_Q_SCALE[args.filter], SOURCE_TEST
        else:
            scale, source = q_scale, SOURCE_GIVEN
        result = run_filter(args.filter, log.y, params, Q=scale * params.Qtrue, truth=log.truth)
        if not np.all(np.isfinite(result.x)):
            raise ValueError(f"log: the {args.filter.upper()} diverged (non-finite estimate)")
        out = {"filter": args.filter, "steps": int(log.n_samples), "source": log.source, "q_scale": scale,
               "q_scale_source": source, "every": every, **log_summary(result, args.alpha)}
        if fit is not None:
            inside = fit.inside
            out["fit_ladder"] = [float(s) for s in fit.scales]
            out["fit_log_likelihood"] = [float(v) for v in fit.log_likelihood]
            out["fit_nis_time_average"] = [float(v) for v in fit.nis_averages]
            out["fit_scales_inside_nis_bounds"] = ([float(inside.min()), float(inside.max())] if inside.size
                                                   else [])
    out["seconds"] = time.perf_counter() - t0
    print_summary(out, args.json)
    return 0
