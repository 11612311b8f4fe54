"""Shared fixtures: where the real recordings and the command line are.

The tests run under Debian's /usr/bin/python3 (ctest runs them so, with PYTHONPATH at the
build's python/ folder). Like the C++ tests, a missing recording skips a test, except under
CI=true, where it fails.
"""

import os
import pathlib
import shutil
import subprocess

import pytest

import scenes

REPO = pathlib.Path(__file__).resolve().parents[2]


def _data_dir():
    for name in ("CHRONOMAP_DATA_DIR", "CHRONOMAP_DEFAULT_DATA_DIR"):
        if os.environ.get(name):
            return pathlib.Path(os.environ[name])
    return REPO.parent / "shared" / "data"


def require(path):
    """`path` when it exists; else a skip, or a failure under CI=true."""
    if path.exists():
        return path
    message = f"missing test data: {path} (set CHRONOMAP_DATA_DIR)"
    if os.environ.get("CI") == "true":
        pytest.fail(message)
    pytest.skip(message)


@pytest.fixture(scope="session")
def threedmatch():
    """The 3DMatch recording: five frames of seq-01 with camera-intrinsics.txt."""
    return require(_data_dir() / "3dmatch" / "3dmatch")


@pytest.fixture(scope="session")
def cli():
    """The chronomap command line of the same build."""
    path = os.environ.get("CHRONOMAP_CLI") or shutil.which("chronomap")
    if not path:
        pytest.fail("CHRONOMAP_CLI is not set (ctest sets it) and chronomap is not on PATH")
    return pathlib.Path(path)


@pytest.fixture(scope="session")
def before():
    """The synthetic room of scenes.py without the box (a SessionMap; tests only read it)."""
    return scenes.session(with_box=False)


@pytest.fixture(scope="session")
def after():
    """The same room with the box."""
    return scenes.session(with_box=True)


@pytest.fixture(scope="session")
def building(tmp_path_factory, cli):
    """The simulator's tiny building at a quarter resolution: its session folders, in order."""
    out = tmp_path_factory.mktemp("sim") / "tiny"
    subprocess.run([str(cli), "simulate", "--preset", "tiny", "--resolution-scale", "0.25", "-o", str(out)],
                   check=True, capture_output=True)
    return sorted(out.glob("session_*"))
