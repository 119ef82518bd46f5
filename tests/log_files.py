"""Hostile and unusual course logs for the reader's tests: FIFOs, links to devices, sockets, sparse files,
compressed-.mat bombs, logs longer than the memory estimate allows and Unix-epoch timestamps.

Every builder skips the calling test (``pytest.skip``) where the OS lacks what it needs (FIFOs and
Unix sockets on Windows, symbolic links without the privilege, /dev/zero)."""

from __future__ import annotations

import functools
import io
import os
import socket
import struct
import threading
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from kfcal_helpers.coop import CoopParams, simulate, write_log_csv
from kfcal_helpers.coop.model import MAX_STEPS


def log_folder(root: Path, duration: float = 1.0) -> Path:
    """A small valid CSV log folder ``root/log``."""
    folder = root / "log"
    write_log_csv(simulate(CoopParams(duration=duration), seed=1).log(), folder)
    return folder


def _unblock_later(path: Path, seconds: float = 5.0) -> None:
    """Guard for a reader that (wrongly) opens a FIFO: after ``seconds`` open its write end and close it,
    so that the reader sees end-of-file and the test fails instead of hanging.  Gives up after 20 s."""
    def run():
        time.sleep(seconds)
        end = time.monotonic() + 20
        while time.monotonic() < end:
            try:
                os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))  # ENXIO while nobody reads
                return
            except OSError:
                time.sleep(0.2)

    threading.Thread(target=run, daemon=True).start()


def fifo(path: Path) -> Path:
    """A named pipe at ``path`` (skip without FIFOs)."""
    if not hasattr(os, "mkfifo"):
        pytest.skip("this OS has no FIFOs (named pipes)")
    os.mkfifo(path)
    _unblock_later(path)
    return path


def link(target, path: Path) -> Path:
    """A symbolic link ``path`` -> ``target`` (skip without symbolic links or without the target)."""
    if not Path(target).exists():
        pytest.skip(f"{target} does not exist on this OS")
    try:
        os.symlink(target, path)
    except (OSError, NotImplementedError) as exc:
        pytest.skip(f"cannot make symbolic links here ({exc})")
    return path


def unix_socket(path: Path) -> Path:
    """A bound Unix-domain socket at ``path`` (skip without AF_UNIX or with too long a path)."""
    if not hasattr(socket, "AF_UNIX"):
        pytest.skip("this OS has no Unix-domain sockets")
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        s.bind(str(path))
    except OSError as exc:
        s.close()
        pytest.skip(f"cannot bind a Unix socket here ({exc})")
    s.close()  # the socket file stays
    return path


def folder_with(root: Path, name: str, make) -> Path:
    """A valid log folder whose ``name``.csv is replaced by ``make(path)``."""
    folder = log_folder(root)
    (folder / f"{name}.csv").unlink()
    make(folder / f"{name}.csv")
    return folder


def sparse_file(path: Path, size: int = 100_000_000) -> Path:
    """A file of ``size`` bytes that occupies (almost) no disk: a hole of zeros."""
    with open(path, "wb") as fh:
        fh.truncate(size)
    return path


def _mat_element(mtype: int, body: bytes, pad: bool = True) -> bytes:
    tag = struct.pack("<II", mtype, len(body))
    return tag + body + (b"\0" * (-len(body) % 8) if pad else b"")


def mat_bomb(path: Path, columns: int = 20_000_000) -> Path:
    path.write_bytes(_mat_bomb_bytes(columns))
    return path


@functools.lru_cache(maxsize=2)
def _mat_bomb_bytes(columns: int) -> bytes:
    """A compressed MATLAB v5 file whose ``ydata`` (5 x ``columns`` zeros, 800 MB for 2e7) is written by
    streaming zlib, so that building it takes a few MB; ``tvec`` (1 x 3), ``Qtrue`` and ``Rtrue`` are
    small and valid.  About 780 kB for 2e7 columns."""
    tail = io.BytesIO()
    savemat(tail, {"tvec": np.arange(3.0)[None, :], "Qtrue": np.eye(6), "Rtrue": np.eye(5)}, do_compression=True)
    header = b"MATLAB 5.0 MAT-file, kfcal test bomb".ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM"
    n_bytes = 8 * 5 * columns
    matrix = (_mat_element(6, struct.pack("<II", 6, 0))  # array flags: class double
              + _mat_element(5, struct.pack("<ii", 5, columns))  # dimensions
              + _mat_element(1, b"ydata"))  # name
    data_tag = struct.pack("<II", 9, n_bytes)  # miDOUBLE
    comp = zlib.compressobj(9)
    parts = [comp.compress(struct.pack("<II", 14, len(matrix) + 8 + n_bytes) + matrix + data_tag)]
    zeros = bytes(1 << 22)
    for _ in range(n_bytes // len(zeros)):
        parts.append(comp.compress(zeros))
    parts.append(comp.compress(bytes(n_bytes % len(zeros))))
    parts.append(comp.flush())
    body = b"".join(parts)
    return header + struct.pack("<II", 15, len(body)) + body + tail.getvalue()[128:]  # miCOMPRESSED: no padding


def long_log(root: Path, steps: int = MAX_STEPS + 1) -> Path:
    """A CSV log folder of ``steps`` steps (one measurement, NaN elsewhere): one step more than the
    memory estimate allows by default."""
    folder = log_folder(root)
    row = ",".join(["NaN"] * (steps - 1))
    (folder / "ydata.csv").write_text("\n".join(f"{v!r},{row}" for v in (0.5, 60.0, 0.3, -50.0, 10.0)) + "\n")
    (folder / "tvec.csv").write_text(",".join(f"{0.1 * k:.1f}" for k in range(steps)) + "\n")
    return folder


def long_mat(root: Path, steps: int = MAX_STEPS + 1) -> Path:
    """A .mat log of ``steps`` steps with matching tvec (valid apart from its length)."""
    y = np.full((5, steps), np.nan)
    y[:, 1] = (0.5, 60.0, 0.3, -50.0, 10.0)
    savemat(root / "long.mat", {"ydata": y, "tvec": 0.1 * np.arange(steps)[None, :], "Qtrue": np.eye(6),
                                "Rtrue": np.eye(5)})
    return root / "long.mat"


def retimed_log(root: Path, t) -> Path:
    """A valid simulated CSV log folder (as many steps as ``t``) whose tvec.csv holds ``t`` (s)."""
    t = np.asarray(t, dtype=float)
    folder = log_folder(root, duration=0.1 * (t.size - 1))
    (folder / "tvec.csv").write_text(",".join(f"{v:.17g}" for v in t) + "\n")
    return folder


#: Unix-epoch seconds of a 0.1 s log (about 2023-11), as a logger writes them
EPOCH = 1.7e9


def short_lines(path: Path, lines: int = 8_900_000) -> Path:
    """A 27 MB CSV of millions of short lines (``12``), just under the byte limit of ydata.csv: the shape
    of a 5 x K matrix is refused from its line count, before the file is split or parsed."""
    path.write_bytes(b"12\n" * lines)
    return path


def one_long_line(path: Path, values: int = 13_000_000) -> Path:
    """A 26 MB CSV of one line of millions of values (``1,1,...``): far more than MAX_STEPS values."""
    path.write_bytes(b"1," * (values - 1) + b"1\n")
    return path


def spreadsheet_log(root: Path, bom: bool = True, newline: str = "\r\n", sep: str = ",") -> Path:
    """A small valid CSV log folder re-saved as a spreadsheet writes it: a UTF-8 byte-order mark at the
    start of every file, CRLF line ends, and ``sep`` between the values."""
    folder = log_folder(root)
    for f in folder.glob("*.csv"):
        text = f.read_text().replace(",", sep).replace("\n", newline)
        f.write_bytes(("\ufeff" if bom else "").encode() + text.encode())
    return folder
