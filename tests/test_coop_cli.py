"""Command line ``python -m kfcal_helpers coop``: JSON keys, readable table, bad input (exit 2, one line)."""

import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.io import savemat

from kfcal_helpers.cli import main
from kfcal_helpers.coop import TUNED_Q_SCALE, CoopParams, course_log_path, simulate, run_filter, write_log_csv
from kfcal_helpers.coop.cli import Q_SCALE_LADDER, SOURCE_FIT, SOURCE_GIVEN, SOURCE_TEST

COURSE_LOG = course_log_path()  # KFCAL_COURSE_LOG, or None


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_generated_log_json(capsys):
    out = _json(capsys, ["coop", "--filter", "ekf", "--json"])
    for key in ("filter", "steps", "seconds", "nis_time_average", "nis_bounds"):
        assert key in out
    assert out["filter"] == "ekf" and out["steps"] == 1001 and len(out["nis_bounds"]) == 2
    assert 3 < out["nis_time_average"] < 7


def test_monte_carlo_json(capsys):
    out = _json(capsys, ["coop", "--filter", "lkf", "--runs", "3", "--seed", "1", "--json"])
    for key in ("filter", "steps", "seconds", "n_runs", "nees_bounds", "nis_bounds",
                "nees_inside_fraction", "nis_inside_fraction"):
        assert key in out
    assert out["n_runs"] == 3 and 0 <= out["nees_inside_fraction"] <= 1


def test_csv_log_and_every_table(capsys, tmp_path):
    write_log_csv(simulate(CoopParams(duration=5.0), seed=2).log(), tmp_path / "log")
    assert main(["coop", "--filter", "ukf", "--log", str(tmp_path / "log"), "--every", "10"]) == 0
    text = capsys.readouterr().out
    assert "nis_time_average" in text and "{" not in text
    assert any(line.split() == ["measurements", "5"] for line in text.splitlines())


@pytest.mark.skipif(COURSE_LOG is None, reason="KFCAL_COURSE_LOG names no course log")
@pytest.mark.parametrize("name, nis", [("ekf", 5.1304), ("ukf", 5.1316), ("lkf", 5.2764)])
def test_course_log_subprocess(name, nis):
    """The default for a course log is the truth-model-tuned Q (never tuned on the log); its NIS on the
    log is then a test: inside the bounds for the EKF and UKF, just above them for the LKF (measured)."""
    proc = subprocess.run([sys.executable, "-m", "kfcal_helpers", "coop", "--filter", name, "--log", str(COURSE_LOG),
                           "--json"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["q_scale_source"] == SOURCE_TEST == "truth-model test" and out["q_scale"] == TUNED_Q_SCALE[name]
    lo, hi = out["nis_bounds"]
    assert out["nis_time_average"] == pytest.approx(nis, abs=1e-4)
    assert out["nis_inside"] == (lo <= out["nis_time_average"] <= hi) == (name != "lkf")


def test_q_scale_choices(capsys, tmp_path):
    """Default: the truth-model-tuned scale, for a generated and a CSV log alike; a given number is used as
    given; 'auto' is a maximum-likelihood fit over the ladder, labelled as a fit, which reports the ladder's
    likelihoods and NIS and the range of scales whose NIS falls inside the bounds."""
    out = _json(capsys, ["coop", "--filter", "ekf", "--json"])
    assert out["q_scale"] == TUNED_Q_SCALE["ekf"] and out["q_scale_source"] == SOURCE_TEST
    write_log_csv(simulate(CoopParams(duration=20.0), seed=3).log(), tmp_path / "log")
    default = _json(capsys, ["coop", "--filter", "ekf", "--log", str(tmp_path / "log"), "--json"])
    assert default["q_scale"] == TUNED_Q_SCALE["ekf"] and default["q_scale_source"] == SOURCE_TEST
    auto = _json(capsys, ["coop", "--filter", "ekf", "--log", str(tmp_path / "log"), "--q-scale", "auto", "--json"])
    assert auto["q_scale_source"] == SOURCE_FIT and "not a test" in SOURCE_FIT
    assert auto["fit_ladder"] == list(Q_SCALE_LADDER)
    log = simulate(CoopParams(duration=20.0), seed=3).log()
    p = log.params()
    ll, nis = {}, {}
    for s in Q_SCALE_LADDER:
        given = _json(capsys, ["coop", "--filter", "ekf", "--log", str(tmp_path / "log"), "--q-scale", str(s), "--json"])
        assert given["q_scale"] == s and given["q_scale_source"] == SOURCE_GIVEN
        nis[s] = given["nis_time_average"]
        # my own innovation log-likelihood from the run's innovations and S
        r = run_filter("ekf", log.y, p, Q=s * p.Qtrue)
        has = np.isfinite(r.nis)
        ll[s] = sum(-0.5 * (nu @ np.linalg.solve(S, nu) + np.log(np.linalg.det(S)) + 5 * np.log(2 * np.pi))
                    for nu, S in zip(r.y[has], r.S[has]))
    assert np.allclose(auto["fit_log_likelihood"], [ll[s] for s in Q_SCALE_LADDER], rtol=1e-9)
    assert np.allclose(auto["fit_nis_time_average"], [nis[s] for s in Q_SCALE_LADDER], rtol=1e-9)
    assert auto["q_scale"] == max(ll, key=ll.get)
    lo, hi = auto["nis_bounds"]
    inside = [s for s in Q_SCALE_LADDER if lo <= nis[s] <= hi]
    assert auto["fit_scales_inside_nis_bounds"] == ([min(inside), max(inside)] if inside else [])


def _bad_mat(tmp_path, **change):
    lg = simulate(CoopParams(duration=1.0), seed=1).log()
    raw = {"ydata": lg.y.T, "tvec": lg.t[None, :], "Qtrue": lg.Qtrue, "Rtrue": lg.Rtrue}
    raw.update(change)
    for key in [k for k, v in raw.items() if v is None]:
        del raw[key]
    savemat(tmp_path / "bad.mat", raw)
    return str(tmp_path / "bad.mat")


@pytest.mark.parametrize("make_args, match", [
    (lambda tmp: ["--log", str(tmp / "missing")], "--log"),
    (lambda tmp: ["--log", _bad_mat(tmp, ydata=np.zeros((3, 11)))], "ydata"),
    (lambda tmp: ["--log", _bad_mat(tmp, Rtrue=None)], "Rtrue"),
    (lambda tmp: ["--log", _bad_mat(tmp, Qtrue=np.eye(6) + np.eye(6, k=1))], "Qtrue must be symmetric"),
    (lambda tmp: ["--log", _bad_mat(tmp, Rtrue=-np.eye(5))], "Rtrue must be positive definite"),
    (lambda tmp: ["--q-scale", "0"], "q-scale"),
    (lambda tmp: ["--q-scale", "big"], "q-scale must be a positive number or 'auto'"),
    (lambda tmp: ["--q-scale", "auto", "--runs", "2"], "q-scale 'auto'"),
    (lambda tmp: ["--runs", "0"], "runs"),
    (lambda tmp: ["--runs", "2", "--log", str(tmp)], "--runs"),
    (lambda tmp: ["--every", "0"], "every"),
])
def test_bad_input_exit_2_one_line(capsys, tmp_path, make_args, match):
    assert main(["coop", "--filter", "ekf", *make_args(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and match in err


def test_unknown_filter_is_usage_error():
    proc = subprocess.run([sys.executable, "-m", "kfcal_helpers", "coop", "--filter", "pf"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1


def test_log_summary_honours_the_measurements_used():
    """The NIS bounds of one run have as many degrees of freedom as the filter used measurements."""
    from kfcal_helpers.consistency import chi2_bounds
    from kfcal_helpers.coop.cli import log_summary

    lg = simulate(CoopParams(duration=5.0), seed=2).log()
    full = log_summary(run_filter("ekf", lg.y, lg.params(), truth=lg.truth))
    sub = log_summary(run_filter("ekf", lg.y, lg.params(), measurements=(0, 1)))
    assert full["nis_bounds"] == list(chi2_bounds(5, 50)) and "nees_bounds" not in full and "nees_time_average" in full
    assert sub["nis_bounds"] == list(chi2_bounds(2, 50)) and "nees_bounds" not in sub
