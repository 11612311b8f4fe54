"""chronomap.changes: the objects chronomap diff --json lists, from the same library call."""

import json
import subprocess

import numpy as np
import pytest

import chronomap
import scenes


def session_with_box_at(dx):
    """The room of scenes.py with the box's front moved by dx metres in x."""
    integrator = chronomap.Integrator(resolution_m=scenes.RESOLUTION_M, max_range_m=5.0)
    points = scenes.wall()
    box = scenes.box_face() + np.array([dx, 0.0, 0.0])
    # The box hides the wall behind it: keep the wall points whose rays pass beside it.
    at_box = points[:, :2] * (1.5 / points[:, 2:3])
    beside = (np.abs(at_box[:, 0] - dx) >= 0.2) | (np.abs(at_box[:, 1]) >= 0.2)
    integrator.add_points(np.vstack([points[beside], box]), np.zeros(3))
    return integrator.finish()


@pytest.fixture(scope="module")
def moved_map(tmp_path_factory):
    m = chronomap.TemporalMap(scenes.RESOLUTION_M)
    m.add(session_with_box_at(-0.4), 100.0, name="box left")
    m.add(session_with_box_at(0.4), 200.0, name="box right")
    path = tmp_path_factory.mktemp("changes") / "moved.cmap"
    m.save(str(path))
    return m, path


def test_a_moved_box_is_one_object_that_moved(moved_map):
    m, _ = moved_map
    objects = chronomap.changes(m, 100.0, 200.0)
    assert len(objects) == 1
    o = objects[0]
    assert o["id"] == 1 and o["kind"] == "moved" and o["voxels"] == 128
    assert o["from"]["voxels"] == 64 and o["to"]["voxels"] == 64
    assert o["distance_m"] == pytest.approx(0.8)
    assert np.allclose(o["from"]["centroid"], [-0.4, 0.0, 1.525])
    assert np.allclose(o["centroid"], [0.4, 0.0, 1.525]) and o["centroid"] == o["to"]["centroid"]
    assert np.allclose(o["size"], [0.4, 0.4, 0.05])
    # Two session maps give the same answer; the raw preset the two halves.
    assert chronomap.changes(m.snapshot(100.0), m.snapshot(200.0)) == objects
    raw = chronomap.changes(m, 100.0, 200.0, preset="raw")
    assert sorted(o["kind"] for o in raw) == ["appeared", "vanished"]
    with pytest.raises(chronomap.UsageError, match="'fancy' is not a preset"):
        chronomap.changes(m, 100.0, 200.0, preset="fancy")


def test_python_equals_the_command_line(moved_map, cli, tmp_path):
    m, path = moved_map
    for preset in ("recommended", "raw"):
        out = subprocess.run([str(cli), "diff", f"{path}@100", f"{path}@200", "--preset", preset, "-o",
                              str(tmp_path / f"{preset}.cmap"), "--json"], check=True, capture_output=True, text=True)
        assert json.loads(out.stdout)["objects"] == chronomap.changes(m, 100.0, 200.0, preset=preset), preset
    # With no flags the command line answers as changes() does with its defaults.
    out = subprocess.run([str(cli), "diff", f"{path}@100", f"{path}@200", "-o", str(tmp_path / "d.cmap"), "--json"],
                         check=True, capture_output=True, text=True)
    assert json.loads(out.stdout)["objects"] == chronomap.changes(m, 100.0, 200.0)


def test_python_answers_as_the_demo_report(cli, tmp_path):
    # The Python front door on `chronomap demo`'s office: every pair of report.json (sessions
    # numbered from 1) lists the objects chronomap.changes() gives for the two sessions' times.
    subprocess.run([str(cli), "demo", "--resolution-scale", "0.2", "-o", str(tmp_path / "demo")], check=True,
                   capture_output=True, text=True)
    report = json.loads((tmp_path / "demo" / "report.json").read_text())
    m = chronomap.TemporalMap.open(tmp_path / "demo" / "office.cmap")
    times = m.times_s
    assert len(report["pairs"]) == len(times) - 1
    listed = 0
    for k, pair in enumerate(report["pairs"]):
        assert (pair["from"], pair["to"]) == (k + 1, k + 2)
        assert pair["objects"] == chronomap.changes(m, float(times[k]), float(times[k + 1])), pair["from"]
        listed += len(pair["objects"])
    assert listed > 0
