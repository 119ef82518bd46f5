"""The filter's P is a single Gaussian conditioning; the RTS smoother never does worse."""

import numpy as np
import pytest

from kfcal_helpers.calibration import (CalibrationParams, batch_conditioning_covariance, batch_filter,
                                       covariance_sequence, error_state_model, make_kalman_filter,
                                       prior_covariances_at_fixes, rts_smooth_fixes, run_filterpy, simulate)

PARAMS = CalibrationParams()


def _normalized_dev(A, B):
    d = np.sqrt(np.einsum("...aa->...a", B))
    return np.max(np.abs(A - B) / (d[..., :, None] * d[..., None, :]))


def test_prior_covariance_matches_propagation():
    Pi = prior_covariances_at_fixes(PARAMS)
    m = error_state_model(PARAMS)
    P = m.M0.copy()
    for j in range(PARAMS.fix_indices[10]):
        P = m.Phi @ P @ m.Phi.T + m.Q
    assert _normalized_dev(Pi[10], P) < 1e-10


def test_batch_conditioning_equals_filter_at_every_fix():
    P_kf = covariance_sequence(PARAMS)[0][PARAMS.fix_indices]
    Pi = prior_covariances_at_fixes(PARAMS)
    P_batch = np.stack([batch_conditioning_covariance(PARAMS, i, Pi=Pi) for i in range(PARAMS.n_gps)])
    assert P_batch.shape == (PARAMS.n_gps, 3, 3)
    assert _normalized_dev(P_batch, P_kf) < 1e-6
    np.testing.assert_allclose(np.sqrt(np.diag(P_batch[-1])), [0.0975, 0.00690, 4.64e-4], rtol=3e-3)


def test_batch_conditioning_other_params():
    p = CalibrationParams(imu_rate=100.0, gps_rate=2.0, duration=10.0, W=0.01, bias_var=0.04)
    P_kf = covariance_sequence(p)[0][p.fix_indices]
    for i in (0, 1, 7, p.n_gps - 1):
        assert _normalized_dev(batch_conditioning_covariance(p, i), P_kf[i]) < 1e-6


@pytest.mark.parametrize("i", [-1, 151, 2.5, "3"])
def test_batch_conditioning_rejects_bad_index(i):
    with pytest.raises(ValueError, match="i"):
        batch_conditioning_covariance(PARAMS, i)


def test_rts_smoother():
    m = error_state_model(PARAMS)
    sim = simulate(PARAMS, 1, np.random.default_rng(5))
    fr = run_filterpy(PARAMS, sim.dz[0])
    n = PARAMS.n_imu
    xs, Ps, _, _ = make_kalman_filter(PARAMS).rts_smoother(fr.x.copy(), fr.P.copy(), Fs=[m.Phi] * n,
                                                           Qs=[m.Q] * n)
    sf = np.sqrt(np.einsum("jaa->ja", fr.P))
    ss = np.sqrt(np.einsum("jaa->ja", Ps))
    assert np.all(ss <= sf * (1 + 1e-9))  # smoothed sigma <= filtered sigma everywhere
    np.testing.assert_allclose(ss[-1], sf[-1], rtol=1e-12)  # equal at the last fix
    np.testing.assert_allclose(ss[:, 2], sf[-1, 2], rtol=1e-6)  # constant bias: the final accuracy throughout
    idx = PARAMS.fix_indices
    xf, Pf = rts_smooth_fixes(PARAMS, fr.x_prior, fr.x_post, fr.P_prior, fr.P_post)
    np.testing.assert_allclose(xf, xs[idx], rtol=1e-9, atol=1e-12)
    assert _normalized_dev(Pf, Ps[idx]) < 1e-9


def test_rts_smoothed_sigma_matches_ensemble():
    N = 400
    sims = simulate(PARAMS, N, np.random.default_rng(8))
    res = batch_filter(PARAMS, sims.dz, full_rate=False)
    xs, Ps = rts_smooth_fixes(PARAMS, res.x_prior, res.x_post, res.P_prior, res.P_post)
    s = (sims.dx_at_fixes - xs).std(axis=0, ddof=1)
    ratio = s / np.sqrt(np.einsum("iaa->ia", Ps))
    assert np.all(np.abs(ratio - 1) < 0.15)


def test_rts_rejects_bad_shapes():
    P = np.eye(3)[None].repeat(PARAMS.n_gps, 0)
    with pytest.raises(ValueError, match="x_post"):
        rts_smooth_fixes(PARAMS, np.zeros((5, 3)), np.zeros((5, 3)), P, P)


@pytest.mark.parametrize("bias_mean", [0.0, 0.05])
def test_conditional_mean_is_the_filter_estimate(bias_mean):
    """E[x(t_i) | dz_0..dz_i] from one conditioning equals filterpy's a posteriori estimate,
    also with a non-zero prior mean (the prior means are propagated by Phi)."""
    from kfcal_helpers.calibration import batch_conditioning, run_filterpy, simulate

    p = CalibrationParams(bias_mean=bias_mean)
    sim = simulate(p, 2, np.random.default_rng(3))
    fr = run_filterpy(p, sim.dz[0])
    for i in (0, 1, 12, 60):
        mean, P = batch_conditioning(p, i, sim.dz[0])
        both, _ = batch_conditioning(p, i, sim.dz)
        np.testing.assert_allclose(mean, fr.x_post[i], rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(both[0], mean, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(P, fr.P_post[i], rtol=1e-8, atol=1e-15)
    assert batch_conditioning(p, 5)[0] is None
    with pytest.raises(ValueError, match="dz"):
        batch_conditioning(p, 5, np.zeros((3, 2)))
