"""The list of course problems: the one place that imports the problem packages.

The command line (:mod:`kfcal_helpers.cli`), the lecture figures (:mod:`kfcal_helpers.figures`)
and the mistakes table (:mod:`kfcal_helpers.mistakes`) read :data:`PROBLEMS` when they run, so a
problem added here (a package that defines ``PROBLEM``, see :mod:`kfcal_helpers.registry`)
appears in ``--help``, ``figures --list`` and the table without editing them.
"""

from __future__ import annotations

from .calibration import PROBLEM as CALIBRATION
from .coop import PROBLEM as COOP
from .orbit import PROBLEM as ORBIT
from .registry import Problem
from .validation import require_text

__all__ = ["PROBLEMS", "problem", "CALIBRATION", "COOP", "ORBIT"]

#: the course problems, in lecture order
PROBLEMS: tuple[Problem, ...] = (CALIBRATION, COOP, ORBIT)


def problem(name: str) -> Problem:
    """The problem called ``name`` (ValueError naming the problems there are)."""
    require_text("problem", name)
    for p in PROBLEMS:
        if p.name == name:
            return p
    raise ValueError(f"problem must be one of {', '.join(p.name for p in PROBLEMS)}, got {name!r}")
