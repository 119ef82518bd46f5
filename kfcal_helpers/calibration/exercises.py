"""Exercise checks of the calibration notebooks: 01-07, 14 (its calibration exercises), 15, 16 and 17.

Every ``check_<topic>(answer, *, settings...)`` takes the student's answer (a number, an array, a
set of names or a function, as the exercise text says) positionally, and the exercise's settings
as keywords only, and returns a one-line :class:`~kfcal_helpers.exercises.Feedback`.  The right
answer is computed here from the project's model (:mod:`kfcal_helpers.calibration`) or from first
principles, with the exercise's settings as keyword defaults; the common wrong answers are
computed the same way.  Each exercise is one :class:`~kfcal_helpers.exercises.Exercise` record
(id, praise, generic hint, the hint of each recognised mistake), defined right above its check;
:data:`EXERCISES` lists them by id.

A check never raises or warns because of the answer: a placeholder (``None`` or ``...``) gives
"not answered yet", a malformed answer (a string, a wrong shape, a complex number, an integer too
large for a float, NaN, a function that raises) gives a one-line hint.  Bad *settings* raise
``ValueError`` naming the setting.  One answer-format rule for every exercise
(:data:`~kfcal_helpers.exercises.FORMAT_RULE`): pass the value you computed, with no rounding; the
tolerances below are float-level, or, where stated, accept a documented approximation.

Exercise ids are ``"NN.k"``: notebook NN, exercise k.  Worked solutions are in
``notebooks/solutions/NN_*.ipynb``.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np
from scipy import stats

from ..consistency import chi2_bounds
from ..exercises._core import (PLACEHOLDER, Exercise, Feedback, as_array, call_student, chi2_average_bounds, distinct_mistakes,
                               shape_hint, too_large, unanswered)
from ..validation import (require_covariance, require_finite, require_instance, require_int, require_positive,
                          require_probability)
from .batch_estimate import batch_conditioning
from .error_model import error_state_model, phi_power
from .filters import covariance_sequence
from .montecarlo import CHECK_NAMES, run_monte_carlo
from .outages import outage_mask
from .params import CalibrationParams
from .simulation import acceleration, analytic_truth, integrate_left

__all__ = [
    # 01 truth model
    "check_euler_velocity_gap", "check_euler_position_gap_max", "check_euler_truth",
    # 02 IMU model
    "check_imu_drift", "check_imu_random_walk", "check_imu_std_band",
    # 03 GPS model
    "check_gps_fix_indices", "check_gps_dz", "check_gps_rms_band",
    # 04 error-state model
    "check_phi_100hz", "check_gamma_100hz", "check_phi_fix_to_fix", "check_m0",
    # 05 the filter
    "check_predict_only", "check_first_gain", "check_second_gain",
    # 06 Monte Carlo
    "check_mc_nis_bounds", "check_fisher_band", "check_simultaneous_nees_band",
    # 07 model mismatch
    "check_apparent_bias", "check_trapezoid_velocity", "check_mismatch_failures",
    # 14 mistakes (calibration)
    "check_failing_checks_gps_sigma", "check_phi02_coupling_change",
    # 15 GPS outages
    "check_outage_mask", "check_outage_sigma",
    # 16 minimum variance
    "check_batch_two_fixes", "BATCH_TWO_FIXES_DZ", "check_smoothed_bias_sigma",
    # 17 live demo
    "check_demo_first_fix_sigma", "check_demo_ratio_band",
    # the records and the reference computations the notebooks and tests use
    "EXERCISES", "first_fix_sigmas", "ratio_band",
]


# ----------------------------------------------------------------------------------------
# shared helpers
# ----------------------------------------------------------------------------------------
def _numeric(ex: Exercise, answer, expected, wrong=(), *, rtol: float = 1e-6, atol: float = 1e-12,
             placeholder: str = PLACEHOLDER, shape_key: str | None = None) -> Feedback:
    """``ex.judge`` with ``wrong`` as ``(mistake key, value)`` pairs, plus the answer judge() would
    misread: a matrix of the right size but another shape (transposed or flat; the hint ``shape_key`` of
    ``ex`` when given, else :func:`shape_hint`).  An answer larger than every expected value is judged
    from its shape before any conversion.  Everything that is
    not real finite numbers is judge()'s (the harness screens it in one place)."""
    if unanswered(answer):
        return ex.unanswered(placeholder)
    e = np.asarray(expected, dtype=float)
    big = too_large(answer, e, *(v for _, v in wrong))  # before any conversion: a broadcast view costs nothing yet
    if big is not None:
        return ex.feedback(False, big)
    a = as_array(answer)
    if a is not None and np.all(np.isfinite(a)):
        if e.ndim == 2 and a.size == e.size and np.squeeze(a).shape != e.shape:
            return ex.mistake(shape_key) if shape_key else ex.feedback(False, shape_hint(a.shape, e.shape))
    return ex.judge(answer, expected, [(v, k) for k, v in wrong], rtol=rtol, atol=atol, placeholder=placeholder)


def _call_once(ex: Exercise, func, what: str, args: tuple):
    """The student's ``func(*args)`` through :func:`call_student`: ``(output, None)`` or ``(None, Feedback)``."""
    outs, fb = call_student(ex.id, func, [args], what)
    return (None, fb) if fb is not None else (outs[0], None)


def _pair(out):
    """``out`` as two float arrays (a 2-tuple/list), or None."""
    if isinstance(out, (str, bytes)) or not isinstance(out, (tuple, list)) or len(out) != 2:
        return None
    first, second = as_array(out[0]), as_array(out[1])
    if first is None or second is None:
        return None
    return first, second


def _close(a, b, rtol: float = 1e-9, atol: float = 1e-12) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.size != b.size:
        return False
    a = a.reshape(b.shape)
    return bool(np.all(np.isfinite(a)) and np.allclose(a, b, rtol=rtol, atol=atol))


# ----------------------------------------------------------------------------------------
# 01 truth model
# ----------------------------------------------------------------------------------------
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
    return _numeric(_EULER_VELOCITY_GAP, answer, _velocity_gap(p, t), wrong, rtol=5e-3)


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
    return _numeric(_EULER_POSITION_GAP_MAX, answer, expected, wrong, rtol=1.5e-2)


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
    out, fb = _call_once(ex, func, "euler_truth(a, p0, v0, dt)", (a.copy(), p0, v0, dt))
    if fb is not None:
        return fb
    pair = _pair(out)
    if pair is None:
        return ex.mistake("tuple")
    p, v = pair
    if p.size != len(a) or v.size != len(a):
        return ex.mistake("length")
    p_ok, v_ok = integrate_left(a, p0, v0, dt)
    if _close(p, p_ok) and _close(v, v_ok):
        return ex.feedback(True)
    if _close(p, v_ok) and _close(v, p_ok):
        return ex.mistake("swapped")
    for kind in ("right", "new_v", "no_acc", "dt2"):
        pw, vw = _euler_variant(a, p0, v0, dt, kind)
        if _close(p, pw) and _close(v, vw):
            return ex.mistake(kind)
    if _close(v, v_ok):
        return ex.feedback(False, "v is right, p is not: " + ex.hint)
    return ex.feedback(False)


# ----------------------------------------------------------------------------------------
# 02 IMU model
# ----------------------------------------------------------------------------------------
_IMU_DRIFT = Exercise(
    "02.1",
    praise="the bias drift is linear in velocity and quadratic in position",
    hint="integrate the bias once for δv and twice for δp, starting from the initial errors (bias only, no noise), "
         "and check each term and its sign",
    hints={
        "sign": "check the sign of the bias terms: a positive bias makes the IMU over-read, so p_c and v_c run "
                "ahead of the truth",
        "no_half": "the bias enters the position like a constant acceleration: t²/2, not t²",
        "no_dv0_t": "the initial velocity error also moves the position: it adds δv0·t to δp",
        "swapped": "give [δp, δv] in this order: position first",
        "no_initial": "the initial errors δp0 and δv0 are still in δp and δv: the bias only adds to them",
    },
)


def check_imu_drift(answer, *, b: float = 0.05, dp0: float = 2.0, dv0: float = -0.3, t: float = 20.0) -> Feedback:
    """Exercise 02.1: bias-only dead-reckoning drift ``[δp(t), δv(t)]`` (m, m/s), shape (2,),
    for bias ``b`` (m/s²), initial errors ``dp0`` (m), ``dv0`` (m/s), after ``t`` seconds."""
    b, dp0, dv0 = (require_finite(n, x) for n, x in (("b", b), ("dp0", dp0), ("dv0", dv0)))
    t = require_positive("t", t)
    dv = dv0 - b * t
    dp = dp0 + dv0 * t - b * t**2 / 2
    wrong = [("sign", [dp0 + dv0 * t + b * t**2 / 2, dv0 + b * t]), ("no_half", [dp0 + dv0 * t - b * t**2, dv]),
             ("no_dv0_t", [dp0 - b * t**2 / 2, dv]), ("swapped", [dv, dp]), ("no_initial", [-b * t**2 / 2, -b * t])]
    return _numeric(_IMU_DRIFT, answer, [dp, dv], wrong)


_IMU_RANDOM_WALK = Exercise(
    "02.2",
    praise="the random walk grows like √t in velocity and t^(3/2) in position",
    hint="build both variances from the per-sample variance W, the exercise's Δt and the number of noise samples "
         "before t, as in the notebook's derivation; then take square roots",
    hints={
        "variance": "these are variances: the exercise asks for standard deviations",
        "rate": "use the exercise's IMU rate (100 Hz): Δt changes, W is per sample",
        "no_dt": "W is a variance per sample: the velocity random walk after n steps has variance n W Δt²",
        "linear": "independent noise samples add in variance, not in amplitude: a random walk grows like √t",
        "swapped": "give [σ_p, σ_v] in this order: position first",
        "no_third": "check the constant in the position variance: Σ(m + 1/2)² over m < j is about j³/3",
        "steps": "check the step count: the noise samples before t number n = t/Δt (samples 0 … n-1), not one "
                 "more or one less",
    },
)


def check_imu_random_walk(answer, *, imu_rate: float = 100.0, W: float = 4e-4, t: float = 20.0) -> Feedback:
    """Exercise 02.2: random-walk standard deviations ``[σ_p(t), σ_v(t)]`` (m, m/s), shape (2,),
    of the dead reckoning for IMU noise variance ``W`` ((m/s²)² per sample) at ``imu_rate`` (Hz)
    after ``t`` seconds. Accepts the exact σ_p or σ_p ≈ √(WΔt t³/3) (rtol 1e-4)."""
    imu_rate, W, t = (require_positive(n, x) for n, x in (("imu_rate", imu_rate), ("W", W), ("t", t)))

    def exact(dt, extra=0):
        j = t / dt + extra
        return np.array([np.sqrt(W * dt**4 * (j**3 / 3 - j / 12)), np.sqrt(W * dt**2 * j)])

    dt = 1.0 / imu_rate
    right = exact(dt)
    wrong = [("variance", right**2), ("rate", exact(0.005)), ("no_dt", [np.sqrt(W * t**3 / 3), np.sqrt(W * t)]),
             ("linear", [np.sqrt(W) * t**2 / 2, np.sqrt(W) * t]), ("swapped", right[::-1]),
             ("no_third", [np.sqrt(W * dt * t**3), right[1]]), ("steps", exact(dt, -1)), ("steps", exact(dt, 1))]
    return _numeric(_IMU_RANDOM_WALK, answer, right, wrong, rtol=1e-4)


_IMU_STD_BAND = Exercise(
    "02.3",
    praise="the sample std of n samples has n - 1 degrees of freedom",
    hint="(n-1)s²/σ² ~ χ²_{n-1}: take the 2.5 % and 97.5 % quantiles and solve for s",
    hints={
        "n_dof": "the sample std subtracts the estimated mean (ddof=1): that uses up one degree of freedom",
        "variance": "this is the band of the sample variance: the exercise asks for the standard deviation",
        "one_sided": "a two-sided 95 % band puts α/2 = 2.5 % in each tail, not 5 %",
        "no_divide": "(n-1)s²/σ² is χ²: divide the quantiles by the degrees of freedom before taking the root",
        "normal": "close, but that is the normal approximation σ(1 ± z/√(2(n-1))): use the exact chi-square "
                  "quantiles",
    },
)


def check_imu_std_band(answer, *, sigma: float = 0.02, n: int = 50, alpha: float = 0.05) -> Feedback:
    """Exercise 02.3: the two-sided ``1 - alpha`` band ``[lower, upper]`` (m/s²), shape (2,), of the
    sample standard deviation (ddof=1) of ``n`` i.i.d. N(0, sigma²) samples."""
    sigma = require_positive("sigma", sigma)
    n = require_int("n", n, minimum=2)
    alpha = require_probability("alpha", alpha)
    right = sigma * np.sqrt(chi2_average_bounds(1, n - 1, alpha))
    z = stats.norm.ppf(1 - alpha / 2)
    wrong = [("n_dof", sigma * np.sqrt(chi2_average_bounds(1, n, alpha))),
             ("variance", sigma**2 * chi2_average_bounds(1, n - 1, alpha)),
             ("one_sided", sigma * np.sqrt(chi2_average_bounds(1, n - 1, alpha, one_sided=True))),
             ("no_divide", sigma * np.sqrt(chi2_average_bounds(1, n - 1, alpha, divide_by=1))),
             ("normal", sigma * (1 + np.array([-z, z]) / np.sqrt(2 * (n - 1)))),
             ("normal", sigma * (1 + np.array([-1.96, 1.96]) / np.sqrt(2 * (n - 1))))]  # with the usual 1.96
    return _numeric(_IMU_STD_BAND, answer, right, wrong)


# ----------------------------------------------------------------------------------------
# 03 GPS model
# ----------------------------------------------------------------------------------------
_GPS_FIX_INDICES = Exercise(
    "03.1",
    praise="those are the IMU samples that carry a 4 Hz fix",
    hint="the fixes sit on every (f_imu/f_gps)-th IMU sample, from t = 0 to t = T",
    hints={
        "no_last": "the last fix, at t = T, is included (n_imu = T·f_imu + 1 samples)",
        "no_first": "the first fix is at t = 0, on IMU sample 0",
        "times": "give IMU sample indices (integers), not times in seconds",
        "rate": "use the exercise's GPS rate (4 Hz): the spacing is f_imu/f_gps samples",
        "one_based": "indices start at 0 (Python), not at 1",
    },
)


def check_gps_fix_indices(answer, *, gps_rate: float = 4.0) -> Feedback:
    """Exercise 03.1: the IMU sample indices (ints, shape (n_gps,)) that carry a GPS fix for a
    200 Hz IMU, GPS at ``gps_rate`` (Hz, dividing 200), over 30 s."""
    p = CalibrationParams(gps_rate=require_positive("gps_rate", gps_rate))
    right = p.fix_indices
    r = p.steps_per_fix
    wrong = [("no_last", right[:-1]), ("no_first", right[1:]), ("times", p.t_gps),
             ("rate", CalibrationParams().fix_indices), ("one_based", right + 1)]
    if r == 40:  # the exercise's rate is the default: the "rate" mistake cannot be told apart
        wrong = [w for w in wrong if w[0] != "rate"]
    return _numeric(_GPS_FIX_INDICES, answer, right, wrong)


_GPS_DZ = Exercise(
    "03.2",
    praise="that is what the filter sees: GPS minus dead reckoning",
    hint="the filter's measurement compares the GPS fix with what the IMU alone says: check which quantities it "
         "uses and in which order",
    hints={
        "sign": "δz is the GPS minus the IMU dead reckoning, not the other way round",
        "swapped": "give [δz_p, δz_v] in this order: position first",
        "noise": "that is the GPS noise η = z - truth; the filter never sees the truth",
        "truth": "that is H δx (truth minus IMU); the filter's measurement uses the GPS instead of the truth",
    },
)


def check_gps_dz(answer, *, z=(4521.37, 103.412), p_c: float = 4518.90, v_c: float = 103.47,
                 p: float = 4520.81, v: float = 103.45) -> Feedback:
    """Exercise 03.2: the filter's measurement ``δz = z - [p_c, v_c]`` (m, m/s), shape (2,), for
    the GPS fix ``z`` = [position m, velocity m/s], the dead reckoning ``p_c``, ``v_c`` and the
    (unknown to the filter) truth ``p``, ``v``."""
    z = np.asarray(z, dtype=float)
    if z.shape != (2,) or not np.all(np.isfinite(z)):
        raise ValueError(f"z must be two finite numbers [position m, velocity m/s], got {z!r}")
    p_c, v_c, p, v = (require_finite(n, x) for n, x in (("p_c", p_c), ("v_c", v_c), ("p", p), ("v", v)))
    imu = np.array([p_c, v_c])
    right = z - imu
    wrong = [("sign", -right), ("swapped", right[::-1]), ("noise", z - [p, v]), ("truth", np.array([p, v]) - imu)]
    return _numeric(_GPS_DZ, answer, right, wrong)


_GPS_RMS_BAND = Exercise(
    "03.3",
    praise="with a known mean, all n samples count as degrees of freedom",
    hint="n·mean(η²)/σ² ~ χ²_n: take the 2.5 % and 97.5 % quantiles and solve for the rms",
    hints={
        "n_minus_1": "the noise mean is known (zero) and not estimated: all n degrees of freedom remain",
        "variance": "this is the band of the mean square: the exercise asks for the rms (take square roots)",
        "one_sided": "a two-sided 95 % band puts α/2 = 2.5 % in each tail, not 5 %",
        "normal": "close, but that is the normal approximation: use the exact chi-square quantiles",
    },
)


def check_gps_rms_band(answer, *, sigma: float = 0.04, n: int = 100, alpha: float = 0.05) -> Feedback:
    """Exercise 03.3: the two-sided ``1 - alpha`` band ``[lower, upper]`` (m/s), shape (2,), of the
    rms ``sqrt(mean(η²))`` of ``n`` i.i.d. N(0, sigma²) samples with known zero mean."""
    sigma = require_positive("sigma", sigma)
    n = require_int("n", n, minimum=2)
    alpha = require_probability("alpha", alpha)
    right = sigma * np.sqrt(chi2_average_bounds(1, n, alpha))
    z = stats.norm.ppf(1 - alpha / 2)
    wrong = [("n_minus_1", sigma * np.sqrt(chi2_average_bounds(1, n - 1, alpha))),
             ("variance", sigma**2 * chi2_average_bounds(1, n, alpha)),
             ("one_sided", sigma * np.sqrt(chi2_average_bounds(1, n, alpha, one_sided=True))),
             ("normal", sigma * (1 + np.array([-z, z]) / np.sqrt(2 * n))),
             ("normal", sigma * (1 + np.array([-1.96, 1.96]) / np.sqrt(2 * n)))]  # with the usual 1.96
    return _numeric(_GPS_RMS_BAND, answer, right, wrong)


# ----------------------------------------------------------------------------------------
# 04 error-state model
# ----------------------------------------------------------------------------------------
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
)


def check_phi_100hz(answer, *, imu_rate: float = 100.0) -> Feedback:
    """Exercise 04.1: the transition matrix Φ (3, 3) of ``[δp, δv, b]`` for an IMU at
    ``imu_rate`` Hz (Δt = 1/imu_rate s)."""
    dt = 1.0 / require_positive("imu_rate", imu_rate)
    right = error_state_model(CalibrationParams(imu_rate=imu_rate, gps_rate=imu_rate / 20)).Phi
    wrong = [("sign_corner", _phi(dt, corner=dt**2 / 2)), ("dt_corner", _phi(dt, corner=-dt)),
             ("signs_bias", _phi(dt, signs=1.0)), ("rate", _phi(0.005)), ("transposed", right.T),
             ("no_half", _phi(dt, corner=-dt**2))]
    return _numeric(_PHI_100HZ, answer, right, wrong)


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
)


def check_gamma_100hz(answer, *, imu_rate: float = 100.0) -> Feedback:
    """Exercise 04.2: the noise input vector Γ, shape (3,) (or (3, 1)), of the error-state model
    for an IMU at ``imu_rate`` Hz.  -Γ is accepted too (the same Q = W Γ Γᵀ), with a praise that says so."""
    dt = 1.0 / require_positive("imu_rate", imu_rate)
    right = error_state_model(CalibrationParams(imu_rate=imu_rate, gps_rate=imu_rate / 20)).Gamma
    wrong = [("dt_first", [-dt, -dt, 0.0]), ("no_half", [-dt**2, -dt, 0.0]),
             ("rate", [-0.005**2 / 2, -0.005, 0.0]), ("bias_noise", [-dt**2 / 2, -dt, 1.0])]
    fb = _numeric(_GAMMA_100HZ, answer, right, wrong)
    if fb.correct or fb.message != _GAMMA_100HZ.hint:
        return fb
    # -Γ gives the same Q: right too (and its mistakes are the same mistakes)
    flipped = replace(_GAMMA_100HZ, praise=GAMMA_OTHER_SIGN_PRAISE)
    other = _numeric(flipped, answer, -right, [(k, -np.asarray(v, dtype=float)) for k, v in wrong])
    return other if other.correct or other.message != _GAMMA_100HZ.hint else fb


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
    return _numeric(_PHI_FIX_TO_FIX, answer, right, wrong)


_M0 = Exercise(
    "04.4",
    praise="M0 in the state order [δp, δv, b]",
    hint="M0 = diag(M_p, M_v, M_b) holds the prior variances in the state order [δp, δv, b]",
    hints={
        "sigmas": "M0 holds variances: square the standard deviations",
        "swapped": "the state order is [δp, δv, b]: the position variance comes first",
        "default": "use the exercise's standard deviations, not the notebook's defaults",
    },
)


def check_m0(answer, *, sigma_p: float = 5.0, sigma_v: float = 0.5, sigma_b: float = 0.05) -> Feedback:
    """Exercise 04.4: the prior covariance M0 (3, 3) of ``[δp, δv, b]`` for prior standard
    deviations ``sigma_p`` (m), ``sigma_v`` (m/s), ``sigma_b`` (m/s²)."""
    s = np.array([require_positive(n, x) for n, x in (("sigma_p", sigma_p), ("sigma_v", sigma_v),
                                                       ("sigma_b", sigma_b))])
    right = error_state_model(CalibrationParams(p0_var=s[0]**2, v0_var=s[1]**2, bias_var=s[2]**2)).M0
    wrong = [("sigmas", np.diag(s)), ("swapped", np.diag(s[[1, 0, 2]] ** 2)),
             ("default", error_state_model(CalibrationParams()).M0)]
    return _numeric(_M0, answer, right, wrong)


# ----------------------------------------------------------------------------------------
# 05 the filter
# ----------------------------------------------------------------------------------------
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
    out, fb = _call_once(ex, func, "predict_only(x, M, Phi, Q, n)", (x0.copy(), P0.copy(), Phi.copy(), Q.copy(), n))
    if fb is not None:
        return fb
    pair = _pair(out)
    if pair is None or pair[0].size != 3 or pair[1].size != 9:
        return ex.mistake("tuple")
    x, P = pair[0].reshape(3), pair[1].reshape(3, 3)
    tol = dict(rtol=1e-8, atol=1e-15)
    x_ok, P_ok = _predict(x0, P0, Phi, Q, n)
    if _close(x, x_ok, **tol) and _close(P, P_ok, **tol):
        return ex.feedback(True)
    Phi_n = np.linalg.matrix_power(Phi, n)
    variants = [("one_short", _predict(x0, P0, Phi, Q, n - 1)), ("one_long", _predict(x0, P0, Phi, Q, n + 1)),
                ("no_q", (x_ok, _predict(x0, P0, Phi, Q, n, q=False)[1])),
                ("transposed", (x_ok, _predict(x0, P0, Phi, Q, n, transposed=True)[1])),
                ("q_once", (x_ok, Phi_n @ P0 @ Phi_n.T + Q)), ("p_static", (x_ok, P0)), ("x_static", (x0, P_ok))]
    for key, (xw, Pw) in variants:
        if _close(x, xw, **tol) and _close(P, Pw, **tol):
            return ex.mistake(key)
    if _close(x, x_ok, **tol):
        return ex.feedback(False, "x̄ is right, M is not: " + ex.hint)
    if _close(P, P_ok, **tol):
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
    return _numeric(_FIRST_GAIN, answer, right, wrong, shape_key="shape")


_SECOND_GAIN = Exercise(
    "05.3",
    praise="the second gain: after 0.2 s of prediction the bias row is no longer zero",
    hint="follow the filter: the first fix's update, the prediction steps to the next fix, then the gain as in 05.2",
    hints={
        "once_per_fix": "one predict call per fix is one IMU step: between two fixes the filter predicts once per IMU "
                        "sample, with the 200 Hz Φ and Q",
        "fix_phi_one_q": "the fix-to-fix Φ^k carries P over the interval, but each of its k IMU steps adds its own "
                         "process noise Q (carried on by the later steps), not one Q for the whole interval",
        "one_short": "count the predictions from one fix to the next: every IMU step, the one onto the fix included",
        "one_long": "one prediction too many: 40 IMU steps separate two fixes at 200 Hz / 5 Hz",
        "no_q": "P grows by the process noise Q at every predict step",
        "no_first_update": "predict from the a posteriori P of the first fix (after its update), not from M0",
        "first_gain": "that is the gain at the first fix (t = 0, exercise 05.2); the exercise asks for the one at the "
                      "second fix, after the first update and 0.2 s of prediction",
    },
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
    return _numeric(_SECOND_GAIN, answer, right, wrong)


# ----------------------------------------------------------------------------------------
# 06 Monte Carlo
# ----------------------------------------------------------------------------------------
_MC_NIS_BOUNDS = Exercise(
    "06.1",
    praise="the NIS band for 50 runs",
    hint="the NIS summed over N runs is χ² with (residual dimension × N) degrees of freedom: take the two-sided "
         "quantiles, then average",
    hints={
        "dim3": "the NIS is a quadratic form in the 2-dimensional residual: χ² with 2N degrees of freedom",
        "dim1": "the residual has 2 components (position and velocity): χ² with 2N degrees of freedom",
        "one_sided": "a two-sided test at α = 0.05 takes the α/2 and 1 - α/2 quantiles",
        "sum": "these bound the sum over runs: the exercise asks for the run average (divide by N)",
        "n_minus_1": "the run average of N independent NIS values has 2N degrees of freedom: no N - 1 here",
    },
)


def check_mc_nis_bounds(answer, *, n_runs: int = 50, alpha: float = 0.05) -> Feedback:
    """Exercise 06.1: the two-sided ``1 - alpha`` bounds ``[lower, upper]`` (dimensionless),
    shape (2,), of the run-averaged NIS (2-dimensional residual) over ``n_runs`` runs."""
    N = require_int("n_runs", n_runs, minimum=2)
    alpha = require_probability("alpha", alpha)
    right = chi2_bounds(2, N, alpha)
    wrong = [("dim3", chi2_average_bounds(3, N, alpha)), ("dim1", chi2_average_bounds(1, N, alpha)),
             ("one_sided", chi2_average_bounds(2, N, alpha, one_sided=True)), ("sum", chi2_average_bounds(2, N, alpha) * N),
             ("n_minus_1", chi2_average_bounds(2, N - 1, alpha))]
    return _numeric(_MC_NIS_BOUNDS, answer, right, wrong)


_FISHER_BAND = Exercise(
    "06.2",
    praise="Fisher's z makes the band of a correlation symmetric and of known width",
    hint="build the band where it is symmetric (Fisher's z of ρ, with its standard error), then transform back",
    hints={
        "sqrt_n": "the standard error of Fisher's z is 1/√(N - 3), not 1/√N",
        "linear": "the band is symmetric in z = atanh ρ, not in ρ: transform, add ± z_q/√(N - 3), transform back",
        "z_space": "transform the band back to a correlation with tanh",
        "one_sided": "a two-sided 95 % band uses the 97.5 % normal quantile (1.96)",
        "z_rounded": "right method, but with the normal quantile rounded: compute it (scipy.stats.norm.ppf), and "
                     "pass the value you computed, with no rounding",
    },
)


def check_fisher_band(answer, *, rho: float = 0.8, n_runs: int = 300, alpha: float = 0.05) -> Feedback:
    """Exercise 06.2: the two-sided ``1 - alpha`` band ``[lower, upper]`` of an ensemble
    correlation over ``n_runs`` runs when the filter's correlation is ``rho`` (Fisher's z)."""
    rho = require_finite("rho", rho)
    if not -1 < rho < 1:
        raise ValueError(f"rho must be in (-1, 1), got {rho!r}")
    N = require_int("n_runs", n_runs, minimum=5)
    alpha = require_probability("alpha", alpha)
    z = stats.norm.ppf(1 - alpha / 2)
    pm = np.array([-1.0, 1.0])
    right = np.tanh(np.arctanh(rho) + pm * z / np.sqrt(N - 3))
    wrong = [("sqrt_n", np.tanh(np.arctanh(rho) + pm * z / np.sqrt(N))), ("linear", rho + pm * z / np.sqrt(N - 3)),
             ("z_space", np.arctanh(rho) + pm * z / np.sqrt(N - 3)),
             ("one_sided", np.tanh(np.arctanh(rho) + pm * stats.norm.ppf(1 - alpha) / np.sqrt(N - 3)))]
    for digits in (2, 3):  # 1.96 or 1.960 typed for the quantile
        wrong.append(("z_rounded", np.tanh(np.arctanh(rho) + pm * round(z, digits) / np.sqrt(N - 3))))
    return _numeric(_FISHER_BAND, answer, right, wrong)


_SIMULTANEOUS_NEES_BAND = Exercise(
    "06.3",
    praise="the simultaneous band is wider: every one of the 151 fixes must pass",
    hint="the per-entry significance is (α/7)/151 (α/7 per check, shared by its 151 fixes); then the usual "
         "χ²_{3N}/N band",
    hints={
        "pointwise": "that is the pointwise band: the simultaneous one gives each check α/7, then splits that over "
                     "the check's entries",
        "fixes_only": "α is first split over the seven checks (α/7 each), then over the 151 fixes of the NEES check",
        "checks_only": "α/7 is the NEES check's share; it is then split over its 151 fixes",
        "one_sided": "each entry's two-sided band puts half of its share of α in each tail",
        "dim2": "the NEES is a quadratic form in the 3-dimensional error: χ² with 3N degrees of freedom",
        "sum": "these bound the SUM of the N NEES values; the check uses their run average: divide by N",
        "dof3": "one NEES has 3 degrees of freedom, but the sum of N independent ones has 3N: use χ²_{3N}, then "
                "divide by N",
    },
)


def check_simultaneous_nees_band(answer, *, n_runs: int = 1000, n_fixes: int = 151, n_checks: int = 7,
                                 alpha: float = 0.05) -> Feedback:
    """Exercise 06.3: the simultaneous (Bonferroni) band ``[lower, upper]`` of the run-averaged
    NEES at each of ``n_fixes`` fixes: ``alpha / n_checks`` per check, split equally over the
    check's ``n_fixes`` entries (as :meth:`MonteCarloResult.checks` does)."""
    N = require_int("n_runs", n_runs, minimum=2)
    n_fixes = require_int("n_fixes", n_fixes, minimum=2)
    n_checks = require_int("n_checks", n_checks, minimum=2)
    alpha = require_probability("alpha", alpha)
    level = alpha / (n_fixes * n_checks)
    right = chi2_bounds(3, N, level)
    wrong = [("pointwise", chi2_average_bounds(3, N, alpha)), ("fixes_only", chi2_average_bounds(3, N, alpha / n_fixes)),
             ("checks_only", chi2_average_bounds(3, N, alpha / n_checks)),
             ("one_sided", chi2_average_bounds(3, N, level, one_sided=True)),
             ("dim2", chi2_average_bounds(2, N, level)),
             ("sum", chi2_average_bounds(3, N, level, divide_by=1)),
             ("dof3", chi2_average_bounds(3, N, level, dof=3, divide_by=1)),
             ("dof3", chi2_average_bounds(3, N, level, dof=3))]
    return _numeric(_SIMULTANEOUS_NEES_BAND, answer, right, wrong)


# ----------------------------------------------------------------------------------------
# 07 model mismatch
# ----------------------------------------------------------------------------------------
_APPARENT_BIAS = Exercise(
    "07.1",
    praise="the apparent bias is Δt/2 times ȧ, the rate of change of the acceleration, and grows with ω",
    hint="the apparent bias is the rate of change of the velocity mismatch (Δt/2)(a(t) - a(0))",
    hints={
        "velocity": "that is the velocity mismatch itself; the apparent bias is its rate of change",
        "hertz": "ω = 2π·0.1 rad/s here: keep the 2π",
        "no_half": "the factor is Δt/2, from the velocity mismatch (Δt/2)(a(t) - a(0))",
        "second_derivative": "differentiate (Δt/2)(a(t) - a(0)) once: one factor ω, not two",
        "omega": "use the exercise's ω = 2π·0.1 rad/s, not the notebook's 0.2 rad/s",
    },
)


def check_apparent_bias(answer, *, omega: float = 2 * np.pi * 0.1) -> Feedback:
    """Exercise 07.1: the largest magnitude (m/s²) of the apparent bias (Δt/2)·da/dt that the
    left-Riemann mismatch feeds the filter, A = 10 m/s², 200 Hz, for ``omega`` (rad/s)."""
    omega = require_positive("omega", omega)
    p = CalibrationParams(omega=omega)
    dt, A = p.dt, p.A
    right = dt / 2 * A * omega
    wrong = [("velocity", dt / 2 * A), ("hertz", dt / 2 * A * omega / (2 * np.pi)), ("no_half", dt * A * omega),
             ("second_derivative", dt / 2 * A * omega**2), ("omega", dt / 2 * A * 0.2)]
    # rtol 1e-4: differencing the sampled acceleration is off by about (ωΔt)²/6 (1.6e-6 at 0.1 Hz)
    return _numeric(_APPARENT_BIAS, answer, right, wrong, rtol=1e-4)


#: test input of the trapezoid exercise (m/s², m/s, s)
_TRAPEZOID_TEST = (np.array([0.3, 1.2, -0.7, 2.5, 0.0, -1.1, 0.8, 1.9]), 100.0, 0.005)


_TRAPEZOID_VELOCITY = Exercise(
    "07.2",
    praise="the trapezoidal mechanization",
    hint="each step adds the area under a_c between two samples: the trapezoid uses both end samples",
    hints={
        "left": "that is the left Riemann sum again: the trapezoid averages a_c(t_j) and a_c(t_{j+1})",
        "right": "that is the right Riemann sum: the trapezoid averages a_c(t_j) and a_c(t_{j+1})",
        "no_half": "the trapezoid is Δt/2 (a_j + a_{j+1}): check the 1/2",
        "length": "return one velocity per sample of a_c, starting with v[0] = v0",
    },
)


def check_trapezoid_velocity(func) -> Feedback:
    """Exercise 07.2: ``func(a_c, v0, dt) -> v``, the trapezoidal velocity mechanization,
    shape (len(a_c),), v[0] = v0. Called on an 8-sample test input (m/s², m/s, s)."""
    ex = _TRAPEZOID_VELOCITY
    a, v0, dt = _TRAPEZOID_TEST
    out, fb = _call_once(ex, func, "trapezoid_velocity(a_c, v0, dt)", (a.copy(), v0, dt))
    if fb is not None:
        return fb
    v = as_array(out) if not isinstance(out, (str, bytes)) else None
    if v is None:
        return ex.feedback(False, f"expected an array of velocities, got {type(out).__name__}")
    if v.size != len(a):
        return ex.mistake("length")
    steps = {"right": np.concatenate([[0.0], np.cumsum((a[:-1] + a[1:]) * dt / 2)])}
    steps["left"] = np.concatenate([[0.0], np.cumsum(a[:-1] * dt)])
    right_sum = np.concatenate([[0.0], np.cumsum(a[1:] * dt)])
    no_half = np.concatenate([[0.0], np.cumsum((a[:-1] + a[1:]) * dt)])
    if _close(v, v0 + steps["right"]):
        return ex.feedback(True)
    for key, w in (("left", v0 + steps["left"]), ("right", v0 + right_sum), ("no_half", v0 + no_half)):
        if _close(v, w):
            return ex.mistake(key)
    return ex.feedback(False)


@lru_cache(maxsize=4)
def _mismatch_failures(w_factor: float, n_runs: int, seed: int) -> frozenset:
    params = CalibrationParams()
    m = error_state_model(params)
    wrong_model = replace(m, W=m.W * w_factor, Q=m.Q * w_factor)
    mc = run_monte_carlo(params, n_runs=n_runs, seed=seed, model=wrong_model)
    return frozenset(name for name, c in mc.checks().items() if not c.passed)


_MISMATCH_FAILURES = Exercise(
    "07.3",
    praise="a filter that believes its IMU is quieter than it is claims too small a P",
    hint="run the Monte Carlo of the exercise and read the verdict column",
    hints={
        "extra": "at least one check in your set passes in that run: for each, ask whether a filter that believes "
                 "its IMU is quieter than it is changes what the check compares (a mean, a spread against P, the "
                 "residuals against S), and by enough for 1000 runs to see",
        "missing": "something is missing: a filter that believes its IMU is quieter than it is claims too small a "
                   "P; which checks compare the error's spread with P?",
        "mixed": "your set holds a check that passes and misses one that fails: run the Monte Carlo of the exercise "
                 "and read the verdict column",
        "unknown": "use the names of CHECK_NAMES (kfcal_helpers.calibration.CHECK_NAMES)",
        "type": "give a set of check names (strings), e.g. {'name_1', 'name_2'}",
    },
)


def check_mismatch_failures(answer, *, w_factor: float = 0.01, n_runs: int = 1000, seed: int = 77) -> Feedback:
    """Exercise 07.3: the set of check names (from ``CHECK_NAMES``) that fail when the filter
    assumes an IMU noise variance ``w_factor`` times the true W, Euler truth,
    ``run_monte_carlo(params, n_runs, seed, model=...)`` with the defaults."""
    ex = _MISMATCH_FAILURES
    w_factor = require_positive("w_factor", w_factor)
    n_runs = require_int("n_runs", n_runs, minimum=2)
    seed = require_int("seed", seed, minimum=0)
    if unanswered(answer):
        return ex.unanswered("replace ... with a set of check names")
    if isinstance(answer, (str, bytes)) or not isinstance(answer, (set, frozenset, list, tuple)):
        return ex.feedback(False, f"{ex.hints['type']}; got {type(answer).__name__}")
    if not all(isinstance(x, str) for x in answer):
        return ex.mistake("type")
    names = set(answer)
    unknown = sorted(names - set(CHECK_NAMES))
    if unknown:
        return ex.feedback(False, f"not a check name: {unknown[0]!r}; {ex.hints['unknown']}")
    expected = _mismatch_failures(w_factor, n_runs, seed)
    if names == expected:
        return ex.feedback(True)
    # never name which check is wrong (that would solve the exercise by elimination)
    extra, missing = names - expected, expected - names
    return ex.mistake("mixed" if extra and missing else "extra" if extra else "missing")


# ----------------------------------------------------------------------------------------
# 15 GPS outages
# ----------------------------------------------------------------------------------------
_OUTAGE_MASK = Exercise(
    "15.1",
    praise="a half-open window: the fix at t_s is missing, the one at t_e is back",
    hint="one entry per GPS fix: check which end of each window is inside it, and what True means",
    hints={
        "closed": "the window is half-open, t_s <= t < t_e: the fix at t_e is the first one back",
        "open_start": "the window is half-open, t_s <= t < t_e: the fix at t_s is already missing",
        "inverted": "True marks a MISSING fix (as outage_mask returns), not a fix that is used",
        "imu_rate": "one entry per GPS fix (151), not per IMU sample",
    },
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
    return _numeric(_OUTAGE_MASK, answer, right.astype(float), [(k, v.astype(float)) for k, v in wrong])


def _propagate(P0, n, q=True):
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
    right = sd(_propagate(P0, n))
    wrong = [("from_gap_start", sd(_propagate(P0, n - r))), ("no_q", sd(_propagate(P0, n, q=False))),
             ("variance", right**2)]
    return _numeric(_OUTAGE_SIGMA, answer, right, wrong)


# ----------------------------------------------------------------------------------------
# 16 minimum variance
# ----------------------------------------------------------------------------------------
#: the data of exercise 16.1: dz_0 (row 0) and dz_1 (row 1), [position (m), velocity (m/s)]
BATCH_TWO_FIXES_DZ = np.array([[3.0, -0.5], [2.5, -0.45]])

_BATCH_TWO_FIXES = Exercise(
    "16.1",
    praise="one Gaussian conditioning on both fixes gives the filter's estimate at 0.2 s",
    hint="build Π_0, Π_1 and Cov(δx_1, δx_0) = Φ^40 Π_0, then Σ_zz (4×4), Σ_xz (3×4), and the mean Σ_xz Σ_zz⁻¹ z "
         "with z = [δz_0; δz_1]",
    hints={
        "only_last": "condition on BOTH fixes, δz_0 and δz_1 (Σ_zz is 4×4), not only on the last one",
        "no_v": "the measurements are noisy: Σ_zz = H C Hᵀ + I ⊗ V",
        "sign": "the conditional mean ADDS the correction: μ + Σ_xz Σ_zz⁻¹ (z − Hμ)",
        "prior": "that is the estimate before the fix at 0.2 s is used (the filter's a priori estimate, "
                 "conditioned on δz_0 only)",
        "unconditioned": "that is the prior mean μ_1 = 0, before any conditioning: condition on the data",
        "swapped": "stack the data in the order of Σ_zz's blocks: z = [δz_0; δz_1], row 0 of dz_16_1 first",
        "no_q_sum": "close, but a difference of method: Π_1 lacks the process noise that the IMU steps between the "
                    "two fixes add (each step adds Q, carried on by Φ); propagate Π_0 step by step",
    },
)


def check_batch_two_fixes(answer) -> Feedback:
    """Exercise 16.1: the conditional mean (3,) of δx(t_1) (t_1 = 0.2 s; m, m/s, m/s^2) given
    δz_0 and δz_1 = the rows of :data:`BATCH_TWO_FIXES_DZ` by one Gaussian conditioning, defaults
    (prior mean zero)."""
    params = CalibrationParams()
    m = error_state_model(params)
    H, V = m.H, m.V
    z = BATCH_TWO_FIXES_DZ.reshape(-1)
    F = phi_power(params, params.steps_per_fix)
    Pi0 = m.M0
    Pi1 = _propagate(m.M0, params.steps_per_fix)

    def mean(Pi1, z, with_v=True):
        C10 = F @ Pi0
        Sxz = np.hstack([C10 @ H.T, Pi1 @ H.T])
        Szz = np.block([[H @ Pi0 @ H.T, H @ C10.T @ H.T], [H @ C10 @ H.T, H @ Pi1 @ H.T]])
        return Sxz @ np.linalg.solve(Szz + (np.kron(np.eye(2), V) if with_v else 0), z)

    dz = np.zeros((params.n_gps, 2))
    dz[:2] = BATCH_TWO_FIXES_DZ                  # batch_conditioning(params, 1, dz) reads rows 0 and 1 only
    right = batch_conditioning(params, 1, dz)[0]
    K0 = Pi0 @ H.T @ np.linalg.inv(H @ Pi0 @ H.T + V)
    wrong = [("only_last", Pi1 @ H.T @ np.linalg.solve(H @ Pi1 @ H.T + V, BATCH_TWO_FIXES_DZ[1])),
             ("sign", -right), ("prior", F @ K0 @ BATCH_TWO_FIXES_DZ[0]), ("unconditioned", np.zeros(3)),
             ("swapped", mean(Pi1, BATCH_TWO_FIXES_DZ[::-1].reshape(-1))),
             ("no_q_sum", mean(F @ Pi0 @ F.T, z))]  # Φ^40 Π_0 Φ^40ᵀ without the 40 steps' process noise
    fb = _numeric(_BATCH_TWO_FIXES, answer, right, wrong, rtol=1e-6, atol=1e-12)
    # without V, Σ_zz has condition number about 3e11: two correct ways of computing that mistake agree
    # only to about 1e-5 (it depends on the machine's BLAS), so it is recognised at rtol 1e-3; it lies
    # about 10 % from the right answer, so nothing right or rounded comes that close to it
    a = as_array(answer)
    if fb.correct or fb.message != _BATCH_TWO_FIXES.hint or a is None or a.size != 3 or not np.all(np.isfinite(a)):
        return fb
    with np.errstate(all="ignore"):
        try:
            no_v = mean(Pi1, z, with_v=False)
        except np.linalg.LinAlgError:  # singular without V: nobody gets that answer
            return fb
    return _BATCH_TWO_FIXES.mistake("no_v") if _close(a.ravel(), no_v, rtol=1e-3) else fb


_SMOOTHED_BIAS_SIGMA = Exercise(
    "16.2",
    praise="offline, the bias is known from t = 0 with the filter's final accuracy",
    hint="the bias is constant with no process noise: look at how the smoothed σ_b varies over the recording in "
         "the notebook's table",
    hints={
        "full_run": "the recording is 10 s long here, not 30 s",
        "prior": "the smoother conditions on every fix of the recording, also the last one",
        "filtered": "that is the filtered σ_b at t = 0; the smoother uses all fixes of the recording",
        "variance": "this is a variance: the exercise asks for a standard deviation",
    },
)


def check_smoothed_bias_sigma(answer, *, duration: float = 10.0) -> Feedback:
    """Exercise 16.2: the RTS-smoothed σ_b (m/s²) at t = 0 for a recording of ``duration`` s
    (defaults otherwise: 200 Hz, 5 Hz, a fix at every 0.2 s)."""
    p = CalibrationParams(duration=require_positive("duration", duration))
    P, P_prior, _, _ = covariance_sequence(p)
    right = np.sqrt(P[-1, 2, 2])
    full = covariance_sequence(CalibrationParams())[0][-1, 2, 2]
    wrong = [("full_run", np.sqrt(full)), ("prior", np.sqrt(P_prior[-1, 2, 2])),
             ("filtered", np.sqrt(P[0, 2, 2])), ("variance", right**2)]
    if abs(p.duration - 30.0) < 1e-9:
        wrong = wrong[1:]
    return _numeric(_SMOOTHED_BIAS_SIGMA, answer, right, wrong, rtol=1e-6)


# ----------------------------------------------------------------------------------------
# 14 mistakes (the calibration exercises of notebook 14)
# ----------------------------------------------------------------------------------------
@lru_cache(maxsize=2)
def _failing_checks_gps_sigma(params: CalibrationParams) -> frozenset:
    """The checks that fail for a filter assuming a GPS position variance of 0.25 m^2
    (1000 realizations, seed 1)."""
    model = error_state_model(replace(params, gps_pos_var=0.25))
    mc = run_monte_carlo(params, 1000, seed=1, model=model, progress=False)
    return frozenset(name for name, c in mc.checks().items() if not c.passed)


_FAILING_CHECKS_GPS_SIGMA = Exercise(
    "14.1",
    praise="these are exactly the checks that leave their simultaneous band",
    hint="compare with the failing checks of your own run: 1000 realizations, seed 1, and only V[0,0] changed "
         "(dataclasses.replace(params, gps_pos_var=0.25))",
    hints={
        "type": "give a set of check names, e.g. {'nees', 'nis'}",
        "extra": "at least one check in your set passes in that run: for each, ask what a filter that believes its "
                 "GPS is twice as accurate as it is gets wrong (its gains, its P, its S) and whether that check "
                 "compares it",
        "missing": "some failing checks are missing: list every check whose verdict is FAIL in your run, not only "
                   "the ones you expected",
        "mixed": "your set holds a check that passes and misses one that fails: compare it with the verdict column "
                 "of your own run",
    },
)


def check_failing_checks_gps_sigma(answer, *, params: CalibrationParams | None = None) -> Feedback:
    """Exercise 14.1: the set of check names (from CHECK_NAMES) that fail when the filter assumes a
    GPS position σ of 0.5 m (V[0,0] = 0.25 m^2) while the truth has 1 m; 1000 realizations, seed 1."""
    ex = _FAILING_CHECKS_GPS_SIGMA
    params = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    if unanswered(answer):
        return ex.unanswered("replace ... with the set of failing check names")
    if isinstance(answer, (str, bytes)) or not isinstance(answer, (set, frozenset, list, tuple)) \
            or not all(isinstance(a, str) for a in answer):
        return ex.mistake("type")
    given = set(answer)
    unknown = given - set(CHECK_NAMES)
    if unknown:
        return ex.feedback(False, f"unknown check names {sorted(unknown)}; the names are {', '.join(CHECK_NAMES)}")
    right = _failing_checks_gps_sigma(params)
    if given == right:
        return ex.feedback(True)
    # never name which check is wrong (that would solve the exercise by elimination)
    extra, missing = given - right, right - given
    return ex.mistake("mixed" if extra and missing else "extra" if extra else "missing")


_PHI02_COUPLING_CHANGE = Exercise(
    "14.2",
    praise="the flipped sign changes the coupling by k dt^2 over k steps",
    hint="multiply out Phi'^k for k = 2 and k = 3 and look at how the [0,2] entry differs",
    hints={
        "sign": "check the sign: which of the two matrices has the larger [0,2] entry?",
        "one_step": "that is the change over one IMU step; the interval asked for has many",
        "coupling": "that is the coupling itself over the interval, not its change",
        "squared": "the per-step change adds up once per step (it enters Phi^k linearly in k)",
        "fix_interval": "that is the change over one fix interval of the default 5 Hz GPS; the exercise asks for "
                        "a longer interval (work out how the change grows with k)",
        "half": "off by a factor of 2: recompute the one-step difference Phi'[0,2] - Phi[0,2] from "
                "Phi'[0,2] = +dt^2/2 and Phi[0,2] = -dt^2/2",
    },
)


def check_phi02_coupling_change(answer, *, steps: int = 200, params: CalibrationParams | None = None) -> Feedback:
    """Exercise 14.2: Phi'^k[0,2] - Phi^k[0,2] in s^2 for k = ``steps`` IMU steps (default 200: one
    second, the fix interval of a 1 Hz GPS), where Phi' has Phi[0,2] = +dt^2/2 (the flipped sign)."""
    ex = _PHI02_COUPLING_CHANGE
    k = require_int("steps", steps, minimum=1)
    p = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    dt = p.dt
    right = k * dt**2
    wrong = distinct_mistakes([(-right, "sign"), (dt**2, "one_step"), (-(k * dt) ** 2 / 2, "coupling"),
                               (k**2 * dt**2, "squared"), (p.steps_per_fix * dt**2, "fix_interval"),
                               (right / 2, "half")], right, 1e-6)
    return replace(ex, praise=f"the flipped sign changes the coupling by k dt^2 = {right:.0e} s^2 over k = {k} "
                              "steps").judge(answer, right, wrong, rtol=1e-6)


# ----------------------------------------------------------------------------------------
# 17 live demo
# ----------------------------------------------------------------------------------------
_RTOL_17_1 = 1e-9  # sigmas from two or three inverse variances: the computed values (no rounding)
_RTOL_BAND = 1e-9  # s/σ band: the computed quantiles (the N vs N-1 and normal-approximation mistakes differ by 1e-4)



def first_fix_sigmas(gps_pos_sigma: float, params: CalibrationParams | None = None) -> np.ndarray:
    """[σ_p, σ_v, σ_b] (m, m/s, m/s²) a posteriori after the first fix at t = 0, with the GPS
    position noise σ ``gps_pos_sigma`` (m) and the other parameters of ``params``."""
    p = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    gps_pos_sigma = require_positive("gps_pos_sigma", gps_pos_sigma)
    var_p = 1.0 / (1.0 / p.p0_var + 1.0 / gps_pos_sigma**2)
    var_v = 1.0 / (1.0 / p.v0_var + 1.0 / p.gps_vel_var)
    return np.sqrt([var_p, var_v, p.bias_var])


_DEMO_FIRST_FIX_SIGMA = Exercise(
    "17.1",
    praise="inverse variances add; the bias is untouched until the prediction correlates it with v",
    hint="combine the prior M0 and the fix's noise component by component: 1/σ² = 1/M + 1/V",
    hints={
        "gps_only": "the filter does not just take the GPS: the first update combines the fix with the prior "
                    "M0 = diag(M_p, M_v, M_b)",
        "sigma_sum": "inverse VARIANCES add when a prior and a measurement are combined, not inverse standard "
                     "deviations",
        "variance": "those are variances; the exercise asks for standard deviations (m, m/s, m/s²)",
        "variance_sum": "adding variances is what happens when errors add up (prediction); combining a prior "
                        "with a measurement adds inverse variances",
        "prior": "that is the prior, before any fix; the first update happens at t = 0",
        "default_gps": "use the exercise's GPS position σ (the slider value), not the default 1 m",
        "bias": "position and velocity are right; but at t = 0 nothing links the bias to p or v yet "
                "(M0 is diagonal), so the first fix cannot change σ_b",
        "rounded_readout": "the readout rounds the slider's value to 2 decimals (3.16 for the stop 10 ** 0.5): "
                           "compute with the exact value (V[0,0] = 10 m² at that stop), not the rounded readout",
    },
)


def check_demo_first_fix_sigma(answer, *, gps_pos_sigma: float = 10**0.5) -> Feedback:
    """Exercise 17.1: the a posteriori ``[σ_p, σ_v, σ_b]`` (m, m/s, m/s²), shape (3,), right
    after the first fix at t = 0 when the GPS position noise has σ = ``gps_pos_sigma`` m (default
    sqrt(10) ≈ 3.16 m, a stop of the demo's log-scale slider; the other parameters the defaults:
    M0 = diag(100, 1, 0.01), GPS velocity variance 0.0016)."""
    ex = _DEMO_FIRST_FIX_SIGMA
    gps_pos_sigma = require_positive("gps_pos_sigma", gps_pos_sigma)
    p = CalibrationParams()
    right = first_fix_sigmas(gps_pos_sigma, p)
    if unanswered(answer):
        return ex.unanswered()
    prior = np.sqrt([p.p0_var, p.v0_var, p.bias_var])
    meas = np.array([gps_pos_sigma, np.sqrt(p.gps_vel_var), np.sqrt(p.bias_var)])
    pairs = [
        (meas, "gps_only"),
        (np.r_[1 / (1 / prior[:2] + 1 / meas[:2]), prior[2]], "sigma_sum"),
        (right**2, "variance"),
        (np.r_[np.sqrt(prior[:2] ** 2 + meas[:2] ** 2), prior[2]], "variance_sum"),
        (prior, "prior"),
        (first_fix_sigmas(np.sqrt(p.gps_pos_var), p), "default_gps"),
        (first_fix_sigmas(round(gps_pos_sigma, 2), p), "rounded_readout"),  # the .2f readout, not the stop
    ]
    a = as_array(answer)
    if (a is not None and a.size == 3 and np.all(np.isfinite(a))
            and np.allclose(a.ravel()[:2], right[:2], rtol=_RTOL_17_1, atol=0)
            and not np.isclose(a.ravel()[2], right[2], rtol=_RTOL_17_1, atol=0)):
        return ex.mistake("bias")
    return ex.judge(answer, right, distinct_mistakes(pairs, right, _RTOL_17_1), rtol=_RTOL_17_1, atol=0.0)


def ratio_band(n_runs: int, alpha: float = 0.05) -> np.ndarray:
    """[lower, upper] of s/σ for the std ``s`` (ddof 1) of ``n_runs`` Gaussian samples of std σ."""
    n = require_int("n_runs", n_runs, minimum=2) - 1
    alpha = require_probability("alpha", alpha)
    return np.sqrt(stats.chi2.ppf([alpha / 2, 1 - alpha / 2], n) / n)


_DEMO_RATIO_BAND = Exercise(
    "17.2",
    praise="(N-1) s²/σ² ~ χ²(N-1): square roots of the scaled quantiles",
    hint="start from (N-1) s²/σ² ~ χ²(N-1) and solve for s/σ",
    hints={
        "n_dof": "the ensemble std s uses the ensemble mean (ddof = 1): (N-1) s²/σ² has N-1 degrees of freedom, "
                 "not N",
        "variance": "that is the band of s²/σ²; the demo compares the std s with σ, so take square roots",
        "one_sided": "a two-sided band at α = 0.05 puts α/2 = 0.025 in each tail",
        "normal": "close: that is the normal approximation 1 ± 1.96/√(2(N-1)); the exact band uses "
                  "chi-square quantiles",
        "mean_band": "1 ± 1.96/√N is the band of a MEAN of unit-variance numbers; s/σ is a ratio of "
                     "standard deviations: (N-1) s²/σ² is chi-square",
    },
)


def check_demo_ratio_band(answer, *, n_runs: int = 200, alpha: float = 0.05) -> Feedback:
    """Exercise 17.2: the two-sided ``1 - alpha`` band ``[lower, upper]`` (dimensionless),
    shape (2,), of the ratio s/σ of the ensemble std (``n_runs`` realizations) to the filter's σ."""
    N = require_int("n_runs", n_runs, minimum=3)
    alpha = require_probability("alpha", alpha)
    ex = replace(_DEMO_RATIO_BAND, praise=f"(N-1) s²/σ² ~ χ²(N-1) with N = {N}: square roots of the scaled quantiles")
    right = ratio_band(N, alpha)
    z = stats.norm.ppf(1 - alpha / 2)
    pm = np.array([-1.0, 1.0])
    pairs = [
        (ratio_band(N + 1, alpha), "n_dof"),
        (right**2, "variance"),
        (np.sqrt(stats.chi2.ppf([alpha, 1 - alpha], N - 1) / (N - 1)), "one_sided"),
    ]
    for zq in (z, 1.96):  # the approximations, with the exact quantile or the usual 1.96
        pairs += [(1 + pm * zq / np.sqrt(2 * (N - 1)), "normal"), (1 + pm * zq / np.sqrt(N), "mean_band")]
    return ex.judge(answer, right, distinct_mistakes(pairs, right, _RTOL_BAND), rtol=_RTOL_BAND, atol=0.0)


#: every exercise record of the calibration notebooks, by id
EXERCISES = {ex.id: ex for ex in (
    _EULER_VELOCITY_GAP, _EULER_POSITION_GAP_MAX, _EULER_TRUTH, _IMU_DRIFT, _IMU_RANDOM_WALK, _IMU_STD_BAND,
    _GPS_FIX_INDICES, _GPS_DZ, _GPS_RMS_BAND, _PHI_100HZ, _GAMMA_100HZ, _PHI_FIX_TO_FIX, _M0, _PREDICT_ONLY,
    _FIRST_GAIN, _SECOND_GAIN, _MC_NIS_BOUNDS, _FISHER_BAND, _SIMULTANEOUS_NEES_BAND, _APPARENT_BIAS,
    _TRAPEZOID_VELOCITY, _MISMATCH_FAILURES, _FAILING_CHECKS_GPS_SIGMA, _PHI02_COUPLING_CHANGE, _OUTAGE_MASK,
    _OUTAGE_SIGMA, _BATCH_TWO_FIXES, _SMOOTHED_BIAS_SIGMA, _DEMO_FIRST_FIX_SIGMA, _DEMO_RATIO_BAND)}


# ----------------------------------------------------------------------------------------
# 02 and 03: the data written as functions (the student builds what simulate() builds)
# ----------------------------------------------------------------------------------------
#: test input of the dead-reckoning exercise: IMU output a_c (3 realizations x 7 samples, m/s²),
#: the prior means p_init (m), v_init (m/s), dt (s).  3 != 7, so an integration along the wrong axis shows.
_DEAD_RECKON_TEST = (np.array([[0.5, -1.0, 2.0, 0.0, 3.0, -2.0, 1.5],
                               [1.0, 1.0, -0.5, 0.25, 0.0, 2.0, -1.0],
                               [-2.0, 0.5, 0.5, 1.5, -1.0, 0.0, 4.0]]), 1.0, 2.0, 0.1)


def _reckon_variant(a_c, p_init, v_init, dt, kind: str = "ok"):
    """The dead reckoning of ``a_c`` (n, n_t) along time by a plain loop, right or with one known mistake."""
    if kind == "axis":  # integrated across the realizations (axis 0) instead of along time
        p, v = _reckon_variant(a_c.T, p_init, v_init, dt)
        return p.T, v.T
    n, n_t = a_c.shape
    p, v = np.empty((n, n_t)), np.empty((n, n_t))
    p[:, 0] = p_init
    v[:, 0] = v_init
    for j in range(n_t - 1):
        aj = a_c[:, j + 1] if kind == "right" else a_c[:, j]
        v[:, j + 1] = v[:, j] + aj * dt
        vel = v[:, j + 1] if kind == "new_v" else v[:, j]
        acc = {"no_acc": 0.0, "dt2": aj * dt**2}.get(kind, aj * dt**2 / 2)
        p[:, j + 1] = p[:, j] + vel * dt + acc
    return p, v


_DEAD_RECKON = Exercise(
    "02.4",
    praise="your loop is the IMU dead reckoning: the same numbers as the notebook's cumulative sums",
    hint="compare your loop with the recursion: v_c[:, j+1] = v_c[:, j] + a_c[:, j] Δt, "
         "p_c[:, j+1] = p_c[:, j] + v_c[:, j] Δt + a_c[:, j] Δt²/2, from p_c[:, 0] = p̄0, v_c[:, 0] = v̄0",
    hints={
        "new_v": "the position step uses the velocity at t_j (before the update), not the new velocity v_c[:, j+1]",
        "no_acc": "the position step is missing the acceleration term a_c[:, j]Δt²/2",
        "dt2": "the acceleration term of the position step is a_c[:, j]Δt²/2, with the 1/2",
        "right": "left Riemann: the step from t_j to t_{j+1} uses a_c[:, j], not a_c[:, j+1]",
        "axis": "a_c has one row per realization and one column per sample: integrate along the columns "
                "(axis 1, time), each row on its own",
        "swapped": "return (p_c, v_c) in this order: position first",
        "shape": "p_c and v_c have the shape of a_c: one row per realization, one column per sample, starting "
                 "with p_c[:, 0] = p̄0 and v_c[:, 0] = v̄0",
        "tuple": "return a tuple (p_c, v_c) of two arrays",
    },
)


def check_dead_reckoning(func) -> Feedback:
    """Exercise 02.4: ``func(a_c, p_init, v_init, dt) -> (p_c, v_c)``, the IMU dead reckoning of
    ``a_c`` (n, n_imu) m/s² from the prior means ``p_init`` (m) and ``v_init`` (m/s), each (n, n_imu).

    Called on a test input of 3 realizations of 7 samples, p_init = 1 m, v_init = 2 m/s, dt = 0.1 s;
    compared with :func:`~kfcal_helpers.calibration.integrate_left` (rtol 1e-9).
    """
    ex = _DEAD_RECKON
    a_c, p_init, v_init, dt = _DEAD_RECKON_TEST
    out, fb = _call_once(ex, func, "dead_reckon(a_c, p_init, v_init, dt)", (a_c.copy(), p_init, v_init, dt))
    if fb is not None:
        return fb
    pair = _pair(out)
    if pair is None:
        return ex.mistake("tuple")
    p, v = pair
    if p.shape != a_c.shape or v.shape != a_c.shape:
        return ex.mistake("shape")
    p_ok, v_ok = integrate_left(a_c, p_init, v_init, dt)
    if _close(p, p_ok) and _close(v, v_ok):
        return ex.feedback(True)
    if _close(p, v_ok) and _close(v, p_ok):
        return ex.mistake("swapped")
    for kind in ("right", "new_v", "no_acc", "dt2", "axis"):
        pw, vw = _reckon_variant(a_c, p_init, v_init, dt, kind)
        if _close(p, pw) and _close(v, vw):
            return ex.mistake(kind)
    if _close(v, v_ok):
        return ex.feedback(False, "v_c is right, p_c is not: " + ex.hint)
    return ex.feedback(False)


#: test input of the IMU-output exercise: a (5 samples, m/s²), b (3 realizations, m/s²), w (3 x 5, m/s²)
_IMU_OUTPUT_TEST = (np.array([0.0, 1.0, 2.0, -1.5, 0.5]), np.array([0.1, -0.2, 0.05]),
                    np.array([[0.01, -0.02, 0.03, 0.0, -0.01],
                              [0.02, 0.01, -0.03, 0.015, 0.0],
                              [-0.01, 0.0, 0.02, -0.02, 0.03]]))

_IMU_OUTPUT = Exercise(
    "02.5",
    praise="that is the IMU output a_c = a + b + w: one constant bias per realization, new noise at every sample",
    hint="a_c[l, j] = a[j] + b[l] + w[l, j]: the truth of sample j, the bias of realization l, the noise of both",
    hints={
        "bias_sign": "the IMU reports the truth PLUS its bias: check the sign of b",
        "noise_sign": "the IMU reports the truth plus the noise w, not minus it",
        "no_bias": "the bias b is missing: every sample of realization l carries the same b[l]",
        "no_noise": "the white noise w is missing",
        "broadcast": "b has one entry per realization (rows of w): give it a column axis, b[:, None], before "
                     "adding it to the (n, n_imu) array",
        "shape": "a_c has one row per realization and one column per sample: the shape of w",
    },
)


def check_imu_output(func) -> Feedback:
    """Exercise 02.5: ``func(a, b, w) -> a_c``, the IMU output ``a_c[l, j] = a[j] + b[l] + w[l, j]`` (m/s²),
    shape (n, n_imu), for ``a`` (n_imu,), ``b`` (n,) and ``w`` (n, n_imu).

    Called on 3 realizations of 5 samples (3 != 5, so a bias added along the wrong axis shows).
    """
    ex = _IMU_OUTPUT
    a, b, w = _IMU_OUTPUT_TEST
    out, fb = _call_once(ex, func, "imu_output(a, b, w)", (a.copy(), b.copy(), w.copy()))
    if fb is not None:
        if fb.answered and "broadcast" in fb.message:
            return ex.mistake("broadcast")
        return fb
    got = as_array(out)
    if got is None or isinstance(out, (str, bytes)):
        return ex.mistake("shape")
    if got.shape != w.shape:
        return ex.mistake("broadcast" if got.shape == w.T.shape else "shape")
    right = a + b[:, None] + w
    if _close(got, right):
        return ex.feedback(True)
    variants = [("bias_sign", a - b[:, None] + w), ("noise_sign", a + b[:, None] - w),
                ("no_bias", a + w), ("no_noise", np.broadcast_to(a + b[:, None], w.shape))]
    for key, value in variants:
        if _close(got, value):
            return ex.mistake(key)
    return ex.feedback(False)


#: test input of the GPS-measurement exercise: truth p (m), v (m/s) of 2 realizations x 13 samples, fixes on
#: every 4th sample (0, 4, 8, 12: 4 fixes), the noise eta (2 x 4 x 2) [m, m/s]
def _gps_test():
    t = np.arange(13) * 0.5
    p = np.stack([10.0 + 3.0 * t + 0.1 * t**2, -4.0 + 2.5 * t - 0.05 * t**2])
    v = np.stack([3.0 + 0.2 * t, 2.5 - 0.1 * t])
    eta = np.array([[[0.3, -0.02], [-1.1, 0.05], [0.4, 0.01], [0.9, -0.03]],
                    [[-0.6, 0.04], [0.2, -0.01], [1.3, 0.02], [-0.7, 0.06]]])
    return p, v, eta, 4


_GPS_MEASUREMENT = Exercise(
    "03.4",
    praise="those are the GPS fixes z = [p, v] + η on every steps_per_fix-th IMU sample from 0, the last one included",
    hint="z[l, i] = [p[l, j_i], v[l, j_i]] + eta[l, i] with j_i = i·steps_per_fix: the truth at the fix samples plus "
         "the noise",
    hints={
        "count": "the fixes are the IMU samples 0, steps_per_fix, 2·steps_per_fix, … up to and including the last "
                 "sample: pick as many samples as eta has fixes",
        "swapped": "give [position, velocity] in this order along the last axis: z[..., 0] is the position",
        "minus": "the GPS reports the truth PLUS its noise η",
        "no_noise": "the noise η is missing: the GPS never sees the exact truth",
        "axis": "stack position and velocity along the LAST axis: z has shape (n, n_gps, 2), like eta",
        "shape": "z has the shape of eta, (n, n_gps, 2): one row per realization, one per fix, [p, v] last",
    },
)


def check_gps_measurement(func) -> Feedback:
    """Exercise 03.4: ``func(p, v, eta, steps_per_fix) -> z``, the GPS fixes
    ``z[l, i] = [p[l, i s], v[l, i s]] + eta[l, i]`` (m, m/s), shape (n, n_gps, 2), for the truth
    ``p``, ``v`` (n, n_imu), the noise ``eta`` (n, n_gps, 2) and ``s = steps_per_fix``.

    Called on 2 realizations of 13 samples with a fix on every 4th sample (4 fixes).
    """
    ex = _GPS_MEASUREMENT
    p, v, eta, r = _gps_test()
    out, fb = _call_once(ex, func, "gps_measurement(p, v, eta, steps_per_fix)", (p.copy(), v.copy(), eta.copy(), r))
    if fb is not None:
        if fb.answered and "broadcast" in fb.message:
            return ex.mistake("count")
        return fb
    got = as_array(out)
    if got is None or isinstance(out, (str, bytes)):
        return ex.mistake("shape")
    n, n_gps, _ = eta.shape
    if got.shape == (2, n, n_gps):
        return ex.mistake("axis")
    if got.shape != eta.shape:
        return ex.mistake("count" if got.ndim == 3 and got.shape[::2] == (n, 2) else "shape")
    truth = np.stack([p[:, ::r], v[:, ::r]], axis=-1)
    if _close(got, truth + eta):
        return ex.feedback(True)
    variants = [("swapped", truth[..., ::-1] + eta), ("minus", truth - eta), ("no_noise", truth)]
    for key, value in variants:
        if _close(got, value):
            return ex.mistake(key)
    return ex.feedback(False)


__all__ += ["check_dead_reckoning", "check_imu_output", "check_gps_measurement"]
EXERCISES.update({e.id: e for e in (_DEAD_RECKON, _IMU_OUTPUT, _GPS_MEASUREMENT)})
