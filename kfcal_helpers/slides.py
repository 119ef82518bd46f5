"""Writing slide files: the shared machinery the problems' figure code and the ``figures`` command
use (this module imports no problem package and not the problem list).

:func:`save_figures` draws :class:`~kfcal_helpers.registry.LectureFigure` entries inside
``matplotlib.rc_context(style_params("slides"))`` (the caller's rcParams are unchanged) and saves each
as ``DIR/<name>.png`` (1280 x 720 px: ``SLIDE_SIZE`` at ``SLIDE_DPI``), optionally SVG, through
:func:`save_atomic` (a temporary name, then a rename: an interrupted or failed save leaves no partial
file).  :func:`check_directory` refuses an unusable output directory before the long work starts.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .output import require_printable
from .process import PARTIAL_FILES
from .style import SLIDE_DPI, style_params

__all__ = ["check_directory", "check_targets", "save_atomic", "save_figures", "use_agg_backend", "FORMATS"]

#: the file formats save_figures writes: PNG always, SVG on request
FORMATS = ("png", "svg")


def check_directory(directory, argname: str = "directory") -> Path:
    """``directory`` as a Path; ValueError naming ``argname`` unless it is a non-empty path that is
    an existing writable directory, or can be created (its nearest existing ancestor is a writable
    directory), and can be printed on stdout.  Nothing is created here: the callers check before
    their long work starts."""
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
    require_printable(argname, str(path / "x.png"))  # the paths written are printed
    return path


def check_targets(directory: Path, names, svg: bool = False, argname: str = "directory") -> list[Path]:
    """The files ``directory/<name>.png`` (and ``.svg``) of ``names``; ValueError naming ``argname`` if
    one of them exists as a directory (it could not be replaced), before anything is drawn."""
    out = []
    for name in names:
        for fmt in FORMATS if svg else FORMATS[:1]:
            target = Path(directory) / f"{name}.{fmt}"
            if target.is_dir():
                raise ValueError(f"{argname}: cannot write {str(target)!r}, a directory of that name exists")
            out.append(target)
    return out


def save_atomic(fig, out: Path, fmt: str, dpi: float, argname: str = "directory") -> Path:
    """Save ``fig`` to ``out`` under a temporary name in the same directory, then rename it, so an
    interrupted or failed save leaves no partial file (ValueError naming ``argname`` if the file
    cannot be written)."""
    out = Path(out)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.part")
    PARTIAL_FILES.add(str(tmp))  # removed by the command line's signal handler
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


def save_figures(figures, directory, data=None, svg: bool = False, argname: str = "directory",
                 data_for=None) -> list[Path]:
    """Draw ``figures`` (LectureFigure entries) in the slides style and save each as
    ``directory/<name>.png`` (and ``.svg`` when ``svg``) at SLIDE_DPI, uncropped, so a PNG is
    SLIDE_SIZE x SLIDE_DPI pixels (1280 x 720); closes every figure; returns the paths written.

    data : what every ``make(data)`` gets; or
    data_for : ``data_for(entry)`` gives the data of each entry (called before the entry is drawn);
        one of the two is required.
    argname : names ``directory`` in errors.
    """
    import matplotlib
    import matplotlib.pyplot as plt

    if (data is None) == (data_for is None):
        raise ValueError("save_figures: give exactly one of data= and data_for=")
    figures = tuple(figures)
    path = check_directory(directory, argname)
    check_targets(path, [entry.name for entry in figures], svg, argname)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{argname}: cannot create directory {str(path)!r}: {exc.strerror}") from None
    formats = FORMATS if svg else FORMATS[:1]
    written = []
    # "standard": the whole canvas, not the style's tight crop, so every PNG is exactly the slide size
    with matplotlib.rc_context({**style_params("slides"), "savefig.bbox": "standard"}):
        for entry in figures:
            fig = entry.make(data if data_for is None else data_for(entry))
            try:
                for fmt in formats:
                    written.append(save_atomic(fig, path / f"{entry.name}.{fmt}", fmt, SLIDE_DPI, argname))
            finally:
                plt.close(fig)
    return written


def use_agg_backend() -> None:
    """Select matplotlib's Agg backend (files only, no display) unless pyplot is already in use,
    as in a notebook, whose backend is left alone.  For the command-line entry points."""
    if "matplotlib.pyplot" not in sys.modules:
        import matplotlib

        matplotlib.use("Agg")
