"""Table-driven fuzz test of the command line: whatever a user types, one line on stderr and exit 2
(or a clean run), never a traceback, a warning, a NaN in JSON, or a file left behind.

Most rows call ``kfcal_helpers.cli.main(argv)`` in this process (fast); a real process is used only
where it matters: Ctrl-C (SIGINT), a closed stdout, files the user cannot read or write (run as
the unprivileged user ``nobody`` when the tests run as root).  The real-process tests are the slow
tier (``@pytest.mark.slow``: ``pytest -m slow``; ``.ci/run`` runs it after ``pytest``).  The peak memory of the largest accepted
runs is checked in real processes by ``tests/test_calibration_memory.py`` and ``tests/test_coop_memory.py``.
"""

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from kfcal_helpers import problems
from kfcal_helpers.calibration import cli as calibration_cli
from kfcal_helpers.calibration.params import CalibrationParams
from kfcal_helpers.cli import main
from kfcal_helpers.coop import CoopParams, simulate, write_log_csv
from kfcal_helpers.orbit import cli as orbit_cli

PROG = "python -m kfcal_helpers"
MEMORY_LIMIT = 500e6  #: bytes, the issue's bound on the peak memory of any accepted run


def _log_folder(root: Path, **change) -> Path:
    """A small course-format CSV log folder; ``change`` replaces a file's text (or makes it a directory: None)."""
    folder = root / "log"
    write_log_csv(simulate(CoopParams(duration=2.0), seed=1).log(), folder)
    for name, text in change.items():
        f = folder / f"{name}.csv"
        f.unlink()
        if text is None:
            f.mkdir()
        else:
            f.write_text(text)
    return folder


def _mat(root: Path, **change) -> Path:
    lg = simulate(CoopParams(duration=1.0), seed=1).log()
    raw = {"ydata": lg.y.T, "tvec": lg.t[None, :], "Qtrue": lg.Qtrue, "Rtrue": lg.Rtrue}
    raw.update(change)
    savemat(root / "log.mat", raw)
    return root / "log.mat"


def _ydata_text(values) -> str:
    return "\n".join(",".join("NaN" if np.isnan(v) else repr(float(v)) for v in row) for row in values) + "\n"


def _huge(root):
    y = simulate(CoopParams(duration=2.0), seed=1).log().y.T.copy()
    y[1, 5] = 1e300
    return _log_folder(root, ydata=_ydata_text(y))


def _every_fifth_missing():
    y = simulate(CoopParams(duration=2.0), seed=1).log().y.T.copy()
    y[:, ::5] = np.nan
    return y


def _all_nan(root):
    return _log_folder(root, ydata=_ydata_text(np.full((5, 21), np.nan)))


# (argv with {tmp} and the placeholders below, words the one stderr line must contain)
BAD = [
    # calibrate: outages
    (["calibrate", "--runs", "3", "--outage", "0:30"], ["--outage", "at least 2"]),
    (["calibrate", "--runs", "3", "--outage", "0:29.9"], ["--outage", "at least 2"]),
    (["calibrate", "--runs", "3", "--outage", "0:15", "--outage", "15:30"], ["--outage", "at least 2"]),
    (["calibrate", "--outage", "-5:3"], ["--outage", "outside [0, 30]"]),
    (["calibrate", "--outage=-5:3"], ["--outage", "outside"]),
    (["calibrate", "--outage", "5"], ["--outage", "START:END"]),
    (["calibrate", "--outage", "a:b"], ["--outage", "START:END"]),
    (["calibrate", "--outage", "10:5"], ["--outage", "START"]),
    (["calibrate", "--outage", "0:31"], ["--outage", "outside"]),
    (["calibrate", "--outage", "nan:3"], ["--outage", "finite"]),
    (["calibrate", "--outage"], ["--outage", "expected one argument"]),
    # calibrate: sizes, memory, time
    (["calibrate", "--runs", str(10**30)], ["--runs", "h", "use fewer"]),
    (["calibrate", "--runs", "1000000000"], ["--runs", "h", "more than the 1 h"]),
    (["calibrate", "--runs", "200000", "--engine", "filterpy"], ["--runs", "h"]),
    (["calibrate", "--gps-rate", "200"], ["--gps-rate", "MB", "500 MB"]),
    (["calibrate", "--imu-rate", "1e7"], ["--imu-rate", "MB"]),
    (["calibrate", "--duration", "1e5"], ["--duration", "MB"]),
    (["calibrate", "--gps-rate", "200", "--duration", "600"], ["--duration", "MB"]),
    (["calibrate", "--gps-rate", "40", "--duration", "23", "--figures", "{tmp}/out"], ["--figures", "MB"]),
    (["calibrate", "--duration", "1e300"], ["--duration", "IMU samples"]),
    (["calibrate", "--imu-rate", "1e-300", "--gps-rate", "1e-300", "--duration", "1e300"], ["--omega"]),
    (["calibrate", "--runs", "-5"], ["--runs", ">= 2"]),
    (["calibrate", "--runs", "1"], ["--runs", ">= 2"]),
    (["calibrate", "--runs", "1e3"], ["--runs", "integer"]),
    (["calibrate", "--runs", ""], ["--runs"]),
    # calibrate: numbers
    (["calibrate", "--omega", "1e308"], ["--omega", "at most"]),
    (["calibrate", "--omega", "1e308", "--json"], ["--omega", "at most"]),
    (["calibrate", "--omega", "1e160", "--truth", "analytic"], ["--omega", "at most"]),
    (["calibrate", "--omega", "-inf"], ["--omega", "> 0"]),
    (["calibrate", "--omega", "-1e5"], ["--omega", "> 0"]),
    (["calibrate", "--omega", "inf"], ["--omega", "> 0"]),
    (["calibrate", "--omega", "nan"], ["--omega"]),
    (["calibrate", "--omega", "0"], ["--omega"]),
    (["calibrate", "--omega", "fast"], ["--omega"]),
    (["calibrate", "--imu-rate", "0"], ["--imu-rate"]),
    (["calibrate", "--imu-rate", "-200"], ["--imu-rate"]),
    (["calibrate", "--gps-rate", "3"], ["--gps-rate", "divide"]),
    (["calibrate", "--gps-rate", "400"], ["--gps-rate", "divide"]),
    (["calibrate", "--duration", "-1"], ["--duration"]),
    (["calibrate", "--duration", "0.1"], ["--duration", "GPS period"]),
    (["calibrate", "--duration", "30.001"], ["--duration", "IMU periods"]),
    (["calibrate", "--seed", "-1"], ["--seed", "0 to 2**63 - 1"]),
    (["calibrate", "--seed", "1.5"], ["--seed"]),
    (["calibrate", "--seed", "x"], ["--seed"]),
    (["calibrate", "--seed", str(2**64)], ["--seed"]),
    (["calibrate", "--engine", "gpu"], ["--engine"]),
    (["calibrate", "--truth", "rk4"], ["--truth"]),
    (["calibrate", "--bogus"], ["--bogus"]),
    (["calibrate", "extra"], ["extra"]),
    # calibrate --figures
    (["calibrate", "--runs", "200000", "--figures", "{file}"], ["--figures", "existing file"]),
    (["calibrate", "--runs", "200000", "--figures", "{file}/sub"], ["--figures", "is a file"]),
    (["calibrate", "--runs", "200000", "--figures", ""], ["--figures"]),
    # coop
    (["coop", "--seed", "-1"], ["--seed"]),
    (["coop", "--seed", "abc"], ["--seed"]),
    (["coop", "--q-scale", "1e308"], ["--q-scale", "1e+06"]),
    (["coop", "--q-scale", "-1"], ["--q-scale"]),
    (["coop", "--q-scale", "nan"], ["--q-scale"]),
    (["coop", "--q-scale", "inf"], ["--q-scale"]),
    (["coop", "--q-scale", "0"], ["--q-scale"]),
    (["coop", "--q-scale", "big"], ["--q-scale"]),
    (["coop", "--runs", "0"], ["--runs"]),
    (["coop", "--runs", "1000000"], ["--runs", "10000"]),
    (["coop", "--runs", "2", "--q-scale", "auto"], ["auto"]),
    (["coop", "--runs", "2", "--log", "{tmp}"], ["--runs"]),
    (["coop", "--every", "0"], ["--every"]),
    (["coop", "--every", "x"], ["--every"]),
    (["coop", "--every", "100000"], ["--every", "at most 1000", "has 1001 steps"]),
    (["coop", "--every", "1001"], ["--every", "at most 1000"]),
    (["calibrate", "--runs", "3", "--outage", "0.01:0.02"], ["--outage", "0.01:0.02 s removes no GPS fix"]),
    (["calibrate", "--runs", "3", "--outage", "5:10", "--outage", "10.1:10.15"], ["--outage", "10.1:10.15 s removes no"]),
    (["coop", "--alpha", "0"], ["--alpha"]),
    (["coop", "--alpha", "1"], ["--alpha"]),
    (["coop", "--alpha", "nan"], ["--alpha"]),
    (["coop", "--filter", "pf"], ["--filter"]),
    (["coop", "--log", "{tmp}/missing"], ["--log", "does not exist"]),
    (["coop", "--log", "{file}"], ["--log", ".mat"]),
    (["coop", "--log", "{log_ydata_dir}"], ["--log", "is a directory"]),
    (["coop", "--log", "{log_no_rtrue}"], ["--log", "Rtrue.csv is missing"]),
    (["coop", "--log", "{log_empty}"], ["ydata", "empty"]),
    (["coop", "--log", "{log_text}"], ["ydata", "not a numeric CSV"]),
    (["coop", "--log", "{log_all_nan}"], ["ydata", "no measurement"]),
    (["coop", "--log", "{log_huge}"], ["ydata", "at most 1e+06"]),
    (["coop", "--log", "{mat_string}"], ["ydata", "numeric", "text"]),
    (["coop", "--log", "{mat_struct}"], ["ydata", "numeric", "struct"]),
    (["coop", "--log", "{mat_complex}"], ["ydata", "real numbers"]),
    (["coop", "--log", "{mat_garbage}"], ["--log", "not a readable MATLAB file"]),
    # orbit
    (["orbit", "--seed", "-1"], ["--seed"]),
    (["orbit", "--runs", "1"], ["--runs", "2 to 10000"]),
    (["orbit", "--runs", "1000000"], ["--runs", "10000"]),
    (["orbit", "--runs", "9000"], ["--runs: 9000 realizations", "500 MB"]),
    (["orbit", "--runs", "2", "--log", "{tmp}"], ["--runs", "--log"]),
    (["orbit", "--every", "0"], ["--every"]),
    (["orbit", "--every", "1401"], ["--every", "at most 1400"]),
    (["orbit", "--runs", "2", "--every", "1401"], ["--every", "at most 1400", "truth model"]),
    (["orbit", "--alpha", "nan"], ["--alpha"]),
    (["orbit", "--filter", "pf"], ["--filter"]),
    (["orbit", "--log", "{tmp}/missing.mat"], ["--log", "does not exist"]),
    (["orbit", "--log", "{file}"], ["--log", ".mat"]),
    (["orbit", "--log", "{mat_garbage}"], ["--log", "not a readable MATLAB file"]),
    (["orbit", "--log", "{log_ydata_dir}"], ["--log", "ydata.csv is a directory"]),
    # figures
    (["figures", "{file}"], ["DIR", "existing file"]),
    (["figures", "{file}/sub"], ["DIR", "is a file"]),
    (["figures"], ["DIR"]),
    (["figures", "{tmp}/out", "--only", "no_such_figure"], ["--only"]),
    (["figures", "{tmp}/out", "--only"], ["--only"]),
    (["figures", "{tmp}/out", "--bogus"], ["--bogus"]),
    # top level
    ([], ["command"]),
    (["simulate"], ["simulate"]),
]


def _placeholders(tmp: Path) -> dict:
    (tmp / "file.png").write_text("not a directory")
    (tmp / "garbage.mat").write_bytes(b"\x00not a MATLAB file" * 10)
    lazy = {
        "log_ydata_dir": lambda d: _log_folder(d, ydata=None),
        "log_no_rtrue": lambda d: (lambda f: ((f / "Rtrue.csv").unlink(), f)[1])(_log_folder(d)),
        "log_empty": lambda d: _log_folder(d, ydata=""),
        "log_text": lambda d: _log_folder(d, ydata="hello,world\n"),
        "log_all_nan": _all_nan,
        "log_huge": _huge,
        "mat_string": lambda d: _mat(d, ydata="hello"),
        "mat_struct": lambda d: _mat(d, ydata={"a": np.ones(3), "b": "x"}),
        "mat_complex": lambda d: _mat(d, ydata=simulate(CoopParams(duration=1.0), seed=1).log().y.T * (1 + 1j)),
    }
    return {"tmp": str(tmp), "file": str(tmp / "file.png"), "mat_garbage": str(tmp / "garbage.mat"), **lazy}


def _expand(argv, tmp: Path) -> list:
    values = _placeholders(tmp)
    out = []
    for a in argv:
        for key, value in values.items():
            if "{" + key + "}" in a:
                if callable(value):
                    sub = tmp / key
                    sub.mkdir(exist_ok=True)
                    value = str(value(sub))
                a = a.replace("{" + key + "}", value)
        out.append(a)
    return out


def _files(root: Path) -> set:
    return {p.relative_to(root) for p in root.rglob("*")}


def _run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _one_error_line(err: str, command: str | None):
    assert err.endswith("\n") and err.count("\n") == 1, err
    assert "Traceback" not in err and "Warning" not in err
    # argparse reports arguments no sub-command knows from the top level
    assert err.startswith(f"{PROG} {command}: error: " if command else "@") or err.startswith(f"{PROG}: error: "), err


def _no_figure_data(monkeypatch, fail):
    """Every problem's figure data (the long work behind the figures) raises ``fail``."""
    import dataclasses

    monkeypatch.setattr(problems, "PROBLEMS", tuple(dataclasses.replace(p, figure_data=fail) for p in problems.PROBLEMS))


@pytest.mark.parametrize("argv, words", BAD, ids=[" ".join(a)[:60] or "(nothing)" for a, _ in BAD])
def test_bad_input_one_line_exit_2(argv, words, tmp_path, capsys, monkeypatch):
    """Exit 2, nothing on stdout, exactly one stderr line naming the option, no file written, and
    the long work (the Monte Carlo) never started."""
    argv = _expand(argv, tmp_path)
    before = _files(tmp_path)

    def no_monte_carlo(*a, **k):
        raise AssertionError("the Monte Carlo started before the input was checked")

    monkeypatch.setattr(calibration_cli, "run_monte_carlo", no_monte_carlo)
    monkeypatch.setattr(coop_cli, "truth_model_test", no_monte_carlo)
    monkeypatch.setattr(coop_cli, "fit_q_scale", no_monte_carlo)
    monkeypatch.setattr(orbit_cli, "truth_model_test", no_monte_carlo)
    _no_figure_data(monkeypatch, no_monte_carlo)
    code, out, err = _run(argv, capsys)
    assert code == 2 and out == ""
    command = argv[0] if argv and argv[0] in ("calibrate", "coop", "orbit", "figures") else None
    _one_error_line(err, command)
    for word in words:
        assert word in err, (word, err)
    assert _files(tmp_path) == before  # nothing written or left behind


GOOD = [
    ["calibrate", "--runs", "3", "--outage", "0:29.8"],  # 2 fixes left, 3 runs: was a RuntimeWarning
    ["calibrate", "--runs", "2", "--outage", "0:29.8", "--json"],
    ["calibrate", "--runs", "4", "--omega", "628", "--json"],  # just below the IMU's Nyquist frequency
    ["calibrate", "--runs", "3", "--omega", "628", "--truth", "analytic", "--json"],
    ["calibrate", "--runs", "2", "--seed", str(2**63 - 1), "--json"],
    ["calibrate", "--runs", "5", "--gps-rate", "200", "--duration", "2", "--json"],
    ["calibrate", "--runs", "3", "--engine", "filterpy", "--duration", "1", "--json"],
    ["coop", "--seed", "0", "--json"],
    ["coop", "--q-scale", "1e6", "--json"],
    ["coop", "--q-scale", "1e-6", "--filter", "ukf", "--json"],
    ["coop", "--runs", "1", "--alpha", "0.5", "--json"],
    ["orbit", "--runs", "2", "--alpha", "0.5", "--every", "1400", "--json"],
    ["orbit", "--filter", "lkf", "--every", "700", "--json"],
]


@pytest.mark.parametrize("argv", GOOD, ids=[" ".join(a) for a in GOOD])
def test_edge_values_run_clean(argv, capsys):
    """Valid edge values: exit 0, nothing on stderr (no warning), strict JSON without NaN."""
    code, out, err = _run(argv, capsys)
    assert code == 0 and err == "", err
    if "--json" not in argv:
        return
    d = json.loads(out, parse_constant=lambda c: pytest.fail(f"{c} in JSON"))

    def finite(v):
        if isinstance(v, float):
            assert math.isfinite(v)
        elif isinstance(v, dict):
            [finite(x) for x in v.values()]
        elif isinstance(v, list):
            [finite(x) for x in v]

    finite(d)


def test_json_is_strict_with_missing_fixes(capsys):
    """NIS is undefined at missing fixes: the JSON holds null there, never NaN (allow_nan=False)."""
    from kfcal_helpers.cli import dumps_json

    assert dumps_json({"a": [1.0, float("nan")], "b": float("inf")}) == '{"a": [1.0, null], "b": null}'
    code, out, _ = _run(["calibrate", "--runs", "3", "--outage", "5:10", "--json"], capsys)
    assert code == 0 and "NaN" not in out and json.loads(out)["outages"] == [[5.0, 10.0]]


def test_help_is_plain_text(capsys):
    for argv in ([], ["calibrate"], ["coop"], ["figures"]):
        code, out, err = _run([*argv, "--help"], capsys)
        assert code == 0 and err == ""
        assert "``" not in out and ":func:" not in out and ":data:" not in out, out
    code, out, _ = _run(["--help"], capsys)
    assert "python -m kfcal_helpers COMMAND" in out


def test_calibrate_table_explains_its_columns(capsys):
    code, out, _ = _run(["calibrate", "--runs", "20"], capsys)
    assert code == 0
    assert "inside:" in out and "worst:" in out and "FAIL when > 1" in out
    assert "model-mismatch" not in out  # the consistent filter passes: no note


def test_analytic_truth_fail_rows_are_labelled(capsys):
    """--truth analytic with a fast acceleration fails some checks, and says that this is intended."""
    code, out, _ = _run(["calibrate", "--runs", "200", "--truth", "analytic", "--omega", "5"], capsys)
    assert code == 0 and "FAIL" in out
    assert "intended model-mismatch demonstration" in out and "--truth analytic" in out


def test_unwritable_output_refused_before_the_work(tmp_path, capsys, monkeypatch):
    """In-process: a directory the user cannot write is refused before the Monte Carlo / the figures."""
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **k: False if Path(p) == tmp_path else real_access(p, mode, **k))

    def no_work(*a, **k):
        raise AssertionError("long work started")

    monkeypatch.setattr(calibration_cli, "run_monte_carlo", no_work)
    _no_figure_data(monkeypatch, no_work)
    for argv, word in ((["calibrate", "--figures", str(tmp_path / "out")], "--figures"),
                       (["figures", str(tmp_path)], "DIR")):
        code, out, err = _run(argv, capsys)
        assert code == 2 and out == ""
        _one_error_line(err, argv[0])
        assert word in err and "cannot write into" in err
    assert list(tmp_path.iterdir()) == []


def test_failed_save_leaves_no_file(tmp_path, capsys, monkeypatch):
    """A save that fails half-way (disk full, permission) leaves neither the file nor its temporary."""
    import matplotlib.figure

    def failing_savefig(self, fname, **kw):
        Path(fname).write_bytes(b"\x89PNG partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", failing_savefig)
    code, out, err = _run(["figures", str(tmp_path), "--only", "coop_paths"], capsys)
    assert code == 2 and out == ""
    _one_error_line(err, "figures")
    assert "No space left on device" in err and "DIR" in err
    assert list(tmp_path.iterdir()) == []


def test_unreadable_log_in_process(tmp_path, capsys, monkeypatch):
    """A log file the user may not read: one line naming --log (simulated: open raises PermissionError)."""
    import builtins

    folder = _log_folder(tmp_path)
    real_open = builtins.open

    def guarded_open(file, *a, **k):
        if Path(str(file)).name == "ydata.csv":
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *a, **k)

    monkeypatch.setattr(builtins, "open", guarded_open)
    code, out, err = _run(["coop", "--log", str(folder)], capsys)
    assert code == 2 and out == ""
    _one_error_line(err, "coop")
    assert "--log: cannot read" in err and "ydata.csv: Permission denied" in err


def test_errors_outside_value_checks_are_one_line(capsys, monkeypatch):
    """The wrapper's last resorts: OSError, MemoryError, a numerical RuntimeWarning, Ctrl-C, a closed pipe."""
    import warnings

    import kfcal_helpers.cli as cli

    def raising(exc):
        def run(*a, **k):
            if exc is RuntimeWarning:
                warnings.warn("overflow encountered in square", RuntimeWarning)
                return 0
            raise exc
        return run

    for exc, code, words in ((PermissionError(13, "Permission denied", "x.png"), 2, ["x.png: Permission denied"]),
                             (MemoryError(), 2, ["not enough memory"]),
                             (RuntimeWarning, 2, ["numerical failure", "overflow"]),
                             (KeyboardInterrupt(), 130, ["calibrate: interrupted"])):
        monkeypatch.setattr(calibration_cli, "run", raising(exc))
        got, out, err = _run(["calibrate"], capsys)
        assert got == code and out == ""
        assert err.count("\n") == 1 and "Traceback" not in err
        for w in words:
            assert w in err
    monkeypatch.setattr(calibration_cli, "run", raising(BrokenPipeError()))
    monkeypatch.setattr(cli, "_quiet_stdout", lambda: None)
    got, out, err = _run(["calibrate"], capsys)
    assert got == 141 and err == ""


# ---------------------------------------------------------------------------
# Real processes
ENV = {**os.environ, "KFCAL_QUIET": "1"}


def _proc(argv, **kw):
    return subprocess.Popen([sys.executable, "-m", "kfcal_helpers", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV, **kw)


def _complete_png(path: Path) -> bool:
    data = path.read_bytes()
    return data[:8] == b"\x89PNG\r\n\x1a\n" and data[-8:-4] == b"IEND"


@pytest.mark.slow
def test_ctrl_c_one_line_exit_130(tmp_path):
    """SIGINT while working (calibrate, coop, figures, side by side): exit 130, one stderr line, and
    only complete files in the output folder, no temporary left."""
    commands = [["calibrate", "--runs", "300000"], ["coop", "--runs", "2000", "--filter", "ukf"], ["figures", str(tmp_path)]]
    procs = [_proc(argv) for argv in commands]
    time.sleep(4.0)  # past the interpreter's start (the handler is set first thing in main)
    for p in procs:
        p.send_signal(signal.SIGINT)
    for argv, p in zip(commands, procs):
        out, err = p.communicate(timeout=60)
        assert p.returncode == 130, (argv, err)
        assert err == f"{PROG} {argv[0]}: interrupted\n"
    for f in tmp_path.iterdir():  # figures: what is there is whole, no temporary is left
        assert f.suffix == ".png" and not f.name.startswith(".") and _complete_png(f), f.name


@pytest.mark.slow
@pytest.mark.parametrize("argv", [["calibrate", "--runs", "3"], ["coop"], ["figures", "--list"]],
                         ids=["calibrate", "coop", "figures"])
def test_closed_stdout_exits_quietly(argv):
    """``| head -1`` closes the pipe: no BrokenPipeError traceback, nothing on stderr, exit 141."""
    p = subprocess.Popen([sys.executable, "-m", "kfcal_helpers", *argv], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, env=ENV)
    p.stdout.close()
    err = p.stderr.read()
    p.wait(timeout=60)
    assert p.returncode == 141 and err == b"", err


# ---------------------------------------------------------------------------
# The process itself: signals (SIGTERM like SIGINT, during the imports, after a progress bar),
# standard streams closed or narrow, matplotlib's config directory not writable.  Real processes
# where it matters; each test's rows failed before kfcal_helpers.process existed.
posix_only = pytest.mark.skipif(os.name != "posix", reason="POSIX signals and descriptors (sh redirections)")
LOUD_ENV = {k: v for k, v in ENV.items() if k not in ("KFCAL_QUIET", "CI")}  # progress bars on

#: run in a process that starts with SIGINT ignored: the root conftest.py, then a command line given Ctrl-C
_AFTER_CONFTEST = """
import runpy, signal, subprocess, sys, time
ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
runpy.run_path(sys.argv[1])  # the root conftest.py, as pytest and each worker load it
p = subprocess.Popen([sys.executable, "-m", "kfcal_helpers", "calibrate", "--runs", "300000"],
                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
time.sleep(4.0)  # past the interpreter's start
p.send_signal(signal.SIGINT)
err = p.communicate(timeout=60)[1]
print(ignored, p.returncode, repr(err))
"""


@pytest.mark.slow
@posix_only
def test_ctrl_c_tests_hold_when_pytest_starts_with_sigint_ignored():
    """A script's background job (``bash .ci/run &``) starts with SIGINT ignored, and what it starts inherits
    that; the root conftest.py takes SIGINT's default back, so the command line the tests start still
    answers Ctrl-C with exit 130 and its one line (without it: exit 0 after the whole run)."""
    conftest = Path(__file__).resolve().parents[1] / "conftest.py"
    r = subprocess.run(["sh", "-c", 'trap "" INT; exec "$@"', "sh", sys.executable, "-c", _AFTER_CONFTEST,
                        str(conftest)], capture_output=True, text=True, env=ENV, timeout=120)
    assert r.stdout.strip().split(maxsplit=2) == ["True", "130", repr(f"{PROG} calibrate: interrupted\n")], (r.stdout, r.stderr)


def _caught(pid: int, signum: int) -> bool | None:
    """Whether process ``pid`` has a handler for ``signum`` (Linux: /proc), None where unknown."""
    try:
        with open(f"/proc/{pid}/status") as f:
            mask = next(int(line.split()[1], 16) for line in f if line.startswith("SigCgt:"))
    except (OSError, StopIteration, ValueError):
        return None
    return bool(mask >> (signum - 1) & 1)


def _wait_for_handler(p, signum, timeout=30.0) -> None:
    """Until ``p`` handles ``signum`` (or ``timeout`` s pass, or 4 s where that cannot be seen)."""
    deadline = time.monotonic() + timeout
    while p.poll() is None and time.monotonic() < deadline:
        caught = _caught(p.pid, signum)
        if caught is None:
            time.sleep(4.0)
            return
        if caught:
            return
        time.sleep(0.01)


@pytest.mark.slow
@posix_only
@pytest.mark.parametrize("argv", [["calibrate", "--runs", "300000"], ["coop", "--runs", "2000", "--filter", "ukf"]],
                         ids=["calibrate", "coop"])
def test_sigterm_while_working_one_line_exit_143(argv):
    """SIGTERM during a Monte Carlo: exit 143 and one line, as for Ctrl-C (was: killed, status -15)."""
    p = _proc(argv)
    _wait_for_handler(p, signal.SIGTERM)
    time.sleep(2.0)  # into the work, past the imports
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 143, (p.returncode, err)
    assert err == f"{PROG} {argv[0]}: terminated\n"


@pytest.mark.slow
@posix_only
@pytest.mark.parametrize("argv", [["figures", "{dir}"], ["calibrate", "--runs", "20", "--figures", "{dir}"]],
                         ids=["figures", "calibrate --figures"])
def test_sigterm_during_a_save_leaves_no_temporary(argv, tmp_path):
    """SIGTERM while a figure is being saved (its ``.NAME.png.PID.part`` file exists): exit 143, one
    line, the temporary removed, every file left complete."""
    out_dir = tmp_path / "out"
    argv = [a.replace("{dir}", str(out_dir)) for a in argv]
    p = _proc(argv)
    caught = []
    deadline = time.monotonic() + 300
    while not caught and p.poll() is None and time.monotonic() < deadline:
        if out_dir.is_dir():
            caught = [f.name for f in out_dir.iterdir() if f.name.endswith(".part")]
        if caught:
            p.send_signal(signal.SIGTERM)
        else:
            time.sleep(0.002)
    out, err = p.communicate(timeout=60)
    assert caught, f"no save seen in progress (exit {p.returncode}, {err!r})"
    assert p.returncode == 143, (p.returncode, err)
    assert err == f"{PROG} {argv[0]}: terminated\n"
    for f in out_dir.iterdir():
        assert f.suffix == ".png" and not f.name.startswith(".") and _complete_png(f), f.name


#: runs ``python -m kfcal_helpers ARGS`` and raises signal SIGNUM the moment module MODULE is first
#: imported: a Ctrl-C (or SIGTERM) during the imports, at a chosen import instead of a guessed time
_SIGNAL_AT_IMPORT = """
import builtins, runpy, signal, sys
module, signum = sys.argv.pop(1), int(sys.argv.pop(1))
real = builtins.__import__
def hook(name, *a, **k):
    if name == module:
        builtins.__import__ = real
        signal.raise_signal(signum)
    return real(name, *a, **k)
builtins.__import__ = hook
runpy.run_module("kfcal_helpers", run_name="__main__", alter_sys=True)
print("the signal was never raised", file=sys.stderr)
"""


@pytest.mark.slow
@pytest.mark.parametrize("module, signame, argv", [
    ("argparse", "SIGINT", ["calibrate", "--runs", "300000"]),  # the command line's first imports
    ("argparse", "SIGTERM", ["coop"]),
    ("numpy", "SIGTERM", ["calibrate", "--runs", "300000"]),  # also: the heavy imports
    ("matplotlib", "SIGTERM", ["figures", "{tmp}", "--only", "coop_paths"]),  # also
    ("process", "SIGINT", ["calibrate", "--runs", "3"]),  # also: while kfcal_helpers.process loads
], ids=["SIGINT at argparse", "SIGTERM at argparse", "SIGTERM at numpy", "SIGTERM at matplotlib",
        "SIGINT at kfcal_helpers.process"])
def test_signal_during_the_imports(module, signame, argv, tmp_path):
    """The handlers are installed before the command line imports anything heavy: a signal during
    the imports ends in one line and 130/143, not a KeyboardInterrupt traceback or a silent kill."""
    signum = getattr(signal, signame)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    r = subprocess.run([sys.executable, "-c", _SIGNAL_AT_IMPORT, module, str(int(signum)), *argv],
                       capture_output=True, text=True, env=ENV, timeout=120)
    code, word = (130, "interrupted") if signame == "SIGINT" else (143, "terminated")
    assert r.returncode == code and r.stderr == f"{PROG} {argv[0]}: {word}\n", (r.returncode, r.stderr)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@posix_only
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_interrupt_line_after_a_progress_bar(signame):
    """With the progress bar on stderr, the interrupt message starts a line of its own (it was glued
    to the end of the bar)."""
    import threading

    signum = getattr(signal, signame)
    p = subprocess.Popen([sys.executable, "-m", "kfcal_helpers", "calibrate", "--runs", "300000"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=LOUD_ENV)
    chunks = []
    reader = threading.Thread(target=lambda: chunks.extend(iter(lambda: p.stderr.read1(4096), b"")), daemon=True)
    reader.start()
    deadline = time.monotonic() + 120
    while b"/300000" not in b"".join(chunks) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert b"/300000" in b"".join(chunks), b"".join(chunks)  # the bar is drawn
    p.send_signal(signum)
    p.wait(timeout=60)
    reader.join(timeout=10)
    p.stdout.close()
    err = b"".join(chunks)
    word = b"interrupted" if signame == "SIGINT" else b"terminated"
    assert p.returncode == (130 if signame == "SIGINT" else 143), err
    assert err.split(b"\n")[-2:] == [PROG.encode() + b" calibrate: " + word, b""], err[-300:]


CLOSED_IN_PROCESS = [  # (stream set to None, argv, exit status)
    ("stdout", ["calibrate", "--runs", "3"], 0),
    ("stdout", ["figures", "--list"], 0),
    ("stdout", ["coop", "--json"], 0),
    ("stdout", ["figures", "{tmp}/out", "--only", "coop_paths"], 0),  # also: the file is still written
    ("stdout", ["calibrate", "--runs", "1"], 2),  # also
    ("stderr", ["calibrate", "--runs", "600"], 0),  # with the progress bar on (it writes to stderr)
    ("stderr", ["coop", "--q-scale", "-1"], 2),  # also: the error line goes nowhere, not on stdout
]


@pytest.mark.parametrize("stream, argv, code", CLOSED_IN_PROCESS,
                         ids=[f"{s} None: {' '.join(a)}" for s, a, _ in CLOSED_IN_PROCESS])
def test_closed_stream_in_process(stream, argv, code, tmp_path, monkeypatch):
    """``sys.stdout`` or ``sys.stderr`` is None (closed with ``>&-`` / ``2>&-``): what would go there is
    discarded, never an exception, and the stream is None again afterwards."""
    import io

    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    other = io.StringIO()
    monkeypatch.setattr(sys, stream, None)
    monkeypatch.setattr(sys, "stderr" if stream == "stdout" else "stdout", other)
    monkeypatch.delenv("KFCAL_QUIET", raising=False)  # progress bars on
    assert main(argv) == code
    assert getattr(sys, stream) is None
    if stream == "stderr":
        assert other.getvalue() == "" if code else other.getvalue().startswith("600 realizations")
    else:
        assert other.getvalue().count("\n") == (1 if code else 0) and "Traceback" not in other.getvalue()
    if "--only" in argv:
        assert _complete_png(tmp_path / "out" / "coop_paths.png")


NARROW = [  # (stdout encoding, argv, bytes the output contains)
    ("ascii", ["figures", "--list"], b"with +/-1sigma, +/-2sigma from P"),
    ("latin-1", ["figures", "--list"], "with ±1sigma, ±2sigma from P".encode("latin-1")),
    ("ascii", ["figures", "{tmp}/dé", "--only", "coop_paths"], b"/d\\xe9/coop_paths.png\n"),
    ("utf-8", ["figures", "{tmp}/x\udcff", "--only", "coop_paths"], b"/x\xff/coop_paths.png\n"),  # an undecodable name
    ("cp1252", ["figures", "--list"], b"sigma"),  # also
    ("ascii", ["figures", "{tmp}/σ", "--only", "coop_paths"], b"/\\u03c3/coop_paths.png\n"),  # also: escaped, not "sigma"
    ("ascii", ["calibrate", "--runs", "3", "--figures", "{tmp}/Δ"], b"wrote "),  # also
]


@pytest.mark.parametrize("encoding, argv, expected", NARROW, ids=[f"{e}: {' '.join(a)}" for e, a, _ in NARROW])
def test_text_output_survives_any_encoding(encoding, argv, expected, tmp_path, monkeypatch, capsys):
    """stdout in ASCII, latin-1, cp1252 or strict UTF-8 (``PYTHONIOENCODING``): exit 0, ASCII
    fallbacks for the characters it lacks, a path printed as its file-system bytes (or escaped)."""
    import io

    if "\udcff" in " ".join(argv) and os.name != "posix":
        pytest.skip("undecodable file names are a POSIX matter")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    raw = io.BytesIO()
    out = io.TextIOWrapper(raw, encoding=encoding, errors="strict", write_through=True)
    monkeypatch.setattr(sys, "stdout", out)
    assert main(argv) == 0, capsys.readouterr().err
    assert capsys.readouterr().err == ""
    assert expected in raw.getvalue(), raw.getvalue()[-300:]
    if "--only" in argv:
        assert _complete_png(Path(argv[1]) / "coop_paths.png")


def test_an_unprintable_path_is_refused_before_writing(tmp_path, monkeypatch, capsys):
    """A stdout that can print only ASCII and cannot be reconfigured: the path that could not be
    printed is refused before any file is written (it was written, then the error reported)."""

    class StrictAscii:
        encoding, errors = "ascii", "strict"

        def write(self, text):
            text.encode("ascii")
            return len(text)

        def flush(self):
            pass

    monkeypatch.setattr(sys, "stdout", StrictAscii())
    for argv, word in ((["figures", str(tmp_path / "dé"), "--only", "coop_paths"], "DIR"),
                       (["calibrate", "--runs", "3", "--figures", str(tmp_path / "dé")], "--figures")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        _one_error_line(err, argv[0])
        assert word in err and "PYTHONIOENCODING" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, blocked, word", [
    (["figures", "{tmp}/out"], "calib_errors.png", "DIR"),
    (["figures", "{tmp}/out", "--svg", "--only", "coop_paths"], "coop_paths.svg", "DIR"),  # also
    (["calibrate", "--runs", "3", "--figures", "{tmp}/out"], "calib_checks.png", "--figures"),  # also
], ids=["figures", "figures --svg", "calibrate --figures"])
def test_a_target_that_is_a_directory_is_refused_before_the_work(argv, blocked, word, tmp_path, capsys, monkeypatch):
    """``DIR/<name>.png`` exists as a directory, so that file cannot be written: refused in one line
    before any figure is drawn or Monte Carlo run, and no other file written (they were, before)."""
    (tmp_path / "out" / blocked).mkdir(parents=True)
    before = _files(tmp_path)

    def no_work(*a, **k):
        raise AssertionError("long work started")

    monkeypatch.setattr(calibration_cli, "run_monte_carlo", no_work)
    _no_figure_data(monkeypatch, no_work)
    code, out, err = _run([a.replace("{tmp}", str(tmp_path)) for a in argv], capsys)
    assert code == 2 and out == ""
    _one_error_line(err, argv[0])
    assert word in err and blocked in err and "a directory of that name exists" in err
    assert _files(tmp_path) == before


def _sh(redirect: str, argv, env=ENV, cwd=None):
    return subprocess.run(["sh", "-c", f'exec "$@" {redirect}', "sh", sys.executable, "-m", "kfcal_helpers", *argv],
                          capture_output=True, env=env, cwd=cwd, timeout=120)


CLOSED_REAL = [  # (redirection, argv, exit status, what stdout holds)
    (">&-", ["calibrate", "--runs", "3"], 0, b""),
    (">&-", ["coop", "--json"], 0, b""),
    (">&-", ["figures", "--list"], 0, b""),
    ("2>&-", ["calibrate", "--runs", "600"], 0, b"600 realizations"),  # progress bar on
    ("2>&-", ["coop", "--q-scale", "-1"], 2, b""),  # also
    (">&- 2>&-", ["figures", "{tmp}/out", "--only", "coop_paths"], 0, b""),  # also
]


@pytest.mark.slow
@posix_only
@pytest.mark.parametrize("redirect, argv, code, stdout", CLOSED_REAL,
                         ids=[f"{r} {' '.join(a)}" for r, a, _, _ in CLOSED_REAL])
def test_closed_stream_real_process(redirect, argv, code, stdout, tmp_path):
    """``python -m kfcal_helpers ... >&-`` (or ``2>&-``): no AttributeError traceback, the usual exit
    status, nothing on the other stream but the command's own output."""
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    r = _sh(redirect, argv, env=LOUD_ENV if "600" in argv else ENV)
    assert r.returncode == code, r.stderr
    assert r.stdout.startswith(stdout) and (stdout or r.stdout == b"")
    if "2>&-" not in redirect:
        assert r.stderr == (b"" if code == 0 else r.stderr.splitlines()[0] + b"\n")
    if "--only" in argv:
        assert _complete_png(tmp_path / "out" / "coop_paths.png")


ENCODED_REAL = [  # (PYTHONIOENCODING, argv, bytes stdout contains)
    ("ascii", ["figures", "--list"], b"+/-1sigma"),
    ("latin-1", ["figures", "--list"], "±1sigma".encode("latin-1")),
    ("ascii", ["figures", "{tmp}/dé", "--only", "coop_paths"], b"d\\xe9/coop_paths.png\n"),
    ("utf-8", ["figures", "{tmp}/x\udcff", "--only", "coop_paths"], b"x\xff/coop_paths.png\n"),  # also
]


@pytest.mark.slow
@posix_only
@pytest.mark.parametrize("encoding, argv, expected", ENCODED_REAL, ids=[f"{e}: {' '.join(a)}" for e, a, _ in ENCODED_REAL])
def test_text_output_survives_any_encoding_real_process(encoding, argv, expected, tmp_path):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    r = subprocess.run([sys.executable, "-m", "kfcal_helpers", *argv], capture_output=True, timeout=120,
                       env={**ENV, "PYTHONIOENCODING": encoding, "PYTHONUTF8": "0"})
    assert r.returncode == 0 and r.stderr == b"", r.stderr
    assert expected in r.stdout, r.stdout[-300:]


@pytest.mark.slow
@posix_only
def test_unwritable_matplotlib_directories_print_nothing():
    """HOME (so ~/.config/matplotlib, ~/.cache/matplotlib) or MPLCONFIGDIR not writable: nothing
    about matplotlib on stderr (it printed two lines per command), the usual output; the private
    directory is the user's own (mode 700).  Also: a decoy directory of that name that is not
    private is not used (a fresh one is, and removed at exit)."""
    prefix = _as_nobody()
    if prefix is None:
        pytest.skip("running as root without setpriv or the user nobody")
    root = Path(tempfile.mkdtemp(prefix="kfcal-mpl-"))
    try:
        root.chmod(0o755)
        home, ro, tmp, out = root / "home", root / "ro", root / "tmp", root / "out"
        for d in (home, ro):
            d.mkdir()
            d.chmod(0o555)
        for d in (tmp, out):
            d.mkdir()
            d.chmod(0o1777)
        base = {k: v for k, v in ENV.items() if k not in ("MPLCONFIGDIR", "XDG_CONFIG_HOME", "XDG_CACHE_HOME")}
        cases = [  # (environment change, argv, exit status)
            ({"HOME": str(home)}, ["coop", "--json"], 0),
            ({"HOME": str(home)}, ["calibrate", "--runs", "3", "--json"], 0),
            ({"HOME": str(home)}, ["figures", "--list"], 0),
            ({"HOME": str(home)}, ["figures", str(out), "--only", "coop_paths"], 0),
            ({"HOME": str(home)}, ["calibrate", "--omega", "-1"], 2),
            ({"HOME": str(home), "MPLCONFIGDIR": str(ro)}, ["coop", "--json"], 0),
            ({"HOME": str(home), "MPLCONFIGDIR": str(ro / "sub")}, ["figures", "--list"], 0),
        ]
        for change, argv, code in cases:
            r = subprocess.run([*prefix, sys.executable, "-m", "kfcal_helpers", *argv], capture_output=True, text=True,
                               env={**base, **change, "TMPDIR": str(tmp)}, cwd=root, timeout=300)
            assert r.returncode == code, (argv, r.stderr)
            if code == 0:
                assert r.stdout and r.stderr == "", (change, argv, r.stderr)
            else:
                _one_error_line(r.stderr, argv[0])
        private = [d for d in tmp.iterdir() if d.name.startswith("kfcal-matplotlib-")]
        assert len(private) == 1 and private[0].stat().st_mode & 0o777 == 0o700
        assert _complete_png(out / "coop_paths.png")
        # a decoy of the private directory's name that others may write: not used
        decoy = private[0]
        for f in decoy.iterdir():
            f.unlink() if f.is_file() else shutil.rmtree(f)
        os.chmod(decoy, 0o777)
        r = subprocess.run([*prefix, sys.executable, "-m", "kfcal_helpers", "figures", "--list"], capture_output=True,
                           text=True, env={**base, "HOME": str(home), "TMPDIR": str(tmp)}, cwd=root, timeout=300)
        assert r.returncode == 0 and r.stderr == "", r.stderr
        assert list(decoy.iterdir()) == [] and sorted(d.name for d in tmp.iterdir()) == [decoy.name]
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _as_nobody():
    """argv prefix running a command as the unprivileged user nobody, or None."""
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    try:
        import pwd

        nobody = pwd.getpwnam("nobody")
    except (ImportError, KeyError):
        return None
    if setpriv is None:
        return None
    return [setpriv, f"--reuid={nobody.pw_uid}", f"--regid={nobody.pw_gid}", "--clear-groups"]


#: ``python -m kfcal_helpers ARGS`` with the long work (every Monte Carlo, filter run and figure data)
#: replaced by a failure: a command that starts it prints a line and exits 99
NO_LONG_WORK = """
import dataclasses, os, runpy, sys
from kfcal_helpers import problems
from kfcal_helpers.calibration import cli as calibration_cli
from kfcal_helpers.coop import cli as coop_cli
def started(*a, **k):
    print("the long work started", file=sys.stderr, flush=True)
    os._exit(99)
calibration_cli.run_monte_carlo = coop_cli.run_filter = coop_cli.truth_model_test = coop_cli.fit_q_scale = started
problems.PROBLEMS = tuple(dataclasses.replace(p, figure_data=started) for p in problems.PROBLEMS)
sys.argv[0] = "kfcal_helpers"
runpy.run_module("kfcal_helpers", run_name="__main__", alter_sys=True)
"""


@pytest.mark.slow
def test_unreadable_and_unwritable_files_real_process():
    """Real permissions (as user nobody when running as root): an unreadable ydata.csv, and output
    folders that cannot be written, refused in one line before any long work."""
    prefix = _as_nobody()
    if prefix is None:
        pytest.skip("running as root without setpriv or the user nobody: the in-process tests cover this")
    import matplotlib

    root = Path(tempfile.mkdtemp(prefix="kfcal-perm-"))
    try:
        root.chmod(0o755)
        mpl = root / "mpl"
        shutil.copytree(matplotlib.get_cachedir(), mpl)  # no "building the font cache" line
        os.chmod(mpl, 0o777)
        for f in mpl.rglob("*"):
            f.chmod(0o777)
        folder = _log_folder(root)
        (folder / "ydata.csv").chmod(0)
        ro = root / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        env = {**ENV, "MPLCONFIGDIR": str(mpl), "HOME": str(root)}
        for argv, words in ((["coop", "--log", str(folder)], ["--log: cannot read", "Permission denied"]),
                            (["calibrate", "--runs", "200000", "--figures", str(ro / "x")],
                             ["--figures: cannot write into"]),
                            (["figures", str(ro)], ["DIR: cannot write into"])):
            # refused before the work: a command that starts it exits 99 (NO_LONG_WORK), not 2
            r = subprocess.run([*prefix, sys.executable, "-c", NO_LONG_WORK, *argv], capture_output=True,
                               text=True, env=env, cwd=root, timeout=120)
            assert r.returncode == 2 and r.stdout == "", r.stderr
            _one_error_line(r.stderr, argv[0])
            for w in words:
                assert w in r.stderr
        assert list(ro.iterdir()) == []
    finally:
        shutil.rmtree(root, ignore_errors=True)


def test_estimate_bounds_chunks_and_refuses():
    """The chunk size follows one realization's size: 500 for the default scenario, fewer for long ones."""
    from kfcal_helpers.calibration import montecarlo
    from kfcal_helpers.calibration.montecarlo import CHUNK_SIZE, chunk_size, estimate_run

    assert montecarlo.MEMORY_LIMIT == MEMORY_LIMIT

    assert chunk_size(CalibrationParams()) == CHUNK_SIZE == 500
    long = CalibrationParams(imu_rate=2000.0, duration=300.0, gps_rate=1.0)
    assert 1 <= chunk_size(long) < 50
    peak, seconds = estimate_run(long, 100)
    assert peak <= MEMORY_LIMIT and seconds > 0
    with pytest.raises(ValueError, match=r"n_runs: 1000000000 realizations .* about \d+ h"):
        estimate_run(CalibrationParams(), 10**9)
    with pytest.raises(ValueError, match=r"params: one realization .* about \d+ MB"):
        estimate_run(CalibrationParams(gps_rate=200.0), 2)


# --- course-log reader (log-api) ---
import log_files as lf  # noqa: E402

from kfcal_helpers.coop import cli as coop_cli  # noqa: E402

# (id, build(tmp) -> the --log argument, extra options, words the one stderr line must contain)
LOG_READER_BAD = [
    ("fifo ydata", lambda t: lf.folder_with(t, "ydata", lf.fifo), [], ["--log", "ydata.csv is a FIFO", "regular files"]),
    ("fifo mat", lambda t: lf.fifo(t / "log.mat"), [], ["--log", "log.mat is a FIFO"]),
    ("ydata link to /dev/zero", lambda t: lf.folder_with(t, "ydata", lambda f: lf.link("/dev/zero", f)), [],
     ["--log", "a link to /dev/zero", "character device"]),
    ("mat link to /dev/zero", lambda t: lf.link("/dev/zero", t / "log.mat"), [], ["--log", "character device"]),
    ("tvec link to /dev/urandom", lambda t: lf.folder_with(t, "tvec", lambda f: lf.link("/dev/urandom", f)), [],
     ["--log", "character device"]),
    ("socket Qtrue", lambda t: lf.folder_with(t, "Qtrue", lf.unix_socket), [], ["--log", "Qtrue.csv is a socket"]),
    ("mat bomb", lambda t: lf.mat_bomb(t / "bomb.mat"), [], ["ydata: 20000000 steps", "MB", "500 MB memory limit"]),
    ("mat too long", lf.long_mat, [], ["ydata: 168270 steps", "more than the 168269 allowed"]),
    ("csv too long", lf.long_log, ["--filter", "lkf"], ["ydata: 168270 steps", "MB"]),
    ("csv too long, every 10", lf.long_log, ["--every", "10"], ["ydata: 168270 steps"]),
    ("sparse 100 MB ydata", lambda t: lf.folder_with(t, "ydata", lf.sparse_file), [], ["ydata", "is larger than the"]),
    ("sparse 200 MB mat", lambda t: lf.sparse_file(t / "log.mat", 200_000_000), [], ["--log", "is larger than the"]),
    ("epoch step below float spacing", lambda t: lf.retimed_log(t, lf.EPOCH + 1e-4 * np.arange(11)), [],
     ["tvec", "too small for times near 1.7e+09 s"]),
    ("256-char log name", lambda t: t / ("a" * 256), [], ["--log", "cannot read"]),
    ("alpha 1e-300", lf.log_folder, ["--alpha", "1e-300"], ["--alpha", "[1e-06, 0.5]"]),
    ("alpha 1e-7 runs", None, ["--runs", "2", "--alpha", "1e-7"], ["--alpha", "[1e-06, 0.5]"]),
    # arguments and messages (inputs)
    ("every 100000 runs", None, ["--runs", "3", "--every", "100000"], ["--every", "at most 1000"]),
    ("every 2000 q-scale auto", lf.log_folder, ["--every", "2000", "--q-scale", "auto"],
     ["--every", "at most 10 (the log has 11 steps"]),
    ("every keeps only NaN rows", lambda t: _log_folder(t, ydata=_ydata_text(_every_fifth_missing())), ["--every", "5"],
     ["--every 5 keeps no measurement of this log"]),
    ("NaN in tvec", lambda t: lf.retimed_log(t, np.r_[0.1 * np.arange(10), np.nan]),
     [], ["tvec must hold only finite times", "nan at column 10"]),
    ("Qtrue 1e300 I", lambda t: (lambda f: ((f / "Qtrue.csv").write_text(
        "".join(",".join("1e300" if i == j else "0" for j in range(6)) + "\n" for i in range(6))), f)[1])(
        lf.log_folder(t)), [], ["Qtrue variances must be at most 1e+12"]),
]


@pytest.mark.parametrize("build, extra, words", [r[1:] for r in LOG_READER_BAD], ids=[r[0] for r in LOG_READER_BAD])
def test_course_log_reader_one_line_exit_2(build, extra, words, tmp_path, capsys, monkeypatch):
    """Special files, bombs, logs too long for memory, timestamps and significance levels: one line naming
    what is wrong with the log (or the option), exit 2, before any filter runs."""
    def no_filter(*a, **k):
        raise AssertionError("a filter started before the log was checked")

    monkeypatch.setattr(coop_cli, "run_filter", no_filter)
    monkeypatch.setattr(coop_cli, "truth_model_test", no_filter)
    argv = ["coop", *(["--log", str(build(tmp_path))] if build is not None else []), *extra]
    code, out, err = _run(argv, capsys)
    assert code == 2 and out == "", err
    _one_error_line(err, "coop")
    for word in words:
        assert word in err, (word, err)
    assert "realizations" not in err


@pytest.mark.parametrize("times", [lf.EPOCH + 0.1 * np.arange(21), 1e3 * lf.EPOCH + 100.1 * np.arange(21)],
                         ids=["epoch s", "epoch ms"])
def test_course_log_with_epoch_times_runs(times, tmp_path, capsys):
    """A log timed in Unix-epoch seconds (or ms): its float-rounded steps are a constant step."""
    code, out, err = _run(["coop", "--log", str(lf.retimed_log(tmp_path, times)), "--json"], capsys)
    assert code == 0 and err == "", err
    assert json.loads(out)["steps"] == times.size


def test_memory_error_on_a_log_blames_the_log(tmp_path, capsys, monkeypatch):
    """Out of memory while filtering a log: the advice is about the log, not about realizations."""
    def no_memory(*a, **k):
        raise MemoryError

    monkeypatch.setattr(coop_cli, "run_filter", no_memory)
    code, out, err = _run(["coop", "--log", str(lf.log_folder(tmp_path))], capsys)
    assert code == 2 and out == ""
    _one_error_line(err, "coop")
    assert "not enough memory" in err and "shorter log" in err and "realizations" not in err


# --- the course-log reader's bounds on lines and values (inputs) ---
LOG_SHAPE_BAD = [
    ("8.9 million short lines", lambda t: lf.folder_with(t, "ydata", lf.short_lines),
     ["ydata", "has 8900000 lines", "5 x K matrix"]),
    ("one line of 13 million values", lambda t: lf.folder_with(t, "ydata", lf.one_long_line),
     ["ydata: 13000000 steps", "168269 allowed"]),
    ("semicolon-separated", lambda t: lf.spreadsheet_log(t, sep=";"), ["ydata", "semicolon-separated", "comma"]),
]

#: a child process: the command line on argv, then its own peak resident memory (VmHWM, bytes) on stderr
_PEAK_CHILD = ("import sys; from kfcal_helpers.cli import main; code = main(sys.argv[1:]); "
               "print([int(l.split()[1]) * 1024 for l in open('/proc/self/status') if l.startswith('VmHWM')][0], "
               "file=sys.stderr); sys.exit(code)")


@pytest.mark.parametrize("build, words", [r[1:] for r in LOG_SHAPE_BAD], ids=[r[0] for r in LOG_SHAPE_BAD])
def test_log_of_the_wrong_shape_one_line_exit_2(build, words, tmp_path, capsys, monkeypatch):
    """A log file of millions of short lines, of one line of millions of values, or separated by semicolons:
    one line naming the file's variable, exit 2, before any filter runs."""
    monkeypatch.setattr(coop_cli, "run_filter", lambda *a, **k: pytest.fail("a filter ran"))
    code, out, err = _run(["coop", "--log", str(build(tmp_path))], capsys)
    assert code == 2 and out == "", err
    _one_error_line(err, "coop")
    for word in words:
        assert word in err, (word, err)


def test_log_saved_by_a_spreadsheet_runs(tmp_path, capsys):
    """A log with a UTF-8 byte-order mark and CRLF line ends gives the numbers of the plain log."""
    plain = _run(["coop", "--log", str(lf.log_folder(tmp_path / "a")), "--json"], capsys)
    sheet = _run(["coop", "--log", str(lf.spreadsheet_log(tmp_path / "b")), "--json"], capsys)
    assert plain[0] == sheet[0] == 0 and sheet[2] == ""
    a, b = json.loads(plain[1]), json.loads(sheet[1])
    assert a["nis_time_average"] == b["nis_time_average"] and a["steps"] == b["steps"]


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="VmHWM is read from /proc (Linux)")
@pytest.mark.parametrize("build, words", [r[1:] for r in LOG_SHAPE_BAD[:2]], ids=[r[0] for r in LOG_SHAPE_BAD[:2]])
def test_refused_log_peak_memory_of_a_child(build, words, tmp_path):
    """The 27 MB file of 8.9 million short lines (which peaked at 883 MB before it was refused) and the
    one-line file of 13 million values: a child process, SIGINT at its default, refuses them (exit 2,
    one line) with a peak resident memory (VmHWM) within the 500 MB promise, and within 100 MB of what
    the interpreter and its imports take on a valid small log."""
    env = {**ENV, "KFCAL_WORKERS": "2"}

    def child(folder):
        r = subprocess.run([sys.executable, "-c", _PEAK_CHILD, "coop", "--log", str(folder)], capture_output=True,
                           text=True, env=env, timeout=300, preexec_fn=_sigint_default)
        *lines, peak = r.stderr.strip().splitlines()
        return r.returncode, lines, int(peak)

    code, lines, peak = child(build(tmp_path / "bad"))
    base_code, _, base = child(lf.log_folder(tmp_path / "good"))
    assert base_code == 0
    assert peak <= MEMORY_LIMIT and peak - base < 100e6, (peak / 1e6, base / 1e6)
    assert code == 2 and len(lines) == 1, lines
    for word in words:
        assert word in lines[0], (word, lines)


def _sigint_default():
    signal.signal(signal.SIGINT, signal.SIG_DFL)
