"""What the command line writes, shared by every sub-command: strict JSON, and the registry of
files being written (removed by the command line's Ctrl-C handler)."""

from __future__ import annotations

import json
import math

__all__ = ["dumps_json", "PARTIAL_FILES"]

#: temporary files being written (see kfcal_helpers.figures.save_atomic), removed on Ctrl-C
PARTIAL_FILES: set = set()


def _strict(value):
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


def dumps_json(obj) -> str:
    """``obj`` as strict JSON (``allow_nan=False``): a non-finite float (NaN, infinity) becomes null."""
    return json.dumps(_strict(obj), allow_nan=False)
