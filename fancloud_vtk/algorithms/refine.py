"""``FanCloudRefineFilter`` (paper section 7)."""

from __future__ import annotations

from fancloud_vtk.core.refinement import refine
from fancloud_vtk.params import FAN_PARAMS, INPUT_PARAMS, REFINE_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import input_fan_cloud
from .entropy import fan_values
from .reduce import fan_cloud_output


def refine_arguments(values: dict) -> dict:
    """The core's keyword arguments from the table's values (n_points 0: factor)."""
    amount = {"n_points": values["n_points"]} if values["n_points"] else \
        {"factor": values["factor"]}
    return {**amount, "weights": values["weights"], "colors": values["color_array"] or None,
            "move": values["move"], "exact": values["exact"]}


@with_parameters(FAN_PARAMS + INPUT_PARAMS + REFINE_PARAMS)
class FanCloudRefineFilter(FanCloudAlgorithm):
    """Refine a fan cloud, mesh or point set beyond its resolution by entropy (section 7).

    Takes three kinds of input and says which in the string field array
    ``fancloud_input``: a fan cloud (its rings are used), a triangle mesh
    (its one-rings are the fans) or a point set (fans built first with this
    filter's fan parameters). ``n_points`` (if not 0) or ``factor`` sets the
    count. The output is the refined fan cloud (or, with ``mesh``, its
    triangle mesh): the input's points first, then the inserted ones; float
    point arrays and colours interpolated with the entropy weights, other
    arrays taken from the first parent; ``original_id`` is -1 on inserted
    points.

    Examples
    --------
    >>> from vtkmodules.vtkFiltersSources import vtkPointSource
    >>> from fancloud_vtk.algorithms import FanCloudRefineFilter, run
    >>> src = vtkPointSource()
    >>> src.SetNumberOfPoints(2000)
    >>> src.SetDistributionToShell()
    >>> ref = FanCloudRefineFilter(factor=2)
    >>> ref.SetInputConnection(src.GetOutputPort())
    >>> run(ref).GetNumberOfPoints()
    4000
    """

    def __init__(self, **params):
        super().__init__(inputType="vtkPointSet", outputType="vtkPolyData", **params)

    def execute(self, dataset):
        values = self.parameters
        fc, kind = input_fan_cloud(dataset, fan_values(values),
                                   lambda f, m: self._progress(0.3 * f, m),
                                   keep_unreferenced=values["keep_unreferenced"])
        fine = refine(fc, **refine_arguments(values),
                      progress=lambda f, m: self._progress(0.3 + 0.6 * f, m))
        return fan_cloud_output(self, fine, kind, values["mesh"], fc)
