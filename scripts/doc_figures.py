#!/usr/bin/env python3
"""The figures that the captions of README.md and docs/*.md quote, measured and checked.

    scripts/doc_figures.py measure FIGURES.json [--demo DIR] [--room DIR] [--weeks DIR] [--floor66 DIR]
    scripts/doc_figures.py check FIGURES.json [--demo DIR] [--room DIR] [--weeks DIR] [--floor66 DIR]

A caption is the italic paragraph under a picture (or, without one, the picture's alt text). Each
caption key of FIGURES.json ("DOC IMAGE", e.g. "docs/viewer.md viewer_office_diff.png") holds the
figures the caption quotes, each as the text it must contain ("603 voxels", "0.65 x 0.55 x 1.25
m"), and whether the script measured them ("measured": what they come from) or they are the
inputs the script gives ("given").

measure (scripts/make-doc-images.sh runs it) writes the keys it can measure from what the script
made: the demo's folder (report.json, report.md, data/scene.json), the study room's
`chronomap integrate --json` and shoot.mjs's JSON; keys it cannot measure stay as they were.

check (ctest's DocFigures runs it, so CI does) fails when
  - a caption lacks one of its figures, or quotes a number that none of its figures holds (so a
    number typed into a caption by hand, or left over from an older picture, fails);
  - a picture of the docs has figures in its caption but no key, or a key names no picture;
  - given --demo, --room, --weeks or --floor66, a key measured from them differs from what they
    measure now.
The demo runs at its defaults (seed 1, 320 x 240) in about 20 s; what only the groups of
make-doc-images.sh that CI does not run measure (weeks, floor66: the simulations and the
benchmark programs) is checked against FIGURES.json alone.
"""
import argparse
import calendar
import json
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOCS = ["README.md"] + sorted(str(p.relative_to(REPO)) for p in (REPO / "docs").glob("*.md"))
WORDS = {1: "one", 2: "two", 3: "three", 4: "four", 5: "five", 6: "six", 7: "seven", 8: "eight", 9: "nine"}
NUMBER = re.compile(r"(?<![§\w.])[0-9]+(?:,[0-9]{3})*(?:\.[0-9]+)?(?![0-9A-Za-z])")
IMAGE = re.compile(r"!\[([^\]]*)\]\((?:docs/)?images/([^)]+)\)")


def numbers(text):
    """The numbers a text quotes, thousands separators removed; links' targets left out."""
    text = re.sub(r"\]\([^)]*\)", "]", text)
    return [m.group(0).replace(",", "") for m in NUMBER.finditer(text)]


def normalised(text):
    return re.sub(r"\s+", " ", text.replace("×", "x")).strip()


def captions():
    """{"DOC IMAGE": caption text} for every picture of README.md and docs/*.md."""
    out = {}
    for doc in DOCS:
        lines = (REPO / doc).read_text().split("\n")
        for i, line in enumerate(lines):
            found = IMAGE.findall(line)
            if not found:
                continue
            j = i + 1
            while j < len(lines) and not lines[j].strip():
                j += 1
            caption = []
            if j < len(lines) and lines[j].startswith("*") and not lines[j].startswith("**"):
                while j < len(lines) and lines[j].strip():
                    caption.append(lines[j])
                    j += 1
                    if re.search(r"(?<!\*)\*$", caption[-1].rstrip()) and len("".join(caption)) > 1:
                        break
            text = "\n".join(caption) if caption else found[0][0]
            out[f"{doc} {found[0][1]}"] = normalised(text)
    return out


# ---------------------------------------------------------------------------------------------
# Measuring


def truths(report_md):
    """{(pair index, object id): the simulator's events the object matches, in words}."""
    out, pair = {}, -1
    for line in report_md.split("\n"):
        if line.startswith("### Session "):
            pair += 1
        m = re.match(r"\| (\d+) \| (\w+) \| (\d+) \|.*\| ([^|]*) \|$", line)
        if m and pair >= 0:
            out[(pair, int(m.group(1)))] = re.sub(r"^.*?; ", "", m.group(4).strip())
    return out


def size_text(o):
    return " x ".join(f"{v:.2f}" for v in o["size"]) + " m"


def voxels_text(n):
    return f"{n:,} voxels"


def office(demo):
    """The keys measured from `chronomap demo`'s folder."""
    demo = Path(demo)
    report = json.loads((demo / "report.json").read_text())
    scene = json.loads((demo / "data" / "scene.json").read_text())
    truth = truths((demo / "report.md").read_text())
    pairs = report["pairs"]
    source = "chronomap demo (seed %d)" % scene["seed"]
    keys = {}

    def key(name, figures, given=None):
        keys[name] = {"measured": source, "figures": figures, "given": given or {}}

    key("README.md office_topview.png", {"sessions": f"recorded {WORDS[len(scene['sessions'])]} times"})
    key("docs/simulator.md office_topview.png", {"preset": f"`{scene['preset']}` preset (seed {scene['seed']})"})
    cam = scene["camera"]
    key("docs/simulator.md office_frame_rgb.png", {"frame size": f"{cam['width']} x {cam['height']}"},
        {"depth colour scale": "red (5 m)"})

    def objects(p, with_truth, with_size):
        out = {}
        for o in pairs[p]["objects"]:
            n = o["id"]
            out[f"object {n}"] = f"{n}"
            out[f"object {n} kind"] = o["kind"]
            if with_size:
                out[f"object {n} voxels"] = voxels_text(o["voxels"])
                out[f"object {n} size"] = size_text(o)
            if o["kind"] == "moved":
                out[f"object {n} distance"] = f"{o['distance_m']:.2f} m"
            if with_truth:
                out[f"object {n} truth"] = truth[(p, n)]
        return out

    key("README.md office_changes_00_01.png", objects(0, True, False))
    key("docs/changes.md office_changes_00_01.png",
        {"pair": f"sessions {pairs[0]['from']} and {pairs[0]['to']}", **objects(0, True, False)})
    key("docs/viewer.md viewer_office_diff.png",
        {"pair": f"sessions {pairs[0]['from']} to {pairs[0]['to']}", "slider": f"session {pairs[0]['to']}",
         "objects": f"the {WORDS[len(pairs[0]['objects'])]} objects", **objects(0, False, True)})
    # shoot.mjs flies to the first moved object between consecutive sessions.
    moved = [(p, o) for p in range(len(pairs)) for o in pairs[p]["objects"] if o["kind"] == "moved"]
    if moved:
        p, o = moved[0]
        key("docs/viewer.md viewer_office_move.png",
            {"pair": f"Sessions {pairs[p]['from']} to {pairs[p]['to']}", "object": f"object {o['id']}",
             "distance": f"{o['distance_m']:.2f} m", "voxels": voxels_text(o["voxels"]), "truth": truth[(p, o["id"])]})
    # shoot.mjs predicts a day and a half past the last session, on the hour.
    last = scene["sessions"][-1]["time_s"]
    import datetime
    at = datetime.datetime.fromtimestamp((int(last // 3600) + 36) * 3600, datetime.timezone.utc)
    key("docs/viewer.md viewer_office_predicted.png", {"time": at.strftime("%Y-%m-%d %H:%M UTC")},
        {"how far": "a day and a half after the last session"})
    return keys


def room(folder):
    """The keys of the study room's and pcl-kinect's pictures, from `chronomap integrate --json`
    (room.json; room_up.json and office1_up.json with --up auto) in `folder`."""
    folder = Path(folder)
    r = json.loads((folder / "room.json").read_text())
    keys = {"docs/integration.md room_topview.png": {
        "measured": "chronomap integrate 3dmatch --resolution 0.04 --max-range 6",
        "figures": {"frames": f"{WORDS[r['frames']]} 3DMatch frames", "resolution": f"{r['resolution_m']:g} m"},
        "given": {"range": "6 m range", "flags": "--resolution 0.04 --max-range 6"}}}

    def floor(j, cells):
        """The caption's words for --up auto's floor: `cells` says how it names the sampled cells."""
        return f"a floor of {100 * j['up_floor_share']:.0f}% of {cells.format(j['up_sampled_cells'])}"

    if (folder / "room_up.json").exists():
        u = json.loads((folder / "room_up.json").read_text())
        keys["docs/frames.md frames_room_up.png"] = {
            "measured": "chronomap integrate 3dmatch --resolution 0.04 --max-range 6 --up auto --json",
            "figures": {"frames": f"The {WORDS[u['frames']]} 3DMatch frames", "up": f"{u['up']} found",
                        "floor": floor(u, "{:,} cells")},
            "given": {"resolution": "at 0.04 m with a 6 m range"}}
    if (folder / "office1_up.json").exists():
        u = json.loads((folder / "office1_up.json").read_text())
        keys["docs/frames.md frames_office1_recorded.png"] = {
            "measured": "chronomap integrate pcl-kinect/office1.pcd --max-range 6 --up auto --json",
            "figures": {"up": f"finds {u['up']}", "floor": floor(u, "the {:,} sampled cells")},
            "given": {"image": "640 x 480", "range": "6 m range", "camera": "the camera at (0, 0)",
                      "far wall": "far wall 5 m away"}}
    return keys


def last_json(path):
    """The JSON object a benchmark program prints last."""
    return json.loads(Path(path).read_text().strip().split("\n")[-1])


def weeks(folder):
    """The keys of the weeks pictures, from make-doc-images.sh's weeks group."""
    w = Path(folder)
    keys = {}
    r = json.loads((w / "rhythm_picture.json").read_text())
    nav = last_json(w / "rhythm_eval.txt")
    found, plans = round(nav["nav_found_costmap"] * nav["nav_plans_costmap"]), nav["nav_plans_costmap"]
    doors = ("all three doors open" if r["doors_open"] == r["doors"] == 3
             else f"{WORDS.get(r['doors_open'], r['doors_open'])} of its {r['doors']} doors open")
    keys["docs/rhythm.md weeks_predicted_vs_true.png"] = {
        "measured": "rhythm_eval --poses true, chronomap costmap, bench/rhythm_picture.py (weeks, seed 1)",
        "figures": {"session": f"Test session {r['session']} ({r['weekday']} {r['time'][11:16]}",
                    "doors": doors,
                    "learning sessions": f"the {r['learn_sessions']} sessions of the first three weeks",
                    "doorways": f"{100 * r['doorway_predicted_occupied']:.0f}% of the doorways' voxels",
                    "routes": f"{found} of the {plans} routes",
                    "time": f"--at {r['time']}"},
        "given": {"band": "over 0.2–1.4 m", "cost map": "--lethal 0.7 --z-min 0.2 --z-max 1.4 --robot-radius 0.25",
                  "test sessions": "14 test sessions"}}
    # The night's alerts: alerts_eval's rows of that session (rank, label).
    rows = [line.split(" | ") for line in (w / "alerts_eval.txt").read_text().split("\n")
            if line.startswith("| 48 |")]
    ranked = {int(row[2]): row[7] for row in rows}
    first = ranked[1].removeprefix("rare: ").rsplit(" ", 1)[0]
    doors = [k for k, label in sorted(ranked.items()) if label.endswith("door door_closed")]
    keys["docs/alerts.md alerts_night.png"] = {
        "measured": "alerts_eval --poses true --map, chronomap alerts --top 5 (weeks with rare events, seed 1)",
        "figures": {"first": f"first (1) {first}",
                    "doors": f"then ({doors[0]}–{doors[-1]}) the doors shut for the night" if doors else "no door"},
        "given": {"session": "session 48"}}
    # The colour picture: the sessions colour_eval drew.
    scene = json.loads((w / "colour_sim" / "scene.json").read_text())
    drawn = re.findall(r"^top views at session (\d+) \(\S+T(\d\d:\d\d)", (w / "colour_eval.txt").read_text(), re.M)
    (m, m_hm), (e, e_hm) = drawn
    day = lambda i: calendar.day_name[scene["sessions"][int(i)]["weekday"]]
    keys["docs/colour.md colour_predicted_vs_true.png"] = {
        "measured": "colour_eval --out, bench/colour_picture.py (weeks with daylight and a repaint, seed 1)",
        "figures": {"morning session": f"{m_hm} on {day(m)} of the test week", "evening session": f"{e_hm} on its {day(e)}",
                    "evening": f"At {e_hm}", "labels": f"OUT.png {m_hm} {e_hm}"},
        "given": {"hours asked": "nearest 09:30 and 20:30"}}
    return keys


def floor66(folder):
    """The keys of the floor66 pictures, from make-doc-images.sh's floor66 group."""
    f = Path(folder)
    t = last_json(f / "temporal.txt")
    build = json.loads((f / "build.json").read_text())
    last = json.loads((f / "last.json").read_text())
    zoom = json.loads((f / "shot.json").read_text())["zoom"]
    return {
        "docs/temporal.md floor66_storage.png": {
            "measured": "bench/temporal --sim on chronomap simulate --preset floor66 --resolution-scale 0.5",
            "figures": {"sessions": f"the {t['sessions']} simulated sessions",
                        "separate": f"{t['nodes_separate'] / 1e6:.1f} M nodes",
                        "4D": f"the 4D map {t['nodes_4d'] / 1e6:.1f} M",
                        "share": f"{100 * t['nodes_4d'] / t['nodes_separate']:.1f}%"},
            "given": {"thesis": "the thesis measured 93 M and 14 M on its 66 real sessions"}},
        "docs/viewer.md viewer_floor66_zoom.png": {
            "measured": "chronomap build --fast, chronomap snapshot and shoot.mjs on the floor66 simulation",
            "figures": {"sessions": f"{build['sessions']} sessions",
                        "occupied": f"{last['occupied']:,} occupied voxels at the last one",
                        "cells": f"{zoom['cells']:,} cells in view"},
            "given": {"level": "cubes of 2³ voxels"}}}


def measured(args):
    keys = {}
    if args.floor66:
        keys.update(floor66(args.floor66))
    if args.weeks:
        keys.update(weeks(args.weeks))
    if args.demo:
        keys.update(office(args.demo))
    if args.room:
        keys.update(room(args.room))
    return keys


# ---------------------------------------------------------------------------------------------
# Checking


def check_caption(name, entry, caption):
    problems = []
    texts = list(entry["figures"].values()) + list(entry.get("given", {}).values())
    for what, text in list(entry["figures"].items()) + list(entry.get("given", {}).items()):
        if normalised(text).lower() not in caption.lower():
            problems.append(f"{name}: the caption does not say {what} \"{text}\"")
    allowed = {n for t in texts for n in numbers(normalised(t))}
    for n in numbers(caption):
        if n not in allowed:
            problems.append(f"{name}: the caption quotes {n}, which none of its figures holds "
                            f"({', '.join(sorted(allowed)) or 'none'})")
    return problems


def check(args, figures):
    problems = []
    found = captions()
    for name in figures:
        if name not in found:
            problems.append(f"{name}: no such picture in its document (figures.json names it)")
    for name, caption in found.items():
        if name in figures:
            problems += check_caption(name, figures[name], caption)
        elif numbers(caption):
            problems.append(f"{name}: its caption quotes {', '.join(numbers(caption))} but figures.json has no key "
                            "for it (scripts/make-doc-images.sh measures the figures of every caption)")
    now = measured(args)
    for name, entry in now.items():
        old = figures.get(name)
        if old is None:
            problems.append(f"{name}: measured now but missing from figures.json")
            continue
        for what, text in entry["figures"].items():
            if old["figures"].get(what) != text:
                problems.append(f"{name}: {what} is \"{text}\" now, figures.json says \"{old['figures'].get(what)}\"")
        for what in old["figures"]:
            if what not in entry["figures"]:
                problems.append(f"{name}: figures.json lists {what}, which the current code no longer measures")
    return problems, len(now)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=["measure", "check"])
    parser.add_argument("figures", type=Path)
    parser.add_argument("--demo", help="the folder chronomap demo wrote")
    parser.add_argument("--room", help="the folder of chronomap integrate --json of the study room (room.json; "
                        "room_up.json and office1_up.json with --up auto)")
    parser.add_argument("--weeks", help="the folder make-doc-images.sh's weeks group wrote")
    parser.add_argument("--floor66", help="the folder make-doc-images.sh's floor66 group wrote")
    args = parser.parse_args()
    figures = json.loads(args.figures.read_text()) if args.figures.exists() else {}
    if args.command == "measure":
        figures.update(measured(args))
        args.figures.write_text(json.dumps(dict(sorted(figures.items())), indent=2, ensure_ascii=False) + "\n")
        print(f"{args.figures}: {len(figures)} captions")
        return 0
    problems, remeasured = check(args, figures)
    for p in problems:
        print(p, file=sys.stderr)
    unmeasured = [name for name, entry in figures.items() if entry.get("measured") is None]
    if unmeasured:
        print(f"not measured by make-doc-images.sh yet (checked against figures.json only): {', '.join(unmeasured)}")
    print(f"{len(figures)} captions checked, {remeasured} measured again: "
          + (f"{len(problems)} problem(s)" if problems else "every caption quotes what the code measures"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
