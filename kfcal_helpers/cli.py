"""Command line: ``python -m kfcal_helpers <command> [options]``.

Each problem registers its sub-command through two functions in its own
``cli`` module: ``add_parser(subparsers)`` and ``run(args) -> int``; the lecture
figures of both problems (``figures``) are registered from :mod:`kfcal_helpers.figures`.  Any
``ValueError`` (bad input) becomes one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["main", "OneLineParser"]


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line on stderr, exit status 2."""

    def error(self, message):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message}\n")


def _build_parser() -> argparse.ArgumentParser:
    from . import figures as figures_cli
    from .calibration import cli as calibration_cli
    from .coop import cli as coop_cli

    parser = OneLineParser(prog="python -m kfcal_helpers", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    calibration_cli.add_parser(sub)
    coop_cli.add_parser(sub)
    figures_cli.add_parser(sub)
    return parser


def main(argv=None) -> int:
    parser = _build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except ValueError as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"{parser.prog} {args.command}: error: {msg}", file=sys.stderr)
        return 2
