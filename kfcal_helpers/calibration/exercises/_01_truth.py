"""Exercise checks of notebook 01 (the truth model): 01.1-01.3."""

from __future__ import annotations



import numpy as np

from ...exercises._core import (Exercise, Feedback)
from ...validation import (require_positive)
from ..params import CalibrationParams
from ..simulation import acceleration, analytic_truth, integrate_left
from ._shared import call_once, close, numeric, as_pair


def _velocity_gap(params: CalibrationParams, t: float) -> float:
    j = int(round(t * params.imu_rate))
    ts = params.t_imu[: j + 1]
    a = acceleration(ts, params)
    _, v = analytic_truth(ts, 0.0, 0.0, params)
    _, v_e = integrate_left(a, 0.0, 0.0, params.dt)
    return float(v[-1] - v_e[-1])


_EULER_VELOCITY_GAP = Exercise(
    "01.1",
    praise="the Euler velocity lags the exact one by about half a step's acceleration change",
    hint="compute v - v_E at t = 10 s for ω = 0.8 rad/s, from the two truths or from (Δt/2)(a(t) - a(0))",
    hints={
        "sign": "check the sign: the exercise asks for the analytic minus the Euler velocity, v - v_E",
        "no_half": "the left sum differs from the trapezoidal rule by HALF the end-point difference: check the "
                   "factor in front of Δt",
        "omega": "use the exercise's ω = 0.8 rad/s, not the notebook's default 0.2 rad/s",
        "hertz": "ω is an angular frequency in rad/s: a(t) = A sin(ωt), with no 2π",
        "position": "that is the position formula; the velocity difference involves the acceleration a(t)",
        "bound": "that is the largest velocity difference over the run, (Δt/2)A; the exercise asks for its value "
                 "at t = 10 s",
    },
)


def check_euler_velocity_gap(answer, *, omega: float = 0.8, t: float = 10.0) -> Feedback:
    """Exercise 01.1: ``v(t) - v_E(t)`` in m/s (analytic minus Euler truth), A = 10 m/s²,
    200 Hz, for ``omega`` (rad/s) at time ``t`` (s, on the IMU grid, 0 < t <= 30).

    Accepts the exact difference or the approximation (Δt/2)(a(t) - a(0)) (rtol 5e-3).
    """
    omega = require_positive("omega", omega)
    t = require_positive("t", t)
    if t > 30.0:
        raise ValueError(f"t must be in (0, 30] s, got {t!r}")
    p = CalibrationParams(omega=omega)
    dt, A = p.dt, p.A
    approx = lambda w: dt / 2 * A * np.sin(w * t)  # noqa: E731  (a(0) = 0)
    wrong = [("sign", -_velocity_gap(p, t)), ("no_half", 2 * approx(omega)), ("omega", approx(0.2)),
             ("hertz", approx(2 * np.pi * omega)), ("position", dt / 2 * A / omega * (1 - np.cos(omega * t))),
             ("bound", dt / 2 * A)]
    return numeric(_EULER_VELOCITY_GAP, answer, _velocity_gap(p, t), wrong, rtol=5e-3)


_EULER_POSITION_GAP_MAX = Exercise(
    "01.2",
    praise="the position gap peaks where 1 - cos ωt = 2, and scales like 1/ω",
    hint="the largest |p - p_E| is (Δt/2) times the largest |v(t) - v0 - a(0)t|; find that maximum over the run",
    hints={
        "no_two": "1 - cos ωt reaches 2, not 1, during the run: check where |v(t) - v0| is largest",
        "velocity": "that is the bound on the velocity difference; the position difference integrates it once more",
        "units": "check the units: (Δt/2)(v(t) - v0) is in metres, A/ω² times Δt is not",
        "omega": "use the exercise's ω = 0.8 rad/s, not the notebook's default 0.2 rad/s",
        "full_dt": "the factor in front is Δt/2 (half the end-point difference), not Δt",
    },
)


def check_euler_position_gap_max(answer, *, omega: float = 0.8) -> Feedback:
    """Exercise 01.2: the largest ``|p(t) - p_E(t)|`` over the 30 s run, in m, for ``omega``
    (rad/s; ω·30 s must exceed π so that the maximum is reached). Accepts the exact maximum
    or the bound (Δt/2)(2A/ω) (rtol 1.5e-2)."""
    omega = require_positive("omega", omega)
    if omega * 30.0 <= np.pi:
        raise ValueError(f"omega must exceed pi/30 rad/s so that the run reaches ωt = π, got {omega!r}")
    p = CalibrationParams(omega=omega)
    t = p.t_imu
    pa, _ = analytic_truth(t, 0.0, 0.0, p)
    pe, _ = integrate_left(acceleration(t, p), 0.0, 0.0, p.dt)
    expected = float(np.max(np.abs(pa - pe)))
    dt, A = p.dt, p.A
    wrong = [("no_two", dt * A / (2 * omega)), ("velocity", dt * A / 2), ("units", dt * A / omega**2),
             ("omega", dt * A / 0.2), ("full_dt", 2 * dt * A / omega)]
    return numeric(_EULER_POSITION_GAP_MAX, answer, expected, wrong, rtol=1.5e-2)


#: test input of the Euler-truth exercise (m/s², m, m/s, s)
_EULER_TEST = (np.array([0.5, -1.0, 2.0, 0.0, 3.0, -2.0, 1.5]), 1.0, 2.0, 0.1)


def _euler_variant(a, p0, v0, dt, kind: str):
    n = len(a)
    p, v = np.empty(n), np.empty(n)
    p[0], v[0] = p0, v0
    for j in range(n - 1):
        aj = a[j + 1] if kind == "right" else a[j]
        v[j + 1] = v[j] + aj * dt
        vv = v[j + 1] if kind == "new_v" else v[j]
        acc = {"no_acc": 0.0, "dt2": aj * dt**2}.get(kind, aj * dt**2 / 2)
        p[j + 1] = p[j] + vv * dt + acc
    return p, v


_EULER_TRUTH = Exercise(
    "01.3",
    praise="your recursion is the Euler truth (and the IMU mechanization) of the notebook",
    hint="compare your recursion with the notebook's Euler truth, term by term: which samples of a and v does each "
         "step use, and with which powers of Δt?",
    hints={
        "new_v": "the position step uses the velocity at t_j (before the update), not v(t_{j+1})",
        "no_acc": "the position step is missing the acceleration term a(t_j)Δt²/2",
        "dt2": "the acceleration term of the position step is a(t_j)Δt²/2, with the 1/2 (or you used the updated "
               "velocity without it)",
        "right": "left Riemann: the step from t_j to t_{j+1} uses a(t_j), not a(t_{j+1})",
        "swapped": "return (p, v) in this order: position first",
        "length": "p and v need one entry per sample of a, starting with p[0] = p0, v[0] = v0",
        "tuple": "return a tuple (p, v) of two arrays",
    },
)


def check_euler_truth(func) -> Feedback:
    """Exercise 01.3: ``func(a, p0, v0, dt) -> (p, v)``, the Euler (left-Riemann) truth.

    Called on a 7-sample test acceleration (m/s²) with p0 = 1 m, v0 = 2 m/s, dt = 0.1 s;
    p, v must equal :func:`~kfcal_helpers.calibration.integrate_left`, shape (7,) each.
    """
    ex = _EULER_TRUTH
    a, p0, v0, dt = _EULER_TEST
    out, fb = call_once(ex, func, "euler_truth(a, p0, v0, dt)", (a.copy(), p0, v0, dt))
    if fb is not None:
        return fb
    pair = as_pair(out)
    if pair is None:
        return ex.mistake("tuple")
    p, v = pair
    if p.size != len(a) or v.size != len(a):
        return ex.mistake("length")
    p_ok, v_ok = integrate_left(a, p0, v0, dt)
    if close(p, p_ok) and close(v, v_ok):
        return ex.feedback(True)
    if close(p, v_ok) and close(v, p_ok):
        return ex.mistake("swapped")
    for kind in ("right", "new_v", "no_acc", "dt2"):
        pw, vw = _euler_variant(a, p0, v0, dt, kind)
        if close(p, pw) and close(v, vw):
            return ex.mistake(kind)
    slip = ex.output_slip([p, v], [p_ok, v_ok], ("p", "v"))
    if slip is not None:
        return slip
    if close(v, v_ok):
        return ex.feedback(False, "v is right, p is not: " + ex.hint)
    return ex.feedback(False)


#: the exercise records of this lesson, in notebook order
RECORDS = (_EULER_VELOCITY_GAP, _EULER_POSITION_GAP_MAX, _EULER_TRUTH)
