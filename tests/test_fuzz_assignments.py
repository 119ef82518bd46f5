"""Fuzz rows of ``python -m kfcal_helpers assignments``: whatever a source notebook holds and whatever
happens while ``--execute`` runs, one line on stderr and exit 2 (130/143 for Ctrl-C/SIGTERM), never a
traceback, a hang, gigabytes of memory or a file written from a bad source.

Most rows call ``kfcal_helpers.cli.main`` in this process on a one-source notebooks folder
(``--notebooks``).  Rows that could hang or grow without bound on a bad reader (a FIFO, ``/dev/zero``,
a YAML alias bomb) run the command in a child process with a timeout and an address-space cap, and
check the child's own peak resident memory (VmHWM); the signal rows start the child with SIGINT at
Python's default.  Those are the slow tier (``@pytest.mark.slow``).
"""

import contextlib
import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kfcal_helpers.cli import main

PROG = "python -m kfcal_helpers assignments"
MEMORY_LIMIT = 500e6  #: bytes, the command line's bound on the peak memory of any run

HEAD = "---\nkernelspec:\n  display_name: Python 3\n  language: python\n  name: python3\n---\n\n# 99 — a lesson\n"


def code(text: str, meta: str | None = None) -> str:
    """A code cell of a source; ``meta`` the YAML (or JSON) of its ``---`` block."""
    block = f"---\n{meta}\n---\n" if meta is not None else ""
    return f"\n```{{code-cell}} ipython3\n{block}{text}\n```\n"


def answer(points: str) -> str:
    return code("### BEGIN SOLUTION\nanswer_99_1 = 1\n### END SOLUTION\ncheck_euler_velocity_gap(answer_99_1)",
                '{"kfcal": {"role": "answer", "exercise": "99.1", "points": %s}}' % points)


def bomb(levels: int = 9) -> str:
    """A YAML "billion laughs": 9 ** levels strings from a few hundred bytes."""
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"a{k}: &a{k} [{','.join([f'*a{k - 1}'] * 9)}]" for k in range(1, levels)]
    return "\n".join(lines)


def folder(root: Path, text: str | None = None, name: str = "99_t.md") -> Path:
    """A notebooks folder holding ``source/NAME`` with ``text`` (None: no file, the caller makes it)."""
    nb = root / "nb"
    (nb / "source").mkdir(parents=True, exist_ok=True)
    if text is not None:
        (nb / "source" / name).write_text(text, encoding="utf-8")
    return nb


def run(*args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code_ = main(["assignments", *map(str, args)])
    return code_, out.getvalue(), err.getvalue()


def one_error_line(code_, err, words):
    lines = err.splitlines()
    assert code_ == 2, (code_, err)
    assert len(lines) == 1 and lines[0].startswith(f"{PROG}: error: "), err
    assert "Traceback" not in err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def written(nb: Path) -> list:
    return sorted(p.name for p in nb.rglob("*") if p.suffix == ".ipynb" or p.name.endswith(".tmp"))


# ---------------------------------------------------------------------------------------------
# what a source holds: each row fails with one line, exit 2, before anything is written
# (text of the source, words the line must contain)
SOURCES = {
    ":load: /etc/passwd": (HEAD + code(":load: /etc/passwd"), [":load:", "99_t.md", "line 11"]),
    ":load: a file beside it": (HEAD + code(":load: other.py"), [":load:", "99_t.md", "line 11"]),
    "load: in the --- block": (HEAD + code("", "load: /etc/passwd"), [":load:", "99_t.md", "line 12"]),
    "YAML alias": (HEAD + code("x = 1", "a: &x 1\nb: *x"), ["alias", "99_t.md", "line"]),
    "YAML alias in the front matter": (HEAD.replace("---\n\n", "a: &x 1\nb: *x\n---\n\n", 1), ["alias", "99_t.md"]),
    "date in the front matter": (HEAD.replace("---\n\n", "created: 2024-01-01\n---\n\n", 1),
                                 ["99_t.md", "JSON", "date"]),
    "datetime in the front matter": (HEAD.replace("---\n\n", "created: 2024-01-01 10:00:00\n---\n\n", 1),
                                     ["99_t.md", "JSON", "datetime"]),
    "date key": (HEAD + code("x = 1", "2024-01-01: x"), ["99_t.md", "line 10", "JSON", "key"]),
    "integer key": (HEAD + code("x = 1", "1: x"), ["99_t.md", "line 10", "JSON", "key"]),
    "!!set": (HEAD + code("x = 1", "kinds: !!set {a, b}"), ["99_t.md", "line 10", "JSON", "set"]),
    "!!binary": (HEAD + code("x = 1", "blob: !!binary aGVsbG8="), ["99_t.md", "JSON", "bytes"]),
    ".nan in metadata": (HEAD + code("x = 1", "v: .nan"), ["99_t.md", "JSON", "finite"]),
    "points .inf": (HEAD + answer(".inf"), ["99_t.md", "points", "finite"]),
    "points -.inf": (HEAD + answer("-.inf"), ["99_t.md", "points"]),
    "points .nan": (HEAD + answer(".nan"), ["99_t.md", "points"]),
    "points 1e400": (HEAD + answer("1e400"), ["99_t.md", "points", "finite"]),
    "empty source": ("", ["99_t.md", "empty"]),
    "blank source": ("\n \n", ["99_t.md", "empty"]),
    "not UTF-8": (None, ["99_t.md", "UTF-8"]),
    "1001 cells": (HEAD + "\n+++\nx\n" * 1001, ["99_t.md", "1001 cells", "1000"]),
    "a metadata block over 64 kB": (HEAD + code("x = 1", "v: [" + ",".join(["1"] * 33000) + "]"),
                                    ["99_t.md", "line 12", "64 kB"]),
}


@pytest.mark.parametrize("mode", [(), ("--check",)], ids=["write", "check"])
@pytest.mark.parametrize("row", list(SOURCES))
def test_a_bad_source_is_one_line_exit_2_and_nothing_written(row, mode, tmp_path):
    text, words = SOURCES[row]
    nb = folder(tmp_path, text)
    if text is None:
        (nb / "source" / "99_t.md").write_bytes(HEAD.encode() + b"\xff\xfe\n")
    (nb / "source" / "other.py").write_text("print('loaded')\n")
    one_error_line(*run(*mode, "--notebooks", nb)[::2], words)
    assert written(nb) == []


def test_a_source_that_is_not_a_regular_file_is_refused(tmp_path):
    nb = folder(tmp_path)
    (nb / "source" / "99_t.md").mkdir()
    one_error_line(*run("--notebooks", nb)[::2], ["99_t.md", "a directory", "regular files only"])


def test_a_source_larger_than_the_cap_is_refused(tmp_path):
    from kfcal_helpers.assignments import MAX_SOURCE_BYTES

    nb = folder(tmp_path)
    with open(nb / "source" / "99_t.md", "wb") as f:  # sparse: no disk, no memory
        f.truncate(MAX_SOURCE_BYTES + 1)
    one_error_line(*run("--check", "--notebooks", nb)[::2], ["99_t.md", "larger than", "kB"])


def test_the_committed_sources_are_far_below_the_cap():
    """The cap leaves room to grow: the largest source (notebook 14, three problems' mistakes, 85 kB) is
    under a third of it."""
    from kfcal_helpers.assignments import MAX_SOURCE_BYTES, NOTEBOOKS

    largest = max(p.stat().st_size for p in (NOTEBOOKS / "source").glob("*.md"))
    assert 3 * largest <= MAX_SOURCE_BYTES, (largest, MAX_SOURCE_BYTES)


def test_finite_points_and_plain_yaml_metadata_still_render(tmp_path):
    """The checks refuse only what is not JSON: YAML metadata that is (lists, strings, numbers) renders."""
    text = HEAD + code("x = 1", "tags: [hide-input]\nn: 3\nok: true\nnothing: null") + answer("2.5")
    nb = folder(tmp_path, text)
    code_, out, err = run("--notebooks", nb)
    assert code_ == 0 and err == "", err
    assert written(nb) == ["99_t.ipynb", "99_t.ipynb"]


def test_course_folder_empty_is_refused(tmp_path, monkeypatch):
    nb = folder(tmp_path, HEAD + answer("1"))
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    one_error_line(*run("--course", "", "--notebooks", nb)[::2], ["--course", "empty"])
    assert sorted(p.name for p in tmp_path.iterdir()) == before


# ---------------------------------------------------------------------------------------------
# child processes: hangs and memory
CAP = 2 * 1024 ** 3  #: the child's address-space cap (bytes): a bad reader stops there, not at the machine's end
CHILD = ("import resource, sys\n"
         f"resource.setrlimit(resource.RLIMIT_AS, ({CAP}, {CAP}))\n"
         "from kfcal_helpers.cli import main\n"
         "rc = main(sys.argv[1:])\n"
         "print([int(line.split()[1]) for line in open('/proc/self/status') if line.startswith('VmHWM')][0], "
         "file=sys.stderr)\n"
         "sys.exit(rc)\n")
linux_only = pytest.mark.skipif(not os.path.exists("/proc/self/status") or os.name != "posix",
                                reason="needs /proc (Linux) for VmHWM, FIFOs and resource limits")


def _child(argv, timeout=120):
    env = {**os.environ, "KFCAL_QUIET": "1"}
    return subprocess.run([sys.executable, "-c", CHILD, *map(str, argv)], capture_output=True, text=True,
                          env=env, timeout=timeout)


def _make_fifo(path):
    os.mkfifo(path)


def _link_zero(path):
    path.symlink_to("/dev/zero")


def _load_zero(path):
    path.write_text(HEAD + code(":load: /dev/zero"))


def _bomb_in_a_cell(path):
    path.write_text(HEAD + code("x = 1", bomb()))


def _bomb_in_the_front_matter(path):
    path.write_text(HEAD.replace("---\n\n", bomb() + "\n---\n\n", 1))


def _bomb_in_a_markdown_cell(path):  # JSON has no aliases: a deep nesting instead
    path.write_text(HEAD + "\n+++ " + "[" * 100000 + "]" * 100000 + "\n\ntext\n")


def _paragraphs_at_the_cap(path):  # the most markdown-it tokens a source may make
    from kfcal_helpers.assignments import MAX_SOURCE_BYTES

    path.write_text(HEAD + "x\n\n" * ((MAX_SOURCE_BYTES - len(HEAD.encode())) // 3))


def _cells_at_the_cap(path):
    from kfcal_helpers.assignments import MAX_CELLS

    path.write_text(HEAD + "".join(code(f"x = {k}") for k in range(MAX_CELLS)))


def _yaml_at_the_cap(path):  # three metadata blocks just under 64 kB
    path.write_text(HEAD + code("x = 1", "v: [" + ",".join(["1"] * 32000) + "]") * 3)


@pytest.mark.slow
@linux_only
@pytest.mark.parametrize("make", [_paragraphs_at_the_cap, _cells_at_the_cap, _yaml_at_the_cap],
                         ids=["paragraphs", "cells", "YAML"])
def test_the_largest_accepted_sources_stay_in_bounds(make, tmp_path):
    """A source at the caps renders within the command line's memory bound and in bounded time."""
    nb = folder(tmp_path)
    make(nb / "source" / "99_t.md")
    start = time.monotonic()
    r = _child(["assignments", "--notebooks", nb], timeout=300)
    seconds = time.monotonic() - start
    *lines, peak = r.stderr.strip().splitlines()
    assert r.returncode == 0 and lines == [], r.stderr
    assert int(peak) * 1024 <= MEMORY_LIMIT, int(peak) / 1e3
    assert written(nb) == ["99_t.ipynb"], written(nb)
    print(f"{make.__name__}: peak {int(peak) / 1e3:.0f} MB, {seconds:.1f} s")


@pytest.mark.slow
@linux_only
@pytest.mark.parametrize("make, words", [
    (_make_fifo, ["99_t.md", "FIFO", "regular files only"]),
    (_link_zero, ["99_t.md", "character device", "regular files only"]),
    (_load_zero, ["99_t.md", ":load:"]),
    (_bomb_in_a_cell, ["99_t.md", "alias"]),
    (_bomb_in_the_front_matter, ["99_t.md", "alias"]),
    (_bomb_in_a_markdown_cell, ["99_t.md"]),
], ids=["FIFO", "link to /dev/zero", ":load: /dev/zero", "alias bomb in a cell", "alias bomb in the front matter",
        "deep JSON in a markdown cell"])
@pytest.mark.parametrize("mode", [(), ("--check",)], ids=["write", "check"])
def test_a_hanging_or_huge_source_is_refused_in_bounded_time_and_memory(make, words, mode, tmp_path):
    nb = folder(tmp_path)
    make(nb / "source" / "99_t.md")
    try:
        r = _child(["assignments", *mode, "--notebooks", nb], timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail("the command did not end within 120 s")
    *lines, peak = r.stderr.strip().splitlines()
    peak = int(peak) * 1024  # VmHWM is in kB
    one_error_line(r.returncode, "\n".join(lines), words)
    assert peak <= MEMORY_LIMIT, peak / 1e6
    assert written(nb) == []


# ---------------------------------------------------------------------------------------------
# --execute: a cell that raises, Ctrl-C and SIGTERM while a notebook runs
SLEEPER = HEAD + code("import os, time\nopen('started', 'w').write(str(os.getpid()))\ntime.sleep(120)")

#: the command line, started with SIGINT at Python's default whatever this process has (a background job
#: starts with it ignored, and a child inherits that)
LAUNCH = ("import runpy, signal, sys\n"
          "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
          "runpy.run_module('kfcal_helpers', run_name='__main__', alter_sys=True)\n")


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/status") as f:
            return not any(line.startswith("State:") and "Z" in line.split()[1] for line in f)
    except OSError:
        return False


@pytest.mark.slow
def test_a_cell_that_raises_is_one_line_naming_the_notebook_and_the_cell(tmp_path):
    nb = folder(tmp_path, HEAD + code("x = 1") + code("def f():\n    return 1 / 0\n\nf()"))
    r = subprocess.run([sys.executable, "-c", LAUNCH, "assignments", "--execute", "--notebooks", nb],
                       capture_output=True, text=True, env={**os.environ, "KFCAL_QUIET": "1"}, timeout=300)
    line = one_error_line(r.returncode, r.stderr, ["99_t.ipynb", "cell 2", "99_t.md, line 14",
                                                   "ZeroDivisionError", "division by zero"])
    assert "executing" in r.stdout and len(line) < 300
    assert written(nb) == []


@pytest.mark.slow
@linux_only
@pytest.mark.parametrize("signame, code_, word", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "terminated")])
def test_a_signal_while_a_notebook_runs_is_one_line_and_the_kernel_ends(signame, code_, word, tmp_path):
    nb = folder(tmp_path, SLEEPER)
    p = subprocess.Popen([sys.executable, "-c", LAUNCH, "assignments", "--execute", "--notebooks", str(nb)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, "KFCAL_QUIET": "1"})
    started = nb / "started"
    deadline = time.monotonic() + 120
    while not (started.exists() and started.read_text()) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    assert started.exists(), p.communicate(timeout=60)
    kernel = int(started.read_text())
    time.sleep(0.5)
    p.send_signal(getattr(signal, signame))
    out, err = p.communicate(timeout=60)
    assert p.returncode == code_, (p.returncode, err)
    assert err == f"{PROG}: {word}\n"
    deadline = time.monotonic() + 10
    while _alive(kernel) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(kernel), "the kernel outlived the command"
    assert written(nb) == []


@linux_only
@pytest.mark.parametrize("last", ["y = 2", "1 / 0"], ids=["runs", "raises"])
def test_execute_ends_its_kernel_however_the_run_ends(last, tmp_path):
    """``execute`` shuts its kernel down when the run ends (it was left running until the process exited),
    and a cell that raises is a one-line ``ValueError`` naming the notebook, the cell and where it comes from."""
    import nbformat

    from kfcal_helpers.assignments import execute

    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.cells += [nbformat.v4.new_code_cell("import os\nopen('pid', 'w').write(str(os.getpid()))"),
                 nbformat.v4.new_code_cell(last)]
    if last == "y = 2":
        execute(nb, tmp_path / "x.ipynb", timeout=120)
        assert nb.cells[1].execution_count == 2
    else:
        with pytest.raises(ValueError) as info:
            execute(nb, tmp_path / "x.ipynb", timeout=120, where=["s.md, line 3", "s.md, line 7"])
        assert str(info.value) == "x.ipynb, cell 1 (s.md, line 7) raised ZeroDivisionError: division by zero"
    kernel = int((tmp_path / "pid").read_text())
    deadline = time.monotonic() + 10
    while _alive(kernel) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(kernel), "the kernel outlived the run"


def test_memory_error_while_rendering_blames_the_sources(monkeypatch, capsys):
    """Out of memory in `assignments`: the advice is about the sources, not about realizations or logs."""
    import kfcal_helpers.assignments._sync as assignments_sync

    def no_memory(*a, **k):
        raise MemoryError

    monkeypatch.setattr(assignments_sync, "sync", no_memory)
    code = main(["assignments"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "not enough memory" in err and "lesson source" in err and "realizations" not in err
