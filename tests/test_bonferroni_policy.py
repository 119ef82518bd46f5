"""One Bonferroni policy in every problem (``Check.bonferroni``): the checks judged together in one verdict
are one family, and every entry's simultaneous band is at ``alpha / entries``, ``entries`` the total number
of entries of those checks.  Calibration once gave each of its seven checks ``alpha / 7`` of its own."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers import calibration, coop, orbit
from kfcal_helpers.calibration import ASSIGNMENT_CHECKS, CHECK_NAMES
from kfcal_helpers.consistency import Check, chi2_bounds

ALPHA = 0.05


def _calibration():
    return calibration.run_monte_carlo(calibration.CalibrationParams(), 30, seed=3, alpha=ALPHA)


def _coop():
    return coop.truth_model_test(replace(coop.CoopParams(), duration=1.0), 20, 7, filter="ekf", alpha=ALPHA)


def _orbit():
    return orbit.truth_model_test(replace(orbit.OrbitParams(), n_steps=120), 10, 3, filter="ekf", alpha=ALPHA)


@pytest.fixture(scope="module")
def results():
    return {"calibration": _calibration(), "coop": _coop(), "orbit": _orbit()}


def _nees_level(result, check):
    """The per-entry significance of the NEES check's simultaneous band, read back from its lower bound:
    the run-averaged NEES of N runs of an n-state filter is chi2_{nN}/N, the band's lower bound its
    level/2 quantile."""
    dim, n = int(round(check.expected[0])), result.n_runs
    return 2 * stats.chi2.cdf(check.sim_lower[0] * n, dim * n)


@pytest.mark.parametrize("problem", ["calibration", "coop", "orbit"])
def test_each_problem_splits_alpha_over_all_entries_of_its_checks(results, problem):
    r = results[problem]
    checks = r.checks()
    total = sum(c.statistic.size for c in checks.values())
    nees = checks["nees"]
    dim = int(round(nees.expected[0]))
    lo, hi = chi2_bounds(dim, r.n_runs, ALPHA / total)            # rebuilt at alpha / (all entries)
    np.testing.assert_allclose(nees.sim_lower, lo, rtol=1e-12)
    np.testing.assert_allclose(nees.sim_upper, hi, rtol=1e-12)
    np.testing.assert_allclose(nees.lower, chi2_bounds(dim, r.n_runs, ALPHA)[0], rtol=1e-12)


def test_the_three_problems_use_the_same_per_entry_level_for_the_same_entries(results):
    """Read back from each problem's NEES band, the per-entry level times the total number of entries of
    the problem's checks is alpha in all three: one rule, whatever the problem."""
    products = {}
    for problem, r in results.items():
        checks = r.checks()
        total = sum(c.statistic.size for c in checks.values())
        products[problem] = _nees_level(r, checks["nees"]) * total
    assert products == pytest.approx(dict.fromkeys(results, ALPHA), rel=1e-6), products


def test_calibration_checks_of_a_subset_are_a_family_of_their_own(results):
    mc = results["calibration"]
    for names in (CHECK_NAMES, ASSIGNMENT_CHECKS, ("nees",), ("residual_variance", "nis")):
        checks = mc.checks(names)
        total = sum(mc.entries(n) for n in names)
        assert total == sum(c.statistic.size for c in checks.values())
        for name, c in checks.items():                             # every check's band at alpha / total
            stat, _, slo, shi = mc.band(name, ALPHA / total)
            np.testing.assert_array_equal(c.sim_lower, np.broadcast_to(slo, np.shape(stat)).ravel())
            np.testing.assert_array_equal(c.sim_upper, np.broadcast_to(shi, np.shape(stat)).ravel())
    assert sum(mc.entries(n) for n in CHECK_NAMES) == 48622       # the seven checks at the 151 default fixes


def test_calibration_entries_count_the_checks_entries_with_missing_fixes():
    p = calibration.CalibrationParams()
    missing = np.zeros(p.n_gps, bool)
    missing[40:60] = True
    mc = calibration.run_monte_carlo(p, 10, seed=1, missing_fixes=missing)
    for name, c in mc.checks().items():
        assert mc.entries(name) == c.statistic.size, name
    with pytest.raises(ValueError, match="name"):
        mc.entries("worst")


def test_bonferroni_has_one_policy_and_no_split_by_checks():
    assert Check.bonferroni(0.05, 48622) == 0.05 / 48622
    with pytest.raises(TypeError):
        Check.bonferroni(0.05, 151, n_checks=7)   # the old per-check split is gone
