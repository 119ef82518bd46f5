"""Benchmark of the cooperative-localization filters.

Run: ``python benchmarks/bench_coop.py [--runs 50] [--workers N]``

Prints the per-step cost of one filterpy run of each filter (LKF, EKF, UKF) on the
project's 1001-sample log, the cost of the closed-form truth simulation, and the wall
time of an N-run truth-model Monte Carlo for each filter (target: the three 50-run
Monte Carlos together in at most 30 s on a 2-core machine).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("KFCAL_QUIET", "1")

from kfcal_helpers.coop import FILTERS, CoopParams, run_filter, simulate, simulate_truth, truth_model_test  # noqa: E402
from kfcal_helpers.coop.montecarlo import default_workers  # noqa: E402


def _best_of(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--workers", type=int, default=None, help=f"processes (default {default_workers()})")
    ap.add_argument("--repeat", type=int, default=3, help="repetitions of the single-run timings (best kept)")
    args = ap.parse_args(argv)
    p = CoopParams()
    log = simulate(p).log()
    steps = log.n_samples - 1
    workers = args.workers or default_workers()
    print(f"cooperative localization, {steps} steps of {p.dt:g} s, {os.cpu_count()} CPUs, {workers} worker(s)")
    t_sim = _best_of(lambda: simulate_truth(p, 0, n_runs=args.runs), args.repeat)
    print(f"truth simulation (closed-form step, vectorised): {args.runs} runs in {t_sim * 1e3:.1f} ms "
          f"({t_sim / (args.runs * steps) * 1e6:.2f} us per run-step)")
    print(f"{'filter':<6}  {'per step [us]':>13}  {'one run [s]':>11}  {f'{args.runs}-run MC [s]':>14}  "
          f"{'NEES inside':>11}  {'NIS inside':>10}")
    total = 0.0
    for name in FILTERS:
        t_run = _best_of(lambda: run_filter(name, log.y, p), args.repeat)
        t0 = time.perf_counter()
        mc = truth_model_test(p, args.runs, 0, filter=name, workers=workers)
        t_mc = time.perf_counter() - t0
        total += t_mc
        print(f"{name.upper():<6}  {t_run / steps * 1e6:13.0f}  {t_run:11.3f}  {t_mc:14.2f}  "
              f"{mc.nees_inside_fraction:11.3f}  {mc.nis_inside_fraction:10.3f}")
    verdict = "within" if total <= 30.0 else "ABOVE"
    print(f"all three {args.runs}-run Monte Carlos: {total:.1f} s ({verdict} the 30 s target)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
