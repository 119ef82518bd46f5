"""Bad input: a ValueError naming the argument, and exit status 2 with one line from the CLI."""

import json
import subprocess
import sys

import numpy as np
import pytest

from kfcal_helpers.calibration import (
    CalibrationParams, batch_filter, covariance_sequence, run_filterpy, run_monte_carlo, simulate,
)
from kfcal_helpers.cli import main

P0 = CalibrationParams()


@pytest.mark.parametrize("field, value", [
    ("W", 0.0), ("W", -1.0), ("bias_var", 0.0), ("p0_var", -2.0), ("v0_var", 0.0),
    ("gps_pos_var", 0.0), ("gps_vel_var", -0.1), ("imu_rate", 0.0), ("gps_rate", -5.0),
    ("duration", 0.0), ("duration", -30.0), ("omega", 0.0),
    ("A", float("nan")), ("W", float("inf")), ("p0_mean", float("nan")), ("gps_rate", 3.0),
    ("duration", 0.1),
])
def test_params_rejected(field, value):
    with pytest.raises(ValueError, match=field):
        CalibrationParams(**{field: value})


def test_gps_rate_must_divide_imu_rate():
    with pytest.raises(ValueError, match="divide"):
        CalibrationParams(imu_rate=200, gps_rate=7)
    assert CalibrationParams(imu_rate=100, gps_rate=10).steps_per_fix == 10


def test_runs_and_choices_rejected():
    with pytest.raises(ValueError, match="n_runs"):
        run_monte_carlo(P0, 1)
    with pytest.raises(ValueError, match="filter"):
        run_monte_carlo(P0, 2, filter="fast")
    with pytest.raises(ValueError, match="engine"):
        run_monte_carlo(P0, 2, engine="fast")
    with pytest.raises(ValueError, match="truth"):
        simulate(P0, 2, np.random.default_rng(0), truth="exact")
    for alpha in (1.5, 0.0, 1.0, float("nan"), "0.05", True):
        with pytest.raises(ValueError, match="alpha must be a number in"):
            run_monte_carlo(P0, 2, alpha=alpha)
    for seed in ("x", -1, 1.5, None):
        with pytest.raises(ValueError, match="seed must be an integer .* or a numpy.random.Generator"):
            simulate(P0, 2, seed)
    with pytest.raises(ValueError, match="workers"):
        run_monte_carlo(P0, 2, workers=0)
    with pytest.raises(ValueError, match="params must be a CalibrationParams, got NoneType"):
        run_monte_carlo(None, 2)
    with pytest.raises(ValueError, match="missing_fixes must be None or a bool array of shape"):
        run_monte_carlo(P0, 2, missing_fixes=np.zeros(P0.n_gps))
    with pytest.raises(TypeError):  # everything after the seed is keyword-only
        run_monte_carlo(P0, 2, 0, "batch")


def test_simulate_takes_a_seed_or_a_generator():
    a = simulate(P0, 2, 7)
    b = simulate(P0, 2, np.random.default_rng(7))
    np.testing.assert_array_equal(a.z, b.z)
    rng = np.random.default_rng(7)
    simulate(P0, 2, rng)
    assert not np.array_equal(simulate(P0, 2, rng).z, a.z)  # a Generator is advanced


def test_measurement_shapes_rejected():
    with pytest.raises(ValueError, match="dz"):
        run_filterpy(P0, np.zeros((150, 2)))
    with pytest.raises(ValueError, match="dz"):
        run_filterpy(P0, np.zeros((151, 3)))
    with pytest.raises(ValueError, match="dz"):
        batch_filter(P0, np.zeros((151, 2)))
    bad = np.zeros((151, 2))
    bad[3, 0] = np.nan  # half a fix missing
    with pytest.raises(ValueError, match="dz"):
        run_filterpy(P0, bad)
    per_run = np.zeros((2, 151, 2))
    per_run[0, 5] = np.nan  # missing in one realization only
    with pytest.raises(ValueError, match="dz"):
        batch_filter(P0, per_run)
    with pytest.raises(ValueError, match="missing_fixes"):
        covariance_sequence(P0, np.zeros(10, bool))


def run_cli(*args):
    """``python -m kfcal_helpers calibrate ARGS`` in a real process (the entry point itself)."""
    return subprocess.run([sys.executable, "-m", "kfcal_helpers", "calibrate", *args],
                          capture_output=True, text=True, env={"KFCAL_QUIET": "1", "PATH": ""})


BAD_ARGS = [
    (["--runs", "1"], "--runs"), (["--gps-rate", "3"], "--gps-rate"), (["--duration", "-1"], "--duration"),
    (["--omega", "nan"], "--omega"), (["--imu-rate", "0"], "--imu-rate"), (["--engine", "gpu"], "--engine"),
    (["--runs", "ten"], "--runs"), (["--truth", "rk4"], "--truth"),
]


def _one_line_exit_2(code, out, err, word):
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and word in lines[0] and "Traceback" not in err


@pytest.mark.parametrize("args, word", BAD_ARGS)
def test_cli_bad_input_one_line_exit_2(args, word, capsys):
    """Each bad value through ``kfcal_helpers.cli.main`` (what ``python -m kfcal_helpers`` runs)."""
    code = main(["calibrate", *args])
    captured = capsys.readouterr()
    _one_line_exit_2(code, captured.out, captured.err, word)


def test_cli_bad_input_one_line_exit_2_real_process():
    """The same through the real entry point, for one row (a ValueError of the library's checks)."""
    args, word = BAD_ARGS[3]
    r = run_cli(*args)
    _one_line_exit_2(r.returncode, r.stdout, r.stderr, word)


def test_cli_json(tmp_path, capsys):
    assert main(["calibrate", "--runs", "50", "--seed", "3", "--json", "--figures", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    d = json.loads(captured.out)
    for key in ("n_runs", "filter", "seconds", "sigma_final", "ensemble_sigma_final", "checks"):
        assert key in d
    assert d["n_runs"] == 50 and d["filter"] == "kf" and d["engine"] == "batch" and len(d["sigma_final"]) == 3
    for name in ("mean_error", "covariance", "orthogonality", "residual_independence", "nees", "nis"):
        assert 0.0 <= d["checks"][name]["inside_fraction"] <= 1.0
    assert len(d["checks"]["nees"]["bounds"]) == 2 and len(d["checks"]["nis"]["bounds"]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "calib_checks.png", "calib_errors.png", "calib_sigma_sawtooth.png"]


def test_cli_table_in_process(capsys):
    assert main(["calibrate", "--runs", "20", "--engine", "filterpy"]) == 0
    out = capsys.readouterr().out
    assert "nees" in out and "filter kf, engine filterpy" in out


def test_filterpy_progress_moves_every_realization(monkeypatch):
    """The progress bar counts realizations, so with the filterpy engine (about 0.03 s per realization)
    it moves well within every second, not once per 500-realization chunk (about 14 s)."""
    import time

    from kfcal_helpers import montecarlo as core
    from kfcal_helpers.calibration import montecarlo

    calls = []

    class Recorder:
        def __init__(self, total, desc=None, enabled=None):
            calls.append(("total", total, time.perf_counter()))

        def update(self, n=1):
            calls.append(("update", n, time.perf_counter()))

        def close(self):
            calls.append(("close", 0, time.perf_counter()))

    monkeypatch.setattr(core, "progress_bar", Recorder)
    run_monte_carlo(P0, 12, seed=0, engine="filterpy", progress=True)
    kinds = [c[0] for c in calls]
    assert kinds == ["total"] + ["update"] * 12 + ["close"] and calls[0][1] == 12
    assert all(c[1] == 1 for c in calls[1:-1])
    gaps = np.diff([c[2] for c in calls[:-1]])
    assert gaps.max() < 1.0, gaps.max()
    calls.clear()
    run_monte_carlo(P0, 1200, seed=0, engine="batch", progress=True)  # batch: by chunk, in total n_runs
    assert sum(c[1] for c in calls if c[0] == "update") == 1200
    calls.clear()
    # on two threads (two chunks of 6 filterpy realizations) the bar, moved from the calling thread,
    # still moves within every second and counts every realization
    monkeypatch.setattr(montecarlo, "CHUNK_SIZE", 6)
    run_monte_carlo(P0, 12, seed=0, engine="filterpy", progress=True, workers=2)
    assert [c[0] for c in calls][0] == "total" and calls[-1][0] == "close"
    assert sum(c[1] for c in calls if c[0] == "update") == 12
    gaps = np.diff([c[2] for c in calls[:-1]])
    assert gaps.max() < 1.0, gaps.max()
