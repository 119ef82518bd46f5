"""The graded answers' record (in the student's kernel) and re-check (in the grader's process):
kfcal_helpers.exercises.grading.  The round trip through nbgrader is tests/test_nbgrader_roundtrip.py."""

import base64
import io
import json
import math
import subprocess
import sys

import numpy as np
import pytest

import kfcal_helpers.calibration.exercises as calib
from kfcal_helpers.exercises.grading import RecordError, decode, encode, make_record, recheck, recheck_all

MODULE = "kfcal_helpers.calibration.exercises"
RIGHT_03_1 = np.arange(0, 30 * 200 + 1, 50)   # the fixes' IMU indices at 200 Hz and 4 Hz


def roundtrip(value):
    return decode(json.loads(json.dumps(encode(value))))


@pytest.mark.parametrize("value", [
    None, ..., True, 0, -7, 10**400, 0.1, -0.0, 1e308, 1 + 2j, "text", b"\x00\xff", [1, [2.5, None]], (1, (2,)),
    {"a": 1, 2: (3.0,)}, np.arange(6.0).reshape(2, 3) / 7, np.array([1, 2], dtype=np.int64), np.float32(0.1),
    np.int64(-3), np.array(["a", "bc"]), np.array([1.0, None], dtype=object), np.zeros((0, 3)),
    np.array([[1 + 1j]]),
])
def test_values_come_back_exactly(value):
    back = roundtrip(value)
    assert type(back) is type(value) or isinstance(value, (list, tuple)) and type(back) is type(value)
    if isinstance(value, np.ndarray):
        assert back.dtype == value.dtype and back.shape == value.shape
        assert [repr(v) for v in back.flat] == [repr(v) for v in value.flat]
    else:
        assert repr(back) == repr(value)


def test_nan_and_inf_come_back():
    back = roundtrip([math.nan, math.inf, np.array([np.nan, -np.inf])])
    assert math.isnan(back[0]) and back[1] == math.inf and np.isnan(back[2][0]) and back[2][1] == -np.inf


def test_other_objects_come_back_as_their_type_name_only():
    class Sneaky:
        def __eq__(self, other):
            return True
    back = roundtrip([Sneaky(), print])
    assert type(back[0]).__name__ == "Sneaky" and back[0] != 1 and type(back[1]).__name__ == "builtin_function_or_method"


@pytest.mark.parametrize("data", [
    {"t": "forged", "v": "right"}, {"t": "float", "v": 1.0}, {"t": "int", "v": 3}, [], "x", {"t": "nd", "npy": "%%"},
    {"t": "list", "v": [{"t": "bool", "v": 1}]}, {"v": 1},
])
def test_anything_else_does_not_decode(data):
    with pytest.raises(RecordError):
        decode(data)


def test_a_pickled_array_is_never_unpickled():
    buf = io.BytesIO()
    np.save(buf, np.array([print], dtype=object), allow_pickle=True)
    with pytest.raises(RecordError):
        decode({"t": "nd", "npy": base64.b64encode(buf.getvalue()).decode("ascii")})


def test_a_value_answer_is_rechecked_by_the_genuine_check():
    line, record = make_record("03.1", MODULE, "check_gps_fix_indices", RIGHT_03_1)
    assert line.startswith("✔ 03.1 correct")
    assert recheck("03.1", MODULE, "check_gps_fix_indices", json.loads(json.dumps(record))) == (True, line)
    line, record = make_record("03.1", MODULE, "check_gps_fix_indices", RIGHT_03_1[:-1])
    correct, again = recheck("03.1", MODULE, "check_gps_fix_indices", record)
    assert not correct and again == line == str(calib.check_gps_fix_indices(RIGHT_03_1[:-1]))


def test_a_record_for_another_exercise_or_check_or_module_is_not_graded():
    _, record = make_record("03.1", MODULE, "check_gps_fix_indices", RIGHT_03_1)
    for exercise, module, check in [("03.2", MODULE, "check_gps_fix_indices"), ("03.1", MODULE, "check_gps_dz"),
                                    ("03.1", "os", "check_gps_fix_indices"), ("03.1", MODULE, "EXERCISES")]:
        correct, line = recheck(exercise, module, check, record)
        assert not correct and "not graded" in line and "record of your answer" in line, (exercise, module, check)
    for broken in ({**record, "v": 0}, {**record, "answer": {"t": "forged"}}, None, "✔"):
        assert not recheck("03.1", MODULE, "check_gps_fix_indices", broken)[0]


def gps_measurement(p, v, eta, steps_per_fix):
    return np.stack([p[:, ::steps_per_fix], v[:, ::steps_per_fix]], axis=-1) + eta


@pytest.mark.parametrize("func, correct", [
    (gps_measurement, True),
    (lambda p, v, eta, r: np.stack([v[:, ::r], p[:, ::r]], axis=-1) + eta, False),   # swapped
    (lambda *args: 1 / 0, False),                                                  # raises
    (lambda *args: None, False),                                                   # returns nothing
])
def test_a_function_answer_is_replayed_with_the_same_verdict(func, correct):
    line, record = make_record("03.4", MODULE, "check_gps_measurement", func)
    assert line == str(calib.check_gps_measurement(func))
    assert recheck("03.4", MODULE, "check_gps_measurement", json.loads(json.dumps(record))) == (correct, line)


def test_a_function_record_with_other_inputs_or_calls_is_not_graded():
    _, record = make_record("03.4", MODULE, "check_gps_measurement", gps_measurement)
    calls = record["answer"]["calls"]
    assert calls
    for changed in ([], [{**calls[0], "args": encode((1.0,))}, *calls[1:]]):
        correct, line = recheck("03.4", MODULE, "check_gps_measurement", {**record, "answer": {"t": "function",
                                                                                                "calls": changed}})
        assert not correct and "not those of the check's test inputs" in line


def test_the_recheck_process_reads_items_and_writes_verdicts():
    _, right = make_record("03.1", MODULE, "check_gps_fix_indices", RIGHT_03_1)
    _, wrong = make_record("03.2", MODULE, "check_gps_dz", 0)
    items = [{"exercise": "03.1", "module": MODULE, "check": "check_gps_fix_indices", "record": right},
             {"exercise": "03.2", "module": MODULE, "check": "check_gps_dz", "record": wrong}]
    done = subprocess.run([sys.executable, "-P", "-m", "kfcal_helpers.exercises.grading"],
                          input=json.dumps(items).encode(), capture_output=True, check=True)
    verdicts = json.loads(done.stdout)
    assert verdicts == recheck_all(items)
    assert [v["correct"] for v in verdicts] == [True, False]
    assert verdicts[1]["line"] == str(calib.check_gps_dz(0)) and verdicts[1]["line"].startswith("✘ 03.2 not yet: ")


def test_every_function_check_replays_in_a_fresh_process():
    """A check that takes a function calls it on the same inputs in every process (no unseeded randomness,
    nothing depending on the process), so that its record replays; here with a function that returns its
    first argument (wrong everywhere, but called on every test input the check has)."""
    import importlib
    import inspect

    from kfcal_helpers.assignments import check_modules

    def first(*args, **kwargs):
        return args[0]

    items, lines = [], []
    for name, module in sorted(check_modules().items()):
        check = getattr(importlib.import_module(module), name)
        if list(inspect.signature(check).parameters)[0] not in ("func", "fn"):
            continue
        line, record = make_record("00.0", module, name, first)
        assert record["answer"]["t"] == "function" and record["answer"]["calls"], name
        items.append({"exercise": "00.0", "module": module, "check": name, "record": record})
        lines.append(line)
    assert len(items) >= 10
    done = subprocess.run([sys.executable, "-P", "-m", "kfcal_helpers.exercises.grading"],
                          input=json.dumps(items).encode(), capture_output=True, check=True)
    assert [v["line"] for v in json.loads(done.stdout)] == lines


def test_the_report_keeps_one_set_of_rows_per_submission(tmp_path):
    import csv

    from kfcal_helpers.assignments._regrade import REPORT_COLUMNS, update_report

    report = tmp_path / "grading_flags.csv"
    update_report(report, ("ann", "03_gps_model", "03_gps_model"), [("03.1", "no record"), ("03.4", "forged")])
    update_report(report, ("bob", "03_gps_model", "03_gps_model"), [("03.2", "no record")])
    update_report(report, ("ann", "03_gps_model", "03_gps_model"), [("03.4", "forged")])   # graded again
    with open(report, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    assert rows == [list(REPORT_COLUMNS), ["ann", "03_gps_model", "03_gps_model", "03.4", "forged"],
                    ["bob", "03_gps_model", "03_gps_model", "03.2", "no record"]]
    update_report(report, ("bob", "03_gps_model", "03_gps_model"), [])
    with open(report, newline="", encoding="utf-8") as f:
        assert [r[0] for r in csv.reader(f)] == ["student", "ann"]
