"""The methods the benchmarks compare: surface reconstruction (``bench mesh``) and
reduction (``bench reduce``).

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

:func:`fancloud_vtk.bench.harness.run_method` runs one loader in a fresh process with
a timeout (warm-up, timed runs, the mesh passed back as ``.npz``); the measures of its
mesh are in :mod:`fancloud_vtk.bench.metrics`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from fancloud_vtk.bench.common import K, _plain


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
