"""Lecture demos (notebooks 17, 18): compute functions against the filters by other routes,
the filters' ``measurements=`` subsets, the figures and controls, and the exercise checks."""

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from matplotlib.figure import Figure
from scipy import stats

from kfcal_helpers.calibration import (CalibrationParams, batch_filter, covariance_sequence, error_state_model,
                                       outage_mask, run_filterpy, simulate)
from kfcal_helpers.coop import (TUNED_Q_SCALE, CoopParams, generate_log, jacobian_C, measure, measurement_residual,
                                nominal_trajectory, run_filter, state_residual)
from kfcal_helpers.demos import (LIVE_FIGSIZE, MEASUREMENT_NAMES, CalibrationDemoFigure, CoopDemoFigure, LiveDemo,
                                 calibration_controls, compute_calibration_demo, compute_coop_demo, coop_controls,
                                 describe_controls, draw_calibration_demo, draw_coop_demo, estimate_between_fixes,
                                 figure_png, filter_errors_at_fixes, noise_of_simulation, sample_noise_at_fixes,
                                 valid_gps_rates)
from kfcal_helpers.exercises import (check_demo_first_fix_sigma, check_demo_lost_directions, check_demo_ratio_band,
                                     check_demo_subset_nis_bounds)
from kfcal_helpers.exercises.demos import HINTS

P = CalibrationParams()
SHORT = CoopParams().replace(duration=20.0)


# ---------------------------------------------------------------------------
# calibration demo
def test_valid_gps_rates_divide_the_imu_rate():
    assert valid_gps_rates() == tuple(float(r) for r in range(1, 26) if 200 % r == 0)
    for r in valid_gps_rates(max_rate=200.0):
        assert CalibrationParams(gps_rate=r).steps_per_fix * r == 200
    assert valid_gps_rates(100.0, 100.0)[-1] == 100.0
    with pytest.raises(ValueError, match="imu_rate"):
        valid_gps_rates(200.5)


def test_demo_sigma_is_the_filters_and_its_realization_is_filterpys():
    demo = compute_calibration_demo(gps_rate=4.0, W=1e-3, gps_pos_var=2.0, bias_var=0.02, outage=(9.0, 14.0), seed=3)
    p = P.replace(gps_rate=4.0, W=1e-3, gps_pos_var=2.0, bias_var=0.02)
    missing = outage_mask(p, [(9.0, 14.0)])
    assert np.array_equal(demo.missing, missing)
    P_seq, P_prior, _, _ = covariance_sequence(p, missing)
    assert np.allclose(demo.sigma, np.sqrt(np.einsum("jaa->ja", P_seq)), rtol=1e-9, atol=0)
    assert np.allclose(demo.P_post, P_seq[p.fix_indices], rtol=1e-9, atol=0)
    assert np.allclose(demo.P_prior, P_prior, rtol=1e-9, atol=0)
    # the drawn realization: the demo's first seeded stream, filtered by filterpy instead
    rng = np.random.default_rng(np.random.SeedSequence(3).spawn(2)[0])
    sim = simulate(p, 1, rng, missing_fixes=missing)
    fp = run_filterpy(p, sim.dz[0])
    assert np.allclose(demo.error, sim.dx[0] - fp.x, rtol=0, atol=1e-8)


def test_estimate_between_fixes_is_batch_full_rate():
    sim = simulate(P, 4, np.random.default_rng(0))
    full = batch_filter(P, sim.dz, full_rate=True)
    assert np.allclose(estimate_between_fixes(P, full.x_post), full.x, rtol=0, atol=1e-9)
    assert np.allclose(estimate_between_fixes(P, full.x_post[2]), full.x[2], rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="x_post"):
        estimate_between_fixes(P, np.zeros((10, 3)))


def test_error_recursion_is_batch_filter_on_the_same_draws():
    p = P.replace(gps_rate=4.0)
    missing = outage_mask(p, [(5.0, 9.0)])
    sim = simulate(p, 6, np.random.default_rng(1), missing_fixes=missing)
    cov = covariance_sequence(p, missing)
    fr = batch_filter(p, sim.dz, full_rate=False, covariances=cov)
    e_prior, e_post = filter_errors_at_fixes(p, cov, *noise_of_simulation(sim))
    assert np.allclose(e_prior, sim.dx_at_fixes - fr.x_prior, rtol=0, atol=1e-9)
    assert np.allclose(e_post, sim.dx_at_fixes - fr.x_post, rtol=0, atol=1e-9)
    e0, w, eta = noise_of_simulation(sim)
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


@pytest.mark.parametrize("ensemble", ["fixes", "simulate"])
def test_ensemble_sigma_within_its_chi2_band(ensemble):
    demo = compute_calibration_demo(outage=(10.0, 16.0), n_runs=300, seed=11, ensemble=ensemble)
    N = demo.n_runs
    assert demo.ratio_band == pytest.approx(np.sqrt(stats.chi2.ppf([0.025, 0.975], N - 1) / (N - 1)), rel=1e-12)
    # simultaneous (Bonferroni) band over all fixes and states: a right P passes with probability >= 0.95
    level = 0.05 / demo.ratio.size
    lo, hi = np.sqrt(stats.chi2.ppf([level / 2, 1 - level / 2], N - 1) / (N - 1))
    assert np.all((demo.ratio > lo) & (demo.ratio < hi))
    z = stats.norm.ppf(1 - level / 2)
    assert np.all(np.abs(demo.ens_mean) < z * demo.ens_std / np.sqrt(N))
    assert 0.8 < demo.inside_fraction <= 1.0


def test_outage_grows_sigma_and_the_first_fix_back_cuts_it():
    demo = compute_calibration_demo(outage=(12.0, 18.0))
    clear = compute_calibration_demo()
    j0, j1 = int(12.0 * P.imu_rate) - P.steps_per_fix, int(18.0 * P.imu_rate)  # last fix before, first fix back
    s = demo.sigma
    assert np.all(np.diff(s[j0:j1, 0]) > 0) and np.all(np.diff(s[j0:j1, 1]) > 0)
    assert np.allclose(s[j0:j1, 2], s[j0, 2], rtol=1e-12)  # nothing drives the bias in the gap
    assert s[j1, 0] < s[j1 - 1, 0] and s[j1, 1] < s[j1 - 1, 1]
    assert np.all(s[j0 + 1:j1 + 1] >= clear.sigma[j0 + 1:j1 + 1] - 1e-15)
    assert s[j1 - 1, 0] > 1.2 * clear.sigma[j1 - 1, 0]


def test_slider_effects_go_the_stated_way():
    slow, fast = compute_calibration_demo(gps_rate=1.0), compute_calibration_demo(gps_rate=25.0)
    saw = [np.sqrt(d.P_prior[:, 1, 1] / d.P_post[:, 1, 1])[np.searchsorted(d.t_gps, 2.0 - 1e-9)] for d in (slow, fast)]
    assert saw[0] > saw[1] > 1.0
    low_w, high_w = compute_calibration_demo(W=4e-5), compute_calibration_demo(W=4e-3)
    assert high_w.sigma[-1, 2] > low_w.sigma[-1, 2]
    assert np.all(np.diff(high_w.sigma_fix[:, 2]) < 0)  # still shrinking: no floor


@pytest.mark.parametrize("kwargs, name", [
    ({"gps_rate": 3.0}, "gps_rate"), ({"W": -1.0}, "W"), ({"gps_pos_var": 0.0}, "gps_pos_var"),
    ({"bias_var": np.nan}, "bias_var"), ({"outage": (20.0, 10.0)}, "outage"), ({"outage": (25.0, 40.0)}, "outage"),
    ({"outage": 5.0}, "outage"), ({"n_runs": 1}, "n_runs"), ({"seed": -1}, "seed"), ({"ensemble": "mc"}, "ensemble"),
    ({"alpha": 1.5}, "alpha"), ({"base": "defaults"}, "base"),
])
def test_compute_calibration_demo_validates(kwargs, name):
    with pytest.raises(ValueError, match=name):
        compute_calibration_demo(**kwargs)


def test_calibration_figure_updates_in_place():
    view = CalibrationDemoFigure(Figure(figsize=(9, 7.2)))
    assert len(view.fig.axes) == 3
    lines = [tuple(ax.lines) for ax in view.axes]
    view.update(compute_calibration_demo(outage=(12.0, 18.0), n_runs=50))
    view.update(compute_calibration_demo(gps_rate=2.0, outage=(5.0, 8.0), n_runs=50))
    assert [tuple(ax.lines) for ax in view.axes] == lines  # the same artists, new data
    assert len(view.spans) == 3 and len(view.axes[0].patches) == 1
    assert view.axes[0].lines[0].get_xdata().size == P.n_imu
    assert "GPS 2 Hz" in view.axes[0].get_title() and "outage 5–8 s" in view.axes[0].get_title()
    for ax in view.axes:
        assert "[" in ax.get_ylabel()
    assert "[s]" in view.axes[-1].get_xlabel()
    png = figure_png(view.fig)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    fig = draw_calibration_demo(compute_calibration_demo(n_runs=20))
    assert len(fig.axes) == 3 and "GPS 5 Hz" in fig.axes[0].get_title()
    with pytest.raises(ValueError, match="demo"):
        view.update("demo")
    with pytest.raises(ValueError, match="figure"):
        CalibrationDemoFigure(figure="fig")


def test_calibration_controls_match_the_compute_function():
    c = calibration_controls()
    assert set(c) == {"gps_rate", "W", "gps_pos_sigma", "bias_sigma", "outage_on", "outage"}
    assert tuple(c["gps_rate"].options) == valid_gps_rates()
    v = {k: w.value for k, w in c.items()}
    assert (v["gps_rate"], v["W"], v["gps_pos_sigma"] ** 2, v["bias_sigma"] ** 2) == (P.gps_rate, P.W, P.gps_pos_var,
                                                                                      pytest.approx(P.bias_var))


# ---------------------------------------------------------------------------
# filters: measurements=
@pytest.fixture(scope="module")
def short_log():
    return generate_log(SHORT, seed=7)


@pytest.mark.parametrize("bad", [[], (5,), (0, 0), (-1, 2), ("a",), (1.0, 2), 1.5, "01", (True,)])
@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_measurements_validated(short_log, name, bad):
    with pytest.raises(ValueError, match="measurements"):
        run_filter(name, short_log.y, SHORT, measurements=bad)


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_all_five_in_any_order_is_the_default(short_log, name):
    a = run_filter(name, short_log.y, SHORT)
    b = run_filter(name, short_log.y, SHORT, measurements=[4, 3, 2, 1, 0])
    assert a.measurements == b.measurements == (0, 1, 2, 3, 4)
    for f in ("x", "P", "innovations", "S", "nis"):
        assert np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
@pytest.mark.parametrize("subset", [(0, 1, 2), (1, 3, 4), (2, 4)])
def test_subset_is_an_infinite_variance_on_the_rest(short_log, name, subset):
    """Dropping measurements = giving them a huge variance (and no correlation)."""
    r = run_filter(name, short_log.y, SHORT, measurements=subset, truth=short_log.truth)
    R = SHORT.Rtrue.copy()
    rest = [i for i in range(5) if i not in subset]
    R[rest, rest] = 1e14
    big = run_filter(name, short_log.y, SHORT, R=R)
    assert np.allclose(r.x, big.x, rtol=0, atol=1e-5)
    assert np.allclose(r.P, big.P, rtol=1e-6, atol=1e-9)
    assert r.measurements == subset
    rows = list(subset)
    assert np.all(np.isnan(r.innovations[1:, rest])) and np.all(np.isfinite(r.innovations[1:, rows]))
    assert np.allclose(r.innovations[1:, rows], big.innovations[1:, rows], rtol=0, atol=1e-6)
    # the NIS uses only the rows used: nu_s^T S_s^-1 nu_s, len(subset) degrees of freedom
    nu, S = r.innovations[1:, rows], r.S[1:][:, rows][:, :, rows]
    assert np.allclose(r.nis[1:], [v @ np.linalg.solve(s, v) for v, s in zip(nu, S)], rtol=1e-9)
    assert np.allclose(r.innovations[1:, rows], measurement_residual(short_log.y[1:], r.z_pred[1:])[:, rows])


def test_subset_nis_is_chi2_with_the_subset_dimension():
    """Five seeded truth-model logs, EKF with Q = Qtrue, bearings and range only: the averaged
    NIS of all updates lies in the 3-dimensional band, far from the 5-dimensional one."""
    values = np.concatenate([run_filter("ekf", generate_log(SHORT, seed=s).y, SHORT, Q=SHORT.Qtrue,
                                        measurements=(0, 1, 2)).nis[1:] for s in range(5)])
    K = values.size
    lo, hi = stats.chi2.ppf([0.005, 0.995], 3 * K) / K
    assert lo < values.mean() < hi
    assert values.mean() < stats.chi2.ppf(0.005, 5 * K) / K


# ---------------------------------------------------------------------------
# coop demo
@pytest.fixture(scope="module")
def log():
    return generate_log()


def test_coop_demo_numbers(log):
    d = compute_coop_demo(log, "ekf", q_scale=2.0, measurements=[2, 0, 1])
    r = run_filter("ekf", log.y, log.params(), Q=2.0 * log.params().Qtrue, measurements=(0, 1, 2))
    assert d.measurements == (0, 1, 2) and d.nis_dim == 3 and d.q_scale == 2.0
    assert np.allclose(d.errors, state_residual(log.truth, r.x))
    assert np.allclose(d.sigma2, 2 * np.sqrt(np.einsum("kii->ki", r.P)))
    K = int(np.isfinite(log.y[:, 0]).sum())
    assert d.n_nis == K == 1000
    assert d.nis_mean == pytest.approx(np.nanmean(r.nis), rel=1e-12)
    assert d.nis_bounds == pytest.approx(tuple(stats.chi2.ppf([0.025, 0.975], 3 * K) / K), rel=1e-12)
    assert d.nis_inside == (d.nis_bounds[0] <= d.nis_mean <= d.nis_bounds[1])
    assert "3 measurements" in d.summary() and MEASUREMENT_NAMES[1] in d.summary()
    full = compute_coop_demo(log, "ukf")
    assert full.q_scale == 1.0 and full.nis_dim == 5
    assert full.nis_bounds == pytest.approx(tuple(stats.chi2.ppf([0.025, 0.975], 5 * K) / K), rel=1e-12)


def test_losing_the_gps_grows_the_common_shift(log):
    v = np.array([1.0, 0, 0, 1.0, 0, 0])
    shift = {sub: 1 / np.sqrt(np.einsum("i,kij,j->k", v, np.linalg.inv(compute_coop_demo(log, "ekf", measurements=sub).P), v))
             for sub in [(0, 1, 2), (0, 2, 3, 4)]}
    # without the GPS nothing shrinks the common shift: it only grows (by the process noise dT^2 Qtrue per
    # step and the heading errors); with the GPS it shrinks below its initial value
    assert np.all(np.diff(shift[(0, 1, 2)]) >= -1e-9) and shift[(0, 1, 2)][-1] > 1.3 * shift[(0, 1, 2)][0]
    assert shift[(0, 2, 3, 4)][-1] < 0.8 * shift[(0, 2, 3, 4)][0] < shift[(0, 1, 2)][-1]


@pytest.mark.parametrize("kwargs, name", [({"filter": "lkf"}, "filter"), ({"q_scale": 0.0}, "q_scale"),
                                          ({"measurements": (7,)}, "measurements"), ({"alpha": 0.0}, "alpha")])
def test_compute_coop_demo_validates(log, kwargs, name):
    with pytest.raises(ValueError, match=name):
        compute_coop_demo(log, **kwargs)
    with pytest.raises(ValueError, match="log"):
        compute_coop_demo(log.y)


def test_coop_figure_and_controls(log):
    view = CoopDemoFigure(Figure(figsize=(11, 5.4)))
    lines = [tuple(ax.lines) for ax in view.axes.flat]
    view.update(compute_coop_demo(log, "ekf", measurements=(3, 4)))
    assert [tuple(ax.lines) for ax in view.axes.flat] == lines and len(lines) == 6
    assert "UAV GPS east" in view.fig.get_suptitle() and "2 dof" in view.fig.get_suptitle()
    assert all("[" in ax.get_ylabel() for ax in view.axes.flat)
    assert figure_png(view.fig)[:4] == b"\x89PNG"
    assert len(draw_coop_demo(compute_coop_demo(log)).axes) == 6
    c = coop_controls()
    assert set(c) == {"filter", "q_scale", "m0", "m1", "m2", "m3", "m4"}
    assert c["filter"].value == "ekf" and c["q_scale"].value == pytest.approx(TUNED_Q_SCALE["ekf"])
    assert [c[f"m{i}"].description for i in range(5)] == list(MEASUREMENT_NAMES)


# ---------------------------------------------------------------------------
# exercise checks
def _rejected(fb, exercise, key):
    return (not fb.correct) and fb.answered and fb.message == HINTS[exercise][key]


def test_check_17_1_first_fix_sigma():
    right = np.sqrt([1 / (1 / 100 + 1 / 9), 1 / (1 / 1 + 1 / 0.0016), 0.01])  # default M0, V with sigma_p = 3 m
    assert check_demo_first_fix_sigma(right).correct
    assert check_demo_first_fix_sigma(list(right)).correct
    demo = compute_calibration_demo(gps_pos_var=9.0, n_runs=10)
    assert np.allclose(demo.sigma[0], right, rtol=1e-12)  # what the slider shows
    wrong = {
        "gps_only": [3.0, 0.04, 0.1],
        "sigma_sum": [1 / (1 / 10 + 1 / 3), 1 / (1 + 1 / 0.04), 0.1],
        "variance": right**2,
        "variance_sum": [np.sqrt(109), np.sqrt(1.0016), 0.1],
        "prior": [10.0, 1.0, 0.1],
        "default_gps": np.sqrt([1 / (1 / 100 + 1), 1 / (1 + 1 / 0.0016), 0.01]),
        "bias": [right[0], right[1], 0.05],
    }
    for key, value in wrong.items():
        assert _rejected(check_demo_first_fix_sigma(value), "17.1", key), key
    assert not check_demo_first_fix_sigma(...).answered
    for bad in ("2.87", [1.0, 2.0], None):
        fb = check_demo_first_fix_sigma(bad)
        assert not fb.correct
    assert check_demo_first_fix_sigma(np.sqrt([1 / (1 / 100 + 1 / 4), 1 / (1 + 625), 0.01]), gps_pos_sigma=2.0).correct
    with pytest.raises(ValueError, match="gps_pos_sigma"):
        check_demo_first_fix_sigma(right, gps_pos_sigma=0.0)


def test_check_17_2_ratio_band():
    N = 200
    right = np.sqrt(stats.chi2.ppf([0.025, 0.975], N - 1) / (N - 1))
    assert check_demo_ratio_band(right).correct and check_demo_ratio_band(np.round(right, 5)).correct
    demo = compute_calibration_demo(n_runs=N)
    assert np.allclose(demo.ratio_band, right, rtol=1e-12)
    wrong = {
        "n_dof": np.sqrt(stats.chi2.ppf([0.025, 0.975], N) / N),
        "variance": stats.chi2.ppf([0.025, 0.975], N - 1) / (N - 1),
        "one_sided": np.sqrt(stats.chi2.ppf([0.05, 0.95], N - 1) / (N - 1)),
        "normal": 1 + np.array([-1, 1]) * 1.959964 / np.sqrt(2 * (N - 1)),
        "mean_band": 1 + np.array([-1, 1]) * 1.959964 / np.sqrt(N),
    }
    for key, value in wrong.items():
        assert _rejected(check_demo_ratio_band(value), "17.2", key), key
    assert not check_demo_ratio_band(...).answered and not check_demo_ratio_band([0.9]).correct
    with pytest.raises(ValueError, match="n_runs"):
        check_demo_ratio_band(right, n_runs=1)


def test_check_18_1_subset_nis_bounds():
    K, m = 1000, 3
    right = stats.chi2.ppf([0.025, 0.975], m * K) / K
    assert check_demo_subset_nis_bounds(right).correct
    wrong = {
        "dim5": stats.chi2.ppf([0.025, 0.975], 5 * K) / K,
        "count_nan": stats.chi2.ppf([0.025, 0.975], m * (K + 1)) / (K + 1),
        "not_divided": stats.chi2.ppf([0.025, 0.975], m * K),
        "one_sided": stats.chi2.ppf([0.05, 0.95], m * K) / K,
        "normal": m + np.array([-1, 1]) * 1.959964 * np.sqrt(2 * m / K),
    }
    for key, value in wrong.items():
        assert _rejected(check_demo_subset_nis_bounds(value), "18.1", key), key
    assert not check_demo_subset_nis_bounds(...).answered and not check_demo_subset_nis_bounds("bounds").correct
    with pytest.raises(ValueError, match="n_meas"):
        check_demo_subset_nis_bounds(right, n_meas=6)


def _lost_directions_independently(rows, window=10):
    """6 - rank by my own stacking (exact one-step Jacobian by finite differences) and an SVD gap,
    and the common translations and the rotation of the whole scene checked as null vectors."""
    p = CoopParams()
    x = nominal_trajectory(p, window)
    blocks, Phi, e = [], np.eye(6), 1e-6
    for k in range(window):
        blocks.append(jacobian_C(x[k])[rows] @ Phi)
        J = np.stack([measurement_free_diff(x[k], j, e, p) for j in range(6)], axis=1)
        Phi = J @ Phi
    O = np.vstack(blocks)
    sv = np.linalg.svd(O, compute_uv=False)
    lost = 6 - int(np.sum(sv > 1e-6 * sv[0]))
    shifts = np.array([[1.0, 0, 0, 1.0, 0, 0], [0, 1.0, 0, 0, 1.0, 0],
                       [-x[0, 1], x[0, 0], 1.0, -x[0, 4], x[0, 3], 1.0]])  # translations, rotation about 0
    return lost, np.abs(O @ shifts.T).max() / sv[0]


def measurement_free_diff(xk, j, e, p):
    """Central difference of the exact one-step map along state j (headings wrapped)."""
    from kfcal_helpers.coop import state_residual, step

    d = np.eye(6)[j] * e
    return state_residual(step(xk + d, p.u0, p.dT, p.L), step(xk - d, p.u0, p.dT, p.L)) / (2 * e)


def test_check_18_2_lost_directions():
    counts = []
    for rows in ([0, 2, 3, 4], [0, 1, 2], [1, 3, 4]):
        lost, null_residual = _lost_directions_independently(rows)
        counts.append(lost)
        if 3 not in rows:  # no GPS: both common shifts and the rotation change no measurement
            assert null_residual < 1e-8
    assert counts == [0, 3, 0]
    # a common shift and a rotation of the whole scene change no relative measurement of the nonlinear model
    x = nominal_trajectory(CoopParams(), 5)
    assert np.allclose(measure(x + [3.0, -2.0, 0, 3.0, -2.0, 0])[:, :3], measure(x)[:, :3], atol=1e-12)
    c, s_ = np.cos(0.3), np.sin(0.3)
    rot = x.copy()
    for i in (0, 3):
        rot[:, i], rot[:, i + 1] = c * x[:, i] - s_ * x[:, i + 1], s_ * x[:, i] + c * x[:, i + 1]
        rot[:, i + 2] = x[:, i + 2] + 0.3
    assert np.allclose(measurement_residual(measure(rot)[:, :3], measure(x)[:, :3]), 0, atol=1e-12)
    assert check_demo_lost_directions(counts).correct and check_demo_lost_directions(np.array(counts, float)).correct
    wrong = {"ranks": [6, 3, 6], "euler": [0, 2, 0], "no_gps_observable": [0, 0, 0],
             "no_range_lost": [1, 3, 0], "no_bearings_lost": [0, 3, 1]}
    for key, value in wrong.items():
        assert _rejected(check_demo_lost_directions(value), "18.2", key), key
    assert "whole number" in check_demo_lost_directions([0, 2.5, 0]).message
    assert not check_demo_lost_directions(...).answered and not check_demo_lost_directions([0, 2]).correct
    with pytest.raises(ValueError, match="window"):
        check_demo_lost_directions(counts, window=1)


# ---------------------------------------------------------------------------
# live demos: argument checks, layout, failures drawn as a one-line message
def test_draw_calibration_demo_rejects_a_negative_t_zoom():
    demo = compute_calibration_demo(n_runs=20)
    for bad in (-1, -0.5, float("nan"), "2"):
        with pytest.raises(ValueError, match="t_zoom"):
            draw_calibration_demo(demo, t_zoom=bad)
    assert len(draw_calibration_demo(demo, t_zoom=0.0).axes) == 3


def calibration_demo_for(gps_rate=5.0, W=4e-4, gps_pos_sigma=1.0, bias_sigma=0.1, outage_on=True,
                         outage=(12.0, 18.0)):
    """Notebook 17's mapping of the controls to compute_calibration_demo."""
    window = outage if outage_on and outage[0] < outage[1] else None
    return compute_calibration_demo(gps_rate=gps_rate, W=W, gps_pos_var=gps_pos_sigma**2, bias_var=bias_sigma**2,
                                    outage=window, n_runs=200, seed=17)


def coop_demo_for(log):
    """Notebook 18's mapping of the controls to compute_coop_demo, for ``log``."""
    def demo_for(filter="ekf", q_scale=1.5, m0=True, m1=True, m2=True, m3=True, m4=True):
        ticked = tuple(i for i, on in enumerate((m0, m1, m2, m3, m4)) if on)
        return compute_coop_demo(log, filter, q_scale, measurements=ticked) if ticked else None
    return demo_for


def _coop_live(log):
    return LiveDemo(coop_controls(), coop_demo_for(log), CoopDemoFigure(Figure(figsize=LIVE_FIGSIZE["coop"])),
                    empty="tick at least one measurement", hint="try a smaller Q / Qtrue")


def _png_size(png):
    from PIL import Image
    import io

    return Image.open(io.BytesIO(png)).size


def test_live_demo_shows_the_figure_and_follows_the_controls(log):
    live = _coop_live(log)
    assert not live.failed and "5 measurements" in live.line.value
    first = live.image.value
    assert _png_size(first) == tuple(round(s * live.view.fig.dpi) for s in LIVE_FIGSIZE["coop"])
    live.controls["m1"].value = False  # untick the range: the observer recomputes and redraws
    assert not live.failed and live.image.value != first
    assert "4 measurements" in live.line.value and "range" not in live.view.fig.get_suptitle().split("\n")[0]
    # the layout: controls in a column beside the image and the line under it
    import ipywidgets as w

    column, right = live.widget.children
    assert isinstance(live.widget, w.HBox) and list(column.children) == list(live.controls.values())
    assert list(right.children) == [live.image, live.line]


@pytest.mark.parametrize("error, says", [
    (np.linalg.LinAlgError("6-th leading minor of the array is not positive definite"),
     "its covariance is no longer positive definite (6-th leading minor"),
    (ValueError("Singular matrix"), "cannot compute these settings: Singular matrix"),
    (FloatingPointError("overflow encountered"), "cannot compute these settings: overflow encountered"),
    (RuntimeWarning("invalid value encountered in sqrt"), "(RuntimeWarning: invalid value encountered in sqrt)")])
def test_a_failing_filter_draws_a_one_line_message(log, monkeypatch, error, says):
    import warnings

    import kfcal_helpers.demos as demos

    live = _coop_live(log)
    good = live.image.value

    def fail(*args, **kwargs):
        if isinstance(error, Warning):
            warnings.warn(error)  # raised as an error inside a redraw, never shown
            return run_filter(*args, **kwargs)
        raise error

    monkeypatch.setattr(demos, "run_filter", fail)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning may escape the redraw
        live.controls["filter"].value = "ukf"
        live.controls["q_scale"].value = 10 ** 0.5
    assert live.failed
    line = live.line.value
    assert says in line
    assert "Traceback" not in line and "\n" not in line and "try a smaller Q / Qtrue" in line
    # the image: same size, no axes, the settings of the failed redraw as its title, one line of message
    fig = live.message_fig
    assert _png_size(live.image.value) == _png_size(good) and live.image.value != good
    message = [t.get_text() for t in fig.texts if t.get_text() != fig.get_suptitle()]
    assert not fig.axes and len(message) == 1 and "\n" not in message[0] and message[0] in line
    title = fig.get_suptitle()
    assert "filter UKF" in title and "Q / Qtrue 3.16" in title and "not drawn" in title
    assert all(name in title for name in MEASUREMENT_NAMES)
    # the next setting that works draws the filter again, under its own title
    monkeypatch.undo()
    live.controls["filter"].value = "ekf"
    assert not live.failed and live.view.fig.get_suptitle().startswith("EKF, Q = 3.16 Qtrue")


def test_non_finite_results_and_empty_subsets_draw_a_message(log, monkeypatch):
    import dataclasses

    live = _coop_live(log)
    real = live.compute

    def nan_errors(**values):
        d = real(**values)
        return dataclasses.replace(d, errors=np.full_like(d.errors, np.nan))

    live.compute = nan_errors
    live.refresh()
    assert live.failed and "not finite" in live.line.value
    live.compute = real
    for i in range(5):
        live.controls[f"m{i}"].value = False
    assert live.failed and "tick at least one measurement" in live.line.value
    assert "none ticked" in live.message_fig.get_suptitle()


def test_an_unexpected_error_is_one_line_too(log):
    live = _coop_live(log)

    def broken(**values):
        raise KeyError("x")

    live.compute = broken
    live.refresh()  # a live demo never shows a traceback
    assert live.failed and "unexpected error" in live.line.value and "KeyError" in live.line.value
    with pytest.raises(KeyError):
        live.render()  # ... but the render path itself does not hide programming errors


def test_live_demo_validates():
    with pytest.raises(ValueError, match="controls"):
        LiveDemo({}, calibration_demo_for, CalibrationDemoFigure(Figure()))
    with pytest.raises(ValueError, match="compute"):
        LiveDemo(calibration_controls(), None, CalibrationDemoFigure(Figure()))
    with pytest.raises(ValueError, match="view"):
        LiveDemo(calibration_controls(), calibration_demo_for, Figure())


def test_describe_controls():
    c = coop_controls()
    c["m0"].value = c["m2"].value = False
    assert describe_controls(c) == f"filter EKF; Q / Qtrue {TUNED_Q_SCALE['ekf']:g}; on: range, UAV GPS east, UAV GPS north"
    assert describe_controls(c, {"filter": "ukf", "m1": False, "m3": False, "m4": False}).endswith("on: none ticked")
    assert describe_controls(calibration_controls()) == ("GPS rate [Hz] 5; IMU noise W [(m/s²)²] 0.0004; GPS σ_p [m] 1; "
                                                         "bias prior σ [m/s²] 0.1; outage window [s] 12–18; on: GPS outage")


def _check_render(live, values):
    """One redraw of the grid: never raises or warns; the title matches what is drawn."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        png, line, ok = live.render(**values)
    assert png[:4] == b"\x89PNG" and "\n" not in line
    assert _png_size(png) == tuple(round(s * live.view.fig.dpi) for s in live.view.fig.get_size_inches())
    if not ok:
        assert describe_controls(live.controls, values) in live.message_fig.get_suptitle()
    return ok


#: slider positions (the ends, the default, and 2.51 and 3.16, where the UKF lost positive definiteness
#: without the bearing UGV->UAV and with the GPS alone) and measurement subsets of the grid
COOP_Q_POSITIONS = (0.01, 1.0, 10 ** 0.4, 10 ** 0.5, 100.0)
COOP_SUBSETS = {"all five": (0, 1, 2, 3, 4), "no bearing UGV->UAV": (1, 2, 3, 4), "GPS only": (3, 4)}


@pytest.mark.parametrize("filter", ["ekf", "ukf"])
def test_coop_demo_over_a_grid_of_controls(log, filter):
    live = _coop_live(log)
    positions = COOP_Q_POSITIONS if filter == "ukf" else (0.01, 100.0)
    outcome = {}
    for q in positions:
        for label, subset in COOP_SUBSETS.items():
            values = {"filter": filter, "q_scale": q, **{f"m{i}": i in subset for i in range(5)}}
            ok = outcome[q, label] = _check_render(live, values)
            if ok:
                title = live.view.fig.get_suptitle()
                assert title.startswith(f"{filter.upper()}, Q = {q:.3g} Qtrue, measurements: "
                                        + ", ".join(MEASUREMENT_NAMES[i] for i in subset) + "\n")
    print(filter, "combinations not drawn:", [k for k, ok in outcome.items() if not ok])
    assert filter == "ekf" or outcome[1.0, "all five"]  # the UKF's tuned defaults draw


def test_calibration_demo_over_a_grid_of_controls():
    live = LiveDemo(calibration_controls(), calibration_demo_for,
                    CalibrationDemoFigure(Figure(figsize=LIVE_FIGSIZE["calibration"])))
    c = live.controls
    corners = [{"W": c["W"].min, "gps_pos_sigma": c["gps_pos_sigma"].min, "bias_sigma": c["bias_sigma"].min},
               {"W": c["W"].max, "gps_pos_sigma": c["gps_pos_sigma"].max, "bias_sigma": c["bias_sigma"].max}]
    outages = [(False, (12.0, 18.0)), (True, (0.0, 30.0)), (True, (0.0, 0.5)), (True, (29.5, 30.0)),
               (True, (10.0, 10.0))]
    for rate in (c["gps_rate"].options[0], c["gps_rate"].options[-1]):
        for corner in corners:
            for on, window in outages:
                values = {"gps_rate": rate, **{k: 10.0 ** v for k, v in corner.items()}, "outage_on": on,
                          "outage": window}
                if _check_render(live, values):
                    title = live.view.axes[0].get_title()
                    assert f"GPS {rate:g} Hz" in title and (("outage" in title) == (on and window[0] < window[1]))
