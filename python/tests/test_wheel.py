"""The package as a user gets it: `pip wheel` makes a wheel offline, it installs into a fresh
virtual environment made from this interpreter (numpy from the system's site-packages), and the
README's Python example runs there; the sdist holds what a build needs.

The wheel packs the module of this build (`--config-settings build-dir=`, the build these tests
run on), so the test takes seconds; a build from scratch is the same backend's CMake step."""

import os
import pathlib
import re
import subprocess
import sys
import tarfile

import pytest

import chronomap
from conftest import REPO, _data_dir
from test_packaging import load_backend

OFFLINE = {"PIP_NO_INDEX": "1", "PIP_DISABLE_PIP_VERSION_CHECK": "1", "PIP_NO_CACHE_DIR": "1"}


def readme_example():
    """The first Python block of README.md's "From Python" section."""
    text = (REPO / "README.md").read_text()
    section = text[text.index("## From Python"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def clean_environment():
    """This environment without the build's package on the path (ctest sets PYTHONPATH)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(OFFLINE)
    return env


def run(*args, **kwargs):
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=300, **kwargs)
    assert done.returncode == 0, f"{args}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def test_the_wheel_installs_into_a_fresh_environment_and_the_readme_example_runs(tmp_path, threedmatch):
    build = pathlib.Path(chronomap.__file__).resolve().parents[2]  # build/<preset>/python/chronomap
    assert (build / "CMakeCache.txt").exists(), f"{build} is not a CMake build folder"
    env = clean_environment()
    # pip's build isolation as a user gets it: the backend requires nothing, so nothing is fetched.
    run(sys.executable, "-m", "pip", "wheel", REPO, "-w", tmp_path / "dist", "--no-deps",
        "--config-settings", f"build-dir={build}", env=env)
    wheels = list((tmp_path / "dist").glob("chronomap-*.whl"))
    assert len(wheels) == 1
    run(sys.executable, "-m", "venv", "--system-site-packages", tmp_path / "env", env=env)
    python = tmp_path / "env" / "bin" / "python"
    run(python, "-m", "pip", "install", "--no-deps", wheels[0], env=env)
    where = run(python, "-c", "import chronomap; print(chronomap.__file__)", cwd=tmp_path, env=env).strip()
    assert where.startswith(str(tmp_path / "env")), where
    # The README's example, as a user pastes it with the placeholder replaced by their folder.
    example = readme_example()
    assert '"PATH/TO/3dmatch"' in example, "the README's example no longer names its folder PATH/TO/3dmatch"
    code = example.replace('"PATH/TO/3dmatch"', f'"{_data_dir()}/3dmatch/3dmatch"')
    out = run(python, "-c", code, cwd=REPO, env=env).splitlines()
    assert len(out) == 2, out
    assert re.match(r"\(\d+, 3\) uint8 \(array\(\[", out[0]), out[0]
    assert out[1].startswith("[(") and "appeared" in out[1], out[1]


def test_the_sdist_holds_the_tree_and_no_build_output(tmp_path):
    backend = load_backend()
    assert backend.get_requires_for_build_sdist() == []
    name = backend.build_sdist(str(tmp_path))
    base = f"chronomap-{backend._version()}"
    assert name == f"{base}.tar.gz"
    with tarfile.open(tmp_path / name) as sdist:
        names = set(sdist.getnames())
        assert {f"{base}/PKG-INFO", f"{base}/pyproject.toml", f"{base}/CMakeLists.txt",
                f"{base}/python/packaging/chronomap_backend.py", f"{base}/python/src/module.cpp",
                f"{base}/include/chronomap/core/time.h", f"{base}/src/core/time.cpp"} <= names
        assert not any(n.startswith((f"{base}/build/", f"{base}/.git/")) or "/node_modules/" in n for n in names)
        assert "Name: chronomap" in sdist.extractfile(f"{base}/PKG-INFO").read().decode()
        sdist.extractall(tmp_path / "unpacked")
    # Unpacked (no git), the backend lists the same files again: an sdist of the sdist.
    again = load_backend_at(tmp_path / "unpacked" / base)
    assert again.build_sdist(str(tmp_path / "again")) == name
    with tarfile.open(tmp_path / "again" / name) as sdist:
        assert set(sdist.getnames()) == names


def load_backend_at(root):
    import importlib.util
    spec = importlib.util.spec_from_file_location("chronomap_backend_copy",
                                                  root / "python" / "packaging" / "chronomap_backend.py")
    backend = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(backend)
    return backend
