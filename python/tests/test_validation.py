"""Times, intrinsics and output paths are checked as the command line checks them: by the same
library functions, so Python cannot store what no command can reach."""

import math
import os
import stat
import subprocess

import numpy as np
import pytest

import chronomap
from scenes import RESOLUTION_M

BAD_TIMES = [1e300, -1e300, math.nan, math.inf, -math.inf, 253402300800.0, -62135596801.0]


@pytest.mark.parametrize("time", BAD_TIMES)
def test_times_outside_the_years_1_to_9999_are_refused(before, time):
    m = chronomap.TemporalMap(RESOLUTION_M)
    with pytest.raises(ValueError, match=r"^time .*(lies outside the years 1 to 9999|is not a number)"):
        m.add(before, time)
    assert len(m) == 0
    m.add(before, 1000.0)
    for ask in (lambda: m.snapshot(time), lambda: m.diff(1000.0, time), lambda: m.diff(time, 1000.0)):
        with pytest.raises(chronomap.UsageError, match=r"^(time|t1|t2) "):
            ask()
    with pytest.raises(chronomap.UsageError, match="^from_time "):
        m.change_counts(from_time=time)
    with pytest.raises(chronomap.UsageError, match="^to_time "):
        m.change_histogram(to_time=time)


def test_the_cli_refuses_the_time_python_refuses(tmp_path, before, cli):
    session = tmp_path / "s.cmap"
    before.save(session)
    out = subprocess.run([str(cli), "add", str(tmp_path / "m.cmap"), str(session), "--time", "1e300"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "lies outside the years 1 to 9999" in out.stderr
    with pytest.raises(chronomap.UsageError, match="lies outside the years 1 to 9999"):
        chronomap.add_session(tmp_path / "m.cmap", session, time=1e300)
    assert not (tmp_path / "m.cmap").exists()
    # The first and last times the CLI accepts are accepted.
    m = chronomap.TemporalMap(RESOLUTION_M)
    m.add(before, -62135596800.0)
    m.add(before, 253402300799.0)
    assert list(m.times_s) == [-62135596800.0, 253402300799.0]


def flat_wall(depth_m=2.0):
    """A 48 x 64 depth image of a wall `depth_m` ahead, as uint16 millimetres."""
    return np.full((48, 64), int(depth_m * 1000), dtype=np.uint16)


# How the library's message writes each value (C++ streams).
WRITTEN = {-525.0: "-525", 0.0: "0", math.inf: "inf", -math.inf: "-inf"}


@pytest.mark.parametrize("name, index, value", [
    ("fx", 0, -525.0),  # a negative focal length would mirror the map
    ("fx", 0, 0.0),
    ("fy", 1, -525.0),
    ("fy", 1, math.nan),
    ("fx", 0, math.inf),
    ("cx", 2, math.nan),
    ("cy", 3, -math.inf),
])
def test_bad_intrinsics_are_refused_naming_them(name, index, value):
    k = [525.0, 525.0, 31.5, 23.5]
    k[index] = value
    written = "nan" if math.isnan(value) else WRITTEN[value]
    message = rf"^add_frame: intrinsics .*\b{name} {written}\b.*: focal lengths must be positive and all values finite"
    integrator = chronomap.Integrator(RESOLUTION_M)
    with pytest.raises(ValueError, match=message):
        integrator.add_frame(flat_wall(), k, np.eye(4))
    K = np.array([[k[0], 0, k[2]], [0, k[1], k[3]], [0, 0, 1]])
    with pytest.raises(chronomap.UsageError, match=message):
        integrator.add_frame(flat_wall(), K, np.eye(4))
    with pytest.raises(chronomap.UsageError, match=message):  # float32 metres: no other check on this path
        integrator.add_frame(flat_wall().astype(np.float32) / 1000, k, np.eye(4))
    assert integrator.frames == 0
    integrator.add_frame(flat_wall(), [525.0, 525.0, 31.5, 23.5], np.eye(4))
    assert integrator.frames == 1


def test_the_cli_refuses_the_intrinsics_python_refuses(tmp_path, cli, threedmatch):
    rule = "focal lengths must be positive and all values finite"
    out = subprocess.run([str(cli), "integrate", str(threedmatch), "-o", str(tmp_path / "s.cmap"),
                          "--intrinsics=-525,525,320,240"], capture_output=True, text=True)
    assert out.returncode == 2 and rule in out.stderr, out.stderr
    with pytest.raises(chronomap.UsageError, match=rule):
        chronomap.Integrator().add_frame(flat_wall(), [-525.0, 525.0, 320.0, 240.0], np.eye(4))


@pytest.mark.parametrize("kind", ["SessionMap", "TemporalMap", "RhythmModels", "ColourModel", "add_session", "build"])
def test_save_refuses_to_replace_a_fifo(tmp_path, before, after, threedmatch, kind):
    # Every way Python writes a file goes through the library's output check: as root,
    # save("/dev/null") replaced the device with a map file.
    m = chronomap.TemporalMap(RESOLUTION_M, color_distance=4.0)
    for day in range(4):
        m.add(before, 86400.0 * day + 8 * 3600)
        m.add(after, 86400.0 * day + 14 * 3600)
    session = tmp_path / "session.cmap"
    before.save(session)
    save = {"SessionMap": lambda path: before.save(path), "TemporalMap": lambda path: m.save(path),
            "RhythmModels": lambda path: chronomap.RhythmModels.fit(m).save(path),
            "ColourModel": lambda path: chronomap.ColourModel.fit(m).save(path),
            "add_session": lambda path: chronomap.add_session(path, session, time=0.0),
            "build": lambda path: chronomap.build(path, [threedmatch], times=[0.0], resolution_m=0.1, fast=True)}[kind]
    fifo = tmp_path / "out"
    os.mkfifo(fifo)
    with pytest.raises(chronomap.Error, match="out"):
        save(fifo)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert sorted(os.listdir(tmp_path)) == ["out", "session.cmap"]
