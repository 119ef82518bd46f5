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


# --- between fixes: the 200 Hz error against the filter's predicted P -------------------------

@pytest.mark.parametrize("seed", [21, 22])
def test_between_fixes_correct_filter_passes(seed):
    mc = run_monte_carlo(n_runs=400, seed=seed, between_fixes=True)
    c = mc.between_fixes_check()
    assert c.passed, c.worst
    assert c.statistic.size == 3 * (mc.params.n_imu - mc.params.n_gps)
    assert 0.8 < c.inside_fraction <= 1.0
    # the seven checks at the fixes do not change when the 200 Hz sums are added
    plain = run_monte_carlo(n_runs=400, seed=seed)
    for name in CHECK_NAMES:
        assert mc.checks()[name].worst == plain.checks()[name].worst


def test_between_fixes_equals_the_direct_statistics_and_filterpy():
    from kfcal_helpers.calibration import batch_filter, run_filterpy, simulate

    n = 12
    mc = run_monte_carlo(n_runs=n, seed=31, between_fixes=True)
    sim = simulate(mc.params, n, np.random.default_rng(31))
    x = np.stack([run_filterpy(mc.params, sim.dz[l]).x for l in range(n)])  # filterpy at 200 Hz
    e = sim.dx - x
    np.testing.assert_allclose(mc.between.e_mean, e.mean(0), rtol=1e-9, atol=1e-12)
    cov = np.einsum("nja,njb->jab", e - e.mean(0), e - e.mean(0)) / (n - 1)
    np.testing.assert_allclose(mc.between.e_cov, cov, rtol=1e-7, atol=1e-15)
    np.testing.assert_allclose(mc.between.P, batch_filter(mc.params, sim.dz[:1]).P, rtol=1e-12)
    fp = run_monte_carlo(n_runs=n, seed=31, engine="filterpy", between_fixes=True)
    np.testing.assert_allclose(fp.between.e_cov, mc.between.e_cov, rtol=1e-7, atol=1e-15)


def test_between_fixes_memory_does_not_grow_with_n():
    import tracemalloc

    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE

    params = CalibrationParams(duration=5.0)
    peaks = []
    for n_runs in (CHUNK_SIZE, 3 * CHUNK_SIZE):  # one chunk, three chunks
        tracemalloc.start()
        run_monte_carlo(params, n_runs=n_runs, seed=1, between_fixes=True)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] < 1.2 * peaks[0], peaks  # the sums, not the realizations, are kept


def test_checks_do_not_depend_on_between_fixes_in_a_long_scenario():
    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE, chunk_size

    params = CalibrationParams(imu_rate=1000.0, duration=60.0)
    assert chunk_size(params) < CHUNK_SIZE  # several chunks of a size set by the realization's length
    n = chunk_size(params) + 7
    plain = run_monte_carlo(params, n_runs=n, seed=1).checks()
    with_between = run_monte_carlo(params, n_runs=n, seed=1, between_fixes=True).checks()
    for name in CHECK_NAMES:
        assert plain[name].worst == with_between[name].worst, name


def test_between_fixes_catches_a_filter_that_holds_P():
    from kfcal_helpers.mistakes import mistaken_model

    p = CalibrationParams()
    mc = run_monte_carlo(p, n_runs=300, seed=4, between_fixes=True, model=mistaken_model(p, "no_propagation"))
    assert not mc.between_fixes_check().passed


def test_between_fixes_argument():
    with pytest.raises(ValueError, match="between_fixes"):
        run_monte_carlo(n_runs=2, between_fixes="yes")
    with pytest.raises(ValueError, match="between_fixes"):
        run_monte_carlo(n_runs=2).between_fixes_check()


def test_cli_json_has_the_between_fixes_check(capsys):
    import json

    from kfcal_helpers.cli import main

    assert main(["calibrate", "--runs", "60", "--seed", "2", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    c = d["checks"]["between_fixes"]
    assert c["passed"] is True and 0.0 <= c["inside_fraction"] <= 1.0 and c["worst"] <= 1.0


@pytest.mark.parametrize("n_runs", [10, 40])
def test_residual_correlation_band_has_its_level(n_runs):
    """The residual_independence band, fed independent zero-mean Gaussian residuals, rejects a share
    alpha of the pairs (within a binomial band), and equals the exact quantile of |rho|: for the
    uncentred correlation of two independent Gaussian vectors in R^N, rho^2 ~ Beta(1/2, (N-1)/2)."""
    from dataclasses import replace

    from scipy import stats

    mc = run_monte_carlo(n_runs=n_runs, seed=0)
    n_gps = mc.params.n_gps
    rng = np.random.default_rng(2024 + n_runs)
    alpha, reps, outside, total = 0.05, 8, 0, 0
    for _ in range(reps):
        r = rng.standard_normal((n_runs, n_gps, 2)) * np.array([1.0, 0.04])   # any scale per component
        fake = replace(mc, residual_moment=np.einsum("nia,nmb->iamb", r, r) / n_runs)
        stat, _, lo, hi = fake.bands(alpha)["residual_independence"]
        outside += np.count_nonzero((stat < lo) | (stat > hi))
        total += stat.size
    # given r_i, the correlations of fix i with the other fixes are independent and have the same law:
    # the indicators are pairwise independent, so the share has the binomial standard deviation
    share, sd = outside / total, np.sqrt(alpha * (1 - alpha) / total)
    assert abs(share - alpha) < 4 * sd, (share, sd)
    for level in (alpha, alpha / 7 / stat.size):
        half = fake.bands(level)["residual_independence"][3].max()
        exact = np.sqrt(stats.beta.ppf(1 - level, 0.5, (n_runs - 1) / 2))
        assert np.isclose(half, exact, rtol=1e-9), (level, half, exact)


def test_between_fixes_check_refuses_when_every_sample_is_a_fix():
    params = CalibrationParams(gps_rate=200.0, duration=2.0)
    mc = run_monte_carlo(params, n_runs=5, seed=0, between_fixes=True)
    with pytest.raises(ValueError, match="between_fixes_check: every IMU sample is a GPS fix"):
        mc.between_fixes_check()
