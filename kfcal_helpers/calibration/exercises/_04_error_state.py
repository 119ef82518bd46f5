"""Exercise checks of notebook 04 (the error-state model): 04.1-04.4."""

from __future__ import annotations


from dataclasses import replace

import numpy as np

from ...exercises._core import (Exercise, Feedback, as_array, too_large, unanswered)
from ...validation import (require_positive)
from ..error_model import error_state_model, phi_power
from ..params import CalibrationParams
from ...exercises._slips import matrix_names
from ._shared import numeric


def _phi(dt: float, corner: float | None = None, signs: float = -1.0) -> np.ndarray:
    corner = signs * dt**2 / 2 if corner is None else corner
    return np.array([[1.0, dt, corner], [0.0, 1.0, signs * dt], [0.0, 0.0, 1.0]])


_PHI_100HZ = Exercise(
    "04.1",
    praise="Φ at 100 Hz",
    hint="write the two recursions of notebook 04 with the exercise's Δt and read off the coefficients",
    hints={
        "sign_corner": "check the sign of Φ[0,2]: a positive bias pulls δp down, like δv",
        "dt_corner": "Φ[0,2] is the position effect of a constant bias over one step: Δt²/2, not Δt",
        "signs_bias": "the bias enters with a minus sign: a positive bias makes the IMU over-read, so δp and δv "
                      "decrease",
        "rate": "use the exercise's IMU rate (100 Hz), so Δt changes",
        "transposed": "Φ maps δx_j to δx_{j+1}: row i holds the coefficients of the new component i (upper "
                      "triangular)",
        "no_half": "the position effect of the bias over one step is Δt²/2, with the 1/2",
    },
    components=matrix_names("Φ", 3),
)


def check_phi_100hz(answer, *, imu_rate: float = 100.0) -> Feedback:
    """Exercise 04.1: the transition matrix Φ (3, 3) of ``[δp, δv, b]`` for an IMU at
    ``imu_rate`` Hz (Δt = 1/imu_rate s)."""
    dt = 1.0 / require_positive("imu_rate", imu_rate)
    right = error_state_model(CalibrationParams(imu_rate=imu_rate, gps_rate=imu_rate / 20)).Phi
    wrong = [("sign_corner", _phi(dt, corner=dt**2 / 2)), ("dt_corner", _phi(dt, corner=-dt)),
             ("signs_bias", _phi(dt, signs=1.0)), ("rate", _phi(0.005)), ("transposed", right.T),
             ("no_half", _phi(dt, corner=-dt**2))]
    return numeric(_PHI_100HZ, answer, right, wrong)


#: the praise of 04.2 for -Γ: the same Q, so also right
GAMMA_OTHER_SIGN_PRAISE = ("Γ at 100 Hz, with the opposite sign of the notebook's: w is zero-mean white noise, so -w is "
                           "the same noise and Q = W Γ Γᵀ is unchanged; either sign is right")

_GAMMA_100HZ = Exercise(
    "04.2",
    praise="Γ at 100 Hz",
    hint="Γ holds the coefficients of w_j in the recursions of δp, δv and b",
    hints={
        "dt_first": "the position effect of w over one step is Δt²/2, not Δt",
        "no_half": "the position effect of w over one step is Δt²/2, with the 1/2",
        "rate": "use the exercise's IMU rate (100 Hz), so Δt changes",
        "bias_noise": "the bias is constant over a run: w does not drive it",
    },
    components=("Γ[0]", "Γ[1]", "Γ[2]"),
)


def check_gamma_100hz(answer, *, imu_rate: float = 100.0) -> Feedback:
    """Exercise 04.2: the noise input vector Γ, shape (3,) (or (3, 1)), of the error-state model
    for an IMU at ``imu_rate`` Hz.  -Γ is accepted too (the same Q = W Γ Γᵀ), with a praise that says so."""
    dt = 1.0 / require_positive("imu_rate", imu_rate)
    right = error_state_model(CalibrationParams(imu_rate=imu_rate, gps_rate=imu_rate / 20)).Gamma
    wrong = [("dt_first", [-dt, -dt, 0.0]), ("no_half", [-dt**2, -dt, 0.0]),
             ("rate", [-0.005**2 / 2, -0.005, 0.0]), ("bias_noise", [-dt**2 / 2, -dt, 1.0])]
    a = as_array(answer) if not unanswered(answer) and too_large(answer, right) is None else None
    if a is not None and a.size == 3 and np.all(np.isfinite(a)) and a.ravel()[1] > 0:
        # -Γ gives the same Q: right too, judged as Γ is (its mistakes and slips are the same, sign flipped)
        flipped = replace(_GAMMA_100HZ, praise=GAMMA_OTHER_SIGN_PRAISE)
        return numeric(flipped, answer, -right, [(k, -np.asarray(v, dtype=float)) for k, v in wrong])
    return numeric(_GAMMA_100HZ, answer, right, wrong)


_PHI_FIX_TO_FIX = Exercise(
    "04.3",
    praise="the fix-to-fix transition: a constant bias over s seconds shifts δv by -b s and δp by -b s²/2",
    hint="multiply Φ by itself k times (or think of what a constant bias does over kΔt seconds); check k and Δt",
    hints={
        "linear": "Φ^k is not I + k(Φ - I): the bias acts on δv, which then acts on δp, so the corner grows like "
                  "(kΔt)²/2",
        "steps": "count the IMU steps between two fixes at the exercise's rates (100 Hz IMU, 4 Hz GPS)",
        "rate": "use the exercise's IMU rate (100 Hz) for Δt",
        "signs": "the bias column keeps its minus signs in every power of Φ",
        "one_short": "from one fix to the next is f_imu/f_gps steps, not one fewer",
    },
    components=matrix_names("Φ^k", 3),
)


def check_phi_fix_to_fix(answer, *, imu_rate: float = 100.0, gps_rate: float = 4.0) -> Feedback:
    """Exercise 04.3: the fix-to-fix transition Φ^k (3, 3), k = imu_rate/gps_rate IMU steps."""
    p = CalibrationParams(imu_rate=require_positive("imu_rate", imu_rate),
                          gps_rate=require_positive("gps_rate", gps_rate))
    k, dt = p.steps_per_fix, p.dt
    right = phi_power(p, k)
    s = k * dt
    wrong = [("linear", _phi(s, corner=-k * dt**2 / 2)), ("steps", phi_power(p, 40)),
             ("rate", _phi(k * 0.005)), ("signs", _phi(s, signs=1.0)), ("one_short", phi_power(p, k - 1))]
    if k == 40:
        wrong = [w for w in wrong if w[0] != "steps"]
    return numeric(_PHI_FIX_TO_FIX, answer, right, wrong)


_M0 = Exercise(
    "04.4",
    praise="M0 in the state order [δp, δv, b]",
    hint="M0 = diag(M_p, M_v, M_b) holds the prior variances in the state order [δp, δv, b]",
    hints={
        "sigmas": "M0 holds variances: square the standard deviations",
        "swapped": "the state order is [δp, δv, b]: the position variance comes first",
        "default": "use the exercise's standard deviations, not the notebook's defaults",
    },
    components=matrix_names("M0", 3),
)


def check_m0(answer, *, sigma_p: float = 5.0, sigma_v: float = 0.5, sigma_b: float = 0.05) -> Feedback:
    """Exercise 04.4: the prior covariance M0 (3, 3) of ``[δp, δv, b]`` for prior standard
    deviations ``sigma_p`` (m), ``sigma_v`` (m/s), ``sigma_b`` (m/s²)."""
    s = np.array([require_positive(n, x) for n, x in (("sigma_p", sigma_p), ("sigma_v", sigma_v),
                                                       ("sigma_b", sigma_b))])
    right = error_state_model(CalibrationParams(p0_var=s[0]**2, v0_var=s[1]**2, bias_var=s[2]**2)).M0
    wrong = [("sigmas", np.diag(s)), ("swapped", np.diag(s[[1, 0, 2]] ** 2)),
             ("default", error_state_model(CalibrationParams()).M0)]
    return numeric(_M0, answer, right, wrong)


#: the exercise records of this lesson, in notebook order
RECORDS = (_PHI_100HZ, _GAMMA_100HZ, _PHI_FIX_TO_FIX, _M0)
