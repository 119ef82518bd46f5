"""Reading a user's file with bounds: regular files only, and no more than a size cap.

Shared by the readers of user-given files (the course-log reader, the source notebooks of
``assignments``).  A FIFO would make the reader wait forever for a writer, a device such as
``/dev/zero`` would be read until memory runs out, so :func:`read_regular` refuses both before
reading (links are resolved), checks the size before reading, opens without waiting for a writer
(a FIFO swapped in after the check), and reads at most ``limit + 1`` bytes (a file that grew meanwhile,
or one whose size is unknown, as ``/proc``'s).  Only the standard library is imported here.
"""

from __future__ import annotations

import os
import stat
from functools import partial

from .validation import checked, optional, require_int, require_path, require_text

__all__ = ["file_kind", "named", "read_regular"]

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a directory"))


@checked(mode=partial(require_int, minimum=0, maximum=2**32 - 1))  # st_mode: a 32-bit unsigned int
def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, for a message ("a FIFO (named pipe)", "a directory", ...)."""
    return next((text for test, text in _KINDS if test(mode)), "not a regular file")


@checked(path=require_path)
def named(path) -> str:
    """``path``, and the file it links to if it is a link (for messages)."""
    try:
        if os.path.islink(path):
            return f"{path} (a link to {os.path.realpath(path)})"
    except (OSError, ValueError):
        pass
    return str(path)


def _nonblocking(path, flags):
    """``open``'s opener: never wait for a writer (a FIFO swapped in after the check)."""
    return os.open(path, flags | getattr(os, "O_NONBLOCK", 0))


@checked(path=require_path, limit=partial(require_int, minimum=0), argname=optional(require_text),
         regular_only=require_text, too_large=require_text)
def read_regular(path, limit: int, *, argname: str | None, regular_only: str, too_large: str) -> bytes:
    """The bytes of the regular file ``path`` (links resolved), at most ``limit`` of them.

    ``ValueError`` for a FIFO, device, socket or directory (``"ARGNAME: PATH is a FIFO (named pipe);
    REGULAR_ONLY"``), for a file that cannot be read (``"ARGNAME: cannot read PATH: REASON"``), and
    ``too_large`` (the whole message) for a file larger than ``limit`` bytes, checked before reading
    and again while reading.  ``argname`` None: the messages start with the path.
    """
    prefix = f"{argname}: " if argname else ""

    def cannot_read(exc: OSError) -> ValueError:
        return ValueError(f"{prefix}cannot read {path}: {exc.strerror or exc}")

    def not_regular(mode: int) -> ValueError:
        return ValueError(f"{prefix}{named(path)} is {file_kind(mode)}; {regular_only}")

    try:
        info = os.stat(path)  # follows links
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the name
        raise cannot_read(exc if isinstance(exc, OSError) else OSError(str(exc))) from None
    if not stat.S_ISREG(info.st_mode):
        raise not_regular(info.st_mode)
    if info.st_size > limit:
        raise ValueError(too_large)
    try:
        with open(path, "rb", opener=_nonblocking) as fh:
            mode = os.fstat(fh.fileno()).st_mode
            if not stat.S_ISREG(mode):
                raise not_regular(mode)
            data = fh.read(min(limit, info.st_size) + 1)  # read(n) reserves n bytes: ask for what is there
            if len(data) > info.st_size:  # it grew (or a file of unknown size, such as /proc's)
                data += fh.read(limit + 1 - len(data))
    except OSError as exc:
        raise cannot_read(exc) from None
    if len(data) > limit:  # it grew after the check
        raise ValueError(too_large)
    return data
