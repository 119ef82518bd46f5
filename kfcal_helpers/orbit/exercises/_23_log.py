"""Exercise checks of notebook 23 (the data log; NIS with the dof present): 23.1-23.2."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import stats

from ...exercises._core import BAND_NAMES, Exercise, Feedback, chi2_average_bounds, distinct_mistakes
from ...validation import require_int, require_probability
from ..params import N_STATES, N_STATION_MEAS
from ._shared import (BOUNDS_RTOL, LOG_ALPHA, LOG_EMPTY_STEPS, LOG_ONE_STATION, LOG_TWO_STATIONS, LOG_STEP_ALPHA,
                      LOG_STEP_STATIONS)

__all__ = ["LOG_NIS_BAND", "STEP_NIS_BAND", "RECORDS", "check_log_nis_band", "check_step_nis_band"]


def _band(dof: int, n: float, alpha: float, one_sided: bool = False) -> np.ndarray:
    """``[lower, upper]``: the chi-square(``dof``) quantiles at ``alpha`` (split in two tails) over ``n``."""
    lo, hi = (alpha, 1 - alpha) if one_sided else (alpha / 2, 1 - alpha / 2)
    return np.array([stats.chi2.ppf(lo, dof), stats.chi2.ppf(hi, dof)]) / n


LOG_NIS_BAND = Exercise(
    "23.1",
    praise="n_upd = {n} updates with {dof} degrees of freedom summed over them (3 per visible station), divided by n_upd",
    hints={
        "fixed_dof": "not every update has 3 components: a step with two stations has 6; sum the dof present over "
                     "the updates",
        "station_dof": "each visible station contributes 3 components (rho, rhodot, phi), not 1",
        "count_empty": "the steps without a station have no NIS: n_upd counts the updates only",
        "per_dof": "the time average divides the sum of the NIS by the number of updates n_upd, not by the dof",
        "not_divided": "the bounds are for the time average: divide the chi-square quantiles by n_upd",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "state_dof": "the NIS has the dimension of the measurement present, not of the state (4)",
    },
    components=BAND_NAMES,
    units=False,
)


def check_log_nis_band(answer, *, one: int = LOG_ONE_STATION, two: int = LOG_TWO_STATIONS,
                       empty: int = LOG_EMPTY_STEPS, alpha: float = LOG_ALPHA) -> Feedback:
    """23.1: bounds of the time-averaged NIS of one run over a log whose updates see one station (``one``
    updates, 3 dof each) or two (``two`` updates, 6 dof each), with ``empty`` further steps without a station,
    at significance ``alpha``.

    answer : array (2,) -- [lower, upper] (dimensionless), the computed values (no rounding)
    """
    one = require_int("one", one, minimum=0)
    two = require_int("two", two, minimum=0)
    empty = require_int("empty", empty, minimum=0)
    alpha = require_probability("alpha", alpha)
    n = one + two
    if n < 1:
        raise ValueError("one + two must be at least 1 (a log with an update)")
    dof = N_STATION_MEAS * (one + 2 * two)
    expected = _band(dof, n, alpha)
    wrong = [(chi2_average_bounds(N_STATION_MEAS, n, alpha), "fixed_dof"),
             (_band(one + 2 * two, n, alpha), "station_dof"),
             (_band(dof, n + empty, alpha), "count_empty"),
             (_band(dof, dof, alpha), "per_dof"),
             (_band(dof, 1, alpha), "not_divided"),
             (_band(dof, n, alpha, one_sided=True), "one_sided"),
             (chi2_average_bounds(N_STATES, n, alpha), "state_dof")]
    E = replace(LOG_NIS_BAND, praise=LOG_NIS_BAND.praise.format(n=n, dof=dof))
    return E.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-6), rtol=BOUNDS_RTOL, atol=0.0)


STEP_NIS_BAND = Exercise(
    "23.2",
    praise="one step's NIS with {dof} dof: its band changes with the stations present",
    hints={
        "fixed_dof": "that is the band of one station (3 dof): with {m} stations the step's NIS has 3 x {m} components",
        "station_dof": "each station contributes 3 components (rho, rhodot, phi): the dof are 3 per station, not 1",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "notebook_alpha": "those are the bounds at alpha = 0.05: this exercise uses alpha = {alpha:g}",
        "state_dof": "the NIS has the dimension of the measurement present, not of the state (4)",
    },
    components=BAND_NAMES,
    units=False,
)


def check_step_nis_band(answer, *, stations: int = LOG_STEP_STATIONS, alpha: float = LOG_STEP_ALPHA) -> Feedback:
    """23.2: the two-sided band of one step's NIS at significance ``alpha`` when ``stations`` stations
    (1..12) are visible at that step.

    answer : array (2,) -- [lower, upper] (dimensionless), the computed values (no rounding)
    """
    stations = require_int("stations", stations, minimum=1, maximum=12)
    alpha = require_probability("alpha", alpha)
    dof = N_STATION_MEAS * stations
    expected = _band(dof, 1, alpha)
    wrong = [(_band(N_STATION_MEAS, 1, alpha), "fixed_dof"), (_band(stations, 1, alpha), "station_dof"),
             (_band(dof, 1, alpha, one_sided=True), "one_sided"), (_band(N_STATES, 1, alpha), "state_dof")]
    if abs(alpha - 0.05) > 1e-12:
        wrong.append((_band(dof, 1, 0.05), "notebook_alpha"))
    E = replace(STEP_NIS_BAND, praise=STEP_NIS_BAND.praise.format(dof=dof),
                hints={k: v.format(m=stations, alpha=alpha) for k, v in STEP_NIS_BAND.hints.items()})
    return E.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-6), rtol=BOUNDS_RTOL, atol=0.0)


#: the exercise records of this lesson, in notebook order
RECORDS = (LOG_NIS_BAND, STEP_NIS_BAND)
