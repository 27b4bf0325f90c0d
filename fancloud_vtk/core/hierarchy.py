"""The levels of detail of a fan cloud: the record of a reduction (paper section 6).

A :class:`Hierarchy` is made by :func:`~fancloud_vtk.hierarchy` (or
``reduce(..., return_hierarchy=True)``, :mod:`.reduction`) and by
``refine(..., return_hierarchy=True)`` (:mod:`.refinement`, whose insertions,
reversed, are removals). It holds the removal order, each removed point's
ring and its position in the local frame of that ring, and the rings its
removal changed, so that any level, coarser or finer, can be recovered,
edited coarse levels refined with their detail, and a region of interest
refined selectively.

This module also holds what the reduction and the refinement share
(:data:`MIN_WIDTH`, :data:`ORIGINAL_ID`, :class:`RoundMarks`): it imports
neither of them, and they import it. It is VTK-free; a hierarchy is saved
here as ``.npz`` only (``.vtp``: :func:`fancloud_vtk.save` /
:func:`fancloud_vtk.load`).
"""

from __future__ import annotations

import numbers
import os

import numpy as np

from . import _csr_kernels as CsrK
from . import _reduction_kernels as RK
from .fans import build_fans
from .model import FanCloud
from .validation import FileReadError, readable_file

#: the removal criteria: ``method`` of a reduction, by name
METHODS = {"entropy": RK.METHOD_ENTROPY, "error": RK.METHOD_ERROR}
#: columns of the fan table during the reduction and the refinement (rings may grow a little)
MIN_WIDTH = 24
#: name of the point array mapping every output point to its input point
ORIGINAL_ID = "original_id"
#: the arrays of a hierarchy besides its source fan cloud (:meth:`Hierarchy.arrays`)
HIERARCHY_ARRAYS = ("order", "rem_off", "rem_ring", "rem_open", "detail", "log_off", "ent_x",
                    "ent_open", "ent_off", "ent_ring", "coarse_off", "coarse_ring",
                    "coarse_open", "original_id")


def level_of(pts, nrm, point_data, original_id, rotated, ids, offsets, ring, ropen
             ) -> FanCloud:
    """The fan cloud of the points ``ids`` with the rings ``offsets``, ``ring`` (numbered
    among them), their point arrays and ``original_id``; the other arrays are per point of
    the whole cloud."""
    if len(ring) and ring.min() < 0:
        raise RuntimeError("internal error: a fan of the level refers to a removed point")
    pdata = {k: v[ids].copy() for k, v in point_data.items()}
    pdata[ORIGINAL_ID] = original_id[ids].copy()
    return FanCloud(np.ascontiguousarray(pts[ids]), offsets, ring,
                    np.ascontiguousarray(nrm[ids]), ropen[ids].copy(), rotated[ids].copy(),
                    pdata, {"hierarchy_level": len(ids)})


def source_arrays(fc: FanCloud):
    """(point arrays without ``original_id``, ``original_id``: the input's own or 0..n-1)."""
    pdata = dict(fc.point_data)
    original = pdata.pop(ORIGINAL_ID, None)
    if original is None:
        original = np.arange(fc.n_points, dtype=np.int64)
    return pdata, np.asarray(original, dtype=np.int64)


class RoundMarks:
    """The uint8 marks of a round's acceptance (``first_disjoint``): a new tag each round,
    1..``cycle``, and the marks cleared when the tags wrap. Rounds of the reduction and of
    the refinement both use it."""

    cycle = 255

    def __init__(self, n: int):
        self.mark = np.zeros(n, np.uint8)
        self._tag = 0

    def next_tag(self) -> np.uint8:
        self._tag = self._tag % self.cycle + 1
        if self._tag == 1:
            self.mark[:] = 0
        return np.uint8(self._tag)


def _inconsistent(problem: str) -> ValueError:
    return ValueError(f"inconsistent hierarchy: {problem}")


def _ints(arr, name: str) -> np.ndarray:
    """An integer array of the hierarchy as int64 (floats are refused, not truncated)."""
    arr = np.asarray(arr)
    if arr.dtype.kind not in "iu":
        raise _inconsistent(f"{name} must hold integers, got {arr.dtype}")
    return arr.astype(np.int64, copy=False)


def _indices(arr, name: str) -> np.ndarray:
    """Point indices as int32 (the logs are long: half the memory) or int64 past 2**31."""
    arr = np.asarray(arr)
    if arr.dtype.kind not in "iu":
        raise _inconsistent(f"{name} must hold integer point indices, got {arr.dtype}")
    if arr.dtype == np.int32:
        return np.ascontiguousarray(arr)
    if arr.size and (arr.max() >= 2**31 or arr.min() < -(2**31)):
        return np.ascontiguousarray(arr, dtype=np.int64)  # out of range: _check says so
    return arr.astype(np.int32)


def _flags(arr, name: str) -> np.ndarray:
    arr = np.asarray(arr)
    if arr.dtype.kind not in "biu":
        raise _inconsistent(f"{name} must hold booleans, got {arr.dtype}")
    return arr.astype(bool, copy=False)


def _first(mask) -> int:
    """Index of the first True of a bool array."""
    return int(np.flatnonzero(mask)[0])


class Hierarchy:
    """Levels of detail of a fan cloud: the record of a reduction (section 6).

    Made by :func:`~fancloud_vtk.hierarchy` or ``reduce(...,
    return_hierarchy=True)``; :func:`~fancloud_vtk.refine_hierarchy` adds
    refined levels above the finest.
    ``level(m)`` gives the fan cloud of any level between the coarsest
    computed (``n_min``) and the input (``n_points``); ``level(m,
    base=edited)`` reinserts the removed points relative to an edited coarse
    level; :meth:`selective` refines only a region of interest.

    Attributes
    ----------
    order : numpy.ndarray
        Input indices of the removed points, first removed first.
    detail : numpy.ndarray
        ``(r, 6)``: per removed point its offset from the centroid of its
        ring at removal time and its normal, in the ring's local frame
        (tangent to the first ring point, normal x tangent, Newell normal).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, hierarchy
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> h = hierarchy(build_fans(p), 300)
    >>> h.n_min, h.n_points, h.level(1000).n_points
    (300, 2000, 1000)
    >>> bool(np.array_equal(h.level(2000).points, p))  # the finest level is the input
    True
    """

    #: which kind of input ``dataset.fancloud.hierarchy()`` took ('fan cloud', 'triangle
    #: mesh' or 'point set'); None for a hierarchy made otherwise (not saved)
    fancloud_input: str | None = None

    def __init__(self, *, source: FanCloud, order, rem_off, rem_ring, rem_open, detail, log_off,
                 ent_x, ent_open, ent_off, ent_ring, coarse_off, coarse_ring, coarse_open,
                 weights, method):
        pdata, original = source_arrays(source)
        self.source = FanCloud(source.points, source.offsets, source.ring, source.normals,
                               source.open, source.rotated, pdata)
        self.original_id = original
        self.order = _ints(order, "order")
        self.rem_off = _ints(rem_off, "rem_off")
        self.rem_ring = _indices(rem_ring, "rem_ring")
        self.rem_open = _flags(rem_open, "rem_open")
        detail = np.asarray(detail)
        if detail.dtype.kind not in "biuf":
            raise _inconsistent(f"detail must hold numbers, got {detail.dtype}")
        self.detail = detail.astype(np.float64, copy=False)
        self.log_off = _ints(log_off, "log_off")
        self.ent_x = _indices(ent_x, "ent_x")
        self.ent_open = _flags(ent_open, "ent_open")
        self.ent_off = _ints(ent_off, "ent_off")
        self.ent_ring = _indices(ent_ring, "ent_ring")
        self.coarse_off = _ints(coarse_off, "coarse_off")
        self.coarse_ring = _ints(coarse_ring, "coarse_ring")
        self.coarse_open = _flags(coarse_open, "coarse_open")
        self.weights = tuple(float(x) for x in weights)
        self.method = str(method)
        self._check()

    #: the CSR offset arrays and the arrays they index
    _CSR = (("rem_off", "rem_ring"), ("log_off", "ent_x"), ("ent_off", "ent_ring"),
            ("coarse_off", "coarse_ring"))

    def _check(self):
        """Raise ``ValueError("inconsistent hierarchy: ...")`` unless the arrays fit together.

        Shapes; CSR offsets that start at 0, never decrease and end at the
        length of the array they index; point indices in range; a removal
        order without repeats; rings that name only points present at their
        level; finite detail, points, normals and weights. What passes cannot
        make the kernels of :meth:`level` read or write out of bounds.
        """
        n = self.n_points
        flat = ("order", "rem_ring", "ent_x", "ent_ring", "coarse_ring")
        problems = [f"{name} must be one-dimensional, got shape {getattr(self, name).shape}"
                    for name in flat if getattr(self, name).ndim != 1]
        if problems:
            raise _inconsistent("; ".join(problems))
        r = len(self.order)
        n_ent = len(self.ent_x)
        shapes = {"rem_off": (r + 1,), "rem_open": (r,), "detail": (r, 6), "log_off": (r + 1,),
                  "ent_open": (n_ent,), "ent_off": (n_ent + 1,), "coarse_off": (n + 1,),
                  "coarse_open": (n,), "original_id": (n,)}
        problems = [f"{name} has shape {getattr(self, name).shape}, expected {shape}"
                    for name, shape in shapes.items() if getattr(self, name).shape != shape]
        if r >= n:
            problems.append(f"order removes {r} of the {n} points (at least one must stay)")
        if problems:
            raise _inconsistent("; ".join(problems))
        for off_name, values_name in self._CSR:
            off = getattr(self, off_name)
            size = len(getattr(self, values_name))
            if off[0] != 0:
                problems.append(f"{off_name} starts at {int(off[0])}, not 0")
            elif np.any(off[1:] < off[:-1]):
                i = _first(off[1:] < off[:-1])
                problems.append(f"{off_name} decreases at entry {i + 1} "
                                f"({int(off[i])} to {int(off[i + 1])})")
            elif off[-1] != size:
                problems.append(f"{off_name} ends at {int(off[-1])}, not at the length of "
                                f"{values_name} ({size})")
        for name in ("order", "rem_ring", "ent_x", "ent_ring", "coarse_ring"):
            arr = getattr(self, name)
            if len(arr) and (arr.min() < 0 or arr.max() >= n):
                i = _first((arr < 0) | (arr >= n))
                problems.append(f"{name} entry {i} is {int(arr[i])}, out of range for {n} points")
        if problems:
            raise _inconsistent("; ".join(problems))
        count = np.bincount(self.order, minlength=n)
        if np.any(count > 1):
            problems.append(f"order removes point {_first(count > 1)} more than once")
        for name, arr in (("detail", self.detail), ("source points", self.source.points),
                          ("source normals", self.source.normals),
                          ("weights", np.asarray(self.weights))):
            if not np.isfinite(arr).all():
                problems.append(f"{name} contain NaN or infinite values")
        if self.method not in METHODS:
            problems.append(f"method must be one of {sorted(METHODS)}, got {self.method!r}")
        if problems:
            raise _inconsistent("; ".join(problems))
        self._check_rings()

    def _check_rings(self):
        """Every ring names only points present when it is in use: a removed point's ring
        (and the rings its removal re-formed) points not removed before it, the coarsest
        level's rings its kept points; no ring names its own point."""
        n = self.n_points
        r = len(self.order)
        at = np.full(n, r, np.int64)  # when each point is removed (r: never)
        at[self.order] = np.arange(r)
        rem_sizes = np.diff(self.rem_off)
        if np.any(rem_sizes == 0):
            i = _first(rem_sizes == 0)
            raise _inconsistent(f"removal {i} (point {int(self.order[i])}) has an empty ring")
        removal = np.repeat(np.arange(r), rem_sizes)
        bad = at[self.rem_ring] <= removal
        if np.any(bad):
            i = int(removal[_first(bad)])
            raise _inconsistent(f"rem_ring of removal {i} names a point removed before it or "
                                "the removed point itself")
        removal = np.repeat(np.arange(r), np.diff(self.log_off))
        bad = at[self.ent_x] <= removal
        if np.any(bad):
            e = _first(bad)
            raise _inconsistent(f"ent_x entry {e} (removal {int(removal[e])}) names a point "
                                "removed by then")
        entry = np.repeat(np.arange(len(self.ent_x)), np.diff(self.ent_off))
        bad = (at[self.ent_ring] < removal[entry]) | (self.ent_ring == self.ent_x[entry])
        if np.any(bad):
            e = int(entry[_first(bad)])
            raise _inconsistent(f"ent_ring of entry {e} (removal {int(removal[e])}) names its "
                                "own point or a point removed before that removal")
        owner = np.repeat(np.arange(n), np.diff(self.coarse_off))
        kept = at == r
        bad = kept[owner] & (~kept[self.coarse_ring] | (self.coarse_ring == owner))
        if np.any(bad):
            p = int(owner[_first(bad)])
            raise _inconsistent(f"the coarsest level's ring of point {p} names a removed point "
                                "or the point itself")

    # -- sizes --------------------------------------------------------------
    @property
    def n_points(self) -> int:
        """Points of the finest level (the input)."""
        return self.source.n_points

    @property
    def n_min(self) -> int:
        """Points of the coarsest level computed."""
        return self.n_points - len(self.order)

    def __repr__(self) -> str:
        return (f"Hierarchy({self.n_points} points down to {self.n_min}, weights={self.weights}, "
                f"method={self.method!r})")

    def _check_level(self, n_points) -> int:
        if isinstance(n_points, bool) or not isinstance(n_points, numbers.Integral):
            raise ValueError(f"n_points must be an integer, got {n_points!r}")
        m = int(n_points)
        if not self.n_min <= m <= self.n_points:
            raise ValueError(
                f"level {m} is outside this hierarchy: it goes from {self.n_min} to "
                f"{self.n_points} points (build it further with hierarchy(..., n_points=...))"
            )
        return m

    # -- levels ---------------------------------------------------------------
    def _state(self, m: int):
        """Fan table, lengths, open flags and active mask of level m."""
        n = self.n_points
        width = max(int(np.diff(self.coarse_off).max(initial=0)),
                    int(np.diff(self.rem_off).max(initial=0)),
                    int(np.diff(self.ent_off).max(initial=0)), 1)
        none = np.zeros(0, np.int64)
        R, rlen = CsrK.table_from_csr(self.coarse_off, self.coarse_ring, none, none, width)
        ropen = self.coarse_open.copy()
        active = np.ones(n, bool)
        active[self.order] = False
        RK.undo(R, rlen, ropen, active, self.order, self.rem_off, self.rem_ring, self.rem_open,
                self.log_off, self.ent_x, self.ent_open, self.ent_off, self.ent_ring,
                len(self.order), n - m)
        return R, rlen, ropen, active

    def _base_positions(self, base):
        """(points, normals, level) with a coarser level's (edited) positions put in."""
        if not isinstance(base, FanCloud):
            raise TypeError(f"base must be a FanCloud (a level of this hierarchy), got "
                            f"{type(base).__name__}")
        base.validate()  # edited in place since: finite points and normals still
        ids = base.point_data.get(ORIGINAL_ID)
        if ids is None:
            raise ValueError(f"base has no {ORIGINAL_ID!r} point array: it must be a level of "
                             "this hierarchy (from level() or reduce())")
        m0 = base.n_points
        self._check_level(m0)
        n = self.n_points
        expected = np.ones(n, bool)
        expected[self.order[: n - m0]] = False
        index = self._positions(ids, expected)
        got = np.zeros(n, bool)
        got[index] = True
        if not np.array_equal(expected, got):
            raise ValueError(f"base's points are not the points of level {m0} of this hierarchy")
        pts = self.source.points.copy()
        nrm = self.source.normals.copy()
        pts[index] = base.points
        nrm[index] = base.normals
        return pts, nrm, m0

    def _positions(self, ids, active) -> np.ndarray:
        """Which points of the hierarchy a level's ``original_id`` array names: the level's
        points in order (inserted points, whose id is -1, are matched by position)."""
        ids = np.asarray(ids, dtype=np.int64)
        index = np.flatnonzero(active)
        if len(index) == len(ids) and np.array_equal(self.original_id[index], ids):
            return index
        return self._index_of(ids)

    def _index_of(self, ids) -> np.ndarray:
        ids = np.asarray(ids, dtype=np.int64)
        sorter = np.argsort(self.original_id, kind="stable")
        at = np.searchsorted(self.original_id, ids, sorter=sorter)
        at = np.clip(at, 0, len(sorter) - 1)
        index = sorter[at]
        if not np.array_equal(self.original_id[index], ids):
            raise ValueError(f"base has {ORIGINAL_ID} values that are not in this hierarchy")
        return index

    def level(self, n_points, base=None) -> FanCloud:
        """The fan cloud of the level with ``n_points`` points.

        Parameters
        ----------
        n_points : int
            Between :attr:`n_min` and :attr:`n_points`.
        base : FanCloud, optional
            A coarser level of this hierarchy (from :meth:`level`, with its
            ``original_id`` array), possibly edited (points moved, e.g.
            smoothed). Its points keep their positions and the points
            reinserted above it are placed by their detail in the local
            frames of the edited surface. Without ``base`` every point has
            its original position (``level(n_points)`` of the finest level
            gives back exactly the input points).

        Returns
        -------
        FanCloud
            Points in input order, with ``original_id``.

        Examples
        --------
        >>> import numpy as np
        >>> from fancloud_vtk import build_fans, hierarchy, laplacian_smooth
        >>> rng = np.random.default_rng(0)
        >>> p = rng.normal(size=(2000, 3))
        >>> p /= np.linalg.norm(p, axis=1)[:, None]
        >>> h = hierarchy(build_fans(p), 300)
        >>> coarse = h.level(300)
        >>> smooth = laplacian_smooth(coarse, 2)  # an edit of the coarse level
        >>> fine = h.level(2000, base=smooth)  # the detail put back on the edited surface
        >>> fine.n_points, bool(np.allclose(fine.points[coarse.point_data["original_id"]],
        ...                                 smooth.points))
        (2000, True)
        """
        m = self._check_level(n_points)
        if base is None:
            pts, nrm = self.source.points, self.source.normals
        else:
            pts, nrm, m0 = self._base_positions(base)
            if m < m0:
                raise ValueError(f"base has {m0} points: it cannot be refined to a coarser "
                                 f"level ({m})")
            n = self.n_points
            RK.place(pts, nrm, self.order, self.rem_off, self.rem_ring, self.detail, n - m0,
                     n - m, np.zeros(n, bool))
        R, rlen, ropen, active = self._state(m)
        return self._fan_cloud(pts, nrm, R, rlen, ropen, active)

    def details(self, fancloud: FanCloud) -> np.ndarray:
        """The local-frame detail of every removed point, measured on a full level.

        ``fancloud``: the finest level (all points, e.g. ``level(n_points,
        base=edited)``); returns ``(r, 3)``, row i for ``order[i]``: the
        offset of the point from the centroid of its ring at removal time, in
        that ring's frame (tangent, bitangent, normal). On the unedited
        input it equals ``detail[:, :3]``.
        """
        if not isinstance(fancloud, FanCloud) or fancloud.n_points != self.n_points:
            raise ValueError(f"details need the finest level ({self.n_points} points)")
        ids = fancloud.point_data.get(ORIGINAL_ID)
        index = np.arange(self.n_points) if ids is None else \
            self._positions(ids, np.ones(self.n_points, bool))
        pts = np.empty_like(self.source.points)
        nrm = np.empty_like(self.source.normals)
        pts[index] = fancloud.points
        nrm[index] = fancloud.normals
        return RK.measure_detail(pts, nrm, self.order, self.rem_off, self.rem_ring)

    def _fan_cloud(self, pts, nrm, R, rlen, ropen, active) -> FanCloud:
        ids, offsets, ring, ok = RK.compact_level(R, rlen, active)
        if not ok:
            raise RuntimeError("internal error: a fan of the level refers to a removed point")
        return level_of(pts, nrm, self.source.point_data, self.original_id,
                         self.source.rotated, ids, offsets, ring, ropen)

    def selective(self, region, base=None, start=None, *, k: int = 6, **fan_params) -> FanCloud:
        """Refine only a region of interest (paper section 6, Figure 11).

        All removed points are updated in reverse removal order (placed by
        their detail on the current, possibly edited, surface), but only
        those inside ``region`` are reinserted.

        Parameters
        ----------
        region : callable, numpy.ndarray, or sequence
            ``region(points) -> bool array`` on ``(m, 3)`` positions; or a
            bool mask over the input points; or box bounds
            ``(xmin, xmax, ymin, ymax, zmin, zmax)``; or a sphere
            ``(center, radius)``.
        base : FanCloud, optional
            The coarse level to start from (possibly edited), as in
            :meth:`level`.
        start : int, optional
            Without ``base``: the level to start from (default: the coarsest).
        k : int, default: 6
            Neighbours per fan of the result, whose fans are built anew
            (its mixed resolution is no level of the hierarchy).
        **fan_params
            The other parameters of :func:`~fancloud_vtk.build_fans` for
            those fans (``max_angle``, ``rule``, ...); not ``normals`` or
            ``point_data``, which come from the hierarchy.

        Returns
        -------
        FanCloud
            The coarse level's points plus the reinserted ones, with
            ``original_id``.

        Raises
        ------
        ValueError
            A region of none of these kinds; a mask or a callable's result of
            the wrong shape; a sphere with a radius <= 0 or a NaN or infinite
            centre or radius; box bounds with a NaN or a min > max (infinite
            bounds are allowed: an open box); both ``base`` and ``start``.

        Examples
        --------
        >>> import numpy as np
        >>> from fancloud_vtk import build_fans, hierarchy
        >>> rng = np.random.default_rng(0)
        >>> p = rng.normal(size=(2000, 3))
        >>> p /= np.linalg.norm(p, axis=1)[:, None]
        >>> h = hierarchy(build_fans(p), 300)
        >>> top = h.selective(([0.0, 0.0, 1.0], 0.5))  # a sphere region around the pole
        >>> inside = np.linalg.norm(p - [0, 0, 1], axis=1) <= 0.5
        >>> bool(np.isin(np.flatnonzero(inside), top.point_data["original_id"]).all())
        True
        >>> top.n_points == 300 + top.info["reinserted"]
        True
        """
        n = self.n_points
        if base is not None:
            if start is not None:
                raise ValueError("give base or start, not both")
            pts, nrm, m0 = self._base_positions(base)
            RK.place(pts, nrm, self.order, self.rem_off, self.rem_ring, self.detail, n - m0, 0,
                     np.zeros(n, bool))
        else:
            m0 = self.n_min if start is None else self._check_level(start)
            pts, nrm = self.source.points, self.source.normals
        removed = self.order[: n - m0]
        inside = _region_mask(region, pts, removed, n)
        active = np.ones(n, bool)
        active[removed] = False
        active[removed[inside]] = True
        ids = np.flatnonzero(active)
        pdata = {key: v[ids] for key, v in self.source.point_data.items()}
        pdata[ORIGINAL_ID] = self.original_id[ids]
        for name in ("normals", "point_data"):
            if name in fan_params:
                raise TypeError(f"selective() takes no {name}=: they come from the hierarchy")
        out = build_fans(pts[ids], k, normals=nrm[ids], point_data=pdata, **fan_params)
        out.info["reinserted"] = int(inside.sum())
        return out

    # -- saving -----------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays of :data:`HIERARCHY_ARRAYS` by name (not copies): with :attr:`source`,
        :attr:`weights` and :attr:`method`, what :meth:`from_arrays` takes back."""
        return {name: getattr(self, name) for name in HIERARCHY_ARRAYS}

    def save(self, path) -> None:
        """Write to ``.npz`` (numpy, no pickle); :meth:`load` reads it back.

        A ``.vtp`` file (the finest fan cloud plus field arrays
        ``hierarchy_<name>``) is written by :func:`fancloud_vtk.save`, which
        needs VTK; this core stays VTK-free.

        Parameters
        ----------
        path : str or os.PathLike
            Ends in ``.npz``.

        Raises
        ------
        ValueError
            Another extension (for ``.vtp``: use :func:`fancloud_vtk.save`),
            or a point array of Python objects.

        Examples
        --------
        >>> import os, tempfile
        >>> import numpy as np
        >>> from fancloud_vtk import Hierarchy, build_fans, hierarchy
        >>> rng = np.random.default_rng(0)
        >>> p = rng.normal(size=(2000, 3))
        >>> p /= np.linalg.norm(p, axis=1)[:, None]
        >>> h = hierarchy(build_fans(p), 300)
        >>> path = os.path.join(tempfile.mkdtemp(), "sphere_lod.npz")
        >>> h.save(path)
        >>> back = Hierarchy.load(path)
        >>> bool(np.array_equal(back.level(700).points, h.level(700).points))
        True
        """
        path = os.fspath(path)
        if isinstance(path, bytes):
            path = os.fsdecode(path)
        if path.lower().endswith(".npz"):
            arrays = {f"h_{k}": v for k, v in self.arrays().items()}
            fc = self.source
            arrays.update(points=fc.points, offsets=fc.offsets, ring=fc.ring,
                          normals=fc.normals, open=fc.open, rotated=fc.rotated,
                          weights=np.array(self.weights), method=np.array(self.method))
            for key, v in fc.point_data.items():
                if v.dtype == object:
                    raise ValueError(f"point array {key!r} holds Python objects: not saved")
                arrays[f"pd_{key}"] = v
            np.savez_compressed(path, **arrays)
        elif path.lower().endswith(".vtp"):
            raise ValueError(f"Hierarchy.save writes .npz only; for {path!r} use "
                             "fancloud_vtk.save(hierarchy, path), which writes .vtp with VTK")
        else:
            raise ValueError(f"a hierarchy is saved as .npz (Hierarchy.save) or .vtp "
                             f"(fancloud_vtk.save), got {path!r}")

    @classmethod
    def load(cls, path) -> Hierarchy:
        """Read a hierarchy written by :meth:`save` (``.npz``).

        A ``.vtp`` file is read by :func:`fancloud_vtk.load`.

        Parameters
        ----------
        path : str or os.PathLike
            A ``.npz`` file.

        Returns
        -------
        Hierarchy

        Raises
        ------
        ValueError
            A path that does not end in ``.npz`` (for ``.vtp``: use
            :func:`fancloud_vtk.load`).
        fancloud_vtk.io.FileReadError
            (a ``ValueError``) naming the path: the file is missing (then the
            error is also a ``FileNotFoundError``), a directory, empty,
            unreadable or damaged, not a saved hierarchy, or its arrays are
            inconsistent (``inconsistent hierarchy: ...``).
        """
        path = os.fspath(path)
        if isinstance(path, bytes):
            path = os.fsdecode(path)
        lower = path.lower()
        if lower.endswith(".vtp"):
            raise ValueError(f"Hierarchy.load reads .npz only; for {path!r} use "
                             "fancloud_vtk.load(path), which reads .vtp with VTK")
        if not lower.endswith(".npz"):
            raise ValueError(f"a hierarchy is read from .npz (Hierarchy.load) or .vtp "
                             f"(fancloud_vtk.load), got {path!r}")
        return cls._from_npz(readable_file(path))

    @classmethod
    def _from_npz(cls, path: str) -> Hierarchy:
        # our own file object: np.load leaves its own open when the archive is bad
        with open(path, "rb") as fh:
            try:
                z = np.load(fh, allow_pickle=False)
            except Exception as exc:  # OSError, ValueError, EOFError, zipfile.BadZipFile...
                raise FileReadError(path, f"not a readable .npz file ({type(exc).__name__}: "
                                          f"{exc})") from exc
            if not hasattr(z, "files"):  # a single .npy array under an .npz name
                raise FileReadError(path, "not an .npz archive (a single .npy array)")
            try:
                with z:
                    data = {k: z[k] for k in z.files}
            except Exception as exc:  # a damaged member: BadZipFile, zlib.error, ValueError...
                raise FileReadError(path, f"a damaged .npz archive ({type(exc).__name__}: "
                                          f"{exc})") from exc
        needed = ("points", "offsets", "ring", "normals", "open", "rotated", "weights",
                  "method", *(f"h_{k}" for k in HIERARCHY_ARRAYS))
        missing = [k for k in needed if k not in data]
        if missing:
            more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
            raise FileReadError(path, f"not a saved hierarchy (Hierarchy.save): no array "
                                      f"{missing[0]!r}{more}")
        try:
            pdata = {k[3:]: v for k, v in data.items() if k.startswith("pd_")}
            fc = FanCloud(data["points"], data["offsets"], data["ring"], data["normals"],
                          data["open"], data["rotated"], pdata)
            h = {k[2:]: v for k, v in data.items() if k.startswith("h_")}
            weights = np.asarray(data["weights"], np.float64).reshape(-1)
            return cls.from_arrays(fc, h, tuple(weights), str(data["method"]))
        except (TypeError, ValueError) as exc:
            raise FileReadError(path, str(exc)) from exc

    @classmethod
    def from_arrays(cls, source: FanCloud, arrays: dict, weights, method) -> Hierarchy:
        """A hierarchy from its source fan cloud and the arrays of :meth:`arrays`.

        Raises ``ValueError`` (``inconsistent hierarchy: ...``, naming the
        array and the problem) unless the arrays fit together.
        """
        missing = [k for k in HIERARCHY_ARRAYS if k not in arrays]
        if missing:
            raise ValueError(f"hierarchy arrays missing: {missing}")
        original = _ints(arrays["original_id"], "original_id")
        src = FanCloud(source.points, source.offsets, source.ring, source.normals, source.open,
                       source.rotated, {**source.point_data, ORIGINAL_ID: original})
        kw = {k: arrays[k] for k in HIERARCHY_ARRAYS if k != "original_id"}
        detail = np.asarray(kw["detail"])
        if detail.size % 6 == 0:
            kw["detail"] = detail.reshape(-1, 6)
        return cls(source=src, weights=weights, method=method, **kw)


def _region_mask(region, pts, removed, n) -> np.ndarray:
    """Which of the ``removed`` points lie in the region."""
    if callable(region):
        got = np.asarray(region(pts[removed].copy()))
        if got.shape != (len(removed),) or got.dtype != bool:
            raise ValueError(
                f"region(points) must return one bool per point ({len(removed)}), got "
                f"{got.dtype} {got.shape}"
            )
        return got
    if isinstance(region, np.ndarray) and region.dtype == bool:
        if region.shape != (n,):
            raise ValueError(f"a region mask must have one bool per input point ({n}), got "
                             f"shape {region.shape}")
        return region[removed]
    if isinstance(region, (tuple, list)) and len(region) == 2:
        center = np.asarray(region[0], dtype=np.float64)
        radius = float(region[1])
        if center.shape != (3,) or not radius > 0:
            raise ValueError("a sphere region is (center (3 numbers), radius > 0)")
        if not np.isfinite(center).all():
            raise ValueError(f"a sphere region's center must be finite, got {center.tolist()}")
        if not np.isfinite(radius):
            raise ValueError(f"a sphere region's radius must be finite, got {radius}")
        return np.linalg.norm(pts[removed] - center, axis=1) <= radius
    box = np.asarray(region, dtype=np.float64) if isinstance(region, (tuple, list, np.ndarray)) \
        else None
    if box is not None and box.shape == (6,):
        if np.isnan(box).any():
            raise ValueError(f"region bounds must be numbers, got NaN: {box.tolist()}")
        if np.any(box[0::2] > box[1::2]):
            raise ValueError(f"region bounds must be (xmin, xmax, ymin, ymax, zmin, zmax) with "
                             f"min <= max, got {box.tolist()}")
        p = pts[removed]
        return ((p[:, 0] >= box[0]) & (p[:, 0] <= box[1]) & (p[:, 1] >= box[2])
                & (p[:, 1] <= box[3]) & (p[:, 2] >= box[4]) & (p[:, 2] <= box[5]))
    raise ValueError(
        "region must be a callable on (m, 3) positions, a bool mask over the input points, "
        "box bounds (xmin, xmax, ymin, ymax, zmin, zmax) or a sphere (center, radius)"
    )


def stacked(upper: Hierarchy, lower: Hierarchy) -> Hierarchy:
    """One hierarchy from ``upper`` (whose coarsest level is ``lower``'s finest, its extra
    points appended) and ``lower``: upper's removals first, then lower's
    (:func:`~fancloud_vtk.refine_hierarchy`)."""
    n, n_low = upper.n_points, lower.n_points
    m = n - n_low

    def cat(a, b, shift=None):
        return np.concatenate([a, b if shift is None else b[1:] + shift])

    coarse_off = np.concatenate([lower.coarse_off,
                                 np.full(m, lower.coarse_off[-1], np.int64)])
    src = upper.source
    source = FanCloud(src.points, src.offsets, src.ring, src.normals, src.open, src.rotated,
                      {**src.point_data, ORIGINAL_ID: upper.original_id})
    return Hierarchy(
        source=source,
        order=cat(upper.order, lower.order),
        rem_off=cat(upper.rem_off, lower.rem_off, upper.rem_off[-1]),
        rem_ring=cat(upper.rem_ring, lower.rem_ring.astype(upper.rem_ring.dtype)),
        rem_open=cat(upper.rem_open, lower.rem_open),
        detail=cat(upper.detail, lower.detail),
        log_off=cat(upper.log_off, lower.log_off, upper.log_off[-1]),
        ent_x=cat(upper.ent_x, lower.ent_x.astype(upper.ent_x.dtype)),
        ent_open=cat(upper.ent_open, lower.ent_open),
        ent_off=cat(upper.ent_off, lower.ent_off, upper.ent_off[-1]),
        ent_ring=cat(upper.ent_ring, lower.ent_ring.astype(upper.ent_ring.dtype)),
        coarse_off=coarse_off,
        coarse_ring=lower.coarse_ring,
        coarse_open=np.concatenate([lower.coarse_open, np.zeros(m, bool)]),
        weights=lower.weights,
        method=lower.method,
    )
