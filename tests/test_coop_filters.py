"""LKF, EKF, UKF: shapes, predict-only steps, agreement, truth-model NEES/NIS, bad input."""

from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers.consistency import chi2_bounds
from kfcal_helpers.coop import (
    CoopParams,
    simulate,
    make_ekf,
    measurement_residual,
    run_filter,
    truth_model_test,
    fit_q_scale,
)
from kfcal_helpers.coop.filters import FilterSetup, SigmaPoints, run

P = CoopParams()
SHORT = replace(P, duration=20.0)


@pytest.fixture(scope="module")
def log():
    return simulate(SHORT, seed=11).log()


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_result_shapes_and_nan_rows(log, name):
    r = run_filter(name, log.y, SHORT, truth=log.truth)
    K = log.n_samples
    assert r.x.shape == (K, 6) and r.P.shape == (K, 6, 6)
    assert r.y.shape == (K, 5) and r.S.shape == (K, 5, 5) and r.nis.shape == (K,) and r.nees.shape == (K,)
    assert np.isnan(r.nis[0]) and np.all(np.isfinite(r.nis[1:]))
    assert np.all(np.isfinite(r.x)) and np.all(np.isfinite(r.nees))
    # the innovation is the wrapped difference of the measurement and the prediction
    assert np.allclose(r.y[1:], measurement_residual(log.y[1:], r.z_pred[1:]))


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_nan_column_is_predict_only(log, name):
    y = log.y.copy()
    y[50:80] = np.nan
    r = run_filter(name, y, SHORT)
    assert np.all(np.isnan(r.nis[50:80])) and np.all(np.isfinite(r.nis[80:]))
    # without updates the uncertainty grows step by step
    tr = np.trace(r.P[50:80], axis1=1, axis2=2)
    assert np.all(np.diff(tr) > 0)
    full = run_filter(name, log.y, SHORT)
    assert np.array_equal(r.x[:50], full.x[:50])


def test_ekf_predict_is_nonlinear():
    ekf = make_ekf(FilterSetup("ekf", P))
    ekf.predict()
    from kfcal_helpers.coop import step

    assert np.allclose(ekf.x[:, 0], step(P.x0, P.u0, P.dt, P.L), atol=1e-12)
    assert ekf.x.shape == (6, 1)


def test_filters_agree_near_the_nominal():
    """With tiny noise everything stays linear: LKF, EKF and UKF give the same estimates."""
    quiet = replace(SHORT, Qtrue=1e-8 * np.eye(6), P0=1e-6 * np.eye(6))
    lg = simulate(quiet, seed=3).log()
    xs = [run_filter(n, lg.y, quiet, Q=quiet.Qtrue).x for n in ("lkf", "ekf", "ukf")]
    assert np.abs(xs[0] - xs[1]).max() < 1e-3 and np.abs(xs[1] - xs[2]).max() < 1e-3


def test_unwrapped_innovation_breaks_nis(log):
    """Wrapped innovations keep the NIS near 5; the raw difference across +-pi does not."""
    r = run_filter("ekf", log.y, SHORT)
    raw = log.y[1:] - r.z_pred[1:]
    assert np.abs(raw[:, 0]).max() > np.pi  # the bearing crosses +-pi in this log
    assert np.abs(r.y[:, 0][1:]).max() < np.pi


@pytest.mark.parametrize("name", ["ekf", "ukf"])
def test_truth_model_nees_nis_inside_bounds(name):
    """Short seeded Monte Carlo: the tuned filters are consistent at most steps."""
    mc = truth_model_test(replace(P, duration=15.0), 12, 5, filter=name, workers=1)
    assert mc.nees_bounds == chi2_bounds(6, 12, 0.05) and mc.nis_bounds == chi2_bounds(5, 12, 0.05)
    assert mc.nees.shape == (12, 151) and mc.nis.shape == (12, 151)
    assert mc.nees_inside_fraction > 0.8
    assert mc.nis_inside_fraction > 0.8


def test_lkf_truth_model_consistent_near_the_nominal():
    """The LKF is consistent while the truth stays near the nominal (small process noise, small initial
    spread, short run): all three checks pass.  (With P0 unchanged, a heading spread of 0.1 rad, its
    NEES fails the simultaneous band for about half of the seeds at 50 runs: the linearization error.)"""
    near = replace(P, duration=10.0, Qtrue=0.01 * P.Qtrue, P0=0.01 * P.P0)
    mc = truth_model_test(near, 50, 5, filter="lkf", workers=1)
    assert all(c.passed for c in mc.checks().values())
    assert mc.nees_inside_fraction > 0.8 and mc.nis_inside_fraction > 0.8


def test_lkf_truth_model_fails_far_from_the_nominal():
    """Over the full 100 s the headings drift from the nominal and the LKF's NEES leaves its bounds."""
    mc = truth_model_test(P, 12, 5, filter="lkf", workers=1)
    assert mc.nees_mean[-50:].min() > mc.nees_bounds[1]


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_filters_use_omega(name):
    """Every filter's per-step process noise is Omega Q Omega^T: with Omega = dt I a predict-only step from
    P = 0 (no measurement) gives dt^2 Q; with the "identity" variant Q itself."""
    y = np.full((2, 5), np.nan)
    Q = np.diag([1.0, 2.0, 0.5, 3.0, 4.0, 0.25])
    for model, factor in (("dt", P.dt ** 2), ("identity", 1.0)):
        pp = replace(P, noise_model=model, duration=P.dt, u0=np.zeros(4))  # standing still: F = I
        r = run_filter(name, y, pp, Q=Q, P0=1e-12 * np.eye(6))
        assert np.allclose(r.P[1], factor * Q + 1e-12 * np.eye(6), rtol=1e-6, atol=1e-12)


def test_robust_sqrt():
    """Symmetrized Cholesky (upper factor) of a P, with a small jitter when rounding made it indefinite."""
    from kfcal_helpers.coop.filters import robust_sqrt

    A = np.random.default_rng(0).standard_normal((6, 6))
    M = A @ A.T + np.eye(6)
    U = robust_sqrt(M + 1e-9 * np.triu(np.ones((6, 6)), 1))  # slightly asymmetric
    assert np.allclose(U, np.triu(U)) and np.allclose(U.T @ U, M, atol=1e-8)
    lam, V = np.linalg.eigh(M)
    lam[0] = -1e-13 * lam.sum()  # one eigenvalue slightly negative, as rounding can leave it
    semi = (V * lam) @ V.T
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(semi)
    U = robust_sqrt(semi)
    assert np.allclose(U.T @ U, semi, atol=1e-8 * np.trace(M))
    with pytest.raises(ValueError, match="P: the UKF covariance is not positive definite"):
        robust_sqrt(-np.eye(6))
    with pytest.raises(ValueError, match="non-finite"):
        robust_sqrt(np.full((6, 6), np.nan))


def test_monte_carlo_does_not_depend_on_workers():
    pp = replace(P, duration=3.0)
    a = truth_model_test(pp, 4, 2, filter="ekf", workers=1)
    b = truth_model_test(pp, 4, 2, filter="ekf", workers=2)
    assert np.allclose(a.nees, b.nees) and np.allclose(a.nis, b.nis, equal_nan=True)


def test_fewer_measurements_grow_the_covariance(log):
    full = run_filter("ekf", log.y, SHORT)
    sparse = run_filter("ekf", log.every(20).y, SHORT)
    assert np.trace(sparse.P[-2]) > np.trace(full.P[-2])
    assert np.isfinite(sparse.nis).sum() == len(range(20, log.n_samples, 20))


def test_fit_q_scale_maximum_likelihood():
    """On a generated log (Q = Qtrue) the likelihood over the ladder peaks at the truth's scale 1 and falls
    on both sides; the scales inside the NIS bounds are reported apart from the fit."""
    lg = simulate(P, seed=21).log()
    fit = fit_q_scale("ekf", lg.y, [0.01, 0.1, 1.0, 10.0, 100.0], P)
    assert fit.best == 1.0
    ll = fit.log_likelihood
    assert ll[0] < ll[1] < ll[2] > ll[3] > ll[4]
    lo, hi = fit.nis_bounds
    assert set(fit.inside) == {s for s, v in zip(fit.scales, fit.nis_averages) if lo <= v <= hi}
    with pytest.raises(ValueError, match="scales"):
        fit_q_scale("ekf", lg.y, [], P)


@pytest.mark.parametrize("kwargs, match", [
    ({"Q": np.diag([1.0, 1, 1, 1, 1, -1])}, "Q must be positive definite"),
    ({"Q": np.eye(6) + np.eye(6, k=1)}, "Q must be symmetric"),
    ({"R": np.eye(4)}, "R must be a 5x5"),
    ({"R": np.eye(5) + 0.5 * np.eye(5, k=1)}, "R must be symmetric"),
    ({"P0": np.zeros((6, 6))}, "P0 must be positive definite"),
    ({"x0": np.zeros(3)}, "x0 must"),
])
def test_filter_bad_input(log, kwargs, match):
    with pytest.raises(ValueError, match=match):
        run_filter("ekf", log.y, SHORT, **kwargs)


def test_filter_bad_measurements(log):
    with pytest.raises(ValueError, match="y must have shape"):
        run_filter("lkf", log.y[:, :4], SHORT)
    y = log.y.copy()
    y[5, 1] = np.nan
    with pytest.raises(ValueError, match="y rows must be all finite or all NaN"):
        run_filter("ukf", y, SHORT)
    with pytest.raises(ValueError, match="filter must be one of"):
        run_filter("pf", log.y, SHORT)
    with pytest.raises(ValueError, match="alpha must"):
        run_filter("ukf", log.y, SHORT, points=SigmaPoints(alpha=0.0))
    with pytest.raises(ValueError, match="points must be a SigmaPoints"):
        run_filter("ukf", log.y, SHORT, points={"alpha": 0.5})
    with pytest.raises(ValueError, match="n_runs must"):
        truth_model_test(P, 0)
    with pytest.raises(ValueError, match="alpha must be a number in"):
        truth_model_test(P, 2, alpha=1.5)
    with pytest.raises(ValueError, match="setup must be a FilterSetup"):
        run(log.y, {"filter": "ekf"})


def test_same_position_in_filter():
    """An estimate where both vehicles coincide has no measurement Jacobian: ValueError, not NaN."""
    y = np.full((3, 5), np.nan)
    y[1] = [0.0, 10.0, 0.0, 10.0, 0.0]
    with pytest.raises(ValueError, match="x: the two vehicles are at the same position"):
        run_filter("ekf", y, replace(P, u0=np.zeros(4)), x0=np.array([10.0, 0, 0, 10.0, 0, 0]), P0=np.eye(6))
    same = replace(P, x0=np.array([10.0, 0, 0, 10.0, 0, 0]), u0=np.zeros(4))
    with pytest.raises(ValueError, match="x: the two vehicles are at the same position"):
        run_filter("lkf", y, same)


def test_truth_model_draws_and_median_run():
    """truth_model_draws draws exactly the truth-model test's data: re-running the median run by
    time-averaged NEES with run_filter (filterpy) reproduces its NEES."""
    from kfcal_helpers.coop import truth_model_draws

    pp = replace(P, duration=3.0)
    mc = truth_model_test(pp, 5, 4, filter="ekf", workers=1, every=2)
    sim = truth_model_draws(pp, 5, 4, every=2)
    truth, y = sim.truth, sim.y
    assert sim.n_runs == 5 and mc.n_runs == 5
    i = mc.median_run()
    avg = mc.nees.mean(axis=1)
    assert np.sum(avg < avg[i]) == 2 and np.sum(avg > avg[i]) == 2
    r = run_filter("ekf", y[i], pp, truth=truth[i])
    assert np.allclose(r.nees, mc.nees[i], rtol=1e-9, atol=1e-9) and np.all(np.isnan(y[:, 1::2]))
    assert np.allclose(r.nis, mc.nis[i], rtol=1e-9, atol=1e-9, equal_nan=True)
    assert np.allclose(r.errors(truth[i]), mc.errors[i], rtol=1e-9, atol=1e-9)


def test_lkf_predicted_bearings_are_wrapped(log):
    r = run_filter("lkf", log.y, SHORT)
    zb = r.z_pred[1:, [0, 2]]
    assert np.all(zb > -np.pi) and np.all(zb <= np.pi)


def test_plot_runs_consistency():
    """Each run's points, the average and both bounds on each panel, titles with the inside fraction."""
    from kfcal_helpers.coop.plots import plot_runs_consistency

    mc = truth_model_test(replace(P, duration=2.0), 3, 1, filter="ekf", workers=1)
    fig = plot_runs_consistency(mc)
    for ax, values in zip(fig.axes, (mc.nees, mc.nis)):
        assert len(ax.lines) == 4 and ax.get_yscale() == "log"
        assert ax.lines[0].get_xydata().shape[0] == np.isfinite(values).sum()
    assert "inside" in fig.axes[0].get_title()


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_result_prior_posterior_and_gain(log, name):
    """filterpy's names: x_prior/P_prior before and x_post/P_post after each update, K the gain:
    x_post - x_prior = K y (headings wrapped) and P_post <= P_prior; without a measurement post = prior."""
    from kfcal_helpers.coop import state_residual

    y = log.y.copy()
    y[30:40] = np.nan
    r = run_filter(name, y, SHORT)
    assert r.x is r.x_post and r.P is r.P_post and r.filter == name
    assert np.array_equal(r.x_prior[0], run_filter(name, y[:1], SHORT).x_prior[0])
    assert np.allclose(r.x_prior[0], SHORT.x0) and np.allclose(r.P_prior[0], SHORT.P0)
    has = np.isfinite(r.nis)
    gain_step = np.einsum("kij,kj->ki", r.K[has], r.y[has])
    assert np.allclose(state_residual(r.x_post[has], r.x_prior[has]), gain_step, atol=1e-9)
    assert np.all(np.isnan(r.K[~has])) and np.array_equal(r.x_post[~has], r.x_prior[~has])
    assert np.all(np.trace(r.P_post[has], axis1=1, axis2=2) < np.trace(r.P_prior[has], axis1=1, axis2=2))


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_setup_runners_equal_run_filter(log, name):
    """run_xkf(y, setup, truth) with a FilterSetup of a measurement model's subset equals run_filter's
    measurements= keyword; NaN in the components not used."""
    from kfcal_helpers.coop import MeasurementModel

    model = MeasurementModel(SHORT.Rtrue).subset((0, 2, 3))
    assert model.rows == (0, 2, 3) and model.angles == (0, 1) and model.dim == 3
    assert np.array_equal(model.R, SHORT.Rtrue[np.ix_([0, 2, 3], [0, 2, 3])])
    assert model.subset((1, 2)).rows == (2, 3) and model.subset([1]).angles == (0,)
    setup = FilterSetup(name, SHORT, measurement=model)
    a = run(log.y, setup, log.truth)
    b = run_filter(name, log.y, SHORT, measurements=(3, 0, 2), truth=log.truth)
    assert a.measurements == b.measurements == (0, 2, 3)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.nis, b.nis, equal_nan=True)
    assert np.all(np.isnan(a.y[:, [1, 4]])) and np.all(np.isnan(a.K[:, :, [1, 4]]))
    with pytest.raises(ValueError, match="idx must be a non-empty sequence"):
        model.subset((0, 3))
    with pytest.raises(ValueError, match="rows must be a sorted"):
        MeasurementModel(np.eye(2), (2, 0))
    with pytest.raises(ValueError, match="R must be a 2x2"):
        MeasurementModel(np.eye(3), (0, 2))


def test_state_descriptor():
    from kfcal_helpers.coop import STATE, StateDescriptor, state_mean, wrap_state

    x = np.array([1.0, 2.0, 3.5, 4.0, 5.0, -3.5])
    assert STATE.angles == (2, 5) and np.array_equal(STATE.wrap(x), wrap_state(x))
    assert np.allclose(STATE.residual(x, -x)[[2, 5]], [7 - 2 * np.pi, -7 + 2 * np.pi])
    pts = np.stack([x, x + 0.1])
    assert np.array_equal(STATE.mean(pts, [0.5, 0.5]), state_mean(pts, [0.5, 0.5]))
    with pytest.raises(ValueError, match="angles must be sorted"):
        StateDescriptor(3, (2, 0))


def test_monte_carlo_of_a_subset_has_its_nis_dimension():
    """With 3 measurements the NIS bounds and the nis check use 3 degrees of freedom."""
    pp = replace(P, duration=2.0)
    mc = truth_model_test(pp, 4, 1, filter="ekf", workers=1, measurements=(0, 1, 2))
    assert mc.measurements == (0, 1, 2) and mc.nis_bounds == chi2_bounds(3, 4)
    assert np.all(mc.checks()["nis"].expected == 3)
