"""One figure style for the notebooks, the lecture demos and the slide figures.

``use_style()`` sets matplotlib's rcParams once per session; ``use_style("slides")``
enlarges fonts and lines so that a figure saved at 1280x720 px (``SLIDE_SIZE`` inches at
``SLIDE_DPI``) is readable on a projector.  Every figure helper of :mod:`kfcal_helpers`
draws with the current rcParams, so the notebooks and ``python -m kfcal_helpers figures``
share this one definition.
"""

from __future__ import annotations

import sys

import matplotlib as mpl

from .validation import checked, require_choice, require_positive

__all__ = ["STYLES", "SLIDE_SIZE", "SLIDE_DPI", "INLINE_BACKEND", "style_params", "use_style", "line_width", "marker_size", "figure_size"]

#: width, height in inches of a slide figure; at SLIDE_DPI this is 1280 x 720 px (16:9)
SLIDE_SIZE = (12.8, 7.2)
SLIDE_DPI = 100

_COMMON = {
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.titleweight": "bold",
    "legend.framealpha": 0.85,
    "figure.constrained_layout.use": False,
    "savefig.bbox": "tight",
    # colour-blind-safe cycle (Okabe-Ito), the same order everywhere: C0 estimate/sigma, C1 ..., C3 error
    "axes.prop_cycle": mpl.cycler(color=["#0072B2", "#E69F00", "#009E73", "#D55E00",
                                         "#CC79A7", "#56B4E9", "#F0E442", "#000000"]),
}

STYLES = {
    "notebook": {**_COMMON, "figure.figsize": (9.0, 4.5), "figure.dpi": 90, "font.size": 10,
                 "axes.titlesize": 11, "axes.labelsize": 10, "legend.fontsize": 9, "lines.linewidth": 1.2},
    "slides": {**_COMMON, "figure.figsize": SLIDE_SIZE, "figure.dpi": SLIDE_DPI, "font.size": 18,
               "axes.titlesize": 20, "axes.labelsize": 18, "xtick.labelsize": 15, "ytick.labelsize": 15,
               "legend.fontsize": 14, "figure.titlesize": 22,
               # the title clear of a y tick label at the axes' top (half a 15 pt label high)
               "axes.titlepad": 10, "lines.linewidth": 2.0, "lines.markersize": 7},
}


def style_params(target: str = "notebook") -> dict:
    """The rcParams of ``target`` ("notebook" or "slides") as a new dict."""
    return dict(STYLES[require_choice("target", target, tuple(STYLES))])


#: the backend of figures shown in a Jupyter notebook (matplotlib-inline, installed with ipykernel)
INLINE_BACKEND = "module://matplotlib_inline.backend_inline"


def _jupyter_kernel_shell():
    """The IPython shell when this runs in a Jupyter kernel (ipykernel), else None."""
    if "IPython" not in sys.modules:
        return None
    from IPython import get_ipython

    shell = get_ipython()
    return shell if shell is not None and hasattr(shell, "kernel") else None


def use_style(target: str = "notebook") -> None:
    """Apply the collection's style (``"notebook"`` or ``"slides"``) to matplotlib's rcParams.

    In a Jupyter kernel it also selects the inline backend (``%matplotlib inline``) when another
    one is set, e.g. by ``MPLBACKEND=Agg`` in the environment (ipykernel only chooses the inline
    backend when ``MPLBACKEND`` is unset): the notebooks then show the same figures and outputs
    whatever ``MPLBACKEND`` says.  For another backend, run ``%matplotlib ...`` after this call.
    Outside a kernel (scripts, the command line, tests) the backend is left alone.
    """
    params = style_params(target)
    shell = _jupyter_kernel_shell()
    if shell is not None and mpl.get_backend(auto_select=False) not in (INLINE_BACKEND, "inline"):
        shell.run_line_magic("matplotlib", INLINE_BACKEND)  # the name ipykernel gives it
    mpl.rcParams.update(params)


@checked(scale=require_positive)
def line_width(scale: float = 1.0) -> float:
    """A line width relative to the current ``rcParams['lines.linewidth']`` (thin lines for dense data)."""
    return scale * mpl.rcParams["lines.linewidth"]


@checked(scale=require_positive)
def marker_size(scale: float = 1.0) -> float:
    """A marker size relative to the current ``rcParams['lines.markersize']``."""
    return scale * mpl.rcParams["lines.markersize"]


def figure_size() -> tuple:
    """The current ``rcParams['figure.figsize']`` (inches): the slide size while ``figures`` saves."""
    return tuple(mpl.rcParams["figure.figsize"])
