"""Exercise checks of notebooks 17 and 18 (lecture demos).

Every ``check_*`` function takes the student's answer and returns a one-line
:class:`~kfcal_helpers.exercises.Feedback`.  The right answer is computed here from the
project's model with the exercise's parameters as keyword defaults; each common wrong answer
is computed the same way and gets the hint in :data:`HINTS` that points at its mistake (never
at the answer).  A placeholder (``None`` or ``...``) gives "not answered yet"; a malformed
answer gives a hint, never an exception.  Bad *keyword parameters* raise ``ValueError``.

* 17.1 :func:`check_demo_first_fix_sigma` -- the filter's sigma right after the first fix
  (t = 0) for a chosen GPS noise: prior and fix combined, the bias not yet touched.
* 17.2 :func:`check_demo_ratio_band` -- the band of the ensemble std over the filter's sigma
  that the demo prints for its 200 realizations.
* 18.1 :func:`check_demo_subset_nis_bounds` -- the chi-square bounds of the time-averaged NIS
  when only 3 of the 5 measurements are used.
* 18.2 :func:`check_demo_lost_directions` -- how many state directions each measurement subset
  leaves unobservable (6 - rank of the stacked observability matrix).

Worked solutions: ``notebooks/solutions/17_calibration_live_demo.ipynb`` and
``notebooks/solutions/18_coop_live_demo.ipynb``.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ..calibration import CalibrationParams
from ..consistency import chi2_bounds
from ..coop import N_MEAS, N_STATES, CoopParams, jacobian_A, jacobian_C, nominal_trajectory, observability_matrix
from ..coop.model import jacobian_step
from ..validation import require_finite, require_int, require_positive
from ._core import Feedback, as_array, judge, unanswered

__all__ = [
    "check_demo_first_fix_sigma",
    "check_demo_ratio_band",
    "check_demo_subset_nis_bounds",
    "check_demo_lost_directions",
]

PLACEHOLDER = "replace ... with your answer"

#: ``HINTS[exercise][mistake]``: the hint a known wrong answer gets (the unit tests look them up)
HINTS: dict[str, dict[str, str]] = {
    "17.1": {
        "gps_only": "the filter does not just take the GPS: the first update combines the fix with the prior "
                    "M0 = diag(M_p, M_v, M_b)",
        "sigma_sum": "inverse VARIANCES add when a prior and a measurement are combined, not inverse standard deviations",
        "variance": "those are variances; the exercise asks for standard deviations (m, m/s, m/s²)",
        "variance_sum": "adding variances is what happens when errors add up (prediction); combining a prior "
                        "with a measurement adds inverse variances",
        "prior": "that is the prior, before any fix; the first update happens at t = 0",
        "default_gps": "use the exercise's GPS position σ (the slider value), not the default 1 m",
        "bias": "position and velocity are right; but at t = 0 nothing links the bias to p or v yet "
                "(M0 is diagonal), so the first fix cannot change σ_b",
    },
    "17.2": {
        "n_dof": "the ensemble std s uses the ensemble mean (ddof = 1): (N-1) s²/σ² has N-1 degrees of freedom, not N",
        "variance": "that is the band of s²/σ²; the demo compares the std s with σ, so take square roots",
        "one_sided": "a two-sided band at α = 0.05 puts α/2 = 0.025 in each tail",
        "normal": "close: that is the normal approximation 1 ± 1.96/√(2(N-1)); the exact band uses "
                  "chi-square quantiles",
        "mean_band": "1 ± 1.96/√N is the band of a MEAN of unit-variance numbers; s/σ is a ratio of "
                     "standard deviations: (N-1) s²/σ² is chi-square",
    },
    "18.1": {
        "dim5": "the NIS of an update that uses m measurements has m degrees of freedom, not always 5",
        "count_nan": "count only the samples with a measurement: the log's first row (t = 0) is NaN",
        "not_divided": "these bound the SUM of the NIS values; the time average is that sum divided by K",
        "one_sided": "a two-sided test at α = 0.05 puts α/2 = 0.025 in each tail",
        "normal": "close: that is the normal approximation m ± 1.96 √(2m/K); use the chi-square quantiles "
                  "(scipy.stats.chi2.ppf or chi2_bounds)",
    },
    "18.2": {
        "ranks": "those are ranks; the exercise asks how many directions are lost: 6 - rank",
        "euler": "that is what the Euler F = I + ΔT A gives: its straight chord breaks the model's invariance "
                 "under a rotation of the whole scene, so one singular value is small (~1e-5) but not zero. "
                 "Use the exact Jacobian of the one-step map, jacobian_step: is a rotation of everything visible "
                 "to two relative bearings and a range?",
        "no_gps_observable": "without the GPS, move both vehicles by the same vector: does any bearing or "
                             "the range change?",
        "no_range_lost": "without the range the two bearings and the UAV's GPS still locate the UGV as the "
                         "vehicles move: compute the rank rather than guess",
        "no_bearings_lost": "with the range and the UAV's GPS, one sample puts the UGV on a circle, but its "
                            "known motion over 10 samples pins it down: compute the rank",
    },
}

_RTOL_17_1 = 1e-4  # sigmas from two or three inverse variances: 4 significant digits
_RTOL_BAND = 5e-5  # s/σ band: the N vs N-1 and normal-approximation mistakes differ by 1e-4
_RTOL_NIS = 5e-6   # NIS bounds: K = 1000 vs 1001 differ by 3e-5 (compute them, do not type rounded numbers)


def _wrong(exercise: str, pairs, expected, rtol):
    """``(value, hint)`` pairs from ``(value, key)``, dropping values equal to ``expected``."""
    out = []
    for value, key in pairs:
        value = np.asarray(value, dtype=float)
        if value.shape == np.shape(expected) and np.allclose(value, expected, rtol=rtol, atol=0):
            continue
        out.append((value, HINTS[exercise][key]))
    return out


def _alpha(alpha) -> float:
    alpha = require_finite("alpha", alpha)
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha!r}")
    return alpha


# ---------------------------------------------------------------------------
# 17: calibration demo
def first_fix_sigmas(gps_pos_sigma: float, params: CalibrationParams | None = None) -> np.ndarray:
    """[σ_p, σ_v, σ_b] (m, m/s, m/s²) a posteriori after the first fix at t = 0, with the GPS
    position noise σ ``gps_pos_sigma`` (m) and the other parameters of ``params``."""
    p = CalibrationParams() if params is None else params
    gps_pos_sigma = require_positive("gps_pos_sigma", gps_pos_sigma)
    var_p = 1.0 / (1.0 / p.p0_var + 1.0 / gps_pos_sigma**2)
    var_v = 1.0 / (1.0 / p.v0_var + 1.0 / p.gps_vel_var)
    return np.sqrt([var_p, var_v, p.bias_var])


def check_demo_first_fix_sigma(answer, *, gps_pos_sigma: float = 3.0) -> Feedback:
    """Exercise 17.1: the a posteriori ``[σ_p, σ_v, σ_b]`` (m, m/s, m/s²), shape (3,), right
    after the first fix at t = 0 when the GPS position noise has σ = ``gps_pos_sigma`` m (the
    other parameters the defaults: M0 = diag(100, 1, 0.01), GPS velocity variance 0.0016)."""
    ex = "17.1"
    gps_pos_sigma = require_positive("gps_pos_sigma", gps_pos_sigma)
    p = CalibrationParams()
    right = first_fix_sigmas(gps_pos_sigma, p)
    if unanswered(answer):
        return Feedback(ex, False, PLACEHOLDER, answered=False)
    prior = np.sqrt([p.p0_var, p.v0_var, p.bias_var])
    meas = np.array([gps_pos_sigma, np.sqrt(p.gps_vel_var), np.sqrt(p.bias_var)])
    pairs = [
        (meas, "gps_only"),
        (np.r_[1 / (1 / prior[:2] + 1 / meas[:2]), prior[2]], "sigma_sum"),
        (right**2, "variance"),
        (np.r_[np.sqrt(prior[:2] ** 2 + meas[:2] ** 2), prior[2]], "variance_sum"),
        (prior, "prior"),
        (first_fix_sigmas(np.sqrt(p.gps_pos_var), p), "default_gps"),
    ]
    a = as_array(answer)
    if (a is not None and a.size == 3 and np.all(np.isfinite(a))
            and np.allclose(a.ravel()[:2], right[:2], rtol=_RTOL_17_1, atol=0)
            and not np.isclose(a.ravel()[2], right[2], rtol=_RTOL_17_1, atol=0)):
        return Feedback(ex, False, HINTS[ex]["bias"])
    return judge(ex, answer, right, _wrong(ex, pairs, right, _RTOL_17_1), rtol=_RTOL_17_1, atol=0.0,
                 praise="inverse variances add; the bias is untouched until the prediction correlates it with v",
                 hint="combine the prior M0 and the fix's noise component by component: 1/σ² = 1/M + 1/V")


def ratio_band(n_runs: int, alpha: float = 0.05) -> np.ndarray:
    """[lower, upper] of s/σ for the std ``s`` (ddof 1) of ``n_runs`` Gaussian samples of std σ."""
    n = require_int("n_runs", n_runs, minimum=2) - 1
    alpha = _alpha(alpha)
    return np.sqrt(stats.chi2.ppf([alpha / 2, 1 - alpha / 2], n) / n)


def check_demo_ratio_band(answer, *, n_runs: int = 200, alpha: float = 0.05) -> Feedback:
    """Exercise 17.2: the two-sided ``1 - alpha`` band ``[lower, upper]`` (dimensionless),
    shape (2,), of the ratio s/σ of the ensemble std (``n_runs`` realizations) to the filter's σ."""
    ex = "17.2"
    N = require_int("n_runs", n_runs, minimum=3)
    alpha = _alpha(alpha)
    right = ratio_band(N, alpha)
    z = stats.norm.ppf(1 - alpha / 2)
    pm = np.array([-1.0, 1.0])
    pairs = [
        (ratio_band(N + 1, alpha), "n_dof"),
        (right**2, "variance"),
        (np.sqrt(stats.chi2.ppf([alpha, 1 - alpha], N - 1) / (N - 1)), "one_sided"),
        (1 + pm * z / np.sqrt(2 * (N - 1)), "normal"),
        (1 + pm * z / np.sqrt(N), "mean_band"),
    ]
    return judge(ex, answer, right, _wrong(ex, pairs, right, _RTOL_BAND), rtol=_RTOL_BAND, atol=0.0,
                 praise=f"(N-1) s²/σ² ~ χ²(N-1) with N = {N}: square roots of the scaled quantiles",
                 hint="start from (N-1) s²/σ² ~ χ²(N-1) and solve for s/σ")


# ---------------------------------------------------------------------------
# 18: cooperative-localization demo
def check_demo_subset_nis_bounds(answer, *, n_meas: int = 3, n_samples: int = 1001, alpha: float = 0.05) -> Feedback:
    """Exercise 18.1: the two-sided ``1 - alpha`` bounds ``[lower, upper]`` (dimensionless),
    shape (2,), of the time-averaged NIS of one run that uses ``n_meas`` of the 5 measurements,
    on a log of ``n_samples`` samples whose first sample has no measurement."""
    ex = "18.1"
    m = require_int("n_meas", n_meas, minimum=1)
    if m > N_MEAS:
        raise ValueError(f"n_meas must be an integer in 1..{N_MEAS}, got {m}")
    n_samples = require_int("n_samples", n_samples, minimum=3)
    alpha = _alpha(alpha)
    K = n_samples - 1
    right = np.array(chi2_bounds(m, K, alpha))
    z = stats.norm.ppf(1 - alpha / 2)
    pairs = [
        (chi2_bounds(N_MEAS, K, alpha), "dim5"),
        (chi2_bounds(m, K + 1, alpha), "count_nan"),
        (right * K, "not_divided"),
        (stats.chi2.ppf([alpha, 1 - alpha], m * K) / K, "one_sided"),
        (m + np.array([-1.0, 1.0]) * z * np.sqrt(2 * m / K), "normal"),
    ]
    return judge(ex, answer, right, _wrong(ex, pairs, right, _RTOL_NIS), rtol=_RTOL_NIS, atol=0.0,
                 praise=f"{m} degrees of freedom per update, K = {K} updates, divided by K",
                 hint="the time average of K independent χ²(m) values: K times it is χ²(mK)")


#: the measurement subsets of exercise 18.2: no range, no GPS, no bearings
LOST_SUBSETS = ((0, 2, 3, 4), (0, 1, 2), (1, 3, 4))


def lost_directions(subsets=LOST_SUBSETS, window: int = 10, params: CoopParams | None = None,
                    exact: bool = True) -> np.ndarray:
    """6 - rank of the stacked observability matrix (``observability_matrix``, rank by
    ``np.linalg.matrix_rank``) of the linearized DT model along the nominal, over the first
    ``window`` samples, with only the rows ``subset`` of H; one integer per subset.

    ``exact=True`` uses the exact Jacobian of the one-step map (``jacobian_step``);
    ``exact=False`` the Euler ``F = I + dT A``, which sees a rotation of the whole scene faintly."""
    p = CoopParams() if params is None else params
    window = require_int("window", window, minimum=1)
    x = nominal_trajectory(p, window)
    if window < 2:
        F = np.zeros((0, 6, 6))
    elif exact:
        F = jacobian_step(x[:-1], p.u0, p.dT, p.L)
    else:
        F = np.eye(N_STATES) + p.dT * jacobian_A(x[:-1], p.u0, p.L)
    H = jacobian_C(x)
    out = []
    for sub in subsets:
        rows = [require_int("subsets", i, minimum=0) for i in sub]
        if not rows or max(rows) >= N_MEAS or len(set(rows)) != len(rows):
            raise ValueError(f"subsets must hold distinct measurement indices 0..4, got {tuple(sub)}")
        out.append(N_STATES - np.linalg.matrix_rank(observability_matrix(F, H[:, rows])))
    return np.array(out, dtype=float)


def check_demo_lost_directions(answer, *, window: int = 10) -> Feedback:
    """Exercise 18.2: for the subsets no range ``(0, 2, 3, 4)``, no GPS ``(0, 1, 2)`` and no
    bearings ``(1, 3, 4)``, the number of state directions that are unobservable over the first
    ``window`` samples of the nominal (6 - rank of the stacked observability matrix of the
    linearized DT model with the exact Jacobian of the one-step map); answer: 3 integers.
    Without the GPS, three directions are lost: the common translation (2) and a rotation of the
    whole scene (1); the Euler ``F = I + dT A`` hides the rotation (an artefact), hence 2."""
    ex = "18.2"
    window = require_int("window", window, minimum=2)
    right = lost_directions(LOST_SUBSETS, window)
    a = as_array(answer)
    if a is not None and a.size == 3 and np.all(np.isfinite(a)) and not np.allclose(a, np.round(a)):
        return Feedback(ex, False, "a number of directions is a whole number: 6 minus a rank")
    pairs = [(N_STATES - right, "ranks"), (lost_directions(LOST_SUBSETS, window, exact=False), "euler"),
             (right * np.array([1, 0, 1]), "no_gps_observable")]
    for lost in (1, 2, 3):
        pairs.append((right + np.array([lost, 0, 0]), "no_range_lost"))
        pairs.append((right + np.array([0, 0, lost]), "no_bearings_lost"))
    return judge(ex, answer, right, _wrong(ex, pairs, right, 0.0), rtol=0.0, atol=1e-9,
                 praise="only the GPS pins the pair to the map: without it the common translation "
                        "(2 directions) and a rotation of the whole scene (1) are lost",
                 hint="build O with observability_matrix(F, H[:, rows]) over the window, F the exact "
                      "jacobian_step, and count 6 - rank")
