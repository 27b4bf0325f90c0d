"""Fan construction (paper section 3): one triangle fan per point.

See :func:`build_fans`; the per-point work is in :mod:`._fan_kernels`.
"""

from __future__ import annotations

import time
import warnings

import numba
import numpy as np
from scipy.spatial import cKDTree

from . import _fan_kernels as K
from . import _grid_kernels as G
from ._normal_kernels import flip_fans, orient_by_propagation, outward_scores, transpose_rings
from .model import FanCloud
from .validation import (
    FanCloudInputError,
    as_normals,
    as_points,
    check_point_data,
    check_spread,
)

RULES = {"cover": K.RULE_COVER, "paper": K.RULE_PAPER}

#: points per range of the parallel normal orientation (fixed, so that the
#: result does not depend on the number of threads)
ORIENT_RANGE = 1 << 16


class DuplicatePointsWarning(UserWarning):
    """Duplicate points were merged before building fans."""


class Cancelled(RuntimeError):
    """The progress callback asked to stop."""


def _report(progress, fraction, message):
    if progress is not None and progress(float(fraction), message):
        raise Cancelled("fan construction was cancelled")


def build_fans(
    points,
    k: int = 6,
    *,
    max_angle: float = 90.0,
    max_replacements: int = 42,
    rule: str = "cover",
    rotate_sharp_edges: bool = True,
    reach: float = 5.0,
    separate_sheets: bool = False,
    normals=None,
    orient: bool = True,
    point_data=None,
    workers: int = -1,
    progress=None,
) -> FanCloud:
    """Build the fan cloud of a point cloud (Linsen & Prautzsch, section 3).

    For every point: its ``k`` nearest neighbours, their least-squares plane,
    the neighbours sorted by angle around the point in that plane, and the
    angle criterion (no gap between consecutive neighbours above
    ``max_angle``) enforced by replacing neighbours with farther ones; if
    that fails, the plane is rotated by 90 degrees about the axis of the
    largest gap (sharp edges), and if that fails too the fan stays open at
    its largest gap (a boundary point).

    Parameters
    ----------
    points : array_like
        ``(n, 3)`` coordinates; not modified. Exact duplicates are merged
        (the first of each kept) with a :class:`DuplicatePointsWarning`, and
        the result then has an ``original_id`` point array.
    k : int, default: 6
        Neighbours per fan (the paper's default).
    max_angle : float, default: 90.0
        Largest angle in degrees between consecutive fan neighbours.
    max_replacements : int, default: 42
        Threshold on neighbour replacements: candidates up to the
        ``k + max_replacements`` nearest are considered. (The paper names
        the threshold but gives no number.)
    rule : {'cover', 'paper'}, default: 'cover'
        Replacement rule. ``'paper'`` is the literal rule: the farthest of
        the ``k`` nearest is replaced by the ``(k+1)``-st, ``(k+2)``-nd, ...
        nearest neighbour. On randomly sampled surfaces it leaves most fans
        open, since ``k`` random directions almost always leave a gap above
        90 degrees. ``'cover'`` grows the candidate set in order of distance
        until it holds ``k`` directions without a gap above ``max_angle``,
        and takes the smallest such subset (containing the newest candidate)
        filled up with the nearest remaining candidates: the farthest fan
        neighbour is as near as possible. Candidates are always the exact
        nearest neighbours in order of distance (ties by index).
    rotate_sharp_edges : bool, default: True
        Retry failed fans in the plane rotated by 90 degrees (Figure 5).
    reach : float, default: 5.0
        Sampling-aware limit, an addition to the paper: a candidate farther
        from the point than ``reach`` times its local spacing never enters
        its fan, which stays open instead (its ``k`` nearest always enter:
        below about 4.5 they may lie beyond). The local spacing is the distance
        of the ``k``-th nearest neighbour, times the square root of the part
        of the circle that the ``k`` nearest cover (up to 3/4), so that a
        point on a boundary gets about the spacing of the points inside. A
        fan still open is retried with the candidates within ``reach`` times
        the larger of the two points' spacings (where the density jumps).
        Fans then do not bridge gaps of the sampling (holes and occlusion
        gaps of range scans) nor reach out to stray
        clusters, and isolated clusters stay separate. ``0`` turns the
        limit off (the paper's rule). On random samples of smooth surfaces
        it leaves no fan open (``tests/test_real_data.py``).
    separate_sheets : bool, default: False
        An addition to the paper: where a point's nearest neighbours form two
        parallel layers (two sheets closer than the spacing: the two sides of
        a thin part), the candidates of the other layer do not enter its fan,
        so the two sheets are not joined (docs/fans.md). Off by default for
        now: on the cow of the corpus it changes a few fans at the ears, and
        the mesh's hole filling then closes a hole between the front legs
        with a bridge.
    normals : array_like, optional
        ``(n, 3)`` normals given with the input: fan normals are oriented to
        agree with them.
    orient : bool, default: True
        Without given normals, orient the normals consistently by
        propagation over the fan adjacency (Hoppe et al. 1992), outward on
        closed surfaces.
    point_data : dict, optional
        Arrays with one row per point, passed through to the result.
    workers : int, default: -1
        Threads for the kd-tree that serves the rare points the uniform grid
        cannot (outliers, fans still open after the grid search; -1: all
        cores). Everything else runs on numba's threads
        (``NUMBA_NUM_THREADS``). The result does not depend on the number of
        threads.
    progress : callable, optional
        ``progress(fraction, message)``; a true return value cancels.

    Returns
    -------
    FanCloud
        Rings counter-clockwise around unit normals; ``info`` holds counts
        and timings.

    Raises
    ------
    TypeError
        ``points`` is not numeric.
    FanCloudInputError
        (a ``ValueError``) for NaN/inf coordinates, a wrong shape, fewer
        than ``k + 1`` distinct points, or points all identical or collinear.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> fc = build_fans(p, k=6)
    >>> fc.n_points, fc.n_open
    (2000, 0)
    """
    k, max_angle, max_replacements, rule_id = _check_parameters(
        k, max_angle, max_replacements, rule
    )
    reach = _check_reach(reach)
    if not isinstance(separate_sheets, bool | np.bool_):
        raise TypeError(f"separate_sheets must be True or False, got {separate_sheets!r}")
    pts = as_points(points)
    n = len(pts)
    given_normals = None if normals is None else as_normals(normals, n)
    pdata = check_point_data(point_data, n)
    _check_size(n, k)
    check_spread(pts)
    return _fans(pts, k, max_angle, max_replacements, rule, rule_id, rotate_sharp_edges, reach,
                 separate_sheets, given_normals, orient, pdata, workers, progress)[0]


def _fans(pts, k, max_angle, max_replacements, rule, rule_id, rotate_sharp_edges, reach,
          separate_sheets, given_normals, orient, pdata, workers, progress, cells=None):
    """:func:`build_fans` on checked arguments: (fan cloud, no_plane), ``no_plane`` (n,) in
    the input order (True where the fan's plane stands in for a normal the nearest points
    do not give: what the orientation needs besides the fans), or None when duplicate
    points were merged. ``cells``: (lo, h) of the whole cloud's grid when ``pts`` are a
    part of it (a tile, its points in the whole cloud's order): the work then runs in the
    whole cloud's cell order, which breaks ties between equal distances as it does."""
    n = len(pts)
    timings = {}
    t0 = time.perf_counter()
    _report(progress, 0.0, "neighbour search")
    grid = Grid(pts, cells)
    if grid.n_dup:
        return _merge_duplicates(
            pts, k, given_normals, pdata,
            dict(max_angle=max_angle, max_replacements=max_replacements, rule=rule,
                 rotate_sharp_edges=rotate_sharp_edges, reach=reach,
                 separate_sheets=separate_sheets, orient=orient, workers=workers,
                 progress=progress),
        ), None
    # Work in the grid's cell order: spatially coherent, so the candidate
    # pools of consecutive points are close in memory (several times faster).
    order, pos, sp = grid.order, grid.pos, grid.sorted_points
    timings["neighbours"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    max_gap = np.deg2rad(max_angle) + 1e-9
    n_normal = min(2 * k, n - 1)  # the stored normal fits the 2k nearest
    cap = min(k + max_replacements, n - 1)
    ring_tab = np.full((n, k), -1, np.int64)
    counts = np.zeros(n, np.int64)
    status = np.zeros(n, np.int8)
    normals_s = np.empty((n, 3), np.float64)
    spacing = np.zeros(n, np.float64)
    no_plane = np.zeros(n, bool)  # the normal is the fan's plane: the 2k nearest have none
    n_cells = grid.n_cells
    n_blocks = max(1, min(16, n // 50_000))
    for b in range(n_blocks):
        K.fans_from_grid(sp, grid.lo, grid.h, grid.start, grid.cell_xyz, grid.table,
                         (n_cells * b) // n_blocks, (n_cells * (b + 1)) // n_blocks,
                         k, cap, max_gap, rule_id, rotate_sharp_edges, n_normal,
                         n_normal + k // 2, grid.MAX_BLOCK, 4 * numba.get_num_threads(),
                         reach, bool(separate_sheets), ring_tab, counts, status, normals_s,
                         spacing, no_plane)
        _report(progress, 0.05 + 0.75 * (b + 1) / n_blocks, "fans")

    retry = np.flatnonzero(status == K.STATUS_RETRY)
    tree = None
    if len(retry):
        # stage 2: the exact k + max_replacements nearest, from wider blocks of cells
        pools, tree = grid.knn(retry, cap, tree, workers)
        K.fans_from_pool(sp, retry, pools, k, max_gap, rule_id, rotate_sharp_edges, n_normal,
                         reach, bool(separate_sheets), ring_tab, counts, status, normals_s,
                         spacing, no_plane)
        del pools
    if rule_id == K.RULE_COVER and np.any(status == K.STATUS_OPEN):
        if tree is None:
            tree = cKDTree(sp, balanced_tree=False)
        _gap_directed_retry(sp, tree, k, cap + 1, max_gap, rotate_sharp_edges, n_normal, reach,
                            bool(separate_sheets), spacing, ring_tab, counts, status, normals_s,
                            no_plane, workers)
    del tree
    timings["fans"] = time.perf_counter() - t1
    _report(progress, 0.85, "orienting normals")

    t2 = time.perf_counter()
    if given_normals is not None:
        flip = np.einsum("ij,ij->i", normals_s, given_normals[order]) < 0
    elif orient:
        flip = _orientation(sp, normals_s, ring_tab, counts, no_plane)
    else:
        flip = np.zeros(n, bool)
    flip_fans(normals_s, ring_tab, counts, flip)
    timings["orientation"] = time.perf_counter() - t2

    # back to the input order
    t3 = time.perf_counter()
    offsets, ring, fan_normals = K.to_input_order(order, pos, ring_tab, counts, normals_s)
    del ring_tab, normals_s, sp
    status = status[pos]
    open_ = status == K.STATUS_OPEN
    rotated = status == K.STATUS_ROTATED
    timings["output"] = time.perf_counter() - t3
    _report(progress, 1.0, "done")

    info = {
        "k": k,
        "rule": rule,
        "max_angle": max_angle,
        "max_replacements": max_replacements,
        "reach": reach,
        "separate_sheets": bool(separate_sheets),
        "fans_open": int(open_.sum()),
        "fans_rotated": int(rotated.sum()),
        "fans_wider_search": int(len(retry)),
        "duplicates_merged": 0,
        "timings": timings,
    }
    return FanCloud(pts, offsets, ring, fan_normals, open_, rotated, pdata, info), no_plane[pos]


def _gap_directed_retry(sp, tree, k, width, max_gap, rotate, n_normal, reach, sheets, spacing,
                        ring_tab,
                        counts, status, normals, no_plane, workers, n_dir=16,
                        steps=(1.0, 2.0, 4.0),
                        rounds=2):
    """Retry open fans with candidates searched in the direction of their void.

    Where sampling density jumps, the nearest candidates all lie on the dense
    side and leave a void on the sparse one. For each open fan, the largest
    angular gap among its candidates is found, and the nearest neighbours of
    points placed into that gap (at 1, 2 and 4 times the distance of the
    farthest candidate, along the gap's bisector) join the candidates, in
    order of distance; twice. On a real boundary these lie on the same side
    again, and the fan stays open.

    With ``reach > 0``, a candidate q stays in p's pool when it lies within
    ``reach`` times the larger of the two local spacings (``spacing``, the
    distance of the k-th nearest neighbour): where the density jumps, the
    dense side's fans may then reach the sparse side's points at the sparse
    side's spacing, while gaps in the sampling stay open.
    """
    n = len(sp)
    idx = np.flatnonzero(status == K.STATUS_OPEN)
    if len(idx) == 0:
        return
    pools = tree.query(sp[idx], k=min(width, n), workers=workers)[1].reshape(len(idx), -1)
    for _ in range(rounds):
        p = sp[idx]
        nrm = normals[idx]
        rel = sp[np.maximum(pools, 0)] - p[:, None, :]
        u = np.cross(nrm, np.where(np.abs(nrm[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
        u /= np.linalg.norm(u, axis=1)[:, None]
        v = np.cross(nrm, u)
        ang = np.arctan2(np.einsum("ijk,ik->ij", rel, v), np.einsum("ijk,ik->ij", rel, u))
        ang = np.where(pools >= 0, ang, 100.0)  # missing candidates sort last
        srt = np.sort(ang, axis=1)
        valid = srt < 50.0
        last = np.where(valid, srt, -np.inf).max(axis=1)
        gaps = np.diff(srt, axis=1)
        gaps[~valid[:, 1:]] = -np.inf
        wrap = srt[:, 0] + 2 * np.pi - last
        j = np.argmax(gaps, axis=1)
        use_wrap = wrap >= gaps[np.arange(len(idx)), j]
        start = np.where(use_wrap, last, srt[np.arange(len(idx)), j])
        width_gap = np.where(use_wrap, wrap, gaps[np.arange(len(idx)), j])
        mid = start + 0.5 * width_gap
        bis = np.cos(mid)[:, None] * u + np.sin(mid)[:, None] * v
        radius = np.where(pools >= 0, np.linalg.norm(rel, axis=2), 0.0).max(axis=1)
        parts = [pools]
        for step in steps:
            centre = p + (step * radius)[:, None] * bis
            found = tree.query(centre, k=min(n_dir, n), workers=workers)[1]
            parts.append(found.reshape(len(idx), -1))
        pools = _sorted_unique_rows(sp, np.concatenate(parts, axis=1), p)
        cand = pools
        if reach > 0.0:
            cand = _within_reach(sp, idx, pools, spacing, reach, k)
        K.fans_from_pool(sp, idx, cand, k, max_gap, K.RULE_COVER, rotate, n_normal, 0.0, sheets,
                         ring_tab, counts, status, normals, spacing, no_plane)
        still = status[idx] == K.STATUS_OPEN
        if not still.any():
            return
        idx = idx[still]
        pools = pools[still]


def _within_reach(sp, idx, pools, spacing, reach, k):
    """The pools (in order of distance) with the candidates beyond reach times the larger
    spacing set to -1 (moved last, the order kept); the k nearest other points always stay,
    as in :func:`~._fan_kernels.reach_limit` (a fan of fewer has no plane)."""
    q = np.maximum(pools, 0)
    d = np.linalg.norm(sp[q] - sp[idx][:, None, :], axis=2)
    other = (pools >= 0) & (pools != idx[:, None])
    nearest = other & (np.cumsum(other, axis=1) <= k)
    ok = other & (nearest | (d <= reach * np.maximum(spacing[idx][:, None], spacing[q])))
    order = np.argsort(~ok, axis=1, kind="stable")
    out = np.take_along_axis(np.where(ok, pools, -1), order, 1)
    return np.ascontiguousarray(out)


def _sorted_unique_rows(sp, pools, p):
    """Each row's candidates once, in order of distance from p (duplicates -> -1, last)."""
    dist = np.linalg.norm(sp[np.maximum(pools, 0)] - p[:, None, :], axis=2)
    dist[pools < 0] = np.inf
    order = np.argsort(pools, axis=1, kind="stable")
    pools = np.take_along_axis(pools, order, 1)
    dist = np.take_along_axis(dist, order, 1)
    dup = np.zeros(pools.shape, bool)
    dup[:, 1:] = pools[:, 1:] == pools[:, :-1]
    dist[dup] = np.inf
    pools[dup] = -1
    order = np.argsort(dist, axis=1, kind="stable")
    return np.ascontiguousarray(np.take_along_axis(pools, order, 1))


class Grid:
    """The points bucketed into uniform cells (:mod:`._grid_kernels`), in cell order."""

    #: points per occupied cell: the 27 cells around a point then certify
    #: about 2k = 12 nearest neighbours and the candidates the angle
    #: criterion usually needs
    TARGET_OCCUPANCY = 8
    #: a block of cells with more points than this (a dense cluster in a
    #: cloud with far outliers, whose cells the 21-bit grid cannot make
    #: small enough) goes to a kd-tree instead: never quadratic work
    MAX_BLOCK = 4096

    def __init__(self, pts: np.ndarray, cells=None):
        if cells is None:
            self.lo, hi = G.bounds(pts)
            # (all one point: a tile of copies of one point, whose duplicates it counts)
            extent = float((hi - self.lo).max()) or 1.0
            self.h = G.cell_size(pts, self.lo, extent, self.TARGET_OCCUPANCY)
        else:  # a part of a cloud in the whole cloud's cells (a tile): the same order
            self.lo, self.h = np.array(cells[0], np.float64), float(cells[1])
        (self.order, self.start, self.cell_xyz, self.table,
         self.n_dup) = G.build_grid(pts, self.lo, 1.0 / self.h,
                                   int(len(pts) / self.TARGET_OCCUPANCY))
        self.n_cells = len(self.start) - 1
        self.sorted_points, self.pos = G.reorder(pts, self.order)

    def knn(self, which: np.ndarray, kq: int, tree, workers: int, w_max: int = 3):
        """Exact kq nearest (self excluded) of sorted points ``which``, in order.

        Wider blocks of cells first; a kd-tree (built once, returned for
        reuse) for the few points that ``w_max`` rings of cells cannot
        certify (outliers, large voids).
        """
        cell_of = np.repeat(np.arange(self.n_cells, dtype=np.int64), np.diff(self.start))
        out = np.full((len(which), kq), -1, np.int64)
        ok = G.knn_grid(self.sorted_points, self.lo, self.h, self.start, self.cell_xyz,
                        self.table, cell_of, which, kq, w_max, self.MAX_BLOCK, out)
        if not ok.all():
            bad = np.flatnonzero(~ok)
            if tree is None:
                tree = cKDTree(self.sorted_points, balanced_tree=False)
            _, idx = tree.query(self.sorted_points[which[bad]], k=kq + 1, workers=workers)
            idx = np.asarray(idx, np.int64).reshape(len(bad), kq + 1)
            # drop the point itself (a duplicate-free cloud: it is the nearest)
            out[bad] = idx[:, 1:]
        return out, tree


def _check_parameters(k, max_angle, max_replacements, rule):
    if isinstance(k, bool) or not isinstance(k, int | np.integer):
        raise TypeError(f"k must be an integer, got {type(k).__name__}")
    if not 3 <= k <= 64:
        raise FanCloudInputError(f"k must be between 3 and 64, got {k}")
    try:
        max_angle = float(max_angle)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"max_angle must be a number of degrees, got {max_angle!r}") from exc
    if not 0.0 < max_angle < 180.0:
        raise FanCloudInputError(f"max_angle must be in (0, 180) degrees, got {max_angle}")
    if isinstance(max_replacements, bool) or not isinstance(max_replacements, int | np.integer):
        raise TypeError("max_replacements must be an integer")
    if not 0 <= max_replacements <= 1000:
        raise FanCloudInputError(
            f"max_replacements must be between 0 and 1000, got {max_replacements}"
        )
    if rule not in RULES:
        raise FanCloudInputError(f"rule must be one of {sorted(RULES)}, got {rule!r}")
    return int(k), max_angle, int(max_replacements), RULES[rule]


def _check_reach(reach):
    if isinstance(reach, bool):
        raise TypeError(f"reach must be a number, got {reach!r}")
    try:
        reach = float(reach)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"reach must be a number, got {reach!r}") from exc
    if not (reach == 0.0 or 1.0 <= reach <= 1e6):
        raise FanCloudInputError(f"reach must be 0 (off) or between 1 and 1e6, got {reach}")
    return reach


def _check_size(n, k):
    if n < k + 1:
        raise FanCloudInputError(
            f"a fan cloud with k={k} needs at least k + 1 = {k + 1} distinct points, got {n}"
        )


def first_of_duplicates(pts, stacklevel: int = 2) -> np.ndarray:
    """The rows of ``pts`` that merging exact duplicates keeps (the first of each set of
    identical points), increasing; a :class:`DuplicatePointsWarning` when any row goes
    (``stacklevel`` counts from the caller of this function). The one rule of
    ``build_fans``, ``tiled_fans`` and ``fancloud reduce --tiles``."""
    _, first = np.unique(pts, axis=0, return_index=True)
    keep = np.sort(first)
    if len(keep) < len(pts):
        warnings.warn(
            f"{len(pts) - len(keep)} duplicate point(s) merged: the first of each set of "
            "identical points is kept; the 'original_id' point array maps the result to the "
            "input", DuplicatePointsWarning, stacklevel=stacklevel + 1)
    return keep


def _merge_duplicates(pts, k, given_normals, pdata, kwargs):
    keep = first_of_duplicates(pts, stacklevel=4)  # <- _fans <- build_fans <- caller
    n_dup = len(pts) - len(keep)
    _check_size(len(keep), k)
    sub = {name: arr[keep] for name, arr in pdata.items()}
    sub["original_id"] = keep.astype(np.int64)
    fc = build_fans(
        pts[keep], k,
        normals=None if given_normals is None else given_normals[keep],
        point_data=sub, **kwargs,
    )
    fc.info["duplicates_merged"] = n_dup
    return fc


def _orientation(points, normals, ring_tab, counts, no_plane):
    """Signs for consistent normals: propagation, then outward per component."""
    t_off, t_src = transpose_rings(ring_tab, counts)
    flip, comp = orient_by_propagation(points, normals, no_plane, ring_tab, counts, t_off, t_src,
                                      32, ORIENT_RANGE)
    del t_off, t_src
    n_comp = int(comp.max()) + 1
    score = outward_scores(points, normals, flip, ring_tab, counts, comp, n_comp)
    return flip ^ (score < 0)[comp]


def _orient_fans(fc: FanCloud, no_plane, grid: Grid | None = None) -> FanCloud:
    """The unoriented fan cloud ``fc`` (``build_fans(..., orient=False)``, or fans stitched
    from tiles) oriented as :func:`build_fans` orients: the same propagation on the same
    spatial order of the points, so the result is the one ``build_fans(fc.points)`` gives.
    ``no_plane`` (n,): see :func:`_fans`; ``grid``: ``Grid(fc.points)`` if made already."""
    grid = Grid(fc.points) if grid is None else grid
    width = max(int(np.diff(fc.offsets).max(initial=0)), 1)
    ring_tab, counts, normals_s, plane_s = K.to_cell_order(
        grid.pos, fc.offsets, fc.ring, fc.normals, np.asarray(no_plane, bool), width)
    flip = _orientation(grid.sorted_points, normals_s, ring_tab, counts, plane_s)
    flip_fans(normals_s, ring_tab, counts, flip)
    offsets, ring, normals = K.to_input_order(grid.order, grid.pos, ring_tab, counts, normals_s)
    return FanCloud(fc.points, offsets, ring, normals, fc.open, fc.rotated, fc.point_data,
                    dict(fc.info))
