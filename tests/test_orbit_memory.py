"""Memory of the orbit truth-model test: the estimate refuses what would exceed 500 MB (the command line
with one line and exit 2), and bounds the peak resident memory a real process reaches (the slow tier)."""

import os

import pytest
from child_memory import command_peak

from kfcal_helpers.cli import main
from kfcal_helpers.montecarlo import MEMORY_LIMIT
from kfcal_helpers.orbit import OrbitParams
from kfcal_helpers.orbit.cli import OUTPUT_BYTES, estimate_truth_model_test


def _largest_accepted(filter, workers=2):
    """The most runs the estimate accepts for the command line (bisection on the estimate only)."""
    lo, hi = 2, 10_000
    while lo < hi:
        mid = (lo + hi + 1) // 2
        try:
            estimate_truth_model_test(OrbitParams(), mid, filter=filter, workers=workers, extra_bytes=OUTPUT_BYTES)
            lo = mid
        except ValueError:
            hi = mid - 1
    return lo


def test_the_estimate_grows_with_the_runs_and_names_the_argument():
    small = estimate_truth_model_test(OrbitParams(), 1300, filter="ekf", workers=2)
    big = estimate_truth_model_test(OrbitParams(), 1400, filter="ekf", workers=2)
    assert small.in_flight == big.in_flight == 1 and small.fits and big.fits
    # the per-run arrays kept (NEES, NIS, dof, 4 errors, 4 two-sigma bounds) and the checks' temporaries
    assert big.peak_bytes - small.peak_bytes == pytest.approx(100 * 1401 * (11 + 12) * 8)
    with pytest.raises(ValueError, match=r"^--runs: 5000 realizations .* more than the 500 MB allowed"):
        estimate_truth_model_test(OrbitParams(), 5000, runs_name="--runs")
    assert 1000 < _largest_accepted("lkf") < 5000


def test_too_many_runs_are_refused_by_the_command_line(capsys):
    runs = _largest_accepted("lkf") + 1
    assert main(["orbit", "--runs", str(runs), "--filter", "lkf"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert captured.out == "" and len(lines) == 1 and f"--runs: {runs} realizations" in lines[0]


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="VmHWM is read from /proc (Linux)")
@pytest.mark.parametrize("filter,runs", [("lkf", None), ("ukf", 100)])
def test_estimate_bounds_the_peak_rss_of_a_child_process(filter, runs):
    """``orbit --runs N`` in a child process on two threads, at the largest N the estimate accepts (LKF) and
    for the UKF's sigma points at one chunk (100 runs, where the chunk's share of the peak is largest): the child's high-water mark (VmHWM) stays under the estimate, which is not
    loose either (at least half of it is used)."""
    runs = _largest_accepted(filter) if runs is None else runs
    est = estimate_truth_model_test(OrbitParams(), runs, filter=filter, workers=2, extra_bytes=OUTPUT_BYTES)
    out, peak = command_peak(["orbit", "--runs", str(runs), "--filter", filter, "--json"], timeout=900)
    assert f'"n_runs": {runs}' in out
    assert 0.5 * est.peak_bytes < peak <= est.peak_bytes <= MEMORY_LIMIT, (peak / 1e6, est.peak_bytes / 1e6)
