"""kfcal_helpers.coop.power: the detection rates of notebook 14's coop power section.  The stored table
is what detection_rates computes (a subset recomputed with the same seeds gives the same failed checks;
the full-size recomputation of two cases is in the slow tier), a repetition is one truth_model_test,
the cases are the EKF with Q = s Qtrue and notebook 14's coop rows, the correct filters' false-alarm
rates are consistent with at most alpha, and bad arguments raise ValueError naming the argument."""

import runpy
from pathlib import Path

import numpy as np
import pytest

from kfcal_helpers.coop import CoopParams, truth_model_test
from kfcal_helpers.coop.mistakes import MISTAKES, coop_case
from kfcal_helpers.coop.power import (CASES, CHECKS, DEFAULT_N_RUNS, Q_SCALES, DetectionRates, case_setup,
                                      detection_rates, repetition_seed, stored_detection_rates)


@pytest.fixture(scope="module")
def stored():
    return stored_detection_rates()


def test_stored_table_covers_every_case_and_n(stored):
    assert stored.mistakes == tuple(CASES) and stored.mistakes[0] == "ekf_correct"
    assert set(MISTAKES) < set(CASES) and Q_SCALES == (0.1, 0.3, 3.0, 10.0)
    assert stored.n_runs == DEFAULT_N_RUNS and stored.reps >= 100 and stored.alpha == 0.05
    assert stored.checks == CHECKS == ("mean_error", "nees", "nis")
    assert stored.failed.shape == (len(CASES), len(DEFAULT_N_RUNS), stored.reps, 3)


def test_a_subset_recomputed_with_the_same_seeds_gives_the_same_failed_checks(stored):
    names, ns, reps = ["ekf_correct", "q_x0.3", "q_x3", "lkf_correct"], [5, 10], 2
    again = detection_rates(names, ns, reps=reps, seed=stored.seed)
    a = [stored.mistakes.index(m) for m in names]
    j = [stored.n_runs.index(n) for n in ns]
    assert np.array_equal(again.failed, stored.failed[np.ix_(a, j)][:, :, :reps])


@pytest.mark.slow
def test_full_size_rows_recomputed_give_the_stored_failed_checks(stored):
    # every stored repetition of the correct EKF and of Q = 3 Qtrue at N = 50
    names = ["ekf_correct", "q_x3"]
    again = detection_rates(names, [50], reps=stored.reps, seed=stored.seed)
    a = [stored.mistakes.index(m) for m in names]
    assert np.array_equal(again.failed, stored.failed[a][:, [stored.n_runs.index(50)]])


def test_a_repetition_is_one_truth_model_test():
    t = detection_rates(["q_x0.1", "ekf_no_wrap"], [5], reps=2, seed=7)
    p = CoopParams()
    mc = truth_model_test(p, 5, repetition_seed(7, 5, 1), filter="ekf", Q=0.1 * p.Qtrue)
    assert t.failed[0, 0, 1].tolist() == [not mc.checks()[c].passed for c in CHECKS]
    f, cp, kw = coop_case("ekf_no_wrap")
    mc = truth_model_test(cp, 5, repetition_seed(7, 5, 1), filter=f, **kw)
    assert t.failed[1, 0, 1].tolist() == [not mc.checks()[c].passed for c in CHECKS]


def test_case_setup():
    p = CoopParams()
    for s in Q_SCALES:
        f, cp, kw = case_setup(f"q_x{s:g}")
        assert f == "ekf" and cp.noise_model == p.noise_model and np.array_equal(cp.Qtrue, p.Qtrue) and set(kw) == {"Q"} and np.array_equal(kw["Q"], s * p.Qtrue)
    for m in MISTAKES:
        f, cp, kw = case_setup(m)
        f2, cp2, kw2 = coop_case(m)
        assert (f, cp.noise_model) == (f2, cp2.noise_model) and set(kw) == set(kw2)
        assert np.array_equal(cp.Qtrue, cp2.Qtrue) and np.array_equal(cp.P0, cp2.P0)
        assert all(np.array_equal(kw[k], kw2[k]) for k in kw)
    with pytest.raises(ValueError, match="case"):
        case_setup("q_x2")


def test_false_alarm_rates_of_the_correct_filters_are_consistent_with_at_most_alpha(stored):
    lo, _ = stored.band(0.95)
    for name in ("ekf_correct", "lkf_correct"):
        assert np.all(lo[stored.mistakes.index(name)] <= stored.alpha), name


@pytest.mark.parametrize("kwargs, name", [
    (dict(cases=["nope"]), "cases"), (dict(cases=[]), "cases"), (dict(n_runs=[1]), "n_runs"),
    (dict(n_runs=[]), "n_runs"), (dict(reps=0), "reps"), (dict(seed=-1), "seed"), (dict(alpha=1.5), "alpha"),
    (dict(params="defaults"), "params"),
])
def test_bad_arguments_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        detection_rates(**kwargs)


@pytest.mark.slow  # the benchmark script in full (every stored row once): about 10 s
def test_the_benchmark_script_regenerates_the_stored_table(tmp_path, stored):
    # benchmarks/coop_detection_rates.py with one repetition: the first repetition of every stored row
    main = runpy.run_path(str(Path(__file__).parents[1] / "benchmarks" / "coop_detection_rates.py"))["main"]
    out = tmp_path / "coop.csv"
    assert main(["--reps", "1", "--out", str(out)]) == 0
    again = DetectionRates.from_csv(out)
    assert (again.mistakes, again.n_runs, again.checks) == (stored.mistakes, stored.n_runs, stored.checks)
    assert np.array_equal(again.failed, stored.first(1).failed)
