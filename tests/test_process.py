"""kfcal_helpers.process, the command-line process's set-up, in-process: the encoding fallbacks, the
stream replacement, the signal handlers' installation rules, matplotlib's directory choice.  The real
processes (signals sent, streams closed, directories unwritable) are in tests/test_fuzz_cli.py."""

import io
import signal
import subprocess
import sys
import threading

import pytest

from kfcal_helpers import process
from kfcal_helpers.output import path_text, require_printable


@pytest.mark.parametrize("text, encoding, expected", [
    ("±1σ, Δt ≤ 2 s", "ascii", b"+/-1sigma, Deltat <= 2 s"),
    ("±1σ", "latin-1", b"\xb11sigma"),  # latin-1 has ±, not σ
    ("é", "ascii", b"\\xe9"),  # no fallback: a backslash escape
    ("dir\udcff/x.png", "ascii", b"dir\xff/x.png"),  # an undecodable file-name byte: that byte
    ("dir\udcff/x.png", "utf-8", b"dir\xff/x.png"),
    ("σ", "utf-8", "σ".encode()),  # nothing to replace
])
def test_fallback_errors(text, encoding, expected):
    assert text.encode(encoding, process.FALLBACK_ERRORS) == expected


def test_standard_streams_replace_and_restore(monkeypatch):
    raw = io.BytesIO()
    strict = io.TextIOWrapper(raw, encoding="ascii", errors="strict", write_through=True)
    monkeypatch.setattr(sys, "stdout", strict)
    monkeypatch.setattr(sys, "stderr", None)
    with process.standard_streams():
        assert sys.stdout is strict and sys.stdout.errors == process.FALLBACK_ERRORS
        assert sys.stderr is not None and sys.stderr.name == process.os.devnull
        print("σ", file=sys.stderr)
        print("±σ")
    assert sys.stderr is None and strict.errors == "strict"
    assert raw.getvalue() == b"+/-sigma\n"


def test_require_printable_names_the_argument():
    strict = io.TextIOWrapper(io.BytesIO(), encoding="ascii", errors="strict")
    with pytest.raises(ValueError, match=r"DIR: 'dé' cannot be printed .* ascii"):
        require_printable("DIR", "dé", strict)
    assert require_printable("DIR", "de", strict) == "de"


def test_command_name():
    assert process.command_name(["calibrate", "--runs", "3"]) == "python -m kfcal_helpers calibrate"
    for words in ([], ["--help"], ["Σ"], ["x" * 100], [""]):
        assert process.command_name(words) == "python -m kfcal_helpers"


def test_handlers_installed_only_over_the_defaults():
    """Not in another thread; not over someone else's handler; restored exactly; idempotent."""
    got = []
    t = threading.Thread(target=lambda: got.append(process.install_signal_handlers("x")))
    t.start()
    t.join()
    assert got == [[]]
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    installed = process.install_signal_handlers("python -m kfcal_helpers x")
    try:
        expected = [s for s, h in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, signal.SIG_DFL))
                    if (before[0] if s == signal.SIGINT else before[1]) is h]
        assert [s for s, _ in installed] == expected
        assert process.install_signal_handlers("again") == []  # already ours (or someone else's)
    finally:
        process.restore_signal_handlers(installed)
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def test_matplotlib_directory_left_alone_when_writable(tmp_path):
    """A writable MPLCONFIGDIR is kept; matplotlib already imported: nothing is changed."""
    code = ("import os; from kfcal_helpers.process import use_writable_matplotlib_config as u; "
            "print(u()); import matplotlib; print(matplotlib.get_configdir() == os.environ['MPLCONFIGDIR']); "
            "print(u())")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env={**process.os.environ, "MPLCONFIGDIR": str(tmp_path)})
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert r.stdout.split() == ["None", "True", "None"]


def test_path_text_escapes_what_the_stream_lacks():
    ascii_out = io.TextIOWrapper(io.BytesIO(), encoding="ascii")
    latin = io.TextIOWrapper(io.BytesIO(), encoding="latin-1")
    assert path_text("out/σé/x.png", ascii_out) == "out/\\u03c3\\xe9/x.png"  # never "sigma"
    assert path_text("out/σé/x.png", latin) == "out/\\u03c3é/x.png"
    assert path_text("out/x\udcff", ascii_out) == "out/x\udcff"  # kept: written back as the byte 0xff
    assert path_text("out/x\udcff", ascii_out).encode("ascii", process.FALLBACK_ERRORS) == b"out/x\xff"
