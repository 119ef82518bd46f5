"""Exercise checks of notebook 03 (the GPS model): 03.1-03.4."""

from __future__ import annotations



import numpy as np
from scipy import stats

from ...exercises._core import (BAND_NAMES, Exercise, Feedback, as_array, chi2_average_bounds)
from ...validation import (require_finite, require_int, require_positive,
                          require_probability)
from ..params import CalibrationParams
from ._shared import call_once, close, numeric


#: 03.1's numbers, their one home: the GPS rate (Hz) of the exercise (the check's default, its praise and
#: hints read it; tests/test_exercises_calibration.py checks that the source notebook's text and solution agree)
GPS_FIX_RATE = 4.0

_GPS_FIX_INDICES = Exercise(
    "03.1",
    praise=f"those are the IMU samples that carry a {GPS_FIX_RATE:g} Hz fix",
    hint="the fixes sit on every (f_imu/f_gps)-th IMU sample, from t = 0 to t = T",
    hints={
        "no_last": "the last fix, at t = T, is included (n_imu = T·f_imu + 1 samples)",
        "no_first": "the first fix is at t = 0, on IMU sample 0",
        "times": "give IMU sample indices (integers), not times in seconds",
        "rate": f"use the exercise's GPS rate ({GPS_FIX_RATE:g} Hz): the spacing is f_imu/f_gps samples",
        "one_based": "indices start at 0 (Python), not at 1",
    },
    units=False,
)


def check_gps_fix_indices(answer, *, gps_rate: float = GPS_FIX_RATE) -> Feedback:
    """Exercise 03.1: the IMU sample indices (ints, shape (n_gps,)) that carry a GPS fix for a
    200 Hz IMU, GPS at ``gps_rate`` (Hz, dividing 200), over 30 s."""
    p = CalibrationParams(gps_rate=require_positive("gps_rate", gps_rate))
    right = p.fix_indices
    r = p.steps_per_fix
    wrong = [("no_last", right[:-1]), ("no_first", right[1:]), ("times", p.t_gps),
             ("rate", CalibrationParams().fix_indices), ("one_based", right + 1)]
    if r == 40:  # the exercise's rate is the default: the "rate" mistake cannot be told apart
        wrong = [w for w in wrong if w[0] != "rate"]
    return numeric(_GPS_FIX_INDICES, answer, right, wrong)


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
    components=("δz_p", "δz_v"),
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
    return numeric(_GPS_DZ, answer, right, wrong)


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
    components=BAND_NAMES,
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
             ("normal", sigma * (1 + np.array([-1.96, 1.96]) / np.sqrt(2 * n))),  # with the usual 1.96
             ("normal", sigma * (1 + np.array([-2.0, 2.0]) / np.sqrt(2 * n)))]  # or the two-sigma rule
    return numeric(_GPS_RMS_BAND, answer, right, wrong)


#: test input of the GPS-measurement exercise: truth p (m), v (m/s) of 2 realizations x 13 samples, fixes on
#: every 4th sample (0, 4, 8, 12: 4 fixes), the noise eta (2 x 4 x 2) [m, m/s]
def _gps_test():
    t = np.arange(13) * 0.5
    p = np.stack([10.0 + 3.0 * t + 0.1 * t**2, -4.0 + 2.5 * t - 0.05 * t**2])
    v = np.stack([3.0 + 0.2 * t, 2.5 - 0.1 * t])
    eta = np.array([[[0.3, -0.02], [-1.1, 0.05], [0.4, 0.01], [0.9, -0.03]],
                    [[-0.6, 0.04], [0.2, -0.01], [1.3, 0.02], [-0.7, 0.06]]])
    return p, v, eta, 4


#: 03.4: the entries of z along its last axis, for the hint that names the wrong one
Z_ENTRIES = ("the position z[..., 0]", "the velocity z[..., 1]")

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
    out, fb = call_once(ex, func, "gps_measurement(p, v, eta, steps_per_fix)", (p.copy(), v.copy(), eta.copy(), r))
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
    if close(got, truth + eta):
        return ex.feedback(True)
    variants = [("swapped", truth[..., ::-1] + eta), ("minus", truth - eta), ("no_noise", truth)]
    for key, value in variants:
        if close(got, value):
            return ex.mistake(key)
    slip = ex.output_slip([got], [truth + eta], ("z",), components=[Z_ENTRIES])
    return ex.feedback(False) if slip is None else slip




#: the exercise records of this lesson, in notebook order
RECORDS = (_GPS_FIX_INDICES, _GPS_DZ, _GPS_RMS_BAND, _GPS_MEASUREMENT)
