"""Observation logs in the course format: a folder of CSVs or a MATLAB ``.mat`` file.

Course format (variables / files):

* ``ydata`` -- 5 x K measurements, one column per time (rad, m, rad, m, m); the first
  column (t = 0) is NaN, and any all-NaN column means "no measurement at that step";
* ``tvec`` -- 1 x K times, s, uniformly spaced;
* ``Qtrue`` -- 6 x 6 per-step process-noise covariance; ``Rtrue`` -- 5 x 5 measurement noise.

As CSV: ``ydata.csv``, ``tvec.csv``, ``Qtrue.csv``, ``Rtrue.csv`` in one folder.
Inside the package a log is a :class:`CoopLog` with one *row* per time.
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..validation import require_covariance, require_instance, require_int
from .model import N_MEAS, N_STATES, CoopParams

__all__ = ["LOG_VARIABLES", "CoopLog", "load_log", "write_log_csv", "write_log_mat"]

LOG_VARIABLES = ("ydata", "tvec", "Qtrue", "Rtrue")


@dataclass(frozen=True, eq=False)
class CoopLog:
    """An observation log.

    Attributes
    ----------
    t : array (K,), s
    y : array (K, 5) -- measurements, rows of NaN where there is none (row 0 in the course log)
    Qtrue : array (6, 6); Rtrue : array (5, 5)
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
        t = np.asarray(self.t, dtype=float)
        y = np.asarray(self.y, dtype=float)
        if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)):
            raise ValueError(f"tvec must be a finite 1 x K vector with K >= 2, got shape {t.shape}")
        if y.shape != (t.size, N_MEAS):
            raise ValueError(f"ydata must have shape (5, {t.size}) to match tvec, got {y.T.shape}")
        steps = np.diff(t)
        if steps[0] <= 0 or not np.allclose(steps, steps[0], rtol=1e-6, atol=0):
            raise ValueError("tvec must be increasing with a constant step")
        bad = np.isnan(y).any(axis=1) & ~np.isnan(y).all(axis=1)
        if bad.any() or np.isinf(y).any():
            raise ValueError(f"ydata columns must be all finite or all NaN; column {int(np.flatnonzero(bad | np.isinf(y).any(axis=1))[0])} is not")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "Qtrue", require_covariance("Qtrue", self.Qtrue, N_STATES))
        object.__setattr__(self, "Rtrue", require_covariance("Rtrue", self.Rtrue, N_MEAS))
        if self.truth is not None:
            truth = np.asarray(self.truth, dtype=float)
            if truth.shape != (t.size, N_STATES):
                raise ValueError(f"truth must have shape ({t.size}, 6), got {truth.shape}")
            object.__setattr__(self, "truth", truth)

    @property
    def dt(self) -> float:
        """Sampling interval, s."""
        return float(self.t[1] - self.t[0])

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
        y = np.full_like(self.y, np.nan)
        y[::m] = self.y[::m]
        return CoopLog(self.t, y, self.Qtrue, self.Rtrue, self.truth, f"{self.source} (every {m})")


#: largest magnitude accepted in a loaded ydata (m, rad): beyond it the filters' squares overflow
MAX_MEASUREMENT = 1e6


def _numeric(name, value) -> np.ndarray:
    """``value`` as a real float array; ValueError naming ``name`` for text, structs, cells or complex."""
    arr = np.asarray(value)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name} must hold real numbers, got complex values")
    if arr.dtype.kind not in "biuf":
        kind = {"U": "text", "S": "text", "V": "a struct", "O": "a cell array or struct"}.get(arr.dtype.kind,
                                                                                               str(arr.dtype))
        raise ValueError(f"{name} must be a numeric matrix, got {kind}")
    return arr.astype(float)


def _matrix(name, value, shape) -> np.ndarray:
    arr = np.atleast_2d(_numeric(name, value))
    if arr.ndim != 2 or any(s is not None and s != n for s, n in zip(shape, arr.shape)):
        want = " x ".join("K" if s is None else str(s) for s in shape)
        raise ValueError(f"{name} must be a {want} matrix, got shape {arr.shape}")
    return arr


def _build(raw: dict, source: str) -> CoopLog:
    ydata = _matrix("ydata", raw["ydata"], (N_MEAS, None))
    tvec = _numeric("tvec", raw["tvec"])
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


def _read_csv(name: str, f: Path, argname: str) -> np.ndarray:
    if f.is_dir():
        raise ValueError(f"{argname}: {f} is a directory, not a CSV file")
    if not f.exists():
        raise ValueError(f"{argname}: {f} is missing (a log folder needs "
                         f"{', '.join(v + '.csv' for v in LOG_VARIABLES)})")
    try:
        with open(f, encoding="utf-8", errors="strict") as fh:
            text = fh.read()
    except OSError as exc:
        raise ValueError(f"{argname}: cannot read {f}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{name}: {f} is not a numeric CSV (not text)") from None
    if not text.strip():
        raise ValueError(f"{name}: {f} is empty")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return np.loadtxt(io.StringIO(text), delimiter=",", ndmin=2)
    except ValueError as exc:
        reason = " ".join(str(exc).split())
        raise ValueError(f"{name}: {f} is not a numeric CSV ({reason})") from None


def load_log(path, argname: str = "path") -> CoopLog:
    """Load a course observation log from a CSV folder or a ``.mat`` file.

    Raises ValueError naming the path (as ``argname``, e.g. ``--log``), the file or the variable
    that is missing, unreadable, not numeric, complex, or has the wrong shape or values.
    """
    if isinstance(path, bool) or not isinstance(path, (str, Path)) or str(path) == "":
        raise ValueError(f"{argname} must be a folder of CSVs or a .mat file path, got {path!r}")
    path = Path(path)
    if path.is_dir():
        raw = {name: _read_csv(name, path / f"{name}.csv", argname) for name in LOG_VARIABLES}
        return _build(raw, str(path))
    if not path.exists():
        raise ValueError(f"{argname}: {path} does not exist (give a CSV folder or a .mat file)")
    if path.suffix.lower() != ".mat":
        raise ValueError(f"{argname}: {path} must be a folder of CSVs or a .mat file")
    from scipy.io import loadmat

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mat = loadmat(path)
    except OSError as exc:
        raise ValueError(f"{argname}: cannot read {path}: {exc.strerror or exc}") from None
    except Exception as exc:  # scipy raises several types for files that are not MATLAB files
        reason = " ".join(str(exc).split())
        raise ValueError(f"{argname}: {path} is not a readable MATLAB file ({reason})") from None
    missing = [v for v in LOG_VARIABLES if v not in mat]
    if missing:
        raise ValueError(f"{missing[0]}: variable missing from {path} (needs {', '.join(LOG_VARIABLES)})")
    return _build({v: mat[v] for v in LOG_VARIABLES}, str(path))


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
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"folder: {folder} is an existing file, not a directory")
    try:
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
    from scipy.io import savemat

    _check_log(log)
    if isinstance(file, bool) or not isinstance(file, (str, Path)) or str(file) == "":
        raise ValueError(f"file must be a file path, got {file!r}")
    file = Path(file)
    if not file.parent.is_dir():
        raise ValueError(f"file: the folder {file.parent} does not exist (create it first)")
    if file.is_dir():
        raise ValueError(f"file: {file} is a directory")
    try:
        savemat(file, _course_arrays(log))
    except OSError as exc:
        raise ValueError(f"file: cannot write {file}: {exc.strerror or exc}") from None
    return file
