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

What the reader accepts (anything else is a ``ValueError`` naming the file, and the line where it can):
a regular file (links resolved; no FIFO, device or directory) of at most :data:`MAX_SOURCE_BYTES`,
checked before reading (:func:`kfcal_helpers.files.read_regular`), in UTF-8, not empty, of at most
:data:`MAX_CELLS` cells (counted before it is parsed); no ``:load:``
option (a cell's code is written in the cell); YAML metadata blocks (the front matter, a code cell's
options) of at most :data:`MAX_METADATA_BYTES` each, without anchors or aliases (``&name``, ``*name``:
a few hundred bytes of them expand to gigabytes); and metadata that is JSON (string keys; strings,
finite numbers, booleans, null, lists and mappings, nested at most :data:`MAX_METADATA_DEPTH` deep),
since it is written to ``.ipynb`` files: a YAML date, set or binary is refused, not written.
"""

from __future__ import annotations

import copy
import hashlib
import math
import re
import textwrap
from pathlib import Path

from ..files import read_regular

__all__ = ["ROLES", "MARKERS", "AnswerCell", "parse_answer", "render", "render_lesson", "render_solutions",
           "answer_cells", "validate", "read_source", "source_indices", "SOURCE_SUFFIX", "MAX_SOURCE_BYTES",
           "MAX_CELLS", "MAX_METADATA_BYTES", "MAX_METADATA_DEPTH"]

#: the file suffix of a source notebook (``notebooks/source/NN_name.md``)
SOURCE_SUFFIX = ".md"
#: the largest source notebook read, bytes (the largest lesson has 49 kB; a source of this many short
#: paragraphs, the most markdown-it tokens, renders within the command line's 500 MB)
MAX_SOURCE_BYTES = 262_144
#: the most cells a source notebook may have (cell markers: code and raw fences, ``+++`` lines; the lessons
#: have at most 40)
MAX_CELLS = 1000
#: the largest YAML metadata block (the front matter, a code cell's options), bytes (the lessons' are < 1 kB)
MAX_METADATA_BYTES = 65_536
#: how deep metadata may nest (mappings and lists)
MAX_METADATA_DEPTH = 50

#: the roles a source cell may have (None: a lesson cell)
ROLES = (None, "exercise", "solution", "answer")
BEGIN_PLACEHOLDER, END_PLACEHOLDER = "### BEGIN PLACEHOLDER", "### END PLACEHOLDER"
BEGIN_SOLUTION, END_SOLUTION = "### BEGIN SOLUTION", "### END SOLUTION"
#: the four marker lines of an answer cell (compared after stripping the indentation)
MARKERS = (BEGIN_PLACEHOLDER, END_PLACEHOLDER, BEGIN_SOLUTION, END_SOLUTION)
_CHECK_CALL = re.compile(r"^(check_\w+)\(([A-Za-z_]\w*)\)\s*$")
_EXERCISE_ID = re.compile(r"^\d\d[a-z]?\.\d+$")
#: a line that starts a cell (a superset of what myst-nb's reader takes: counted before it parses)
_CELL_MARKER = re.compile(r"^ {0,3}(?:(?:`{3,}|~{3,})\s*\{(?:code|raw)-cell\}|\+\+\+)", re.MULTILINE)


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
    if isinstance(points, bool) or not isinstance(points, (int, float)) or not points > 0 \
            or not math.isfinite(points):
        raise ValueError(f"{where}: metadata kfcal.points must be a positive finite number, not {points!r}")
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


def _rendered(nb, which: str) -> list[tuple[int, dict]]:
    """``[(source index, cell)]`` of the ``which`` notebook of the source ``nb``, in order."""
    if which not in ("lesson", "solutions"):
        raise ValueError(f"which must be 'lesson' or 'solutions', not {which!r}")
    validate(nb)
    cells = []
    for index, cell in enumerate(nb["cells"]):
        role, _ = _role(index, cell)
        if role == "answer":
            answer = parse_answer(index, cell)
            text = answer.lesson_source() if which == "lesson" else answer.solution_source()
            cells.append((index, _copy_cell(cell, text)))
        elif role == "exercise" or (role is None) == (which == "lesson"):
            cells.append((index, _copy_cell(cell, cell["source"])))
    return cells


def render(nb, which: str):
    """The ``"lesson"`` or ``"solutions"`` notebook of the source ``nb`` (a new notebook; cells unexecuted)."""
    cells = _rendered(nb, which)
    out = copy.deepcopy(nb)
    out["metadata"].pop("kfcal", None)
    out["cells"] = [cell for _, cell in cells]
    return out


def source_indices(nb, which: str) -> list[int]:
    """The index of the source cell each cell of the ``which`` notebook of the source ``nb`` comes from."""
    return [index for index, _ in _rendered(nb, which)]


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


def _yaml_blocks(text: str) -> list[tuple[int, str, bool]]:
    """``[(line, yaml, is_cell_options)]``: the YAML blocks myst-nb's reader loads from the source ``text``
    (the front matter, each top-level code or raw cell's options block, ``---`` fenced or ``:key:`` lines),
    found as that reader finds them; ``line`` (from 1) is the block's first line in the file."""
    import dataclasses

    from markdown_it.renderer import RendererHTML
    from myst_parser.config.main import MdParserConfig
    from myst_parser.parsers.mdit import create_md_parser

    config = MdParserConfig()
    config = dataclasses.replace(config, disable_syntax=[*config.disable_syntax, "inline"])
    tokens = create_md_parser(config, RendererHTML).parse(text + "\n")
    blocks, nesting = [], 0
    for k, token in enumerate(tokens):
        nesting += token.nesting
        start = token.map[0] if token.map else 0
        if k == 0 and token.type == "front_matter":
            blocks.append((start + 2, token.content, False))
        elif nesting == 0 and token.type == "fence" and token.info.startswith(("{code-cell}", "{raw-cell}")):
            lines = token.content.splitlines()
            if token.content.startswith("---"):
                end = next((j for j in range(1, len(lines)) if lines[j].startswith("---")), len(lines))
                blocks.append((start + 3, textwrap.dedent("\n".join(lines[1:end])), True))
            elif token.content.lstrip().startswith(":"):
                options = []
                for line in lines:
                    stripped = line.lstrip()
                    if not stripped.startswith(":") or stripped.startswith(":::"):
                        break
                    options.append(stripped[1:])
                blocks.append((start + 2, "\n".join(options), True))
    return blocks


def _check_yaml(name: str, text: str) -> None:
    """Refuse, before myst-nb loads them, the YAML blocks of the source ``text`` (of file ``name``) that are
    too large, hold an anchor or an alias, or give a cell the ``:load:`` option."""
    import yaml

    for line, block, cell in _yaml_blocks(text):
        if len(block.encode("utf-8")) > MAX_METADATA_BYTES:
            raise ValueError(f"{name}, line {line}: a metadata block of more than {MAX_METADATA_BYTES // 1024} kB")
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)   # libyaml's when there: 50 times faster
        try:
            for token in yaml.scan(block, Loader=loader):
                if isinstance(token, (yaml.AnchorToken, yaml.AliasToken)):
                    raise ValueError(f"{name}, line {line + token.start_mark.line}: YAML anchors and aliases "
                                     f"(&name, *name) are not allowed in a source's metadata: write the value out")
            options = yaml.load(block, Loader=loader) if cell and "load" in block else None
        except (yaml.YAMLError, RecursionError):
            continue  # myst-nb's reader reports it
        if isinstance(options, dict) and "load" in options:
            raise ValueError(f"{name}, line {line}: a source notebook takes no :load: option (write the code "
                             f"into the cell)")


def _not_json(value, where: str) -> str | None:
    """What in ``value`` (metadata, at ``where``) is not JSON, or None."""
    stack = [(value, where, 0)]
    while stack:
        item, at, depth = stack.pop()
        if depth > MAX_METADATA_DEPTH:
            return f"{at} nests more than {MAX_METADATA_DEPTH} levels deep"
        if isinstance(item, dict):
            for key, sub in item.items():
                if not isinstance(key, str):
                    return (f"{at} has the key {repr(key)[:40]}, a {type(key).__name__}: a key must be a "
                            f"string (JSON)")
                stack.append((sub, f"{at}.{key[:40]}", depth + 1))
        elif isinstance(item, list):
            stack.extend((sub, f"{at}[{i}]", depth + 1) for i, sub in enumerate(item))
        elif isinstance(item, float) and not math.isfinite(item):
            return f"{at} is {item}, not a finite number (JSON)"
        elif not (item is None or isinstance(item, (str, int, float))):
            return f"{at} is a {type(item).__name__} ({repr(item)[:40]}), not a JSON value (quote it as a string)"
    return None


def read_source(path, *, with_lines: bool = False):
    """The source notebook at ``path`` (``NN_name.md``, a MyST Markdown notebook), read by myst-nb's
    reader, as an nbformat notebook (version 4.5) whose cells have ids made from their text.  With
    ``with_lines``, ``(notebook, lines)``: the line of the file (from 1) where each cell's marker is.
    ``ValueError`` naming the file (and the cell and line) when it cannot be read or breaks a rule of
    the module docstring (a FIFO, a file over :data:`MAX_SOURCE_BYTES`, ``:load:``, a YAML alias,
    metadata that is not JSON)."""
    path = Path(path)
    try:
        from myst_nb.core.read import read_myst_markdown_notebook
    except ImportError:
        raise ValueError(f"{path.name}: reading a source notebook needs myst-nb: "
                         f"pip install -r environment.txt") from None
    data = read_regular(path, MAX_SOURCE_BYTES, argname=None,
                        regular_only="a source notebook is read from regular files only",
                        too_large=f"{path}: larger than the {MAX_SOURCE_BYTES // 1024} kB a source notebook "
                                  f"may have (the largest lesson has 49 kB)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path.name}: cannot be read (not UTF-8 text: byte {exc.start})") from None
    del data
    if not text.strip():
        raise ValueError(f"{path.name}: the source notebook is empty")
    markers = sum(1 for _ in _CELL_MARKER.finditer(text))
    if markers > MAX_CELLS:
        raise ValueError(f"{path.name}: {markers} cells, more than the {MAX_CELLS} a source notebook may have "
                         f"(the lessons have at most 40)")
    try:
        _check_yaml(path.name, text)
        # no path: myst-nb's reader then refuses :load: (which would read any file) instead of reading it
        nb = read_myst_markdown_notebook(text, add_source_map=True, path=None)
    except ValueError:
        raise
    except Exception as exc:   # MystMetadataParsingError, a YAML error of the front matter, a deep nesting
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise ValueError(f"{path.name}: {reason}") from None
    starts = nb.metadata.pop("source_map")
    if not isinstance(nb.metadata, dict) or any(not isinstance(c.metadata, dict) for c in nb.cells):
        raise ValueError(f"{path.name}: metadata must be mappings")
    lines = text.splitlines()
    cell_lines = [start if c.cell_type == "code"   # the fence's line
                  else next((j for j in range(start, len(lines)) if lines[j].strip()), start) + 1   # its first line
                  for start, c in zip(starts, nb.cells)]
    problem = _not_json(nb.metadata, "the front matter")
    if problem is not None:
        raise ValueError(f"{path.name}, line 1: {problem}")
    for index, (line, cell) in enumerate(zip(cell_lines, nb.cells)):
        problem = _not_json(cell.metadata, f"source cell {index}: metadata")
        if problem is not None:
            raise ValueError(f"{path.name}, line {line}: {problem}")
    nb.nbformat, nb.nbformat_minor = 4, 5
    _cell_ids(nb)
    return (nb, cell_lines) if with_lines else nb
