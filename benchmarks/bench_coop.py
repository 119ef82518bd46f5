"""Benchmark of the cooperative-localization truth-model tests (run: python benchmarks/bench_coop.py).

Measures in one run, on the course's scenario (1001 samples of 0.1 s):
* the three 50-run truth-model tests (LKF, EKF, UKF: simulation, batched filter, per-run arrays) on
  the default thread pool (``KFCAL_WORKERS``, else ``min(2, os.cpu_count())``), best of 3 wall times
  each, and their sum;
* a 1000-run EKF truth-model test (best of 2);
* the cost per run of the per-run filterpy path (one filterpy filter per run on one thread, on the
  same draws, :func:`kfcal_helpers.coop.truth_model_draws`), and the speed-up of the batched tests
  against it.
Targets (2-core machine): the three 50-run tests together in at most 3 s, the 1000-run EKF test in
at most 10 s.  Prints every number and PASS or FAIL per target; exit status 1 if a target is missed.
Other work on the machine slows the timings: the load average is printed with them.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("KFCAL_QUIET", "1")

from kfcal_helpers.coop import FILTERS, CoopParams, run, truth_model_draws, truth_model_test  # noqa: E402
from kfcal_helpers.coop.filters import FilterSetup  # noqa: E402
from kfcal_helpers.montecarlo import default_workers  # noqa: E402

TARGET_THREE_50, TARGET_EKF_1000 = 3.0, 10.0


def _peak_mb() -> str:
    """This process's peak resident memory, where the OS reports it."""
    try:
        import resource
    except ImportError:  # Windows
        return "not reported on this OS"
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return f"{rss / 1e6 if sys.platform == 'darwin' else rss * 1024 / 1e6:.0f} MB"  # bytes on macOS, KiB on Linux


def _load() -> str:
    """The 1-minute load average, where the OS reports it."""
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except (AttributeError, OSError):  # Windows
        return "n/a"


def _best(fn, repeat):
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50, help="runs of each of the three tests (default 50)")
    ap.add_argument("--big", type=int, default=1000, help="runs of the EKF test (default 1000)")
    ap.add_argument("--filterpy-runs", type=int, default=6, help="runs timed on the filterpy path (default 6)")
    args = ap.parse_args(argv)
    p = CoopParams()
    workers = default_workers()
    load_before = _load()
    print(f"cooperative localization, {p.n_samples} samples of {p.dt:g} s, {os.cpu_count()} CPUs, "
          f"{workers} thread(s)")
    truth_model_test(p, 4, 0, filter="ukf")  # warm-up: imports, page faults
    print(f"{'filter':<6}  {f'{args.runs}-run test [s]':>16}  {'filterpy per run [s]':>20}  {'speed-up':>8}  "
          f"{'NEES inside':>11}  {'NIS inside':>10}")
    total = total_fp = 0.0
    sim = truth_model_draws(p, args.runs, 1)
    for name in FILTERS:
        t_mc, mc = _best(lambda: truth_model_test(p, args.runs, 1, filter=name), 3)
        setup = FilterSetup.build(name, p)
        t0 = time.perf_counter()
        for i in range(args.filterpy_runs):
            run(sim.y[i], setup, sim.truth[i])
        per_fp = (time.perf_counter() - t0) / args.filterpy_runs
        total += t_mc
        total_fp += per_fp * args.runs
        print(f"{name.upper():<6}  {t_mc:16.2f}  {per_fp:20.3f}  {per_fp * args.runs / t_mc:7.0f}x  "
              f"{mc.nees_inside_fraction:11.3f}  {mc.nis_inside_fraction:10.3f}")
    ok_three = total <= TARGET_THREE_50
    print(f"the three {args.runs}-run tests: {total:.2f} s (filterpy per run, one thread: {total_fp:.1f} s, "
          f"{total_fp / total:.0f}x) -- target <= {TARGET_THREE_50:g} s: {'PASS' if ok_three else 'FAIL'}")
    t_big, big = _best(lambda: truth_model_test(p, args.big, 2, filter="ekf"), 2)
    ok_big = t_big <= TARGET_EKF_1000
    print(f"{args.big}-run EKF test: {t_big:.2f} s ({t_big / args.big * 1e3:.1f} ms per run; NEES inside "
          f"{big.nees_inside_fraction:.3f}) -- target <= {TARGET_EKF_1000:g} s: {'PASS' if ok_big else 'FAIL'}")
    print(f"peak memory (max RSS) {_peak_mb()}; load average {load_before} before, {_load()} after")
    return 0 if ok_three and ok_big else 1


if __name__ == "__main__":
    sys.exit(main())
