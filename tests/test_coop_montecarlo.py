"""The coop truth-model test on the shared Monte Carlo core: the core's seed policy over chunks, the
redraw of any run (truth_model_draws), independence of the threads, the result's interface, its NEES and
NIS checks against their chi-square bands written out from scipy."""

import pathlib
from dataclasses import replace

import numpy as np
import pytest

from kfcal_helpers import montecarlo as core
from kfcal_helpers.consistency import MonteCarloSummary
from kfcal_helpers.coop import CoopParams, run_filter, simulate, truth_model_draws, truth_model_test
from kfcal_helpers.coop.filters import FilterSetup
from kfcal_helpers.coop.montecarlo import CHUNK_SIZE, TruthModelExperiment

SHORT = replace(CoopParams(), duration=1.0)
N = 2 * CHUNK_SIZE + 30  # three chunks, the last one short


@pytest.fixture(scope="module")
def mc():
    return truth_model_test(SHORT, N, 7, filter="ekf", every=2, workers=2)


def test_the_draws_are_those_of_the_core_policy(mc):
    """Chunk c of CHUNK_SIZE runs is simulate(params, size, generator c) with generator c =
    Generator(PCG64DXSM(SeedSequence(seed).spawn(n_chunks)[c]))."""
    sim = truth_model_draws(SHORT, N, 7, every=2)
    assert sim.n_runs == N and sim.seed == 7 and sim.every == 2
    seeds = np.random.SeedSequence(7).spawn(3)
    third = simulate(SHORT, 30, np.random.Generator(np.random.PCG64DXSM(seeds[2])), every=2)
    assert np.array_equal(sim.truth[2 * CHUNK_SIZE:], third.truth)
    assert np.array_equal(sim.y[2 * CHUNK_SIZE:], third.y, equal_nan=True)
    assert not np.array_equal(sim.truth[:30], third.truth)


@pytest.mark.parametrize("i", [0, CHUNK_SIZE - 1, CHUNK_SIZE, N - 1])
def test_truth_model_draws_redraws_what_the_test_filtered(mc, i):
    """Run i redrawn (alone, or among all) and filtered by filterpy gives the test's NEES, NIS and errors."""
    one = truth_model_draws(SHORT, N, 7, every=2, run=i)
    every = truth_model_draws(SHORT, N, 7, every=2)
    assert one.n_runs is None and np.array_equal(one.truth, every.truth[i])
    assert np.array_equal(one.y, every.y[i], equal_nan=True)
    r = run_filter("ekf", one.y, SHORT, truth=one.truth)
    np.testing.assert_allclose(mc.nees[i], r.nees, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mc.nis[i], r.nis, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mc.errors[i], r.errors(one.truth), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mc.sigma2[i], r.sigma2, rtol=1e-9, atol=1e-9)


def test_the_result_does_not_depend_on_the_threads(mc):
    one = truth_model_test(SHORT, N, 7, filter="ekf", every=2, workers=1)
    for name in ("nees", "nis", "errors", "sigma2"):
        assert np.array_equal(getattr(one, name), getattr(mc, name), equal_nan=True), name


def test_the_result_offers_the_shared_interface(mc):
    assert isinstance(mc, MonteCarloSummary)
    assert mc.n_runs == N and mc.alpha == 0.05 and mc.filter == "ekf" and mc.every == 2 and mc.seconds > 0
    assert mc.nees.shape == mc.nis.shape == (N, SHORT.n_samples) and mc.errors.shape == (N, SHORT.n_samples, 6)
    assert set(mc.checks()) == {"mean_error", "nees", "nis"}
    check = mc.checks()["mean_error"]
    sem = mc.errors.std(axis=0, ddof=1).ravel() / np.sqrt(N)  # the blocked deviation equals numpy's
    from scipy import stats
    np.testing.assert_allclose(check.upper, stats.t.ppf(0.975, N - 1) * sem, rtol=1e-12)


def test_the_experiment_is_one_of_the_core():
    exp = TruthModelExperiment(FilterSetup.build("ukf", SHORT), 5)
    assert isinstance(exp, core.Experiment) and exp.chunk_size() == CHUNK_SIZE
    assert exp.fixed_bytes(10) - exp.fixed_bytes(5) == 5 * SHORT.n_samples * 14 * 8
    with pytest.raises(ValueError, match="n_runs: the experiment was made for 5 runs"):
        core.run(exp, 6, 0)


def test_a_generator_seed_is_spawned():
    a = truth_model_test(SHORT, 3, np.random.default_rng(4), filter="lkf")
    b = truth_model_draws(SHORT, 3, np.random.default_rng(4))
    assert b.seed is None
    r = run_filter("lkf", b.y[2], SHORT, truth=b.truth[2])
    np.testing.assert_allclose(a.nees[2], r.nees, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("call,message", [
    (lambda: truth_model_draws(SHORT, 4, 0, run=4), r"run must be an integer in 0\.\.3, got 4"),
    (lambda: truth_model_draws(SHORT, 4, 0, run=-1), "run must be"),
    (lambda: truth_model_draws(SHORT, 0, 0), "n_runs must be"),
    (lambda: truth_model_draws(SHORT, 4, -1), r"seed must be None or an integer in \[0, 2\*\*63 - 1\]"),
    (lambda: truth_model_draws(SHORT, 4, 0, every=0), "every must be"),
    (lambda: truth_model_draws({"dt": 0.1}, 4, 0), "params must be a CoopParams"),
    (lambda: truth_model_test(SHORT, 4, "1"), "seed must be"),
    (lambda: truth_model_test(SHORT, 4, 0, workers=0), "workers must be"),
])
def test_bad_arguments_are_value_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_no_process_pool_in_the_package():
    """Threads only: nothing in the package forks or imports multiprocessing."""
    root = pathlib.Path(__file__).resolve().parents[1] / "kfcal_helpers"
    for path in root.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        assert "multiprocessing" not in text and "ProcessPoolExecutor" not in text, path
        assert 'get_context("fork")' not in text and "os.fork" not in text, path


def _chi2_band(dim, n_runs, level):
    """The band of a run average of chi-square(dim) terms, written out from scipy."""
    from scipy import stats
    return stats.chi2.ppf(level / 2, dim * n_runs) / n_runs, stats.chi2.ppf(1 - level / 2, dim * n_runs) / n_runs


@pytest.mark.parametrize("filter,seed,n_runs,settings", [
    ("lkf", 3, 7, dict(every=2)),
    ("ekf", 5, 6, dict(alpha=0.01, measurements=(0, 2, 4))),
    ("ukf", 8, 9, dict(every=3, measurements=(1, 3))),
    ("ekf", 1, 8, dict(Q=0.01 * CoopParams().Qtrue)),  # an overconfident filter: the NEES fails
])
def test_the_nees_and_nis_checks_are_the_run_averages_against_their_chi2_bands(filter, seed, n_runs, settings):
    """Per step: the run-averaged NEES against chi2(6 N)/N, the run-averaged NIS at the steps with a
    measurement against chi2(m N)/N (m = the measurements used), each with its pointwise band at alpha and
    its simultaneous band at alpha / (all entries of the three checks); inside fraction, worst and verdict
    as defined by Check.  Equal to the last bit to the formulas written out here."""
    mc = truth_model_test(replace(CoopParams(), duration=5.0), n_runs, seed, filter=filter, workers=1, **settings)
    checks = mc.checks()
    N, K = mc.nees.shape
    has = np.isfinite(mc.nis).all(axis=0)
    assert 0 < has.sum() < K  # no measurement at t = 0, nor between the kept ones with every > 1
    a_sim = mc.alpha / (6 * K + K + int(has.sum()))
    m = len(mc.measurements)
    assert m == len(settings.get("measurements", range(5)))
    for name, statistic, dim in (("nees", mc.nees.mean(axis=0), 6), ("nis", mc.nis[:, has].mean(axis=0), m)):
        c = checks[name]
        assert c.name == name and np.array_equal(c.statistic, statistic), name
        assert np.array_equal(c.expected, np.full(statistic.size, float(dim))), name
        for got, want in zip((c.lower, c.upper, c.sim_lower, c.sim_upper),
                             (*_chi2_band(dim, N, mc.alpha), *_chi2_band(dim, N, a_sim))):
            assert np.array_equal(got, np.full(statistic.size, want)), name
        lo, hi = _chi2_band(dim, N, mc.alpha)
        slo, shi = _chi2_band(dim, N, a_sim)
        assert c.inside_fraction == np.mean((statistic >= lo) & (statistic <= hi)), name
        dev = statistic - dim
        worst = np.max(np.abs(dev) / np.where(dev >= 0, shi - dim, dim - slo))
        assert c.worst == worst and c.passed == (worst <= 1.0), name
    # the mean error's simultaneous band shares the same split
    t = checks["mean_error"]
    from scipy import stats
    np.testing.assert_allclose(t.sim_upper / t.upper, stats.t.ppf(1 - a_sim / 2, N - 1) / stats.t.ppf(
        1 - mc.alpha / 2, N - 1), rtol=1e-12)
    if "Q" in settings:
        assert not checks["nees"].passed and checks["nees"].worst > 1


def test_a_result_with_a_diverged_run_is_refused_not_judged(mc):
    """The batch refuses a diverged run (ValueError 'diverged'); a result that holds one anyway (built by
    hand) gets a one-line ValueError from checks(), never a verdict computed from inf or NaN."""
    bad = replace(mc, nees=mc.nees.copy())
    bad.nees[3, 1] = np.inf
    with pytest.raises(ValueError, match="^nees must hold only finite numbers"):
        bad.checks()
