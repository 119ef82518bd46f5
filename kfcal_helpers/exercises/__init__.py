"""The harness of the exercise self-checks at the end of each notebook.

The checks themselves live with their problem: :mod:`kfcal_helpers.calibration.exercises`
(notebooks 01-07, 14-17) and :mod:`kfcal_helpers.coop.exercises` (08-14, 18).  Each is named
``check_<topic>(answer, *, settings...)``: the student's answer (a number, an array or a function)
first, every setting keyword-only.  It returns a :class:`Feedback` that shows as one line: correct,
or a hint at the likely mistake (wrong sign, swapped variances, missing wrap...) without the answer.
The one answer-format rule, :data:`FORMAT_RULE`: pass the value you computed, with no rounding.
Each exercise's texts are one :class:`Exercise` record (id, praise, hint, the hints of its common
mistakes) next to its check.  Worked solutions are in ``notebooks/solutions/``.
"""

from ._core import (FORMAT_RULE, GENERIC_HINT, NON_FINITE_HINT, PLACEHOLDER, PLACEHOLDER_FUNC, ROUNDED_HINT, Exercise,
                    Feedback, answer_problem, as_array, call_student, chi2_average_bounds, distinct_mistakes, first_line,
                    is_rounding, judge, matches, unanswered)

__all__ = ["Feedback", "Exercise", "judge", "matches", "is_rounding", "unanswered", "as_array", "answer_problem",
           "call_student", "first_line", "chi2_average_bounds", "distinct_mistakes", "FORMAT_RULE", "GENERIC_HINT",
           "NON_FINITE_HINT", "PLACEHOLDER", "PLACEHOLDER_FUNC", "ROUNDED_HINT"]
