"""``fancloud demo``: the main job on built-in data.

Loads the Stanford bunny shipped inside pymeshlab (points only), builds its
fan cloud, writes it as ``.vtp``, renders it offscreen (shaded, and with its
open fans marked) and prints a summary table. Then the triangle mesh of the
fan cloud (paper section 4, its Figure 8): written as ``.ply``, rendered
beside the fan cloud, and its stage counts and checks printed. Then the
reduction (section 5, Figure 9): the bunny reduced to 17.6% by distance only
and with the shape weights, side by side; and the selective refinement of
section 6 (Figure 11): reduced to 15%, smoothed, the head refined. Last the
refinement beyond the resolution (section 7): the bunny reduced to 25% and
refined back x4 by entropy, its inserted points marked. And the view-dependent
fan cloud (section 8, Figures 15 and 16) of matplotlib's Jacksboro fault DEM:
its merge forest built in blocks, the front's points for one viewpoint seen
from above, and the front shaded from that viewpoint.
"""

from __future__ import annotations

import os
import sys
import time
import warnings

from fancloud_vtk.render import render_panels


def render_fancloud(fc, path: str, title: str = "") -> None:
    """Offscreen picture: the shaded fan cloud and, beside it, its open fans in red."""
    import numpy as np
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    from fancloud_vtk.algorithms.convert import to_vtk

    # without a display VTK warns "bad X server connection" and renders
    # offscreen all the same: keep errors, drop that warning
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    mesh = pv.wrap(to_vtk(fc))
    pl = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(1400, 700), border=False)
    pl.subplot(0, 0)
    pl.add_text(f"{title}fan cloud, shaded ({fc.n_points:,} points)", font_size=10)
    pl.add_mesh(mesh, color="#d8c8a8", smooth_shading=True, specular=0.3)
    pl.subplot(0, 1)
    pl.add_text(f"open fans marked ({fc.n_open:,})", font_size=10)
    pl.add_mesh(mesh, color="white", show_edges=True, edge_color="#888888", line_width=0.3)
    if fc.n_open:
        pts = pv.PolyData(fc.points[np.flatnonzero(fc.open)])
        pl.add_mesh(pts, color="red", point_size=8, render_points_as_spheres=True)
    pl.link_views()
    pl.camera_position = "xy"
    pl.camera.zoom(1.3)
    pl.screenshot(path)
    pl.close()


def render_mesh(fc, mesh, path: str, title: str = "") -> None:
    """Offscreen picture: the fan cloud (left) and its triangle mesh with edges (right)."""
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    from fancloud_vtk.algorithms.convert import mesh_to_vtk, to_vtk

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)  # see render_fancloud
    s = mesh.stats
    pl = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(1400, 700), border=False)
    pl.subplot(0, 0)
    pl.add_text(f"{title}fan cloud ({fc.n_points:,} points, "
                f"{len(fc.triangles()):,} distinct fan triangles)", font_size=10)
    pl.add_mesh(pv.wrap(to_vtk(fc)), color="#d8c8a8", smooth_shading=True, specular=0.3)
    pl.subplot(0, 1)
    pl.add_text(f"{title}mesh ({mesh.n_triangles:,} triangles, {s['holes']} holes, "
                f"{s['non_manifold_edges'] + s['non_manifold_vertices']} non-manifold)",
                font_size=10)
    pl.add_mesh(pv.wrap(mesh_to_vtk(mesh)), color="#d8c8a8", show_edges=True,
                edge_color="#9c8f75", line_width=0.3, specular=0.3)
    pl.link_views()
    pl.camera_position = "xy"
    pl.camera.zoom(1.3)
    pl.screenshot(path)
    pl.close()


#: the bunny's head (pymeshlab's bunny.obj coordinates), Figure 11's region of interest
HEAD = ((0.1, 0.33, 0.36), 0.14)


def reduction_panel(fc, out_dir: str, quiet: bool) -> dict:
    """Figures 9 and 11 on the bunny: reductions side by side, selective refinement."""
    from fancloud_vtk._console import _print_rows, _Progress
    from fancloud_vtk.core.reduction import hierarchy, laplacian_smooth, reduce

    rows, out = [], {}
    panels = [(f"input ({fc.n_points:,} points)", fc)]
    for label, weights in (("distance only (1,0,0,0)", (1, 0, 0, 0)),
                           ("shape (1,1,50,0)", (1, 1, 50, 0))):
        progress = _Progress(f"reduce {label}", quiet)
        t0 = time.perf_counter()
        small = reduce(fc, keep=0.176, weights=weights, progress=progress)
        elapsed = time.perf_counter() - t0
        progress.close()
        panels.append((f"17.6% by {label}: {small.n_points:,} points", small))
        rows.append((f"reduced to 17.6%, {label}", f"{small.n_points:,} points, {elapsed:.2f} s"))
        out[f"reduce_{weights}"] = {"points": small.n_points, "time": elapsed}
    png = os.path.join(out_dir, "bunny_reduce.png")
    render_panels(panels, png)
    rows.append(("picture (Figure 9)", png))

    target = round(0.15 * fc.n_points)
    t0 = time.perf_counter()
    h = hierarchy(fc, target)
    coarse = h.level(target)
    smooth = laplacian_smooth(coarse, 5)
    refined = h.selective(HEAD, base=smooth)
    elapsed = time.perf_counter() - t0
    png11 = os.path.join(out_dir, "bunny_selective.png")
    render_panels([(f"reduced to 15% ({coarse.n_points:,} points)", coarse),
                   ("smoothed (5 Laplacian steps)", smooth),
                   (f"head refined with its detail ({refined.n_points:,} points)", refined)],
                  png11)
    rows += [("selective refinement", f"{coarse.n_points:,} -> smoothed -> "
              f"{refined.n_points:,} points (head), {elapsed:.2f} s"),
             ("picture (Figure 11)", png11)]
    out["selective"] = {"coarse": coarse.n_points, "refined": refined.n_points}
    print()
    print("reduction by entropy (paper sections 5 and 6, Figures 9 and 11)")
    _print_rows(rows)
    return {**out, "reduce_png": png, "selective_png": png11}


def refinement_panel(fc, mesh, out_dir: str, quiet: bool) -> dict:
    """Section 7 on the bunny: reduced to 25%, refined back x4 by entropy, the inserted points
    marked."""
    import numpy as np

    from fancloud_vtk._console import _print_rows, _Progress
    from fancloud_vtk.bench.metrics import MeshDistance
    from fancloud_vtk.core.reduction import reduce
    from fancloud_vtk.core.refinement import refine

    small = reduce(fc, keep=0.25)
    progress = _Progress("refine x4", quiet)
    t0 = time.perf_counter()
    fine = refine(small, factor=4, progress=progress)
    elapsed = time.perf_counter() - t0
    progress.close()
    inserted = np.flatnonzero(fine.point_data["original_id"] == -1)
    diag = float(np.linalg.norm(fc.points.max(axis=0) - fc.points.min(axis=0)))
    d = MeshDistance(mesh.points, mesh.triangles)(fine.points[inserted]) / diag
    png = os.path.join(out_dir, "bunny_refine.png")
    render_panels([(f"reduced to 25% ({small.n_points:,} points)", small),
                   (f"refined x4 by entropy ({fine.n_points:,} points)", fine),
                   (f"the {len(inserted):,} inserted points (red)", fine, inserted)], png)
    rows = [("refined x4", f"{small.n_points:,} -> {fine.n_points:,} points, {elapsed:.2f} s"),
            ("inserted points to input", f"max {d.max():.2g}, mean {d.mean():.2g} "
             "(of the bounding-box diagonal; distance to the input's mesh)"),
            ("picture", png)]
    print()
    print("refinement by entropy (paper section 7): the bunny reduced to 25%, refined x4")
    _print_rows(rows)
    return {"reduced": small.n_points, "refined": fine.n_points, "inserted": len(inserted),
            "time": elapsed, "distance_max": float(d.max()), "distance_mean": float(d.mean()),
            "refine_png": png}


#: the viewpoint of the terrain panel, as fractions of the terrain's extent and metres
TERRAIN_VIEW = ((0.35, -0.02, 1200.0), (0.55, 0.45, 300.0))


def terrain_panel(out_dir: str, quiet: bool) -> dict:
    """Section 8 on the Jacksboro DEM: the forest in blocks; Figures 15 and 16."""
    import numpy as np
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    from fancloud_vtk._console import _print_rows, _Progress
    from fancloud_vtk.algorithms.convert import to_vtk
    from fancloud_vtk.core.vdfc import ViewDependentFanCloud, terrain_blocks, terrain_fan_cloud
    from fancloud_vtk.data import jacksboro_terrain

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)  # see render_fancloud
    heights, spacing, _ = jacksboro_terrain()
    fc = terrain_fan_cloud(heights, spacing)
    progress = _Progress("terrain forest", quiet)
    t0 = time.perf_counter()
    vd = ViewDependentFanCloud.build(fc, blocks=terrain_blocks(heights.shape, (180, 210)),
                                     progress=progress)
    build_time = time.perf_counter() - t0
    progress.close()
    lo, hi = fc.points.min(axis=0), fc.points.max(axis=0)
    (ex, ey, ez), (fx, fy, fz) = TERRAIN_VIEW
    eye = (lo[0] + ex * (hi[0] - lo[0]), lo[1] + ey * (hi[1] - lo[1]), ez)
    focal = (lo[0] + fx * (hi[0] - lo[0]), lo[1] + fy * (hi[1] - lo[1]), fz)
    size = (900, 700)
    camera = (eye, focal, (0.0, 0.0, 1.0), 50.0, size[0] / size[1])
    e_max = 40.0  # metres at the range of sight
    vd.front_arrays(camera, e_max)  # compile
    vd.reset_front()
    front = vd.front_arrays(camera, e_max)
    poly = pv.wrap(to_vtk(front))
    png = os.path.join(out_dir, "terrain_vdfc.png")
    pl = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(2 * size[0], size[1]),
                    border=False)
    pl.subplot(0, 0)
    pl.add_text(f"Figure 15: the front's {front.n_points:,} points of {fc.n_points:,}, "
                "from above (camera: black)", font_size=10)
    pts = pv.PolyData(front.points)
    pts["level"] = front.point_data["level"]
    pl.add_mesh(pts, scalars="level", cmap="viridis", point_size=2, show_scalar_bar=False)
    pl.add_mesh(pv.PolyData(np.array([eye])), color="black", point_size=14,
                render_points_as_spheres=True)
    pl.add_mesh(pv.Line(eye, focal), color="black", line_width=3)
    pl.camera_position = "xy"
    pl.subplot(0, 1)
    pl.add_text(f"Figure 16: the front shaded from the viewpoint "
                f"({front.stats['triangles']:,} triangles)", font_size=10)
    pl.add_mesh(poly, color="#c8b890", smooth_shading=True, specular=0.2)
    pl.camera_position = [eye, focal, (0.0, 0.0, 1.0)]
    pl.camera.view_angle = 50.0
    pl.screenshot(png)
    pl.close()
    s = front.stats
    rows = [("terrain", f"{heights.shape[0]} x {heights.shape[1]} = {fc.n_points:,} points, "
                        f"spacing {spacing[0]:.1f} x {spacing[1]:.1f} m"),
            ("merge forest", f"{vd.n_nodes:,} nodes, built in {build_time:.2f} s "
                             "(4 blocks sharing their boundary)"),
            ("front (e_max 40 m)", f"{s['active']:,} points, {s['triangles']:,} triangles "
                                   f"({s['triangles_per_point']:.2f} per point)"),
            ("front update", f"{1e3 * s['seconds']:.1f} ms from the roots"),
            ("picture (Figures 15, 16)", png)]
    print()
    print("view-dependent fan cloud (paper section 8): the Jacksboro fault DEM")
    _print_rows(rows)
    return {"points": fc.n_points, "nodes": vd.n_nodes, "build_time": build_time,
            "active": s["active"], "triangles": s["triangles"],
            "triangles_per_point": s["triangles_per_point"], "front_seconds": s["seconds"],
            "terrain_png": png}


def run_demo(out_dir: str = "fancloud_demo", quiet: bool = False) -> dict:
    """Run the demo; return the summary (also printed)."""
    from fancloud_vtk._console import _print_mesh_summary, _print_summary, _Progress
    from fancloud_vtk.algorithms.convert import mesh_to_vtk, save, write_mesh
    from fancloud_vtk.core.fans import build_fans
    from fancloud_vtk.core.mesh import DoubtfulMeshWarning, fan_cloud_to_mesh
    from fancloud_vtk.data import bunny_path
    from fancloud_vtk.io import read_point_cloud

    os.makedirs(out_dir, exist_ok=True)
    src = read_point_cloud(bunny_path())
    if not quiet:  # a first run is silent for minutes otherwise
        print("fancloud demo: loading the numba kernels (a first run compiles them, which "
              "takes minutes; they are cached for later runs)", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    # compile the numba kernels (cached after the first run); a patch of 500 points is no
    # surface to judge
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DoubtfulMeshWarning)
        fan_cloud_to_mesh(build_fans(src.points[:500]))
    compile_time = time.perf_counter() - t0
    progress = _Progress("bunny fans", quiet)
    t0 = time.perf_counter()
    fc = build_fans(src.points, progress=progress)
    elapsed = time.perf_counter() - t0
    progress.close()
    vtp = os.path.join(out_dir, "bunny_fans.vtp")
    png = os.path.join(out_dir, "bunny_fans.png")
    save(fc, vtp)
    render_fancloud(fc, png, "bunny: ")
    print(f"fancloud demo: Stanford bunny from pymeshlab ({bunny_path()}), points only")
    print(f"(numba warm-up / compile: {compile_time:.2f} s)")
    _print_summary(fc, elapsed, vtp)
    print(f"{'picture':<26}  {png}")

    t0 = time.perf_counter()
    mesh = fan_cloud_to_mesh(fc)
    mesh_time = time.perf_counter() - t0
    mesh_ply = os.path.join(out_dir, "bunny_mesh.ply")
    mesh_png = os.path.join(out_dir, "bunny_mesh.png")
    write_mesh(mesh_to_vtk(mesh), mesh_ply)
    render_mesh(fc, mesh, mesh_png, "bunny: ")
    print()
    print("triangle mesh of the fan cloud (paper section 4, Figure 8)")
    _print_mesh_summary(mesh, mesh_time, mesh_ply, extra=[("picture", mesh_png)])
    mesh_stats = {k: v for k, v in mesh.stats.items() if k != "timings"}
    reduction = reduction_panel(fc, out_dir, quiet)
    refinement = refinement_panel(fc, mesh, out_dir, quiet)
    terrain = terrain_panel(out_dir, quiet)
    return {**fc.summary(), "time": elapsed, "vtp": vtp, "png": png,
            "mesh": mesh_stats, "mesh_time": mesh_time, "mesh_ply": mesh_ply,
            "mesh_png": mesh_png, "reduction": reduction, "refinement": refinement,
            "terrain": terrain}
