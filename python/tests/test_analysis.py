"""diff, segment and the 4D map on a room where a box appears: known answers."""

import numpy as np
import pytest

import chronomap

BOX_MIN = np.array([-0.2, -0.2, 1.5])
BOX_MAX = np.array([0.2, 0.2, 1.55])


def test_diff_finds_the_box(before, after):
    d = chronomap.diff(before, after)
    assert d.mode == "hard" and len(d) == 64
    assert d.voxel_count(chronomap.APPEARED) == 64 and d.voxel_count(chronomap.VANISHED) == 0
    centers = d.changed_centers()
    assert centers.shape == (64, 3) and centers.dtype == np.float64
    assert (d.kinds() == chronomap.APPEARED).all() and d.kinds().dtype == np.int8
    assert (d.levels() == 0).all()
    assert np.allclose(centers.min(axis=0), BOX_MIN + 0.025) and np.allclose(centers.max(axis=0), BOX_MAX - 0.025)
    back = chronomap.diff(after, before)
    assert back.voxel_count(chronomap.VANISHED) == 64 and back.voxel_count(chronomap.APPEARED) == 0


def test_weak_change_rule_keeps_an_object_that_hides_the_surface_behind_it(before, after):
    # The box hides the part of the room behind it, so the room's surface is not "still seen
    # unchanged" there: the rule (docs/changes.md) keeps every one of its voxels, both ways.
    d = chronomap.diff(before, after, kept_surface_radius_voxels=3)
    assert d.voxel_count(chronomap.APPEARED) == 64
    assert chronomap.diff(after, before, kept_surface_radius_voxels=3, kept_surface_share=0.8).voxel_count(
        chronomap.VANISHED) == 64
    with pytest.raises(chronomap.UsageError, match="kept-surface radius"):
        chronomap.diff(before, after, kept_surface_radius_voxels=7)
    with pytest.raises(chronomap.UsageError, match="dark-surface radius"):
        chronomap.diff(before, after, dark_surface_radius_voxels=7)
    with pytest.raises(chronomap.UsageError, match="dark-surface contrast"):
        chronomap.diff(before, after, dark_surface_radius_voxels=3, dark_surface_contrast=0.0)
    with pytest.raises(chronomap.UsageError, match="dark-surface share"):
        chronomap.diff(before, after, dark_surface_radius_voxels=2, dark_surface_share=0.0)
    with pytest.raises(chronomap.UsageError):
        chronomap.diff(before, after, kept_surface_radius_voxels=3, kept_surface_share=1.5)
    with pytest.raises(chronomap.UsageError, match="shift plane ratio"):
        chronomap.diff(before, after, neighbourhood_voxels=1, min_shift_voxels=0.5, shift_plane_ratio=1.5)
    # The box is no plane and moved whole: the shift test across planes keeps it as well.
    assert chronomap.diff(before, after, mode="band", neighbourhood_voxels=1, min_shift_voxels=0.5,
                          shift_plane_ratio=0.15).voxel_count(chronomap.APPEARED) == 64


def test_segment_gives_one_object(before, after):
    components = chronomap.segment(chronomap.diff(before, after))
    assert len(components) == 1
    c = components[0]
    assert c.id == 1 and c.kind == "appeared" and c.voxels == 64
    assert c.volume_m3 == pytest.approx(64 * 0.05**3)
    assert np.allclose(c.bbox_min_m, BOX_MIN) and np.allclose(c.bbox_max_m, BOX_MAX)
    assert np.allclose(c.centroid_m, [0.0, 0.0, 1.525])
    assert c.cells.shape == (64,)


def test_identical_maps_have_no_changes(before):
    assert len(chronomap.diff(before, before)) == 0
    assert chronomap.segment(chronomap.diff(before, before)) == []


def test_temporal_map(tmp_path, before, after):
    m = chronomap.TemporalMap(0.05)
    m.add(after, 200.0, name="with box")
    report = m.add(before, 100.0, name="empty")  # out of order on purpose
    assert report["out_of_order"]
    assert list(m.times_s) == [100.0, 200.0] and len(m) == 2
    box = [0.0, 0.0, 1.525]
    assert [(e["time_s"], e["state"]) for e in m.history(box)] == [(100.0, "free"), (200.0, "occupied")]
    assert m.history([0.0, 0.0, 9.0]) == []
    assert m.snapshot(150.0).state(np.array([box]))[0] == chronomap.FREE
    assert m.snapshot(250.0).state(np.array([box]))[0] == chronomap.OCCUPIED
    assert m.snapshot(50.0).empty()
    changes = m.diff(100.0, 200.0)
    assert len(m.diff(100.0, 200.0, kept_surface_radius_voxels=3)) == 64
    with pytest.raises(chronomap.UsageError, match="dark-surface radius"):
        m.diff(100.0, 200.0, dark_surface_radius_voxels=7)
    direct = chronomap.diff(m.snapshot(100.0), m.snapshot(200.0))
    assert len(changes) == len(direct) == 64 and changes.voxel_count(chronomap.APPEARED) == 64
    assert np.array_equal(changes.changed_centers(), direct.changed_centers())
    with pytest.raises(chronomap.UsageError):
        m.add(before, 100.0)
    path = tmp_path / "place.cmap"
    m.save(path)
    back = chronomap.TemporalMap.open(path)  # written compacted: same answers, maybe fewer lists
    assert list(back.times_s) == [100.0, 200.0]
    # (The file keeps lengths to 2^-8 relative: states, times and hits are the same.)
    def stored(history):
        return [(e["time_s"], e["state"], e["hits"]) for e in history]
    assert stored(back.history(box)) == stored(m.history(box))
    probes = np.stack(np.meshgrid(*[np.arange(-1.2, 1.2, 0.05)] * 2, np.arange(0.0, 2.5, 0.05)), -1).reshape(-1, 3)
    for t in (100.0, 200.0):
        a, b = back.snapshot(t), m.snapshot(t)
        assert (a.state(probes) == b.state(probes)).all()
        assert np.array_equal(a.occupied_centers(), b.occupied_centers())
    back.save(tmp_path / "again.cmap")
    assert (tmp_path / "again.cmap").read_bytes() == path.read_bytes()
