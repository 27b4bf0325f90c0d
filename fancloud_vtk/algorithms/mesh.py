"""``FanCloudMeshFilter``: a fan cloud (or points) in, a triangle mesh out (paper section 4)."""

from __future__ import annotations

from fancloud_vtk.core import verbs
from fancloud_vtk.params import VERB_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import result_to_vtk, source_of


@with_parameters(VERB_PARAMS["mesh"])
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
        result = verbs.mesh(source_of(dataset), self.parameters, self._progress)
        return result_to_vtk(result, mark=False)
