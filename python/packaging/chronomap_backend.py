"""The build backend of `pip install .` (PEP 517), in the tree: it needs only the standard
library and CMake, so `pip install --no-build-isolation .` works offline.

build_wheel configures the project with the interpreter that runs pip (CHRONOMAP_PYTHON), builds
the extension module and packs build/wheel-<tag>/python/chronomap/ into a wheel. The build
folder is kept, so a second install rebuilds only what changed. The config setting `build-dir`
(`pip wheel -C build-dir=build/ci`) names a build folder already configured for this
interpreter instead: only the module's target is built there (CI packs the module its tests ran
on, in seconds). CMAKE_BUILD_PARALLEL_LEVEL limits the build's jobs (default: every core).

build_sdist packs the source tree (the files git tracks, or every file but build folders when
the tree is not a git checkout, as in an unpacked sdist) with PKG-INFO, so `pip wheel` of the
sdist builds as from the checkout.
"""

import base64
import hashlib
import io
import os
import pathlib
import re
import shutil
import subprocess
import sys
import sysconfig
import tarfile
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


def _cmake_environment():
    """The environment for CMake, without pip's build isolation: pip hides the interpreter's
    site-packages from the backend (PYTHONPATH to its own folder, PYTHONNOUSERSITE), and CMake
    asks that interpreter where numpy's headers are. Nothing is installed into the isolation
    (the backend requires nothing), so `pip wheel .` works offline with it or without it."""
    env = dict(os.environ)
    if "pip-build-env" in env.get("PYTHONPATH", ""):
        env.pop("PYTHONPATH")
        env.pop("PYTHONNOUSERSITE", None)
    return env


def _cached_python(build):
    for line in (build / "CMakeCache.txt").read_text().splitlines():
        if line.startswith("CHRONOMAP_PYTHON:"):
            return line.split("=", 1)[1]
    return None


def _build_existing(build):
    """Builds the module in a build folder configured before (config setting build-dir)."""
    if not (build / "CMakeCache.txt").exists():
        raise RuntimeError(f"build-dir {build}: no CMakeCache.txt there; configure it first (cmake --preset ci) "
                           f"or leave build-dir out")
    python = _cached_python(build)
    if python is None or os.path.realpath(python) != os.path.realpath(sys.executable):
        raise RuntimeError(f"build-dir {build} builds the module for {python}, not for {sys.executable} that runs "
                           f"this build: run pip with that interpreter, or leave build-dir out")
    jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
    subprocess.run(["cmake", "--build", str(build), "--target", "_chronomap", "-j", jobs], check=True,
                   stdout=sys.stderr, env=_cmake_environment())
    return build / "python" / NAME


def _build_package(config_settings=None):
    """Builds the module; returns the folder laid out as the package installs."""
    given = (config_settings or {}).get("build-dir")
    if given:
        return _build_existing(pathlib.Path(given).resolve())
    build = ROOT / "build" / f"wheel-{_tag()}"
    jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
    configure = ["cmake", "-S", str(ROOT), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                 f"-DCHRONOMAP_PYTHON={sys.executable}", "-DCHRONOMAP_BUILD_PYTHON=ON", "-DCHRONOMAP_BUILD_TESTS=OFF"]
    if shutil.which("ninja") and not (build / "CMakeCache.txt").exists():
        configure += ["-G", "Ninja"]
    print(f"chronomap: building the Python module for {sys.executable} in {build}", file=sys.stderr)
    subprocess.run(configure, check=True, stdout=sys.stderr, env=_cmake_environment())
    subprocess.run(["cmake", "--build", str(build), "--target", "_chronomap", "-j", jobs], check=True,
                   stdout=sys.stderr, env=_cmake_environment())
    return build / "python" / NAME


def _record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    package = _build_package(config_settings)
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


def get_requires_for_build_sdist(config_settings=None):
    return []


# Never in an sdist: the build and output folders at the top, and anywhere git's folder, caches
# and installed npm packages (as .gitignore has them).
_SKIPPED_AT_TOP = {"build", "dist", "out"}
_SKIPPED = {".git", "__pycache__", "node_modules"}


def _source_files():
    """The tree's files, relative to ROOT: git's tracked files in a checkout, else every file."""
    if (ROOT / ".git").exists() and shutil.which("git"):
        listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], check=True, capture_output=True).stdout
        names = [n for n in listed.decode().split("\0") if n]
        return sorted(n for n in names if (ROOT / n).is_file())
    files = []
    for folder, dirs, names in os.walk(ROOT):
        top = os.path.samefile(folder, ROOT)
        dirs[:] = sorted(d for d in dirs if d not in _SKIPPED and not (top and d in _SKIPPED_AT_TOP))
        files += [os.path.relpath(os.path.join(folder, n), ROOT) for n in names if n != "PKG-INFO"]
    return sorted(files)


def build_sdist(sdist_directory, config_settings=None):
    base = f"{NAME}-{_version()}"
    name = f"{base}.tar.gz"
    pathlib.Path(sdist_directory).mkdir(parents=True, exist_ok=True)
    with tarfile.open(pathlib.Path(sdist_directory) / name, "w:gz", format=tarfile.PAX_FORMAT) as sdist:
        for file in _source_files():
            sdist.add(ROOT / file, arcname=f"{base}/{file}", recursive=False)
        info = tarfile.TarInfo(f"{base}/PKG-INFO")
        data = _metadata().encode()
        info.size, info.mode = len(data), 0o644
        sdist.addfile(info, io.BytesIO(data))
    return name
