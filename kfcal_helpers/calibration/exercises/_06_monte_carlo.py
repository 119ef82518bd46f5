"""Exercise checks of notebook 06 (Monte Carlo validation): 06.1-06.4."""

from __future__ import annotations



import numpy as np
from scipy import stats

from ...consistency import chi2_bounds
from ...exercises._core import (BAND_NAMES, Exercise, Feedback, chi2_average_bounds)
from ...validation import (require_finite, require_int, require_probability)
from ._shared import as_pair, call_once, close, numeric


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
    components=BAND_NAMES,
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
    return numeric(_MC_NIS_BOUNDS, answer, right, wrong)


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
        "z_two": "right method, but z = 2 is not the quantile: the two-sided 95 % band uses the 97.5 % normal quantile "
                 "(scipy.stats.norm.ppf)",
    },
    components=BAND_NAMES,
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
    wrong.append(("z_two", np.tanh(np.arctanh(rho) + pm * 2.0 / np.sqrt(N - 3))))   # the "two sigma" rule
    return numeric(_FISHER_BAND, answer, right, wrong)


def seven_check_entries(n_fixes: int) -> int:
    """The number of entries of the seven checks together at ``n_fixes`` fixes, none missing: 3 + 6 + 9
    per fix (mean error, covariance, orthogonality), 4 per pair of fixes (residual independence), 2 per
    fix (residual variance), 1 + 1 per fix (NEES, NIS): ``22 n + 2 n (n - 1)``."""
    n = require_int("n_fixes", n_fixes, minimum=2)
    return 22 * n + 2 * n * (n - 1)


#: the verdict's family of exercise 06.3: the fixes of the default run and the entries of its seven checks
SIMULTANEOUS_NEES_FIXES = 151
SIMULTANEOUS_NEES_ENTRIES = seven_check_entries(SIMULTANEOUS_NEES_FIXES)   # 48,622

_SIMULTANEOUS_NEES_BAND = Exercise(
    "06.3",
    praise=f"the simultaneous band is wider: every one of the {SIMULTANEOUS_NEES_ENTRIES:,} entries of the seven "
           f"checks must pass",
    hint=f"the per-entry significance is α/{SIMULTANEOUS_NEES_ENTRIES:,} (α shared by all entries of the seven "
         f"checks, judged together); then the usual χ²_{{3N}}/N band",
    hints={
        "pointwise": "that is the pointwise band: the simultaneous one splits α over every entry of the seven "
                     "checks together",
        "fixes_only": f"the verdict judges the seven checks together: α is split over all their "
                      f"{SIMULTANEOUS_NEES_ENTRIES:,} entries, not over the NEES check's {SIMULTANEOUS_NEES_FIXES} "
                      f"fixes alone",
        "per_check": f"that gives each check α/7 of its own; the course's one policy splits α over all "
                     f"{SIMULTANEOUS_NEES_ENTRIES:,} entries of the seven checks together",
        "one_sided": "each entry's two-sided band puts half of its share of α in each tail",
        "dim2": "the NEES is a quadratic form in the 3-dimensional error: χ² with 3N degrees of freedom",
        "sum": "these bound the SUM of the N NEES values; the check uses their run average: divide by N",
        "dof3": "one NEES has 3 degrees of freedom, but the sum of N independent ones has 3N: use χ²_{3N}, then "
                "divide by N",
    },
    components=BAND_NAMES,
)


def check_simultaneous_nees_band(answer, *, n_runs: int = 1000, n_fixes: int = SIMULTANEOUS_NEES_FIXES,
                                 alpha: float = 0.05) -> Feedback:
    """Exercise 06.3: the simultaneous (Bonferroni) band ``[lower, upper]`` of the run-averaged
    NEES at each of ``n_fixes`` fixes, when the seven checks are judged together (as
    :meth:`MonteCarloResult.checks` does): per-entry significance ``alpha`` over the seven checks'
    entries, :func:`seven_check_entries` (48,622 for 151 fixes)."""
    N = require_int("n_runs", n_runs, minimum=2)
    n_fixes = require_int("n_fixes", n_fixes, minimum=2)
    alpha = require_probability("alpha", alpha)
    level = alpha / seven_check_entries(n_fixes)
    right = chi2_bounds(3, N, level)
    wrong = [("pointwise", chi2_average_bounds(3, N, alpha)), ("fixes_only", chi2_average_bounds(3, N, alpha / n_fixes)),
             ("per_check", chi2_average_bounds(3, N, alpha / 7 / n_fixes)),
             ("one_sided", chi2_average_bounds(3, N, level, one_sided=True)),
             ("dim2", chi2_average_bounds(2, N, level)),
             ("sum", chi2_average_bounds(3, N, level, divide_by=1)),
             ("dof3", chi2_average_bounds(3, N, level, dof=3, divide_by=1)),
             ("dof3", chi2_average_bounds(3, N, level, dof=3))]
    return numeric(_SIMULTANEOUS_NEES_BAND, answer, right, wrong)


#: the test ensemble of exercise 06.4: realizations, fixes, components, and the significance it is called with
MEAN_ERROR_TEST = (12, 5, 3, 0.1)


def _mean_error_test():
    """The errors e (12, 5, 3) the check passes (m, m/s, m/s^2 per component; the same on every call)."""
    n, n_fix, n_comp, _ = MEAN_ERROR_TEST
    rng = np.random.default_rng(604)
    return rng.normal(0.0, [1.0, 0.1, 0.01], size=(n, n_fix, n_comp)) + np.array([0.3, -0.02, 0.001])


_MEAN_ERROR_BAND = Exercise(
    "06.4",
    praise="your mean-error check: the ensemble mean and its Student-t band, for any ensemble and any α",
    hint="the mean over the realizations (axis 0) and the half-width t_{N-1}(1 - α/2) · s / √N, s the ensemble "
         "standard deviation with ddof=1",
    hints={
        "tuple": "return a tuple (e_bar, half): two arrays of the shape of one realization's errors, (n_fixes, 3)",
        "axis": "average over the realizations, the first axis of e (axis=0): e_bar has the shape of one "
                "realization's errors",
        "z": "with the ensemble's own standard deviation the standardized mean is Student-t with N - 1 degrees of "
             "freedom, not normal: use scipy.stats.t",
        "dof_n": "the ensemble standard deviation uses up one degree of freedom: Student-t with N - 1",
        "ddof0": "the sample standard deviation divides by N - 1 (np.std(..., ddof=1))",
        "no_sqrt_n": "that is the band of one realization's error: the mean of N has standard error s/√N",
        "over_n": "the standard error of a mean of N is s/√N, not s/N",
        "one_sided": "a two-sided band puts α/2 in each tail: the 1 - α/2 quantile",
        "two": "2 is not the quantile: use the Student-t quantile at 1 - α/2 with N - 1 degrees of freedom",
        "fixed_alpha": "use the significance the function is given (alpha), not 0.05",
    },
)


def check_mean_error_band(func) -> Feedback:
    """Exercise 06.4: ``func(e, alpha) -> (e_bar, half)``, the ensemble mean error and the half-width of its
    two-sided ``1 - alpha`` Student-t band, both of shape ``e.shape[1:]``, for errors ``e`` of shape
    (N, n_fixes, 3). Called on a fixed test ensemble (``MEAN_ERROR_TEST``: N = 12, 5 fixes, alpha = 0.1)."""
    ex = _MEAN_ERROR_BAND
    e = _mean_error_test()
    n, alpha = len(e), MEAN_ERROR_TEST[3]
    out, fb = call_once(ex, func, "mean_error_band(e, alpha)", (e.copy(), alpha))
    if fb is not None:
        return fb
    pair = as_pair(out)
    if pair is None:
        return ex.mistake("tuple")
    e_bar, half = pair
    right_bar = e.mean(axis=0)
    if e_bar.size != right_bar.size:
        return ex.mistake("axis")
    if half.size != right_bar.size:
        return ex.mistake("tuple")
    s, s0 = e.std(axis=0, ddof=1), e.std(axis=0)
    t = stats.t.ppf(1 - alpha / 2, n - 1)
    right_half = t * s / np.sqrt(n)
    if not close(e_bar, right_bar):
        slip = ex.output_slip([e_bar, half], [right_bar, right_half], ("e_bar", "half"))
        return slip if slip is not None else ex.feedback(False, "e_bar is not the ensemble mean: " + ex.hint)
    if close(half, right_half):
        return ex.feedback(True)
    wrong = [("z", stats.norm.ppf(1 - alpha / 2) * s / np.sqrt(n)), ("dof_n", stats.t.ppf(1 - alpha / 2, n) * s / np.sqrt(n)),
             ("ddof0", t * s0 / np.sqrt(n)), ("no_sqrt_n", t * s), ("over_n", t * s / n),
             ("one_sided", stats.t.ppf(1 - alpha, n - 1) * s / np.sqrt(n)), ("two", 2 * s / np.sqrt(n)),
             ("fixed_alpha", stats.t.ppf(0.975, n - 1) * s / np.sqrt(n))]
    for key, value in wrong:
        if close(half, value):
            return ex.mistake(key)
    slip = ex.output_slip([e_bar, half], [right_bar, right_half], ("e_bar", "half"))
    return slip if slip is not None else ex.feedback(False, "e_bar is right, the half-width is not: " + ex.hint)


#: the exercise records of this lesson, in notebook order
RECORDS = (_MC_NIS_BOUNDS, _FISHER_BAND, _SIMULTANEOUS_NEES_BAND, _MEAN_ERROR_BAND)
