"""Command line ``python -m kfcal_helpers orbit``: JSON keys, the checks table, logs in both forms, bad input
(exit 2, one line), in process; Ctrl-C and the full-size runs in child processes are the slow tier."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers.cli import main
from kfcal_helpers.orbit import OrbitParams, course_log_path, run_filter, simulate, write_log_csv, write_log_mat
from kfcal_helpers.orbit.cli import every_log, log_summary
from kfcal_helpers.orbit.data import log_params

SMALL = OrbitParams(n_steps=200)


@pytest.fixture(scope="module")
def small_log():
    return simulate(SMALL, seed=2).log()


def _run(capsys, argv):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _json(capsys, argv):
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    return json.loads(out)


def test_monte_carlo_json_and_table(capsys):
    out = _json(capsys, ["orbit", "--filter", "ekf", "--runs", "4", "--seed", "1", "--json"])
    assert out["filter"] == "ekf" and out["n_runs"] == 4 and out["steps"] == 1401 and out["alpha"] == 0.05
    assert set(out["checks"]) == {"mean_error", "nees", "nis"}
    for entry in out["checks"].values():
        assert set(entry) == {"inside_fraction", "worst", "passed"} and 0 <= entry["inside_fraction"] <= 1
    assert out["passed"] == all(e["passed"] for e in out["checks"].values())
    code, text, err = _run(capsys, ["orbit", "--filter", "ekf", "--runs", "4", "--seed", "1"])
    assert code == 0 and err == ""
    lines = text.splitlines()
    rows = {line.split()[0]: line.split() for line in lines if line.split()[:1] in (["nees"], ["nis"], ["mean_error"])}
    assert set(rows) == {"mean_error", "nees", "nis"}
    for name, row in rows.items():  # the table prints what the JSON holds
        assert float(row[1]) == pytest.approx(out["checks"][name]["inside_fraction"], abs=5e-4)
        assert row[3] == ("pass" if out["checks"][name]["passed"] else "FAIL")


def test_log_json_matches_the_filter(capsys, tmp_path, small_log):
    f = write_log_mat(small_log, tmp_path / "log.mat")
    out = _json(capsys, ["orbit", "--filter", "ukf", "--log", str(f), "--json"])
    result = run_filter("ukf", small_log.y, log_params(small_log))
    has = result.dof > 0
    dof = int(result.dof[has].sum())
    assert out["updates"] == int(has.sum()) and out["nis_dof"] == dof == small_log.dof.sum()
    assert out["nis_sum"] == pytest.approx(result.nis[has].sum(), rel=1e-9)
    assert out["nis_bounds"] == pytest.approx(list(stats.chi2.ppf([0.025, 0.975], dof) / dof))
    assert out["nis_inside"] == (out["nis_bounds"][0] <= out["nis_per_dof"] <= out["nis_bounds"][1])
    assert "nees_time_average" not in out and out["source"] == str(f)  # a file carries no truth


def test_generated_log_has_nees_and_csv_every(capsys, tmp_path, small_log):
    out = _json(capsys, ["orbit", "--json"])
    assert out["steps"] == 1401 and out["source"] == "simulated (seed 5044)" and "nees_time_average" in out
    folder = write_log_csv(small_log, tmp_path / "csv")
    code, text, err = _run(capsys, ["orbit", "--filter", "lkf", "--log", str(folder), "--every", "5"])
    assert code == 0 and err == "" and "{" not in text
    kept = every_log(small_log, 5)
    assert all(b.shape[1] == 0 for k, b in enumerate(kept.ydata) if k % 5)
    assert any(line.split() == ["updates", str(int((kept.dof > 0).sum()))] for line in text.splitlines())


def test_log_summary_counts_the_dof_present(small_log):
    r = run_filter("ekf", small_log.y, log_params(small_log), truth=small_log.truth)
    s = log_summary(r, alpha=0.1)
    assert s["nis_dof"] == int(r.dof.sum()) and s["nis_per_dof"] == pytest.approx(np.nansum(r.nis) / r.dof.sum())
    assert s["nees_time_average"] == pytest.approx(r.nees.mean())
    wide = log_summary(r, alpha=0.01)["nis_bounds"]
    assert wide[0] < s["nis_bounds"][0] < s["nis_bounds"][1] < wide[1]


BAD = [
    (["orbit", "--runs", "1"], ["--runs", "2 to 10000"]),
    (["orbit", "--runs", "20000"], ["--runs"]),
    (["orbit", "--runs", "9000"], ["--runs: 9000 realizations", "more than the 500 MB allowed"]),
    (["orbit", "--runs", "2", "--log", "x.mat"], ["--runs", "do not give --log"]),
    (["orbit", "--every", "0"], ["--every"]),
    (["orbit", "--every", "1401"], ["--every must be at most 1400"]),
    (["orbit", "--runs", "2", "--every", "5000"], ["--every must be at most 1400", "truth model"]),
    (["orbit", "--alpha", "0.7"], ["--alpha"]),
    (["orbit", "--filter", "pf"], ["--filter"]),
    (["orbit", "--seed", "-1"], ["--seed"]),
    (["orbit", "--log", "{tmp}/missing.mat"], ["--log:", "does not exist"]),
    (["orbit", "--log", "{tmp}/zero.mat"], ["--log:", "/dev/zero", "character device"]),
    (["orbit", "--log", "{tmp}/text.mat"], ["--log:", "not a readable MATLAB file"]),
    (["orbit", "--log", "{tmp}/ids.mat"], ["ydata{3}: station ids must be distinct integers 1..12, got 13"]),
]


@pytest.mark.parametrize("argv,pieces", BAD, ids=[" ".join(a[1:]) for a, _ in BAD])
def test_bad_input_exit_2_one_line(capsys, tmp_path, argv, pieces):
    from scipy.io import savemat

    if os.path.exists("/dev/zero"):
        os.symlink("/dev/zero", tmp_path / "zero.mat")
    (tmp_path / "text.mat").write_text("not matlab" * 30)
    cells = np.empty((1, 3), dtype=object)
    cells[0, 0], cells[0, 1] = np.empty((4, 0)), np.empty((4, 0))
    cells[0, 2] = np.array([[7000.0], [0.1], [0.2], [13.0]])
    savemat(tmp_path / "ids.mat", {"tvec": np.array([[0.0, 10.0, 20.0]]), "ydata": cells, "Qtrue": 1e-10 * np.eye(2),
                                   "Rtrue": np.diag([0.01, 1.0, 0.01])})
    if "zero.mat" in " ".join(argv) and not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    code, out, err = _run(capsys, [a.replace("{tmp}", str(tmp_path)) for a in argv])
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("python -m kfcal_helpers orbit: error:"), err
    for piece in pieces:
        assert piece in lines[0], lines[0]


def test_help_lists_orbit(capsys):
    code, out, _ = _run(capsys, ["--help"])
    assert code == 0 and "orbit determination" in out


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process group is POSIX")
def test_ctrl_c_during_the_monte_carlo_is_one_line_and_130():
    proc = subprocess.Popen([sys.executable, "-m", "kfcal_helpers", "orbit", "--runs", "1000", "--filter", "ukf"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "KFCAL_QUIET": "1"})
    time.sleep(6)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and out == ""
    assert err.strip().splitlines() == ["python -m kfcal_helpers orbit: interrupted"], err


@pytest.mark.slow
@pytest.mark.skipif(course_log_path() is None, reason="KFCAL_ORBIT_LOG names no course log")
@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_course_log_in_a_child_process(name):
    proc = subprocess.run([sys.executable, "-m", "kfcal_helpers", "orbit", "--filter", name, "--log",
                           str(course_log_path()), "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["updates"] > 0 and out["nis_dof"] % 3 == 0 and len(out["nis_bounds"]) == 2
