"""Real and realistic point clouds with their true surfaces, for tests and benchmarks.

Synthetic spheres and the bunny are where a surface reconstruction looks
best; this module gathers the data where it does not (issue 22): the sample
meshes shipped inside pymeshlab (thin parts, sharp CAD edges, low-poly
triangles, unreferenced vertices, a real range scan), random resamplings of
them (uniform, with a 10x density ramp, with noise) and simulated range
scans (occlusion gaps, silhouettes, grazing-angle stretch, dropouts, depth
noise and stray clusters). Every entry carries its reference surface, the
model's own mesh, so a reconstruction can be measured against it.

Nothing is downloaded or copied: the models are read from pymeshlab's
folder at run time (:func:`fancloud_vtk.data.pymeshlab_sample`).

* :class:`CorpusEntry`: input points, reference mesh, kind, outliers.
* :func:`model`: a pymeshlab sample, its referenced vertices only.
* :func:`resample`: random points on a reference mesh.
* :func:`range_scan`: a simulated range scan of a reference mesh.
* :func:`rasterize`: the z-buffer behind :func:`range_scan` (also renders).
* :func:`corpus`: the lists ``'small'`` (CI) and ``'full'``.

``fancloud bench mesh --data corpus-small`` (or ``corpus``) runs the mesh
benchmark on them (docs/mesh.md, "The corpus").

Examples
--------
>>> from fancloud_vtk.corpus import corpus, model, range_scan
>>> cow = model("cow")  # doctest: +SKIP
>>> scan = range_scan(cow.ref_points, cow.ref_triangles, seed=1)  # doctest: +SKIP
>>> scan.points.shape, len(scan.outliers)  # doctest: +SKIP
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["KINDS", "MODELS", "CorpusEntry", "DepthImage", "corpus", "corpus_names", "model",
           "range_scan", "rasterize", "resample"]

#: The kinds of entry: a model's own vertices, its resamplings, a range scan.
KINDS = ("model", "uniform", "density", "noisy", "scan")

#: Name -> (file in pymeshlab's ``tests/sample_meshes``, kind, what it is).
MODELS = {
    "cow": ("cow.obj", "model", "the cow (legs, horns, ears: thin parts)"),
    "airplane": ("airplane.obj", "model",
                 "the airplane (thin wings, sharp edges, low-poly, 1,617 unreferenced vertices)"),
    "colored_airplane": ("colored_airplane.ply", "model",
                         "the airplane with vertex colours (the same geometry as airplane)"),
    "bone": ("bone.ply", "model", "the bone (359 unreferenced vertices)"),
    "bunny": ("bunny.obj", "model", "the Stanford bunny (closed)"),
    "bunny10k_textured": ("bunny10k_textured.obj", "model",
                          "the bunny, 10k triangles (open at the base)"),
    "cube": ("cube.obj", "model", "the cube (8 vertices, 12 triangles)"),
    "face000": ("rangemaps/face000.ply", "scan",
                "a real range scan of a face (rangemaps/face000.ply; its own mesh as reference)"),
}

#: The field of view of the corpus's scans, degrees: the model fills about 2/3 of the image.
SCAN_FOV = 20.0

#: The density ratio of ``resample(..., mode='density')`` across the model.
DENSITY_RATIO = 10.0


@dataclass(eq=False)
class CorpusEntry:
    """A point cloud with its true surface.

    Compared by identity (``eq=False``): arrays have no single truth value.

    Attributes
    ----------
    name : str
        Short name (``'cow'``, ``'cow-density-6k'``, ``'bunny-scan-1'``).
    points : numpy.ndarray
        ``(n, 3)`` float64: the input point cloud.
    ref_points, ref_triangles : numpy.ndarray
        The true surface, the model's own mesh: ``(v, 3)`` float64 points
        (every one used by a triangle) and ``(m, 3)`` int64 triangles.
    closed : bool
        The reference has no boundary edges (a scan of a closed model is
        still open: ``closed`` is about the reference).
    kind : str
        One of :data:`KINDS`.
    outliers : numpy.ndarray
        Indices into ``points`` of the stray points (off the surface) of a
        scan, int64, increasing; empty for every other kind.
    description : str
        How the points were made, for tables.
    info : dict
        Parameters and by-products (e.g. a scan's ``viewpoint``,
        ``target``, ``spacing``; a resampling's ``spacing``).
    """

    name: str
    points: np.ndarray
    ref_points: np.ndarray
    ref_triangles: np.ndarray
    closed: bool
    kind: str
    outliers: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    description: str = ""
    info: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"CorpusEntry({self.name!r}, {self.kind}, {len(self.points):,} points, "
                f"{len(self.outliers)} outliers, reference {len(self.ref_triangles):,} "
                f"triangles, {'closed' if self.closed else 'open'})")


# -- checks and small helpers ------------------------------------------------------------


def _as_mesh(ref_points, ref_triangles) -> tuple[np.ndarray, np.ndarray]:
    """Validated float64 ``(v, 3)`` points and int64 ``(m, 3)`` triangles."""
    pts = np.asarray(ref_points)
    tri = np.asarray(ref_triangles)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise ValueError(f"ref_points must be a non-empty (v, 3) array, got shape {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number) or not np.all(np.isfinite(pts)):
        raise ValueError("ref_points must be finite numbers")
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
        raise ValueError(f"ref_triangles must be a non-empty (m, 3) array, got shape "
                         f"{tri.shape}")
    if not np.issubdtype(tri.dtype, np.integer):
        raise ValueError(f"ref_triangles must be integer indices, got {tri.dtype}")
    if tri.min() < 0 or tri.max() >= len(pts):
        raise ValueError(f"ref_triangles index outside 0..{len(pts) - 1}")
    return (np.ascontiguousarray(pts, dtype=np.float64),
            np.ascontiguousarray(tri, dtype=np.int64))


def _rng_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def _child_seed(seed: int, *key: int) -> int:
    """A seed derived from ``seed`` and ``key`` (independent streams per corpus entry)."""
    return int(np.random.SeedSequence([seed, *key]).generate_state(1)[0])


def boundary_edge_count(triangles) -> int:
    """Edges (unordered vertex pairs) of exactly one triangle."""
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(tri) == 0:
        return 0
    e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    span = int(tri.max()) + 1
    _, counts = np.unique(e[:, 0] * span + e[:, 1], return_counts=True)
    return int(np.count_nonzero(counts == 1))


def referenced(points, triangles) -> tuple[np.ndarray, np.ndarray]:
    """The vertices used by a triangle, in their order, and the triangles reindexed to them."""
    pts = np.asarray(points, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    used = np.zeros(len(pts), dtype=bool)
    used[tri.ravel()] = True
    new_index = np.cumsum(used) - 1
    return np.ascontiguousarray(pts[used]), np.ascontiguousarray(new_index[tri])


def median_spacing(points) -> float:
    """Median distance of a point to its nearest other point."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 2:
        return 0.0
    d, _ = cKDTree(pts).query(pts, k=2)
    return float(np.median(d[:, 1]))


def _triangle_frames(pts: np.ndarray, tri: np.ndarray):
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    cross = np.cross(b - a, c - a)
    norm = np.linalg.norm(cross, axis=1)
    unit = np.divide(cross, norm[:, None], out=np.zeros_like(cross), where=norm[:, None] > 0)
    return a, b, c, 0.5 * norm, unit


# -- models ----------------------------------------------------------------------------------


def model(name: str) -> CorpusEntry:
    """A pymeshlab sample model as a corpus entry: its referenced vertices and its mesh.

    Parameters
    ----------
    name : str
        A key of :data:`MODELS` (``'cow'``, ``'airplane'``, ``'bone'``,
        ``'bunny'``, ``'bunny10k_textured'``, ``'cube'``,
        ``'colored_airplane'``, ``'face000'``); a file name with its
        extension is accepted too (``'cow.obj'``).

    Returns
    -------
    CorpusEntry
        ``points`` and ``ref_points`` are the vertices used by a face (in
        file order: unreferenced vertices are left out and the faces
        reindexed), ``ref_triangles`` the faces; kind ``'model'``, or
        ``'scan'`` for ``face000`` (a real range scan, its own mesh as
        reference).

    Raises
    ------
    ValueError
        For an unknown name.
    """
    key = str(name)
    if key not in MODELS:
        by_file = {f: k for k, (f, _, _) in MODELS.items()}
        by_file.update({f.rsplit("/", 1)[-1]: k for f, k in list(by_file.items())})
        if key not in by_file:
            raise ValueError(f"unknown model {name!r}: one of {', '.join(MODELS)}")
        key = by_file[key]
    filename, kind, text = MODELS[key]
    from fancloud_vtk.data import pymeshlab_sample
    from fancloud_vtk.io import read_point_cloud

    f = read_point_cloud(pymeshlab_sample(filename))
    if f.faces is None or len(f.faces) == 0:  # pragma: no cover - every sample has faces
        raise ValueError(f"{filename} has no faces")
    pts, tri = referenced(f.points, f.faces)
    dropped = len(f.points) - len(pts)
    return CorpusEntry(
        name=key, points=pts, ref_points=pts, ref_triangles=tri,
        closed=boundary_edge_count(tri) == 0, kind=kind,
        description=f"{text}: {len(pts):,} referenced vertices of {filename}"
                    + (f" ({dropped:,} unreferenced left out)" if dropped else ""),
        info={"file": filename, "unreferenced": dropped})


# -- resampling ------------------------------------------------------------------------------

_RESAMPLE_MODES = ("uniform", "density", "noisy")


def _sample_triangles(rng, cum, a, b, c, m):
    """``m`` area-weighted uniform points on the triangles; and their triangles."""
    idx = np.minimum(np.searchsorted(cum, rng.random(m) * cum[-1], side="right"), len(cum) - 1)
    r1 = np.sqrt(rng.random(m))[:, None]
    r2 = rng.random(m)[:, None]
    x = (1.0 - r1) * a[idx] + r1 * (1.0 - r2) * b[idx] + r1 * r2 * c[idx]
    return x, idx


def density_ramp(points, ref_points) -> np.ndarray:
    """The relative density of ``mode='density'`` at ``points``: 0.1 to 1, smooth.

    ``10 ** (t - 1)`` with ``t`` the position from 0 to 1 along the longest
    bounding-box axis of ``ref_points``: the density grows by the same
    factor per length, 10x from one end to the other.
    """
    ref = np.asarray(ref_points, dtype=np.float64)
    lo, hi = ref.min(axis=0), ref.max(axis=0)
    axis = int(np.argmax(hi - lo))
    span = max(float(hi[axis] - lo[axis]), np.finfo(float).tiny)
    t = np.clip((np.asarray(points, dtype=np.float64)[:, axis] - lo[axis]) / span, 0.0, 1.0)
    return DENSITY_RATIO ** (t - 1.0)


def resample(ref_points, ref_triangles, n: int, mode: str = "uniform", *, sigma: float = 0.25,
             seed: int = 0, name: str | None = None) -> CorpusEntry:
    """Random points on a reference mesh.

    Parameters
    ----------
    ref_points, ref_triangles : array_like
        The reference mesh, ``(v, 3)`` and ``(m, 3)`` integer indices.
    n : int
        Number of points (at least 1).
    mode : {'uniform', 'density', 'noisy'}, default: 'uniform'
        ``'uniform'``: area-weighted random points on the triangles
        (triangle by area, uniform barycentric coordinates).
        ``'density'``: the same, thinned by rejection to the smooth ramp
        :func:`density_ramp`: the density varies 10x along the model's
        longest bounding-box axis. ``'noisy'``: uniform points moved along
        their triangle's normal by Gaussian noise of standard deviation
        ``sigma`` times their median nearest-neighbour spacing.
    sigma : float, default: 0.25
        Noise of ``'noisy'``, in median spacings (0.1 to 0.5 is realistic);
        ignored by the other modes.
    seed : int, default: 0
        Random seed: the same arguments give the same points.
    name : str, optional
        The entry's name (default: ``'resample-<mode>'``).

    Returns
    -------
    CorpusEntry
        Kind ``mode``; ``info['spacing']`` is the median spacing of the
        points before the noise, ``info['noise']`` the noise's standard
        deviation (0 unless ``'noisy'``).

    Raises
    ------
    ValueError
        For a bad mesh, ``n``, ``mode``, ``sigma`` or ``seed``, or a mesh of
        zero area.
    """
    pts, tri = _as_mesh(ref_points, ref_triangles)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if mode not in _RESAMPLE_MODES:
        raise ValueError(f"mode must be one of {_RESAMPLE_MODES}, got {mode!r}")
    sigma = float(sigma)
    if not math.isfinite(sigma) or sigma < 0:
        raise ValueError(f"sigma must be a finite number >= 0, got {sigma!r}")
    rng = np.random.default_rng(_rng_seed(seed))
    n = int(n)
    a, b, c, area, normal = _triangle_frames(pts, tri)
    cum = np.cumsum(area)
    if not cum[-1] > 0:
        raise ValueError("the reference mesh has zero area")
    if mode == "density":
        chunks, got = [], 0
        idx_chunks = []
        while got < n:
            m = max(1024, int(1.5 * (n - got) * DENSITY_RATIO))
            x, idx = _sample_triangles(rng, cum, a, b, c, m)
            keep = rng.random(m) < density_ramp(x, pts)
            chunks.append(x[keep])
            idx_chunks.append(idx[keep])
            got += int(np.count_nonzero(keep))
        x = np.concatenate(chunks)[:n]
        idx = np.concatenate(idx_chunks)[:n]
    else:
        x, idx = _sample_triangles(rng, cum, a, b, c, n)
    spacing = median_spacing(x)
    noise = 0.0
    if mode == "noisy":
        noise = sigma * spacing
        x = x + normal[idx] * rng.normal(0.0, noise, n)[:, None] if noise > 0 else x
    text = {"uniform": "uniform random points", "density": "random points, density ramp 10x "
            "along the longest axis", "noisy": f"uniform random points, noise {sigma:g} median "
            "spacings along the normal"}[mode]
    return CorpusEntry(
        name=name or f"resample-{mode}", points=np.ascontiguousarray(x), ref_points=pts,
        ref_triangles=tri, closed=boundary_edge_count(tri) == 0, kind=mode,
        description=f"{n:,} {text} (seed {seed})",
        info={"mode": mode, "seed": int(seed), "sigma": sigma if mode == "noisy" else 0.0,
              "spacing": spacing, "noise": noise})


# -- rasterising: the z-buffer ---------------------------------------------------------------


class DepthImage(NamedTuple):
    """What :func:`rasterize` sees: per pixel the first triangle hit and its depth.

    ``viewpoint + depth[i, j] * rays[i, j]`` is the point hit through pixel
    ``(i, j)`` (row ``i`` from the top); ``depth`` is ``inf`` and
    ``triangle`` -1 where the ray hits nothing.
    """

    depth: np.ndarray  #: ``(h, w)`` float64, distance along the view axis
    triangle: np.ndarray  #: ``(h, w)`` int64, the triangle hit, or -1
    rays: np.ndarray  #: ``(h, w, 3)`` float64, the pixel's ray, unit depth along the view axis
    viewpoint: np.ndarray  #: ``(3,)``
    forward: np.ndarray  #: ``(3,)`` unit view axis
    right: np.ndarray  #: ``(3,)`` unit, the image's x axis (columns)
    up: np.ndarray  #: ``(3,)`` unit, the image's y axis (up: rows decrease)
    focal: float  #: focal length in pixels

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """The points hit (``(k, 3)``, row-major pixel order) and their flat pixel indices."""
        flat = np.flatnonzero(self.triangle.ravel() >= 0)
        z = self.depth.ravel()[flat]
        return self.viewpoint + z[:, None] * self.rays.reshape(-1, 3)[flat], flat

    def project(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Image coordinates ``(row, column)`` (pixel ``(i, j)`` spans ``[i, i + 1) x [j, j + 1)``)
        and depth of points ``x``; meaningless where the depth is not positive."""
        rel = np.asarray(x, dtype=np.float64).reshape(-1, 3) - self.viewpoint
        depth = rel @ self.forward
        safe = np.where(depth > 0, depth, 1.0)
        h, w = self.depth.shape
        return (0.5 * h - self.focal * (rel @ self.up) / safe,
                0.5 * w + self.focal * (rel @ self.right) / safe, depth)


@njit(cache=True)
def _zbuffer(sx, sy, z, tri, near, depth, tid):  # pragma: no cover - numba
    """Rasterise every triangle with all vertices beyond ``near``: nearest depth per pixel.

    Screen coordinates ``sx, sy`` (pixel ``(i, j)`` has its centre at
    ``(j + 0.5, i + 0.5)``); ``1 / z`` is affine in screen space, so the
    depth at a pixel centre is the exact depth of the ray's hit with the
    triangle's plane. Pixel centres on an edge belong to both triangles.
    """
    h, w = depth.shape
    eps = 1e-9
    for t in range(tri.shape[0]):
        i0, i1, i2 = tri[t, 0], tri[t, 1], tri[t, 2]
        za, zb, zc = z[i0], z[i1], z[i2]
        if za <= near or zb <= near or zc <= near:
            continue
        xa, ya, xb, yb, xc, yc = sx[i0], sy[i0], sx[i1], sy[i1], sx[i2], sy[i2]
        area = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
        if area == 0.0:
            continue
        jlo = max(0, int(math.ceil(min(xa, xb, xc) - 0.5)))
        jhi = min(w - 1, int(math.floor(max(xa, xb, xc) - 0.5)))
        ilo = max(0, int(math.ceil(min(ya, yb, yc) - 0.5)))
        ihi = min(h - 1, int(math.floor(max(ya, yb, yc) - 0.5)))
        inv = 1.0 / area
        for i in range(ilo, ihi + 1):
            py = i + 0.5
            for j in range(jlo, jhi + 1):
                px = j + 0.5
                w0 = ((xb - px) * (yc - py) - (xc - px) * (yb - py)) * inv
                w1 = ((xc - px) * (ya - py) - (xa - px) * (yc - py)) * inv
                w2 = 1.0 - w0 - w1
                if w0 < -eps or w1 < -eps or w2 < -eps:
                    continue
                d = 1.0 / (w0 / za + w1 / zb + w2 / zc)
                if d < depth[i, j]:
                    depth[i, j] = d
                    tid[i, j] = t


def _camera(viewpoint, target, up=None):
    """Unit forward, right and up vectors of a camera at ``viewpoint`` looking at ``target``."""
    f = np.asarray(target, dtype=np.float64) - np.asarray(viewpoint, dtype=np.float64)
    dist = float(np.linalg.norm(f))
    if not dist > 0:
        raise ValueError("viewpoint and target must differ")
    f /= dist
    if up is None:  # the world axis least aligned with the view
        up = np.eye(3)[int(np.argmin(np.abs(f)))]
    r = np.cross(f, np.asarray(up, dtype=np.float64))
    if not np.linalg.norm(r) > 1e-12:
        raise ValueError("up is parallel to the view direction")
    r /= np.linalg.norm(r)
    return f, r, np.cross(r, f)


def _resolution(resolution) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in resolution)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"resolution must be (width, height), got {resolution!r}") from exc
    if w < 1 or h < 1 or (w, h) != tuple(resolution):
        raise ValueError(f"resolution must be two positive integers, got {resolution!r}")
    return w, h


def _point3(value, what: str) -> np.ndarray:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be three finite numbers, got {value!r}")
    return v


def rasterize(points, triangles, *, viewpoint, target, resolution=(256, 256), fov: float = 40.0,
              up=None) -> DepthImage:
    """The first triangle hit by the ray through each pixel of a pinhole camera.

    A z-buffer (numba): every triangle with all three vertices in front of
    the camera is projected and its pixels kept where it is the nearest;
    the depth is interpolated perspective-correctly, so the back-projected
    point is the ray's exact hit with the triangle. Triangles reaching
    behind the camera (closer than 1e-6 of the scene's size) are skipped.

    Parameters
    ----------
    points, triangles : array_like
        The mesh, ``(v, 3)`` and ``(m, 3)`` integer indices.
    viewpoint, target : array_like
        The camera's position and the point it looks at, ``(3,)``.
    resolution : (int, int), default: (256, 256)
        Width and height in pixels (square pixels).
    fov : float, default: 40.0
        Vertical field of view in degrees, in (0, 180).
    up : array_like, optional
        The camera's up direction (default: the world axis least aligned
        with the view).

    Returns
    -------
    DepthImage
    """
    pts, tri = _as_mesh(points, triangles)
    eye = _point3(viewpoint, "viewpoint")
    f, r, u = _camera(eye, _point3(target, "target"), up)
    w, h = _resolution(resolution)
    fov = float(fov)
    if not 0.0 < fov < 180.0:
        raise ValueError(f"fov must be in (0, 180) degrees, got {fov!r}")
    focal = 0.5 * h / math.tan(math.radians(0.5 * fov))
    rel = pts - eye
    z = rel @ f
    near = 1e-6 * max(float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))),
                      float(np.linalg.norm(rel, axis=1).max()))
    safe = np.where(z > near, z, 1.0)
    sx = 0.5 * w + focal * (rel @ r) / safe
    sy = 0.5 * h - focal * (rel @ u) / safe
    depth = np.full((h, w), np.inf)
    tid = np.full((h, w), -1, dtype=np.int64)
    _zbuffer(sx, sy, z, tri, near, depth, tid)
    x = (np.arange(w) + 0.5 - 0.5 * w) / focal
    y = (0.5 * h - (np.arange(h) + 0.5)) / focal
    rays = f + x[None, :, None] * r + y[:, None, None] * u
    return DepthImage(depth, tid, rays, eye, f, r, u, focal)


# -- distances to a mesh (for the outliers) --------------------------------------------------


@njit(cache=True)
def _point_triangle_sq(p, a, b, c):  # pragma: no cover - numba
    """Squared distance of ``p`` to triangle ``abc`` (Ericson, Real-Time Collision Detection)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = ab @ ap
    d2 = ac @ ap
    if d1 <= 0.0 and d2 <= 0.0:
        q = a
    else:
        bp = p - b
        d3 = ab @ bp
        d4 = ac @ bp
        vc = d1 * d4 - d3 * d2
        cp = p - c
        d5 = ab @ cp
        d6 = ac @ cp
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            q = b
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            q = a + ab * (d1 / (d1 - d3))
        elif d6 >= 0.0 and d5 <= d6:
            q = c
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            q = a + ac * (d2 / (d2 - d6))
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            q = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
        else:
            den = va + vb + vc
            if den == 0.0:  # a degenerate triangle: its edges
                q = a
                best = ap @ ap
                for s, e in ((a, b), (b, c), (c, a)):
                    se = e - s
                    ll = se @ se
                    t = 0.0 if ll == 0.0 else min(1.0, max(0.0, (p - s) @ se / ll))
                    dd = p - (s + se * t)
                    if dd @ dd < best:
                        best = dd @ dd
                return best
            q = a + ab * (vb / den) + ac * (vc / den)
    d = p - q
    return d @ d


@njit(cache=True)
def _min_distance(x, pts, tri, cand_offsets, cand):  # pragma: no cover - numba
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        best = np.inf
        for k in range(cand_offsets[i], cand_offsets[i + 1]):
            t = cand[k]
            d = _point_triangle_sq(x[i], pts[tri[t, 0]], pts[tri[t, 1]], pts[tri[t, 2]])
            if d < best:
                best = d
        out[i] = math.sqrt(best)
    return out


def distance_to_mesh(x, ref_points, ref_triangles) -> np.ndarray:
    """Exact unsigned distance of each point of ``x`` to a triangle mesh.

    Candidate triangles are those whose centroid lies within the distance
    to the nearest vertex plus the largest centroid-to-vertex distance (a
    bound that cannot miss the nearest triangle): fast for points near the
    surface or few points, quadratic for many points far from it.
    """
    from scipy.spatial import cKDTree

    pts, tri = _as_mesh(ref_points, ref_triangles)
    q = np.ascontiguousarray(np.asarray(x, dtype=np.float64).reshape(-1, 3))
    if len(q) == 0:
        return np.empty(0)
    centroid = pts[tri].mean(axis=1)
    reach = float(np.linalg.norm(pts[tri] - centroid[:, None, :], axis=2).max())
    d_vertex, _ = cKDTree(pts).query(q)
    lists = cKDTree(centroid).query_ball_point(q, d_vertex + reach * (1 + 1e-9) + 1e-12)
    offsets = np.zeros(len(q) + 1, np.int64)
    offsets[1:] = np.cumsum([len(c) for c in lists])
    cand = np.fromiter((t for c in lists for t in c), dtype=np.int64, count=int(offsets[-1]))
    return _min_distance(q, pts, tri, offsets, cand)


# -- range scans -----------------------------------------------------------------------------

_LOST_BLOBS = (2, 5)  #: lost blobs per scan with dropouts: at least 2, fewer than 5
_BLOB_RADIUS = (0.02, 0.05)  #: their radius, a fraction of the smaller image side
_OUTLIER_DISTANCE = (10.0, 50.0)  #: outlier distance to the surface, in median spacings
_OUTLIER_SPREAD = 1.0  #: standard deviation of a cluster around its centre, median spacings


def range_scan(ref_points, ref_triangles, *, viewpoint=None, target=None,
               resolution=(256, 256), fov: float = 40.0, dropout: float = 0.02,
               depth_noise: float = 0.1, outlier_clusters: int = 3, cluster_size: int = 15,
               seed: int = 0, name: str | None = None) -> CorpusEntry:
    """A simulated range scan of a mesh: one ray per pixel, the first hit.

    A pinhole camera at ``viewpoint`` looks at ``target``; every pixel's ray
    keeps its first hit (:func:`rasterize`), so the scan has the occlusion
    gaps, silhouettes and grazing-angle stretch of a real one. Then, in this
    order: dropouts (a random ``dropout`` fraction of the hit pixels lost,
    and 2 to 4 lost round blobs of 2% to 5% of the image side), depth noise
    along each ray (Gaussian, ``depth_noise`` median spacings), and
    ``outlier_clusters`` clusters of ``cluster_size`` stray points floating
    between the camera and the surface, every point of them 10 to 50 median
    spacings from the surface (the exact distance to the mesh is checked).

    Parameters
    ----------
    ref_points, ref_triangles : array_like
        The scanned mesh (also the entry's reference), ``(v, 3)`` and
        ``(m, 3)`` integer indices.
    viewpoint : array_like, optional
        The scanner's position; default: 2.5 bounding-box diagonals from
        ``target`` in a seeded random direction.
    target : array_like, optional
        The point looked at; default: the bounding-box centre.
    resolution : (int, int), default: (256, 256)
        Width and height of the pixel grid.
    fov : float, default: 40.0
        Vertical field of view in degrees.
    dropout : float, default: 0.02
        Fraction of the hit pixels lost at random, in [0, 1); with 0 there
        are no lost blobs either.
    depth_noise : float, default: 0.1
        Standard deviation of the noise along the ray, in median spacings
        of the scan (the spacing of the hit points before the noise), >= 0.
    outlier_clusters, cluster_size : int, default: 3 and 15
        Stray clusters and points per cluster (>= 0; a cluster needs
        ``cluster_size >= 1``).
    seed : int, default: 0
        Random seed: the same arguments give the same scan.
    name : str, optional
        The entry's name (default: ``'scan'``).

    Returns
    -------
    CorpusEntry
        Kind ``'scan'``: the hits in row-major pixel order, then the stray
        points (``outliers``: their indices). ``info`` has ``viewpoint``,
        ``target``, ``resolution``, ``fov``, ``spacing`` (median spacing of
        the hits before the noise), ``noise`` (the depth noise's standard
        deviation), ``pixels`` (flat pixel index per hit), ``hit_pixels``,
        ``lost_pixels``.

    Raises
    ------
    ValueError
        For bad arguments, or a camera that sees no more than a few points
        of the mesh.
    """
    pts, tri = _as_mesh(ref_points, ref_triangles)
    seed = _rng_seed(seed)
    dropout, depth_noise = float(dropout), float(depth_noise)
    if not 0.0 <= dropout < 1.0:
        raise ValueError(f"dropout must be in [0, 1), got {dropout!r}")
    if not math.isfinite(depth_noise) or depth_noise < 0:
        raise ValueError(f"depth_noise must be a finite number >= 0, got {depth_noise!r}")
    for value, what in ((outlier_clusters, "outlier_clusters"), (cluster_size, "cluster_size")):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
            raise ValueError(f"{what} must be a non-negative integer, got {value!r}")
    if outlier_clusters and not cluster_size:
        raise ValueError("cluster_size must be at least 1 when outlier_clusters > 0")
    w, h = _resolution(resolution)
    rng = np.random.default_rng(seed)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    target = 0.5 * (lo + hi) if target is None else _point3(target, "target")
    if viewpoint is None:
        d = rng.normal(size=3)
        viewpoint = target + 2.5 * diag * d / np.linalg.norm(d)
    viewpoint = _point3(viewpoint, "viewpoint")
    image = rasterize(pts, tri, viewpoint=viewpoint, target=target, resolution=(w, h), fov=fov)

    hit = image.triangle >= 0
    n_hit = int(np.count_nonzero(hit))
    lost = np.zeros((h, w), dtype=bool)
    if dropout > 0 and n_hit:
        lost |= hit & (rng.random((h, w)) < dropout)
        rows, cols = np.nonzero(hit)
        ii, jj = np.mgrid[0:h, 0:w]
        for _ in range(int(rng.integers(*_LOST_BLOBS))):
            k = int(rng.integers(n_hit))
            radius = rng.uniform(*_BLOB_RADIUS) * min(w, h)
            lost |= (ii - rows[k]) ** 2 + (jj - cols[k]) ** 2 <= radius * radius
    keep = hit & ~lost
    flat = np.flatnonzero(keep.ravel())
    if len(flat) < 4:
        raise ValueError(f"the camera sees {len(flat)} points of the mesh: aim it at the mesh "
                         "(viewpoint, target, fov)")
    z = image.depth.ravel()[flat]
    rays = image.rays.reshape(-1, 3)[flat]
    clean = viewpoint + z[:, None] * rays
    spacing = median_spacing(clean)
    unit = rays / np.linalg.norm(rays, axis=1)[:, None]
    noise = depth_noise * spacing
    scan = clean + unit * rng.normal(0.0, noise, len(flat))[:, None] if noise > 0 else clean

    strays = _outlier_clusters(rng, pts, tri, clean, unit, spacing, int(outlier_clusters),
                               int(cluster_size))
    points = np.ascontiguousarray(np.concatenate([scan, strays]))
    outliers = np.arange(len(scan), len(points), dtype=np.int64)
    return CorpusEntry(
        name=name or "scan", points=points, ref_points=pts, ref_triangles=tri,
        closed=boundary_edge_count(tri) == 0, kind="scan", outliers=outliers,
        description=(f"simulated range scan {w}x{h}, fov {fov:g} deg (seed {seed}): "
                     f"{len(scan):,} hits, {len(outliers)} outliers in {outlier_clusters} "
                     f"clusters, dropout {dropout:g} + blobs, depth noise {depth_noise:g} "
                     "spacings"),
        info={"viewpoint": viewpoint, "target": np.asarray(target, dtype=np.float64),
              "resolution": (w, h), "fov": float(fov), "seed": seed, "spacing": spacing,
              "noise": noise, "pixels": flat, "hit_pixels": n_hit,
              "lost_pixels": int(np.count_nonzero(hit & lost)), "dropout": dropout,
              "depth_noise": depth_noise})


def _outlier_clusters(rng, pts, tri, clean, unit, spacing, clusters, size,
                      tries: int = 200) -> np.ndarray:
    """Stray clusters in front of the surface, each point 10 to 50 spacings from it."""
    out = []
    lo_d, hi_d = _OUTLIER_DISTANCE
    if spacing <= 0:
        return np.empty((0, 3))
    for _ in range(clusters):
        for _attempt in range(tries):
            k = int(rng.integers(len(clean)))
            # towards the scanner along the anchor's ray, well inside the distance band
            along = rng.uniform(lo_d + 4 * _OUTLIER_SPREAD, hi_d - 4 * _OUTLIER_SPREAD) * spacing
            centre = clean[k] - along * unit[k]
            cluster = centre + rng.normal(0.0, _OUTLIER_SPREAD * spacing, (size, 3))
            d = distance_to_mesh(cluster, pts, tri) / spacing
            if d.min() >= lo_d and d.max() <= hi_d:
                out.append(cluster)
                break
        else:  # pragma: no cover - only on a tiny or very crumpled mesh
            raise ValueError("could not place an outlier cluster 10 to 50 median spacings from "
                             "the surface")
    return np.concatenate(out) if out else np.empty((0, 3))


# -- the corpus ------------------------------------------------------------------------------

#: What :func:`corpus` builds: (name, recipe); the small list first, then what 'full' adds.
_SMALL = (
    ("cow", ("model", "cow")),
    ("bone", ("model", "bone")),
    ("airplane", ("model", "airplane")),
    ("cube", ("model", "cube")),
    ("bunny10k_textured", ("model", "bunny10k_textured")),
    ("cow-uniform-6k", ("resample", "cow", 6000, "uniform")),
    ("cow-density-6k", ("resample", "cow", 6000, "density")),
    ("cow-noisy-6k", ("resample", "cow", 6000, "noisy")),
    ("bunny10k-scan-1", ("scan", "bunny10k_textured", 160)),
    ("cow-scan-1", ("scan", "cow", 192)),
)
_FULL = (
    ("bunny", ("model", "bunny")),
    ("face000", ("model", "face000")),
    ("bunny-uniform-30k", ("resample", "bunny", 30000, "uniform")),
    ("bunny-density-30k", ("resample", "bunny", 30000, "density")),
    ("bunny-noisy-30k", ("resample", "bunny", 30000, "noisy")),
    ("airplane-uniform-20k", ("resample", "airplane", 20000, "uniform")),
    ("airplane-density-20k", ("resample", "airplane", 20000, "density")),
    ("bone-noisy-8k", ("resample", "bone", 8000, "noisy")),
    ("bunny-scan-1", ("scan", "bunny", 320)),
    ("bunny-scan-2", ("scan", "bunny", 320)),
    ("bunny-scan-3", ("scan", "bunny", 320)),
)
_WHICH = {"small": _SMALL, "full": _SMALL + _FULL}


def corpus_names(which: str = "small") -> list[str]:
    """The names of the entries of :func:`corpus` (nothing is built)."""
    if which not in _WHICH:
        raise ValueError(f"which must be 'small' or 'full', got {which!r}")
    return [name for name, _ in _WHICH[which]]


def corpus(which: str = "small", seed: int = 0, *, only=None) -> list[CorpusEntry]:
    """The corpus: pymeshlab's models, resamplings of them and simulated range scans.

    Parameters
    ----------
    which : {'small', 'full'}, default: 'small'
        ``'small'`` (for CI; builds in about a second once the numba
        kernels are cached): the cow, bone, airplane, cube and
        bunny10k_textured models; 6,000 uniform, density-ramp and noisy
        points on the cow; a 160x160 scan of bunny10k_textured and a
        192x192 scan of the cow. ``'full'``: the small list, plus the bunny
        and the real face scan (face000); uniform, density and noisy
        resamplings of the bunny (30k), uniform and density of the
        airplane (20k), noisy of the bone (8k); three 320x320 scans of the
        bunny from different viewpoints. (``colored_airplane`` is left out:
        the airplane's geometry again.)
    seed : int, default: 0
        Seed of the resamplings and scans (each entry draws from its own
        stream derived from it and its position in the list).
    only : iterable of str, optional
        Build only the entries whose name matches one of these shell
        patterns (``['cow*', 'cube']``).

    Returns
    -------
    list of CorpusEntry
        In the order of :func:`corpus_names`.
    """
    names = corpus_names(which)
    seed = _rng_seed(seed)
    patterns = None if only is None else [str(p) for p in only]
    models: dict[str, CorpusEntry] = {}

    def base(key):
        if key not in models:
            models[key] = model(key)
        return models[key]

    out = []
    for k, (name, recipe) in enumerate(_WHICH[which]):
        if patterns is not None and not any(fnmatch.fnmatchcase(name, p) for p in patterns):
            continue
        if recipe[0] == "model":
            out.append(base(recipe[1]))
            continue
        m = base(recipe[1])
        stream = _child_seed(seed, k)
        if recipe[0] == "resample":
            _, _, n, mode = recipe
            e = resample(m.ref_points, m.ref_triangles, n, mode, seed=stream, name=name)
        else:
            _, _, res = recipe
            e = range_scan(m.ref_points, m.ref_triangles, resolution=(res, res),
                           fov=SCAN_FOV, seed=stream, name=name)
        e.description = f"{m.name}: {e.description}"
        out.append(e)
    if patterns is not None and not out:
        raise ValueError(f"no entry of the {which} corpus matches {patterns}: "
                         f"{', '.join(names)}")
    return out
