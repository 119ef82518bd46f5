"""``python -m kfcal_helpers figures``: every listed file written (PNG 1280x720, SVG on request),
``--list``, bad input; and the two ``calibrate`` fixes (figures with the outages, ``outages`` in JSON)."""

import json
import struct
import xml.etree.ElementTree as ET

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest

from kfcal_helpers.calibration import CalibrationParams, run_monte_carlo
from kfcal_helpers.calibration import cli as calibration_cli
from kfcal_helpers.cli import main
from kfcal_helpers.figures import FIGURES, calibration_realization, write_figures
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
    assert all(f.name.startswith(("calib_", "coop_")) for f in FIGURES)
    assert sum(f.name.startswith("calib_") for f in FIGURES) >= 9
    assert sum(f.name.startswith("coop_") for f in FIGURES) >= 5


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


# ---------------------------------------------------------------------------
# calibrate --figures with --outage, and --json's "outages"
PARAMS = CalibrationParams()
# fixes every 0.2 s; the window 5:10 s removes the fixes at 5.0, 5.2, ..., 9.8 s (indices 25..49)
GAP = np.arange(25, 50)


def test_realization_has_the_outage():
    missing = np.zeros(PARAMS.n_gps, bool)
    missing[GAP] = True
    sim, fr = calibration_realization(PARAMS, missing, seed=4)
    sim0, fr0 = calibration_realization(PARAMS, None, seed=4)
    assert np.isnan(sim.z[0, GAP]).all() and not np.isnan(np.delete(sim.z[0], GAP, axis=0)).any()
    assert not np.isnan(sim0.z).any()
    assert np.all(fr.K[GAP] == 0) and np.all(fr0.K[GAP] != 0)  # no update inside the gap
    j0, j1 = GAP[0] * PARAMS.steps_per_fix, (GAP[-1] + 1) * PARAMS.steps_per_fix
    assert np.all(np.diff(fr.P[j0:j1, 0, 0]) > 0)  # position variance grows through the gap
    # the same draws: identical before the gap, different from its first missing fix on
    np.testing.assert_array_equal(fr.x[:j0], fr0.x[:j0])
    assert np.abs(fr.x[j0 + 1:] - fr0.x[j0 + 1:]).max() > 0


def test_calibrate_figures_draw_the_outage(tmp_path, capsys, monkeypatch):
    cases = []
    original = calibration_cli.figure_case

    def recording_figure_case(mc, seed=0):
        cases.append(original(mc, seed))
        return cases[-1]

    monkeypatch.setattr(calibration_cli, "figure_case", recording_figure_case)
    assert main(["calibrate", "--runs", "20", "--seed", "4", "--outage", "5:10", "--figures", str(tmp_path),
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["outages"] == [[5.0, 10.0]]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "calib_checks.png", "calib_errors.png", "calib_sigma_sawtooth.png"]
    assert png_size(tmp_path / "calib_errors.png") == SLIDE_PX
    (case,) = cases
    sim, fr = case.realization  # the realization the figures drew
    assert np.flatnonzero(np.isnan(sim.z[0, :, 0])).tolist() == GAP.tolist()
    assert np.all(fr.K[GAP] == 0)
    assert case.spans == [(5.0, 10.0)]  # shaded in the figures
    # the same realization as the function builds directly, with the same seed and gap
    np.testing.assert_array_equal(fr.x, calibration_realization(PARAMS, case.missing, seed=4)[1].x)


def test_calibrate_json_lists_the_outages(capsys):
    assert main(["calibrate", "--runs", "5", "--outage", "14:29", "--outage", "2.5:4", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["outages"] == [[14.0, 29.0], [2.5, 4.0]]
    assert main(["calibrate", "--runs", "5", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["outages"] == []
    mc = run_monte_carlo(n_runs=2, seed=0)
    assert calibration_cli.result_to_dict(mc)["outages"] == []


def test_calibrate_figures_into_a_file_fails_before_the_monte_carlo(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert main(["calibrate", "--runs", "100000000", "--figures", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--figures" in err


def test_legend_below_leaves_one_legend_under_the_panels():
    from kfcal_helpers.coop.plots import legend_below, plot_states

    t = np.linspace(0, 1, 11)
    x = np.zeros((11, 6))
    fig = plot_states(t, x, truth=x + 1)
    assert sum(ax.get_legend() is not None for ax in fig.axes) + len(fig.legends) == 1
    leg = legend_below(fig)
    assert leg is not None and fig.legends == [leg]
    assert all(ax.get_legend() is None for ax in fig.axes)
    assert [t.get_text() for t in leg.get_texts()] == ["estimate", "truth"]
    single = plot_states(t, x)
    assert legend_below(single) is None and not single.legends
    plt.close("all")
