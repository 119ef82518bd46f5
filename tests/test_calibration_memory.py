"""The memory estimate of ``calibrate`` bounds the peak resident memory of a real process on every
path: the table and ``--json`` (both with the 200 Hz check between fixes when it fits), ``--figures``,
the filterpy engine, at the largest runs the estimate accepts.

The peak is the child's own high-water mark (VmHWM, Linux): ``ru_maxrss`` of a child would include the
resident size of this (large) test process at the moment it was spawned.  Each case searches the
longest duration the estimate accepts (cheap: no simulation) and runs the command line there.  The
child processes are the slow tier (``pytest -m slow``; ``.ci/run`` runs it after ``pytest``).
"""

import json
import os
import subprocess
import sys

import pytest

from kfcal_helpers.calibration import CalibrationParams
from kfcal_helpers.calibration import cli as calibration_cli
from kfcal_helpers.calibration.cli import output_bytes, plan_between_fixes
from kfcal_helpers.cli import main
from kfcal_helpers.calibration.montecarlo import MEMORY_LIMIT, estimate_run

pytestmark = pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs /proc (Linux) for VmHWM")

CHILD = ("import sys; from kfcal_helpers.cli import main; rc = main(sys.argv[1:]); "
         "print([int(line.split()[1]) for line in open('/proc/self/status') if line.startswith('VmHWM')][0], "
         "file=sys.stderr); sys.exit(rc)")


def _plan(params, runs, engine, figures):
    """``(between, estimated peak bytes)`` of ``calibrate`` for ``params``, as its run() plans it."""
    between, _ = plan_between_fixes(params, runs, engine, figures)
    peak = estimate_run(params, runs, engine, between_fixes=between,
                        extra_bytes=output_bytes(params, figures, between))[0]
    return between, peak


def _largest(imu_rate, gps_rate, runs, engine="batch", figures=False, between=None):
    """The longest duration (whole GPS periods) the estimate accepts, with the 200 Hz check (between
    True), without it (False) or either (None); returns (params, between, estimated peak)."""
    def accepted(k):
        try:
            b, _ = _plan(CalibrationParams(imu_rate=imu_rate, gps_rate=gps_rate, duration=k / gps_rate), runs,
                         engine, figures)
        except ValueError:
            return False
        return between is None or b == between
    lo, hi = 1, 1
    while accepted(hi):
        lo, hi = hi, hi * 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if accepted(mid) else (lo, mid)
    params = CalibrationParams(imu_rate=imu_rate, gps_rate=gps_rate, duration=lo / gps_rate)
    return (params, *_plan(params, runs, engine, figures))


def _argv(params, runs, engine, output, figures_dir=None):
    """``calibrate``'s arguments for ``params`` (figures into ``figures_dir`` when given)."""
    argv = ["calibrate", "--imu-rate", f"{params.imu_rate:g}", "--gps-rate", f"{params.gps_rate:g}",
            "--duration", repr(params.duration), "--runs", str(runs), "--engine", engine, *output]
    return argv + (["--figures", str(figures_dir)] if figures_dir is not None else [])


CASES = {  # (imu Hz, gps Hz, runs, engine, figures, between wanted, output)
    "fixes-table": (200.0, 40.0, 5, "batch", False, None, []),
    "fixes-json": (200.0, 40.0, 5, "batch", False, None, ["--json"]),
    "between-json": (1000.0, 5.0, 50, "batch", False, True, ["--json"]),
    "between-table": (2000.0, 1.0, 5, "batch", False, True, []),
    "samples-json": (20000.0, 1.0, 3, "batch", False, None, ["--json"]),
    "long-period-json": (20000.0, 0.5, 3, "batch", False, True, ["--json"]),
    "many-runs-json": (200.0, 5.0, 2000, "batch", False, True, ["--json"]),
    "figures": (200.0, 40.0, 5, "batch", True, None, []),
    "filterpy-json": (200.0, 5.0, 2, "filterpy", False, True, ["--json"]),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_estimate_bounds_the_peak_of_a_child_at_the_largest_accepted_run(case, tmp_path):
    imu, gps, runs, engine, figures, between, output = CASES[case]
    if engine == "filterpy":  # a short scenario: filterpy takes about 6 us per IMU sample and realization
        params = CalibrationParams(duration=120.0)
        between, estimate = _plan(params, runs, engine, figures)
    else:
        params, between, estimate = _largest(imu, gps, runs, engine, figures, between)
    argv = _argv(params, runs, engine, output, tmp_path if figures else None)
    env = {"KFCAL_QUIET": "1", "PATH": os.environ.get("PATH", ""), "MPLBACKEND": "Agg",
           "MPLCONFIGDIR": str(tmp_path / "mpl"), "HOME": str(tmp_path)}
    if "PYTHONPATH" in os.environ:
        env["PYTHONPATH"] = os.environ["PYTHONPATH"]
    r = subprocess.run([sys.executable, "-c", CHILD, *argv], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    peak = int(r.stderr.strip().splitlines()[-1]) * 1024  # VmHWM is in kB
    if output:  # the JSON and the table show the same checks: between_fixes when it was run
        shown = "between_fixes" in json.loads(r.stdout)["checks"]
    else:
        shown = any(line.split()[:1] == ["between_fixes"] for line in r.stdout.splitlines())
    assert shown == between
    assert peak <= estimate <= MEMORY_LIMIT, (case, argv, peak / 1e6, estimate / 1e6)


@pytest.mark.parametrize("case", [c for c in CASES if CASES[c][3] == "batch"])
def test_one_period_more_than_the_largest_accepted_run_is_refused_before_the_work(case, tmp_path, monkeypatch,
                                                                                   capsys):
    """One GPS period longer than the largest run the estimate accepts (with or without the 200 Hz check
    between fixes): exit 2 with the estimate, in one line, and no realization drawn (the estimate refuses
    it before the Monte Carlo starts)."""
    imu, gps, runs, engine, figures, _, output = CASES[case]
    params, _, _ = _largest(imu, gps, runs, engine, figures)
    longer = CalibrationParams(imu_rate=imu, gps_rate=gps, duration=params.duration + 1 / gps)
    refused = []
    real = calibration_cli.estimate_run

    def estimate_run(*a, **k):
        try:
            return real(*a, **k)
        except ValueError:
            refused.append(k.get("between_fixes"))
            raise

    def no_monte_carlo(*a, **k):
        raise AssertionError("the Monte Carlo started: the estimate did not refuse the run")

    monkeypatch.setattr(calibration_cli, "estimate_run", estimate_run)
    monkeypatch.setattr(calibration_cli, "run_monte_carlo", no_monte_carlo)
    assert main(_argv(longer, runs, engine, output, tmp_path if figures else None)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "calibrate: error:" in err[0] and "MB" in err[0], err
    assert refused and not refused[-1]   # refused with the 200 Hz sums (when asked), then without them too
    if figures:
        assert list(tmp_path.iterdir()) == []
