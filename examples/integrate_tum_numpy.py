#!/usr/bin/env python3
"""Integrate a TUM RGB-D folder frame by frame from numpy arrays, as a SLAM loop would.

    python3 examples/integrate_tum_numpy.py SESSION_FOLDER OUT.cmap [--resolution 0.05]

The folder holds depth.txt, rgb.txt, trajectory.txt (or groundtruth.txt) and
camera-intrinsics.txt ("fx fy cx cy"), as `chronomap simulate` writes them. Each depth image
(16-bit PNG, 5000 units per metre) and colour image is read into a numpy array, its pose
turned into a 4x4 matrix, and the three given to Integrator.add_frame.
"""

import argparse
import pathlib
import sys
import time

import numpy as np

import chronomap


def stamped(path):
    """(timestamp, rest of the line) of every line of a TUM list that is not a comment."""
    rows = []
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            first, *rest = line.split()
            rows.append((float(first), rest))
    return sorted(rows, key=lambda r: r[0])


def nearest(rows, t, tolerance=0.02):
    """The row whose timestamp is closest to t, within the tolerance, else None."""
    stamps = np.array([r[0] for r in rows])
    i = int(np.argmin(np.abs(stamps - t)))
    return rows[i] if abs(stamps[i] - t) <= tolerance else None


def pose_matrix(tx, ty, tz, qx, qy, qz, qw):
    """The 4x4 camera-to-world matrix of a translation and a unit quaternion."""
    q = np.array([qw, qx, qy, qz]) / np.linalg.norm([qw, qx, qy, qz])
    w, x, y, z = q
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                 [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                 [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = [tx, ty, tz]
    return T


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder", type=pathlib.Path)
    parser.add_argument("output", type=pathlib.Path)
    parser.add_argument("--resolution", type=float, default=0.05, help="voxel edge, metres")
    parser.add_argument("--max-range", type=float, default=3.0, help="farthest point kept, metres")
    args = parser.parse_args()

    folder = args.folder
    trajectory = folder / "trajectory.txt"
    if not trajectory.exists():
        trajectory = folder / "groundtruth.txt"
    poses = stamped(trajectory)
    colors = stamped(folder / "rgb.txt")
    fx, fy, cx, cy = map(float, (folder / "camera-intrinsics.txt").read_text().split()[:4])

    integrator = chronomap.Integrator(resolution_m=args.resolution, max_range_m=args.max_range)
    start = time.perf_counter()
    depths = stamped(folder / "depth.txt")
    for i, (t, (depth_name,)) in enumerate(depths):
        pose, color = nearest(poses, t), nearest(colors, t)
        if pose is None or color is None:
            continue  # no pose or no colour close enough in time
        depth = chronomap.read_depth_png(folder / depth_name)  # (H, W) uint16
        rgb = chronomap.read_color_png(folder / color[1][0])    # (H, W, 3) uint8
        T_world_camera = pose_matrix(*map(float, pose[1]))
        integrator.add_frame(depth, (fx, fy, cx, cy), T_world_camera, rgb=rgb, depth_scale=5000.0)
        print(f"\rframe {i + 1}/{len(depths)}", end="", file=sys.stderr)
    frames = integrator.frames
    session = integrator.finish()
    session.save(args.output)
    counts = session.counts()
    print(f"\n{frames} frames in {time.perf_counter() - start:.2f} s: "
          f"{counts['occupied_voxels']} occupied and {counts['free_voxels']} free voxels -> {args.output}")


if __name__ == "__main__":
    main()
