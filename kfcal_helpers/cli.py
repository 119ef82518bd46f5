"""Command line: python -m kfcal_helpers COMMAND [options].

The sub-commands come from the problem list (:data:`kfcal_helpers.problems.PROBLEMS`): each problem's
``add_cli(subparsers)`` adds its command, whose parser sets ``run(args) -> int``; ``figures`` (the
lecture figures of every problem) is the shared command of :mod:`kfcal_helpers.figures`, and
``assignments`` (lessons and solutions rendered from ``notebooks/source``, an nbgrader course) that of
:mod:`kfcal_helpers.assignments`.

Whatever a user types, the command ends in one of these ways, never in a traceback:

* exit 0 -- done;
* exit 2 -- bad input: one line ``python -m kfcal_helpers COMMAND: error: ...`` on stderr naming the
  option in its command-line spelling and what is allowed (argparse errors, every ``ValueError`` of
  the library, an unreadable or unwritable file, not enough memory);
* exit 130 -- interrupted (Ctrl-C, SIGINT): one line ``...: interrupted`` on stderr, on its own line;
* exit 143 -- terminated (SIGTERM): one line ``...: terminated`` on stderr;
* exit 141 -- stdout was closed while printing (e.g. ``| head -1``): nothing more is printed.

Output files are written under a temporary name and renamed when complete, so an interrupted
command leaves no partial file behind.  A stream closed from the start (``>&-``) discards what would
be printed there; text prints in any encoding (ASCII fallbacks such as ``sigma``, ``+/-``); an
unwritable matplotlib config directory is replaced by a private one (:mod:`kfcal_helpers.process`).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import warnings

from . import process
from .output import dumps_json
from .process import EXIT_INTERRUPTED, EXIT_TERMINATED, PROG

__all__ = ["main", "OneLineParser", "dumps_json", "EXIT_USAGE", "EXIT_INTERRUPTED", "EXIT_TERMINATED",
           "EXIT_BROKEN_PIPE"]

EXIT_USAGE = 2  #: bad input
EXIT_BROKEN_PIPE = 141  #: stdout closed (128 + SIGPIPE)

# values that start with "-" but are not options: negative numbers (also 1e5 form), -inf, -nan,
# and outage windows such as -5:3, so that "--omega -inf" and "--outage -5:3" reach the checks
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line on stderr, exit status 2, that takes
    values starting with ``-`` (``-5:3``, ``-1e5``, ``-inf``) as option values, and whose help
    shows plain text."""

    def error(self, message):  # noqa: D401 - argparse API
        message = " ".join(str(message).split())
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")

    def _parse_optional(self, arg_string):
        if _NEGATIVE_VALUE.match(arg_string):
            return None
        return super()._parse_optional(arg_string)

    def format_help(self):
        return super().format_help().replace("``", "")


def _build_parser() -> argparse.ArgumentParser:
    from . import figures as figures_cli
    from . import problems
    from .assignments import add_parser as add_assignments_parser

    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    for problem in problems.PROBLEMS:
        problem.add_cli(sub)
    figures_cli.add_parser(sub)
    add_assignments_parser(sub)
    return parser


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _os_error(exc: OSError) -> str:
    what = exc.strerror or _one_line(exc)
    name = exc.filename if exc.filename is not None else None
    return f"{name}: {what}" if name is not None else what


def _quiet_stdout() -> None:
    """After a closed pipe: send what is left on stdout to /dev/null, so the interpreter's final
    flush raises nothing."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv=None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``), run the sub-command, return the exit status."""
    words = sys.argv[1:] if argv is None else list(argv)
    # the command's name before the (slow) imports of argument parsing, for a signal during them
    state = {"command": process.command_name(words)}
    installed = process.install_signal_handlers(state["command"])
    try:
        with process.standard_streams():
            process.use_writable_matplotlib_config()
            return _main(argv, state)
    finally:
        process.restore_signal_handlers(installed)


def _main(argv, state: dict) -> int:
    command = state["command"]
    args = None
    try:
        parser = _build_parser()
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # argparse: --help (0) or a usage error (2, already printed)
            return exc.code if isinstance(exc.code, int) else EXIT_USAGE
        command = state["command"] = f"{PROG} {args.command}"
        process.install_signal_handlers(command)  # names the command (nothing new is installed)
        with warnings.catch_warnings():
            # a numerical warning would mean NaN or infinity in the output: stop with one line instead
            warnings.simplefilter("error", RuntimeWarning)
            code = int(args.run(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's final flush
        return code
    except KeyboardInterrupt:
        process.remove_partial_files()
        _error_line(f"{command}: interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        _quiet_stdout()
        return EXIT_BROKEN_PIPE
    except ValueError as exc:
        _error_line(f"{command}: error: {_one_line(exc)}")
        return EXIT_USAGE
    except RuntimeWarning as exc:
        _error_line(f"{command}: error: numerical failure ({_one_line(exc)}); the inputs are outside "
                    f"the range this command handles")
        return EXIT_USAGE
    except MemoryError:
        if args.command == "assignments":
            advice = "a lesson source or notebook is too large to render"
        elif getattr(args, "log", None) is not None:
            advice = "use a shorter log (fewer steps)"
        else:
            advice = "use fewer or shorter realizations"
        _error_line(f"{command}: error: not enough memory for this run; {advice}")
        return EXIT_USAGE
    except OSError as exc:
        _error_line(f"{command}: error: {_os_error(exc)}")
        return EXIT_USAGE


def _error_line(text: str) -> None:
    """``text`` as one line on stderr; nothing if stderr is closed (never on stdout)."""
    if sys.stderr is None:
        return
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass
