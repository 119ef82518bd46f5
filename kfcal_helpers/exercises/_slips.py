"""Slip variants every check can recognise: an answer that is the right one scaled by a power of ten
(a units slip: mm for m, cm/s for m/s), in degrees for radians (or back), in reversed order (a band
[upper, lower]), transposed, or right in all but some components (named: "the heading of the UAV").

:func:`slip_hint` tries them in that order on an answer that is neither right nor a listed mistake and
returns one line naming the slip, never the answer; :func:`component_hint` names the wrong components.
Both serve a student's function's output too (:func:`output_slip_hint`, one line naming the output:
"your function's p is 10 times the right one"), so a function exercise gets the same slips as a number.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SCALES", "ANSWER", "slip_variants", "slip_hint", "component_hint", "output_slip_hint", "matrix_names"]

#: the unit factors a units slip multiplies by (m -> cm, mm; and their inverses)
SCALES = (10.0, 100.0, 1000.0)
#: what a hint calls a judged answer (a function's output is "your function's result", or names the output)
ANSWER = "your answer"

_SCALE_HINT = ("{what} is {factor:g} times the right one: check the units (the exercise works in SI units: "
               "m, m/s, s, rad; not cm, mm or cm/s)")
_DEGREE_HINT = "{what} is in degrees: the exercise asks for radians (np.radians, or leave out np.degrees)"
_RADIAN_HINT = "{what} is in radians: the exercise asks for degrees"
_REVERSED_HINT = "your entries are in reverse order: check which comes first (a band is [lower, upper])"
_REVERSED_OUTPUT_HINT = "the entries of {what} are in reverse order: check which comes first"
_TRANSPOSED_HINT = "{matrix} is transposed: rows and columns are swapped"


def matrix_names(symbol: str, n: int, m: int | None = None) -> tuple:
    """``("K[0,0]", "K[0,1]", ...)``: the names of an (n, m) matrix's entries (m = n by default), row by
    row, for the hint that names the one or two wrong ones (:func:`component_hint`)."""
    return tuple(f"{symbol}[{i},{j}]" for i in range(n) for j in range(n if m is None else m))


def _close(a: np.ndarray, b: np.ndarray, rtol: float, atol: float) -> bool:
    return a.shape == b.shape and bool(np.all(np.isfinite(a)) and np.allclose(a, b, rtol=rtol, atol=atol))


def _angle_index(angles, n: int) -> np.ndarray:
    """The indices along the last axis (of length ``n``) that ``angles`` marks (True: all)."""
    return np.arange(n) if angles is True else np.asarray(angles, int)


def slip_variants(expected, *, angles=None, scales: bool = True, reverse: bool = True, transpose: bool = True,
                  what: str = ANSWER):
    """``(value, hint)`` pairs: ``expected`` as each slip turns it.  ``angles``: the indices along the last
    axis of the entries in radians (of a vector: its entries; of a stack of a function's outputs, one row
    per test case: the columns), or True for all (the degree slips), None for none.  ``what``: what the
    hints call the answer ("your answer", "your function's v")."""
    e = np.asarray(expected, dtype=float)
    out = []
    if scales:
        for f in SCALES:
            out.append((e * f, _SCALE_HINT.format(what=what, factor=f)))
            out.append((e / f, _SCALE_HINT.format(what=what, factor=1 / f)))
    if angles is not None and angles is not False and e.ndim >= 1:
        idx = _angle_index(angles, e.shape[-1])
        deg, rad = e.copy(), e.copy()
        deg[..., idx], rad[..., idx] = np.degrees(e[..., idx]), np.radians(e[..., idx])
        out.append((deg, _DEGREE_HINT.format(what=what)))
        out.append((rad, _RADIAN_HINT.format(what=what)))
    elif angles is True:  # a single angle
        out.append((np.degrees(e), _DEGREE_HINT.format(what=what)))
        out.append((np.radians(e), _RADIAN_HINT.format(what=what)))
    if reverse and e.ndim == 1 and e.size > 1:
        out.append((e[::-1], _REVERSED_HINT if what == ANSWER else _REVERSED_OUTPUT_HINT.format(what=what)))
    if transpose and e.ndim == 2 and e.shape[0] > 1 and e.shape[1] > 1:
        out.append((e.T, _TRANSPOSED_HINT.format(matrix="your matrix" if what == ANSWER else what)))
    return [(v, h) for v, h in out if not _close(v, e, 1e-9, 0.0)]


def slip_hint(answer, expected, *, rtol: float = 1e-6, atol: float = 1e-12, angles=None, scales: bool = True,
              reverse: bool = True, transpose: bool = True, what: str = ANSWER) -> str | None:
    """The hint of the first slip (:func:`slip_variants`) that turns ``expected`` into ``answer``
    (a float array of ``expected``'s size), else None."""
    e = np.asarray(expected, dtype=float)
    a = np.asarray(answer, dtype=float)
    if a.size != e.size:
        return None
    if not (e.ndim == 2 and a.shape == e.T.shape):
        a = a.reshape(e.shape)
    for value, hint in slip_variants(e, angles=angles, scales=scales, reverse=reverse, transpose=transpose,
                                     what=what):
        if value.shape == a.shape and _close(a, value, rtol, atol):
            return hint
    return None


def _column_slip(a: np.ndarray, e: np.ndarray, cols, angles, rtol: float, atol: float, units: bool) -> str | None:
    """What turns the columns ``cols`` of ``e`` into those of ``a``: a units factor or degrees (for
    columns among ``angles``), as a few words, or None."""
    a, e = a[:, cols], e[:, cols]
    for f in SCALES if units else ():
        for factor in (f, 1 / f):
            if _close(a, e * factor, rtol, atol) and not _close(e * factor, e, 1e-9, 0.0):
                return f"{factor:g} times the right value: check the units"
    among_angles = angles is True or (angles is not None and angles is not False
                                      and set(cols) <= set(np.asarray(angles, int).tolist()))
    if among_angles and _close(a, np.degrees(e), rtol, atol):
        return "in degrees: the exercise asks for radians"
    return None


def component_hint(answer, expected, names, *, rtol: float = 1e-6, atol: float = 1e-12, limit: int = 2,
                   angles=None, units: bool = True) -> str | None:
    """One line naming the components of ``answer`` that differ from ``expected``, by their ``names``,
    when at most ``limit`` of them differ and the rest are right (two that trade places are called
    swapped); else None.  ``names`` has one name per
    entry (flattened), or one per entry of the last axis: then ``expected`` is a stack (a function's
    outputs, one row per test case) and a component is off when it is off in any row.  When the wrong
    components are the right ones times a units factor, or in degrees (``angles``: indices along the last
    axis, or True), the hint says so (``units=False``: no units factor).  Names components, never their values."""
    e = np.asarray(expected, dtype=float)
    a = np.asarray(answer, dtype=float)
    n = len(names)
    if a.size != e.size or n == 0 or not (n == e.size or (e.ndim >= 1 and e.shape[-1] == n)):
        return None
    e, a = e.reshape(-1, n), a.reshape(-1, n)
    with np.errstate(all="ignore"):
        wrong = np.any(~np.isclose(a, e, rtol=rtol, atol=atol), axis=0)
    k = int(np.count_nonzero(wrong))
    if k == 0 or k > limit or k == n:
        return None
    which = [names[i] for i in np.flatnonzero(wrong)]
    if k == 2:
        i, j = np.flatnonzero(wrong)
        with np.errstate(all="ignore"):
            swapped = (np.allclose(a[:, i], e[:, j], rtol=rtol, atol=atol)
                       and np.allclose(a[:, j], e[:, i], rtol=rtol, atol=atol))
        if swapped:
            return f"{which[0]} and {which[1]} are swapped, the rest is right: check the order of the entries"
    listed = which[0] if k == 1 else ", ".join(which[:-1]) + " and " + which[-1]
    verb = "is" if k == 1 else "are"
    slip = _column_slip(a, e, list(np.flatnonzero(wrong)), angles, rtol, atol, units)
    if slip is not None:
        return f"only {listed} {verb} off, the rest is right: {'it is' if k == 1 else 'they are'} {slip}"
    return f"only {listed} {verb} off, the rest is right: look again at how you computed {'it' if k == 1 else 'them'}"


def output_slip_hint(outputs, expected, names, *, rtol: float = 1e-9, atol: float = 1e-12, angles=None,
                     components=None, units: bool = True) -> str | None:
    """The slip hint for a student's function whose outputs are right but for a slip: ``outputs`` and
    ``expected`` are sequences of float arrays (the function's results, e.g. ``(p, v)``, each stacked over
    the test cases), ``names`` what each is called ("p", "v").  When every output is right or the right
    one slipped (:func:`slip_variants`: ×10, ×100, ×1000 and inverses, degrees for ``angles`` (a list
    with one per output, or one for all), reversed, transposed) and one is slipped, the first slipped output's hint
    ("your function's p is 10 times the right one: ..."); else, with ``components`` (names of each
    output's entries or of the entries along its last axis: a list with one tuple (or None) per output), the hint naming the one or two wrong components of the one
    output that is off.  ``units=False``: no units slip.  None otherwise."""
    outputs = [np.asarray(o, dtype=float) for o in outputs]
    expected = [np.asarray(e, dtype=float) for e in expected]
    per = lambda v: v if isinstance(v, list) and len(v) == len(expected) else [v] * len(expected)  # noqa: E731
    angles_of, comps = per(angles), per(components)
    if len(outputs) != len(expected):
        return None
    first, off = None, []
    for i, (o, e, name, ang) in enumerate(zip(outputs, expected, names, angles_of)):
        if o.size != e.size:
            return None
        if _close(o.reshape(e.shape), e, rtol, atol):
            continue
        off.append((o, e, i))
        hint = slip_hint(o, e, rtol=rtol, atol=atol, angles=ang, what=f"your function's {name}", scales=units)
        if hint is None:
            first = False
        elif first is None:
            first = hint
    if first:
        return first
    if len(off) == 1 and comps[off[0][2]]:
        o, e, i = off[0]
        return component_hint(o, e, comps[i], rtol=rtol, atol=atol, angles=angles_of[i], units=units)
    return None
