"""Orbit-determination filters on filterpy (kfcal_helpers.orbit.filters): a measurement whose size changes
per step, predict-only steps, phi wrapped, consistency on the truth model, the LKF's drift from the nominal."""

from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers.orbit import OrbitParams, nominal_trajectory, simulate, visible
from kfcal_helpers.orbit.filters import FILTERS, FilterSetup, run, run_filter

P = OrbitParams()
SHORT = replace(P, n_steps=300)
NEAR = replace(SHORT, dx0=np.zeros(4), P0=np.diag([1e-4, 1e-8, 1e-4, 1e-8]))  # truth close to the nominal


@pytest.fixture(scope="module")
def short_sim():
    return simulate(SHORT, seed=11, every=1)


@pytest.mark.parametrize("name", FILTERS)
def test_sizes_follow_the_stations_and_empty_steps_only_predict(name):
    sim = simulate(SHORT, seed=12, every=4)  # every 4th step measured: the others predict only
    r = run_filter(name, sim.y, SHORT, truth=sim.truth)
    K = SHORT.n_samples
    assert r.x_prior.shape == r.x_post.shape == (K, 4) and r.P_prior.shape == r.P_post.shape == (K, 4, 4)
    assert len(r.y) == len(r.S) == len(r.K) == len(r.stations) == K
    counts = np.isfinite(sim.y).all(axis=-1).sum(axis=-1)
    np.testing.assert_array_equal(r.dof, 3 * counts)
    assert set(r.dof[::4][1:].tolist()) >= {3, 6}  # one and two stations both occur
    for k in range(K):
        d = r.dof[k]
        assert r.y[k].shape == (d,) and r.S[k].shape == (d, d) and r.K[k].shape == (4, d)
        if d == 0:
            np.testing.assert_array_equal(r.x_post[k], r.x_prior[k])
            np.testing.assert_array_equal(r.P_post[k], r.P_prior[k])
            assert np.isnan(r.nis[k])
        else:
            assert np.all(np.diag(r.P_post[k]) < np.diag(r.P_prior[k]))
            np.testing.assert_allclose(r.nis[k], r.y[k] @ np.linalg.solve(r.S[k], r.y[k]), rtol=1e-10)
    err = sim.truth - r.x_post
    np.testing.assert_allclose(r.nees, np.einsum("ki,ki->k", err, np.linalg.solve(r.P_post, err[..., None])[..., 0]),
                               rtol=1e-10)
    np.testing.assert_array_equal(r.stations[5], np.flatnonzero(np.isfinite(sim.y[5]).all(axis=-1)))


@pytest.mark.parametrize("name", FILTERS)
def test_phi_is_wrapped_a_turn_added_to_every_phi_changes_nothing(name, short_sim):
    y = short_sim.y.copy()
    y[..., 2] += np.where(y[..., 2] > 0, -2 * np.pi, 2 * np.pi)  # the same angles, outside (-pi, pi]
    a = run_filter(name, short_sim.y, SHORT)
    b = run_filter(name, y, SHORT)
    np.testing.assert_allclose(b.x_post, a.x_post, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.nis, a.nis, rtol=1e-9, atol=1e-9)
    assert max(np.abs(v[2::3]).max(initial=0) for v in b.y) < np.pi


@pytest.mark.parametrize("name", ["ekf", "ukf"])
def test_ekf_and_ukf_are_consistent_over_the_whole_pass(name):
    """The course's scenario (1401 samples, dx0, Qtrue, Rtrue): time-averaged NEES near 4, NIS per dof near 1."""
    sim = simulate(P, seed=3)
    r = run_filter(name, sim.y, P, truth=sim.truth)
    has = np.isfinite(r.nis)
    nees, nis = r.nees.mean(), r.nis[has].sum() / r.dof[has].sum()
    print(f"{name}: NEES {nees:.2f} (4 dof), NIS per dof {nis:.3f}")
    assert 3.0 < nees < 5.0
    assert 0.9 < nis < 1.1
    assert np.abs(r.errors(sim.truth)[:, [0, 2]]).max() < 1.0  # km


def test_lkf_near_the_nominal_agrees_with_the_ekf_and_is_consistent():
    nees = []
    for seed in range(4):
        sim = simulate(NEAR, seed=seed)
        lkf = run_filter("lkf", sim.y, NEAR, truth=sim.truth)
        ekf = run_filter("ekf", sim.y, NEAR, truth=sim.truth)
        assert np.abs(lkf.x_post - ekf.x_post)[:, [0, 2]].max() < 0.5  # km
        nees.append(lkf.nees.mean())
    assert 3.0 < np.mean(nees) < 6.0


def test_lkf_about_the_nominal_degrades_as_the_orbit_drifts_and_the_ekf_does_not():
    sim = simulate(P, seed=3)
    lkf = run_filter("lkf", sim.y, P, truth=sim.truth)
    ekf = run_filter("ekf", sim.y, P, truth=sim.truth)
    drift = np.hypot(*(sim.truth - nominal_trajectory(P))[:, [0, 2]].T)  # km from the nominal
    assert drift[0] < 1 and drift[-100:].min() > 300
    e_lkf = np.hypot(*lkf.errors(sim.truth)[:, [0, 2]].T)
    e_ekf = np.hypot(*ekf.errors(sim.truth)[:, [0, 2]].T)
    first, last = slice(1, 100), slice(-100, None)
    print(f"LKF position error {e_lkf[first].mean():.3f} km early, {e_lkf[last].mean():.1f} km late; "
          f"EKF {e_ekf[first].mean():.3f}, {e_ekf[last].mean():.3f} km")
    assert e_lkf[last].mean() > 10 * e_lkf[first].mean()
    assert e_lkf[last].mean() > 100 * e_ekf[last].mean()
    assert e_ekf[last].mean() < 1.0


def test_a_measurement_at_t0_updates_the_initial_estimate():
    p = replace(SHORT, n_steps=20)
    sim = simulate(p, seed=2, first=True)
    assert np.isfinite(sim.y[0]).all(axis=-1).any()
    for name in FILTERS:
        r = run_filter(name, sim.y, p)
        assert r.dof[0] > 0 and not np.allclose(r.x_post[0], r.x_prior[0])


def test_the_filters_read_a_course_log(short_sim):
    log = short_sim.log()
    a = run_filter("ekf", log, SHORT)
    b = run_filter("ekf", short_sim.y, SHORT)
    np.testing.assert_array_equal(a.x_post, b.x_post)
    np.testing.assert_array_equal(a.dof, log.dof)


def test_stations_seen_are_the_visible_ones(short_sim):
    r = run_filter("ekf", short_sim.y, SHORT)
    v = visible(short_sim.truth, SHORT.t, SHORT)
    for k in range(1, SHORT.n_samples):
        np.testing.assert_array_equal(r.stations[k], np.flatnonzero(v[k]))


def test_bad_inputs_name_the_argument(short_sim):
    y = short_sim.y.copy()
    with pytest.raises(ValueError, match="y must have shape"):
        run_filter("ekf", y[:, :5])
    y[3, 0, 1] = np.nan if np.isfinite(y[3, 0, 0]) else 1.0
    with pytest.raises(ValueError, match="all finite or all NaN"):
        run_filter("ekf", y)
    with pytest.raises(ValueError, match="filter must be one of"):
        run_filter("kf", short_sim.y)
    with pytest.raises(ValueError, match="nope is not a filter setting"):
        run_filter("ekf", short_sim.y, nope=1)
    with pytest.raises(ValueError, match="Q must be a 2x2"):
        FilterSetup("ekf", Q=np.eye(4))
    with pytest.raises(ValueError, match="alpha"):
        FilterSetup("ukf", alpha=0.0)
    with pytest.raises(ValueError, match="setup must be a FilterSetup"):
        run(short_sim.y, {"filter": "ekf"})
    with pytest.raises(ValueError, match="truth"):
        run_filter("ekf", short_sim.y, SHORT, truth=np.zeros((3, 4)))
