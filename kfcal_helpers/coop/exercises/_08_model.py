"""Exercise checks of notebook 08 (the nonlinear model): 08.1-08.3."""

from __future__ import annotations


import math

import numpy as np

from ..model import (
    MEAS_ANGLES,
    N_MEAS,
    N_STATES,
    dynamics,
    measure,
    step,
    wrap_angle,
    wrap_measurement,
    wrap_state,
)
from ...exercises._core import (Exercise, Feedback, as_array, call_student, distinct_mistakes, unanswered)
from ...validation import require_positive, require_shape
from ._shared import (FN_ATOL, FN_RESULT, FN_RTOL, MEAS_NAMES, MEAS_X, NUM_ATOL, NUM_RTOL, STATE_NAMES, STEP_DT, STEP_U,
                      STEP_X, pi_for_minus_pi, slip_before_wrapping, wrap_answer)


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
    components=STATE_NAMES,
    angles=(2, 5),
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
    deg = slip_before_wrapping(E, answer, expected)  # headings in degrees, x100...: before wrapping
    if deg is not None:
        return deg
    answer, unwrapped = wrap_answer(answer, expected, wrap_state)
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
    return E.judge(answer, expected, wrong, rtol=NUM_RTOL, atol=NUM_ATOL)


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
    components=MEAS_NAMES,
    angles=MEAS_ANGLES,
)


def check_measurement(answer, *, x=MEAS_X) -> Feedback:
    """08.2: the noise-free measurement vector ``h(x)`` of the configuration ``x`` (6,).

    answer : array (5,) -- [bearing UGV->UAV, range, bearing UAV->UGV, xi_a, eta_a]
        (rad, m, rad, m, m), bearings wrapped to (-pi, pi]
    """
    x = require_shape("x", x, (N_STATES,))
    E = MEASUREMENT
    expected = measure(x)
    deg = slip_before_wrapping(E, answer, expected)  # bearings in degrees, x100...: before wrapping
    if deg is not None:
        return deg
    answer, unwrapped = wrap_answer(answer, expected, wrap_measurement)
    if unwrapped:
        return E.mistake("wrap")
    wrong = [(_measure_variant(x, m), m) for m in
             ("atan2_order", "atan", "no_heading", "heading_sign", "same_direction", "range_squared", "ugv_gps")]
    return E.judge(answer, expected, wrong, rtol=NUM_RTOL, atol=NUM_ATOL)


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
    if mistake == "wrap_2pi":
        b1, b2 = np.mod(b1, 2 * np.pi), np.mod(b2, 2 * np.pi)
    elif mistake != "no_wrap":
        b1, b2 = wrap_angle(b1), wrap_angle(b2)
    if mistake == "degrees":
        b1, b2 = np.degrees(b1), np.degrees(b2)
    rng = np.hypot(dxi, deta)
    gps_e, gps_n = (x[..., 0], x[..., 1]) if mistake == "ugv_gps" else (x[..., 3], x[..., 4])
    return np.stack([b1, rng, b2, gps_e, gps_n], axis=-1)


MEASURE_FUNCTION = Exercise(
    "08.3",
    praise="h(x) for one state and for a stack of states: bearings wrapped, each from its own vehicle's heading",
    hint="compare with the measurement formula, in its order: [bearing UGV->UAV (minus theta_g, wrapped), range, "
         "bearing UAV->UGV (minus theta_a, wrapped), the UAV's east, the UAV's north]",
    hints={
        "atan2_order": "np.arctan2 takes the north difference first: np.arctan2(d_eta, d_xi)",
        "no_wrap": "the bearings leave (-pi, pi]: wrap them after subtracting the heading",
        "wrap_2pi": "the bearings are wrapped to [0, 2 pi): wrap them to (-pi, pi] instead",
        "stack_axis": "for a stack your function returns (5, K): put the measurements on the last axis "
                      "(np.stack([...], axis=-1)) so that a stack (K, 6) gives (K, 5)",
        "swapped_heading": "each bearing is measured from its own vehicle's heading: the UGV's bearing minus theta_g (x[..., 2]), the UAV's minus theta_a (x[..., 5])",
        "same_direction": "the UAV looks back at the UGV: its line of sight is the reverse direction, np.arctan2(-d_eta, -d_xi)",
        "degrees": "the bearings are in radians, not degrees",
        "ugv_gps": "the GPS is on the UAV: the last two entries are the UAV's position x[..., 3], x[..., 4]",
        "one_state": "your function works for one state only: index the last axis (x[..., 0], not x[0]) so that a stack (K, 6) gives (K, 5)",
    },    components=MEAS_NAMES,
    angles=MEAS_ANGLES,
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
        raised = fb.message.startswith("your function raised")   # not a changed input or the time limit
        return E.mistake("one_state") if raised and single is not None and single.size == N_MEAS else fb
    outs = outs + more
    arrays = [as_array(o) for o in outs]
    if any(a is None for a in arrays):
        bad = next(o for o, a in zip(outs, arrays) if a is None)
        return E.feedback(False, f"your function must return numbers, shape (..., 5), it returned {type(bad).__name__}")
    shapes = [(N_MEAS,), (len(cases[1][0]), N_MEAS)]
    if arrays[0].size == N_MEAS and arrays[1].shape == shapes[1][::-1]:
        return E.mistake("stack_axis")
    if arrays[0].size == N_MEAS and arrays[1].shape != shapes[1]:
        return E.mistake("one_state")
    if any(a.size != int(np.prod(s)) for a, s in zip(arrays, shapes)):
        return E.feedback(False, f"your function must return shape (5,) for one state and (4, 5) for four, "
                                 f"it returned {arrays[0].shape} and {arrays[1].shape}")
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return E.feedback(False, "your function returned NaN or inf")
    answer = pi_for_minus_pi(np.concatenate([a.reshape(-1, N_MEAS) for a in arrays]), MEAS_ANGLES)

    def each(f):
        return pi_for_minus_pi(np.concatenate([np.reshape(f(c[0]), (-1, N_MEAS)) for c in cases]), MEAS_ANGLES)

    expected = each(measure)
    wrong = [(each(lambda x, m=m: _measure_fn_variant(x, m)), m) for m in
             ("atan2_order", "no_wrap", "wrap_2pi", "swapped_heading", "same_direction", "degrees", "ugv_gps")]
    return E.judge(answer, expected, distinct_mistakes(wrong, expected, FN_RTOL), rtol=FN_RTOL, atol=FN_ATOL,
                   what=FN_RESULT)


#: the exercise records of this lesson, in notebook order
RECORDS = (STEP_MAP, MEASUREMENT, MEASURE_FUNCTION)
