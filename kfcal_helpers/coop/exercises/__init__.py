"""Exercise checks of notebooks 08-13 and 18 (cooperative localization).

Each ``check_<topic>(answer, *, settings...)`` takes the student's answer (numbers, or a function for
the exercises that ask for code) and returns a :class:`~kfcal_helpers.exercises._core.Feedback`
whose repr is one line: correct, or a hint at the likely mistake.  The right answer is
computed from the project's model (:mod:`kfcal_helpers.coop`) or from first principles;
the common wrong answers are computed by making the mistake on purpose.  Each exercise is one
:class:`~kfcal_helpers.exercises._core.Exercise` record (id, praise, hint, hints by mistake, never
the answer) right above its check.  The exercise's parameters are keyword-only arguments, with
the values of the exercise text as defaults (each number's one home is ``_shared``, where the
exercise texts' values are listed).  One answer-format rule for every exercise
(:data:`~kfcal_helpers.exercises.FORMAT_RULE`): pass the value you computed, with no rounding (the
tolerances are float-level); a rounded copy is told so.  No answer makes a check raise or warn.

A function answer is called through :func:`~kfcal_helpers.exercises._core.call_student` on fixed
test inputs (copies, so it may modify them); an exception it raises becomes a hint naming the
exception type, and a function that returns ``None`` (a body still ``...``) counts as not answered yet.

=========  ========================================  ==================================
exercise   check                                     answer
=========  ========================================  ==================================
08.1       :func:`check_step_map`                    state after one step, (6,)
08.2       :func:`check_measurement`                 measurement vector, (5,)
09.1       :func:`check_bearing_row`                 first row of C, (6,)
09.2       :func:`check_F_dt`                        F for another dt, (6, 6)
09.3       :func:`check_obs_rank`                    ranks for two windows, (2,)
09.4       :func:`check_omega_q`                     Omega Qtrue Omega^T for dT = 0.05 s, (6, 6)
10.1       :func:`check_mc_bounds`                   NEES and NIS bounds, (2, 2)
10.2       :func:`check_lkf_innovation`              function (y, y_nom, H, dx) -> (5,)
11.1       :func:`check_ekf_residual`                function (a, b) -> (5, 1)
11.2       :func:`check_ekf_F`                       F at the posterior, (6, 6)
12.1       :func:`check_merwe_weights`               [lambda, Wm0, Wc0, Wi], (4,)
12.2       :func:`check_circular_mean`               function (angles, weights) -> float
13.1       :func:`check_log_nis_bounds`              time-averaged NIS bounds, (2,)
13.2       :func:`check_sparse_nis_bounds`           the same, every 10th measurement, (2,)
18.1       :func:`check_subset_nis_bounds`           NIS bounds with 3 of 5 measurements, (2,)
18.2       :func:`check_lost_directions`             lost directions of three subsets, (3,)
=========  ========================================  ==================================

The checks live one module per lesson, in notebook order (``_08_model`` ... ``_18_live_demo``; the
exercises' numbers, tolerances and the calls of a student's function in ``_shared``); each module
lists its records in ``RECORDS``, and this package re-exports every name, so
``from kfcal_helpers.coop.exercises import check_...`` is the one import path.
"""

from ._shared import EKF_T, EKF_X, FDT_DT, FDT_X, LOG_ALPHA, LOG_SAMPLES, MC_RUNS, MEAS_X, MERWE, RANK_ROWS, RANK_WINDOWS, ROW_X, SPARSE_EVERY, SPARSE_SAMPLES, STEP_DT, STEP_U, STEP_X, OMEGA_DT  # noqa: F401
from ._08_model import MEASUREMENT, MEASURE_FUNCTION, STEP_MAP, check_measure_function, check_measurement, check_step_map  # noqa: F401
from ._08_model import RECORDS as _08_MODEL_RECORDS
from ._09_linearization import BEARING_ROW, F_DT, OBS_RANK, OMEGA_Q, check_F_dt, check_bearing_row, check_obs_rank, check_omega_q  # noqa: F401
from ._09_linearization import RECORDS as _09_LINEARIZATION_RECORDS
from ._10_lkf import LKF_INNOVATION, MC_BOUNDS, check_lkf_innovation, check_mc_bounds  # noqa: F401
from ._10_lkf import RECORDS as _10_LKF_RECORDS
from ._11_ekf import EKF_F, EKF_RESIDUAL, check_ekf_F, check_ekf_residual  # noqa: F401
from ._11_ekf import RECORDS as _11_EKF_RECORDS
from ._12_ukf import CIRCULAR_MEAN, MERWE_WEIGHTS, NEGATIVE_WM0_PRAISE, check_circular_mean, check_merwe_weights  # noqa: F401
from ._12_ukf import RECORDS as _12_UKF_RECORDS
from ._13_log import LOG_NIS_BOUNDS, SPARSE_NIS_BOUNDS, check_log_nis_bounds, check_sparse_nis_bounds  # noqa: F401
from ._13_log import RECORDS as _13_LOG_RECORDS
from ._18_live_demo import LOST_DIRECTIONS, LOST_SUBSETS, SUBSET_NIS_BOUNDS, check_lost_directions, check_subset_nis_bounds, lost_directions  # noqa: F401
from ._18_live_demo import RECORDS as _18_LIVE_DEMO_RECORDS

__all__ = ["EXERCISES", "check_step_map", "check_measurement", "check_bearing_row", "check_F_dt", "check_obs_rank", "check_omega_q", "check_mc_bounds", "check_lkf_innovation", "check_ekf_residual", "check_ekf_F", "check_merwe_weights", "check_circular_mean", "check_log_nis_bounds", "check_sparse_nis_bounds", "check_subset_nis_bounds", "check_lost_directions", "lost_directions", "LOST_SUBSETS", "check_measure_function"]

#: every exercise record of these notebooks, by id (in notebook order)
EXERCISES = {e.id: e for e in sorted((*_08_MODEL_RECORDS, *_09_LINEARIZATION_RECORDS, *_10_LKF_RECORDS, *_11_EKF_RECORDS, *_12_UKF_RECORDS, *_13_LOG_RECORDS, *_18_LIVE_DEMO_RECORDS), key=lambda e: tuple(int(k) for k in e.id.split('.')))}
