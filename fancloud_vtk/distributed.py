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
from .core.mesh import TriangleMesh
from .core.model import FanCloud
from .core.validation import FanCloudInputError, as_points, check_point_data, check_spread

__all__ = ["BAND", "MARGIN", "MESH_HALO", "OPEN_MARGIN", "read_tiles", "tile_boxes", "tiled_fans",
           "tiled_mesh", "tiled_reduce", "tiled_vdfc", "write_tiled_fans"]

#: an owned point is certified when the grown box reaches this many times its fan's
#: radius beyond it (the radius: the farther of its farthest ring neighbour and a bound
#: of its ``2k``-th nearest neighbour's distance)
MARGIN = 3.0
#: the same for an open fan (its gap-directed search reaches farther)
OPEN_MARGIN = 6.0
#: points sampled for the default halo width
_HALO_SAMPLE = 20_000


def _dask(name: str):
    """The ``dask`` module, or an ImportError saying that ``name`` needs it (an optional
    dependency)."""
    try:
        import dask
    except ImportError as exc:  # pragma: no cover - the test extra installs it
        raise ImportError(f'{name} needs Dask: pip install "fancloud-vtk[distributed]"') \
            from exc
    return dask


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
        The points (finite). Duplicate points are merged as ``build_fans`` merges them
        (the first of each set kept, a ``DuplicatePointsWarning``, the point array
        ``original_id``).
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
        Bad points (as ``build_fans``) or bad ``tiles`` / ``halo``.

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
    dask = _dask("tiled_fans")
    k, max_angle, max_replacements, rule_id, reach = _check_fan_options(
        k, max_angle, max_replacements, rule, reach, separate_sheets=separate_sheets,
        orient=orient, rotate_sharp_edges=rotate_sharp_edges)
    pts = as_points(points)
    n = len(pts)
    pdata = check_point_data(point_data, n)
    _F._check_size(n, k)
    check_spread(pts)
    t_all = time.perf_counter()
    grid = _F.Grid(pts)  # the spatial order of the orientation, and the duplicates
    if grid.n_dup:  # merged as build_fans merges them: the first of each kept
        keep = _F.first_of_duplicates(pts, stacklevel=2)
        sub = {name: arr[keep] for name, arr in pdata.items()}
        sub["original_id"] = keep.astype(np.int64)
        fc = tiled_fans(pts[keep], k, tiles=tiles, halo=halo, scheduler=scheduler,
                        max_angle=max_angle, max_replacements=max_replacements, rule=rule,
                        rotate_sharp_edges=rotate_sharp_edges, reach=reach,
                        separate_sheets=separate_sheets, orient=orient, point_data=sub)
        fc.info["duplicates_merged"] = n - len(keep)
        return fc
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
            jobs.append((pts[ids], ids, owned[t], lo[t], hi[t], widths[t], blo, bhi, options,
                         (grid.lo, grid.h)))
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
        dst = _positions(offsets[ids], s)
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


def _tile(sub, ids, own, lo, hi, width, blo, bhi, options, cells=None):
    """One tile's task: the fans of ``sub`` (the points ``ids``, sorted), those of the
    owned points ``own`` (global, sorted) kept. Returns (own, sizes, ring (global), normals,
    open, rotated, no_plane, halo needed). ``cells``: the whole cloud's grid (lo, h), whose
    order breaks ties between equal distances (:func:`~fancloud_vtk.core.fans._fans`)."""
    k, max_angle, max_replacements, rule, rule_id, rotate, reach, sheets = options
    fc, no_plane = _F._fans(sub, k, max_angle, max_replacements, rule, rule_id, rotate, reach,
                            sheets, None, False, {}, 1, None, cells)
    loc = np.searchsorted(ids, own)
    sizes = np.diff(fc.offsets)[loc]
    take = _positions(fc.offsets[loc], sizes)
    ring = ids[fc.ring[take]]
    # the halo the owned fans need (see _halo_needed)
    needed = _halo_needed(sub, fc, loc, lo, hi, width, blo, bhi, k)
    return (own, sizes, ring, fc.normals[loc], fc.open[loc], fc.rotated[loc], no_plane[loc],
            needed)


def _run_tiles(dask, jobs, scheduler, fn=None) -> list:
    """``fn(*job)`` (default :func:`_tile`) for every job, on the scheduler; the results in
    order."""
    fn = _tile if fn is None else fn
    if isinstance(scheduler, str) and "://" in scheduler:
        from dask.distributed import Client

        with Client(scheduler) as client:
            return _on_client(client, jobs, fn)
    if isinstance(scheduler, str):
        return list(dask.compute(*[dask.delayed(fn, pure=False)(*job) for job in jobs],
                                 scheduler=scheduler))
    if all(hasattr(scheduler, name) for name in ("compute", "gather")):
        return _on_client(scheduler, jobs, fn)
    raise TypeError("scheduler must be a Dask scheduler name, a scheduler address or a "
                    f"dask.distributed.Client, got {scheduler!r}")


def _on_client(client, jobs, fn) -> list:
    """The tiles on a ``dask.distributed`` client, each tile's points inside its task: the
    scheduler keeps them, so a task whose worker dies runs again on another (points
    scattered to a worker would die with it). Dask's advice against large graphs is
    silenced here for that reason."""
    import dask

    tasks = [dask.delayed(fn, pure=False)(*job) for job in jobs]
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Sending large graph", category=UserWarning)
        futures = client.compute(tasks)
    return client.gather(futures)


def _positions(starts, sizes) -> np.ndarray:
    """The CSR positions of runs: ``starts[i] + 0 .. sizes[i] - 1`` for every run, in order
    (where a fan's ring entries are read from, or written to)."""
    return np.repeat(starts, sizes) + (np.arange(int(sizes.sum()))
                                       - np.repeat(np.cumsum(sizes) - sizes, sizes))


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


def _check_fan_options(k, max_angle, max_replacements, rule, reach, **flags):
    """The fans' parameters checked as build_fans checks them: (k, max_angle,
    max_replacements, rule_id, reach); ``flags``: named booleans."""
    k, max_angle, max_replacements, rule_id = _F._check_parameters(
        k, max_angle, max_replacements, rule)
    reach = _F._check_reach(reach)
    for name, flag in flags.items():
        if not isinstance(flag, bool | np.bool_):
            raise TypeError(f"{name} must be True or False, got {flag!r}")
    return k, max_angle, max_replacements, rule_id, reach


def _check_tile_points(tile_points) -> int:
    if isinstance(tile_points, bool) or not isinstance(tile_points, int | np.integer) \
            or tile_points < 1000:
        raise FanCloudInputError(f"tile_points must be an integer of at least 1000, got "
                                 f"{tile_points!r}")
    return int(tile_points)


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


# ----------------------------------------------------------------------------- out of core

#: the name of a tiled fan cloud's index (a JSON file) in its folder
INDEX_NAME = "index.json"
#: the partitioned dataset (VTK's ``.vtpd``) listing the tiles' files, for ParaView
VTPD_NAME = "fans.vtpd"
#: points of a tile's halo (and of its owned points) whose normals are compared across
#: tiles: those whose global id hashes to 0 modulo this
_SAMPLE_MODULUS = 64
_WORK = ".work"
#: a tile file's point array: 1 where the fan's normal and ring were turned from the way
#: the fan was built (by the tile's orientation and the agreement between tiles);
#: :func:`read_tiles` turns them back before orienting the whole cloud as build_fans does
FAN_FLIPPED = "fan_flipped"


#: the mesh's halo, by default: this many times the fans' default halo (the growing and
#: the hole closing look a few rings further than a fan does; see :func:`tiled_mesh`)
MESH_HALO = 2.0
#: the band around a tile's box whose triangles its owners must have made the same, as a
#: fraction of the tile's halo
BAND = 0.1


def tiled_mesh(
    points,
    k: int = 6,
    *,
    tiles=(2, 2, 2),
    halo: float | None = None,
    scheduler="threads",
    rings: str = "auto",
    close_holes: bool = True,
    max_hole: int = 32,
    max_hole_diameter: float = 6.0,
    remove_self_intersections: bool = True,
    min_component: int = 20,
    self_intersections: bool = True,
    max_angle: float = 90.0,
    max_replacements: int = 42,
    rule: str = "cover",
    rotate_sharp_edges: bool = True,
    reach: float = 5.0,
    separate_sheets: bool = False,
    point_data=None,
) -> TriangleMesh:
    """The mesh of a point cloud (section 4), grown in tiles with halos as Dask tasks.

    The triangles (each the same way round), normals and outliers of
    ``fan_cloud_to_mesh(build_fans(points))`` with the same parameters, in another order,
    wherever the mesh's stages decide from what lies near; see "Not the same" below. The
    fans are built by :func:`tiled_fans`. The mesh's normals are then oriented again over
    the whole cloud (which way the fans run the triangles they share: a vote over each
    connected piece). Each tile then builds the fans of its points and of a halo ``halo``
    wide around them, and grows, closes and cleans their mesh as the whole cloud's is:
    in the whole cloud's spatial order, which breaks the ties. A triangle is kept by the
    tile that owns its lowest-numbered point. The outliers (small stray pieces), the
    choice of ``rings='auto'``, the checks and the turning of closed pieces outward look
    at the whole mesh, and are done on the stitched triangles.

    No bound on how far a decision reaches is proved: every tile therefore also returns
    its triangles in a band around its box (:data:`BAND` times the halo wide), which the
    tiles owning them must have made the same; where they did not, those tiles are built
    again with their halos doubled (``stats['rebuilt']``), until they agree or a halo
    holds the whole cloud.

    Not the same: two stages of the clean-up choose by a count over the whole mesh. The
    filling rounds keep the round that leaves the fewest boundary edges and unused points
    in all, and the self-intersection rounds step back when a refill made more crossing
    pairs in all. A tile counts over its own points and halo, and may choose another
    round; the triangles that round changed then differ from the one-process mesh, inside
    the tile (where the band check does not look). Seen in the tests: 4 of 60,000
    triangles on a torus of 30,000 points in 2x2x1 tiles; none on the other clouds. The
    stitched mesh's checks (``stats``) are those of the mesh returned.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        The points (finite); duplicates are merged as ``build_fans`` merges them.
    k : int, default: 6
        Neighbours per fan.
    tiles : tuple of 3 int, default: (2, 2, 2)
        Tiles along x, y and z.
    halo : float, optional
        Width of the mesh's halo around each tile, in the points' units. Default:
        :data:`MESH_HALO` times the halo the tile's fans needed in :func:`tiled_fans` (at
        least their default halo: about 40 point spacings).
    scheduler : str or dask.distributed.Client, default: 'threads'
        As in :func:`tiled_fans`.
    rings, close_holes, max_hole, max_hole_diameter, remove_self_intersections, \
min_component, self_intersections
        As in :func:`fancloud_vtk.fan_cloud_to_mesh` (``rings='fans'`` is not offered:
        whether the fans are the one-rings of a 2-manifold is a question about all of
        them).
    max_angle, max_replacements, rule, rotate_sharp_edges, reach, separate_sheets
        As in :func:`fancloud_vtk.build_fans`.
    point_data : dict of str to array_like, optional
        Arrays with one row per point, carried to the mesh.

    Returns
    -------
    TriangleMesh
        ``stats`` holds the checks of the final mesh (as ``fan_cloud_to_mesh``'s),
        ``normals_flipped``, ``local_rings``, ``outliers``, ``final``, ``cut_pieces``,
        ``cut_points`` and ``pieces_turned``, and ``tiles``, ``halos`` (per tile),
        ``rebuilt`` and ``timings``; not the counts of the stages in between, which are
        the tiles'.

    Raises
    ------
    ValueError
        Bad points or parameters, as ``build_fans`` and ``fan_cloud_to_mesh`` raise.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, fan_cloud_to_mesh, tiled_mesh
    >>> p = np.random.default_rng(0).normal(size=(20000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> mesh = tiled_mesh(p, tiles=(2, 2, 1), scheduler="sync")
    >>> one = fan_cloud_to_mesh(build_fans(p))  # here the same mesh
    >>> def rows(t):  # each triangle from its lowest point, the rows sorted
    ...     t = np.array([np.roll(r, -int(np.argmin(r))) for r in t])
    ...     return t[np.lexsort(t.T[::-1])]
    >>> bool(np.array_equal(rows(mesh.triangles), rows(one.triangles)))
    True
    >>> bool(np.array_equal(mesh.normals, one.normals))
    True
    """
    dask = _dask("tiled_mesh")
    from .core import mesh as _M

    if rings == "fans":
        raise ValueError("tiled_mesh: rings='fans' is not offered in tiles (whether the fans "
                         "are the one-rings of a 2-manifold is a question about all of them); "
                         "use 'auto', 'delaunay' or 'local'")
    k, max_angle, max_replacements, rule_id, reach = _check_fan_options(
        k, max_angle, max_replacements, rule, reach, separate_sheets=separate_sheets,
        rotate_sharp_edges=rotate_sharp_edges)
    max_hole_diameter = _M._check_mesh_options(rings, min_component, max_hole,
                                               max_hole_diameter)
    mesh_halo = None if halo is None else _check_halo(halo)
    t_all = time.perf_counter()
    fc = tiled_fans(points, k, tiles=tiles, scheduler=scheduler, max_angle=max_angle,
                    max_replacements=max_replacements, rule=rule,
                    rotate_sharp_edges=rotate_sharp_edges, reach=reach,
                    separate_sheets=separate_sheets, point_data=point_data)
    timings = {"fans": time.perf_counter() - t_all}
    pts = fc.points
    n = len(pts)
    t0 = time.perf_counter()
    grid = _F.Grid(pts)  # the mesh's spatial order, and the fans' (ties between distances)
    rank = np.empty(n, np.int64)
    rank[grid.order] = np.arange(n)
    cells = (grid.lo, grid.h)
    lo, hi, owner = tile_boxes(pts, tiles)
    if mesh_halo is None:  # per tile, MESH_HALO times the halo its fans needed
        start = MESH_HALO * np.maximum(np.asarray(fc.info["halos"], np.float64),
                                       _auto_halo(pts, k))
    else:
        start = np.full(len(lo), mesh_halo)
    timings["setup"] = time.perf_counter() - t0
    fan_options = (k, max_angle, max_replacements, rule, rule_id, bool(rotate_sharp_edges),
                   reach, bool(separate_sheets))
    opts = (bool(close_holes), int(max_hole), max_hole_diameter,
            bool(remove_self_intersections))
    stats = {"tiles": tuple(int(x) for x in _check_tiles(tiles))}

    def run(kind):
        t0 = time.perf_counter()
        flip = _M._mesh_flip(fc, rank, kind)
        timings[kind + "_orientation"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        tris, normals, halos, rebuilt = _mesh_tiles(dask, scheduler, fc, rank, flip, kind,
                                                    owner, lo, hi, start, fan_options, opts,
                                                    cells)
        timings[kind + "_tiles"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        base = FanCloud(pts, fc.offsets, fc.ring, normals, fc.open, fc.rotated)
        tris, outliers = _M._outliers(base, tris, min_component)
        timings[kind + "_outliers"] = time.perf_counter() - t0
        return tris, outliers, flip, base, halos, rebuilt

    kind = "local" if rings == "local" else "delaunay"
    tris, outliers, flip, base, halos, rebuilt = run(kind)
    local = kind == "local"
    if rings == "auto":  # as fan_cloud_to_mesh decides, on the stitched mesh
        cut, _ = _M._cut_pieces(fc, tris, {})
        if not cut:
            used = np.zeros(n, bool)
            used[tris.ravel()] = True
            cut = int(n - used.sum() - len(outliers) > 0.1 * n)
        if cut:
            other = run("local")
            if _M._score(fc, other[0], other[1]) < _M._score(fc, tris, outliers):
                tris, outliers, flip, base, halos, rebuilt = other
                local = True
            else:
                rebuilt += other[5]
    stats.update(normals_flipped=int(flip.sum()), local_rings=int(local),
                 outliers=len(outliers), final=len(tris), halos=halos, rebuilt=rebuilt)
    timings_all = timings
    # (the self-intersections are counted on the stitched mesh, not assumed gone)
    mesh = _M._conclude(fc, np.arange(n), base, tris, outliers, flip, local, stats,
                        timings_all, close_holes, False, self_intersections)
    timings_all["total"] = time.perf_counter() - t_all
    return mesh


def _mesh_tiles(dask, scheduler, fc, rank, flip, kind, owner, lo, hi, start, fan_options,
                opts, cells):
    """The tiles' meshes of the rings ``kind``, stitched: (triangles, the normals they were
    grown with, the halos, the tiles built again). A tile whose band triangles (those
    within :data:`BAND` times its halo of its box that it does not own) are not those their owners
    made is built again, with the owners, at twice the halo."""
    pts = fc.points
    n = len(pts)
    n_tiles = len(lo)
    widths = np.array(start, np.float64)
    todo = [t for t in range(n_tiles) if (owner == t).any()]
    own_tris: list = [np.empty((0, 3), np.int64)] * n_tiles
    bands: list = [np.empty((0, 3), np.int64)] * n_tiles
    normals = fc.normals.copy()
    full = np.zeros(n_tiles, bool)
    rebuilt = 0
    while todo:
        jobs = []
        for t in todo:
            ids = _grown(pts, lo[t], hi[t], widths[t])
            full[t] = len(ids) == n
            jobs.append((pts[ids], ids, fc.normals[ids], rank[ids], flip[ids], owner[ids], t,
                         lo[t], hi[t], BAND * widths[t], fan_options, kind, opts, cells))
        for t, (own, band, nrm) in zip(todo, _run_tiles(dask, jobs, scheduler, _mesh_tile),
                                       strict=True):
            own_tris[t], bands[t] = own, band
            normals[owner == t] = nrm
        # each tile's band against its owners' triangles
        stitched = np.concatenate(own_tris)
        tri_owner = np.repeat(np.arange(n_tiles), [len(x) for x in own_tris])
        keys = _tri_keys(stitched)
        again = set()
        for t in range(n_tiles):
            if not len(own_tris[t]) and not len(bands[t]):
                continue
            near = np.all((pts >= lo[t] - BAND * widths[t]) & (pts <= hi[t] + BAND * widths[t]),
                          axis=1)
            theirs = (tri_owner != t) & near[stitched].all(axis=1)
            made = set(_tri_keys(bands[t]).tolist())
            want = set(keys[theirs].tolist())
            if made != want:
                differ = made ^ want
                again.add(t)
                wrong = np.isin(keys, np.fromiter(differ, np.int64, len(differ)))
                again.update(np.unique(tri_owner[wrong]).tolist())
        todo = sorted(t for t in again if not full[t])
        for t in todo:
            widths[t] *= 2.0
        rebuilt += len(todo)
    return np.concatenate(own_tris), normals, widths.tolist(), rebuilt


def _tri_keys(tris) -> np.ndarray:
    """One int64 per triangle, the same for the same triangle the same way round (a hash
    of its points from the lowest one on; equal triangles, equal keys)."""
    tris = np.asarray(tris, np.int64).reshape(-1, 3)
    first = np.argmin(tris, axis=1)
    rows = np.arange(len(tris))[:, None]
    t = tris[rows, (first[:, None] + np.arange(3)) % 3].astype(np.uint64)
    h = t[:, 0] * np.uint64(0x9E3779B97F4A7C15)
    h = (h ^ (h >> np.uint64(29)) ^ t[:, 1]) * np.uint64(0xBF58476D1CE4E5B9)
    h = (h ^ (h >> np.uint64(32)) ^ t[:, 2]) * np.uint64(0x94D049BB133111EB)
    return (h ^ (h >> np.uint64(31))).view(np.int64)


def _mesh_tile(sub, ids, normals, rank, flip, sub_owner, t, lo, hi, band, fan_options, kind,
               opts, cells):
    """One tile's mesh task: the fans of ``sub`` (the points ``ids``, sorted), turned to
    the whole cloud's ``normals``, meshed in the whole cloud's order ``rank`` with its
    orientation ``flip``. Returns (the triangles the tile owns, the others within ``band``
    of its box, both in global indices; the grown-with normals of the owned points)."""
    from .core import mesh as _M

    k, max_angle, max_replacements, rule, rule_id, rotate, reach, sheets = fan_options
    fc, _ = _F._fans(sub, k, max_angle, max_replacements, rule, rule_id, rotate, reach,
                     sheets, None, False, {}, 1, None, cells)
    turn = np.einsum("ij,ij->i", fc.normals, normals) < 0.0
    if turn.any():
        fc = _M._flipped(fc, turn)
    tri, grown_with = _M._mesh_part(fc, rank, flip, kind, opts)
    mine = sub_owner == t
    own = mine[tri.min(axis=1)]  # ids are sorted: the lowest index is the lowest id
    inside = np.all((sub >= lo - band) & (sub <= hi + band), axis=1)
    near = ~own & inside[tri].all(axis=1)
    return ids[tri[own]], ids[tri[near]], grown_with[mine]


def write_tiled_fans(
    source,
    outdir,
    k: int = 6,
    *,
    tiles="auto",
    tile_points: int = 2_000_000,
    halo: float | None = None,
    scheduler=None,
    workers: int | None = None,
    chunk: int = 1_000_000,
    max_angle: float = 90.0,
    max_replacements: int = 42,
    rule: str = "cover",
    rotate_sharp_edges: bool = True,
    reach: float = 5.0,
    separate_sheets: bool = False,
    point_data=None,
    progress=None,
) -> dict:
    """The fan cloud of a cloud larger than memory, built in tiles and written per tile.

    The input streams through twice in chunks (:func:`fancloud_vtk.io.read_point_chunks`):
    once for its size, bounding box and a sample (the halo width), once to sort its points
    into the tiles' boxes grown by the halo, on disk (``OUTDIR/.work``). Each tile then runs
    as a task that reads only its own points, builds their fans (the halo rule of
    :func:`tiled_fans`; a tile whose points need a wider halo is sorted again with it),
    orients them over its box and writes ``OUTDIR/tile_NNNN.vtp``. The tiles' normals are
    made to agree (a tile whose normals point against its neighbours' on the points they
    share is flipped, from the tile with the most points), then ``index.json`` and
    ``fans.vtpd`` are written: no tile file or index is half-written at any time (each is
    written under a temporary name and renamed), and a folder without ``index.json`` is an
    unfinished run. :func:`read_tiles` puts the tiles together: the fan cloud
    ``build_fans`` gives on the same points, ring for ring and normal for normal.

    Each tile file is a fan cloud ``.vtp`` (``fancloud mesh tile_0000.vtp`` reads it) of the
    tile's own points followed by the points of other tiles that their fans use, with the
    point arrays ``GlobalPointIds`` (the point's row in the input) and ``vtkGhostType`` (1:
    another tile's point; its fan is empty here), and the input's own point arrays
    (``point_data``). ParaView opens ``fans.vtpd`` as one partitioned dataset.

    Parameters
    ----------
    source : str, os.PathLike or array_like
        A point file (``.npy``, ``.ply``, ``.las``, ``.laz`` are read in chunks; other
        formats whole) or an ``(n, 3)`` array.
    outdir : str or os.PathLike
        The output folder; made if missing, and must not hold a tiled fan cloud already
        (no ``index.json``) unless empty of one.
    k : int, default: 6
        Neighbours per fan.
    tiles : "auto" or tuple of 3 int, default: "auto"
        Tiles along x, y and z; ``"auto"``: about ``n / tile_points`` tiles, cut along
        the longest sides of the bounding box.
    tile_points : int, default: 2_000_000
        With ``tiles="auto"``: the points a tile should own at most, on average.
    halo : float, optional
        The starting halo width (as in :func:`tiled_fans`).
    scheduler : str or dask.distributed.Client, optional
        None (default): a ``LocalCluster`` of ``workers`` single-threaded processes, closed
        at the end. Otherwise as in :func:`tiled_fans` (a scheduler address for a real
        cluster: its workers must see ``outdir``).
    workers : int, optional
        The ``LocalCluster``'s worker processes (default: the CPU count).
    chunk : int, default: 1_000_000
        Points read at a time.
    max_angle, max_replacements, rule, rotate_sharp_edges, reach, separate_sheets
        As in ``build_fans``.
    point_data : dict or bool, optional
        The point arrays carried into the tiles (and back by :func:`read_tiles`). None
        (default) or True: a file's own arrays, as :func:`fancloud_vtk.io.read_point_chunks`
        reads them (LAS/LAZ ``RGB``, ``intensity``, ``classification``,
        ``return_number``; PLY vertex properties; ``.npy``: none); for an array
        ``source``, a dict of arrays with one row per point. False: none. An input array
        named ``Normals``, ``fan_open`` or ``fan_rotated`` (the fan cloud's own) or as
        the tiles' arrays is dropped with a ``DroppedArrayWarning``.
    progress : callable, optional
        ``progress(fraction, message)``, called as tiles finish.

    Returns
    -------
    dict
        The index (what ``index.json`` holds): ``n_points`` (the input's rows),
        ``duplicates_merged``, ``bounds``, ``tiles``,
        ``parameters``, ``point_arrays`` (the names carried), and per tile its ``file``,
        ``box``, ``halo``, ``owned``, ``built``, ``ghosts``, ``flipped``; ``no_plane``
        (global ids of the points whose fan plane stands in for a normal, which the
        orientation of :func:`read_tiles` needs);
        ``timings``.

    Raises
    ------
    FanCloudInputError
        Non-finite coordinates (naming the row), too few points, bad ``tiles`` / ``halo``
        / ``tile_points``, or an ``outdir`` that already holds one.

    Warns
    -----
    DuplicatePointsWarning
        Exact duplicate points were merged, as ``build_fans`` merges them: the first of
        each set kept (the index counts them in ``duplicates_merged``; :func:`read_tiles`
        gives the kept points the point array ``original_id``, their rows in the input).
    FileReadError
        An unreadable input file.

    Examples
    --------
    >>> import numpy as np, tempfile
    >>> from fancloud_vtk import build_fans
    >>> from fancloud_vtk.distributed import read_tiles, write_tiled_fans
    >>> p = np.random.default_rng(0).normal(size=(20000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> out = tempfile.mkdtemp()
    >>> index = write_tiled_fans(p, out, tiles=(2, 2, 1), scheduler="sync")
    >>> len(index["tile_list"])
    4
    >>> fc, one = read_tiles(out), build_fans(p)
    >>> bool(np.array_equal(fc.ring, one.ring) and np.array_equal(fc.normals, one.normals))
    True
    """
    import json
    import os
    import shutil

    dask = _dask("write_tiled_fans")
    k, max_angle, max_replacements, rule_id, reach = _check_fan_options(
        k, max_angle, max_replacements, rule, reach, separate_sheets=separate_sheets,
        rotate_sharp_edges=rotate_sharp_edges)
    tile_points = _check_tile_points(tile_points)
    if not (isinstance(tiles, str) and tiles == "auto"):
        _check_tiles(tiles)
    start_halo = None if halo is None else _check_halo(halo)
    outdir = os.fspath(outdir)
    if os.path.exists(os.path.join(outdir, INDEX_NAME)):
        raise FanCloudInputError(f"{outdir} already holds a tiled fan cloud ({INDEX_NAME}): "
                                 "choose another folder or remove it")
    if os.path.exists(outdir) and not os.path.isdir(outdir):
        raise FanCloudInputError(f"{outdir} exists and is not a folder")
    chunks = _chunk_source(source, chunk, point_data)
    report = progress if progress is not None else (lambda f, m: None)
    t_all = time.perf_counter()
    timings = {}

    # pass 1: size, bounds, a sample
    t0 = time.perf_counter()
    report(0.0, "scan the input")
    n, blo, bhi, sample, schema, t = _scan_checked(chunks, k, tiles, tile_points)
    lo, hi, number = _box_grid(blo, bhi, t)
    width0 = start_halo if start_halo is not None else _auto_halo_sample(sample, n, k)
    timings["scan"] = time.perf_counter() - t0

    os.makedirs(outdir, exist_ok=True)
    work = os.path.join(outdir, _WORK)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    for name in os.listdir(outdir):  # an interrupted run's files
        if name.startswith("tile_") or name.endswith(".tmp"):
            os.remove(os.path.join(outdir, name))
    options = (k, max_angle, max_replacements, rule, rule_id, bool(rotate_sharp_edges), reach,
               bool(separate_sheets))
    m = len(lo)
    widths = np.full(m, width0)
    summaries: list = [None] * m
    todo = list(range(m))
    client, close = _client_for(scheduler, workers)
    try:
        t_tiles = 0.0
        t_sort = 0.0
        while todo:
            t0 = time.perf_counter()
            report(0.02, f"sort the points into {len(todo)} tile(s)")
            counts = _bucket(chunks(), work, todo, lo, hi, widths, blo, bhi, t, number,
                             schema)
            t_sort += time.perf_counter() - t0
            t0 = time.perf_counter()
            jobs = []
            for i in todo:
                if counts[i][0] == 0:  # a tile that owns no point: nothing to write
                    summaries[i] = _empty_summary(i, lo[i], hi[i], widths[i])
                    continue
                jobs.append((work, i, lo[i], hi[i], widths[i], blo, bhi, t, number, options,
                             outdir, n, schema))
            done_before = sum(s is not None for s in summaries)
            again = []
            for res in _map_tasks(dask, client, scheduler, _file_tile, jobs,
                                  lambda j, d=done_before: report(
                                      0.05 + 0.85 * (d + j) / m, f"tiles done: {d + j}/{m}")):
                i = res["tile"]
                if res["needed"] > widths[i] and res["built"] < n:
                    widths[i] = max(2.0 * widths[i], res["needed"])
                    again.append(i)
                else:
                    summaries[i] = res
            t_tiles += time.perf_counter() - t0
            todo = sorted(again)
        timings["sort"] = t_sort
        timings["tiles"] = t_tiles

        # the tiles' normals agree: flip a tile whose shared points point the other way
        t0 = time.perf_counter()
        report(0.92, "make the tiles' normals agree")
        flips = _tile_flips(summaries)
        flip_jobs = [(os.path.join(outdir, summaries[i]["file"]),) for i in np.flatnonzero(flips)]
        for _ in _map_tasks(dask, client, scheduler, _flip_tile_file, flip_jobs, None):
            pass
        timings["agree"] = time.perf_counter() - t0
    finally:
        if close is not None:
            close()
        shutil.rmtree(work, ignore_errors=True)
        for name in os.listdir(outdir) if os.path.isdir(outdir) else ():
            if name.endswith(".tmp"):
                os.remove(os.path.join(outdir, name))

    timings["total"] = time.perf_counter() - t_all
    no_plane = np.concatenate([s["no_plane"] for s in summaries]).astype(np.int64)
    merged = sum(s["merged"] for s in summaries)
    if merged:
        warnings.warn(
            f"{merged} duplicate point(s) merged: the first of each set of identical points "
            "is kept; read_tiles gives the 'original_id' point array (rows of the input)",
            _F.DuplicatePointsWarning, stacklevel=2)
    index = {
        "format": "fancloud-vtk tiled fan cloud 1",
        "n_points": int(n),
        "duplicates_merged": int(merged),
        "bounds": [blo.tolist(), bhi.tolist()],
        "tiles": [int(x) for x in t],
        "parameters": {"k": k, "max_angle": max_angle, "max_replacements": max_replacements,
                       "rule": rule, "rotate_sharp_edges": bool(rotate_sharp_edges),
                       "reach": reach, "separate_sheets": bool(separate_sheets)},
        "point_arrays": [name for name, _, _ in schema],
        "tile_list": [
            {"tile": i, "file": s["file"], "box": [lo[i].tolist(), hi[i].tolist()],
             "halo": float(widths[i]), "owned": s["owned"], "built": s["built"],
             "ghosts": s["ghosts"], "open": s["open"], "flipped": bool(flips[i]),
             "seconds": float(s["seconds"]), "worker_peak_mb": float(s["peak_mb"])}
            for i, s in enumerate(summaries)],
        "no_plane": np.sort(no_plane).tolist(),
        "timings": timings,
    }
    files = [s["file"] for s in summaries if s["file"]]
    _write_atomic(os.path.join(outdir, VTPD_NAME), _vtpd(files))
    _write_atomic(os.path.join(outdir, INDEX_NAME), json.dumps(index, indent=1))
    report(1.0, "done")
    return index


def read_tiles(outdir, *, orient: bool = True) -> FanCloud:
    """The fan cloud of a folder written by :func:`write_tiled_fans`, in one piece.

    Each point's fan comes from the tile that owns it; with ``orient`` (default) the
    normals are then oriented over the whole cloud as ``build_fans`` orients them, so the
    result is the fan cloud ``build_fans`` gives on the same points (the input's row order;
    when the run merged duplicates, the first of each, with the point array
    ``original_id`` giving their rows in the input, as ``build_fans`` gives it); without,
    each tile's normals are kept as written (agreeing across tiles).

    Raises
    ------
    FileReadError
        No ``index.json`` (an unfinished run), or a missing or damaged tile file.
    """
    import json
    import os

    from .algorithms.convert import fancloud_from_vtk, read_vtp
    from .core.validation import FileReadError

    outdir = os.fspath(outdir)
    path = os.path.join(outdir, INDEX_NAME)
    if not os.path.isfile(path):
        raise FileReadError(path, "no index: not a tiled fan cloud, or its run did not finish")
    try:
        with open(path) as fh:
            index = json.load(fh)
        n = int(index["n_points"])
        merged = int(index.get("duplicates_merged", 0))
        tiles = index["tile_list"]
    except (ValueError, KeyError, TypeError) as exc:
        raise FileReadError(path, f"not a tiled fan cloud index ({exc})") from exc
    points = np.empty((n, 3))
    normals = np.empty((n, 3))
    sizes = np.zeros(n, np.int64)
    is_open = np.zeros(n, bool)
    rotated = np.zeros(n, bool)
    turned = np.zeros(n, bool)
    seen = np.zeros(n, bool)
    parts = []
    carried = {}  # the input's point arrays, one row per point
    for tile in tiles:
        if not tile["file"]:
            continue
        fpath = os.path.join(outdir, tile["file"])
        try:
            fc = fancloud_from_vtk(read_vtp(fpath))
            gid = np.asarray(fc.point_data["GlobalPointIds"], np.int64)
            flag = np.asarray(fc.point_data[FAN_FLIPPED]) != 0
        except (OSError, ValueError, KeyError) as exc:
            raise FileReadError(fpath, f"not a tile of this fan cloud ({exc})") from exc
        own = int(tile["owned"])
        ids = gid[:own]
        if len(gid) != len(fc.points) or ids.size and (ids.min() < 0 or ids.max() >= n) \
                or seen[ids].any():
            raise FileReadError(fpath, "its GlobalPointIds do not fit the index")
        seen[ids] = True
        points[ids] = fc.points[:own]
        normals[ids] = fc.normals[:own]
        is_open[ids] = fc.open[:own]
        rotated[ids] = fc.rotated[:own]
        turned[ids] = flag[:own]
        s = np.diff(fc.offsets)[:own]
        sizes[ids] = s
        for name, arr in fc.point_data.items():
            if name in _TILE_ARRAYS:
                continue
            arr = np.asarray(arr)
            if name not in carried:
                carried[name] = np.zeros((n, *arr.shape[1:]), arr.dtype)
            carried[name][ids] = arr[:own]
        parts.append((ids, s, gid[fc.ring[: fc.offsets[own]]]))
    if int(seen.sum()) != n - merged:
        raise FileReadError(path, f"{int(n - merged - seen.sum()):,} point(s) in no tile file")
    no_plane = np.zeros(n, bool)
    no_plane[np.asarray(index.get("no_plane", []), np.int64)] = True
    rank = None
    if merged:  # the points kept: the input's rows renumbered, as build_fans merges them
        kept = np.flatnonzero(seen)
        rank = np.full(n, -1, np.int64)
        rank[kept] = np.arange(len(kept))
        points, normals, sizes = points[kept], normals[kept], sizes[kept]
        is_open, rotated, turned, no_plane = (is_open[kept], rotated[kept], turned[kept],
                                              no_plane[kept])
        carried = {name: arr[kept] for name, arr in carried.items()}
        carried["original_id"] = kept
    offsets = np.zeros(len(points) + 1, np.int64)
    np.cumsum(sizes, out=offsets[1:])
    ring = np.empty(offsets[-1], np.int64)
    for ids, s, r in parts:
        if rank is not None:
            ids, r = rank[ids], rank[r]
        dst = _positions(offsets[ids], s)
        ring[dst] = r
    p = index.get("parameters", {})
    info = {**p, "fans_open": int(is_open.sum()), "fans_rotated": int(rotated.sum()),
            "duplicates_merged": merged, "tiles": tuple(index.get("tiles", ()))}
    fc = FanCloud(points, offsets, ring, normals, is_open, rotated, carried, info)
    if orient:  # the fans as built (the orientation's result depends on them), oriented
        normals[turned] *= -1.0
        sizes_t = np.diff(offsets)
        at = np.flatnonzero(np.repeat(turned, sizes_t))
        start = np.repeat(offsets[:-1], sizes_t)[at]
        end = np.repeat(offsets[1:], sizes_t)[at]
        ring[at] = ring[start + end - 1 - at]
        fc = _F._orient_fans(fc, no_plane)
    return fc


def _chunk_source(source, chunk, point_data=None):
    """A function giving a fresh iterator over the source's chunks: (coordinates, point
    arrays) pairs."""
    import os

    from .io import read_point_chunks

    if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
        raise FanCloudInputError(f"chunk must be a positive integer, got {chunk!r}")
    if point_data is not None and not isinstance(point_data, bool | np.bool_) \
            and not hasattr(point_data, "items"):
        raise TypeError("point_data must be None, True, False or a mapping of array name to "
                        f"array, got {type(point_data).__name__}")
    if isinstance(source, str | bytes | os.PathLike):
        if hasattr(point_data, "items"):
            raise FanCloudInputError("point_data arrays go with an array source; a file "
                                     "brings its own (point_data=True or False)")
        path = source  # (a bad file raises with the first chunk)
        want = point_data is not False
        return lambda: read_point_chunks(path, chunk=int(chunk), point_data=True) if want \
            else ((c, {}) for c in read_point_chunks(path, chunk=int(chunk)))
    pts = as_points(source)
    data = check_point_data(point_data, len(pts)) if hasattr(point_data, "items") else {}
    return lambda: ((pts[i:i + chunk], {k: v[i:i + chunk] for k, v in data.items()})
                    for i in range(0, len(pts), chunk))


# the fan cloud's own point arrays and the tiles': an input array of one of these names
# is not carried into the tiles
_TILE_ARRAYS = ("Normals", "fan_open", "fan_rotated", "GlobalPointIds", "vtkGhostType",
                "fan_flipped")


def _carried(arrays, schema=None, stacklevel=4):
    """The point arrays of a chunk that go into the tiles, checked against ``schema`` (the
    first chunk's names, dtypes and row shapes; None: this is the first chunk)."""
    from .io import DroppedArrayWarning

    out = {}
    for name, arr in arrays.items():
        if name in _TILE_ARRAYS:
            if schema is None:
                warnings.warn(f"point array {name!r} dropped: the tiles' own array has that "
                              "name", DroppedArrayWarning, stacklevel=stacklevel)
            continue
        out[str(name)] = np.ascontiguousarray(arr)
    if schema is not None:
        got = [(k, v.dtype.str, v.shape[1:]) for k, v in out.items()]
        if got != schema:
            raise FanCloudInputError(f"the chunks' point arrays differ: {got} after {schema}")
    return out


def _scan(chunks):
    """(n, bounds lo, bounds hi, a random sample of up to _HALO_SAMPLE points), checking
    that every coordinate is finite."""
    n = 0
    blo = np.full(3, np.inf)
    bhi = np.full(3, -np.inf)
    rng = np.random.default_rng(0)
    keys = np.empty(0)
    sample = np.empty((0, 3))
    schema = None
    for c, arrays in chunks:
        carried = _carried(arrays, schema)
        if schema is None:
            schema = [(k, v.dtype.str, v.shape[1:]) for k, v in carried.items()]
        c = np.asarray(c, np.float64)
        if c.ndim != 2 or c.shape[1] != 3:
            raise FanCloudInputError(f"points must have shape (n, 3), got a chunk {c.shape}")
        bad = ~np.isfinite(c).all(axis=1)
        if bad.any():
            row = n + int(np.flatnonzero(bad)[0])
            raise FanCloudInputError(f"{int(bad.sum()):,} point(s) with NaN or infinite "
                                     f"coordinates (the first: row {row:,})")
        if len(c):
            blo = np.minimum(blo, c.min(axis=0))
            bhi = np.maximum(bhi, c.max(axis=0))
            kc = rng.random(len(c))
            keys = np.concatenate([keys, kc])
            sample = np.concatenate([sample, c])
            if len(keys) > _HALO_SAMPLE:
                keep = np.argpartition(keys, _HALO_SAMPLE)[:_HALO_SAMPLE]
                keys, sample = keys[keep], sample[keep]
        n += len(c)
    if n == 0:
        raise FanCloudInputError("the input has no points")
    return n, blo, bhi, sample, schema or []


def _scan_checked(chunks, k, tiles, tile_points):
    """The first pass over a chunked input: (n, bounds lo, hi, sample, schema, tiles),
    refusing too few points or points on a line; ``tiles`` "auto" made from the size."""
    n, blo, bhi, sample, schema = _scan(chunks())
    _F._check_size(n, k)
    check_spread(sample)  # all points on a line (or one point) have no fans
    auto = isinstance(tiles, str) and tiles == "auto"
    t = _auto_tiles(n, blo, bhi, tile_points) if auto else _check_tiles(tiles)
    return n, blo, bhi, sample, schema, t


def _auto_tiles(n, blo, bhi, tile_points) -> np.ndarray:
    """About n / tile_points tiles, each cut made across the longest side of a tile."""
    want = max(1, int(np.ceil(n / tile_points)))
    t = np.ones(3, np.int64)
    span = np.where(bhi > blo, bhi - blo, 0.0)
    while t.prod() < want:
        t[int(np.argmax(span / t))] += 1
    return t


def _box_grid(blo, bhi, t):
    """The tiles' boxes (Morton order) and the grid of their numbers (see tile_boxes)."""
    span = np.where(bhi > blo, bhi - blo, 1.0)
    ijk = np.array([(i, j, m) for i in range(t[0]) for j in range(t[1]) for m in range(t[2])],
                   np.int64).reshape(-1, 3)
    ijk = ijk[np.argsort(_morton(ijk), kind="stable")]
    number = np.empty(t, np.int64)
    number[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = np.arange(len(ijk))
    lo = blo + span * ijk / t
    hi = np.where(ijk + 1 == t, bhi, blo + span * (ijk + 1) / t)
    return lo, hi, number


def _owner(pts, blo, bhi, t, number) -> np.ndarray:
    """The tile that owns each point (as tile_boxes)."""
    span = np.where(bhi > blo, bhi - blo, 1.0)
    cell = np.minimum(np.floor((pts - blo) / span * t).astype(np.int64), t - 1)
    return number[cell[:, 0], cell[:, 1], cell[:, 2]]


def _bucket(chunks, work, todo, lo, hi, widths, blo, bhi, t, number, schema=()) -> dict:
    """Append each chunk's points (their global ids, their point arrays of ``schema``) in a
    tile's grown box to the tile's files in ``work``; {tile: (owned, in the grown box)}."""
    import os

    counts = {i: [0, 0] for i in todo}
    exts = [".xyz", ".ids"] + [f".a{j}" for j in range(len(schema))]
    for i in todo:
        for ext in exts:
            path = os.path.join(work, f"tile_{i:05d}{ext}")
            if os.path.exists(path):
                os.remove(path)
    base = 0
    uniform = len(todo) == len(lo) and np.all(widths == widths[0])
    for c, arrays in chunks:
        arrays = list(_carried(arrays, list(schema)).values())
        c = np.asarray(c, np.float64)
        own = _owner(c, blo, bhi, t, number)
        if uniform:  # every tile, one width: each point's few tiles, not every tile
            members = _grown_members(c, lo, hi, float(widths[0]), t, number)
        else:
            members = _box_members(c, todo, lo, hi, widths)
        for i, inside in members:
            counts[i][0] += int(np.count_nonzero(own[inside] == i))
            counts[i][1] += len(inside)
            with open(os.path.join(work, f"tile_{i:05d}.xyz"), "ab") as fh:
                c[inside].tofile(fh)
            with open(os.path.join(work, f"tile_{i:05d}.ids"), "ab") as fh:
                (inside + base).astype(np.int64).tofile(fh)
            for j, arr in enumerate(arrays):
                with open(os.path.join(work, f"tile_{i:05d}.a{j}"), "ab") as fh:
                    np.ascontiguousarray(arr[inside]).tofile(fh)
        base += len(c)
    return counts


def _box_members(c, todo, lo, hi, widths):
    """(tile, sorted row numbers of ``c`` in its grown box) for the tiles ``todo``, each
    with its own width, by testing every tile."""
    clo, chi = c.min(axis=0), c.max(axis=0)
    for i in todo:
        glo, ghi = lo[i] - widths[i], hi[i] + widths[i]
        if np.any(chi < glo) or np.any(clo > ghi):
            continue
        inside = np.flatnonzero(np.all((c >= glo) & (c <= ghi), axis=1))
        if len(inside):
            yield i, inside


def _grown_members(c, lo, hi, width, t, number):
    """(tile, sorted row numbers of ``c`` in its box grown by ``width``) for every tile that
    gets any: per axis, the cells whose grown interval holds the coordinate (the same
    comparisons as ``lo - width <= x <= hi + width``), then their combinations."""
    ranges = []
    for a in range(3):
        edge_lo = np.array([lo[number.take(j, axis=a).ravel()[0], a] for j in range(t[a])])
        edge_hi = np.array([hi[number.take(j, axis=a).ravel()[0], a] for j in range(t[a])])
        x = c[:, a]
        first = np.searchsorted(edge_hi + width, x, side="left")  # edge_hi + w >= x
        last = np.searchsorted(edge_lo - width, x, side="right") - 1  # edge_lo - w <= x
        ranges.append((np.clip(first, 0, t[a] - 1), np.clip(last, 0, t[a] - 1)))
    rows_all, tiles_all = [], []
    span = [int((r[1] - r[0]).max(initial=0)) + 1 for r in ranges]
    for dx in range(span[0]):
        for dy in range(span[1]):
            for dz in range(span[2]):
                ci = ranges[0][0] + dx
                cj = ranges[1][0] + dy
                ck = ranges[2][0] + dz
                ok = (ci <= ranges[0][1]) & (cj <= ranges[1][1]) & (ck <= ranges[2][1])
                rows = np.flatnonzero(ok)
                rows_all.append(rows)
                tiles_all.append(number[ci[rows], cj[rows], ck[rows]])
    rows = np.concatenate(rows_all)
    tiles = np.concatenate(tiles_all)
    order = np.lexsort((rows, tiles))
    rows, tiles = rows[order], tiles[order]
    cut = np.flatnonzero(np.diff(tiles)) + 1
    for part_rows, part_tiles in zip(np.split(rows, cut), np.split(tiles, cut), strict=True):
        if len(part_rows):
            yield int(part_tiles[0]), part_rows


def _file_tile(work, i, lo, hi, width, blo, bhi, t, number, options, outdir, n, schema=()):
    """One tile's task: read its points, build their fans (with the halo's), check the
    halo, orient over the tile, write ``tile_NNNN.vtp``; a summary dict."""
    import os
    import resource

    t_start = time.perf_counter()
    sub = np.fromfile(os.path.join(work, f"tile_{i:05d}.xyz"), np.float64).reshape(-1, 3)
    ids = np.fromfile(os.path.join(work, f"tile_{i:05d}.ids"), np.int64)
    carried = {name: np.fromfile(os.path.join(work, f"tile_{i:05d}.a{j}"), np.dtype(dt))
               .reshape((len(sub), *shape)) for j, (name, dt, shape) in enumerate(schema)}
    rows = len(sub)  # the rows read: with duplicates, more than the points kept
    grid = _F.Grid(sub)
    own_mask = _owner(sub, blo, bhi, t, number) == i
    merged = 0
    if grid.n_dup:
        # the copies of a point fall in the same tiles (its owner's and the same halos):
        # the tile keeps the first (lowest global id) of each, as build_fans keeps it
        keep = _first_rows(sub, ids)
        merged = int(own_mask.sum() - own_mask[keep].sum())
        sub, ids, own_mask = sub[keep], ids[keep], own_mask[keep]
        carried = {name: arr[keep] for name, arr in carried.items()}
        grid = _F.Grid(sub)
    own_loc = np.flatnonzero(own_mask)
    k, max_angle, max_replacements, rule, rule_id, rotate, reach, sheets = options
    if len(sub) < k + 1:  # too few distinct points to make fans: a wider halo
        if rows < n:
            return {"tile": i, "built": rows, "owned": len(own_loc),
                    "needed": max(2.0 * width, float((hi - lo).max()))}
        _F._check_size(len(sub), k)
    fc, no_plane = _F._fans(sub, k, max_angle, max_replacements, rule, rule_id, rotate, reach,
                            sheets, None, False, {}, 1, None)
    needed = _halo_needed(sub, fc, own_loc, lo, hi, width, blo, bhi, k)
    summary = {"tile": i, "built": rows, "owned": len(own_loc), "needed": needed,
               "merged": merged}
    if needed > width and rows < n:
        return summary  # the caller sorts the tile again with a wider halo
    built = fc.normals
    fc = _F._orient_fans(fc, no_plane, grid)
    turned = (np.einsum("ij,ij->i", built, fc.normals) < 0).astype(np.uint8)
    # the tile's fan cloud: its own points, then the other tiles' points their fans use
    sizes = np.diff(fc.offsets)[own_loc]
    take = _positions(fc.offsets[own_loc], sizes)
    ring_loc = fc.ring[take]
    ghosts = np.setdiff1d(ring_loc[~own_mask[ring_loc]], [])
    order = np.concatenate([own_loc, ghosts])
    new = np.full(len(sub), -1, np.int64)
    new[order] = np.arange(len(order))
    offsets = np.zeros(len(order) + 1, np.int64)
    offsets[1:len(own_loc) + 1] = np.cumsum(sizes)
    offsets[len(own_loc) + 1:] = offsets[len(own_loc)]
    ghost_type = np.zeros(len(order), np.uint8)
    ghost_type[len(own_loc):] = 1
    out = FanCloud(sub[order], offsets, new[ring_loc], fc.normals[order],
                   fc.open[order] & (ghost_type == 0), fc.rotated[order] & (ghost_type == 0),
                   {**{name: arr[order] for name, arr in carried.items()},
                    "GlobalPointIds": ids[order], "vtkGhostType": ghost_type,
                    FAN_FLIPPED: turned[order]}, {})
    name = f"tile_{i:04d}.vtp"
    _write_tile(out, os.path.join(outdir, name))
    # the normals other tiles compare with theirs: a sample (by global id) of the owned
    # points and of the halo's
    pick = _sampled(ids)
    summary.update({
        "file": name, "ghosts": len(ghosts), "open": int(fc.open[own_loc].sum()),
        "no_plane": ids[own_loc[no_plane[own_loc]]],
        "own_sample": (ids[pick & own_mask], fc.normals[pick & own_mask]),
        "halo_sample": (ids[pick & ~own_mask], fc.normals[pick & ~own_mask]),
        "seconds": time.perf_counter() - t_start,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    })
    return summary


def _first_rows(sub, ids) -> np.ndarray:
    """The rows of ``sub`` left when exact duplicates are merged: of each set of identical
    points the one with the lowest global id (``ids``), in the rows' order."""
    order = np.argsort(ids, kind="stable")
    _, first = np.unique(sub[order], axis=0, return_index=True)
    return np.sort(order[first])


def _halo_needed(sub, fc, loc, lo, hi, width, blo, bhi, k) -> float:
    """The halo width the owned fans ``loc`` (rows of ``sub``, the tile's box ``lo``,
    ``hi`` grown by ``width``) need, 0 when ``width`` is enough. The radius each fan looked
    at: its farthest fan neighbour and (a bound of) its 2k-th nearest point, from its two
    rings (where they are too few, the exact 2k-th nearest); the room: to the grown box's
    faces that are not the cloud's bounding box's (``blo``, ``bhi``)."""
    if not len(loc):
        return 0.0
    p = sub[loc]
    far, near = RingK.fan_radii(sub, fc.offsets, fc.ring, loc, min(2 * k, len(sub) - 1),
                                2 * numba.get_num_threads())
    few = near < 0
    if few.any():
        kq = min(2 * k + 1, len(sub))
        d = cKDTree(sub).query(p[few], k=kq)[0]
        near[few] = d[:, -1] if d.ndim == 2 else d
    need = np.where(fc.open[loc], OPEN_MARGIN, MARGIN) * np.maximum(far, near)
    glo, ghi = lo - width, hi + width
    room = np.minimum(np.where(glo > blo, p - glo, np.inf),
                      np.where(ghi < bhi, ghi - p, np.inf)).min(axis=1)
    short = need > room
    if not short.any():
        return 0.0
    inner = np.minimum(np.where(glo > blo, p - lo, np.inf),
                       np.where(ghi < bhi, hi - p, np.inf)).min(axis=1)
    return float((need - inner)[short].max())


def _sampled(ids) -> np.ndarray:
    """The points whose global id hashes to 0 modulo _SAMPLE_MODULUS (the same on every
    tile, so two tiles' samples meet)."""
    h = (ids.astype(np.uint64) * np.uint64(2654435761)) >> np.uint64(7)
    return (h % np.uint64(_SAMPLE_MODULUS)) == 0


def _empty_summary(i, lo, hi, width) -> dict:
    return {"tile": i, "built": 0, "owned": 0, "needed": 0.0, "merged": 0, "file": "",
            "ghosts": 0,
            "open": 0, "no_plane": np.empty(0, np.int64), "seconds": 0.0, "peak_mb": 0.0,
            "own_sample": (np.empty(0, np.int64), np.empty((0, 3))),
            "halo_sample": (np.empty(0, np.int64), np.empty((0, 3)))}


def _tile_flips(summaries) -> np.ndarray:
    """Which tiles to flip so that their normals agree: on the points a tile's halo shares
    with another tile's own points, the sign of the normals' dot products votes; the tiles
    are then walked from the one with the most points, strongest agreement first."""
    import heapq

    m = len(summaries)
    own_ids = np.concatenate([s["own_sample"][0] for s in summaries])
    own_nrm = np.concatenate([s["own_sample"][1] for s in summaries])
    own_tile = np.concatenate([np.full(len(s["own_sample"][0]), s["tile"]) for s in summaries])
    order = np.argsort(own_ids)
    own_ids, own_nrm, own_tile = own_ids[order], own_nrm[order], own_tile[order]
    votes = np.zeros((m, m))
    for s in summaries:
        hid, hn = s["halo_sample"]
        if not len(hid) or not len(own_ids):
            continue
        pos = np.clip(np.searchsorted(own_ids, hid), 0, len(own_ids) - 1)
        hit = own_ids[pos] == hid
        dots = np.einsum("ij,ij->i", hn[hit], own_nrm[pos[hit]])
        np.add.at(votes, (np.full(hit.sum(), s["tile"]), own_tile[pos[hit]]), np.sign(dots))
    votes = votes + votes.T
    flips = np.zeros(m, bool)
    done = np.zeros(m, bool)
    for root in np.argsort([-s["owned"] for s in summaries], kind="stable"):
        if done[root]:
            continue
        done[root] = True
        heap = [(-abs(votes[root, j]), int(root), int(j)) for j in range(m) if votes[root, j]]
        heapq.heapify(heap)
        while heap:
            _, a, b = heapq.heappop(heap)
            if done[b]:
                continue
            done[b] = True
            flips[b] = flips[a] ^ (votes[a, b] < 0)
            for j in range(m):
                if votes[b, j] and not done[j]:
                    heapq.heappush(heap, (-abs(votes[b, j]), b, j))
    return flips


def _flip_tile_file(path) -> None:
    """A tile file with its normals negated and its rings reversed."""
    from .algorithms.convert import fancloud_from_vtk, read_vtp

    fc = fancloud_from_vtk(read_vtp(path))
    sizes = np.diff(fc.offsets)
    idx = np.arange(len(fc.ring))
    start = np.repeat(fc.offsets[:-1], sizes)
    end = np.repeat(fc.offsets[1:], sizes)
    ring = fc.ring[start + end - 1 - idx]
    pdata = dict(fc.point_data)
    pdata[FAN_FLIPPED] = (pdata[FAN_FLIPPED] ^ 1).astype(np.uint8)
    _write_tile(FanCloud(fc.points, fc.offsets, ring, -fc.normals, fc.open, fc.rotated,
                         pdata, {}), path)


def _write_tile(fc, path) -> None:
    """``fc`` to ``path`` under a temporary name first (a killed task leaves no half file
    under the real name)."""
    import os

    from .algorithms.convert import fancloud_to_vtk, write_vtp

    tmp = f"{path}.{os.getpid()}.tmp.vtp"
    write_vtp(fancloud_to_vtk(fc), tmp, compressor="lz4")
    os.replace(tmp, path)


def _write_atomic(path, text) -> None:
    import os

    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)


def _vtpd(files) -> str:
    """VTK's partitioned dataset file listing the tiles' ``.vtp`` files."""
    rows = "\n".join(f'    <DataSet index="{j}" file="{f}"/>' for j, f in enumerate(files))
    return ('<?xml version="1.0"?>\n<VTKFile type="vtkPartitionedDataSet" version="1.0" '
            'byte_order="LittleEndian" header_type="UInt64">\n  <vtkPartitionedDataSet>\n'
            f"{rows}\n  </vtkPartitionedDataSet>\n</VTKFile>\n")


def _auto_halo_sample(sample, n, k) -> float:
    """:func:`_auto_halo` from a sample already drawn."""
    m = len(sample)
    d = cKDTree(sample).query(sample[: min(m, 2000)], k=min(2 * k + 1, m))[0][:, -1]
    return float(3.0 * MARGIN * np.median(d) * np.sqrt(m / n))


def _client_for(scheduler, workers):
    """(client or None, closer or None): None makes a LocalCluster of single-threaded
    worker processes; an address connects; a client or a scheduler name is used as is."""
    if scheduler is None:
        import os

        from dask.distributed import Client, LocalCluster

        if workers is not None and (isinstance(workers, bool) or
                                    not isinstance(workers, int | np.integer) or workers < 1):
            raise FanCloudInputError(f"workers must be a positive integer, got {workers!r}")
        nw = int(workers) if workers is not None else (os.cpu_count() or 1)
        # the dashboard (or Dask's HTTP server without it) on a free port: at the fixed
        # default one, a cluster already running makes the start warn or fail
        cluster = LocalCluster(n_workers=nw, threads_per_worker=1, processes=True,
                               dashboard_address=":0")
        client = Client(cluster)

        def close():
            client.close()
            cluster.close()
        return client, close
    if isinstance(scheduler, str) and "://" in scheduler:
        from dask.distributed import Client

        client = Client(scheduler)
        return client, client.close
    if isinstance(scheduler, str):
        return None, None
    if all(hasattr(scheduler, name) for name in ("compute", "gather", "submit")):
        return scheduler, None
    raise TypeError("scheduler must be None, a Dask scheduler name, a scheduler address or a "
                    f"dask.distributed.Client, got {scheduler!r}")


def _map_tasks(dask, client, scheduler, fn, jobs, done):
    """``fn(*job)`` for every job, yielded as they finish; ``done(count)`` after each."""
    if not jobs:
        return
    if client is not None:
        from dask.distributed import as_completed

        with warnings.catch_warnings():  # the blocks of tiled_reduce go with their points
            warnings.filterwarnings("ignore", message="Sending large graph",
                                    category=UserWarning)
            futures = client.map(fn, *zip(*jobs, strict=True), pure=False)
        for j, fut in enumerate(as_completed(futures), 1):
            res = fut.result()
            if done is not None:
                done(j)
            yield res
        return
    step = max(1, (numba.get_num_threads() if scheduler != "sync" else 1))
    count = 0
    for s in range(0, len(jobs), step):
        batch = [dask.delayed(fn, pure=False)(*job) for job in jobs[s:s + step]]
        for res in dask.compute(*batch, scheduler=scheduler):
            count += 1
            if done is not None:
                done(count)
            yield res


# ----------------------------------------------------------------------------- reduction


def tiled_reduce(
    points,
    n_points: int | None = None,
    keep: float | None = None,
    *,
    k: int = 6,
    tiles=(2, 2, 2),
    halo: float | None = None,
    scheduler="threads",
    workers: int | None = None,
    tile_points: int = 2_000_000,
    weights=(1.0, 1.0, 50.0, 0.0),
    method: str = "entropy",
    max_spacing: float = 4.0,
    error_step: float = 2.0,
    max_angle: float = 90.0,
    max_replacements: int = 42,
    rule: str = "cover",
    rotate_sharp_edges: bool = True,
    reach: float = 5.0,
    separate_sheets: bool = False,
    point_data=None,
    chunk: int = 1_000_000,
    progress=None,
) -> FanCloud:
    """The reduction of a point cloud in blocks, as Dask tasks (the paper's §8 blocks).

    Each tile (a block) builds the fans of its points and of a halo around it and reduces
    them (:func:`fancloud_vtk.reduce`, its removal order recorded); the block keeps the
    prefix of that order at which its *own* points are down to their share of the target
    (the target split over the blocks by their points, largest remainders first, so the
    shares sum to it exactly). Its removals near its faces saw the halo, so both sides of
    a face are reduced at the same density. The kept points keep the fans the reduction
    re-formed for them; a fan that uses a point another block removed is built again over
    the kept points, and the normals are oriented over the whole result (as
    ``build_fans`` orients).

    Parameters
    ----------
    points : array_like, shape (n, 3), or str or os.PathLike
        The points, or a point file read in chunks (out of core: ``.npy``, ``.ply``,
        ``.las``, ``.laz``; other formats whole, see
        :func:`fancloud_vtk.io.read_point_chunks`), its points sorted into the blocks'
        files (in a temporary folder) as :func:`write_tiled_fans` sorts them, each block a
        task that reads its own; only the kept points are put together here. Exact
        duplicates are merged as ``build_fans`` merges them (the first of each kept, a
        ``DuplicatePointsWarning``).
    n_points, keep
        The target, as in :func:`fancloud_vtk.reduce` (``keep`` of the distinct points).
    k : int, default: 6
        Neighbours per fan.
    tiles : "auto" or tuple of 3 int, default: (2, 2, 2)
        Blocks along x, y and z; ``"auto"``: about ``n / tile_points`` blocks, each cut
        across the longest side (as :func:`write_tiled_fans`).
    halo : float, optional
        The blocks' halo (default: the default halo of :func:`tiled_fans`; for a file, of
        :func:`write_tiled_fans`, from a sample of the points).
    scheduler : None, str or dask.distributed.Client, default: "threads"
        As in :func:`tiled_fans`; ``None``: a ``LocalCluster`` of ``workers``
        single-threaded worker processes (as :func:`write_tiled_fans`), closed at the end.
    workers : int, optional
        With ``scheduler=None``: the worker processes (default: the CPU count).
    tile_points : int, default: 2_000_000
        With ``tiles="auto"``: the points a block should own at most, on average.
    weights, method, max_spacing, error_step
        As in :func:`fancloud_vtk.reduce`.
    max_angle, max_replacements, rule, rotate_sharp_edges, reach, separate_sheets
        The fans' parameters, as in :func:`fancloud_vtk.build_fans` (the blocks' fans and
        the fans built again along their faces).
    point_data : dict or bool, optional
        Arrays with one row per point: the kept points' rows are passed through (one
        named as the fan cloud's own, ``Normals``, ``fan_open``, ``fan_rotated``, is
        dropped with a ``DroppedArrayWarning``). For a file: None or True (default) its
        own arrays, as :func:`fancloud_vtk.io.read_point_chunks` reads them; False none.
    chunk : int, default: 1_000_000
        For a file: the points read at a time.
    progress : callable, optional
        ``progress(fraction, message)`` after each block (``fancloud reduce --tiles``
        draws its bar from it).

    Returns
    -------
    FanCloud
        The reduced fan cloud (exactly the target's points), with the kept rows of
        ``point_data`` and the point array ``original_id`` (rows of ``points``); ``info``
        adds ``tiles``, ``halo``, ``fans_rebuilt`` (the fans built again along the blocks'
        faces), ``input_points``, ``duplicates_merged`` and ``timings``.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.distributed import tiled_reduce
    >>> p = np.random.default_rng(0).normal(size=(40000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> small = tiled_reduce(p, keep=0.2, tiles=(2, 2, 1), scheduler="sync")
    >>> small.n_points
    8000
    """
    dask = _dask("tiled_reduce")
    import os

    from .core.reduction import target_count

    k = _check_fan_options(k, max_angle, max_replacements, rule, reach,
                           separate_sheets=separate_sheets,
                           rotate_sharp_edges=rotate_sharp_edges)[0]
    fan_options = {"max_angle": max_angle, "max_replacements": max_replacements, "rule": rule,
                   "rotate_sharp_edges": rotate_sharp_edges, "reach": reach,
                   "separate_sheets": separate_sheets}
    tile_points = _check_tile_points(tile_points)
    if isinstance(points, str | bytes | os.PathLike):  # out of core: read in chunks
        return _reduce_file(
            dask, points, n_points, keep, k, tiles, halo, scheduler, workers, tile_points,
            (k, tuple(float(x) for x in weights), method, max_spacing, error_step,
             fan_options), fan_options, point_data, chunk, progress)
    pts = as_points(points)
    n = len(pts)
    data = _carried(check_point_data(point_data, n), stacklevel=3)
    _F._check_size(n, k)
    check_spread(pts)
    if _F.Grid(pts).n_dup:  # merged as build_fans merges them: the first of each kept
        first = _F.first_of_duplicates(pts, stacklevel=2)
        fc = tiled_reduce(
            pts[first], n_points, keep, k=k, tiles=tiles, halo=halo, scheduler=scheduler,
            workers=workers, tile_points=tile_points, weights=weights, method=method,
            max_spacing=max_spacing, error_step=error_step, point_data={
                name: arr[first] for name, arr in data.items()},
            progress=progress, **fan_options)
        fc.point_data["original_id"] = first[fc.point_data["original_id"]]
        fc.info.update({"input_points": n, "duplicates_merged": n - len(first)})
        return fc
    target = target_count(n, n_points, keep)
    if isinstance(tiles, str) and tiles == "auto":
        t = _auto_tiles(n, pts.min(axis=0), pts.max(axis=0), tile_points)
    else:
        t = _check_tiles(tiles)
    width = _auto_halo(pts, k) if halo is None else _check_halo(halo)
    t_all = time.perf_counter()
    lo, hi, owner = tile_boxes(pts, t)
    share = _shares(np.bincount(owner, minlength=len(lo)), target)
    options = (k, tuple(float(x) for x in weights), method, max_spacing, error_step,
               fan_options)
    jobs = []
    for i in range(len(lo)):
        own = np.flatnonzero(owner == i)
        if not len(own):
            continue
        ids = _grown(pts, lo[i], hi[i], width)
        jobs.append((pts[ids], ids, own, int(share[i]), options))
    report = progress if progress is not None else (lambda f, m: None)
    report(0.0, f"reduce {len(jobs)} block(s)")
    t0 = time.perf_counter()
    client, close = _client_for(scheduler, workers)
    try:
        parts = list(_map_tasks(dask, client, scheduler, _block, jobs,
                                lambda j: report(0.9 * j / len(jobs),
                                                 f"{j} of {len(jobs)} block(s) reduced")))
    finally:
        if close is not None:
            close()
    timings = {"blocks": time.perf_counter() - t0}
    report(0.9, "stitch the blocks")

    t0 = time.perf_counter()
    fc = _stitch_blocks(parts, k, fan_options, data)
    timings["stitch"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    fc.info.update({"k": k, "tiles": tuple(int(x) for x in t), "halo": width,
                    "input_points": n, "duplicates_merged": 0,
                    "fans_rebuilt": fc.info["fans_rebuilt"],
                    "fans_open": int(fc.open.sum()), "timings": timings})
    report(1.0, "done")
    return fc


def _stitch_blocks(parts, k, fan_options, data=None) -> FanCloud:
    """The blocks' kept points in input order, each with its block's fan where every ring
    member was kept; the others built again over the kept points; the normals oriented
    over the result. ``parts``: the blocks' (global ids, fan sizes, rings in global ids,
    normals, open flags, coordinates, point arrays); ``data``: the input's point arrays
    (whole; None: those the blocks give)."""
    ids_all = np.concatenate([part[0] for part in parts])
    order = np.argsort(ids_all, kind="stable")
    kept = ids_all[order]
    m = len(kept)

    def where(g):  # rows of the kept points, -1 for points removed
        pos = np.minimum(np.searchsorted(kept, g), max(m - 1, 0))
        return np.where(kept[pos] == g, pos, -1) if m else np.full(len(g), -1, np.int64)

    sizes = np.zeros(m, np.int64)
    normals = np.zeros((m, 3))
    is_open = np.zeros(m, bool)
    sub = np.concatenate([part[5] for part in parts])[order]
    for ids, s, _, nrm, op, _, _ in parts:
        at = where(ids)
        sizes[at] = s
        normals[at] = nrm
        is_open[at] = op
    offsets = np.zeros(m + 1, np.int64)
    np.cumsum(sizes, out=offsets[1:])
    ring = np.empty(offsets[-1], np.int64)
    for ids, s, r, _, _, _, _ in parts:
        dst = _positions(offsets[where(ids)], s)
        ring[dst] = where(r)
    bad = np.zeros(m, bool)
    if len(ring):
        owner_of_entry = np.repeat(np.arange(m), sizes)
        bad[owner_of_entry[ring < 0]] = True
    if bad.any():
        fresh = _F.build_fans(sub, k, orient=False, **fan_options)
        fsz = np.diff(fresh.offsets)
        sizes[bad] = fsz[bad]
        normals[bad] = fresh.normals[bad]
        is_open[bad] = fresh.open[bad]
        old_off, old_ring = offsets, ring
        offsets = np.zeros(m + 1, np.int64)
        np.cumsum(sizes, out=offsets[1:])
        src_off = np.where(bad, fresh.offsets[:-1], old_off[:-1])
        take = _positions(src_off, sizes)
        from_fresh = np.repeat(bad, sizes)
        ring = np.empty(offsets[-1], np.int64)
        ring[from_fresh] = fresh.ring[take[from_fresh]]
        ring[~from_fresh] = old_ring[take[~from_fresh]]
    fc = FanCloud(sub, offsets, ring, normals, is_open, np.zeros(m, bool), {}, {})
    fc = _F._orient_fans(fc, np.zeros(m, bool))
    if data is not None:
        for name, arr in data.items():
            fc.point_data[name] = arr[kept]
    elif parts:
        for name in parts[0][6]:
            fc.point_data[name] = np.concatenate([part[6][name] for part in parts])[order]
    fc.point_data["original_id"] = kept
    fc.info["fans_rebuilt"] = int(bad.sum())
    return fc


def _reduce_file(dask, path, n_points, keep, k, tiles, halo, scheduler, workers, tile_points,
                 options, fan_options, point_data, chunk, progress) -> FanCloud:
    """tiled_reduce of a point file read in chunks: its points sorted into the blocks'
    files (as write_tiled_fans sorts them), each block a task reading its own, the result
    (the kept points) put together in this process."""
    import shutil
    import tempfile

    from .core.reduction import target_count

    if point_data is not None and not isinstance(point_data, bool | np.bool_):
        raise FanCloudInputError("point_data arrays go with an array source; a file brings "
                                 "its own (point_data=True or False)")
    chunks = _chunk_source(path, chunk, point_data)
    report = progress if progress is not None else (lambda f, m: None)
    t_all = time.perf_counter()
    timings = {}
    t0 = time.perf_counter()
    report(0.0, "scan the input")
    n, blo, bhi, sample, schema, t = _scan_checked(chunks, k, tiles, tile_points)
    width = _auto_halo_sample(sample, n, k) if halo is None else _check_halo(halo)
    lo, hi, number = _box_grid(blo, bhi, t)
    m = len(lo)
    timings["scan"] = time.perf_counter() - t0
    work = tempfile.mkdtemp(prefix="fancloud-reduce-")
    client, close = _client_for(scheduler, workers)
    try:
        t0 = time.perf_counter()
        report(0.02, f"sort the points into {m} block(s)")
        counts = _bucket(chunks(), work, list(range(m)), lo, hi, np.full(m, width), blo, bhi,
                         t, number, schema)
        timings["sort"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        todo = [i for i in range(m) if counts[i][0]]
        jobs = [(work, i, blo, bhi, t, number, schema) for i in todo]
        own = dict(_map_tasks(dask, client, scheduler, _file_block_size, jobs, None))
        distinct = np.array([own.get(i, 0) for i in range(m)], np.int64)
        n_distinct = int(distinct.sum())
        if n_distinct < n:
            warnings.warn(
                f"{n - n_distinct} duplicate point(s) merged: the first of each set of "
                "identical points is kept; the 'original_id' point array maps the result to "
                "the input", _F.DuplicatePointsWarning, stacklevel=3)
        _F._check_size(n_distinct, k)
        share = _shares(distinct, target_count(n_distinct, n_points, keep))
        jobs = [(work, i, blo, bhi, t, number, schema, int(share[i]), options) for i in todo]
        report(0.05, f"reduce {len(jobs)} block(s)")
        parts = list(_map_tasks(dask, client, scheduler, _file_block, jobs,
                                lambda j: report(0.05 + 0.85 * j / len(jobs),
                                                 f"{j} of {len(jobs)} block(s) reduced")))
        timings["blocks"] = time.perf_counter() - t0
    finally:
        if close is not None:
            close()
        shutil.rmtree(work, ignore_errors=True)
    report(0.9, "stitch the blocks")
    t0 = time.perf_counter()
    fc = _stitch_blocks(parts, k, fan_options)
    timings["stitch"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    fc.info.update({"k": k, "tiles": tuple(int(x) for x in t), "halo": width,
                    "input_points": n, "duplicates_merged": n - n_distinct,
                    "fans_rebuilt": fc.info["fans_rebuilt"],
                    "fans_open": int(fc.open.sum()), "timings": timings})
    report(1.0, "done")
    return fc


def _shares(counts, target) -> np.ndarray:
    """The target split over the blocks by their points, largest remainders first (the
    shares sum to it exactly)."""
    exact = counts * (target / max(int(counts.sum()), 1))
    share = np.floor(exact).astype(np.int64)
    extra = target - int(share.sum())
    share[np.argsort(-(exact - share), kind="stable")[:extra]] += 1
    return share


def _read_block(work, i, blo, bhi, t, number, schema):
    """A block's points from its files: (coordinates, global ids, point arrays, own mask),
    duplicates merged (the lowest id of each kept)."""
    import os

    sub = np.fromfile(os.path.join(work, f"tile_{i:05d}.xyz"), np.float64).reshape(-1, 3)
    ids = np.fromfile(os.path.join(work, f"tile_{i:05d}.ids"), np.int64)
    carried = {name: np.fromfile(os.path.join(work, f"tile_{i:05d}.a{j}"), np.dtype(dt))
               .reshape((len(sub), *shape)) for j, (name, dt, shape) in enumerate(schema)}
    if _F.Grid(sub).n_dup:
        keep = _first_rows(sub, ids)
        sub, ids = sub[keep], ids[keep]
        carried = {name: arr[keep] for name, arr in carried.items()}
    return sub, ids, carried, _owner(sub, blo, bhi, t, number) == i


def _file_block_size(work, i, blo, bhi, t, number, schema):
    """(block, its own distinct points)."""
    return i, int(_read_block(work, i, blo, bhi, t, number, schema)[3].sum())


def _file_block(work, i, blo, bhi, t, number, schema, share, options):
    """One block's task of an out-of-core reduction: _block on the block's files."""
    sub, ids, carried, own = _read_block(work, i, blo, bhi, t, number, schema)
    return _block(sub, ids, ids[own], share, options, carried)


def _block(sub, ids, own, share, options, carried=None):
    """One block's task: the block's kept own points (global ids, sorted), their fan sizes,
    rings (global ids), normals and open flags."""
    from .core.reduction import reduce as _reduce

    k, weights, method, max_spacing, error_step, fan_options = options
    own_mask = np.zeros(len(sub), bool)
    own_mask[np.searchsorted(ids, own)] = True
    need = len(own) - share  # own points to remove
    fc = _F.build_fans(sub, k, **fan_options)
    if need <= 0:
        level, prefix = fc, 0
    else:
        low = max(4, int(len(sub) * share / len(own) * 0.5))
        while True:
            _, h = _reduce(fc, n_points=low, weights=weights, method=method,
                           max_spacing=max_spacing, error_step=error_step,
                           return_hierarchy=True)
            removed_own = np.cumsum(own_mask[h.order])
            if removed_own[-1] >= need or low == 4:
                break
            low = max(4, low // 2)
        prefix = int(np.searchsorted(removed_own, need) + 1)
        level = h.level(len(sub) - prefix)
    loc = level.point_data.get("original_id", np.arange(level.n_points))
    mine = np.flatnonzero(own_mask[loc])
    sizes = np.diff(level.offsets)[mine]
    take = _positions(level.offsets[mine], sizes)
    ring = ids[loc[level.ring[take]]]
    rows = loc[mine]
    return (ids[rows], sizes, ring, level.normals[mine], level.open[mine], sub[rows],
            {name: arr[rows] for name, arr in (carried or {}).items()})




# ----------------------------------------------------------------------------- VDFC forest


def tiled_vdfc(
    source,
    k: int = 6,
    *,
    blocks=None,
    n_blocks: int = 64,
    tiles=(2, 2, 2),
    scheduler="threads",
    workers: int | None = None,
    merge: str = "entropy",
    weights=None,
    n_roots: int = 1,
    colors=None,
    progress=None,
):
    """The merge forest of a view-dependent fan cloud, its blocks as Dask tasks.

    The paper's §8 builds the forest of a terrain in blocks that share their boundary
    points: each block merges its nodes with the shared points left alone, then the blocks
    are united and merged further, so that the forest has no seam.
    :meth:`~fancloud_vtk.ViewDependentFanCloud.build` runs the blocks in threads; here
    each block is a Dask task (its arrays inside the task), on any scheduler, and a point
    set's fans are built in tiles (:func:`tiled_fans`) on the same scheduler. The forest
    is the one ``ViewDependentFanCloud.build(fans, blocks=...)`` gives, array for array,
    whoever runs the blocks. The united merge runs in the calling process, over the nodes
    the blocks leave (the whole forest is in its memory).

    Parameters
    ----------
    source : FanCloud, TriangleMesh or array_like of shape (n, 3)
        The fans (a mesh's one-rings), or points whose fans are built with
        :func:`tiled_fans` (``k``, ``tiles``).
    k : int, default: 6
        Neighbours per fan, for points.
    blocks : list of index arrays or one label per point, optional
        The blocks, as in ``ViewDependentFanCloud.build`` (e.g. from
        :func:`~fancloud_vtk.terrain_blocks` for a height field). Default: about
        ``n_blocks`` spatial blocks (:func:`~fancloud_vtk.point_blocks`).
    n_blocks : int, default: 64
        With ``blocks=None``: the spatial blocks to aim for.
    tiles : tuple of 3 int, default: (2, 2, 2)
        For points: the tiles of :func:`tiled_fans`.
    scheduler : None, str or dask.distributed.Client, default: "threads"
        Where the blocks (and a point set's tiles) run: a Dask scheduler name, a
        ``Client`` or a scheduler address; None: a ``LocalCluster`` of ``workers``
        single-threaded worker processes, closed at the end.
    workers : int, optional
        With ``scheduler=None``: the worker processes (default: the CPU count).
    merge, weights, n_roots, colors
        As in ``ViewDependentFanCloud.build`` (``weights`` None: its default).
    progress : callable, optional
        ``progress(fraction, message)``, after each block.

    Returns
    -------
    ViewDependentFanCloud

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import ViewDependentFanCloud, build_fans, point_blocks
    >>> from fancloud_vtk.distributed import tiled_vdfc
    >>> p = np.random.default_rng(0).normal(size=(6000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> fc = build_fans(p)
    >>> vd = tiled_vdfc(fc, blocks=point_blocks(fc, 4), scheduler="sync")
    >>> one = ViewDependentFanCloud.build(fc, blocks=point_blocks(fc, 4))
    >>> bool(np.array_equal(vd.children, one.children) and np.array_equal(vd.error, one.error))
    True
    """
    dask = _dask("tiled_vdfc")
    from .core.mesh import TriangleMesh
    from .core.vdfc import VDFC_WEIGHTS, ViewDependentFanCloud, point_blocks

    client, close = _client_for(scheduler, workers)
    try:
        if isinstance(source, FanCloud | TriangleMesh):
            fc = source
        else:
            fc = tiled_fans(source, k, tiles=tiles,
                            scheduler=client if client is not None else scheduler)
        if blocks is None:
            blocks = point_blocks(fc, n_blocks)
        report = progress if progress is not None else (lambda f, m: None)
        tasks = _TaskMap(dask, client, scheduler,
                         lambda j, m: report(0.6 * j / m, f"{j} of {m} block(s) merged"))
        return ViewDependentFanCloud.build(
            fc, merge, weights=VDFC_WEIGHTS if weights is None else weights, blocks=blocks,
            n_roots=n_roots, colors=colors, executor=tasks,
            progress=lambda f, m: report(f, m) if f >= 0.6 else None)
    finally:
        if close is not None:
            close()


class _TaskMap:
    """``map(fn, *iterables)`` as Dask tasks, the results in order (the executor that
    ``ViewDependentFanCloud.build`` takes)."""

    def __init__(self, dask, client, scheduler, done=None):
        self.dask, self.client, self.scheduler, self.done = dask, client, scheduler, done

    def map(self, fn, *iterables):
        jobs = [(fn, i, *args) for i, args in enumerate(zip(*iterables, strict=True))]
        out: list = [None] * len(jobs)
        m = len(jobs)
        for i, res in _map_tasks(self.dask, self.client, self.scheduler, _indexed, jobs,
                                 None if self.done is None else
                                 (lambda j: self.done(j, m))):
            out[i] = res
        return out


def _indexed(fn, i, *args):
    """(i, fn(*args)): a task's result with its place."""
    return i, fn(*args)
