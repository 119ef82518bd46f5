"""Exercise checks of the calibration notebooks: 01-07, 14 (its calibration exercises), 15, 16 and 17.

Every ``check_<topic>(answer, *, settings...)`` takes the student's answer (a number, an array, a
set of names or a function, as the exercise text says) positionally, and the exercise's settings
as keywords only, and returns a one-line :class:`~kfcal_helpers.exercises.Feedback`.  The right
answer is computed here from the project's model (:mod:`kfcal_helpers.calibration`) or from first
principles, with the exercise's settings as keyword defaults; the common wrong answers are
computed the same way.  Each exercise is one :class:`~kfcal_helpers.exercises.Exercise` record
(id, praise, generic hint, the hint of each recognised mistake), defined right above its check;
:data:`EXERCISES` lists them by id.

A check never raises or warns because of the answer: a placeholder (``None`` or ``...``) gives
"not answered yet", a malformed answer (a string, a wrong shape, a complex number, an integer too
large for a float, NaN, a function that raises) gives a one-line hint.  Bad *settings* raise
``ValueError`` naming the setting.  One answer-format rule for every exercise
(:data:`~kfcal_helpers.exercises.FORMAT_RULE`): pass the value you computed, with no rounding; the
tolerances below are float-level, or, where stated, accept a documented approximation.

The checks live one module per lesson, in notebook order (``_01_truth`` ... ``_17_live_demo``; what
they share in ``_shared``); each module lists its records in ``RECORDS``, and this package re-exports
every name, so ``from kfcal_helpers.calibration.exercises import check_...`` is the one import path.

Exercise ids are ``"NN.k"``: notebook NN, exercise k.  Worked solutions are in
``notebooks/solutions/NN_*.ipynb``.
"""

from ._01_truth import check_euler_position_gap_max, check_euler_truth, check_euler_velocity_gap
from ._01_truth import RECORDS as _01_TRUTH_RECORDS
from ._02_imu import check_dead_reckoning, check_imu_drift, check_imu_output, check_imu_random_walk, check_imu_std_band
from ._02_imu import RECORDS as _02_IMU_RECORDS
from ._03_gps import GPS_FIX_RATE, check_gps_dz, check_gps_fix_indices, check_gps_measurement, check_gps_rms_band
from ._03_gps import RECORDS as _03_GPS_RECORDS
from ._04_error_state import GAMMA_OTHER_SIGN_PRAISE, check_gamma_100hz, check_m0, check_phi_100hz, check_phi_fix_to_fix
from ._04_error_state import RECORDS as _04_ERROR_STATE_RECORDS
from ._05_filter import check_first_gain, check_predict_only, check_second_gain
from ._05_filter import RECORDS as _05_FILTER_RECORDS
from ._06_monte_carlo import (MEAN_ERROR_TEST, SIMULTANEOUS_NEES_ENTRIES, check_fisher_band, check_mc_nis_bounds,
                              check_mean_error_band, check_simultaneous_nees_band)
from ._06_monte_carlo import RECORDS as _06_MONTE_CARLO_RECORDS
from ._07_mismatch import check_apparent_bias, check_mismatch_failures, check_trapezoid_velocity
from ._07_mismatch import RECORDS as _07_MISMATCH_RECORDS
from ._14_mistakes import check_failing_checks_gps_sigma, check_phi02_coupling_change
from ._14_mistakes import RECORDS as _14_MISTAKES_RECORDS
from ._15_outages import check_outage_mask, check_outage_sigma
from ._15_outages import RECORDS as _15_OUTAGES_RECORDS
from ._16_minimum_variance import BATCH_TWO_FIXES_DZ, check_batch_two_fixes, check_smoothed_bias_sigma
from ._16_minimum_variance import RECORDS as _16_MINIMUM_VARIANCE_RECORDS
from ._17_live_demo import check_demo_first_fix_sigma, check_demo_ratio_band, first_fix_sigmas, ratio_band
from ._17_live_demo import RECORDS as _17_LIVE_DEMO_RECORDS

__all__ = ["GAMMA_OTHER_SIGN_PRAISE", "GPS_FIX_RATE", "check_euler_velocity_gap", "check_euler_position_gap_max", "check_euler_truth", "check_imu_drift", "check_imu_random_walk", "check_imu_std_band", "check_gps_fix_indices", "check_gps_dz", "check_gps_rms_band", "check_phi_100hz", "check_gamma_100hz", "check_phi_fix_to_fix", "check_m0", "check_predict_only", "check_first_gain", "check_second_gain", "check_mc_nis_bounds", "check_fisher_band", "check_simultaneous_nees_band", "check_mean_error_band", "MEAN_ERROR_TEST", "SIMULTANEOUS_NEES_ENTRIES", "check_apparent_bias", "check_trapezoid_velocity", "check_mismatch_failures", "check_failing_checks_gps_sigma", "check_phi02_coupling_change", "check_outage_mask", "check_outage_sigma", "check_batch_two_fixes", "BATCH_TWO_FIXES_DZ", "check_smoothed_bias_sigma", "check_demo_first_fix_sigma", "check_demo_ratio_band", "EXERCISES", "first_fix_sigmas", "ratio_band", "check_dead_reckoning", "check_imu_output", "check_gps_measurement"]

#: every exercise record of these notebooks, by id (in notebook order)
EXERCISES = {e.id: e for e in sorted((*_01_TRUTH_RECORDS, *_02_IMU_RECORDS, *_03_GPS_RECORDS, *_04_ERROR_STATE_RECORDS, *_05_FILTER_RECORDS, *_06_MONTE_CARLO_RECORDS, *_07_MISMATCH_RECORDS, *_14_MISTAKES_RECORDS, *_15_OUTAGES_RECORDS, *_16_MINIMUM_VARIANCE_RECORDS, *_17_LIVE_DEMO_RECORDS), key=lambda e: tuple(int(k) for k in e.id.split('.')))}
