"""Exercise checks of notebook 17 (the calibration live demo): 17.1-17.2."""

from __future__ import annotations


from dataclasses import replace

import numpy as np
from scipy import stats

from ...exercises._core import (BAND_NAMES, Exercise, Feedback, as_array, distinct_mistakes,
                               unanswered)
from ...validation import (require_instance, require_int, require_positive,
                          require_probability)
from ..params import CalibrationParams



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
    components=("σ_p", "σ_v", "σ_b"),
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
    components=BAND_NAMES,
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
    for zq in (z, 1.96, 2.0):  # the approximations, with the exact quantile, the usual 1.96 or the two-sigma rule
        pairs += [(1 + pm * zq / np.sqrt(2 * (N - 1)), "normal"), (1 + pm * zq / np.sqrt(N), "mean_band")]
    return ex.judge(answer, right, distinct_mistakes(pairs, right, _RTOL_BAND), rtol=_RTOL_BAND, atol=0.0)


#: the exercise records of this lesson, in notebook order
RECORDS = (_DEMO_FIRST_FIX_SIGMA, _DEMO_RATIO_BAND)
