"""Exercise checks of notebook 11 (the extended Kalman filter): 11.1-11.2."""

from __future__ import annotations


import math

import numpy as np

from ..model import (
    MEAS_ANGLES,
    N_MEAS,
    N_STATES,
    CoopParams,
    jacobian_A,
    measurement_residual,
    nominal_trajectory,
    step,
    wrap_angle,
)
from ...exercises._core import (Exercise, Feedback)
from ...validation import require_finite, require_shape
from ...exercises._slips import matrix_names
from ._shared import (EKF_T, EKF_X, FN_ATOL, FN_RESULT, FN_RTOL, MEAS_NAMES, NUM_ATOL, NUM_RTOL, call_checked,
                      pi_for_minus_pi)
from ._09_linearization import euler_F


def _residual_cases():
    """(a, b) column-vector pairs (5, 1) of 11.1: bearing differences across +-pi and exactly +-pi."""
    rows = (
        ((3.1, 30.0, -3.1, 100.0, -50.0), (-3.1, 25.0, 3.0, 98.0, -45.0)),
        ((math.pi / 2, 10.0, -math.pi / 2, 0.0, 0.0), (-math.pi / 2, 12.0, math.pi / 2, 1.0, 1.0)),
        ((0.1, 50.0, -0.2, -20.0, 7.0), (0.3, 40.0, 0.1, -30.0, 0.0)),
    )
    return [(np.array(a).reshape(N_MEAS, 1), np.array(b).reshape(N_MEAS, 1)) for a, b in rows]


EKF_RESIDUAL = Exercise(
    "11.1",
    praise="bearing differences wrapped, range and GPS untouched, column vectors kept",
    hints={
        "no_wrap": "that is np.subtract, filterpy's default: wrap the bearing differences to (-pi, pi]",
        "wrap_all": "wrap only the bearings (components 0 and 2): range and GPS are not angles",
        "reversed": "the residual is a - b (measurement minus prediction), not b - a",
        "mod_2pi": "the wrapped difference must land in (-pi, pi], not in [0, 2 pi)",
        "shape": "right values, but filterpy passes column vectors (5, 1) and needs the same shape back",
    },
    components=MEAS_NAMES,
    angles=MEAS_ANGLES,
)


def check_ekf_residual(fn) -> Feedback:
    """11.1: the student's ``fn(a, b)`` for filterpy's ``residual=``: ``a - b`` with the two
    bearings wrapped to (-pi, pi], for column vectors (5, 1), returning (5, 1).

    A result of exactly -pi instead of pi is accepted (the same angle).
    """
    E = EKF_RESIDUAL
    cases = _residual_cases()
    outs, fb = call_checked(E, fn, cases, (N_MEAS, 1), "residual(a, b)")
    if fb is not None:
        return fb
    answer = pi_for_minus_pi(np.array([o.reshape(N_MEAS) for o in outs]), MEAS_ANGLES)
    flat = [(a[:, 0], b[:, 0]) for a, b in cases]

    def mod(a, b):
        d = a - b
        d[list(MEAS_ANGLES)] = np.mod(d[list(MEAS_ANGLES)], 2 * np.pi)
        return d

    def each(f):
        return pi_for_minus_pi(np.array([f(a, b) for a, b in flat]), MEAS_ANGLES)

    expected = each(measurement_residual)
    wrong = [
        (each(np.subtract), "no_wrap"),
        (each(lambda a, b: wrap_angle(a - b)), "wrap_all"),
        (each(lambda a, b: measurement_residual(b, a)), "reversed"),
        (each(mod), "mod_2pi"),
    ]
    fb = E.judge(answer, expected, wrong, rtol=FN_RTOL, atol=FN_ATOL, what=FN_RESULT)
    if fb.correct and any(o.shape != (N_MEAS, 1) for o in outs):
        return E.mistake("shape")
    return fb


def _fd_jacobian(fun, x, eps=1e-6):
    cols = []
    for i in range(x.size):
        d = np.zeros_like(x)
        d[i] = eps
        cols.append(_state_diff(fun(x + d), fun(x - d)) / (2 * eps))
    return np.stack(cols, axis=-1)


def _state_diff(a, b):
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    d[[2, 5]] = wrap_angle(d[[2, 5]])
    return d


EKF_F = Exercise(
    "11.2",
    praise="F_k = I + dT A at the posterior, where the step starts",
    hints={
        "prior": "that F is evaluated at the predicted state: F_k linearizes the step from where it starts, the posterior",
        "nominal": "that is the LKF's F (on the nominal): the EKF relinearizes about its own estimate",
        "A_only": "that is A: F maps a state to the next one, so it starts from the identity",
        "no_dt": "the heading-to-position terms must scale with the step length dT",
        "transposed": "transposed: row i of F says how state i at k+1 depends on the states at k",
        "exact_map": "that is the Jacobian of the exact arc map: the filter uses the first-order F of the notebook",
    },
    components=matrix_names("F", N_STATES),
)


def check_ekf_F(answer, *, x_post=EKF_X, t: float = EKF_T) -> Feedback:
    """11.2: the EKF's ``F_k`` for the step from the posterior ``x_post`` (6,) at time ``t`` (s),
    with the nominal control u0 = [2, -pi/18, 12, pi/25], dt = 0.1 s and L = 0.5 m.

    answer : array (6, 6)
    """
    x = require_shape("x_post", x_post, (N_STATES,))
    p = CoopParams()
    t = require_finite("t", t)
    k = int(round(t / p.dt))
    if k < 0 or k >= p.n_samples or abs(k * p.dt - t) > 1e-9:
        raise ValueError(f"t must be a sample time k dt in [0, {p.duration:g}] s, got {t!r}")
    A = jacobian_A(x, p.u0, p.L)
    expected = euler_F(A, p.dt)
    prior = step(x, p.u0, p.dt, p.L)
    x_nom = nominal_trajectory(p, n_samples=k + 1)[k]
    exact = _fd_jacobian(lambda z: step(z, p.u0, p.dt, p.L), x)
    wrong = [
        (euler_F(jacobian_A(prior, p.u0, p.L), p.dt), "prior"),
        (euler_F(jacobian_A(x_nom, p.u0, p.L), p.dt), "nominal"),
        (A, "A_only"),
        (euler_F(A, 1.0), "no_dt"),
        (expected.T, "transposed"),
        (exact, "exact_map"),
    ]
    return EKF_F.judge(answer, expected, wrong, rtol=NUM_RTOL, atol=NUM_ATOL)


#: the exercise records of this lesson, in notebook order
RECORDS = (EKF_RESIDUAL, EKF_F)
