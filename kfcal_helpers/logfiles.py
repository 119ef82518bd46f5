"""Pieces the course-log readers of the problems share: MATLAB headers read without loading, numeric
checks, the text of a CSV a spreadsheet saved, and the uniform time vector ``tvec``.

Used by :mod:`kfcal_helpers.coop.data` and :mod:`kfcal_helpers.orbit.data`; the files themselves are read
by :func:`kfcal_helpers.files.read_regular` (regular files only, a size cap checked before reading).
Every function raises ValueError with a one-line message naming the variable, file or argument.
"""

from __future__ import annotations

import io
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np

__all__ = ["MAT_NUMERIC", "MAT_KINDS", "mat5_headers", "mat_headers", "mat_inflated_bytes", "load_mat",
           "numeric", "cannot_read", "csv_text", "check_times", "require_csv_file", "bounded_lines", "parse_csv", "env_path", "write_mat"]

#: MATLAB classes (as scipy.io.whosmat names them) that hold numbers, and how the others are named
MAT_NUMERIC = {"double", "single", "logical", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
               "uint64"}
MAT_KINDS = {"char": "text", "struct": "a struct", "cell": "a cell array", "object": "an object",
             "sparse": "a sparse matrix", "function": "a function handle", "opaque": "an opaque object"}

#: MATLAB class numbers of a v5 array's flags, by scipy.io.whosmat's names
_MAT5_CLASSES = {1: "cell", 2: "struct", 3: "object", 4: "char", 5: "sparse", 6: "double", 7: "single", 8: "int8",
                 9: "uint8", 10: "int16", 11: "uint16", 12: "int32", 13: "uint32", 14: "int64", 15: "uint64",
                 16: "function", 17: "opaque"}


def _v5_order(data: bytes) -> str | None:
    """The byte order of a MATLAB v5 file ("<" or ">"), None for a file that is not v5 (v4, v7.3)."""
    if len(data) < 128 or data[126:128] not in (b"IM", b"MI"):
        return None
    e = "<" if data[126:128] == b"IM" else ">"
    return e if struct.unpack_from(e + "H", data, 124)[0] == 0x0100 else None


def _element(buf, pos, e):
    """(type, body, next position) of the v5 data element at ``pos``."""
    mtype, nbytes = struct.unpack_from(e + "II", buf, pos)
    if mtype >> 16:  # small element: the data sits in the tag's second word
        return mtype & 0xFFFF, buf[pos + 4:pos + 4 + (mtype >> 16)], pos + 8
    end = pos + 8 + nbytes
    return mtype, buf[pos + 8:end], end if mtype == 15 else end + (-nbytes) % 8


def mat5_headers(data: bytes) -> list | None:
    """``[(name, shape, class)]`` of a MATLAB v5 file's variables (as ``scipy.io.whosmat`` gives them), read
    from each variable's header only: of a compressed variable just the first 4 kB are inflated, so a small
    file that expands to gigabytes costs nothing.  None for a file that is not v5 (v4, v7.3).
    Raises ValueError (no argument name) for a damaged v5 file."""
    e = _v5_order(data)
    if e is None:
        return None
    out, pos = [], 128
    try:
        while pos + 8 <= len(data):
            mtype, body, pos = _element(data, pos, e)
            if mtype == 15:  # miCOMPRESSED: inflate the matrix header only
                head = zlib.decompressobj().decompress(body, 4096)
                mtype, body, _ = _element(head, 0, e)
            if mtype != 14:  # not miMATRIX (e.g. a subsystem block)
                continue
            _, flags, p = _element(body, 0, e)
            _, dims, p = _element(body, p, e)
            _, name, _ = _element(body, p, e)
            word = struct.unpack_from(e + "I", flags, 0)[0]
            cls = "logical" if word & 0x200 else _MAT5_CLASSES.get(word & 0xFF, "unknown")
            shape = struct.unpack(e + f"{len(dims) // 4}i", dims[:len(dims) // 4 * 4])
            out.append((name.decode("latin1"), tuple(shape), cls))
    except (struct.error, zlib.error) as exc:
        raise ValueError(f"damaged MATLAB v5 file ({exc})") from None
    return out


def mat_inflated_bytes(data: bytes, limit: int) -> int:
    """The size of a MATLAB v5 file's variables once their compressed elements are inflated, counted
    while inflating in pieces and stopping past ``limit`` (the returned number is then above ``limit``),
    so that a small file whose cell array expands to gigabytes is refused before ``loadmat`` sees it.
    The file's own size for a file that is not v5.  ValueError (no argument name) for a damaged file."""
    e = _v5_order(data)
    if e is None:
        return len(data)
    total, pos = 128, 128
    try:
        while pos + 8 <= len(data) and total <= limit:
            start = pos
            mtype, body, pos = _element(data, pos, e)
            if mtype != 15:
                total += pos - start
                continue
            inflate = zlib.decompressobj()
            rest = body
            while rest and total <= limit:
                total += len(inflate.decompress(rest, 1 << 20))
                rest = inflate.unconsumed_tail
    except (struct.error, zlib.error) as exc:
        raise ValueError(f"damaged MATLAB v5 file ({exc})") from None
    return total


def _unreadable(argname: str, path, exc: Exception) -> ValueError:
    reason = " ".join(str(exc).split())
    return ValueError(f"{argname}: {path} is not a readable MATLAB file ({reason})")


def mat_headers(data: bytes, path, argname: str, names=(), check=None) -> dict:
    """``{name: (shape, class)}`` of the variables of the MATLAB file ``data`` (v5 from the headers only,
    else scipy's ``whosmat``: v4 is not compressed, v7.3 is refused).  ValueError naming ``argname`` for a
    file that is not a MATLAB file, naming the first of the variables ``names`` that is missing, and
    whatever ``check(name, shape, class)`` raises for each of ``names``."""
    from scipy.io import whosmat

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            headers = mat5_headers(data)
            if headers is None:
                headers = whosmat(io.BytesIO(data))
    except Exception as exc:  # scipy raises several types for files that are not MATLAB files
        raise _unreadable(argname, path, exc) from None
    found = {name: (shape, cls) for name, shape, cls in headers}
    missing = [v for v in names if v not in found]
    if missing:
        raise ValueError(f"{missing[0]}: variable missing from {path} (needs {', '.join(names)})")
    for name in names:
        check(name, *found[name])
    return found


def load_mat(data: bytes, path, argname: str, names) -> dict:
    """The variables ``names`` of the MATLAB file ``data`` (``scipy.io.loadmat``, warnings silenced);
    ValueError naming ``argname`` for a file scipy cannot read."""
    from scipy.io import loadmat

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mat = loadmat(io.BytesIO(data), variable_names=tuple(names))
    except Exception as exc:
        raise _unreadable(argname, path, exc) from None
    return {v: mat[v] for v in names}


def numeric(name: str, value) -> np.ndarray:
    """``value`` as a real float array; ValueError naming ``name`` for text, structs, cells or complex."""
    arr = np.asarray(value)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name} must hold real numbers, got complex values")
    if arr.dtype.kind not in "biuf":
        kind = {"U": "text", "S": "text", "V": "a struct", "O": "a cell array or struct"}.get(arr.dtype.kind,
                                                                                               str(arr.dtype))
        raise ValueError(f"{name} must be a numeric matrix, got {kind}")
    return arr.astype(float)


def cannot_read(argname: str, f: Path, exc: OSError) -> ValueError:
    """``"ARGNAME: cannot read F: REASON"``."""
    return ValueError(f"{argname}: cannot read {f}: {exc.strerror or exc}")


def csv_text(name: str, f: Path, data: bytes) -> str:
    """The text of the CSV ``f`` holding variable ``name`` from its bytes: UTF-8, without the byte-order mark
    a spreadsheet writes, line ends made ``"\\n"`` (CRLF and CR too).  ValueError naming ``name`` for a file
    that is not text or is empty."""
    try:
        text = data.decode("utf-8", errors="strict")
    except UnicodeDecodeError:
        raise ValueError(f"{name}: {f} is not a numeric CSV (not text)") from None
    if text.startswith("\ufeff"):  # the byte-order mark a spreadsheet writes at the start of a UTF-8 file
        text = text[1:]
    if not text.strip():
        raise ValueError(f"{name}: {f} is empty")
    if "\r" in text:  # CRLF (a spreadsheet's) or CR line ends
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


#: the shortest step relative to the float spacing of the largest |t| (below it tvec cannot hold the step)
_MIN_STEP_SPACINGS = 1000
#: the step may deviate from the mean step by this share of it, plus 4 float spacings of the largest |t|
_STEP_RTOL = 1e-6


def check_times(t, too_many) -> np.ndarray:
    """``tvec`` as a float vector (K,), K >= 2, finite, increasing with a constant step up to the float
    rounding of its largest time (Unix-epoch seconds pass).  ``too_many(K)``: the message for a K above the
    caller's limit, or None when K is allowed.  ValueError naming ``tvec``."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"tvec must be a 1 x K vector with K >= 2, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        raise ValueError(f"tvec must hold only finite times, got {t[k]} at column {k}")
    message = too_many(t.size)
    if message:
        raise ValueError(message)
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
    return t


def require_csv_file(f: Path, argname: str, files) -> None:
    """Refuse the CSV ``f`` of a log folder if it is a directory or missing (``files``: the CSVs a log
    folder needs, for the message); ValueError naming ``argname``.  Its type and size are checked when it
    is read."""
    try:
        is_dir, exists = f.is_dir(), f.exists()
    except OSError as exc:
        raise cannot_read(argname, f, exc) from None
    if is_dir:
        raise ValueError(f"{argname}: {f} is a directory, not a CSV file")
    if not exists and not f.is_symlink():
        raise ValueError(f"{argname}: {f} is missing (a log folder needs {', '.join(files)})")


def bounded_lines(text: str, max_lines: int, lines_error, max_fields: int, fields_error) -> list:
    """The lines of a CSV's ``text`` (line ends ``"\\n"``, :func:`csv_text`), after counting them and each
    line's comma-separated fields, so that a file of millions of short lines (or one line of millions of
    values) is refused before it is split or parsed (a parsed value costs about 30 times its bytes):
    ValueError ``lines_error(n_lines)`` above ``max_lines``, ``fields_error(most)`` above ``max_fields``."""
    # only "\n" ends a line (str.splitlines would split on form feeds too); the last may lack its "\n"
    n_lines = text.count("\n") + (not text.endswith("\n"))
    if n_lines > max_lines:
        raise ValueError(lines_error(n_lines))
    lines = text.split("\n")
    most = max(line.count(",") + 1 for line in lines)
    if most > max_fields:
        raise ValueError(fields_error(most))
    return lines


def parse_csv(name: str, f: Path, lines: list) -> np.ndarray:
    """The numbers of a CSV's ``lines`` as a 2-D float array (``numpy.loadtxt``, comma-separated, ``#``
    comments).  ValueError naming ``name`` for a value that is not a number, with a hint for a
    semicolon-separated file."""
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


def env_path(variable: str) -> Path | None:
    """The path the environment variable ``variable`` names if it exists (``~`` expanded), else None."""
    import os

    value = os.environ.get(variable, "").strip()
    if not value:
        return None
    path = Path(value).expanduser()
    return path if path.exists() else None


def write_mat(arrays: dict, file) -> Path:
    """Write ``arrays`` (variable name -> array; an object array is a cell array) as a MATLAB ``.mat``
    file; returns the path.  ValueError naming ``file`` if it is not a path, its folder does not exist or
    it cannot be written."""
    from scipy.io import savemat

    if isinstance(file, bool) or not isinstance(file, (str, Path)) or str(file) == "":
        raise ValueError(f"file must be a file path, got {file!r}")
    file = Path(file)
    try:
        if not file.parent.is_dir():
            raise ValueError(f"file: the folder {file.parent} does not exist (create it first)")
        if file.is_dir():
            raise ValueError(f"file: {file} is a directory")
        savemat(file, arrays)
    except OSError as exc:
        raise ValueError(f"file: cannot write {file}: {exc.strerror or exc}") from None
    return file
