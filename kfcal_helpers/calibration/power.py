"""How many realizations does a check need?  The detection rate of each calibration mistake
(:data:`kfcal_helpers.calibration.mistakes.MISTAKES`, the rows of notebook 14) as a function of the
number of realizations N, estimated from repeated Monte Carlos on the batch path.

One *repetition* at N is one ``run_monte_carlo(params, N, seed, filter="batch",
model=mistaken_model(params, mistake))``; the mistake is *detected* when at least one of the
seven checks fails (its simultaneous band, family-wise level ``alpha``).  For the correct filter
(the first entry of ``MISTAKES``) that rate is the false-alarm rate, at most ``alpha`` by
construction.  Repetition ``r`` at N uses the seed ``repetition_seed(seed, N, r)`` for every
mistake (common random numbers: the mistakes are compared on the same draws), so the first
``reps`` repetitions of a larger computation are those of a smaller one.

:func:`detection_rates` runs the computation; :class:`DetectionRates` holds every repetition's
failed checks, the rates and their exact (Clopper-Pearson) binomial confidence bands, and
reads/writes the small CSV that ``benchmarks/detection_rates.py`` stores
(:data:`STORED_CSV`, loaded by :func:`stored_detection_rates`).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from ..validation import require_choice, require_instance, require_int, require_probability, require_seed
from .mistakes import MISTAKES, mistaken_model
from .montecarlo import CHECK_NAMES, run_monte_carlo
from .params import CalibrationParams

__all__ = ["DEFAULT_N_RUNS", "STORED_CSV", "DetectionRates", "detection_rates", "repetition_seed",
           "stored_detection_rates"]

#: the realization counts of the stored table: the course's ladder 10, 40, 160, 640 and the steps between, and 1000
DEFAULT_N_RUNS = (10, 20, 40, 80, 160, 320, 640, 1000)
#: the stored table (written by ``benchmarks/detection_rates.py``)
STORED_CSV = Path(__file__).with_name("detection_rates.csv")
_FIELDS = ("mistake", "n_runs", "reps", "seed", "alpha", "detected", "failed_checks")


def repetition_seed(seed: int, n_runs: int, rep: int) -> int:
    """The ``run_monte_carlo`` seed of repetition ``rep`` at ``n_runs`` realizations: an int in
    [0, 2**32) drawn from ``numpy.random.SeedSequence((seed, n_runs, rep))``."""
    return int(np.random.SeedSequence((seed, n_runs, rep)).generate_state(1)[0])


@dataclass(frozen=True)
class DetectionRates:
    """Repeated Monte Carlos of each mistake at each N.

    mistakes : names (keys of ``MISTAKES``), m of them; n_runs : the N values, k of them;
    reps : repetitions per (mistake, N); seed, alpha : as given to :func:`detection_rates`;
    failed : bool array (m, k, reps, 7), ``failed[a, j, r, c]`` = check ``CHECK_NAMES[c]`` failed in
    repetition r of mistake a at ``n_runs[j]``.
    """

    mistakes: tuple
    n_runs: tuple
    reps: int
    seed: int
    alpha: float
    failed: np.ndarray

    @property
    def detected(self) -> np.ndarray:
        """bool (m, k, reps): at least one of the seven checks failed."""
        return self.failed.any(axis=-1)

    @property
    def counts(self) -> np.ndarray:
        """int (m, k): repetitions in which the mistake was detected."""
        return self.detected.sum(axis=-1)

    @property
    def rates(self) -> np.ndarray:
        """(m, k): share of the repetitions in which the mistake was detected, in [0, 1]."""
        return self.counts / self.reps

    def check_rates(self) -> np.ndarray:
        """(m, k, 7): share of the repetitions in which each check failed."""
        return self.failed.mean(axis=2)

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
        return DetectionRates(self.mistakes, self.n_runs, reps, self.seed, self.alpha, self.failed[:, :, :reps])

    def to_csv(self, path) -> None:
        """Write one row per (mistake, N); ``failed_checks`` holds two hex digits per repetition, the
        bit ``2**c`` set when check ``CHECK_NAMES[c]`` failed."""
        weights = 2 ** np.arange(len(CHECK_NAMES))
        with open(path, "w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(_FIELDS)
            for a, mistake in enumerate(self.mistakes):
                for j, n in enumerate(self.n_runs):
                    codes = self.failed[a, j].astype(int) @ weights
                    w.writerow([mistake, n, self.reps, self.seed, self.alpha, int(self.counts[a, j]),
                                "".join(f"{c:02x}" for c in codes)])

    @classmethod
    def from_csv(cls, path) -> "DetectionRates":
        """Read a table written by :meth:`to_csv`."""
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows or tuple(rows[0]) != _FIELDS:
            raise ValueError(f"path must name a detection-rates CSV with the columns {_FIELDS}, got {path!s}")
        mistakes = tuple(dict.fromkeys(r["mistake"] for r in rows))
        n_runs = tuple(dict.fromkeys(int(r["n_runs"]) for r in rows))
        reps, seed, alpha = int(rows[0]["reps"]), int(rows[0]["seed"]), float(rows[0]["alpha"])
        failed = np.zeros((len(mistakes), len(n_runs), reps, len(CHECK_NAMES)), bool)
        bits = 2 ** np.arange(len(CHECK_NAMES))
        for r in rows:
            codes = np.array([int(r["failed_checks"][i:i + 2], 16) for i in range(0, 2 * reps, 2)])
            failed[mistakes.index(r["mistake"]), n_runs.index(int(r["n_runs"]))] = (codes[:, None] & bits) > 0
        out = cls(mistakes, n_runs, reps, seed, alpha, failed)
        stored = {(r["mistake"], int(r["n_runs"])): int(r["detected"]) for r in rows}
        if any(stored[m, n] != out.counts[a, j] for a, m in enumerate(mistakes) for j, n in enumerate(n_runs)):
            raise ValueError(f"path {path!s}: a 'detected' count disagrees with its failed_checks")
        return out


def detection_rates(mistakes=None, n_runs=DEFAULT_N_RUNS, reps: int = 20, seed: int = 0, *,
                    alpha: float = 0.05, params: CalibrationParams | None = None) -> DetectionRates:
    """Detection rate of each mistake at each N from ``reps`` repeated Monte Carlos (batch path).

    mistakes : names from ``MISTAKES`` (None: all, the correct filter first); n_runs : realization
        counts, each an int >= 2; reps : repetitions per (mistake, N), >= 1; seed : int >= 0;
    alpha : family-wise level of the seven checks, in (0, 1); params : CalibrationParams (None: defaults).
    Cost: about 0.02 s of checks plus 0.1 ms per realization, per Monte Carlo.
    """
    p = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    names = tuple(MISTAKES) if mistakes is None else tuple(mistakes)
    if not names:
        raise ValueError("mistakes must name at least one mistake, got an empty list")
    names = tuple(require_choice("mistakes", m, tuple(MISTAKES)) for m in names)
    ns = tuple(require_int("n_runs", n, minimum=2) for n in np.atleast_1d(n_runs).tolist())
    if not ns:
        raise ValueError("n_runs must hold at least one realization count, got an empty list")
    reps = require_int("reps", reps, minimum=1)
    seed = require_seed("seed", seed, allow_none=False)
    alpha = require_probability("alpha", alpha)
    models = {m: mistaken_model(p, m) for m in names}
    failed = np.zeros((len(names), len(ns), reps, len(CHECK_NAMES)), bool)
    for j, n in enumerate(ns):
        for r in range(reps):
            s = repetition_seed(seed, n, r)
            for a, m in enumerate(names):
                checks = run_monte_carlo(p, n, seed=s, filter="batch", alpha=alpha, model=models[m],
                                         progress=False).checks()
                failed[a, j, r] = [not checks[c].passed for c in CHECK_NAMES]
    return DetectionRates(names, ns, reps, seed, alpha, failed)


def stored_detection_rates() -> DetectionRates:
    """The table stored with the package (:data:`STORED_CSV`, written by ``benchmarks/detection_rates.py``)."""
    return DetectionRates.from_csv(STORED_CSV)
