"""Synthetic scenes with known answers, integrated with Integrator.add_points."""

import numpy as np

import chronomap

RESOLUTION_M = 0.05


def grid_face(x0, x1, y0, y1, z, step):
    """Points on the plane z between (x0, y0) and (x1, y1), `step` apart."""
    xs = np.arange(x0, x1 + 1e-9, step)
    ys = np.arange(y0, y1 + 1e-9, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])


def wall():
    """A wall 2.0 m in front of the origin: voxel centres of cells z = 40, x and y in -20..19."""
    c = RESOLUTION_M
    return grid_face(-1.0 + c / 4, 1.0 - c / 4, -1.0 + c / 4, 1.0 - c / 4, 2.0 + c / 2, c / 2)


def box_face():
    """The front of a box at 1.5 m: 8 x 8 voxels, x and y in [-0.2, 0.2), z in [1.5, 1.55)."""
    c = RESOLUTION_M
    return grid_face(-0.2 + c / 4, 0.2 - c / 4, -0.2 + c / 4, 0.2 - c / 4, 1.5 + c / 2, c / 2)


def session(with_box):
    """The room seen from the origin, with or without the box."""
    integrator = chronomap.Integrator(resolution_m=RESOLUTION_M, max_range_m=5.0)
    points = wall()
    if with_box:
        # The box hides the wall behind it: keep the wall points whose rays pass beside it.
        beside = np.abs(points[:, :2]).max(axis=1) * (1.5 / points[:, 2]) >= 0.2
        points = np.vstack([points[beside], box_face()])
    integrator.add_points(points, np.zeros(3))
    return integrator.finish()
