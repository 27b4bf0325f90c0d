"""``FanCloudFilter``: points in, fan cloud ``vtkPolyData`` out (paper section 3)."""

from __future__ import annotations

from fancloud_vtk.core import verbs
from fancloud_vtk.params import VERB_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import fancloud_to_vtk, source_of


@with_parameters(VERB_PARAMS["fans"])
class FanCloudFilter(FanCloudAlgorithm):
    """Build the fan cloud of any ``vtkPointSet``.

    Only the points are used (cells are ignored), but of a triangle mesh only
    the vertices of its triangles unless ``keep_unreferenced`` (the others are
    dropped with a warning and counted in the field array
    ``unreferenced_dropped``; ``original_id`` maps the points to the input's).
    Every point array passes through. A ``Normals`` array on the input orients
    the fan normals. The
    output is ``vtkPolyData``: the points, the distinct fan triangles as
    polys, point arrays ``Normals``, ``fan_open``, ``fan_rotated`` and field
    arrays ``fan_offsets``/``fan_ring`` (see docs/data_model.md).

    Parameters are properties (``alg.k = 8``) and VTK-style methods
    (``alg.SetK(8)``), listed in ``FanCloudFilter.PARAMETERS``.

    Examples
    --------
    >>> from vtkmodules.vtkFiltersSources import vtkPointSource
    >>> from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
    >>> from fancloud_vtk.algorithms import FanCloudFilter
    >>> src = vtkPointSource()
    >>> src.SetNumberOfPoints(2000)
    >>> src.SetDistributionToShell()
    >>> fans = FanCloudFilter(k=6)
    >>> fans.SetInputConnection(src.GetOutputPort())
    >>> normals = vtkPolyDataNormals()
    >>> normals.SetInputConnection(fans.GetOutputPort())
    >>> normals.SplittingOff()  # keep one point per input point
    >>> _ = normals.Update()  # VTK 9.2 returns None, later versions 1
    >>> normals.GetOutput().GetNumberOfPoints()
    2000
    """

    def __init__(self, **params):
        super().__init__(inputType="vtkPointSet", outputType="vtkPolyData", **params)

    def execute(self, dataset):
        result = verbs.fans(source_of(dataset), self.parameters, self._progress)
        return fancloud_to_vtk(result.fancloud)
