"""Benchmark of the orbit-determination truth-model tests (run: python benchmarks/bench_orbit.py).

Measures in one run, on the course's scenario (1401 samples of 10 s):
* the three 50-run truth-model tests (LKF, EKF, UKF: truth simulation, measurements, batched filter, the
  per-run arrays) on the default thread pool, best of ``--repeat`` wall times each, and their sum, for
  the truth integrated by ``solve_ivp`` (the default) and by the vectorised RK4 (``integrator="rk4"``);
* a 1000-run EKF truth-model test with each integrator (one timing each);
* the cost per run of the per-run filterpy filters on the same draws, and the batch's speed-up.
Targets (2-core machine): the three 50-run tests together in at most 3 s, the 1000-run EKF test in at most
15 s, each judged on the tests' default integrator (RK4).  Prints every number, the load average and PASS or FAIL per
target; exit status 1 if a target is missed.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("KFCAL_QUIET", "1")

from kfcal_helpers import montecarlo as core  # noqa: E402
from kfcal_helpers.orbit import FILTERS, FilterSetup, OrbitParams, run, simulate  # noqa: E402
from kfcal_helpers.orbit.montecarlo import CHUNK_SIZE, truth_model_test  # noqa: E402

TARGETS = {"three 50-run tests": 3.0, "1000-run EKF test": 15.0}


def timed(fn, repeat: int = 1):
    """(best wall time over ``repeat`` calls, the last result)."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return min(times), result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50, help="runs of each of the three tests (default 50)")
    ap.add_argument("--big", type=int, default=1000, help="runs of the EKF test (default 1000)")
    ap.add_argument("--repeat", type=int, default=2, help="timings of each small test, best kept (default 2)")
    ap.add_argument("--filterpy-runs", type=int, default=2, help="runs timed on the filterpy path (default 2)")
    args = ap.parse_args(argv)
    p = OrbitParams()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"orbit determination, {p.n_samples} samples of {p.dt:g} s, {os.cpu_count()} CPUs, "
          f"{core.default_workers()} thread(s), load average {load:.2f}")
    truth_model_test(replace_steps(p, 20), 4, 0, filter="ukf")  # warm-up: imports, page faults
    (size, rng), = core.chunk_generators(CHUNK_SIZE, min(args.runs, CHUNK_SIZE), 1)[:1]
    draws = simulate(p, size, rng)
    filterpy_s = {}
    for name in FILTERS:
        setup = FilterSetup(name, p)
        filterpy_s[name], _ = timed(lambda: [run(draws.y[i], setup, draws.truth[i]) for i in range(args.filterpy_runs)])
        filterpy_s[name] /= args.filterpy_runs
    verdicts = []
    for integrator in ("rk4", "solve_ivp"):
        print(f"\ntruth integrated by {integrator}")
        print(f"{'filter':<6} {f'{args.runs}-run test [s]':>16} {'filterpy per run [s]':>21} {'speed-up':>9} "
              f"{'NEES':>5} {'NIS':>5}")
        total = 0.0
        for name in FILTERS:
            seconds, r = timed(lambda: truth_model_test(p, args.runs, 1, filter=name, integrator=integrator),
                               args.repeat)
            total += seconds
            c = r.checks()
            print(f"{name.upper():<6} {seconds:16.2f} {filterpy_s[name]:21.3f} "
                  f"{filterpy_s[name] * args.runs / seconds:8.0f}x {verdict(c['nees']):>5} {verdict(c['nis']):>5}")
        big, r = timed(lambda: truth_model_test(p, args.big, 2, filter="ekf", integrator=integrator))
        print(f"the three {args.runs}-run tests: {total:.2f} s; {args.big}-run EKF test: {big:.2f} s "
              f"({big / args.big * 1e3:.1f} ms per run; NEES check {verdict(r.checks()['nees'])})")
        if integrator == "rk4":
            verdicts = [("three 50-run tests", total), ("1000-run EKF test", big)]
    print()
    ok = True
    for what, seconds in verdicts:
        passed = seconds <= TARGETS[what]
        ok &= passed
        print(f"{what} (RK4 truth): {seconds:.2f} s, target <= {TARGETS[what]:g} s: {'PASS' if passed else 'FAIL'}")
    after = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average {load:.2f} before, {after:.2f} after")
    return 0 if ok else 1


def verdict(check) -> str:
    return "pass" if check.passed else "FAIL"


def replace_steps(p, n_steps):
    from dataclasses import replace
    return replace(p, n_steps=n_steps)


if __name__ == "__main__":
    sys.exit(main())
