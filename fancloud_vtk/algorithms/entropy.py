"""``FanCloudEntropyFilter``: the entropy of every point as point arrays (paper section 5)."""

from __future__ import annotations

from vtkmodules.vtkCommonDataModel import vtkPolyData

from fancloud_vtk.core.entropy import entropy
from fancloud_vtk.params import ENTROPY_PARAMS, FAN_PARAMS, INPUT_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import (
    KIND_POINTS,
    _to_vtk_array,
    fancloud_to_vtk,
    input_fan_cloud,
    mark_input,
)


def fan_values(values: dict) -> dict:
    """The fan parameters (the keywords of ``build_fans``) among a filter's values."""
    return {p.name: values[p.name] for p in FAN_PARAMS}


@with_parameters(FAN_PARAMS + INPUT_PARAMS + ENTROPY_PARAMS)
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
        values = self.parameters
        fc, kind = input_fan_cloud(dataset, fan_values(values),
                                   lambda f, m: self._progress(0.8 * f, m),
                                   keep_unreferenced=values["keep_unreferenced"])
        ent = entropy(fc, values["weights"], colors=values["color_array"] or None)
        if (kind == KIND_POINTS or not dataset.IsA("vtkPolyData")
                or fc.n_points != dataset.GetNumberOfPoints()):
            # a point set, a grid, or a mesh whose unreferenced vertices were dropped
            out = fancloud_to_vtk(fc)
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
        for name, arr in ent.as_dict().items():
            out.GetPointData().AddArray(_to_vtk_array(arr, name))
        out.GetPointData().SetActiveScalars("entropy")
        mark_input(out, kind, fc)
        self._progress(1.0, "done")
        return out
