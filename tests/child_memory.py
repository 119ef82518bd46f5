"""The peak resident memory of a command line run in a child process: its own high-water mark (VmHWM,
read from /proc: Linux), for the memory tests of the Monte Carlo commands."""

from __future__ import annotations

import os
import subprocess
import sys

HWM = ("[int(line.split()[1]) * 1024 for line in open('/proc/self/status') "
       "if line.startswith('VmHWM')][0]")


def command_peak(argv, timeout: float = 600) -> tuple[str, int]:
    """``(stdout, peak bytes)`` of ``python -m kfcal_helpers ARGV`` run in a child on two threads (no progress
    bar); fails the calling test (AssertionError with its stderr) when the command does not exit 0."""
    code = ("import sys; from kfcal_helpers.cli import main; "
            f"code = main({list(argv)!r}); print({HWM}, file=sys.stderr); sys.exit(code)")
    env = {"KFCAL_QUIET": "1", "KFCAL_WORKERS": "2", "PATH": ""}
    if os.environ.get("PYTHONPATH"):
        env["PYTHONPATH"] = os.environ["PYTHONPATH"]
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout, env=env)
    assert r.returncode == 0, r.stderr
    return r.stdout, int(r.stderr.split()[-1])
