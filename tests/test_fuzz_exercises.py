"""Fuzz rows of the exercise-check harness (issue 31): a student's function that never returns, one
that raises anything (``SystemExit`` and the other ``BaseException`` subclasses; Ctrl-C excepted), one
that modifies its inputs, and answers that cost no memory until converted (a ``np.broadcast_to`` view
of 10**8 entries).  Every check that takes a function gets every row; the memory rows run the check
in a child process and measure that child's peak (the slow tier)."""

import inspect
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import kfcal_helpers.calibration.exercises as cal
import kfcal_helpers.coop.exercises as coop
from kfcal_helpers.exercises import Feedback, _limits

ALL_CHECKS = [(m, name) for m in (cal, coop) for name in m.__all__ if name.startswith("check_")]
#: the checks whose answer is a function (their first parameter is named func or fn)
FUNCTION_CHECKS = [f"{m.__name__.split('.')[1]}.{name}" for m, name in ALL_CHECKS
                   if next(iter(inspect.signature(getattr(m, name)).parameters)) in ("func", "fn")]
VALUE_CHECKS = [f"{m.__name__.split('.')[1]}.{name}" for m, name in ALL_CHECKS
                if f"{m.__name__.split('.')[1]}.{name}" not in FUNCTION_CHECKS]


def _check(label):
    module, name = label.split(".")
    return getattr({"calibration": cal, "coop": coop}[module], name)


def _one_line_verdict(fb):
    assert isinstance(fb, Feedback), fb
    assert not fb.correct and fb.message and "\n" not in str(fb), str(fb)
    assert str(fb).startswith(f"✘ {fb.exercise} "), str(fb)


class _Deadline(BaseException):
    """The test's own deadline: on the old harness a check hangs; this makes it a failure instead."""


@pytest.fixture
def deadline():
    """Fail (not hang) when the check takes over 20 s: SIGALRM raises a BaseException no check catches."""
    if not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        pytest.skip("needs SIGALRM on the main thread")

    def fire(signum, frame):
        raise _Deadline("the check did not return within 20 s")

    old = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, 20.0)
    yield
    signal.setitimer(signal.ITIMER_REAL, 0)
    signal.signal(signal.SIGALRM, old)


def test_every_function_check_is_listed():
    assert len(FUNCTION_CHECKS) >= 10 and "calibration.check_euler_truth" in FUNCTION_CHECKS
    assert "coop.check_measure_function" in FUNCTION_CHECKS and "calibration.check_phi_100hz" in VALUE_CHECKS


# --------------------------------------------------------------------------------------------
# a function that never returns: stopped at the time limit, one line
# --------------------------------------------------------------------------------------------
def _never_returns(*args):
    while True:
        pass


def _never_returns_catching(*args):  # a loop that swallows every Exception (the time limit is not one)
    while True:
        try:
            while True:
                pass
        except Exception:
            pass


def _sleeps_forever(*args):
    time.sleep(10**6)


@pytest.mark.parametrize("func", [_never_returns, _never_returns_catching, _sleeps_forever],
                         ids=["loop", "loop-catching", "sleep"])
@pytest.mark.parametrize("label", FUNCTION_CHECKS)
def test_a_function_that_never_returns_is_stopped_at_the_time_limit(label, func, deadline, monkeypatch):
    monkeypatch.setattr(_limits, "TIME_LIMIT", 0.2)
    start = time.monotonic()
    fb = _check(label)(func)
    _one_line_verdict(fb)
    assert "ran for more than 0.2 s" in fb.message and "was stopped" in fb.message, str(fb)
    assert time.monotonic() - start < 5.0


def test_the_time_limit_leaves_an_outer_timer_running(monkeypatch):
    """A timer set before the check (a test runner's, a student's) is given back, less the time spent."""
    monkeypatch.setattr(_limits, "TIME_LIMIT", 0.1)
    fired = []
    old = signal.signal(signal.SIGALRM, lambda *a: fired.append(1))
    try:
        signal.setitimer(signal.ITIMER_REAL, 1.0)
        _one_line_verdict(cal.check_euler_truth(lambda *a: time.sleep(0.6)))   # stopped after 0.1 s
        remaining = signal.getitimer(signal.ITIMER_REAL)[0]
        assert 0.5 < remaining < 0.95, remaining
        time.sleep(remaining + 0.2)
        assert fired == [1]
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize("label", ["calibration.check_euler_truth", "coop.check_measure_function"])
def test_where_a_call_cannot_be_stopped_the_check_says_so(label, monkeypatch):
    """The fallback (Windows; any thread but the main one): a watchdog writes one line when the limit
    passes, and the verdict, once the call returns, says that this platform could not stop it.  Forced
    here by running the check on another thread."""
    monkeypatch.setattr(_limits, "TIME_LIMIT", 0.2)
    written, result = [], []

    class Stream:
        def write(self, text):
            written.append(text)

        def flush(self):
            pass

    def slow(*args):
        time.sleep(0.8)
        return 0.0

    def run():
        sys_stdout = sys.stdout
        sys.stdout = Stream()
        try:
            result.append(_check(label)(slow))
        finally:
            sys.stdout = sys_stdout

    worker = threading.Thread(target=run)
    worker.start()
    worker.join(10.0)
    assert result, "the check did not return"
    fb = result[0]
    _one_line_verdict(fb)
    assert "could not stop it" in fb.message, str(fb)
    lines = "".join(written).splitlines()
    assert len(lines) == 1 and "cannot stop it" in lines[0] and lines[0].startswith(fb.exercise), written


def test_the_fallback_path_can_be_forced_on_the_main_thread_too(monkeypatch, capsys):
    monkeypatch.setattr(_limits, "TIME_LIMIT", 0.2)
    out, exc = _limits.run_limited(lambda: time.sleep(0.5) or 1.0, (), interrupt=False, report="one line")
    assert out is None and isinstance(exc, _limits.TimeLimitExceeded)
    assert capsys.readouterr().out == "one line\n"
    assert _limits.run_limited(lambda: 2.0, (), interrupt=False) == (2.0, None)


# --------------------------------------------------------------------------------------------
# a function that raises anything: one line (Ctrl-C goes through)
# --------------------------------------------------------------------------------------------
class _Custom(BaseException):
    pass


class _BadMessage(Exception):
    def __str__(self):
        raise SystemExit("no message either")


def _raiser(exc):
    def func(*args):
        raise exc
    return func


def _calls_exit(*args):
    sys.exit(3)


def _calls_builtin_exit(*args):
    exit()  # noqa: PLR1722  (the builtin a student types)


RAISERS = {
    "SystemExit": _raiser(SystemExit(1)), "sys.exit": _calls_exit, "exit()": _calls_builtin_exit,
    "GeneratorExit": _raiser(GeneratorExit()), "BaseException subclass": _raiser(_Custom("x")),
    "StopIteration": _raiser(StopIteration()), "message raises": _raiser(_BadMessage()),
    "RecursionError": lambda *a: RAISERS["RecursionError"](*a),
}


@pytest.mark.parametrize("kind", list(RAISERS))
@pytest.mark.parametrize("label", FUNCTION_CHECKS)
def test_anything_a_function_raises_becomes_one_line(label, kind):
    fb = _check(label)(RAISERS[kind])
    _one_line_verdict(fb)
    if kind in ("SystemExit", "sys.exit", "exit()"):
        assert "SystemExit" in fb.message, str(fb)
    else:
        assert "your function raised" in fb.message, str(fb)


@pytest.mark.parametrize("label", FUNCTION_CHECKS)
def test_ctrl_c_in_a_student_function_still_stops_the_cell(label):
    with pytest.raises(KeyboardInterrupt):
        _check(label)(_raiser(KeyboardInterrupt()))


class _Hostile:
    """An answer whose conversion raises SystemExit (a student's class)."""

    def __array__(self, *args, **kwargs):
        raise SystemExit("converted")

    def __len__(self):
        raise SystemExit("measured")


@pytest.mark.parametrize("label", VALUE_CHECKS + FUNCTION_CHECKS)
def test_an_answer_whose_conversion_raises_systemexit_gets_one_line(label):
    check = _check(label)
    answer = (lambda *a: _Hostile()) if label in FUNCTION_CHECKS else _Hostile()
    _one_line_verdict(check(answer))


# --------------------------------------------------------------------------------------------
# a function that modifies its inputs: told so, by the input's name; the check's own data unchanged
# --------------------------------------------------------------------------------------------
def _modifies_first(first, *rest):
    first[...] = 0.0
    return 0.0


def _modifies_last(*args):
    args[-1][...] = -1.0 if isinstance(args[-1], np.ndarray) else args[-1]
    return 0.0


@pytest.mark.parametrize("label", FUNCTION_CHECKS)
def test_a_function_that_modifies_its_input_is_told_which(label):
    for _ in range(2):  # twice: the check's own test inputs are unchanged by the first call
        fb = _check(label)(_modifies_first)
        _one_line_verdict(fb)
        assert fb.message.startswith("don't modify your inputs: your function changed first;"), str(fb)


# --------------------------------------------------------------------------------------------
# answers that cost no memory until converted: judged from their shape (in process: verdicts)
# --------------------------------------------------------------------------------------------
VIEW = np.broadcast_to(1.0, (10**4, 10**4))  # 10**8 entries, 8 bytes of memory


@pytest.mark.parametrize("label", VALUE_CHECKS)
def test_a_huge_view_answer_gets_a_shape_verdict(label):
    for answer in (VIEW, [VIEW, VIEW], np.broadcast_to(np.nan, (10**8,))):
        fb = _check(label)(answer)
        _one_line_verdict(fb)
        if "a set of check names" not in fb.message:  # the set exercises say what they take instead
            assert str(10**4) in fb.message or str(10**8) in fb.message or "entries" in fb.message, str(fb)


@pytest.mark.parametrize("label", FUNCTION_CHECKS)
def test_a_function_returning_a_huge_view_gets_a_shape_verdict(label):
    for out in (VIEW, (VIEW, VIEW), np.broadcast_to(1.0, (10**8, 1))):
        fb = _check(label)(lambda *a, out=out: out)
        _one_line_verdict(fb)
        assert "far more than" in fb.message, str(fb)


CHILD = textwrap.dedent("""
    import sys
    import numpy as np
    import kfcal_helpers.calibration.exercises as cal
    import kfcal_helpers.coop.exercises as coop

    def hwm():
        return [int(line.split()[1]) for line in open('/proc/self/status') if line.startswith('VmHWM')][0] * 1024

    def reset_hwm():
        try:
            with open('/proc/self/clear_refs', 'w') as f:
                f.write('5')   # resets VmHWM to the current resident size
        except OSError:
            pass

    module, name, kind = sys.argv[1:4]
    check = getattr({'calibration': cal, 'coop': coop}[module], name)
    view = np.broadcast_to(1.0, (10**4, 10**4))
    answer = {'value': view, 'function': lambda *a: view, 'pair': lambda *a: (view, view)}[kind]
    small = (lambda *a: np.zeros(3)) if kind != 'value' else np.zeros(3)
    check(small)   # warm-up: lazy imports and caches
    reset_hwm()
    before = hwm()
    fb = check(answer)
    print(hwm() - before, str(fb).replace('\\n', ' '))
""")

MEMORY_ROWS = [("calibration", "check_phi_100hz", "value"), ("coop", "check_measure_function", "function"),
               ("calibration", "check_euler_truth", "pair")]
MEMORY_ROWS += [(label.split(".")[0], label.split(".")[1], "value") for label in VALUE_CHECKS
                if label not in ("calibration.check_phi_100hz",)]


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs /proc (Linux) for VmHWM")
@pytest.mark.parametrize("module, name, kind", MEMORY_ROWS, ids=lambda v: v)
def test_a_huge_view_costs_a_child_no_memory(module, name, kind, tmp_path):
    """The child's peak resident memory grows by less than 50 MB while the check judges a view of 10**8
    entries (the old checks allocated 1.6 to 3.2 GB before their shape hint)."""
    env = {"PATH": os.environ.get("PATH", ""), "MPLBACKEND": "Agg", "HOME": str(tmp_path), "KFCAL_QUIET": "1"}
    if "PYTHONPATH" in os.environ:
        env["PYTHONPATH"] = os.environ["PYTHONPATH"]
    r = subprocess.run([sys.executable, "-c", CHILD, module, name, kind], capture_output=True, text=True,
                       env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    grown, verdict = r.stdout.strip().splitlines()[-1].split(" ", 1)
    assert verdict.startswith("✘ ") and " not yet: " in verdict, verdict
    assert int(grown) < 50e6, (name, int(grown) / 1e6, verdict)


def test_every_lesson_with_a_function_exercise_states_the_time_limit():
    """The exercise introduction of each lesson whose exercises take a function states the limit the
    harness applies (its one home: TIME_LIMIT)."""
    from pathlib import Path

    from kfcal_helpers.exercises import TIME_LIMIT

    sources = sorted((Path(__file__).parents[1] / "notebooks" / "source").glob("*.md"))
    names = [label.split(".")[1] for label in FUNCTION_CHECKS]
    with_functions = [p for p in sources if any(f"{name}(" in p.read_text(encoding="utf-8") for name in names)]
    assert len(with_functions) >= 9
    readme = (Path(__file__).parents[1] / "README.md").read_text(encoding="utf-8")
    assert f"stopped after {TIME_LIMIT:g} s" in readme
    for path in with_functions:
        text = path.read_text(encoding="utf-8")
        assert f"stopped after {TIME_LIMIT:g} s" in text and "changes its inputs is told which" in text, path.name
