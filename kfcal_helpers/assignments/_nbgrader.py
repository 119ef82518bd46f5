"""An nbgrader course made from the source notebooks.

Each lesson with exercises becomes one assignment (unless its source says ``kfcal: {graded: false}``:
:func:`graded`), named after the notebook's stem, whose source
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
import sys
from pathlib import Path

from ._source import BEGIN_SOLUTION, END_SOLUTION, parse_answer, read_source, validate
from ._sync import located, write_notebook

__all__ = ["COURSE_ID", "INSTRUCTORS_FILE", "SOLUTIONS_LINK", "check_modules", "nbgrader_notebook", "write_course",
           "generate", "nbgrader_missing", "check_course_dir", "graded", "autograde_preprocessors"]

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
#: the first line of the course's ``nbgrader_config.py``: a folder whose config starts with it is a course
#: this command made (and may make again)
CONFIG_FIRST_LINE = CONFIG.split("\n", 1)[0]


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


def _repositories(notebooks: Path | None) -> list[Path]:
    """The folders a course must stay out of: the notebooks folder, and the repository holding it or this
    package (a folder with ``pyproject.toml`` or ``.git``)."""
    notebooks = [] if notebooks is None else [Path(notebooks).resolve()]
    candidates = [_PACKAGE.parent, *(folder.parent for folder in notebooks)]
    return [folder for folder in candidates
            if (folder / "pyproject.toml").exists() or (folder / ".git").exists()] + notebooks


def check_course_dir(course: Path, notebooks: Path | None = None) -> Path:
    """``course`` if a course may be written there, else ``ValueError`` (one line, naming ``--course``):
    a folder inside the repository (or the notebooks folder ``notebooks``) is refused, and so is a folder
    that holds anything and is not a course made here before (its ``nbgrader_config.py`` starts with
    :data:`CONFIG_FIRST_LINE`).  A course made before keeps all its files when it is made again."""
    from ..output import path_text

    course = Path(course)
    where = course.resolve()
    for folder in _repositories(notebooks):
        if where == folder or where.is_relative_to(folder):
            raise ValueError(f"--course: {path_text(course)} is inside {path_text(folder)}: make the course in a "
                             f"folder of its own outside the repository (e.g. ~/kf-course)")
    try:
        holds = where.is_dir() and any(where.iterdir())
    except OSError as exc:
        raise ValueError(f"--course: {path_text(course)} cannot be read ({exc.strerror})") from None
    if holds:
        config = where / "nbgrader_config.py"
        try:
            first = config.read_text(encoding="utf-8").split("\n", 1)[0]
        except (OSError, UnicodeDecodeError):
            first = None
        if first != CONFIG_FIRST_LINE:
            raise ValueError(f"--course: {path_text(course)} holds files and is not a course made by this command: "
                             f"name a new or empty folder")
    return course


def graded(nb) -> bool:
    """Whether the source notebook ``nb`` has a graded assignment: it has an answer cell and its metadata
    does not say ``kfcal: {graded: false}`` (lessons whose exercises are self-checks, their answers in
    the text)."""
    meta = nb.get("metadata", {}).get("kfcal", {})
    if not isinstance(meta, dict) or set(meta) - {"graded"} or not isinstance(meta.get("graded", True), bool):
        raise ValueError(f"the front matter's kfcal must be {{graded: false}} or absent, not {meta!r}")
    return meta.get("graded", True) and any(
        isinstance(c.get("metadata", {}).get("kfcal"), dict) and c.metadata["kfcal"].get("role") == "answer"
        for c in nb.cells)


def write_course(course: Path, sources: list[Path]) -> list[str]:
    """Write ``course/nbgrader_config.py`` and ``course/source/<stem>/<stem>.ipynb`` for every source
    (``notebooks/source/NN_name.md``) that is :func:`graded`; returns the assignment names.  A source
    notebook already in the course is replaced; nothing else there is touched (hand-ins, autograded
    notebooks, feedback and the gradebook stay).  The cells keep the ids
    :func:`._source.read_source` gives them (made from their text), so the same sources make the same
    course."""
    course = Path(course)
    modules = check_modules()
    names = []
    made = []
    for path in sources:
        nb, lines = read_source(path, with_lines=True)
        try:
            if not graded(nb):
                continue
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
    adding it to the course's gradebook, with the course's own ``nbgrader_config.py`` (the settings the
    graders' ``nbgrader`` commands read).  nbgrader starts its ``alembic`` command by name to make the
    gradebook: the running interpreter's scripts folder goes first on the PATH while it runs, so that an
    environment that is not activated works too.  Needs nbgrader (:func:`nbgrader_missing`)."""
    import sysconfig

    from nbgrader.apps import NbGraderAPI
    from traitlets.config.loader import ConfigFileNotFound, PyFileConfigLoader

    from ..output import path_text

    course = Path(course).resolve()
    quiet = os.environ.get("KFCAL_QUIET")   # the file sets it for nbgrader's own processes, not for this one
    try:
        config = PyFileConfigLoader("nbgrader_config.py", path=str(course)).load_config()
    except ConfigFileNotFound:
        raise ValueError(f"{path_text(course)} has no nbgrader_config.py (write_course writes it)") from None
    except Exception as exc:   # the file is Python: any error it raises
        raise ValueError(f"{path_text(course / 'nbgrader_config.py')} does not load: "
                         f"{type(exc).__name__}: {' '.join(str(exc).split())}") from None
    finally:
        if quiet is None:
            os.environ.pop("KFCAL_QUIET", None)
        else:
            os.environ["KFCAL_QUIET"] = quiet
    config.CourseDirectory.root = str(course)
    config.CourseDirectory.course_id = COURSE_ID
    scripts = [sysconfig.get_path("scripts"), os.path.dirname(sys.executable)]
    path = os.pathsep.join(dict.fromkeys([*scripts, os.environ.get("PATH", "")]))
    if not (course / "gradebook.db").exists() and shutil.which("alembic", path=path) is None:
        raise ValueError(f"nbgrader's alembic command is not in {path_text(Path(scripts[0]))}: "
                         f"pip install -r {INSTRUCTORS_FILE} into the environment that runs this command")
    old_path = os.environ.get("PATH")
    os.environ["PATH"] = path
    try:
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
    finally:
        if old_path is None:
            os.environ.pop("PATH", None)
        else:
            os.environ["PATH"] = old_path
