"""The mistakes table (notebook 14): which Monte Carlo checks catch which mistake.

Each problem of :data:`kfcal_helpers.problems.PROBLEMS` lists its mistakes (``mistakes``: name ->
what the filter does wrong, its correct filter first) and runs one row (``mistake_row``: the Monte
Carlo of the filter with that mistake, :class:`~kfcal_helpers.registry.MistakeRow`).  This module
joins them: :func:`mistake_table` runs the rows, :func:`format_mistake_table` prints them, one column
per check (the checks of every problem, in order of first appearance; "-" where a problem does not
have that check).
"""

from __future__ import annotations

from .consistency import Check
from .registry import MistakeRow
from .validation import (checked, optional, require_choice, require_iterable, require_probability, require_sequence,
                         require_text)

__all__ = ["MistakeRow", "all_mistakes", "mistake_table", "format_mistake_table", "table_checks"]


def _owners() -> dict:
    from . import problems

    out = {}
    for problem in problems.PROBLEMS:
        for name in problem.mistakes:
            if name in out:
                raise ValueError(f"mistake name {name!r} is used by two problems ({out[name].name} and {problem.name})")
            out[name] = problem
    return out


def all_mistakes() -> tuple:
    """Every problem's mistake names, in problem order (each problem's correct filter first)."""
    return tuple(_owners())


def _per_problem(name: str, value, problems_by_name: dict) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ValueError(f"{name} must be None or a dict problem name -> value, "
                         f"problem names {', '.join(problems_by_name)}; got {type(value).__name__}")
    for key in value:
        require_choice(f"{name} key", key, tuple(problems_by_name))
    return value


def mistake_table(mistakes=None, n_runs=None, params=None, alpha: float = 0.05) -> dict:
    """The table mistake x check: dict mistake -> :class:`MistakeRow`, in the order given.

    Parameters
    ----------
    mistakes : sequence of mistake names (default: :func:`all_mistakes`)
    n_runs : optional dict problem name -> realizations per row (default: each problem's own)
    params : optional dict problem name -> that problem's parameters (default: its defaults)
    alpha : significance of the checks, in (0, 1)

    Every row of a problem uses that problem's seed, so the rows differ only by the mistake.
    """
    owners = _owners()
    by_name = {p.name: p for p in owners.values()}
    n_runs = _per_problem("n_runs", n_runs, by_name)
    params = _per_problem("params", params, by_name)
    alpha = require_probability("alpha", alpha)
    if mistakes is None:
        mistakes = tuple(owners)
    elif isinstance(mistakes, str):
        mistakes = (mistakes,)
    else:
        mistakes = require_iterable("mistakes", mistakes)
    out = {}
    for mistake in mistakes:
        mistake = require_choice("mistakes", mistake, tuple(owners))
        problem = owners[mistake]
        out[mistake] = problem.mistake_row(mistake, n_runs=n_runs.get(problem.name), params=params.get(problem.name),
                                           alpha=alpha)
    return out


def _rows(name: str, rows) -> dict:
    if not isinstance(rows, dict) or not rows or not all(isinstance(r, MistakeRow) for r in rows.values()):
        raise ValueError(f"{name} must be a non-empty dict mistake -> MistakeRow, as mistake_table() returns")
    return rows


def _check_names(name: str, checks) -> tuple:
    return tuple(require_text(name, c) for c in require_sequence(name, checks))


@checked(rows=_rows)
def table_checks(rows: dict) -> tuple:
    """The check names of ``rows`` (dict mistake -> MistakeRow), in order of first appearance."""
    return tuple(dict.fromkeys(name for row in rows.values() for name in row.checks))


def _cell(check: Check | None) -> str:
    if check is None:
        return "-"
    return f"{'pass' if check.passed else 'FAIL'} {check.worst:.3g}"


@checked(rows=_rows, checks=optional(_check_names))
def format_mistake_table(rows: dict, checks=None) -> str:
    """Fixed-width text table: one row per mistake, one column per check (default
    :func:`table_checks`), each cell "pass w" or "FAIL w" with w = worst deviation / its
    simultaneous bound (> 1 fails), "-" where the check does not apply."""
    checks = table_checks(rows) if checks is None else tuple(checks)
    width = max(len("mistake"), *(len(m) for m in rows))
    cols = [max(len(c), 12) for c in checks]
    lines = [f"{'mistake':<{width}}  " + "  ".join(f"{c:>{w}}" for c, w in zip(checks, cols))]
    lines.append("-" * len(lines[0]))
    for mistake, row in rows.items():
        lines.append(f"{mistake:<{width}}  " + "  ".join(f"{_cell(row.checks.get(c)):>{w}}" for c, w in zip(checks, cols)))
    return "\n".join(lines)
