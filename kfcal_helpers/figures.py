"""Lecture figures of every course problem, written as slide-ready files.

``python -m kfcal_helpers figures DIR [--svg] [--only NAME ...] [--list]`` writes every lecture
figure as ``DIR/<name>.png`` (1280 x 720 px: ``SLIDE_SIZE`` at ``SLIDE_DPI``), and also
``DIR/<name>.svg`` with ``--svg``, and prints each path written, one per line.

The registry is the problems' own: each problem of :data:`kfcal_helpers.problems.PROBLEMS` lists its
:class:`~kfcal_helpers.registry.LectureFigure` entries (file stem, one-line description,
``make(data)``) in lecture order, and ``figure_data()``, its results computed once, lazily and
seeded.  :func:`all_figures` joins them in problem order.  The figures are drawn and saved inside
``matplotlib.rc_context(style_params("slides"))``, so the caller's rcParams are unchanged, and every
figure is closed after saving.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .registry import LectureFigure
from .style import SLIDE_DPI, style_params
from .validation import require_choice

__all__ = ["LectureFigure", "all_figures", "check_directory", "save_atomic", "save_figures", "write_figures",
           "use_agg_backend", "add_parser", "run"]


def _registry() -> dict:
    """``{figure name: (problem, LectureFigure)}`` over every problem, in problem order."""
    from . import problems

    out = {}
    for problem in problems.PROBLEMS:
        for fig in problem.figures:
            if fig.name in out:
                raise ValueError(f"figure name {fig.name!r} is used by two problems "
                                 f"({out[fig.name][0].name} and {problem.name})")
            out[fig.name] = (problem, fig)
    return out


def all_figures() -> tuple:
    """Every problem's lecture figures (LectureFigure), in problem order, then lecture order."""
    return tuple(fig for _, fig in _registry().values())


# ---------------------------------------------------------------------------
# Writing
def check_directory(directory, argname: str = "directory") -> Path:
    """``directory`` as a Path; ValueError naming ``argname`` unless it is a non-empty path that is
    an existing writable directory, or can be created (its nearest existing ancestor is a writable
    directory).  Nothing is created here: the callers check before their long work starts."""
    if isinstance(directory, bool) or not isinstance(directory, (str, Path)) or str(directory) == "":
        raise ValueError(f"{argname} must be a directory path, got {directory!r}")
    path = Path(directory)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{argname} must be a directory (existing or to create), got the existing file {str(path)!r}")
    existing = path.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{argname}: cannot create {str(path)!r}, {str(existing)!r} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{argname}: cannot write into {str(existing)!r} (permission denied)")
    return path


def save_atomic(fig, out: Path, fmt: str, dpi: float, argname: str = "directory") -> Path:
    """Save ``fig`` to ``out`` under a temporary name in the same directory, then rename it, so an
    interrupted or failed save leaves no partial file (ValueError naming ``argname`` if the file
    cannot be written)."""
    from .output import PARTIAL_FILES

    out = Path(out)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.part")
    PARTIAL_FILES.add(str(tmp))  # removed by the command line's Ctrl-C handler
    try:
        fig.savefig(tmp, format=fmt, dpi=dpi)
        os.replace(tmp, out)
    except OSError as exc:
        raise ValueError(f"{argname}: cannot write {str(out)!r}: {exc.strerror or exc}") from None
    finally:
        PARTIAL_FILES.discard(str(tmp))
        if tmp.exists():
            try:
                tmp.unlink()
            except OSError:
                pass
    return out


def _select(names, argname: str) -> tuple:
    by_name = {name: fig for name, (_, fig) in _registry().items()}
    if names is None:
        return tuple(by_name.values())
    if isinstance(names, str):
        names = [names]
    try:
        names = list(names)
    except TypeError:
        raise ValueError(f"{argname} must be a sequence of figure names, got {names!r}") from None
    if not names:
        raise ValueError(f"{argname} must name at least one figure, one of {', '.join(by_name)}")
    for n in names:
        require_choice(argname, n, tuple(by_name))
    return tuple(by_name[n] for n in dict.fromkeys(names))


def save_figures(figures, directory, data=None, svg: bool = False, argname: str = "directory") -> list[Path]:
    """Draw ``figures`` (LectureFigure entries) in the slides style and save each as
    ``directory/<name>.png`` (and ``.svg`` when ``svg``) at SLIDE_DPI, uncropped, so a PNG is
    SLIDE_SIZE x SLIDE_DPI pixels (1280 x 720); closes every figure; returns the paths written.

    data : what every ``make(data)`` gets (a problem's figure data, when all the figures are that
        problem's); default: each figure's own problem's ``figure_data()``, made once per problem.
    argname : names ``directory`` in errors.
    """
    import matplotlib
    import matplotlib.pyplot as plt

    path = check_directory(directory, argname)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{argname}: cannot create directory {str(path)!r}: {exc.strerror}") from None
    owners = {name: problem for name, (problem, _) in _registry().items()} if data is None else {}
    made = {}
    formats = ("png", "svg") if svg else ("png",)
    written = []
    # "standard": the whole canvas, not the style's tight crop, so every PNG is exactly the slide size
    with matplotlib.rc_context({**style_params("slides"), "savefig.bbox": "standard"}):
        for entry in figures:
            if data is None:
                problem = owners.get(entry.name)
                if problem is None or problem.figure_data is None:
                    raise ValueError(f"figures: {entry.name!r} is not a registered figure with figure data; "
                                     "pass data=")
                if problem.name not in made:
                    made[problem.name] = problem.figure_data()
                fig = entry.make(made[problem.name])
            else:
                fig = entry.make(data)
            try:
                for fmt in formats:
                    written.append(save_atomic(fig, path / f"{entry.name}.{fmt}", fmt, SLIDE_DPI, argname))
            finally:
                plt.close(fig)
    return written


def write_figures(directory, svg: bool = False, names=None, data=None) -> list[Path]:
    """Write the lecture figures of every problem (:func:`all_figures`) to ``directory`` (created if needed).

    Parameters
    ----------
    directory : str or Path, a directory (not an existing file)
    svg : also write SVG next to each PNG
    names : optional sequence of registry names (default: all, in registry order)
    data : optional figure data to draw every selected figure from (default: each problem's own,
        seeded ``figure_data()``)

    Returns
    -------
    list of Path, the files written (PNG 1280 x 720 px; with ``svg`` each PNG followed by its SVG)

    Raises
    ------
    ValueError naming ``directory`` or ``names`` and what is allowed.
    """
    selected = _select(names, "names")
    return save_figures(selected, directory, data, svg=bool(svg))


# ---------------------------------------------------------------------------
# Command line
def use_agg_backend() -> None:
    """Select matplotlib's Agg backend (files only, no display) unless pyplot is already in use,
    as in a notebook, whose backend is left alone.  For the command-line entry points."""
    if "matplotlib.pyplot" not in sys.modules:
        import matplotlib

        matplotlib.use("Agg")


def add_parser(subparsers):
    """Register ``figures`` on an argparse sub-parsers object."""
    p = subparsers.add_parser("figures", help="write the lecture figures of every problem (PNG, optionally SVG)",
                              description="Write the lecture figures of every problem as 1280x720 PNG "
                                          "(and SVG with --svg) and print each path written.")
    p.add_argument("directory", nargs="?", metavar="DIR", help="output directory (created if needed)")
    p.add_argument("--svg", action="store_true", help="also write SVG")
    p.add_argument("--only", nargs="+", metavar="NAME", help="write only these figures (see --list)")
    p.add_argument("--list", action="store_true", help="list the figure names and descriptions, write nothing")
    p.set_defaults(run=run)
    return p


def run(args) -> int:
    """Run the sub-command; returns the exit code (ValueError for bad input)."""
    selected = _select(args.only, "--only")
    if args.list:
        width = max(len(f.name) for f in selected)
        for f in selected:
            print(f"{f.name:<{width}}  {f.description}")
        return 0
    if args.directory is None:
        raise ValueError("DIR is required (or give --list)")
    check_directory(args.directory, "DIR")
    use_agg_backend()
    for path in save_figures(selected, args.directory, svg=args.svg, argname="DIR"):
        print(path)
    return 0
