"""The problem list drives the command line, the lecture figures and the mistakes table: a toy third
problem, registered in the list, appears in ``--help``, runs as a sub-command, is listed and written by
``figures`` and has its rows in the mistakes table -- without editing any shared module.  And the
imports of the package point one way: problem code -> shared code, never back, never across."""

import ast
import struct
from pathlib import Path

import numpy as np
import pytest

import kfcal_helpers
from kfcal_helpers import montecarlo as core
from kfcal_helpers import problems
from kfcal_helpers.cli import main
from kfcal_helpers.consistency import Check, format_checks
from kfcal_helpers.figures import all_figures, write_figures
from kfcal_helpers.mistakes import all_mistakes, format_mistake_table, mistake_table
from kfcal_helpers.registry import LectureFigure, MistakeRow, Problem


def _toy_cli(subparsers):
    p = subparsers.add_parser("toy", help="run the toy problem")
    p.add_argument("--gain", type=float, default=1.0)

    def run(args):
        if args.gain <= 0:
            raise ValueError("--gain must be > 0")
        print(f"toy ran with gain {args.gain:g}")
        return 0

    p.set_defaults(run=run)


def _toy_line(data):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, data["slope"]])
    return fig


def _toy_row(mistake, n_runs=None, params=None, alpha=0.05):
    n_runs = 10 if n_runs is None else n_runs
    stat = np.array([0.0 if mistake == "toy_correct" else 3.0])
    check = Check("bias", "toy bias", stat, np.zeros(1), -np.ones(1), np.ones(1), -2 * np.ones(1), 2 * np.ones(1))
    return MistakeRow("toy", mistake, TOY.mistakes[mistake], {"bias": check}, {"n_runs": n_runs, "alpha": alpha})


class ToyResult:
    """The toy Monte Carlo's result: the interface every problem's result offers
    (``consistency.MonteCarloSummary``), its bands from ``kfcal_helpers.consistency``."""

    def __init__(self, n_runs, alpha, seconds, mean, var, nees, bias):
        self.n_runs, self.alpha, self.filter, self.seconds = n_runs, alpha, "toy", seconds
        self.mean, self.var, self.nees, self.bias = mean, var, nees, bias

    def checks(self):
        from kfcal_helpers.consistency import chi2_bounds, t_band, variance_band

        N, a, sd = self.n_runs, self.alpha, np.sqrt(self.var)
        bands = {"mean_error": (self.mean, 0.0, lambda level: (-t_band(sd, N, level), t_band(sd, N, level))),
                 "variance": (self.var, 1.0, lambda level: variance_band(np.ones(3), N - 1, level)),
                 "nees": (np.array([self.nees]), 3.0, lambda level: chi2_bounds(3, N, level))}
        a_sim = Check.bonferroni(a, 3 + 3 + 1)  # one family: every entry of the three checks
        return {name: Check.from_band(name, f"toy {name}", stat, expected, band, a, a_sim)
                for name, (stat, expected, band) in bands.items()}


class ToyExperiment(core.ArrayExperiment):
    """A toy problem's Monte Carlo for the shared core: ``N(bias, I_3)`` errors of a 3-state estimate,
    chunks of 64 realizations, running sums of the errors, their squares and their NEES."""

    keep, CHUNK_SIZE, CHUNK_BYTES_PER_RUN, SECONDS_PER_RUN = "sums", 64, 200.0, 1e-6

    def __init__(self, bias=0.0, alpha=0.05):
        self.bias, self.alpha = bias, alpha

    def arrays(self):
        return {"s": (3,), "ss": (3,), "nees": ()}

    def run_chunk(self, size, rng, chunk):
        e = self.bias + rng.standard_normal((size, 3))
        return e.sum(0), (e**2).sum(0), (e**2).sum()

    def result(self, total, n, seconds):
        mean = total["s"] / n
        return ToyResult(n, self.alpha, seconds, mean, (total["ss"] - n * mean**2) / (n - 1), total["nees"] / n,
                         self.bias)


TOY = Problem(name="toy", title="a toy problem", add_cli=_toy_cli,
              figures=(LectureFigure("toy_line", "toy: a straight line", _toy_line),),
              figure_data=lambda: {"slope": 2.0},
              mistakes={"toy_correct": "the correct toy", "toy_wrong": "the toy with a bias"}, mistake_row=_toy_row)


@pytest.fixture
def with_toy(monkeypatch):
    monkeypatch.setattr(problems, "PROBLEMS", (*problems.PROBLEMS, TOY))


def test_the_toy_appears_in_help_and_runs(with_toy, capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "toy" in out and "calibrate" in out and "coop" in out and "figures" in out
    assert main(["toy", "--gain", "2.5"]) == 0
    assert capsys.readouterr().out == "toy ran with gain 2.5\n"
    assert main(["toy", "--gain", "-1"]) == 2
    assert capsys.readouterr().err == "python -m kfcal_helpers toy: error: --gain must be > 0\n"


def test_without_the_toy_there_is_no_toy_command(capsys):
    assert main(["toy"]) == 2
    assert "invalid choice: 'toy'" in capsys.readouterr().err


def test_the_toy_figure_is_listed_and_written(with_toy, tmp_path, capsys):
    assert main(["figures", "--list"]) == 0
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert listed[-1] == "toy_line" and listed == [f.name for f in all_figures()]
    assert any(n.startswith("calib_") for n in listed) and any(n.startswith("coop_") for n in listed)
    assert main(["figures", str(tmp_path), "--only", "toy_line"]) == 0
    png = tmp_path / "toy_line.png"
    assert capsys.readouterr().out == f"{png}\n"
    assert struct.unpack(">II", png.read_bytes()[16:24]) == (1280, 720)
    assert write_figures(tmp_path / "again", names=["toy_line"], data={"slope": -1.0}) == [tmp_path / "again" / "toy_line.png"]


def test_the_toy_mistakes_are_rows_of_the_table(with_toy):
    assert all_mistakes()[-2:] == ("toy_correct", "toy_wrong")
    rows = mistake_table(["toy_correct", "toy_wrong"], n_runs={"toy": 7})
    assert rows["toy_correct"].passed and rows["toy_wrong"].failed == ("bias",)
    assert rows["toy_wrong"].result == {"n_runs": 7, "alpha": 0.05}
    text = format_mistake_table(rows)
    assert text.splitlines()[0].split() == ["mistake", "bias"]
    assert "FAIL 1.5" in text and "pass 0" in text
    assert format_checks(rows["toy_wrong"].checks).splitlines()[-1].split() == ["bias", "0.000", "1.50", "FAIL"]


def test_the_toy_monte_carlo_runs_through_the_shared_core():
    """A third problem's Monte Carlo is an Experiment for kfcal_helpers.montecarlo.run: seeds, threads,
    chunk order and the estimate come from the core, its result offers the shared interface, its bands
    come from consistency, and format_checks prints it."""
    from kfcal_helpers.consistency import MonteCarloSummary

    assert isinstance(ToyExperiment(), core.Experiment)
    runs = [core.run(ToyExperiment(), 1000, 3, workers=w) for w in (1, 2)]
    mc = runs[0]
    assert isinstance(mc, MonteCarloSummary) and mc.n_runs == 1000 and mc.filter == "toy" and mc.seconds >= 0
    assert np.array_equal(mc.mean, runs[1].mean) and mc.nees == runs[1].nees  # bit for bit on 1 and 2 threads
    checks = mc.checks()
    assert all(c.passed for c in checks.values()), format_checks(mc)
    lines = format_checks(mc).splitlines()
    assert [line.split()[0] for line in lines[2:]] == ["mean_error", "variance", "nees"]
    assert all(line.split()[-1] == "pass" for line in lines[2:])
    # a biased estimate fails its mean and NEES checks, not its variance check
    biased = core.run(ToyExperiment(bias=0.3), 1000, 3).checks()
    assert not biased["mean_error"].passed and not biased["nees"].passed and biased["variance"].passed
    # memory does not grow with the runs (sums only); the core refuses a run that would take too long
    assert core.estimate(ToyExperiment(), 10**9).peak_bytes == core.estimate(ToyExperiment(), 10**3).peak_bytes
    with pytest.raises(ValueError, match="^n_runs: 10000000000 realizations would take about 2.78 h"):
        core.estimate(ToyExperiment(), 10**10)


def test_names_must_be_unique_over_problems(monkeypatch):
    twin = Problem(name="twin", title="a twin", add_cli=lambda sub: None, figures=TOY.figures,
                   mistakes=TOY.mistakes, mistake_row=_toy_row)
    monkeypatch.setattr(problems, "PROBLEMS", (TOY, twin))
    with pytest.raises(ValueError, match="figure name 'toy_line' is used by two problems"):
        all_figures()
    with pytest.raises(ValueError, match="mistake name 'toy_correct' is used by two problems"):
        all_mistakes()


@pytest.mark.parametrize("kwargs, word", [({"mistakes": ["nope"]}, "mistakes"), ({"n_runs": 5}, "n_runs"),
                                          ({"params": {"nope": 1}}, "params key"), ({"alpha": 1.5}, "alpha")])
def test_mistake_table_validates(kwargs, word):
    with pytest.raises(ValueError, match=word):
        mistake_table(**kwargs)


def test_problem_lookup():
    assert problems.problem("coop") is problems.COOP
    with pytest.raises(ValueError, match="problem must be one of calibration, coop"):
        problems.problem("nope")


# ---------------------------------------------------------------------------
# Imports point one way
PACKAGE = Path(kfcal_helpers.__file__).parent
# the shared subpackages: the exercise harness and the assignments (lessons rendered from notebooks/source)
PROBLEM_PACKAGES = tuple(p.name for p in PACKAGE.iterdir()
                         if (p / "__init__.py").exists() and p.name not in ("exercises", "assignments"))


def _imports(path: Path, root: Path = PACKAGE.parent):
    """(module path of each import, names imported) of a source file under ``root`` (the folder holding
    the package), relative imports resolved."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    package = parts if path.name == "__init__.py" else parts[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = [*base, *(node.module.split(".") if node.module else [])]
            names = [a.name for a in node.names]
            yield ".".join(module), names
            for name in names:  # "from . import calibration" imports a package too
                yield ".".join([*module, name]), []
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, []


def test_problem_packages_are_the_expected_ones():
    assert set(PROBLEM_PACKAGES) == {"calibration", "coop", "orbit"}


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_point_one_way(path):
    rel = path.relative_to(PACKAGE)
    mine = rel.parts[0] if len(rel.parts) > 1 and rel.parts[0] in PROBLEM_PACKAGES else None
    for module, names in _imports(path):
        if not module.startswith("kfcal_helpers"):
            continue
        target = module.split(".")
        other = target[1] if len(target) > 1 and target[1] in PROBLEM_PACKAGES else None
        if mine is not None:
            assert other in (None, mine), f"{rel} imports another problem: {module}"
        elif rel != Path("problems.py"):
            assert other is None, f"shared module {rel} imports a problem package: {module}"
        if module != ".".join(["kfcal_helpers", *rel.with_suffix("").parts]):
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            assert not private, f"{rel} imports private names {private} from {module}"


def _module_names(package: Path) -> dict:
    """``{dotted module name: file}`` of every module of ``package`` (a package is its ``__init__``)."""
    out = {}
    for path in package.rglob("*.py"):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def import_graph(package: Path = PACKAGE) -> dict:
    """``{module: {modules of ``package`` it imports}}`` from every ``import`` and ``from ... import``
    statement anywhere in each module (top level, functions, classes, ``if`` blocks), relative
    imports resolved; ``from M import n`` counts as importing ``M.n`` when that is a module, else ``M``."""
    modules = _module_names(package)
    graph = {}
    for name, path in modules.items():
        edges = set()
        for module, names in _imports(path, package.parent):
            if names and all(f"{module}.{n}" in modules for n in names):
                continue  # "from M import submodule": the submodules are yielded on their own
            if module in modules and module != name:
                edges.add(module)
        graph[name] = edges
    return graph


def import_cycles(graph: dict) -> list:
    """The import circles of ``graph``: one cycle (a list of modules, first repeated at the end) per
    strongly connected component with more than one module."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def strongconnect(v):  # Tarjan's algorithm
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strongconnect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(_one_cycle(graph, set(component)))

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)
    return cycles


def _one_cycle(graph: dict, component: set) -> list:
    """A shortest cycle through the smallest module of a strongly connected ``component`` (breadth first)."""
    start = min(component)
    paths = {start: [start]}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v] & component):
            if w == start:
                return [*paths[v], start]
            if w not in paths:
                paths[w] = [*paths[v], w]
                queue.append(w)
    raise AssertionError("not a strongly connected component")


def test_cycle_finder_finds_function_level_circles(tmp_path):
    """On a small package: imports inside functions and ``if`` blocks, relative and absolute, are
    edges; ``from . import sub`` points to the submodule; the circle of three is reported."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("import os\n\n\ndef f():\n    from . import b\n    return b\n")
    (pkg / "b.py").write_text("if True:\n    from .sub.c import VALUE\n")
    (pkg / "sub" / "__init__.py").write_text("from . import c\n")
    (pkg / "sub" / "c.py").write_text("class K:\n    def m(self):\n        import pkg.a\n\n\nVALUE = 1\n")
    (pkg / "d.py").write_text("from .sub import c\nfrom . import a\n")
    graph = import_graph(pkg)
    assert graph == {"pkg": set(), "pkg.a": {"pkg.b"}, "pkg.b": {"pkg.sub.c"}, "pkg.sub": {"pkg.sub.c"},
                     "pkg.sub.c": {"pkg.a"}, "pkg.d": {"pkg.sub.c", "pkg.a"}}
    assert import_cycles(graph) == [["pkg.a", "pkg.b", "pkg.sub.c", "pkg.a"]]
    assert import_cycles({"a": {"b"}, "b": set()}) == []
    real = import_graph()
    assert "kfcal_helpers.calibration" in real["kfcal_helpers.problems"]  # from .calibration import PROBLEM
    assert "kfcal_helpers.calibration.cli" in real["kfcal_helpers.calibration"]  # from . import cli


def test_no_import_circle():
    """No chain of imports leads from a module back to itself, imports inside functions included:
    problem code -> shared code, and the command line -> the problem list -> problem code."""
    cycles = import_cycles(import_graph())
    assert cycles == [], "import circles: " + "; ".join(" -> ".join(c) for c in cycles)
