"""Conversions between chronomap and Open3D (``import chronomap.o3d``; needs ``open3d``).

Maps become ``open3d.geometry.PointCloud`` (occupied voxel centres with their colours) or
``open3d.geometry.VoxelGrid`` (on the map's own grid); Open3D point clouds become the arrays
``Integrator.add_points`` takes. Nothing here computes: it moves arrays between the two.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from . import APPEARED, DiffMap, Integrator, SessionMap


def _cloud(points: np.ndarray, colors_u8: np.ndarray | None) -> o3d.geometry.PointCloud:
    cloud = o3d.geometry.PointCloud()
    cloud.points = o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64))
    if colors_u8 is not None and len(colors_u8):
        cloud.colors = o3d.utility.Vector3dVector(np.asarray(colors_u8, dtype=np.float64) / 255.0)
    return cloud


def to_point_cloud(session_map: SessionMap) -> o3d.geometry.PointCloud:
    """The occupied voxels of a SessionMap as a point cloud of their centres, coloured by their
    mean colour."""
    return _cloud(session_map.occupied_centers(), session_map.occupied_colors())


def to_voxel_grid(session_map: SessionMap) -> o3d.geometry.VoxelGrid:
    """The occupied voxels of a SessionMap as an Open3D VoxelGrid of the map's resolution whose
    voxels are chronomap's voxels (the grid's origin lies on a voxel corner)."""
    cloud = to_point_cloud(session_map)
    return o3d.geometry.VoxelGrid.create_from_point_cloud(cloud, voxel_size=session_map.resolution_m)


def voxel_grid_centers(grid: o3d.geometry.VoxelGrid) -> np.ndarray:
    """The centres of a VoxelGrid's voxels, (N, 3) float64, in the grid's own order."""
    voxels = grid.get_voxels()
    if not voxels:
        return np.zeros((0, 3))
    index = np.array([v.grid_index for v in voxels], dtype=np.float64)
    return np.asarray(grid.origin) + (index + 0.5) * grid.voxel_size


def from_point_cloud(cloud: o3d.geometry.PointCloud) -> tuple[np.ndarray, np.ndarray | None]:
    """An Open3D point cloud as (points (N, 3) float64, colours (N, 3) uint8 or None)."""
    points = np.asarray(cloud.points, dtype=np.float64)
    if not cloud.has_colors():
        return points, None
    colors = np.clip(np.rint(np.asarray(cloud.colors) * 255.0), 0, 255).astype(np.uint8)
    return points, colors


def add_point_cloud(integrator: Integrator, cloud: o3d.geometry.PointCloud, origin) -> None:
    """Adds an Open3D point cloud in the world frame, seen from the sensor at ``origin`` (3,),
    with its colours when it has them."""
    points, colors = from_point_cloud(cloud)
    integrator.add_points(points, np.asarray(origin, dtype=np.float64), colors)


def diff_to_point_cloud(changes: DiffMap) -> o3d.geometry.PointCloud:
    """The changed voxels of a diff: appeared green, vanished red."""
    kinds = changes.kinds()
    colors = np.where((kinds == APPEARED)[:, None], np.array([[40, 200, 60]], np.uint8),
                      np.array([[220, 40, 40]], np.uint8))
    return _cloud(changes.changed_centers(), colors.astype(np.uint8))


def component_boxes(components) -> list[o3d.geometry.AxisAlignedBoundingBox]:
    """The boxes of segmented components (chronomap.segment), appeared green and vanished red."""
    boxes = []
    for c in components:
        box = o3d.geometry.AxisAlignedBoundingBox(np.asarray(c.bbox_min_m), np.asarray(c.bbox_max_m))
        box.color = (0.16, 0.78, 0.24) if c.kind == "appeared" else (0.86, 0.16, 0.16)
        boxes.append(box)
    return boxes
