"""The coop rows of the mistakes table (notebook 14): each mistake is caught by the checks the notebook
names, the correct filters pass them all, and the one no truth-model test sees is caught by the log."""

import numpy as np
import pytest

from kfcal_helpers.consistency import MonteCarloSummary, chi2_bounds, format_checks
from kfcal_helpers.coop import (PROBLEM, CoopParams, course_log, measure, measurement_residual, nominal_trajectory,
                                run_filter, simulate)
from kfcal_helpers.coop.mistakes import MISTAKES, N_RUNS, SEED, coop_case, mistake_row
from kfcal_helpers.registry import MistakeRow

from mistake_expectations import COOP_ALL, COOP_CAUGHT_BY

CAUGHT_BY = COOP_CAUGHT_BY  #: what notebook 14 says, check by check


@pytest.fixture(scope="module")
def rows(mistakes_table):
    """``mistake_row(m)`` of every mistake: the rows of the joined table at its defaults, which calls
    PROBLEM.mistake_row, i.e. mistake_row (tests/conftest.py: computed once, shared with tests/test_mistakes.py)."""
    return {m: mistakes_table[m] for m in MISTAKES}


def test_problem_entry():
    assert PROBLEM.name == "coop" and PROBLEM.mistakes is MISTAKES and PROBLEM.mistake_row is mistake_row
    assert list(MISTAKES) == list(CAUGHT_BY) and N_RUNS == 50 and SEED == 11


@pytest.mark.parametrize("mistake", list(MISTAKES))
def test_caught_by_the_checks_the_notebook_names(rows, mistake):
    row = rows[mistake]
    assert isinstance(row, MistakeRow) and row.problem == "coop" and row.mistake == mistake
    assert set(row.checks) == COOP_ALL
    assert set(row.failed) == CAUGHT_BY[mistake]
    assert row.passed == (not CAUGHT_BY[mistake])
    assert isinstance(row.result, MonteCarloSummary) and row.result.n_runs == N_RUNS
    assert "FAIL" in format_checks(row.result) or row.passed


def test_large_mistakes_fail_by_orders_of_magnitude(rows):
    for mistake in ("ekf_no_wrap", "lkf_no_nominal"):
        assert max(c.worst for c in rows[mistake].checks.values()) > 10


def test_lkf_without_nominal_innovation_is_the_raw_measurement():
    """The filter starts on the nominal (dx = 0), so its first innovation without y* is y_1 itself;
    with y* subtracted it is y_1 - y*_1."""
    log = simulate(CoopParams(duration=1.0), seed=3).log()
    name, _, kwargs = coop_case("lkf_no_nominal")
    assert name == "lkf" and kwargs["subtract_nominal"] is False
    wrong = run_filter("lkf", log.y, log.params(), subtract_nominal=False)
    right = run_filter("lkf", log.y, log.params())
    assert np.allclose(wrong.y[1], log.y[1])
    assert np.allclose(right.y[1], measurement_residual(log.y[1], measure(nominal_trajectory(log.params())[1])))


def test_omega_identity_is_caught_only_by_the_course_log(rows):
    """The Omega = I row passes its truth-model test (same wrong model in truth and filter); on the course
    log (KFCAL_COURSE_LOG, else skipped) its time-averaged NIS falls below the bounds, the correct EKF's not."""
    name, p, kwargs = coop_case("ekf_omega_identity")
    assert p.noise_model == "identity" and np.allclose(p.process_noise(), p.Qtrue)
    assert rows["ekf_omega_identity"].passed
    log, found, _ = course_log()
    if not found:
        pytest.skip("KFCAL_COURSE_LOG names no course log")
    lo, hi = chi2_bounds(5, int(np.isfinite(log.y[:, 0]).sum()), 0.05)
    wrong = run_filter(name, log.y, log.params(p), **kwargs).time_average_nis()
    right_name, right_p, right_kwargs = coop_case("ekf_correct")
    right = run_filter(right_name, log.y, log.params(right_p), Q=right_kwargs["Q"]).time_average_nis()
    assert wrong < lo <= right <= hi
    assert wrong == pytest.approx(4.393, abs=5e-4) and right == pytest.approx(5.130, abs=5e-4)


@pytest.mark.parametrize("bad", ["wrong_sign", "", None, "correct"])
def test_unknown_mistake_is_a_value_error(bad):
    with pytest.raises(ValueError, match="mistake must be one of"):
        coop_case(bad)
    with pytest.raises(ValueError, match="mistake must be one of"):
        mistake_row(bad)


def test_mistake_row_validates():
    with pytest.raises(ValueError, match="n_runs"):
        mistake_row("ekf_correct", n_runs=1)
    with pytest.raises(ValueError, match="params must be a CoopParams"):
        mistake_row("ekf_correct", params={"dt": 0.1})
    with pytest.raises(ValueError, match="alpha"):
        mistake_row("ekf_correct", n_runs=2, alpha=1.0)
