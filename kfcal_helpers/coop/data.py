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

import io
import struct
import warnings
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..files import named, read_regular
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

#: the shortest step relative to the float spacing of the largest |t| (below it tvec cannot hold the step)
_MIN_STEP_SPACINGS = 1000
#: the step may deviate from the mean step by this share of it, plus 4 float spacings of the largest |t|
_STEP_RTOL = 1e-6


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
        if t.ndim != 1 or t.size < 2:
            raise ValueError(f"tvec must be a 1 x K vector with K >= 2, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            k = int(np.flatnonzero(~np.isfinite(t))[0])
            raise ValueError(f"tvec must hold only finite times, got {t[k]} at column {k}")
        if y.shape != (t.size, N_MEAS):
            raise ValueError(f"ydata must have shape (5, {t.size}) to match tvec, got {y.T.shape}")
        if t.size > MAX_STEPS:
            raise ValueError(too_many_steps("tvec", t.size))
        steps = np.diff(t)
        mean_step = (t[-1] - t[0]) / (t.size - 1)
        spacing = float(np.spacing(np.abs(t).max()))  # float rounding of the largest time
        if not np.all(steps > 0):
            raise ValueError("tvec must be increasing with a constant step")
        if mean_step < _MIN_STEP_SPACINGS * spacing:
            raise ValueError(f"tvec: the step {mean_step:.3g} s is too small for times near {np.abs(t).max():.6g} s "
                             f"(their float spacing is {spacing:.3g} s)")
        worst = float(np.abs(steps - mean_step).max())
        if worst > _STEP_RTOL * mean_step + 4 * spacing:
            raise ValueError(f"tvec must be increasing with a constant step (a step differs from the mean step "
                             f"{mean_step:.6g} s by {worst:.3g} s)")
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
    if ydata.shape[1] > MAX_STEPS:
        raise ValueError(too_many_steps("ydata", ydata.shape[1]))
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


def _cannot_read(argname: str, f: Path, exc: OSError) -> ValueError:
    return ValueError(f"{argname}: cannot read {f}: {exc.strerror or exc}")


def _read_bytes(f: Path, limit: int, argname: str, name: str) -> bytes:
    """The bytes of the regular file ``f`` (links resolved), at most ``limit`` of them: ValueError naming
    ``argname`` for a FIFO, device, socket or unreadable file, naming ``name`` for a file that is too large
    (:func:`kfcal_helpers.files.read_regular`)."""
    return read_regular(f, limit, argname=argname, regular_only="a log is read from regular files only",
                        too_large=f"{name}: {named(f)} is larger than the {limit / 1e6:.1f} MB a log of at most "
                                  f"{MAX_STEPS} steps needs (a longer log would not fit in memory)")


def _read_csv(name: str, f: Path, argname: str) -> np.ndarray:
    try:
        is_dir, exists = f.is_dir(), f.exists()
    except OSError as exc:
        raise _cannot_read(argname, f, exc) from None
    if is_dir:
        raise ValueError(f"{argname}: {f} is a directory, not a CSV file")
    if not exists and not f.is_symlink():
        raise ValueError(f"{argname}: {f} is missing (a log folder needs "
                         f"{', '.join(v + '.csv' for v in LOG_VARIABLES)})")
    data = _read_bytes(f, MAX_FILE_BYTES[name], argname, name)
    try:
        text = data.decode("utf-8", errors="strict")
    except UnicodeDecodeError:
        raise ValueError(f"{name}: {f} is not a numeric CSV (not text)") from None
    del data
    if text.startswith("\ufeff"):  # the byte-order mark a spreadsheet writes at the start of a UTF-8 file
        text = text[1:]
    if not text.strip():
        raise ValueError(f"{name}: {f} is empty")
    lines = _bounded_lines(name, f, text)
    del text
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return np.loadtxt(lines, delimiter=",", ndmin=2)
    except ValueError as exc:
        reason = " ".join(str(exc).split())
        reason = reason if len(reason) <= 200 else reason[:197] + "..."  # loadtxt quotes the whole bad value
        hint = ""
        if any(";" in line for line in lines[:10]):
            hint = "; it looks semicolon-separated: save it comma-separated, with '.' as the decimal point"
        raise ValueError(f"{name}: {f} is not a numeric CSV ({reason}){hint}") from None


#: the rows each CSV may hold (tvec: one row of K times, or one column of them), and the blank or comment
#: lines allowed beside them
_CSV_ROWS = {"ydata": N_MEAS, "tvec": MAX_STEPS, "Qtrue": N_STATES, "Rtrue": N_MEAS}
_CSV_SPARE_LINES = 100
#: the values one line may hold (one row of ydata or tvec holds at most MAX_STEPS)
_CSV_FIELDS = {"ydata": MAX_STEPS, "tvec": MAX_STEPS, "Qtrue": N_STATES, "Rtrue": N_MEAS}


def _bounded_lines(name: str, f: Path, text: str) -> list:
    """The lines of a CSV's ``text``, after counting its lines and each line's fields against the
    shape the variable may have, so that a file of millions of short lines (or one line of millions of
    values) is refused before it is split or parsed (a parsed value costs about 30 times its bytes)."""
    rows = _CSV_ROWS[name]
    if "\r" in text:  # CRLF (a spreadsheet's) or CR line ends
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    # only these end a line (str.splitlines would split on form feeds too); the last may lack its "\n"
    n_lines = text.count("\n") + (not text.endswith("\n"))
    shape = "a 1 x K vector" if name == "tvec" else ("a 5 x K matrix" if name == "ydata" else
                                                      f"a {rows} x {rows} matrix")
    if n_lines > rows + _CSV_SPARE_LINES:
        raise ValueError(f"{name}: {f} has {n_lines} lines, more than {shape} can have "
                         f"({rows} rows{' of times' if name == 'tvec' else ''})")
    lines = text.split("\n")
    most = max(line.count(",") + 1 for line in lines)
    if most > _CSV_FIELDS[name]:
        raise ValueError(too_many_steps(name, most) if name in ("ydata", "tvec") else
                         f"{name}: {f} has a line of {most} values; {shape} has {rows}")
    return lines


#: MATLAB classes (as scipy.io.whosmat names them) that hold numbers, and how the others are named
_MAT_NUMERIC = {"double", "single", "logical", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
                "uint64"}
_MAT_KINDS = {"char": "text", "struct": "a struct", "cell": "a cell array", "object": "an object",
              "sparse": "a sparse matrix", "function": "a function handle", "opaque": "an opaque object"}
#: the shapes the four variables may have (None: any length up to MAX_STEPS)
_MAT_SHAPES = {"ydata": (N_MEAS, None), "Qtrue": (N_STATES, N_STATES), "Rtrue": (N_MEAS, N_MEAS)}


def _check_mat_header(name: str, shape: tuple, cls: str) -> None:
    """Refuse a ``.mat`` variable from its header (class, shape) before it is loaded."""
    if cls not in _MAT_NUMERIC:
        raise ValueError(f"{name} must be a numeric matrix, got {_MAT_KINDS.get(cls, cls)}")
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


#: MATLAB class numbers of a v5 array's flags, by scipy.io.whosmat's names
_MAT5_CLASSES = {1: "cell", 2: "struct", 3: "object", 4: "char", 5: "sparse", 6: "double", 7: "single", 8: "int8",
                 9: "uint8", 10: "int16", 11: "uint16", 12: "int32", 13: "uint32", 14: "int64", 15: "uint64",
                 16: "function", 17: "opaque"}


def _mat5_headers(data: bytes) -> list | None:
    """``[(name, shape, class)]`` of a MATLAB v5 file's variables (as ``scipy.io.whosmat`` gives them), read
    from each variable's header only: of a compressed variable just the first 4 kB are inflated, so a small
    file that expands to gigabytes costs nothing.  None for a file that is not v5 (v4, v7.3).
    Raises ValueError (no argument name) for a damaged v5 file."""
    if len(data) < 128 or data[126:128] not in (b"IM", b"MI"):
        return None
    e = "<" if data[126:128] == b"IM" else ">"
    if struct.unpack_from(e + "H", data, 124)[0] != 0x0100:
        return None

    def element(buf, pos):  # (type, body, next position) of the data element at pos
        mtype, nbytes = struct.unpack_from(e + "II", buf, pos)
        if mtype >> 16:  # small element: the data sits in the tag's second word
            return mtype & 0xFFFF, buf[pos + 4:pos + 4 + (mtype >> 16)], pos + 8
        end = pos + 8 + nbytes
        return mtype, buf[pos + 8:end], end if mtype == 15 else end + (-nbytes) % 8

    out, pos = [], 128
    try:
        while pos + 8 <= len(data):
            mtype, body, pos = element(data, pos)
            if mtype == 15:  # miCOMPRESSED: inflate the matrix header only
                head = zlib.decompressobj().decompress(body, 4096)
                mtype, body, _ = element(head, 0)
            if mtype != 14:  # not miMATRIX (e.g. a subsystem block)
                continue
            _, flags, p = element(body, 0)
            _, dims, p = element(body, p)
            _, name, _ = element(body, p)
            word = struct.unpack_from(e + "I", flags, 0)[0]
            cls = "logical" if word & 0x200 else _MAT5_CLASSES.get(word & 0xFF, "unknown")
            shape = struct.unpack(e + f"{len(dims) // 4}i", dims[:len(dims) // 4 * 4])
            out.append((name.decode("latin1"), tuple(shape), cls))
    except (struct.error, zlib.error) as exc:
        raise ValueError(f"damaged MATLAB v5 file ({exc})") from None
    return out


def _read_mat(path: Path, argname: str) -> dict:
    from scipy.io import loadmat, whosmat

    data = _read_bytes(path, MAX_FILE_BYTES["mat"], argname, argname)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            headers = _mat5_headers(data)
            if headers is None:  # not v5: scipy reads the headers (v4 is not compressed; v7.3 is refused)
                headers = whosmat(io.BytesIO(data))
    except Exception as exc:  # scipy raises several types for files that are not MATLAB files
        reason = " ".join(str(exc).split())
        raise ValueError(f"{argname}: {path} is not a readable MATLAB file ({reason})") from None
    found = {name: (shape, cls) for name, shape, cls in headers}
    missing = [v for v in LOG_VARIABLES if v not in found]
    if missing:
        raise ValueError(f"{missing[0]}: variable missing from {path} (needs {', '.join(LOG_VARIABLES)})")
    for name in LOG_VARIABLES:
        _check_mat_header(name, *found[name])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mat = loadmat(io.BytesIO(data), variable_names=LOG_VARIABLES)
    except Exception as exc:
        reason = " ".join(str(exc).split())
        raise ValueError(f"{argname}: {path} is not a readable MATLAB file ({reason})") from None
    return {v: mat[v] for v in LOG_VARIABLES}


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
        raise _cannot_read(argname, path, exc) from None
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
    from scipy.io import savemat

    _check_log(log)
    if isinstance(file, bool) or not isinstance(file, (str, Path)) or str(file) == "":
        raise ValueError(f"file must be a file path, got {file!r}")
    file = Path(file)
    try:
        if not file.parent.is_dir():
            raise ValueError(f"file: the folder {file.parent} does not exist (create it first)")
        if file.is_dir():
            raise ValueError(f"file: {file} is a directory")
        savemat(file, _course_arrays(log))
    except OSError as exc:
        raise ValueError(f"file: cannot write {file}: {exc.strerror or exc}") from None
    return file
