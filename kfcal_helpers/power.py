"""How many realizations does a check need?  Detection rates from repeated Monte Carlos, for any problem.

A *case* is one filter (a mistake, or the correct filter, whose rate is the false-alarm rate); a
*repetition* at N is one Monte Carlo of N realizations of that case; a check *fails* in it when its
simultaneous band is left.  :func:`detection_table` runs ``reps`` repetitions of every case at every
N, repetition ``r`` at N with the seed :func:`repetition_seed` ``(seed, N, r)`` for every case (common
random numbers: the cases are compared on the same draws, and the first ``reps`` repetitions of a larger
computation are those of a smaller one).  :class:`DetectionRates` holds every repetition's failed checks,
the rates and their exact (Clopper-Pearson) binomial confidence bands, and reads and writes the small CSV
a problem stores with its package (``kfcal_helpers.calibration.power``, ``kfcal_helpers.coop.power``).
"""

from __future__ import annotations

import csv
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import stats

from .validation import require_choice, require_int, require_probability, require_seed

__all__ = ["DetectionRates", "detection_table", "repetition_seed", "require_counts", "write_by_n"]

_FIELDS = ("mistake", "n_runs", "reps", "seed", "alpha", "detected", "failed_checks", "checks")
_MAX_CHECKS = 8  #: two hex digits per repetition hold the failed checks of at most 8 checks


def repetition_seed(seed: int, n_runs: int, rep: int) -> int:
    """The Monte Carlo seed of repetition ``rep`` at ``n_runs`` realizations: an int in
    [0, 2**32) drawn from ``numpy.random.SeedSequence((seed, n_runs, rep))``."""
    return int(np.random.SeedSequence((seed, n_runs, rep)).generate_state(1)[0])


def require_counts(name: str, values) -> tuple:
    """A non-empty tuple of realization counts, each an int >= 2 (ValueError naming ``name``)."""
    out = tuple(require_int(name, n, minimum=2) for n in np.atleast_1d(values).tolist())
    if not out:
        raise ValueError(f"{name} must hold at least one realization count, got an empty list")
    return out


@dataclass(frozen=True)
class DetectionRates:
    """Repeated Monte Carlos of each case at each N.

    mistakes : case names, m of them; n_runs : the N values, k of them; reps : repetitions per (case, N);
    seed, alpha : as given to the run; failed : bool array (m, k, reps, c), ``failed[a, j, r, i]`` = check
    ``checks[i]`` failed in repetition r of case a at ``n_runs[j]``; checks : the c check names.
    """

    mistakes: tuple
    n_runs: tuple
    reps: int
    seed: int
    alpha: float
    failed: np.ndarray
    checks: tuple

    @property
    def detected(self) -> np.ndarray:
        """bool (m, k, reps): at least one of the checks failed."""
        return self.failed.any(axis=-1)

    @property
    def counts(self) -> np.ndarray:
        """int (m, k): repetitions in which the case was detected."""
        return self.detected.sum(axis=-1)

    @property
    def rates(self) -> np.ndarray:
        """(m, k): share of the repetitions in which the case was detected, in [0, 1]."""
        return self.counts / self.reps

    def check_rates(self) -> np.ndarray:
        """(m, k, c): share of the repetitions in which each check failed."""
        return self.failed.mean(axis=2)

    def only(self, checks) -> "DetectionRates":
        """The same repetitions judged by the named checks only (their bits as stored: each check keeps
        the share of ``alpha`` it had in the family it was run with)."""
        names = tuple(require_choice("checks", c, self.checks) for c in checks)
        if not names:
            raise ValueError("checks must name at least one check, got an empty list")
        cols = [self.checks.index(c) for c in names]
        return DetectionRates(self.mistakes, self.n_runs, self.reps, self.seed, self.alpha, self.failed[..., cols],
                              names)

    def band(self, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Exact (Clopper-Pearson) two-sided confidence band of each rate, ``(lower, upper)``, each
        (m, k), from ``scipy.stats.binomtest(count, reps).proportion_ci(confidence, "exact")``."""
        confidence = require_probability("confidence", confidence)
        lo, hi = np.empty(self.counts.shape), np.empty(self.counts.shape)
        for idx, k in np.ndenumerate(self.counts):
            ci = stats.binomtest(int(k), self.reps).proportion_ci(confidence, method="exact")
            lo[idx], hi[idx] = ci.low, ci.high
        return lo, hi

    def rate(self, mistake: str, n_runs: int) -> float:
        """The detection rate of ``mistake`` at ``n_runs`` realizations."""
        mistake = require_choice("mistake", mistake, self.mistakes)
        if n_runs not in self.n_runs:
            raise ValueError(f"n_runs must be one of {list(self.n_runs)}, got {n_runs!r}")
        return float(self.rates[self.mistakes.index(mistake), self.n_runs.index(n_runs)])

    def first(self, reps: int) -> "DetectionRates":
        """The same table restricted to its first ``reps`` repetitions (what a smaller run gives)."""
        reps = require_int("reps", reps, minimum=1)
        if reps > self.reps:
            raise ValueError(f"reps must be at most {self.reps}, got {reps}")
        return DetectionRates(self.mistakes, self.n_runs, reps, self.seed, self.alpha, self.failed[:, :, :reps],
                              self.checks)

    def joined(self, other: "DetectionRates") -> "DetectionRates":
        """This table and ``other`` (more N values of the same cases, repetitions and checks) as one table."""
        if (other.mistakes, other.reps, other.seed, other.alpha, other.checks) != (
                self.mistakes, self.reps, self.seed, self.alpha, self.checks):
            raise ValueError("other must hold the same cases, repetitions, seed, alpha and checks")
        return DetectionRates(self.mistakes, self.n_runs + other.n_runs, self.reps, self.seed, self.alpha,
                              np.concatenate([self.failed, other.failed], axis=1), self.checks)

    def to_csv(self, path) -> None:
        """Write one row per (case, N); ``failed_checks`` holds two hex digits per repetition, the bit
        ``2**i`` set when check ``checks[i]`` failed; ``checks`` the check names, separated by spaces."""
        weights = 2 ** np.arange(len(self.checks))
        with open(path, "w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(_FIELDS)
            for a, mistake in enumerate(self.mistakes):
                for j, n in enumerate(self.n_runs):
                    codes = self.failed[a, j].astype(int) @ weights
                    w.writerow([mistake, n, self.reps, self.seed, self.alpha, int(self.counts[a, j]),
                                "".join(f"{c:02x}" for c in codes), " ".join(self.checks)])

    @classmethod
    def from_csv(cls, path) -> "DetectionRates":
        """Read a table written by :meth:`to_csv` (ValueError naming ``path`` when it is not one)."""
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows or tuple(rows[0]) != _FIELDS:
            raise ValueError(f"path must name a detection-rates CSV with the columns {_FIELDS}, got {path!s}")
        mistakes = tuple(dict.fromkeys(r["mistake"] for r in rows))
        n_runs = tuple(dict.fromkeys(int(r["n_runs"]) for r in rows))
        reps, seed, alpha = int(rows[0]["reps"]), int(rows[0]["seed"]), float(rows[0]["alpha"])
        checks = tuple(rows[0]["checks"].split())
        if not 0 < len(checks) <= _MAX_CHECKS or any(r["checks"].split() != list(checks) for r in rows):
            raise ValueError(f"path {path!s}: every row must name the same 1 to {_MAX_CHECKS} checks")
        failed = np.zeros((len(mistakes), len(n_runs), reps, len(checks)), bool)
        bits = 2 ** np.arange(len(checks))
        for r in rows:
            if len(r["failed_checks"]) != 2 * reps:
                raise ValueError(f"path {path!s}: failed_checks must hold two hex digits per repetition")
            codes = np.array([int(r["failed_checks"][i:i + 2], 16) for i in range(0, 2 * reps, 2)])
            failed[mistakes.index(r["mistake"]), n_runs.index(int(r["n_runs"]))] = (codes[:, None] & bits) > 0
        out = cls(mistakes, n_runs, reps, seed, alpha, failed, checks)
        stored = {(r["mistake"], int(r["n_runs"])): int(r["detected"]) for r in rows}
        if any(stored[m, n] != out.counts[a, j] for a, m in enumerate(mistakes) for j, n in enumerate(n_runs)):
            raise ValueError(f"path {path!s}: a 'detected' count disagrees with its failed_checks")
        return out


def detection_table(cases: dict[str, Callable[[int, list], list]], checks, n_runs, reps: int, seed: int,
                    alpha: float) -> DetectionRates:
    """Run ``reps`` repetitions of every case at every N and record its failed checks.

    cases : name -> ``run(n_runs, seeds)`` returning, for each seed, the checks of the Monte Carlo of
        ``n_runs`` realizations with that seed, ``[{name: Check}, ...]`` (a case may run several
        repetitions at once); checks : the names of the checks to record (at most 8); n_runs :
        realization counts, each an int >= 2; reps : repetitions per (case, N), >= 1; seed : int >= 0;
        alpha : what the cases' checks were run at, recorded with the table.
    Repetition r at N gets the seed ``repetition_seed(seed, N, r)`` in every case.
    """
    if not cases:
        raise ValueError("cases must name at least one case, got an empty dict")
    checks = tuple(checks)
    if not 0 < len(checks) <= _MAX_CHECKS:
        raise ValueError(f"checks must name 1 to {_MAX_CHECKS} checks, got {len(checks)}")
    ns = require_counts("n_runs", n_runs)
    reps = require_int("reps", reps, minimum=1)
    seed = require_seed("seed", seed, allow_none=False)
    alpha = require_probability("alpha", alpha)
    names = tuple(cases)
    failed = np.zeros((len(names), len(ns), reps, len(checks)), bool)
    for j, n in enumerate(ns):
        seeds = [repetition_seed(seed, n, r) for r in range(reps)]
        for a, name in enumerate(names):
            results = cases[name](n, seeds)
            failed[a, j] = [[not result[c].passed for c in checks] for result in results]
    return DetectionRates(names, ns, reps, seed, alpha, failed, checks)


def write_by_n(compute: Callable[[int], DetectionRates], n_runs, path, log: Callable[[str], None] = print
               ) -> DetectionRates:
    """Compute a table one N at a time (``compute(n)`` returns the table of that N) and write the joined
    table to ``path`` after each N, so that a partial file is a valid table of the N values done so far;
    ``log`` gets one line per N: the wall time, this process's CPU time, the load average and the last
    N's rates."""
    table = None
    start, cpu = time.perf_counter(), time.process_time()
    for n in require_counts("n_runs", n_runs):
        part = compute(n)
        table = part if table is None else table.joined(part)
        table.to_csv(path)
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        log(f"N = {n:5d} done after {time.perf_counter() - start:.0f} s, CPU {time.process_time() - cpu:.0f} s "
            f"(load {load:.1f}); " + ", ".join(f"{m} {r:.2f}" for m, r in zip(table.mistakes, table.rates[:, -1])))
    return table
