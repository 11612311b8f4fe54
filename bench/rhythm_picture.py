#!/usr/bin/env python3
"""The picture of docs/rhythm.md: one test session of the `weeks` building, its true occupancy,
the occupancy the combined model predicts for that time from a 4D map of the learning weeks, and
the cost map `chronomap costmap` writes for it, each seen from above over a height band.

Usage: PYTHONPATH=build/ci/python /usr/bin/python3 bench/rhythm_picture.py SIM MAP SESSION COST.png OUT.png [FIGURES.json]
  SIM      a `chronomap simulate --preset weeks` output (scene.json, truth/occupancy_NN.cmap)
  MAP      the 4D map of the learning sessions
  SESSION  the test session's index in scene.json
  COST.png the picture `chronomap costmap MAP --at <the session's time> -o COST.yaml` wrote (its
           YAML beside it), at the default 0.05 m cells
  FIGURES  also write what the picture shows, for its caption (scripts/make-doc-images.sh): the
           session's time and weekday, the learning sessions, the doors open in the truth, and
           the predicted probability on the doorways (the doors' voxels free in the truth then)
"""
import calendar
import json
import re
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

import chronomap

Z_MIN, Z_MAX, RES = 0.2, 1.4, 0.05


def column_max(m, xs, ys, zs):
    """Per (x, y) column the highest probability over the band, and whether any voxel is known."""
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    p = m.probability(np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)).reshape(len(xs), len(ys), len(zs))
    known = ~np.isnan(p).all(axis=2)
    return np.nanmax(np.where(np.isnan(p), -1.0, p), axis=2), known


def main(sim, map_path, session, cost_png, out):
    scene = json.loads((Path(sim) / "scene.json").read_text())
    time_s = scene["sessions"][session]["time_s"]
    temporal = chronomap.TemporalMap.open(map_path)
    predicted = chronomap.RhythmModels.fit(temporal).predict_map(temporal, time_s)
    truth = chronomap.SessionMap.open(Path(sim) / "truth" / f"occupancy_{session:02d}.cmap")
    cost = np.array(Image.open(cost_png).convert("RGB"))
    height, width = cost.shape[:2]
    # The cost map's grid: its origin from the YAML beside the picture.
    yaml_text = Path(cost_png).with_suffix(".yaml").read_text()
    x0, y0 = (float(v) for v in re.search(r"origin:\s*\[([^,]+),([^,]+),", yaml_text).groups())
    xs = x0 + RES * (np.arange(width) + 0.5)
    ys = y0 + RES * (np.arange(height) + 0.5)
    zs = np.arange(Z_MIN + RES / 2, Z_MAX, RES)
    p, known = column_max(predicted, xs, ys, zs)
    t, _ = column_max(truth, xs, ys, zs)
    v = np.clip(p, 0.0, 1.0)  # white free, orange at 0.5, black occupied; grey unknown
    ramp = np.stack([255 * (1 - v**2), 255 * (1 - v) ** 1.2, 255 * (1 - v) ** 2], 2)
    pred_rgb = np.where(known[..., None], ramp, 150).astype(np.uint8)
    truth_rgb = (np.where((t > 0.5)[..., None], 0, 255) * np.ones(3)).astype(np.uint8)
    rows = lambda a: np.transpose(a, (1, 0, 2))[::-1]  # first image row the highest y
    when = scene["sessions"][session]["time"]
    panels = [(f"truth at {when} (occupied between {Z_MIN} and {Z_MAX} m)", rows(truth_rgb)),
              ("predicted probability of occupancy, combined model", rows(pred_rgb)),
              ("cost map", cost)]
    scale, pad = 3, 22
    picture = Image.new("RGB", (width * scale, (height * scale + pad) * len(panels)), (255, 255, 255))
    draw = ImageDraw.Draw(picture)
    for i, (title, pixels) in enumerate(panels):
        top = i * (height * scale + pad)
        picture.paste(Image.fromarray(pixels).resize((width * scale, height * scale), Image.NEAREST), (0, top + pad))
        draw.text((6, top + 5), title, fill=(0, 0, 0))
    picture.save(out)
    return {"session": session, "time": when, "weekday": calendar.day_name[scene["sessions"][session]["weekday"]],
            "learn_sessions": len(temporal), **doors(scene, session, predicted, truth)}


def doors(scene, session, predicted, truth):
    """How many doors are open in the truth at `session`, and on the doors' voxels in the band that
    the truth has free then (the doorways) the share the model predicts occupied (above 0.5)."""
    res = scene["voxel_resolution_m"]
    state, keys = {}, {}
    for e in scene["events"]:
        if e.get("object_kind") != "door":
            continue
        keys.setdefault(e["object"], set()).update(map(tuple, e["voxels"]))
        if e["to_session"] <= session:
            state[e["object"]] = e["kind"] == "door_opened"
        else:  # before its first event a door is in the state that event leaves
            state.setdefault(e["object"], e["kind"] == "door_closed")
    points = np.array(sorted(k for ks in keys.values() for k in ks), dtype=float)
    points = (points - 32768 + 0.5) * res
    points = points[(points[:, 2] > Z_MIN) & (points[:, 2] < Z_MAX)]
    free = ~(truth.probability(points) > 0.5)  # the truth stores what is occupied
    p = predicted.probability(points[free])
    return {"doors": len(state), "doors_open": sum(state.values()),
            "doorway_voxels": int(free.sum()), "doorway_predicted_occupied": float(np.mean(p > 0.5))}


if __name__ == "__main__":
    if len(sys.argv) not in (6, 7):
        sys.exit(__doc__)
    figures = main(sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5])
    if len(sys.argv) == 7:
        Path(sys.argv[6]).write_text(json.dumps(figures, indent=2) + "\n")
