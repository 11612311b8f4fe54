"""Ctrl-C stops a long call: SIGINT during integrate_dataset or build raises KeyboardInterrupt
at the next frame instead of after the whole recording, and build writes nothing.

Each run is a child interpreter: the signal goes to the child only, and before the fix the
interrupt arrived long after the call (and could have hit pytest itself)."""

import pytest

import child

# The 3DMatch recording's five frames repeated: 400 frames at 2 cm take tens of seconds
# uninterrupted. The signal comes 0.5 s after the call starts, or with the third progress report.
INTERRUPTED = """
    import os, pathlib, signal, sys, threading, time
    import chronomap

    source, root, call = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), sys.argv[3]
    (root / "seq-01").mkdir(parents=True)
    os.symlink(source / "camera-intrinsics.txt", root / "camera-intrinsics.txt")
    stems = sorted(p.name[: -len(".pose.txt")] for p in (source / "seq-01").glob("*.pose.txt"))
    for i in range(400):
        for ext in (".color.png", ".depth.png", ".pose.txt"):
            os.symlink(source / "seq-01" / (stems[i % len(stems)] + ext), root / "seq-01" / f"frame-{i:06d}{ext}")
    reports = []

    def progress(label, done, total):
        reports.append(done)
        if done == 3:  # Ctrl-C while the call runs on, from the progress callback's thread
            os.kill(os.getpid(), signal.SIGINT)

    calls = {
        "integrate_dataset": lambda: chronomap.integrate_dataset(root, resolution_m=0.02, threads=1),
        "integrate_dataset_parallel": lambda: chronomap.integrate_dataset(root, resolution_m=0.02, threads=2),
        "integrate_dataset_progress": lambda: chronomap.integrate_dataset(root, resolution_m=0.02, progress=progress),
        "build": lambda: chronomap.build(root.parent / "map.cmap", [root], times=[0.0], resolution_m=0.02),
    }
    if call != "integrate_dataset_progress":
        threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT)).start()
    start = time.monotonic()
    try:
        calls[call]()
        print(f"finished after {time.monotonic() - start:.2f} s")
    except KeyboardInterrupt:
        print(f"interrupted after {time.monotonic() - start:.2f} s")
    print("reports", len(reports))
    print("map written", (root.parent / "map.cmap").exists())
"""


@pytest.mark.parametrize("call", ["integrate_dataset", "integrate_dataset_parallel", "integrate_dataset_progress",
                                  "build"])
def test_ctrl_c_stops_a_long_call(tmp_path, threedmatch, call):
    process = child.run(INTERRUPTED, threedmatch, tmp_path / "long", call, timeout=300)
    assert process.returncode == 0, child.describe(process)
    lines = process.stdout.splitlines()
    assert lines[0].startswith("interrupted after "), child.describe(process)
    # Stopped at the next frame: well before the 400 frames' tens of seconds.
    assert float(lines[0].split()[2]) < 2.5, lines[0]
    assert lines[2] == "map written False"
    if call == "integrate_dataset_progress":
        assert 3 <= int(lines[1].split()[1]) < 20, lines[1]
