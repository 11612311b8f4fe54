"""chronomap: 4D (temporal octree) maps of RGB-D recordings, with numpy arrays in and out.

The classes and functions are those of the C++ library (built as the extension module
``chronomap._chronomap``); names carry their units (``resolution_m``, ``time_s``). Times are
epoch seconds, ISO-8601 strings (as the command line takes them) or ``datetime.datetime``
(naive ones are UTC). ``chronomap.o3d`` converts to and from Open3D when ``open3d`` is
importable.
"""

from ._chronomap import (  # noqa: F401
    APPEARED,
    FREE,
    OCCUPIED,
    UNCHANGED,
    UNKNOWN,
    VANISHED,
    ColourModel,
    Component,
    DataError,
    DiffMap,
    Error,
    FormatError,
    Integrator,
    IoError,
    RhythmModels,
    SessionMap,
    TemporalMap,
    UsageError,
    add_session,
    build,
    changes,
    costmap,
    diff,
    formats,
    integrate_dataset,
    read_color_png,
    read_depth_png,
    segment,
)

__all__ = [
    "APPEARED", "FREE", "OCCUPIED", "UNCHANGED", "UNKNOWN", "VANISHED",
    "ColourModel", "Component", "DataError", "DiffMap", "Error", "FormatError", "Integrator", "IoError", "RhythmModels",
    "SessionMap", "TemporalMap", "UsageError", "add_session", "build", "changes", "costmap", "diff", "formats", "integrate_dataset", "read_color_png",
    "read_depth_png", "segment",
]
