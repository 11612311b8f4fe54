"""Runs test code in a child interpreter, so that a crash (a double free, an abort) or a stray
signal fails one test instead of ending the whole pytest run."""

import os
import pathlib
import subprocess
import sys
import textwrap

TESTS = pathlib.Path(__file__).resolve().parent


def run(source, *args, timeout=120):
    """Runs `source` (Python, dedented) with `args` in sys.argv[1:]; returns the finished process
    (stdout and stderr as text). The child imports chronomap as this process does, and scenes."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS)] + [p for p in sys.path if p])
    return subprocess.run([sys.executable, "-c", textwrap.dedent(source), *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=timeout)


def describe(process):
    """What a failed child said, for an assertion message."""
    return f"exit status {process.returncode}\nstdout:\n{process.stdout}\nstderr:\n{process.stderr[-4000:]}"
