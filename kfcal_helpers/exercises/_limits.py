"""How a check calls the student's function: on deep copies of its inputs, within a time limit.

Every call of a student's function goes through :func:`run_limited` (from
:func:`~kfcal_helpers.exercises.call_student`):

- the function gets deep copies of the check's inputs, and the copies are compared with the originals
  afterwards (:func:`changed_input`): a function that modifies its inputs is told so, by the input's
  name, and never corrupts the check's own data;
- each call has a time limit, :data:`TIME_LIMIT` seconds.  On Linux and macOS, on the main thread (where
  Jupyter runs a cell), a timer signal (``SIGALRM`` via ``signal.setitimer``) stops the call.  Elsewhere
  (Windows, or a check run from another thread) nothing can stop a Python call from outside: a watchdog
  thread then writes one line saying so once the limit has passed, and the call runs on until it returns
  or the kernel is interrupted;
- every exception the student's code raises, ``SystemExit`` and the other ``BaseException`` subclasses
  included, becomes a one-line verdict; only ``KeyboardInterrupt`` (Ctrl-C, the kernel's stop button)
  goes through, so that the student can always stop a cell.
"""

from __future__ import annotations

import copy
import inspect
import signal
import sys
import threading
import time

import numpy as np

__all__ = ["TIME_LIMIT", "TimeLimitExceeded", "run_limited", "can_interrupt", "input_names", "changed_input",
           "time_limit_hint", "time_limit", "copies"]

#: seconds one call of a student's function may take on a check's test input (the inputs are small:
#: a right answer takes milliseconds)
TIME_LIMIT = 10.0


def time_limit() -> float:
    """The time limit now, :data:`TIME_LIMIT` (read at each call, so that a test may lower it)."""
    return TIME_LIMIT


class TimeLimitExceeded(BaseException):
    """Raised inside the student's call when its time limit passes (a BaseException, so that the
    student's ``except Exception`` cannot swallow it)."""


def time_limit_hint(seconds: float, interrupted: bool) -> str:
    """The one-line verdict of a call that took longer than ``seconds``."""
    how = "and was stopped" if interrupted else "(this platform could not stop it)"
    return (f"your function ran for more than {seconds:g} s on a small test input {how}: "
            "look for a loop that never ends (a while loop whose condition never changes)")


def can_interrupt() -> bool:
    """True when a call can be stopped at its time limit here: a POSIX timer signal on the main thread."""
    return hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()


def _alarm_call(func, args, seconds: float):
    """``func(*args)`` stopped by SIGALRM after ``seconds``: the timer re-fires every 0.1 s, so that a
    function that catches the first exception is stopped by the next.  The previous handler and timer
    (e.g. a test runner's) are restored afterwards."""
    def on_alarm(signum, frame):
        raise TimeLimitExceeded()

    start = time.monotonic()
    old_handler = signal.signal(signal.SIGALRM, on_alarm)
    old_delay, old_interval = signal.setitimer(signal.ITIMER_REAL, seconds, 0.1)
    try:
        return func(*args)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old_handler)
        if old_delay > 0:  # someone else's timer was running: give it back, less the time spent
            signal.setitimer(signal.ITIMER_REAL, max(old_delay - (time.monotonic() - start), 1e-3), old_interval)


def _watched_call(func, args, seconds: float, report: str):
    """``func(*args)`` with a watchdog thread that writes ``report`` (one line) to the stdout of the
    moment when the call is still running after ``seconds``; the call itself cannot be stopped."""
    stream = sys.stdout
    done = threading.Event()

    def watch():
        if not done.wait(seconds):
            try:
                stream.write(report + "\n")
                stream.flush()
            except Exception:  # a closed stream: nothing left to tell
                pass

    dog = threading.Thread(target=watch, name="kfcal-exercise-watchdog", daemon=True)
    dog.start()
    try:
        return func(*args)
    finally:
        done.set()


def run_limited(func, args: tuple, *, seconds: float | None = None, report: str = "", interrupt: bool | None = None):
    """``(output, None)`` or ``(None, exception)``: ``func(*args)`` within the time limit.

    seconds : the limit (default :data:`TIME_LIMIT`)
    report : the line the watchdog writes when the call cannot be stopped and runs past the limit
    interrupt : force the signal path (True) or the watchdog path (False); default :func:`can_interrupt`
    A call that ran past the limit returns ``(None, TimeLimitExceeded())`` also when it returned on its
    own.  ``KeyboardInterrupt`` propagates; every other exception is returned, never raised.
    """
    seconds = TIME_LIMIT if seconds is None else float(seconds)
    interrupt = can_interrupt() if interrupt is None else interrupt
    start = time.monotonic()
    try:
        if interrupt:
            out = _alarm_call(func, args, seconds)
        else:
            out = _watched_call(func, args, seconds, report or time_limit_hint(seconds, False))
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # SystemExit, GeneratorExit, the time limit...: a verdict, never an exit
        return None, exc
    if time.monotonic() - start > seconds:
        return None, TimeLimitExceeded()
    return out, None


def input_names(func, n: int) -> list[str]:
    """Names of the first ``n`` positional parameters of the student's ``func`` (the names the student
    wrote), ``"input k"`` where the signature does not tell."""
    names = []
    try:
        params = [p for p in inspect.signature(func).parameters.values()
                  if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD, p.VAR_POSITIONAL)]
    except (TypeError, ValueError):
        params = []
    for k in range(n):
        if k < len(params) and params[k].kind != params[k].VAR_POSITIONAL:
            names.append(params[k].name)
        else:
            names.append(f"input {k + 1}")
    return names


def _same(a, b, depth: int = 0) -> bool:
    """True when ``a`` (after the call) equals ``b`` (the copy kept before it), type, shape and NaNs
    included; never raises."""
    try:
        if type(a) is not type(b):
            return False
        if isinstance(a, np.ndarray):
            return a.shape == b.shape and a.dtype == b.dtype and bool(
                np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))
        if depth > 4:
            return True
        if isinstance(a, (list, tuple)):
            return len(a) == len(b) and all(_same(x, y, depth + 1) for x, y in zip(a, b))
        if isinstance(a, dict):
            return a.keys() == b.keys() and all(_same(a[k], b[k], depth + 1) for k in a)
        if isinstance(a, float) and a != a:
            return b != b
        if hasattr(a, "__dict__") and not isinstance(a, type):
            return _same(vars(a), vars(b), depth + 1)
        return bool(a == b)
    except Exception:
        return True  # an object that cannot be compared is not blamed


def changed_input(func, before: tuple, after: tuple) -> str | None:
    """The name of the first input the call changed (``after`` against the deep copy ``before``), or None."""
    for name, b, a in zip(input_names(func, len(before)), before, after):
        if not _same(a, b):
            return name
    return None


def copies(args: tuple) -> tuple:
    """A deep copy of ``args`` (the student's function gets one, the check keeps another)."""
    return copy.deepcopy(tuple(args))
