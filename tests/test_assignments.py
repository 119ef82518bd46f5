"""notebooks/source renders exactly the committed lessons and solutions; the renderer's roles and
regions, its errors, the nbgrader conversion, and the ``assignments`` command's errors."""

import contextlib
import io
import shutil
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import nbformat
import pytest

from kfcal_helpers import assignments
from kfcal_helpers.cli import main
from kfcal_helpers.assignments import (differing, nbgrader_notebook, parse_answer, read_source, render_lesson,
                                       render_solutions, sync)

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"


def cli(*args):
    """``python -m kfcal_helpers assignments ARGS`` through ``kfcal_helpers.cli.main`` in this process
    (what the entry point runs; :func:`test_cli_error_in_a_real_process` runs the entry point itself):
    ``(returncode, stdout, stderr)``."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["assignments", *map(str, args)])
    return Run(code, out.getvalue(), err.getvalue())


class Run(NamedTuple):
    returncode: int
    stdout: str
    stderr: str


def one_error_line(proc):
    lines = proc.stderr.splitlines()
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert len(lines) == 1 and lines[0].startswith("python -m kfcal_helpers assignments: error: "), proc.stderr
    assert "Traceback" not in proc.stderr
    return lines[0]


def source(*cells):
    nb = nbformat.v4.new_notebook()
    nb.metadata = {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}}
    for kind, text, meta in cells:
        cell = (nbformat.v4.new_code_cell if kind == "code" else nbformat.v4.new_markdown_cell)(text)
        if meta is not None:
            cell.metadata["kfcal"] = meta
        nb.cells.append(cell)
    return nb


ANSWER = {"role": "answer", "exercise": "99.1", "points": 2}
FUNCTION = """def f(x):
    \"\"\"twice x\"\"\"
    ### BEGIN PLACEHOLDER
    ...   # replace ... with your code
    ### END PLACEHOLDER
    ### BEGIN SOLUTION
    y = 2 * x
    return y
    ### END SOLUTION

answer_99_1 = f
check_double(answer_99_1)"""


def tiny():
    return source(("markdown", "# Lesson\n\nWorked solutions: [solutions/99_x.ipynb](solutions/99_x.ipynb).", None),
                  ("code", "x = 1", None),
                  ("markdown", "# Solutions 99", {"role": "solution"}),
                  ("markdown", "**Exercise 99.1 — double.** Write f.", {"role": "exercise"}),
                  ("markdown", "**Solution.** Multiply.", {"role": "solution"}),
                  ("code", FUNCTION, ANSWER),
                  ("code", "assert f(2) == 4", {"role": "solution"}),
                  ("markdown", "## Checks", None))


# ------------------------------------------------------------------------------------------------
# the committed notebooks and their sources
# ------------------------------------------------------------------------------------------------
def test_every_committed_lesson_and_solution_equals_what_its_source_renders():
    names = sorted(p.stem for p in (NOTEBOOKS / "source").glob("*.md"))
    assert names == sorted(p.stem for p in NOTEBOOKS.glob("[0-9][0-9]*_*.ipynb"))   # one source per lesson
    assert sorted(p.name for p in (NOTEBOOKS / "source").iterdir()) == [f"{n}.md" for n in names]  # and nothing else
    solved = [t.path.name for t in assignments.targets() if t.which == "solutions"]
    assert solved == sorted(p.name for p in (NOTEBOOKS / "solutions").glob("*.ipynb"))
    assert differing() == []


def test_no_notebook_of_the_repository_is_left_unexecuted():
    """The house rule: every .ipynb is committed executed top to bottom (the sources are text)."""
    for path in sorted(NOTEBOOKS.rglob("*.ipynb")):
        if ".ipynb_checkpoints" in path.parts:
            continue
        nb = nbformat.read(path, 4)
        counts = [c.execution_count for c in nb.cells if c.cell_type == "code"]
        assert counts == list(range(1, len(counts) + 1)), path


@pytest.fixture
def copy_01(tmp_path):
    """notebooks/ of one lesson (01) in a temporary folder: source, lesson, solutions."""
    name = "01_truth_model.ipynb"
    (tmp_path / "source").mkdir()
    (tmp_path / "solutions").mkdir()
    for rel in ("source/01_truth_model.md", name, f"solutions/{name}"):
        shutil.copy(NOTEBOOKS / rel, tmp_path / rel)
    return tmp_path, name


def edit_source(folder, exercise, edit):
    """Replace the text of exercise ``exercise``'s answer cell in ``folder/source/01_truth_model.md`` by
    ``edit(text)``; returns the cell's index."""
    path = folder / "source" / "01_truth_model.md"
    nb = read_source(path)
    index = next(i for i, c in enumerate(nb.cells) if c.metadata.get("kfcal", {}).get("exercise") == exercise)
    text = path.read_text(encoding="utf-8")
    assert text.count(nb.cells[index].source) == 1
    path.write_text(text.replace(nb.cells[index].source, edit(nb.cells[index].source)), encoding="utf-8")
    return index


def test_a_lesson_edited_without_its_source_is_caught_and_rendered_back(copy_01):
    folder, name = copy_01
    assert differing(folder) == []
    lesson = nbformat.read(folder / name, 4)
    md = next(c for c in lesson.cells if c.cell_type == "markdown" and c.source.startswith("**Exercise 01.2"))
    original = md.source
    md.source += " Edited in the lesson only."
    nbformat.write(lesson, folder / name)
    assert differing(folder) == [folder / name]
    proc = cli("--check", "--notebooks", folder)
    assert proc.returncode == 1 and str(folder / name) in proc.stdout and proc.stderr == "", proc
    solution_bytes = (folder / "solutions" / name).read_bytes()
    written = sync(folder, log=lambda line: None)
    assert written == [(folder / name, "written")]          # a markdown change: outputs kept, no execution
    assert differing(folder) == []
    again = nbformat.read(folder / name, 4)
    before = nbformat.read(NOTEBOOKS / name, 4)
    assert [c.get("outputs") for c in again.cells] == [c.get("outputs") for c in before.cells]
    # every other cell keeps its id; the edited one gets its source cell's (made from its text)
    assert [c.id for c in again.cells if c.source != original] == [c.id for c in before.cells if c.source != original]
    assert len({c.id for c in again.cells}) == len(again.cells)
    assert (folder / "solutions" / name).read_bytes() == solution_bytes   # unchanged: untouched
    assert sync(folder, log=lambda line: None) == []


def test_an_edited_solution_in_the_source_is_written_as_needing_execution(copy_01):
    folder, name = copy_01
    edit_source(folder, "01.1", lambda text: text.replace("t_end = 10.0", "t_end = 10.0  # s"))
    assert differing(folder) == [folder / "solutions" / name]    # the placeholder is unchanged
    lesson_bytes = (folder / name).read_bytes()
    assert sync(folder, log=lambda line: None) == [(folder / "solutions" / name, "needs execution")]
    assert (folder / name).read_bytes() == lesson_bytes
    solved = nbformat.read(folder / "solutions" / name, 4)
    changed = next(c for c in solved.cells if "t_end = 10.0  # s" in c.source)
    assert changed.outputs == [] and changed.execution_count is None


# ------------------------------------------------------------------------------------------------
# the renderer
# ------------------------------------------------------------------------------------------------
def test_roles_and_regions_render_the_lesson_and_the_solutions():
    nb = tiny()
    lesson, solved = render_lesson(nb), render_solutions(nb)
    assert [c.source.split("\n")[0] for c in lesson.cells] == [
        "# Lesson", "x = 1", "**Exercise 99.1 — double.** Write f.", "def f(x):", "## Checks"]
    assert [c.source.split("\n")[0] for c in solved.cells] == [
        "# Solutions 99", "**Exercise 99.1 — double.** Write f.", "**Solution.** Multiply.", "def f(x):",
        "assert f(2) == 4"]
    assert lesson.cells[3].source == ('def f(x):\n    """twice x"""\n    ...   # replace ... with your code\n\n'
                                      'answer_99_1 = f\ncheck_double(answer_99_1)')
    assert solved.cells[3].source == ('def f(x):\n    """twice x"""\n    y = 2 * x\n    return y\n\n'
                                      'answer_99_1 = f\ncheck_double(answer_99_1)')
    assert all("kfcal" not in c.metadata for c in lesson.cells + solved.cells)
    assert [c.id for c in lesson.cells] == [nb.cells[i].id for i in (0, 1, 3, 5, 7)]
    answer = parse_answer(5, nb.cells[5])
    assert (answer.check, answer.answer, answer.exercise, answer.points) == ("check_double", "answer_99_1", "99.1", 2)


def _bad(text=None, meta=ANSWER, kind="code"):
    nb = tiny()
    nb.cells[5].cell_type = kind
    if kind == "markdown":
        del nb.cells[5]["outputs"], nb.cells[5]["execution_count"]
    nb.cells[5].source = FUNCTION if text is None else text
    nb.cells[5].metadata["kfcal"] = meta
    return nb


@pytest.mark.parametrize("nb, words", [
    (_bad(FUNCTION.replace("    ### END SOLUTION\n", "")), "not closed"),
    (_bad(FUNCTION.replace("    ### END PLACEHOLDER\n", "")), "inside the placeholder region"),
    (_bad(FUNCTION.replace("    ### BEGIN SOLUTION\n", "").replace("    ### END SOLUTION\n", "")),
     "followed directly by a solution region"),
    (_bad(FUNCTION.replace("    ### BEGIN PLACEHOLDER\n", "")), "without its BEGIN line"),
    (_bad(FUNCTION + "\nprint(1)"), "last line must be the check call"),
    (_bad(FUNCTION.replace("### BEGIN SOLUTION", "### begin solution")), "exactly as"),
    (_bad("answer_99_1 = 1\ncheck_double(answer_99_1)"), "needs a ### BEGIN SOLUTION"),
    (_bad(meta={"role": "answers"}), "kfcal.role"),
    (_bad(meta={"role": "answer", "exercise": "1"}), "kfcal.exercise"),
    (_bad(meta={"role": "answer", "exercise": "99.1", "points": 0}), "kfcal.points"),
    (_bad(meta={"role": "answer", "exercise": "99.1", "points": True}), "kfcal.points"),
    (_bad(meta="answer"), "must be a mapping"),
    (_bad(kind="markdown"), "must be a code cell"),
])
def test_a_bad_source_raises_valueerror_naming_the_cell(nb, words):
    for render in (render_lesson, render_solutions, nbgrader_notebook):
        with pytest.raises(ValueError, match="source cell 5") as info:
            render(nb)
        assert words in str(info.value)


def test_outputs_and_a_second_answer_cell_are_refused():
    nb = tiny()
    nb.cells[1].outputs = [nbformat.v4.new_output("stream", text="1\n")]
    with pytest.raises(ValueError, match="source cell 1.*no outputs"):
        render_lesson(nb)
    nb = tiny()
    nb.cells.append(nbformat.v4.new_code_cell(FUNCTION, metadata={"kfcal": dict(ANSWER)}))
    with pytest.raises(ValueError, match="source cell 8.*second answer cell"):
        render_lesson(nb)


# ------------------------------------------------------------------------------------------------
# the nbgrader conversion (no nbgrader needed)
# ------------------------------------------------------------------------------------------------
def test_nbgrader_notebook_has_answer_and_tests_cells_and_no_solutions_link():
    from kfcal_helpers.assignments._regrade import grade_cell_call

    nb = nbgrader_notebook(tiny(), modules={"check_double": "somewhere.exercises"})
    assert [c.source.split("\n")[0] for c in nb.cells] == [   # the checks after the exercises move before them
        "# Lesson", "x = 1", "## Checks", "**Exercise 99.1 — double.** Write f.", "def f(x):",
        "# the check of exercise 99.1 (2 points): shows ✔ or a hint; the grader checks the recorded answer again"]
    assert nb.cells[0].source == "# Lesson"
    answer, test = nb.cells[4], nb.cells[5]
    assert answer.source == ('def f(x):\n    """twice x"""\n    ...   # replace ... with your code\n'
                             '    ### BEGIN SOLUTION\n    y = 2 * x\n    return y\n    ### END SOLUTION\n\n'
                             'answer_99_1 = f')
    assert answer.metadata["nbgrader"]["solution"] and not answer.metadata["nbgrader"]["grade"]
    assert test.source.split("\n")[1:] == ["from kfcal_helpers.exercises.grading import record_answer",
                                           "record_answer('99.1', 'somewhere.exercises', 'check_double', answer_99_1)"]
    # what the grader reads from it (kfcal_helpers.assignments._regrade)
    assert grade_cell_call(test.source) == ("99.1", "somewhere.exercises", "check_double")
    assert test.metadata["nbgrader"]["grade"] and test.metadata["nbgrader"]["points"] == 2
    assert test.metadata["nbgrader"]["locked"]
    with pytest.raises(ValueError, match="source cell 5.*no check named check_double"):
        nbgrader_notebook(tiny(), modules={})


def test_every_lesson_converts_for_nbgrader_without_a_link_to_the_solutions():
    modules = assignments.check_modules()
    assert {"check_euler_truth", "check_measure_function"} <= set(modules)
    total, calls = 0, 0
    for path in assignments.sources():
        src = read_source(path)
        nb = nbgrader_notebook(src, modules)
        text = "\n".join(c.source for c in nb.cells)
        assert "solutions/" not in text and "Worked solutions" not in text, path.name
        assert "### BEGIN PLACEHOLDER" not in text and "**Solution.**" not in text
        graded = [c.metadata["nbgrader"] for c in nb.cells if c.metadata.get("nbgrader", {}).get("grade")]
        assert len(graded) == len(assignments.answer_cells(src))
        assert len({c.metadata["nbgrader"]["grade_id"] for c in nb.cells if "nbgrader" in c.metadata}) == 2 * len(graded)
        total += len(graded)
        lesson = nbformat.read(NOTEBOOKS / f"{path.stem}.ipynb", 4)
        calls += sum(c.cell_type == "code" and c.source.rstrip().split("\n")[-1].startswith("check_")
                     for c in lesson.cells)
    assert total == calls and total >= 40   # one graded check per check call of the lessons


# ------------------------------------------------------------------------------------------------
# the command's errors: one line on stderr, exit 2, no traceback
# ------------------------------------------------------------------------------------------------
def test_cli_errors_are_one_line_exit_2(tmp_path, copy_01):
    assert "--notebooks" in one_error_line(cli("--notebooks", tmp_path / "nothing"))
    assert "not allowed with" in one_error_line(cli("--check", "--course", tmp_path / "c"))
    assert "--execute" in one_error_line(cli("--check", "--execute"))
    (tmp_path / "file").write_text("x")
    line = one_error_line(cli("--course", tmp_path / "file"))
    assert "--course" in line
    folder, name = copy_01
    index = edit_source(folder, "01.2", lambda text: text.replace("### END SOLUTION", ""))
    line_number = read_source(folder / "source" / "01_truth_model.md", with_lines=True)[1][index]
    for args in (("--check",), ()):
        line = one_error_line(cli(*args, "--notebooks", folder))
        assert f"01_truth_model.md, line {line_number}: source cell {index}" in line and "not closed" in line


def test_cli_error_in_a_real_process(tmp_path):
    """One error row through the real entry point, ``python -m kfcal_helpers``."""
    proc = subprocess.run([sys.executable, "-m", "kfcal_helpers", "assignments", "--notebooks",
                           str(tmp_path / "nothing")], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert "--notebooks" in one_error_line(proc)


def test_course_without_nbgrader_names_the_instructors_file(tmp_path):
    pytest.importorskip("nbformat")
    try:
        import nbgrader  # noqa: F401
    except ImportError:
        line = one_error_line(cli("--course", tmp_path / "course"))
        assert "environment-instructors.txt" in line
        assert not (tmp_path / "course").exists()
    else:
        pytest.skip("nbgrader is installed here: tests/test_nbgrader_roundtrip.py makes the course")


# ------------------------------------------------------------------------------------------------
# the sources' text format (MyST Markdown notebooks, read by myst-nb)
# ------------------------------------------------------------------------------------------------
TRICKY = '''---
kernelspec:
  display_name: Python 3 (ipykernel)
  language: python
  name: python3
---

# Tricky

A fenced block in markdown, holding marker-like lines:

```python
+++
---
x = 1
```

---

A horizontal rule above.

+++ {"kfcal": {"role": "exercise"}}

**Exercise 99.1** is followed by two blank lines, not part of it.


````{code-cell} ipython3
---
{"kfcal": {"role": "answer", "exercise": "03.2", "points": 1}}
---
### BEGIN PLACEHOLDER
answer_03_2 = ...
### END PLACEHOLDER
### BEGIN SOLUTION
answer_03_2 = """
```
+++
---
"""
### END SOLUTION
check_x(answer_03_2)
````

```{code-cell} ipython3
y = 2

```

```{code-cell} ipython3
---
{}
---
---
```

```{code-cell} ipython3
y = 2

```

+++

last
'''


def test_a_text_source_reads_every_cell_exactly(tmp_path):
    path = tmp_path / "99_tricky.md"
    path.write_text(TRICKY, encoding="utf-8")
    nb, lines = read_source(path, with_lines=True)
    assert nb.metadata == {"kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python",
                                          "name": "python3"}}
    assert [(c.cell_type, c.source, c.metadata) for c in nb.cells] == [
        ("markdown", "# Tricky\n\nA fenced block in markdown, holding marker-like lines:\n\n```python\n+++\n---\n"
                     "x = 1\n```\n\n---\n\nA horizontal rule above.", {}),
        ("markdown", "**Exercise 99.1** is followed by two blank lines, not part of it.", {"kfcal": {"role": "exercise"}}),
        ("code", '### BEGIN PLACEHOLDER\nanswer_03_2 = ...\n### END PLACEHOLDER\n### BEGIN SOLUTION\n'
                 'answer_03_2 = """\n```\n+++\n---\n"""\n### END SOLUTION\ncheck_x(answer_03_2)',
         {"kfcal": {"role": "answer", "exercise": "03.2", "points": 1}}),   # "03.2" a string, not 3.2
        ("code", "y = 2\n", {}),
        ("code", "---", {}),
        ("code", "y = 2\n", {}),
        ("markdown", "last", {})]
    assert lines == [8, 24, 27, 44, 49, 56, 63]   # where each cell starts: its text, or its fence
    # ids: made from the text, the same in every reading, unique (two equal cells), valid
    assert [c.id for c in nb.cells] == [c.id for c in read_source(path).cells]
    assert len({c.id for c in nb.cells}) == len(nb.cells)
    nbformat.validate(nb)
    assert render_solutions(nb).cells[1].source.startswith('answer_03_2 = """\n```')


@pytest.mark.parametrize("bad, words", [
    ("```{code-cell} ipython3\n---\n{\"kfcal\": {\"role\": \"answer\"\n---\nx = 1\n```\n", "Code cell 1"),
    ("+++ {\"kfcal\": {\"role\": \"exercise\"}\n\ntext\n", "Markdown cell 1"),
    ("```{code-cell} ipython3\n---\nkfcal: [unclosed\n---\nx = 1\n```\n", "Code cell 1"),
])
def test_a_malformed_source_raises_valueerror_naming_the_file_and_the_cell(tmp_path, bad, words):
    path = tmp_path / "99_bad.md"
    path.write_text("# Lesson\n\n" + bad, encoding="utf-8")
    with pytest.raises(ValueError, match=f"^99_bad.md: {words} at line [0-9]+ could not be read"):
        read_source(path)


def test_cli_names_a_malformed_source_in_one_line_exit_2(copy_01):
    folder, _ = copy_01
    path = folder / "source" / "01_truth_model.md"
    text = path.read_text(encoding="utf-8")
    assert text.count('+++ {"kfcal": {"role": "exercise"}}') >= 1
    path.write_text(text.replace('+++ {"kfcal": {"role": "exercise"}}', '+++ {"kfcal": {"role": "exercise"}', 1),
                    encoding="utf-8")
    for args in (("--check",), ()):
        line = one_error_line(cli(*args, "--notebooks", folder))
        assert "01_truth_model.md: Markdown cell" in line and "could not be read" in line


def test_rendering_twice_gives_the_same_notebooks_and_course_ids(copy_01):
    folder, name = copy_01
    source = folder / "source" / "01_truth_model.md"
    assert render_lesson(read_source(source)) == render_lesson(read_source(source))
    a, b = (nbgrader_notebook(read_source(source)) for _ in range(2))
    assert [c.id for c in a.cells] == [c.id for c in b.cells]
    assert len({c.id for c in a.cells}) == len(a.cells)
    nbformat.validate(a)
    assert sync(folder, log=lambda line: None) == []          # nothing changed: nothing written


def _lesson_code(name):
    """The lesson's code cells (no solution or answer cells), joined in order."""
    nb = read_source(NOTEBOOKS / "source" / name)
    return "\n".join(c.source for c in nb.cells if c.cell_type == "code" and "kfcal" not in c.metadata)


def test_calibration_lessons_05_06_build_their_filter_before_the_package_runs_it():
    """05 computes both first-update conventions with its own loop before covariance_sequence is called; 06 runs
    its own vectorised filter over the realization ladder before batch_filter, covariance_sequence or the package's
    Monte Carlo is called, and shows them equal (issue 32)."""
    code05 = _lesson_code("05_kalman_filter_filterpy.md")
    assert code05.index("def covariances(") < code05.index("covariance_sequence(")
    code06 = _lesson_code("06_monte_carlo_validation.md")
    own = code06.index("def filter_ensemble(")
    ladder = code06.index("LADDER = (10, 40, 160, 640)")
    for package_call in ("batch_filter(", "covariance_sequence(", "run_monte_carlo(", "chunk_generators("):
        assert own < ladder < code06.index(package_call), package_call
    assert code06.index("np.allclose(theirs, ours") < code06.index("run_monte_carlo(")
