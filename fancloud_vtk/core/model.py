"""The fan cloud data model: points plus one ring of neighbours per point.

A fan cloud stores, for every point ``p``, the indices of its fan neighbours
``q_1 .. q_m`` in counter-clockwise order around the unit normal of ``p``.
The fan is the triangles ``(p, q_j, q_{j+1})``; a *closed* fan also has the
triangle ``(p, q_m, q_1)``, an *open* fan (a boundary point) does not: its gap
is always between the last and the first ring entry. The rings are kept in
compressed sparse row (CSR) form, ``ring[offsets[i]:offsets[i + 1]]``.

This module is VTK-free, as is all of :mod:`fancloud_vtk.core`. The VTK
conversion and ``.vtp`` files are :func:`fancloud_vtk.to_vtk`,
:func:`fancloud_vtk.from_vtk`, :func:`fancloud_vtk.save` and
:func:`fancloud_vtk.load` (in :mod:`fancloud_vtk.algorithms.convert`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .validation import check_finite

#: Point-data names that may hold a colour array, in order of preference.
COLOR_NAMES = ("RGB", "RGBA", "Colors", "colors", "Colours", "colours", "rgb", "rgba")


def find_color_array(point_data: dict, name: str | None = None) -> str | None:
    """Name of the colour array in ``point_data``, or ``None``.

    A colour array has 3 (RGB) or 4 (RGBA) components, either uint8 or floats
    in [0, 1]. ``name`` picks one explicitly (a ``KeyError`` if missing).
    """
    if name is not None:
        if name not in point_data:
            raise KeyError(f"no point array named {name!r}; arrays: {sorted(point_data)}")
        return name
    for candidate in COLOR_NAMES:
        arr = point_data.get(candidate)
        if arr is not None and arr.ndim == 2 and arr.shape[1] in (3, 4):
            return candidate
    return None


@dataclass(eq=False)
class FanCloud:
    """One triangle fan per point (Linsen & Prautzsch, section 3).

    Parameters
    ----------
    points : numpy.ndarray
        ``(n, 3)`` float64 coordinates.
    offsets : numpy.ndarray
        ``(n + 1,)`` int64 CSR offsets into ``ring``.
    ring : numpy.ndarray
        int64 neighbour indices, counter-clockwise around each point's normal.
    normals : numpy.ndarray
        ``(n, 3)`` float64 unit normals, oriented consistently over each
        connected component (outward on closed surfaces).
    open : numpy.ndarray
        ``(n,)`` bool, True where the fan is open (a boundary point); the gap
        lies between the last and the first entry of the ring.
    rotated : numpy.ndarray, optional
        ``(n,)`` bool, True where the fan was built in the plane rotated by
        90 degrees at a sharp edge (paper, Figure 5).
    point_data : dict of str to numpy.ndarray, optional
        Passthrough point arrays (colours among them), one row per point.
    info : dict, optional
        Statistics of the construction (not part of the saved data).
    """

    points: np.ndarray
    offsets: np.ndarray
    ring: np.ndarray
    normals: np.ndarray
    open: np.ndarray
    rotated: np.ndarray | None = None
    point_data: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.rotated is None:
            self.rotated = np.zeros(len(self.points), dtype=bool)
        self.validate()

    # -- basic queries -------------------------------------------------
    @property
    def n_points(self) -> int:
        """Number of points (and of fans)."""
        return int(self.points.shape[0])

    @property
    def fan_sizes(self) -> np.ndarray:
        """Number of ring neighbours of every point."""
        return np.diff(self.offsets)

    @property
    def n_open(self) -> int:
        """Number of open fans (boundary points)."""
        return int(np.count_nonzero(self.open))

    def neighbours(self, i: int) -> np.ndarray:
        """Ring of point ``i`` (a view, counter-clockwise)."""
        return self.ring[self.offsets[i] : self.offsets[i + 1]]

    @property
    def colors(self) -> np.ndarray | None:
        """The colour point array if the cloud has one (see ``COLOR_NAMES``)."""
        name = find_color_array(self.point_data)
        return None if name is None else self.point_data[name]

    def fan_triangles(self) -> np.ndarray:
        """All fan triangles ``(p, q_j, q_{j+1})``, ``(m, 3)`` int64, fan by fan."""
        sizes = self.fan_sizes
        n_tri = np.where(self.open, np.maximum(sizes - 1, 0), np.where(sizes >= 2, sizes, 0))
        total = int(n_tri.sum())
        owner = np.repeat(np.arange(self.n_points, dtype=np.int64), n_tri)
        first = np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
        j = np.arange(total, dtype=np.int64) - first  # position within the fan
        start = self.offsets[owner]
        size = sizes[owner]
        a = self.ring[start + j]
        b = self.ring[start + (j + 1) % np.maximum(size, 1)]
        return np.stack([owner, a, b], axis=1)

    def triangles(self) -> np.ndarray:
        """Distinct fan triangles (same three points counted once), ``(m, 3)`` int64.

        Each keeps the orientation of its first occurrence, which agrees
        with the normal of the fan it came from.
        """
        tri = self.fan_triangles()
        if len(tri) == 0:
            return tri
        key = np.sort(tri, axis=1)
        n = max(self.n_points, 1)
        if n < 2**21:
            packed = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
            _, first = np.unique(packed, return_index=True)
        else:
            _, first = np.unique(key, axis=0, return_index=True)
        return tri[np.sort(first)]

    def summary(self) -> dict:
        """Counts for reports: points, closed/open/rotated fans, triangles per point."""
        n = self.n_points
        n_tri = len(self.triangles())
        return {
            "points": n,
            "fans_closed": n - self.n_open,
            "fans_open": self.n_open,
            "fans_rotated": int(np.count_nonzero(self.rotated)),
            "fan_triangles": len(self.fan_triangles()),
            "distinct_triangles": n_tri,
            "distinct_triangles_per_point": n_tri / n if n else 0.0,
        }

    def nbytes(self) -> int:
        """Bytes held by the arrays of the fan cloud."""
        arrays = [self.points, self.offsets, self.ring, self.normals, self.open, self.rotated]
        arrays += list(self.point_data.values())
        return int(sum(a.nbytes for a in arrays))

    def copy(self) -> FanCloud:
        """Deep copy."""
        return FanCloud(
            self.points.copy(),
            self.offsets.copy(),
            self.ring.copy(),
            self.normals.copy(),
            self.open.copy(),
            self.rotated.copy(),
            {k: v.copy() for k, v in self.point_data.items()},
            dict(self.info),
        )

    def validate(self) -> None:
        """Check shapes, dtypes, index ranges and that points and normals are finite; raise
        ``ValueError`` naming the problem.

        The names are those of the arrays in VTK (``fan_offsets``,
        ``fan_ring``, ``Normals``, ``fan_open``, ``fan_rotated``).
        """
        arrays = {
            "points": self.points,
            "fan_offsets": self.offsets,
            "fan_ring": self.ring,
            "Normals": self.normals,
            "fan_open": self.open,
            "fan_rotated": self.rotated,
        }
        for key, arr in arrays.items():
            if not isinstance(arr, np.ndarray):
                raise ValueError(f"fan cloud {key} must be a numpy array, got {type(arr).__name__}")
        p = self.points
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"fan cloud points must be an (n, 3) array, got {p.shape}")
        n = p.shape[0]
        if p.dtype != np.float64:
            raise ValueError(f"fan cloud points must be float64, got {p.dtype}")
        off, ring = self.offsets, self.ring
        for key, arr in (("fan_offsets", off), ("fan_ring", ring)):
            if arr.dtype != np.int64:
                raise ValueError(f"{key} must be int64, got {arr.dtype}")
            if arr.ndim != 1:
                raise ValueError(f"{key} must be one-dimensional, got shape {arr.shape}")
        if off.shape[0] != n + 1:
            raise ValueError(f"fan_offsets must have n + 1 = {n + 1} entries, got {off.shape[0]}")
        if off[0] != 0 or off[-1] != len(ring) or np.any(np.diff(off) < 0):
            raise ValueError(
                "fan_offsets must start at 0, never decrease and end at len(fan_ring) "
                f"= {len(ring)}"
            )
        if len(ring) and (ring.min() < 0 or ring.max() >= n):
            bad = int(np.flatnonzero((ring < 0) | (ring >= n))[0])
            raise ValueError(
                f"fan_ring entry {bad} is {int(ring[bad])}, out of range for {n} points"
            )
        if self.normals.shape != (n, 3) or self.normals.dtype != np.float64:
            raise ValueError(
                f"Normals must be a float64 array of shape ({n}, 3), "
                f"got {self.normals.dtype} {self.normals.shape}"
            )
        check_finite(p, "fan cloud points")
        check_finite(self.normals, "fan cloud Normals", "values")
        for key in ("fan_open", "fan_rotated"):
            arr = arrays[key]
            if arr.shape != (n,) or arr.dtype != np.bool_:
                raise ValueError(
                    f"{key} flags must be a bool array of shape ({n},), got {arr.dtype} {arr.shape}"
                )
        if not isinstance(self.point_data, dict):
            raise ValueError("fan cloud point_data must be a dict of name to array")
        for key, arr in self.point_data.items():
            if not isinstance(arr, np.ndarray) or arr.ndim == 0 or arr.shape[0] != n:
                raise ValueError(
                    f"point array {key!r} has shape {np.shape(arr)}, expected {n} rows"
                )

    def __repr__(self) -> str:
        return (
            f"FanCloud({self.n_points} points, {self.n_points - self.n_open} closed fans, "
            f"{self.n_open} open, arrays: {sorted(self.point_data)})"
        )
