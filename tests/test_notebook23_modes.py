"""Notebook 23 is true in every mode it can meet: without KFCAL_ORBIT_LOG (a seeded generated log, the
committed mode) and with KFCAL_ORBIT_LOG naming another valid log in the course's format (the course's own
file is not available here: logs written by ``write_log_mat`` / ``write_log_csv`` from other seeds and
settings stand in for it, among them a 50-step log and a 2-sample log with one update).  Each run executes the whole notebook in a fresh kernel
(nbclient): every assert of the mode runs, and a failing one fails the test with its cell; no output may
hold an error, a NaN or a warning, and the lines that carry the log-dependent verdicts must be there."""

from dataclasses import replace
from pathlib import Path

import nbformat
import numpy as np
import pytest
from nbclient import NotebookClient

from kfcal_helpers.orbit import OrbitParams, load_log, simulate, write_log_csv, write_log_mat

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "23_orbit_data_log.ipynb"

FIRST_LINE = {
    "generated": "no course log (KFCAL_ORBIT_LOG is not set): using a generated log",
    "log": "course log found (KFCAL_ORBIT_LOG): ",
}


def _execute(monkeypatch, log_path):
    if log_path is None:
        monkeypatch.delenv("KFCAL_ORBIT_LOG", raising=False)
    else:
        monkeypatch.setenv("KFCAL_ORBIT_LOG", str(log_path))
    monkeypatch.setenv("KFCAL_QUIET", "1")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(NOTEBOOK.parent)}}).execute()
    return nb


def _text(cell) -> str:
    return "".join(o.get("text", "") for o in cell.get("outputs", [])
                   if o.get("output_type") == "stream" and o.get("name") == "stdout")


def _check(nb, mode) -> str:
    code = [c for c in nb.cells if c.cell_type == "code"]
    first = _text(code[0]).splitlines()[0]
    assert first.startswith(FIRST_LINE[mode]), first
    for cell in code:
        outputs = cell.get("outputs", [])
        assert not any(o.get("output_type") == "error" for o in outputs)
        assert not any(o.get("output_type") == "stream" and o.get("name") == "stderr" for o in outputs), outputs
        assert "nan" not in _text(cell).lower(), _text(cell)
        assert "warning" not in _text(cell).lower(), _text(cell)
    joined = "\n".join(_text(c) for c in code)
    # the verdict lines the text points at, on every log
    for words in ("LKF: time-averaged NIS", "EKF: time-averaged NIS", "UKF: time-averaged NIS",
                  "fixed 3 dof, band", "on this log: fewer measurements", "checks passed: per-step bands"):
        assert words in joined, words
    assert f"(mode: {mode})" in joined
    # the three bad files each get their one line
    for name in ("orbit_log.txt: path: <folder>/orbit_log.txt must be a .mat file or a folder of CSVs",
                 "matrix_ydata.mat: ydata must be a cell array", "no_Rtrue.mat: Rtrue: variable missing from"):
        assert name in joined, name
    return joined


def test_without_a_log(monkeypatch):
    joined = _check(_execute(monkeypatch, None), "generated")
    assert "checks passed: per-step bands, generated log (mode: generated)" in joined


LOGS = {
    "another seed (.mat)": lambda: simulate(seed=7).log(),
    "50 steps (.mat)": lambda: simulate(OrbitParams(n_steps=50), seed=3).log(),
    "2 samples (.mat)": lambda: simulate(OrbitParams(n_steps=1), seed=3).log(),
    "Rtrue x 4, 300 steps (CSV folder)": lambda: simulate(replace(OrbitParams(n_steps=300),
                                                                  Rtrue=4 * OrbitParams().Rtrue), seed=11).log(),
}
#: the logs whose run takes longest (the full-size one and the 300 steps): the slow tier, which .ci/run runs
SLOW_LOGS = ("another seed (.mat)", "Rtrue x 4, 300 steps (CSV folder)")


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_LOGS else n for n in LOGS])
def test_with_another_valid_log(name, tmp_path, monkeypatch):
    log = LOGS[name]()
    path = write_log_csv(log, tmp_path / "log") if "CSV" in name else write_log_mat(log, tmp_path / "orbit.mat")
    read = load_log(path)
    assert read.truth is None and read.t.size == log.t.size
    joined = _check(_execute(monkeypatch, path), "log")
    assert "(mode: log)" in joined and "generated log (mode" not in joined
    assert "this log has no truth" in joined            # a file carries no truth: no error is claimed
    # the sentences stated for any log of this geometry: at most two stations per step, and at most one once
    # every other station is dropped (stations 60 degrees apart do not overlap at 300 km)
    assert read.dof.max() <= 6
    odd = [np.asarray(b).reshape(4, -1) for b in read.ydata]
    assert max(int((b[3] % 2 == 1).sum()) for b in odd) <= 1
    if log.t.size == 2:         # one update: the thinned logs that keep none say so in one line
        assert "every 3rd step: no measurement left on this log" in joined
    if log.t.size == 1401:      # a full-length log: the fewer-measurement verdict is that of the text
        assert "on this log: fewer measurements widen the median 2-sigma band" in joined


def test_a_bad_file_named_by_the_variable_gets_the_notebooks_one_line(tmp_path, monkeypatch):
    """What the notebook's first cell raises when KFCAL_ORBIT_LOG names a bad file: the line its text shows
    for load_log, the path named as KFCAL_ORBIT_LOG."""
    from kfcal_helpers.orbit import course_log
    bad = tmp_path / "orbit_log.txt"
    bad.write_text("0, 10, 20\n")
    monkeypatch.setenv("KFCAL_ORBIT_LOG", str(bad))
    with pytest.raises(ValueError) as info:
        course_log()
    assert str(info.value) == f"KFCAL_ORBIT_LOG: {bad} must be a .mat file or a folder of CSVs"
