"""The machinery every exercise check shares: a one-line verdict and matching against
the right answer and the common wrong ones.

A check function takes the student's answer and returns a :class:`Feedback`, whose
repr is one line, so a notebook check cell shows exactly that line::

    check_phi_10hz(Phi)     # -> ✔ 04.1 correct: ...   or   ✘ 04.1 not yet: <hint>

An answer that is still the placeholder (``None`` or ``...``) gives "not answered yet"
rather than an error, so the student notebooks run top to bottom unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = ["Feedback", "unanswered", "as_array", "matches", "judge", "chi2_average_bounds", "GENERIC_HINT"]

GENERIC_HINT = "compare your answer with the formula in the notebook, term by term"


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
    A shape different from the expected one gets its own hint.
    """
    if unanswered(answer):
        return Feedback(exercise, False, placeholder, answered=False)
    if matches(answer, expected, rtol, atol):
        return Feedback(exercise, True, praise)
    for value, why in wrong:
        if matches(answer, value, rtol, atol):
            return Feedback(exercise, False, why)
    a, e = as_array(answer), np.asarray(expected, dtype=float)
    if a is None:
        return Feedback(exercise, False, f"expected numbers (an array of shape {e.shape}), got {type(answer).__name__}")
    if a.size != e.size:
        return Feedback(exercise, False, f"expected shape {e.shape}, got {a.shape}")
    return Feedback(exercise, False, hint)


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
