"""The wheel that `pip install .` builds (python/packaging/chronomap_backend.py): its layout,
its RECORD, and that the package imports from it. The module is the one of this build (the
backend's CMake step is replaced), so the test takes seconds."""

import base64
import hashlib
import importlib.util
import pathlib
import subprocess
import sys
import zipfile

import chronomap
from conftest import REPO


def load_backend():
    spec = importlib.util.spec_from_file_location("chronomap_backend",
                                                  REPO / "python" / "packaging" / "chronomap_backend.py")
    backend = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(backend)
    return backend


def test_wheel_installs_an_importable_package(tmp_path, monkeypatch):
    backend = load_backend()
    assert backend.get_requires_for_build_wheel() == []
    package = pathlib.Path(chronomap.__file__).resolve().parent
    monkeypatch.setattr(backend, "_build_package", lambda config_settings=None: package)
    name = backend.build_wheel(str(tmp_path / "dist"))
    version = backend._version()
    assert name.startswith(f"chronomap-{version}-cp{sys.version_info.major}{sys.version_info.minor}-")
    with zipfile.ZipFile(tmp_path / "dist" / name) as wheel:
        names = set(wheel.namelist())
        info = f"chronomap-{version}.dist-info"
        assert {"chronomap/__init__.py", "chronomap/__init__.pyi", "chronomap/py.typed", "chronomap/o3d.py",
                f"{info}/METADATA", f"{info}/WHEEL", f"{info}/RECORD"} <= names
        assert any(n.startswith("chronomap/_chronomap") and n.endswith(".so") for n in names)
        # Every file but RECORD is listed with its size and its sha256, as pip checks them.
        record = wheel.read(f"{info}/RECORD").decode().splitlines()
        assert len(record) == len(names)
        for line in record:
            file, digest, size = line.rsplit(",", 2)
            if file.endswith("RECORD"):
                assert digest == size == ""
                continue
            data = wheel.read(file)
            assert int(size) == len(data)
            assert digest == "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        assert "Requires-Dist: numpy" in wheel.read(f"{info}/METADATA").decode()
        wheel.extractall(tmp_path / "site")
    # The extracted wheel is an installed package: it imports, alone on the path, and works.
    code = ("import chronomap, numpy as np; i = chronomap.Integrator(0.1); "
            "i.add_points(np.array([[0.0, 0.0, 1.0]]), np.zeros(3)); print(chronomap.__file__, "
            "i.finish().counts()['occupied_voxels'])")
    done = subprocess.run([sys.executable, "-c", code], env={"PYTHONPATH": str(tmp_path / "site")}, cwd=tmp_path,
                          capture_output=True, text=True, check=True)
    where, occupied = done.stdout.split()
    assert where.startswith(str(tmp_path / "site")) and occupied == "1"


def test_metadata_matches_the_wheel(tmp_path):
    backend = load_backend()
    folder = backend.prepare_metadata_for_build_wheel(str(tmp_path))
    metadata = (tmp_path / folder / "METADATA").read_text()
    assert "Name: chronomap" in metadata and f"Version: {backend._version()}" in metadata
