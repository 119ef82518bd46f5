"""The batched orbit LKF/EKF/UKF (kfcal_helpers.orbit.batch) equal the per-run filterpy filters on the same
draws, runs whose visible stations differ included: x, P, NEES, NIS, dof, errors, two-sigma bounds, to 1e-9."""

from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers.orbit import OrbitParams, simulate
from kfcal_helpers.orbit.batch import run_batch
from kfcal_helpers.orbit.filters import FilterSetup, run

P = replace(OrbitParams(), n_steps=200, P0=np.diag([4.0, 1e-4, 4.0, 1e-4]))  # runs 2 km apart: stations differ
N = 3


def _same(b, setup, y, truth):
    for i in range(y.shape[0]):
        r = run(y[i], setup, truth[i])
        for got, want in ((b.x[i], r.x_post), (b.P[i], r.P_post), (b.nees[i], r.nees), (b.nis[i], r.nis),
                          (b.errors[i], r.errors(truth[i])), (b.sigma2[i], r.sigma2)):
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
        np.testing.assert_array_equal(b.dof[i], r.dof)


CASES = [("lkf", {}), ("ekf", {}), ("ukf", {}), ("ekf", {"substeps": 2}),
         ("lkf", {"transition": "expm"}), ("ukf", {"alpha": 0.5, "beta": 2.0, "kappa": 1.0}),
         ("ukf", {"Q": 1e-9 * np.eye(2), "R": np.diag([0.04, 0.5, 0.02])})]


@pytest.mark.parametrize("every", [1, 3])
@pytest.mark.parametrize("name,settings", CASES, ids=[f"{n}-{'-'.join(s) or 'default'}" for n, s in CASES])
def test_batch_equals_filterpy_per_run(name, settings, every):
    sim = simulate(P, N, seed=21, every=every)
    have = np.isfinite(sim.y).all(axis=-1)
    assert (have != have[:1]).any(axis=(0, 2)).sum() >= 3  # steps where the runs' stations differ
    setup = FilterSetup(name, P, **settings)
    b = run_batch(sim.y, setup, sim.truth, keep_estimates=True)
    assert b.x.shape == (N, P.n_samples, 4) and b.P.shape == (N, P.n_samples, 4, 4)
    assert b.nis.shape == b.nees.shape == b.dof.shape == (N, P.n_samples)
    _same(b, setup, sim.y, sim.truth)


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_batch_equals_filterpy_with_a_first_measurement_and_a_run_without_stations(name):
    p = replace(P, n_steps=30)
    sim = simulate(p, 3, seed=5, first=True)
    y = sim.y.copy()
    y[1, 10:20] = np.nan  # run 1 sees nothing for ten steps while the others do
    setup = FilterSetup(name, p)
    b = run_batch(y, setup, sim.truth, keep_estimates=True)
    assert (b.dof[1, 10:20] == 0).all() and (b.dof[0, 10:20] > 0).all()
    _same(b, setup, y, sim.truth)


def test_batch_without_truth_and_bad_inputs():
    sim = simulate(replace(P, n_steps=10), 2, seed=1)
    setup = FilterSetup("ekf", replace(P, n_steps=10))
    b = run_batch(sim.y, setup)
    assert b.nees is None and b.errors is None and b.x is None and b.sigma2.shape == (2, 11, 4)
    with pytest.raises(ValueError, match="y must have shape"):
        run_batch(sim.y[0], setup)
    with pytest.raises(ValueError, match="truth must have shape"):
        run_batch(sim.y, setup, sim.truth[:1])
    with pytest.raises(ValueError, match="setup must be a FilterSetup"):
        run_batch(sim.y, "ekf")
