"""kfcal_helpers.calibration.power: the detection rates of notebook 06b.  Each stored table (the seven
checks, and the assignment's four as a family of their own) is what detection_rates computes (a subset recomputed with the same seeds gives the same failed checks, and
with other seeds a rate consistent with the stored one), its CSV round-trips, its bands are the exact
binomial (Clopper-Pearson) bands, the correct filter's false-alarm rate is consistent with at most
alpha over all N together (at N = 80 alone it is not: 20 of 200, all by the residual-independence check, a
rare draw of those seeds: the stored fresh-seed table, 1000 other seeds at N = 10 and 80, is consistent with
at most alpha, and a subset of it recomputed gives the same failed checks, slow tier), and bad arguments raise ValueError naming the argument."""

from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers.calibration import ASSIGNMENT_CHECKS, CHECK_NAMES, CalibrationParams, run_monte_carlo
from kfcal_helpers.calibration.mistakes import MISTAKES, mistaken_model
from kfcal_helpers.calibration.power import (DEFAULT_N_RUNS, DetectionRates, detection_rates, repetition_seed,
                                             stored_detection_rates)
from kfcal_helpers.power import write_by_n


@pytest.fixture(scope="module")
def stored():
    return stored_detection_rates()


@pytest.fixture(scope="module")
def stored4():
    return stored_detection_rates("assignment")


def test_stored_table_covers_every_mistake_and_n(stored):
    assert stored.mistakes == tuple(MISTAKES) and stored.mistakes[0] == "correct"
    assert stored.n_runs == DEFAULT_N_RUNS and stored.reps >= 100 and stored.alpha == 0.05
    assert stored.failed.shape == (len(MISTAKES), len(DEFAULT_N_RUNS), stored.reps, len(CHECK_NAMES))
    assert stored.checks == CHECK_NAMES
    assert np.array_equal(stored.counts, stored.detected.sum(axis=-1))


def test_stored_assignment_table_has_the_same_repetitions_judged_by_the_four_checks(stored, stored4):
    assert ASSIGNMENT_CHECKS == ("mean_error", "covariance", "orthogonality", "residual_independence",
                                 "residual_variance")
    assert stored4.checks == ASSIGNMENT_CHECKS
    assert stored4.mistakes == ("correct", "phi02_sign", "w_is_gps_velocity_var")
    assert (stored4.n_runs, stored4.reps, stored4.seed, stored4.alpha) == (
        DEFAULT_N_RUNS[:-1], stored.reps, stored.seed, stored.alpha)
    # the same Monte Carlos; the four split alpha over their 48,320 entries instead of the seven's 48,622, so
    # their bands are narrower: each fails at least where it failed among the seven
    seven = stored.only(ASSIGNMENT_CHECKS).failed[[stored.mistakes.index(m) for m in stored4.mistakes]]
    assert np.all(stored4.failed >= seven[:, :len(stored4.n_runs)])


def test_the_assignment_subset_recomputed_with_the_same_seeds_gives_the_same_failed_checks(stored4):
    names, ns, reps = ["correct", "w_is_gps_velocity_var"], [40, 160], 4
    again = detection_rates(names, ns, reps=reps, seed=stored4.seed, checks="assignment")
    a = [stored4.mistakes.index(m) for m in names]
    j = [stored4.n_runs.index(n) for n in ns]
    assert again.checks == ASSIGNMENT_CHECKS
    assert np.array_equal(again.failed, stored4.failed[np.ix_(a, j)][:, :, :reps])


def test_the_four_checks_are_a_family_of_their_own():
    # the same Monte Carlo judged by the assignment's four checks alone: alpha is split over the entries of
    # their five check names instead of the seven's, so their simultaneous bands are narrower; the pointwise
    # bands are the same
    p = CalibrationParams()
    mc = run_monte_carlo(p, 40, seed=3, model=mistaken_model(p, "w_is_gps_velocity_var"))
    seven, four = mc.checks(), mc.checks(ASSIGNMENT_CHECKS)
    assert tuple(four) == ASSIGNMENT_CHECKS
    for name in ASSIGNMENT_CHECKS:
        assert np.array_equal(four[name].lower, seven[name].lower)
        w4, w7 = four[name].sim_upper - four[name].sim_lower, seven[name].sim_upper - seven[name].sim_lower
        assert np.all(w4 <= w7) and np.all(w4[w7 > 0] < w7[w7 > 0])      # (a zero-width band stays zero)
        level = 0.05 / sum(mc.entries(n) for n in ASSIGNMENT_CHECKS)               # 0.05 / 48320
        assert np.allclose(four[name].sim_upper, np.ravel(np.broadcast_to(mc.band(name, level)[3],
                                                                          np.shape(mc.band(name, level)[0]))))
    with pytest.raises(ValueError, match="names"):
        mc.checks(["nope"])
    with pytest.raises(ValueError, match="names"):
        mc.checks([])


def test_a_subset_recomputed_with_the_same_seeds_gives_the_same_failed_checks(stored):
    names, ns, reps = ["correct", "w_is_gps_velocity_var"], [10, 160, 1000], 6
    again = detection_rates(names, ns, reps=reps, seed=stored.seed)
    a = [stored.mistakes.index(m) for m in names]
    j = [stored.n_runs.index(n) for n in ns]
    assert np.array_equal(again.failed, stored.failed[np.ix_(a, j)][:, :, :reps])


def test_a_subset_recomputed_with_other_seeds_agrees_with_the_stored_rate(stored):
    # 30 fresh repetitions of the W mistake at N = 40 against the stored ones: Fisher's exact test of two
    # binomial samples does not reject at the 1 % level, and the fresh rate is inside the stored 99 % band
    # widened by the fresh sample's own 99 % band
    fresh = detection_rates(["w_is_gps_velocity_var"], [40], reps=30, seed=stored.seed + 1)
    k_new, k_old = int(fresh.counts[0, 0]), int(stored.counts[4, 2])
    assert stored.mistakes[4] == "w_is_gps_velocity_var" and stored.n_runs[2] == 40
    table = [[k_new, 30 - k_new], [k_old, stored.reps - k_old]]
    assert stats.fisher_exact(table).pvalue > 0.01
    lo, hi = stored.band(0.99)
    flo, fhi = fresh.band(0.99)
    assert fhi[0, 0] >= lo[4, 2] and flo[0, 0] <= hi[4, 2]


def test_a_repetition_is_one_run_monte_carlo():
    # repetition 3 at N = 40 of the W mistake: the same failed checks as the Monte Carlo it stands for
    p = CalibrationParams()
    t = detection_rates(["w_is_gps_velocity_var"], [40], reps=4, seed=7)
    mc = run_monte_carlo(p, 40, seed=repetition_seed(7, 40, 3), model=mistaken_model(p, "w_is_gps_velocity_var"))
    assert t.failed[0, 0, 3].tolist() == [not mc.checks()[c].passed for c in CHECK_NAMES]


def test_csv_round_trip_and_first(tmp_path, stored):
    t = stored.first(5)
    path = tmp_path / "rates.csv"
    t.to_csv(path)
    back = DetectionRates.from_csv(path)
    assert (back.mistakes, back.n_runs, back.reps, back.seed, back.alpha, back.checks) == (
        t.mistakes, t.n_runs, 5, t.seed, t.alpha, t.checks)
    assert np.array_equal(back.failed, t.failed)
    lines = path.read_text().splitlines()
    fields = lines[1].split(",")
    fields[5] = str(int(fields[5]) + 1)                 # a 'detected' count that disagrees with its bits
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([lines[0], ",".join(fields)] + lines[2:]) + "\n")
    with pytest.raises(ValueError, match="path"):
        DetectionRates.from_csv(bad)
    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="path"):
        DetectionRates.from_csv(tmp_path / "other.csv")


def test_bands_are_clopper_pearson(stored):
    lo, hi = stored.band(0.95)
    k, n = stored.counts, stored.reps
    # Clopper-Pearson from the beta distribution, 0 / 1 at the ends
    lo_beta = np.where(k == 0, 0.0, stats.beta.ppf(0.025, k, n - k + 1))
    hi_beta = np.where(k == n, 1.0, stats.beta.ppf(0.975, k + 1, n - k))
    assert np.allclose(lo, lo_beta, atol=1e-9) and np.allclose(hi, hi_beta, atol=1e-9)
    assert np.all((lo <= stored.rates) & (stored.rates <= hi))


def test_false_alarm_rate_of_the_correct_filter_is_consistent_with_at_most_alpha(stored):
    """Over all N together the correct filter's false alarms are consistent with at most alpha; per N they are
    at every N but 80, where 20 of the 200 repetitions fail, each by the residual-independence check alone
    (notebooks 06 and 06b state it)."""
    lo, _ = stored.band(0.95)
    j80 = stored.n_runs.index(80)
    assert np.all(np.delete(lo[0], j80) <= stored.alpha) and lo[0, j80] > stored.alpha
    k = int(stored.counts[0].sum())
    assert stats.binomtest(k, stored.reps * len(stored.n_runs)).proportion_ci(0.95, method="exact").low <= stored.alpha
    ri = np.array(CHECK_NAMES) == "residual_independence"
    assert np.all(stored.failed[0, j80][stored.detected[0, j80]] == ri)


def test_the_fresh_seed_table_of_the_correct_filter_is_consistent_with_at_most_alpha(stored):
    """The stored fresh-seed table (benchmarks/detection_rates.py --fresh): the correct filter alone, 1000
    repetitions at N = 10 and 80 on seeds other than the main table's; at both N its false-alarm rate is
    consistent with at most alpha (at N = 80 too, where the main table's 200 seeds gave 20 false alarms), and
    the W mistake fails the residual-independence check on exactly the correct filter's repetitions at N = 80."""
    fresh = stored_detection_rates("fresh")
    assert fresh.mistakes == ("correct",) and fresh.n_runs == (10, 80) and fresh.reps == 1000
    assert fresh.checks == CHECK_NAMES and fresh.alpha == stored.alpha and fresh.seed != stored.seed
    lo, hi = fresh.band(0.95)
    assert np.all(lo[0] <= fresh.alpha) and np.all(fresh.alpha < hi[0] + 0.01)
    j80, ri = stored.n_runs.index(80), CHECK_NAMES.index("residual_independence")
    w = stored.mistakes.index("w_is_gps_velocity_var")
    assert np.array_equal(stored.failed[0, j80, :, ri], stored.failed[w, j80, :, ri])


@pytest.mark.slow
def test_a_subset_of_the_fresh_seed_table_recomputed_gives_the_same_failed_checks():
    """The first 100 repetitions of the stored fresh-seed table at N = 10 and 80, recomputed with its seed."""
    fresh = stored_detection_rates("fresh")
    reps = 100
    again = detection_rates(["correct"], list(fresh.n_runs), reps=reps, seed=fresh.seed)
    assert np.array_equal(again.failed, fresh.failed[:, :, :reps])


def test_the_repetitions_only_phi02_sign_fails_fail_the_orthogonality_check_alone(stored):
    """Notebook 06b: at N = 1000 the 4 repetitions failed by phi02_sign and not by the correct filter (none the
    other way) all failed the orthogonality check and no other: a real effect, not chance; the one at N = 640
    failed the residual-independence check, as the correct filter's false alarms do."""
    ph, c0 = stored.mistakes.index("phi02_sign"), stored.mistakes.index("correct")
    names = np.array(CHECK_NAMES)
    for n, n_only, check in ((640, 1, "residual_independence"), (1000, 4, "orthogonality")):
        j = stored.n_runs.index(n)
        only = stored.detected[ph, j] & ~stored.detected[c0, j]
        assert not np.any(stored.detected[c0, j] & ~stored.detected[ph, j])
        assert np.all(stored.failed[ph, j][only] == (names == check))
        assert int(only.sum()) == n_only


def test_rate_lookup(stored):
    assert stored.rate("correct", 10) == stored.rates[0, 0]
    with pytest.raises(ValueError, match="n_runs"):
        stored.rate("correct", 11)
    with pytest.raises(ValueError, match="mistake"):
        stored.rate("nope", 10)


@pytest.mark.parametrize("kwargs, name", [
    (dict(mistakes=["nope"]), "mistakes"), (dict(mistakes=[]), "mistakes"), (dict(n_runs=[1]), "n_runs"),
    (dict(n_runs=[]), "n_runs"), (dict(reps=0), "reps"), (dict(seed=-1), "seed"), (dict(alpha=1.5), "alpha"),
    (dict(params="defaults"), "params"), (dict(checks="four"), "checks"),
])
def test_bad_arguments_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        detection_rates(**kwargs)


def test_only_and_joined(stored):
    nees = stored.only(["nees"])
    assert nees.checks == ("nees",) and np.array_equal(nees.failed[..., 0], stored.failed[..., CHECK_NAMES.index("nees")])
    assert np.array_equal(stored.only(CHECK_NAMES).rates, stored.rates)
    with pytest.raises(ValueError, match="checks"):
        stored.only(["nope"])
    with pytest.raises(ValueError, match="checks"):
        stored.only([])
    a = DetectionRates(stored.mistakes, stored.n_runs[:2], stored.reps, stored.seed, stored.alpha,
                       stored.failed[:, :2], stored.checks)
    b = DetectionRates(stored.mistakes, stored.n_runs[2:], stored.reps, stored.seed, stored.alpha,
                       stored.failed[:, 2:], stored.checks)
    assert np.array_equal(a.joined(b).failed, stored.failed) and a.joined(b).n_runs == stored.n_runs
    with pytest.raises(ValueError, match="other"):
        a.joined(b.only(["nees"]))


def test_bad_confidence_and_first(stored):
    with pytest.raises(ValueError, match="confidence"):
        stored.band(95)
    with pytest.raises(ValueError, match="reps"):
        stored.first(stored.reps + 1)


@pytest.mark.slow  # the benchmark script in full (every stored row once): about 10 s
def test_the_benchmark_script_regenerates_the_stored_tables(tmp_path, stored, stored4):
    # benchmarks/detection_rates.py with one repetition of two mistakes: the first repetition of the stored rows
    import runpy
    main = runpy.run_path(str(Path(__file__).parents[1] / "benchmarks" / "detection_rates.py"))["main"]
    names = ["correct", "w_is_gps_velocity_var"]
    for checks, table in (("all", stored), ("assignment", stored4)):
        out = tmp_path / f"{checks}.csv"
        assert main(["--reps", "1", "--checks", checks, "--mistakes", *names, "--n-runs", "10", "40",
                     "--out", str(out)]) == 0
        again = DetectionRates.from_csv(out)
        assert again.mistakes == tuple(names) and again.n_runs == (10, 40) and again.checks == table.checks
        rows = [table.mistakes.index(m) for m in names]
        assert np.array_equal(again.failed, table.first(1).failed[rows][:, [0, 2]])


def test_write_by_n_writes_a_valid_table_after_each_n(tmp_path, stored):
    path, lines = tmp_path / "t.csv", []

    def compute(n):
        j = stored.n_runs.index(n)
        if n == 40:   # the file holds the N values done so far
            assert DetectionRates.from_csv(path).n_runs == (10, 20)
        return DetectionRates(stored.mistakes, (n,), stored.reps, stored.seed, stored.alpha,
                              stored.failed[:, j:j + 1], stored.checks)

    table = write_by_n(compute, [10, 20, 40], path, log=lines.append)
    assert table.n_runs == (10, 20, 40) and np.array_equal(DetectionRates.from_csv(path).failed, stored.failed[:, :3])
    assert len(lines) == 3 and lines[-1].startswith("N =    40 done after")
