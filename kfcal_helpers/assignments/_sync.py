"""Keeping ``notebooks/`` and ``notebooks/solutions/`` equal to what ``notebooks/source/`` renders.

The sources are ``notebooks/source/NN_name.md`` (MyST Markdown notebooks, :func:`._source.read_source`);
each renders ``notebooks/NN_name.ipynb`` and, when it has an answer cell, ``notebooks/solutions/NN_name.ipynb``.

Two notebooks are *equal* when they have the same notebook metadata (``widgets``, the widget state
saved by an execution, left out) and the same cells: cell type, source and metadata (``execution``
left out).  Outputs, execution counts and cell ids are not compared.
"""

from __future__ import annotations

import copy
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..process import AT_SIGNAL, PARTIAL_FILES
from ._source import SOURCE_SUFFIX, read_source, render, source_indices

__all__ = ["NOTEBOOKS", "Target", "sources", "targets", "render_source", "located", "comparable", "equal", "differing", "merge",
           "sync", "execute", "write_notebook"]

#: the repository's notebooks folder (lessons; ``solutions/`` and ``source/`` below it)
NOTEBOOKS = Path(__file__).resolve().parents[2] / "notebooks"


@dataclass(frozen=True)
class Target:
    """One rendered notebook: ``which`` ("lesson" or "solutions") of ``source``, kept at ``path``."""

    source: Path
    which: str
    path: Path


def _read(path: Path):
    """A rendered notebook (``.ipynb``) or a source (``.md``, :func:`._source.read_source`)."""
    if path.suffix == SOURCE_SUFFIX:
        return read_source(path)
    import nbformat

    return nbformat.read(str(path), as_version=4)


def sources(notebooks: Path = NOTEBOOKS) -> list[Path]:
    """The source notebooks, ``notebooks/source/*.md``, in order."""
    return sorted(Path(notebooks, "source").glob(f"*{SOURCE_SUFFIX}"))


def targets(notebooks: Path = NOTEBOOKS) -> list[Target]:
    """Every notebook rendered from ``notebooks/source/*.md``: each source's lesson, and its
    solutions when it has an answer cell."""
    notebooks = Path(notebooks)
    out = []
    for source in sources(notebooks):
        name = source.stem + ".ipynb"
        out.append(Target(source, "lesson", notebooks / name))
        nb = _read(source)
        if any(isinstance(c.get("metadata", {}).get("kfcal"), dict) and c.metadata["kfcal"].get("role") == "answer"
               for c in nb.cells):
            out.append(Target(source, "solutions", notebooks / "solutions" / name))
    return out


def render_source(path: Path, which: str):
    """The ``which`` ("lesson" or "solutions") notebook of the source at ``path``; a ``ValueError`` of a bad
    cell names the file and the cell's line."""
    nb, lines = read_source(path, with_lines=True)
    try:
        return render(nb, which)
    except ValueError as exc:
        raise ValueError(located(path, lines, exc)) from None


def located(path: Path, lines: list[int], exc: ValueError) -> str:
    """The message of ``exc`` (naming "source cell N") prefixed with the file's name and that cell's line."""
    import re

    match = re.match(r"source cell (\d+)", str(exc))
    where = f", line {lines[int(match.group(1))]}" if match and int(match.group(1)) < len(lines) else ""
    return f"{Path(path).name}{where}: {exc}"


def comparable(nb):
    """What equality compares: the notebook metadata without ``widgets`` and, per cell, its type,
    source and metadata without ``execution``."""
    meta = {k: v for k, v in nb["metadata"].items() if k != "widgets"}
    cells = [(c["cell_type"], c["source"], {k: v for k, v in c.get("metadata", {}).items() if k != "execution"})
             for c in nb["cells"]]
    return meta, cells


def equal(a, b) -> bool:
    """True when the notebooks ``a`` and ``b`` are equal in the sense of this module."""
    return comparable(a) == comparable(b)


def differing(notebooks: Path = NOTEBOOKS) -> list[Path]:
    """The rendered notebooks that are missing or differ from what their source renders."""
    out = []
    for target in targets(notebooks):
        wanted = render_source(target.source, target.which)
        if not target.path.exists() or not equal(wanted, _read(target.path)):
            out.append(target.path)
    return out


def merge(rendered, old):
    """``rendered`` with what ``old`` (the notebook it replaces, or None) already has for unchanged
    cells: a cell equal to an old one (type and source, in order) keeps its id, and a code cell its
    outputs, execution count and ``execution`` metadata.  Returns ``(notebook, n_new_code_cells)``."""
    out = copy.deepcopy(rendered)
    pool = list(old["cells"]) if old is not None else []
    new_code = 0
    fresh = []   # the cells that keep the id of their source cell
    for cell in out["cells"]:
        match = next((i for i, c in enumerate(pool) if c["cell_type"] == cell["cell_type"]
                      and c["source"] == cell["source"]), None)
        if match is None:
            new_code += cell["cell_type"] == "code"
            fresh.append(cell)
            continue
        prev = pool.pop(match)
        if "id" in prev:
            cell["id"] = prev["id"]
        else:
            fresh.append(cell)
        if cell["cell_type"] == "code":
            cell["outputs"], cell["execution_count"] = prev.get("outputs", []), prev.get("execution_count")
            if "execution" in prev.get("metadata", {}):
                cell["metadata"]["execution"] = prev["metadata"]["execution"]
    if old is not None and "widgets" in old["metadata"] and new_code == 0:
        out["metadata"]["widgets"] = old["metadata"]["widgets"]
    kept = {c.get("id") for c in out["cells"] if all(c is not f for f in fresh)}
    for cell in fresh:   # a new cell's id, made from its text, must not be one an old cell keeps
        if cell.get("id") in kept:
            base, k = cell["id"][:60], 2
            while f"{base}-{k}" in kept:
                k += 1
            cell["id"] = f"{base}-{k}"
        kept.add(cell.get("id"))
    return out, new_code


def _refuse_signal_handlers(*args, **kwargs):
    raise RuntimeError("SIGINT and SIGTERM stay with the caller")


def _end_kernel(km, sockets: str) -> None:
    """Kill the kernel of ``km`` at once (if it runs) and remove its connection file and ``sockets``."""
    process = getattr(getattr(km, "provisioner", None), "process", None)
    if process is not None and process.poll() is None:
        process.kill()
    try:
        km.cleanup_connection_file()
    except Exception:  # noqa: BLE001 - best effort, as the kernel's own cleanup would be
        pass
    shutil.rmtree(sockets, ignore_errors=True)


def _one_line(text: str, limit: int = 200) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def execute(nb, path: Path, timeout: int = 1200, where: list[str] | None = None):
    """Run ``nb`` (which lives at ``path``) top to bottom in a fresh kernel, in ``path``'s folder, with
    ``KFCAL_QUIET=1`` and without the course log (``KFCAL_COURSE_LOG`` unset: every notebook is committed in the
    mode a student without the log gets; the course-log numbers in the text are labelled as such).  The
    kernel listens on Unix sockets (:func:`kfcal_helpers.kernels.over_ipc`; TCP on Windows) and is shut
    down when the run ends, however it ends.

    A cell that raises is a ``ValueError`` of one line naming the notebook, the cell (its index, and
    ``where[index]``, e.g. the source file and line it comes from) and the exception; a kernel that dies
    or a cell that runs longer than ``timeout`` s is one too.  SIGINT and SIGTERM stay with the caller's
    handlers (nbclient's own are not installed): the command line's print one line and end the process
    with 130 or 143, after killing the kernel (:data:`kfcal_helpers.process.AT_SIGNAL`); elsewhere Ctrl-C
    raises ``KeyboardInterrupt`` and the kernel is killed on the way out."""
    import asyncio

    from jupyter_client import AsyncKernelManager
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError, CellTimeoutError, DeadKernelError

    from ..kernels import over_ipc

    saved = dict(os.environ)
    os.environ["KFCAL_QUIET"] = "1"
    os.environ.pop("KFCAL_COURSE_LOG", None)
    sockets = tempfile.mkdtemp(prefix="kfcal-kernel-")
    # the kernel on Unix sockets of its own (kfcal_helpers.kernels: no TCP port to race for); TCP on Windows
    km = over_ipc(AsyncKernelManager, folder=sockets)(kernel_name="python3")
    current = {"cell": None}

    def on_cell_execute(cell, cell_index):
        current["cell"] = cell_index

    def end():
        _end_kernel(km, sockets)

    client = NotebookClient(nb, km=km, timeout=timeout, kernel_name="python3", on_cell_execute=on_cell_execute,
                            resources={"metadata": {"path": str(path.parent)}})
    # nbclient would put its own SIGINT/SIGTERM handlers on the event loop, over the caller's: refused
    loop = asyncio.new_event_loop()
    loop.add_signal_handler = loop.remove_signal_handler = _refuse_signal_handlers
    AT_SIGNAL.append(end)
    try:
        loop.run_until_complete(client.async_execute(cleanup_kc=True))
    except CellExecutionError as exc:
        index = current["cell"]
        origin = f" ({where[index]})" if where is not None and index is not None and index < len(where) else ""
        reason = _one_line(exc.evalue)
        raise ValueError(f"{path.name}, cell {index}{origin} raised {exc.ename}" + (f": {reason}" if reason else "")) \
            from None
    except (CellTimeoutError, DeadKernelError) as exc:
        index = current["cell"]
        raise ValueError(f"{path.name}, cell {index}: {_one_line(exc)}") from None
    finally:
        AT_SIGNAL.remove(end)
        end()
        loop.close()
        os.environ.clear()
        os.environ.update(saved)
    return nb


def write_notebook(nb, path: Path) -> None:
    """Write ``nb`` to ``path`` under a temporary name, renamed when complete (no partial file is left)."""
    import nbformat

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    PARTIAL_FILES.add(tmp)   # removed by the command line's signal handler
    try:
        nbformat.write(nb, tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        PARTIAL_FILES.discard(tmp)


def sync(notebooks: Path = NOTEBOOKS, *, run: bool = False, log=print) -> list[tuple[Path, str]]:
    """Re-render every lesson and solutions notebook from its source; write only those that differ
    (the others are left untouched, byte for byte).  Unchanged cells keep their outputs (:func:`merge`);
    a notebook with new or changed code cells is executed when ``run`` (:func:`execute`), else written
    with those cells unexecuted.  Returns ``[(path, state)]`` of the written notebooks, state
    ``"executed"``, ``"needs execution"`` or ``"written"`` (markdown changes only)."""
    written = []
    for target in targets(notebooks):
        wanted = render_source(target.source, target.which)
        old = _read(target.path) if target.path.exists() else None
        if old is not None and equal(wanted, old):
            continue
        nb, new_code = merge(wanted, old)
        state = "written"
        if new_code:
            if run:
                log(f"executing {target.path.relative_to(notebooks.parent)} ...")
                source_nb, lines = read_source(target.source, with_lines=True)
                where = [f"{target.source.name}, line {lines[i]}" for i in source_indices(source_nb, target.which)]
                execute(nb, target.path, where=where)
                state = "executed"
            else:
                state = "needs execution"
        write_notebook(nb, target.path)
        written.append((target.path, state))
    return written
