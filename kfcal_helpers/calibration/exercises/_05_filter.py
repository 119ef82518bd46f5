"""Exercise checks of notebook 05 (the Kalman filter with filterpy): 05.1-05.3."""

from __future__ import annotations


from functools import lru_cache

import numpy as np

from ...exercises._core import (Exercise, Feedback)
from ...validation import (require_covariance)
from ..error_model import error_state_model, phi_power
from ..filters import covariance_sequence
from ..params import CalibrationParams
from ...exercises._slips import matrix_names
from ._shared import call_once, close, numeric, as_pair


@lru_cache(maxsize=1)
def _predict_test():
    """Test input of the predict-only exercise: x (3,), a full P (3, 3), Phi, Q of the defaults, n."""
    params = CalibrationParams()
    m = error_state_model(params)
    P = covariance_sequence(params)[0][params.fix_indices[10]]
    return np.array([1.0, -0.5, 0.02]), P, m.Phi, m.Q, 40


def _predict(x, P, Phi, Q, n, transposed=False, q=True):
    for _ in range(n):
        x = Phi @ x
        P = (Phi.T @ P @ Phi if transposed else Phi @ P @ Phi.T) + (Q if q else 0.0)
    return x, P


#: the entries of x̄ and of M (flattened, row by row), for the hints that name the wrong ones (05.1)
X_ENTRIES = ("x̄[0] (δp)", "x̄[1] (δv)", "x̄[2] (b)")
M_ENTRIES = tuple(f"M[{i},{j}]" for i in range(3) for j in range(3))

_PREDICT_ONLY = Exercise(
    "05.1",
    praise="your predict-only loop matches filterpy's predict()",
    hint="each of the n steps is one filterpy predict(): compare what it does to x̄ and to M with your loop",
    hints={
        "no_q": "M also grows by the process noise Q at every step",
        "transposed": "the covariance step is Φ M Φᵀ (Φ on the left), not Φᵀ M Φ",
        "x_static": "the estimate is predicted too: x̄ ← Φ x̄ at every step",
        "one_short": "your loop runs one step too few: n steps means n predictions",
        "one_long": "your loop runs one step too many: n steps means n predictions",
        "q_once": "Q is added at every step, not once at the end",
        "p_static": "the covariance must be propagated as well: M ← Φ M Φᵀ + Q at every step",
        "tuple": "return a tuple (x, M): x of shape (3,) or (3, 1), M of shape (3, 3)",
    },
)


def check_predict_only(func) -> Feedback:
    """Exercise 05.1: ``func(x, M, Phi, Q, n) -> (x, M)`` after ``n`` predict-only steps (M the covariance,
    the a priori one after the first step).

    Called with the defaults' Φ, Q, x = [1, -0.5, 0.02] (m, m/s, m/s²), a full covariance (the filter's
    a posteriori P at the fix t = 2 s) and n = 40; x may come back as (3,) or (3, 1), M as (3, 3).
    """
    ex = _PREDICT_ONLY
    x0, P0, Phi, Q, n = _predict_test()
    out, fb = call_once(ex, func, "predict_only(x, M, Phi, Q, n)", (x0.copy(), P0.copy(), Phi.copy(), Q.copy(), n))
    if fb is not None:
        return fb
    pair = as_pair(out)
    if pair is None or pair[0].size != 3 or pair[1].size != 9:
        return ex.mistake("tuple")
    x, P = pair[0].reshape(3), pair[1].reshape(3, 3)
    tol = dict(rtol=1e-8, atol=1e-15)
    x_ok, P_ok = _predict(x0, P0, Phi, Q, n)
    if close(x, x_ok, **tol) and close(P, P_ok, **tol):
        return ex.feedback(True)
    Phi_n = np.linalg.matrix_power(Phi, n)
    variants = [("one_short", _predict(x0, P0, Phi, Q, n - 1)), ("one_long", _predict(x0, P0, Phi, Q, n + 1)),
                ("no_q", (x_ok, _predict(x0, P0, Phi, Q, n, q=False)[1])),
                ("transposed", (x_ok, _predict(x0, P0, Phi, Q, n, transposed=True)[1])),
                ("q_once", (x_ok, Phi_n @ P0 @ Phi_n.T + Q)), ("p_static", (x_ok, P0)), ("x_static", (x0, P_ok))]
    for key, (xw, Pw) in variants:
        if close(x, xw, **tol) and close(P, Pw, **tol):
            return ex.mistake(key)
    slip = ex.output_slip([x, P], [x_ok, P_ok], ("x̄", "M"), components=[X_ENTRIES, M_ENTRIES], **tol)
    if slip is not None:
        return slip
    if close(x, x_ok, **tol):
        return ex.feedback(False, "x̄ is right, M is not: " + ex.hint)
    if close(P, P_ok, **tol):
        return ex.feedback(False, "M is right, x̄ is not: " + ex.hint)
    return ex.feedback(False)


def _gain(P, H, V):
    return P @ H.T @ np.linalg.inv(H @ P @ H.T + V)


_FIRST_GAIN = Exercise(
    "05.2",
    praise="the first gain: a diagonal prior gives a gain that ignores the bias",
    hint="at the first fix nothing has been predicted yet: form the gain of notebook 05 from the prior M0 and the "
         "exercise's V, and check each factor",
    hints={
        "default_v": "use the exercise's GPS noise V = diag(4, 0.01), not the notebook's",
        "swapped": "the variances are swapped: V[0,0] is the position variance (m²), V[1,1] the velocity one ((m/s)²)",
        "no_p_in_s": "the innovation covariance is S = H M Hᵀ + V (M the a priori covariance): the prior "
                     "uncertainty is in S too",
        "no_p": "K = M Hᵀ S⁻¹: the a priori covariance M multiplies Hᵀ S⁻¹",
        "shape": "K maps a measurement (2) to a state correction (3): shape (3, 2)",
    },
    components=matrix_names("K", 3, 2),
)


def check_first_gain(answer, *, V=((4.0, 0.0), (0.0, 0.01))) -> Feedback:
    """Exercise 05.2: the Kalman gain K (3, 2) at the first fix (t = 0, prior M0 of the defaults)
    for a GPS noise covariance ``V`` (2, 2) in m², (m/s)²."""
    V = require_covariance("V", V, 2)
    m = error_state_model(CalibrationParams())
    M0, H = m.M0, m.H
    right = _gain(M0, H, V)
    wrong = [("default_v", _gain(M0, H, m.V)), ("swapped", _gain(M0, H, V[::-1, ::-1])),
             ("no_p_in_s", M0 @ H.T @ np.linalg.inv(V)), ("no_p", H.T @ np.linalg.inv(H @ M0 @ H.T + V))]
    if np.allclose(V, m.V):
        wrong = wrong[1:]
    return numeric(_FIRST_GAIN, answer, right, wrong, shape_key="shape")


_SECOND_GAIN = Exercise(
    "05.3",
    praise="the second gain: after 0.2 s of prediction the bias row is no longer zero",
    hint="follow the filter: the first fix's update, the prediction steps to the next fix, then the gain as in 05.2",
    hints={
        "once_per_fix": "one predict call per fix is one IMU step: between two fixes the filter predicts once per IMU "
                        "sample, with the 200 Hz Φ and Q",
        "fix_phi_one_q": "the fix-to-fix Φ⁴⁰ carries P over the interval, but each of its 40 IMU steps adds its own "
                         "process noise Q (carried on by the later steps), not one Q for the whole interval",
        "one_short": "count the predictions from one fix to the next: every IMU step, the one onto the fix included",
        "one_long": "one prediction too many: 40 IMU steps separate two fixes at 200 Hz / 5 Hz",
        "no_q": "P grows by the process noise Q at every predict step",
        "no_first_update": "predict from the a posteriori P of the first fix (after its update), not from M0",
        "first_gain": "that is the gain at the first fix (t = 0, exercise 05.2); the exercise asks for the one at the "
                      "second fix, after the first update and 0.2 s of prediction",
    },
    components=matrix_names("K", 3, 2),
)


def check_second_gain(answer) -> Feedback:
    """Exercise 05.3: the Kalman gain K (3, 2) at the second fix (t = 0.2 s), defaults."""
    params = CalibrationParams()
    right = covariance_sequence(params)[3][1]
    m = error_state_model(params)
    H, V = m.H, m.V
    K0 = _gain(m.M0, H, V)
    I_KH = np.eye(3) - K0 @ H
    P0 = I_KH @ m.M0 @ I_KH.T + K0 @ V @ K0.T
    r = params.steps_per_fix

    def gain_after(P, n, q=True):
        return _gain(_predict(np.zeros(3), P, m.Phi, m.Q, n, q=q)[1], H, V)

    wrong = [("one_short", gain_after(P0, r - 1)), ("one_long", gain_after(P0, r + 1)),
             ("no_q", gain_after(P0, r, q=False)), ("no_first_update", gain_after(m.M0, r)),
             ("once_per_fix", gain_after(P0, 1)), ("first_gain", K0)]
    F = phi_power(params, r)
    wrong.append(("fix_phi_one_q", _gain(F @ P0 @ F.T + m.Q, H, V)))
    return numeric(_SECOND_GAIN, answer, right, wrong)


#: the exercise records of this lesson, in notebook order
RECORDS = (_PREDICT_ONLY, _FIRST_GAIN, _SECOND_GAIN)
