"""Exercise checks of notebooks 08-13 and 18 (cooperative localization).

Each ``check_<topic>(answer, *, settings...)`` takes the student's answer (numbers, or a function for
the exercises that ask for code) and returns a :class:`~kfcal_helpers.exercises._core.Feedback`
whose repr is one line: correct, or a hint at the likely mistake.  The right answer is
computed from the project's model (:mod:`kfcal_helpers.coop`) or from first principles;
the common wrong answers are computed by making the mistake on purpose.  Each exercise is one
:class:`~kfcal_helpers.exercises._core.Exercise` record (id, praise, hint, hints by mistake, never
the answer) right above its check.  The exercise's parameters are keyword-only arguments, with
the values of the exercise text as defaults.  One answer-format rule for every exercise
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
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import stats

from ..consistency import chi2_bounds
from .model import (
    MEAS_ANGLES,
    N_MEAS,
    N_STATES,
    CoopParams,
    dynamics,
    jacobian_A,
    jacobian_C,
    measure,
    measurement_residual,
    nominal_trajectory,
    observability_matrix,
    step,
    wrap_angle,
    jacobian_step,
    wrap_measurement,
    wrap_state,
)
from ..exercises._core import (GENERIC_HINT, Exercise, Feedback, as_array, call_student, chi2_average_bounds, distinct_mistakes, matches,
                               too_large, unanswered)
from ..validation import require_finite, require_instance, require_int, require_positive, require_probability, require_shape

__all__ = [
    "EXERCISES",
    "check_step_map",
    "check_measurement",
    "check_bearing_row",
    "check_F_dt",
    "check_obs_rank",
    "check_mc_bounds",
    "check_lkf_innovation",
    "check_ekf_residual",
    "check_ekf_F",
    "check_merwe_weights",
    "check_circular_mean",
    "check_log_nis_bounds",
    "check_sparse_nis_bounds",
    "check_subset_nis_bounds",
    "check_lost_directions",
    "lost_directions",
    "LOST_SUBSETS",
]

_U0 = tuple(CoopParams().u0)

# ---------------------------------------------------------------------------
# Parameters of the exercises (as stated in the notebooks' exercise text)
#: 08.1: state (m, m, rad, m, m, rad), control (m/s, rad, m/s, rad/s), step (s), wheelbase (m)
STEP_X = (2.0, 1.0, 3.0, -30.0, 40.0, -0.5)
STEP_U = (1.0, math.pi / 8, 8.0, 0.0)
STEP_DT = 0.5
#: 08.2: the configuration whose measurement vector is asked
MEAS_X = (5.0, -3.0, 2.5, -20.0, -10.0, -1.0)
#: 09.1: the configuration of the bearing row of C
ROW_X = (3.0, -4.0, 0.7, 15.0, 1.0, 2.0)
#: 09.2: the state and the other sampling interval
FDT_X = (0.0, 0.0, 2.0, 0.0, 0.0, -0.8)
FDT_DT = 0.05
#: 09.3: rows of H kept (the UAV's GPS) and window lengths, from t = 0 along the nominal
RANK_ROWS = (3, 4)
RANK_WINDOWS = (1, 10)
#: 10.1: runs and significance
MC_RUNS = 20
#: 11.2: the EKF posterior at t = 3 s
EKF_X = (4.0, -2.0, 2.6, -40.0, 10.0, -2.2)
EKF_T = 3.0
#: 12.1: Merwe scaled sigma points
MERWE = {"n": 6, "alpha": 0.5, "beta": 2.0, "kappa": 1.0}
#: 13.1: a 15 s log (151 samples, the first one without a measurement), alpha = 0.01
LOG_SAMPLES = 151
LOG_ALPHA = 0.01
#: 13.2: the 100 s log (1001 samples) with every 10th measurement kept
SPARSE_EVERY = 10
SPARSE_SAMPLES = 1001

_NUM_RTOL, _NUM_ATOL = 1e-7, 1e-9  # numeric answers: the computed value (no rounding), any float-exact formula
_FN_RTOL, _FN_ATOL = 1e-7, 1e-9  # outputs of a student's function (same float formula)
_BOUNDS_RTOL = 1e-9  # chi-square bounds: the computed quantiles (no rounding)


def _finite_of_size(answer, size):
    """``answer`` as a flat float array when it has ``size`` finite entries, else None (a larger answer
    before any conversion)."""
    if too_large(answer, np.zeros(size)) is not None:
        return None
    a = as_array(answer)
    if a is None or a.size != size or not np.all(np.isfinite(a)):
        return None
    return a.reshape(size)


def _call(exercise: Exercise, fn, cases, out_shape: tuple, what: str, size_hint: str | None = None):
    """Call the student's ``fn`` on every case (:func:`call_student`, arguments as float copies) and
    check each output: numbers of ``out_shape`` entries, all finite.  Returns ``(outputs, None)``
    (a list of float arrays) or ``(None, Feedback)``."""
    outs, fb = call_student(exercise.id, fn, cases, what, convert=lambda a: np.array(a, dtype=float))
    if fb is not None:
        return None, fb
    arrays = []
    for out in outs:
        arr = as_array(out)
        if arr is None:
            return None, exercise.feedback(False, f"your function must return numbers (shape {out_shape}), "
                                                  f"it returned {type(out).__name__}")
        if arr.size != int(np.prod(out_shape)):
            return None, exercise.feedback(False, size_hint or f"your function must return shape {out_shape}, "
                                                               f"it returned {arr.shape}")
        if not np.all(np.isfinite(arr)):
            return None, exercise.feedback(False, "your function returned NaN or inf: look for a division by zero")
        arrays.append(arr)
    return arrays, None


def _wrapped(answer, expected, wrap):
    """``(answer with its angles wrapped by wrap, unwrapped)``: ``unwrapped`` is True when only the
    wrapping was missing (the wrapped answer is right, the answer as given is not)."""
    flat = _finite_of_size(answer, np.size(expected))
    if flat is None:
        return answer, False
    wrapped = wrap(flat)
    right = matches(wrapped, expected, _NUM_RTOL, _NUM_ATOL) and not matches(flat, expected, _NUM_RTOL, _NUM_ATOL)
    return wrapped, right


def _pi_for_minus_pi(values, idx=None):
    """Copy of ``values`` with entries equal to -pi (to rounding) replaced by pi: both are
    the same angle, and (-pi, pi] vs [-pi, pi) is a convention, not a mistake."""
    v = np.array(values, dtype=float)
    sel = v if idx is None else v[..., list(idx)]
    sel = np.where(np.abs(sel + np.pi) < 1e-9, np.pi, sel)
    if idx is None:
        return sel
    v[..., list(idx)] = sel
    return v


# ---------------------------------------------------------------------------
# 08: the nonlinear model
def _arc_variant(x, u, dt, L, *, length="sinc", heading="mid", yaw_L=True, trig="ok"):
    """The one-step map with a chosen mistake (for the wrong answers of 08.1)."""
    x = np.asarray(x, dtype=float)
    vg, phi, va, wa = u
    wg = vg * math.tan(phi) / (L if yaw_L else 1.0)
    out = np.empty(6)
    for i, v, w in ((0, vg, wg), (3, va, wa)):
        th, half = x[i + 2], 0.5 * w * dt
        if length == "sinc":
            d = v * dt * (math.sin(half) / half if half != 0 else 1.0)
        elif length == "np_sinc":
            d = v * dt * float(np.sinc(half))
        else:
            d = v * dt
        direction = th + half if heading == "mid" else th
        c, s = (math.cos(direction), math.sin(direction)) if trig == "ok" else (math.sin(direction), math.cos(direction))
        out[i], out[i + 1], out[i + 2] = x[i] + d * c, x[i + 1] + d * s, th + w * dt
    return wrap_state(out)


STEP_MAP = Exercise(
    "08.1",
    praise="each vehicle moved along the chord of its arc (the UAV, with omega = 0, on a straight line)",
    hints={
        "euler": "that is an Euler step: over dT each vehicle moves along the chord of its arc, not along its initial heading",
        "start_heading": "the chord points along the mean heading of the step (theta_k + omega dT/2), not along theta_k",
        "np_sinc": "numpy's np.sinc(z) is sin(pi z)/(pi z), the normalized sinc: divide its argument by pi",
        "no_sinc": "the chord is shorter than the arc: its length carries the factor sinc(omega dT/2)",
        "no_L": "the UGV's yaw rate is v_g tan(phi_g) / L: the wheelbase is missing",
        "cos_sin": "east (xi) goes with cos(heading) and north (eta) with sin(heading)",
        "wrap": "right position, but wrap the headings to (-pi, pi]",
        "nan": "NaN or inf in your answer: the form v/omega divides by zero when omega = 0 (the UAV flies straight); use the sinc form",
    },
)


def check_step_map(answer, *, x=STEP_X, u=STEP_U, dt: float = STEP_DT, L: float = 0.5) -> Feedback:
    """08.1: the state one step ``dt`` (s) after ``x`` under the constant control ``u``.

    answer : array (6,) -- [xi_g, eta_g, theta_g, xi_a, eta_a, theta_a] (m, m, rad, m, m, rad),
        headings wrapped to (-pi, pi]
    x : (6,) state; u : (4,) control [v_g, phi_g, v_a, omega_a]; dt, L : s, m (> 0)
    """
    x = require_shape("x", x, (N_STATES,))
    u = require_shape("u", u, (4,))
    dt, L = require_positive("dt", dt), require_positive("L", L)
    E = STEP_MAP
    expected = step(x, u, dt, L)
    a = as_array(answer)
    if not unanswered(answer) and a is not None and a.size == N_STATES and not np.all(np.isfinite(a)):
        return E.mistake("nan")
    answer, unwrapped = _wrapped(answer, expected, wrap_state)
    if unwrapped:
        return E.mistake("wrap")
    wrong = [
        (wrap_state(x + dt * dynamics(x, u, L)), "euler"),
        (_arc_variant(x, u, dt, L, heading="start"), "start_heading"),
        (_arc_variant(x, u, dt, L, length="np_sinc"), "np_sinc"),
        (_arc_variant(x, u, dt, L, length="none"), "no_sinc"),
        (_arc_variant(x, u, dt, L, yaw_L=False), "no_L"),
        (_arc_variant(x, u, dt, L, trig="swapped"), "cos_sin"),
    ]
    return E.judge(answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL)


def _measure_variant(x, mistake):
    """h(x) with one mistake (for the wrong answers of 08.2), bearings wrapped."""
    xg, eg, tg, xa, ea, ta = np.asarray(x, dtype=float)
    dxi, deta = xa - xg, ea - eg
    b1, b2 = math.atan2(deta, dxi) - tg, math.atan2(-deta, -dxi) - ta
    rng, gps = math.hypot(dxi, deta), [xa, ea]
    if mistake == "atan2_order":
        b1, b2 = math.atan2(dxi, deta) - tg, math.atan2(-dxi, -deta) - ta
    elif mistake == "atan":
        with np.errstate(divide="ignore"):
            direction = float(np.arctan(np.divide(deta, dxi)))
        b1, b2 = direction - tg, direction - ta
    elif mistake == "no_heading":
        b1, b2 = b1 + tg, b2 + ta
    elif mistake == "heading_sign":
        b1, b2 = b1 + 2 * tg, b2 + 2 * ta
    elif mistake == "same_direction":
        b2 = math.atan2(deta, dxi) - ta
    elif mistake == "range_squared":
        rng = rng ** 2
    elif mistake == "ugv_gps":
        gps = [xg, eg]
    return wrap_measurement(np.array([b1, rng, b2, *gps]))


MEASUREMENT = Exercise(
    "08.2",
    praise="two wrapped bearings, the range and the UAV's GPS",
    hints={
        "wrap": "right values, but the bearings must be wrapped to (-pi, pi]",
        "atan2_order": "atan2 takes the north difference first: atan2(d_eta, d_xi)",
        "atan": "arctan(d_eta/d_xi) loses the quadrant (d_xi < 0 here): use atan2",
        "no_heading": "a bearing is measured from the vehicle's own heading: subtract it",
        "heading_sign": "the heading is subtracted from the direction, not added",
        "same_direction": "the UAV looks back at the UGV: its line of sight is the reverse direction, atan2(-d_eta, -d_xi)",
        "range_squared": "the range is the distance, not its square",
        "ugv_gps": "the GPS is on the UAV: the last two entries are the UAV's position",
    },
)


def check_measurement(answer, *, x=MEAS_X) -> Feedback:
    """08.2: the noise-free measurement vector ``h(x)`` of the configuration ``x`` (6,).

    answer : array (5,) -- [bearing UGV->UAV, range, bearing UAV->UGV, xi_a, eta_a]
        (rad, m, rad, m, m), bearings wrapped to (-pi, pi]
    """
    x = require_shape("x", x, (N_STATES,))
    E = MEASUREMENT
    expected = measure(x)
    answer, unwrapped = _wrapped(answer, expected, wrap_measurement)
    if unwrapped:
        return E.mistake("wrap")
    wrong = [(_measure_variant(x, m), m) for m in
             ("atan2_order", "atan", "no_heading", "heading_sign", "same_direction", "range_squared", "ugv_gps")]
    return E.judge(answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL)


# ---------------------------------------------------------------------------
# 09: linearization
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
    return BEARING_ROW.judge(answer, row, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL)


def _F(A, dt):
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
)


def check_F_dt(answer, *, x=FDT_X, dt: float = FDT_DT, u=_U0, L: float = 0.5) -> Feedback:
    """09.2: ``F = I + dt A(x, u)`` for the sampling interval ``dt`` (s).

    answer : array (6, 6), dimensionless except the heading columns (m/rad)
    """
    x = require_shape("x", x, (N_STATES,))
    u = require_shape("u", u, (4,))
    dt, L = require_positive("dt", dt), require_positive("L", L)
    A = jacobian_A(x, u, L)
    expected = _F(A, dt)
    sign = -A
    sin_cos = np.zeros((6, 6))
    sin_cos[0, 2], sin_cos[1, 2] = -u[0] * math.cos(x[2]), u[0] * math.sin(x[2])
    sin_cos[3, 5], sin_cos[4, 5] = -u[2] * math.cos(x[5]), u[2] * math.sin(x[5])
    speeds = np.zeros((6, 6))  # each vehicle's rows with the other one's speed
    speeds[0, 2], speeds[1, 2] = -u[2] * math.sin(x[2]), u[2] * math.cos(x[2])
    speeds[3, 5], speeds[4, 5] = -u[0] * math.sin(x[5]), u[0] * math.cos(x[5])
    pairs = [(A, "A_only"), (_F(A, 1.0), "no_dt"), (_F(A, dt).T, "transposed"), (_F(sign, dt), "sign"),
             (_F(sin_cos, dt), "sin_cos"), (_F(speeds, dt), "speeds")]
    if abs(dt - 0.1) > 1e-12:
        pairs.append((_F(A, 0.1), "notebook_dt"))
    return F_DT.judge(answer, expected, pairs, rtol=_NUM_RTOL, atol=_NUM_ATOL)


def _ranks(rows, windows, start):
    p = CoopParams()
    x_nom = nominal_trajectory(p, n_samples=start + max(windows))
    F = _F(jacobian_A(x_nom, p.u0, p.L), p.dt)
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
    },
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
             (np.r_[expected[-1], expected[1:]], "one_step")]
    wrong = [(v, key) for v, key in pairs if not np.array_equal(v, expected)]
    flat = _finite_of_size(answer, len(windows))
    if flat is not None and not np.allclose(flat, np.round(flat)):
        return OBS_RANK.mistake("whole")
    return OBS_RANK.judge(answer, expected, wrong)


# ---------------------------------------------------------------------------
# 10: LKF
def _normal_bounds(dim, n, alpha, z=None):
    """The normal approximation dim ± z sqrt(2 dim / n) (a common wrong answer); z defaults to the exact quantile."""
    z = stats.norm.ppf(1 - alpha / 2) if z is None else z
    return np.array([dim - z * math.sqrt(2 * dim / n), dim + z * math.sqrt(2 * dim / n)])


MC_BOUNDS = Exercise(
    "10.1",
    praise="chi-square with N n degrees of freedom, divided by N = {N}, alpha/2 in each tail",
    hints={
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "swapped_dims": "the dimensions are swapped: NEES has the state's dimension, NIS the measurement's",
        "not_divided": "the bounds are for the run average: divide the chi-square quantiles by N",
        "dof_N": "the sum over N runs of an n-dimensional statistic has N*n degrees of freedom, not N",
        "N_minus_1": "the N runs are independent with known covariance: N*n degrees of freedom, not (N-1)*n",
        "order": "give the lower bound first, then the upper one",
        "normal": "close, but that is the normal approximation: use the chi-square quantiles",
        "notebook_N": "those are the bounds for the notebook's N = 50: use this exercise's number of runs",
        "one_run": "those are the bounds of a single run: the average of N runs has N*n degrees of freedom (not n), "
                   "and its quantiles are divided by N",
    },
)


def check_mc_bounds(answer, *, n_runs: int = MC_RUNS, alpha: float = 0.05) -> Feedback:
    """10.1: the two-sided bounds of the run-averaged NEES and NIS for ``n_runs`` Monte Carlo runs.

    answer : array (2, 2) -- [[NEES lower, NEES upper], [NIS lower, NIS upper]] (dimensionless),
        the computed values (no rounding)
    """
    N = require_int("n_runs", n_runs, minimum=2)
    alpha = require_probability("alpha", alpha)
    expected = np.array([chi2_bounds(N_STATES, N, alpha), chi2_bounds(N_MEAS, N, alpha)])

    def both(**kw):
        return np.array([chi2_average_bounds(N_STATES, N, alpha, **kw), chi2_average_bounds(N_MEAS, N, alpha, **kw)])

    pairs = [(both(one_sided=True), "one_sided"), (expected[::-1], "swapped_dims"), (both(divide_by=1), "not_divided"),
             (np.array([chi2_average_bounds(N_STATES, N, alpha, dof=N), chi2_average_bounds(N_MEAS, N, alpha, dof=N)]),
              "dof_N"),
             (np.array([chi2_average_bounds(N_STATES, N - 1, alpha), chi2_average_bounds(N_MEAS, N - 1, alpha)]),
              "N_minus_1"),
             (expected[:, ::-1], "order"),
             (np.array([chi2_average_bounds(N_STATES, N, alpha, dof=N_STATES, divide_by=1),
                        chi2_average_bounds(N_MEAS, N, alpha, dof=N_MEAS, divide_by=1)]), "one_run"),
             (np.array([_normal_bounds(N_STATES, N, alpha), _normal_bounds(N_MEAS, N, alpha)]), "normal")]
    if abs(alpha - 0.05) < 1e-12:  # the same with the usual 1.96
        pairs.append((np.array([_normal_bounds(N_STATES, N, alpha, 1.96), _normal_bounds(N_MEAS, N, alpha, 1.96)]),
                      "normal"))
    if N != 50:
        pairs.append((np.array([chi2_bounds(N_STATES, 50, alpha), chi2_bounds(N_MEAS, 50, alpha)]), "notebook_N"))
    return replace(MC_BOUNDS, praise=MC_BOUNDS.praise.format(N=N)).judge(answer, expected, pairs, rtol=_BOUNDS_RTOL,
                                                                      atol=0.0)


def _lkf_cases():
    """(y, y_nom, H, dx_prior) test inputs of 10.2: bearings near +-pi, a large range innovation."""
    cases = []
    for x_lin, dx, nu in (
        ((0.0, 0.0, 0.0, -50.0, -8.0, 0.4), (0.5, -0.3, 0.05, 1.0, 0.4, -0.02), (-0.3, 4.0, 0.1, -2.0, 5.5)),
        ((10.0, 5.0, 1.0, 40.0, -20.0, 2.5), (-0.4, 0.8, 0.1, -1.5, 0.6, -0.6), (0.2, -6.0, 2.9, 4.5, -3.5)),
        ((-3.0, 2.0, -2.0, 60.0, 30.0, 0.0), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (0.05, 1.0, -0.1, 0.5, -0.5)),
    ):
        y_nom = measure(np.array(x_lin))
        H = jacobian_C(np.array(x_lin))
        y = wrap_measurement(y_nom + H @ np.array(dx) + np.array(nu))
        cases.append((y, y_nom, H, np.array(dx)))
    return cases


LKF_INNOVATION = Exercise(
    "10.2",
    praise="perturbation innovation with the bearings wrapped after the subtraction",
    hints={
        "no_wrap": "the bearing components jump by 2 pi across +-pi: wrap them",
        "no_nominal": "the LKF works with perturbations: the measurement perturbation is y - y_nom",
        "plus": "the predicted measurement perturbation H dx is subtracted, not added",
        "wrap_all": "wrap only the bearings (components 0 and 2): range and GPS are not angles",
        "wrap_early": "wrap the whole innovation after subtracting H dx (it can cross +-pi again)",
        "no_H": "subtract the predicted measurement perturbation H dx",
    },
)


def check_lkf_innovation(fn) -> Feedback:
    """10.2: the student's ``fn(y, y_nom, H, dx_prior)`` -> LKF innovation (5,), called on fixed cases.

    y, y_nom : (5,) measurement and nominal measurement (rad, m, rad, m, m); H : (5, 6);
    dx_prior : (6,) predicted perturbation.  Right: ``(y - y_nom) - H dx_prior``, bearings wrapped.
    """
    cases = _lkf_cases()
    outs, fb = _call(LKF_INNOVATION, fn, cases, (N_MEAS,), "lkf_innovation(y, y_nom, H, dx_prior)")
    if fb is not None:
        return fb
    answer = _pi_for_minus_pi(np.array([o.reshape(N_MEAS) for o in outs]), MEAS_ANGLES)

    def each(f):
        return _pi_for_minus_pi(np.array([f(y, yn, H, dx) for y, yn, H, dx in cases]), MEAS_ANGLES)

    def wrap_early(y, yn, H, dx):
        return wrap_measurement(y - yn) - H @ dx

    expected = each(lambda y, yn, H, dx: wrap_measurement((y - yn) - H @ dx))
    wrong = [
        (each(lambda y, yn, H, dx: (y - yn) - H @ dx), "no_wrap"),
        (each(lambda y, yn, H, dx: wrap_measurement(y - H @ dx)), "no_nominal"),
        (each(lambda y, yn, H, dx: wrap_measurement((y - yn) + H @ dx)), "plus"),
        (each(lambda y, yn, H, dx: wrap_angle((y - yn) - H @ dx)), "wrap_all"),
        (each(wrap_early), "wrap_early"),
        (each(lambda y, yn, H, dx: wrap_measurement(y - yn)), "no_H"),
    ]
    return LKF_INNOVATION.judge(answer, expected, wrong, rtol=_FN_RTOL, atol=_FN_ATOL)


# ---------------------------------------------------------------------------
# 11: EKF
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
)


def check_ekf_residual(fn) -> Feedback:
    """11.1: the student's ``fn(a, b)`` for filterpy's ``residual=``: ``a - b`` with the two
    bearings wrapped to (-pi, pi], for column vectors (5, 1), returning (5, 1).

    A result of exactly -pi instead of pi is accepted (the same angle).
    """
    E = EKF_RESIDUAL
    cases = _residual_cases()
    outs, fb = _call(E, fn, cases, (N_MEAS, 1), "residual(a, b)")
    if fb is not None:
        return fb
    answer = _pi_for_minus_pi(np.array([o.reshape(N_MEAS) for o in outs]), MEAS_ANGLES)
    flat = [(a[:, 0], b[:, 0]) for a, b in cases]

    def mod(a, b):
        d = a - b
        d[list(MEAS_ANGLES)] = np.mod(d[list(MEAS_ANGLES)], 2 * np.pi)
        return d

    def each(f):
        return _pi_for_minus_pi(np.array([f(a, b) for a, b in flat]), MEAS_ANGLES)

    expected = each(measurement_residual)
    wrong = [
        (each(np.subtract), "no_wrap"),
        (each(lambda a, b: wrap_angle(a - b)), "wrap_all"),
        (each(lambda a, b: measurement_residual(b, a)), "reversed"),
        (each(mod), "mod_2pi"),
    ]
    fb = E.judge(answer, expected, wrong, rtol=_FN_RTOL, atol=_FN_ATOL)
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
    expected = _F(A, p.dt)
    prior = step(x, p.u0, p.dt, p.L)
    x_nom = nominal_trajectory(p, n_samples=k + 1)[k]
    exact = _fd_jacobian(lambda z: step(z, p.u0, p.dt, p.L), x)
    wrong = [
        (_F(jacobian_A(prior, p.u0, p.L), p.dt), "prior"),
        (_F(jacobian_A(x_nom, p.u0, p.L), p.dt), "nominal"),
        (A, "A_only"),
        (_F(A, 1.0), "no_dt"),
        (expected.T, "transposed"),
        (exact, "exact_map"),
    ]
    return EKF_F.judge(answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL)


# ---------------------------------------------------------------------------
# 12: UKF
def _merwe(n, alpha, beta, kappa, *, lam=None, wc_extra=None, wi_den=None):
    """[lambda, Wm0, Wc0, Wi]; the keywords make one mistake (inf/NaN where it divides by zero)."""
    lam = np.float64(alpha ** 2 * (n + kappa) - n if lam is None else lam)
    with np.errstate(divide="ignore", invalid="ignore"):
        wm0 = lam / (n + lam)
        wc0 = wm0 + (1 - alpha ** 2 + beta if wc_extra is None else wc_extra)
        wi = np.float64(1.0) / (2 * (n + lam) if wi_den is None else np.float64(wi_den))
    return np.array([lam, wm0, wc0, wi])


MERWE_WEIGHTS = Exercise(
    "12.1",
    praise="the mean weights sum to 1",
    hints={
        "alpha_not_squared": "lambda uses alpha squared",
        "wc0_equals_wm0": "the covariance weight of the centre point has an extra term (1 - alpha^2 + beta)",
        "wc0_alpha": "the extra term of Wc0 uses alpha squared",
        "wc0_beta_only": "the extra term of Wc0 is 1 - alpha^2 + beta, not beta alone",
        "wi_lambda": "the outer weights divide by 2 (n + lambda), not by 2 lambda",
        "n_points": "n is the state dimension (6), not the number of sigma points",
        "no_kappa": "kappa is missing from lambda",
        "no_minus_n": "lambda is missing its - n term",
        "sum": "your mean weights do not sum to 1 (Wm0 + 2n Wi): recheck lambda and the weights",
    },
)
#: the praise of 12.1 when the centre weight is negative
NEGATIVE_WM0_PRAISE = "note the negative centre weight Wm0: the weights still sum to 1"


def check_merwe_weights(answer, *, n: int = MERWE["n"], alpha: float = MERWE["alpha"],
                        beta: float = MERWE["beta"], kappa: float = MERWE["kappa"]) -> Feedback:
    """12.1: Merwe's scaled sigma-point parameter and weights.

    answer : array (4,) -- [lambda, Wm0, Wc0, Wi] (dimensionless): lambda, the mean and covariance
        weights of the centre point, and the weight of each of the 2n other points
    """
    n = require_int("n", n, minimum=1)
    alpha, beta, kappa = require_positive("alpha", alpha), require_finite("beta", beta), require_finite("kappa", kappa)
    if abs(alpha ** 2 * (n + kappa)) < 1e-12:
        raise ValueError("alpha and kappa must give n + lambda != 0")
    expected = _merwe(n, alpha, beta, kappa)
    lam = expected[0]
    pairs = [
        (_merwe(n, alpha, beta, kappa, lam=alpha * (n + kappa) - n), "alpha_not_squared"),
        (_merwe(n, alpha, beta, kappa, wc_extra=0.0), "wc0_equals_wm0"),
        (_merwe(n, alpha, beta, kappa, wc_extra=1 - alpha + beta), "wc0_alpha"),
        (_merwe(n, alpha, beta, kappa, wc_extra=beta), "wc0_beta_only"),
        (_merwe(n, alpha, beta, kappa, wi_den=2 * lam), "wi_lambda"),
        (_merwe(2 * n + 1, alpha, beta, kappa), "n_points"),
        (_merwe(n, alpha, beta, 0.0), "no_kappa"),
        (_merwe(n, alpha, beta, kappa, lam=alpha ** 2 * (n + kappa)), "no_minus_n"),
    ]
    wrong = [(v, key) for v, key in pairs if np.all(np.isfinite(v)) and not np.allclose(v, expected)]
    E = MERWE_WEIGHTS if expected[1] >= 0 else replace(MERWE_WEIGHTS, praise=NEGATIVE_WM0_PRAISE)
    fb = E.judge(answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL)
    flat = _finite_of_size(answer, 4)
    with np.errstate(all="ignore"):  # 1e308 entries: an overflowing sum is simply not 1
        off_sum = flat is not None and not abs(flat[1] + 2 * n * flat[3] - 1.0) <= 1e-3
    if not fb.correct and fb.answered and fb.message == GENERIC_HINT and off_sum:
        return E.mistake("sum")
    return fb


def _circular_cases():
    """(angles, weights) test inputs of 12.2 (rad, dimensionless)."""
    return [
        (np.array([3.0, -3.0, 2.9, -3.1]), np.array([0.25, 0.25, 0.25, 0.25])),
        (np.array([0.2, -0.4, 6.0]), np.array([0.5, 0.3, 0.2])),
        (np.array([1.0, 2.0, 1.5]), np.array([-1.0, 1.0, 1.0])),
        (np.array([2.5, -2.8]), np.array([0.7, 0.3])),
    ]


CIRCULAR_MEAN = Exercise(
    "12.2",
    praise="atan2 of the weighted sine and cosine sums, right across +-pi and with a negative weight",
    hints={
        "plain": "that is the plain weighted mean: angles near +pi and -pi average to about 0 instead of pi",
        "unweighted": "use the weights: sum w_i sin(theta_i) and sum w_i cos(theta_i)",
        "atan2_order": "atan2 takes the sine sum first: atan2(sum w sin, sum w cos)",
        "shifted": "shifting the angles into [0, 2 pi) only moves the problem from pi to 0",
        "arctan": "arctan of the ratio loses the quadrant (the cosine sum can be negative): use atan2",
        "size": "the circular mean of a set of angles is one angle: return a single float",
    },
)


def check_circular_mean(fn) -> Feedback:
    """12.2: the student's ``fn(angles, weights)`` -> weighted circular mean (rad, one float in
    (-pi, pi]), called on fixed sets of angles (m,) and weights (m,), one of them negative."""
    E = CIRCULAR_MEAN
    cases = _circular_cases()
    outs, fb = _call(E, fn, cases, (1,), "circular_mean(angles, weights)", size_hint=E.hints["size"])
    if fb is not None:
        return fb
    answer = _pi_for_minus_pi(np.array(outs).reshape(len(cases)))

    def each(f):
        return _pi_for_minus_pi(np.array([f(a, w) for a, w in cases]))

    expected = each(lambda a, w: math.atan2(np.dot(w, np.sin(a)), np.dot(w, np.cos(a))))
    wrong = [
        (each(lambda a, w: np.dot(w, a)), "plain"),
        (each(lambda a, w: math.atan2(np.sin(a).sum(), np.cos(a).sum())), "unweighted"),
        (each(lambda a, w: math.atan2(np.dot(w, np.cos(a)), np.dot(w, np.sin(a)))), "atan2_order"),
        (each(lambda a, w: float(wrap_angle(np.dot(w, np.mod(a, 2 * np.pi))))), "shifted"),
        (each(lambda a, w: math.atan(np.dot(w, np.sin(a)) / np.dot(w, np.cos(a)))), "arctan"),
    ]
    return E.judge(answer, expected, wrong, rtol=_FN_RTOL, atol=_FN_ATOL)


# ---------------------------------------------------------------------------
# 13: the log; fewer measurements
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
             (_normal_bounds(N_MEAS, K, alpha), "normal"),
             (_normal_bounds(N_MEAS, K, alpha, stats.norm.ppf(1 - alpha / 2).round(2)), "normal")]
    if abs(alpha - 0.05) > 1e-12:
        extra.append((np.array(chi2_bounds(N_MEAS, K, 0.05)), "notebook_alpha"))
    E = replace(LOG_NIS_BOUNDS, praise=LOG_NIS_BOUNDS.praise.format(K=K))
    return E.judge(answer, expected, _nis_bounds_wrong(K, alpha, extra), rtol=_BOUNDS_RTOL, atol=0.0)


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
    return E.judge(answer, expected, _nis_bounds_wrong(K, alpha, extra), rtol=_BOUNDS_RTOL, atol=0.0)


# ---------------------------------------------------------------------------
# 18: the live demo
_RTOL_NIS = 1e-9   # NIS bounds: the computed quantiles (K = 1000 vs 1001 differ by 3e-5)



SUBSET_NIS_BOUNDS = Exercise(
    "18.1",
    praise="{m} degrees of freedom per update, K = {K} updates, divided by K",
    hint="the time average of K independent χ²(m) values: K times it is χ²(mK)",
    hints={
        "dim5": "the NIS of an update that uses m measurements has m degrees of freedom, not always 5",
        "count_nan": "count only the samples with a measurement: the log's first row (t = 0) is NaN",
        "not_divided": "these bound the SUM of the NIS values; the time average is that sum divided by K",
        "one_sided": "a two-sided test at α = 0.05 puts α/2 = 0.025 in each tail",
        "normal": "close: that is the normal approximation m ± 1.96 √(2m/K); use the chi-square quantiles (scipy.stats.chi2.ppf or chi2_bounds)",
    },
)


def check_subset_nis_bounds(answer, *, n_meas: int = 3, n_samples: int = 1001, alpha: float = 0.05) -> Feedback:
    """Exercise 18.1: the two-sided ``1 - alpha`` bounds ``[lower, upper]`` (dimensionless),
    shape (2,), of the time-averaged NIS of one run that uses ``n_meas`` of the 5 measurements,
    on a log of ``n_samples`` samples whose first sample has no measurement."""
    m = require_int("n_meas", n_meas, minimum=1)
    if m > N_MEAS:
        raise ValueError(f"n_meas must be an integer in 1..{N_MEAS}, got {m}")
    n_samples = require_int("n_samples", n_samples, minimum=3)
    alpha = require_probability("alpha", alpha)
    K = n_samples - 1
    right = np.array(chi2_bounds(m, K, alpha))
    z = stats.norm.ppf(1 - alpha / 2)
    pairs = [
        (chi2_bounds(N_MEAS, K, alpha), "dim5"),
        (chi2_bounds(m, K + 1, alpha), "count_nan"),
        (right * K, "not_divided"),
        (stats.chi2.ppf([alpha, 1 - alpha], m * K) / K, "one_sided"),
        (m + np.array([-1.0, 1.0]) * z * np.sqrt(2 * m / K), "normal"),
        (m + np.array([-1.0, 1.0]) * round(z, 2) * np.sqrt(2 * m / K), "normal"),  # with z rounded (1.96)
    ]
    E = replace(SUBSET_NIS_BOUNDS, praise=SUBSET_NIS_BOUNDS.praise.format(m=m, K=K))
    return E.judge(answer, right, distinct_mistakes(pairs, right, _RTOL_NIS), rtol=_RTOL_NIS, atol=0.0)


#: the measurement subsets of exercise 18.2: no bearings, no GPS north, bearings only (notebook 18
#: prints all five, no range, no GPS and GPS only before it)
LOST_SUBSETS = ((1, 3, 4), (0, 1, 2, 3), (0, 2))


def lost_directions(subsets=LOST_SUBSETS, window: int = 10, params: CoopParams | None = None,
                    exact: bool = True) -> np.ndarray:
    """6 - rank of the stacked observability matrix (``observability_matrix``, rank by
    ``np.linalg.matrix_rank``) of the linearized DT model along the nominal, over the first
    ``window`` samples, with only the rows ``subset`` of H; one integer per subset.

    ``exact=True`` uses the exact Jacobian of the one-step map (``jacobian_step``);
    ``exact=False`` the Euler ``F = I + dt A``, which makes a rotation of the whole scene look
    weakly observable (a small but non-zero singular value), because it is the Jacobian of the
    Euler step and not of the arcs that generated the nominal."""
    p = require_instance("params", params, CoopParams, allow_none=True) or CoopParams()
    window = require_int("window", window, minimum=1)
    x = nominal_trajectory(p, window)
    if window < 2:
        F = np.zeros((0, 6, 6))
    elif exact:
        F = jacobian_step(x[:-1], p.u0, p.dt, p.L)
    else:
        F = np.eye(N_STATES) + p.dt * jacobian_A(x[:-1], p.u0, p.L)
    H = jacobian_C(x)
    out = []
    for sub in subsets:
        rows = [require_int("subsets", i, minimum=0) for i in sub]
        if not rows or max(rows) >= N_MEAS or len(set(rows)) != len(rows):
            raise ValueError(f"subsets must hold distinct measurement indices 0..4, got {tuple(sub)}")
        out.append(N_STATES - np.linalg.matrix_rank(observability_matrix(F, H[:, rows])))
    return np.array(out, dtype=float)


LOST_DIRECTIONS = Exercise(
    "18.2",
    praise="without the bearings nothing is lost; without the GPS north only the common north shift (1); with the bearings alone the common translation (2) and a rotation of the whole scene (1), while the vehicles' known speeds fix the scale",
    hint="build O as in the notebook's observability cell, with the rows of each subset, F the exact jacobian_step, and count 6 - rank",
    hints={
        "ranks": "those are ranks; the exercise asks how many directions are lost: 6 - rank",
        "euler": "check which F you used: the exercise asks first for the exact Jacobian of the one-step map, jacobian_step, not the Euler F = I + ΔT A (that is the follow-up question); then compute 6 - rank again",
        "reversed": "right counts, wrong order: give them as [no bearings, no GPS north, bearings only]",
        "north_observable": "without the GPS north, move both vehicles north together: does any bearing, the range or the GPS east change?",
        "north_both_lost": "for the subset without the GPS north, test the common shifts one at a time: which of the remaining rows of H change when both vehicles move east together, and which when they move north together? Then compute the rank",
        "bearings_observable": "with the bearings alone, move both vehicles by the same vector: does either bearing change?",
        "bearings_scale_lost": "O stacks 10 samples of a moving scene, not one snapshot: what the bearings cannot see at one sample is not what they cannot see over the window; compute the rank of the stacked O",
        "no_bearings_lost": "for the subset without the bearings, count with the stacked O over all 10 samples, not from one sample's geometry: build O with rows (1, 3, 4) and compute 6 - rank",
    },
)


def check_lost_directions(answer, *, window: int = 10) -> Feedback:
    """Exercise 18.2: for the subsets no bearings ``(1, 3, 4)``, no GPS north ``(0, 1, 2, 3)`` and
    bearings only ``(0, 2)``, the number of state directions that are unobservable over the first
    ``window`` samples of the nominal (6 - rank of the stacked observability matrix of the
    linearized DT model with the exact Jacobian of the one-step map); answer: 3 integers.
    Without the GPS north the common north shift is lost (1); with the bearings alone the common
    translation (2) and a rotation of the whole scene (1); the Euler ``F = I + dt A`` makes the
    rotation look weakly observable, hence 2 there: it is the Jacobian of the Euler step, not of the
    arcs that generated the nominal (an artefact of that mismatch, not information)."""
    window = require_int("window", window, minimum=2)
    right = lost_directions(LOST_SUBSETS, window)
    a = as_array(answer)
    if a is not None and a.size == 3 and np.all(np.isfinite(a)) and not np.allclose(a, np.round(a)):
        return LOST_DIRECTIONS.feedback(False, "a number of directions is a whole number: 6 minus a rank")
    pairs = [(N_STATES - right, "ranks"), (lost_directions(LOST_SUBSETS, window, exact=False), "euler"),
             (right * np.array([1, 0, 1]), "north_observable"), (right + np.array([0, 1, 0]), "north_both_lost"),
             (right * np.array([1, 1, 0]), "bearings_observable"), (right + np.array([0, 0, 1]), "bearings_scale_lost"),
             (right[::-1], "reversed")]
    for lost in (1, 2, 3):
        pairs.append((right + np.array([lost, 0, 0]), "no_bearings_lost"))
    return LOST_DIRECTIONS.judge(answer, right, distinct_mistakes(pairs, right, 0.0), rtol=0.0, atol=1e-9)


#: every exercise of this module by id
EXERCISES = {e.id: e for e in (STEP_MAP, MEASUREMENT, BEARING_ROW, F_DT, OBS_RANK, MC_BOUNDS, LKF_INNOVATION,
                               EKF_RESIDUAL, EKF_F, MERWE_WEIGHTS, CIRCULAR_MEAN, LOG_NIS_BOUNDS, SPARSE_NIS_BOUNDS,
                               SUBSET_NIS_BOUNDS, LOST_DIRECTIONS)}


# ---------------------------------------------------------------------------
# 08.3: the measurement function written by the student, for one state or a stack of states
def _measure_fn_cases():
    """State arrays of 08.3: one state (6,) and a stack (4, 6) whose UGV-to-UAV bearing lies near +-pi
    (before and after subtracting the heading), with headings near +-pi and the UAV west of the UGV."""
    one = np.array([5.0, -3.0, 2.5, -20.0, -10.0, -1.0])
    stack = np.array([
        [10.0, 0.0, 1.5708, -60.0, 0.0, -1.5708],       # the nominal start: UAV due west
        [0.0, 0.0, -3.0, -40.0, 1.0, 3.1],              # bearing direction near pi, heading near -pi
        [2.0, 1.0, 3.0, -30.0, -1.5, -2.9],             # direction near -pi
        [-5.0, 4.0, 0.3, 35.0, 60.0, 2.0],              # UAV north-east: no wrapping needed
    ])
    return [(one,), (stack,)]


def _measure_fn_variant(x, mistake):
    """The measurement function with one mistake (wrong answers of 08.3), for x (..., 6)."""
    x = np.asarray(x, dtype=float)
    dxi, deta = x[..., 3] - x[..., 0], x[..., 4] - x[..., 1]
    direction = np.arctan2(deta, dxi)
    back = np.arctan2(-deta, -dxi)
    th_g, th_a = x[..., 2], x[..., 5]
    if mistake == "atan2_order":
        direction, back = np.arctan2(dxi, deta), np.arctan2(-dxi, -deta)
    elif mistake == "swapped_heading":
        th_g, th_a = th_a, th_g
    elif mistake == "same_direction":
        back = direction
    b1, b2 = direction - th_g, back - th_a
    if mistake != "no_wrap":
        b1, b2 = wrap_angle(b1), wrap_angle(b2)
    if mistake == "degrees":
        b1, b2 = np.degrees(b1), np.degrees(b2)
    rng = np.hypot(dxi, deta)
    gps_e, gps_n = (x[..., 0], x[..., 1]) if mistake == "ugv_gps" else (x[..., 3], x[..., 4])
    return np.stack([b1, rng, b2, gps_e, gps_n], axis=-1)


MEASURE_FUNCTION = Exercise(
    "08.3",
    praise="h(x) for one state and for a stack of states: bearings wrapped, each from its own vehicle's heading",
    hint="compare with the measurement formula: two bearings (each minus its own vehicle's heading, wrapped), the range, the UAV's east and north",
    hints={
        "atan2_order": "np.arctan2 takes the north difference first: np.arctan2(d_eta, d_xi)",
        "no_wrap": "the bearings leave (-pi, pi]: wrap them after subtracting the heading",
        "swapped_heading": "each bearing is measured from its own vehicle's heading: the UGV's bearing minus theta_g (x[..., 2]), the UAV's minus theta_a (x[..., 5])",
        "same_direction": "the UAV looks back at the UGV: its line of sight is the reverse direction, np.arctan2(-d_eta, -d_xi)",
        "degrees": "the bearings are in radians, not degrees",
        "ugv_gps": "the GPS is on the UAV: the last two entries are the UAV's position x[..., 3], x[..., 4]",
        "one_state": "your function works for one state only: index the last axis (x[..., 0], not x[0]) so that a stack (K, 6) gives (K, 5)",
    },
)


def check_measure_function(fn) -> Feedback:
    """08.3: the student's ``fn(x)`` -> noise-free measurement ``h(x)``, called on one state (6,) and on
    a stack of four states (4, 6); right: the shape (..., 5) of :func:`~kfcal_helpers.coop.model.measure`,
    [bearing UGV->UAV, range, bearing UAV->UGV, xi_a, eta_a] (rad, m, rad, m, m), bearings wrapped to
    (-pi, pi] (-pi for pi is accepted: the same angle)."""
    E = MEASURE_FUNCTION
    cases = _measure_fn_cases()
    convert = lambda a: np.array(a, dtype=float)  # noqa: E731
    outs, fb = call_student(E.id, fn, cases[:1], "measure_fn(x)", convert=convert)
    if fb is not None:
        return fb
    more, fb = call_student(E.id, fn, cases[1:], "measure_fn(x)", convert=convert)
    if fb is not None:   # right size for one state, but a stack fails (x[3] of four rows, say)
        single = as_array(outs[0])
        return E.mistake("one_state") if fb.answered and single is not None and single.size == N_MEAS else fb
    outs = outs + more
    arrays = [as_array(o) for o in outs]
    if any(a is None for a in arrays):
        bad = next(o for o, a in zip(outs, arrays) if a is None)
        return E.feedback(False, f"your function must return numbers, shape (..., 5), it returned {type(bad).__name__}")
    shapes = [(N_MEAS,), (len(cases[1][0]), N_MEAS)]
    if arrays[0].size == N_MEAS and arrays[1].shape != shapes[1]:
        return E.mistake("one_state")
    if any(a.size != int(np.prod(s)) for a, s in zip(arrays, shapes)):
        return E.feedback(False, f"your function must return shape (5,) for one state and (4, 5) for four, "
                                 f"it returned {arrays[0].shape} and {arrays[1].shape}")
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return E.feedback(False, "your function returned NaN or inf")
    answer = _pi_for_minus_pi(np.concatenate([a.reshape(-1, N_MEAS) for a in arrays]), MEAS_ANGLES)

    def each(f):
        return _pi_for_minus_pi(np.concatenate([np.reshape(f(c[0]), (-1, N_MEAS)) for c in cases]), MEAS_ANGLES)

    expected = each(measure)
    wrong = [(each(lambda x, m=m: _measure_fn_variant(x, m)), m) for m in
             ("atan2_order", "no_wrap", "swapped_heading", "same_direction", "degrees", "ugv_gps")]
    return E.judge(answer, expected, distinct_mistakes(wrong, expected, _FN_RTOL), rtol=_FN_RTOL, atol=_FN_ATOL)


__all__.append("check_measure_function")
EXERCISES[MEASURE_FUNCTION.id] = MEASURE_FUNCTION
