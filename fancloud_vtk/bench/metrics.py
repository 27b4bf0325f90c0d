"""The measures of the benchmarks: distances to a reference surface, mesh statistics,
Hausdorff, feature and colour errors, volumes, and the memory of a process.

Importable on its own (numpy, and VTK / scipy / pymeshlab inside the functions that
need them): the tests and ``fancloud demo`` use it without the rest of the bench.
"""

from __future__ import annotations

import os
import resource
import threading
import time

import numpy as np

from fancloud_vtk.bench.common import _plain, _read, _short

SAMPLE_CHUNK = 1 << 20  #: surface samples per chunk
SAMPLE_INTERVAL = 0.002  #: seconds between RSS samples
FEATURE_FRACTION = 0.10  #: the most curved share of the input points: the feature region


# -- distances -----------------------------------------------------------------------


class MeshDistance:
    """Unsigned distance to a triangle mesh (``vtkImplicitPolyDataDistance``), vectorised."""

    def __init__(self, points: np.ndarray, triangles: np.ndarray):
        from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
        from vtkmodules.vtkCommonCore import vtkPoints
        from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
        from vtkmodules.vtkFiltersCore import vtkImplicitPolyDataDistance

        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
        polys = vtkCellArray()
        polys.SetData(3, numpy_to_vtkIdTypeArray(
            np.ascontiguousarray(triangles, dtype=np.int64).ravel(), deep=True))
        self._mesh = vtkPolyData()
        self._mesh.SetPoints(pts)
        self._mesh.SetPolys(polys)
        self._distance = vtkImplicitPolyDataDistance()
        self._distance.SetInput(self._mesh)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
        from vtkmodules.vtkCommonCore import vtkDoubleArray

        out = vtkDoubleArray()
        self._distance.FunctionValue(numpy_to_vtk(np.ascontiguousarray(x), deep=True), out)
        return np.abs(vtk_to_numpy(out))


def sphere_distance(x: np.ndarray) -> np.ndarray:
    """Distance to the unit sphere."""
    return np.abs(np.linalg.norm(x, axis=1) - 1.0)


def surface_distance(vertices, triangles, distance, n_samples: int, seed: int = 0) -> dict:
    """Distance of a mesh to a reference surface: area-weighted samples plus the used vertices.

    ``n_samples`` points uniform on the mesh's surface (triangle chosen by
    area, uniform barycentric coordinates), in chunks; the mean is over the
    samples, the max over the samples and every vertex of a triangle.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(t) == 0:
        return {"mean": None, "max": None, "samples": 0}
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    cum = np.cumsum(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1))
    dmax = float(distance(v[np.flatnonzero(np.bincount(np.ravel(t), minlength=len(v)))]).max())
    total, dsum, done = cum[-1], 0.0, 0
    rng = np.random.default_rng(seed)
    while total > 0 and done < n_samples:
        m = min(SAMPLE_CHUNK, n_samples - done)
        idx = np.minimum(np.searchsorted(cum, rng.random(m) * total, side="right"), len(t) - 1)
        r1 = np.sqrt(rng.random(m))[:, None]
        r2 = rng.random(m)[:, None]
        x = (1.0 - r1) * a[idx] + r1 * (1.0 - r2) * b[idx] + r1 * r2 * c[idx]
        d = distance(x)
        dsum += float(d.sum())
        dmax = max(dmax, float(d.max()))
        done += m
    return {"mean": dsum / done if done else None, "max": dmax, "samples": done}


def mesh_statistics_of(vertices, triangles, self_intersections: bool) -> dict:
    """:func:`fancloud_vtk.core.mesh_stats.mesh_statistics`, or why it is not available."""
    try:
        from fancloud_vtk.core.mesh_stats import mesh_statistics
    except ImportError as exc:
        return {"error": f"mesh_statistics not available ({_short(exc)})"}
    try:
        t0 = time.perf_counter()
        stats = _plain(dict(mesh_statistics(vertices, triangles,
                                            self_intersections=self_intersections)))
        if (stats.get("self_intersections") or 0) < 0:
            stats["self_intersections"] = None  # -1: not computed
        return {**stats, "time": time.perf_counter() - t0}
    except Exception as exc:
        return {"error": f"mesh_statistics failed ({_short(exc)})"}


def used_inputs(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
                diag: float) -> np.ndarray:
    """Which input points are vertices of a triangle (by position: a method may reorder)."""
    used = np.unique(triangles)
    if len(vertices) == len(points) and np.array_equal(vertices, points):
        mask = np.zeros(len(points), dtype=bool)
        mask[used] = True
        return mask
    if len(used) == 0:
        return np.zeros(len(points), dtype=bool)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(vertices[used]).query(points, distance_upper_bound=1e-6 * diag + 1e-300)
    return np.isfinite(d)


def signed_volume(vertices, triangles) -> float:
    """Volume enclosed by an oriented triangle mesh (divergence theorem: sum a.(b x c) / 6)."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0


# -- errors of a reduced surface against its input (bench reduce, bench refine) ---------


def curvature(points, triangles) -> tuple[np.ndarray, str]:
    """Per-point curvature of the input and how it was computed.

    pymeshlab's discrete ``ABS Curvature`` (|k1| + |k2|), a measure
    independent of ours; the entropy's curvature term when pymeshlab fails.
    """
    try:
        import pymeshlab

        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(points, np.float64),
                                   face_matrix=np.ascontiguousarray(triangles, np.int32)))
        ms.compute_scalar_by_discrete_curvature_per_vertex(curvaturetype="ABS Curvature")
        q = np.asarray(ms.current_mesh().vertex_scalar_array(), dtype=np.float64)
        if len(q) == len(points) and np.isfinite(q).any():
            return np.nan_to_num(q, nan=0.0), (
                "pymeshlab compute_scalar_by_discrete_curvature_per_vertex('ABS Curvature')")
    except Exception:  # pragma: no cover - pymeshlab is a dependency
        pass
    from fancloud_vtk import entropy, fan_cloud_of_mesh

    return entropy(fan_cloud_of_mesh(points, triangles)).curv, "fancloud_vtk entropy M_curv"


def sample_surface(vertices, triangles, m: int, rng) -> np.ndarray:
    """``m`` points uniform on a triangle mesh (triangle by area, uniform barycentrics)."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    cum = np.cumsum(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1))
    idx = np.minimum(np.searchsorted(cum, rng.random(m) * cum[-1], side="right"), len(t) - 1)
    r1 = np.sqrt(rng.random(m))[:, None]
    r2 = rng.random(m)[:, None]
    return (1.0 - r1) * a[idx] + r1 * (1.0 - r2) * b[idx] + r1 * r2 * c[idx]


class Reference:
    """The input surface and what every result is measured against."""

    def __init__(self, data: dict, samples: int, seed: int):
        pts, tri = data["points"], data["triangles"]
        self.n = len(pts)
        self.points, self.triangles = pts, tri
        self.diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
        self.distance = MeshDistance(pts, tri)
        self.samples = samples
        self.seed = seed
        self.surface = sample_surface(pts, tri, samples * self.n, np.random.default_rng(seed))
        curv, self.curvature_source = curvature(pts, tri)
        n_feat = max(1, int(round(FEATURE_FRACTION * self.n)))
        self.features = np.argsort(-curv, kind="stable")[:n_feat]
        self.colors = (None if data["colors"] is None  # RGB in [0, 1]
                       else np.asarray(data["colors"], dtype=np.float64)[:, :3] / 255.0)
        self._tree = None
        self.topology = topology(pts, tri)

    def tree(self):
        from scipy.spatial import cKDTree

        if self._tree is None:
            self._tree = cKDTree(self.points)
        return self._tree


def colour_at(query, vertices, triangles, colors) -> np.ndarray:
    """Colours at ``query``: barycentric on the nearest point of the mesh (pyvista locator)."""
    import pyvista as pv

    faces = np.column_stack([np.full(len(triangles), 3), triangles]).ravel()
    mesh = pv.PolyData(np.asarray(vertices, np.float64), faces)
    cell, closest = mesh.find_closest_cell(np.asarray(query, np.float64),
                                           return_closest_point=True)
    tri = np.asarray(triangles)[cell]
    a, b, c = (np.asarray(vertices)[tri[:, i]] for i in range(3))
    v0, v1, v2 = b - a, c - a, closest - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    den[den == 0] = 1.0
    w1 = np.clip((d11 * d20 - d01 * d21) / den, 0, 1)
    w2 = np.clip((d00 * d21 - d01 * d20) / den, 0, 1)
    w0 = np.clip(1.0 - w1 - w2, 0, 1)
    w = np.column_stack([w0, w1, w2])
    w /= np.maximum(w.sum(1, keepdims=True), 1e-300)
    col = np.asarray(colors, np.float64)[:, :3]
    return w[:, :1] * col[tri[:, 0]] + w[:, 1:2] * col[tri[:, 1]] + w[:, 2:] * col[tri[:, 2]]


#: the topology counts of a mesh that ``fancloud bench reduce`` reports (mesh_statistics)
TOPOLOGY_KEYS = ("boundary_edges", "non_manifold_edges", "non_manifold_vertices",
                 "euler_characteristic", "components", "self_intersections")


def topology(points, triangles) -> dict:
    """Boundary edges, non-manifold edges and vertices, Euler characteristic, components
    and self-intersecting triangle pairs of a mesh."""
    from fancloud_vtk.core.mesh_stats import mesh_statistics

    s = mesh_statistics(np.asarray(points, np.float64), np.asarray(triangles, np.int64),
                        self_intersections=True)
    return {k: int(s[k]) for k in TOPOLOGY_KEYS}


def topology_defects(mine: dict, ref: dict) -> int:
    """How far a result is from a 2-manifold with the input's topology: its non-manifold
    edges and vertices, its boundary edges if the input has none, and the changes of the
    Euler characteristic and of the number of components."""
    bad = mine["non_manifold_edges"] + mine["non_manifold_vertices"]
    if ref["boundary_edges"] == 0:
        bad += mine["boundary_edges"]
    bad += abs(mine["euler_characteristic"] - ref["euler_characteristic"])
    return bad + abs(mine["components"] - ref["components"])


def measure_result(r: dict, ref: Reference) -> None:
    """Kept vertices, Hausdorff, feature and colour errors of one result, in place."""
    vertices, triangles = r.pop("vertices", None), r.pop("triangles", None)
    colors, ids = r.pop("colors", None), r.pop("original_id", None)
    if vertices is None:
        return
    t0 = time.perf_counter()
    triangles = np.asarray(triangles, np.int64).reshape(-1, 3)
    r["kept"] = len(vertices)
    r["triangles_out"] = len(triangles)
    diag = ref.diag
    m = {"points_only": bool((r.get("info") or {}).get("points_only"))}
    if not m["points_only"] and len(triangles) == 0:
        r["message"] += "; its mesh has no triangles: distances not measured"
        m.update(hausdorff_max=None, hausdorff_mean=None, feature_mean=None, feature_max=None,
                 how="no triangles")
    elif m["points_only"]:
        # one way: the kept points to the input surface; no surface to measure features on
        d = ref.distance(np.asarray(vertices, np.float64)) if len(vertices) else np.zeros(1)
        m.update(hausdorff_max=float(d.max()) / diag, hausdorff_mean=float(d.mean()) / diag,
                 feature_mean=None, feature_max=None,
                 how="one way: kept points to the input surface (a point set has no surface)")
    else:
        r["unreferenced"] = int(len(vertices) - len(np.unique(triangles)))
        to_result = MeshDistance(vertices, triangles)
        d_samples = to_result(ref.surface)
        d_points = to_result(ref.points)
        back = surface_distance(vertices, triangles, ref.distance, ref.samples * ref.n,
                                ref.seed + 1)
        fwd_mean = float(d_samples.mean())
        fwd_max = max(float(d_samples.max()), float(d_points.max()))
        feat = d_points[ref.features]
        m.update(forward_mean=fwd_mean / diag, forward_max=fwd_max / diag,
                 backward_mean=back["mean"] / diag, backward_max=back["max"] / diag,
                 hausdorff_max=max(fwd_max, back["max"]) / diag,
                 hausdorff_mean=0.5 * (fwd_mean + back["mean"]) / diag,
                 feature_mean=float(feat.mean()) / diag, feature_max=float(feat.max()) / diag,
                 how="both ways, mean of the two directions' means")
        m["topology"] = topology(vertices, triangles)
        m["topology_defects"] = topology_defects(m["topology"], ref.topology)
    if ref.colors is not None and len(vertices) and (m["points_only"] or len(triangles)):
        if colors is not None and len(colors) == len(vertices):
            # uint8 from ours, 0..255 floats from pymeshlab (see fancloud_vtk.bench.peers)
            vcol = np.asarray(colors, np.float64)[:, :3] / 255.0
            m["colour_source"] = "carried"
        else:  # the method drops colours: its vertices take the nearest input point's
            _, near = ref.tree().query(vertices)
            vcol, m["colour_source"] = ref.colors[near], "nearest input point"
        if m["points_only"]:
            from scipy.spatial import cKDTree

            _, near = cKDTree(vertices).query(ref.points)
            est = vcol[near]
        else:
            est = colour_at(ref.points, vertices, triangles, vcol)
        m["colour_rms"] = float(np.sqrt(np.mean((est - ref.colors) ** 2)))
    if ids is not None and len(ids) == len(vertices):
        m["vertices_are_input_points"] = bool(np.allclose(vertices, ref.points[ids]))
    m["time"] = time.perf_counter() - t0
    r["measures"] = m


# -- memory of this process (the fresh processes of bench fans) -----------------------------


_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def rss_bytes() -> int:
    """Current resident set size (``/proc/self/statm``)."""
    with open("/proc/self/statm", "rb") as f:
        return int(f.read().split()[1]) * _PAGE


def maxrss_bytes() -> int:
    """Peak resident set size so far (``getrusage``; kilobytes on Linux).

    It also keeps the peaks of exited threads (scipy's query workers), which
    :func:`reset_peak_rss` does not clear; :func:`hwm_bytes` does.
    """
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def hwm_bytes() -> int | None:
    """Peak resident set size of the address space (``VmHWM`` in ``/proc/self/status``)."""
    for line in _read("/proc/self/status").splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    return None


def reset_peak_rss() -> bool:
    """Reset the kernel's peak-RSS mark ``VmHWM`` (Linux ``clear_refs`` 5); True if it worked."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        return False
    hwm = hwm_bytes()
    return hwm is not None and hwm <= rss_bytes() + (1 << 20)


class RssSampler(threading.Thread):
    """Samples the RSS every ``interval`` seconds in the background; keeps the peak.

    Code holding the GIL (numba kernels without ``nogil``) starves it, so the
    peak from ``getrusage`` is taken as well (see
    :func:`fancloud_vtk.bench.fans.child_memory`).
    """

    def __init__(self, interval: float = SAMPLE_INTERVAL):
        super().__init__(daemon=True)
        self.interval = interval
        self.peak = rss_bytes()
        self.samples = 0
        self._stop_event = threading.Event()

    def run(self):
        fd = os.open("/proc/self/statm", os.O_RDONLY)
        try:
            while not self._stop_event.is_set():
                self.peak = max(self.peak, int(os.pread(fd, 128, 0).split()[1]) * _PAGE)
                self.samples += 1
                time.sleep(self.interval)
        finally:
            os.close(fd)

    def stop(self) -> int:
        """Stop sampling (one last sample first); the peak in bytes."""
        self.peak = max(self.peak, rss_bytes())
        self._stop_event.set()
        self.join()
        return self.peak

