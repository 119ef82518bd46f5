"""Write the stored detection-rate table of notebook 06b (run: python benchmarks/detection_rates.py).

For every calibration mistake of notebook 14 (the correct filter first: its rate is the false-alarm
rate) and every N in ``DEFAULT_N_RUNS`` (10 ... 1000), ``REPS`` repeated Monte Carlos on the batch
path, seed ``SEED``: ``kfcal_helpers.calibration.power.detection_rates``.  The table is written to
``kfcal_helpers/calibration/detection_rates.csv`` after each N (a partial table is a valid table of
the N values done so far; the repetitions' seeds depend only on (SEED, N, repetition)).
``tests/test_calibration_power.py`` recomputes a subset of it and checks it.  Cost: 7 x 8 x 200 =
11,200 Monte Carlos, about 50 ms each plus 0.1 ms per realization on an idle core (about 15 minutes);
the stored table took 33 minutes on a 2-core machine under a load average of 3 to 11.  The load average
is printed with the time.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from kfcal_helpers.calibration.power import DEFAULT_N_RUNS, STORED_CSV, DetectionRates, detection_rates

REPS, SEED = 200, 2026


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=REPS, help=f"repetitions per (mistake, N), default {REPS}")
    parser.add_argument("--out", default=str(STORED_CSV), help="CSV to write (default: the stored table)")
    args = parser.parse_args(argv)
    parts = []
    start = time.perf_counter()
    for n in DEFAULT_N_RUNS:
        parts.append(detection_rates(n_runs=[n], reps=args.reps, seed=SEED))
        table = DetectionRates(parts[0].mistakes, tuple(p.n_runs[0] for p in parts), args.reps, SEED, parts[0].alpha,
                               np.concatenate([p.failed for p in parts], axis=1))
        table.to_csv(args.out)
        print(f"N = {n:5d} done after {time.perf_counter() - start:.0f} s (load {os.getloadavg()[0]:.1f}); "
              + ", ".join(f"{m} {r:.2f}" for m, r in zip(table.mistakes, table.rates[:, -1])), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
