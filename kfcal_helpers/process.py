"""What the command-line process sets up before anything heavy is imported: signal handlers, usable
standard streams and a writable matplotlib config directory; and the registries the signal handler
reads (temporary files being written, progress bars on the screen).

``python -m kfcal_helpers`` calls :func:`prepare` first thing (``kfcal_helpers/__main__.py``), before
numpy, matplotlib or argparse is imported, so a Ctrl-C during the imports is handled too;
:func:`kfcal_helpers.cli.main` calls the same pieces when it is called in-process.  This module
imports only the standard library's always-loaded modules (``os``, ``sys``, ``signal``, ``codecs``).

* Signals: SIGINT (Ctrl-C) and SIGTERM print one line on stderr (on its own line, after a progress
  bar), remove the temporary files being written (:data:`PARTIAL_FILES`), end what :data:`AT_SIGNAL`
  holds (a Jupyter kernel being run) and end the process at once
  with status 130 (SIGINT) or 143 (SIGTERM): an exception raised inside a library callback could
  be swallowed ("Exception ignored in ...") and the work go on, and the Monte Carlo's worker threads
  end with the process.  A handler is installed only where the default one is in place (not in a
  notebook kernel, not in another thread).  On Windows, SIGTERM can be handled
  but is rarely sent; nothing here needs POSIX-only calls.
* Streams: a stream closed before the start (``>&-``, ``sys.stdout is None``) is replaced by
  ``os.devnull``: what would be printed there is discarded and the command runs normally.  Text on
  stdout survives any encoding: a character the encoding lacks is written as an ASCII fallback
  (``sigma``, ``+/-``, ``Delta``, ...), a file name's undecodable byte as that byte, anything else as
  a backslash escape (:data:`FALLBACK_ERRORS`; paths are printed through
  :func:`kfcal_helpers.output.path_text`, escaped, never transliterated).  stderr keeps Python's
  backslash escapes (the handler is set only on a strict stderr).
* matplotlib: when the config or cache directory matplotlib would use is not writable, the
  environment variable ``MPLCONFIGDIR`` is set to a private directory (``kfcal-matplotlib-UID`` in
  the temporary folder, mode 700, reused so that the font cache is built once), so matplotlib prints
  nothing about it.
"""

from __future__ import annotations

import codecs
import os
import signal
import sys

__all__ = ["PROG", "EXIT_INTERRUPTED", "EXIT_TERMINATED", "PARTIAL_FILES", "AT_SIGNAL", "OPEN_BARS", "FALLBACK_ERRORS",
           "ASCII_FALLBACKS", "command_name", "install_signal_handlers", "restore_signal_handlers",
           "remove_partial_files", "standard_streams", "use_fallback_errors", "use_writable_matplotlib_config",
           "prepare"]

PROG = "python -m kfcal_helpers"
EXIT_INTERRUPTED = 130  #: Ctrl-C (128 + SIGINT)
EXIT_TERMINATED = 143  #: SIGTERM (128 + 15)

#: temporary files being written (see kfcal_helpers.slides.save_atomic), removed by the signal handler
PARTIAL_FILES: set = set()
#: callables (no arguments) the signal handler calls before the process ends, such as ending a Jupyter kernel
#: this process started (see kfcal_helpers.assignments.execute); their errors are ignored
AT_SIGNAL: list = []
#: progress bars made (tqdm objects; one whose ``disable`` is true is closed), see kfcal_helpers.progress
OPEN_BARS: list = []
#: directories this process created for itself (a last-resort matplotlib config dir), removed at exit
_OWN_DIRS: list = []

_STATE = {"command": PROG}
_SIGNALS = {"SIGINT": (EXIT_INTERRUPTED, "interrupted"), "SIGTERM": (EXIT_TERMINATED, "terminated")}


def command_name(words) -> str:
    """``python -m kfcal_helpers WORD`` when the first of ``words`` looks like a command, else PROG."""
    word = words[0] if words else ""
    ok = isinstance(word, str) and 0 < len(word) <= 40 and word[0].isalpha() and word.isascii() and \
        all(c.isalnum() or c in "_-" for c in word) and word.islower()
    return f"{PROG} {word}" if ok else PROG


# ---------------------------------------------------------------------------
# Signals
def remove_partial_files() -> None:
    """Remove every temporary file being written (:data:`PARTIAL_FILES`); errors are ignored."""
    for path in list(PARTIAL_FILES):
        try:
            os.unlink(path)
        except OSError:
            pass


def _remove_own_dirs() -> None:
    shutil = sys.modules.get("shutil")  # imported when a directory was made (_private_dir)
    for d in list(_OWN_DIRS) if shutil is not None else ():
        shutil.rmtree(d, ignore_errors=True)


def _bar_on_screen() -> bool:
    return any(not getattr(bar, "disable", True) for bar in OPEN_BARS)


def _write_stderr(text: str) -> None:
    """Write ``text`` on stderr without Python's buffers (safe inside a signal handler)."""
    stream = sys.stderr or sys.__stderr__
    try:
        fd = stream.fileno()
        encoding = getattr(stream, "encoding", None) or "utf-8"
        os.write(fd, text.encode(encoding, "backslashreplace"))
        return
    except Exception:  # no file descriptor (an in-memory stream), a closed one, an unknown encoding
        pass
    try:
        stream.write(text)
        stream.flush()
    except Exception:
        pass


def _on_signal(signum, frame):
    code, word = EXIT_INTERRUPTED, "interrupted"
    for name, (c, w) in _SIGNALS.items():
        if getattr(signal, name, None) == signum:
            code, word = c, w
    _write_stderr(("\n" if _bar_on_screen() else "") + f"{_STATE['command']}: {word}\n")
    remove_partial_files()
    for call in list(AT_SIGNAL):
        try:
            call()
        except Exception:
            pass
    _remove_own_dirs()
    os._exit(code)


def install_signal_handlers(command: str | None = None, replace=()) -> list:
    """Handle SIGINT and SIGTERM as the module docstring says, naming ``command`` in the line.

    Installs a handler only in the main thread and only where the default one is in place (Python's
    ``default_int_handler`` for SIGINT, ``SIG_DFL`` for SIGTERM, or one of the handlers in ``replace``);
    if this module's handler is already installed, only ``command`` is updated.  Returns ``[(signal, previous handler)]`` of the handlers
    installed, for :func:`restore_signal_handlers`.
    """
    if command is not None:
        _STATE["command"] = command
    installed = []
    defaults = {"SIGINT": signal.default_int_handler, "SIGTERM": signal.SIG_DFL}
    for name in _SIGNALS:  # SIGINT first: once SIGTERM is caught, both are
        signum = getattr(signal, name, None)
        if signum is None:
            continue
        try:
            previous = signal.getsignal(signum)
            if previous is _on_signal or not (previous is defaults[name] or previous in replace):
                continue  # ours already, or someone else's (a notebook kernel, a test runner)
            signal.signal(signum, _on_signal)
        except (ValueError, OSError):  # not the main thread, or not supported on this platform
            continue
        installed.append((signum, previous))
    return installed


def restore_signal_handlers(installed) -> None:
    """Put back the handlers :func:`install_signal_handlers` replaced."""
    for signum, previous in installed:
        try:
            signal.signal(signum, previous)
        except (ValueError, OSError, TypeError):
            pass


# ---------------------------------------------------------------------------
# Streams
#: ASCII fallbacks of the non-ASCII characters the collection prints
ASCII_FALLBACKS = {
    "σ": "sigma", "±": "+/-", "Δ": "Delta", "δ": "delta", "χ": "chi", "²": "^2", "³": "^3", "√": "sqrt",
    "≤": "<=", "≥": ">=", "≈": "~", "≠": "!=", "→": "->", "←": "<-", "×": "x", "·": "*", "—": "--", "–": "-",
    "…": "...", "µ": "u", "μ": "u", "ω": "omega", "Ω": "Omega", "θ": "theta", "α": "alpha", "β": "beta",
    "λ": "lambda", "ν": "nu", "π": "pi", "ε": "eps", "ᵀ": "^T", "°": " deg", "‘": "'", "’": "'", "“": '"',
    "”": '"', "\u00a0": " ",
}

#: the name of the encoding error handler of :func:`use_fallback_errors` (for ``str.encode`` too)
FALLBACK_ERRORS = "kfcal_fallback"


def _fallback(exc):
    if not isinstance(exc, UnicodeEncodeError):
        raise exc
    ch = exc.object[exc.start]
    code = ord(ch)
    if 0xDC80 <= code <= 0xDCFF:  # a byte of a file name that did not decode (surrogateescape)
        return bytes([code - 0xDC00]), exc.start + 1
    if ch in ASCII_FALLBACKS:
        return ASCII_FALLBACKS[ch], exc.start + 1
    return ch.encode("ascii", "backslashreplace").decode("ascii"), exc.start + 1


codecs.register_error(FALLBACK_ERRORS, _fallback)


def use_fallback_errors(stream):
    """Make ``stream`` (a text stream) write characters its encoding lacks as fallbacks
    (:data:`FALLBACK_ERRORS`); returns its previous ``errors`` setting, or None if unchanged."""
    reconfigure = getattr(stream, "reconfigure", None)
    previous = getattr(stream, "errors", None)
    if reconfigure is None or previous == FALLBACK_ERRORS:
        return None
    try:
        reconfigure(errors=FALLBACK_ERRORS)
    except Exception:  # a closed or special stream
        return None
    return previous


class standard_streams:
    """Context manager: while it is active, ``sys.stdout`` and ``sys.stderr`` exist (a stream closed
    from the start is ``os.devnull``) and write any text (:func:`use_fallback_errors`); on exit the
    previous streams and settings are back.  ``restore=False`` keeps the changes (for the process)."""

    def __init__(self, restore: bool = True):
        self.restore = restore
        self._saved = []

    def __enter__(self):
        for name in ("stdout", "stderr"):
            stream = getattr(sys, name)
            if stream is None:
                try:
                    stream = open(os.devnull, "w", encoding="utf-8")
                except OSError:
                    continue
                setattr(sys, name, stream)
                self._saved.append((name, None, None, stream))
            if name == "stderr" and getattr(stream, "errors", None) != "strict":
                continue  # Python's stderr escapes what it cannot encode: messages echo input as typed
            previous = use_fallback_errors(stream)
            if previous is not None:
                self._saved.append((name, stream, previous, None))
        return self

    def __exit__(self, *exc):
        if not self.restore:
            return False
        for name, stream, errors, opened in reversed(self._saved):
            if opened is not None:
                setattr(sys, name, None)
                try:
                    opened.close()
                except OSError:
                    pass
            else:
                try:
                    stream.reconfigure(errors=errors)
                except Exception:
                    pass
        self._saved.clear()
        return False


# ---------------------------------------------------------------------------
# matplotlib's config and cache directories
def _matplotlib_dirs() -> list:
    """The config and cache directories matplotlib would use (as ``matplotlib.get_configdir`` and
    ``get_cachedir`` choose them), or None for one it could not determine."""
    from pathlib import Path

    given = os.environ.get("MPLCONFIGDIR")
    if given:
        return [Path(given)]
    out = []
    for variable, default in (("XDG_CONFIG_HOME", ".config"), ("XDG_CACHE_HOME", ".cache")):
        try:
            if sys.platform.startswith(("linux", "freebsd")):
                out.append(Path(os.environ.get(variable) or Path.home() / default, "matplotlib"))
            elif sys.platform == "win32":
                old = Path.home() / ".matplotlib"
                local = os.environ.get("LOCALAPPDATA")
                out.append(old if old.is_dir() or not local else Path(local) / "matplotlib")
            else:
                out.append(Path.home() / ".matplotlib")
        except RuntimeError:  # no home directory
            out.append(None)
    return out


def _writable_dir(path) -> bool:
    """Whether ``path`` is (or can be made, as matplotlib would) a writable directory."""
    if path is None:
        return False
    try:
        path = path.resolve()
        path.mkdir(parents=True, exist_ok=True)
        return path.is_dir() and os.access(path, os.W_OK)
    except (OSError, RuntimeError):
        return False


def _private_dir():
    """A directory of this user's own in the temporary folder, or None."""
    import tempfile
    from pathlib import Path

    uid = os.getuid() if hasattr(os, "getuid") else None
    if uid is not None:
        path = Path(tempfile.gettempdir()) / f"kfcal-matplotlib-{uid}"
        try:
            path.mkdir(mode=0o700, exist_ok=True)
            st = path.lstat()
            import stat

            if stat.S_ISDIR(st.st_mode) and st.st_uid == uid and not st.st_mode & 0o022 and os.access(path, os.W_OK):
                return str(path)
        except OSError:
            pass
    try:  # not ours, or no user ids (Windows): a fresh one, removed at exit
        import atexit
        import shutil

        path = tempfile.mkdtemp(prefix="kfcal-matplotlib-")
    except OSError:
        return None
    _OWN_DIRS.append(path)
    atexit.register(shutil.rmtree, path, True)
    return path


def use_writable_matplotlib_config() -> str | None:
    """Before matplotlib is imported: if the config or cache directory it would use is not writable,
    set ``MPLCONFIGDIR`` to a private one (module docstring).  Returns the directory set, or None
    (nothing changed: matplotlib is already imported, or its directories are writable)."""
    if "matplotlib" in sys.modules:
        return None
    if all(_writable_dir(d) for d in _matplotlib_dirs()):
        return None
    path = _private_dir()
    if path is not None:
        os.environ["MPLCONFIGDIR"] = path
    return path


def prepare(argv=None, replace=()) -> None:
    """Everything above, for the command-line process, in this order: the signal handlers (naming the
    command ``argv[0]``, default ``sys.argv[1:]``; taking over from the handlers in ``replace``), the
    streams (kept), matplotlib's directory, and no matplotlib log line on stderr (e.g. "building the
    font cache")."""
    words = sys.argv[1:] if argv is None else list(argv)
    install_signal_handlers(command_name(words), replace)
    standard_streams(restore=False).__enter__()
    try:
        use_writable_matplotlib_config()
    except Exception:  # never fatal: matplotlib then chooses (and may print a warning)
        pass
    import logging

    logging.getLogger("matplotlib").addHandler(logging.NullHandler())
