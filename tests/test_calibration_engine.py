"""The calibration batch engine: Phi^k, the covariances, the estimates and the live demo's error
recursion, each against filterpy (or the 200 Hz simulation) on the same draws."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers.calibration import (CalibrationParams, batch_filter, covariance_sequence, error_state_model,
                                       make_kalman_filter, outage_mask, prior_covariances_at_fixes, run_filterpy,
                                       simulate)
from kfcal_helpers.calibration.engine import (Covariances, accumulated_noise, between_fixes, estimate_between_fixes,
                                              filter_errors_at_fixes, filter_errors_time_major, matrix_powers,
                                              noise_of_simulation, sample_noise_at_fixes, sample_noise_time_major,
                                              scale_unit_noise, unit_noise_time_major)
from kfcal_helpers.calibration.simulation import draw_realizations, error_state_at_fixes, error_state_full

P = CalibrationParams()


def test_matrix_powers_and_accumulated_noise_are_the_predict_steps():
    """Phi^k and Q_k equal k of filterpy's predict steps, for the true and a mistaken model."""
    right = error_state_model(P)
    flipped = right.Phi.copy()
    flipped[0, 2] *= -1  # a mistaken model: Phi^k is not the closed form of the true one
    for model in (right, replace(right, Phi=flipped)):
        powers = matrix_powers(model.Phi, 41)
        Qk = accumulated_noise(powers[:40], model.Q)
        kf = make_kalman_filter(P, model)
        kf.P = np.zeros((3, 3))
        for k in range(41):
            np.testing.assert_allclose(powers[k], np.linalg.matrix_power(model.Phi, k), rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(Qk[k], kf.P, rtol=1e-10, atol=1e-18)
            kf.predict()
        got_powers, got_Qk = between_fixes(P, model)
        np.testing.assert_array_equal(got_powers, powers)
        np.testing.assert_array_equal(got_Qk, Qk)


def test_covariances_are_a_named_tuple_and_the_prior_covariances_share_them():
    cov = covariance_sequence(P)
    assert isinstance(cov, Covariances) and len(cov) == 4
    P_all, P_prior, S, K = cov
    assert P_all is cov.P and K is cov.K
    # with every fix missing, the filter only predicts: its P_prior is the unconditional covariance
    none = np.ones(P.n_gps, bool)
    np.testing.assert_allclose(covariance_sequence(P, none).P_prior, prior_covariances_at_fixes(P), rtol=1e-9)


@pytest.mark.parametrize("truth", ["euler", "analytic"])
@pytest.mark.parametrize("params", [P, CalibrationParams(gps_rate=2.0, duration=30.1),
                                    CalibrationParams(gps_rate=200.0, duration=2.0)], ids=["default", "tail", "r1"])
def test_error_state_from_the_draws_is_the_simulations(truth, params):
    """The Monte Carlo's error state (from the noise summed per GPS period) is simulate's, to rounding."""
    sim = simulate(params, 5, np.random.default_rng(3), truth=truth)
    draws = draw_realizations(params, 5, np.random.default_rng(3))
    np.testing.assert_array_equal(draws.w, sim.w)
    scale = np.abs(sim.dx).max(axis=(0, 1))
    at_fixes = error_state_at_fixes(params, draws, truth)
    full = error_state_full(params, draws, truth)
    assert np.all(np.abs(at_fixes - sim.dx_at_fixes).max(axis=(0, 1)) <= 1e-12 * scale + 1e-14)
    assert np.all(np.abs(full - sim.dx).max(axis=(0, 1)) <= 1e-12 * scale + 1e-14)
    dz = at_fixes[..., :2] + draws.eta
    np.testing.assert_allclose(dz, sim.dz, rtol=0, atol=1e-12 * scale[0])
    with pytest.raises(ValueError, match="draws must be a Draws"):
        error_state_at_fixes(params, sim, truth)


def test_estimate_between_fixes_is_batch_full_rate_and_filterpys():
    sim = simulate(P, 4, np.random.default_rng(0))
    full = batch_filter(P, sim.dz, full_rate=True)
    assert np.array_equal(estimate_between_fixes(P, full.x_post), full.x)  # batch_filter calls it
    assert np.allclose(estimate_between_fixes(P, full.x_post[2]), full.x[2], rtol=0, atol=1e-9)
    fp = run_filterpy(P, sim.dz[1])
    assert np.allclose(estimate_between_fixes(P, fp.x_post), fp.x, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="x_post"):
        estimate_between_fixes(P, np.zeros((10, 3)))


def test_error_recursion_is_filterpy_on_the_same_draws():
    p = P.replace(gps_rate=4.0)
    missing = outage_mask(p, [(5.0, 9.0)])
    sim = simulate(p, 6, np.random.default_rng(1), missing_fixes=missing)
    cov = covariance_sequence(p, missing)
    fr = batch_filter(p, sim.dz, full_rate=False, covariances=cov)
    e_prior, e_post = filter_errors_at_fixes(p, cov, *noise_of_simulation(sim))
    assert np.allclose(e_prior, sim.dx_at_fixes - fr.x_prior, rtol=0, atol=1e-9)
    assert np.allclose(e_post, sim.dx_at_fixes - fr.x_post, rtol=0, atol=1e-9)
    for l in (0, 5):
        fp = run_filterpy(p, sim.dz[l])
        assert np.allclose(e_post[l], sim.dx_at_fixes[l] - fp.x_post, rtol=0, atol=1e-8)
        assert np.allclose(e_prior[l], sim.dx_at_fixes[l] - fp.x_prior, rtol=0, atol=1e-8)
    # the time-major form gives the same numbers
    e0, w, eta = noise_of_simulation(sim)
    tm_prior, tm_post = filter_errors_time_major(p, cov, e0, w.transpose(1, 0, 2), eta.transpose(1, 0, 2))
    assert np.array_equal(tm_post.transpose(1, 0, 2), e_post)
    with pytest.raises(ValueError, match="eta"):
        filter_errors_at_fixes(p, cov, e0, w, eta[:, :-1])
    with pytest.raises(ValueError, match="sim"):
        noise_of_simulation(sim.dz)


def test_noise_at_fixes_follows_the_error_model():
    p = P.replace(gps_rate=2.0, W=4e-3)
    n = 3000
    e0, w, eta = sample_noise_at_fixes(p, n, np.random.default_rng(5))
    assert e0.shape == (n, 3) and w.shape == (n, p.n_gps - 1, 3) and eta.shape == (n, p.n_gps, 2)
    m = error_state_model(p)
    # Q_r by r predict steps from zero: the covariance of the IMU noise summed between fixes
    Q_r = np.zeros((3, 3))
    for _ in range(p.steps_per_fix):
        Q_r = m.Phi @ Q_r @ m.Phi.T + m.Q
    assert np.all(w[..., 2] == 0.0)  # the bias has no process noise
    w2 = w[..., :2].reshape(-1, 2)
    assert np.allclose(w2.T @ w2 / len(w2), Q_r[:2, :2], rtol=0.02, atol=0)
    lo, hi = stats.chi2.ppf([1e-4, 1 - 1e-4], n - 1) / (n - 1)
    for got, want in ((e0.var(axis=0, ddof=1), np.diag(m.M0)), (eta[:, 7].var(axis=0, ddof=1), np.diag(m.V))):
        assert np.all((got / want > lo) & (got / want < hi))
    # the same draws read off a (shorter) 200 Hz simulation have the same covariance
    sim = simulate(p.replace(duration=10.0), 2000, np.random.default_rng(6))
    ws = noise_of_simulation(sim)[1][..., :2].reshape(-1, 2)
    assert np.allclose(ws.T @ ws / len(ws), Q_r[:2, :2], rtol=0.03, atol=0)
    # a seed or a Generator; the time-major arrays are the same draws
    a = sample_noise_at_fixes(p, 4, 9)
    b = sample_noise_time_major(p, 4, np.random.default_rng(9))
    assert np.array_equal(a[1], b[1].transpose(1, 0, 2)) and np.array_equal(a[2], b[2].transpose(1, 0, 2))
    # ... scaled from their standard normals, which are the generator's, in this order
    z0, z, zeta = unit_noise_time_major(p.n_gps, 4, np.random.default_rng(9))
    rng = np.random.default_rng(9)
    assert all(np.array_equal(x, rng.standard_normal(x.shape)) for x in (z0, z, zeta))
    assert all(np.array_equal(x, y) for x, y in zip(scale_unit_noise(p, z0, z, zeta), b))
    with pytest.raises(ValueError, match="n_gps"):
        unit_noise_time_major(0, 4, 9)
    with pytest.raises(ValueError, match="zeta must have shape"):
        scale_unit_noise(p, z0, z, zeta[1:])
    with pytest.raises(ValueError, match="seed"):
        sample_noise_at_fixes(p, 4, "x")
    with pytest.raises(ValueError, match="params must be a CalibrationParams"):
        sample_noise_at_fixes(None, 4, 0)
