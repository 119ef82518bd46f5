"""Exercise checks of notebook 09 (linearization): 09.1-09.4."""

from __future__ import annotations


import math
from dataclasses import replace

import numpy as np

from ..model import (
    N_MEAS,
    N_STATES,
    CoopParams,
    jacobian_A,
    jacobian_C,
    nominal_trajectory,
    observability_matrix,
)
from ...exercises._core import Exercise, Feedback, distinct_mistakes
from ...validation import require_int, require_positive, require_shape
from ...exercises._slips import matrix_names
from ._shared import (FDT_DT, FDT_X, NUM_ATOL, OMEGA_DT, NUM_RTOL, RANK_ROWS, RANK_WINDOWS, ROW_X, U0_DEFAULT, finite_of_size)


BEARING_ROW = Exercise(
    "09.1",
    praise="d(bearing)/dx: +-d_eta/r^2, -+d_xi/r^2 for the two vehicles, -1 for theta_g",
    hints={
        "vehicle_sign": "the UGV and UAV columns have opposite signs to yours: moving the UGV east decreases d_xi",
        "over_r": "the derivative of atan2(d_eta, d_xi) is divided by r squared, not by r",
        "swapped": "d_xi and d_eta are swapped: recheck which difference goes with the east and which with the north columns",
        "heading_plus": "check the sign of the heading entry: the bearing is a direction minus theta_g",
        "heading_zero": "the bearing also depends on the UGV's heading theta_g",
        "other_bearing": "that is the row of the other bearing (UAV to UGV): this one depends on theta_g, not theta_a",
        "range_row": "that is the range row (row 2 of C): this exercise asks for the first bearing",
    },
    components=tuple(f"the derivative by {s}" for s in ("xi_g", "eta_g", "theta_g", "xi_a", "eta_a", "theta_a")),
)


def check_bearing_row(answer, *, x=ROW_X) -> Feedback:
    """09.1: the first row of ``C = dh/dx`` (bearing UGV->UAV) at the configuration ``x``.

    answer : array (6,) -- derivatives with respect to [xi_g, eta_g, theta_g, xi_a, eta_a, theta_a]
        (1/m, 1/m, 1, 1/m, 1/m, 1)
    """
    x = require_shape("x", x, (N_STATES,))
    C = jacobian_C(x)
    row = C[0]
    dxi, deta = x[3] - x[0], x[4] - x[1]
    r2 = dxi ** 2 + deta ** 2
    r = math.sqrt(r2)
    sign = row.copy()
    sign[[0, 1, 3, 4]] *= -1
    over_r = row.copy()
    over_r[[0, 1, 3, 4]] *= r2 / r
    swapped = np.array([dxi / r2, -deta / r2, -1.0, -dxi / r2, deta / r2, 0.0])
    plus, zero = row.copy(), row.copy()
    plus[2], zero[2] = 1.0, 0.0
    wrong = [(sign, "vehicle_sign"), (over_r, "over_r"), (swapped, "swapped"), (plus, "heading_plus"),
             (zero, "heading_zero"), (C[2], "other_bearing"), (C[1], "range_row")]
    return BEARING_ROW.judge(answer, row, wrong, rtol=NUM_RTOL, atol=NUM_ATOL)


def euler_F(A, dt):
    return np.eye(N_STATES) + dt * A


F_DT = Exercise(
    "09.2",
    praise="F = I + dT A: a heading error moves each position by v dT per rad in one step",
    hints={
        "A_only": "that is A: F maps a state to the next one, so it starts from the identity",
        "no_dt": "the heading-to-position terms must scale with the step length dT",
        "notebook_dt": "that is F for the notebook's dT = 0.1 s: use this exercise's sampling interval",
        "transposed": "transposed: row i of F says how state i at k+1 depends on the states at k",
        "sign": "check the signs: d(cos theta)/d(theta) = -sin theta, d(sin theta)/d(theta) = +cos theta",
        "sin_cos": "sin and cos are swapped: the east rate v cos(theta) differentiates to -v sin(theta)",
        "speeds": "each vehicle's rows use its own speed (v_g = 2 m/s for the UGV, v_a = 12 m/s for the UAV)",
    },
    components=matrix_names("F", N_STATES),
)


def check_F_dt(answer, *, x=FDT_X, dt: float = FDT_DT, u=U0_DEFAULT, L: float = 0.5) -> Feedback:
    """09.2: ``F = I + dt A(x, u)`` for the sampling interval ``dt`` (s).

    answer : array (6, 6), dimensionless except the heading columns (m/rad)
    """
    x = require_shape("x", x, (N_STATES,))
    u = require_shape("u", u, (4,))
    dt, L = require_positive("dt", dt), require_positive("L", L)
    A = jacobian_A(x, u, L)
    expected = euler_F(A, dt)
    sign = -A
    sin_cos = np.zeros((6, 6))
    sin_cos[0, 2], sin_cos[1, 2] = -u[0] * math.cos(x[2]), u[0] * math.sin(x[2])
    sin_cos[3, 5], sin_cos[4, 5] = -u[2] * math.cos(x[5]), u[2] * math.sin(x[5])
    speeds = np.zeros((6, 6))  # each vehicle's rows with the other one's speed
    speeds[0, 2], speeds[1, 2] = -u[2] * math.sin(x[2]), u[2] * math.cos(x[2])
    speeds[3, 5], speeds[4, 5] = -u[0] * math.sin(x[5]), u[0] * math.cos(x[5])
    pairs = [(A, "A_only"), (euler_F(A, 1.0), "no_dt"), (euler_F(A, dt).T, "transposed"), (euler_F(sign, dt), "sign"),
             (euler_F(sin_cos, dt), "sin_cos"), (euler_F(speeds, dt), "speeds")]
    if abs(dt - 0.1) > 1e-12:
        pairs.append((euler_F(A, 0.1), "notebook_dt"))
    return F_DT.judge(answer, expected, pairs, rtol=NUM_RTOL, atol=NUM_ATOL)


def _ranks(rows, windows, start):
    p = CoopParams()
    x_nom = nominal_trajectory(p, n_samples=start + max(windows))
    F = euler_F(jacobian_A(x_nom, p.u0, p.L), p.dt)
    H = jacobian_C(x_nom)
    out = []
    for m in windows:
        O = observability_matrix(F[start:start + m - 1], H[start:start + m][:, list(rows)])
        out.append(int(np.linalg.matrix_rank(O)))
    return np.array(out, dtype=float)


OBS_RANK = Exercise(
    "09.3",
    praise="the UAV's heading becomes observable through its motion; the UGV stays unobservable",
    hints={
        "no_motion": "over several steps the motion adds information: which state moves the UAV's next GPS position?",
        "full": "none of these rows depends on the UGV's states: they cannot become observable",
        "all_rows": "those are the ranks with all five measurements: keep only the UAV's GPS rows (3 and 4)",
        "rows_count": "a rank cannot exceed the number of columns of O, the 6 states",
        "one_step": "at one instant O has only the two GPS rows",
        "whole": "a rank is a whole number: count the independent rows of O (np.linalg.matrix_rank)",
        "reversed": "the first entry is the window of m = 1 step, the second the longer one",
    },
    components=("the rank of the 1-step window", "the rank of the longer window"),
    units=False,
)


def check_obs_rank(answer, *, windows=RANK_WINDOWS, start: int = 0) -> Feedback:
    """09.3: ranks of the stacked observability matrix with only the UAV's GPS rows (3, 4) of H,
    for windows of ``windows`` steps (the first one of 1 step) starting at sample ``start`` of the nominal.

    answer : array (len(windows),) of integers
    """
    windows = tuple(require_int("windows", m, minimum=1) for m in windows)
    if len(windows) < 2 or windows[0] != 1:
        raise ValueError(f"windows must hold 1 and at least one longer window, got {windows}")
    rows = RANK_ROWS
    start = require_int("start", start, minimum=0)
    expected = _ranks(rows, windows, start)
    full = _ranks(tuple(range(N_MEAS)), windows, start)
    first = expected[0]
    pairs = [(np.full(len(windows), first), "no_motion"), (np.r_[first, np.full(len(windows) - 1, 6.0)], "full"),
             (full, "all_rows"), (np.r_[first, [len(rows) * m for m in windows[1:]]], "rows_count"),
             (np.r_[expected[-1], expected[1:]], "one_step"), (expected[::-1], "reversed")]
    wrong = [(v, key) for v, key in pairs if not np.array_equal(v, expected)]
    flat = finite_of_size(answer, len(windows))
    if flat is not None and not np.allclose(flat, np.round(flat)):
        return OBS_RANK.mistake("whole")
    E = OBS_RANK if len(windows) == 2 else replace(OBS_RANK, components=tuple(
        f"the rank of the {m}-step window" for m in windows))
    return E.judge(answer, expected, wrong)


OMEGA_Q = Exercise(
    "09.4",
    praise="Omega = dT I scales the noise's standard deviation by dT, so its covariance by dT²",
    hints={
        "one_dt": "Omega appears twice, on each side of Q: the covariance scales by dT², not dT",
        "no_omega": "that is Qtrue, the covariance of w_k; the state receives Omega w_k, with Omega = dT I",
        "notebook_dt": "use the exercise's sample period, not the notebook's 0.1 s",
        "divided": "Omega = dT I multiplies: Omega Qtrue Omega^T = dT² Qtrue, not Qtrue / dT²",
    },
    components=matrix_names("the entry ", N_STATES),
)


def check_omega_q(answer, *, dt: float = OMEGA_DT) -> Feedback:
    """09.4: the per-step state-noise covariance ``Omega Qtrue Omega^T`` (6, 6), in the units of Qtrue
    times s², of the course's model (``Omega = dt I``) for the sample period ``dt`` (s)."""
    dt = require_positive("dt", dt)
    p = CoopParams(dt=dt)
    expected = p.process_noise()
    Q = p.Qtrue
    pairs = [(dt * Q, "one_dt"), (Q, "no_omega"), (0.01 * Q, "notebook_dt"), (Q / dt**2, "divided")]
    return OMEGA_Q.judge(answer, expected, distinct_mistakes(pairs, expected, 1e-9), rtol=NUM_RTOL, atol=1e-15)


#: the exercise records of this lesson, in notebook order
RECORDS = (BEARING_ROW, F_DT, OBS_RANK, OMEGA_Q)
