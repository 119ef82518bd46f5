"""Checks shared by the demo tests of both problems (tests/test_*demos.py import them)."""

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
