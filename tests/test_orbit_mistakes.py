"""The orbit rows of the mistakes table: each mistake is caught by the checks named in
tests/mistake_expectations.py (or, for the two no truth-model check sees, by none), the correct EKF passes
them all, and each mistaken filter differs from the correct one exactly where the mistake is."""

import numpy as np
import pytest

from kfcal_helpers.consistency import MonteCarloSummary
from kfcal_helpers.orbit import PROBLEM, OrbitParams, measure, simulate, station_states
from kfcal_helpers.orbit.filters import FilterSetup, OrbitEKF
from kfcal_helpers.orbit.mistakes import (MISTAKES, N_RUNS, SEED, InertialRhodotEKF, NoWrapEKF, mistake_row,
                                          orbit_case, wrong_visibility_measurements)
from kfcal_helpers.registry import MistakeRow

from mistake_expectations import ORBIT_ALL, ORBIT_CAUGHT_BY


@pytest.fixture(scope="module")
def rows(mistakes_table):
    """The orbit rows of the joined table at its defaults (tests/conftest.py: computed once)."""
    return {m: mistakes_table[m] for m in MISTAKES}


def test_problem_entry():
    from kfcal_helpers import problems

    assert problems.problem("orbit") is PROBLEM is problems.PROBLEMS[-1] is problems.ORBIT
    assert [f.name for f in PROBLEM.figures] == ["orbit_geometry", "orbit_measurements", "orbit_nees_nis"]
    assert PROBLEM.name == "orbit" and PROBLEM.mistakes is MISTAKES and PROBLEM.mistake_row is mistake_row
    assert list(MISTAKES) == list(ORBIT_CAUGHT_BY) and N_RUNS == 50 and SEED == 11


@pytest.mark.parametrize("mistake", list(MISTAKES))
def test_caught_by_the_expected_checks(rows, mistake):
    row = rows[mistake]
    assert isinstance(row, MistakeRow) and row.problem == "orbit" and row.mistake == mistake
    assert set(row.checks) == ORBIT_ALL
    assert set(row.failed) == ORBIT_CAUGHT_BY[mistake]
    assert isinstance(row.result, MonteCarloSummary) and row.result.n_runs == N_RUNS


def test_sizes_of_the_caught_mistakes(rows):
    assert rows["orbit_no_rotation"].checks["nees"].worst > 1e6
    assert rows["orbit_no_wrap"].checks["nis"].worst > 100
    assert rows["orbit_omega_gamma"].checks["nees"].worst > 10
    assert 1 < rows["orbit_nis_fixed_dof"].checks["nis"].worst < 10
    # the fixed-dof row is the correct filter judged with the wrong band: same NEES, same NIS values
    same = rows["orbit_ekf_correct"].checks
    assert rows["orbit_nis_fixed_dof"].checks["nees"].worst == same["nees"].worst
    assert np.array_equal(rows["orbit_nis_fixed_dof"].checks["nis"].statistic, same["nis"].statistic)


def test_the_missed_mistakes_leave_a_trace(rows):
    """Not caught, but not without effect: the inertial rhodot moves the NIS's share inside its band down,
    the wrong visibility test loses measurements."""
    share = {m: rows[m].checks["nis"].inside_fraction for m in ("orbit_ekf_correct", "orbit_inertial_rhodot")}
    assert share["orbit_inertial_rhodot"] < share["orbit_ekf_correct"] - 0.02
    assert rows["orbit_visibility"].result.dof.sum() < 0.8 * rows["orbit_ekf_correct"].result.dof.sum()


def test_mistaken_measurement_models():
    """The inertial-rhodot EKF differs only in rhodot, by the station's velocity along the line of sight;
    the no-wrap EKF's residual is the plain difference."""
    p = OrbitParams()
    setup = FilterSetup("ekf", p)
    x = p.x0.reshape(4, 1)
    t, ids = 600.0, np.array([0, 1])
    right, wrong = OrbitEKF(setup).hx(x, t, ids), InertialRhodotEKF(setup).hx(x, t, ids)
    assert np.allclose(right, measure(p.x0, t, p)[ids].reshape(-1, 1))
    diff = (wrong - right).reshape(2, 3)
    assert np.allclose(diff[:, [0, 2]], 0) and np.all(np.abs(diff[:, 1]) > 1e-3)
    st = station_states(t, p)[ids]
    los = (p.x0[[0, 2]] - st[:, [0, 2]]) / np.linalg.norm(p.x0[[0, 2]] - st[:, [0, 2]], axis=1)[:, None]
    assert np.allclose(diff[:, 1], (st[:, [1, 3]] * los).sum(axis=1))
    H = InertialRhodotEKF(setup).H_jacobian(x, t, ids)
    eps = 1e-6
    numeric = np.column_stack([(InertialRhodotEKF(setup).hx(x + eps * np.eye(4)[:, [j]], t, ids) - wrong)[:, 0] / eps
                               for j in range(4)])
    assert np.allclose(H, numeric, atol=1e-5)
    a, b = np.array([[1.0], [0.0], [3.1]]), np.array([[1.0], [0.0], [-3.1]])
    assert np.isclose(NoWrapEKF.residual_z(a, b)[2, 0], 6.2)
    assert np.isclose(OrbitEKF.residual_z(a, b)[2, 0], 6.2 - 2 * np.pi)


def test_wrong_visibility_draws_the_same_noise_and_keeps_a_subset():
    p = OrbitParams(n_steps=600)
    right = simulate(p, 2, np.random.default_rng(3), integrator="rk4")
    rng = np.random.default_rng(3)
    from kfcal_helpers.orbit import simulate_truth
    truth = simulate_truth(p, rng, n_runs=2, integrator="rk4")
    wrong = wrong_visibility_measurements(truth, p, rng)
    kept = np.isfinite(wrong[..., 0])
    assert np.array_equal(truth, right.truth)
    assert np.all(np.isfinite(right.y[..., 0])[kept])  # a subset of the correct test's stations
    assert np.array_equal(wrong[kept], right.y[kept])  # with the same noise
    assert kept.sum() < np.isfinite(right.y[..., 0]).sum()


def test_cases_and_bad_input():
    case = orbit_case("orbit_no_rotation")
    assert case["setup"].params.omegaE == 0 and case["truth_params"].omegaE > 0
    assert np.allclose(orbit_case("orbit_omega_gamma")["setup"].Q, OrbitParams().Qtrue / 100)
    with pytest.raises(ValueError, match="mistake must be one of"):
        orbit_case("ekf_no_wrap")
    with pytest.raises(ValueError, match="n_runs"):
        mistake_row("orbit_ekf_correct", n_runs=1)


def test_the_per_run_path_equals_the_batch_for_the_correct_ekf():
    """The rows run by filterpy run by run (ekf_class) give, with the correct OrbitEKF, the batched EKF's
    NEES, NIS, dof, errors and bounds on the same draws."""
    from kfcal_helpers import montecarlo as core
    from kfcal_helpers.orbit.mistakes import MistakeExperiment

    p = OrbitParams(n_steps=150)
    per_run = core.run(MistakeExperiment(FilterSetup("ekf", p), 3, ekf_class=OrbitEKF), 3, 5)
    batch = core.run(MistakeExperiment(FilterSetup("ekf", p), 3), 3, 5)
    assert np.array_equal(per_run.dof, batch.dof) and per_run.dof.sum() > 0
    for name in ("nees", "nis", "errors", "sigma2"):
        assert np.allclose(getattr(per_run, name), getattr(batch, name), rtol=1e-6, atol=1e-9, equal_nan=True), name
    with pytest.raises(ValueError, match="ekf_class must be None or a subclass of OrbitEKF"):
        MistakeExperiment(FilterSetup("ekf", p), 3, ekf_class=dict)
