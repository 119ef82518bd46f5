"""Jupyter kernels on Unix sockets: no TCP port to race for.

Over TCP, jupyter_client picks a kernel's five ports by binding port 0 and closing the socket; the
kernel binds them when it has started, a second or more later on a busy machine.  A port taken
meanwhile by any other process (another kernel, another test run, another pytest-xdist worker) makes
the kernel exit at once (``ZMQError: Address already in use``, on its stderr), and the client reports
"Kernel died before replying to kernel_info".  Over IPC (Unix sockets at a path no other kernel uses)
there is nothing to race for, and no warning about unencrypted TCP either.  On Windows, where zmq has
no IPC transport, kernels keep TCP.

Used by ``python -m kfcal_helpers assignments --execute`` (:func:`kfcal_helpers.assignments.execute`)
and by the tests' kernels (nbval's and nbclient's, in the root ``conftest.py``).  Only the standard
library is imported here; jupyter_client by the caller.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import uuid

__all__ = ["IPC_AVAILABLE", "over_ipc", "socket_folder"]

#: whether kernels can listen on Unix sockets here (zmq's IPC transport: not on Windows)
IPC_AVAILABLE = os.name != "nt"

_FOLDER: list[str] = []   # this process's socket folder, made when the first kernel manager needs it


def socket_folder() -> str:
    """The folder of this process's kernel sockets: one short path in the temporary folder (a socket's
    path may have only about 100 bytes), made on first use and removed with what is in it when the
    process exits."""
    if not _FOLDER:
        _FOLDER.append(tempfile.mkdtemp(prefix="kfcal-kernels-"))
        atexit.register(shutil.rmtree, _FOLDER[0], ignore_errors=True)
    return _FOLDER[0]


def over_ipc(manager_class, folder: str | None = None):
    """A subclass of the jupyter_client kernel manager class ``manager_class`` (``KernelManager``,
    ``AsyncKernelManager``, nbval's ...) whose kernels listen on Unix sockets under a path no other
    kernel uses (``<folder>/<12 hex digits>-1`` .. ``-5``), instead of TCP ports; ``manager_class``
    itself where there is no IPC (:data:`IPC_AVAILABLE`).  ``folder`` (a short path; the caller removes
    it) defaults to :func:`socket_folder`, removed when the process exits.  ``transport`` and ``ip``
    given by the caller win.  A kernel removes its sockets when it shuts down."""
    if not IPC_AVAILABLE:
        return manager_class

    def __init__(self, **kwargs):
        kwargs.setdefault("transport", "ipc")
        kwargs.setdefault("ip", os.path.join(folder or socket_folder(), uuid.uuid4().hex[:12]))
        manager_class.__init__(self, **kwargs)

    return type(f"IPC{manager_class.__name__}", (manager_class,), {"__init__": __init__,
                                                                   "__module__": __name__})
