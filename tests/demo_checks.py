"""Checks shared by the demo tests of the problems (tests/test_*demos.py import them)."""

import io
import warnings

from kfcal_helpers.demos import describe_controls


def png_size(png: bytes) -> tuple:
    """(width, height) in pixels of PNG bytes."""
    from PIL import Image

    return Image.open(io.BytesIO(png)).size


def check_render(live, values) -> bool:
    """One redraw of a live demo for ``values``: never raises or warns; the PNG has the view's size and
    one line under it; a redraw that fails shows the settings in its title.  Returns whether it drew."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        png, line, ok = live.render(**values)
    assert png[:4] == b"\x89PNG" and "\n" not in line
    assert png_size(png) == tuple(round(s * live.view.fig.dpi) for s in live.view.fig.get_size_inches())
    if not ok:
        assert describe_controls(live.controls, values) in live.message_fig.get_suptitle()
    return ok


def fast_draw_is_full_draw(view) -> bool:
    """The view's ``draw()`` (the kept background and the changed artists) gives the image of a full
    ``fig.canvas.draw()``, pixel for pixel; returns True (asserts otherwise)."""
    import numpy as np

    assert view.draw() is view.fig
    fast = np.array(view.fig.canvas.buffer_rgba())
    view.fig.canvas.draw()
    full = np.array(view.fig.canvas.buffer_rgba())
    assert fast.shape == full.shape
    differ = np.any(fast != full, axis=-1)
    assert not differ.any(), f"{int(differ.sum())} pixels differ, e.g. at (row, col) {np.argwhere(differ)[:3].tolist()}"
    return True


def slider_stops(control):
    """The values a slider of ``control`` can take in the browser, as a list (``None`` for a control
    that is not a slider): a selection slider's options; a float or int slider's ``min + k * step``;
    a log slider's ``base ** (min + k * step)`` (the browser's slider moves the exponent in steps), up
    to ``max``.  A range slider has the same stops for both ends."""
    import ipywidgets as w
    import numpy as np

    if isinstance(control, (w.SelectionSlider, w.SelectionRangeSlider)):
        return list(control.options if not control.options or not isinstance(control.options[0], tuple)
                    else [v for _, v in control.options])
    if isinstance(control, (w.FloatLogSlider, w.FloatSlider, w.IntSlider, w.FloatRangeSlider, w.IntRangeSlider)):
        n = int(np.floor((control.max - control.min) / control.step + 1e-9))
        grid = control.min + control.step * np.arange(n + 1)
        return list(control.base ** grid if isinstance(control, w.FloatLogSlider) else grid)
    return None


def off_grid_defaults(controls: dict) -> list:
    """The sliders among ``controls`` (a dict of ipywidgets by name) whose value is not one of their
    stops (:func:`slider_stops`, to a relative 1e-12 for the rounding of ``min + k * step``), as
    ``[(name, value, nearest stop)]``: the browser would move such a value to the nearest stop when
    it draws the slider."""
    import numpy as np

    out = []
    for name, c in controls.items():
        stops = slider_stops(c)
        if stops is None:
            continue
        for v in (c.value if isinstance(c.value, tuple) else (c.value,)):
            if not any(np.isclose(v, s, rtol=1e-12, atol=0) if isinstance(s, (float, int)) else v == s for s in stops):
                nearest = min(stops, key=lambda s: abs(np.log(s / v)) if v > 0 and s > 0 else abs(s - v))
                out.append((name, v, nearest))
    return out


def legend_is_outside_the_panels(view) -> bool:
    """After a draw of ``view.fig``: its legend, title and other figure texts overlap no panel (so no
    curve, at any setting, can lie under them), and the legend and texts do not overlap one another.
    Returns True (asserts otherwise)."""
    fig = view.fig
    renderer = fig.canvas.get_renderer()
    panels = [ax.get_window_extent(renderer) for ax in fig.axes]
    legends = [lg.get_window_extent(renderer) for lg in fig.legends]
    # the figure's texts, its title (suptitle) among them
    texts = [t.get_window_extent(renderer) for t in fig.texts if t.get_visible() and t.get_text()]
    assert legends, "the figure has no legend of its own (fig.legend)"
    assert fig.get_suptitle() and len(texts) >= 1
    for box in legends + texts:
        hit = [p for p in panels if box.overlaps(p)]
        assert not hit, f"{box} overlaps a panel {hit[0]}"
    for i, a in enumerate(legends + texts):
        for b in (legends + texts)[i + 1:]:
            assert not a.overlaps(b), f"{a} overlaps {b}"
    return True
