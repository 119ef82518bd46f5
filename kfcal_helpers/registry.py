"""The interface every course problem implements, so that one list of problems
(:mod:`kfcal_helpers.problems`) drives the command line, the lecture figures and the
mistakes table.

A problem package (``kfcal_helpers.calibration``, ``kfcal_helpers.coop``, or a third one)
defines ``PROBLEM = Problem(...)`` in its ``__init__``:

* ``name`` -- its key (``"calibration"``, ``"coop"``), e.g. in the mistakes table's per-problem settings;
* ``title`` -- one line for ``--help`` and the tables;
* ``add_cli(subparsers)`` -- registers its sub-command (``calibrate``, ``coop``) on an argparse
  sub-parsers object; the parser it adds must ``set_defaults(run=...)`` with ``run(args) -> int``;
* ``figures`` -- its :class:`LectureFigure` entries, in lecture order; ``make(data)`` draws one from
  ``figure_data()``, the problem's lazily computed, seeded results;
* ``mistakes`` -- ``{mistake name: what it does}``, the correct filter first;
* ``mistake_row(mistake, n_runs=None, params=None, alpha=0.05) -> MistakeRow`` -- the Monte Carlo of
  the filter with that mistake (``n_runs=None``: the problem's default).

This module imports no problem package: imports point from problem code to shared code.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

__all__ = ["Problem", "LectureFigure", "MistakeRow"]


@dataclass(frozen=True)
class LectureFigure:
    """One lecture figure: ``name`` (file stem, unique over all problems), ``description`` (one
    line) and ``make(data) -> matplotlib.figure.Figure`` drawing from the problem's figure data."""

    name: str
    description: str
    make: Callable


@dataclass(frozen=True)
class MistakeRow:
    """One row of the mistakes table.

    problem : the problem's name; mistake : the mistake's name; description : one line;
    checks : ``{check name: consistency.Check}``; result : the Monte Carlo result behind them.
    """

    problem: str
    mistake: str
    description: str
    checks: dict
    result: object

    @property
    def failed(self) -> tuple:
        """Names of the checks that fail (outside their simultaneous band)."""
        return tuple(name for name, c in self.checks.items() if not c.passed)

    @property
    def passed(self) -> bool:
        """True when every check of the row passes."""
        return not self.failed


@dataclass(frozen=True)
class Problem:
    """A course problem as the command line, ``figures`` and the mistakes table see it
    (see the module docstring for each field)."""

    name: str
    title: str
    add_cli: Callable
    figures: tuple = ()
    figure_data: Callable | None = None
    mistakes: dict = field(default_factory=dict)
    mistake_row: Callable | None = None
