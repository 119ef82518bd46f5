"""Orbit observation logs: the course's .mat format (a cell array per step, written here with scipy's
savemat as the course's file is), the CSV folder, the generated stand-in, and hostile or wrong files, each
refused in one line naming the file or variable."""

import os

import numpy as np
import pytest
from scipy.io import savemat

from kfcal_helpers.orbit import OrbitParams, simulate
from kfcal_helpers.orbit.data import (COURSE_LOG_VARIABLE, MAX_FILE_BYTES, course_log, course_log_path, load_log,
                                      log_params, write_generated_log, write_log_csv, write_log_mat)

import log_files as lf

SMALL = OrbitParams(n_steps=300)  # 3000 s: passes of several stations


@pytest.fixture(scope="module")
def small_log():
    return simulate(SMALL, seed=3).log()


def _cells(blocks):
    """A 1 x K MATLAB cell array (an object array) of ``blocks``."""
    cells = np.empty((1, len(blocks)), dtype=object)
    for k, b in enumerate(blocks):
        cells[0, k] = b
    return cells


def _course_mat(log, path, **change):
    """The log as the course's .mat: tvec 1 x K, ydata a 1 x K cell of 4 x m blocks, Qtrue, Rtrue, measLabels."""
    arrays = {"tvec": log.t[None, :], "ydata": _cells(log.ydata), "Qtrue": log.Qtrue, "Rtrue": log.Rtrue,
              "measLabels": np.array(["rho", "rhodot", "phi", "id"], dtype=object)}
    arrays.update(change)
    savemat(path, arrays)
    return path


def test_generated_log_is_seeded_and_has_stations(small_log):
    again = simulate(SMALL, seed=3).log()
    assert all(np.array_equal(a, b) for a, b in zip(small_log.ydata, again.ydata))
    assert small_log.dof.sum() > 0 and small_log.ydata[0].shape == (4, 0)
    assert not all(np.array_equal(a, b) for a, b in zip(small_log.ydata, simulate(SMALL, seed=4).log().ydata))


def test_course_mat_round_trip(small_log, tmp_path):
    back = load_log(_course_mat(small_log, tmp_path / "orbitdeterm_finalproj_KFdata.mat"))
    assert np.array_equal(back.y, small_log.y, equal_nan=True) and np.array_equal(back.t, small_log.t)
    assert np.array_equal(back.Qtrue, small_log.Qtrue) and np.array_equal(back.Rtrue, small_log.Rtrue)
    assert back.truth is None and back.source.endswith("KFdata.mat")
    again = load_log(write_log_mat(back, tmp_path / "again.mat"))
    assert np.array_equal(again.y, back.y, equal_nan=True)
    p = log_params(back)
    assert p.n_steps == 300 and p.dt == pytest.approx(10.0) and np.array_equal(p.Rtrue, small_log.Rtrue)


def test_csv_round_trip_and_row_order(small_log, tmp_path):
    folder = write_log_csv(small_log, tmp_path / "log")
    assert (folder / "ydata.csv").read_text().startswith("t,station_id,rho,rhodot,phi\n")
    back = load_log(folder)
    assert np.array_equal(back.y, small_log.y, equal_nan=True)
    lines = (folder / "ydata.csv").read_text().splitlines()
    (folder / "ydata.csv").write_text("\n".join(lines[:1] + lines[:0:-1]) + "\n")  # rows reversed
    assert np.array_equal(load_log(folder).y, small_log.y, equal_nan=True)


def test_column_forms_of_tvec_and_ydata(small_log, tmp_path):
    """MATLAB may hold tvec as K x 1 and ydata as a K x 1 cell array: both are read."""
    f = _course_mat(small_log, tmp_path / "col.mat", tvec=small_log.t[:, None], ydata=_cells(small_log.ydata).T)
    assert np.array_equal(load_log(f).y, small_log.y, equal_nan=True)


def test_written_generated_log_is_the_fallback(monkeypatch, tmp_path, small_log):
    for name in ("gen.mat", "gen_csv"):
        path = write_generated_log(tmp_path / name, seed=3, params=SMALL)
        assert np.array_equal(load_log(path).y, small_log.y, equal_nan=True)
    monkeypatch.setenv(COURSE_LOG_VARIABLE, str(tmp_path / "gen.mat"))
    log, found, _ = course_log()
    assert found and np.array_equal(log.y, small_log.y, equal_nan=True)
    with pytest.raises(ValueError, match="seed"):
        write_generated_log(tmp_path / "x.mat", seed=-1)


def test_spreadsheet_csv_bom_crlf(small_log, tmp_path):
    folder = write_log_csv(small_log, tmp_path / "log")
    for name in ("tvec", "ydata", "Qtrue", "Rtrue"):
        f = folder / f"{name}.csv"
        f.write_bytes(b"\xef\xbb\xbf" + f.read_text().replace("\n", "\r\n").encode())
    assert np.array_equal(load_log(folder).y, small_log.y, equal_nan=True)


def test_phi_in_0_2pi_is_wrapped(small_log, tmp_path):
    shifted = tuple(np.vstack([b[:2], np.mod(b[2:3], 2 * np.pi), b[3:]]) for b in small_log.ydata)
    back = load_log(_course_mat(small_log, tmp_path / "a.mat",
                                ydata=_cells(shifted)))
    assert np.allclose(back.y, small_log.y, equal_nan=True, atol=1e-12)


def test_course_log_falls_back_to_the_generated_log(monkeypatch, tmp_path, small_log):
    monkeypatch.delenv(COURSE_LOG_VARIABLE, raising=False)
    log, found, message = course_log(SMALL, seed=3)
    assert not found and "KFCAL_ORBIT_LOG is not set" in message and "seed 3" in message
    assert np.array_equal(log.y, small_log.y, equal_nan=True) and log.truth is not None
    monkeypatch.setenv(COURSE_LOG_VARIABLE, str(tmp_path / "missing.mat"))
    assert course_log_path() is None and "names no existing path" in course_log(SMALL, seed=3)[2]
    monkeypatch.setenv(COURSE_LOG_VARIABLE, str(_course_mat(small_log, tmp_path / "c.mat")))
    log, found, message = course_log()
    assert found and message.startswith("course log found") and np.array_equal(log.y, small_log.y, equal_nan=True)


def _block_log(log, k, block):
    blocks = list(log.ydata)
    blocks[k] = block
    return _cells(blocks)


def _edit_csv(name, edit):
    def make(root, log):
        folder = write_log_csv(log, root / "log")
        f = folder / f"{name}.csv"
        edit(f)
        return folder
    return make


def _mat(**change):
    def make(root, log):
        values = {k: (v(log) if callable(v) else v) for k, v in change.items()}
        return _course_mat(log, root / "log.mat", **values)
    return make


def _raw(content: bytes, suffix=".mat"):
    def make(root, log):
        f = root / f"file{suffix}"
        f.write_bytes(content)
        return f
    return make


def _fifo(root, log):
    folder = write_log_csv(log, root / "log")
    (folder / "ydata.csv").unlink()
    lf.fifo(folder / "ydata.csv")
    return folder


def _zero_link(root, log):
    folder = write_log_csv(log, root / "log")
    (folder / "ydata.csv").unlink()
    lf.link("/dev/zero", folder / "ydata.csv")
    return folder


def _zero_mat(root, log):
    return lf.link("/dev/zero", root / "log.mat")


def _socket(root, log):
    return lf.unix_socket(root / "s.mat")


def _huge_csv(root, log):
    folder = write_log_csv(log, root / "log")
    (folder / "ydata.csv").unlink()
    lf.sparse_file(folder / "ydata.csv", MAX_FILE_BYTES["ydata"] + 1)
    return folder


def _huge_mat(root, log):
    return lf.sparse_file(root / "log.mat", MAX_FILE_BYTES["mat"] + 1)


def _short_lines(root, log):
    folder = write_log_csv(log, root / "log")
    (folder / "ydata.csv").write_text("1\n" * 300_000)
    return folder


def _mat_bomb(root, log):
    """A small compressed .mat whose one cell inflates to 40 MB of zeros."""
    cells = _cells([np.empty((4, 0)), np.zeros((4, 1_250_000)), np.empty((4, 0))])
    f = root / "bomb.mat"
    savemat(f, {"tvec": np.array([[0.0, 10.0, 20.0]]), "ydata": cells, "Qtrue": 1e-10 * np.eye(2),
                "Rtrue": np.eye(3)}, do_compression=True)
    assert f.stat().st_size < 1_000_000
    return f


def _bad_ids(ids):
    return _mat(ydata=lambda log: _block_log(log, 50, np.array([[7000.0] * len(ids), [0.1] * len(ids),
                                                                  [0.2] * len(ids), ids])))


#: (id, builder(root, log) -> path, pieces the one-line message must hold)
BAD = [
    ("missing", lambda root, log: root / "nothing.mat", ["path:", "does not exist"]),
    ("not mat suffix", _raw(b"x", ".txt"), ["path:", "must be a .mat file or a folder of CSVs"]),
    ("fifo", _fifo, ["path:", "FIFO", "regular files only"]),
    ("dev zero link", _zero_link, ["path:", "/dev/zero", "character device"]),
    ("dev zero mat", _zero_mat, ["path:", "/dev/zero", "character device"]),
    ("socket", _socket, ["path:", "socket"]),
    ("huge csv", _huge_csv, ["ydata:", "larger than the", "MB a log of at most 100000 steps needs"]),
    ("huge mat", _huge_mat, ["path:", "larger than the"]),
    ("many short lines", _short_lines, ["ydata:", "300000 lines", "more than one row per station measurement"]),
    ("mat bomb", _mat_bomb, ["path:", "expands to more than"]),
    ("garbage mat", _raw(b"not a matlab file at all" * 10), ["path:", "not a readable MATLAB file"]),
    ("bad columns", _edit_csv("ydata", lambda f: f.write_text("t,station_id,rho\n10,1,7000\n")),
     ["ydata:", "must have the 5 columns t, station_id, rho, rhodot, phi, got the header t, station_id, rho"]),
    ("3 columns", _edit_csv("ydata", lambda f: f.write_text("10,1,7000\n")),
     ["ydata:", "must have the 5 columns t, station_id, rho, rhodot, phi, got 3"]),
    ("too many columns", _edit_csv("ydata", lambda f: f.write_text("10,1,7000,0.1,0.2,5\n")),
     ["ydata:", "a line of 6 values"]),
    ("text value", _edit_csv("ydata", lambda f: f.write_text("10,1,far,0.1,0.2\n")),
     ["ydata:", "not a numeric CSV"]),
    ("semicolons", _edit_csv("ydata", lambda f: f.write_text("10;1;7000;0,1;0,2\n")),
     ["ydata:", "semicolon-separated"]),
    ("nan csv", _edit_csv("ydata", lambda f: f.write_text("10,1,nan,0.1,0.2\n")),
     ["ydata:", "finite numbers", "row 1"]),
    ("time not in tvec", _edit_csv("ydata", lambda f: f.write_text("15,1,7000,0.1,0.2\n")),
     ["ydata:", "t = 15 s is not one of tvec's times"]),
    ("empty ydata", _edit_csv("ydata", lambda f: f.write_text("t,station_id,rho,rhodot,phi\n")),
     ["ydata holds no measurement"]),
    ("empty tvec", _edit_csv("tvec", lambda f: f.write_text("\n")), ["tvec:", "is empty"]),
    ("binary csv", _edit_csv("Qtrue", lambda f: f.write_bytes(b"\xff\xfe\x00")), ["Qtrue:", "not text"]),
    ("Qtrue 3x3", _edit_csv("Qtrue", lambda f: f.write_text("1,0,0\n0,1,0\n0,0,1\n")),
     ["Qtrue:", "a line of 3 values"]),
    ("tvec from 10", _mat(tvec=lambda log: log.t[None, :] + 10.0), ["tvec must start at 0 s"]),
    ("tvec uneven", _mat(tvec=lambda log: (log.t + np.r_[0, 3.0, np.zeros(log.t.size - 2)])[None, :]),
     ["tvec must be increasing with a constant step"]),
    ("tvec nan", _mat(tvec=lambda log: np.r_[log.t[:-1], np.nan][None, :]), ["tvec must hold only finite times"]),
    ("ydata numeric", _mat(ydata=np.zeros((4, 301))), ["ydata must be a cell array", "numeric matrix"]),
    ("ydata text", _mat(ydata="abc"), ["ydata must be a cell array", "text"]),
    ("ydata 2 rows", _mat(ydata=np.vstack([_cells([np.empty((4, 0))] * 301)] * 2)), ["ydata must be 1 x K"]),
    ("ydata short", _mat(ydata=lambda log: _cells(log.ydata[:-1])),
     ["ydata must have one block per time of tvec (301), got 300"]),
    ("block 3 rows", _mat(ydata=lambda log: _block_log(log, 50, np.ones((3, 1)))),
     ["ydata{51} must be a 4 x m block", "(3, 1)"]),
    ("block text", _mat(ydata=lambda log: _block_log(log, 50, "abc")), ["ydata{51} must be a numeric matrix, got text"]),
    ("block nan", _mat(ydata=lambda log: _block_log(log, 50, np.array([[np.nan], [0.1], [0.2], [1.0]]))),
     ["ydata{51} must hold finite numbers"]),
    ("station id 13", _bad_ids([13.0]), ["ydata{51}: station ids must be distinct integers 1..12, got 13"]),
    ("station id 0", _bad_ids([0.0]), ["station ids must be distinct integers 1..12, got 0"]),
    ("station id 2.5", _bad_ids([2.5]), ["station ids", "got 2.5"]),
    ("station twice", _bad_ids([3.0, 3.0]), ["station ids must be distinct", "got 3, 3"]),
    ("negative range", _mat(ydata=lambda log: _block_log(log, 50, np.array([[-1.0], [0.1], [0.2], [1.0]]))),
     ["ydata{51}: rho must be a range in (0, 1e+06] km, got -1"]),
    ("phi 10 rad", _mat(ydata=lambda log: _block_log(log, 50, np.array([[7000.0], [0.1], [10.0], [1.0]]))),
     ["ydata{51}: phi must be an angle in [-2 pi, 2 pi] rad, got 10"]),
    ("Rtrue singular", _mat(Rtrue=np.zeros((3, 3))), ["Rtrue", "positive"]),
    ("Qtrue huge", _mat(Qtrue=1e300 * np.eye(2)), ["Qtrue", "at most"]),
    ("Rtrue 5x5", _mat(Rtrue=np.eye(5)), ["Rtrue must be a 3 x 3 matrix, got shape (5, 5)"]),
    ("Qtrue complex", _mat(Qtrue=1j * np.eye(2)), ["Qtrue must hold real numbers"]),
    ("Qtrue missing", lambda root, log: savemat(root / "q.mat", {"tvec": log.t[None, :]}) or root / "q.mat",
     ["ydata: variable missing from", "needs tvec, ydata, Qtrue, Rtrue"]),
]


@pytest.mark.parametrize("build,pieces", [(b, p) for _, b, p in BAD], ids=[i for i, _, _ in BAD])
def test_bad_logs_are_refused_in_one_line(small_log, tmp_path, build, pieces):
    path = build(tmp_path, small_log)
    with pytest.raises(ValueError) as info:
        load_log(path)
    message = str(info.value)
    assert "\n" not in message and len(message) < 400, message
    for piece in pieces:
        assert piece in message, message


def test_argname_names_the_option(tmp_path):
    with pytest.raises(ValueError, match=r"^--log: .* does not exist"):
        load_log(tmp_path / "x.mat", argname="--log")
    for bad in (None, 3, True, ""):
        with pytest.raises(ValueError, match="--log must be a .mat file or a folder of CSVs path"):
            load_log(bad, argname="--log")
    with pytest.raises(ValueError, match="n_stations must be an integer in 1..36"):
        load_log(tmp_path, n_stations=40)


def test_write_errors_name_the_argument(small_log, tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="folder: .* is an existing file"):
        write_log_csv(small_log, tmp_path / "file")
    with pytest.raises(ValueError, match="file: the folder .* does not exist"):
        write_log_mat(small_log, tmp_path / "no" / "x.mat")
    with pytest.raises(ValueError, match="log must be"):
        write_log_mat("log", tmp_path / "x.mat")


@pytest.mark.skipif(course_log_path() is None, reason="KFCAL_ORBIT_LOG does not name the course's log")
def test_the_course_log_when_present():
    log = load_log(course_log_path())
    assert log.t.size >= 2 and log.dof.sum() > 0 and os.path.exists(log.source)
