"""kfcal_helpers.calibration.power: the detection rates of notebook 06b.  The stored table is what
detection_rates computes (a subset recomputed with the same seeds gives the same failed checks, and
with other seeds a rate consistent with the stored one), its CSV round-trips, its bands are the exact
binomial (Clopper-Pearson) bands, the correct filter's false-alarm rate is consistent with at most
alpha, and bad arguments raise ValueError naming the argument."""

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers.calibration import CHECK_NAMES, CalibrationParams, run_monte_carlo
from kfcal_helpers.calibration.mistakes import MISTAKES, mistaken_model
from kfcal_helpers.calibration.power import (DEFAULT_N_RUNS, DetectionRates, detection_rates, repetition_seed,
                                             stored_detection_rates)


@pytest.fixture(scope="module")
def stored():
    return stored_detection_rates()


def test_stored_table_covers_every_mistake_and_n(stored):
    assert stored.mistakes == tuple(MISTAKES) and stored.mistakes[0] == "correct"
    assert stored.n_runs == DEFAULT_N_RUNS and stored.reps >= 100 and stored.alpha == 0.05
    assert stored.failed.shape == (len(MISTAKES), len(DEFAULT_N_RUNS), stored.reps, len(CHECK_NAMES))
    assert np.array_equal(stored.counts, stored.detected.sum(axis=-1))


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
    assert (back.mistakes, back.n_runs, back.reps, back.seed, back.alpha) == (t.mistakes, t.n_runs, 5, t.seed, t.alpha)
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
    lo, _ = stored.band(0.95)
    assert np.all(lo[0] <= stored.alpha)


def test_rate_lookup(stored):
    assert stored.rate("correct", 10) == stored.rates[0, 0]
    with pytest.raises(ValueError, match="n_runs"):
        stored.rate("correct", 11)
    with pytest.raises(ValueError, match="mistake"):
        stored.rate("nope", 10)


@pytest.mark.parametrize("kwargs, name", [
    (dict(mistakes=["nope"]), "mistakes"), (dict(mistakes=[]), "mistakes"), (dict(n_runs=[1]), "n_runs"),
    (dict(n_runs=[]), "n_runs"), (dict(reps=0), "reps"), (dict(seed=-1), "seed"), (dict(alpha=1.5), "alpha"),
    (dict(params="defaults"), "params"),
])
def test_bad_arguments_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        detection_rates(**kwargs)


def test_bad_confidence_and_first(stored):
    with pytest.raises(ValueError, match="confidence"):
        stored.band(95)
    with pytest.raises(ValueError, match="reps"):
        stored.first(stored.reps + 1)
