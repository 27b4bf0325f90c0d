"""``FanCloudReduceFilter`` and ``FanCloudSelectiveRefineFilter`` (paper sections 5 and 6)."""

from __future__ import annotations

from fancloud_vtk.core import verbs
from fancloud_vtk.params import VERB_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import result_to_vtk, source_of


@with_parameters(VERB_PARAMS["reduce"])
class FanCloudReduceFilter(FanCloudAlgorithm):
    """Reduce a fan cloud, mesh or point set by entropy to an exact number of points.

    Takes three kinds of input and says which in the string field array
    ``fancloud_input``: a fan cloud (its rings are reused), a triangle mesh
    (its one-rings are the fans) or a point set (fans built first with this
    filter's fan parameters). ``n_points`` (if not 0) or ``keep`` sets the
    count. The output is the reduced fan cloud (or, with ``mesh``, its
    triangle mesh): the kept points with their point arrays and the point
    array ``original_id``, the index of every output point in the input.
    A mesh's vertices that no triangle uses are dropped first unless
    ``keep_unreferenced`` (field array ``unreferenced_dropped``).

    Examples
    --------
    >>> from vtkmodules.vtkFiltersSources import vtkPointSource
    >>> from fancloud_vtk.algorithms import FanCloudReduceFilter, run
    >>> src = vtkPointSource()
    >>> src.SetNumberOfPoints(4000)
    >>> src.SetDistributionToShell()
    >>> red = FanCloudReduceFilter(n_points=1000)
    >>> red.SetInputConnection(src.GetOutputPort())
    >>> run(red).GetNumberOfPoints()
    1000
    """

    def __init__(self, **params):
        super().__init__(inputType="vtkPointSet", outputType="vtkPolyData", **params)

    def execute(self, dataset):
        return result_to_vtk(verbs.reduce(source_of(dataset), self.parameters, self._progress))


@with_parameters(VERB_PARAMS["selective"])
class FanCloudSelectiveRefineFilter(FanCloudAlgorithm):
    """Reduce, optionally smooth the coarse level, then refine only a region (Figure 11).

    The input (fan cloud, triangle mesh or point set, as for
    :class:`FanCloudReduceFilter`) is reduced to ``n_points``/``keep``; the
    coarse level is smoothed ``smooth_iterations`` times; then every removed
    point is put back on the (smoothed) surface by its local-frame detail,
    in reverse removal order, and those inside the region of interest (a
    sphere ``region_center``/``region_radius`` or a box ``region_bounds``)
    are reinserted. The output is the resulting fan cloud, its fans built
    anew with this filter's fan parameters (``k``, ``max_angle``, ...), with
    ``original_id``.

    Examples
    --------
    >>> from vtkmodules.vtkFiltersSources import vtkPointSource
    >>> from fancloud_vtk.algorithms import FanCloudSelectiveRefineFilter, run
    >>> src = vtkPointSource()
    >>> src.SetNumberOfPoints(4000)
    >>> src.SetDistributionToShell()
    >>> sel = FanCloudSelectiveRefineFilter(keep=0.2, region_center=(0, 0, 0.5),
    ...                                     region_radius=0.3)
    >>> sel.SetInputConnection(src.GetOutputPort())
    >>> n = run(sel).GetNumberOfPoints()
    >>> 800 < n < 4000
    True
    """

    def __init__(self, **params):
        super().__init__(inputType="vtkPointSet", outputType="vtkPolyData", **params)

    def execute(self, dataset):
        verbs.region_of(self.parameters)  # a bad region fails before the input is read
        return result_to_vtk(verbs.selective(source_of(dataset), self.parameters,
                                             self._progress))
