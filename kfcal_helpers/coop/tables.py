"""Plain-text tables and matrices with fixed precision, for notebook output that is the
same on every machine (no numpy reprs, no negative zeros from rounding noise)."""

from __future__ import annotations

import numpy as np

from functools import partial

from ..validation import checked, optional, require_array, require_int

__all__ = ["format_number", "format_matrix", "format_table"]

#: decimals a table may show (a float has 17 significant digits)
_DIGITS = partial(require_int, minimum=0, maximum=17)


def _matrix(name, value):
    arr = require_array(name, value)
    if arr.ndim > 2 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty number, vector or 2-D matrix, got shape {arr.shape}")
    return arr


def _headers(name, value):
    if isinstance(value, (str, bytes)) or not all(isinstance(h, (str, int, float)) for h in _sequence(name, value)):
        raise ValueError(f"{name} must be a sequence of column names (text)")
    return value


def _rows(name, value):
    for row in _sequence(name, value):
        if isinstance(row, (str, bytes)) or not all(isinstance(v, (str, int, float, np.number, np.bool_))
                                                    for v in _sequence(name, row)):
            raise ValueError(f"{name} must be a sequence of rows of numbers or text")
    return value


def _sequence(name, value):
    try:
        return list(value)
    except TypeError:
        raise ValueError(f"{name} must be a sequence, got {type(value).__name__}") from None


@checked(digits=_DIGITS)
def format_number(value, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals; -0.000 is printed as 0.000; strings pass through."""
    if isinstance(value, str):
        return value
    if not isinstance(value, (int, float, np.number, np.bool_)):
        raise ValueError(f"value must be a number or a text, got {type(value).__name__}")
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    digits = require_int("digits", digits, minimum=0)
    v = float(value)
    if not np.isfinite(v):
        return str(v)
    return f"{round(v, digits) + 0.0:.{digits}f}"


@checked(matrix=_matrix, digits=_DIGITS, width=optional(partial(require_int, minimum=1, maximum=100)))
def format_matrix(matrix, digits: int = 3, width: int | None = None) -> str:
    """Rows of a 2-D array, right-aligned columns of ``digits`` decimals."""
    m = np.atleast_2d(np.asarray(matrix, dtype=float))
    cells = [[format_number(v, digits) for v in row] for row in m]
    w = width or max(len(c) for row in cells for c in row)
    return "\n".join(" ".join(c.rjust(w) for c in row) for row in cells)


@checked(rows=_rows, headers=_headers, digits=_DIGITS)
def format_table(rows, headers, digits: int = 3) -> str:
    """A table: ``rows`` is a list of sequences (numbers or strings), ``headers`` their names."""
    cells = [[str(h) for h in headers]] + [[format_number(v, digits) for v in row] for row in rows]
    if any(len(row) != len(headers) for row in cells):
        raise ValueError("rows must each have one entry per header")
    widths = [max(len(row[j]) for row in cells) for j in range(len(headers))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
