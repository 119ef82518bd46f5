"""Observation logs in the course format: a folder of CSVs or a MATLAB ``.mat`` file.

Course format (variables / files):

* ``ydata`` -- 5 x K measurements, one column per time (rad, m, rad, m, m); the first
  column (t = 0) is NaN, and any all-NaN column means "no measurement at that step";
* ``tvec`` -- 1 x K times, s, uniformly spaced;
* ``Qtrue`` -- 6 x 6 covariance of the DT process noise w_k, a noise on the rates ((m/s)^2, (rad/s)^2) held
  constant over each step; the state receives ``Omega Qtrue Omega^T = dt^2 Qtrue`` per step (``Omega = dt I``,
  the Euler step of the held noise); ``Rtrue`` -- 5 x 5 measurement noise.

As CSV: ``ydata.csv``, ``tvec.csv``, ``Qtrue.csv``, ``Rtrue.csv`` in one folder.
Inside the package a log is a :class:`CoopLog` with one *row* per time.

What the reader accepts (anything else is a ValueError naming the path, file or variable):

* regular files only, after resolving links (no FIFO, device such as ``/dev/zero``, or socket);
* at most :data:`~kfcal_helpers.coop.model.MAX_STEPS` steps: one filter run of the log must fit in the
  500 MB memory limit (:func:`~kfcal_helpers.coop.model.run_bytes` estimates it), and the files may not be
  larger than such a log needs (:data:`MAX_FILE_BYTES`), checked before reading;
* in a ``.mat``, the class and shape of the four variables are checked from their headers
  (``scipy.io.whosmat``) before they are loaded, so a small compressed file that would expand to
  gigabytes is refused unread;
* ``tvec`` with a constant step up to the float rounding of its largest time (Unix-epoch seconds pass).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..files import named, read_regular
from ..logfiles import (MAT_KINDS, MAT_NUMERIC, bounded_lines, cannot_read, check_times, csv_text, load_mat, mat_headers,
                        numeric, parse_csv, require_csv_file, write_mat)
from ..validation import require_array, require_covariance, require_instance, require_int, require_text
from .model import MAX_MEASUREMENT, MAX_STEPS, MAX_VARIANCE, N_MEAS, N_STATES, CoopParams, too_many_steps

__all__ = ["LOG_VARIABLES", "CoopLog", "load_log", "write_log_csv", "write_log_mat", "MAX_FILE_BYTES",
           "MAX_MEASUREMENT"]

LOG_VARIABLES = ("ydata", "tvec", "Qtrue", "Rtrue")

#: bytes one number may take in a CSV (``-1.2345678901234567e-100,`` is 25; room for spaces)
_CSV_BYTES_PER_VALUE = 32
#: the largest file accepted, bytes: the CSVs of a log of MAX_STEPS steps (5 rows of ydata, tvec), the
#: two small matrices, and a ``.mat`` with room for other variables (8 x the four variables' raw size)
MAX_FILE_BYTES = {
    "ydata": N_MEAS * MAX_STEPS * _CSV_BYTES_PER_VALUE + 65536,
    "tvec": MAX_STEPS * _CSV_BYTES_PER_VALUE + 65536,
    "Qtrue": 65536,
    "Rtrue": 65536,
    "mat": 8 * 8 * (N_MEAS + 1) * MAX_STEPS + 65536,
}

@dataclass(frozen=True, eq=False)
class CoopLog:
    """An observation log.

    Attributes
    ----------
    t : array (K,), s
    y : array (K, 5) -- measurements, rows of NaN where there is none (row 0 in the course log)
    Qtrue : array (6, 6) -- covariance of the rate noise w_k held over a step; Rtrue : array (5, 5)
    truth : array (K, 6) or None -- true states, known only for simulated logs
    source : str -- where the log came from (for messages)
    """

    t: np.ndarray
    y: np.ndarray
    Qtrue: np.ndarray
    Rtrue: np.ndarray
    truth: np.ndarray | None = None
    source: str = ""

    def __post_init__(self):
        t = require_array("tvec", self.t)
        y = require_array("ydata", self.y)
        require_text("source", self.source)
        t = check_times(t, lambda k: too_many_steps("tvec", k) if k > MAX_STEPS else None)
        if y.shape != (t.size, N_MEAS):
            raise ValueError(f"ydata must have shape (5, {t.size}) to match tvec, got {y.T.shape}")
        bad = np.isnan(y).any(axis=1) & ~np.isnan(y).all(axis=1)
        if bad.any() or np.isinf(y).any():
            raise ValueError(f"ydata columns must be all finite or all NaN; column {int(np.flatnonzero(bad | np.isinf(y).any(axis=1))[0])} is not")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "Qtrue", require_covariance("Qtrue", self.Qtrue, N_STATES, MAX_VARIANCE))
        object.__setattr__(self, "Rtrue", require_covariance("Rtrue", self.Rtrue, N_MEAS, MAX_VARIANCE))
        if self.truth is not None:
            truth = require_array("truth", self.truth)
            if truth.shape != (t.size, N_STATES):
                raise ValueError(f"truth must have shape ({t.size}, 6), got {truth.shape}")
            object.__setattr__(self, "truth", truth)

    @property
    def dt(self) -> float:
        """Sampling interval, s: the mean step of ``t`` (exact for rounded times such as Unix-epoch seconds)."""
        return float((self.t[-1] - self.t[0]) / (self.t.size - 1))

    @property
    def n_samples(self) -> int:
        return self.t.size

    def params(self, base: CoopParams | None = None) -> CoopParams:
        """``base`` (default: the course's) with this log's dt, duration, Qtrue and Rtrue."""
        base = base if base is not None else CoopParams()
        return replace(base, dt=self.dt, duration=self.dt * (self.n_samples - 1), Qtrue=self.Qtrue, Rtrue=self.Rtrue)

    def every(self, m: int) -> "CoopLog":
        """A copy that keeps the measurements of every ``m``-th step (k = 0, m, 2m, ...), NaN elsewhere."""
        m = require_int("m", m, minimum=1)
        if m > self.n_samples - 1:
            raise ValueError(f"m must be at most {self.n_samples - 1} (the log has {self.n_samples} steps), got {m}")
        y = np.full_like(self.y, np.nan)
        y[::m] = self.y[::m]
        return CoopLog(self.t, y, self.Qtrue, self.Rtrue, self.truth, f"{self.source} (every {m})")


def _matrix(name, value, shape) -> np.ndarray:
    arr = np.atleast_2d(numeric(name, value))
    if arr.ndim != 2 or any(s is not None and s != n for s, n in zip(shape, arr.shape)):
        want = " x ".join("K" if s is None else str(s) for s in shape)
        raise ValueError(f"{name} must be a {want} matrix, got shape {arr.shape}")
    return arr


def _build(raw: dict, source: str) -> CoopLog:
    ydata = _matrix("ydata", raw["ydata"], (N_MEAS, None))
    if ydata.shape[1] > MAX_STEPS:
        raise ValueError(too_many_steps("ydata", ydata.shape[1]))
    tvec = numeric("tvec", raw["tvec"])
    if tvec.ndim > 2 or (tvec.ndim == 2 and min(tvec.shape) != 1):
        raise ValueError(f"tvec must be a 1 x K vector, got shape {tvec.shape}")
    finite = ydata[np.isfinite(ydata)]
    if finite.size == 0:
        raise ValueError("ydata holds no measurement (every column is NaN)")
    if np.abs(finite).max() > MAX_MEASUREMENT:
        raise ValueError(f"ydata values must be at most {MAX_MEASUREMENT:g} in magnitude (m, rad), "
                         f"got {np.abs(finite).max():.3g}")
    return CoopLog(tvec.ravel(), ydata.T, _matrix("Qtrue", raw["Qtrue"], (N_STATES, N_STATES)),
                   _matrix("Rtrue", raw["Rtrue"], (N_MEAS, N_MEAS)), source=source)


def _read_bytes(f: Path, limit: int, argname: str, name: str) -> bytes:
    """The bytes of the regular file ``f`` (links resolved), at most ``limit`` of them: ValueError naming
    ``argname`` for a FIFO, device, socket or unreadable file, naming ``name`` for a file that is too large
    (:func:`kfcal_helpers.files.read_regular`)."""
    return read_regular(f, limit, argname=argname, regular_only="a log is read from regular files only",
                        too_large=f"{name}: {named(f)} is larger than the {limit / 1e6:.1f} MB a log of at most "
                                  f"{MAX_STEPS} steps needs (a longer log would not fit in memory)")


def _read_csv(name: str, f: Path, argname: str) -> np.ndarray:
    require_csv_file(f, argname, [v + ".csv" for v in LOG_VARIABLES])
    text = csv_text(name, f, _read_bytes(f, MAX_FILE_BYTES[name], argname, name))
    lines = _bounded_lines(name, f, text)
    del text
    return parse_csv(name, f, lines)


#: the rows each CSV may hold (tvec: one row of K times, or one column of them), and the blank or comment
#: lines allowed beside them
_CSV_ROWS = {"ydata": N_MEAS, "tvec": MAX_STEPS, "Qtrue": N_STATES, "Rtrue": N_MEAS}
_CSV_SPARE_LINES = 100
#: the values one line may hold (one row of ydata or tvec holds at most MAX_STEPS)
_CSV_FIELDS = {"ydata": MAX_STEPS, "tvec": MAX_STEPS, "Qtrue": N_STATES, "Rtrue": N_MEAS}


def _bounded_lines(name: str, f: Path, text: str) -> list:
    """The lines of a CSV's ``text``, its lines and each line's fields counted against the shape the
    variable may have before it is split or parsed (:func:`kfcal_helpers.logfiles.bounded_lines`)."""
    rows = _CSV_ROWS[name]
    shape = "a 1 x K vector" if name == "tvec" else ("a 5 x K matrix" if name == "ydata" else
                                                      f"a {rows} x {rows} matrix")
    return bounded_lines(
        text, rows + _CSV_SPARE_LINES,
        lambda n: (f"{name}: {f} has {n} lines, more than {shape} can have "
                   f"({rows} rows{' of times' if name == 'tvec' else ''})"),
        _CSV_FIELDS[name],
        lambda most: (too_many_steps(name, most) if name in ("ydata", "tvec") else
                      f"{name}: {f} has a line of {most} values; {shape} has {rows}"))


#: the shapes the four variables may have (None: any length up to MAX_STEPS)
_MAT_SHAPES = {"ydata": (N_MEAS, None), "Qtrue": (N_STATES, N_STATES), "Rtrue": (N_MEAS, N_MEAS)}


def _check_mat_header(name: str, shape: tuple, cls: str) -> None:
    """Refuse a ``.mat`` variable from its header (class, shape) before it is loaded."""
    if cls not in MAT_NUMERIC:
        raise ValueError(f"{name} must be a numeric matrix, got {MAT_KINDS.get(cls, cls)}")
    shape = tuple(int(n) for n in shape)
    if name == "tvec":
        if len(shape) > 2 or (len(shape) == 2 and min(shape) != 1):
            raise ValueError(f"tvec must be a 1 x K vector, got shape {shape}")
        if max(shape, default=1) > MAX_STEPS:
            raise ValueError(too_many_steps("tvec", max(shape)))
        return
    want = _MAT_SHAPES[name]
    if len(shape) != 2 or any(w is not None and w != n for w, n in zip(want, shape)):
        text = " x ".join("K" if w is None else str(w) for w in want)
        raise ValueError(f"{name} must be a {text} matrix, got shape {shape}")
    if name == "ydata" and shape[1] > MAX_STEPS:
        raise ValueError(too_many_steps("ydata", shape[1]))


def _read_mat(path: Path, argname: str) -> dict:
    data = _read_bytes(path, MAX_FILE_BYTES["mat"], argname, argname)
    mat_headers(data, path, argname, LOG_VARIABLES, _check_mat_header)
    return load_mat(data, path, argname, LOG_VARIABLES)


def load_log(path, argname: str = "path") -> CoopLog:
    """Load a course observation log from a CSV folder or a ``.mat`` file.

    Raises ValueError naming the path (as ``argname``, e.g. ``--log``), the file or the variable
    that is missing, unreadable, not a regular file, too large, not numeric, complex, or has the wrong
    shape or values (see the module's docstring for the limits).
    """
    if isinstance(path, bool) or not isinstance(path, (str, Path)) or str(path) == "":
        raise ValueError(f"{argname} must be a folder of CSVs or a .mat file path, got {path!r}")
    path = Path(path)
    try:
        is_dir, exists = path.is_dir(), path.exists()
    except OSError as exc:  # e.g. a name too long for the file system
        raise cannot_read(argname, path, exc) from None
    if is_dir:
        raw = {name: _read_csv(name, path / f"{name}.csv", argname) for name in LOG_VARIABLES}
        return _build(raw, str(path))
    if not exists:
        raise ValueError(f"{argname}: {path} does not exist (give a CSV folder or a .mat file)")
    if path.suffix.lower() != ".mat":
        raise ValueError(f"{argname}: {path} must be a folder of CSVs or a .mat file")
    return _build(_read_mat(path, argname), str(path))


def _course_arrays(log: CoopLog) -> dict:
    return {"ydata": log.y.T, "tvec": log.t[None, :], "Qtrue": log.Qtrue, "Rtrue": log.Rtrue}


def _check_log(log) -> None:
    require_instance("log", log, CoopLog)


def write_log_csv(log: CoopLog, folder) -> Path:
    """Write ``log`` as the four course CSV files into ``folder`` (created); returns the folder.
    ValueError naming ``folder`` if it is a file or cannot be created or written."""
    _check_log(log)
    if isinstance(folder, bool) or not isinstance(folder, (str, Path)) or str(folder) == "":
        raise ValueError(f"folder must be a directory path, got {folder!r}")
    folder = Path(folder)
    try:
        if folder.exists() and not folder.is_dir():
            raise ValueError(f"folder: {folder} is an existing file, not a directory")
        folder.mkdir(parents=True, exist_ok=True)
        for name, arr in _course_arrays(log).items():
            lines = [",".join("NaN" if np.isnan(v) else f"{v:.17g}" for v in row) for row in arr]
            (folder / f"{name}.csv").write_text("\n".join(lines) + "\n")
    except OSError as exc:
        raise ValueError(f"folder: cannot write into {folder}: {exc.strerror or exc}") from None
    return folder


def write_log_mat(log: CoopLog, file) -> Path:
    """Write ``log`` as a MATLAB ``.mat`` file with the course variable names; returns the path.
    ValueError naming ``file`` if its folder does not exist or it cannot be written."""
    _check_log(log)
    return write_mat(_course_arrays(log), file)
