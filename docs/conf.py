"""Sphinx configuration of the course site: the executed lesson notebooks as static HTML pages.

Build it, with no network, from the repository's root:

    python -m sphinx -b html docs build/site

then open ``build/site/index.html`` in a browser (also from a file share or an intranet server).
The notebooks are committed executed and are NOT run here (``nb_execution_mode = "off"``); the
solutions in ``notebooks/solutions/`` are not part of the site. MathJax is served from the site
itself (``_static/mathjax``, from the ``sphinx-mathjax-offline`` package, with MathJax's license,
``docs/_mathjax/LICENSE``, as ``_static/mathjax/LICENSE``), so neither the build nor a reader's
browser fetches anything from the internet.  An image a notebook cell printed is shown at most as
wide as the page's column and links to its file: a click opens it at full size.

Sphinx reads documents only below ``docs/``, so each build first copies the lesson notebooks
``notebooks/[0-9][0-9]*_*.ipynb`` into ``docs/lessons/`` (ignored by git), changing two things in
the copy: a link to a worked solution becomes the solution's path in the repository, a ``$$`` display
that continues a paragraph gets a blank line before it (as MyST needs), and the live demo's widget
(which needs a running kernel) becomes the image and status line it stored.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import re
import shutil
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
NOTEBOOKS = ROOT / "notebooks"
LESSONS = DOCS / "lessons"

WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"
WIDGET_STATE = "application/vnd.jupyter.widget-state+json"
LIVE_NOTE = ("<p class=\"kfcal-live-note\"><em>On this page the demo shows the image it stored when the "
             "notebook was executed; its controls work when the notebook runs in Jupyter.</em></p>")
SOLUTION_LINK = re.compile(r"\[([^\]]*)\]\((solutions/[0-9A-Za-z_.-]+\.ipynb)\)")


def _display_math_as_blocks(source: str) -> str:
    """Put a blank line before each ``$$`` display that follows a line of text, outside code fences.

    Jupyter finds ``$$ ... $$`` anywhere; MyST's ``dollarmath`` reads it as a display block only when
    it does not continue a paragraph, and inside a paragraph a display line that begins with ``+``
    or ``-`` would start a list. The page looks as it does in Jupyter: the display on its own."""
    lines, out = source.split("\n"), []
    fence, in_math = None, False
    for line in lines:
        stripped = line.strip()
        if fence is None and not in_math and stripped[:3] in ("```", "~~~"):
            fence = stripped[:3]
        elif fence is not None:
            if stripped.startswith(fence):
                fence = None
        elif in_math:
            in_math = not stripped.endswith("$$")
        elif stripped.startswith("$$"):
            if out and out[-1].strip():
                out.append("")
            in_math = not (len(stripped) > 3 and stripped.endswith("$$"))
        out.append(line)
    return "\n".join(out)


def _widget_parts(state: dict, model_id: str) -> tuple[list[dict], list[str]]:
    """The ImageModel states and HTMLModel values below widget ``model_id``, in display order."""
    images, html = [], []
    model = state.get(model_id)
    if model is None:
        return images, html
    name = model.get("model_name")
    if name == "ImageModel":
        images.append(model)
    elif name == "HTMLModel" and model["state"].get("value"):
        html.append(model["state"]["value"])
    for child in model["state"].get("children", []):
        sub_images, sub_html = _widget_parts(state, child.removeprefix("IPY_MODEL_"))
        images += sub_images
        html += sub_html
    return images, html


def _static_widget_output(output: dict, state: dict) -> list[dict]:
    """Replace one widget-view output by display outputs of the image (PNG) and text it stored."""
    images, html = _widget_parts(state, output["data"][WIDGET_VIEW]["model_id"])
    outputs = []
    for model in images:
        fmt = model["state"].get("format", "png")
        for buffer in model.get("buffers", []):
            if buffer.get("path") == ["value"] and buffer.get("encoding") == "base64" and fmt == "png":
                outputs.append({"output_type": "display_data", "metadata": {},
                                "data": {"image/png": buffer["data"], "text/plain": "<the demo's image>"}})
    if html:
        outputs.append({"output_type": "display_data", "metadata": {},
                        "data": {"text/html": "".join(html), "text/plain": "<the demo's status line>"}})
    if not outputs:  # nothing stored: say so rather than leave a widget placeholder
        outputs.append({"output_type": "display_data", "metadata": {},
                        "data": {"text/plain": "(a live widget: run the notebook in Jupyter to see it)"}})
    outputs.append({"output_type": "display_data", "metadata": {},
                    "data": {"text/html": LIVE_NOTE, "text/plain": "(live demo)"}})
    return outputs


def lesson_for_site(nb: dict) -> dict:
    """The notebook ``nb`` (nbformat 4 JSON as a dict) as the site shows it: solution links become
    repository paths, and live widgets their stored image and status line (no widget JavaScript)."""
    nb = copy.deepcopy(nb)
    state = nb.get("metadata", {}).pop("widgets", {}).get(WIDGET_STATE, {}).get("state", {})
    for cell in nb["cells"]:
        if cell["cell_type"] == "markdown":
            source = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
            source = SOLUTION_LINK.sub(
                lambda m: f"`notebooks/{m.group(2)}` (in the repository; the solutions are not on this site)",
                source)
            cell["source"] = _display_math_as_blocks(source)
        elif cell["cell_type"] == "code":
            outputs = []
            for output in cell.get("outputs", []):
                if WIDGET_VIEW in output.get("data", {}):
                    outputs += _static_widget_output(output, state)
                else:
                    outputs.append(output)
            cell["outputs"] = outputs
    return nb


def sync_lessons() -> list[str]:
    """Write every lesson notebook, as the site shows it, to ``docs/lessons/``; remove stale ones.
    A file whose text is unchanged is not rewritten, so Sphinx rebuilds only changed pages."""
    LESSONS.mkdir(exist_ok=True)
    names = sorted(p.name for p in NOTEBOOKS.glob("[0-9][0-9]*_*.ipynb"))
    for name in names:
        nb = json.loads((NOTEBOOKS / name).read_text(encoding="utf-8"))
        text = json.dumps(lesson_for_site(nb), indent=1, ensure_ascii=False) + "\n"
        target = LESSONS / name
        if not target.exists() or target.read_text(encoding="utf-8") != text:
            target.write_text(text, encoding="utf-8")
    for stale in LESSONS.glob("*.ipynb"):
        if stale.name not in names:
            stale.unlink()
    return names


sync_lessons()

# -- the site ---------------------------------------------------------------------------------------

project = "Kalman filtering, step by step"
author = "The kfcal-helpers contributors"
copyright = "2026 The kfcal-helpers contributors; text, equations and figures CC BY 4.0, code MIT"
language = "en"

extensions = ["myst_nb", "sphinx.ext.mathjax"]
root_doc = "index"
exclude_patterns = ["_build", "_mathjax", "**/.ipynb_checkpoints", ".gitignore"]

# notebooks: as committed, executed; never run at build time
nb_execution_mode = "off"
nb_ipywidgets_js = {}  # no widget JavaScript from a CDN (the live widgets are replaced above)
nb_output_stderr = "show"
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3

# math: MathJax 3 from inside the built site (copied after the build), never from a CDN
_MATHJAX_PACKAGE = importlib.util.find_spec("sphinx-mathjax-offline")  # its folder's name has hyphens
if _MATHJAX_PACKAGE is None:
    from sphinx.errors import ConfigError

    raise ConfigError("the package sphinx-mathjax-offline (MathJax for the site) is not installed: "
                      "pip install -r environment.txt")
MATHJAX_SOURCE = Path(_MATHJAX_PACKAGE.origin).parent / "static" / "mathjax"
#: MathJax's license (Apache 2.0), which the package does not ship; it travels with the built site
MATHJAX_LICENSE = DOCS / "_mathjax" / "LICENSE"
mathjax_path = "mathjax/tex-chtml.js"  # relative to _static/
# MathJax's other combined builds and its SVG output are not used by tex-chtml.js
_UNUSED_MATHJAX = {"tex-chtml-full-speech.js", "tex-chtml-full.js", "tex-mml-chtml.js", "tex-mml-svg.js",
                   "tex-svg-full.js", "tex-svg.js", "mml-chtml.js", "mml-svg.js", "node-main.js", "svg"}

html_theme = "sphinx_book_theme"
html_title = "Kalman filtering, step by step"
html_static_path: list[str] = []
html_last_updated_fmt = None
html_theme_options = {
    "use_download_button": True,
    "use_fullscreen_button": True,
    "use_repository_button": False,
    "use_issues_button": False,
    "use_edit_page_button": False,
    "show_toc_level": 2,
    "navigation_with_keys": True,
}
html_context = {"default_mode": "auto"}  # light or dark as the reader's system says (the theme's own default)
# the search shows titles only: a result's text snippet is fetched with fetch(), which browsers
# refuse on file:// pages (a site opened from a folder or a file share)
html_show_search_summary = False
html_copy_source = True
html_show_sourcelink = False


def _copy_mathjax(app, exception):
    if exception is not None or app.builder.format != "html":
        return
    target = Path(app.outdir) / "_static" / "mathjax"
    if target.exists():
        shutil.rmtree(target)
    shutil.copytree(MATHJAX_SOURCE, target,
                    ignore=lambda folder, names: [n for n in names if n in _UNUSED_MATHJAX])
    shutil.copyfile(MATHJAX_LICENSE, target / "LICENSE")


def _output_images_link_full_size(app, doctree, docname):
    """Give every image a notebook cell printed its own pixel width.  The page's column (688 px in a
    1280 px window) shrinks a wider figure, so its labels become hard to read; with a width given,
    Sphinx links the image to its file (``html_scaled_image_link``): a click opens it at full size."""
    from docutils import nodes
    from sphinx.util.images import get_image_size

    for image in doctree.findall(nodes.image):
        parent = image.parent
        while parent is not None and "cell_output" not in parent.get("classes", ()):
            parent = parent.parent
        if parent is None or any(key in image for key in ("width", "height", "scale")):
            continue
        source = image.get("candidates", {}).get("*", image["uri"])
        size = get_image_size(Path(app.srcdir) / source)
        if size is not None:
            image["width"] = f"{size[0]}px"
            image["classes"].append("kfcal-output-figure")


def setup(app):
    # MathJax on every page: the lesson titles in the navigation hold math, also on pages without any
    app.set_html_assets_policy("always")
    app.connect("doctree-resolved", _output_images_link_full_size)
    app.connect("build-finished", _copy_mathjax)
