"""How many realizations does a check need?  The detection rate of each calibration mistake
(:data:`kfcal_helpers.calibration.mistakes.MISTAKES`, the rows of notebook 14) as a function of the
number of realizations N, estimated from repeated Monte Carlos on the batch path.

One *repetition* at N is one ``run_monte_carlo(params, N, seed, engine="batch",
model=mistaken_model(params, mistake))``; the mistake is *detected* when at least one of the
checks fails (its simultaneous band, family-wise level ``alpha``): the seven checks
(:data:`CHECK_NAMES`), or the assignment's four (:data:`ASSIGNMENT_CHECKS`, ``alpha`` split over
them alone).  For the correct filter (the first entry of ``MISTAKES``) that rate is the false-alarm
rate, whose probability is at most about ``alpha`` by construction (about: the Fisher band of the correlations
is approximate); a rate from a few hundred repetitions scatters around it (the stored table's 20 of 200 at
N = 80 is a rare draw of its seeds: :data:`STORED_FRESH_CSV`, 1000 other seeds, gives 0.039 there).  Repetition ``r`` at N uses the seed
``repetition_seed(seed, N, r)`` for every mistake (common random numbers: the mistakes are compared on
the same draws, and the two families on the same Monte Carlos), so the first ``reps`` repetitions of a
larger computation are those of a smaller one.

:func:`detection_rates` runs the computation (:func:`kfcal_helpers.power.detection_table`);
:class:`~kfcal_helpers.power.DetectionRates` holds every repetition's failed checks, the rates and
their exact (Clopper-Pearson) binomial confidence bands, and reads/writes the small CSVs that
``benchmarks/detection_rates.py`` stores (:data:`STORED_CSV`, :data:`STORED_ASSIGNMENT_CSV`, loaded by
:func:`stored_detection_rates`).
"""

from __future__ import annotations

from pathlib import Path

from ..power import DetectionRates, detection_table, repetition_seed
from ..validation import require_choice, require_instance, require_probability
from .mistakes import MISTAKES, mistaken_model
from .montecarlo import ASSIGNMENT_CHECKS, CHECK_NAMES, run_monte_carlo
from .params import CalibrationParams

__all__ = ["DEFAULT_N_RUNS", "STORED_CSV", "STORED_ASSIGNMENT_CSV", "STORED_FRESH_CSV", "DetectionRates", "detection_rates",
           "repetition_seed", "stored_detection_rates"]

#: the realization counts of the stored tables: the course's ladder 10, 40, 160, 640 and the steps between, and 1000
DEFAULT_N_RUNS = (10, 20, 40, 80, 160, 320, 640, 1000)
#: the stored table of the seven checks (written by ``benchmarks/detection_rates.py``)
STORED_CSV = Path(__file__).with_name("detection_rates.csv")
#: the stored table of the assignment's four checks (``benchmarks/detection_rates.py --checks assignment``)
STORED_ASSIGNMENT_CSV = Path(__file__).with_name("detection_rates_assignment.csv")
#: the correct filter's false alarms with fresh seeds, N = 10 and 80 (``benchmarks/detection_rates.py --fresh``)
STORED_FRESH_CSV = Path(__file__).with_name("detection_rates_fresh.csv")
_FAMILIES = {"all": (CHECK_NAMES, STORED_CSV), "assignment": (ASSIGNMENT_CHECKS, STORED_ASSIGNMENT_CSV)}
_STORED = {"all": STORED_CSV, "assignment": STORED_ASSIGNMENT_CSV, "fresh": STORED_FRESH_CSV}


def detection_rates(mistakes=None, n_runs=DEFAULT_N_RUNS, reps: int = 20, seed: int = 0, *,
                    alpha: float = 0.05, params: CalibrationParams | None = None,
                    checks: str = "all") -> DetectionRates:
    """Detection rate of each mistake at each N from ``reps`` repeated Monte Carlos (batch path).

    mistakes : names from ``MISTAKES`` (None: all, the correct filter first); n_runs : realization
        counts, each an int >= 2; reps : repetitions per (mistake, N), >= 1; seed : int >= 0;
    alpha : family-wise level of the checks, in (0, 1); params : CalibrationParams (None: defaults);
    checks : "all" (the seven, :data:`CHECK_NAMES`) or "assignment" (the assignment's four,
        :data:`ASSIGNMENT_CHECKS`, a family of their own).
    Cost: about 0.02 s of checks plus 0.1 ms per realization, per Monte Carlo.
    """
    p = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    names = tuple(MISTAKES) if mistakes is None else tuple(mistakes)
    names = tuple(require_choice("mistakes", m, tuple(MISTAKES)) for m in names)
    if not names:
        raise ValueError("mistakes must name at least one mistake, got an empty list")
    family = _FAMILIES[require_choice("checks", checks, tuple(_FAMILIES))][0]
    alpha = require_probability("alpha", alpha)

    def case(model):
        return lambda n, seeds: [run_monte_carlo(p, n, seed=s, engine="batch", alpha=alpha, model=model,
                                                 progress=False).checks(family) for s in seeds]

    return detection_table({m: case(mistaken_model(p, m)) for m in names}, family, n_runs, reps, seed, alpha)


def stored_detection_rates(checks: str = "all") -> DetectionRates:
    """The table stored with the package for ``checks`` ("all": :data:`STORED_CSV`; "assignment":
    :data:`STORED_ASSIGNMENT_CSV`; "fresh": :data:`STORED_FRESH_CSV`, the correct filter's false alarms
    at N = 10 and 80 on seeds other than the first table's), written by ``benchmarks/detection_rates.py``."""
    return DetectionRates.from_csv(_STORED[require_choice("checks", checks, tuple(_STORED))])
