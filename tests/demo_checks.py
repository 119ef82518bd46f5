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
