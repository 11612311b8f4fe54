"""Arrays in and out: dtypes, shapes, strides, non-contiguous input, wrong input rejected."""

import numpy as np
import pytest

import chronomap
from scenes import box_face, session, wall


@pytest.fixture(scope="module")
def room():
    return session(with_box=True)


def test_state_of_points(room):
    probes = np.array([[0.0, 0.0, 1.525], [0.0, 0.0, 1.0], [0.9, 0.9, 2.025], [0.0, 0.0, 3.0], [1e9, 0, 0]])
    states = room.state(probes)
    assert states.dtype == np.int8 and states.shape == (5,)
    assert list(states) == [chronomap.OCCUPIED, chronomap.FREE, chronomap.OCCUPIED, chronomap.UNKNOWN,
                            chronomap.UNKNOWN]


def test_occupied_centers_and_colors(room):
    centers = room.occupied_centers()
    colors = room.occupied_colors()
    assert centers.dtype == np.float64 and centers.ndim == 2 and centers.shape[1] == 3
    assert centers.flags.c_contiguous and centers.strides == (24, 8)
    assert colors.dtype == np.uint8 and colors.shape == centers.shape
    assert (room.state(centers) == chronomap.OCCUPIED).all()
    assert centers.shape[0] == room.counts()["occupied_voxels"]
    # The box face: 8 x 8 voxels at z in [1.5, 1.55); centres on the voxel grid.
    box = centers[np.abs(centers[:, 2] - 1.525) < 1e-9]
    assert box.shape == (64, 3)
    assert np.allclose(np.sort(np.unique(box[:, 0])), np.arange(-0.175, 0.2, 0.05))


def test_bounds(room):
    lo, hi = room.bounds_m()
    assert lo.shape == (3,) and hi.shape == (3,)
    assert hi[2] == pytest.approx(2.05)
    assert lo[0] <= -1.0 and hi[0] >= 1.0
    assert chronomap.SessionMap(0.05).bounds_m() is None


def test_non_contiguous_input_gives_the_same_answer(room):
    probes = np.array([[0.0, 0.0, 1.525], [0.0, 0.0, 1.0], [0.9, 0.9, 2.025]])
    wide = np.zeros((3, 6))
    wide[:, ::2] = probes
    strided = wide[:, ::2]
    assert not strided.flags.c_contiguous
    assert (room.state(strided) == room.state(probes)).all()
    assert (room.state(np.asfortranarray(probes)) == room.state(probes)).all()
    assert (room.state(probes.astype(np.float32)) == room.state(probes)).all()
    assert (room.state(probes[::-1]) == room.state(probes)[::-1]).all()


def test_non_contiguous_points_integrate_alike():
    points = np.vstack([wall(), box_face()])
    fortran = np.asfortranarray(points)
    a = chronomap.Integrator(max_range_m=5.0)
    a.add_points(points, np.zeros(3))
    b = chronomap.Integrator(max_range_m=5.0)
    b.add_points(fortran, np.zeros(3))
    assert a.finish() == b.finish()


@pytest.mark.parametrize("bad", [np.zeros((4, 2)), np.zeros(3), np.zeros((2, 3, 1))])
def test_wrong_shapes_are_value_errors(room, bad):
    with pytest.raises(ValueError, match="points"):
        room.state(bad)


def test_wrong_dtypes_are_type_errors(room):
    with pytest.raises(TypeError, match="points"):
        room.state(np.array([["a", "b", "c"]]))
    with pytest.raises(TypeError, match="points"):
        room.state(np.zeros((2, 3), dtype=np.complex128))


def test_add_frame_rejects_wrong_input():
    integrator = chronomap.Integrator()
    depth = np.zeros((4, 5), dtype=np.uint16)
    k = (500.0, 500.0, 2.0, 1.5)
    pose = np.eye(4)
    with pytest.raises(TypeError, match="depth"):
        integrator.add_frame(depth.astype(np.int32), k, pose)
    with pytest.raises(ValueError, match="depth"):
        integrator.add_frame(np.zeros((4, 5, 1), dtype=np.uint16), k, pose)
    with pytest.raises(ValueError, match="T_world_camera"):
        integrator.add_frame(depth, k, np.eye(4)[:3])
    with pytest.raises(TypeError, match="rgb"):
        integrator.add_frame(depth, k, pose, rgb=np.zeros((4, 5, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="rgb"):
        integrator.add_frame(depth, k, pose, rgb=np.zeros((4, 5), dtype=np.uint8))
    with pytest.raises(ValueError, match="intrinsics"):
        integrator.add_frame(depth, (1.0, 2.0), pose)
    with pytest.raises(chronomap.DataError, match="colour image"):
        integrator.add_frame(depth, k, pose, rgb=np.zeros((5, 4, 3), dtype=np.uint8))
    with pytest.raises(chronomap.DataError, match="rigid"):
        integrator.add_frame(depth, k, 2 * np.eye(4))
    with pytest.raises(ValueError, match="colors"):
        integrator.add_points(np.zeros((3, 3)), np.ones(3), colors=np.zeros((2, 3), dtype=np.uint8))
    with pytest.raises(ValueError, match="origin"):
        integrator.add_points(np.zeros((3, 3)), np.ones(2))
    assert integrator.frames == 0


def test_colors_round_trip():
    points = box_face()
    colors = np.tile(np.array([[200, 40, 7]], dtype=np.uint8), (len(points), 1))
    integrator = chronomap.Integrator(max_range_m=5.0)
    integrator.add_points(points, np.zeros(3), colors=colors)
    m = integrator.finish()
    assert m.occupied_centers().shape == (64, 3)
    assert (m.occupied_colors() == [200, 40, 7]).all()


def test_read_png_arrays(tmp_path, threedmatch):
    frame = threedmatch / "seq-01" / "frame-000000"
    depth = chronomap.read_depth_png(f"{frame}.depth.png")
    rgb = chronomap.read_color_png(f"{frame}.color.png")
    assert depth.dtype == np.uint16 and depth.shape == (480, 640)
    assert rgb.dtype == np.uint8 and rgb.shape == (480, 640, 3)
    assert depth.max() > 0 and rgb.max() > 0
