"""Slip variants every check can recognise: an answer that is the right one scaled by a power of ten
(a units slip: mm for m, cm/s for m/s), in degrees for radians (or back), in reversed order (a band
[upper, lower]), transposed, or right in all but some components (named: "the heading of the UAV").

:func:`slip_hint` tries them in that order on an answer that is neither right nor a listed mistake and
returns one line naming the slip, never the answer; :func:`component_hint` names the wrong components.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SCALES", "slip_variants", "slip_hint", "component_hint"]

#: the unit factors a units slip multiplies by (m -> cm, mm; and their inverses)
SCALES = (10.0, 100.0, 1000.0)

_SCALE_HINT = ("your answer is {factor:g} times the right one: check the units (the exercise works in SI units: "
               "m, m/s, s, rad; not cm, mm or cm/s)")
_DEGREE_HINT = "your answer is in degrees: the exercise asks for radians (np.radians, or leave out np.degrees)"
_RADIAN_HINT = "your answer is in radians: the exercise asks for degrees"
_REVERSED_HINT = "your entries are in reverse order: check which comes first (a band is [lower, upper])"
_TRANSPOSED_HINT = "your matrix is transposed: rows and columns are swapped"


def _close(a: np.ndarray, b: np.ndarray, rtol: float, atol: float) -> bool:
    return a.shape == b.shape and bool(np.all(np.isfinite(a)) and np.allclose(a, b, rtol=rtol, atol=atol))


def slip_variants(expected, *, angles=None, scales: bool = True, reverse: bool = True, transpose: bool = True):
    """``(value, hint)`` pairs: ``expected`` as each slip turns it.  ``angles``: indices (of the
    flattened value) of the entries in radians, or True for all (the degree slips), None for none."""
    e = np.asarray(expected, dtype=float)
    out = []
    if scales:
        for f in SCALES:
            out.append((e * f, _SCALE_HINT.format(factor=f)))
            out.append((e / f, _SCALE_HINT.format(factor=1 / f)))
    if angles is not None and angles is not False:
        flat = e.ravel().copy()
        idx = np.arange(flat.size) if angles is True else np.asarray(angles, int)
        deg, rad = flat.copy(), flat.copy()
        deg[idx], rad[idx] = np.degrees(flat[idx]), np.radians(flat[idx])
        out.append((deg.reshape(e.shape), _DEGREE_HINT))
        out.append((rad.reshape(e.shape), _RADIAN_HINT))
    if reverse and e.ndim == 1 and e.size > 1:
        out.append((e[::-1], _REVERSED_HINT))
    if transpose and e.ndim == 2 and e.shape[0] > 1 and e.shape[1] > 1:
        out.append((e.T, _TRANSPOSED_HINT))
    return [(v, h) for v, h in out if not _close(v, e, 1e-9, 0.0)]


def slip_hint(answer, expected, *, rtol: float = 1e-6, atol: float = 1e-12, angles=None, scales: bool = True,
              reverse: bool = True, transpose: bool = True) -> str | None:
    """The hint of the first slip (:func:`slip_variants`) that turns ``expected`` into ``answer``
    (a float array of ``expected``'s size), else None."""
    e = np.asarray(expected, dtype=float)
    a = np.asarray(answer, dtype=float)
    if a.size != e.size:
        return None
    if not (e.ndim == 2 and a.shape == e.T.shape):
        a = a.reshape(e.shape)
    for value, hint in slip_variants(e, angles=angles, scales=scales, reverse=reverse, transpose=transpose):
        if value.shape == a.shape and _close(a, value, rtol, atol):
            return hint
    return None


def component_hint(answer, expected, names, *, rtol: float = 1e-6, atol: float = 1e-12, limit: int = 2) -> str | None:
    """One line naming the components of ``answer`` that differ from ``expected`` (entry by entry,
    flattened), by their ``names`` (one per entry), when at most ``limit`` of them differ and the rest
    are right; else None.  Names components, never their values."""
    e = np.asarray(expected, dtype=float).ravel()
    a = np.asarray(answer, dtype=float).ravel()
    if a.size != e.size or len(names) != e.size:
        return None
    with np.errstate(all="ignore"):
        wrong = ~np.isclose(a, e, rtol=rtol, atol=atol)
    k = int(np.count_nonzero(wrong))
    if k == 0 or k > limit or k == e.size:
        return None
    which = [names[i] for i in np.flatnonzero(wrong)]
    listed = which[0] if k == 1 else ", ".join(which[:-1]) + " and " + which[-1]
    verb = "is" if k == 1 else "are"
    return f"only {listed} {verb} off, the rest is right: look again at how you computed {'it' if k == 1 else 'them'}"
