"""The harness of the exercise self-checks at the end of each notebook.

The checks themselves live with their problem: :mod:`kfcal_helpers.calibration.exercises`
(notebooks 01-07, 14-17), :mod:`kfcal_helpers.coop.exercises` (08-14, 18) and
:mod:`kfcal_helpers.orbit.exercises` (19-20, 23).  Each is named
``check_<topic>(answer, *, settings...)``: the student's answer (a number, an array or a function)
first, every setting keyword-only.  It returns a :class:`Feedback` that shows as one line: correct,
or a hint at the likely mistake (wrong sign, swapped variances, missing wrap...) without the answer.
The one answer-format rule, :data:`FORMAT_RULE`: pass the value you computed, with no rounding.
A function answer is called on deep copies of its inputs (a function that changes an input is told
which), each call within :data:`TIME_LIMIT` seconds (:mod:`~kfcal_helpers.exercises._limits`), and
anything it raises (``SystemExit`` included; Ctrl-C excepted) or returns is answered in one line; an
answer's size is read before any conversion (:func:`too_large`).
A slip (a units factor, degrees for radians, reversed, transposed, one or two entries off: named) gets
its own hint, for a judged answer and for a function's outputs alike (:mod:`~kfcal_helpers.exercises._slips`,
:meth:`Exercise.output_slip`).
Each exercise's texts are one :class:`Exercise` record (id, praise, hint, the hints of its common
mistakes, the names of its entries, which entries are angles) next to its check.  Worked solutions are in ``notebooks/solutions/``.
"""

from ._core import (BAND_NAMES, FORMAT_RULE, GENERIC_HINT, MAX_OUTPUT_ENTRIES, NON_FINITE_HINT, PLACEHOLDER, PLACEHOLDER_FUNC,
                    ROUNDED_HINT, TIME_LIMIT, Exercise, Feedback, answer_problem, answer_shape, as_array, call_student,
                    chi2_average_bounds, distinct_mistakes, first_line, is_rounding, judge, matches, shape_hint, too_large,
                    unanswered)
from ._limits import TimeLimitExceeded, can_interrupt, run_limited
from ._slips import SCALES, component_hint, matrix_names, output_slip_hint, slip_hint, slip_variants

__all__ = ["Feedback", "Exercise", "judge", "matches", "is_rounding", "unanswered", "as_array", "answer_problem",
           "call_student", "first_line", "chi2_average_bounds", "distinct_mistakes", "answer_shape", "shape_hint",
           "too_large", "slip_variants", "slip_hint", "component_hint", "output_slip_hint", "matrix_names", "SCALES", "run_limited", "can_interrupt", "TimeLimitExceeded", "BAND_NAMES", "FORMAT_RULE", "GENERIC_HINT",
           "NON_FINITE_HINT", "PLACEHOLDER", "PLACEHOLDER_FUNC", "ROUNDED_HINT", "TIME_LIMIT", "MAX_OUTPUT_ENTRIES"]
