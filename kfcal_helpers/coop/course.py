"""Where the course's observation log is: the ``KFCAL_COURSE_LOG`` environment variable.

The course owns its log, so the project never ships it.  Set ``KFCAL_COURSE_LOG`` to the
course's CSV folder (``ydata.csv``, ``tvec.csv``, ``Qtrue.csv``, ``Rtrue.csv``) or ``.mat``
file.  :func:`course_log` loads it, or, when the variable is unset or names nothing,
falls back to a seeded generated log made with the same noise model and says so.
"""

from __future__ import annotations

import os
from pathlib import Path

from .data import CoopLog, load_log
from .model import CoopParams
from .simulation import DEFAULT_LOG_SEED, simulate

__all__ = ["COURSE_LOG_VARIABLE", "course_log_path", "course_log"]

#: the environment variable naming the course log (a CSV folder or a .mat file)
COURSE_LOG_VARIABLE = "KFCAL_COURSE_LOG"


def course_log_path() -> Path | None:
    """The path named by ``KFCAL_COURSE_LOG`` if it exists, else None."""
    value = os.environ.get(COURSE_LOG_VARIABLE, "").strip()
    if not value:
        return None
    path = Path(value).expanduser()
    return path if path.exists() else None


def course_log(params: CoopParams | None = None, seed: int = DEFAULT_LOG_SEED) -> tuple[CoopLog, bool, str]:
    """``(log, found, message)``: the course log named by ``KFCAL_COURSE_LOG`` (``found`` True), or a
    seeded generated log with ``params``' noise model (``found`` False); ``message`` is one line
    saying which.  ValueError if the variable names a file that is not a valid log."""
    path = course_log_path()
    if path is not None:
        return load_log(path), True, f"course log found ({COURSE_LOG_VARIABLE}): {path}"
    why = "is not set" if not os.environ.get(COURSE_LOG_VARIABLE, "").strip() else "names no existing path"
    log = simulate(params, seed=seed).log()
    return log, False, (f"no course log ({COURSE_LOG_VARIABLE} {why}): using a generated log "
                        f"(seed {seed}, same noise model) instead")
