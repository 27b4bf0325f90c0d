"""The surface-reconstruction methods compared by ``fancloud bench mesh``, and how they run.

Each method is a *loader*: a function that imports what the method needs
(an :class:`ImportError` there means the method is missing) and returns a
``run(points)`` callable. ``run`` returns a dict:

``vertices``
    ``(v, 3)`` float array, the mesh's points;
``triangles``
    ``(m, 3)`` integer indices into ``vertices``;
``new_points``
    True when ``vertices`` are new points (an iso-surface), not the input;
``info``
    anything JSON-serialisable worth keeping (stage counts, parameters).

``--methods`` also accepts ``module:function`` loaders of this form.

:func:`run_method` (the benchmark's side) runs one loader in a fresh process,
:func:`child_main`, with a timeout. The child warms the method up on a small
cloud, times ``run`` on the points, and writes ``result.json`` (before and
after every timed run) and ``mesh.npz`` (after the first), so a method that
is missing, raises, crashes (a segfault) or hangs is reported as such instead
of taking the benchmark down. :func:`mesh_statistics_of` and
:func:`surface_distance` then measure the mesh in the benchmark's process.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass

import numpy as np

K = 6  #: neighbours per fan (the paper's default), as in ``bench fans``


@dataclass(frozen=True)
class Method:
    """A method of the comparison: its name, loader and how it is called."""

    name: str
    label: str
    loader: str  #: ``module:function`` returning ``run(points)``
    call: str  #: the calls timed, for the table
    new_points: bool = False  #: output vertices are new points (unused points: n/a)


def _result(vertices, triangles, *, new_points=False, **info) -> dict:
    return {"vertices": np.asarray(vertices, dtype=np.float64),
            "triangles": np.asarray(triangles, dtype=np.int64).reshape(-1, 3),
            "new_points": new_points, "info": info}


# -- the methods ----------------------------------------------------------------------


def load_ours():
    """This project: build_fans, then fan_cloud_to_mesh (timed together)."""
    from fancloud_vtk import build_fans, fan_cloud_to_mesh

    def run(points):
        t0 = time.perf_counter()
        fc = build_fans(points, k=K)
        t1 = time.perf_counter()
        # the harness counts self-intersections for every method alike: not timed here
        mesh = fan_cloud_to_mesh(fc, close_holes=True, self_intersections=False)
        t2 = time.perf_counter()
        stats = _plain(dict(getattr(mesh, "stats", None) or {}))
        stages = {k: v for k, v in stats.items() if isinstance(v, int | float)}
        return _result(getattr(mesh, "points", fc.points), mesh.triangles,
                       build_fans_time=t1 - t0, to_mesh_time=t2 - t1, stages=stages,
                       other_stats={k: v for k, v in stats.items() if k not in stages},
                       fans_open=int(fc.n_open),
                       duplicates_merged=int(fc.info.get("duplicates_merged", 0)))

    return run


def load_ours_pyvista():
    """This project as a user calls it: ``pv.PolyData(points).fancloud.mesh()``, defaults.

    PolyData in and out: the conversions, the fans, the mesh (self-intersections
    removed), the statistics as field arrays.
    """
    import pyvista as pv

    import fancloud_vtk.accessor  # noqa: F401  (the entry point, registered explicitly)

    def run(points):
        out = pv.PolyData(np.ascontiguousarray(points, dtype=np.float64)).fancloud.mesh()
        faces = np.asarray(out.faces).reshape(-1, 4)[:, 1:]
        return _result(np.asarray(out.points, dtype=np.float64), faces)

    return run


def load_meshlib():
    """MeshLib: ``triangulatePointCloud`` with its default parameters."""
    import meshlib.mrmeshnumpy as mn
    import meshlib.mrmeshpy as mm

    def run(points):
        cloud = mn.pointCloudFromPoints(np.ascontiguousarray(points, dtype=np.float64))
        mesh = mm.triangulatePointCloud(cloud)
        if mesh is None:
            raise RuntimeError("triangulatePointCloud returned no mesh (interrupted)")
        triangles = mn.getNumpyFaces(mesh.topology)
        # MeshLib keeps the input points, in order (stored as float32); keep the exact ones
        verts = points if mesh.points.size() == len(points) else mn.getNumpyVerts(mesh)
        return _result(verts, triangles)

    return run


def _pymeshlab_cloud(points):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.ascontiguousarray(points, dtype=np.float64)))
    ms.compute_normal_for_point_clouds()
    return ms


def load_ball_pivoting():
    """pymeshlab ball pivoting, normals from its point-cloud filter, default parameters."""
    import pymeshlab  # noqa: F401

    def run(points):
        ms = _pymeshlab_cloud(points)
        ms.generate_surface_reconstruction_ball_pivoting()
        m = ms.current_mesh()
        return _result(m.vertex_matrix(), m.face_matrix())

    return run


def load_poisson():
    """pymeshlab screened Poisson, normals from its point-cloud filter, default parameters."""
    import pymeshlab  # noqa: F401

    def run(points):
        ms = _pymeshlab_cloud(points)
        ms.generate_surface_reconstruction_screened_poisson()
        m = ms.current_mesh()
        return _result(m.vertex_matrix(), m.face_matrix(), new_points=True)

    return run


def load_vtk():
    """VTK: vtkSurfaceReconstructionFilter, then vtkContourFilter at 0."""
    from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkContourFilter
    from vtkmodules.vtkImagingHybrid import vtkSurfaceReconstructionFilter

    def run(points):
        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
        cloud = vtkPolyData()
        cloud.SetPoints(pts)
        recon = vtkSurfaceReconstructionFilter()
        recon.SetInputData(cloud)
        contour = vtkContourFilter()
        contour.SetInputConnection(recon.GetOutputPort())
        contour.SetValue(0, 0.0)
        contour.Update()
        out = contour.GetOutput()
        if out.GetNumberOfPoints() == 0:
            return _result(np.empty((0, 3)), np.empty((0, 3)), new_points=True,
                           sample_spacing=recon.GetSampleSpacing())
        polys = out.GetPolys()
        conn = vtk_to_numpy(polys.GetConnectivityArray())
        offsets = vtk_to_numpy(polys.GetOffsetsArray())
        if not np.all(np.diff(offsets) == 3):
            raise RuntimeError("vtkContourFilter returned polygons that are not triangles")
        return _result(vtk_to_numpy(out.GetPoints().GetData()), conn.reshape(-1, 3),
                       new_points=True, sample_spacing=recon.GetSampleSpacing(),
                       neighborhood_size=recon.GetNeighborhoodSize())

    return run


_HERE = __name__

METHODS = {m.name: m for m in (
    Method("ours", "fancloud_vtk (this project)", f"{_HERE}:load_ours",
           f"build_fans(points, k={K}) + fan_cloud_to_mesh(fc, self_intersections=False) "
           "(self-intersections removed, the default)"),
    Method("ours-pyvista", "fancloud_vtk, PolyData in and out", f"{_HERE}:load_ours_pyvista",
           "pv.PolyData(points).fancloud.mesh() with its defaults (the call a user makes)"),
    Method("meshlib", "MeshLib triangulatePointCloud", f"{_HERE}:load_meshlib",
           "mrmeshnumpy.pointCloudFromPoints(points) + mrmeshpy.triangulatePointCloud(cloud), "
           "default TriangulationParameters (numNeighbours 16, critAngle 90 deg, "
           "automaticRadiusIncrease)"),
    Method("ball-pivoting", "pymeshlab ball pivoting", f"{_HERE}:load_ball_pivoting",
           "compute_normal_for_point_clouds() (k=10) + "
           "generate_surface_reconstruction_ball_pivoting() (defaults: radius auto, "
           "clustering 20%, creasethr 90)"),
    Method("poisson", "pymeshlab screened Poisson", f"{_HERE}:load_poisson",
           "compute_normal_for_point_clouds() (k=10) + "
           "generate_surface_reconstruction_screened_poisson() (defaults: depth 8, "
           "samplespernode 1.5, pointweight 4, threads 2)", new_points=True),
    Method("vtk", "VTK vtkSurfaceReconstructionFilter", f"{_HERE}:load_vtk",
           "vtkSurfaceReconstructionFilter (neighbourhood 20, spacing auto) + "
           "vtkContourFilter(value 0)", new_points=True),
)}

#: What a missing method needs, for its "missing: ... not available" message.
REQUIRES = {"ours": "fan_cloud_to_mesh", "ours-pyvista": "pyvista",
            "meshlib": "meshlib (pip install meshlib)", "ball-pivoting": "pymeshlab",
            "poisson": "pymeshlab", "vtk": "vtk"}


def method_for(spec: str) -> Method:
    """A registered method by name, or a ``module:function`` loader of the same protocol."""
    if spec in METHODS:
        return METHODS[spec]
    if ":" in spec:
        return Method(spec, spec, spec, f"{spec} (user loader)")
    raise ValueError(f"unknown method {spec!r}: one of {', '.join(METHODS)} or module:function")


# -- the subprocess ------------------------------------------------------------------------


def _import_loader(path: str):
    import importlib

    module, _, attr = path.partition(":")
    return getattr(importlib.import_module(module), attr)


def _short(exc: BaseException, limit: int = 240) -> str:
    """``Type: message`` on one line, without the file path ImportError appends, shortened."""
    import re

    text = " ".join(str(exc).split())
    text = re.sub(r"\s*\((?:unknown location|/[^)]*)\)$", "", text)
    if len(text) > limit:
        text = text[: limit - 3] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _write_json(path: str, data: dict) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(data, f, default=str)
    os.replace(tmp, path)


def _load_method(loader: str, res: dict, result_path: str):
    """The method's run function, or None after writing why it is missing or failed."""
    try:
        return _import_loader(loader)()
    except ImportError as exc:
        res.update(status="missing", error=_short(exc))
    except Exception as exc:
        res.update(status="failed", error="loading: " + _short(exc),
                   traceback=traceback.format_exc()[-3000:])
    _write_json(result_path, res)
    return None


def child_main(argv: list[str]) -> int:
    """``NAME LOADER POINTS.npy OUT_DIR REPEAT WARMUP_N``: run one method, write its results."""
    name, loader, points_path, out_dir, repeat, warmup_n = argv
    repeat, warmup_n = int(repeat), int(warmup_n)
    result_path = os.path.join(out_dir, "result.json")
    res = {"name": name, "status": "running", "times": []}
    run = _load_method(loader, res, result_path)
    if run is None:
        return 0
    points = np.load(points_path)
    try:
        if warmup_n:
            from fancloud_vtk.bench import surface_points

            t0 = time.perf_counter()
            run(surface_points(warmup_n, 1, "sphere"))
            res["warmup_time"] = time.perf_counter() - t0
            res["warmup_points"] = warmup_n
        _write_json(result_path, res)
        for i in range(repeat):
            res["timed_start_epoch"] = time.time()
            _write_json(result_path, res)
            t0 = time.perf_counter()
            out = run(points)
            res["times"].append(time.perf_counter() - t0)
            if i == 0:
                tmp = os.path.join(out_dir, "mesh.tmp.npz")
                np.savez(tmp, vertices=np.asarray(out["vertices"], dtype=np.float64),
                         triangles=np.asarray(out["triangles"], dtype=np.int64).reshape(-1, 3))
                os.replace(tmp, os.path.join(out_dir, "mesh.npz"))
                res["new_points"] = bool(out.get("new_points", False))
                res["info"] = out.get("info", {})
            del out
            res["status"] = "ok" if i == repeat - 1 else "running"
            _write_json(result_path, res)
    except Exception as exc:
        res.update(status="failed", error=_short(exc),
                   traceback=traceback.format_exc()[-3000:])
        _write_json(result_path, res)
    return 0


# -- the parent side: a method's process, and the measures of its mesh ---------------------

SAMPLE_CHUNK = 1 << 20  #: surface samples per chunk

_PEER_CHILD = ("import sys; from fancloud_vtk._bench_peers import child_main; "
               "sys.exit(child_main(sys.argv[1:]))")


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


def _plain(value):
    """numpy scalars and arrays to Python objects (for JSON), recursively through containers."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value.item() if isinstance(value, np.generic) else value


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


def _signal_name(code: int) -> str:
    import signal

    try:
        return signal.Signals(-code).name
    except ValueError:
        return f"signal {-code}"


def _last_line(path: str) -> str:
    """The last line of a child's stderr, or faulthandler's ``Fatal Python error`` line."""
    with open(path, errors="replace") as f:
        lines = [line.strip() for line in f.read().splitlines() if line.strip()]
    fatal = [line for line in lines if line.startswith("Fatal Python error")]
    return (fatal or lines or ["no output on stderr"])[-1][:300]


def _child_status(method, code, child: dict, err_path: str, timeout: float, times: list,
                  repeat: int, requires: dict | None = None) -> tuple[str, str]:
    """``(status, message)`` of a method's process from its exit code and ``result.json``.

    ``status`` is ``ok``, ``missing``, ``failed``, ``crashed`` or ``timeout``;
    ``times`` are the timed runs that finished (a timeout after one is ``ok``).
    """
    phase = "while timed" if child.get("timed_start_epoch") else "while loading or warming up"
    if code is None:
        if not times:
            return "timeout", f"timed out after {timeout:g} s ({phase})"
        return "ok", f"ok ({len(times)} of {repeat} runs before the {timeout:g} s timeout)"
    if code < 0:
        return "crashed", f"crashed ({_signal_name(code)}, {phase}): {_last_line(err_path)}"
    if child.get("status") == "missing":
        need = (REQUIRES if requires is None else requires).get(method.name, method.loader)
        return "missing", f"missing: {need} not available ({child['error']})"
    if child.get("status") == "failed":
        return "failed", f"failed: {child['error']}"
    if code != 0 or child.get("status") != "ok":
        return "failed", f"failed (exit {code}): {_last_line(err_path)}"
    return "ok", "ok"


def run_method(method, points_path: str, work_dir: str, *, timeout: float, repeat: int = 1,
               warmup: int | None = None) -> dict:
    """Run one method in a fresh process (:func:`child_main`), with a timeout.

    Returns ``status`` (``ok``, ``missing``, ``failed``, ``crashed`` or
    ``timeout``), ``message`` (for the table), the timed runs and, when a
    run finished, the mesh (``vertices``, ``triangles``).
    """
    from fancloud_vtk.bench import WARMUP_POINTS, _child_env

    warmup = WARMUP_POINTS if warmup is None else warmup
    out_dir = tempfile.mkdtemp(prefix=f"{method.name.replace(':', '_')}-", dir=work_dir)
    err_path = os.path.join(out_dir, "stderr.txt")
    cmd = [sys.executable, "-X", "faulthandler", "-c", _PEER_CHILD, method.name,
           method.loader, points_path, out_dir, str(repeat), str(warmup)]
    t0 = time.perf_counter()
    with open(os.path.join(out_dir, "stdout.txt"), "w") as out, open(err_path, "w") as err:
        try:
            code = subprocess.run(cmd, env=_child_env(), stdout=out, stderr=err,
                                  timeout=timeout, check=False).returncode
        except subprocess.TimeoutExpired:
            code = None
    wall, killed_epoch = time.perf_counter() - t0, time.time()
    result_path = os.path.join(out_dir, "result.json")
    child = {}
    if os.path.isfile(result_path):
        with open(result_path) as f:
            child = json.load(f)
    times = child.get("times", [])
    res = {"method": method.name, "label": method.label, "call": method.call,
           "new_points": bool(child.get("new_points", method.new_points)), "times": times,
           "time": min(times) if times else None, "warmup_time": child.get("warmup_time"),
           "wall_time": wall, "exit_code": code, "info": child.get("info", {})}
    started = child.get("timed_start_epoch")
    if code is None and started and not times:  # the timed run took at least this long
        res["time_lower_bound"] = killed_epoch - started
    status, message = _child_status(method, code, child, err_path, timeout, times, repeat)
    if status == "failed" and child.get("traceback"):
        res["traceback"] = child["traceback"]
    res.update(status=status, message=message)
    mesh_path = os.path.join(out_dir, "mesh.npz")
    if status == "ok" and os.path.isfile(mesh_path):
        with np.load(mesh_path) as z:
            res["vertices"], res["triangles"] = z["vertices"], z["triangles"]
    elif status == "ok":
        res.update(status="failed", message="failed: the method wrote no mesh")
    return res



# == ``fancloud bench reduce``: the reduction methods ======================================
#
# A reduction loader returns ``run(data, target)``. ``data`` is a dict: ``points``
# ``(n, 3)``, ``triangles`` ``(m, 3)`` (the input mesh), ``colors`` (``(n, 3)`` uint8 or
# None) and ``from_points`` (True: the input is the points, the mesh is what the peers
# get). ``target`` is the number of vertices to keep. ``run`` returns a dict:
# ``vertices``, ``triangles`` (``(0, 3)`` for a point-only result), optionally ``colors``
# (per output vertex, uint8, when the method carries them), ``original_id`` (when the
# vertices are input points), ``time`` (the seconds that count, when not the whole call)
# and ``info`` (``points_only``: True for a point set, whose triangles are none by design).


def _ours_reducer(weights, method="entropy"):
    from fancloud_vtk import build_fans, fan_cloud_of_mesh, fan_cloud_to_mesh, reduce

    def run(data, target):
        colors = data.get("colors")
        pdata = {"RGB": colors} if colors is not None else None
        t0 = time.perf_counter()
        if data["from_points"]:
            fc = build_fans(data["points"], k=K, point_data=pdata)
            prepare = "build_fans"
        else:
            fc = fan_cloud_of_mesh(data["points"], data["triangles"], point_data=pdata)
            prepare = "fan_cloud_of_mesh"
        t1 = time.perf_counter()
        small = reduce(fc, target, weights=weights, method=method)
        t2 = time.perf_counter()
        # for the measures; rings as the reduce filter meshes them (docs/entropy.md)
        rings = "delaunay" if data["from_points"] else "fans"
        mesh = fan_cloud_to_mesh(small, rings=rings, self_intersections=False)
        t3 = time.perf_counter()
        out_colors = mesh.point_data.get("RGB", small.point_data.get("RGB"))
        if len(mesh.points) != small.n_points:  # not expected: keep the ids only if they fit
            out_colors = None
        return {"vertices": mesh.points, "triangles": mesh.triangles, "colors": out_colors,
                "original_id": small.point_data["original_id"]
                if len(mesh.points) == small.n_points else None,
                "time": t2 - t1,
                "info": {"prepare": prepare, "prepare_time": t1 - t0, "reduce_time": t2 - t1,
                         "to_mesh_time": t3 - t2, "kept_points": int(small.n_points)}}

    return run


def load_reduce_uniform():
    """Ours: entropy with weights (1, 0, 0, 0) (the paper's Figure 9a)."""
    return _ours_reducer((1.0, 0.0, 0.0, 0.0))


def load_reduce_shape():
    """Ours: entropy with weights (1, 1, 50, 0) (the default; Figure 9b)."""
    return _ours_reducer((1.0, 1.0, 50.0, 0.0))


def load_reduce_colour():
    """Ours: entropy with weights (1, 1, 50, 1) and the input's colours."""
    return _ours_reducer((1.0, 1.0, 50.0, 1.0))


def load_reduce_colour_distance():
    """Ours: entropy with weights (1, 0, 0, 1) (spacing and colour only) and the input's
    colours."""
    return _ours_reducer((1.0, 0.0, 0.0, 1.0))


def load_reduce_error():
    """Ours: ``method='error'`` (the paper's Figure 10b)."""
    return _ours_reducer((1.0, 1.0, 50.0, 0.0), method="error")


def triangle_target(n_points: int, n_triangles: int, target: int) -> int:
    """Triangles to ask a mesh decimator for to keep about ``target`` vertices.

    The input's triangles per vertex times ``target`` (2 on a closed mesh,
    fewer on an open one): decimators count triangles, not vertices.
    """
    return max(1, int(round(n_triangles * target / n_points)))


def load_fast_simplification():
    """fast-simplification ``simplify`` with ``target_count`` (triangles)."""
    import fast_simplification

    def run(data, target):
        pts, tri = data["points"], data["triangles"]
        count = triangle_target(len(pts), len(tri), target)
        v, f = fast_simplification.simplify(pts, tri, target_count=count)
        return {"vertices": v, "triangles": f, "info": {"target_count": count}}

    return run


def _pymeshlab_mesh(data):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    kwargs = {}
    if data.get("colors") is not None:
        rgb = np.asarray(data["colors"], dtype=np.float64)[:, :3] / 255.0
        kwargs["v_color_matrix"] = np.column_stack([rgb, np.ones(len(rgb))])
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(data["points"], np.float64),
                               face_matrix=np.ascontiguousarray(data["triangles"], np.int32),
                               **kwargs))
    return ms


def _pymeshlab_result(ms, data, **info):
    m = ms.current_mesh()
    out = {"vertices": m.vertex_matrix(), "triangles": m.face_matrix(), "info": info}
    if data.get("colors") is not None and m.has_vertex_color():
        out["colors"] = np.clip(np.rint(m.vertex_color_matrix()[:, :3] * 255), 0, 255)
    return out


def _quadric_reducer(filter_name: str, **params):
    import pymeshlab  # noqa: F401

    def run(data, target):
        ms = _pymeshlab_mesh(data)
        count = triangle_target(len(data["points"]), len(data["triangles"]), target)
        getattr(ms, filter_name)(targetfacenum=count, **params)
        return _pymeshlab_result(ms, data, targetfacenum=count, **params)

    return run


def load_quadric():
    """pymeshlab quadric edge collapse, default parameters (optimal placement on)."""
    return _quadric_reducer("meshing_decimation_quadric_edge_collapse")


#: the shape-preserving options of the quadric edge collapse (variant ``quadric-normal``)
QUADRIC_SHAPE = {"preservenormal": True, "preserveboundary": True, "preservetopology": True,
                 "optimalplacement": True, "planarquadric": True}


def load_quadric_normal():
    """pymeshlab quadric edge collapse, preserving normals, boundary and topology."""
    return _quadric_reducer("meshing_decimation_quadric_edge_collapse", **QUADRIC_SHAPE)


def load_quadric_subset():
    """pymeshlab quadric edge collapse keeping input vertices (optimal placement off): every
    collapse keeps one of its edge's ends, so the result is a subset of the input points, as
    ours is; it shows what keeping input points costs a quadric decimator."""
    return _quadric_reducer("meshing_decimation_quadric_edge_collapse", optimalplacement=False)


def load_quadric_texture():
    """pymeshlab's texture-aware quadric edge collapse (needs per-wedge texture coords)."""
    return _quadric_reducer("meshing_decimation_quadric_edge_collapse_with_texture")


def load_poisson_disk():
    """pymeshlab Poisson-disk point simplification (``generate_simplified_point_cloud``)."""
    import pymeshlab  # noqa: F401

    def run(data, target):
        ms = _pymeshlab_mesh(data)
        ms.generate_simplified_point_cloud(samplenum=int(target))
        out = _pymeshlab_result(ms, data, samplenum=int(target), points_only=True)
        out["triangles"] = np.empty((0, 3), np.int64)
        return out

    return run


def load_vtk_quadric():
    """VTK vtkQuadricDecimation with a target reduction of the triangles."""
    from vtkmodules.util.numpy_support import (
        numpy_to_vtk,
        numpy_to_vtkIdTypeArray,
        vtk_to_numpy,
    )
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkQuadricDecimation

    def run(data, target):
        pts, tri = data["points"], data["triangles"]
        count = triangle_target(len(pts), len(tri), target)
        reduction = 1.0 - count / len(tri)
        vp = vtkPoints()
        vp.SetData(numpy_to_vtk(np.ascontiguousarray(pts, dtype=np.float64), deep=True))
        polys = vtkCellArray()
        polys.SetData(3, numpy_to_vtkIdTypeArray(
            np.ascontiguousarray(tri, dtype=np.int64).ravel(), deep=True))
        mesh = vtkPolyData()
        mesh.SetPoints(vp)
        mesh.SetPolys(polys)
        dec = vtkQuadricDecimation()
        dec.SetInputData(mesh)
        dec.SetTargetReduction(reduction)
        dec.Update()
        out = dec.GetOutput()
        conn = vtk_to_numpy(out.GetPolys().GetConnectivityArray())
        verts = vtk_to_numpy(out.GetPoints().GetData()) if out.GetNumberOfPoints() else \
            np.empty((0, 3))
        return {"vertices": verts, "triangles": conn.reshape(-1, 3),
                "info": {"target_reduction": reduction}}

    return run


#: ``fancloud bench reduce``'s methods; ``ours-*`` first, ``ours-shape`` the default weights.
REDUCE_METHODS = {m.name: m for m in (
    Method("ours-uniform", "ours entropy (1,0,0,0)", f"{_HERE}:load_reduce_uniform",
           "reduce(fc, target, weights=(1, 0, 0, 0))"),
    Method("ours-shape", "ours entropy (1,1,50,0)", f"{_HERE}:load_reduce_shape",
           "reduce(fc, target, weights=(1, 1, 50, 0))"),
    Method("ours-colour", "ours entropy (1,1,50,1) + colour", f"{_HERE}:load_reduce_colour",
           "reduce(fc, target, weights=(1, 1, 50, 1)) with the input's RGB (only on data "
           "with colour)"),
    Method("ours-colour-distance", "ours entropy (1,0,0,1) + colour",
           f"{_HERE}:load_reduce_colour_distance",
           "reduce(fc, target, weights=(1, 0, 0, 1)) with the input's RGB (only on data "
           "with colour)"),
    Method("ours-error", "ours error", f"{_HERE}:load_reduce_error",
           "reduce(fc, target, method='error')"),
    Method("fast-simplification", "fast-simplification", f"{_HERE}:load_fast_simplification",
           "fast_simplification.simplify(points, triangles, target_count=round(m * target / n))",
           new_points=True),
    Method("quadric", "pymeshlab quadric edge collapse", f"{_HERE}:load_quadric",
           "meshing_decimation_quadric_edge_collapse(targetfacenum=round(m * target / n)), "
           "defaults (optimalplacement on, qualitythr 0.3)", new_points=True),
    Method("quadric-normal", "pymeshlab quadric edge collapse, shape options",
           f"{_HERE}:load_quadric_normal",
           "meshing_decimation_quadric_edge_collapse(targetfacenum=..., "
           + ", ".join(f"{k}={v}" for k, v in QUADRIC_SHAPE.items()) + ")", new_points=True),
    Method("quadric-subset", "pymeshlab quadric edge collapse, input vertices",
           f"{_HERE}:load_quadric_subset",
           "meshing_decimation_quadric_edge_collapse(targetfacenum=..., optimalplacement=False) "
           "(every collapse keeps an end of its edge: a subset of the input points, as ours)"),
    Method("quadric-texture", "pymeshlab quadric edge collapse with texture",
           f"{_HERE}:load_quadric_texture",
           "meshing_decimation_quadric_edge_collapse_with_texture(targetfacenum=...) (the "
           "texture-aware variant: needs per-wedge texture coordinates; pymeshlab has no "
           "colour-aware quadric variant)", new_points=True),
    Method("poisson-disk", "pymeshlab Poisson-disk points", f"{_HERE}:load_poisson_disk",
           "generate_simplified_point_cloud(samplenum=target), defaults (exactnumflag off; "
           "a point set: no triangles)"),
    Method("vtk-quadric", "VTK vtkQuadricDecimation", f"{_HERE}:load_vtk_quadric",
           "vtkQuadricDecimation, SetTargetReduction(1 - round(m * target / n) / m), defaults",
           new_points=True),
)}

#: what a missing reduction method needs
REDUCE_REQUIRES = {"fast-simplification": "fast-simplification (pip install "
                   "fast-simplification)", "quadric": "pymeshlab", "quadric-normal": "pymeshlab",
                   "quadric-subset": "pymeshlab",
                   "quadric-texture": "pymeshlab", "poisson-disk": "pymeshlab",
                   "vtk-quadric": "vtk", **{k: "fancloud_vtk.reduce" for k in
                                            ("ours-uniform", "ours-shape", "ours-colour",
                                             "ours-colour-distance", "ours-error")}}


def reduce_method_for(spec: str) -> Method:
    """A registered reduction method by name, or a ``module:function`` loader."""
    if spec in REDUCE_METHODS:
        return REDUCE_METHODS[spec]
    if ":" in spec:
        return Method(spec, spec, spec, f"{spec} (user loader)")
    raise ValueError(f"unknown method {spec!r}: one of {', '.join(REDUCE_METHODS)} or "
                     "module:function")


def load_reduce_data(path: str) -> dict:
    """The ``data`` dict of a reduction loader from the ``.npz`` the benchmark wrote."""
    with np.load(path) as z:
        colors = z["colors"]
        return {"points": z["points"], "triangles": z["triangles"],
                "colors": colors if len(colors) else None,
                "from_points": bool(z["from_points"])}


def save_reduce_data(path: str, points, triangles, colors, from_points: bool) -> None:
    """Write what :func:`load_reduce_data` reads."""
    np.savez(path, points=np.ascontiguousarray(points, np.float64),
             triangles=np.ascontiguousarray(triangles, np.int64),
             colors=np.zeros((0, 3), np.uint8) if colors is None else np.asarray(colors),
             from_points=np.bool_(from_points))


def reduce_child_main(argv: list[str]) -> int:
    """``NAME LOADER DATA.npz WARMUP.npz|- OUT_DIR REPEAT TARGETS``: run one reducer.

    For every target (comma-separated vertex counts) in turn: ``repeat``
    timed runs, the first result saved as ``out_I.npz``, and ``result.json``
    rewritten (a run that raises is recorded and the next target tried).
    """
    name, loader, data_path, warmup_path, out_dir, repeat, targets = argv
    repeat = int(repeat)
    targets = [int(t) for t in targets.split(",")]
    result_path = os.path.join(out_dir, "result.json")
    res = {"name": name, "status": "running", "runs": []}
    run = _load_method(loader, res, result_path)
    if run is None:
        return 0
    data = load_reduce_data(data_path)
    if warmup_path != "-":
        warm = load_reduce_data(warmup_path)
        t0 = time.perf_counter()
        try:
            run(warm, max(4, int(0.3 * len(warm["points"]))))
        except Exception as exc:  # the timed runs will report it
            res["warmup_error"] = _short(exc)
        res["warmup_time"] = time.perf_counter() - t0
    _write_json(result_path, res)
    for i, target in enumerate(targets):
        r = {"target": target, "times": [], "calls": [], "status": "running"}
        res["runs"].append(r)
        res["timed_start_epoch"] = time.time()
        _write_json(result_path, res)
        try:
            for j in range(repeat):
                t0 = time.perf_counter()
                out = run(data, target)
                call = time.perf_counter() - t0
                r["calls"].append(call)
                r["times"].append(float(out.get("time", call)))
                if j == 0:
                    arrays = {"vertices": np.asarray(out["vertices"], dtype=np.float64),
                              "triangles": np.asarray(out["triangles"],
                                                      dtype=np.int64).reshape(-1, 3)}
                    for key in ("colors", "original_id"):
                        if out.get(key) is not None:
                            arrays[key] = np.asarray(out[key])
                    tmp = os.path.join(out_dir, f"out_{i}.tmp.npz")
                    np.savez(tmp, **arrays)
                    os.replace(tmp, os.path.join(out_dir, f"out_{i}.npz"))
                    r["info"] = _plain(out.get("info", {}))
                del out
            r["status"] = "ok"
        except Exception as exc:
            r.update(status="failed", error=_short(exc),
                     traceback=traceback.format_exc()[-3000:])
        res.pop("timed_start_epoch", None)
        _write_json(result_path, res)
    res["status"] = "ok"
    _write_json(result_path, res)
    return 0


_REDUCE_CHILD = ("import sys; from fancloud_vtk._bench_peers import reduce_child_main; "
                 "sys.exit(reduce_child_main(sys.argv[1:]))")


def run_reduce_method(method, data_path: str, warmup_path: str | None, work_dir: str,
                      targets: list[int], *, timeout: float, repeat: int = 1) -> list[dict]:
    """Run one reducer on every target in a fresh process, with one timeout for all.

    One dict per target: ``status`` (``ok``, ``missing``, ``failed``,
    ``crashed``, ``timeout``), ``message``, ``time`` (best of the timed runs),
    ``times`` and, when it finished, the result's arrays (``vertices``,
    ``triangles``, and ``colors`` / ``original_id`` when the method gave them).
    Targets not reached (a timeout or crash before them) say so.
    """
    from fancloud_vtk.bench import _child_env

    out_dir = tempfile.mkdtemp(prefix=f"{method.name.replace(':', '_')}-", dir=work_dir)
    err_path = os.path.join(out_dir, "stderr.txt")
    cmd = [sys.executable, "-X", "faulthandler", "-c", _REDUCE_CHILD, method.name,
           method.loader, data_path, warmup_path or "-", out_dir, str(repeat),
           ",".join(str(t) for t in targets)]
    t0 = time.perf_counter()
    with open(os.path.join(out_dir, "stdout.txt"), "w") as out, open(err_path, "w") as err:
        try:
            code = subprocess.run(cmd, env=_child_env(), stdout=out, stderr=err,
                                  timeout=timeout, check=False).returncode
        except subprocess.TimeoutExpired:
            code = None
    wall, killed_epoch = time.perf_counter() - t0, time.time()
    child = {}
    result_path = os.path.join(out_dir, "result.json")
    if os.path.isfile(result_path):
        with open(result_path) as f:
            child = json.load(f)
    runs = child.get("runs", [])
    results = []
    for i, target in enumerate(targets):
        run = runs[i] if i < len(runs) else {}
        times = run.get("times", [])
        res = {"method": method.name, "label": method.label, "call": method.call,
               "target": target, "times": times, "time": min(times) if times else None,
               "calls": run.get("calls", []), "info": run.get("info", {}),
               "warmup_time": child.get("warmup_time"), "process_wall_time": wall,
               "exit_code": code}
        npz = os.path.isfile(os.path.join(out_dir, f"out_{i}.npz"))
        if run.get("status") == "ok":
            status, message = "ok", "ok"
        elif run.get("status") == "failed":
            status, message = "failed", f"failed: {run['error']}"
            res["traceback"] = run.get("traceback")
        elif run and times and npz:  # killed after some of the repeats
            status, message = "ok", f"ok ({len(times)} of {repeat} runs before the process ended)"
        elif run or not runs:  # the target running when the process ended, or none ran
            status, message = _child_status(method, code, child, err_path, timeout, [],
                                            repeat, REDUCE_REQUIRES)
            if status == "ok":
                status, message = "failed", f"failed (exit {code}): the target did not finish"
            if run and status == "timeout" and child.get("timed_start_epoch"):
                res["time_lower_bound"] = killed_epoch - child["timed_start_epoch"]
        else:  # an earlier target took the process down
            status = "timeout" if code is None else "crashed" if code < 0 else "failed"
            what = {"timeout": f"timed out ({timeout:g} s for all targets)",
                    "crashed": "crashed"}.get(status, f"exited ({code})")
            message = f"not run: the process {what} on an earlier target"
        res.update(status=status, message=message)
        path = os.path.join(out_dir, f"out_{i}.npz")
        if status == "ok" and os.path.isfile(path):
            with np.load(path) as z:
                for key in z.files:
                    res[key] = z[key]
        elif status == "ok":
            res.update(status="failed", message="failed: the method wrote no result")
        results.append(res)
    return results


if __name__ == "__main__":  # pragma: no cover
    sys.exit(child_main(sys.argv[1:]))
