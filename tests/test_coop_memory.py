"""Memory of the coop truth-model test: the estimate refuses what would exceed 500 MB (the command line
with one line and exit 2), and bounds the peak resident memory a real process reaches (the slow tier:
``pytest -m slow``; ``.ci/run`` runs it after ``pytest``)."""

import os

import pytest
from child_memory import command_peak

from kfcal_helpers.cli import main
from kfcal_helpers.coop import CoopParams
from kfcal_helpers.coop.montecarlo import estimate_truth_model_test
from kfcal_helpers.montecarlo import MEMORY_LIMIT


def _largest_accepted(filter, workers=2):
    """The most runs of 100 s the estimate accepts (bisection on the estimate only)."""
    lo, hi = 1, 10_000
    while lo < hi:
        mid = (lo + hi + 1) // 2
        try:
            estimate_truth_model_test(CoopParams(), mid, filter=filter, workers=workers)
            lo = mid
        except ValueError:
            hi = mid - 1
    return lo


@pytest.mark.parametrize("runs", [4000, 10_000])
def test_too_many_runs_are_refused_with_the_estimate(capsys, runs):
    assert main(["coop", "--runs", str(runs), "--filter", "lkf"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert captured.out == "" and len(lines) == 1, captured.err
    assert f"--runs: {runs} realizations" in lines[0] and "MB, more than the 500 MB allowed" in lines[0]


def test_the_estimate_grows_with_the_runs_and_names_the_argument():
    small = estimate_truth_model_test(CoopParams(), 500, filter="ekf", workers=2)
    big = estimate_truth_model_test(CoopParams(), 1000, filter="ekf", workers=2)
    # the per-run arrays kept: NEES, NIS, 6 errors, 6 two-sigma bounds per step, float64 (same chunks in flight)
    assert small.in_flight == big.in_flight == 2
    assert small.fits and big.fits and big.peak_bytes - small.peak_bytes == pytest.approx(500 * 1001 * 14 * 8)
    with pytest.raises(ValueError, match=r"^n_runs: 4000 realizations"):
        estimate_truth_model_test(CoopParams(), 4000, filter="lkf")
    assert 1500 < _largest_accepted("lkf") < 4000


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="VmHWM is read from /proc (Linux)")
@pytest.mark.parametrize("filter,runs", [("lkf", None), ("ukf", 300)])
def test_estimate_bounds_the_peak_rss_of_a_child_process(filter, runs):
    """``coop --runs N`` in a child process on two threads, at the largest N the estimate accepts (LKF)
    and for the UKF's sigma points: the child's own high-water mark (VmHWM) stays under the estimate,
    which is not loose either (at least half of it is used: with chunks on two threads the estimate also counts
    the end's statistics on top of the chunks, since memory freed by a worker thread stays with its allocator)."""
    runs = _largest_accepted(filter) if runs is None else runs
    est = estimate_truth_model_test(CoopParams(), runs, filter=filter, workers=2)
    out, peak = command_peak(["coop", "--runs", str(runs), "--filter", filter, "--json"], timeout=900)
    assert f'"n_runs": {runs}' in out
    assert 0.5 * est.peak_bytes < peak <= est.peak_bytes <= MEMORY_LIMIT, (peak / 1e6, est.peak_bytes / 1e6)


def test_a_run_too_long_for_memory_names_the_params():
    """Even one realization of 500,001 steps does not fit: the refusal names the scenario, before any work."""
    from dataclasses import replace

    from kfcal_helpers.coop import truth_model_test

    with pytest.raises(ValueError, match=r"^params: .*500001 steps of the EKF.*use a smaller scenario"):
        truth_model_test(replace(CoopParams(), duration=50_000.0), 2)
