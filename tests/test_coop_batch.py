"""The batched LKF/EKF/UKF (kfcal_helpers.coop.batch) equal the per-run filterpy filters on the same
draws: x, P, NEES, NIS, errors and two-sigma bounds, to 1e-9."""

from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers.coop import CoopParams, simulate
from kfcal_helpers.coop.batch import batch_sigma_points, run_batch
from kfcal_helpers.coop.filters import FilterSetup, SigmaPoints, robust_sqrt, run
from kfcal_helpers.coop.simulation import simulate_measurements, simulate_truth

P = CoopParams(duration=20.0)
N = 3


def _same(batch, setup, y, truth):
    """Each run of the batch against its own filterpy run."""
    for i in range(y.shape[0]):
        r = run(y[i], setup, truth[i])
        np.testing.assert_allclose(batch.x[i], r.x_post, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(batch.P[i], r.P_post, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(batch.nees[i], r.nees, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(batch.nis[i], r.nis, rtol=1e-9, atol=1e-9)  # NaN where filterpy has NaN
        np.testing.assert_allclose(batch.errors[i], r.errors(truth[i]), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(batch.sigma2[i], r.sigma2, rtol=1e-9, atol=1e-9)
    assert batch.measurements == setup.measurement.rows


CASES = [
    ("lkf", {}),
    ("ekf", {}),
    ("ukf", {}),
    ("lkf", {"measurements": (0, 1, 2)}),
    ("ekf", {"measurements": (0, 1, 2)}),
    ("ukf", {"measurements": (1, 3, 4)}),
    ("ekf", {"wrap_innovations": False}),
    ("lkf", {"subtract_nominal": False}),
    ("ukf", {"points": SigmaPoints(alpha=0.5, beta=2.0, kappa=1.0)}),
    ("ukf", {"points": SigmaPoints(alpha=0.3, beta=0.0, kappa=-2.0), "measurements": (0, 2)}),
]


@pytest.mark.parametrize("every", [1, 3])
@pytest.mark.parametrize("name,settings", CASES, ids=[f"{n}-{'-'.join(s) or 'default'}" for n, s in CASES])
def test_batch_equals_filterpy_per_run(name, settings, every):
    sim = simulate(P, N, 3, every=every)
    setup = FilterSetup.build(name, P, **settings)
    b = run_batch(sim.y, setup, sim.truth, keep_estimates=True)
    assert b.x.shape == (N, P.n_samples, 6) and b.P.shape == (N, P.n_samples, 6, 6)
    assert b.nis.shape == b.nees.shape == (N, P.n_samples) and b.errors.shape == b.sigma2.shape == (N, P.n_samples, 6)
    assert np.isnan(b.nis[:, 1]).all() == (every > 1)
    _same(b, setup, sim.y, sim.truth)


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_batch_equals_filterpy_with_other_settings_and_a_first_measurement(name):
    """A measurement at t_0 (the UKF's sigma points of (x0, P0)), another Q, R, x0, P0, noise model."""
    p = replace(P, duration=8.0, noise_model="identity")
    rng = np.random.default_rng(12)
    truth = simulate_truth(p, rng, n_runs=N)
    y = simulate_measurements(truth, p, rng, first=True)
    setup = FilterSetup.build(name, p, Q=3.0 * p.Qtrue, R=np.diag([0.03, 50.0, 0.05, 30.0, 40.0]),
                              x0=p.x0 + np.array([0.5, -0.5, 0.05, 1.0, 0.0, -0.05]), P0=2.0 * p.P0)
    b = run_batch(y, setup, truth, keep_estimates=True)
    assert np.isfinite(b.nis[:, 0]).all()
    _same(b, setup, y, truth)


def test_the_lkf_gains_are_those_of_every_run():
    """The LKF's covariances do not depend on the data: one P for all runs, equal to each filterpy run's."""
    sim = simulate(P, N, 8)
    b = run_batch(sim.y, FilterSetup.build("lkf", P), sim.truth, keep_estimates=True)
    assert np.array_equal(b.P[0], b.P[-1])
    assert not np.allclose(b.x[0], b.x[-1])


def test_without_truth_or_estimates_only_the_nis_and_bounds_are_kept():
    sim = simulate(P, 2, 4)
    b = run_batch(sim.y, FilterSetup.build("ekf", P))
    assert b.nees is None and b.errors is None and b.x is None and b.P is None
    assert b.nis.shape == (2, P.n_samples) and np.isfinite(b.nis[:, 1:]).all() and np.isnan(b.nis[:, 0]).all()
    r = run(sim.y[1], FilterSetup.build("ekf", P))
    np.testing.assert_allclose(b.nis[1], r.nis, rtol=1e-9, atol=1e-9)


def test_sigma_points_use_the_jitter_of_robust_sqrt_for_a_singular_covariance():
    """A rank-deficient P fails the plain Cholesky factorization; that run gets robust_sqrt's jitter,
    the other its plain factor."""
    from filterpy.kalman import MerweScaledSigmaPoints

    pts = MerweScaledSigmaPoints(6, alpha=1.0, beta=2.0, kappa=0.0)
    v = np.arange(1.0, 7.0)
    singular = np.outer(v, v)  # rank 1
    good = np.diag(v)
    x = np.zeros((2, 6))
    sig = batch_sigma_points(x, np.stack([good, singular]), pts)
    assert sig.shape == (2, 13, 6)
    for i, M in enumerate((good, singular)):
        pts.sqrt = robust_sqrt
        np.testing.assert_allclose(sig[i], pts.sigma_points(x[i], M), rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="non-finite"):
        batch_sigma_points(x, np.stack([good, np.full((6, 6), np.nan)]), pts)


@pytest.mark.parametrize("bad,message", [
    (lambda y: y[0], r"y must have shape \(n_runs, K, 5\)"),
    (lambda y: np.where(np.arange(5) == 1, np.nan, y), "all finite or all NaN"),
    (lambda y: np.concatenate([y[:1], np.where(np.arange(y.shape[1])[:, None] == 3, np.nan, y[1:2])]),
     "same in every run"),
])
def test_malformed_measurements_are_refused(bad, message):
    sim = simulate(replace(P, duration=1.0), 2, 1)
    with pytest.raises(ValueError, match=message):
        run_batch(bad(sim.y), FilterSetup.build("ekf", sim.params))


def test_a_truth_of_another_shape_is_refused():
    sim = simulate(replace(P, duration=1.0), 2, 1)
    with pytest.raises(ValueError, match=r"truth must have shape \(2, 11, 6\)"):
        run_batch(sim.y, FilterSetup.build("ukf", sim.params), sim.truth[:, :5])
    with pytest.raises(ValueError, match="setup must be"):
        run_batch(sim.y, "ekf")


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_a_diverging_run_is_one_value_error_without_warnings(name):
    import warnings

    sim = simulate(replace(P, duration=2.0), 2, 1)
    setup = FilterSetup.build(name, sim.params, P0=1e300 * np.eye(6))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"diverged|non-finite"):
            run_batch(sim.y, setup, sim.truth)
