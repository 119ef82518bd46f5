"""Exercise checks of notebook 15 (GPS outages): 15.1-15.2."""

from __future__ import annotations



import numpy as np

from ...exercises._core import (Exercise, Feedback, as_array, unanswered)
from ...validation import (require_covariance)
from ..error_model import error_state_model
from ..outages import outage_mask
from ..params import CalibrationParams
from ._shared import numeric


_OUTAGE_MASK = Exercise(
    "15.1",
    praise="a half-open window: the fix at t_s is missing, the one at t_e is back",
    hint="one entry per GPS fix: check which end of each window is inside it, and what True means",
    hints={
        "closed": "the window is half-open, t_s <= t < t_e: the fix at t_e is the first one back",
        "open_start": "the window is half-open, t_s <= t < t_e: the fix at t_s is already missing",
        "inverted": "True marks a MISSING fix (as outage_mask returns), not a fix that is used",
        "imu_rate": "one entry per GPS fix, not per IMU sample",
    },
    units=False,
)


def check_outage_mask(answer, *, windows=((5.0, 7.0), (20.0, 21.5))) -> Feedback:
    """Exercise 15.1: the bool mask (151,) of the missing GPS fixes (defaults: 5 Hz, 30 s) for
    half-open outage ``windows`` [(start, end), ...] in seconds."""
    params = CalibrationParams()
    right = outage_mask(params, windows)
    t = params.t_gps
    closed = np.zeros(params.n_gps, bool)
    open_start = np.zeros(params.n_gps, bool)
    for ts, te in windows:
        closed |= (t >= ts - 1e-9) & (t <= te + 1e-9)
        open_start |= (t > ts + 1e-9) & (t < te - 1e-9)
    wrong = [("closed", closed), ("open_start", open_start), ("inverted", ~right)]
    a = as_array(answer) if not (unanswered(answer) or isinstance(answer, (str, bytes)) or callable(answer)) else None
    if a is not None and a.size == params.n_imu:
        return _OUTAGE_MASK.mistake("imu_rate")
    return numeric(_OUTAGE_MASK, answer, right.astype(float), [(k, v.astype(float)) for k, v in wrong])


def propagate(P0, n, q=True):
    m = error_state_model(CalibrationParams())
    P = np.array(P0, dtype=float)
    for _ in range(n):
        P = m.Phi @ P @ m.Phi.T + (m.Q if q else 0.0)
    return P


_OUTAGE_SIGMA = Exercise(
    "15.2",
    praise="the a priori σ at the first fix back",
    hint="propagate P0 with P ← Φ P Φᵀ + Q from the last fix before the gap to the first fix back",
    hints={
        "from_gap_start": "the filter coasts from the last fix BEFORE the gap (t_s - 0.2 s), not from t_s",
        "no_q": "the IMU noise keeps adding Q = W ΓΓᵀ at every step of the outage",
        "variance": "these are variances: the exercise asks for standard deviations",
    },
    components=("σ_p", "σ_v", "σ_b"),
)


def check_outage_sigma(answer, *, P0=((0.04, 0.0, 0.0), (0.0, 1e-4, 0.0), (0.0, 0.0, 1e-6)),
                       start: float = 10.0, end: float = 20.0) -> Feedback:
    """Exercise 15.2: the a priori standard deviations ``[σ_p, σ_v, σ_b]`` (m, m/s, m/s²), shape (3,),
    at the first fix back after the outage [start, end) s (defaults: 200 Hz, 5 Hz), when the
    a posteriori P at the last fix before the gap is ``P0`` (3, 3)."""
    P0 = require_covariance("P0", P0, 3)
    params = CalibrationParams()
    mask = outage_mask(params, [(start, end)], name="start/end")
    idx = np.flatnonzero(mask)
    if idx[0] == 0:
        raise ValueError("start must leave a fix before the outage (start >= 0.2 s)")
    if idx[-1] == params.n_gps - 1:
        raise ValueError("end must leave a fix after the outage (end <= 30 s)")
    r = params.steps_per_fix
    n = (idx[-1] + 1 - (idx[0] - 1)) * r  # IMU steps from the last fix before to the first fix back
    sd = lambda P: np.sqrt(np.diag(P))  # noqa: E731
    right = sd(propagate(P0, n))
    wrong = [("from_gap_start", sd(propagate(P0, n - r))), ("no_q", sd(propagate(P0, n, q=False))),
             ("variance", right**2)]
    return numeric(_OUTAGE_SIGMA, answer, right, wrong)


#: the exercise records of this lesson, in notebook order
RECORDS = (_OUTAGE_MASK, _OUTAGE_SIGMA)
