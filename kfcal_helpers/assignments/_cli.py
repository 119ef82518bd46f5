"""The ``assignments`` sub-command of ``python -m kfcal_helpers``."""

from __future__ import annotations

import os
from pathlib import Path

from ..output import path_text

__all__ = ["add_parser", "run"]


def add_parser(subparsers):
    """Register ``assignments`` on an argparse sub-parsers object."""
    p = subparsers.add_parser(
        "assignments", help="render the lessons and solutions from notebooks/source; make an nbgrader course",
        description="Render every lesson and worked-solutions notebook from its source in notebooks/source/ "
                    "(NN_name.md, a MyST Markdown notebook) and "
                    "write those that changed (the others are left untouched), or check that none differs "
                    "(--check), or make an nbgrader course of the exercises (--course DIR).")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--check", action="store_true",
                      help="write nothing; list the notebooks that differ from their source and exit 1 if any")
    mode.add_argument("--course", metavar="DIR",
                      help="make an nbgrader course in DIR (config, source/, release/); needs nbgrader "
                           "(pip install -r environment-instructors.txt)")
    p.add_argument("--execute", action="store_true",
                   help="execute the written notebooks whose code changed, each in a fresh kernel")
    p.add_argument("--notebooks", metavar="DIR",
                   help="the notebooks folder holding source/ and solutions/ (default: the repository's)")
    p.set_defaults(run=run)
    return p


def _notebooks(value) -> Path:
    from ._sync import NOTEBOOKS

    folder = Path(value) if value is not None else NOTEBOOKS
    if not (folder / "source").is_dir():
        raise ValueError(f"--notebooks: {path_text(folder / 'source')} is not a folder of source notebooks")
    return folder


def _course_dir(value: str) -> Path:
    if not value.strip():
        raise ValueError("--course: the folder name is empty (give a folder, e.g. --course course)")
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise ValueError(f"--course: {path_text(path)} exists and is not a folder")
    parent = path if path.exists() else path.parent
    while not parent.exists():
        parent = parent.parent
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"--course: {path_text(parent)} is not writable")
    return path


def run(args) -> int:
    """Run the sub-command; returns the exit code (``ValueError`` for bad input: exit 2)."""
    from ._nbgrader import check_course_dir, generate, nbgrader_missing, write_course
    from ._sync import differing, sources, sync, targets

    notebooks = _notebooks(args.notebooks)
    if args.course is not None:
        if args.execute:
            raise ValueError("--execute renders the notebooks: it does not go with --course")
        course = check_course_dir(_course_dir(args.course), notebooks)
        missing = nbgrader_missing()
        if missing:
            raise ValueError(f"--course: {missing}")
        names = write_course(course, sources(notebooks))
        generate(course, names, log=lambda line: print(line, flush=True))
        print(f"course {path_text(course)}: {len(names)} assignments released; graders run nbgrader there "
              f"(collect, autograde, generate_feedback)")
        return 0
    if args.check:
        if args.execute:
            raise ValueError("--execute writes notebooks: it does not go with --check")
        differ = differing(notebooks)
        for path in differ:
            print(path_text(path))
        if differ:
            print(f"{len(differ)} notebook(s) differ from notebooks/source: run python -m kfcal_helpers assignments")
            return 1
        print(f"all {len(targets(notebooks))} notebooks equal their sources")
        return 0
    written = sync(notebooks, run=args.execute, log=lambda line: print(line, flush=True))
    for path, state in written:
        print(f"wrote {path_text(path)} ({state})")
    if not written:
        print("every notebook already equals its source: nothing written")
    if any(state == "needs execution" for _, state in written):
        print("code cells changed: run again with --execute, or re-execute those notebooks "
              "(CONTRIBUTING: Re-executing a notebook)")
    return 0
