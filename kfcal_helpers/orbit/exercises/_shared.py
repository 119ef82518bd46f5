"""What the orbit-determination checks share: the exercises' numbers (as the notebooks' exercise texts
state them) and tolerances."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...exercises._core import Feedback
from ...validation import require_finite, require_int, require_shape
from ..params import N_STATES, OrbitParams

#: the course's parameters, which every exercise uses
PARAMS = OrbitParams()

# ---------------------------------------------------------------------------
# Parameters of the exercises (as stated in the notebooks' exercise texts); the course's OrbitParams
# (mu = 398600 km^3/s^2, RE = 6378 km, omegaE = 2 pi / 86400 rad/s, 12 stations) otherwise.
#: 19.1: the satellite's state [X, Xdot, Y, Ydot] (km, km/s), the time (s) and the station (1..12)
MEAS_X = (-1200.0, -7.5, 6560.0, -1.4)
MEAS_T = 3000.0
MEAS_STATION = 4
#: 19.2: the satellite's state and the time (s) at which the visible stations are asked
VIS_X = (6640.0, 1.0, -880.0, 7.7)
VIS_T = 9000.0
#: 19.3: the initial perturbation [dX, dXdot, dY, dYdot] (km, km/s) of the orbit whose period is asked
PERIOD_DX0 = (0.0, 0.075, 0.0, -0.021)
#: 20.1: the state at which A is asked
A_X = (5000.0, -4.0, 4400.0, 5.0)
#: 20.2: the state, time (s) and station (1..12) of the range-rate row of C_i
ROW_X = (-1200.0, -7.5, 6560.0, -1.4)
ROW_T = 3000.0
ROW_STATION = 4
#: 20.3: the sampling interval (s) of F = expm(dt A) on the nominal at t = 0
EXPM_DT = 600.0

NUM_RTOL, NUM_ATOL = 1e-7, 1e-12  # numeric answers: the computed value (no rounding), any float-exact formula


def station_setting(x, t, station: int) -> tuple[np.ndarray, float, int]:
    """The settings of a one-station exercise, checked: ``x`` (4,) the satellite state (km, km/s), ``t`` the time
    (s, finite), ``station`` (1..n_stations, the course's numbering); ValueError naming the argument otherwise."""
    return (require_shape("x", x, (N_STATES,)), require_finite("t", t),
            require_int("station", station, minimum=1, maximum=PARAMS.n_stations))


#: the orbit exercises' units, named in a units slip's hint instead of the harness's SI units (m, m/s)
KM_UNITS = "(the orbit exercises work in km, km/s, s and rad: not m or m/s)"


def in_km(feedback: Feedback) -> Feedback:
    """``feedback`` with a units slip's hint naming the orbit exercises' units (km, km/s, s, rad) instead of the
    shared harness's SI units (m, m/s): the right answer scaled by 1000 is an answer in m."""
    message = feedback.message
    start = message.find("(the exercise works in SI units")
    if feedback.correct or start < 0:
        return feedback
    end = message.find(")", start)
    return replace(feedback, message=message[:start] + KM_UNITS + message[end + 1:])

#: 22.1: the phi entries (rad) of the nine measurement sigma points of one station, the centre point first, and
#: the notebook's MerweScaledSigmaPoints(4, alpha, beta, kappa) of the UKF
UKF_PHI = (-3.0832, -2.8332, -2.9832, -2.7332, -3.0332, 3.0000, 3.0800, 2.9200, 3.1400)
UKF_ALPHA, UKF_BETA, UKF_KAPPA = 1.0, 2.0, 0.0
#: 22.2: one EKF update: the time (s), the stations (1..12) with a measurement, the prior x- (4,) and the
#: diagonal of P- (km, km/s), and the two stations' measurements [rho, rhodot, phi] (km, km/s, rad)
UPD_T = 576.0
UPD_STATIONS = (4, 5)
UPD_X = (-1991.4, -7.3743, 6374.2, -2.3039)
UPD_P = (0.04, 1e-6, 0.04, 1e-6)
UPD_Y = ((1724.40, 6.60, -3.1410), (1735.45, -7.35, 0.6070))
#: 23.1: a log's updates with one station (3 dof) and with two (6 dof), its steps without a station, and alpha
LOG_ONE_STATION = 1200
LOG_TWO_STATIONS = 180
LOG_EMPTY_STEPS = 20
LOG_ALPHA = 0.05
#: 23.2: the stations visible at the step whose NIS band is asked, and alpha
LOG_STEP_STATIONS = 2
LOG_STEP_ALPHA = 0.01
BOUNDS_RTOL = 1e-9  # chi-square bounds: the computed quantiles (no rounding)
