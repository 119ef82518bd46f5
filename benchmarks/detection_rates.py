"""Write the stored detection-rate tables of notebook 06b (run: python benchmarks/detection_rates.py).

For every calibration mistake of notebook 14 (the correct filter first: its rate is the false-alarm
rate) and every N in ``DEFAULT_N_RUNS`` (10 ... 1000), ``REPS`` repeated Monte Carlos on the batch
path, seed ``SEED``: ``kfcal_helpers.calibration.power.detection_rates``.  ``--checks all`` (the default)
judges each Monte Carlo by the seven checks and writes ``kfcal_helpers/calibration/detection_rates.csv``.
The stored table of the assignment's four checks alone (``alpha`` split over them), for the correct filter
and the two mistakes that the seven checks do not catch in every Monte Carlo at N = 10, up to N = 640, is

    python benchmarks/detection_rates.py --checks assignment --mistakes correct phi02_sign w_is_gps_velocity_var \
        --n-runs 10 20 40 80 160 320 640

written to ``kfcal_helpers/calibration/detection_rates_assignment.csv``.  The same seeds, so the same Monte
Carlos, for both.  The table is written after each N (a partial table is a valid table of the N values done
so far; the repetitions' seeds depend only on (SEED, N, repetition)).  ``tests/test_calibration_power.py``
recomputes a subset of each and checks it.  Cost of the seven checks' table: 7 x 8 x 200 = 11,200 Monte
Carlos, about 50 ms each plus 0.1 ms per realization on an idle core (about 15 minutes); it took 33 minutes
on a 2-core machine under a load average of 3 to 11.  The four checks' table took 140 s of CPU time (15 minutes
under a load average of 7 to 9).  Rerun for the one Bonferroni policy on 2026-12-04 (one worker): the seven
checks' table 429 s of CPU time (11 minutes under a load average of 2 to 5), the four's 126 s (3 minutes).  The load average, the wall time and this process's CPU time are printed
after each N.

The stored false-alarm check with fresh seeds (the correct filter alone, N = 10 and 80, ``FRESH_REPS``
repetitions from the seed ``FRESH_SEED``, so Monte Carlos other than the table's), read by notebook 06b, is

    python benchmarks/detection_rates.py --fresh

written to ``kfcal_helpers/calibration/detection_rates_fresh.csv``: 2 x 1000 Monte Carlos, 70 s (23 s at N = 10, 46 s at N = 80)
of CPU time on one core on 2026-12-04 (load average below 1).
"""

from __future__ import annotations

import argparse

from kfcal_helpers.calibration.power import (DEFAULT_N_RUNS, STORED_ASSIGNMENT_CSV, STORED_CSV, STORED_FRESH_CSV,
                                             detection_rates)
from kfcal_helpers.power import write_by_n

REPS, SEED = 200, 2026
#: the fresh-seed false-alarm table: the correct filter at N = 10 and 80, FRESH_REPS repetitions from FRESH_SEED
FRESH_REPS, FRESH_SEED, FRESH_N_RUNS = 1000, 2027, (10, 80)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=REPS, help=f"repetitions per (mistake, N), default {REPS}")
    parser.add_argument("--checks", choices=("all", "assignment"), default="all",
                        help="the seven checks (default) or the assignment's four")
    parser.add_argument("--mistakes", nargs="+", default=None,
                        help="the mistakes to run (default: all; the stored table of the four checks holds the correct "
                             "filter and the two mistakes the seven checks do not catch every time at N = 10)")
    parser.add_argument("--n-runs", type=int, nargs="+", default=list(DEFAULT_N_RUNS),
                        help="the realization counts (default: all of DEFAULT_N_RUNS; the stored table of the four "
                             "checks stops at 640)")
    parser.add_argument("--out", default=None, help="CSV to write (default: the stored table of --checks)")
    parser.add_argument("--fresh", action="store_true",
                        help=f"the correct filter's false alarms with fresh seeds: {FRESH_REPS} repetitions at N = 10 and "
                             f"80 from seed {FRESH_SEED} (the seven checks), written to the stored fresh-seed table")
    args = parser.parse_args(argv)
    if args.fresh:
        write_by_n(lambda n: detection_rates(["correct"], n_runs=[n], reps=FRESH_REPS, seed=FRESH_SEED),
                   FRESH_N_RUNS, args.out or STORED_FRESH_CSV, log=lambda line: print(line, flush=True))
        return 0
    out = args.out or (STORED_CSV if args.checks == "all" else STORED_ASSIGNMENT_CSV)
    write_by_n(lambda n: detection_rates(args.mistakes, n_runs=[n], reps=args.reps, seed=SEED, checks=args.checks),
               args.n_runs, out, log=lambda line: print(line, flush=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
