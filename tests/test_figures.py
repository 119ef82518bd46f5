"""``python -m kfcal_helpers figures``: every figure of every problem written (PNG 1280x720, SVG on
request), ``--list``, bad input.  Each problem's own figures are tested in tests/test_<problem>_figures.py."""

import struct
import xml.etree.ElementTree as ET

import matplotlib
import matplotlib.pyplot as plt
import pytest

from kfcal_helpers.cli import main
from kfcal_helpers.figures import all_figures, write_figures
from kfcal_helpers.style import SLIDE_DPI, SLIDE_SIZE

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SLIDE_PX = (round(SLIDE_SIZE[0] * SLIDE_DPI), round(SLIDE_SIZE[1] * SLIDE_DPI))
CHEAP = ["calib_truth_euler", "coop_paths"]  # figures that need no filter run or Monte Carlo


def png_size(path):
    """(width, height) in pixels of a PNG, read from its header; asserts it is a complete PNG."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and data[12:16] == b"IHDR", f"{path.name} is not a PNG"
    assert data[-8:-4] == b"IEND", f"{path.name} is truncated"
    return struct.unpack(">II", data[16:24])


def run_cli(capsys, argv):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out.splitlines(), err


FIGURES = all_figures()


def test_every_listed_figure_written_as_slide_png(tmp_path, capsys):
    before = {k: matplotlib.rcParams[k] for k in ("font.size", "figure.figsize", "lines.linewidth", "savefig.bbox")}
    open_figures = plt.get_fignums()
    code, lines, _ = run_cli(capsys, ["figures", str(tmp_path / "slides")])
    assert code == 0
    expected = [str(tmp_path / "slides" / f"{f.name}.png") for f in FIGURES]
    assert lines == expected  # one path per line, in registry order
    assert sorted(p.name for p in (tmp_path / "slides").iterdir()) == sorted(f"{f.name}.png" for f in FIGURES)
    for path in (tmp_path / "slides").iterdir():
        assert path.stat().st_size > 10_000, path.name  # a drawn figure, not an empty canvas
        assert png_size(path) == SLIDE_PX == (1280, 720), path.name
    image = plt.imread(tmp_path / "slides" / "calib_errors.png")  # it decodes, with the slide shape
    assert image.shape[:2] == (720, 1280) and image.std() > 0.01
    # no pyplot figure left open, the caller's rcParams unchanged
    assert plt.get_fignums() == open_figures
    assert {k: matplotlib.rcParams[k] for k in before} == before


def test_svg_subset(tmp_path, capsys):
    code, lines, _ = run_cli(capsys, ["figures", str(tmp_path), "--svg", "--only", *CHEAP])
    assert code == 0
    assert lines == [str(tmp_path / f"{name}.{ext}") for name in CHEAP for ext in ("png", "svg")]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f"{n}.{e}" for n in CHEAP for e in ("png", "svg"))
    for name in CHEAP:
        assert png_size(tmp_path / f"{name}.png") == SLIDE_PX
        root = ET.parse(tmp_path / f"{name}.svg").getroot()
        assert root.tag == "{http://www.w3.org/2000/svg}svg"
        assert root.get("width") == f"{SLIDE_SIZE[0] * 72:g}pt" and root.get("height") == f"{SLIDE_SIZE[1] * 72:g}pt"
        assert len(root.findall(".//{http://www.w3.org/2000/svg}path")) > 20  # axes, ticks, lines


def test_list_names_the_registry(tmp_path, capsys):
    code, lines, _ = run_cli(capsys, ["figures", "--list"])
    assert code == 0
    assert [line.split()[0] for line in lines] == [f.name for f in FIGURES]
    assert all(len(line.split(maxsplit=1)) == 2 for line in lines)  # each with its description
    assert len({f.name for f in FIGURES}) == len(FIGURES)
    assert all(f.name.startswith(("calib_", "coop_", "orbit_")) for f in FIGURES)
    assert sum(f.name.startswith("calib_") for f in FIGURES) >= 9
    assert sum(f.name.startswith("coop_") for f in FIGURES) >= 5
    assert sum(f.name.startswith("orbit_") for f in FIGURES) >= 3


@pytest.mark.parametrize("argv, word", [
    (["figures", "FILE"], "DIR"),
    (["figures", "OUT", "--only", "calib_errors", "no_such_figure"], "--only"),
    (["figures"], "DIR"),
    (["figures", "OUT", "--bogus"], "--bogus"),
])
def test_bad_input_one_line_exit_2(tmp_path, capsys, argv, word):
    (tmp_path / "file.png").write_text("not a directory")
    names = {"FILE": str(tmp_path / "file.png"), "OUT": str(tmp_path / "out")}
    try:
        code = main([names.get(a, a) for a in argv])
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and word in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()  # nothing written


def test_write_figures_validates_its_arguments(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ValueError, match="directory"):
        write_figures(tmp_path / "f", names=CHEAP)
    with pytest.raises(ValueError, match="names.*calib_errors"):  # names the allowed values
        write_figures(tmp_path, names=["calib_errors", "nope"])
    with pytest.raises(ValueError, match="names"):
        write_figures(tmp_path, names=[])
    assert list(tmp_path.iterdir()) == [tmp_path / "f"]


def test_readme_slides_folder_is_ignored_by_git():
    """README's ``python -m kfcal_helpers figures slides/``, run in a clone, writes nothing git would add."""
    import re
    import shutil
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    if shutil.which("git") is None or not (root / ".git").exists():
        pytest.skip("not a git checkout")
    folder = re.search(r"python -m kfcal_helpers figures (\S+?)/?`", (root / "README.md").read_text(encoding="utf-8"))
    assert folder, "README no longer shows the figures command with a folder"
    for ext in ("png", "svg"):
        path = f"{folder.group(1)}/{FIGURES[0].name}.{ext}"
        run = subprocess.run(["git", "check-ignore", "-q", "--no-index", path], cwd=root)
        assert run.returncode == 0, f"{path} would be added by git (.gitignore)"
