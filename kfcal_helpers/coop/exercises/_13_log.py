"""Exercise checks of notebook 13 (the log; fewer measurements): 13.1-13.2."""

from __future__ import annotations


from dataclasses import replace

import numpy as np
from scipy import stats

from ...consistency import chi2_bounds
from ..model import (
    N_MEAS,
    N_STATES,
)
from ...exercises._core import (BAND_NAMES, Exercise, Feedback, chi2_average_bounds)
from ...validation import require_int, require_probability
from ._shared import BOUNDS_RTOL, LOG_ALPHA, LOG_SAMPLES, SPARSE_EVERY, SPARSE_SAMPLES
from ._10_lkf import normal_bounds


def _nis_bounds_wrong(K, alpha, extra):
    """Common wrong answers for the time-averaged NIS bounds of K updates."""
    pairs = [(chi2_average_bounds(N_MEAS, K, alpha, one_sided=True), "one_sided"),
             (chi2_average_bounds(N_MEAS, K, alpha, dof=K), "dof_K"),
             (np.array(chi2_bounds(N_STATES, K, alpha)), "dim6")]
    return pairs + extra


LOG_NIS_BOUNDS = Exercise(
    "13.1",
    praise="n_upd = {K} updates, 5 n_upd degrees of freedom, divided by n_upd",
    hints={
        "count_nan": "count only the steps that have a measurement: the first sample is NaN",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "notebook_alpha": "those are the bounds at alpha = 0.05: this exercise uses alpha = 0.01",
        "dof_K": "n_upd steps of a 5-dimensional NIS give 5 n_upd degrees of freedom, not n_upd",
        "not_divided": "the bounds are for the time average: divide the chi-square quantiles by n_upd",
        "dim6": "the NIS has the dimension of the measurement, not of the state",
        "normal": "close, but that is the normal approximation: use the chi-square quantiles",
    },
    components=BAND_NAMES,
)


def check_log_nis_bounds(answer, *, n_samples: int = LOG_SAMPLES, alpha: float = LOG_ALPHA) -> Feedback:
    """13.1: bounds of the time-averaged NIS of one run over a log of ``n_samples`` samples whose
    first sample has no measurement, at significance ``alpha``.

    answer : array (2,) -- [lower, upper] (dimensionless), the computed values (no rounding)
    """
    n_samples = require_int("n_samples", n_samples, minimum=3)
    alpha = require_probability("alpha", alpha)
    K = n_samples - 1
    expected = np.array(chi2_bounds(N_MEAS, K, alpha))
    extra = [(np.array(chi2_bounds(N_MEAS, K + 1, alpha)), "count_nan"),
             (chi2_average_bounds(N_MEAS, K, alpha, divide_by=1), "not_divided"),
             (normal_bounds(N_MEAS, K, alpha), "normal"),
             (normal_bounds(N_MEAS, K, alpha, stats.norm.ppf(1 - alpha / 2).round(2)), "normal")]
    if abs(alpha - 0.05) > 1e-12:
        extra.append((np.array(chi2_bounds(N_MEAS, K, 0.05)), "notebook_alpha"))
    E = replace(LOG_NIS_BOUNDS, praise=LOG_NIS_BOUNDS.praise.format(K=K))
    return E.judge(answer, expected, _nis_bounds_wrong(K, alpha, extra), rtol=BOUNDS_RTOL, atol=0.0)


SPARSE_NIS_BOUNDS = Exercise(
    "13.2",
    praise="n_upd = {K} updates: fewer updates, wider bounds",
    hints={
        "count_nan": "the first kept sample (t = 0) has no measurement: do not count it",
        "all_steps": "only every 10th step has a measurement now: n_upd counts the updates, not the steps of the log",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "dof_K": "n_upd steps of a 5-dimensional NIS give 5 n_upd degrees of freedom, not n_upd",
        "dim6": "the NIS has the dimension of the measurement, not of the state",
    },
    components=BAND_NAMES,
)


def check_sparse_nis_bounds(answer, *, every: int = SPARSE_EVERY, n_samples: int = SPARSE_SAMPLES,
                            alpha: float = 0.05) -> Feedback:
    """13.2: bounds of the time-averaged NIS of one run when only every ``every``-th sample
    (k = 0, every, 2 every, ...) of a log of ``n_samples`` samples is used; sample 0 has no measurement.

    answer : array (2,) -- [lower, upper] (dimensionless), the computed values (no rounding)
    """
    every = require_int("every", every, minimum=2)
    n_samples = require_int("n_samples", n_samples, minimum=2 * every + 1)
    alpha = require_probability("alpha", alpha)
    K = len(range(0, n_samples, every)) - 1
    expected = np.array(chi2_bounds(N_MEAS, K, alpha))
    extra = [(np.array(chi2_bounds(N_MEAS, K + 1, alpha)), "count_nan"),
             (np.array(chi2_bounds(N_MEAS, n_samples - 1, alpha)), "all_steps"),
             (np.array(chi2_bounds(N_MEAS, n_samples, alpha)), "all_steps")]  # every sample, the NaN one too
    E = replace(SPARSE_NIS_BOUNDS, praise=SPARSE_NIS_BOUNDS.praise.format(K=K))
    return E.judge(answer, expected, _nis_bounds_wrong(K, alpha, extra), rtol=BOUNDS_RTOL, atol=0.0)


#: the exercise records of this lesson, in notebook order
RECORDS = (LOG_NIS_BOUNDS, SPARSE_NIS_BOUNDS)
