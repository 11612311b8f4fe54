"""integrate_dataset against the command line, and frame by frame against integrate_dataset."""

import json
import subprocess
import threading
import time
import warnings

import numpy as np
import pytest

import chronomap


def frames_of(root):
    """The 3DMatch frames as numpy arrays: (depth uint16, rgb, T_world_camera), in frame order."""
    k = np.loadtxt(root / "camera-intrinsics.txt")
    out = []
    for pose_file in sorted((root / "seq-01").glob("frame-*.pose.txt")):
        stem = str(pose_file)[: -len(".pose.txt")]
        out.append((chronomap.read_depth_png(stem + ".depth.png"), chronomap.read_color_png(stem + ".color.png"),
                    np.loadtxt(pose_file)))
    return k, out


@pytest.mark.parametrize("fast", [False, True])
def test_integrate_dataset_equals_the_cli(tmp_path, threedmatch, cli, fast):
    cli_file = tmp_path / "cli.cmap"
    command = [str(cli), "integrate", str(threedmatch), "-o", str(cli_file)] + (["--fast"] if fast else [])
    subprocess.run(command, check=True, capture_output=True)
    ours = chronomap.integrate_dataset(threedmatch, resolution_m=0.05, fast=fast)
    theirs = chronomap.SessionMap.open(cli_file)
    assert ours.counts()["occupied_voxels"] > 1000
    # The same map bytes: both written by SessionMap.save; and the same map once read (a file
    # keeps hit positions quantised, docs/file-format.md).
    ours.save(tmp_path / "ours.cmap")
    theirs.save(tmp_path / "theirs.cmap")
    assert (tmp_path / "ours.cmap").read_bytes() == (tmp_path / "theirs.cmap").read_bytes()
    assert chronomap.SessionMap.open(tmp_path / "ours.cmap") == theirs


def test_a_range_that_drops_more_than_a_tenth_of_the_points_warns(threedmatch):
    with pytest.warns(UserWarning, match=r"of \d+ valid points \(\d+\.\d%\) lie beyond --max-range 3 m"):
        chronomap.integrate_dataset(threedmatch, fast=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        chronomap.integrate_dataset(threedmatch, fast=True, max_range_m=10.0)


@pytest.mark.parametrize("fast", [False, True])
def test_add_frame_equals_integrate_dataset(threedmatch, fast):
    k, frames = frames_of(threedmatch)
    assert len(frames) == 5
    integrator = chronomap.Integrator(resolution_m=0.05, max_range_m=3.0, fast=fast)
    for depth, rgb, pose in frames:
        integrator.add_frame(depth, k, pose, rgb=rgb, depth_scale=1000.0)
    assert integrator.frames == 5
    assert integrator.finish() == chronomap.integrate_dataset(threedmatch, fast=fast)


def test_carving_beyond_the_range_equals_the_cli_and_adds_free_space(tmp_path, threedmatch, cli):
    cli_file = tmp_path / "cli.cmap"
    subprocess.run([str(cli), "integrate", str(threedmatch), "-o", str(cli_file), "--fast", "--max-range", "1.5",
                    "--carve-beyond-range"], check=True, capture_output=True)
    carved = chronomap.integrate_dataset(threedmatch, fast=True, max_range_m=1.5, carve_beyond_range=True)
    carved.save(tmp_path / "carved.cmap")  # files keep hit positions quantised
    assert chronomap.SessionMap.open(tmp_path / "carved.cmap") == chronomap.SessionMap.open(cli_file)
    plain = chronomap.integrate_dataset(threedmatch, fast=True, max_range_m=1.5)
    assert carved.counts()["free_voxels"] > plain.counts()["free_voxels"]
    k, frames = frames_of(threedmatch)
    integrator = chronomap.Integrator(resolution_m=0.05, max_range_m=1.5, fast=True, carve_beyond_range=True)
    for depth, rgb, pose in frames:
        integrator.add_frame(depth, k, pose, rgb=rgb, depth_scale=1000.0)
    assert integrator.finish() == carved


def test_depth_edges_equal_the_cli_and_drop_flying_pixels(tmp_path, threedmatch, cli):
    cli_file = tmp_path / "cli.cmap"
    subprocess.run([str(cli), "integrate", str(threedmatch), "-o", str(cli_file), "--fast", "--depth-edges", "0.05"],
                   check=True, capture_output=True)
    edged = chronomap.integrate_dataset(threedmatch, fast=True, depth_edges=0.05)
    edged.save(tmp_path / "edged.cmap")  # files keep hit positions quantised
    assert chronomap.SessionMap.open(tmp_path / "edged.cmap") == chronomap.SessionMap.open(cli_file)
    plain = chronomap.integrate_dataset(threedmatch, fast=True)
    assert edged.counts()["occupied_voxels"] < plain.counts()["occupied_voxels"]
    k, frames = frames_of(threedmatch)
    integrator = chronomap.Integrator(resolution_m=0.05, fast=True, depth_edges=0.05)
    for depth, rgb, pose in frames:
        integrator.add_frame(depth, k, pose, rgb=rgb, depth_scale=1000.0)
    assert integrator.finish() == edged
    with pytest.raises(ValueError, match="depth edge ratio"):
        chronomap.integrate_dataset(threedmatch, depth_edges=-0.1)


def test_carve_level_auto_is_two_in_fast_mode_at_two_centimetres(threedmatch):
    auto = chronomap.integrate_dataset(threedmatch, resolution_m=0.02, fast=True)
    assert auto == chronomap.integrate_dataset(threedmatch, resolution_m=0.02, fast=True, carve_level=2)
    off = chronomap.integrate_dataset(threedmatch, resolution_m=0.02, fast=True, carve_level=0)
    assert auto != off
    # Coarse cubes make voxels next to crossed ones known free; the hits stay fast mode's.
    assert auto.counts()["free_voxels"] > off.counts()["free_voxels"]
    assert auto.counts()["occupied_voxels"] == pytest.approx(off.counts()["occupied_voxels"], rel=0.01)
    k, frames = frames_of(threedmatch)
    integrator = chronomap.Integrator(resolution_m=0.02, fast=True)
    for depth, rgb, pose in frames:
        integrator.add_frame(depth, k, pose, rgb=rgb, depth_scale=1000.0)
    assert integrator.finish() == auto
    assert chronomap.integrate_dataset(threedmatch, fast=True) == chronomap.integrate_dataset(
        threedmatch, fast=True, carve_level=0)  # auto is off at 0.05 m
    for bad in (5, -1, "two", True, 1.5):
        with pytest.raises(ValueError, match="carve_level must be 'auto' or a level from 0 to 4"):
            chronomap.integrate_dataset(threedmatch, fast=True, carve_level=bad)


def test_float_depth_in_metres_agrees_with_uint16(threedmatch):
    k, frames = frames_of(threedmatch)
    depth, rgb, pose = frames[0]
    a = chronomap.Integrator()
    a.add_frame(depth, k, pose, rgb=rgb)
    b = chronomap.Integrator()
    b.add_frame((depth / 1000.0).astype(np.float32), k, pose, rgb=rgb)
    ma, mb = a.finish(), b.finish()
    assert a.points == 0  # finish() starts again empty
    ca, cb = ma.occupied_centers(), mb.occupied_centers()
    assert len(ca) > 1000
    # Depths differ by float rounding only: the occupied voxels are nearly all the same ones.
    assert abs(len(ca) - len(cb)) <= 0.01 * len(ca)
    assert (mb.state(ca) == chronomap.OCCUPIED).mean() > 0.98


def test_non_contiguous_frames_integrate_alike(threedmatch):
    k, frames = frames_of(threedmatch)
    depth, rgb, pose = frames[0]
    a = chronomap.Integrator()
    a.add_frame(depth, k, pose, rgb=rgb)
    b = chronomap.Integrator()
    wide = np.zeros((depth.shape[0], depth.shape[1] * 2), dtype=np.uint16)
    wide[:, ::2] = depth
    bgr = rgb[:, :, ::-1].copy()
    b.add_frame(wide[:, ::2], np.array([[k[0, 0], 0, k[0, 2]], [0, k[1, 1], k[1, 2]], [0, 0, 1]]),
                np.asfortranarray(pose), rgb=bgr[:, :, ::-1])
    assert a.finish() == b.finish()


def test_progress_callback(threedmatch):
    calls = []
    chronomap.integrate_dataset(threedmatch, progress=lambda label, done, total: calls.append((label, done, total)))
    assert calls == [("integrating", i, 5) for i in range(1, 6)]


def test_progress_callback_exception_propagates(threedmatch):
    def fail(label, done, total):
        raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        chronomap.integrate_dataset(threedmatch, progress=fail)


def test_gil_is_released_during_integration(threedmatch):
    ticks = 0
    result = {}

    def work():
        start = time.perf_counter()
        result["map"] = chronomap.integrate_dataset(threedmatch, threads=1)
        result["seconds"] = time.perf_counter() - start

    worker = threading.Thread(target=work)
    worker.start()
    while worker.is_alive():
        ticks += 1
        time.sleep(0.001)
    worker.join()
    assert result["map"].counts()["occupied_voxels"] > 1000
    # With the GIL held for the whole call this thread would tick about once.
    assert ticks >= 10, (ticks, result["seconds"])


def test_formats_are_the_registry_the_cli_lists(cli, threedmatch):
    # One registry: Python's formats(), the CLI's --list-formats and what format= takes.
    listed = json.loads(subprocess.run([str(cli), "integrate", "--list-formats", "--json"], check=True,
                                       capture_output=True, text=True).stdout)
    ours = chronomap.formats()
    assert [f["name"] for f in ours] == [f["name"] for f in listed]
    assert [f["aliases"] for f in ours] == [f["aliases"] for f in listed]
    names = [f["name"] for f in ours]
    assert names[:4] == ["tum", "3dmatch", "scannet", "clouds"]
    assert "7scenes" in ours[1]["aliases"]
    # An alias reads as its reader; a name no reader has is refused listing those there are.
    by_alias = chronomap.integrate_dataset(threedmatch, format="7scenes")
    assert by_alias == chronomap.integrate_dataset(threedmatch, format="3dmatch")
    with pytest.raises(chronomap.UsageError, match="expected auto, tum, 3dmatch"):
        chronomap.integrate_dataset(threedmatch, format="kinectfusion")
    if "rosbag" in names:
        # The bag readers are registered before format= is read: a TUM folder is not a bag.
        with pytest.raises(chronomap.UsageError):
            chronomap.integrate_dataset(threedmatch, format="rosbag")
