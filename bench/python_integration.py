#!/usr/bin/env python3
"""chronomap from Python against C++ on the same frames, measured in one run.

    python3 bench/python_integration.py [--folder TUM_FOLDER] [--frames 30] [--resolution 0.05]
        [--fast] [--cpp build/bench/bench/incremental_frames] [--floor66 MAP.cmap]

1. Frame-by-frame integration: the frames of a TUM folder (default: session 0 of the simulated
   office at 640 x 480, made with `chronomap simulate`) are decoded into numpy arrays first; the
   timed part is Integrator.add_frame for each frame and finish(). The C++ program
   bench/incremental_frames does the same from decoded images (io::depthToCloud and
   IncrementalIntegrator) in the same run; the ratio is Python's time over C++'s.
2. With --floor66 MAP: a snapshot of that 4D map at its last session, to numpy arrays (the
   occupied centres and colours), timed from the open map.

Run it with the interpreter the package was built for and the package on PYTHONPATH, e.g.
PYTHONPATH=build/ci/python /usr/bin/python3 bench/python_integration.py. Prints a JSON object last.
"""

import argparse
import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

import chronomap

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))
from integrate_tum_numpy import nearest, pose_matrix, stamped  # noqa: E402


def decoded_frames(folder, count):
    """(depth, rgb, T_world_camera) of the first `count` frames, as the C++ program reads them."""
    trajectory = folder / "trajectory.txt"
    if not trajectory.exists():
        trajectory = folder / "groundtruth.txt"
    poses, colors = stamped(trajectory), stamped(folder / "rgb.txt")
    frames = []
    for t, (name,) in stamped(folder / "depth.txt")[:count]:
        frames.append((chronomap.read_depth_png(folder / name),
                       chronomap.read_color_png(folder / nearest(colors, t, np.inf)[1][0]),
                       pose_matrix(*map(float, nearest(poses, t, np.inf)[1]))))
    return frames


def python_seconds(frames, intrinsics, resolution, fast, rounds):
    best, points = np.inf, 0
    for _ in range(rounds):
        start = time.perf_counter()
        integrator = chronomap.Integrator(resolution_m=resolution, max_range_m=3.0, fast=fast)
        for depth, rgb, pose in frames:
            integrator.add_frame(depth, intrinsics, pose, rgb=rgb, depth_scale=5000.0)
        points = integrator.points
        integrator.finish()
        best = min(best, time.perf_counter() - start)
    return best, points


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--folder", type=pathlib.Path, help="a TUM folder with camera-intrinsics.txt")
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--resolution", type=float, default=0.05)
    parser.add_argument("--fast", action="store_true")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--cpp", type=pathlib.Path, default=REPO / "build/bench/bench/incremental_frames")
    parser.add_argument("--cli", type=pathlib.Path, default=REPO / "build/ci/apps/chronomap/chronomap")
    parser.add_argument("--floor66", type=pathlib.Path, help="a 4D map of the floor66 preset")
    args = parser.parse_args()

    results = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
               "python": sys.version.split()[0]}
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.folder
        if folder is None:
            subprocess.run([str(args.cli), "simulate", "--preset", "office", "--sessions", "1", "-o", f"{tmp}/office"],
                           check=True, capture_output=True)
            folder = pathlib.Path(tmp) / "office" / "session_00"
        intrinsics = tuple(map(float, (folder / "camera-intrinsics.txt").read_text().split()[:4]))
        frames = decoded_frames(folder, args.frames)
        py_s, points = python_seconds(frames, intrinsics, args.resolution, args.fast, args.rounds)
        cmd = [str(args.cpp), str(folder), "--resolution", str(args.resolution), "--frames", str(args.frames),
               "--rounds", str(args.rounds)] + (["--fast"] if args.fast else [])
        cpp = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.splitlines()[-1])
    if cpp["points"] != points:
        sys.exit(f"the two sides cast different points: C++ {cpp['points']}, Python {points}")
    h, w = frames[0][0].shape
    results["integration"] = {
        "frames": len(frames), "size": f"{w}x{h}", "points": points, "resolution_m": args.resolution,
        "fast": args.fast, "python_ms_per_frame": round(1000 * py_s / len(frames), 2),
        "cpp_ms_per_frame": round(cpp["ms_per_frame"], 2), "python_over_cpp": round(py_s / cpp["seconds"], 3)}
    print(f"integration, {len(frames)} frames {w}x{h} ({points} points), {args.resolution} m"
          f"{', fast' if args.fast else ''}: Python {1000 * py_s / len(frames):.2f} ms a frame, "
          f"C++ {cpp['ms_per_frame']:.2f} ms a frame: Python/C++ = {py_s / cpp['seconds']:.3f}")

    if args.floor66:
        start = time.perf_counter()
        m = chronomap.TemporalMap.open(args.floor66)
        opened = time.perf_counter() - start
        best = np.inf
        for _ in range(args.rounds):
            start = time.perf_counter()
            snapshot = m.snapshot(m.times_s[-1])
            centers, colors = snapshot.occupied_centers(), snapshot.occupied_colors()
            best = min(best, time.perf_counter() - start)
        results["snapshot"] = {"map": str(args.floor66), "sessions": len(m), "open_s": round(opened, 2),
                               "snapshot_to_arrays_s": round(best, 3), "occupied_voxels": len(centers)}
        print(f"floor66 snapshot at the last of {len(m)} sessions to arrays: {best:.3f} s "
              f"({len(centers)} occupied voxels, {colors.nbytes + centers.nbytes} bytes; opening the map {opened:.1f} s)")
    print(json.dumps(results))


if __name__ == "__main__":
    main()
