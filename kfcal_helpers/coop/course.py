"""Where the course's observation log is: the ``KFCAL_COURSE_LOG`` environment variable.

The course owns its log, so the project never ships it.  Set ``KFCAL_COURSE_LOG`` to the
course's CSV folder (``ydata.csv``, ``tvec.csv``, ``Qtrue.csv``, ``Rtrue.csv``) or ``.mat``
file.  :func:`course_log` loads it, or, when the variable is unset or names nothing,
falls back to a seeded generated log made with the same noise model and says so.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from functools import partial

from ..logfiles import env_path
from ..validation import checked, optional, require_instance, require_seed
from .data import CoopLog, load_log
from .model import CoopParams
from .simulation import DEFAULT_LOG_SEED, simulate

__all__ = ["COURSE_LOG_VARIABLE", "COURSE_LOG_ROW_MEANS", "course_log_path", "course_log", "is_course_log"]

#: the environment variable naming the course log (a CSV folder or a .mat file)
COURSE_LOG_VARIABLE = "KFCAL_COURSE_LOG"


#: mean of each measurement row of the course's log (bearing rad, range m, bearing rad, east m, north m, over the
#: 1000 columns with a measurement): a fingerprint that tells the course's log from any other valid log
COURSE_LOG_ROW_MEANS = (-0.016611491, 101.816714229, 1.571116849, 48.827709559, -0.911894946)


@checked(log=partial(require_instance, cls=CoopLog), params=optional(partial(require_instance, cls=CoopParams)))
def is_course_log(log: CoopLog, params: CoopParams | None = None) -> bool:
    """True if ``log`` is the course's observation log: 1001 samples 0.1 s apart, the truth model's ``Qtrue``
    and ``Rtrue`` (of ``params``, default the course's) and the row means :data:`COURSE_LOG_ROW_MEANS`
    (to 1e-6).  The notebooks check the numbers they quote for the course log only on it."""
    p = params if params is not None else CoopParams()
    if not isinstance(log, CoopLog) or log.n_samples != 1001 or abs(log.dt - 0.1) > 1e-9:
        return False
    if not (np.allclose(log.Qtrue, p.Qtrue) and np.allclose(log.Rtrue, p.Rtrue)):
        return False
    has = ~np.isnan(log.y).all(axis=1)
    return bool(np.allclose(log.y[has].mean(axis=0), COURSE_LOG_ROW_MEANS, rtol=0, atol=1e-6))


def course_log_path() -> Path | None:
    """The path named by ``KFCAL_COURSE_LOG`` if it exists, else None."""
    return env_path(COURSE_LOG_VARIABLE)


@checked(params=optional(partial(require_instance, cls=CoopParams)), seed=partial(require_seed, allow_none=False))
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
