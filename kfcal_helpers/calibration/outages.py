"""GPS outages: which fixes a set of time windows removes.

A window ``(start, end)`` in seconds covers the half-open interval
``start <= t < end``: the fix at ``start`` is missing and the fix at ``end`` is
the first one back.  A 5 s window starting on a fix therefore removes
``5 * gps_rate`` fixes (25 at 5 Hz).  Fix times are compared with a tolerance of
1e-9 s, so ``t = 5.0`` is "at 5 s" even when it is computed as ``1000 * 0.005``.
"""

from __future__ import annotations

import numpy as np

from ..validation import checked, require_instance, require_text
from .params import CalibrationParams

__all__ = ["outage_mask", "parse_outage"]

_TOL = 1e-9  #: s, tolerance when comparing fix times with window ends


@checked(name=require_text)
def outage_mask(params: CalibrationParams, windows, name: str = "windows") -> np.ndarray:
    """Bool mask of the GPS fixes inside the outage windows.

    Parameters
    ----------
    params : CalibrationParams
    windows : sequence of (start, end) pairs, seconds, with ``0 <= start < end <= duration``
    name : the argument name used in error messages (the CLI passes ``--outage``)

    Returns
    -------
    bool array (n_gps,), True for the fixes with ``start <= t_gps < end`` for some window
    (pass it as ``missing_fixes`` to :func:`simulate`, :func:`covariance_sequence`
    or :func:`run_monte_carlo`).

    Raises
    ------
    ValueError naming ``name`` if a window is malformed, empty or outside ``[0, duration]``.
    """
    require_instance("params", params, CalibrationParams)
    try:
        pairs = [tuple(w) for w in windows]
    except TypeError:
        raise ValueError(f"{name} must be a sequence of (start, end) pairs in seconds, got {windows!r}") from None
    t = params.t_gps
    mask = np.zeros(params.n_gps, bool)
    for w in pairs:
        if len(w) != 2:
            raise ValueError(f"{name}: each window must be a (start, end) pair in seconds, got {w!r}")
        try:
            start, end = float(w[0]), float(w[1])
        except (TypeError, ValueError):
            raise ValueError(f"{name}: window bounds must be numbers (seconds), got {w!r}") from None
        if not (np.isfinite(start) and np.isfinite(end)):
            raise ValueError(f"{name}: window bounds must be finite, got {w!r}")
        if start >= end:
            raise ValueError(f"{name}: window start must be before its end, got {start:g}:{end:g} s")
        if start < 0 or end > params.duration + _TOL:
            raise ValueError(f"{name}: window {start:g}:{end:g} s is outside [0, {params.duration:g}] s")
        mask |= (t >= start - _TOL) & (t < end - _TOL)
    return mask


@checked(text=require_text, name=require_text)
def parse_outage(text: str, name: str = "--outage") -> tuple[float, float]:
    """Parse ``"START:END"`` (seconds) into ``(start, end)`` floats.

    Only the syntax and ``start < end`` are checked here; the range
    ``[0, duration]`` is checked by :func:`outage_mask`.  ValueError naming ``name``.
    """
    parts = str(text).split(":")
    if len(parts) != 2:
        raise ValueError(f"{name} must be START:END in seconds, got {text!r}")
    try:
        start, end = float(parts[0]), float(parts[1])
    except ValueError:
        raise ValueError(f"{name} must be START:END in seconds (two numbers), got {text!r}") from None
    if not (np.isfinite(start) and np.isfinite(end)):
        raise ValueError(f"{name} bounds must be finite, got {text!r}")
    if start >= end:
        raise ValueError(f"{name} START must be less than END, got {text!r}")
    return start, end
