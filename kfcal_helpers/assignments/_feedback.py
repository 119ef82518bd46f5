"""Math in nbgrader's feedback pages without a network: MathJax inside each page.

nbgrader's feedback template loads MathJax 2 from a CDN.  :func:`feedback_template_dirs` (called by the
course's ``nbgrader_config.py``) writes, into the course folder, a template ``mathjax.html.j2`` that nbconvert
finds before its own: it holds MathJax 3 (``tex-svg.js``, whose SVG output needs no font files) from the
``sphinx-mathjax-offline`` package the course site uses, so that a feedback page shows its equations
offline, on its own, wherever the student opens it.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

__all__ = ["FEEDBACK_TEMPLATES", "feedback_template_dirs", "mathjax_script"]

#: the folder of the course that holds the feedback's template
FEEDBACK_TEMPLATES = ".kfcal_feedback_templates"

_CONFIG = """window.MathJax = {
  tex: {inlineMath: [["$", "$"], ["\\\\(", "\\\\)"]], displayMath: [["$$", "$$"], ["\\\\[", "\\\\]"]],
        processEscapes: true, processEnvironments: true, tags: "ams"},
  svg: {fontCache: "global"}
};"""


def mathjax_script() -> Path | None:
    """``tex-svg.js`` of the installed ``sphinx-mathjax-offline`` package, or None without it."""
    spec = importlib.util.find_spec("sphinx-mathjax-offline")   # its folder's name has hyphens
    if spec is None or spec.origin is None:
        return None
    path = Path(spec.origin).parent / "static" / "mathjax" / "tex-svg.js"
    return path if path.is_file() else None


def feedback_template_dirs(root) -> list[str]:
    """The value of ``HTMLExporter.extra_template_basedirs`` that gives nbgrader's feedback pages MathJax
    inside them: ``[root/.kfcal_feedback_templates, nbgrader's templates]``, after writing there (when it is
    missing or out of date) ``feedback/mathjax.html.j2``.  Without ``sphinx-mathjax-offline`` (or nbgrader),
    ``[]``: nbgrader's own (MathJax from its CDN)."""
    script = mathjax_script()
    try:
        import nbgrader
    except ImportError:
        return []
    if script is None:
        return []
    nbgrader_templates = Path(nbgrader.__file__).parent / "server_extensions" / "formgrader" / "templates"
    base = Path(root) / FEEDBACK_TEMPLATES
    target = base / "feedback" / "mathjax.html.j2"
    code = script.read_text(encoding="utf-8")
    if "{% endraw %}" in code or "</script" in code:
        return []   # not embeddable as it is: keep nbgrader's
    text = ("{%- macro mathjax(url=None) -%}\n"
            "<!-- MathJax 3 (tex-svg.js, from sphinx-mathjax-offline) inside the page: no network -->\n<script>\n" + _CONFIG + "\n</script>\n<script>\n{% raw %}" + code
            + "{% endraw %}\n</script>\n{%- endmacro %}\n")
    if not (target.is_file() and target.read_text(encoding="utf-8") == text):
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(".tmp")
        partial.write_text(text, encoding="utf-8")
        os.replace(partial, target)
    return [str(base), str(nbgrader_templates)]
