"""Notebook 13 is true in every mode it can meet: without the course log (KFCAL_COURSE_LOG unset: a seeded
generated log, the committed mode), with the course log (when KFCAL_COURSE_LOG names it; skipped otherwise)
and with other valid logs (another Q; 2 or 101 samples; every 20th measurement, where the NIS moving
average's 50 measurements span 100 s, not 5 s), where it says in one line that the course-log numbers
are not that log's and goes on.  Each run executes the whole notebook in a fresh kernel (nbclient): every
assert of the mode runs, and a failing one fails the test with its cell.

nbval runs notebook 13 too (in the mode the environment selects); when it has done so in this process
(the root ``conftest.py`` schedules it first, on the same worker), with every cell passed and the same
KFCAL_COURSE_LOG, that mode's test checks nbval's outputs instead of running the notebook once more."""

import os
from dataclasses import replace
from pathlib import Path

import nbformat
import numpy as np
import pytest
from nbclient import NotebookClient

from kfcal_helpers.coop import CoopParams, course_log_path, is_course_log, load_log, simulate, write_log_csv

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "13_coop_log_comparison.ipynb"

FIRST_LINE = {
    "generated": "no course log (KFCAL_COURSE_LOG is not set): using a generated log",
    "course": "course log found (KFCAL_COURSE_LOG)",
    "other": "a log other than the course's (KFCAL_COURSE_LOG): the numbers quoted below for the course log",
}


def _execute(monkeypatch, log_path, nbval_runs=None):
    """Notebook 13 executed with KFCAL_COURSE_LOG naming ``log_path`` (unset for None): nbval's run of it
    when that had the same environment and passed (``nbval_runs``), else a fresh one."""
    wanted = None if log_path is None else str(log_path)
    run = (nbval_runs or {}).get(str(NOTEBOOK))
    if run is not None and run["passed"] and run["course_log"] == wanted and run["quiet"] == "1":
        nb = nbformat.read(NOTEBOOK, as_version=4)
        code = [c for c in nb.cells if c.cell_type == "code"]
        if len(run["outputs"]) == len(code):
            for cell, outputs in zip(code, run["outputs"]):
                cell.outputs = [nbformat.from_dict(o) for o in outputs]
            return nb
    if log_path is None:
        monkeypatch.delenv("KFCAL_COURSE_LOG", raising=False)
    else:
        monkeypatch.setenv("KFCAL_COURSE_LOG", str(log_path))
    monkeypatch.setenv("KFCAL_QUIET", "1")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(nb, timeout=900, kernel_name="python3",
                   resources={"metadata": {"path": str(NOTEBOOK.parent)}}).execute()
    return nb


def _text(cell) -> str:
    return "".join(o.get("text", "") for o in cell.get("outputs", []) if o.get("output_type") == "stream")


def _check(nb, mode):
    code = [c for c in nb.cells if c.cell_type == "code"]
    first = _text(code[0]).splitlines()[0]
    assert first.startswith(FIRST_LINE[mode]), first
    for cell in code:
        assert not any(o.get("output_type") == "error" for o in cell.get("outputs", []))
        assert "nan" not in _text(cell).lower().replace("first column nan", ""), _text(cell)
        assert "Warning" not in _text(cell), _text(cell)


def test_without_the_course_log(monkeypatch, nbval_runs):
    _check(_execute(monkeypatch, None, nbval_runs), "generated")


def test_with_the_course_log(monkeypatch, nbval_runs):
    path = course_log_path()
    if path is None:
        pytest.skip("KFCAL_COURSE_LOG names no course log")
    assert is_course_log(load_log(path))
    # the variable as set (what nbval's kernel had), naming the course log
    _check(_execute(monkeypatch, os.environ["KFCAL_COURSE_LOG"], nbval_runs), "course")


# each case executes the whole notebook in a kernel of its own (about 7 s): the slow tier, which .ci/run runs
@pytest.mark.slow
@pytest.mark.parametrize("make", [
    lambda: simulate(replace(CoopParams(), Qtrue=4.0 * CoopParams().Qtrue), seed=7).log(),
    lambda: simulate(CoopParams(duration=0.1), seed=3).log(),
    lambda: simulate(CoopParams(duration=10.0), seed=3).log(),
    lambda: simulate(seed=5).log().every(20),
], ids=["another Q", "2 samples", "101 samples", "every 20th measurement"])
def test_with_another_valid_log(make, tmp_path, monkeypatch):
    log = make()
    assert not is_course_log(log)
    nb = _execute(monkeypatch, write_log_csv(log, tmp_path / "log"))
    _check(nb, "other")
    joined = "\n".join(_text(c) for c in nb.cells if c.cell_type == "code")
    n_updates = int(np.isfinite(log.y).all(axis=1).sum())
    if log.n_samples == 2:  # the views that need many measurements say so in one line
        assert "only 1 measurement(s): too few for a 50-step moving average" in joined
        assert "too few for autocorrelations" in joined
    if log.n_samples == 101:  # a moving average, but no window after t = 80 s
        assert "after t = 80 s: no complete window (the last window's centre is at t = 7.6 s)" in joined
        assert "a window: 50 measurements, 0.1 s apart (median), covering 5 s" in joined
    if log.n_samples == 1001 and n_updates == 50:  # every 20th: the one window spans 100 s, not 5 s
        assert "a window: 50 measurements, 2 s apart (median), covering 100 s" in joined
    if log.n_samples == 1001 and n_updates == 1000:  # Qtrue x 4: the EKF and the UKF part by more than the course log's 0.15 m
        assert "on this log: the EKF and the UKF differ by up to" in joined


def test_course_log_fingerprint_tells_logs_apart():
    """is_course_log: the generated log and small changes of a log are not the course's."""
    generated = simulate().log()
    assert not is_course_log(generated)
    with pytest.raises(ValueError, match="log must be a CoopLog"):   # not a log at all: named, not a verdict
        is_course_log("not a log")
    path = course_log_path()
    if path is None:
        return
    course = load_log(path)
    assert is_course_log(course)
    y = course.y.copy()
    y[5, 1] += 0.01  # one range 1 cm off
    assert not is_course_log(type(course)(course.t, y, course.Qtrue, course.Rtrue))
    assert not is_course_log(type(course)(course.t, course.y, 2 * course.Qtrue, course.Rtrue))
    assert np.isfinite(course.dt)
