"""Monte Carlo checks: a consistent filter passes, a mismatched one fails."""

import numpy as np
import pytest

from kfcal_helpers.calibration import CHECK_NAMES, CalibrationParams, run_monte_carlo
from kfcal_helpers.consistency import Check, chi2_bounds

P0 = CalibrationParams()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_correct_filter_passes_every_check(seed):
    mc = run_monte_carlo(P0, n_runs=400, seed=seed)
    checks = mc.checks()
    assert set(checks) == set(CHECK_NAMES)
    for name, c in checks.items():
        assert c.passed, (name, c.worst)
        assert c.inside_fraction > 0.5, name
    # the run-averaged NEES and NIS hover around their dimension: averaged over the fixes (correlated
    # through the bias) the NEES has a standard deviation of about 0.08 for N = 400 (20 seeds), the NIS
    # (nearly independent fixes) about 0.01; bounds at about 4 standard deviations
    assert abs(mc.nees.mean() - 3) < 0.3 and abs(np.nanmean(mc.nis) - 2) < 0.05


def test_ensemble_sigma_agrees_with_P():
    mc = run_monte_carlo(P0, n_runs=2000, seed=4)
    np.testing.assert_allclose(mc.ensemble_sigma_final, mc.sigma_final, rtol=0.06)


def test_analytic_truth_is_caught():
    mc = run_monte_carlo(P0, n_runs=1000, seed=5, truth="analytic")
    checks = mc.checks()
    assert not checks["mean_error"].passed and not checks["nees"].passed
    assert checks["nees"].inside_fraction < 0.5


def test_filterpy_engine_gives_the_same_statistics():
    a = run_monte_carlo(P0, n_runs=6, seed=9, engine="batch")
    b = run_monte_carlo(P0, n_runs=6, seed=9, engine="filterpy")
    for name in ("e_mean", "e_cov", "orthogonality", "residual_moment", "nees", "nis"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-9, atol=1e-12)


def test_chunking_keeps_statistics_exact():
    """Sums over chunks of CHUNK_SIZE equal the statistics of one big array."""
    from kfcal_helpers.calibration import batch_filter, simulate
    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE

    from kfcal_helpers.calibration.montecarlo import chunk_generators

    n = CHUNK_SIZE + 7
    mc = run_monte_carlo(P0, n_runs=n, seed=12)
    chunks = chunk_generators(mc.params, n, 12)
    assert [size for size, _ in chunks] == [CHUNK_SIZE, 7]
    # every chunk has its own stream from SeedSequence(seed).spawn: simulate draws the same realizations
    sims = [simulate(mc.params, size, rng) for size, rng in chunks]
    e = np.concatenate([s.dx_at_fixes - batch_filter(mc.params, s.dz, full_rate=False).x_post for s in sims])
    # the Monte Carlo's error state at the fixes is computed without the 200 Hz arrays: the same to
    # rounding (the 200 Hz subtraction p - p_c loses about 1e-11 m)
    np.testing.assert_allclose(mc.e_mean, e.mean(0), rtol=1e-9, atol=1e-9 * e.std(axis=(0, 1)).max())
    np.testing.assert_allclose(mc.e_cov[-1], np.cov(e[:, -1].T), rtol=1e-9)


def test_outage_monte_carlo_runs_and_passes():
    missing = np.zeros(CalibrationParams().n_gps, bool)
    missing[50:75] = True
    # seed 3: at seed 2 this consistent filter raises a false alarm (residual independence 1.02 of its band
    # under alpha split over all 34,747 entries of the seven checks), which happens in about alpha of the seeds
    mc = run_monte_carlo(P0, n_runs=300, seed=3, missing_fixes=missing)
    assert np.isnan(mc.nis[50:75]).all()
    assert all(c.passed for c in mc.checks().values())


def test_chi2_bounds_match_spec_examples():
    np.testing.assert_allclose(chi2_bounds(6, 50), (5.078, 6.997), atol=1e-3)
    np.testing.assert_allclose(chi2_bounds(5, 50), (4.162, 5.914), atol=1e-3)


# --- between fixes: the 200 Hz error against the filter's predicted P -------------------------

@pytest.mark.parametrize("seed", [21, 22])
def test_between_fixes_correct_filter_passes(seed):
    mc = run_monte_carlo(P0, n_runs=400, seed=seed, between_fixes=True)
    c = mc.between_fixes_check()
    assert c.passed, c.worst
    assert c.statistic.size == 3 * (mc.params.n_imu - mc.params.n_gps)
    assert 0.8 < c.inside_fraction <= 1.0
    # the seven checks at the fixes do not change when the 200 Hz sums are added
    plain = run_monte_carlo(P0, n_runs=400, seed=seed)
    for name in CHECK_NAMES:
        assert mc.checks()[name].worst == plain.checks()[name].worst


def test_between_fixes_equals_the_direct_statistics_and_filterpy():
    from kfcal_helpers.calibration import batch_filter, run_filterpy, simulate

    from kfcal_helpers.calibration.montecarlo import chunk_generators

    n = 12
    mc = run_monte_carlo(P0, n_runs=n, seed=31, between_fixes=True)
    sim = simulate(mc.params, n, chunk_generators(mc.params, n, 31)[0][1])
    x = np.stack([run_filterpy(mc.params, sim.dz[l]).x for l in range(n)])  # filterpy at 200 Hz
    e = sim.dx - x
    np.testing.assert_allclose(mc.between.e_mean, e.mean(0), rtol=1e-9, atol=1e-9 * e.std(axis=(0, 1)).max())
    cov = np.einsum("nja,njb->jab", e - e.mean(0), e - e.mean(0)) / (n - 1)
    # covariances relative to sqrt(var_a var_b) (the 200 Hz simulation's own rounding is about 1e-11 m)
    sd = np.sqrt(np.einsum("jaa->ja", cov))
    scale = sd[:, :, None] * sd[:, None, :]
    np.testing.assert_allclose(mc.between.e_cov / scale, cov / scale, rtol=0, atol=1e-7)
    np.testing.assert_allclose(mc.between.P, batch_filter(mc.params, sim.dz[:1]).P, rtol=1e-12)
    fp = run_monte_carlo(P0, n_runs=n, seed=31, engine="filterpy", between_fixes=True)
    np.testing.assert_allclose(fp.between.e_cov / scale, mc.between.e_cov / scale, rtol=0, atol=1e-7)


def test_between_fixes_memory_does_not_grow_with_n():
    import tracemalloc

    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE

    params = CalibrationParams(duration=5.0)

    def peak(n_runs, workers):
        tracemalloc.start()
        try:
            run_monte_carlo(params, n_runs=n_runs, seed=1, between_fixes=True, workers=workers)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    one = peak(CHUNK_SIZE, 1)
    many = peak(3 * CHUNK_SIZE, 1)
    assert many < 1.2 * one, (one, many)  # the sums, not the realizations, are kept
    threads = peak(6 * CHUNK_SIZE, 2)
    assert threads < 2.2 * one, (one, threads)  # at most two chunks in flight on two threads


def test_checks_do_not_depend_on_between_fixes_in_a_long_scenario():
    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE, chunk_size

    params = CalibrationParams(imu_rate=1000.0, duration=60.0)
    assert chunk_size(params) < CHUNK_SIZE  # several chunks of a size set by the realization's length
    n = chunk_size(params) + 7
    plain = run_monte_carlo(params, n_runs=n, seed=1).checks()
    with_between = run_monte_carlo(params, n_runs=n, seed=1, between_fixes=True).checks()
    for name in CHECK_NAMES:
        assert plain[name].worst == with_between[name].worst, name


def test_between_fixes_catches_a_filter_that_holds_P():
    from kfcal_helpers.calibration.mistakes import mistaken_model

    p = CalibrationParams()
    mc = run_monte_carlo(p, n_runs=300, seed=4, between_fixes=True, model=mistaken_model(p, "no_propagation"))
    assert not mc.between_fixes_check().passed


def test_between_fixes_argument():
    with pytest.raises(ValueError, match="between_fixes"):
        run_monte_carlo(P0, n_runs=2, between_fixes="yes")
    with pytest.raises(ValueError, match="between_fixes"):
        run_monte_carlo(P0, n_runs=2).between_fixes_check()


def test_cli_json_has_the_between_fixes_check(capsys):
    import json

    from kfcal_helpers.cli import main

    assert main(["calibrate", "--runs", "60", "--seed", "2", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    c = d["checks"]["between_fixes"]
    assert c["passed"] is True and 0.0 <= c["inside_fraction"] <= 1.0 and c["worst"] <= 1.0


def _cli_checks(argv, capsys):
    """{check: worst} printed by calibrate as a table and as JSON, and the rest of the output."""
    import json

    from kfcal_helpers.cli import main

    assert main(["calibrate", *argv]) == 0
    table = capsys.readouterr().out
    rows = {}
    for line in table.splitlines():
        words = line.split()
        if len(words) == 4 and words[3] in ("pass", "FAIL"):
            rows[words[0]] = float(words[2])
    assert main(["calibrate", *argv, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    return rows, {name: c["worst"] for name, c in d["checks"].items()}, table, d


def test_cli_table_and_json_show_the_same_checks(capsys):
    rows, js, table, d = _cli_checks(["--runs", "60", "--seed", "2", "--truth", "analytic"], capsys)
    assert list(rows) == list(js) == [*CHECK_NAMES, "between_fixes"]
    assert all(f"{js[name]:.2f}" == f"{rows[name]:.2f}" for name in rows)
    assert "skipped_checks" not in d and "not run" not in table


def test_cli_says_in_both_outputs_when_between_fixes_does_not_fit(capsys, monkeypatch):
    """A run that fits only without the 200 Hz sums runs without them, and both outputs say why."""
    from kfcal_helpers import montecarlo as core
    from kfcal_helpers.calibration.cli import output_bytes
    from kfcal_helpers.calibration.montecarlo import estimate_run

    params = CalibrationParams(imu_rate=2000.0, duration=5.0)
    without = estimate_run(params, 20, extra_bytes=output_bytes(params))[0]
    with_between = estimate_run(params, 20, between_fixes=True, extra_bytes=output_bytes(params, between_fixes=True))[0]
    assert without < with_between
    monkeypatch.setattr(core, "MEMORY_LIMIT", (without + with_between) / 2)
    rows, js, table, d = _cli_checks(["--runs", "20", "--imu-rate", "2000", "--duration", "5"], capsys)
    assert list(rows) == list(js) == list(CHECK_NAMES)
    assert "between_fixes: not run: its 200 Hz sums over 10001 IMU samples" in table
    assert d["skipped_checks"]["between_fixes"].startswith("not run: its 200 Hz sums over 10001 IMU samples")


@pytest.mark.parametrize("n_runs", [10, 40])
def test_residual_correlation_band_has_its_level(n_runs):
    """The residual_independence band, fed independent zero-mean Gaussian residuals, rejects a share
    alpha of the pairs (within a binomial band), and equals the exact quantile of |rho|: for the
    uncentred correlation of two independent Gaussian vectors in R^N, rho^2 ~ Beta(1/2, (N-1)/2)."""
    from dataclasses import replace

    from scipy import stats

    mc = run_monte_carlo(P0, n_runs=n_runs, seed=0)
    n_gps = mc.params.n_gps
    rng = np.random.default_rng(2024 + n_runs)
    alpha, reps, outside, total = 0.05, 8, 0, 0
    for _ in range(reps):
        r = rng.standard_normal((n_runs, n_gps, 2)) * np.array([1.0, 0.04])   # any scale per component
        fake = replace(mc, residual_moment=np.einsum("nia,nmb->iamb", r, r) / n_runs)
        stat, _, lo, hi = fake.bands(alpha)["residual_independence"]
        outside += np.count_nonzero((stat < lo) | (stat > hi))
        total += stat.size
    # given r_i, the correlations of fix i with the other fixes are independent and have the same law:
    # the indicators are pairwise independent, so the share has the binomial standard deviation
    share, sd = outside / total, np.sqrt(alpha * (1 - alpha) / total)
    assert abs(share - alpha) < 4 * sd, (share, sd)
    for level in (alpha, alpha / 48622):   # pointwise, and the per-entry level of the seven checks at 151 fixes
        half = fake.bands(level)["residual_independence"][3].max()
        exact = np.sqrt(stats.beta.ppf(1 - level, 0.5, (n_runs - 1) / 2))
        assert np.isclose(half, exact, rtol=1e-9), (level, half, exact)


def test_between_fixes_check_refuses_when_every_sample_is_a_fix():
    params = CalibrationParams(gps_rate=200.0, duration=2.0)
    mc = run_monte_carlo(params, n_runs=5, seed=0, between_fixes=True)
    with pytest.raises(ValueError, match="between_fixes_check: every IMU sample is a GPS fix"):
        mc.between_fixes_check()


# --- threads: chunks with their own streams, sums in chunk order ------------------------------

def _same_result(a, b):
    for name in ("e_mean", "e_cov", "e_prior_mean", "e_prior_cov", "orthogonality", "xhat_sq_mean",
                 "residual_moment", "nees", "nis", "P_post", "S"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
    if a.between is not None:
        assert np.array_equal(a.between.e_mean, b.between.e_mean)
        assert np.array_equal(a.between.e_cov, b.between.e_cov)


def test_any_number_of_workers_gives_the_same_result_bit_for_bit():
    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE, chunk_sizes

    n = 3 * CHUNK_SIZE + 11
    assert len(chunk_sizes(P0, n)) == 4
    runs = [run_monte_carlo(P0, n, seed=8, workers=w) for w in (1, 2, 3)]
    for other in runs[1:]:
        _same_result(runs[0], other)
    assert runs[0].n_runs == n and all(c.passed for c in runs[0].checks().values())


@pytest.mark.parametrize("case", ["outage_between", "filterpy", "generator"])
def test_workers_do_not_change_other_modes(case, monkeypatch):
    from kfcal_helpers.calibration import montecarlo

    monkeypatch.setattr(montecarlo, "CHUNK_SIZE", 4)  # several chunks of a few realizations
    kw = {}
    if case == "outage_between":
        missing = np.zeros(P0.n_gps, bool)
        missing[30:60] = True
        kw = {"missing_fixes": missing, "between_fixes": True, "truth": "analytic"}
    elif case == "filterpy":
        kw = {"engine": "filterpy"}
    n = 10
    runs = []
    for w in (1, 2, 3):
        seed = np.random.default_rng(5) if case == "generator" else 5
        runs.append(run_monte_carlo(P0, n, seed=seed, workers=w, **kw))
    for other in runs[1:]:
        _same_result(runs[0], other)


def test_chunk_streams_are_spawned_from_the_seed():
    from kfcal_helpers.calibration.montecarlo import chunk_generators

    params = CalibrationParams(imu_rate=1000.0, duration=60.0)
    chunks = chunk_generators(params, 150, 3)
    assert len(chunks) > 1 and sum(size for size, _ in chunks) == 150
    kids = np.random.SeedSequence(3).spawn(len(chunks))
    for (_, rng), kid in zip(chunks, kids):
        assert rng.standard_normal() == np.random.Generator(np.random.PCG64DXSM(kid)).standard_normal()


def test_result_has_the_shared_interface():
    from kfcal_helpers.consistency import MonteCarloSummary, format_checks

    mc = run_monte_carlo(P0, 50, seed=1, between_fixes=True)
    assert isinstance(mc, MonteCarloSummary) and mc.n_runs == 50 and mc.alpha == 0.05 and mc.filter == "kf" and mc.engine == "batch"
    table = format_checks({**mc.checks(), "between_fixes": mc.between_fixes_check()})
    assert [line.split()[0] for line in table.splitlines()[2:]] == [*CHECK_NAMES, "between_fixes"]


# --- memory: the estimate bounds what is allocated, with every chunk in flight ------------------

def test_chunks_in_flight_are_bounded_by_memory():
    from kfcal_helpers.calibration.montecarlo import MEMORY_LIMIT, chunks_in_flight, estimate_run

    n = 5000
    assert chunks_in_flight(P0, n, workers=2) == 2
    assert chunks_in_flight(P0, 10, workers=2) == 1  # one chunk only
    one, _ = estimate_run(P0, n, workers=1)
    two, _ = estimate_run(P0, n, workers=2)
    assert two > one  # the second chunk in flight is counted
    # a long scenario between fixes: the batch filter needs the running sums of the IMU noise only, two
    # chunks fit; filterpy keeps its 200 Hz estimates of every realization of a chunk, only one fits
    long = CalibrationParams(imu_rate=1000.0, duration=60.0)
    assert chunks_in_flight(long, 1000, workers=2, between_fixes=True) == 2
    assert chunks_in_flight(long, 1000, workers=2, between_fixes=True, engine="filterpy") == 1
    assert chunks_in_flight(long, 1000, workers=2, engine="filterpy") == 2
    for engine in ("batch", "filterpy"):
        assert estimate_run(long, 100, engine, workers=2, between_fixes=True)[0] <= MEMORY_LIMIT


@pytest.mark.parametrize("params, n_runs, between, workers", [
    (CalibrationParams(), 1200, False, 2),
    (CalibrationParams(), 600, True, 2),
    (CalibrationParams(imu_rate=2000.0, duration=30.0, gps_rate=1.0), 60, True, 1),
    (CalibrationParams(gps_rate=40.0, duration=15.0), 5, False, 2),
    (CalibrationParams(imu_rate=20000.0, duration=20.0, gps_rate=1.0), 4, False, 2),
])
def test_estimate_bounds_the_traced_memory(params, n_runs, between, workers):
    """What numpy allocates during a run (tracemalloc; the interpreter excluded) stays under the
    estimate that estimate_run refuses on, with its chunks running on ``workers`` threads."""
    import tracemalloc

    from kfcal_helpers.calibration.montecarlo import estimate_run
    from kfcal_helpers.montecarlo import BASE_BYTES

    estimate = estimate_run(params, n_runs, between_fixes=between, workers=workers)[0] - BASE_BYTES
    tracemalloc.start()
    try:
        run_monte_carlo(params, n_runs, seed=0, between_fixes=between, workers=workers)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= estimate, (peak / 1e6, estimate / 1e6)


def test_peak_rss_on_two_threads_stays_under_the_limit():
    """A real process at the largest default-scenario runs, with the 200 Hz sums and on two threads.
    The peak is the child's own high-water mark (VmHWM): ``ru_maxrss`` of a child would include
    the resident size of this (large) test process at the moment it was spawned."""
    import subprocess
    import sys

    from kfcal_helpers.calibration.montecarlo import MEMORY_LIMIT

    hwm = ("[int(line.split()[1]) * 1024 for line in open('/proc/self/status') "
           "if line.startswith('VmHWM')][0]")
    code = ("from kfcal_helpers.calibration import CalibrationParams, run_monte_carlo; "
            "run_monte_carlo(CalibrationParams(), 2000, seed=0, between_fixes=True, workers=2); "
            f"print({hwm}); "
            "run_monte_carlo(CalibrationParams(), 4000, seed=0, workers=2); "
            f"print({hwm})")
    import os

    from kfcal_helpers.calibration.montecarlo import estimate_run

    env = {"KFCAL_QUIET": "1", "PATH": ""}
    if "PYTHONPATH" in os.environ:
        env["PYTHONPATH"] = os.environ["PYTHONPATH"]
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    peaks = [int(v) for v in r.stdout.split()]
    # each run's estimate bounds the high-water mark so far (the second run's estimate is the larger)
    estimates = [estimate_run(CalibrationParams(), 2000, between_fixes=True, workers=2)[0],
                 estimate_run(CalibrationParams(), 4000, workers=2)[0]]
    assert 100e6 < peaks[0] <= estimates[0] and peaks[1] <= max(estimates) <= MEMORY_LIMIT, (peaks, estimates)


def test_an_interrupted_threaded_run_does_not_hang(monkeypatch):
    """A KeyboardInterrupt in the calling thread (Ctrl-C in a notebook) ends the run at once: the
    chunks not started are cancelled and the running ones stop at their next realization.  Counted as
    work done: the realizations filterpy filtered (a hook on run_filterpy), not as wall time."""
    import threading
    import time

    from kfcal_helpers import montecarlo as core
    from kfcal_helpers.calibration import montecarlo

    monkeypatch.setattr(montecarlo, "CHUNK_SIZE", 50)
    calls = {"n": 0}
    filtered = []
    lock = threading.Lock()
    real = montecarlo.run_filterpy

    def counting(*args, **kwargs):
        out = real(*args, **kwargs)
        with lock:
            filtered.append(1)
        return out

    class Interrupting:
        def __init__(self, *a, **k):
            pass

        def update(self, n=1):
            calls["n"] += n
            if calls["n"] >= 3:
                raise KeyboardInterrupt

        def close(self):
            pass

    monkeypatch.setattr(montecarlo, "run_filterpy", counting)
    monkeypatch.setattr(core, "progress_bar", Interrupting)
    before = threading.active_count()
    with pytest.raises(KeyboardInterrupt):
        run_monte_carlo(P0, 400, seed=0, engine="filterpy", workers=2, progress=True)
    deadline = time.perf_counter() + 5
    while threading.active_count() > before and time.perf_counter() < deadline:
        time.sleep(0.05)
    assert threading.active_count() == before  # no worker left running
    # the bar had counted calls["n"] realizations when Ctrl-C came; each of the two threads then ends the
    # realization it is filtering (and, at most, one that started just before the flag was set)
    done = len(filtered)
    assert calls["n"] >= 3 and done <= calls["n"] + 2 * 2, (done, calls["n"])
    assert done < 50  # not even one chunk of 50 finished: 400 would have been filtered without the stop


# --- the refactoring onto the shared core changed no number ------------------------------------

def _old_route(params, n_runs, seed, truth="euler", missing=None):
    """The drawing and summing of the calibration Monte Carlo before it ran on the shared core, written
    out from public functions: draw_realizations + error_state_at_fixes + filter_estimates on the core's
    chunk streams, the same sums in chunk order, the same statistics."""
    from kfcal_helpers import montecarlo as core
    from kfcal_helpers.calibration.engine import covariance_sequence, filter_estimates
    from kfcal_helpers.calibration.montecarlo import chunk_size
    from kfcal_helpers.calibration.simulation import draw_realizations, error_state_at_fixes

    missing = np.zeros(params.n_gps, bool) if missing is None else missing
    P, P_prior, S, K = covariance_sequence(params, missing)
    n_gps, ok = params.n_gps, ~missing
    e, eb, x, m = np.zeros((n_gps, 3)), np.zeros((n_gps, 3)), np.zeros((n_gps, 3)), np.zeros((n_gps, 9, 9))
    rr = np.zeros((2 * ok.sum(), 2 * ok.sum()))
    N = 0
    for size, rng in core.chunk_generators(chunk_size(params), n_runs, seed):
        draws = draw_realizations(params, size, rng)
        dx = error_state_at_fixes(params, draws, truth)
        dz = dx[..., :2] + draws.eta
        dz[:, missing] = np.nan
        x_prior, x_post, y = filter_estimates(params, dz, K, missing)
        z = np.empty((n_gps, 9, size))
        np.subtract(dx.transpose(1, 2, 0), x_post.transpose(1, 2, 0), out=z[:, 0:3])
        np.subtract(dx.transpose(1, 2, 0), x_prior.transpose(1, 2, 0), out=z[:, 3:6])
        z[:, 6:9] = x_post.transpose(1, 2, 0)
        s = z.sum(axis=2)
        part = (s[:, 0:3], s[:, 3:6], s[:, 6:9], z @ z.transpose(0, 2, 1))
        r = y[:, ok].reshape(size, -1)
        part_rr = np.einsum("na,nb->ab", r, r)
        N += size
        for total, add in zip((e, eb, x, m), part):
            total += add
        rr += part_rr
    e_mean = e / N
    e_cov = (m[:, 0:3, 0:3] - N * np.einsum("ia,ib->iab", e_mean, e_mean)) / (N - 1)
    nees = np.einsum("iab,iab->i", np.linalg.inv(P[params.fix_indices]), m[:, 0:3, 0:3]) / N
    return {"e_mean": e_mean, "e_cov": e_cov, "nees": nees, "rr": rr / N}


@pytest.mark.parametrize("case", ["default", "analytic_outage", "generator"])
def test_the_core_route_equals_the_old_drawing_route_bit_for_bit(case):
    params, n, seed, kw = P0, 1011, 8, {}
    if case == "analytic_outage":
        missing = np.zeros(P0.n_gps, bool)
        missing[30:60] = True
        n, seed, kw = 30, 3, {"truth": "analytic", "missing": missing}
    mc = run_monte_carlo(P0, n, np.random.default_rng(77) if case == "generator" else seed,
                         truth=kw.get("truth", "euler"), missing_fixes=kw.get("missing"))
    old = _old_route(params, n, np.random.default_rng(77) if case == "generator" else seed, **kw)
    for name in ("e_mean", "e_cov", "nees"):
        assert np.array_equal(getattr(mc, name), old[name]), name
    ok = ~mc.missing
    moment = mc.residual_moment[ok][:, :, ok, :].reshape(old["rr"].shape)
    assert np.array_equal(moment, old["rr"])


# Values of the code before the refactoring (commit a0c294c), at full precision: the numbers the
# notebooks quote come from these routes.  Compared to 1e-12 (another machine's BLAS may round the
# summed outer products differently in the last bits).
PINNED = {
    "default": (P0, 1011, 8, {}, [0.47909206786786096, 0.6351447830019716, 0.5128437062105373,
                                   0.8169379237921947, 0.6879249632363945, 0.6958800713215174,
                                   0.6648353212473845], 2.9107537151545007),
    "analytic_outage_between": (P0, 30, 3, {"truth": "analytic", "between_fixes": True},
                                [3.8171841645765983, 0.7818935195479368, 0.5923921275453826,
                                 0.9404504253313312, 0.7215606473369052, 12.492197598847362,
                                 0.7239752885819429], 12.060293030880626),
    "generator": (P0, 20, None, {}, [0.5745728454426676, 0.7715052932758845, 0.6040392854915436,
                                     0.9700211093533742, 0.8515172659205523, 0.47103741037951713,
                                     0.7746958865103188], 2.9983975839325177),
}
PINNED_BETWEEN = {"default": (P0, 1011, 8, [0.6081736874832272, 0.9686609686609686]),
                  "analytic_outage_between": (P0, 30, 3, [0.7484737684887439, 0.98005698005698])}


def _worst_split_by_checks(mc) -> list:
    """The seven worst values under the split of the code before the one Bonferroni policy: alpha / 7 per
    check, split over that check's own entries (the pinned values below were computed that way)."""
    out = []
    for name in CHECK_NAMES:
        stat, expected, lo, hi = mc.band(name, mc.alpha)
        slo, shi = mc.band(name, mc.alpha / 7 / mc.entries(name))[2:]
        full = [np.broadcast_to(v, np.shape(stat)) for v in (expected, lo, hi, slo, shi)]
        out.append(Check(name, "d", stat, *full).worst)
    return out


@pytest.mark.parametrize("case", list(PINNED))
def test_numbers_equal_those_before_the_core(case):
    params, n, seed, kw, worst, nees_mean = PINNED[case]
    if case == "analytic_outage_between":
        missing = np.zeros(P0.n_gps, bool)
        missing[30:60] = True
        kw = {**kw, "missing_fixes": missing}
    mc = run_monte_carlo(params, n, np.random.default_rng(77) if seed is None else seed, **kw)
    # the statistics and bands of then, judged by the split of then (checks() now splits alpha over all entries
    # of the seven checks: tests/test_bonferroni_policy.py)
    np.testing.assert_allclose(_worst_split_by_checks(mc), worst, rtol=1e-12)
    np.testing.assert_allclose(mc.nees.mean(), nees_mean, rtol=1e-12)


@pytest.mark.parametrize("case", list(PINNED_BETWEEN))
def test_between_fixes_check_equals_the_one_before_the_core(case):
    params, n, seed, (worst, inside) = PINNED_BETWEEN[case]
    kw = {}
    if case == "analytic_outage_between":
        missing = np.zeros(P0.n_gps, bool)
        missing[30:60] = True
        kw = {"truth": "analytic", "missing_fixes": missing}
    c = run_monte_carlo(params, n, seed, between_fixes=True, **kw).between_fixes_check()
    assert c.inside_fraction == inside
    np.testing.assert_allclose(c.worst, worst, rtol=1e-9)


@pytest.mark.parametrize("case", ["euler", "analytic_outage", "mistaken_model", "short_last_period", "long"])
def test_between_fixes_by_linearity_equals_the_direct_formula(case):
    """The batch filter's 200 Hz sums (running sums of the IMU noise, by linearity) equal the direct
    formula of the earlier code, ``e = error_state_full - estimate_between_fixes`` summed over the
    realizations, to rounding: 1e-12 of the scale of each statistic."""
    from kfcal_helpers.calibration.engine import estimate_between_fixes
    from kfcal_helpers.calibration.mistakes import mistaken_model
    from kfcal_helpers.calibration.simulation import draw_realizations, error_state_full

    params, n, kw = P0, 40, {}
    if case == "analytic_outage":
        missing = np.zeros(P0.n_gps, bool)
        missing[30:60] = True
        kw = {"truth": "analytic", "missing_fixes": missing}
    elif case == "mistaken_model":
        kw = {"model": mistaken_model(P0, "no_propagation")}
    elif case == "short_last_period":  # 5.1 s at 4 Hz: 5 samples after the last fix
        params = CalibrationParams(duration=5.1, imu_rate=100.0, gps_rate=4.0)
    elif case == "long":
        params, n = CalibrationParams(imu_rate=1000.0, duration=20.0, gps_rate=2.0), 12
    assert params.n_imu > (params.n_gps - 1) * params.steps_per_fix
    mc = run_monte_carlo(params, n, 5, between_fixes=True, workers=1, **kw)
    (size, rng), = chunk_generators_of(params, n, 5)
    draws = draw_realizations(params, size, rng)
    truth = kw.get("truth", "euler")
    # the estimate at the fixes is the Monte Carlo's own (redrawn the same way), then predicted
    from kfcal_helpers.calibration.engine import covariance_sequence, filter_estimates
    from kfcal_helpers.calibration.simulation import error_state_at_fixes

    missing = kw.get("missing_fixes", np.zeros(params.n_gps, bool))
    model = kw.get("model")
    K = covariance_sequence(params, missing, model).K
    dx = error_state_at_fixes(params, draws, truth)
    dz = dx[..., :2] + draws.eta
    dz[:, missing] = np.nan
    x_post = filter_estimates(params, dz, K, missing, model)[1]
    e = error_state_full(params, draws, truth) - estimate_between_fixes(params, x_post, model)
    mean = e.mean(0)
    cov = np.einsum("nja,njb->jab", e - mean, e - mean) / (n - 1)
    sd = np.sqrt(np.einsum("jaa->ja", cov))
    sd[:, 2] = np.maximum(sd[:, 2], 1e-300)
    assert np.abs(mc.between.e_mean - mean).max() <= 1e-12 * np.abs(mean).max() + 1e-12 * sd.max()
    scale = np.maximum(sd[:, :, None] * sd[:, None, :], 1e-12 * sd.max() ** 2)
    assert np.max(np.abs(mc.between.e_cov - cov) / scale) < 1e-9


def chunk_generators_of(params, n, seed):
    from kfcal_helpers.calibration.montecarlo import chunk_generators

    return chunk_generators(params, n, seed)
