"""Orbit observation logs: the course's MATLAB file, a CSV folder, and the seeded generated stand-in.

The course's log is never shipped: set the environment variable ``KFCAL_ORBIT_LOG`` to it
(:func:`course_log`); without it a seeded generated log in the same format is used, and says so.

Course format (a ``.mat`` file, e.g. ``orbitdeterm_finalproj_KFdata.mat``):

* ``tvec`` -- 1 x K times, s, uniformly spaced from 0 (the stations' angles and the nominal orbit are
  measured from t = 0);
* ``ydata`` -- a 1 x K cell array: per step a 4 x m_k block, one column ``[rho; rhodot; phi; station id]``
  (km, km/s, rad, an integer 1..12) per station that sees the satellite, empty where none;
* ``Qtrue`` -- 2 x 2 covariance of the acceleration noise w_k, (km/s^2)^2; ``Rtrue`` -- 3 x 3 covariance
  of one station's measurement noise, [km^2, (km/s)^2, rad^2];
* other variables (``measLabels``) are ignored.

CSV folder (this package's form of the same log): ``tvec.csv`` (the K times, one row or one column),
``ydata.csv`` (one row per station measurement: ``t, station_id, rho, rhodot, phi``, in any order, an
optional header line with these names, each ``t`` one of ``tvec``'s times), ``Qtrue.csv`` (2 x 2),
``Rtrue.csv`` (3 x 3).  A step without a row has no measurement.

What the reader accepts (anything else is a ValueError naming the path, file or variable, in one line):

* regular files only, after resolving links (no FIFO, device such as ``/dev/zero``, or socket), no larger
  than a log of :data:`MAX_STEPS` steps and :data:`MAX_COLUMNS` station measurements needs
  (:data:`MAX_FILE_BYTES`), checked before reading; a CSV's lines and each line's values are counted
  before it is parsed; in a ``.mat`` the class and shape of the variables are read from their headers and
  its compressed variables are inflated (counting) up to the same bound before it is loaded;
* finite numbers only; station ids distinct integers 1..n_stations per step; ``rho`` in (0, 1e6] km,
  ``|rhodot|`` at most 1e6 km/s, ``phi`` in [-2 pi, 2 pi] (stored wrapped to (-pi, pi]).

A log is an :class:`~kfcal_helpers.orbit.simulation.OrbitLog` (``t``, ``ydata``, ``Qtrue``, ``Rtrue``,
``n_stations``, ``truth``, ``source``; its ``y`` is the dense (K, n_stations, 3) form the filters take);
:func:`log_params` gives the :class:`OrbitParams` of a log.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from ..angles import wrap_angle
from ..files import named, read_regular
from ..logfiles import (MAT_KINDS, MAT_NUMERIC, bounded_lines, cannot_read, check_times, csv_text, env_path, load_mat,
                        mat_headers, mat_inflated_bytes, numeric, parse_csv, require_csv_file, write_mat)
from ..validation import checked, optional, require_covariance, require_instance, require_int, require_seed
from .params import MAX_STATIONS, MAX_STEPS, N_NOISE, N_STATION_MEAS, OrbitParams
from .simulation import DEFAULT_LOG_SEED, OrbitLog, simulate

__all__ = ["LOG_VARIABLES", "CSV_COLUMNS", "MAX_COLUMNS", "MAX_FILE_BYTES", "MAX_MEASUREMENT", "MAX_STEPS",
           "MAX_VARIANCE", "COURSE_LOG_VARIABLE", "load_log", "write_log_csv", "write_log_mat", "log_params", "course_log_path",
           "course_log", "write_generated_log"]

#: the variables of a log (the course's ``.mat`` names; the CSV folder's file stems)
LOG_VARIABLES = ("tvec", "ydata", "Qtrue", "Rtrue")
#: the columns of ``ydata.csv``, one row per station measurement
CSV_COLUMNS = ("t", "station_id", "rho", "rhodot", "phi")
#: most station measurements (columns of ``ydata``) a log may hold: two per step on average (at the course's
#: 300 km altitude no more than two of the 12 stations see the satellite at once)
MAX_COLUMNS = 2 * MAX_STEPS
#: largest |rho| (km) and |rhodot| (km/s) accepted
MAX_MEASUREMENT = 1e6
#: largest variance in Qtrue or Rtrue
MAX_VARIANCE = 1e12
#: the environment variable naming the course's log
COURSE_LOG_VARIABLE = "KFCAL_ORBIT_LOG"

#: bytes one number may take in a CSV (``-1.2345678901234567e-100,`` is 25; room for spaces)
_CSV_BYTES_PER_VALUE = 32
#: bytes of a .mat cell element besides its numbers (tag, flags, dimensions, name, data tag), rounded up
_MAT_BYTES_PER_CELL = 64
#: the largest file accepted, bytes (and, for a .mat, the largest size its variables may inflate to):
#: the CSVs, or twice the raw size of the variables of a log of MAX_STEPS steps and MAX_COLUMNS columns
MAX_FILE_BYTES = {
    "tvec": MAX_STEPS * _CSV_BYTES_PER_VALUE + 65536,
    "ydata": MAX_COLUMNS * len(CSV_COLUMNS) * _CSV_BYTES_PER_VALUE + 65536,
    "Qtrue": 65536,
    "Rtrue": 65536,
    "mat": 2 * ((_MAT_BYTES_PER_CELL + 8) * MAX_STEPS + 4 * 8 * MAX_COLUMNS) + 65536,
}
_CSV_SPARE_LINES = 100  #: blank or comment lines allowed beside a CSV's rows


def _too_many(name: str, n: int, what: str = "steps", most: int = MAX_STEPS) -> str:
    return (f"{name}: the log has {n} {what}, more than the {most} a log may have "
            f"(one filter run of it must fit in memory)")


def _read_bytes(f: Path, limit: int, argname: str, name: str) -> bytes:
    return read_regular(f, limit, argname=argname, regular_only="a log is read from regular files only",
                        too_large=f"{name}: {named(f)} is larger than the {limit / 1e6:.1f} MB a log of at most "
                                  f"{MAX_STEPS} steps needs (a longer log would not fit in memory)")


# ---------------------------------------------------------------------------------------------------------
# checking the numbers (both forms)
def _matrix(name: str, value, n: int) -> np.ndarray:
    arr = np.atleast_2d(numeric(name, value))
    if arr.shape != (n, n):
        raise ValueError(f"{name} must be a {n} x {n} matrix, got shape {arr.shape}")
    return require_covariance(name, arr, n, MAX_VARIANCE)


def _times(value) -> np.ndarray:
    t = numeric("tvec", value)
    if t.ndim > 2 or (t.ndim == 2 and min(t.shape) != 1):
        raise ValueError(f"tvec must be a 1 x K vector, got shape {t.shape}")
    t = check_times(t.ravel(), lambda k: _too_many("tvec", k) if k > MAX_STEPS else None)
    dt = (t[-1] - t[0]) / (t.size - 1)
    if abs(t[0]) > 1e-6 * dt:
        raise ValueError(f"tvec must start at 0 s (the stations' angles and the nominal orbit are measured from "
                         f"t = 0), got {t[0]:.6g} s")
    return t


def _block(k: int, cols: np.ndarray, n_stations: int) -> np.ndarray:
    """Step k's block (4, m) checked, phi wrapped."""
    where = f"ydata{{{k + 1}}}"  # MATLAB's name of the cell, 1-based
    if not np.isfinite(cols).all():
        raise ValueError(f"{where} must hold finite numbers, got NaN or inf")
    ids = cols[3]
    if np.any(ids != np.round(ids)) or np.any(ids < 1) or np.any(ids > n_stations) or np.unique(ids).size != ids.size:
        shown = ", ".join(f"{v:g}" for v in ids[:6]) + (", ..." if ids.size > 6 else "")
        raise ValueError(f"{where}: station ids must be distinct integers 1..{n_stations}, got {shown}")
    rho, rhodot, phi = cols[0], cols[1], cols[2]
    if np.any(rho <= 0) or np.any(rho > MAX_MEASUREMENT):
        raise ValueError(f"{where}: rho must be a range in (0, {MAX_MEASUREMENT:g}] km, got {rho[(rho <= 0) | (rho > MAX_MEASUREMENT)][0]:.6g}")
    if np.any(np.abs(rhodot) > MAX_MEASUREMENT):
        raise ValueError(f"{where}: rhodot must be at most {MAX_MEASUREMENT:g} km/s in magnitude, "
                         f"got {rhodot[np.abs(rhodot) > MAX_MEASUREMENT][0]:.3g}")
    if np.any(np.abs(phi) > 2 * math.pi + 1e-9):
        raise ValueError(f"{where}: phi must be an angle in [-2 pi, 2 pi] rad, got {phi[np.abs(phi) > 2 * math.pi + 1e-9][0]:.6g}")
    out = cols[:, np.argsort(ids, kind="stable")]
    out[2] = wrap_angle(out[2])
    return out


def _build(t, blocks, Qtrue, Rtrue, n_stations: int, source: str) -> OrbitLog:
    if len(blocks) != t.size:
        raise ValueError(f"ydata must have one block per time of tvec ({t.size}), got {len(blocks)}")
    total = sum(b.shape[1] for b in blocks)
    if total == 0:
        raise ValueError("ydata holds no measurement (every step is empty)")
    if total > MAX_COLUMNS:
        raise ValueError(_too_many("ydata", total, "station measurements", MAX_COLUMNS))
    checked_blocks = tuple(_block(k, b, n_stations) if b.shape[1] else np.empty((4, 0)) for k, b in enumerate(blocks))
    return OrbitLog(t, checked_blocks, _matrix("Qtrue", Qtrue, N_NOISE), _matrix("Rtrue", Rtrue, N_STATION_MEAS),
                    n_stations, None, source)


# ---------------------------------------------------------------------------------------------------------
# the .mat form
def _check_mat_header(name: str, shape: tuple, cls: str) -> None:
    """Refuse a ``.mat`` variable from its header (class, shape) before anything is loaded."""
    shape = tuple(int(n) for n in shape)
    if name == "ydata":
        if cls != "cell":
            raise ValueError(f"ydata must be a cell array of K blocks 4 x m (one column [rho; rhodot; phi; station "
                             f"id] per station), got {MAT_KINDS.get(cls, 'a numeric matrix')}")
    elif cls not in MAT_NUMERIC:
        raise ValueError(f"{name} must be a numeric matrix, got {MAT_KINDS.get(cls, cls)}")
    if name in ("tvec", "ydata"):
        if len(shape) > 2 or (len(shape) == 2 and min(shape) != 1):
            raise ValueError(f"{name} must be 1 x K, got shape {shape}")
        if max(shape, default=1) > MAX_STEPS:
            raise ValueError(_too_many(name, max(shape)))
        return
    n = N_NOISE if name == "Qtrue" else N_STATION_MEAS
    if shape != (n, n):
        raise ValueError(f"{name} must be a {n} x {n} matrix, got shape {shape}")


def _mat_blocks(cells) -> list:
    """The K blocks (4, m) of a loaded cell array (an object array)."""
    out = []
    for k, cell in enumerate(np.asarray(cells, dtype=object).ravel()):
        arr = numeric(f"ydata{{{k + 1}}}", cell)
        if arr.size == 0:
            out.append(np.empty((4, 0)))
            continue
        if arr.ndim != 2 or arr.shape[0] != 4:
            raise ValueError(f"ydata{{{k + 1}}} must be a 4 x m block (one column [rho; rhodot; phi; station id] per "
                             f"station), got shape {arr.shape}")
        out.append(arr)
    return out


def _read_mat(path: Path, argname: str, n_stations: int) -> OrbitLog:
    limit = MAX_FILE_BYTES["mat"]
    data = _read_bytes(path, limit, argname, argname)
    mat_headers(data, path, argname, LOG_VARIABLES, _check_mat_header)
    try:
        inflated = mat_inflated_bytes(data, limit)
    except ValueError as exc:
        raise ValueError(f"{argname}: {path} is not a readable MATLAB file ({exc})") from None
    if inflated > limit:
        raise ValueError(f"{argname}: {named(path)} expands to more than the {limit / 1e6:.1f} MB a log of at most "
                         f"{MAX_STEPS} steps needs (a longer log would not fit in memory)")
    raw = load_mat(data, path, argname, LOG_VARIABLES)
    del data
    t = _times(raw["tvec"])
    return _build(t, _mat_blocks(raw["ydata"]), raw["Qtrue"], raw["Rtrue"], n_stations, str(path))


# ---------------------------------------------------------------------------------------------------------
# the CSV folder
#: rows each CSV may hold and values per line
_CSV_ROWS = {"tvec": MAX_STEPS, "ydata": MAX_COLUMNS + 1, "Qtrue": N_NOISE, "Rtrue": N_STATION_MEAS}
_CSV_FIELDS = {"tvec": MAX_STEPS, "ydata": len(CSV_COLUMNS), "Qtrue": N_NOISE, "Rtrue": N_STATION_MEAS}
_CSV_SHAPES = {"tvec": "a 1 x K vector", "ydata": "one row per station measurement (t, station_id, rho, rhodot, phi)",
               "Qtrue": "a 2 x 2 matrix", "Rtrue": "a 3 x 3 matrix"}


def _read_csv(name: str, f: Path, argname: str) -> np.ndarray:
    require_csv_file(f, argname, [v + ".csv" for v in LOG_VARIABLES])
    text = csv_text(name, f, _read_bytes(f, MAX_FILE_BYTES[name], argname, name))
    lines = bounded_lines(
        text, _CSV_ROWS[name] + _CSV_SPARE_LINES,
        lambda n: f"{name}: {f} has {n} lines, more than {_CSV_SHAPES[name]} can have",
        _CSV_FIELDS[name],
        lambda most: (_too_many(name, most) if name == "tvec" else
                      f"{name}: {f} has a line of {most} values; {_CSV_SHAPES[name]} has {_CSV_FIELDS[name]}"))
    del text
    if name == "ydata":
        first = next((i for i, line in enumerate(lines) if line.strip()), None)
        names = [] if first is None else [c.strip().lower() for c in lines[first].split(",")]
        if names and names[0] == CSV_COLUMNS[0]:  # a header line
            if names != list(CSV_COLUMNS):
                raise ValueError(f"ydata: {f} must have the {len(CSV_COLUMNS)} columns {', '.join(CSV_COLUMNS)}, "
                                 f"got the header {', '.join(names)}")
            lines[first] = ""
        if not any(line.strip() and not line.lstrip().startswith("#") for line in lines):
            return np.empty((0, len(CSV_COLUMNS)))
    return parse_csv(name, f, lines)


def _csv_blocks(rows: np.ndarray, t: np.ndarray, f: Path) -> list:
    """The K blocks (4, m) from the rows ``t, station_id, rho, rhodot, phi`` of ``ydata.csv``."""
    if rows.size and rows.shape[1] != len(CSV_COLUMNS):
        raise ValueError(f"ydata: {f} must have the {len(CSV_COLUMNS)} columns {', '.join(CSV_COLUMNS)}, "
                         f"got {rows.shape[1]}")
    if not np.isfinite(rows).all():
        i = int(np.flatnonzero(~np.isfinite(rows).all(axis=1))[0])
        raise ValueError(f"ydata: {f} must hold finite numbers, got NaN or inf in row {i + 1}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    k = np.rint((rows[:, 0] - t[0]) / dt) if rows.size else np.empty(0)
    bad = (k < 0) | (k > t.size - 1)
    bad[~bad] |= np.abs(rows[~bad, 0] - t[k[~bad].astype(int)]) > 1e-6 * dt
    if bad.any():
        raise ValueError(f"ydata: {f} row {int(np.flatnonzero(bad)[0]) + 1}: t = {rows[bad][0, 0]:.6g} s is not one "
                         f"of tvec's times")
    k = k.astype(int)
    order = np.argsort(k, kind="stable")
    cuts = np.searchsorted(k[order], np.arange(t.size + 1))
    cols = rows[order][:, [2, 3, 4, 1]].T
    return [cols[:, cuts[j]:cuts[j + 1]] for j in range(t.size)]


# ---------------------------------------------------------------------------------------------------------
def load_log(path, argname: str = "path", n_stations: int = 12) -> OrbitLog:
    """Load an orbit observation log from the course's ``.mat`` file or a CSV folder (module docstring).

    path : str or Path; argname : how messages name it (e.g. ``--log``); n_stations : stations of the
    problem (ids 1..n_stations, default 12).  Returns an :class:`OrbitLog` (``t`` (K,) s; ``ydata`` K blocks
    (4, m_k) ``[rho; rhodot; phi; station id]`` in km, km/s, rad (wrapped to (-pi, pi]), ids increasing;
    ``Qtrue`` (2, 2) (km/s^2)^2; ``Rtrue`` (3, 3) [km^2, (km/s)^2, rad^2]; ``truth`` None; ``source`` the path).
    Raises ValueError in one line naming the path (as ``argname``), the file or the variable.
    """
    n_stations = require_int("n_stations", n_stations, minimum=1)
    if n_stations > MAX_STATIONS:
        raise ValueError(f"n_stations must be an integer in 1..{MAX_STATIONS}, got {n_stations}")
    if isinstance(path, bool) or not isinstance(path, (str, Path)) or str(path) == "":
        raise ValueError(f"{argname} must be a .mat file or a folder of CSVs path, got {path!r}")
    path = Path(path)
    try:
        is_dir, exists = path.is_dir(), path.exists()
    except (OSError, ValueError) as exc:  # a name too long for the file system, a NUL byte
        raise cannot_read(argname, path, exc if isinstance(exc, OSError) else OSError(str(exc))) from None
    if is_dir:
        raw = {name: _read_csv(name, path / f"{name}.csv", argname) for name in LOG_VARIABLES}
        t = _times(raw["tvec"])
        return _build(t, _csv_blocks(raw["ydata"], t, path / "ydata.csv"), raw["Qtrue"], raw["Rtrue"], n_stations,
                      str(path))
    if not exists:
        raise ValueError(f"{argname}: {path} does not exist (give a .mat file or a CSV folder)")
    if path.suffix.lower() != ".mat":
        raise ValueError(f"{argname}: {path} must be a .mat file or a folder of CSVs")
    return _read_mat(path, argname, n_stations)


def log_params(log: OrbitLog, base: OrbitParams | None = None) -> OrbitParams:
    """``base`` (default: the course's) with the log's ``dt``, steps, ``Qtrue``, ``Rtrue`` and stations."""
    log = require_instance("log", log, OrbitLog)
    base = require_instance("base", base, OrbitParams, allow_none=True) or OrbitParams()
    t = np.asarray(log.t, dtype=float)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    return replace(base, dt=dt, n_steps=t.size - 1, Qtrue=log.Qtrue, Rtrue=log.Rtrue, n_stations=log.n_stations)


def _check_log(log) -> OrbitLog:
    return require_instance("log", log, OrbitLog)


def _course_arrays(log: OrbitLog) -> dict:
    cells = np.empty((1, len(log.ydata)), dtype=object)
    for k, block in enumerate(log.ydata):
        cells[0, k] = np.asarray(block, dtype=float).reshape(4, -1)
    return {"tvec": np.asarray(log.t, dtype=float)[None, :], "ydata": cells, "Qtrue": log.Qtrue, "Rtrue": log.Rtrue,
            "measLabels": np.array(["rho (km)", "rhodot (km/s)", "phi (rad)", "station id"], dtype=object)}


def write_log_mat(log: OrbitLog, file) -> Path:
    """Write ``log`` as a MATLAB ``.mat`` file in the course's format (``ydata`` a 1 x K cell array);
    returns the path.  ValueError naming ``file`` if its folder does not exist or it cannot be written."""
    _check_log(log)
    return write_mat(_course_arrays(log), file)


def write_log_csv(log: OrbitLog, folder) -> Path:
    """Write ``log`` as the CSV folder (``tvec.csv``, ``ydata.csv`` with a header line, ``Qtrue.csv``,
    ``Rtrue.csv``; created); returns the folder.  ValueError naming ``folder`` if it is a file or cannot be
    created or written."""
    _check_log(log)
    if isinstance(folder, bool) or not isinstance(folder, (str, Path)) or str(folder) == "":
        raise ValueError(f"folder must be a directory path, got {folder!r}")
    folder = Path(folder)
    num = "{:.17g}".format
    rows = [",".join(CSV_COLUMNS)]
    for tk, block in zip(log.t, log.ydata):
        for rho, rhodot, phi, station in np.asarray(block, dtype=float).reshape(4, -1).T:
            rows.append(f"{num(tk)},{int(station)},{num(rho)},{num(rhodot)},{num(phi)}")
    texts = {"tvec": ",".join(num(v) for v in log.t), "ydata": "\n".join(rows),
             "Qtrue": "\n".join(",".join(num(v) for v in r) for r in log.Qtrue),
             "Rtrue": "\n".join(",".join(num(v) for v in r) for r in log.Rtrue)}
    try:
        if folder.exists() and not folder.is_dir():
            raise ValueError(f"folder: {folder} is an existing file, not a directory")
        folder.mkdir(parents=True, exist_ok=True)
        for name, text in texts.items():
            (folder / f"{name}.csv").write_text(text + "\n")
    except OSError as exc:
        raise ValueError(f"folder: cannot write into {folder}: {exc.strerror or exc}") from None
    return folder


def course_log_path() -> Path | None:
    """The path named by ``KFCAL_ORBIT_LOG`` if it exists, else None."""
    return env_path(COURSE_LOG_VARIABLE)


@checked(params=optional(partial(require_instance, cls=OrbitParams)), seed=partial(require_seed, allow_none=False))
def course_log(params: OrbitParams | None = None, seed: int = DEFAULT_LOG_SEED) -> tuple[OrbitLog, bool, str]:
    """``(log, found, message)``: the course's log named by ``KFCAL_ORBIT_LOG`` (``found`` True), or the
    seeded generated log of ``params``' truth model (``found`` False, with its truth); ``message`` is one
    line saying which.  ValueError if the variable names a file that is not a valid log."""
    path = course_log_path()
    if path is not None:
        return load_log(path, argname=COURSE_LOG_VARIABLE), True, f"course log found ({COURSE_LOG_VARIABLE}): {path}"
    why = "is not set" if not os.environ.get(COURSE_LOG_VARIABLE, "").strip() else "names no existing path"
    log = simulate(params, seed=seed).log()
    return log, False, (f"no course log ({COURSE_LOG_VARIABLE} {why}): using a generated log "
                        f"(seed {seed}, same noise model) instead")



@checked(params=optional(partial(require_instance, cls=OrbitParams)), seed=partial(require_seed, allow_none=False))
def write_generated_log(path, seed: int = DEFAULT_LOG_SEED, params: OrbitParams | None = None) -> Path:
    """Write the seeded generated log (``simulate(params, seed=seed).log()``, the stand-in :func:`course_log`
    uses) in the course's format: a ``.mat`` file when ``path`` ends in ``.mat``, else a CSV folder.
    Returns the path; ValueError naming ``file`` or ``folder`` if it cannot be written."""
    log = simulate(params, seed=seed).log()
    if isinstance(path, (str, Path)) and not isinstance(path, bool) and Path(path).suffix.lower() == ".mat":
        return write_log_mat(log, path)
    return write_log_csv(log, path)
