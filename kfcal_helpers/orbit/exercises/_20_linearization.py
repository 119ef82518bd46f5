"""Exercise checks of notebook 20 (linearization of the orbit model): 20.1-20.3."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from ...exercises._core import Exercise, Feedback, distinct_mistakes
from ...validation import require_positive, require_shape
from ..model import jacobian_A, jacobian_C, jacobian_relative, nominal_state, station_states
from ..params import N_STATES
from ._shared import PARAMS, in_km, station_setting, A_X, EXPM_DT, NUM_ATOL, NUM_RTOL, ROW_STATION, ROW_T, ROW_X

__all__ = ["GRAVITY_JACOBIAN", "RANGE_RATE_ROW", "EXPM_F", "RECORDS", "check_gravity_jacobian", "check_range_rate_row",
           "check_expm_F"]

_P = PARAMS

GRAVITY_JACOBIAN = Exercise(
    "20.1",
    praise="A = df/dx: the kinematics rows and the gravity gradient mu (3 X^2 - r^2) / r^5, 3 mu X Y / r^5, ...",
    hints={
        "sign": "check the sign of the gravity gradient: d(-mu X / r^3)/dX = mu (3 X^2 - r^2) / r^5, positive along "
                "the radius",
        "constant_r": "r depends on X and Y too: differentiate 1/r^3 as well (d r/dX = X / r), not only the X in "
                      "front of it",
        "no_kinematics": "rows 1 and 3 (X and Y) of A are the kinematics: dX/dt = Xdot puts a 1 at (1, 2) and at "
                         "(3, 4) (counting from 1)",
        "swapped_xy": "d(-mu X / r^3)/dX has 3 X^2 (not 3 Y^2) in its numerator, and d(-mu Y / r^3)/dY has 3 Y^2",
    },
)


def check_gravity_jacobian(answer, *, x=A_X) -> Feedback:
    """20.1: the CT Jacobian ``A = df/dx`` (4, 4) of the two-body dynamics at the state ``x`` (4,)
    [X, Xdot, Y, Ydot] (km, km/s); entries in 1/s (kinematics) and 1/s^2 (gravity gradient).

    answer : array (4, 4)
    """
    x = require_shape("x", x, (N_STATES,))
    expected = jacobian_A(x, _P)
    X, Y = x[0], x[2]
    r2 = X * X + Y * Y
    r3 = r2 ** 1.5
    sign = expected.copy()
    sign[[1, 3]] *= -1
    constant_r = expected.copy()
    constant_r[1, [0, 2]] = -_P.mu / r3, 0.0
    constant_r[3, [0, 2]] = 0.0, -_P.mu / r3
    kin = expected.copy()
    kin[0, 1] = kin[2, 3] = 0.0
    swapped = expected.copy()
    swapped[1, 0], swapped[3, 2] = expected[3, 2], expected[1, 0]
    wrong = [(sign, "sign"), (constant_r, "constant_r"), (kin, "no_kinematics"), (swapped, "swapped_xy")]
    return in_km(GRAVITY_JACOBIAN.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL,
                                        atol=1e-15))


RANGE_RATE_ROW = Exercise(
    "20.2",
    praise="d rhodot/dx: the relative velocity across the line of sight over rho, and the line of sight's direction",
    hints={
        "rho_constant": "rho depends on X and Y too: d/dX of (dX dXdot + dY dYdot) / rho has a second term, "
                        "-rhodot dX / rho^2",
        "station_fixed": "the station moves: the relative velocity is Xdot - Xidot (and Ydot - Yidot), with the "
                         "station's velocity from the Earth's rotation",
        "range_row": "that is the range row (d rho/dx): this exercise asks for the range rate's",
        "velocity_only": "rhodot also depends on the position: moving the satellite turns the line of sight",
        "zero_based": "that is the next station's row: station i sits at omegaE t + (i - 1) pi/6",
    },
    components=("d rhodot/dX", "d rhodot/dXdot", "d rhodot/dY", "d rhodot/dYdot"),
)


def check_range_rate_row(answer, *, x=ROW_X, t: float = ROW_T, station: int = ROW_STATION) -> Feedback:
    """20.2: the row ``d rhodot_i / dx`` (4,) of ``C_i`` for station ``station`` (1..12) at time ``t`` (s) and
    the satellite state ``x`` (4,) (km, km/s); entries in 1/s and 1 (dimensionless).

    answer : array (4,)
    """
    x, t, station = station_setting(x, t, station)
    C = jacobian_C(x, t, _P)
    i = station - 1
    expected = C[i, 1]
    d = x - station_states(t, _P)[i]
    rho = np.hypot(d[0], d[2])
    rho_constant = np.array([d[1] / rho, d[0] / rho, d[3] / rho, d[2] / rho])
    fixed = d.copy()
    fixed[[1, 3]] = x[[1, 3]]
    wrong = [(rho_constant, "rho_constant"), (jacobian_relative(fixed)[1], "station_fixed"), (C[i, 0], "range_row"),
             (np.array([0.0, d[0] / rho, 0.0, d[2] / rho]), "velocity_only"),
             (C[station % _P.n_stations, 1], "zero_based")]
    return in_km(RANGE_RATE_ROW.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL,
                                      atol=NUM_ATOL))


EXPM_F = Exercise(
    "20.3",
    praise="F = expm(dT A): over 600 s the Euler form I + dT A is far off",
    hints={
        "euler": "that is I + dT A, the first two terms of the series: the exercise asks for the matrix exponential "
                 "(scipy.linalg.expm)",
        "elementwise": "np.exp takes the exponential of each entry: the matrix exponential is scipy.linalg.expm",
        "no_dt": "the exponent is dT A, not A",
        "dt_outside": "dT goes inside the exponential: expm(dT A), not dT expm(A)",
    },
)


def check_expm_F(answer, *, dt: float = EXPM_DT) -> Feedback:
    """20.3: ``F = expm(dt A)`` (4, 4) with ``A`` the CT Jacobian on the circular nominal at t = 0, for the
    sampling interval ``dt`` (s).

    answer : array (4, 4)
    """
    dt = require_positive("dt", dt)
    A = jacobian_A(nominal_state(0.0, _P), _P)
    expected = expm(dt * A)
    with np.errstate(over="ignore"):
        elementwise = np.exp(dt * A)
    wrong = [(np.eye(N_STATES) + dt * A, "euler"), (elementwise, "elementwise"), (expm(A), "no_dt"),
             (dt * expm(A), "dt_outside")]
    wrong = [(v, k) for v, k in wrong if np.all(np.isfinite(v))]
    return in_km(EXPM_F.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL, atol=NUM_ATOL))


#: the exercise records of this lesson, in notebook order
RECORDS = (GRAVITY_JACOBIAN, RANGE_RATE_ROW, EXPM_F)
