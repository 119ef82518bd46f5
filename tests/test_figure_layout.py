"""Every lecture figure of every problem is laid out within its slide: each text (titles, axis and
tick labels), legend and colour bar lies inside the 1280 x 720 canvas, and no legend, title or colour
bar lies over another one or over a text.  The figures are drawn as ``figures`` saves them (the slides
style, the whole canvas) and measured by matplotlib's own Agg renderer, so what is checked is what the
PNG shows."""

import itertools

import matplotlib
import matplotlib.pyplot as plt
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from kfcal_helpers import problems
from kfcal_helpers.style import SLIDE_DPI, SLIDE_SIZE, style_params

TOLERANCE_PX = 0.5  # boxes that touch within half a pixel do not count as overlapping

FIGURES = [(problem, fig) for problem in problems.PROBLEMS for fig in problem.figures]


def _boxes(fig, renderer):
    """The laid-out boxes of ``fig`` that must stay inside the canvas and apart, as
    ``(kind, owner, description, Bbox)``: kind "text", "title", "legend" or "colorbar"; owner the
    axes they belong to (None for the figure's own)."""
    out = []

    def text(kind, owner, artist, what):
        if artist.get_visible() and artist.get_text().strip():
            out.append((kind, owner, f"{what} {artist.get_text()!r}", artist.get_window_extent(renderer)))

    for t in fig.texts:  # the suptitle among them
        if t is fig._suptitle:
            text("title", None, t, "suptitle")
        else:
            text("text", None, t, "figure text")
    for legend in fig.legends:
        out.append(("legend", None, "figure legend", legend.get_window_extent(renderer)))
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        name = ax.get_title() or ax.get_label() or f"axes {fig.axes.index(ax)}"
        if ax.get_label() == "<colorbar>":  # its ticks, label and extension triangles as one box
            out.append(("colorbar", ax, f"colour bar {ax.get_ylabel()!r}", ax.get_tightbbox(renderer)))
            continue
        for title in (ax.title, ax._left_title, ax._right_title):
            text("title", ax, title, f"title of {name!r}:")
        for axis, what in ((ax.xaxis, "x"), (ax.yaxis, "y")):
            text("text", ax, axis.label, f"{what} label of {name!r}:")
            lo, hi = sorted(axis.get_view_interval())
            for tick in axis.get_major_ticks():
                if lo - 1e-9 * (hi - lo) <= tick.get_loc() <= hi + 1e-9 * (hi - lo):
                    for label in (tick.label1, tick.label2):
                        text("text", ax, label, f"{what} tick label of {name!r}:")
        for t in ax.texts:
            text("text", ax, t, f"text in {name!r}:")
        legend = ax.get_legend()
        if legend is not None and legend.get_visible():
            out.append(("legend", ax, f"legend of {name!r}", legend.get_window_extent(renderer)))
    return out


def layout_problems(fig) -> list[str]:
    """What is wrong with ``fig``'s layout, one line each (empty when nothing): a box (see
    :func:`_boxes`) outside the canvas, and a legend, title or colour bar overlapping another box.
    Texts that matplotlib places itself next to each other (an axes' tick and axis labels) are not
    compared with each other."""
    canvas = fig.canvas if hasattr(fig.canvas, "get_renderer") else FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    width, height = fig.bbox.width, fig.bbox.height
    boxes = _boxes(fig, renderer)
    found = []
    for kind, _, what, box in boxes:
        if (box.x0 < -TOLERANCE_PX or box.y0 < -TOLERANCE_PX or box.x1 > width + TOLERANCE_PX
                or box.y1 > height + TOLERANCE_PX):
            found.append(f"{what} extends past the {width:.0f} x {height:.0f} px canvas "
                         f"(x {box.x0:.0f}..{box.x1:.0f}, y {box.y0:.0f}..{box.y1:.0f})")
    for (k1, o1, w1, b1), (k2, o2, w2, b2) in itertools.combinations(boxes, 2):
        if k1 == k2 == "text" and o1 is o2:
            continue
        if k1 == "text" and k2 == "text":
            continue  # only legends, titles and colour bars are compared with texts
        overlap_x = min(b1.x1, b2.x1) - max(b1.x0, b2.x0)
        overlap_y = min(b1.y1, b2.y1) - max(b1.y0, b2.y0)
        if overlap_x > TOLERANCE_PX and overlap_y > TOLERANCE_PX:
            found.append(f"{w1} overlaps {w2} ({overlap_x:.0f} x {overlap_y:.0f} px)")
    return found


@pytest.fixture(scope="module")
def figure_data():
    """Each problem's seeded figure data, made once for all its figures."""
    made = {}

    def data(problem):
        if problem.name not in made:
            made[problem.name] = problem.figure_data()
        return made[problem.name]

    return data


@pytest.mark.parametrize("problem, entry", FIGURES, ids=[f.name for _, f in FIGURES])
def test_lecture_figure_laid_out_inside_the_slide(problem, entry, figure_data):
    # as kfcal_helpers.slides.save_figures draws them: the slides style, the whole canvas
    with matplotlib.rc_context({**style_params("slides"), "savefig.bbox": "standard"}):
        fig = entry.make(figure_data(problem))
        try:
            assert (fig.bbox.width, fig.bbox.height) == (SLIDE_SIZE[0] * SLIDE_DPI, SLIDE_SIZE[1] * SLIDE_DPI)
            problems_found = layout_problems(fig)
        finally:
            plt.close(fig)
    assert not problems_found, f"{entry.name}:\n  " + "\n  ".join(problems_found)


def test_every_problem_has_lecture_figures():
    assert {p.name for p, _ in FIGURES} == {p.name for p in problems.PROBLEMS}
    assert len(FIGURES) == sum(len(p.figures) for p in problems.PROBLEMS) >= 2


# --- the check itself finds each kind of fault --------------------------------------------------
def _figure():
    fig = Figure(figsize=(6.4, 3.6), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def test_clean_figure_passes():
    fig = _figure()
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], label="a line")
    ax.set_title("a title")
    ax.set_xlabel("x")
    ax.legend(loc="lower right")
    fig.suptitle("suptitle")
    fig.tight_layout()
    assert layout_problems(fig) == []


def test_title_cut_at_the_right_is_found():
    fig = _figure()
    ax = fig.add_subplot()
    ax.set_title("a title far too long to fit on this small canvas, running past its right edge", loc="left")
    found = layout_problems(fig)
    assert any("title of" in f and "extends past" in f for f in found), found


def test_legend_outside_the_canvas_and_over_another_legend_is_found():
    fig = _figure()
    left, right = fig.subplots(1, 2)
    for ax in (left, right):
        ax.plot([0, 1], [0, 1], label="a rather long label for a line")
        ax.plot([0, 1], [1, 0], label="another rather long label")
        ax.legend(ncol=2, loc="upper center")
    found = layout_problems(fig)
    assert any(f.startswith("legend of") and "extends past" in f for f in found), found
    assert any(f.startswith("legend of") and "overlaps legend of" in f for f in found), found


def test_colorbar_over_a_title_is_found():
    fig = _figure()
    ax = fig.add_subplot()
    image = ax.imshow([[0, 1], [1, 0]])
    fig.colorbar(image, ax=ax, location="top")   # a colour bar above the axes, where the title goes
    ax.set_title("A long title, on two lines\nthe second line of it")   # (no words the finding is matched on)
    found = layout_problems(fig)
    assert any(f.startswith("title of") and "overlaps colour bar" in f for f in found), found


def test_legend_over_tick_labels_is_found():
    fig = _figure()
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], label="label")
    ax.legend(loc="upper left", bbox_to_anchor=(-0.1, 1.0))
    fig.tight_layout()
    found = layout_problems(fig)
    assert any("legend of" in f and "tick label" in f and "overlaps" in f for f in found), found

