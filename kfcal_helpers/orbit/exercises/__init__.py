"""Exercise checks of the orbit-determination notebooks (19-23).

Each ``check_<topic>(answer, *, settings...)`` takes the student's answer and returns a
:class:`~kfcal_helpers.exercises._core.Feedback` whose repr is one line: correct, or a hint at the likely
mistake, never the answer.  The right answer is computed from the package's model
(:mod:`kfcal_helpers.orbit`); the common wrong answers by making the mistake on purpose.  Each exercise
is one :class:`~kfcal_helpers.exercises._core.Exercise` record right above its check; the exercises'
numbers have one home, ``_shared``, and are the checks' defaults.  Pass the value you computed, with no
rounding (the tolerances are float-level); a rounded copy is told so.  No answer makes a check raise or
warn.

=========  ==========================================  ====================================
exercise   check                                       answer
=========  ==========================================  ====================================
19.1       :func:`check_station_measurement`           [rho, rhodot, phi] of one station, (3,)
19.2       :func:`check_visible_stations`              ids of the visible stations, (m,)
19.3       :func:`check_perturbed_period`              period of the perturbed orbit, s
20.1       :func:`check_gravity_jacobian`              A = df/dx at a state, (4, 4)
20.2       :func:`check_range_rate_row`                d rhodot_i/dx of one station, (4,)
20.3       :func:`check_expm_F`                        F = expm(dT A) on the nominal, (4, 4)
21.1       :func:`check_nis_step_band`                 one step's NIS band, (2,)
21.2       :func:`check_two_station_S`                 S of a two-station step, (6, 6)
22.1       :func:`check_ukf_phi_mean`                  the UKF's predicted phi, circular mean, rad
22.2       :func:`check_stacked_update`                EKF correction K nu of a 2-station update, (4,)
23.1       :func:`check_log_nis_band`                  time-averaged NIS bounds, dof summed, (2,)
23.2       :func:`check_step_nis_band`                 one step's NIS bounds, (2,)
=========  ==========================================  ====================================

The checks live one module per lesson (``_19_model``, ``_20_linearization``, ``_21_lkf``, ``_22_ekf_ukf``, ``_23_log``), each listing its records in ``RECORDS``; this
package re-exports every name, so ``from kfcal_helpers.orbit.exercises import check_...`` is the one
import path.
"""

from ._shared import A_X, EXPM_DT, MEAS_STATION, MEAS_T, MEAS_X, PERIOD_DX0, ROW_STATION, ROW_T, ROW_X, VIS_T, VIS_X  # noqa: F401
from ._shared import LOG_ALPHA, LOG_EMPTY_STEPS, LOG_ONE_STATION, LOG_TWO_STATIONS, LOG_STEP_ALPHA, LOG_STEP_STATIONS  # noqa: F401
from ._shared import UKF_ALPHA, UKF_BETA, UKF_KAPPA, UKF_PHI, UPD_P, UPD_STATIONS, UPD_T, UPD_X, UPD_Y  # noqa: F401
from ._19_model import (PERTURBED_PERIOD, STATION_MEASUREMENT, VISIBLE_STATIONS, check_perturbed_period,  # noqa: F401
                        check_station_measurement, check_visible_stations)
from ._19_model import RECORDS as _19_MODEL_RECORDS
from ._20_linearization import EXPM_F, GRAVITY_JACOBIAN, RANGE_RATE_ROW, check_expm_F, check_gravity_jacobian, check_range_rate_row  # noqa: F401
from ._20_linearization import RECORDS as _20_LINEARIZATION_RECORDS
from ._23_log import LOG_NIS_BAND, STEP_NIS_BAND, check_log_nis_band, check_step_nis_band  # noqa: F401
from ._23_log import RECORDS as _23_LOG_RECORDS

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

from ._22_ekf_ukf import STACKED_UPDATE, UKF_PHI_MEAN, check_stacked_update, check_ukf_phi_mean  # noqa: F401
from ._22_ekf_ukf import RECORDS as _22_EKF_UKF_RECORDS

__all__ = ["EXERCISES", "check_station_measurement", "check_visible_stations", "check_perturbed_period", "check_gravity_jacobian",
           "check_range_rate_row", "check_expm_F", "check_nis_step_band", "check_two_station_S",
           "STEP_STATIONS", "STEP_ALPHA", "S_TIME", "S_PRIOR", "step_stations_visible", "check_ukf_phi_mean", "check_stacked_update",
           "check_log_nis_band", "check_step_nis_band"]

#: every exercise record of these notebooks, by id (in notebook order)
EXERCISES = {e.id: e for e in sorted((*_19_MODEL_RECORDS, *_20_LINEARIZATION_RECORDS, *_21_LKF_RECORDS, *_22_EKF_UKF_RECORDS,
                                      *_23_LOG_RECORDS), key=lambda e: tuple(int(k) for k in e.id.split(".")))}
