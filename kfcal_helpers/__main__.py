"""``python -m kfcal_helpers``: the signal handlers, streams and matplotlib's directory are set up
first (:func:`kfcal_helpers.process.prepare`), before the command line's imports.  Until
:mod:`kfcal_helpers.process` is loaded (a few ms), a minimal handler does the same for a signal."""

import os
import signal
import sys


def _until_prepared(signum, frame):
    """SIGINT or SIGTERM before :func:`kfcal_helpers.process.prepare` ran: one line, exit 130 or 143
    (no file is being written yet)."""
    word = sys.argv[1] if len(sys.argv) > 1 else ""
    command = "python -m kfcal_helpers" + (f" {word}" if word.isascii() and word.isalpha() and word.islower() else "")
    terminated = signum == getattr(signal, "SIGTERM", None)
    try:
        os.write(2, f"{command}: {'terminated' if terminated else 'interrupted'}\n".encode())
    except OSError:
        pass
    os._exit(143 if terminated else 130)


for _name in ("SIGINT", "SIGTERM"):
    try:
        if signal.getsignal(getattr(signal, _name)) in (signal.default_int_handler, signal.SIG_DFL):
            signal.signal(getattr(signal, _name), _until_prepared)
    except (AttributeError, ValueError, OSError):  # no such signal here, or not the main thread
        pass

from .process import prepare  # noqa: E402 - after the handlers, on purpose

prepare(replace=(_until_prepared,))

from .cli import main  # noqa: E402

sys.exit(main())
