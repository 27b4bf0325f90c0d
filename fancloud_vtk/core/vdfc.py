"""View-dependent fan clouds (paper section 8): merge forest, error, active front.

:meth:`ViewDependentFanCloud.build` merges, again and again, the point of
lowest entropy ``p`` with its lowest-entropy neighbour ``q`` into

    r = (M(p) p + M(q) q) / (M(p) + M(q))     (or r at q: half-edge collapse)

whose neighbours are those of ``p`` and ``q`` minus ``p`` and ``q``. The
merges make a forest: every node stores its two children, its position,
its fan at merge time and e(r), the largest distance of its descendants
(the original points) from that fan, computed once in preprocessing.

:meth:`ViewDependentFanCloud.front_arrays` walks the forest for a camera: a node is
refined (its children shown instead) when it is in the view frustum and
``e(r) > d(r) / d_max * e_max``. The front is kept between calls and only
moved where the camera changed it. The active fans are drawn; a fan
neighbour that is not active is replaced by its active ancestor (or, if it
is refined, by its active descendant nearest to the fan's point).

Terrain: :func:`terrain_fan_cloud` makes a fan cloud from a height field,
:func:`terrain_blocks` cuts its grid into blocks that share their boundary
rows and columns; ``build(blocks=...)`` builds every block's forest without
merging the shared points, then unites them and merges further (so adjacent
blocks always agree on their shared points: no crack).
:meth:`ViewDependentFanCloud.add_object` adds another fan cloud (a building,
a ledge) as further trees of the same forest.

Two choices go beyond the paper's text, to make the front well defined and
incremental (see docs/vdfc.md): d(r) is the distance from the viewpoint to
the node's bounding sphere (which holds its descendants), and the test uses
``bound(r)``, the largest e over r and its descendants (at least a tiny
floor on inner nodes). Then refining a node always implies refining its
parent, the front from scratch is unique, and the incremental front equals
it. The ``error`` array of the front is e(r) itself.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from . import _entropy_kernels as EK
from . import _vdfc_kernels as VK
from .entropy import as_colors, as_fan_cloud, check_weights
from .mesh import TriangleMesh
from .model import FanCloud, find_color_array
from .validation import FanCloudInputError

#: Entropy weights of the merges (a1 distance, a2 curvature, a3 change, a4 colour).
VDFC_WEIGHTS = (1.0, 1.0, 0.0, 0.0)
MERGES = ("entropy", "half_edge")
#: Width of the neighbour table during the build: a merge whose neighbour set
#: would exceed it waits (the pair is skipped).
WIDTH = 32
FORMAT = "fancloud-vdfc-1"
#: Front size (nodes of the previous front) from which the front update runs on all numba threads.
PARALLEL_FRONT = 8192


# -- terrain -------------------------------------------------------------------------


def terrain_fan_cloud(heights, spacing=1.0, origin=(0.0, 0.0), *, point_data=None) -> FanCloud:
    """A fan cloud of a height field: one point per grid node, fans of the grid.

    Point ``(i, j)`` is ``(origin[0] + j * dx, origin[1] + i * dy,
    heights[i, j])``, with index ``i * nx + j``. Each fan is the six
    neighbours of the regular triangulation with diagonals ``(i, j)`` to
    ``(i + 1, j + 1)``, counter-clockwise seen from above; the fans on the
    border are open. The normals come from the height gradient (upward).

    Parameters
    ----------
    heights : numpy.ndarray
        ``(ny, nx)`` finite heights, ``ny, nx >= 2``.
    spacing : float or (float, float), default: 1.0
        Grid spacing ``dx`` (or ``(dx, dy)``), positive.
    origin : (float, float), default: (0, 0)
        x and y of ``heights[0, 0]``.
    point_data : dict, optional
        Arrays of shape ``(ny, nx, ...)`` or ``(ny * nx, ...)`` to carry along.

    Returns
    -------
    FanCloud

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import terrain_fan_cloud
    >>> z = np.add.outer(np.sin(np.linspace(0, 3, 40)), np.cos(np.linspace(0, 3, 50)))
    >>> fc = terrain_fan_cloud(z, spacing=0.1)
    >>> fc.n_points, int(fc.fan_sizes.max()), fc.n_open
    (2000, 6, 176)
    """
    try:
        h = np.asarray(heights)
    except Exception as exc:
        raise TypeError(f"heights must be a 2-d array of numbers: {exc}") from exc
    if h.dtype == object or h.dtype.kind not in "biuf":
        raise TypeError(f"heights must be a 2-d array of real numbers, got dtype {h.dtype}")
    if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2:
        raise FanCloudInputError(f"heights must be a 2-d grid of at least 2 x 2, got {h.shape}")
    h = np.array(h, dtype=np.float64)
    if not np.isfinite(h).all():
        bad = np.argwhere(~np.isfinite(h))[0]
        raise FanCloudInputError(
            f"heights contain NaN or infinite values ({int((~np.isfinite(h)).sum())}), "
            f"first at {tuple(int(v) for v in bad)}"
        )
    sp = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (2,))
    if not (np.isfinite(sp).all() and (sp > 0).all()):
        raise FanCloudInputError(f"spacing must be positive and finite, got {spacing!r}")
    org = np.asarray(origin, dtype=np.float64)
    if org.shape != (2,) or not np.isfinite(org).all():
        raise FanCloudInputError(f"origin must be two finite numbers, got {origin!r}")
    ny, nx = h.shape
    jj, ii = np.meshgrid(np.arange(nx), np.arange(ny))
    pts = np.column_stack([org[0] + jj.ravel() * sp[0], org[1] + ii.ravel() * sp[1], h.ravel()])
    gy, gx = np.gradient(h, sp[1], sp[0])
    nrm = np.column_stack([-gx.ravel(), -gy.ravel(), np.ones(h.size)])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    # the six neighbours counter-clockwise from east: E, NE, N, W, SW, S
    di = np.array([0, 1, 1, 0, -1, -1])
    dj = np.array([1, 1, 0, -1, -1, 0])
    ni = ii.ravel()[:, None] + di
    nj = jj.ravel()[:, None] + dj
    ok = (ni >= 0) & (ni < ny) & (nj >= 0) & (nj < nx)
    nb = np.where(ok, ni * nx + nj, -1)
    is_open = ~ok.all(axis=1)
    # an open fan starts after its gap: the first present neighbour after a missing one
    start = np.zeros(h.size, dtype=np.int64)
    after_gap = ok & ~np.roll(ok, 1, axis=1)
    has = after_gap.any(axis=1)
    start[has] = np.argmax(after_gap[has], axis=1)
    cols = (start[:, None] + np.arange(6)) % 6
    nb = np.take_along_axis(nb, cols, axis=1)
    sizes = ok.sum(axis=1)
    # present entries are contiguous from the start in cyclic order
    ring = nb[nb >= 0].astype(np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    pdata = {}
    for name, arr in (point_data or {}).items():
        a = np.asarray(arr)
        if a.shape[:2] == (ny, nx):
            a = a.reshape((ny * nx,) + a.shape[2:])
        if a.shape[0] != ny * nx:
            raise FanCloudInputError(
                f"point array {name!r} has shape {a.shape}, expected ({ny}, {nx}, ...) "
                f"or ({ny * nx}, ...)")
        pdata[name] = a.copy()
    return FanCloud(pts, offsets, ring, nrm, is_open, None, pdata,
                    {"grid_shape": (ny, nx)})


def terrain_blocks(shape, block_shape) -> list[np.ndarray]:
    """Point indices of the blocks of a ``(ny, nx)`` grid that share their boundary.

    Blocks of about ``block_shape = (by, bx)`` grid cells; neighbouring
    blocks share one row or column of points (the corner points are shared
    by up to four). For :meth:`ViewDependentFanCloud.build` ``blocks=``, on
    a cloud from :func:`terrain_fan_cloud` of the same shape.

    Examples
    --------
    >>> from fancloud_vtk import terrain_blocks
    >>> blocks = terrain_blocks((5, 7), (2, 3))
    >>> len(blocks), sorted(blocks[0].tolist())
    (4, [0, 1, 2, 3, 7, 8, 9, 10, 14, 15, 16, 17])
    """
    ny, nx = (int(v) for v in shape)
    by, bx = (int(v) for v in np.broadcast_to(block_shape, (2,)))
    if ny < 2 or nx < 2:
        raise ValueError(f"shape must be at least (2, 2), got {shape!r}")
    if by < 1 or bx < 1:
        raise ValueError(f"block_shape must be at least 1 cell each way, got {block_shape!r}")

    def cuts(n, b):
        k = max(1, int(round((n - 1) / b)))
        return np.unique(np.round(np.linspace(0, n - 1, k + 1)).astype(np.int64))

    ci, cj = cuts(ny, by), cuts(nx, bx)
    blocks = []
    for a in range(len(ci) - 1):
        for b in range(len(cj) - 1):
            ii, jj = np.meshgrid(np.arange(ci[a], ci[a + 1] + 1), np.arange(cj[b], cj[b + 1] + 1),
                                 indexing="ij")
            blocks.append((ii * nx + jj).ravel().astype(np.int64))
    return blocks


def point_blocks(fancloud, n_blocks: int = 64) -> list[np.ndarray]:
    """Point indices of spatial blocks of a fan cloud that share their boundary points.

    The bounding box is cut into about ``n_blocks`` cells of equal sides
    (a side along which the box is thinner than a cell is not cut: a
    terrain's blocks are columns). Each point is in its cell's block and in
    the block of each of its fan neighbours, so every fan edge lies in one
    block: the points along the cuts are shared. For
    :meth:`ViewDependentFanCloud.build` ``blocks=`` on point sets and
    meshes, as :func:`terrain_blocks` is for height fields (the paper's
    section 8 does this for terrain).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, point_blocks
    >>> rng = np.random.default_rng(0)
    >>> fc = build_fans(np.column_stack([rng.random((2000, 2)), np.zeros(2000)]))
    >>> blocks = point_blocks(fc, 4)
    >>> len(blocks), sum(map(len, blocks)) > fc.n_points
    (4, True)
    """
    fc = as_fan_cloud(fancloud)
    if isinstance(n_blocks, (bool, np.bool_)) or not isinstance(n_blocks, (int, np.integer)) \
            or n_blocks < 1:
        raise ValueError(f"n_blocks must be an integer >= 1, got {n_blocks!r}")
    p = fc.points
    if len(p) == 0:
        raise ValueError("the fan cloud is empty: no points to cut into blocks")
    lo, hi = p.min(axis=0), p.max(axis=0)
    ext = hi - lo
    cut = ext > 0
    side = 1.0
    while cut.any():
        side = float(np.prod(ext[cut]) / n_blocks) ** (1.0 / int(cut.sum()))
        thin = cut & (ext < side)
        if not thin.any():
            break
        cut &= ~thin
    dims = np.ones(3, np.int64)
    if cut.any():
        dims[cut] = np.maximum(1, np.round(ext[cut] / side)).astype(np.int64)
    cell = np.floor((p - lo) / np.where(ext > 0, ext, 1.0) * dims).astype(np.int64)
    cell = np.minimum(cell, dims - 1)
    label = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    used, label = np.unique(label, return_inverse=True)
    off, members = VK.point_block_members(label.astype(np.int64), fc.offsets, fc.ring,
                                          len(used))
    return [members[off[b]:off[b + 1]] for b in range(len(used))]


def terrain_path(bounds, n_frames: int = 120, *, height: float = 0.15, look_ahead: float = 0.3,
                 view_angle: float = 45.0, aspect: float = 4 / 3) -> list[tuple]:
    """A smooth fly-through over a terrain: camera tuples along a gentle S-curve.

    The eye flies from one end of the bounds to the other (along the longer
    side) at ``height`` times the diagonal above the top, weaving sideways,
    and looks ``look_ahead`` times the length ahead, down at the ground.

    Parameters
    ----------
    bounds : sequence of 6 float
        ``(xmin, xmax, ymin, ymax, zmin, zmax)`` of the terrain.
    n_frames : int, default: 120
        Number of cameras (>= 2).

    Returns
    -------
    list of tuple
        ``(position, focal_point, view_up, view_angle, aspect)`` per frame.

    Examples
    --------
    >>> from fancloud_vtk import terrain_path
    >>> path = terrain_path((0, 100, 0, 50, 0, 10), 5)
    >>> len(path), path[0][2]
    (5, (0.0, 0.0, 1.0))
    """
    b = np.asarray(bounds, dtype=np.float64)
    if b.shape != (6,) or not np.isfinite(b).all() or (b[1::2] < b[::2]).any():
        raise ValueError(f"bounds must be (xmin, xmax, ymin, ymax, zmin, zmax), got {bounds!r}")
    if isinstance(n_frames, (bool, np.bool_)) or not isinstance(n_frames, (int, np.integer)) \
            or n_frames < 2:
        raise ValueError(f"n_frames must be an integer >= 2, got {n_frames!r}")
    lo, hi = b[::2], b[1::2]
    size = hi - lo
    diag = float(np.linalg.norm(size))
    along = 0 if size[0] >= size[1] else 1
    side = 1 - along
    t = np.linspace(0.05, 0.95 - look_ahead * 0.5, n_frames)
    cams = []
    for u in t:
        eye = np.empty(3)
        eye[along] = lo[along] + u * size[along]
        eye[side] = lo[side] + size[side] * (0.5 + 0.25 * np.sin(2 * np.pi * u))
        eye[2] = hi[2] + height * diag
        u2 = min(u + look_ahead, 1.0)
        focal = np.empty(3)
        focal[along] = lo[along] + u2 * size[along]
        focal[side] = lo[side] + size[side] * (0.5 + 0.25 * np.sin(2 * np.pi * u2))
        focal[2] = lo[2] + 0.5 * size[2]
        cams.append((tuple(float(v) for v in eye), tuple(float(v) for v in focal),
                     (0.0, 0.0, 1.0), float(view_angle), float(aspect)))
    return cams


# -- cameras -------------------------------------------------------------------------


@dataclass(frozen=True)
class Camera:
    """A perspective camera: eye, focal point, view up, vertical view angle, aspect."""

    position: tuple
    focal_point: tuple
    view_up: tuple
    view_angle: float
    aspect: float = 1.0

    @classmethod
    def of(cls, camera, aspect=None) -> Camera:
        """A :class:`Camera` from a ``vtkCamera`` (or PyVista's), a tuple or a Camera.

        A tuple is ``(position, focal_point, view_up, view_angle[, aspect[,
        clipping_range]])``; the clipping range is accepted and not used
        (viewers set it to fit what is drawn, so it cannot cull).
        """
        if isinstance(camera, Camera):
            cam = camera if aspect is None else Camera(*camera.as_tuple()[:4], aspect)
        elif hasattr(camera, "GetPosition") and hasattr(camera, "GetViewAngle"):
            if camera.GetParallelProjection():
                raise ValueError("the camera uses parallel projection: the view-dependent "
                                 "front needs a perspective camera (distances to the eye)")
            cam = cls(tuple(camera.GetPosition()), tuple(camera.GetFocalPoint()),
                      tuple(camera.GetViewUp()), float(camera.GetViewAngle()),
                      1.0 if aspect is None else aspect)
        else:
            try:
                parts = list(camera)
            except TypeError:
                raise TypeError("camera must be a vtkCamera, a pyvista Camera, a Camera or a "
                                "tuple (position, focal_point, view_up, view_angle[, aspect])"
                                f", got {type(camera).__name__}") from None
            if len(parts) not in (4, 5, 6):
                raise ValueError("a camera tuple is (position, focal_point, view_up, view_angle"
                                 f"[, aspect[, clipping_range]]), got {len(parts)} entries")
            asp = parts[4] if len(parts) > 4 else 1.0
            cam = cls(parts[0], parts[1], parts[2], parts[3], asp if aspect is None else aspect)
        cam._check()
        return cam

    def as_tuple(self):
        return (self.position, self.focal_point, self.view_up, self.view_angle, self.aspect)

    def _check(self):
        for name in ("position", "focal_point", "view_up"):
            v = np.asarray(getattr(self, name), dtype=np.float64) \
                if np.asarray(getattr(self, name)).dtype.kind in "biuf" else None
            if v is None or v.shape != (3,) or not np.isfinite(v).all():
                raise ValueError(f"camera {name} must be three finite numbers, "
                                 f"got {getattr(self, name)!r}")
        for name in ("view_angle", "aspect"):
            v = getattr(self, name)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.number)) \
                    or not np.isfinite(v):
                raise ValueError(f"camera {name} must be a finite number, got {v!r}")
        if not 0 < self.view_angle < 180:
            raise ValueError(
                f"camera view angle must be in (0, 180) degrees, got {self.view_angle}")
        if not self.aspect > 0:
            raise ValueError(f"camera aspect must be > 0, got {self.aspect}")
        f = np.subtract(self.focal_point, self.position, dtype=np.float64)
        if np.linalg.norm(f) == 0:
            raise ValueError("the camera looks at nothing: its focal point is its position")
        up = np.asarray(self.view_up, dtype=np.float64)
        if np.linalg.norm(np.cross(f / np.linalg.norm(f), up)) < 1e-9 * max(np.linalg.norm(up),
                                                                            1e-300):
            raise ValueError("the camera's view up is zero or parallel to its direction of view")

    def frustum(self) -> tuple[np.ndarray, np.ndarray]:
        """(eye (3,), planes (5, 4)): inward unit normals and offsets, ``n.x + d >= 0`` inside.

        The four side planes and the plane through the eye facing forward;
        no near or far plane.
        """
        eye = np.asarray(self.position, dtype=np.float64)
        f = np.subtract(self.focal_point, eye, dtype=np.float64)
        f /= np.linalg.norm(f)
        up = np.asarray(self.view_up, dtype=np.float64)
        up = up - up.dot(f) * f
        up /= np.linalg.norm(up)
        right = np.cross(f, up)
        tv = np.tan(np.radians(self.view_angle) / 2)
        th = tv * self.aspect
        normals = [tv * f - up, tv * f + up, th * f - right, th * f + right, f]
        planes = np.empty((5, 4))
        for i, nv in enumerate(normals):
            nv = nv / np.linalg.norm(nv)
            planes[i, :3] = nv
            planes[i, 3] = -nv.dot(eye)
        return eye, planes

    def direction(self) -> np.ndarray:
        f = np.subtract(self.focal_point, self.position, dtype=np.float64)
        return f / np.linalg.norm(f)


# -- the front -----------------------------------------------------------------------


@dataclass(eq=False)
class Front(TriangleMesh):
    """The active front for one camera: points, distinct triangles, point arrays.

    A :class:`~fancloud_vtk.TriangleMesh` (``points``, ``triangles``,
    ``normals``, ``point_data``, ``stats``) over the active points only.

    ``point_data`` holds ``node_id`` (forest node), ``level`` (depth below
    its root), ``error`` (e(r); 0 on original points) and the colours if the
    cloud has them. ``stats`` holds ``active`` (points: ``in_view``, whose
    bounding spheres meet the frustum, and ``border``, front nodes just
    outside it that the fans of the former reach), ``triangles`` (and
    ``distinct``, the count before superfluous ones were removed: equal
    unless asked), ``folded`` (triangles that turned against their fan point's
    normal, written the other way round: :meth:`folded_triangles`), ``front``
    (front nodes, in and out of view), ``visited``
    (nodes looked at by this update), ``seconds`` (the whole call, from the
    camera to these arrays; of which, besides reading the camera,
    ``seconds_update`` moving the front, ``seconds_triangles`` the active
    fans' triangles, ``seconds_points`` gathering the points' arrays and
    ``seconds_superfluous`` removing superfluous triangles) and
    ``triangles_per_point``.
    """

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    def folded_triangles(self) -> np.ndarray:
        """Which triangles fold: turn against the normal of the point whose fan gave them.

        Each triangle is ``(p, a, b)`` with ``a``, ``b`` consecutive in the fan of ``p``
        as drawn (its neighbours, or the active stand-ins of those that are not active),
        counter-clockwise around ``p``'s normal when the fan is valid. A merge can move a
        stand-in across another (the paper's Figure 14: a fan made invalid by a merge);
        the triangle then turns over. ``front_arrays`` writes such a triangle the other
        way round, so that it runs as its neighbours do (nothing is removed or refined
        further: docs/vdfc.md), and counts it in ``stats["folded"]``; on its fronts this
        method finds none.
        """
        return _turned(self.points, self.normals, self.triangles[:, 0],
                       self.triangles[:, 1], self.triangles[:, 2])


def _turned(points, normals, p, a, b) -> np.ndarray:
    """det[a - p, b - p, n_p] < 0 (beyond round-off): the triangle turns against p's
    normal."""
    u = points[a] - points[p]
    v = points[b] - points[p]
    det = np.einsum("ij,ij->i", np.cross(u, v), normals[p])
    scale = np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)
    return det < -1e-9 * scale


# -- the forest ----------------------------------------------------------------------


def _check_blocks(blocks, fc: FanCloud) -> tuple[list[np.ndarray], np.ndarray]:
    """Validated blocks and the shared-point mask; ValueError if they do not tile the data."""
    n = fc.n_points
    if isinstance(blocks, np.ndarray) and blocks.ndim == 1 and blocks.dtype.kind in "iu" \
            and blocks.shape[0] == n:
        labels = blocks.astype(np.int64)
        if labels.min() < 0:
            raise ValueError("block labels must be >= 0")
        blocks = [np.flatnonzero(labels == b) for b in np.unique(labels)]
    try:
        blocks = list(blocks)
    except TypeError:
        raise TypeError("blocks must be a list of point index arrays or one label per point, "
                        f"got {type(blocks).__name__}") from None
    out = []
    for i, b in enumerate(blocks):
        a = np.asarray(b)
        if a.ndim != 1 or a.dtype.kind not in "iu" or a.size == 0:
            raise ValueError(f"block {i} must be a non-empty 1-d array of point indices, "
                             f"got {a.dtype} {a.shape}")
        if a.min() < 0 or a.max() >= n:
            raise ValueError(f"block {i} has point indices outside 0..{n - 1}")
        a = a.astype(np.int64)
        if not (a[1:] > a[:-1]).all():  # sorted without repeats already: the usual case
            a = np.unique(a)
        out.append(a)
    if not out:
        raise ValueError("blocks is empty")
    count = np.zeros(n, np.int64)
    for a in out:
        count[a] += 1
    if (count == 0).any():
        raise ValueError(f"the blocks do not tile the data: {int((count == 0).sum())} point(s) "
                         f"in no block, first {int(np.flatnonzero(count == 0)[0])}")
    mem_off = np.concatenate([[0], np.cumsum(count)])
    mem = np.empty(mem_off[-1], np.int64)
    fill = mem_off[:-1].copy()
    for b, a in enumerate(out):
        mem[fill[a]] = b
        fill[a] += 1
    bad, first = VK.edges_outside_blocks(fc.offsets, fc.ring, mem_off, mem)
    if bad:
        raise ValueError(f"the blocks do not tile the data: {bad} fan edge(s) join points of "
                         f"different blocks that share neither point (first at point {first}); "
                         "neighbouring blocks must share their boundary points")
    return out, count >= 2


#: An open fan that covers less than this angle (radians) marks a corner of the
#: boundary: a square corner covers pi / 2, a straight boundary pi. A merge keeps a
#: corner where it is (docs/vdfc.md).
CORNER_ANGLE = 0.75 * np.pi


def _open_codes(fc: FanCloud) -> np.ndarray:
    """Per point: ``VK.CLOSED``, ``VK.OPEN`` or ``VK.CORNER`` (an open fan covering less
    than :data:`CORNER_ANGLE`: the sum of the angles between its consecutive neighbours)."""
    codes = fc.open.astype(np.uint8)
    idx = np.flatnonzero(fc.open)
    if len(idx) == 0:
        return codes
    sizes = np.diff(fc.offsets)[idx]
    pairs = np.maximum(sizes - 1, 0)
    owner = np.repeat(np.arange(len(idx)), pairs)
    start = np.repeat(fc.offsets[idx] - np.concatenate([[0], np.cumsum(pairs)[:-1]]), pairs)
    j = start + np.arange(len(owner))
    c = fc.points[idx[owner]]
    u = fc.points[fc.ring[j]] - c
    v = fc.points[fc.ring[j + 1]] - c
    ang = np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))
    covered = np.bincount(owner, weights=ang, minlength=len(idx))
    codes[idx[covered < CORNER_ANGLE]] = VK.CORNER
    return codes


class _Nodes:
    """Growing node tables while the blocks and the final merges are put together."""

    def __init__(self, fc: FanCloud, col):
        n = fc.n_points
        self.pos = [fc.points]
        self.nrm = [fc.normals]
        self.col = [col]
        self.open = [_open_codes(fc)]
        self.child = [np.full((n, 2), -1, np.int64)]
        self.ring_sizes = [np.diff(fc.offsets)]
        self.ring = [fc.ring]
        self.taint = [np.zeros(n, np.bool_)]
        self.count = n

    def absorb(self, res, ids):
        """Append the new nodes of one ``merge_forest`` result; ``ids``: global ids of its inputs.

        Returns the global ids of all its nodes (inputs then new ones).
        """
        k, child, pos, nrm, col, opn, ring_off, ring = res[:8]
        gid = np.concatenate([ids, self.count + np.arange(k, dtype=np.int64)])
        self.pos.append(pos)
        self.nrm.append(nrm)
        self.col.append(col)
        self.open.append(opn)
        self.child.append(gid[child])
        self.ring_sizes.append(np.diff(ring_off))
        self.ring.append(gid[ring])
        self.taint.append(res[11])
        self.count += k
        return gid


def _alive_edges(res, gid):
    """Global (alive ids, edge pairs) of the nodes left by a ``merge_forest`` result."""
    alive, off, adj = res[8], res[9], res[10]
    ids = np.flatnonzero(alive)
    src = np.repeat(np.arange(len(alive)), np.diff(off))
    return gid[ids], np.column_stack([gid[src], gid[adj]])


class ViewDependentFanCloud:
    """A merge forest over a fan cloud and its camera-driven active front (section 8).

    Build one with :meth:`build`; ask :meth:`front_arrays` for the active
    front of a camera. Node ids: the original points first (their input index), then
    the merged nodes in merge order, so a node's children have smaller ids.

    Attributes
    ----------
    positions, normals : numpy.ndarray
        ``(n_nodes, 3)`` per node.
    children : numpy.ndarray
        ``(n_nodes, 2)`` int64, ``-1`` on leaves (original points).
    parent : numpy.ndarray
        ``(n_nodes,)`` int64, ``-1`` on roots.
    level : numpy.ndarray
        Depth below the root.
    error : numpy.ndarray
        e(r): the largest distance of the node's original points from its
        fan at merge time (0 on leaves).
    bound : numpy.ndarray
        The largest e over the node and its descendants (the front's test).
    radius : numpy.ndarray
        Radius of a sphere about the node holding all its descendants.
    ring_offsets, ring, open : numpy.ndarray
        Every node's fan (CSR; leaves: the input fans; merged nodes: the fan
        at merge time) and its open flag.
    """

    def __init__(self, *, positions, normals, children, ring_offsets, ring, open, error,
                 bound, radius, colors=None, color_name=None, color_uint8=False,
                 merge="entropy", weights=VDFC_WEIGHTS, n_leaves_of=None):
        self.positions = positions
        self.normals = normals
        self.children = children
        self.ring_offsets = ring_offsets
        self.ring = ring
        self.open = open
        self.error = error
        self.bound = bound
        self.radius = radius
        self.colors = colors
        self.color_name = color_name
        self.color_uint8 = bool(color_uint8)
        self.merge = merge
        self.weights = tuple(float(v) for v in weights)
        #: with build(influence=...) or blocks: the nodes the followed points reached
        self.influenced = None
        self.parent, self.level, self._order, self._lo, self._hi = VK.leaf_order(children)
        self.roots = np.flatnonzero(self.parent < 0)
        self._rep = None  # front_arrays: each ring entry's last stand-in (valid while a front node)
        self.reset_front()

    # -- building ---------------------------------------------------------------
    @classmethod
    def build(cls, fancloud, merge: str = "entropy", *, weights=VDFC_WEIGHTS, blocks=None,
              n_roots: int = 1, colors=None, workers: int | None = None, executor=None,
              influence=None, progress=None) -> ViewDependentFanCloud:
        """Build the merge forest of a fan cloud or triangle mesh.

        Parameters
        ----------
        fancloud : FanCloud or TriangleMesh
            The original points and their fans (a mesh's one-rings).
        merge : {"entropy", "half_edge"}, default: "entropy"
            ``"entropy"`` places the merged point at the entropy-weighted
            mean of the two; ``"half_edge"`` keeps the lower-entropy
            neighbour's position (a half-edge collapse).
        weights : sequence of 4 float, default: (1, 1, 0, 0)
            Entropy weights ``(a1, a2, a3, a4)`` of the merge order.
        blocks : list of index arrays, or one label per point, optional
            Blocks that share their boundary points (e.g. from
            :func:`terrain_blocks`): each block's forest is built without
            merging the shared points (the blocks in parallel threads),
            then the blocks are united and merged further.
        n_roots : int, default: 1
            Stop merging when this many nodes are left (fewer merges may be
            possible: a pair whose neighbour set would exceed 32 waits).
        colors : None, str or numpy.ndarray, optional
            Colours carried to the merged nodes and the front (default: the
            cloud's colour array if it has one).
        workers : int, optional
            Threads for the blocks (default: the number of CPUs).
        executor : concurrent.futures.Executor, optional
            Runs the blocks instead of the threads: anything with the
            ``map(fn, *iterables)`` of :class:`concurrent.futures.Executor`
            giving the results in order (a ``ProcessPoolExecutor``, a Dask
            client's ``get_executor()``;
            :func:`fancloud_vtk.distributed.tiled_vdfc` runs them on any Dask
            scheduler). Each block is one call of a module-level function on
            its own arrays (picklable); the forest is the same whoever runs
            them.
        influence : array of bool or point indices, optional
            Points whose influence to follow: ``influenced[node]`` is True for
            the nodes whose merge involved them or a node they reached (see
            docs/vdfc.md). With ``blocks``, the shared points are followed too.
            The rest of the forest was built from the same data in the same
            order whatever happened at those points: this is how the blocks'
            result is checked against a build without blocks.
        progress : callable, optional
            ``progress(fraction, message)``.

        Returns
        -------
        ViewDependentFanCloud

        Raises
        ------
        ValueError
            An unknown merge, bad weights or n_roots, blocks that do not
            tile the data, an empty cloud.

        Examples
        --------
        >>> import numpy as np
        >>> from fancloud_vtk import ViewDependentFanCloud, terrain_fan_cloud
        >>> z = np.add.outer(np.sin(np.linspace(0, 6, 60)), np.cos(np.linspace(0, 6, 60)))
        >>> vd = ViewDependentFanCloud.build(terrain_fan_cloud(z, spacing=0.1))
        >>> vd.n_leaves, len(vd.roots), vd.n_nodes == 2 * vd.n_leaves - len(vd.roots)
        (3600, 1, True)
        >>> cam = ((3.0, -4.0, 3.0), (3.0, 3.0, 0.0), (0, 0, 1), 45.0)
        >>> front = vd.front_arrays(cam, e_max=0.05)  # numpy arrays; VTK: fancloud_vtk.to_vtk
        >>> sorted(front.point_data)
        ['error', 'level', 'node_id']
        """
        if merge not in MERGES:
            raise ValueError(f"merge must be one of {list(MERGES)}, got {merge!r}")
        fc = as_fan_cloud(fancloud)
        w = np.array(check_weights(weights), dtype=np.float64)
        if isinstance(n_roots, (bool, np.bool_)) or not isinstance(n_roots, (int, np.integer)) \
                or n_roots < 1:
            raise ValueError(f"n_roots must be an integer >= 1, got {n_roots!r}")
        name = find_color_array(fc.point_data, colors if isinstance(colors, str) else None) \
            if not isinstance(colors, np.ndarray) else None
        rgb = as_colors(colors, fc.point_data, fc.n_points)
        if w[3] > 0 and rgb is None:
            raise ValueError("the colour weight a4 is > 0 but the cloud has no colours")
        uint8 = name is not None and fc.point_data[name].dtype == np.uint8
        col = rgb if rgb is not None else np.zeros((fc.n_points, 0))
        dbar = EK.mean_distance(fc.points, fc.offsets, fc.ring)
        if not dbar > 0:
            raise FanCloudInputError("the fans have no neighbours at a distance > 0")
        method = VK.MERGE_HALF_EDGE if merge == "half_edge" else VK.MERGE_ENTROPY
        n = fc.n_points
        report = progress or (lambda f, m: None)
        adj_off, adj = VK.symmetric_adjacency(fc.offsets, fc.ring, n)
        width = max(WIDTH, int(np.diff(adj_off).max(initial=0)) + 8)
        nodes = _Nodes(fc, col)
        codes = nodes.open[0]
        taint = np.zeros(n, np.bool_) if influence is None else _influence_mask(influence, n)
        nodes.taint[0] = taint

        def run(ids, off, nb, locked, min_alive):
            return VK.merge_forest(fc.points[ids] if ids is not None else fc.points,
                                   fc.normals[ids] if ids is not None else fc.normals,
                                   col[ids] if ids is not None else col,
                                   codes[ids] if ids is not None else codes,
                                   off, nb, locked, w, dbar, method, min_alive, width,
                                   taint[ids] if ids is not None else taint)

        if blocks is None:
            report(0.0, "merging")
            res = run(None, adj_off, adj, np.zeros(n, np.bool_), n_roots)
            nodes.absorb(res, np.arange(n, dtype=np.int64))
        else:
            blist, shared = _check_blocks(blocks, fc)
            taint |= shared
            report(0.0, f"merging {len(blist)} blocks")

            def one(ids):
                off, nb = VK.restrict_adjacency(adj_off, adj, ids, n)
                return run(ids, off, nb, shared[ids], 0)

            n_workers = workers or os.cpu_count() or 1
            if executor is not None:  # each block's arrays go to its task
                def args(ids):
                    off, nb = VK.restrict_adjacency(adj_off, adj, ids, n)
                    return (fc.points[ids], fc.normals[ids], col[ids], codes[ids], off, nb,
                            shared[ids], w, dbar, method, 0, width, taint[ids])

                results = list(executor.map(_merge_block, *zip(*map(args, blist),
                                                               strict=True)))
            elif n_workers > 1 and len(blist) > 1:
                with ThreadPoolExecutor(n_workers) as pool:
                    results = list(pool.map(one, blist))
            else:
                results = [one(ids) for ids in blist]
            alive_ids, edges = [], []
            alive_taint = np.zeros(n + sum(r[0] for r in results), np.bool_)
            for ids, res in zip(blist, results, strict=True):
                gid = nodes.absorb(res, ids)
                a, e = _alive_edges(res, gid)
                alive_ids.append(a)
                edges.append(e)
                alive_taint[gid[res[12]]] = True
            report(0.6, "uniting the blocks")
            # the united graph: shared points keep the neighbours of every block
            keep = np.unique(np.concatenate(alive_ids))
            local = np.full(nodes.count, -1, np.int64)
            local[keep] = np.arange(len(keep))
            e = np.concatenate(edges)
            e = local[e]
            key = np.unique(e[:, 0] * len(keep) + e[:, 1])
            src, dst = key // len(keep), key % len(keep)
            off = np.concatenate([[0], np.cumsum(np.bincount(src, minlength=len(keep)))])
            pos = np.concatenate(nodes.pos)[keep]
            nrm = np.concatenate(nodes.nrm)[keep]
            colk = np.concatenate(nodes.col)[keep]
            opn = np.concatenate(nodes.open)[keep]
            res = VK.merge_forest(pos, nrm, colk, opn, off.astype(np.int64), dst.astype(np.int64),
                                  np.zeros(len(keep), np.bool_), w, dbar, method, n_roots, width,
                                  alive_taint[keep])
            nodes.absorb(res, keep)
        report(0.8, "errors of the nodes")
        vd = cls._from_nodes(nodes, n, merge, w, name, uint8,
                             np.concatenate(nodes.taint) if taint.any() else None)
        report(1.0, "done")
        return vd

    @classmethod
    def _from_nodes(cls, nodes: _Nodes, n_leaves, merge, w, color_name, uint8, influenced=None):
        pos = np.concatenate(nodes.pos)
        nrm = np.concatenate(nodes.nrm)
        col = np.concatenate(nodes.col)
        child = np.concatenate(nodes.child)
        ring_off = np.zeros(len(pos) + 1, np.int64)
        np.cumsum(np.concatenate(nodes.ring_sizes), out=ring_off[1:])
        ring = np.concatenate(nodes.ring, dtype=np.int64)
        opn = np.concatenate(nodes.open) != VK.CLOSED
        pos, nrm, col, child, ring_off, ring, opn, new = _renumber(
            n_leaves, pos, nrm, col, child, ring_off, ring, opn)
        if influenced is not None:
            moved = np.empty_like(influenced)
            moved[new] = influenced
            influenced = moved
        err, bound, radius = _errors(pos, nrm, child, ring_off, ring, opn)
        vd = cls(positions=pos, normals=nrm, children=child, ring_offsets=ring_off, ring=ring,
                 open=opn, error=err, bound=bound, radius=radius,
                 colors=col if col.shape[1] else None, color_name=color_name,
                 color_uint8=uint8, merge=merge, weights=w)
        vd.influenced = influenced
        return vd

    def add_object(self, other, merge: str | None = None, **build_kwargs) -> ViewDependentFanCloud:
        """A new forest with ``other``'s trees added (a building, a ledge, any shape).

        ``other`` is a :class:`ViewDependentFanCloud`, or a fan cloud or
        mesh whose forest is built with ``merge`` (default: this forest's)
        and ``build_kwargs``. Its node ids follow this forest's.
        """
        if not isinstance(other, ViewDependentFanCloud):
            other = ViewDependentFanCloud.build(other, merge or self.merge, **build_kwargs)
        shift = self.n_nodes
        child = np.concatenate([self.children, np.where(other.children >= 0,
                                                        other.children + shift, -1)])
        colors = None
        if self.colors is not None or other.colors is not None:
            c = max(x.colors.shape[1] for x in (self, other) if x.colors is not None)

            def cols(x):
                return x.colors[:, :c] if x.colors is not None and x.colors.shape[1] >= c \
                    else np.full((x.n_nodes, c), 0.5)

            colors = np.concatenate([cols(self), cols(other)])
        return ViewDependentFanCloud(
            positions=np.concatenate([self.positions, other.positions]),
            normals=np.concatenate([self.normals, other.normals]),
            children=child,
            ring_offsets=np.concatenate([self.ring_offsets,
                                         other.ring_offsets[1:] + self.ring_offsets[-1]]),
            ring=np.concatenate([self.ring, other.ring + shift]),
            open=np.concatenate([self.open, other.open]),
            error=np.concatenate([self.error, other.error]),
            bound=np.concatenate([self.bound, other.bound]),
            radius=np.concatenate([self.radius, other.radius]),
            colors=colors, color_name=self.color_name or other.color_name,
            color_uint8=self.color_uint8 or other.color_uint8, merge=self.merge,
            weights=self.weights)

    # -- queries ----------------------------------------------------------------
    def folded_fans(self) -> np.ndarray:
        """Which nodes' fans fold: a pair of consecutive neighbours turns against the node's
        normal (the fan does not go round the node once; the paper's Figure 14, a fan
        made invalid by a merge). A merged node's fan is sorted around its normal at
        merge time, so it folds only where a gap of more than 180 degrees falls inside
        it (a closed fan's node outside its neighbours' polygon); a leaf keeps its input
        fan. Boolean, one per node. Nothing in the forest or the front changes such a
        fan (docs/vdfc.md); ``fancloud bench vdfc`` counts them.
        """
        off = self.ring_offsets
        sizes = np.diff(off)
        node = np.repeat(np.arange(self.n_nodes), sizes)
        at = np.arange(off[-1])
        nxt = at + 1
        last = nxt == np.repeat(off[1:], sizes)
        nxt[last] = np.repeat(off[:-1], sizes)[last]  # the closing pair (closed fans)
        use = (~last | ~self.open[node]) & (np.repeat(sizes, sizes) >= 2)
        bad = _turned(self.positions, self.normals, node[use], self.ring[at[use]],
                      self.ring[nxt[use]])
        out = np.zeros(self.n_nodes, bool)
        out[node[use][bad]] = True
        return out

    @property
    def n_nodes(self) -> int:
        return int(self.positions.shape[0])

    @property
    def is_leaf(self) -> np.ndarray:
        return self.children[:, 0] < 0

    @property
    def n_leaves(self) -> int:
        return int(np.count_nonzero(self.is_leaf))

    def leaves(self, node: int) -> np.ndarray:
        """The original points (leaf ids) below ``node``."""
        return self._order[self._lo[node]:self._hi[node]]

    def bounds(self) -> np.ndarray:
        """``(xmin, xmax, ymin, ymax, zmin, zmax)`` of the original points.

        Computed once: the default range of sight and ``e_max`` ask for it every frame.
        """
        if getattr(self, "_bounds", None) is None:
            p = self.positions[self.is_leaf]
            self._bounds = np.column_stack([p.min(axis=0), p.max(axis=0)]).ravel()
        return self._bounds.copy()

    def __repr__(self) -> str:
        return (f"ViewDependentFanCloud({self.n_leaves} points, {self.n_nodes} nodes, "
                f"{len(self.roots)} roots, merge={self.merge!r})")

    # -- the front --------------------------------------------------------------
    def reset_front(self) -> None:
        """Forget the kept front: the next :meth:`front_arrays` starts from the roots."""
        self._state = np.zeros(self.n_nodes, np.int8)
        self._state[self.roots] = VK.FRONT
        self._front = self.roots.copy()
        self._aidx = np.full(self.n_nodes, -1, np.int32)
        # the front's tests of ancestors, made once per frame (valid for one tick)
        self._tick = 0
        self._memo = np.full(self.n_nodes, -2, np.int32)

    def default_d_max(self, camera) -> float:
        """The range of sight by default: from the eye to the farthest corner of the bounds."""
        eye = np.asarray(Camera.of(camera).position, dtype=np.float64)
        b = self.bounds().reshape(3, 2)
        corners = np.array(np.meshgrid(*b)).reshape(3, -1).T
        return float(np.linalg.norm(corners - eye, axis=1).max())

    def front_arrays(self, camera, e_max: float, d_max: float | None = None, *,
                     aspect: float | None = None, incremental: bool = True,
                     superfluous: bool = False) -> Front:
        """The active front for a camera: a :class:`Front` (numpy arrays).

        Parameters
        ----------
        camera : vtkCamera, pyvista.Camera, Camera or tuple
            ``(position, focal_point, view_up, view_angle[, aspect])`` for a
            tuple; view angle in degrees (vertical, as VTK's).
        e_max : float
            The largest error allowed at distance ``d_max`` (> 0).
        d_max : float, optional
            The range of sight (default: from the eye to the farthest corner
            of the bounds).
        aspect : float, optional
            Width / height of the view (a VTK camera does not know it;
            default 1, or the tuple's).
        incremental : bool, default: True
            Start from the front of the previous call (False: from the roots;
            the result is the same).
        superfluous : bool, default: False
            Also remove superfluous triangles, as the mesh does (paper
            section 4): where fans of different levels meet, their triangles
            overlap, and a convex quadrilateral covered by both diagonals'
            triangles keeps one pair (the complete diagonal, then the one
            more fans hold, then the better-shaped); no ground loses its
            cover. About 2.0 triangles per point instead of about 2.15, for
            about twice the update time (``stats["distinct"]``: the count
            before).

        Returns
        -------
        Front
            The active points and their distinct triangles, with point arrays
            ``node_id``, ``level``, ``error`` (and the colours), and the
            statistics ``stats``. As a ``vtkPolyData``:
            ``fancloud_vtk.to_vtk(front)``; the accessor's forest
            (``cloud.fancloud.vdfc()``) has ``front()``, which gives a
            ``pyvista.PolyData``.
        """
        t0 = time.perf_counter()
        cam = Camera.of(camera, aspect)
        e_max = _positive("e_max", e_max)
        d_max = self.default_d_max(cam) if d_max is None else _positive("d_max", d_max)
        eye, planes = cam.frustum()
        if not isinstance(superfluous, (bool, np.bool_)):
            raise ValueError(f"superfluous must be True or False, got {superfluous!r}")
        tu = time.perf_counter()  # the camera read
        if not incremental:
            self.reset_front()
        self._tick += 1
        if self._tick >= 2**30:  # the memo holds 2 tick + answer in 32 bits: start again
            self._memo.fill(-2)
            self._tick = 1
        # two cores halve the work of a large front; a small one is not worth waking them
        chunks = numba.get_num_threads() if len(self._front) >= PARALLEL_FRONT else 1
        args = (self.positions, self.radius, self.bound, self.children, self.parent)
        dec, walk, vis = VK.front_decisions(*args, self._front, planes, eye, e_max / d_max,
                                            self._memo, self._tick, chunks)
        front, active, visited = VK.update_front(*args, self._state, self._front, planes, eye,
                                                 e_max / d_max, self._memo, self._tick, dec,
                                                 walk, vis)
        self._front = front
        t1 = time.perf_counter()
        self._aidx[active] = np.arange(len(active))
        if self._rep is None:  # the ring entries' last stand-ins, kept for the forest's life
            self._rep = self.ring.astype(np.int32 if self.n_nodes < 2**31 else np.int64)
        tri, held, extra, n_folded = VK.front_triangles(
            self.positions, self.normals, self.children, self.parent, self._state, active,
            self._aidx, self.open, self.ring_offsets, self.ring, self._rep, chunks,
            superfluous, planes)
        t2 = time.perf_counter()
        n_view = len(active)
        ids, points, normals, level, error = VK.front_points(
            active, extra, self._aidx, self.positions, self.normals, self.level, self.error,
            chunks)
        t3 = time.perf_counter()
        n_distinct = len(tri)
        if superfluous:
            tri = tri[VK.front_superfluous(points, normals, tri, held, chunks)]
        t4 = time.perf_counter()
        pdata = {"node_id": ids, "level": level, "error": error}
        if self.colors is not None:
            c = self.colors[ids]
            if self.color_uint8:
                c = np.clip(np.round(c * 255), 0, 255).astype(np.uint8)
            pdata[self.color_name or "RGB"] = c
        seconds = time.perf_counter() - t0
        stats = {"active": len(ids), "in_view": n_view, "border": len(extra),
                 "triangles": len(tri), "distinct": n_distinct, "folded": int(n_folded),
                 "front": len(front),
                 "visited": int(visited), "seconds": seconds,
                 "triangles_per_point": len(tri) / len(ids) if len(ids) else 0.0,
                 "seconds_update": t1 - tu, "seconds_triangles": t2 - t1,
                 "seconds_points": t3 - t2,
                 "seconds_superfluous": t4 - t3,
                 "e_max": e_max, "d_max": d_max}
        return Front(points, tri, normals, pdata, stats)

    # -- saving -----------------------------------------------------------------
    def _arrays(self) -> dict[str, np.ndarray]:
        out = {"format": np.array(FORMAT), "positions": self.positions, "normals": self.normals,
               "children": self.children, "ring_offsets": self.ring_offsets, "ring": self.ring,
               "open": self.open, "error": self.error, "bound": self.bound,
               "radius": self.radius, "merge": np.array(self.merge),
               "weights": np.asarray(self.weights, dtype=np.float64)}
        if self.colors is not None:
            out["colors"] = self.colors
            out["color_name"] = np.array(self.color_name or "RGB")
            out["color_uint8"] = np.array(self.color_uint8)
        return out

    def save(self, path) -> None:
        """Write the forest to a ``.npz`` file (no pickle); :meth:`load` reads it."""
        np.savez_compressed(path, **self._arrays())

    @classmethod
    def load(cls, path) -> ViewDependentFanCloud:
        """Read a forest written by :meth:`save`."""
        try:
            with np.load(path, allow_pickle=False) as z:
                a = {k: z[k] for k in z.files}
        except (OSError, ValueError) as exc:
            raise ValueError(f"cannot read a view-dependent fan cloud from {path}: {exc}") from exc
        if "format" not in a or str(a["format"]) != FORMAT:
            raise ValueError(f"{path} is not a view-dependent fan cloud (.npz from "
                             "ViewDependentFanCloud.save)")
        vd = cls(positions=a["positions"], normals=a["normals"], children=a["children"],
                 ring_offsets=a["ring_offsets"], ring=a["ring"], open=a["open"],
                 error=a["error"], bound=a["bound"], radius=a["radius"],
                 colors=a.get("colors"),
                 color_name=str(a["color_name"]) if "color_name" in a else None,
                 color_uint8=bool(a["color_uint8"]) if "color_uint8" in a else False,
                 merge=str(a["merge"]), weights=a["weights"])
        vd._check()
        return vd

    def _check(self):
        n = self.n_nodes
        c = self.children
        if c.shape != (n, 2) or (c >= np.arange(n)[:, None]).any() or (c < -1).any():
            raise ValueError("the forest's children are not smaller ids than their parents")
        if self.ring_offsets.shape != (n + 1,) or self.ring_offsets[-1] != len(self.ring):
            raise ValueError("the forest's ring offsets do not match its ring")
        if len(self.ring) and (self.ring.min() < 0 or self.ring.max() >= n):
            raise ValueError("the forest's rings name nodes that do not exist")


def _merge_block(*args):
    """One block's merges (:func:`._vdfc_kernels.merge_forest` on the block's arrays): the
    task :meth:`ViewDependentFanCloud.build` gives an ``executor``."""
    return VK.merge_forest(*args)


def _renumber(n_leaves, pos, nrm, col, child, ring_off, ring, opn):
    """The merged nodes renumbered in depth-first post-order (leaves keep their ids).

    Merge order scatters a subtree's nodes over the whole id range; the
    post-order keeps them together, which the front's walks feel as fewer
    cache misses on large forests.
    """
    new = VK.inner_postorder(child, n_leaves)
    return (*VK.renumbered(new, pos, nrm, np.ascontiguousarray(col), child, ring_off, ring, opn),
            new)


def _influence_mask(influence, n) -> np.ndarray:
    a = np.asarray(influence)
    if a.dtype == np.bool_:
        if a.shape != (n,):
            raise ValueError(f"influence must be {n} bools or point indices, got shape {a.shape}")
        return a.copy()
    if a.dtype.kind not in "iu" or a.ndim != 1 or (a.size and (a.min() < 0 or a.max() >= n)):
        raise ValueError(f"influence must be {n} bools or point indices in 0..{n - 1}")
    mask = np.zeros(n, np.bool_)
    mask[a] = True
    return mask


def _positive(name, value) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _errors(pos, nrm, child, ring_off, ring, opn):
    """e(r), the monotone bound and the nested radii of every node."""
    _, _, order, lo, hi = VK.leaf_order(child)
    inner = np.flatnonzero(child[:, 0] >= 0)
    # spread the big (late) nodes over the threads
    shuffled = inner[np.random.default_rng(0).permutation(len(inner))]
    err = VK.node_errors(pos, nrm, child, ring_off, ring, opn, order, lo, hi, shuffled)
    leaves = pos[child[:, 0] < 0]
    diag = float(np.linalg.norm(leaves.max(axis=0) - leaves.min(axis=0))) if len(leaves) else 1.0
    bound, radius = VK.bounds_up(pos, child, err, 1e-12 * max(diag, 1e-300))
    return err, bound, radius
