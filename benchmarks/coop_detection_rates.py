"""Write the stored detection-rate table of notebook 14's coop power section (run: python benchmarks/coop_detection_rates.py).

For every case of ``kfcal_helpers.coop.power.CASES`` (the correct EKF first: its rate is the false-alarm
rate; the EKF with Q = 0.1, 0.3, 3, 10 Qtrue; the other coop rows of notebook 14) and every N in
``DEFAULT_N_RUNS`` (5, 10, 20, 50), ``REPS`` repeated truth-model tests, seed ``SEED``:
``kfcal_helpers.coop.power.detection_rates``, written to ``kfcal_helpers/coop/detection_rates.csv`` after
each N (a partial table is a valid table of the N values done so far; the repetitions' seeds depend only
on (SEED, N, repetition)).  ``tests/test_coop_power.py`` recomputes a subset of it and checks it.  Cost:
9 x 4 x 100 = 3,600 truth-model tests, filtered 500 runs at a time (several repetitions together) when the
stored table was made: 330 s of CPU time on one thread (N = 5, 10, 20: 184 s; N = 50: 145 s, peak memory
478 MB, too near the 500 MB promise, so batches are now at most 250 runs; the results do not depend on it), 34 minutes under a load average of 7 to 9.  The load average, the wall time and this process's CPU time are printed
after each N.
"""

from __future__ import annotations

import argparse

from kfcal_helpers.coop.power import DEFAULT_N_RUNS, STORED_CSV, detection_rates
from kfcal_helpers.power import write_by_n

REPS, SEED = 100, 2026


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=REPS, help=f"repetitions per (case, N), default {REPS}")
    parser.add_argument("--out", default=str(STORED_CSV), help="CSV to write (default: the stored table)")
    args = parser.parse_args(argv)
    write_by_n(lambda n: detection_rates(n_runs=[n], reps=args.reps, seed=SEED), DEFAULT_N_RUNS, args.out,
               log=lambda line: print(line, flush=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
