"""An nbgrader course made from the source notebooks.

Each lesson with exercises becomes one assignment, named after the notebook's stem, whose source
notebook is the lesson with every answer cell turned into two nbgrader cells:

* an *autograded answer* cell: the answer cell's common and placeholder lines and its solution
  region (between ``### BEGIN SOLUTION`` and ``### END SOLUTION``, which nbgrader clears in the
  release, leaving our placeholder); the check call is removed.  The first one also holds, as a
  solution region, the worked solutions' setup code (their own settings, e.g. ``dt = 0.01``), so that
  the instructor's version, lesson and worked answers together, earns full marks;
* an *autograder tests* cell worth the exercise's points, which calls
  ``record_answer("NN.k", "kfcal_helpers.<problem>.exercises", "check_xxx", answer)``
  (:mod:`kfcal_helpers.exercises.grading`): the student sees the check's one-line verdict, and the
  answer is recorded as data.  The grade is not decided in the student's kernel: the course's
  ``nbgrader_config.py`` adds :class:`._regrade.RecheckAnswers` to ``nbgrader autograde``, which
  re-checks every record in a fresh Python process and writes each verdict in its grade cell (the ✔
  line, or an error whose one line is the check's hint: nbgrader shows it in the feedback).

The sentence that links to the worked solutions ("Worked solutions: [...](...)") is dropped, and the
lesson cells after the last exercise (the checks of the numbers quoted in the text) move before the
exercises, so that no answer can change what they check.
nbgrader itself (``environment-instructors.txt``) is imported only by :func:`generate`.
"""

from __future__ import annotations

import copy
import os
import re
import shutil
from pathlib import Path

from ._source import BEGIN_SOLUTION, END_SOLUTION, parse_answer, read_source, validate
from ._sync import located, write_notebook

__all__ = ["COURSE_ID", "INSTRUCTORS_FILE", "SOLUTIONS_LINK", "check_modules", "nbgrader_notebook", "write_course",
           "generate", "nbgrader_missing", "autograde_preprocessors"]

COURSE_ID = "kfcal"
#: the pip requirements file that adds nbgrader to environment.txt
INSTRUCTORS_FILE = "environment-instructors.txt"
#: the sentence of the exercises' introduction that links to the worked solutions
SOLUTIONS_LINK = re.compile(r"\s*Worked\s+solutions:\s*\[[^\]]*\]\([^)]*\)\.?")
_PACKAGE = Path(__file__).resolve().parents[1]

CONFIG = '''"""nbgrader configuration of the course made by python -m kfcal_helpers assignments --course."""

import os

os.environ.setdefault("KFCAL_QUIET", "1")   # no progress bars in the autograded notebooks

c = get_config()  # noqa: F821 (defined by nbgrader when it reads this file)
c.CourseDirectory.course_id = {course_id!r}
c.CourseDirectory.root = os.path.dirname(os.path.abspath(__file__)) if "__file__" in globals() else os.getcwd()
# the release keeps the lesson's own placeholder ("answer = ...   # replace ... with your answer")
c.ClearSolutions.code_stub = {{"python": ""}}
# some lessons run short Monte Carlo runs: allow a cell a few minutes
c.Execute.timeout = 600
# the answers recorded by the grade cells are re-checked outside the student's kernel, after execution
from kfcal_helpers.assignments import autograde_preprocessors, feedback_template_dirs  # noqa: E402
c.Autograde.autograde_preprocessors = autograde_preprocessors()
# the grade cells it could not grade (no record, or one forged or altered): one row each
c.RecheckAnswers.report = os.path.join(c.CourseDirectory.root, "grading_flags.csv")
# the feedback pages carry MathJax inside them: their equations show offline
_templates = feedback_template_dirs(c.CourseDirectory.root)
if _templates:
    c.HTMLExporter.extra_template_basedirs = _templates
'''


def check_modules(package: Path = _PACKAGE) -> dict[str, str]:
    """``{check function name: module}`` for every ``check_*`` that ``kfcal_helpers.<problem>.exercises`` lists
    in its ``__all__`` (a module ``exercises.py`` or a package ``exercises/``, imported)."""
    import importlib

    out = {}
    for folder in sorted(p for p in package.iterdir() if p.is_dir()):
        if not ((folder / "exercises.py").is_file() or (folder / "exercises" / "__init__.py").is_file()):
            continue
        module = f"{package.name}.{folder.name}.exercises"
        for name in getattr(importlib.import_module(module), "__all__", ()):
            if name.startswith("check_"):
                out[name] = module
    return out


def _grade_id(exercise: str) -> str:
    return "ex_" + exercise.replace(".", "_")


def nbgrader_notebook(nb, modules: dict[str, str] | None = None):
    """The nbgrader source notebook of the source notebook ``nb`` (see the module's docstring)."""
    import nbformat

    validate(nb)
    modules = check_modules() if modules is None else modules
    out = copy.deepcopy(nb)
    out["metadata"].pop("kfcal", None)
    cells = []
    setup = []   # the worked solutions' setup: code cells of the solutions before the first answer cell
    for index, cell in enumerate(nb["cells"]):
        role = cell.get("metadata", {}).get("kfcal", {}).get("role")
        if role == "solution":
            if cell["cell_type"] == "code" and setup is not None:
                setup.append(cell["source"])
            continue
        new = copy.deepcopy(cell)
        new["metadata"].pop("kfcal", None)
        if role != "answer":
            if new["cell_type"] == "markdown":
                new["source"] = SOLUTIONS_LINK.sub("", new["source"])
            cells.append(new)
            continue
        answer = parse_answer(index, cell)
        if answer.check not in modules:
            raise ValueError(f"source cell {index} (id {cell.get('id')}): no check named {answer.check} in "
                             f"kfcal_helpers/*/exercises.py")
        lines = []
        if setup:   # the instructor's version runs the worked answers with their own setup
            lines += [f"{BEGIN_SOLUTION}   (the worked solutions' setup)", *"\n\n".join(setup).split("\n"),
                      END_SOLUTION]
        setup = None
        for region, text in answer.lines[:-1]:
            if region == "marker" and text.strip() not in (BEGIN_SOLUTION, END_SOLUTION):
                continue
            lines.append(text)
        while lines and not lines[-1].strip():
            lines.pop()
        grade_id = _grade_id(answer.exercise)
        new["source"] = "\n".join(lines)
        new["metadata"]["nbgrader"] = {"grade": False, "grade_id": grade_id, "locked": False, "schema_version": 3,
                                       "solution": True, "task": False}
        cells.append(new)
        test = nbformat.v4.new_code_cell(
            f"# the check of exercise {answer.exercise} ({answer.points:g} point{'s' if answer.points != 1 else ''}):"
            f" shows ✔ or a hint; the grader checks the recorded answer again\n"
            f"from kfcal_helpers.exercises.grading import record_answer\n"
            f"record_answer({answer.exercise!r}, {modules[answer.check]!r}, {answer.check!r}, {answer.answer})")
        test["id"] = (cell.get("id") or grade_id)[:40] + "-check"
        test["metadata"]["nbgrader"] = {"grade": True, "grade_id": grade_id + "_check", "locked": True,
                                        "points": answer.points, "schema_version": 3, "solution": False,
                                        "task": False}
        cells.append(test)
    out["cells"] = _checks_before_exercises(cells)
    return out


def _checks_before_exercises(cells):
    """The lesson cells after the last graded cell (the checks of the numbers quoted in the text) moved
    before the exercises (the first "## Exercises" cell, else the first exercise cell): a student's
    answer, or the worked solutions' setup, cannot change what they check."""
    graded = [i for i, c in enumerate(cells) if c.get("metadata", {}).get("nbgrader", {}).get("grade")]
    if not graded:
        return cells
    tail = cells[graded[-1] + 1:]
    head = cells[:graded[-1] + 1]
    start = next((i for i, c in enumerate(head) if c["cell_type"] == "markdown"
                  and c["source"].lstrip().startswith("## Exercises")), None)
    if start is None:
        start = next(i for i, c in enumerate(head) if "nbgrader" in c.get("metadata", {}))
        while start > 0 and head[start - 1]["cell_type"] == "markdown" and head[start - 1]["source"].startswith("**"):
            start -= 1
    return head[:start] + tail + head[start:]


def autograde_preprocessors() -> list:
    """nbgrader's autograde preprocessors with the re-check of the recorded answers after execution
    (:func:`._regrade.autograde_preprocessors`; for the course's ``nbgrader_config.py``).  Needs nbgrader."""
    from ._regrade import autograde_preprocessors as preprocessors

    return preprocessors()


def nbgrader_missing() -> str | None:
    """None when nbgrader can be imported, else the one-line reason (naming :data:`INSTRUCTORS_FILE`)."""
    try:
        import nbgrader  # noqa: F401
    except ImportError:
        return f"nbgrader is not installed: pip install -r {INSTRUCTORS_FILE} (the instructors' pins)"
    return None


def write_course(course: Path, sources: list[Path]) -> list[str]:
    """Write ``course/nbgrader_config.py`` and ``course/source/<stem>/<stem>.ipynb`` for every source
    (``notebooks/source/NN_name.md``) with an answer cell; returns the assignment names.  A source
    notebook already in the course is replaced; nothing else there is touched.  The cells keep the ids
    :func:`._source.read_source` gives them (made from their text), so the same sources make the same
    course."""
    course = Path(course)
    modules = check_modules()
    names = []
    made = []
    for path in sources:
        nb, lines = read_source(path, with_lines=True)
        if not any(isinstance(c.get("metadata", {}).get("kfcal"), dict) and c.metadata["kfcal"].get("role") == "answer"
                   for c in nb.cells):
            continue
        try:
            made.append((path.stem, nbgrader_notebook(nb, modules)))
        except ValueError as exc:
            raise ValueError(located(path, lines, exc)) from None
    course.mkdir(parents=True, exist_ok=True)
    config = course / "nbgrader_config.py"
    partial = course / ".nbgrader_config.py.tmp"
    partial.write_text(CONFIG.format(course_id=COURSE_ID), encoding="utf-8")
    os.replace(partial, config)
    for name, nb in made:
        folder = course / "source" / name
        folder.mkdir(parents=True, exist_ok=True)
        write_notebook(nb, folder / f"{name}.ipynb")
        names.append(name)
    return names


def generate(course: Path, names: list[str], log=print) -> None:
    """Run nbgrader's ``generate_assignment`` for each assignment in ``names`` (into ``course/release/``),
    adding it to the course's gradebook.  Needs nbgrader (:func:`nbgrader_missing`)."""
    from nbgrader.apps import NbGraderAPI
    from traitlets.config import Config

    course = Path(course).resolve()
    config = Config()
    config.CourseDirectory.root = str(course)
    config.CourseDirectory.course_id = COURSE_ID
    config.ClearSolutions.code_stub = {"python": ""}
    api = NbGraderAPI(config=config)
    for name in names:
        release = course / "release" / name
        if release.exists():
            shutil.rmtree(release)
        result = api.generate_assignment(name, force=True, create=True)
        if not result.get("success"):
            error = " ".join(str(result.get("error") or result.get("log") or "unknown error").split())
            raise ValueError(f"nbgrader generate_assignment {name} failed: {error[-300:]}")
        log(f"released {name}")
