#!/usr/bin/env python3
"""Build a 4D map of the simulated office, with registration, and print what each session added.

    chronomap simulate --preset office -o office          # the recordings (TUM folders)
    python3 examples/build_office.py office office.cmap [--resolution 0.05]

Every session_NN folder is integrated, the sessions are registered to their consensus (the
part of the localisation error that is one offset per session is removed), ordered by time and
added to the 4D map, which is written once. Progress goes to stderr.
"""

import argparse
import pathlib
import sys
import time

import chronomap


def progress(label, done, total):
    print(f"\r{label}: {done}/{total}   ", end="" if done < total else "\n", file=sys.stderr, flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("simulation", type=pathlib.Path, help="folder written by `chronomap simulate`")
    parser.add_argument("output", type=pathlib.Path, help="the 4D map to write (.cmap)")
    parser.add_argument("--resolution", type=float, default=0.05, help="voxel edge, metres")
    parser.add_argument("--no-register", action="store_true", help="skip the registration to the consensus")
    args = parser.parse_args()

    sessions = sorted(args.simulation.glob("session_*"))
    if not sessions:
        sys.exit(f"{args.simulation}: no session_NN folders (make them with `chronomap simulate`)")
    start = time.perf_counter()
    result = chronomap.build(args.output, sessions, resolution_m=args.resolution, fast=True,
                             register=not args.no_register, progress=progress)
    print(f"{len(result['added'])} sessions in {time.perf_counter() - start:.1f} s -> {args.output} "
          f"({result['nodes']} nodes, {result['file_bytes'] / 1024:.0f} KiB)")
    for s in result["added"]:
        shift = s.get("registration_m")
        moved = f", registered by {1000 * (shift ** 2).sum() ** 0.5:.0f} mm" if shift is not None else ""
        print(f"  {s['dataset'].name}: {s['points']} points, {s['entries_added']} entries added{moved}")

    m = chronomap.TemporalMap.open(args.output)
    counts = m.change_histogram()
    print(f"times: {m.times[0]:%Y-%m-%d %H:%M} .. {m.times[-1]:%Y-%m-%d %H:%M} UTC; "
          f"voxels that changed once: {counts[1] if len(counts) > 1 else 0}, more often: {int(counts[2:].sum())}")


if __name__ == "__main__":
    main()
