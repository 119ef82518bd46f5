"""How many runs does the coop truth-model test need?  The detection rate of a mis-scaled Q and of each
coop mistake of notebook 14 (:data:`kfcal_helpers.coop.mistakes.MISTAKES`) as a function of the number
of runs N, estimated from repeated truth-model tests (the batched filters of :mod:`kfcal_helpers.coop.batch`).

The cases (:data:`CASES`): the correct EKF (the course's truth model, ``Q = Qtrue``; its rate is the
false-alarm rate), the EKF with ``Q = s Qtrue`` for each s of :data:`Q_SCALES` (the truth keeps
``Qtrue``), and the other rows of notebook 14 (:func:`kfcal_helpers.coop.mistakes.coop_case`; the correct
LKF is a second false-alarm rate, in its own near-nominal setting).  One *repetition* at N is one
``truth_model_test`` of N runs; a check *fails* when its simultaneous band is left
(:meth:`~kfcal_helpers.coop.montecarlo.MonteCarloResult.checks`: ``alpha`` split over all entries of the
mean error, the NEES and the NIS together), and the case is *detected* when any of the three fails;
:meth:`~kfcal_helpers.power.DetectionRates.only` gives the NEES test's and the NIS test's rates alone.
Repetition ``r`` at N uses the seed ``repetition_seed(seed, N, r)`` for every case (the same truths for
every EKF case).

:func:`detection_rates` runs the computation (:func:`kfcal_helpers.power.detection_table`);
``benchmarks/coop_detection_rates.py`` stores the table (:data:`STORED_CSV`, read by
:func:`stored_detection_rates`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..power import DetectionRates, detection_table, repetition_seed
from ..validation import require_choice, require_instance, require_probability
from .filters import FilterSetup
from .mistakes import MISTAKES, coop_case
from .model import CoopParams
from .batch import run_batch
from .montecarlo import TruthModelExperiment, truth_model_draws

__all__ = ["CASES", "CHECKS", "DEFAULT_N_RUNS", "Q_SCALES", "STORED_CSV", "DetectionRates", "case_setup",
           "detection_rates", "repetition_seed", "stored_detection_rates"]

#: the scales s of the mis-scaled ``Q = s Qtrue`` of the EKF (the truth keeps Qtrue)
Q_SCALES = (0.1, 0.3, 3.0, 10.0)
#: the cases, the correct EKF first: name -> what the filter does
CASES = {"ekf_correct": MISTAKES["ekf_correct"],
         **{f"q_x{s:g}": f"the EKF with Q = {s:g} Qtrue (the truth: Qtrue)" for s in Q_SCALES},
         **{m: text for m, text in MISTAKES.items() if m != "ekf_correct"}}
#: the checks recorded, those of ``MonteCarloResult.checks()``
CHECKS = ("mean_error", "nees", "nis")
#: the run counts of the stored table
DEFAULT_N_RUNS = (5, 10, 20, 50)
_BATCH_RUNS = 250  #: most runs filtered together (several repetitions at once; 500 peaked at 478 MB, too near 500 MB)
#: the stored table (written by ``benchmarks/coop_detection_rates.py``)
STORED_CSV = Path(__file__).with_name("detection_rates.csv")


def case_setup(case: str, params: CoopParams | None = None) -> tuple[str, CoopParams, dict]:
    """Filter name, truth-model parameters and filter settings of a case of :data:`CASES` (the
    mistakes' from :func:`~kfcal_helpers.coop.mistakes.coop_case`)."""
    case = require_choice("case", case, tuple(CASES))
    p = require_instance("params", params, CoopParams, allow_none=True) or CoopParams()
    if case.startswith("q_x"):
        return "ekf", p, {"Q": float(case[3:]) * p.Qtrue}
    return coop_case(case, p)


def detection_rates(cases=None, n_runs=DEFAULT_N_RUNS, reps: int = 20, seed: int = 0, *, alpha: float = 0.05,
                    params: CoopParams | None = None) -> DetectionRates:
    """Detection rate of each case at each N from ``reps`` repeated truth-model tests.

    cases : names from :data:`CASES` (None: all, the correct EKF first); n_runs : run counts, each an
        int >= 2; reps : repetitions per (case, N), >= 1; seed : int >= 0; alpha : family-wise level
        of the three checks, in (0, 1); params : CoopParams (None: the course's, 100 s of 0.1 s steps).
    Returns a :class:`~kfcal_helpers.power.DetectionRates` whose ``mistakes`` are the cases and whose
    checks are :data:`CHECKS`.  The repetitions of a case at one N are filtered together, up to 250 runs
    at a time: one thread takes about 0.2 s per batch plus 3 ms per run for the EKF.
    """
    p = require_instance("params", params, CoopParams, allow_none=True) or CoopParams()
    names = tuple(CASES) if cases is None else tuple(cases)
    names = tuple(require_choice("cases", c, tuple(CASES)) for c in names)
    if not names:
        raise ValueError("cases must name at least one case, got an empty list")
    alpha = require_probability("alpha", alpha)

    def case(name):
        filter, truth, settings = case_setup(name, p)
        setup = FilterSetup.build(filter, truth, **settings)
        return lambda n, seeds: _repetitions(setup, n, seeds, alpha)

    return detection_table({c: case(c) for c in names}, CHECKS, n_runs, reps, seed, alpha)


def _repetitions(setup: FilterSetup, n_runs: int, seeds: list, alpha: float) -> list:
    """The checks of ``truth_model_test(setup.params, n_runs, s)`` for each seed s, the same truths and
    measurements (``truth_model_draws``), filtered together in batches of at most :data:`_BATCH_RUNS` runs
    (the batched filters treat every run on its own: ``tests/test_coop_power.py`` shows the result equal to
    the tests one by one)."""
    per = max(1, _BATCH_RUNS // n_runs)
    out = []
    for i in range(0, len(seeds), per):
        group = seeds[i:i + per]
        draws = [truth_model_draws(setup.params, n_runs, s) for s in group]
        b = run_batch(np.concatenate([d.y for d in draws]), setup, np.concatenate([d.truth for d in draws]))
        for k in range(len(group)):
            exp = TruthModelExperiment(setup, n_runs, 1, alpha)
            part = slice(k * n_runs, (k + 1) * n_runs)
            total = exp.add(exp.empty(n_runs), (b.nees[part], b.nis[part], b.errors[part], b.sigma2[part]))
            out.append(exp.result(total, n_runs, 0.0).checks())
    return out


def stored_detection_rates() -> DetectionRates:
    """The table stored with the package (:data:`STORED_CSV`, written by ``benchmarks/coop_detection_rates.py``)."""
    return DetectionRates.from_csv(STORED_CSV)
