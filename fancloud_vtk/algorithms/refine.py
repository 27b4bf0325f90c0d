"""``FanCloudRefineFilter`` (paper section 7)."""

from __future__ import annotations

from fancloud_vtk.core import verbs
from fancloud_vtk.params import VERB_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import result_to_vtk, source_of


@with_parameters(VERB_PARAMS["refine"])
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
        return result_to_vtk(verbs.refine(source_of(dataset), self.parameters, self._progress))
