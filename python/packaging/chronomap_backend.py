"""The build backend of `pip install .` (PEP 517), in the tree: it needs only the standard
library and CMake, so `pip install --no-build-isolation .` works offline.

build_wheel configures the project with the interpreter that runs pip (CHRONOMAP_PYTHON), builds
the extension module and packs build/wheel-<tag>/python/chronomap/ into a wheel. The build
folder is kept, so a second install rebuilds only what changed.
"""

import base64
import hashlib
import os
import pathlib
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[2]
NAME = "chronomap"
SUMMARY = "4D (temporal octree) maps of RGB-D recordings, with numpy arrays in and out"


def _version():
    text = (ROOT / "CMakeLists.txt").read_text()
    return re.search(r"project\(chronomap VERSION ([0-9.]+)", text).group(1)


def _tag():
    interpreter = f"cp{sys.version_info.major}{sys.version_info.minor}"
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    return f"{interpreter}-{interpreter}-{platform}"


def _metadata():
    return (f"Metadata-Version: 2.1\nName: {NAME}\nVersion: {_version()}\nSummary: {SUMMARY}\n"
            f"Requires-Python: >=3.9\nRequires-Dist: numpy\n")


def _dist_info():
    return f"{NAME}-{_version()}.dist-info"


def get_requires_for_build_wheel(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    folder = pathlib.Path(metadata_directory) / _dist_info()
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "METADATA").write_text(_metadata())
    return folder.name


def _build_package():
    """Builds the module; returns the folder laid out as the package installs."""
    build = ROOT / "build" / f"wheel-{_tag()}"
    jobs = str(os.cpu_count() or 1)
    configure = ["cmake", "-S", str(ROOT), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                 f"-DCHRONOMAP_PYTHON={sys.executable}", "-DCHRONOMAP_BUILD_PYTHON=ON", "-DCHRONOMAP_BUILD_TESTS=OFF"]
    if shutil.which("ninja") and not (build / "CMakeCache.txt").exists():
        configure += ["-G", "Ninja"]
    print(f"chronomap: building the Python module for {sys.executable} in {build}", file=sys.stderr)
    subprocess.run(configure, check=True, stdout=sys.stderr)
    subprocess.run(["cmake", "--build", str(build), "--target", "_chronomap", "-j", jobs], check=True,
                   stdout=sys.stderr)
    return build / "python" / NAME


def _record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    package = _build_package()
    wheel_name = f"{NAME}-{_version()}-{_tag()}.whl"
    files = {}
    for path in sorted(package.iterdir()):
        if path.is_file() and path.suffix in (".py", ".pyi", ".so", ".typed"):
            files[f"{NAME}/{path.name}"] = path.read_bytes()
    info = _dist_info()
    files[f"{info}/METADATA"] = _metadata().encode()
    files[f"{info}/WHEEL"] = (f"Wheel-Version: 1.0\nGenerator: chronomap_backend\nRoot-Is-Purelib: false\n"
                              f"Tag: {_tag()}\n").encode()
    if (ROOT / "LICENSE").exists():
        files[f"{info}/LICENSE"] = (ROOT / "LICENSE").read_bytes()
    record = [_record_line(name, data) for name, data in files.items()] + [f"{info}/RECORD,,"]
    files[f"{info}/RECORD"] = ("\n".join(record) + "\n").encode()
    pathlib.Path(wheel_directory).mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(pathlib.Path(wheel_directory) / wheel_name, "w", zipfile.ZIP_DEFLATED) as wheel:
        for name, data in files.items():
            wheel.writestr(name, data)
    return wheel_name
