"""Input checks shared by the core functions.

Every check raises a ``ValueError`` (or ``TypeError`` for a wrong kind of
object) whose message names the problem, and never modifies its input: the
arrays returned are new ones.
"""

from __future__ import annotations

import errno
import os

import numpy as np


class FanCloudInputError(ValueError):
    """The input points or parameters cannot give a fan cloud."""


class FileReadError(ValueError):
    """A file could not be read: names the path and the reason.

    Defined here so that the core can raise it without importing the file
    readers; :mod:`fancloud_vtk.io` exports the same class
    (``fancloud_vtk.io.FileReadError``).

    Parameters
    ----------
    path : str
        The file that could not be read.
    reason : str
        Why it could not be read.
    """

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(path, reason)
        self.path = path
        self.reason = reason

    def __str__(self) -> str:
        return f"cannot read {self.path!r}: {self.reason}"


class _NoSuchFile(FileReadError, FileNotFoundError):
    """A missing file: a :class:`FileReadError` (a ``ValueError``) as
    :func:`~fancloud_vtk.io.read_point_cloud` raises, and a ``FileNotFoundError`` as
    :func:`~fancloud_vtk.algorithms.convert.read_vtp` raises."""

    def __init__(self, path: str, reason: str = "no such file"):
        super().__init__(path, reason)
        self.errno, self.strerror, self.filename = errno.ENOENT, reason, path

    def __reduce__(self):
        return type(self), (self.path, self.reason)


def readable_file(path) -> str:
    """``path`` as a ``str`` if it names a non-empty file; else a :class:`FileReadError`
    naming it: missing (then also a ``FileNotFoundError``), a directory, or empty."""
    path = os.fspath(path)
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not os.path.exists(path):
        raise _NoSuchFile(path)
    if os.path.isdir(path):
        raise FileReadError(path, "is a directory, not a file")
    if os.path.getsize(path) == 0:
        raise FileReadError(path, "the file is empty (0 bytes)")
    return path


def as_points(points, *, name: str = "points") -> np.ndarray:
    """Return ``points`` as a new C-contiguous ``(n, 3)`` float64 array.

    Raises
    ------
    TypeError
        If ``points`` is not numeric (strings, objects, complex numbers).
    FanCloudInputError
        If the shape is not ``(n, 3)`` or a coordinate is NaN or infinite.
    """
    try:
        arr = np.asarray(points)
    except Exception as exc:  # ragged lists and the like
        raise TypeError(f"{name} must be an (n, 3) array of numbers: {exc}") from exc
    if arr.dtype == object or arr.dtype.kind not in "biuf":
        raise TypeError(
            f"{name} must be an (n, 3) array of real numbers, got dtype {arr.dtype}"
        )
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise FanCloudInputError(f"{name} must have shape (n, 3), got {arr.shape}")
    out = np.array(arr, dtype=np.float64, order="C", copy=True)
    check_finite(out, name)
    return out


def check_finite(arr: np.ndarray, name: str, what: str = "coordinates") -> None:
    """Raise :class:`FanCloudInputError` naming the first row of the ``(n, k)`` array
    ``arr`` with a NaN or infinite value."""
    finite = np.isfinite(arr).all(axis=1)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise FanCloudInputError(
            f"{name} contain NaN or infinite {what} at {bad.size} point(s), "
            f"first at index {int(bad[0])}: {arr[bad[0]].tolist()}"
        )


def as_normals(normals, n: int, *, name: str = "normals") -> np.ndarray:
    """Return given normals as a new ``(n, 3)`` float64 array of unit vectors."""
    arr = as_points(normals, name=name)
    if arr.shape[0] != n:
        raise FanCloudInputError(f"{name} must have {n} rows (one per point), got {arr.shape[0]}")
    length = np.linalg.norm(arr, axis=1)
    if np.any(length == 0):
        bad = int(np.flatnonzero(length == 0)[0])
        raise FanCloudInputError(f"{name} has a zero vector at index {bad}")
    return arr / length[:, None]


def check_spread(points: np.ndarray) -> None:
    """Reject clouds whose points are all identical or all on one line."""
    centred = points - points.mean(axis=0)
    s = np.linalg.svd(centred[:: max(1, len(points) // 200_000)], compute_uv=False)
    scale = max(float(np.abs(points).max()), 1.0)
    if s[0] <= 1e-12 * scale * np.sqrt(len(points)):
        raise FanCloudInputError("all points are identical: a fan cloud needs a surface")
    if s[1] <= 1e-9 * s[0]:
        raise FanCloudInputError(
            "all points are collinear (they lie on one line): a fan cloud needs a surface"
        )


def check_point_data(point_data, n: int) -> dict[str, np.ndarray]:
    """Check passthrough arrays: a mapping of name to array with ``n`` rows."""
    if point_data is None:
        return {}
    if not hasattr(point_data, "items"):
        raise TypeError("point_data must be a mapping of array name to array")
    out = {}
    for key, value in point_data.items():
        arr = np.array(value, copy=True)  # the fan cloud never shares the caller's buffers
        if arr.ndim == 0 or arr.shape[0] != n:
            raise FanCloudInputError(
                f"point array {key!r} has shape {arr.shape}, expected {n} rows (one per point)"
            )
        out[str(key)] = arr
    return out
