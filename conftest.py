"""Test-session settings shared by the unit tests and the notebooks run under nbval, and how
pytest-xdist groups the test files (files sharing a session fixture run on one worker)."""

import atexit
import os
import shutil
import tempfile
import uuid

# Notebooks run under nbval inherit this environment: no progress bars.
os.environ["KFCAL_QUIET"] = "1"


def _notebook_kernels_over_ipc():
    """Start nbval's notebook kernels on Unix sockets instead of TCP ports (POSIX; TCP on Windows,
    where zmq has no IPC transport).

    Over TCP, jupyter_client picks a kernel's five ports by binding port 0 and closing the socket;
    the kernel binds them when it has started, a second or more later on a busy machine.  A port
    taken meanwhile by any other process (another xdist worker's kernel, another test run) makes the
    kernel exit at once (``ZMQError: Address already in use``, on its stderr, which nbval discards),
    and nbval reports "Kernel died before replying to kernel_info".  Over IPC each kernel binds socket
    files under a path no other kernel uses, so there is nothing to race for.
    """
    if os.name == "nt":
        return
    try:
        import nbval.kernel
        from jupyter_client.manager import KernelManager
    except ImportError:  # nbval not installed: no notebooks to run
        return
    sockets = tempfile.mkdtemp(prefix="kfcal-kernels-")  # short: a socket path has at most ~100 bytes
    atexit.register(shutil.rmtree, sockets, ignore_errors=True)

    class IPCKernelManager(KernelManager):
        def __init__(self, **kwargs):
            kwargs.setdefault("transport", "ipc")
            kwargs.setdefault("ip", os.path.join(sockets, uuid.uuid4().hex[:12]))  # sockets <ip>-1 .. <ip>-5
            super().__init__(**kwargs)

    nbval.kernel.KernelManager = IPCKernelManager  # what nbval.kernel.start_new_kernel instantiates


_notebook_kernels_over_ipc()


#: test files that share a session fixture of tests/conftest.py, by the work unit they form: pytest-xdist
#: (``--dist loadfile``) gives each unit to one worker, so the fixture is computed once per run
SHARED_SCOPES = {
    "tests/test_mistakes.py": "mistakes table",
    "tests/test_calibration_mistakes.py": "mistakes table",
    "tests/test_coop_mistakes.py": "mistakes table",
}


def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the files of :data:`SHARED_SCOPES` joined into one work unit each."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class SharedFixtureScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid):
            file = super()._split_scope(nodeid)
            return SHARED_SCOPES.get(file, file)

    return SharedFixtureScheduling(config, log)
