"""chronomap: 4D (temporal octree) maps of RGB-D recordings, with numpy arrays in and out.

The classes and functions are those of the C++ library (built as the extension module
``chronomap._chronomap``); names carry their units (``resolution_m``, ``time_s``).
"""

from ._chronomap import (  # noqa: F401
    APPEARED,
    FREE,
    OCCUPIED,
    UNCHANGED,
    UNKNOWN,
    VANISHED,
    Component,
    DataError,
    DiffMap,
    Error,
    FormatError,
    Integrator,
    IoError,
    SessionMap,
    TemporalMap,
    UsageError,
    diff,
    integrate_dataset,
    read_color_png,
    read_depth_png,
    segment,
)

__all__ = [
    "APPEARED", "FREE", "OCCUPIED", "UNCHANGED", "UNKNOWN", "VANISHED",
    "Component", "DataError", "DiffMap", "Error", "FormatError", "Integrator", "IoError",
    "SessionMap", "TemporalMap", "UsageError", "diff", "integrate_dataset", "read_color_png",
    "read_depth_png", "segment",
]
