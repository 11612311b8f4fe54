"""Voxel queries (probability, counters, free leaves), times as datetimes and the change layers,
on synthetic scenes with known answers."""

import datetime

import numpy as np
import pytest

import chronomap
from scenes import RESOLUTION_M

BOX = [0.01, 0.01, 1.525]      # inside a voxel of the box face
WALL = [0.5, 0.5, 2.025]         # a voxel of the wall, seen in both sessions
AIR = [0.01, 0.01, 1.01]       # between the sensor and the box, inside a voxel: free
OUTSIDE = [0.0, 0.0, -5.0]       # behind the sensor: never observed


def test_probability_and_counters_agree_with_the_counters_definition(after):
    probes = np.array([BOX, AIR, OUTSIDE, [1e9, 0, 0]])
    p = after.probability(probes)
    assert p.dtype == np.float64 and p.shape == (4,)
    c = after.counters(probes)
    assert c["hits"].dtype == np.uint32 and c["length_m"].dtype == np.float32
    assert c["mean_color"].shape == (4, 3) and c["mean_offset_voxels"].shape == (4, 3)
    # P = 1 - exp(-hits / length), for every observed voxel.
    expected = 1.0 - np.exp(-c["hits"][:2].astype(np.float64) / c["length_m"][:2].astype(np.float64))
    assert np.allclose(p[:2], expected)
    assert p[0] > 0.5 and c["hits"][0] > 0 and c["state"][0] == chronomap.OCCUPIED
    assert p[1] < 0.5 and c["hits"][1] == 0 and c["length_m"][1] > 0 and c["state"][1] == chronomap.FREE
    assert np.isnan(p[2:]).all() and (c["state"][2:] == chronomap.UNKNOWN).all() and (c["hits"][2:] == 0).all()
    assert (np.abs(c["mean_offset_voxels"]) <= 0.5).all()
    assert (after.state(probes) == c["state"]).all()


def test_free_leaves_cover_exactly_the_free_space(after):
    centers, sizes = after.free_centers()
    assert centers.shape == (len(sizes), 3) and sizes.dtype == np.float64 and len(sizes) > 0
    levels = np.log2(sizes / RESOLUTION_M)
    assert np.allclose(levels, np.round(levels)) and (levels >= 0).all()
    assert (sizes > RESOLUTION_M).any(), "free space is compressed into larger cubes"
    # Every leaf centre is free, and the unit voxels of every leaf add up to the free count.
    assert (after.state(centers) == chronomap.FREE).all()
    assert int(np.round(((sizes / RESOLUTION_M) ** 3).sum())) == after.counts()["free_voxels"]
    # A free voxel lies inside exactly one leaf; an occupied one in none.
    def covering(point):
        return (np.abs(centers - np.asarray(point)) <= sizes[:, None] / 2 + 1e-9).all(axis=1).sum()
    assert covering(AIR) == 1 and covering(BOX) == 0


def test_times_as_datetimes(before, after):
    m = chronomap.TemporalMap(RESOLUTION_M)
    t1 = datetime.datetime(2026, 3, 2, 8, 30, tzinfo=datetime.timezone.utc)
    m.add(before, t1)
    m.add(after, datetime.datetime(2026, 3, 2, 20, 30))  # naive: UTC
    assert list(m.times_s) == [t1.timestamp(), t1.timestamp() + 12 * 3600]
    assert m.times == [t1, t1 + datetime.timedelta(hours=12)]
    assert m.times[0].tzinfo is not None
    noon = datetime.datetime(2026, 3, 2, 12, 0, tzinfo=datetime.timezone.utc)
    assert m.snapshot(noon) == m.snapshot(noon.timestamp())
    assert np.array_equal(m.snapshot(noon).occupied_centers(), before.occupied_centers())
    assert m.diff(t1, m.times[1]).voxel_count(chronomap.APPEARED) == 64
    with pytest.raises(TypeError, match="time"):
        m.snapshot([2026, 3, 2])
    with pytest.raises(chronomap.UsageError, match="time 'yesterday' is neither ISO-8601"):  # text as the CLI reads it
        m.snapshot("yesterday")
    with pytest.raises(TypeError, match="time"):
        m.snapshot(True)


def test_change_counts_on_a_box_that_comes_and_goes(before, after):
    m = chronomap.TemporalMap(RESOLUTION_M)
    for i, s in enumerate([before, after, before, after, before]):
        m.add(s, 100.0 * (i + 1))
    centers, counts = m.change_counts()
    assert counts.dtype == np.uint32 and centers.shape == (len(counts), 3)
    box = np.abs(centers - BOX).max(axis=1) < 0.2
    # The 64 box voxels changed four times (free, occupied, free, occupied, free).
    assert box.sum() == 64 and (counts[box] == 4).all()
    hist = m.change_histogram()
    assert hist.dtype == np.uint64 and hist[4] >= 64 and hist[0] == 0
    assert int(hist.sum()) == len(counts)
    # A window (150, 350] holds two of the box's changes; min_changes filters.
    c2, n2 = m.change_counts(150.0, 350.0, min_changes=2)
    assert len(n2) >= 64 and (n2 >= 2).all()
    _, n3 = m.change_counts(150.0, 350.0, min_changes=3)
    assert len(n3) == 0
    with pytest.raises(chronomap.UsageError):
        m.change_counts(min_changes=0)


def test_rhythm_models_predict_and_costmap(tmp_path, before, after):
    # A box that is there every afternoon (14:00) and gone every morning (08:00) for two weeks.
    m = chronomap.TemporalMap(RESOLUTION_M)
    day0 = datetime.datetime(2026, 3, 2, tzinfo=datetime.timezone.utc)  # a Monday
    for d in range(14):
        m.add(before, day0 + datetime.timedelta(days=d, hours=8))
        m.add(after, day0 + datetime.timedelta(days=d, hours=14))
    models = chronomap.RhythmModels.fit(m)
    assert len(models) >= 64 and models.sessions == 28
    # .rhythm version 4: a 60-byte header and each learning session's time, the voxels, the objects.
    assert models.bytes == 60 + 8 * 28 + 105 * len(models) + 8 + 96 * models.groups
    afternoon = day0 + datetime.timedelta(days=15, hours=14)
    morning = day0 + datetime.timedelta(days=15, hours=8)
    p = models.predict(np.array([BOX, OUTSIDE]), afternoon, model="hourly")
    assert p[0] > 0.9 and np.isnan(p[1])
    assert models.predict(np.array([BOX]), morning, model="hourly")[0] < 0.1
    # Saved and read back, it answers the same.
    models.save(tmp_path / "m.rhythm")
    back = chronomap.RhythmModels.open(tmp_path / "m.rhythm")
    for model in ("latest", "mean", "markov", "periodic", "hourly", "combined"):
        assert np.array_equal(back.predict(np.array([BOX]), afternoon, model), models.predict(np.array([BOX]), afternoon, model))
    predicted = models.predict_map(m, afternoon, model="hourly")
    assert predicted.state(np.array([BOX]))[0] == chronomap.OCCUPIED
    assert models.predict_map(m, morning, model="hourly").state(np.array([BOX]))[0] == chronomap.FREE
    with pytest.raises(chronomap.UsageError):
        models.predict(np.array([BOX]), afternoon, model="fourier")
    # A model belongs to the map it was fitted on: on another map (the same times, other voxels)
    # it is refused as `chronomap predict --rhythm` refuses it, unless allowed with a warning.
    other = chronomap.TemporalMap(RESOLUTION_M)
    for d in range(14):
        other.add(after, day0 + datetime.timedelta(days=d, hours=8))
        other.add(before, day0 + datetime.timedelta(days=d, hours=14))
    with pytest.raises(ValueError, match="fingerprint"):
        back.predict_map(other, afternoon)
    with pytest.warns(UserWarning):
        back.predict_map(other, afternoon, allow_other_map=True)
    assert back.predict_map(m, afternoon, model="hourly").state(np.array([BOX]))[0] == chronomap.OCCUPIED
    # The costmap over the box's height: its cells lethal in the afternoon.
    cost, origin, resolution = chronomap.costmap(predicted, z_min_m=1.4, z_max_m=1.6, robot_radius_m=0.0)
    assert cost.dtype == np.int8 and cost.ndim == 2 and resolution == pytest.approx(RESOLUTION_M)
    i, j = int((BOX[0] - origin[0]) / resolution), int((BOX[1] - origin[1]) / resolution)
    assert cost[j, i] == 100
    with pytest.raises(chronomap.UsageError):
        chronomap.costmap(predicted, z_min_m=2.0, z_max_m=1.0)


def test_colour_model_predicts_colours_by_hour(tmp_path):
    # An 8 x 8 wall under lamps (09:00, 13:00) and a warm sunset (19:00) for five days.
    light = {9: (0.8, 0.8, 0.75), 13: (1.0, 1.0, 1.0), 19: (0.9, 0.55, 0.3)}
    m = chronomap.TemporalMap(RESOLUTION_M, color_distance=4.0)
    day0 = datetime.datetime(2026, 3, 2, tzinfo=datetime.timezone.utc)
    xs, ys = np.meshgrid(np.arange(8), np.arange(8))
    points = np.stack([xs.ravel(), ys.ravel(), np.zeros(64)], axis=1) * RESOLUTION_M + RESOLUTION_M / 2
    albedo = np.stack([120 + 10 * xs.ravel(), 100 + 8 * ys.ravel(), np.full(64, 90)], axis=1).astype(float)
    for d in range(5):
        for h, l in light.items():
            colours = np.round(albedo * np.array(l)).astype(np.uint8)
            integ = chronomap.Integrator(RESOLUTION_M)
            integ.add_points(points, origin=points.mean(axis=0) + [0, 0, 1.0], colors=colours)
            m.add(integ.finish(), day0 + datetime.timedelta(days=d, hours=h))
    model = chronomap.ColourModel.fit(m)
    assert len(model) >= 64 and model.components == 2
    later = day0 + datetime.timedelta(days=9, hours=19)
    p = model.predict(points, later)
    assert p.shape == (64, 3)
    assert np.abs(p - albedo * np.array(light[19])).max() < 6.0
    assert np.isnan(model.predict(np.array([[5.0, 5.0, 5.0]]), later)).all()
    assert model.curves(12.0).shape == (2, 3)
    painted = model.recolour(m.snapshot(later), later)
    assert isinstance(painted, chronomap.SessionMap)
    model.save(tmp_path / "wall.colour")
    back = chronomap.ColourModel.open(tmp_path / "wall.colour")
    assert len(back) == len(model) and back.bytes == model.bytes
    assert np.array_equal(back.predict(points, later), p)
    (tmp_path / "cut.colour").write_bytes((tmp_path / "wall.colour").read_bytes()[:-3])
    with pytest.raises(chronomap.FormatError, match="truncated"):
        chronomap.ColourModel.open(tmp_path / "cut.colour")
    with pytest.raises(chronomap.UsageError):
        chronomap.ColourModel.fit(chronomap.TemporalMap(RESOLUTION_M))
