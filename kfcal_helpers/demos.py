"""The machinery of the live lecture demos, shared by every problem: a figure rendered to PNG for an
``ipywidgets.Image``, the one-line settings and failure messages, and :class:`LiveDemo`, which puts a
problem's controls above the image and redraws on every change.

Each problem's ``demos`` module (``kfcal_helpers.calibration.demos``, ``kfcal_helpers.coop.demos``,
``kfcal_helpers.orbit.demos``)
splits its demo into a *compute* function, which returns plain arrays in a small dataclass, and a
figure class built once (:func:`new_figure`) whose ``update(demo)`` only replaces the data, so a redraw
costs one render; a figure class may also offer ``draw()``, which renders its figure faster onto its
canvas (e.g. with a :class:`CachedBackground`, as :class:`DemoFigure` does), and :class:`LiveDemo` then uses it.  A demo result may
name in ``finite_fields`` (a class attribute) the arrays that must be finite before it is drawn.  A setting that cannot be computed (e.g. a covariance losing
positive definiteness) shows a one-line message in the image's place, never a traceback.
"""

from __future__ import annotations

import io
from functools import partial

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.axes import Axes
from matplotlib.axis import Axis
from matplotlib.figure import Figure
from matplotlib.ticker import FixedFormatter, FixedLocator

from .validation import checked, describe, optional, require_bool, require_finite_array, require_instance, require_int

__all__ = ["NOTEBOOK_WIDTH_PX", "MIN_TEXT_PX", "new_figure", "figure_png", "smallest_text", "CachedBackground", "DemoFigure", "error_lines", "show_errors", "DEMO_FAILURES", "require_finite_demo",
           "failure_message", "describe_controls", "LiveDemo"]


#: the width (CSS px) JupyterLab 4.6 gives a notebook's output in a 1280x800 browser window in its
#: default layout (the file browser open in the left sidebar), measured by tests/test_browser_demos.py:
#: a live figure at most this wide is shown pixel for pixel, not scaled down
NOTEBOOK_WIDTH_PX = 833
#: the smallest text a live demo shows on screen, px (a figure's: points * dpi / 72 at its own size)
MIN_TEXT_PX = 10.0


_a_dict = partial(require_instance, cls=dict)


def _figsize(name, value):
    size = require_finite_array(name, value, shape=(2,))
    if not (size > 0).all():
        raise ValueError(f"{name} must be (width, height) in inches, both > 0, got {tuple(size.tolist())}")
    return tuple(size.tolist())


@checked(figsize=optional(_figsize))
def new_figure(figure, figsize):
    """``figure`` if given (a matplotlib Figure; given an Agg canvas if it has none that can
    render), else a new pyplot figure of ``figsize`` inches."""
    if figure is None:
        return plt.figure(figsize=figsize)
    if not isinstance(figure, Figure):
        raise ValueError(f"figure must be a matplotlib Figure or None, got {type(figure).__name__}")
    if not isinstance(figure.canvas, FigureCanvasAgg):
        FigureCanvasAgg(figure)
    figure.clear()
    return figure


@checked(drawn=require_bool)
def figure_png(fig, *, drawn: bool = False) -> bytes:
    """The figure rendered once by Agg and encoded as an RGB PNG with light compression, for an
    ``ipywidgets.Image`` (about twice as fast as ``savefig``, which renders again for the tight
    bounding box of this collection's style).  ``drawn=True``: the figure's Agg canvas already holds
    the current rendering (e.g. from :meth:`CachedBackground.draw`), so only the encoding is done."""
    from PIL import Image

    if not isinstance(fig, Figure):
        raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    if drawn and not isinstance(fig.canvas, FigureCanvasAgg):
        raise ValueError("drawn=True needs a figure with an Agg canvas that has been drawn")
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    if not drawn:
        canvas.draw()
    rgba = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
    buf = io.BytesIO()
    rgba.convert("RGB").save(buf, format="png", compress_level=1)
    return buf.getvalue()


def smallest_text(fig) -> tuple[float, str]:
    """The smallest font size (points) among the visible, non-empty texts of ``fig`` (titles, labels,
    tick labels, legend, annotations), and that text: ``(points, text)``.  On screen it is
    ``points * fig.dpi / 72`` px when the PNG is shown at its own size.  Tick labels exist once the
    figure has been drawn: call this after a draw."""
    from matplotlib.text import Text

    if not isinstance(fig, Figure):
        raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    texts = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()
             and all(a.get_visible() for a in _ancestors(t))]
    if not texts:
        raise ValueError("fig has no visible text")
    small = min(texts, key=lambda t: t.get_fontsize())
    return float(small.get_fontsize()), small.get_text()


def _ancestors(artist):
    """The artists holding ``artist`` up to its figure (an Axes, an axis, a tick, a legend ...)."""
    fig = artist.get_figure(root=True) if hasattr(artist, "get_figure") else artist.figure
    parents = {}
    for a in fig.findobj():
        for child in a.get_children():
            parents.setdefault(id(child), a)
    out, a = [], parents.get(id(artist))
    while a is not None and a is not fig:
        out.append(a)
        a = parents.get(id(a))
    return out


def _draw_order(fig):
    """Every artist of ``fig`` in the order ``Figure.draw`` renders it, two levels deep: the figure's
    patch, then its children by zorder, each Axes as its patch followed by its children by zorder
    (matplotlib's own order: a stable sort of ``get_children()``).  Yields ``(axes or None, artist)``."""
    yield None, fig.patch
    for child in sorted((c for c in fig.get_children() if c is not fig.patch), key=lambda c: c.get_zorder()):
        if isinstance(child, Axes):
            if not child.get_visible():
                continue
            if child.axison and child.get_frame_on():
                yield child, child.patch
            skip = {child.patch}
            if not (child.axison and child.get_frame_on()):
                skip.update(child.spines.values())
            if not child.axison:
                skip.update((child.xaxis, child.yaxis))
            for a in sorted((a for a in child.get_children() if a not in skip), key=lambda a: a.get_zorder()):
                yield child, a
        else:
            yield None, child


class CachedBackground:
    """Fast redraws of a figure whose data-independent part is rendered once (blitting on Agg).

    ``static``: artists a redraw does not change, e.g. the x axes (ticks, grid lines, tick labels,
    label) of panels whose time axis stays the same; with the figure's and the Axes' backgrounds they
    are rendered once into a background.  :meth:`draw` puts the background back and renders every
    other artist, in the order of a full draw, so its image is the one ``fig.canvas.draw()`` gives
    (``tests/test_demos.py`` compares them pixel for pixel).  ``key()`` (optional) returns what the
    static artists depend on (e.g. the x limits); the background is rendered again when it, the
    figure's size or its dpi change.

    Each static artist must come before every other artist of its Axes in the drawing order (a
    lower zorder, or the same zorder and earlier in ``get_children()``), else ValueError.  A redraw
    in which an Axes with a title shows a y-axis offset text (e.g. ``1e-5``), or has a left or right
    title, is done in full: matplotlib then places the titles, which only its own draw does.

    The ticks of every axis redrawn (e.g. the y axes, whose limits follow the data) are computed once
    per redraw: matplotlib's draw of an axis asks its locator several times (for the ticks, again to
    place the axis label beside the tick labels, again for the spine's extent: six times for one y axis
    in ``tests/test_demos.py``).  :meth:`draw` asks the locator and the formatter once, hands the axis
    fixed ticks with the same positions, labels and offset text for this one render, and gives the
    axis its own locator and formatter back after it, so any later draw (a full ``fig.canvas.draw()``,
    new limits) ticks the axis as matplotlib does.
    """

    def __init__(self, fig, static, key=None):
        if not isinstance(fig, Figure):
            raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
        if key is not None and not callable(key):
            raise ValueError(f"key must be None or callable (-> what the static artists depend on), "
                             f"got {type(key).__name__}")
        if not isinstance(fig.canvas, FigureCanvasAgg):
            FigureCanvasAgg(fig)
        self.fig, self.key = fig, key
        self.static = [fig.patch, *(ax.patch for ax in fig.axes), *static]
        self._static_ids = {id(a) for a in self.static}
        self._background = None
        self._background_key = None
        self.full_draws = 0  #: redraws done in full (the first one, a new key, a y offset text beside a title)

    def _dynamic(self):
        """The artists drawn on every redraw, in drawing order; checks that static ones come first."""
        order, seen_dynamic = [], set()
        for ax, a in _draw_order(self.fig):
            if id(a) in self._static_ids:
                if ax is not None and ax in seen_dynamic:
                    raise ValueError(f"static artist {a!r} is drawn after a changing artist of its Axes: "
                                     f"give it a lower zorder")
            else:
                order.append(a)
                seen_dynamic.add(ax)
        return order

    def _offset_beside_title(self) -> bool:
        for ax in self.fig.axes:
            if ax.get_title("left") or ax.get_title("right"):
                return True  # only the centre title is public (ax.title): let matplotlib place the others
            if not ax.get_title():
                continue
            if ax.yaxis.get_visible() and ax.yaxis.offsetText.get_visible():
                fmt = ax.yaxis.get_major_formatter()
                fmt.set_locs(ax.yaxis.get_majorticklocs())
                if fmt.get_offset():
                    return True
        return False

    def draw(self):
        """Render the figure onto its Agg canvas; returns the Figure (then ``figure_png(fig, drawn=True)``)."""
        canvas = self.fig.canvas
        dynamic = self._dynamic()
        key = (canvas.get_width_height(), self.fig.dpi, None if self.key is None else self.key())
        if self._offset_beside_title():
            self.full_draws += 1
            canvas.draw()
            return self.fig
        if self._background is None or key != self._background_key:
            self.full_draws += 1
            hidden = [a for a in dynamic if not a.get_animated()]
            for a in hidden:  # animated artists are left out of a draw: render the static part alone
                a.set_animated(True)
            try:
                canvas.draw()
            finally:
                for a in hidden:
                    a.set_animated(False)
            self._background, self._background_key = canvas.copy_from_bbox(self.fig.bbox), key
        else:
            canvas.restore_region(self._background)
        renderer = canvas.get_renderer()
        for ax in self.fig.axes:
            ax.apply_aspect()
            ax.title.set_position((ax.title.get_position()[0], 1.0))  # where a full draw puts it
        frozen = self._freeze_ticks(dynamic)
        try:
            for a in dynamic:
                a.draw(renderer)
        finally:
            for ticker, locator, formatter in frozen:
                ticker.locator, ticker.formatter = locator, formatter
        return self.fig

    @staticmethod
    def _freeze_ticks(dynamic):
        """Give each axis among ``dynamic`` fixed major ticks for one render: the positions its own
        locator gives for the current limits, the labels and offset text its own formatter gives them.
        Returns ``(ticker, locator, formatter)`` of each axis, to give them back."""
        frozen = []
        for axis in dynamic:
            if not isinstance(axis, Axis) or not axis.get_visible():
                continue
            ticker = axis.major
            locator, formatter = ticker.locator, ticker.formatter
            locs = locator()
            fixed = FixedFormatter(formatter.format_ticks(locs))
            fixed.set_offset_string(formatter.get_offset())
            frozen.append((ticker, locator, formatter))
            ticker.locator, ticker.formatter = FixedLocator(locs), fixed
        return frozen


class DemoFigure:
    """The base of the problems' demo figures: a subclass builds ``fig`` (a matplotlib Figure) and ``background``
    (a :class:`CachedBackground` of it) once, and defines ``update(demo) -> Figure``; :meth:`draw` is the fast
    render :class:`LiveDemo` uses."""

    fig: Figure
    background: CachedBackground

    def draw(self):
        """Render the figure onto its Agg canvas, the static artists kept from an earlier render (rendered again
        when their key changes); returns the Figure (then ``figure_png(fig, drawn=True)``)."""
        return self.background.draw()


@checked(ax=partial(require_instance, cls=Axes))
def error_lines(ax):
    """On ``ax``: an estimation error's line (red, labelled "error") and the filter's +-2 sigma pair (black,
    the upper one labelled), all empty; returns ``(error, up, down)`` for :func:`show_errors`."""
    err, = ax.plot([], [], color="C3", lw=0.7, label="error")
    up, = ax.plot([], [], color="k", lw=0.8, label=r"$\pm 2\sigma$")
    down, = ax.plot([], [], color="k", lw=0.8)
    return err, up, down


def _require_error_lines(name, value):
    from matplotlib.lines import Line2D
    if not (isinstance(value, tuple) and len(value) == 3 and all(isinstance(v, Line2D) for v in value)):
        raise ValueError(f"{name} must be the (error, up, down) lines of error_lines, got {describe(value)}")
    return value


@checked(lines=_require_error_lines, t=require_finite_array, error=require_finite_array, sigma2=require_finite_array,
         skip=partial(require_int, minimum=0, maximum=2**31))
def show_errors(lines, t, error, sigma2, skip: int = 0) -> None:
    """Put one state's error ``error`` (K,) and its 2 sigma ``sigma2`` (K,) against ``t`` (K,) into the
    ``lines`` of :func:`error_lines`, and give their Axes symmetric y limits 15 % beyond the largest
    error or bound from sample ``skip`` on (so a large prior sigma does not flatten the rest)."""
    err, up, down = lines
    t, error, sigma2 = (np.asarray(a, dtype=float) for a in (t, error, sigma2))
    if not (t.ndim == 1 and error.shape == t.shape == sigma2.shape and t.size > 0):
        raise ValueError(f"t, error and sigma2 must be (K,) arrays of one length K >= 1, got shapes "
                         f"{t.shape}, {error.shape}, {sigma2.shape}")
    skip = min(max(int(skip), 0), t.size - 1)
    err.set_data(t, error)
    up.set_data(t, sigma2)
    down.set_data(t, -sigma2)
    top = max(sigma2[skip:].max(), np.abs(error[skip:]).max())
    err.axes.set_ylim(-1.15 * top, 1.15 * top)


#: what a redraw turns into a one-line message instead of a traceback: ``numpy.linalg.LinAlgError``
#: (a ValueError: a covariance that is no longer positive definite), any other ValueError (a value
#: the filter or the draw cannot use), arithmetic faults, and warnings (raised as errors while a
#: redraw runs, so a RuntimeWarning of an overflow never reaches the notebook)
DEMO_FAILURES = (ValueError, ArithmeticError, Warning)

def require_finite_demo(demo) -> None:
    """Raise ValueError when an array named in ``demo.finite_fields`` holds inf or NaN."""
    for name in getattr(type(demo), "finite_fields", ()):
        if not np.all(np.isfinite(getattr(demo, name))):
            raise ValueError(f"the result is not finite ({name} holds inf or NaN): the filter diverged")


@checked(error=partial(require_instance, cls=BaseException))
def failure_message(error: BaseException) -> str:
    """One line that says why a redraw failed, for the figure area of a live demo."""
    text = " ".join(str(error).split()) or type(error).__name__
    if len(text) > 80:
        text = text[:77] + "..."
    if isinstance(error, np.linalg.LinAlgError):
        return f"the filter failed: its covariance is no longer positive definite ({text})"
    if isinstance(error, Warning):
        return f"the computation overflowed or lost precision ({type(error).__name__}: {text})"
    return f"cannot compute these settings: {text}"


def _format_value(value) -> str:
    if isinstance(value, (float, np.floating)):
        return f"{value:.3g}"
    if isinstance(value, tuple) and all(isinstance(v, (int, float, np.number)) for v in value):
        return "–".join(f"{v:g}" for v in value)
    return str(value)


@checked(controls=_a_dict,
         values=optional(_a_dict))
def describe_controls(controls: dict, values: dict | None = None) -> str:
    """Settings of ``controls`` in one line (``values`` by name, default the controls' own):
    ``description value`` for every control that is not a checkbox, then the descriptions of the
    ticked checkboxes (or "none ticked")."""
    import ipywidgets as w

    values = {} if values is None else values
    parts, ticked, boxes = [], [], 0
    for name, c in controls.items():
        value = values.get(name, c.value)
        if isinstance(c, w.Checkbox):
            boxes += 1
            if value:
                ticked.append(c.description)
            continue
        for option in getattr(c, "options", ()) if isinstance(c, (w.ToggleButtons, w.Dropdown)) else ():
            if isinstance(option, tuple) and option[1] == value:
                value = option[0]
        parts.append(f"{c.description} {_format_value(value)}")
    if boxes:
        parts.append("on: " + (", ".join(ticked) if ticked else "none ticked"))
    return "; ".join(parts)


class LiveDemo:
    """A live demo in the notebook: ``controls`` (a dict of ipywidgets, as a problem's
    ``*_controls()`` returns) in rows above an ``ipywidgets.Image`` of ``view``'s figure (they wrap
    to the notebook's width), and one line of text under it.  The image gets the notebook's whole
    width, so a figure sized for it (a problem's ``LIVE_FIGSIZE``) is shown pixel for pixel.

    A change of any control calls ``compute(**values)`` (the control values by name; it returns
    the problem's demo result, or None when there is nothing to draw), puts the result into
    ``view`` (any object with a matplotlib Figure ``fig`` and ``update(demo) -> Figure``) and
    shows its PNG; the line shows ``demo.summary()`` when the demo has one.  A redraw that
    fails (:data:`DEMO_FAILURES`, e.g. the UKF's covariance losing positive definiteness, or a
    result that is not finite) shows instead an image of the same size with the settings as its
    title and a one-line message, so the title always matches what is drawn and no traceback or
    warning appears.  ``empty`` is the message when ``compute`` returns None; ``hint`` (optional)
    is appended to a failure message.
    """

    def __init__(self, controls: dict, compute, view, empty: str = "nothing to draw for these settings",
                 hint: str = ""):
        import ipywidgets as w

        if not isinstance(controls, dict) or not controls:
            raise ValueError("controls must be a non-empty dict of ipywidgets, e.g. a problem's controls()")
        if not callable(compute):
            raise ValueError(f"compute must be callable (control values -> demo), got {type(compute).__name__}")
        if not isinstance(getattr(view, "fig", None), Figure) or not callable(getattr(view, "update", None)):
            raise ValueError(f"view must be a demo figure (with a Figure .fig and .update(demo)), "
                             f"got {type(view).__name__}")
        self.controls, self.compute, self.view, self.empty, self.hint = controls, compute, view, empty, hint
        self.message_fig = Figure(figsize=view.fig.get_size_inches(), dpi=view.fig.dpi)
        FigureCanvasAgg(self.message_fig)
        self.image = w.Image(format="png")
        self.line = w.HTML()
        self.failed = False
        bar = w.Box(list(controls.values()), layout=w.Layout(display="flex", flex_flow="row wrap",
                                                             align_items="center"))
        self.widget = w.VBox([bar, self.image, self.line], layout=w.Layout(align_items="flex-start"))
        for c in controls.values():
            c.observe(self._changed, names="value")
        self.refresh()

    def values(self) -> dict:
        """The controls' current values, by name."""
        return {name: c.value for name, c in self.controls.items()}

    def render(self, **values) -> tuple[bytes, str, bool]:
        """One redraw for ``values`` (default: the controls' current values), without touching the
        widgets: returns ``(png, line, ok)``; ``ok`` is False when the PNG shows a message."""
        import warnings

        values = {**self.values(), **values}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                demo = self.compute(**values)
                if demo is None:
                    return self._message_png(values, self.empty), self.empty, False
                require_finite_demo(demo)
                fig = self.view.update(demo)
                fast = getattr(self.view, "draw", None)
                png = figure_png(fast(), drawn=True) if callable(fast) else figure_png(fig)
        except DEMO_FAILURES as error:
            text = failure_message(error)
            return self._message_png(values, text), text + (f"; {self.hint}" if self.hint else ""), False
        return png, demo.summary() if hasattr(demo, "summary") else "", True

    def refresh(self):
        """Redraw for the controls' current values and show the result."""
        import html

        try:
            png, line, ok = self.render()
        except Exception as error:  # a live demo never shows a traceback; say what happened in one line
            text = " ".join(str(error).split())[:80]
            line = f"unexpected error, nothing drawn: {type(error).__name__}: {text}"
            png, ok = self._message_png(self.values(), line), False
        self.failed = not ok
        self.image.value = png
        self.line.value = f"<span style='font-size: 12px'>{html.escape(line)}</span>"

    def _changed(self, change):
        self.refresh()

    def _message_png(self, values, text) -> bytes:
        fig = self.message_fig
        fig.clear()
        fig.suptitle(f"{describe_controls(self.controls, values)}\nnot drawn", fontsize=9)
        fig.text(0.5, 0.5, text, ha="center", va="center", fontsize=9, color="C3", wrap=True)
        return figure_png(fig)
