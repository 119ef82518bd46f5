"""Graded answers that a student's kernel cannot grade itself: record in the kernel, re-check outside it.

A graded notebook's grade cell (nbgrader's "autograder tests" cell) calls :func:`record_answer`: it runs the
check in the student's kernel only to show the student its one-line verdict, and records the answer as
data (an output of MIME type :data:`RECORD_MIME`).  A function answer is recorded by its results: the
check calls it on its test inputs, and each call's inputs and output (or the exception's name and first
line) are recorded.  The grader then re-checks every record in a fresh Python process, with the package
as installed (:func:`recheck_all`, run by ``python -m kfcal_helpers.exercises.grading``): no code of the
student runs there, a function answer is replayed from its record (:class:`Replay`: the genuine check's
inputs must be the recorded ones, call by call), and nothing the student patched in their kernel (the
checks, :class:`Feedback`, numpy, builtins) takes part in the verdict.

Records are JSON made of tagged values (:func:`encode`, :func:`decode`); arrays travel in numpy's ``.npy``
format read with ``allow_pickle=False``: decoding a record never runs code.
"""

from __future__ import annotations

import base64
import contextlib
import importlib
import io
import json
import re
import sys

import numpy as np

from ._core import Feedback, first_line

__all__ = ["RECORD_MIME", "RecordError", "Replay", "ReplayMismatch", "encode", "decode", "make_record", "record_answer", "recheck",
           "recheck_all", "exercise_of"]

#: the MIME type of a grade cell's record (a JSON object: exercise, check, answer)
RECORD_MIME = "application/vnd.kfcal.answer+json"
#: version of the record format
VERSION = 1
_MAX_BYTES = 64_000_000   # an array larger than this is recorded by its type only
_MAX_DEPTH = 32
_NAME = re.compile(r"[^A-Za-z0-9_.]")


class RecordError(ValueError):
    """A record that does not decode (damaged, or not made by :func:`encode`)."""


class ReplayMismatch(BaseException):
    """The check called a replayed function with inputs other than the recorded ones (a BaseException, so
    that the check's own ``except Exception`` of a student's error does not swallow it)."""


def _safe_name(name) -> str:
    text = _NAME.sub("_", str(name))[:60]
    return text if text and not text[0].isdigit() else "_" + text


def _opaque(value) -> dict:
    try:
        name = type(value).__name__
    except Exception:
        name = "object"
    return {"t": "obj", "type": _safe_name(name)}


def _npy(arr: np.ndarray) -> str:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def encode(value, _depth: int = 0) -> dict:
    """``value`` as JSON-able tagged data: None, ``...``, bool, int, float, complex, str, bytes, lists,
    tuples, dicts, numpy arrays and scalars exactly (floats to the last bit); any other object by its type
    name only (it decodes to an empty object of a class of that name).  Never raises."""
    try:
        if _depth > _MAX_DEPTH:
            return {"t": "obj", "type": "nested_too_deep"}
        if value is None:
            return {"t": "none"}
        if value is Ellipsis:
            return {"t": "ellipsis"}
        if isinstance(value, np.ndarray) or isinstance(value, np.generic):
            arr = np.asarray(value)
            if arr.dtype == object:
                return {"t": "ndobj", "shape": list(arr.shape), "v": [encode(v, _depth + 1) for v in arr.flat]}
            if arr.nbytes > _MAX_BYTES:
                return {"t": "obj", "type": "array_too_large"}
            return {"t": "nd" if isinstance(value, np.ndarray) else "np0", "npy": _npy(np.array(arr))}
        if isinstance(value, bool):
            return {"t": "bool", "v": bool(value)}
        if isinstance(value, int):
            return {"t": "int", "v": str(int(value))}
        if isinstance(value, float):
            return {"t": "float", "v": repr(float(value))}
        if isinstance(value, complex):
            return {"t": "complex", "re": repr(float(value.real)), "im": repr(float(value.imag))}
        if isinstance(value, str):
            return {"t": "str", "v": str(value)}
        if isinstance(value, (bytes, bytearray)):
            return {"t": "bytes", "v": base64.b64encode(bytes(value)).decode("ascii")}
        if isinstance(value, (list, tuple)):
            return {"t": "list" if isinstance(value, list) else "tuple",
                    "v": [encode(v, _depth + 1) for v in list(value)]}
        if isinstance(value, dict):
            return {"t": "dict", "v": [[encode(k, _depth + 1), encode(v, _depth + 1)] for k, v in list(value.items())]}
        if not callable(value) and hasattr(value, "__array__"):   # e.g. a pandas Series: judged by its numbers
            arr = np.asarray(value)
            if arr.dtype != object and arr.nbytes <= _MAX_BYTES:
                return {"t": "nd", "npy": _npy(np.array(arr))}
        return _opaque(value)
    except Exception:  # a student's object whose methods raise: recorded by its type only
        return _opaque(value)


def _float(text) -> float:
    if not isinstance(text, str):
        raise RecordError("a float is not text")
    return float(text)


def decode(data, _depth: int = 0):
    """The value :func:`encode` recorded (an object recorded by its type: an empty object of a class of that
    name).  Raises :class:`RecordError` for anything :func:`encode` does not make."""
    if _depth > _MAX_DEPTH + 1 or not isinstance(data, dict):
        raise RecordError("not a recorded value")
    try:
        tag = data["t"]
        if tag == "none":
            return None
        if tag == "ellipsis":
            return Ellipsis
        if tag in ("nd", "np0"):
            raw = base64.b64decode(data["npy"].encode("ascii"), validate=True)
            arr = np.load(io.BytesIO(raw), allow_pickle=False)
            return arr if tag == "nd" else arr[()]
        if tag == "ndobj":
            shape = tuple(int(n) for n in data["shape"])
            items = [decode(v, _depth + 1) for v in data["v"]]
            arr = np.empty(len(items), dtype=object)
            for i, item in enumerate(items):
                arr[i] = item
            return arr.reshape(shape)
        if tag == "bool":
            if not isinstance(data["v"], bool):
                raise RecordError("a bool is not a bool")
            return data["v"]
        if tag == "int":
            if not isinstance(data["v"], str):
                raise RecordError("an int is not text")
            return int(data["v"])
        if tag == "float":
            return _float(data["v"])
        if tag == "complex":
            return complex(_float(data["re"]), _float(data["im"]))
        if tag == "str":
            if not isinstance(data["v"], str):
                raise RecordError("a str is not text")
            return data["v"]
        if tag == "bytes":
            return base64.b64decode(data["v"].encode("ascii"), validate=True)
        if tag in ("list", "tuple"):
            items = [decode(v, _depth + 1) for v in data["v"]]
            return items if tag == "list" else tuple(items)
        if tag == "dict":
            return {decode(k, _depth + 1): decode(v, _depth + 1) for k, v in data["v"]}
        if tag == "obj":
            return type(_safe_name(data["type"]), (), {"__repr__": lambda self: f"<{type(self).__name__}>"})()
    except RecordError:
        raise
    except Exception as exc:
        raise RecordError(f"a recorded value does not decode ({type(exc).__name__})") from None
    raise RecordError(f"unknown tag {tag!r}")


class _Recorder:
    """Calls the student's function and records each call: inputs, then the output or the exception."""

    def __init__(self, func):
        self._func = func
        self.calls = []

    def __call__(self, *args, **kwargs):
        call = {"args": encode(args), "kwargs": encode(kwargs)}
        try:
            out = self._func(*args, **kwargs)
        except Exception as exc:
            call["raised"] = [_safe_name(type(exc).__name__), first_line(exc)]
            self.calls.append(call)
            raise
        call["out"] = encode(out)
        self.calls.append(call)
        return out


class Replay:
    """A function answer replayed from its record: the k-th call must have the recorded k-th inputs (else
    :class:`ReplayMismatch`); it returns the recorded output, or raises an exception of the recorded name
    and message."""

    def __init__(self, calls):
        if not isinstance(calls, list):
            raise RecordError("a function's calls are not a list")
        for call in calls:
            if not (isinstance(call, dict) and "args" in call and "kwargs" in call and ("out" in call) != ("raised" in call)):
                raise RecordError("a function's call does not decode")
            if "raised" in call and not (isinstance(call["raised"], list) and len(call["raised"]) == 2
                                         and all(isinstance(t, str) for t in call["raised"])):
                raise RecordError("a function's exception does not decode")
            if "out" in call:
                decode(call["out"])
        self._calls = calls
        self._next = 0
        #: why the replay failed, if it did (the check's harness turns what the function raises into a verdict,
        #: so the mismatch is kept here as well as raised)
        self.mismatch = None

    def __call__(self, *args, **kwargs):
        if self._next >= len(self._calls):
            self.mismatch = "the check called the function more often than recorded"
            raise ReplayMismatch(self.mismatch)
        call = self._calls[self._next]
        self._next += 1
        if encode(args) != call["args"] or encode(kwargs) != call["kwargs"]:
            self.mismatch = "the check's inputs are not the recorded ones"
            raise ReplayMismatch(self.mismatch)
        if "raised" in call:
            name, message = call["raised"]
            raise type(_safe_name(name), (Exception,), {})(message)
        return decode(call["out"])


def _check_function(module: str, check: str):
    if not (module.startswith("kfcal_helpers.") and re.fullmatch(r"check_\w+", check)):
        raise RecordError(f"{module}.{check} is not an exercise check")
    mod = importlib.import_module(module)
    if check not in getattr(mod, "__all__", ()):
        raise RecordError(f"{module} has no check {check}")
    return getattr(mod, check)


def make_record(exercise: str, module: str, check: str, answer) -> tuple[str, dict]:
    """``(verdict line, record)``: the check ``module.check`` run here on ``answer`` (for the student only) and
    the record of the answer (a function answer: its calls by the check, inputs and outputs)."""
    func = _check_function(module, check)
    is_function = callable(answer) and not isinstance(answer, (np.ndarray, np.generic))
    subject = _Recorder(answer) if is_function else answer
    try:
        line = str(func(subject))
    except Exception as exc:  # the checks do not raise; a kernel where they do still records the answer
        line = f"{exercise}: the check raised {type(exc).__name__} (your answer is recorded for the grader)"
    recorded = {"t": "function", "calls": subject.calls} if is_function else encode(answer)
    return line, {"v": VERSION, "exercise": exercise, "check": check, "answer": recorded}


def record_answer(exercise: str, module: str, check: str, answer) -> None:
    """In a graded notebook's grade cell: show the check's one-line verdict on ``answer`` and record the
    answer for the grader (one output with the verdict as text and the record as :data:`RECORD_MIME`).

    exercise : the exercise id, "NN.k"; module, check : where the check is (``kfcal_helpers.<problem>.exercises``,
    ``check_*``); answer : the student's answer (a value, or a function: recorded by its results on the
    check's test inputs, :func:`make_record`).  The verdict shown here is for the student only: the grade is
    the grader's re-check of the record (:func:`recheck`)."""
    line, record = make_record(exercise, module, check, answer)
    try:
        from IPython.display import display
    except ImportError:  # outside IPython: the verdict only
        print(line)
        return
    display({"text/plain": line, RECORD_MIME: record}, raw=True)


def exercise_of(record) -> str | None:
    """The exercise id a record names, or None when it is not a record."""
    return record.get("exercise") if isinstance(record, dict) and isinstance(record.get("exercise"), str) else None


def recheck(exercise: str, module: str, check: str, record) -> tuple[bool, str]:
    """``(correct, one line)``: the genuine check ``module.check`` on the answer ``record`` holds (made by
    :func:`record_answer` for ``exercise``).  A record that does not decode, names another exercise or
    check, or holds a function whose recorded calls are not the check's, is wrong, with a line that says so."""
    altered = (f"✘ {exercise} not graded: the record of your answer in the grade cell's output is missing or "
               "altered; run the notebook from the top and hand it in again")
    try:
        func = _check_function(module, check)
        if not (isinstance(record, dict) and record.get("v") == VERSION and record.get("exercise") == exercise
                and record.get("check") == check and isinstance(record.get("answer"), dict)):
            return False, altered
        data = record["answer"]
        answer = Replay(data.get("calls")) if data.get("t") == "function" else decode(data)
    except RecordError:
        return False, altered
    mismatch = (False, f"✘ {exercise} not graded: the recorded results of your function are not those of the "
                       "check's test inputs; run the notebook from the top and hand it in again")
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            feedback = func(answer)
    except ReplayMismatch:
        return mismatch
    except Exception as exc:
        return False, f"✘ {exercise} not graded: the check failed on the recorded answer ({type(exc).__name__})"
    if isinstance(answer, Replay) and answer.mismatch is not None:   # the check's harness caught the mismatch
        return mismatch
    if not isinstance(feedback, Feedback):
        return False, f"✘ {exercise} not graded: the check returned no verdict"
    return bool(feedback.correct), str(feedback)


def recheck_all(items: list[dict]) -> list[dict]:
    """:func:`recheck` of each ``{"exercise", "module", "check", "record"}``: ``[{"correct", "line"}, ...]``."""
    out = []
    for item in items:
        correct, line = recheck(item["exercise"], item["module"], item["check"], item["record"])
        out.append({"correct": correct, "line": line})
    return out


def _main() -> int:
    """``python -m kfcal_helpers.exercises.grading``: JSON items on stdin, verdicts as JSON on stdout."""
    items = json.loads(sys.stdin.buffer.read().decode("utf-8"))
    with contextlib.redirect_stdout(io.StringIO()):
        verdicts = recheck_all(items)
    sys.stdout.write(json.dumps(verdicts))
    return 0


if __name__ == "__main__":
    sys.exit(_main())
