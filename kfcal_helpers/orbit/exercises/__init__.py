"""Exercise checks of the orbit-determination notebooks (21 here).

Each ``check_<topic>(answer, *, settings...)`` takes the student's answer and returns a
:class:`~kfcal_helpers.exercises._core.Feedback` whose repr is one line: correct, or a hint at the likely
mistake, never the answer.  The checks live one module per lesson, in notebook order (``_21_lkf``); each
module lists its records in ``RECORDS``, and this package re-exports every name, so
``from kfcal_helpers.orbit.exercises import check_...`` is the one import path.

=========  ========================================  ==================================
exercise   check                                     answer
=========  ========================================  ==================================
21.1       :func:`check_nis_step_band`               one step's NIS band, (2,)
21.2       :func:`check_two_station_S`               S of a two-station step, (6, 6)
=========  ========================================  ==================================
"""

from ._21_lkf import (  # noqa: F401
    NIS_STEP_BAND,
    S_PRIOR,
    S_TIME,
    STEP_ALPHA,
    STEP_STATIONS,
    TWO_STATION_S,
    check_nis_step_band,
    check_two_station_S,
    nis_step_band,
    step_stations_visible,
)
from ._21_lkf import RECORDS as _21_LKF_RECORDS

__all__ = ["EXERCISES", "check_nis_step_band", "check_two_station_S", "STEP_STATIONS", "STEP_ALPHA", "S_TIME",
           "S_PRIOR", "step_stations_visible"]

#: every exercise record of these notebooks, by id (in notebook order)
EXERCISES = {e.id: e for e in sorted((*_21_LKF_RECORDS,), key=lambda e: tuple(int(k) for k in e.id.split('.')))}
