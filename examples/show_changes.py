#!/usr/bin/env python3
"""Show the objects that changed between two sessions of a 4D map, with matplotlib and Open3D.

    python3 examples/show_changes.py MAP.cmap -o changes/ [--from 0] [--to -1] [--show]

--from and --to are session numbers (negative from the end). Writes changes/top_view.png (a
matplotlib top view: the later session's occupied voxels in grey, appeared voxels green,
vanished red, each object framed and numbered) and, when open3d is importable,
changes/changes.ply (the changed voxels) and changes/scene.ply (the later session); --show
opens an Open3D window with the scene, the changes and a box around each object.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.patches as patches  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import chronomap  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("map", type=pathlib.Path)
    parser.add_argument("-o", "--output", type=pathlib.Path, required=True)
    parser.add_argument("--from", dest="first", type=int, default=0, help="session number of the earlier state")
    parser.add_argument("--to", dest="last", type=int, default=-1, help="session number of the later state")
    parser.add_argument("--min-voxels", type=int, default=20, help="smallest object reported")
    parser.add_argument("--show", action="store_true", help="open an Open3D window")
    args = parser.parse_args()

    m = chronomap.TemporalMap.open(args.map)
    t1, t2 = m.times_s[args.first], m.times_s[args.last]
    changes = m.diff(t1, t2, mode="band", neighbourhood_voxels=1, min_shift_voxels=0.5)
    objects = chronomap.segment(changes, connectivity="vertex", min_voxels=args.min_voxels)
    after = m.snapshot(t2)
    print(f"{m.times[args.first]:%Y-%m-%d %H:%M} -> {m.times[args.last]:%Y-%m-%d %H:%M}: "
          f"{len(changes)} changed cells, {len(objects)} objects of {args.min_voxels}+ voxels")
    for c in objects:
        print(f"  #{c.id} {c.kind:8s} {c.voxels:6d} voxels at ({c.centroid_m[0]:.2f}, {c.centroid_m[1]:.2f}, "
              f"{c.centroid_m[2]:.2f}) m")

    args.output.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(10, 7))
    # The later session from above: how many occupied voxels each column holds, in grey.
    scene, res = after.occupied_centers(), m.resolution_m
    lo, hi = scene[:, :2].min(axis=0), scene[:, :2].max(axis=0) + res
    bins = np.maximum(1, np.round((hi - lo) / res).astype(int))
    columns, _, _ = np.histogram2d(scene[:, 0], scene[:, 1], bins=bins, range=[[lo[0], hi[0]], [lo[1], hi[1]]])
    ax.imshow(np.log1p(columns.T), origin="lower", extent=(lo[0], hi[0], lo[1], hi[1]), cmap="Greys",
              vmax=np.log1p(columns.max()) * 1.6, interpolation="nearest")
    centers, kinds = changes.changed_centers(), changes.kinds()
    for kind, colour, label in ((chronomap.APPEARED, "tab:green", "appeared"),
                                (chronomap.VANISHED, "tab:red", "vanished")):
        pick = kinds == kind
        ax.scatter(centers[pick, 0], centers[pick, 1], s=1.5, c=colour, marker="s", linewidths=0, label=label)
    for c in objects:
        lo, hi = c.bbox_min_m, c.bbox_max_m
        colour = "tab:green" if c.kind == "appeared" else "tab:red"
        ax.add_patch(patches.Rectangle(lo[:2], *(hi - lo)[:2], fill=False, edgecolor=colour, linewidth=1.2))
        ax.annotate(str(c.id), (hi[0], hi[1]), fontsize=9, color=colour, weight="bold")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"changes between sessions {args.first} and {args.last}: {len(objects)} objects")
    ax.legend(loc="upper right", markerscale=6)
    fig.savefig(args.output / "top_view.png", dpi=120, bbox_inches="tight")
    print(f"wrote {args.output / 'top_view.png'}")

    try:
        import open3d as o3d

        import chronomap.o3d as co3d
    except ImportError:
        print("open3d is not importable: no PLY files")
        return
    cloud = co3d.diff_to_point_cloud(changes)
    o3d.io.write_point_cloud(str(args.output / "changes.ply"), cloud)
    o3d.io.write_point_cloud(str(args.output / "scene.ply"), co3d.to_point_cloud(after))
    print(f"wrote {args.output / 'changes.ply'} and {args.output / 'scene.ply'}")
    if args.show:
        o3d.visualization.draw_geometries([co3d.to_voxel_grid(after), cloud, *co3d.component_boxes(objects)])


if __name__ == "__main__":
    main()
