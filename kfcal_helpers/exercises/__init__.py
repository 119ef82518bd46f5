"""Self-checks for the exercises at the end of each notebook.

Each ``check_*`` function takes the student's answer and returns a
:class:`~kfcal_helpers.exercises.Feedback` that shows as one line: correct, or a
hint at the likely mistake (wrong sign, swapped variances, missing wrap...) without the
answer.  Worked solutions are in ``notebooks/solutions/``.

Modules by notebook group: :mod:`.calibration` (01-07, 15, 16), :mod:`.coop` (08-13),
:mod:`.mistakes` (14), :mod:`.demos` (17, 18); all their checks are importable from here.
"""

from . import calibration, coop, demos, mistakes
from ._core import Feedback, judge, matches, unanswered
from .calibration import *  # noqa: F401,F403
from .coop import *  # noqa: F401,F403
from .demos import *  # noqa: F401,F403
from .mistakes import *  # noqa: F401,F403

__all__ = ["Feedback", "judge", "matches", "unanswered",
           *calibration.__all__, *coop.__all__, *mistakes.__all__, *demos.__all__]
