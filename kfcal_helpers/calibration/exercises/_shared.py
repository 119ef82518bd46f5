"""What the calibration checks share: numeric judging with the shape checks, one call of a student's function."""

from __future__ import annotations



import numpy as np

from ...exercises._core import (PLACEHOLDER, Exercise, Feedback, as_array, call_student, shape_hint, too_large, unanswered)



def numeric(ex: Exercise, answer, expected, wrong=(), *, rtol: float = 1e-6, atol: float = 1e-12,
             placeholder: str = PLACEHOLDER, shape_key: str | None = None) -> Feedback:
    """``ex.judge`` with ``wrong`` as ``(mistake key, value)`` pairs, plus the answer judge() would
    misread: a matrix of the right size but another shape (transposed or flat; the hint ``shape_key`` of
    ``ex`` when given, else :func:`shape_hint`).  An answer larger than every expected value is judged
    from its shape before any conversion.  Everything that is
    not real finite numbers is judge()'s (the harness screens it in one place)."""
    if unanswered(answer):
        return ex.unanswered(placeholder)
    e = np.asarray(expected, dtype=float)
    big = too_large(answer, e, *(v for _, v in wrong))  # before any conversion: a broadcast view costs nothing yet
    if big is not None:
        return ex.feedback(False, big)
    a = as_array(answer)
    if a is not None and np.all(np.isfinite(a)):
        if e.ndim == 2 and a.size == e.size and np.squeeze(a).shape != e.shape:
            return ex.mistake(shape_key) if shape_key else ex.feedback(False, shape_hint(a.shape, e.shape))
    return ex.judge(answer, expected, [(v, k) for k, v in wrong], rtol=rtol, atol=atol, placeholder=placeholder)


def call_once(ex: Exercise, func, what: str, args: tuple):
    """The student's ``func(*args)`` through :func:`call_student`: ``(output, None)`` or ``(None, Feedback)``."""
    outs, fb = call_student(ex.id, func, [args], what)
    return (None, fb) if fb is not None else (outs[0], None)


def as_pair(out):
    """``out`` as two float arrays (a 2-tuple/list), or None."""
    if isinstance(out, (str, bytes)) or not isinstance(out, (tuple, list)) or len(out) != 2:
        return None
    first, second = as_array(out[0]), as_array(out[1])
    if first is None or second is None:
        return None
    return first, second


def close(a, b, rtol: float = 1e-9, atol: float = 1e-12) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.size != b.size:
        return False
    a = a.reshape(b.shape)
    return bool(np.all(np.isfinite(a)) and np.allclose(a, b, rtol=rtol, atol=atol))
