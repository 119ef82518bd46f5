"""The calibration rows of the mistakes table (notebook 14): each mistake is caught by the checks
the notebook names, the correct filter passes them all, the one the checks miss at 1000 realizations
fails the orthogonality check at 5000 and is caught by the model identity; the problem's registry entry; the calibration exercise checks of notebook 14."""

from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers.calibration import CHECK_NAMES, PROBLEM, CalibrationParams, error_state_model, run_monte_carlo, simulate
from kfcal_helpers.calibration.exercises import check_failing_checks_gps_sigma, check_phi02_coupling_change
from kfcal_helpers.calibration.mistakes import MISTAKES, mistake_row, mistaken_model
from kfcal_helpers.registry import MistakeRow

from mistake_expectations import CALIBRATION_CAUGHT_BY

CAUGHT_BY = CALIBRATION_CAUGHT_BY  #: what notebook 14 says, check by check

P = CalibrationParams()


@pytest.fixture(scope="module")
def rows(mistakes_table):
    """``mistake_row(mistake)`` of every mistake: the rows of the joined table at its defaults, which calls
    PROBLEM.mistake_row, i.e. mistake_row (tests/conftest.py: computed once, shared with tests/test_mistakes.py)."""
    return {mistake: mistakes_table[mistake] for mistake in MISTAKES}


def test_rows_and_their_checks(rows):
    assert tuple(MISTAKES) == tuple(CAUGHT_BY) and next(iter(MISTAKES)) == "correct"
    for mistake, row in rows.items():
        assert isinstance(row, MistakeRow)
        assert (row.problem, row.mistake, row.description) == ("calibration", mistake, MISTAKES[mistake])
        assert tuple(row.checks) == tuple(CHECK_NAMES)
        assert row.result.n_runs == 1000


@pytest.mark.parametrize("mistake", list(CAUGHT_BY))
def test_caught_by_the_checks_the_notebook_names(rows, mistake):
    assert set(rows[mistake].failed) == CAUGHT_BY[mistake]
    assert rows[mistake].passed == (not CAUGHT_BY[mistake])


def test_large_mistakes_fail_by_orders_of_magnitude(rows):
    for mistake in ("no_propagation", "gps_interval_0_02"):
        assert rows[mistake].checks["nees"].worst > 100


def test_problem_registers_the_rows():
    assert PROBLEM.name == "calibration" and PROBLEM.mistakes is MISTAKES and PROBLEM.mistake_row is mistake_row
    row = PROBLEM.mistake_row("w_is_gps_velocity_var", n_runs=200, alpha=0.1, seed=5)
    assert row.result.n_runs == 200 and row.result.alpha == 0.1
    same = run_monte_carlo(P, 200, seed=5, alpha=0.1, model=mistaken_model(P, "w_is_gps_velocity_var"),
                           progress=False)
    assert {n: c.worst for n, c in row.checks.items()} == {n: c.worst for n, c in same.checks().items()}


def test_variants_are_one_change_each():
    m = error_state_model(P)
    same = lambda a, b: np.array_equal(getattr(m, a), getattr(b, a))  # noqa: E731
    fields = ("Phi", "Q", "H", "V", "M0", "x0")
    changed = {k: {f for f in fields if not same(f, mistaken_model(P, k))} for k in MISTAKES}
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
    row = mistake_row("v0_zero", n_runs=400, seed=seed)
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


def test_phi02_sign_fails_only_the_orthogonality_check_at_5000():
    """The wrong Phi puts (Phi - Phi') x_hat into the prediction error, correlating the error with the
    estimate: at N = 5000 (seed 0, as notebook 14) the orthogonality check fails, in the position error's row
    against the bias estimate (against the velocity estimate it comes close, 0.96 of the band), and no other
    check does; the correct filter passes all seven."""
    checks = {m: run_monte_carlo(P, 5000, seed=0, model=mistaken_model(P, m)).checks() for m in ("correct", "phi02_sign")}
    assert all(c.passed for c in checks["correct"].values())
    assert [n for n, c in checks["phi02_sign"].items() if not c.passed] == ["orthogonality"]
    orth = checks["phi02_sign"]["orthogonality"]
    dev = orth.statistic - orth.expected
    half = np.where(dev >= 0, orth.sim_upper - orth.expected, orth.expected - orth.sim_lower)
    outside = (np.abs(dev) > half).reshape(P.n_gps, 3, 3).any(axis=0)     # (error component, estimate component)
    assert outside[0, 2] and outside.sum() == 1
    with np.errstate(invalid="ignore", divide="ignore"):   # entries of zero deviation and zero band (t = 0)
        ratio = np.where(dev == 0, 0.0, np.abs(dev) / half).reshape(P.n_gps, 3, 3).max(axis=0)
    assert 0.9 < ratio[0, 1] < 1


@pytest.mark.parametrize("bad", ["wrong_sign", "", None])
def test_unknown_mistake_is_a_value_error(bad):
    with pytest.raises(ValueError, match="mistake must be one of"):
        mistaken_model(P, bad)
    with pytest.raises(ValueError, match="mistake must be one of"):
        mistake_row(bad)


@pytest.mark.parametrize("kwargs, name", [({"n_runs": 1}, "n_runs"), ({"params": {}}, "params"),
                                          ({"alpha": 1.5}, "alpha")])
def test_bad_row_arguments_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        mistake_row("correct", **kwargs)


# exercise checks of notebook 14 -----------------------------------------------------------------
def test_check_14_1_accepts_the_run_and_rejects_common_answers():
    m = error_state_model(P)
    model = replace(m, V=np.diag([0.25, P.gps_vel_var]))  # a different route to the same filter
    mc = run_monte_carlo(P, 1000, seed=1, model=model, progress=False)
    right = {n for n, c in mc.checks().items() if not c.passed}
    assert "nees" in right and "mean_error" not in right
    assert check_failing_checks_gps_sigma(right).correct
    from kfcal_helpers.calibration import CHECK_NAMES
    from kfcal_helpers.calibration.exercises import EXERCISES

    hints = EXERCISES["14.1"].hints
    passing = sorted(set(CHECK_NAMES) - right)
    # a wrong set is told whether it holds a passing check, misses a failing one, or both, never which one
    # (naming them would solve the exercise by elimination)
    for answer, key in ((right | {"mean_error"}, "extra"), (right | {passing[-1]}, "extra"), ({"nees"}, "missing"),
                        ({"nees", "mean_error"}, "mixed")):
        fb = check_failing_checks_gps_sigma(answer)
        assert not fb.correct and fb.message == hints[key], (answer, str(fb))
        assert not any(name in fb.message for name in CHECK_NAMES), str(fb)
    assert not check_failing_checks_gps_sigma(...).answered
    assert "unknown check names" in check_failing_checks_gps_sigma({"nees", "chi2"}).message
    for bad in ("nees", 3, {1, 2}, lambda: None):
        assert "set of check names" in check_failing_checks_gps_sigma(bad).message
    with pytest.raises(ValueError, match="params"):
        check_failing_checks_gps_sigma(right, params="defaults")


def test_check_14_2():
    Phi = error_state_model(P).Phi
    flipped = Phi.copy()
    flipped[0, 2] *= -1
    for k in (200, 40, 7):
        right = np.linalg.matrix_power(flipped, k)[0, 2] - np.linalg.matrix_power(Phi, k)[0, 2]
        assert np.isclose(right, k * P.dt**2, rtol=1e-9)
        assert check_phi02_coupling_change(right, steps=k).correct
    k = 200                      # the default: one second, not the 40-step fix interval the notebook prints
    right = k * P.dt**2
    assert check_phi02_coupling_change(right).correct
    for wrong, hint in ((-right, "sign"), (P.dt**2, "one IMU step"), (-(k * P.dt) ** 2 / 2, "coupling itself"),
                        (k**2 * P.dt**2, "once per step"), (P.steps_per_fix * P.dt**2, "fix interval of the default"),
                        (k * P.dt**2 / 2, "a factor of 2")):
        fb = check_phi02_coupling_change(wrong)
        assert not fb.correct and hint in fb.message
    # at k = 40 the fix-interval value is the right answer, not a mistake
    assert check_phi02_coupling_change(P.steps_per_fix * P.dt**2, steps=P.steps_per_fix).correct
    assert "not the shape the exercise asks for" in check_phi02_coupling_change([1.0, 2.0]).message   # the size not revealed
    assert not check_phi02_coupling_change(None).answered
    for bad in (0, 2.5, "200"):
        with pytest.raises(ValueError, match="steps"):
            check_phi02_coupling_change(right, steps=bad)
