"""The orbit truth-model test through the shared Monte Carlo core: the same draws as simulate + run_batch
on the core's chunk generators, independent of the number of workers, per-step checks with the dof present."""

from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers import montecarlo as core
from kfcal_helpers.consistency import format_checks
from kfcal_helpers.orbit import OrbitParams, run_batch, simulate
from kfcal_helpers.orbit.filters import FilterSetup
from kfcal_helpers.orbit.montecarlo import CHUNK_SIZE, OrbitExperiment, truth_model_test

P = replace(OrbitParams(), n_steps=120)


def test_the_test_filters_the_core_s_draws_and_does_not_depend_on_workers():
    n = CHUNK_SIZE + 7  # two chunks
    one = truth_model_test(P, n, 3, filter="ekf", workers=1)
    two = truth_model_test(P, n, 3, filter="ekf", workers=2)
    for name in ("nees", "nis", "dof", "errors", "sigma2"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    (s0, g0), (s1, g1) = core.chunk_generators(CHUNK_SIZE, n, 3)
    sims = [simulate(P, s0, g0, integrator="rk4"), simulate(P, s1, g1, integrator="rk4")]
    b = [run_batch(s.y, FilterSetup("ekf", P), s.truth) for s in sims]
    np.testing.assert_array_equal(one.nees, np.concatenate([x.nees for x in b]))
    np.testing.assert_array_equal(one.dof, 3 * np.concatenate([np.isfinite(s.y).all(axis=-1).sum(axis=-1) for s in sims]))
    assert one.n_runs == n and one.seconds > 0


@pytest.mark.parametrize("name", ["ekf", "ukf"])
def test_ekf_and_ukf_pass_their_truth_model_checks(name):
    r = truth_model_test(P, 40, 5, filter=name, integrator="solve_ivp")
    checks = r.checks()
    print(format_checks(r))
    assert set(checks) == {"mean_error", "nees", "nis"}
    assert all(c.passed for c in checks.values())
    has = (r.dof > 0).any(axis=0)
    assert checks["nis"].statistic.size == has.sum()
    np.testing.assert_allclose(checks["nis"].expected, r.dof[:, has].sum(axis=0) / (r.dof[:, has] > 0).sum(axis=0))


def test_lkf_fails_when_the_orbit_drifts_from_the_nominal():
    p = replace(OrbitParams(), n_steps=700)  # half the pass: the truth is hundreds of km off the nominal
    r = truth_model_test(p, 20, 2, filter="lkf")
    assert not r.checks()["nees"].passed


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match="n_runs"):
        truth_model_test(P, 0)
    with pytest.raises(ValueError, match="integrator"):
        truth_model_test(P, 2, integrator="euler")
    with pytest.raises(ValueError, match="setup: give either"):
        truth_model_test(P, 2, setup=FilterSetup("ekf", P))
    with pytest.raises(ValueError, match="n_runs must be at least 2"):
        truth_model_test(P, 1).checks()
    exp = OrbitExperiment(FilterSetup("ekf", P), 10)
    assert exp.chunk_size() == CHUNK_SIZE and exp.seconds(10) > 0


@pytest.mark.slow
def test_1000_run_ekf_nees_is_four_now_the_truth_is_the_filters_dt_model():
    """With the truth's noise held over each step (a position noise the filter does not model) this test's
    time-and-run averaged NEES was 3.90 and the per-step check failed; with ``Omega w_k`` it is 4 within
    three standard deviations of the grand mean (from the runs' own time averages)."""
    r = truth_model_test(OrbitParams(), 1000, 2, filter="ekf")
    per_run = r.nees[:, 1:].mean(axis=1)
    sd = per_run.std(ddof=1) / np.sqrt(r.n_runs)
    assert abs(r.nees.mean() - 4.0) < 3 * sd, (r.nees.mean(), sd)
    assert r.checks()["nees"].passed
