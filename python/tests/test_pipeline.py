"""build() and add_session() against the command line on the simulator's tiny building."""

import subprocess
import threading

import numpy as np
import pytest

import chronomap


def same_maps(a_path, b_path):
    a, b = chronomap.TemporalMap.open(a_path), chronomap.TemporalMap.open(b_path)
    return a == b


def test_build_gives_the_command_lines_map(tmp_path, cli, building):
    reports = []
    result = chronomap.build(tmp_path / "py.cmap", building, resolution_m=0.1, fast=True,
                             progress=lambda label, done, total: reports.append((label, done, total)))
    subprocess.run([str(cli), "build", str(tmp_path / "cli.cmap"), *map(str, building), "--resolution", "0.1",
                    "--fast"], check=True, capture_output=True)
    assert same_maps(tmp_path / "py.cmap", tmp_path / "cli.cmap")
    assert result["created"] and result["sessions"] == 3 and len(result["added"]) == 3
    assert result["file_bytes"] == (tmp_path / "py.cmap").stat().st_size
    times = [s["time_s"] for s in result["added"]]
    assert times == sorted(times)
    assert list(chronomap.TemporalMap.open(tmp_path / "py.cmap").times_s) == times
    assert reports and all(0 <= done <= total for _, done, total in reports)
    assert any(done == total for _, done, total in reports)


def test_build_with_registration_reports_each_correction(tmp_path, cli, building):
    result = chronomap.build(tmp_path / "reg.cmap", building, resolution_m=0.1, fast=True, register=True,
                             registration_rounds=1)
    subprocess.run([str(cli), "build", str(tmp_path / "cli.cmap"), *map(str, building), "--resolution", "0.1",
                    "--fast", "--register", "--register-rounds", "1"], check=True, capture_output=True)
    assert same_maps(tmp_path / "reg.cmap", tmp_path / "cli.cmap")
    for s in result["added"]:
        assert s["registration_m"].shape == (3,) and np.isfinite(s["registration_m"]).all()


def test_build_with_a_registration_preset_matches_the_cli(tmp_path, cli, building):
    result = chronomap.build(tmp_path / "odo.cmap", building[:2], resolution_m=0.1, fast=True, register="odometry",
                             registration_rounds=1)
    subprocess.run([str(cli), "build", str(tmp_path / "cli.cmap"), *map(str, building[:2]), "--resolution", "0.1",
                    "--fast", "--register-preset", "odometry", "--register-rounds", "1"], check=True,
                   capture_output=True)
    assert same_maps(tmp_path / "odo.cmap", tmp_path / "cli.cmap")
    for s in result["added"]:
        assert s["correction"]["per_frame"] is not None  # the preset corrects drift
        assert s["registration_m"][2] == 0.0  # planar
    # The mean kept: the two sessions' rigid corrections are opposite.
    assert np.allclose(result["added"][0]["registration_m"] + result["added"][1]["registration_m"], 0.0, atol=1e-6)
    with pytest.raises(chronomap.UsageError, match="localiser or odometry"):
        chronomap.build(tmp_path / "x.cmap", building[:1], resolution_m=0.1, register="recommended")
    assert not (tmp_path / "x.cmap").exists()
    # Anything but a name counts by its truth, as before: None and 0 do not register.
    plain = chronomap.build(tmp_path / "n.cmap", building[:1], resolution_m=0.1, fast=True, register=None)
    assert "correction" not in plain["added"][0]


def test_build_with_times_and_a_failing_progress_callback(tmp_path, building):
    def fail(label, done, total):
        raise KeyError("stop here")
    with pytest.raises(KeyError, match="stop here"):
        chronomap.build(tmp_path / "x.cmap", building[:1], resolution_m=0.1, fast=True, progress=fail)
    import datetime
    t = datetime.datetime(2026, 1, 5, 3, 0, tzinfo=datetime.timezone.utc)
    result = chronomap.build(tmp_path / "t.cmap", building[:2], times=[t, t.timestamp() + 60.0],
                             resolution_m=0.1, fast=True)
    assert [s["time_s"] for s in result["added"]] == [t.timestamp(), t.timestamp() + 60.0]
    with pytest.raises(chronomap.UsageError):
        chronomap.build(tmp_path / "u.cmap", building[:2], times=[t], resolution_m=0.1)
    with pytest.raises(chronomap.UsageError):
        chronomap.build(tmp_path / "v.cmap", [tmp_path / "no such folder"], resolution_m=0.1)
    assert not (tmp_path / "v.cmap").exists()


def test_add_session_appends_and_the_map_answers_as_one_built_whole(tmp_path, building):
    sessions = []
    for i, folder in enumerate(building):
        m = chronomap.integrate_dataset(folder, resolution_m=0.1, fast=True)
        sessions.append(tmp_path / f"s{i}.cmap")
        m.save(sessions[-1])
    first = chronomap.add_session(tmp_path / "4d.cmap", sessions[0], time=1000.0)
    assert first["created"] and first["sessions"] == 1
    second = chronomap.add_session(tmp_path / "4d.cmap", sessions[1], time=2000.0, write="append")
    assert second["appended"] and second["sessions"] == 2 and second["record_bytes"] > 0
    with pytest.raises(chronomap.UsageError):
        chronomap.add_session(tmp_path / "4d.cmap", sessions[2], time=2000.0)
    m = chronomap.TemporalMap.open(tmp_path / "4d.cmap")
    assert list(m.times_s) == [1000.0, 2000.0]
    memory = chronomap.TemporalMap(0.1)
    memory.add(chronomap.SessionMap.open(sessions[0]), 1000.0)
    memory.add(chronomap.SessionMap.open(sessions[1]), 2000.0)
    for t in (1000.0, 2000.0):
        assert m.snapshot(t) == memory.snapshot(t)


def test_build_releases_the_gil(tmp_path, building):
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(1)
            done.wait(0.001)

    t = threading.Thread(target=count)
    t.start()
    try:
        chronomap.build(tmp_path / "g.cmap", building, resolution_m=0.05)
    finally:
        done.set()
        t.join()
    assert len(ticks) > 5


def test_up_turns_the_recording_and_a_bad_one_names_the_argument(tmp_path, threedmatch):
    # 3DMatch's world has +y up: auto finds it, and the map is the one up='+y' gives.
    estimated = chronomap.integrate_dataset(threedmatch, fast=True, up="auto")
    assert estimated == chronomap.integrate_dataset(threedmatch, fast=True, up="+y")
    assert estimated != chronomap.integrate_dataset(threedmatch, fast=True)
    for bad in ("sideways", 3, "Y"):
        with pytest.raises(ValueError, match="up must be"):
            chronomap.integrate_dataset(threedmatch, fast=True, up=bad)
    summary = chronomap.build(tmp_path / "m.cmap", [threedmatch], times=[0.0], fast=True, up="auto")
    assert (summary["up"], summary["up_from"]) == ("+y", "auto")
