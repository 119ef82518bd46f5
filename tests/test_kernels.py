"""The kernels the tests start (nbval's, one per notebook; nbclient's in tests/test_style_backend.py)
listen on Unix sockets, not TCP ports: a port picked by jupyter_client and bound by the kernel a
moment later can be taken meanwhile by another process, and the kernel then dies at startup
("Kernel died before replying to kernel_info").  The root conftest.py sets this up."""

import os

import pytest

posix = pytest.mark.skipif(os.name == "nt", reason="zmq has no IPC transport on Windows: TCP there")


@posix
def test_nbval_kernels_listen_on_their_own_unix_sockets():
    import nbval.kernel

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
