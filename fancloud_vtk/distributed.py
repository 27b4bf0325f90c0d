"""Fan clouds in tiles: the fans of a large cloud built tile by tile, on Dask.

A fan depends only on the points near it (paper section 1). :func:`tiled_fans` cuts the
bounding box into tiles, builds the fans of each tile's points together with a *halo* of
the points around the tile, keeps the fans of the points the tile owns and stitches them;
the normals are then oriented over the whole cloud, as :func:`~fancloud_vtk.build_fans`
orients them. The result is the fan cloud ``build_fans`` gives, ring for ring, normal for
normal (tested bit for bit).

The halo is wide enough when every owned point's fan looked only at points inside the
tile's box grown by the halo. A fan looks at its point's nearest neighbours (the normal
at the ``2k`` nearest, the fan at its ring and the candidates before them) and at the
local spacing of its candidates (their own nearest). An owned point is *certified* when
its distance to the nearest face of the grown box (faces on the cloud's bounding box do
not count: nothing lies beyond them) is at least :data:`MARGIN` times its fan's radius,
:data:`OPEN_MARGIN` times for an open fan (its gap-directed search looks across the
gap). The radius: the larger of its farthest ring neighbour and a bound of its ``2k``-th
nearest neighbour's distance (the ``2k``-th nearest point of its two rings; any ``2k``
points are no nearer than the ``2k`` nearest). A tile with a point that is not certified
is built again with its halo grown to what that point needs (at least doubled), until
every point is certified or the grown box holds the whole cloud.

Tiles run as Dask tasks (``scheduler``: a Dask scheduler name such as ``"threads"`` or
``"sync"``, a ``dask.distributed.Client``, or a scheduler address). On a client each
tile's points travel inside its task, so that the scheduler can run a tile again on
another worker when one dies. Dask is an optional dependency:
``pip install "fancloud-vtk[distributed]"``.
"""

from __future__ import annotations

import time
import warnings

import numba
import numpy as np
from scipy.spatial import cKDTree

from .core import _ring_kernels as RingK
from .core import fans as _F
from .core.model import FanCloud
from .core.validation import FanCloudInputError, as_points, check_point_data, check_spread

__all__ = ["MARGIN", "OPEN_MARGIN", "tile_boxes", "tiled_fans"]

#: an owned point is certified when the grown box reaches this many times its fan's
#: radius beyond it (the radius: the farther of its farthest ring neighbour and a bound
#: of its ``2k``-th nearest neighbour's distance)
MARGIN = 3.0
#: the same for an open fan (its gap-directed search reaches farther)
OPEN_MARGIN = 6.0
#: points sampled for the default halo width
_HALO_SAMPLE = 20_000


def tile_boxes(points, tiles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tiles of the points' bounding box and the tile that owns each point.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        The points.
    tiles : tuple of 3 int
        Tiles along x, y and z (each at least 1).

    Returns
    -------
    lo, hi : numpy.ndarray, shape (m, 3)
        The tiles' boxes, ``m = tiles[0] * tiles[1] * tiles[2]``, in Morton order (the
        bits of the tile's x, y and z numbers interleaved), so that consecutive tiles are
        near each other.
    owner : numpy.ndarray, shape (n,)
        The number of the tile that owns each point (its box holds the point; a point on
        a face between two boxes belongs to the upper one).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.distributed import tile_boxes
    >>> lo, hi, owner = tile_boxes(np.random.default_rng(0).random((1000, 3)), (2, 2, 1))
    >>> lo.shape, np.bincount(owner).sum()
    ((4, 3), np.int64(1000))
    """
    pts = as_points(points)
    t = _check_tiles(tiles)
    blo, bhi = pts.min(axis=0), pts.max(axis=0)
    span = np.where(bhi > blo, bhi - blo, 1.0)
    cell = np.minimum(np.floor((pts - blo) / span * t).astype(np.int64), t - 1)
    ijk = np.array([(i, j, m) for i in range(t[0]) for j in range(t[1]) for m in range(t[2])],
                   np.int64).reshape(-1, 3)
    rank = np.argsort(_morton(ijk), kind="stable")
    ijk = ijk[rank]
    number = np.empty(t, np.int64)
    number[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = np.arange(len(ijk))
    lo = blo + span * ijk / t
    hi = blo + span * (ijk + 1) / t
    hi = np.where(ijk + 1 == t, bhi, hi)
    return lo, hi, number[cell[:, 0], cell[:, 1], cell[:, 2]]


def tiled_fans(
    points,
    k: int = 6,
    *,
    tiles=(2, 2, 2),
    halo: float | None = None,
    scheduler="threads",
    max_angle: float = 90.0,
    max_replacements: int = 42,
    rule: str = "cover",
    rotate_sharp_edges: bool = True,
    reach: float = 5.0,
    separate_sheets: bool = False,
    orient: bool = True,
    point_data=None,
) -> FanCloud:
    """The fan cloud of a point cloud, built in tiles with halos as Dask tasks.

    The same fan cloud as :func:`fancloud_vtk.build_fans` with the same parameters: each
    tile builds the fans of its points and of a halo around it, keeps those of its own
    points, and the normals are oriented over the whole cloud afterwards (see the module
    docstring for the halo rule).

    Parameters
    ----------
    points : array_like, shape (n, 3)
        The points (finite, distinct: duplicate points are refused here, while
        ``build_fans`` merges them).
    k : int, default: 6
        Neighbours per fan, as in ``build_fans``.
    tiles : tuple of 3 int, default: (2, 2, 2)
        Tiles along x, y and z.
    halo : float, optional
        The starting halo width, in the points' units (default: ``3 * MARGIN`` times the
        median distance of a point's ``2k``-th nearest neighbour, from a sample). A tile
        whose points need more grows it (the widths used are in ``info['halos']``).
    scheduler : str or dask.distributed.Client, default: "threads"
        Where the tiles run: a Dask scheduler name (``"threads"``, ``"sync"``,
        ``"processes"``), a ``dask.distributed.Client`` (a ``LocalCluster``'s or a real
        cluster's), or a scheduler address such as ``"tcp://10.0.0.1:8786"``.
    max_angle, max_replacements, rule, rotate_sharp_edges, reach, separate_sheets, orient, \
point_data
        As in ``build_fans``.

    Returns
    -------
    FanCloud
        ``info`` holds ``tiles``, ``halos`` (per tile, the width it ended with),
        ``tile_points`` (per tile, owned and built), ``rebuilt`` (tiles built again with a
        wider halo) and ``timings``.

    Raises
    ------
    ImportError
        Dask is not installed.
    FanCloudInputError
        Bad points (as ``build_fans``), duplicate points or bad ``tiles`` / ``halo``.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans
    >>> from fancloud_vtk.distributed import tiled_fans
    >>> p = np.random.default_rng(0).normal(size=(20000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> fc = tiled_fans(p, tiles=(2, 2, 1), scheduler="sync")
    >>> one = build_fans(p)
    >>> bool(np.array_equal(fc.ring, one.ring) and np.array_equal(fc.normals, one.normals))
    True
    """
    try:
        import dask
    except ImportError as exc:  # pragma: no cover - the test extra installs it
        raise ImportError('tiled_fans needs Dask: pip install "fancloud-vtk[distributed]"') \
            from exc
    k, max_angle, max_replacements, rule_id = _F._check_parameters(
        k, max_angle, max_replacements, rule)
    reach = _F._check_reach(reach)
    for name, flag in (("separate_sheets", separate_sheets), ("orient", orient),
                       ("rotate_sharp_edges", rotate_sharp_edges)):
        if not isinstance(flag, bool | np.bool_):
            raise TypeError(f"{name} must be True or False, got {flag!r}")
    pts = as_points(points)
    n = len(pts)
    pdata = check_point_data(point_data, n)
    _F._check_size(n, k)
    check_spread(pts)
    t_all = time.perf_counter()
    grid = _F.Grid(pts)  # the spatial order of the orientation, and the duplicates
    n_dup = grid.n_dup
    if n_dup:
        raise FanCloudInputError(
            f"{n_dup:,} duplicate point(s): tiled_fans needs "
            "distinct points (build_fans merges them; merge them first, e.g. with "
            "numpy.unique(points, axis=0))")
    lo, hi, owner = tile_boxes(pts, tiles)
    blo, bhi = pts.min(axis=0), pts.max(axis=0)
    start = _auto_halo(pts, k) if halo is None else _check_halo(halo)
    options = (k, max_angle, max_replacements, rule, rule_id, bool(rotate_sharp_edges), reach,
               bool(separate_sheets))
    owned = [np.flatnonzero(owner == t) for t in range(len(lo))]
    widths = np.full(len(lo), start)
    results: list = [None] * len(lo)
    built = np.zeros(len(lo), np.int64)
    rebuilt = 0
    todo = [t for t in range(len(lo)) if len(owned[t])]
    t0 = time.perf_counter()
    while todo:
        jobs = []
        for t in todo:
            ids = _grown(pts, lo[t], hi[t], widths[t])
            while len(ids) < min(n, 4 * (k + 1)):  # too few to make fans: a wider halo
                widths[t] = max(2.0 * widths[t], 1e-9 * float(np.abs(bhi - blo).max()))
                ids = _grown(pts, lo[t], hi[t], widths[t])
            built[t] = len(ids)
            jobs.append((pts[ids], ids, owned[t], lo[t], hi[t], widths[t], blo, bhi, options))
        out = _run_tiles(dask, jobs, scheduler)
        again = []
        for t, res in zip(todo, out, strict=True):
            need = res[-1]
            if need > widths[t] and built[t] < n:
                widths[t] = max(2.0 * widths[t], need)
                again.append(t)
            else:
                results[t] = res
        rebuilt += len(again)
        todo = again
    timings = {"tiles": time.perf_counter() - t0}

    # stitch: every point's fan from the tile that owns it
    t0 = time.perf_counter()
    sizes = np.zeros(n, np.int64)
    normals = np.empty((n, 3))
    is_open = np.zeros(n, bool)
    rotated = np.zeros(n, bool)
    no_plane = np.zeros(n, bool)
    for res in results:
        if res is None:
            continue
        ids, s, _, nrm, op, rot, npl, _ = res
        sizes[ids] = s
        normals[ids] = nrm
        is_open[ids] = op
        rotated[ids] = rot
        no_plane[ids] = npl
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(sizes, out=offsets[1:])
    ring = np.empty(offsets[-1], np.int64)
    for res in results:
        if res is None:
            continue
        ids, s, r = res[0], res[1], res[2]
        dst = np.repeat(offsets[ids], s) + (np.arange(len(r)) - np.repeat(np.cumsum(s) - s, s))
        ring[dst] = r
    info = {"k": k, "rule": rule, "max_angle": max_angle,
            "max_replacements": max_replacements, "reach": reach,
            "separate_sheets": bool(separate_sheets), "fans_open": int(is_open.sum()),
            "fans_rotated": int(rotated.sum()), "duplicates_merged": 0,
            "tiles": tuple(int(x) for x in _check_tiles(tiles)),
            "halos": widths.tolist(), "tile_points": [(len(o), int(b)) for o, b in
                                                       zip(owned, built, strict=True)],
            "rebuilt": rebuilt}
    fc = FanCloud(pts, offsets, ring, normals, is_open, rotated, pdata, info)
    timings["stitch"] = time.perf_counter() - t0
    if orient:
        t0 = time.perf_counter()
        fc = _F._orient_fans(fc, no_plane, grid)
        timings["orientation"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    fc.info["timings"] = timings
    return fc


def _tile(sub, ids, own, lo, hi, width, blo, bhi, options):
    """One tile's task: the fans of ``sub`` (the points ``ids``, sorted), those of the
    owned points ``own`` (global, sorted) kept. Returns (own, sizes, ring (global), normals,
    open, rotated, no_plane, halo needed)."""
    k, max_angle, max_replacements, rule, rule_id, rotate, reach, sheets = options
    fc, no_plane = _F._fans(sub, k, max_angle, max_replacements, rule, rule_id, rotate, reach,
                            sheets, None, False, {}, 1, None)
    loc = np.searchsorted(ids, own)
    sizes = np.diff(fc.offsets)[loc]
    take = np.repeat(fc.offsets[loc], sizes) + (
        np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes))
    ring = ids[fc.ring[take]]
    # the radius each owned fan looked at, and the halo that radius needs: its farthest
    # fan neighbour and (a bound of) its 2k-th nearest point, from its two rings; where
    # the two rings are too few, the exact 2k-th nearest
    p = sub[loc]
    far, near = RingK.fan_radii(sub, fc.offsets, fc.ring, loc, min(2 * k, len(sub) - 1),
                                2 * numba.get_num_threads())
    few = near < 0
    if few.any():
        kq = min(2 * k + 1, len(sub))
        d = cKDTree(sub).query(p[few], k=kq)[0]
        near[few] = d[:, -1] if d.ndim == 2 else d
    radius = np.maximum(far, near)
    factor = np.where(fc.open[loc], OPEN_MARGIN, MARGIN)
    need = factor * radius
    # room: to the grown box's faces that are not the cloud's bounding box's
    glo, ghi = lo - width, hi + width
    room_lo = np.where(glo > blo, p - glo, np.inf)
    room_hi = np.where(ghi < bhi, ghi - p, np.inf)
    room = np.minimum(room_lo, room_hi).min(axis=1)
    short = need > room
    needed = 0.0
    if short.any():
        # the halo that gives the shortest point its room
        to_lo = np.where(glo > blo, p - lo, np.inf)
        to_hi = np.where(ghi < bhi, hi - p, np.inf)
        inner = np.minimum(to_lo, to_hi).min(axis=1)
        needed = float((need - inner)[short].max())
    return (own, sizes, ring, fc.normals[loc], fc.open[loc], fc.rotated[loc], no_plane[loc],
            needed)


def _run_tiles(dask, jobs, scheduler) -> list:
    """``_tile(*job)`` for every job, on the scheduler; the results in order."""
    if isinstance(scheduler, str) and "://" in scheduler:
        from dask.distributed import Client

        with Client(scheduler) as client:
            return _on_client(client, jobs)
    if isinstance(scheduler, str):
        return list(dask.compute(*[dask.delayed(_tile, pure=False)(*job) for job in jobs],
                                 scheduler=scheduler))
    if all(hasattr(scheduler, name) for name in ("compute", "gather")):
        return _on_client(scheduler, jobs)
    raise TypeError("scheduler must be a Dask scheduler name, a scheduler address or a "
                    f"dask.distributed.Client, got {scheduler!r}")


def _on_client(client, jobs) -> list:
    """The tiles on a ``dask.distributed`` client, each tile's points inside its task: the
    scheduler keeps them, so a task whose worker dies runs again on another (points
    scattered to a worker would die with it). Dask's advice against large graphs is
    silenced here for that reason."""
    import dask

    tasks = [dask.delayed(_tile, pure=False)(*job) for job in jobs]
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Sending large graph", category=UserWarning)
        futures = client.compute(tasks)
    return client.gather(futures)


def _grown(pts, lo, hi, width):
    """The indices (sorted) of the points in the box [lo - width, hi + width]."""
    inside = np.all((pts >= lo - width) & (pts <= hi + width), axis=1)
    return np.flatnonzero(inside)


def _auto_halo(pts, k) -> float:
    """``3 * MARGIN`` times the median distance of the ``2k``-th nearest neighbour, from
    a sample (a random subset's distances scaled to the whole cloud's density on a
    surface)."""
    n = len(pts)
    m = min(n, _HALO_SAMPLE)
    sub = pts if m == n else pts[np.random.default_rng(0).choice(n, m, replace=False)]
    d = cKDTree(sub).query(sub[: min(m, 2000)], k=min(2 * k + 1, m))[0][:, -1]
    return float(3.0 * MARGIN * np.median(d) * np.sqrt(m / n))


def _check_tiles(tiles) -> np.ndarray:
    t = np.asarray(tiles)
    if t.shape != (3,) or t.dtype.kind not in "iu" or (t < 1).any():
        raise FanCloudInputError(f"tiles must be 3 integers of at least 1, got {tiles!r}")
    return t.astype(np.int64)


def _check_halo(halo) -> float:
    if isinstance(halo, bool) or not isinstance(halo, int | float | np.number):
        raise TypeError(f"halo must be a number, got {halo!r}")
    halo = float(halo)
    if not (np.isfinite(halo) and halo >= 0.0):
        raise FanCloudInputError(f"halo must be a finite width of at least 0, got {halo}")
    return halo


def _morton(ijk) -> np.ndarray:
    """Morton codes of small non-negative integer triples (21 bits each)."""
    code = np.zeros(len(ijk), np.int64)
    for bit in range(21):
        for axis in range(3):
            code |= ((ijk[:, axis] >> bit) & 1) << (3 * bit + axis)
    return code
