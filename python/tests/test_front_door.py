"""Python takes what the command line takes and answers as it does: ISO-8601 times wherever a
time is taken (the CLI's parseTime), a voxel's history as `chronomap history --json` lists it
(named states with their counters), and build()'s poses per frame with the registration's
correction."""

import datetime
import json
import subprocess

import numpy as np
import pytest

import chronomap
from scenes import RESOLUTION_M

T1 = "2026-01-05T03:00:00Z"
T1_S = datetime.datetime(2026, 1, 5, 3, 0, tzinfo=datetime.timezone.utc).timestamp()
T2 = "2026-01-05T05:30:00+02:00"  # 03:30 UTC
T2_S = T1_S + 1800.0
BOX = [0.0, 0.0, 1.525]


@pytest.fixture()
def two_times(before, after):
    m = chronomap.TemporalMap(RESOLUTION_M)
    m.add(before, T1)
    m.add(after, T2)
    return m


def test_iso_strings_are_times_wherever_a_time_is_taken(tmp_path, before, after, two_times):
    m = two_times
    assert list(m.times_s) == [T1_S, T2_S]
    by_number = chronomap.TemporalMap(RESOLUTION_M)
    by_number.add(before, T1_S)
    by_number.add(after, T2_S)
    assert m == by_number
    # A date alone is midnight UTC, a time without a zone is UTC, seconds as text are seconds.
    assert m.snapshot("2026-01-05").empty()
    assert m.snapshot("2026-01-05 03:10:00") == m.snapshot(T1_S + 600.0) == m.snapshot(str(T1_S + 600.0))
    assert m.snapshot(T2) == m.snapshot(T2_S)
    assert np.array_equal(m.diff(T1, T2).changed_centers(), m.diff(T1_S, T2_S).changed_centers())
    assert len(m.diff(T1, T2)) == 64
    # The box is no plane and nothing stood where it appeared: the shift test across planes keeps it.
    assert len(m.diff(T1, T2, mode="band", neighbourhood_voxels=1, min_shift_voxels=0.5, shift_plane_ratio=0.15)) == 64
    with pytest.raises(chronomap.UsageError, match="shift plane ratio"):
        m.diff(T1, T2, neighbourhood_voxels=1, min_shift_voxels=0.5, shift_plane_ratio=-1.0)
    assert chronomap.changes(m, T1, T2) == chronomap.changes(m, T1_S, T2_S)
    centres, counts = m.change_counts(from_time=T1, to_time="2026-01-06")
    assert len(centres) == 64 and (counts == 1).all()
    assert m.change_histogram(from_time=T1, to_time=T2).sum() == m.change_histogram(T1_S, T2_S).sum() > 0
    models = chronomap.RhythmModels.fit(m, from_time="2026-01-01", to_time=T2)
    probe = np.array([BOX])
    assert np.array_equal(models.predict(probe, "2026-01-06T03:30:00Z"), models.predict(probe, T2_S + 86400.0),
                          equal_nan=True)
    # The workflows on files: add_session and build take them too.
    session = tmp_path / "s.cmap"
    after.save(session)
    added = chronomap.add_session(tmp_path / "4d.cmap", session, time="2026-02-01T00:00:00.5Z")
    assert added["time_s"] == datetime.datetime(2026, 2, 1, tzinfo=datetime.timezone.utc).timestamp() + 0.5


@pytest.mark.parametrize("text", ["yesterday", "2026-13-01", "2026-01-05T25:00:00Z", "", "10000-01-01"])
def test_a_time_the_cli_refuses_is_refused_naming_the_argument_and_the_text(tmp_path, before, two_times, cli, text):
    with pytest.raises(chronomap.UsageError, match=r"^time\b") as raised:
        two_times.snapshot(text)
    assert (repr(text) in str(raised.value) or "empty time" in str(raised.value))
    with pytest.raises(chronomap.UsageError, match=r"^t2\b"):
        two_times.diff(T1, text)
    with pytest.raises(chronomap.UsageError, match=r"^from_time\b"):
        two_times.change_counts(from_time=text)
    assert len(two_times) == 2
    session = tmp_path / "s.cmap"
    before.save(session)
    out = subprocess.run([str(cli), "add", str(tmp_path / "m.cmap"), str(session), "--time", text],
                         capture_output=True, text=True)
    assert out.returncode == 2, out.stdout


def test_other_types_are_still_a_type_error(two_times):
    with pytest.raises(TypeError, match="ISO-8601 string"):
        two_times.snapshot(b"2026-01-05")


def test_history_names_each_state_with_its_counters_as_the_cli_lists_them(tmp_path, two_times, cli):
    entries = two_times.history(BOX)
    assert [e["state"] for e in entries] == ["free", "occupied"]
    assert [e["time_s"] for e in entries] == [T1_S, T2_S]
    assert entries[0]["time"] == datetime.datetime(2026, 1, 5, 3, 0, tzinfo=datetime.timezone.utc)
    free, occupied = entries
    assert free["hits"] == 0 and free["length_m"] > 0 and free["probability"] == 0.0
    assert occupied["hits"] > 0 and occupied["probability"] > 0.5 and occupied["level"] == 0
    assert len(occupied["color"]) == 3
    assert two_times.history([0.0, 0.0, 9.0]) == []
    # The same entries as chronomap history --json on the saved map (which keeps lengths to 2^-8).
    two_times.save(tmp_path / "m.cmap")
    entries = chronomap.TemporalMap.open(tmp_path / "m.cmap").history(BOX)
    out = subprocess.run([str(cli), "history", str(tmp_path / "m.cmap"), "--point", "0,0,1.525", "--json"],
                         capture_output=True, text=True, check=True)
    listed = json.loads(out.stdout)["entries"]
    assert len(listed) == len(entries)
    for mine, theirs in zip(entries, listed):
        assert set(mine) == set(theirs)
        assert mine["time"].strftime("%Y-%m-%dT%H:%M:%SZ") == theirs["time"]
        for key in ("time_s", "state", "hits", "level"):
            assert mine[key] == theirs[key]
        assert list(mine["color"]) == theirs["color"]
        assert mine["length_m"] == pytest.approx(theirs["length_m"], rel=1e-6)
        assert mine["probability"] == pytest.approx(theirs["probability"], rel=1e-12)


def trajectory(folder):
    """The poses of a TUM folder's trajectory.txt: (F, 4, 4)."""
    rows = np.loadtxt(folder / "trajectory.txt", comments="#")
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    for T, (_, tx, ty, tz, qx, qy, qz, qw) in zip(poses, rows):
        T[:3, :3] = [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                     [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                     [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]
        T[:3, 3] = tx, ty, tz
    return poses


def corrected(correction, T, i):
    """PoseCorrection.apply as align/pose_correction.h defines it, in numpy."""
    def per_pose(c, T):
        out = T.copy()
        out[:3, :3] = c[:3, :3] @ T[:3, :3]
        out[:3, 3] = T[:3, 3] + c[:3, 3]
        return out
    c = correction["motion"]
    out = c @ T if correction["model"] == "world" else per_pose(c, T)
    if correction["per_frame"] is not None:
        out = per_pose(correction["per_frame"][i], out)
    return out


def test_build_returns_each_frames_pose_and_the_registrations_correction(tmp_path, building):
    times = ["2026-01-05T03:00:00Z", "2026-01-06T03:00:00Z", "2026-01-07T03:00:00Z"]
    plain = chronomap.build(tmp_path / "plain.cmap", building, times=times, resolution_m=0.1, fast=True)
    assert [s["time_s"] for s in plain["added"]] == [T1_S, T1_S + 86400.0, T1_S + 2 * 86400.0]
    for folder, s in zip(building, plain["added"]):
        recorded = trajectory(folder)
        assert s["poses"].shape == s["recorded_poses"].shape == recorded.shape
        assert np.allclose(s["recorded_poses"], recorded, atol=1e-6)
        assert np.array_equal(s["poses"], s["recorded_poses"]) and "correction" not in s
    registered = chronomap.build(tmp_path / "reg.cmap", building, times=times, resolution_m=0.1, fast=True,
                                 register=True, registration_rounds=1)
    moved = 0
    for p, s in zip(plain["added"], registered["added"]):
        assert np.array_equal(s["recorded_poses"], p["recorded_poses"])
        c = s["correction"]
        assert c["model"] in ("world", "per-pose") and c["motion"].shape == (4, 4)
        assert np.array_equal(c["motion"][:3, 3], s["registration_m"])
        for i, (T, R) in enumerate(zip(s["poses"], s["recorded_poses"])):
            assert np.allclose(T, corrected(c, R, i), atol=1e-9)
        moved += not np.array_equal(s["poses"], s["recorded_poses"])
    assert moved >= 1


def test_the_evidence_rule_is_kept_with_the_map_and_bad_values_are_refused(tmp_path, before, after):
    ruled = chronomap.TemporalMap(RESOLUTION_M, min_free_length_m=0.025, min_hits=2)
    plain = chronomap.TemporalMap(RESOLUTION_M)
    for m in (ruled, plain):
        m.add(before, T1)
        m.add(after, T2)
    ruled.save(tmp_path / "ruled.cmap")
    plain.save(tmp_path / "plain.cmap")
    assert ruled != plain  # the criterion is part of the map
    again = chronomap.TemporalMap.open(tmp_path / "ruled.cmap")
    again.save(tmp_path / "again.cmap")
    assert (tmp_path / "again.cmap").read_bytes() == (tmp_path / "ruled.cmap").read_bytes()
    with pytest.raises(chronomap.UsageError, match="minimum free length"):
        chronomap.TemporalMap(RESOLUTION_M, min_free_length_m=-1.0)
