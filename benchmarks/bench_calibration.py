"""Benchmark of the calibration Monte Carlo (run: python benchmarks/bench_calibration.py).

Measures in one run, on the default scenario (200 Hz, 5 Hz, 30 s):
* the full Monte Carlo (200 Hz simulation + filter + all checks) with 10,000
  realizations on the batch engine, wall time and peak memory (max RSS of this process);
* the cost per realization of the filterpy engine (one KalmanFilter per realization);
* their ratio.
Targets (2-core machine): 10,000 realizations in at most 2 s, at least 100x less time per
realization than filterpy, peak memory at most 500 MB.  Exit status 1 if a target is missed.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys

from kfcal_helpers.calibration import run_monte_carlo


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10_000, help="batch realizations (default 10000)")
    ap.add_argument("--filterpy-runs", type=int, default=40, help="filterpy realizations (default 40)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    run_monte_carlo(n_runs=50, seed=0)  # warm-up: imports, page faults
    batch = min((run_monte_carlo(n_runs=args.runs, seed=s) for s in (1, 2, 3)), key=lambda r: r.seconds)
    fp = run_monte_carlo(n_runs=args.filterpy_runs, seed=4, engine="filterpy")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    per_batch = batch.seconds / batch.n_runs
    per_fp = fp.seconds / fp.n_runs
    out = {
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
        "batch_runs": batch.n_runs,
        "batch_seconds_best_of_3": round(batch.seconds, 3),
        "batch_ms_per_realization": round(1e3 * per_batch, 4),
        "filterpy_runs": fp.n_runs,
        "filterpy_ms_per_realization": round(1e3 * per_fp, 2),
        "speedup_per_realization": round(per_fp / per_batch, 1),
        "peak_rss_mb": round(peak_mb, 1),
    }
    targets = {
        "10k realizations <= 2 s": batch.seconds <= 2.0 * batch.n_runs / 10_000,
        "speed-up >= 100x": per_fp / per_batch >= 100,
        "peak memory <= 500 MB": peak_mb <= 500,
    }
    if args.json:
        print(json.dumps({**out, "targets_met": targets}))
    else:
        for k, v in out.items():
            print(f"{k:>28}: {v}")
        for k, ok in targets.items():
            print(f"{'target':>28}: {k}: {'met' if ok else 'MISSED'}")
    return 0 if all(targets.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
