"""The scripts in examples/ run as a user runs them, and give what they say."""

import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import chronomap
from conftest import REPO

EXAMPLES = REPO / "examples"


def run_example(name, *args):
    # The chronomap package these tests import, first on the scripts' path.
    package_root = str(pathlib.Path(chronomap.__file__).resolve().parents[1])
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")])))
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *map(str, args)], env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def office(tmp_path_factory, cli):
    out = tmp_path_factory.mktemp("office") / "office"
    subprocess.run([str(cli), "simulate", "--preset", "office", "--resolution-scale", "0.2", "-o", str(out)],
                   check=True, capture_output=True)
    return out


def test_integrate_tum_numpy_gives_the_dataset_readers_map(tmp_path, office):
    session = office / "session_00"
    out = run_example("integrate_tum_numpy.py", session, tmp_path / "s.cmap")
    assert "frames in" in out
    mine, reader = chronomap.SessionMap.open(tmp_path / "s.cmap"), chronomap.integrate_dataset(session)
    # The same voxels with the same hits and colours; ray lengths agree to float rounding (the
    # example's poses are 4x4 matrices made in numpy, the reader's come from the quaternions)
    # and to the file's quantisation of lengths (format version 3: within 2^-8 relative).
    assert mine.counts() == reader.counts()
    assert np.array_equal(mine.occupied_centers(), reader.occupied_centers())
    assert np.array_equal(mine.occupied_colors(), reader.occupied_colors())
    probes = np.vstack([reader.occupied_centers(), reader.free_centers()[0]])
    a, b = mine.counters(probes), reader.counters(probes)
    assert np.array_equal(a["hits"], b["hits"])
    assert np.allclose(a["length_m"], b["length_m"], rtol=2.0**-8 + 1e-5, atol=1e-6)


def test_build_office_and_show_changes(tmp_path, office):
    out = run_example("build_office.py", office, tmp_path / "office.cmap", "--resolution", "0.1", "--no-register")
    assert "6 sessions in" in out
    m = chronomap.TemporalMap.open(tmp_path / "office.cmap")
    assert len(m) == 6 and m.resolution_m == pytest.approx(0.1)
    shown = run_example("show_changes.py", tmp_path / "office.cmap", "-o", tmp_path / "changes", "--min-voxels", "5")
    png = (tmp_path / "changes" / "top_view.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    # The objects it lists are segment()'s on the same diff.
    changes = m.diff(m.times_s[0], m.times_s[-1], mode="band", neighbourhood_voxels=1, min_shift_voxels=0.5)
    objects = chronomap.segment(changes, connectivity="vertex", min_voxels=5)
    assert f"{len(objects)} objects of 5+ voxels" in shown and len(objects) >= 1
    import open3d as o3d
    ply = o3d.io.read_point_cloud(str(tmp_path / "changes" / "changes.ply"))
    assert len(ply.points) == len(changes)
    assert np.allclose(np.asarray(ply.points), changes.changed_centers())
