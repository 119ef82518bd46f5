"""The ``figures`` command: the lecture figures of every course problem, written as slide-ready files.

``python -m kfcal_helpers figures DIR [--svg] [--only NAME ...] [--list]`` writes every lecture
figure as ``DIR/<name>.png`` (1280 x 720 px: ``SLIDE_SIZE`` at ``SLIDE_DPI``), and also
``DIR/<name>.svg`` with ``--svg``, and prints each path written, one per line.

The registry is the problems' own: each problem of :data:`kfcal_helpers.problems.PROBLEMS` lists its
:class:`~kfcal_helpers.registry.LectureFigure` entries (file stem, one-line description,
``make(data)``) in lecture order, and ``figure_data()``, its results computed once, lazily and
seeded.  :func:`all_figures` joins them in problem order.  The drawing and saving is the shared
:mod:`kfcal_helpers.slides` (which the problems' own code uses, e.g. ``calibrate --figures``); this
module reads the problem list, so imports point one way: figures -> problems -> problem code -> slides.
"""

from __future__ import annotations

from pathlib import Path

from . import problems, slides
from .output import path_text
from .registry import LectureFigure
from .slides import check_directory, save_atomic, use_agg_backend
from .validation import checked, require_bool, require_choice, require_instance, require_path, require_sequence, require_text

__all__ = ["LectureFigure", "all_figures", "check_directory", "save_atomic", "save_figures", "write_figures",
           "use_agg_backend", "add_parser", "run"]


def _registry() -> dict:
    """``{figure name: (problem, LectureFigure)}`` over every problem, in problem order."""
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


def _entries(name: str, figures) -> tuple:
    return tuple(require_instance(name, entry, LectureFigure) for entry in require_sequence(name, figures))


def _check_data(figures, data) -> None:
    """``data`` must be the figure data of the problem of every entry of ``figures`` (its ``figure_data()``'s type)."""
    owners = {name: problem for name, (problem, _) in _registry().items()}
    for problem in {owners[e.name].name: owners[e.name] for e in figures if e.name in owners}.values():
        if problem.figure_data is not None:
            require_instance("data", data, type(problem.figure_data()))


@checked(figures=_entries, directory=require_path, svg=require_bool, argname=require_text)
def save_figures(figures, directory, data=None, svg: bool = False, argname: str = "directory") -> list[Path]:
    """:func:`kfcal_helpers.slides.save_figures` of ``figures``, drawn from ``data`` when given, else
    each from its own problem's ``figure_data()`` (made once per problem, ValueError if a figure is
    not registered)."""
    if data is not None:
        _check_data(figures, data)
        return slides.save_figures(figures, directory, data, svg=svg, argname=argname)
    owners = {name: problem for name, (problem, _) in _registry().items()}
    made = {}

    def data_for(entry):
        problem = owners[entry.name]
        if problem.name not in made:
            made[problem.name] = problem.figure_data()
        return made[problem.name]

    figures = tuple(figures)
    for entry in figures:  # before anything is drawn or written
        if owners.get(entry.name) is None or owners[entry.name].figure_data is None:
            raise ValueError(f"figures: {entry.name!r} is not a registered figure with figure data; pass data=")
    return slides.save_figures(figures, directory, svg=svg, argname=argname, data_for=data_for)


@checked(directory=require_path, svg=require_bool)
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
    path = check_directory(args.directory, "DIR")
    slides.check_targets(path, [f.name for f in selected], args.svg, "DIR")
    use_agg_backend()
    for path in save_figures(selected, args.directory, svg=args.svg, argname="DIR"):
        print(path_text(path))
    return 0
