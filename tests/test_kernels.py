"""The kernels the tests start (nbval's, one per notebook; nbclient's in tests/test_style_backend.py) and
those ``python -m kfcal_helpers assignments --execute`` starts listen on Unix sockets, not TCP ports: a
port picked by jupyter_client and bound by the kernel a moment later can be taken meanwhile by another
process, and the kernel then dies at startup ("Kernel died before replying to kernel_info").  One
helper does it for both, :func:`kfcal_helpers.kernels.over_ipc`; the root conftest.py applies it to
the tests' kernels."""

import os
from pathlib import Path

import nbformat
import pytest

from kfcal_helpers import kernels

posix = pytest.mark.skipif(os.name == "nt", reason="zmq has no IPC transport on Windows: TCP there")


@posix
def test_nbval_kernels_listen_on_their_own_unix_sockets():
    import nbval.kernel

    assert nbval.kernel.KernelManager.__module__ == "kfcal_helpers.kernels"   # made by the package's helper
    a, b = nbval.kernel.KernelManager(), nbval.kernel.KernelManager()
    assert a.transport == b.transport == "ipc" and a.ip != b.ip
    assert os.path.dirname(a.ip) == os.path.dirname(b.ip) and os.path.isdir(os.path.dirname(a.ip))
    km, kc = nbval.kernel.start_new_kernel(kernel_name=nbval.kernel.CURRENT_ENV_KERNEL_NAME,
                                           stderr=open(os.devnull, "w"))
    try:
        assert km.transport == "ipc" and km.is_alive()
        assert all(os.path.exists(f"{km.ip}-{port}") for port in km.ports)  # the kernel's sockets
        reply = kc.execute("x = 6 * 7", reply=True, timeout=60)  # it runs code
        assert reply["content"]["status"] == "ok"
    finally:
        kc.stop_channels()
        km.shutdown_kernel(now=True)
    assert not any(os.path.exists(f"{km.ip}-{port}") for port in km.ports)  # removed at shutdown


@posix
def test_nbclient_kernel_manager_is_over_ipc_too(kernel_manager_class):
    from jupyter_client import AsyncKernelManager

    km = kernel_manager_class()
    assert issubclass(kernel_manager_class, AsyncKernelManager) and km.transport == "ipc"


@posix
def test_over_ipc_keeps_what_the_caller_gives_and_uses_the_folder_given(tmp_path):
    from jupyter_client import KernelManager

    cls = kernels.over_ipc(KernelManager, folder=str(tmp_path))
    assert issubclass(cls, KernelManager) and cls.__name__ == "IPCKernelManager"
    km = cls()
    assert km.transport == "ipc" and os.path.dirname(km.ip) == str(tmp_path)
    assert cls(transport="tcp", ip="127.0.0.1").transport == "tcp"
    assert os.path.dirname(kernels.over_ipc(KernelManager)().ip) == kernels.socket_folder()


def test_over_ipc_keeps_tcp_where_zmq_has_no_ipc(monkeypatch):
    from jupyter_client import KernelManager

    monkeypatch.setattr(kernels, "IPC_AVAILABLE", False)
    assert kernels.over_ipc(KernelManager) is KernelManager


@posix
def test_assignments_execute_runs_its_kernel_on_unix_sockets_and_removes_them(tmp_path, monkeypatch):
    import tempfile

    from kfcal_helpers.assignments import execute

    made = []
    real = tempfile.mkdtemp
    monkeypatch.setattr(tempfile, "mkdtemp", lambda *a, **k: made.append(real(*a, **k)) or made[-1])
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.cells.append(nbformat.v4.new_code_cell(
        "from ipykernel.kernelapp import IPKernelApp\napp = IPKernelApp.instance()\nprint(app.transport, app.ip)"))
    execute(nb, tmp_path / "x.ipynb", timeout=120)
    transport, ip = nb.cells[0].outputs[0]["text"].split()
    assert transport == "ipc" and len(made) == 1 and Path(ip).parent == Path(made[0])
    assert not Path(made[0]).exists()   # the socket folder is removed
