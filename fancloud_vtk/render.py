"""Offscreen pictures of fan clouds shared by ``fancloud demo`` and the benchmarks."""

from __future__ import annotations

import warnings


def render_panels(panels, path: str) -> None:
    """Offscreen picture: one shaded mesh with edges per panel ``(title, fan cloud)``.

    A panel ``(title, fan cloud, marked)`` also draws the points ``marked``
    (an index array) in red.
    """
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    from fancloud_vtk.algorithms.convert import mesh_to_vtk
    from fancloud_vtk.core.mesh import DoubtfulMeshWarning, fan_cloud_to_mesh

    # without a display VTK warns "bad X server connection" and renders offscreen all the
    # same: keep errors, drop that warning
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    pl = pv.Plotter(off_screen=True, shape=(1, len(panels)), window_size=(700 * len(panels), 700),
                    border=False)
    for i, (title, fc, *marked) in enumerate(panels):
        pl.subplot(0, i)
        # a doubtful mesh (a reduction that broke the surface) is said in the panel
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DoubtfulMeshWarning)
            mesh = fan_cloud_to_mesh(fc, self_intersections=False)
        doubts = [str(w.message).removeprefix("fan_cloud_to_mesh: ").split(" (")[0]
                  for w in caught if issubclass(w.category, DoubtfulMeshWarning)]
        pl.add_text(title + "".join(f"\nmesh: {d}" for d in doubts), font_size=10)
        pl.add_mesh(pv.wrap(mesh_to_vtk(mesh)), color="#d8c8a8", show_edges=True,
                    edge_color="#9c8f75", line_width=0.3, specular=0.3)
        if marked and len(marked[0]):
            pl.add_mesh(pv.PolyData(fc.points[marked[0]]), color="red", point_size=3,
                        render_points_as_spheres=True)
    pl.link_views()
    pl.camera_position = "xy"
    pl.camera.zoom(1.3)
    pl.screenshot(path)
    pl.close()
