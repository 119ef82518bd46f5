"""What the cooperative-localization checks share: the exercises' numbers (as the notebooks' exercise texts state them), tolerances, and the calls of a student's function."""

from __future__ import annotations


import math

import numpy as np

from ..model import (
    CoopParams,
)
from ...exercises._core import (Exercise, as_array, call_student, matches,
                               too_large, unanswered)
from ...exercises._slips import slip_hint



U0_DEFAULT = tuple(CoopParams().u0)

# ---------------------------------------------------------------------------
# Parameters of the exercises (as stated in the notebooks' exercise text)
#: 08.1: state (m, m, rad, m, m, rad), control (m/s, rad, m/s, rad/s), step (s), wheelbase (m)
STEP_X = (2.0, 1.0, 3.0, -30.0, 40.0, -0.5)
STEP_U = (1.0, math.pi / 8, 8.0, 0.0)
STEP_DT = 0.5
#: 08.2: the configuration whose measurement vector is asked
MEAS_X = (5.0, -3.0, 2.5, -20.0, -10.0, 1.0)  # the UAV's bearing is negative: [0, 2pi) wrapping shows
#: 09.1: the configuration of the bearing row of C
ROW_X = (3.0, -4.0, 0.7, 15.0, 1.0, 2.0)
#: 09.2: the state and the other sampling interval
FDT_X = (0.0, 0.0, 2.0, 0.0, 0.0, -0.8)
FDT_DT = 0.05
#: 09.4: the sample period (s) of the per-step state noise Omega Qtrue Omega^T
OMEGA_DT = 0.05
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

#: the entries of a state and of a measurement by name, for the hints that name the one or two wrong ones
STATE_NAMES = ("the UGV's east position xi_g", "the UGV's north position eta_g", "the UGV's heading theta_g",
               "the UAV's east position xi_a", "the UAV's north position eta_a", "the UAV's heading theta_a")
MEAS_NAMES = ("the bearing UGV->UAV", "the range", "the bearing UAV->UGV", "the UAV's GPS east xi_a",
              "the UAV's GPS north eta_a")
#: what a slip's hint calls the outputs of a student's function (stacked over the test cases)
FN_RESULT = "your function's result"


def slip_before_wrapping(exercise: Exercise, answer, expected):
    """The Feedback of a slip (:func:`~kfcal_helpers.exercises.slip_hint`: units, degrees for the
    exercise's ``angles``, reversed) of an answer whose angles the check wraps before judging it: the
    wrapping would hide the slip (an angle in degrees or times 100 wraps to another angle).  None when
    the answer is no slip of ``expected``."""
    a = finite_of_size(answer, np.size(expected)) if not unanswered(answer) else None
    if a is None:
        return None
    hint = slip_hint(a, expected, rtol=NUM_RTOL, atol=NUM_ATOL, angles=exercise.angles)
    return None if hint is None else exercise.feedback(False, hint)


NUM_RTOL, NUM_ATOL = 1e-7, 1e-9  # numeric answers: the computed value (no rounding), any float-exact formula
FN_RTOL, FN_ATOL = 1e-7, 1e-9  # outputs of a student's function (same float formula)
BOUNDS_RTOL = 1e-9  # chi-square bounds: the computed quantiles (no rounding)


def finite_of_size(answer, size):
    """``answer`` as a flat float array when it has ``size`` finite entries, else None (a larger answer
    before any conversion)."""
    if too_large(answer, np.zeros(size)) is not None:
        return None
    a = as_array(answer)
    if a is None or a.size != size or not np.all(np.isfinite(a)):
        return None
    return a.reshape(size)


def call_checked(exercise: Exercise, fn, cases, out_shape: tuple, what: str, size_hint: str | None = None):
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


def wrap_answer(answer, expected, wrap):
    """``(answer with its angles wrapped by wrap, unwrapped)``: ``unwrapped`` is True when only the
    wrapping was missing (the wrapped answer is right, the answer as given is not)."""
    flat = finite_of_size(answer, np.size(expected))
    if flat is None:
        return answer, False
    wrapped = wrap(flat)
    right = matches(wrapped, expected, NUM_RTOL, NUM_ATOL) and not matches(flat, expected, NUM_RTOL, NUM_ATOL)
    return wrapped, right


def pi_for_minus_pi(values, idx=None):
    """Copy of ``values`` with entries equal to -pi (to rounding) replaced by pi: both are
    the same angle, and (-pi, pi] vs [-pi, pi) is a convention, not a mistake."""
    v = np.array(values, dtype=float)
    sel = v if idx is None else v[..., list(idx)]
    sel = np.where(np.abs(sel + np.pi) < 1e-9, np.pi, sel)
    if idx is None:
        return sel
    v[..., list(idx)] = sel
    return v
