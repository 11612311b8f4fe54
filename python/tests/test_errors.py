"""chronomap's errors arrive as Python exceptions of matching types, naming the file."""

import pytest

import chronomap
from scenes import session


def test_hierarchy():
    assert issubclass(chronomap.FormatError, chronomap.DataError)
    assert issubclass(chronomap.DataError, chronomap.Error)
    assert issubclass(chronomap.UsageError, chronomap.Error) and issubclass(chronomap.UsageError, ValueError)
    assert issubclass(chronomap.IoError, chronomap.Error) and issubclass(chronomap.IoError, OSError)


def test_missing_file_is_an_io_error(tmp_path):
    path = tmp_path / "nothing.cmap"
    with pytest.raises(chronomap.IoError, match="nothing.cmap"):
        chronomap.SessionMap.open(path)
    with pytest.raises(OSError):
        chronomap.TemporalMap.open(path)


def test_truncated_file_is_a_format_error(tmp_path):
    good = tmp_path / "good.cmap"
    session(with_box=False).save(good)
    data = good.read_bytes()
    bad = tmp_path / "truncated.cmap"
    bad.write_bytes(data[: len(data) // 2])
    with pytest.raises(chronomap.FormatError, match="truncated.cmap"):
        chronomap.SessionMap.open(bad)
    garbage = tmp_path / "garbage.cmap"
    garbage.write_bytes(b"not a map at all" * 10)
    with pytest.raises(chronomap.FormatError, match="garbage.cmap"):
        chronomap.SessionMap.open(garbage)


def test_a_session_map_is_not_a_4d_map(tmp_path):
    path = tmp_path / "session.cmap"
    session(with_box=False).save(path)
    with pytest.raises(chronomap.FormatError, match="session.cmap"):
        chronomap.TemporalMap.open(path)


def test_bad_dataset_path_and_settings(tmp_path):
    with pytest.raises(chronomap.UsageError, match="no-such-folder"):
        chronomap.integrate_dataset(tmp_path / "no-such-folder")
    with pytest.raises(chronomap.UsageError):
        chronomap.SessionMap(-1.0)
    with pytest.raises(ValueError, match="median"):
        chronomap.diff(chronomap.SessionMap(), chronomap.SessionMap(), mode="median")


def test_bad_dataset_file_is_a_data_error(tmp_path):
    folder = tmp_path / "broken"
    (folder / "seq-01").mkdir(parents=True)
    (folder / "camera-intrinsics.txt").write_text("570 0 320\n0 570 240\n0 0 1\n")
    (folder / "seq-01" / "frame-000000.depth.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    (folder / "seq-01" / "frame-000000.color.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    (folder / "seq-01" / "frame-000000.pose.txt").write_text("1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    with pytest.raises(chronomap.DataError, match="frame-000000"):
        chronomap.integrate_dataset(folder)
