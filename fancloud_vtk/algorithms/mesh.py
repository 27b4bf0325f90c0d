"""``FanCloudMeshFilter``: a fan cloud (or points) in, a triangle mesh out (paper section 4)."""

from __future__ import annotations

from fancloud_vtk.core.entropy import UNREFERENCED_DROPPED
from fancloud_vtk.core.fans import Cancelled
from fancloud_vtk.core.mesh import fan_cloud_to_mesh
from fancloud_vtk.params import FAN_PARAMS, INPUT_PARAMS, MESH_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import (
    add_unreferenced_field,
    fancloud_from_vtk,
    is_fancloud,
    mesh_to_vtk,
    point_fans,
)
from .entropy import fan_values


@with_parameters(FAN_PARAMS + INPUT_PARAMS + MESH_PARAMS)
class FanCloudMeshFilter(FanCloudAlgorithm):
    """Triangle mesh from a fan cloud: a 2-manifold grown from the fan triangles.

    The input is either a fan cloud (the output of ``FanCloudFilter`` or a
    ``.vtp`` it wrote: its rings are used as they are) or any point set, whose
    fans are built first with this filter's fan parameters (``k``,
    ``max_angle``, ...; of a triangle mesh only the vertices of its triangles,
    unless ``keep_unreferenced``: the field array ``unreferenced_dropped``
    counts the others). The output ``vtkPolyData`` has every point,
    the mesh triangles as polys, the point arrays of the input, ``Normals``,
    and the mesh statistics as one-value field arrays ``mesh_<name>``
    (``mesh_final``, ``mesh_holes``, ``mesh_non_manifold_edges``, ...).

    Examples
    --------
    >>> from vtkmodules.vtkFiltersSources import vtkPointSource
    >>> from fancloud_vtk.algorithms import FanCloudMeshFilter, run
    >>> src = vtkPointSource()
    >>> src.SetNumberOfPoints(3000)
    >>> src.SetDistributionToShell()
    >>> mesh = FanCloudMeshFilter()
    >>> mesh.SetInputConnection(src.GetOutputPort())
    >>> run(mesh).GetNumberOfCells()
    5996
    """

    def __init__(self, **params):
        super().__init__(inputType="vtkPointSet", outputType="vtkPolyData", **params)

    def execute(self, dataset):
        values = self.parameters
        mesh_values = {p.name: values[p.name] for p in MESH_PARAMS}
        if is_fancloud(dataset):
            fc = fancloud_from_vtk(dataset)
        else:
            fc = point_fans(dataset, fan_values(values),
                            lambda f, m: self._progress(0.5 * f, m),
                            keep_unreferenced=values["keep_unreferenced"])
        if self._progress(0.5, "mesh"):  # the mesh stage cannot stop midway: ask before
            raise Cancelled("meshing was cancelled")
        mesh = fan_cloud_to_mesh(fc, **mesh_values)
        self._progress(1.0, "done")
        out = mesh_to_vtk(mesh)
        add_unreferenced_field(out, fc.info.get(UNREFERENCED_DROPPED))
        return out
