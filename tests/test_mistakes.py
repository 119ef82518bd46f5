"""The mistakes table of notebook 14: each mistake is caught by the checks the notebook names,
the correct filters pass them all, and the one no check sees is caught by the model identity."""

from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers.calibration import CHECK_NAMES, CalibrationParams, error_state_model, run_monte_carlo, simulate
from kfcal_helpers.consistency import chi2_bounds
from kfcal_helpers.coop import (CoopParams, course_log, generate_log, measure, measurement_residual, nominal_trajectory,
                                run_filter)
from kfcal_helpers.exercises import check_failing_checks_gps_sigma, check_phi02_coupling_change
from kfcal_helpers.mistakes import (CALIBRATION_MISTAKES, COOP_MISTAKES, MISTAKES, calibration_row, coop_case,
                                    format_mistake_table, mistake_table, mistaken_model)

ALL_BUT_MEAN = set(CHECK_NAMES) - {"mean_error"}
COOP_ALL = {"mean_error", "nees", "nis"}

#: what notebook 14 says, check by check
CAUGHT_BY = {
    "correct": set(),
    "no_propagation": ALL_BUT_MEAN,
    "phi02_sign": set(),
    "m0_swapped": ALL_BUT_MEAN,
    "w_is_gps_velocity_var": {"covariance", "nees"},
    "gps_interval_0_02": ALL_BUT_MEAN,
    "v0_zero": {"mean_error", "residual_independence", "residual_variance", "nees", "nis"},
    "ekf_correct": set(),
    "ekf_no_wrap": COOP_ALL,
    "ekf_omega_identity": set(),
    "lkf_correct": set(),
    "lkf_no_nominal": COOP_ALL,
}

P = CalibrationParams()


@pytest.fixture(scope="module")
def table():
    return mistake_table()


def test_table_rows_and_columns(table):
    assert tuple(table) == MISTAKES == (*CALIBRATION_MISTAKES, *COOP_MISTAKES)
    for mistake, row in table.items():
        expected = set(CHECK_NAMES) if mistake in CALIBRATION_MISTAKES else COOP_ALL
        assert set(row.checks) == expected
    text = format_mistake_table(table)
    assert len(text.splitlines()) == 2 + len(MISTAKES) and "FAIL" in text and "pass" in text


@pytest.mark.parametrize("mistake", MISTAKES)
def test_caught_by_the_checks_the_notebook_names(table, mistake):
    assert set(table[mistake].failed) == CAUGHT_BY[mistake]
    assert table[mistake].passed == (not CAUGHT_BY[mistake])


def test_large_mistakes_fail_by_orders_of_magnitude(table):
    for mistake in ("no_propagation", "gps_interval_0_02", "ekf_no_wrap", "lkf_no_nominal"):
        assert table[mistake].checks["nees"].worst > 100


def test_variants_are_one_change_each():
    m = error_state_model(P)
    same = lambda a, b: np.array_equal(getattr(m, a), getattr(b, a))  # noqa: E731
    fields = ("Phi", "Q", "H", "V", "M0", "x0")
    changed = {k: {f for f in fields if not same(f, mistaken_model(P, k))} for k in CALIBRATION_MISTAKES}
    assert changed == {"correct": set(), "no_propagation": {"Phi", "Q"}, "phi02_sign": {"Phi"},
                       "m0_swapped": {"M0"}, "w_is_gps_velocity_var": {"Q"}, "gps_interval_0_02": {"Phi", "Q"},
                       "v0_zero": {"x0"}}
    assert np.array_equal(mistaken_model(P, "v0_zero").x0, [0.0, -P.v0_mean, P.bias_mean])
    flipped = mistaken_model(P, "phi02_sign").Phi
    assert flipped[0, 2] == P.dt**2 / 2 and np.array_equal(np.delete(flipped.ravel(), 2), np.delete(m.Phi.ravel(), 2))
    assert np.allclose(np.diag(mistaken_model(P, "m0_swapped").M0), [P.v0_var, P.p0_var, P.bias_var])
    # 0.02 s between fixes: Phi over the 40 steps is that of 0.02 s
    phi_fix = np.linalg.matrix_power(mistaken_model(P, "gps_interval_0_02").Phi, P.steps_per_fix)
    assert np.isclose(phi_fix[1, 2], -0.02)


@pytest.mark.parametrize("seed", [2, 3])
def test_v0_zero_fails_the_mean_error_check_on_other_seeds(seed):
    """The only listed mistake the mean-error check catches: a wrong prior mean is a bias,
    whatever the seed; the spread around it is right (covariance and orthogonality pass)."""
    row = calibration_row("v0_zero", n_runs=400, seed=seed)
    assert "mean_error" in row.failed and row.checks["mean_error"].worst > 5
    assert row.checks["covariance"].passed and row.checks["orthogonality"].passed


def test_phi02_sign_is_caught_by_the_model_identity():
    sim = simulate(P, 5, np.random.default_rng(7))
    gamma = error_state_model(P).Gamma
    for mistake, small in (("correct", True), ("phi02_sign", False)):
        Phi = mistaken_model(P, mistake).Phi
        resid = sim.dx[:, 1:] - sim.dx[:, :-1] @ Phi.T - sim.w[:, :-1, None] * gamma
        assert (np.abs(resid).max() < 1e-9) == small
    resid_pos = sim.dx[:, 1:, 0] - sim.dx[:, :-1] @ mistaken_model(P, "phi02_sign").Phi[0] - sim.w[:, :-1] * gamma[0]
    assert np.allclose(resid_pos, -P.dt**2 * sim.b[:, None], rtol=1e-4, atol=1e-12)


def test_lkf_without_nominal_innovation_is_the_raw_measurement():
    """The filter starts on the nominal (dx = 0), so its first innovation without y* is y_1 itself;
    with y* subtracted it is y_1 - y*_1."""
    log = generate_log(CoopParams(duration=1.0), seed=3)
    name, _, kwargs = coop_case("lkf_no_nominal")
    assert name == "lkf" and kwargs["subtract_nominal"] is False
    wrong = run_filter("lkf", log.y, log.params(), subtract_nominal=False)
    right = run_filter("lkf", log.y, log.params())
    assert np.allclose(wrong.innovations[1], log.y[1])
    assert np.allclose(right.innovations[1], measurement_residual(log.y[1], measure(nominal_trajectory(log.params())[1])))


def test_omega_identity_is_caught_only_by_the_course_log(table):
    """The Omega = I row passes its truth-model test (same wrong model in truth and filter); on the course
    log (KFCAL_COURSE_LOG, else skipped) its time-averaged NIS falls below the bounds, the correct EKF's not."""
    name, p, kwargs = coop_case("ekf_omega_identity")
    assert p.noise_model == "identity" and np.allclose(p.process_noise(), p.Qtrue)
    assert table["ekf_omega_identity"].passed
    log, found, _ = course_log()
    if not found:
        pytest.skip("KFCAL_COURSE_LOG names no course log")
    lo, hi = chi2_bounds(5, int(np.isfinite(log.y[:, 0]).sum()), 0.05)
    wrong = run_filter(name, log.y, log.params(p), **kwargs).time_average_nis()
    right_name, right_p, right_kwargs = coop_case("ekf_correct")
    right = run_filter(right_name, log.y, log.params(right_p), Q=right_kwargs["Q"]).time_average_nis()
    assert wrong < lo <= right <= hi
    assert wrong == pytest.approx(4.393, abs=5e-4) and right == pytest.approx(5.130, abs=5e-4)


@pytest.mark.parametrize("bad", ["wrong_sign", "", None])
def test_unknown_mistake_is_a_value_error(bad):
    with pytest.raises(ValueError, match="mistake must be one of"):
        mistaken_model(P, bad)
    with pytest.raises(ValueError, match="mistake must be one of"):
        coop_case(bad)
    with pytest.raises(ValueError, match="mistakes must be one of"):
        mistake_table([bad])


# exercise checks of notebook 14 -----------------------------------------------------------------

def test_check_14_1_accepts_the_run_and_rejects_common_answers():
    m = error_state_model(P)
    model = replace(m, V=np.diag([0.25, P.gps_vel_var]))  # a different route to the same filter
    mc = run_monte_carlo(P, 1000, seed=1, model=model, progress=False)
    right = {n for n, c in mc.checks().items() if not c.passed}
    assert "nees" in right and "mean_error" not in right
    assert check_failing_checks_gps_sigma(right).correct
    assert "mean error cannot fail" in check_failing_checks_gps_sigma(right | {"mean_error"}).message
    assert "missing" in check_failing_checks_gps_sigma({"nees"}).message
    extra = right | ({"residual_independence"} if "residual_independence" not in right else set())
    assert not check_failing_checks_gps_sigma(extra).correct
    assert not check_failing_checks_gps_sigma(...).answered
    assert "unknown check names" in check_failing_checks_gps_sigma({"nees", "chi2"}).message
    assert "set of check names" in check_failing_checks_gps_sigma("nees").message


def test_check_14_2():
    Phi = error_state_model(P).Phi
    flipped = Phi.copy()
    flipped[0, 2] *= -1
    k = P.steps_per_fix
    right = np.linalg.matrix_power(flipped, k)[0, 2] - np.linalg.matrix_power(Phi, k)[0, 2]
    assert check_phi02_coupling_change(right).correct
    for wrong, hint in ((-right, "sign"), (P.dt**2, "one IMU step"), (-(k * P.dt) ** 2 / 2, "coupling itself"),
                        (k**2 * P.dt**2, "once per step")):
        fb = check_phi02_coupling_change(wrong)
        assert not fb.correct and hint in fb.message
    assert "expected shape" in check_phi02_coupling_change([1.0, 2.0]).message
    assert not check_phi02_coupling_change(None).answered
