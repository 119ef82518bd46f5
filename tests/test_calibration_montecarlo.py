"""Monte Carlo checks: a consistent filter passes, a mismatched one fails."""

import numpy as np
import pytest

from kfcal_helpers.calibration import CHECK_NAMES, CalibrationParams, run_monte_carlo
from kfcal_helpers.consistency import chi2_bounds


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_correct_filter_passes_every_check(seed):
    mc = run_monte_carlo(n_runs=400, seed=seed)
    checks = mc.checks()
    assert set(checks) == set(CHECK_NAMES)
    for name, c in checks.items():
        assert c.passed, (name, c.worst)
        assert c.inside_fraction > 0.5, name
    # the run-averaged NEES and NIS hover around their dimension
    assert abs(mc.nees.mean() - 3) < 0.1 and abs(np.nanmean(mc.nis) - 2) < 0.1


def test_ensemble_sigma_agrees_with_P():
    mc = run_monte_carlo(n_runs=2000, seed=4)
    np.testing.assert_allclose(mc.ensemble_sigma_final, mc.sigma_final, rtol=0.06)


def test_analytic_truth_is_caught():
    mc = run_monte_carlo(n_runs=1000, seed=5, truth="analytic")
    checks = mc.checks()
    assert not checks["mean_error"].passed and not checks["nees"].passed
    assert checks["nees"].inside_fraction < 0.5


def test_filterpy_engine_gives_the_same_statistics():
    a = run_monte_carlo(n_runs=6, seed=9, engine="batch")
    b = run_monte_carlo(n_runs=6, seed=9, engine="filterpy")
    for name in ("e_mean", "e_cov", "orthogonality", "residual_moment", "nees", "nis"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-9, atol=1e-12)


def test_chunking_keeps_statistics_exact():
    """Sums over chunks of CHUNK_SIZE equal the statistics of one big array."""
    from kfcal_helpers.calibration import batch_filter, simulate
    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE

    n = CHUNK_SIZE + 7
    mc = run_monte_carlo(n_runs=n, seed=12)
    rng = np.random.default_rng(12)
    sims = [simulate(mc.params, CHUNK_SIZE, rng), simulate(mc.params, 7, rng)]
    e = np.concatenate([s.dx_at_fixes - batch_filter(mc.params, s.dz, full_rate=False).x_post for s in sims])
    np.testing.assert_allclose(mc.e_mean, e.mean(0), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(mc.e_cov[-1], np.cov(e[:, -1].T), rtol=1e-9)


def test_outage_monte_carlo_runs_and_passes():
    missing = np.zeros(CalibrationParams().n_gps, bool)
    missing[50:75] = True
    mc = run_monte_carlo(n_runs=300, seed=2, missing_fixes=missing)
    assert np.isnan(mc.nis[50:75]).all()
    assert all(c.passed for c in mc.checks().values())


def test_chi2_bounds_match_spec_examples():
    np.testing.assert_allclose(chi2_bounds(6, 50), (5.078, 6.997), atol=1e-3)
    np.testing.assert_allclose(chi2_bounds(5, 50), (4.162, 5.914), atol=1e-3)
