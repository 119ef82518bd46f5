"""Per-step chi-square checks with a measurement dimension that changes per step and per run
(kfcal_helpers.consistency.step_checks, chi2_sum_bounds), against scipy.stats.chi2 directly."""

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers.consistency import chi2_bounds, chi2_sum_bounds, step_checks


def test_chi2_sum_bounds_are_scipys_quantiles_and_reduce_to_chi2_bounds():
    dof, n = np.array([3, 9, 12, 30]), np.array([1, 3, 2, 10])
    lo, hi = chi2_sum_bounds(dof, n, 0.05)
    np.testing.assert_allclose(lo, stats.chi2.ppf(0.025, dof) / n)
    np.testing.assert_allclose(hi, stats.chi2.ppf(0.975, dof) / n)
    np.testing.assert_allclose(np.array(chi2_sum_bounds(np.array([4 * 50]), np.array([50]), 0.01))[:, 0],
                               chi2_bounds(4, 50, 0.01))
    with pytest.raises(ValueError, match="dof"):
        chi2_sum_bounds(np.array([0]), np.array([1]))


def _draws(rng, n_runs=40, K=60):
    dof = 3 * rng.integers(0, 3, size=(n_runs, K))  # 0, 3 or 6 per run and step
    dof[:, 5] = 0  # a step where no run has a measurement
    nis = np.where(dof > 0, rng.chisquare(np.maximum(dof, 1)), np.nan)
    nees = rng.chisquare(4, size=(n_runs, K))
    return nees, nis, dof


def test_step_checks_use_the_dof_present_at_each_step():
    rng = np.random.default_rng(7)
    nees, nis, dof = _draws(rng)
    c = step_checks(nees, nis, dof, 4, alpha=0.05)
    K = nees.shape[1]
    assert c["nees"].statistic.shape == (K,) and c["nis"].statistic.shape == (K - 1,)  # step 5 left out
    keep = np.arange(K) != 5
    count, total = (dof > 0).sum(axis=0)[keep], dof.sum(axis=0)[keep]
    np.testing.assert_allclose(c["nis"].statistic, np.nansum(nis, axis=0)[keep] / count)
    np.testing.assert_allclose(c["nis"].expected, total / count)
    np.testing.assert_allclose(c["nis"].lower, stats.chi2.ppf(0.025, total) / count)
    np.testing.assert_allclose(c["nis"].upper, stats.chi2.ppf(0.975, total) / count)
    a_sim = 0.05 / (K + K - 1)
    np.testing.assert_allclose(c["nis"].sim_upper, stats.chi2.ppf(1 - a_sim / 2, total) / count)
    np.testing.assert_allclose(c["nees"].lower, stats.chi2.ppf(0.025, 4 * 40) / 40)
    np.testing.assert_allclose(c["nees"].statistic, nees.mean(axis=0))
    assert c["nees"].passed and c["nis"].passed  # drawn from the distributions the bands assume


def test_a_fixed_dof_band_is_the_classic_mistake():
    """Averaging NIS with the dof of one station when two were often present: the band misjudges."""
    rng = np.random.default_rng(8)
    n_runs, K = 50, 200
    dof = np.full((n_runs, K), 6)
    dof[:, ::2] = 3
    nis = rng.chisquare(dof).astype(float)
    nees = rng.chisquare(4, size=(n_runs, K))
    right = step_checks(nees, nis, dof, 4)["nis"]
    wrong = step_checks(nees, nis, np.full_like(dof, 3), 4)["nis"]
    assert right.passed and right.inside_fraction > 0.9
    assert not wrong.passed and wrong.inside_fraction < 0.6


def test_step_checks_validate():
    rng = np.random.default_rng(9)
    nees, nis, dof = _draws(rng, 5, 10)
    with pytest.raises(ValueError, match="same shape"):
        step_checks(nees[:, :3], nis, dof, 4)
    bad = nis.copy()
    bad[dof == 0] = 1.0
    with pytest.raises(ValueError, match="nis must be finite exactly where dof > 0"):
        step_checks(nees, bad, dof, 4)
    with pytest.raises(ValueError, match="n_states"):
        step_checks(nees, nis, dof, 0)
    with pytest.raises(ValueError, match="dof must hold integers"):
        step_checks(nees, nis, dof + 0.5, 4)


def test_one_dof_for_every_nis_present_is_the_array_of_that_dof():
    """dof as one int (every NIS present has that dimension; a NaN NIS marks a run without a measurement)
    gives the checks of the (N, K) array holding it where the NIS is finite."""
    rng = np.random.default_rng(10)
    n_runs, K = 30, 40
    nis = rng.chisquare(3, size=(n_runs, K))
    nis[:, ::4] = np.nan  # steps without a measurement in every run
    nis[:5, 1] = np.nan  # and a step where some runs have none
    nees = rng.chisquare(4, size=(n_runs, K))
    dof = np.where(np.isfinite(nis), 3, 0)
    one, array = step_checks(nees, nis, 3, 4, extra_entries=7), step_checks(nees, nis, dof, 4, extra_entries=7)
    for name in ("nees", "nis"):
        for field in ("expected", "lower", "upper", "sim_lower", "sim_upper"):
            assert np.array_equal(getattr(one[name], field), getattr(array[name], field)), (name, field)
        np.testing.assert_allclose(one[name].statistic, array[name].statistic, rtol=1e-14)
        assert one[name].passed == array[name].passed
    assert one["nis"].statistic.size == K - K // 4
    np.testing.assert_allclose(one["nis"].statistic[0], nis[5:, 1].mean(), rtol=1e-14)  # step 1: 25 runs
    assert one["nis"].lower[0] == stats.chi2.ppf(0.025, 3 * 25) / 25
    for bad, message in ((0, "dof must be"), (2.5, "dof must be"), (np.full((2, 2), 3), "same shape")):
        with pytest.raises(ValueError, match=message):
            step_checks(nees, nis, bad, 4)
    with pytest.raises(ValueError, match="nis must hold only finite numbers or NaN"):
        step_checks(nees, np.where(np.isnan(nis), np.inf, nis), 3, 4)
