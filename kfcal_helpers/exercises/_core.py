"""The machinery every exercise check shares: a one-line verdict and matching against
the right answer and the common wrong ones.

A check function takes the student's answer and returns a :class:`Feedback`, whose
repr is one line, so a notebook check cell shows exactly that line::

    check_phi_10hz(Phi)     # -> ✔ 04.1 correct: ...   or   ✘ 04.1 not yet: <hint>

An answer that is still the placeholder (``None`` or ``...``) gives "not answered yet"
rather than an error, so the student notebooks run top to bottom unchanged.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

__all__ = ["Feedback", "Exercise", "unanswered", "as_array", "matches", "judge", "call_student", "first_line",
           "chi2_average_bounds", "distinct_mistakes", "GENERIC_HINT", "PLACEHOLDER", "PLACEHOLDER_FUNC",
           "ROUNDED_RTOL", "ROUNDED_HINT"]

GENERIC_HINT = "compare your answer with the formula in the notebook, term by term"
PLACEHOLDER = "replace ... with your answer"
#: an answer this close (relative) to the expected value, but not within the check's own tolerance, is
#: taken for the right value rounded (digits copied from a printout) and gets :data:`ROUNDED_HINT`
ROUNDED_RTOL = 1e-3
ROUNDED_HINT = ("close, but not exactly: pass the value you computed (a variable or an expression), not digits "
                "copied from a printout; if you did, look for a small difference of method")
PLACEHOLDER_FUNC = "write the body of your function (replace ... with your code), then pass the function to the check"


@dataclass(frozen=True)
class Feedback:
    """Verdict of one exercise check.

    exercise : the exercise id, "NN.k" (notebook number, exercise number)
    correct : True when the answer is right
    message : one line: what was right, or a hint at the likely mistake
    answered : False while the answer is still the placeholder
    """

    exercise: str
    correct: bool
    message: str
    answered: bool = True

    def __str__(self) -> str:
        mark = "✔" if self.correct else "✘"
        verdict = "correct" if self.correct else ("not answered yet" if not self.answered else "not yet")
        return f"{mark} {self.exercise} {verdict}: {self.message}"

    __repr__ = __str__

    def __bool__(self) -> bool:
        return self.correct


@dataclass(frozen=True)
class Exercise:
    """One exercise's feedback, kept next to its check.

    id : "NN.k" (notebook number, exercise number)
    praise : the line shown with a correct answer (what the answer teaches)
    hint : the hint when the answer is wrong in no recognised way
    hints : ``{mistake key: hint}`` for the common mistakes the check recognises (never the answer)
    """

    id: str
    praise: str
    hint: str = GENERIC_HINT
    hints: dict = field(default_factory=dict)

    def feedback(self, correct: bool, message: str | None = None, answered: bool = True) -> Feedback:
        """A Feedback of this exercise: ``message`` defaults to the praise (correct) or the hint."""
        if message is None:
            message = self.praise if correct else self.hint
        return Feedback(self.id, correct, message, answered)

    def mistake(self, key: str) -> Feedback:
        """The Feedback for the recognised mistake ``key``."""
        return Feedback(self.id, False, self.hints[key])

    def unanswered(self, placeholder: str = PLACEHOLDER) -> Feedback:
        """The Feedback while the answer is still the placeholder."""
        return Feedback(self.id, False, placeholder, answered=False)

    def judge(self, answer, expected, wrong=(), *, rtol: float = 1e-6, atol: float = 1e-12,
              placeholder: str = PLACEHOLDER) -> Feedback:
        """:func:`judge` with this exercise's praise and hint; ``wrong`` holds ``(value, mistake key)`` pairs."""
        pairs = [(value, self.hints[key]) for value, key in wrong]
        return judge(self.id, answer, expected, pairs, rtol=rtol, atol=atol, praise=self.praise, hint=self.hint,
                     placeholder=placeholder)


def first_line(exc: BaseException, limit: int = 100) -> str:
    """The first line of an exception's message, cut to ``limit`` characters."""
    text = str(exc).strip().splitlines()
    text = text[0] if text else ""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def call_student(exercise: str, func, cases, what: str = "your function", convert=None):
    """Call the student's ``func`` once per argument tuple in ``cases``, safely.

    Returns ``(outputs, None)`` with one output per case, or ``(None, Feedback)`` when the function
    is still the placeholder, is not callable, raises (the exception's name and first line become the
    hint), or returns the placeholder (None or ...).  ``convert`` (optional) maps each argument before
    the call (e.g. ``np.asarray``).  Floating-point warnings inside the student's code are silenced:
    a NaN result is judged by the check, never shown as a warning.
    """
    if unanswered(func):
        return None, Feedback(exercise, False, PLACEHOLDER_FUNC, answered=False)
    if not callable(func):
        return None, Feedback(exercise, False, f"expected a function {what}, got {type(func).__name__}: "
                                               "pass the function itself, without calling it")
    outs = []
    for args in cases:
        if convert is not None:
            args = tuple(convert(a) for a in args)
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                out = func(*args)
        except Exception as exc:  # a half-written function: name the exception, never crash
            return None, Feedback(exercise, False, f"your function raised {type(exc).__name__} on the test input: "
                                                   f"{first_line(exc)}")
        if unanswered(out):
            return None, Feedback(exercise, False, f"your function returns {out!r}: {PLACEHOLDER_FUNC}",
                                  answered=False)
        outs.append(out)
    return outs, None


def distinct_mistakes(pairs, expected, rtol: float):
    """The ``(value, key)`` pairs whose value differs from ``expected`` (within ``rtol``): a mistake
    that gives the right answer for these settings is not a mistake."""
    out = []
    for value, key in pairs:
        value = np.asarray(value, dtype=float)
        if value.shape == np.shape(expected) and np.allclose(value, expected, rtol=rtol, atol=0):
            continue
        out.append((value, key))
    return out


def unanswered(answer) -> bool:
    """True for the placeholders ``None`` and ``...`` (Ellipsis)."""
    return answer is None or answer is Ellipsis


def as_array(answer):
    """``answer`` as a float ndarray, or None when it cannot be one (a string, ragged lists...)."""
    try:
        arr = np.asarray(answer, dtype=float)
    except (TypeError, ValueError):
        return None
    return arr


def matches(answer, expected, rtol: float = 1e-6, atol: float = 1e-12) -> bool:
    """True when ``answer`` has the shape of ``expected`` (after squeezing) and equals it
    within ``rtol``/``atol``; never raises for a malformed answer."""
    a, e = as_array(answer), np.asarray(expected, dtype=float)
    if a is None or a.size != e.size:
        return False
    a = a.reshape(e.shape)
    return bool(np.all(np.isfinite(a)) and np.allclose(a, e, rtol=rtol, atol=atol))


def judge(exercise: str, answer, expected, wrong=(), *, rtol: float = 1e-6, atol: float = 1e-12,
          praise: str = "well done", hint: str = GENERIC_HINT, placeholder: str = "replace ... with your answer") -> Feedback:
    """The verdict on ``answer`` against ``expected`` and the common mistakes.

    wrong : sequence of ``(value, hint)`` pairs: the value a common mistake gives and the
        hint that points at that mistake (never the answer itself)
    hint : the hint when the answer is neither right nor a known mistake
    A shape different from the expected one gets its own hint.  An answer within
    :data:`ROUNDED_RTOL` (relative to the largest entry) of the expected value or of a known mistake's
    value gets the message of the nearest of them: :data:`ROUNDED_HINT` (a rounded copy of the right
    value) or that mistake's hint (a rounded copy of a wrong one).
    """
    if unanswered(answer):
        return Feedback(exercise, False, placeholder, answered=False)
    if matches(answer, expected, rtol, atol):
        return Feedback(exercise, True, praise)
    for value, why in wrong:
        if matches(answer, value, rtol, atol):
            return Feedback(exercise, False, why)
    if rtol < ROUNDED_RTOL:
        near = _nearest(answer, [(expected, ROUNDED_HINT), *wrong])
        if near is not None:
            return Feedback(exercise, False, near)
    a, e = as_array(answer), np.asarray(expected, dtype=float)
    if a is None:
        return Feedback(exercise, False, f"expected numbers (an array of shape {e.shape}), got {type(answer).__name__}")
    if a.size != e.size:
        return Feedback(exercise, False, f"expected shape {e.shape}, got {a.shape}")
    return Feedback(exercise, False, hint)


def _nearest(answer, candidates):
    """The message of the candidate ``(value, message)`` nearest to ``answer`` when it is within
    :data:`ROUNDED_RTOL` of it, relative to the candidate's largest entry (so a matrix rounded to a few
    decimals counts as close too); None when no candidate is that close or the shapes differ."""
    a = as_array(answer)
    best, best_d = None, ROUNDED_RTOL
    for value, message in candidates:
        v = np.asarray(value, dtype=float)
        if a is None or a.size != v.size or not np.all(np.isfinite(a)):
            continue
        scale = np.max(np.abs(v))
        if scale == 0:
            continue
        d = float(np.max(np.abs(a.reshape(v.shape) - v)) / scale)
        if d <= best_d:
            best, best_d = message, d
    return best


def chi2_average_bounds(dim: int, n: int, alpha: float, *, dof: int | None = None, divide_by: float | None = None,
                        one_sided: bool = False) -> np.ndarray:
    """``[lower, upper]`` of the average of ``n`` chi-square(``dim``) variables at level ``alpha``:
    ``chi2.ppf((alpha/2, 1 - alpha/2), dim n) / n`` (as :func:`kfcal_helpers.consistency.chi2_bounds`).

    The keywords build the common wrong answers the checks recognise: ``dof`` (other degrees of
    freedom), ``divide_by`` (another divisor; 1 = not divided), ``one_sided`` (quantiles
    ``alpha`` and ``1 - alpha``).
    """
    dof = dim * n if dof is None else dof
    lo, hi = (alpha, 1 - alpha) if one_sided else (alpha / 2, 1 - alpha / 2)
    return np.array([stats.chi2.ppf(lo, dof), stats.chi2.ppf(hi, dof)]) / (n if divide_by is None else divide_by)
