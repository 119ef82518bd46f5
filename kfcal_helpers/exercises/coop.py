"""Exercise checks of notebooks 08-13 (cooperative localization).

Each ``check_coop_*`` function takes the student's answer (numbers, or a function for
the exercises that ask for code) and returns a :class:`~kfcal_helpers.exercises.Feedback`
whose repr is one line: correct, or a hint at the likely mistake.  The right answer is
computed from the project's model (:mod:`kfcal_helpers.coop`) or from first principles;
the common wrong answers are computed by making the mistake on purpose, and each has
its hint in :data:`HINTS` (never the answer itself).  The exercise's parameters are the
keyword arguments, with the values of the exercise text as defaults.

A function answer is called on fixed test inputs (copies, so it may modify them); an
exception it raises becomes a hint naming the exception type, and a function that
returns ``None`` (a body still ``...``) counts as not answered yet.

=========  ========================================  ==================================
exercise   check                                     answer
=========  ========================================  ==================================
08.1       :func:`check_coop_step_map`               state after one step, (6,)
08.2       :func:`check_coop_measurement`            measurement vector, (5,)
09.1       :func:`check_coop_bearing_row`            first row of C, (6,)
09.2       :func:`check_coop_F_dt`                   F for another dT, (6, 6)
09.3       :func:`check_coop_obs_rank`               ranks for two windows, (2,)
10.1       :func:`check_coop_mc_bounds`              NEES and NIS bounds, (2, 2)
10.2       :func:`check_coop_lkf_innovation`         function (y, y_nom, H, dx) -> (5,)
11.1       :func:`check_coop_ekf_residual`           function (a, b) -> (5, 1)
11.2       :func:`check_coop_ekf_F`                  F at the posterior, (6, 6)
12.1       :func:`check_coop_merwe_weights`          [lambda, Wm0, Wc0, Wi], (4,)
12.2       :func:`check_coop_circular_mean`          function (angles, weights) -> float
13.1       :func:`check_coop_log_nis_bounds`         time-averaged NIS bounds, (2,)
13.2       :func:`check_coop_sparse_nis_bounds`      the same, every 10th measurement, (2,)
=========  ========================================  ==================================
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import stats

from ..consistency import chi2_bounds
from ..coop.model import (
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
    wrap_measurement,
    wrap_state,
)
from ..validation import require_finite, require_int, require_positive, require_shape
from ._core import GENERIC_HINT, Feedback, as_array, chi2_average_bounds, judge, matches, unanswered

__all__ = [
    "check_coop_step_map",
    "check_coop_measurement",
    "check_coop_bearing_row",
    "check_coop_F_dt",
    "check_coop_obs_rank",
    "check_coop_mc_bounds",
    "check_coop_lkf_innovation",
    "check_coop_ekf_residual",
    "check_coop_ekf_F",
    "check_coop_merwe_weights",
    "check_coop_circular_mean",
    "check_coop_log_nis_bounds",
    "check_coop_sparse_nis_bounds",
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

#: the hint of every listed wrong answer, by exercise and mistake
HINTS: dict[str, dict[str, str]] = {
    "08.1": {
        "euler": "that is an Euler step: over dT each vehicle moves along the chord of its arc, not along its initial heading",
        "start_heading": "the chord points along the mean heading of the step (theta_k + omega dT/2), not along theta_k",
        "np_sinc": "numpy's np.sinc(z) is sin(pi z)/(pi z), the normalized sinc: divide its argument by pi",
        "no_sinc": "the chord is shorter than the arc: its length carries the factor sinc(omega dT/2)",
        "no_L": "the UGV's yaw rate is v_g tan(phi_g) / L: the wheelbase is missing",
        "cos_sin": "east (xi) goes with cos(heading) and north (eta) with sin(heading)",
        "wrap": "right position, but wrap the headings to (-pi, pi]",
        "nan": "NaN or inf in your answer: the form v/omega divides by zero when omega = 0 (the UAV flies straight); use the sinc form",
    },
    "08.2": {
        "wrap": "right values, but the bearings must be wrapped to (-pi, pi]",
        "atan2_order": "atan2 takes the north difference first: atan2(d_eta, d_xi)",
        "atan": "arctan(d_eta/d_xi) loses the quadrant (d_xi < 0 here): use atan2",
        "no_heading": "a bearing is measured from the vehicle's own heading: subtract it",
        "heading_sign": "the heading is subtracted from the direction, not added",
        "same_direction": "the UAV looks back at the UGV: its line of sight is the reverse direction, atan2(-d_eta, -d_xi)",
        "range_squared": "the range is the distance, not its square",
        "ugv_gps": "the GPS is on the UAV: the last two entries are the UAV's position",
    },
    "09.1": {
        "vehicle_sign": "the UGV and UAV columns have opposite signs to yours: moving the UGV east decreases d_xi",
        "over_r": "the derivative of atan2(d_eta, d_xi) is divided by r squared, not by r",
        "swapped": "d_xi and d_eta are swapped: recheck which difference goes with the east and which with the north columns",
        "heading_plus": "check the sign of the heading entry: the bearing is a direction minus theta_g",
        "heading_zero": "the bearing also depends on the UGV's heading theta_g",
        "other_bearing": "that is the row of the other bearing (UAV to UGV): this one depends on theta_g, not theta_a",
        "range_row": "that is the range row (row 2 of C): this exercise asks for the first bearing",
    },
    "09.2": {
        "A_only": "that is A: F maps a state to the next one, so it starts from the identity",
        "no_dt": "the heading-to-position terms must scale with the step length dT",
        "notebook_dt": "that is F for the notebook's dT = 0.1 s: use this exercise's sampling interval",
        "transposed": "transposed: row i of F says how state i at k+1 depends on the states at k",
        "sign": "check the signs: d(cos theta)/d(theta) = -sin theta, d(sin theta)/d(theta) = +cos theta",
        "sin_cos": "sin and cos are swapped: the east rate v cos(theta) differentiates to -v sin(theta)",
        "speeds": "each vehicle's rows use its own speed (v_g = 2 m/s for the UGV, v_a = 12 m/s for the UAV)",
    },
    "09.3": {
        "no_motion": "over several steps the motion adds information: which state moves the UAV's next GPS position?",
        "full": "none of these rows depends on the UGV's states: they cannot become observable",
        "all_rows": "those are the ranks with all five measurements: keep only the UAV's GPS rows (3 and 4)",
        "rows_count": "a rank cannot exceed the number of columns of O, the 6 states",
        "one_step": "at one instant O has only the two GPS rows",
        "whole": "a rank is a whole number: count the independent rows of O (np.linalg.matrix_rank)",
    },
    "10.1": {
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "swapped_dims": "the dimensions are swapped: NEES has the state's dimension, NIS the measurement's",
        "not_divided": "the bounds are for the run average: divide the chi-square quantiles by N",
        "dof_N": "the sum over N runs of an n-dimensional statistic has N*n degrees of freedom, not N",
        "N_minus_1": "the N runs are independent with known covariance: N*n degrees of freedom, not (N-1)*n",
        "order": "give the lower bound first, then the upper one",
        "normal": "close, but that is the normal approximation: use the chi-square quantiles",
        "notebook_N": "those are the bounds for the notebook's N = 50: use this exercise's number of runs",
    },
    "10.2": {
        "no_wrap": "the bearing components jump by 2 pi across +-pi: wrap them",
        "no_nominal": "the LKF works with perturbations: the measurement perturbation is y - y_nom",
        "plus": "the predicted measurement perturbation H dx is subtracted, not added",
        "wrap_all": "wrap only the bearings (components 0 and 2): range and GPS are not angles",
        "wrap_early": "wrap the whole innovation after subtracting H dx (it can cross +-pi again)",
        "no_H": "subtract the predicted measurement perturbation H dx",
    },
    "11.1": {
        "no_wrap": "that is np.subtract, filterpy's default: wrap the bearing differences to (-pi, pi]",
        "wrap_all": "wrap only the bearings (components 0 and 2): range and GPS are not angles",
        "reversed": "the residual is a - b (measurement minus prediction), not b - a",
        "mod_2pi": "the wrapped difference must land in (-pi, pi], not in [0, 2 pi)",
        "shape": "right values, but filterpy passes column vectors (5, 1) and needs the same shape back",
    },
    "11.2": {
        "prior": "that F is evaluated at the predicted state: F_k linearizes the step from where it starts, the posterior",
        "nominal": "that is the LKF's F (on the nominal): the EKF relinearizes about its own estimate",
        "A_only": "that is A: F maps a state to the next one, so it starts from the identity",
        "no_dt": "the heading-to-position terms must scale with the step length dT",
        "transposed": "transposed: row i of F says how state i at k+1 depends on the states at k",
        "exact_map": "that is the Jacobian of the exact arc map: the filter uses the first-order F of the notebook",
    },
    "12.1": {
        "alpha_not_squared": "lambda uses alpha squared",
        "wc0_equals_wm0": "the covariance weight of the centre point has an extra term (1 - alpha^2 + beta)",
        "wc0_alpha": "the extra term of Wc0 uses alpha squared",
        "wi_lambda": "the outer weights divide by 2 (n + lambda), not by 2 lambda",
        "n_points": "n is the state dimension (6), not the number of sigma points",
        "no_kappa": "kappa is missing from lambda",
        "no_minus_n": "lambda is missing its - n term",
        "sum": "your mean weights do not sum to 1 (Wm0 + 2n Wi): recheck lambda and the weights",
    },
    "12.2": {
        "plain": "that is the plain weighted mean: angles near +pi and -pi average to about 0 instead of pi",
        "unweighted": "use the weights: sum w_i sin(theta_i) and sum w_i cos(theta_i)",
        "atan2_order": "atan2 takes the sine sum first: atan2(sum w sin, sum w cos)",
        "shifted": "shifting the angles into [0, 2 pi) only moves the problem from pi to 0",
        "arctan": "arctan of the ratio loses the quadrant (the cosine sum can be negative): use atan2",
        "size": "the circular mean of a set of angles is one angle: return a single float",
    },
    "13.1": {
        "count_nan": "count only the steps that have a measurement: the first sample is NaN",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "notebook_alpha": "those are the bounds at alpha = 0.05: this exercise uses alpha = 0.01",
        "dof_K": "K steps of a 5-dimensional NIS give 5K degrees of freedom, not K",
        "not_divided": "the bounds are for the time average: divide the chi-square quantiles by K",
        "dim6": "the NIS has the dimension of the measurement, not of the state",
        "normal": "close, but that is the normal approximation: use the chi-square quantiles",
    },
    "13.2": {
        "count_nan": "the first kept sample (t = 0) has no measurement: do not count it",
        "all_steps": "only every 10th step has a measurement now: K counts the updates, not the steps of the log",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "dof_K": "K steps of a 5-dimensional NIS give 5K degrees of freedom, not K",
        "dim6": "the NIS has the dimension of the measurement, not of the state",
    },
}

_FN_PLACEHOLDER = "write the function, then pass it (not ...) to the check"
_NUM_RTOL, _NUM_ATOL = 1e-4, 1e-8  # numeric answers (typed or printed with a few decimals)
_FN_RTOL, _FN_ATOL = 1e-7, 1e-9  # outputs of a student's function (same float formula)
_BOUNDS_RTOL = 2e-4  # chi-square bounds given with at least three decimals


def _wrong(exercise: str, pairs):
    """``(value, hint)`` pairs from ``(value, mistake key)`` pairs."""
    return [(v, HINTS[exercise][key]) for v, key in pairs]


def _finite_of_size(answer, size):
    """``answer`` as a flat float array when it has ``size`` finite entries, else None."""
    a = as_array(answer)
    if a is None or a.size != size or not np.all(np.isfinite(a)):
        return None
    return a.reshape(size)


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    text = text[0] if text else ""
    return f" ({text[:90]})" if text else ""


def _call_all(exercise: str, fn, cases, out_shape: tuple, what: str, size_hint: str | None = None):
    """Call the student's ``fn`` on every case; returns ``(outputs, None)`` with outputs of
    shape (n_cases, *out_shape) as returned (list of arrays), or ``(None, Feedback)``."""
    if unanswered(fn):
        return None, Feedback(exercise, False, _FN_PLACEHOLDER, answered=False)
    if not callable(fn):
        return None, Feedback(exercise, False, f"expected a function {what}, got {type(fn).__name__}: "
                                               "pass the function itself, without calling it")
    outs = []
    for args in cases:
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                out = fn(*(np.array(a, dtype=float) for a in args))
        except Exception as exc:  # any mistake in the student's code becomes a hint
            return None, Feedback(exercise, False, f"your function raised {type(exc).__name__}{_short(exc)}: "
                                                   "try it on a small example and read the line it points to")
        if out is None:
            return None, Feedback(exercise, False, "your function returns None: replace ... with your code, "
                                                   "and return the result", answered=False)
        arr = as_array(out)
        if arr is None:
            return None, Feedback(exercise, False, f"your function must return numbers (shape {out_shape}), "
                                                   f"it returned {type(out).__name__}")
        if arr.size != int(np.prod(out_shape)):
            return None, Feedback(exercise, False, size_hint or f"your function must return shape {out_shape}, "
                                                                f"it returned {arr.shape}")
        if not np.all(np.isfinite(arr)):
            return None, Feedback(exercise, False, "your function returned NaN or inf: look for a division by zero")
        outs.append(arr)
    return outs, None


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
def _arc_variant(x, u, dT, L, *, length="sinc", heading="mid", yaw_L=True, trig="ok"):
    """The one-step map with a chosen mistake (for the wrong answers of 08.1)."""
    x = np.asarray(x, dtype=float)
    vg, phi, va, wa = u
    wg = vg * math.tan(phi) / (L if yaw_L else 1.0)
    out = np.empty(6)
    for i, v, w in ((0, vg, wg), (3, va, wa)):
        th, half = x[i + 2], 0.5 * w * dT
        if length == "sinc":
            d = v * dT * (math.sin(half) / half if half != 0 else 1.0)
        elif length == "np_sinc":
            d = v * dT * float(np.sinc(half))
        else:
            d = v * dT
        direction = th + half if heading == "mid" else th
        c, s = (math.cos(direction), math.sin(direction)) if trig == "ok" else (math.sin(direction), math.cos(direction))
        out[i], out[i + 1], out[i + 2] = x[i] + d * c, x[i + 1] + d * s, th + w * dT
    return wrap_state(out)


def check_coop_step_map(answer, x=STEP_X, u=STEP_U, dT: float = STEP_DT, L: float = 0.5) -> Feedback:
    """08.1: the state one step ``dT`` (s) after ``x`` under the constant control ``u``.

    answer : array (6,) -- [xi_g, eta_g, theta_g, xi_a, eta_a, theta_a] (m, m, rad, m, m, rad),
        headings wrapped to (-pi, pi]
    x : (6,) state; u : (4,) control [v_g, phi_g, v_a, omega_a]; dT, L : s, m (> 0)
    """
    x = require_shape("x", x, (N_STATES,))
    u = require_shape("u", u, (4,))
    dT, L = require_positive("dT", dT), require_positive("L", L)
    ex = "08.1"
    expected = step(x, u, dT, L)
    a = as_array(answer)
    if not unanswered(answer) and a is not None and a.size == N_STATES and not np.all(np.isfinite(a)):
        return Feedback(ex, False, HINTS[ex]["nan"])
    flat = _finite_of_size(answer, N_STATES)
    if flat is not None:
        wrapped = wrap_state(flat)
        if matches(wrapped, expected, _NUM_RTOL, _NUM_ATOL) and not matches(flat, expected, _NUM_RTOL, _NUM_ATOL):
            return Feedback(ex, False, HINTS[ex]["wrap"])
        answer = wrapped
    wrong = _wrong(ex, [
        (wrap_state(x + dT * dynamics(x, u, L)), "euler"),
        (_arc_variant(x, u, dT, L, heading="start"), "start_heading"),
        (_arc_variant(x, u, dT, L, length="np_sinc"), "np_sinc"),
        (_arc_variant(x, u, dT, L, length="none"), "no_sinc"),
        (_arc_variant(x, u, dT, L, yaw_L=False), "no_L"),
        (_arc_variant(x, u, dT, L, trig="swapped"), "cos_sin"),
    ])
    return judge(ex, answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL,
                 praise="each vehicle moved along the chord of its arc (the UAV, with omega = 0, on a straight line)")


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


def check_coop_measurement(answer, x=MEAS_X) -> Feedback:
    """08.2: the noise-free measurement vector ``h(x)`` of the configuration ``x`` (6,).

    answer : array (5,) -- [bearing UGV->UAV, range, bearing UAV->UGV, xi_a, eta_a]
        (rad, m, rad, m, m), bearings wrapped to (-pi, pi]
    """
    x = require_shape("x", x, (N_STATES,))
    ex = "08.2"
    expected = measure(x)
    flat = _finite_of_size(answer, N_MEAS)
    if flat is not None:
        wrapped = wrap_measurement(flat)
        if matches(wrapped, expected, _NUM_RTOL, _NUM_ATOL) and not matches(flat, expected, _NUM_RTOL, _NUM_ATOL):
            return Feedback(ex, False, HINTS[ex]["wrap"])
        answer = wrapped
    wrong = _wrong(ex, [(_measure_variant(x, m), m) for m in
                        ("atan2_order", "atan", "no_heading", "heading_sign", "same_direction", "range_squared", "ugv_gps")])
    return judge(ex, answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL,
                 praise="two wrapped bearings, the range and the UAV's GPS")


# ---------------------------------------------------------------------------
# 09: linearization
def check_coop_bearing_row(answer, x=ROW_X) -> Feedback:
    """09.1: the first row of ``C = dh/dx`` (bearing UGV->UAV) at the configuration ``x``.

    answer : array (6,) -- derivatives with respect to [xi_g, eta_g, theta_g, xi_a, eta_a, theta_a]
        (1/m, 1/m, 1, 1/m, 1/m, 1)
    """
    x = require_shape("x", x, (N_STATES,))
    ex = "09.1"
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
    wrong = _wrong(ex, [(sign, "vehicle_sign"), (over_r, "over_r"), (swapped, "swapped"), (plus, "heading_plus"),
                        (zero, "heading_zero"), (C[2], "other_bearing"), (C[1], "range_row")])
    return judge(ex, answer, row, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL,
                 praise="d(bearing)/dx: +-d_eta/r^2, -+d_xi/r^2 for the two vehicles, -1 for theta_g")


def _F(A, dT):
    return np.eye(N_STATES) + dT * A


def check_coop_F_dt(answer, x=FDT_X, dT: float = FDT_DT, u=_U0, L: float = 0.5) -> Feedback:
    """09.2: ``F = I + dT A(x, u)`` for the sampling interval ``dT`` (s).

    answer : array (6, 6), dimensionless except the heading columns (m/rad)
    """
    x = require_shape("x", x, (N_STATES,))
    u = require_shape("u", u, (4,))
    dT, L = require_positive("dT", dT), require_positive("L", L)
    ex = "09.2"
    A = jacobian_A(x, u, L)
    expected = _F(A, dT)
    sign = -A
    sin_cos = np.zeros((6, 6))
    sin_cos[0, 2], sin_cos[1, 2] = -u[0] * math.cos(x[2]), u[0] * math.sin(x[2])
    sin_cos[3, 5], sin_cos[4, 5] = -u[2] * math.cos(x[5]), u[2] * math.sin(x[5])
    speeds = np.zeros((6, 6))  # each vehicle's rows with the other one's speed
    speeds[0, 2], speeds[1, 2] = -u[2] * math.sin(x[2]), u[2] * math.cos(x[2])
    speeds[3, 5], speeds[4, 5] = -u[0] * math.sin(x[5]), u[0] * math.cos(x[5])
    pairs = [(A, "A_only"), (_F(A, 1.0), "no_dt"), (_F(A, dT).T, "transposed"), (_F(sign, dT), "sign"),
             (_F(sin_cos, dT), "sin_cos"), (_F(speeds, dT), "speeds")]
    if abs(dT - 0.1) > 1e-12:
        pairs.append((_F(A, 0.1), "notebook_dt"))
    return judge(ex, answer, expected, _wrong(ex, pairs), rtol=_NUM_RTOL, atol=_NUM_ATOL,
                 praise="F = I + dT A: a heading error moves each position by v dT per rad in one step")


def _ranks(rows, windows, start):
    p = CoopParams()
    x_nom = nominal_trajectory(p, n_samples=start + max(windows))
    F = _F(jacobian_A(x_nom, p.u0, p.L), p.dT)
    H = jacobian_C(x_nom)
    out = []
    for m in windows:
        O = observability_matrix(F[start:start + m - 1], H[start:start + m][:, list(rows)])
        out.append(int(np.linalg.matrix_rank(O)))
    return np.array(out, dtype=float)


def check_coop_obs_rank(answer, windows=RANK_WINDOWS, start: int = 0) -> Feedback:
    """09.3: ranks of the stacked observability matrix with only the UAV's GPS rows (3, 4) of H,
    for windows of ``windows`` steps (the first one of 1 step) starting at sample ``start`` of the nominal.

    answer : array (len(windows),) of integers
    """
    windows = tuple(require_int("windows", m, minimum=1) for m in windows)
    if len(windows) < 2 or windows[0] != 1:
        raise ValueError(f"windows must hold 1 and at least one longer window, got {windows}")
    rows = RANK_ROWS
    start = require_int("start", start, minimum=0)
    ex = "09.3"
    expected = _ranks(rows, windows, start)
    full = _ranks(tuple(range(N_MEAS)), windows, start)
    first = expected[0]
    pairs = [(np.full(len(windows), first), "no_motion"), (np.r_[first, np.full(len(windows) - 1, 6.0)], "full"),
             (full, "all_rows"), (np.r_[first, [len(rows) * m for m in windows[1:]]], "rows_count"),
             (np.r_[expected[-1], expected[1:]], "one_step")]
    wrong = [(v, h) for v, h in _wrong(ex, pairs) if not np.array_equal(v, expected)]
    flat = _finite_of_size(answer, len(windows))
    if flat is not None and not np.allclose(flat, np.round(flat)):
        return Feedback(ex, False, HINTS[ex]["whole"])
    return judge(ex, answer, expected, wrong,
                 praise="the UAV's heading becomes observable through its motion; the UGV stays unobservable")


# ---------------------------------------------------------------------------
# 10: LKF
def _normal_bounds(dim, n, alpha):
    z = stats.norm.ppf(1 - alpha / 2)
    return np.array([dim - z * math.sqrt(2 * dim / n), dim + z * math.sqrt(2 * dim / n)])


def check_coop_mc_bounds(answer, n_runs: int = MC_RUNS, alpha: float = 0.05) -> Feedback:
    """10.1: the two-sided bounds of the run-averaged NEES and NIS for ``n_runs`` Monte Carlo runs.

    answer : array (2, 2) -- [[NEES lower, NEES upper], [NIS lower, NIS upper]] (dimensionless),
        at least three decimals
    """
    N = require_int("n_runs", n_runs, minimum=2)
    alpha = require_finite("alpha", alpha)
    ex = "10.1"
    expected = np.array([chi2_bounds(N_STATES, N, alpha), chi2_bounds(N_MEAS, N, alpha)])

    def both(**kw):
        return np.array([chi2_average_bounds(N_STATES, N, alpha, **kw), chi2_average_bounds(N_MEAS, N, alpha, **kw)])

    pairs = [(both(one_sided=True), "one_sided"), (expected[::-1], "swapped_dims"), (both(divide_by=1), "not_divided"),
             (np.array([chi2_average_bounds(N_STATES, N, alpha, dof=N), chi2_average_bounds(N_MEAS, N, alpha, dof=N)]),
              "dof_N"),
             (np.array([chi2_average_bounds(N_STATES, N - 1, alpha), chi2_average_bounds(N_MEAS, N - 1, alpha)]),
              "N_minus_1"),
             (expected[:, ::-1], "order"),
             (np.array([_normal_bounds(N_STATES, N, alpha), _normal_bounds(N_MEAS, N, alpha)]), "normal")]
    if N != 50:
        pairs.append((np.array([chi2_bounds(N_STATES, 50, alpha), chi2_bounds(N_MEAS, 50, alpha)]), "notebook_N"))
    return judge(ex, answer, expected, _wrong(ex, pairs), rtol=_BOUNDS_RTOL, atol=0.0,
                 praise=f"chi-square with N n degrees of freedom, divided by N = {N}, alpha/2 in each tail")


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


def check_coop_lkf_innovation(fn) -> Feedback:
    """10.2: the student's ``fn(y, y_nom, H, dx_prior)`` -> LKF innovation (5,), called on fixed cases.

    y, y_nom : (5,) measurement and nominal measurement (rad, m, rad, m, m); H : (5, 6);
    dx_prior : (6,) predicted perturbation.  Right: ``(y - y_nom) - H dx_prior``, bearings wrapped.
    """
    ex = "10.2"
    cases = _lkf_cases()
    outs, fb = _call_all(ex, fn, cases, (N_MEAS,), "lkf_innovation(y, y_nom, H, dx_prior)")
    if fb is not None:
        return fb
    answer = _pi_for_minus_pi(np.array([o.reshape(N_MEAS) for o in outs]), MEAS_ANGLES)

    def each(f):
        return _pi_for_minus_pi(np.array([f(y, yn, H, dx) for y, yn, H, dx in cases]), MEAS_ANGLES)

    def wrap_early(y, yn, H, dx):
        return wrap_measurement(y - yn) - H @ dx

    expected = each(lambda y, yn, H, dx: wrap_measurement((y - yn) - H @ dx))
    wrong = _wrong(ex, [
        (each(lambda y, yn, H, dx: (y - yn) - H @ dx), "no_wrap"),
        (each(lambda y, yn, H, dx: wrap_measurement(y - H @ dx)), "no_nominal"),
        (each(lambda y, yn, H, dx: wrap_measurement((y - yn) + H @ dx)), "plus"),
        (each(lambda y, yn, H, dx: wrap_angle((y - yn) - H @ dx)), "wrap_all"),
        (each(wrap_early), "wrap_early"),
        (each(lambda y, yn, H, dx: wrap_measurement(y - yn)), "no_H"),
    ])
    return judge(ex, answer, expected, wrong, rtol=_FN_RTOL, atol=_FN_ATOL,
                 praise="perturbation innovation with the bearings wrapped after the subtraction")


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


def check_coop_ekf_residual(fn) -> Feedback:
    """11.1: the student's ``fn(a, b)`` for filterpy's ``residual=``: ``a - b`` with the two
    bearings wrapped to (-pi, pi], for column vectors (5, 1), returning (5, 1).

    A result of exactly -pi instead of pi is accepted (the same angle).
    """
    ex = "11.1"
    cases = _residual_cases()
    outs, fb = _call_all(ex, fn, cases, (N_MEAS, 1), "residual(a, b)")
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
    wrong = _wrong(ex, [
        (each(np.subtract), "no_wrap"),
        (each(lambda a, b: wrap_angle(a - b)), "wrap_all"),
        (each(lambda a, b: measurement_residual(b, a)), "reversed"),
        (each(mod), "mod_2pi"),
    ])
    fb = judge(ex, answer, expected, wrong, rtol=_FN_RTOL, atol=_FN_ATOL,
               praise="bearing differences wrapped, range and GPS untouched, column vectors kept")
    if fb.correct and any(o.shape != (N_MEAS, 1) for o in outs):
        return Feedback(ex, False, HINTS[ex]["shape"])
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


def check_coop_ekf_F(answer, x_post=EKF_X, t: float = EKF_T) -> Feedback:
    """11.2: the EKF's ``F_k`` for the step from the posterior ``x_post`` (6,) at time ``t`` (s),
    with the nominal control u0 = [2, -pi/18, 12, pi/25], dT = 0.1 s and L = 0.5 m.

    answer : array (6, 6)
    """
    x = require_shape("x_post", x_post, (N_STATES,))
    p = CoopParams()
    t = require_finite("t", t)
    k = int(round(t / p.dT))
    if k < 0 or k >= p.n_samples or abs(k * p.dT - t) > 1e-9:
        raise ValueError(f"t must be a sample time k dT in [0, {p.duration:g}] s, got {t!r}")
    ex = "11.2"
    A = jacobian_A(x, p.u0, p.L)
    expected = _F(A, p.dT)
    prior = step(x, p.u0, p.dT, p.L)
    x_nom = nominal_trajectory(p, n_samples=k + 1)[k]
    exact = _fd_jacobian(lambda z: step(z, p.u0, p.dT, p.L), x)
    wrong = _wrong(ex, [
        (_F(jacobian_A(prior, p.u0, p.L), p.dT), "prior"),
        (_F(jacobian_A(x_nom, p.u0, p.L), p.dT), "nominal"),
        (A, "A_only"),
        (_F(A, 1.0), "no_dt"),
        (expected.T, "transposed"),
        (exact, "exact_map"),
    ])
    return judge(ex, answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL,
                 praise="F_k = I + dT A at the posterior, where the step starts")


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


def check_coop_merwe_weights(answer, n: int = MERWE["n"], alpha: float = MERWE["alpha"],
                             beta: float = MERWE["beta"], kappa: float = MERWE["kappa"]) -> Feedback:
    """12.1: Merwe's scaled sigma-point parameter and weights.

    answer : array (4,) -- [lambda, Wm0, Wc0, Wi] (dimensionless): lambda, the mean and covariance
        weights of the centre point, and the weight of each of the 2n other points
    """
    n = require_int("n", n, minimum=1)
    alpha, beta, kappa = require_positive("alpha", alpha), require_finite("beta", beta), require_finite("kappa", kappa)
    if abs(alpha ** 2 * (n + kappa)) < 1e-12:
        raise ValueError("alpha and kappa must give n + lambda != 0")
    ex = "12.1"
    expected = _merwe(n, alpha, beta, kappa)
    lam = expected[0]
    pairs = [
        (_merwe(n, alpha, beta, kappa, lam=alpha * (n + kappa) - n), "alpha_not_squared"),
        (_merwe(n, alpha, beta, kappa, wc_extra=0.0), "wc0_equals_wm0"),
        (_merwe(n, alpha, beta, kappa, wc_extra=1 - alpha + beta), "wc0_alpha"),
        (_merwe(n, alpha, beta, kappa, wi_den=2 * lam), "wi_lambda"),
        (_merwe(2 * n + 1, alpha, beta, kappa), "n_points"),
        (_merwe(n, alpha, beta, 0.0), "no_kappa"),
        (_merwe(n, alpha, beta, kappa, lam=alpha ** 2 * (n + kappa)), "no_minus_n"),
    ]
    wrong = [(v, h) for v, h in _wrong(ex, pairs) if np.all(np.isfinite(v)) and not np.allclose(v, expected)]
    fb = judge(ex, answer, expected, wrong, rtol=_NUM_RTOL, atol=_NUM_ATOL,
               praise="note the negative centre weight Wm0: the weights still sum to 1" if expected[1] < 0
               else "the mean weights sum to 1")
    flat = _finite_of_size(answer, 4)
    if not fb.correct and fb.answered and fb.message == GENERIC_HINT and flat is not None \
            and abs(flat[1] + 2 * n * flat[3] - 1.0) > 1e-3:
        return Feedback(ex, False, HINTS[ex]["sum"])
    return fb


def _circular_cases():
    """(angles, weights) test inputs of 12.2 (rad, dimensionless)."""
    return [
        (np.array([3.0, -3.0, 2.9, -3.1]), np.array([0.25, 0.25, 0.25, 0.25])),
        (np.array([0.2, -0.4, 6.0]), np.array([0.5, 0.3, 0.2])),
        (np.array([1.0, 2.0, 1.5]), np.array([-1.0, 1.0, 1.0])),
        (np.array([2.5, -2.8]), np.array([0.7, 0.3])),
    ]


def check_coop_circular_mean(fn) -> Feedback:
    """12.2: the student's ``fn(angles, weights)`` -> weighted circular mean (rad, one float in
    (-pi, pi]), called on fixed sets of angles (m,) and weights (m,), one of them negative."""
    ex = "12.2"
    cases = _circular_cases()
    outs, fb = _call_all(ex, fn, cases, (1,), "circular_mean(angles, weights)", size_hint=HINTS[ex]["size"])
    if fb is not None:
        return fb
    answer = _pi_for_minus_pi(np.array(outs).reshape(len(cases)))

    def each(f):
        return _pi_for_minus_pi(np.array([f(a, w) for a, w in cases]))

    expected = each(lambda a, w: math.atan2(np.dot(w, np.sin(a)), np.dot(w, np.cos(a))))
    wrong = _wrong(ex, [
        (each(lambda a, w: np.dot(w, a)), "plain"),
        (each(lambda a, w: math.atan2(np.sin(a).sum(), np.cos(a).sum())), "unweighted"),
        (each(lambda a, w: math.atan2(np.dot(w, np.cos(a)), np.dot(w, np.sin(a)))), "atan2_order"),
        (each(lambda a, w: float(wrap_angle(np.dot(w, np.mod(a, 2 * np.pi))))), "shifted"),
        (each(lambda a, w: math.atan(np.dot(w, np.sin(a)) / np.dot(w, np.cos(a)))), "arctan"),
    ])
    return judge(ex, answer, expected, wrong, rtol=_FN_RTOL, atol=_FN_ATOL,
                 praise="atan2 of the weighted sine and cosine sums, right across +-pi and with a negative weight")


# ---------------------------------------------------------------------------
# 13: the log; fewer measurements
def _nis_bounds_wrong(K, alpha, extra):
    """Common wrong answers for the time-averaged NIS bounds of K updates."""
    pairs = [(chi2_average_bounds(N_MEAS, K, alpha, one_sided=True), "one_sided"),
             (chi2_average_bounds(N_MEAS, K, alpha, dof=K), "dof_K"),
             (np.array(chi2_bounds(N_STATES, K, alpha)), "dim6")]
    return pairs + extra


def check_coop_log_nis_bounds(answer, n_samples: int = LOG_SAMPLES, alpha: float = LOG_ALPHA) -> Feedback:
    """13.1: bounds of the time-averaged NIS of one run over a log of ``n_samples`` samples whose
    first sample has no measurement, at significance ``alpha``.

    answer : array (2,) -- [lower, upper] (dimensionless), at least three decimals
    """
    n_samples = require_int("n_samples", n_samples, minimum=3)
    alpha = require_finite("alpha", alpha)
    ex = "13.1"
    K = n_samples - 1
    expected = np.array(chi2_bounds(N_MEAS, K, alpha))
    extra = [(np.array(chi2_bounds(N_MEAS, K + 1, alpha)), "count_nan"),
             (chi2_average_bounds(N_MEAS, K, alpha, divide_by=1), "not_divided"),
             (_normal_bounds(N_MEAS, K, alpha), "normal")]
    if abs(alpha - 0.05) > 1e-12:
        extra.append((np.array(chi2_bounds(N_MEAS, K, 0.05)), "notebook_alpha"))
    wrong = _wrong(ex, _nis_bounds_wrong(K, alpha, extra))
    return judge(ex, answer, expected, wrong, rtol=_BOUNDS_RTOL, atol=0.0,
                 praise=f"K = {K} updates, 5K degrees of freedom, divided by K")


def check_coop_sparse_nis_bounds(answer, every: int = SPARSE_EVERY, n_samples: int = SPARSE_SAMPLES,
                                 alpha: float = 0.05) -> Feedback:
    """13.2: bounds of the time-averaged NIS of one run when only every ``every``-th sample
    (k = 0, every, 2 every, ...) of a log of ``n_samples`` samples is used; sample 0 has no measurement.

    answer : array (2,) -- [lower, upper] (dimensionless), at least three decimals
    """
    every = require_int("every", every, minimum=2)
    n_samples = require_int("n_samples", n_samples, minimum=2 * every + 1)
    alpha = require_finite("alpha", alpha)
    ex = "13.2"
    K = len(range(0, n_samples, every)) - 1
    expected = np.array(chi2_bounds(N_MEAS, K, alpha))
    extra = [(np.array(chi2_bounds(N_MEAS, K + 1, alpha)), "count_nan"),
             (np.array(chi2_bounds(N_MEAS, n_samples - 1, alpha)), "all_steps")]
    wrong = _wrong(ex, _nis_bounds_wrong(K, alpha, extra))
    return judge(ex, answer, expected, wrong, rtol=_BOUNDS_RTOL, atol=0.0,
                 praise=f"K = {K} updates: fewer updates, wider bounds")
