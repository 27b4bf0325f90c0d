"""``FanCloudEntropyFilter``: the entropy of every point as point arrays (paper section 5)."""

from __future__ import annotations

from vtkmodules.vtkCommonDataModel import vtkPolyData

from fancloud_vtk.core import verbs
from fancloud_vtk.params import VERB_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import _to_vtk_array, fancloud_to_vtk, mark_input, source_of


@with_parameters(VERB_PARAMS["entropy"])
class FanCloudEntropyFilter(FanCloudAlgorithm):
    """The entropy of every point and its four terms, as point arrays.

    Takes three kinds of input and says which in the string field array
    ``fancloud_input``: a fan cloud (its rings are used), a triangle mesh
    (every vertex's one-ring is its fan; the vertices that no triangle uses
    are dropped unless ``keep_unreferenced``, and counted in the field array
    ``unreferenced_dropped``) or a plain point set (its fans are built first
    with this filter's fan parameters). The output is the input (or, for a
    point set, a grid or a mesh that lost vertices, its fan cloud) with the
    point arrays ``entropy``, ``entropy_dist``, ``entropy_curv``,
    ``entropy_cc`` and ``entropy_col`` added; the input is not modified.

    Examples
    --------
    >>> from vtkmodules.vtkFiltersSources import vtkSphereSource
    >>> from fancloud_vtk.algorithms import FanCloudEntropyFilter, run
    >>> src = vtkSphereSource()
    >>> src.SetThetaResolution(40)
    >>> src.SetPhiResolution(40)
    >>> ent = FanCloudEntropyFilter(weights=(1, 0, 0, 0))
    >>> ent.SetInputConnection(src.GetOutputPort())
    >>> out = run(ent)
    >>> out.GetPointData().GetArray("entropy").GetNumberOfTuples() == out.GetNumberOfPoints()
    True
    """

    def __init__(self, **params):
        super().__init__(inputType="vtkPointSet", outputType="vtkPolyData", **params)

    def execute(self, dataset):
        result = verbs.entropy(source_of(dataset), self.parameters, self._progress)
        keeps_input = (result.kind != verbs.KIND_POINTS and dataset.IsA("vtkPolyData")
                       and result.source.n_points == dataset.GetNumberOfPoints())
        return entropy_output(result, dataset if keeps_input else None)


def entropy_output(result: verbs.Result, dataset=None) -> vtkPolyData:
    """The entropy verb's output: ``dataset`` (the input polydata, when its points are the
    fan cloud's: not a point set, no vertex dropped) with the arrays ``entropy``,
    ``entropy_dist``, ... added (the input is not modified), else the fan cloud with them.
    The filter and ``fancloud entropy`` (the file's mesh as ``dataset``) both give this."""
    if dataset is None:
        # a point set, a grid, or a mesh whose unreferenced vertices were dropped
        out = fancloud_to_vtk(result.source)
    else:
        out = vtkPolyData()
        out.ShallowCopy(dataset)
        # new point and field data objects: the input's stay untouched
        pd = out.GetPointData().NewInstance()
        pd.ShallowCopy(dataset.GetPointData())
        out.GetPointData().ShallowCopy(pd)
        fd = out.GetFieldData().NewInstance()
        fd.ShallowCopy(dataset.GetFieldData())
        out.SetFieldData(fd)
    for name, arr in result.entropy.as_dict().items():
        out.GetPointData().AddArray(_to_vtk_array(arr, name))
    out.GetPointData().SetActiveScalars("entropy")
    mark_input(out, result.kind, result.source)
    return out
