"""Reading a source notebook and rendering its lesson and its worked solutions.

A source notebook, ``notebooks/source/NN_name.md``, is a lesson with its exercises' placeholders
and their worked solutions side by side, kept as a MyST Markdown notebook (the text format of Jupyter
Book and jupytext's ``md:myst``; read by :func:`read_source`): the notebook metadata as YAML front
matter, each code cell as a ```` ```{code-cell} ipython3 ```` fence (its metadata, as JSON, in a
``---`` block at the top of the fence), and a ``+++`` line before a markdown cell that follows another
markdown cell or has metadata (``+++ {"kfcal": {"role": "exercise"}}``).  Each cell says where it goes
by ``metadata["kfcal"]``:

* no ``kfcal`` entry: a lesson cell, in the lesson only;
* ``{"role": "exercise"}``: a cell of both notebooks (the exercise's text, or any cell the two share);
* ``{"role": "solution"}``: a cell of the solutions notebook only (its header and setup, the
  "**Solution.**" text, extra code, the closing line);
* ``{"role": "answer", "exercise": "NN.k", "points": 1}``: an exercise's answer cell, a code cell in
  both notebooks.  Its lines between ``### BEGIN PLACEHOLDER`` and ``### END PLACEHOLDER`` are the
  lesson's placeholder (lesson only), its lines between ``### BEGIN SOLUTION`` and
  ``### END SOLUTION`` (nbgrader's markers) the worked answer (solutions only); the lines outside
  both are common.  Markers may be indented (inside a function); regions do not nest, and a
  placeholder region is followed directly by a solution region (which may be empty).  The last
  line, outside every region, is the check call ``check_xxx(answer_NN_k)`` (or ``check_xxx(f)``, the
  student's function ``f`` itself).

Everything else of a cell (type, source, other metadata, id) is copied; the source holds no outputs
(a text source has none).  A cell's text is what stands between its marker and the next one, without the
blank lines around it (myst-nb's reading, used as it is).
"""

from __future__ import annotations

import copy
import hashlib
import re
from pathlib import Path

__all__ = ["ROLES", "MARKERS", "AnswerCell", "parse_answer", "render", "render_lesson", "render_solutions",
           "answer_cells", "validate", "read_source", "SOURCE_SUFFIX"]

#: the file suffix of a source notebook (``notebooks/source/NN_name.md``)
SOURCE_SUFFIX = ".md"

#: the roles a source cell may have (None: a lesson cell)
ROLES = (None, "exercise", "solution", "answer")
BEGIN_PLACEHOLDER, END_PLACEHOLDER = "### BEGIN PLACEHOLDER", "### END PLACEHOLDER"
BEGIN_SOLUTION, END_SOLUTION = "### BEGIN SOLUTION", "### END SOLUTION"
#: the four marker lines of an answer cell (compared after stripping the indentation)
MARKERS = (BEGIN_PLACEHOLDER, END_PLACEHOLDER, BEGIN_SOLUTION, END_SOLUTION)
_CHECK_CALL = re.compile(r"^(check_\w+)\(([A-Za-z_]\w*)\)\s*$")
_EXERCISE_ID = re.compile(r"^\d\d[a-z]?\.\d+$")


class AnswerCell:
    """An answer cell split into its lines.

    lines : ``[(region, line)]`` in order, region ``None`` (common), ``"placeholder"`` or ``"solution"``;
        marker lines are kept as region ``"marker"`` (with their indentation)
    check : the check function's name (``check_xxx``); answer : the name passed to it (``answer_NN_k``)
    exercise : ``"NN.k"``; points : the exercise's points (a positive number)
    """

    def __init__(self, lines, check, answer, exercise, points):
        self.lines, self.check, self.answer, self.exercise, self.points = lines, check, answer, exercise, points

    def lesson_source(self) -> str:
        """The lesson's cell: common and placeholder lines."""
        return "\n".join(text for region, text in self.lines if region in (None, "placeholder"))

    def solution_source(self) -> str:
        """The solutions notebook's cell: common and solution lines."""
        return "\n".join(text for region, text in self.lines if region in (None, "solution"))


def _where(index: int, cell) -> str:
    cell_id = cell.get("id")
    return f"source cell {index}" + (f" (id {cell_id})" if cell_id else "")


def _role(index: int, cell):
    meta = cell.get("metadata", {}).get("kfcal")
    if meta is None:
        return None, {}
    if not isinstance(meta, dict):
        raise ValueError(f"{_where(index, cell)}: metadata 'kfcal' must be a mapping, not {type(meta).__name__}")
    role = meta.get("role")
    if role not in ROLES[1:]:
        raise ValueError(f"{_where(index, cell)}: metadata kfcal.role must be one of "
                         f"{', '.join(map(repr, ROLES[1:]))}, not {role!r}")
    return role, meta


def parse_answer(index: int, cell) -> AnswerCell:
    """The :class:`AnswerCell` of source cell number ``index``; ``ValueError`` naming the cell when
    its metadata, its regions or its last line are malformed."""
    where = _where(index, cell)
    _, meta = _role(index, cell)
    if cell.get("cell_type") != "code":
        raise ValueError(f"{where}: an answer cell must be a code cell, not {cell.get('cell_type')!r}")
    exercise = meta.get("exercise")
    if not isinstance(exercise, str) or not _EXERCISE_ID.match(exercise):
        raise ValueError(f"{where}: metadata kfcal.exercise must be an exercise id such as '03.2', not {exercise!r}")
    points = meta.get("points", 1)
    if isinstance(points, bool) or not isinstance(points, (int, float)) or not points > 0:
        raise ValueError(f"{where}: metadata kfcal.points must be a positive number, not {points!r}")
    lines, region, last_closed = [], None, None
    for number, text in enumerate(cell["source"].split("\n"), start=1):
        marker = text.strip()
        if marker.startswith("###") and marker.upper().replace(" ", "") in {m.replace(" ", "") for m in MARKERS} \
                and marker not in MARKERS:
            raise ValueError(f"{where}, line {number}: write the marker exactly as {marker.upper()!r}")
        if marker in (BEGIN_PLACEHOLDER, BEGIN_SOLUTION):
            if region is not None:
                raise ValueError(f"{where}, line {number}: {marker!r} inside the {region} region (regions do not nest)")
            region = "placeholder" if marker == BEGIN_PLACEHOLDER else "solution"
            if region == "placeholder" and last_closed == "placeholder":
                raise ValueError(f"{where}, line {number}: a placeholder region must be followed by a solution region")
            lines.append(("marker", text))
        elif marker in (END_PLACEHOLDER, END_SOLUTION):
            wanted = "placeholder" if marker == END_PLACEHOLDER else "solution"
            if region != wanted:
                raise ValueError(f"{where}, line {number}: {marker!r} without its BEGIN line")
            region, last_closed = None, wanted
            lines.append(("marker", text))
        else:
            if region is None and last_closed == "placeholder" and marker:
                raise ValueError(f"{where}, line {number}: a placeholder region must be followed directly by a "
                                 f"solution region")
            if region is None and marker:
                last_closed = None
            lines.append((region, text))
    if region is not None:
        raise ValueError(f"{where}: the {region} region is not closed (### END {region.upper()} missing)")
    if last_closed == "placeholder":
        raise ValueError(f"{where}: a placeholder region must be followed by a solution region")
    if not any(r == "marker" and t.strip() == BEGIN_SOLUTION for r, t in lines):
        raise ValueError(f"{where}: an answer cell needs a ### BEGIN SOLUTION ... ### END SOLUTION region")
    while lines and lines[-1][0] is None and not lines[-1][1].strip():
        lines.pop()
    last = lines[-1] if lines else ("marker", "")
    match = _CHECK_CALL.match(last[1])
    if last[0] is not None or match is None:
        raise ValueError(f"{where}: the last line must be the check call check_xxx(answer_NN_k), outside the regions")
    return AnswerCell(lines, match.group(1), match.group(2), exercise, points)


def _copy_cell(cell, source: str):
    out = copy.deepcopy(cell)
    out["source"] = source
    meta = out.get("metadata", {})
    meta.pop("kfcal", None)
    meta.pop("execution", None)
    if out["cell_type"] == "code":
        out["outputs"], out["execution_count"] = [], None
    return out


def validate(nb) -> None:
    """Check every cell's role (and every answer cell); ``ValueError`` naming the first bad cell."""
    seen = {}
    for index, cell in enumerate(nb["cells"]):
        role, _ = _role(index, cell)
        if cell.get("cell_type") == "code" and (cell.get("outputs") or cell.get("execution_count")):
            raise ValueError(f"{_where(index, cell)}: a source notebook holds no outputs (clear them)")
        if role == "answer":
            answer = parse_answer(index, cell)
            if answer.exercise in seen:
                raise ValueError(f"{_where(index, cell)}: exercise {answer.exercise} has a second answer cell "
                                 f"(the first is source cell {seen[answer.exercise]})")
            seen[answer.exercise] = index


def answer_cells(nb) -> list[tuple[int, AnswerCell]]:
    """``[(index, AnswerCell)]`` of the source ``nb``'s answer cells, in order."""
    return [(i, parse_answer(i, c)) for i, c in enumerate(nb["cells"]) if _role(i, c)[0] == "answer"]


def render(nb, which: str):
    """The ``"lesson"`` or ``"solutions"`` notebook of the source ``nb`` (a new notebook; cells unexecuted)."""
    if which not in ("lesson", "solutions"):
        raise ValueError(f"which must be 'lesson' or 'solutions', not {which!r}")
    validate(nb)
    out = copy.deepcopy(nb)
    out["metadata"].pop("kfcal", None)
    cells = []
    for index, cell in enumerate(nb["cells"]):
        role, _ = _role(index, cell)
        if role == "answer":
            answer = parse_answer(index, cell)
            text = answer.lesson_source() if which == "lesson" else answer.solution_source()
            cells.append(_copy_cell(cell, text))
        elif role == "exercise" or (role is None) == (which == "lesson"):
            cells.append(_copy_cell(cell, cell["source"]))
    out["cells"] = cells
    return out


def render_lesson(nb):
    """The lesson notebook of the source ``nb``: lesson and exercise cells, answers as placeholders."""
    return render(nb, "lesson")


def render_solutions(nb):
    """The worked-solutions notebook of the source ``nb``: exercise and solution cells, answers solved."""
    return render(nb, "solutions")


def _cell_ids(nb) -> None:
    """Give each cell an id made from its type and text (a text source has none): the same cell gets the
    same id in every reading, and an edit changes only its own cell's id."""
    seen = set()
    for cell in nb.cells:
        base = hashlib.sha1(f"{cell.cell_type}\n{cell.source}".encode()).hexdigest()[:8]
        cell_id, k = base, 1
        while cell_id in seen:
            k += 1
            cell_id = f"{base}-{k}"
        seen.add(cell_id)
        cell["id"] = cell_id


def read_source(path, *, with_lines: bool = False):
    """The source notebook at ``path`` (``NN_name.md``, a MyST Markdown notebook), read by myst-nb's
    reader, as an nbformat notebook (version 4.5) whose cells have ids made from their text.  With
    ``with_lines``, ``(notebook, lines)``: the line of the file (from 1) where each cell's marker is.
    ``ValueError`` naming the file (and the cell and line) when it cannot be read."""
    path = Path(path)
    try:
        from myst_nb.core.read import read_myst_markdown_notebook
    except ImportError:
        raise ValueError(f"{path.name}: reading a source notebook needs myst-nb: "
                         f"pip install -r environment.txt") from None
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path.name}: cannot be read ({exc})") from None
    try:
        nb = read_myst_markdown_notebook(text, add_source_map=True, path=path)
    except Exception as exc:   # MystMetadataParsingError, a YAML error of the front matter, a bad :load:
        raise ValueError(f"{path.name}: {' '.join(str(exc).split())}") from None
    starts = nb.metadata.pop("source_map")
    if not isinstance(nb.metadata, dict) or any(not isinstance(c.metadata, dict) for c in nb.cells):
        raise ValueError(f"{path.name}: metadata must be mappings")
    nb.nbformat, nb.nbformat_minor = 4, 5
    _cell_ids(nb)
    if with_lines:
        lines = text.splitlines()
        return nb, [start if c.cell_type == "code"   # the fence's line
                    else next((j for j in range(start, len(lines)) if lines[j].strip()), start) + 1   # its first line
                    for start, c in zip(starts, nb.cells)]
    return nb
