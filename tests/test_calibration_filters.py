"""The calibration model, the filterpy wrapper and the batch path."""

import numpy as np
import pytest

from kfcal_helpers.calibration import (
    CalibrationParams, batch_filter, covariance_sequence, error_state_model, make_kalman_filter,
    outage_mask, phi_power, run_filterpy, simulate,
)

P0 = CalibrationParams()


def rel(a, b):
    return np.nanmax(np.abs(a - b)) / np.nanmax(np.abs(b))


@pytest.fixture(scope="module")
def sim():
    return simulate(P0, 4, np.random.default_rng(7))


def test_shapes(sim):
    n, ni, ng = 4, P0.n_imu, P0.n_gps
    assert (ni, ng, P0.steps_per_fix) == (6001, 151, 40)
    for name in ("p", "v", "w", "a_c", "p_c", "v_c"):
        assert getattr(sim, name).shape == (n, ni)
    assert sim.z.shape == (n, ng, 2) and sim.dz.shape == (n, ng, 2)
    assert sim.dx.shape == (n, ni, 3) and sim.dx_at_fixes.shape == (n, ng, 3)
    np.testing.assert_array_equal(sim.dx[:, P0.fix_indices], sim.dx_at_fixes)
    r = run_filterpy(P0, sim.dz[0])
    assert r.x.shape == (ni, 3) and r.P.shape == (ni, 3, 3) and r.K.shape == (ng, 3, 2)
    b = batch_filter(P0, sim.dz)
    assert b.x.shape == (n, ni, 3) and b.y.shape == (n, ng, 2)


def test_error_state_identity_on_euler_truth(sim):
    """dx[j+1] = Phi dx[j] + Gamma w[j] holds to rounding on the full simulation."""
    m = error_state_model(P0)
    dx = sim.dx
    pred = dx[:, :-1] @ m.Phi.T + sim.w[:, :-1, None] * m.Gamma
    scale = np.abs(dx).max(axis=(0, 1))
    assert np.all(np.abs(dx[:, 1:] - pred).max(axis=(0, 1)) <= 1e-12 * scale + 1e-15)


def test_error_state_identity_fails_on_analytic_truth():
    s = simulate(P0, 2, np.random.default_rng(7), truth="analytic")
    m = error_state_model(P0)
    resid = s.dx[:, 1:] - (s.dx[:, :-1] @ m.Phi.T + s.w[:, :-1, None] * m.Gamma)
    assert np.abs(resid[..., 1]).max() > 1e-6  # the left-Riemann velocity mismatch


def test_phi_power_closed_form():
    m = error_state_model(P0)
    for k in (0, 1, 7, 40):
        np.testing.assert_allclose(phi_power(P0, k), np.linalg.matrix_power(m.Phi, k), rtol=1e-12, atol=1e-15)


def test_batch_equals_filterpy_on_same_draws(sim):
    b = batch_filter(P0, sim.dz)
    for l in range(sim.n_runs):
        f = run_filterpy(P0, sim.dz[l])
        assert rel(b.x[l], f.x) < 1e-9
        assert rel(b.x_prior[l], f.x_prior) < 1e-9
        assert rel(b.y[l], f.y) < 1e-9
    assert rel(b.P, f.P) < 1e-9 and rel(b.K, f.K) < 1e-9 and rel(b.S, f.S) < 1e-9


def test_batch_equals_filterpy_with_missing_fixes():
    missing = np.zeros(P0.n_gps, bool)
    missing[20:45] = True
    s = simulate(P0, 3, np.random.default_rng(3), missing_fixes=missing)
    assert np.isnan(s.dz[:, 20:45]).all() and np.isfinite(s.dz[:, :20]).all()
    b = batch_filter(P0, s.dz)
    for l in range(3):
        f = run_filterpy(P0, s.dz[l])
        assert rel(b.x[l], f.x) < 1e-9
        assert np.isnan(f.y[20:45]).all()
    assert rel(b.P, f.P) < 1e-9
    # predict-only through the outage: position variance grows at every missing fix
    Ppp = b.P_post[:, 0, 0]
    assert np.all(np.diff(Ppp[19:45]) > 0) and Ppp[45] < Ppp[44]
    np.testing.assert_array_equal(b.K[20:45], 0.0)


@pytest.mark.parametrize("rate, outage", [(1.0, None), (5.0, [(10.0, 16.0)]), (50.0, [(3.0, 4.5)])])
def test_covariance_sequence_fix_to_fix_equals_filterpy_step_by_step(rate, outage):
    """covariance_sequence takes the predict steps between fixes at once; filterpy takes them one by one."""
    p = CalibrationParams(gps_rate=rate)
    missing = np.zeros(p.n_gps, bool) if outage is None else outage_mask(p, outage)
    dz = np.zeros((p.n_gps, 2))
    dz[missing] = np.nan
    f = run_filterpy(p, dz)
    for fast, slow in zip(covariance_sequence(p, missing), (f.P, f.P_prior, f.S, f.K)):
        assert fast.shape == slow.shape
        assert np.allclose(fast, slow, rtol=1e-9, atol=0)


def test_covariance_symmetric_positive_definite():
    P, P_prior, S, K = covariance_sequence(P0)
    np.testing.assert_allclose(P, np.swapaxes(P, 1, 2), rtol=0, atol=1e-12 * np.abs(P).max())
    assert np.all(np.linalg.eigvalsh(P) > 0)
    assert np.all(np.linalg.eigvalsh(P_prior) > 0) and np.all(np.linalg.eigvalsh(S) > 0)


def test_reference_sigmas_from_spec():
    P = covariance_sequence(P0)[0]
    np.testing.assert_allclose(np.sqrt(np.diag(P[-1])), [0.0975, 0.00690, 4.64e-4], rtol=3e-3)
    first_at_02 = np.zeros(P0.n_gps, bool)
    first_at_02[0] = True
    P = covariance_sequence(P0, first_at_02)[0]
    np.testing.assert_allclose(np.sqrt(np.diag(P[-1])), [0.0976, 0.00692, 4.68e-4], rtol=3e-3)


def test_filter_does_not_depend_on_acceleration_profile():
    """Same draws, different omega / A: the same error state and the same estimate."""
    out = []
    for params in (P0, P0.replace(omega=0.1), P0.replace(omega=2 * np.pi * 0.1), P0.replace(A=0.0)):
        s = simulate(params, 2, np.random.default_rng(11))
        out.append((s.dx, batch_filter(params, s.dz).x))
    for dx, xh in out[1:]:
        np.testing.assert_allclose(dx, out[0][0], rtol=0, atol=1e-8)
        np.testing.assert_allclose(xh, out[0][1], rtol=0, atol=1e-8)


def test_make_kalman_filter_matrices():
    kf = make_kalman_filter(P0)
    m = error_state_model(P0)
    assert kf.x.shape == (3, 1) and kf.dim_z == 2
    np.testing.assert_array_equal(kf.F, m.Phi)
    np.testing.assert_allclose(kf.Q, m.W * np.outer(m.Gamma, m.Gamma))
    np.testing.assert_array_equal(kf.P, np.diag([100.0, 1.0, 0.01]))
    np.testing.assert_array_equal(kf.R, np.diag([1.0, 0.0016]))
