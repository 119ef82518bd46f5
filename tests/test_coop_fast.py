"""The lean single-run EKF and UKF (kfcal_helpers.coop.fast) equal filterpy's filters (run_filter) on the
same log: x, P, NIS, NEES, errors, two-sigma bounds, innovations and S, to 1e-9; and the live demo's
compute_coop_demo, which runs them, gives what filterpy's run gives."""

import warnings
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers.coop import CoopParams, run_filter, simulate
from kfcal_helpers.coop.demos import compute_coop_demo
from kfcal_helpers.coop.fast import FastResult, run_fast, run_filter_fast
from kfcal_helpers.coop.filters import FilterSetup, SigmaPoints
from kfcal_helpers.coop.simulation import simulate_measurements, simulate_truth

TOL = {"rtol": 1e-9, "atol": 1e-9}


@pytest.fixture(scope="module")
def log():
    """The demo's seeded 1001-sample log."""
    return simulate().log()


def _same(fast, ref, truth):
    assert isinstance(fast, FastResult) and fast.measurements == ref.measurements
    assert fast.x.shape == ref.x.shape and fast.P.shape == ref.P.shape
    np.testing.assert_allclose(fast.t, ref.t, rtol=0, atol=0)
    np.testing.assert_allclose(fast.x, ref.x, **TOL)
    np.testing.assert_allclose(fast.P, ref.P, **TOL)
    np.testing.assert_allclose(fast.nis, ref.nis, **TOL)  # NaN exactly where filterpy's is NaN
    np.testing.assert_allclose(fast.nees, ref.nees, **TOL)
    np.testing.assert_allclose(fast.errors(truth), ref.errors(truth), **TOL)
    np.testing.assert_allclose(fast.sigma2, ref.sigma2, **TOL)
    np.testing.assert_allclose(fast.y, ref.y, **TOL)  # NaN in the rows not used
    np.testing.assert_allclose(fast.S, ref.S, **TOL)
    assert np.isfinite(fast.nis).sum() == np.isfinite(ref.nis).sum() > 0


#: Q scales across the demo's slider (10^-2 .. 10^2) with measurement subsets (None: all five)
CASES = [(1.0, None), (0.01, (1, 2, 3, 4)), (0.1, (0, 1, 2)), (10 ** 0.4, (0, 2, 3, 4)), (10 ** 0.5, (3, 4)),
         (10.0, (0, 2)), (100.0, (0, 2)), (100.0, None)]


@pytest.mark.parametrize("filter", ["ekf", "ukf"])
@pytest.mark.parametrize("q_scale, measurements", CASES, ids=[f"q{q:.3g}-{m or 'all'}" for q, m in CASES])
def test_fast_equals_filterpy_on_the_demo_log(log, filter, q_scale, measurements):
    p = log.params()
    kw = {"Q": q_scale * p.Qtrue, "measurements": measurements, "truth": log.truth}
    _same(run_filter_fast(filter, log.y, p, **kw), run_filter(filter, log.y, p, **kw), log.truth)


@pytest.mark.parametrize("filter", ["ekf", "ukf"])
def test_fast_equals_filterpy_with_other_settings_and_a_first_measurement(filter):
    """A measurement at t_0, another Q, R, x0, P0 and noise model; the UKF with other sigma points."""
    p = replace(CoopParams(), duration=10.0, noise_model="identity")
    rng = np.random.default_rng(12)
    truth = simulate_truth(p, rng, n_runs=1)[0]
    y = simulate_measurements(truth[None], p, rng, first=True)[0]
    settings = {"Q": 3.0 * p.Qtrue, "R": np.diag([0.03, 50.0, 0.05, 30.0, 40.0]), "P0": 2.0 * p.P0,
                "x0": p.x0 + np.array([0.5, -0.5, 0.05, 1.0, 0.0, -0.05])}
    if filter == "ukf":
        settings["points"] = SigmaPoints(alpha=0.5, beta=2.0, kappa=1.0)
    setup = FilterSetup.build(filter, p, **settings)
    fast = run_fast(y, setup, truth)
    assert np.isfinite(fast.nis[0])
    _same(fast, run_filter(filter, y, p, truth=truth, **settings), truth)


def test_one_range_and_a_large_q_amplify_rounding_in_any_ukf(log):
    """With the range alone and Q = 100 Qtrue the UKF is so poorly determined that it amplifies rounding:
    filterpy's and the batched UKF (kfcal_helpers.coop.batch, the same equations) part by ~1e-3 m by the
    end of the log, and so do filterpy's and the lean one.  They agree to 1e-9 for the first 40 s, and
    stay within 1e-3 of the filter's own sigma throughout: rounding that grows, not another filter.
    (Worse at Q = 100 Qtrue with the bearing UAV->UGV and the GPS north: heading sigmas of 1.25 rad put
    the sigma points' heading offsets near pi, where the wraps jump, and filterpy's, the batched and the
    lean UKF part by metres after 35 s -- any two roundings do.  Those settings are not compared here.)"""
    p = log.params()
    kw = {"Q": 100.0 * p.Qtrue, "measurements": (1,), "truth": log.truth}
    fast, ref = run_filter_fast("ukf", log.y, p, **kw), run_filter("ukf", log.y, p, **kw)
    np.testing.assert_allclose(fast.x[:401], ref.x[:401], **TOL)
    np.testing.assert_allclose(fast.P[:401], ref.P[:401], **TOL)
    assert np.all(np.abs(fast.x - ref.x) < 1e-3 * np.sqrt(np.einsum("kii->ki", ref.P)))


def test_fast_ukf_equals_filterpy_when_the_headings_are_lost():
    """Heading variances so large (4 rad^2 at t_0) that the sigma points' heading offsets exceed pi: the
    lean UKF's general wrap paths (the residuals of the arcs and of the sigma points), GPS only, a
    measurement at t_0, a log thinned to 1 Hz."""
    p = replace(CoopParams(), duration=30.0)
    rng = np.random.default_rng(5)
    truth = simulate_truth(p, rng, n_runs=1)[0]
    y = simulate_measurements(truth[None], p, rng, first=True)[0]
    y[1:][np.arange(1, y.shape[0]) % 10 != 0] = np.nan
    settings = {"P0": np.diag([1.0, 1.0, 4.0, 1.0, 1.0, 4.0]), "measurements": (3, 4), "Q": 30.0 * p.Qtrue}
    ref = run_filter("ukf", y, p, truth=truth, **settings)
    assert 6 * ref.P_prior[0, 2, 2] > np.pi ** 2 and np.isfinite(ref.nis[0])  # (n + lambda) P0: offsets > pi
    assert np.isnan(ref.nis[1:10]).all() and np.isfinite(ref.nis[10])
    _same(run_filter_fast("ukf", y, p, truth=truth, **settings), ref, truth)


def test_fast_ekf_without_wrapped_innovations_is_filterpys_mistake_too(log):
    p = log.params()
    kw = {"wrap_innovations": False, "measurements": (0, 1, 2), "truth": log.truth}
    ref = run_filter("ekf", log.y, p, **kw)
    assert np.nanmax(np.abs(ref.y[:, 0])) > np.pi  # the unwrapped bearing innovations jump by 2 pi
    _same(run_filter_fast("ekf", log.y, p, **kw), ref, log.truth)


@pytest.mark.parametrize("filter", ["ekf", "ukf"])
def test_compute_coop_demo_is_filterpys_run(log, filter):
    """What the demo draws (errors, bounds, P, NIS, its average and NEES) is filterpy's run, to 1e-9."""
    p = log.params()
    for q, sub in [(None, None), (0.05, (0, 1, 2)), (20.0, (1, 3, 4))]:
        d = compute_coop_demo(log, filter, q, measurements=sub)
        ref = run_filter(filter, log.y, p, Q=d.q_scale * p.Qtrue, truth=log.truth, measurements=sub)
        np.testing.assert_allclose(d.errors, ref.errors(log.truth), **TOL)
        np.testing.assert_allclose(d.sigma2, ref.sigma2, **TOL)
        np.testing.assert_allclose(d.P, ref.P, **TOL)
        np.testing.assert_allclose(d.nis, ref.nis, **TOL)
        assert d.nis_mean == pytest.approx(ref.time_average_nis(), rel=1e-9)
        assert d.nees_mean == pytest.approx(float(ref.nees.mean()), rel=1e-9)
        assert d.measurements == ref.measurements and d.n_nis == 1000
        K = d.n_nis
        m = len(ref.measurements)
        assert d.nis_bounds == pytest.approx(tuple(stats.chi2.ppf([0.025, 0.975], m * K) / K), rel=1e-12)


def test_fast_stores_symmetric_covariances_and_nan_outside_the_rows_used(log):
    r = run_filter_fast("ukf", log.y, log.params(), measurements=(1, 3, 4))
    assert np.array_equal(r.P, np.swapaxes(r.P, 1, 2))
    assert np.isnan(r.y[:, [0, 2]]).all() and np.isfinite(r.y[1:, [1, 3, 4]]).all()
    assert np.isnan(r.S[1:, 0]).all() and np.isfinite(r.S[1:][:, [1, 3, 4]][:, :, [1, 3, 4]]).all()
    assert r.nees is None and np.isnan(r.nis[0])


@pytest.mark.parametrize("call, name", [
    (lambda y: run_filter_fast("lkf", y), "filter"),
    (lambda y: run_filter_fast("ekf", y[:, :4]), "y"),
    (lambda y: run_filter_fast("ukf", np.where(np.arange(5) == 1, np.nan, y)), "y"),
    (lambda y: run_filter_fast("ekf", y * np.where(np.arange(5) == 3, 1e6, 1.0)), "y values must be at most"),
    (lambda y: run_filter_fast("ekf", y, bogus=1.0), "bogus"),
    (lambda y: run_filter_fast("ekf", y, measurements=(5,)), "measurements"),
    (lambda y: run_filter_fast("ukf", y, truth=np.zeros((3, 6))), "truth"),
    (lambda y: run_fast(y, FilterSetup("ekf")), None),
    (lambda y: run_fast(y, "ekf"), "setup"),
    (lambda y: run_fast(y, FilterSetup("lkf")), "filter"),
])
def test_fast_validates_its_arguments(log, call, name):
    if name is None:  # the valid call, for contrast
        assert call(log.y).x.shape == (log.y.shape[0], 6)
        return
    with pytest.raises(ValueError, match=name):
        call(log.y)


@pytest.mark.parametrize("filter, settings", [("ekf", {"P0": 1e300 * np.eye(6)}), ("ekf", {"P0": 1e308 * np.eye(6)}),
                                              ("ukf", {"Q": 1e308 * np.eye(6)}), ("ukf", {"P0": 1e308 * np.eye(6)})])
def test_a_diverging_fast_run_is_one_value_error_without_warnings(log, filter, settings):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy warning escapes
        with pytest.raises(ValueError, match="diverged"):
            run_filter_fast(filter, log.y, log.params(), **settings)
