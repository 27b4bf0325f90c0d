"""``FanCloudReduceFilter`` and ``FanCloudSelectiveRefineFilter`` (paper sections 5 and 6)."""

from __future__ import annotations

import numpy as np

from fancloud_vtk.core.fans import Cancelled
from fancloud_vtk.core.mesh import fan_cloud_to_mesh
from fancloud_vtk.core.reduction import hierarchy, laplacian_smooth, reduce, target_count
from fancloud_vtk.params import FAN_PARAMS, INPUT_PARAMS, REDUCE_PARAMS, SELECTIVE_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import (
    KIND_MESH,
    fancloud_to_vtk,
    input_fan_cloud,
    mark_input,
    mesh_to_vtk,
)
from .entropy import fan_values


def mesh_rings(kind: str) -> str:
    """How to mesh a reduced fan cloud: the re-formed fans of a mesh's one-rings are
    consistent already (``'fans'``); those grown from a point set's fans are not
    everywhere (``'delaunay'``). See docs/entropy.md."""
    return "fans" if kind == KIND_MESH else "delaunay"


def _amount(values: dict) -> dict:
    """``n_points=`` or ``keep=`` for the core, from the table's values (n_points 0: keep)."""
    if values["n_points"]:
        return {"n_points": values["n_points"]}
    return {"keep": values["keep"]}


def _reduce_values(values: dict) -> dict:
    return {"weights": values["weights"], "method": values["method"],
            "colors": values["color_array"] or None, "exact": values["exact"]}


@with_parameters(FAN_PARAMS + INPUT_PARAMS + REDUCE_PARAMS)
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
        values = self.parameters
        fc, kind = input_fan_cloud(dataset, fan_values(values),
                                   lambda f, m: self._progress(0.3 * f, m),
                                   keep_unreferenced=values["keep_unreferenced"])
        small = reduce(fc, **_amount(values), **_reduce_values(values),
                       progress=lambda f, m: self._progress(0.3 + 0.6 * f, m))
        return fan_cloud_output(self, small, kind, values["mesh"], fc)


def fan_cloud_output(alg: FanCloudAlgorithm, fc, kind: str, mesh: bool, source):
    """The filter's output: the fan cloud, or with ``mesh`` its triangle mesh, saying which
    kind of input it came from (:func:`~.convert.mark_input`; ``source``: the input's fan
    cloud)."""
    if mesh:
        if alg._progress(0.9, "mesh"):
            raise Cancelled("meshing was cancelled")
        out = mesh_to_vtk(fan_cloud_to_mesh(fc, rings=mesh_rings(kind)))
    else:
        out = fancloud_to_vtk(fc)
    mark_input(out, kind, source)
    alg._progress(1.0, "done")
    return out


def region_of(values: dict):
    """The region of interest of the selective refinement's values (a ``(center, radius)``
    sphere or box bounds) for :meth:`~fancloud_vtk.Hierarchy.selective`."""
    if values["region"] == "sphere":
        if not values["region_radius"] > 0:
            raise ValueError("region_radius must be > 0 for a sphere region of interest")
        return values["region_center"], values["region_radius"]
    b = values["region_bounds"]
    if b[0] == b[1] and b[2] == b[3] and b[4] == b[5]:
        raise ValueError(f"region_bounds must be set for a box region of interest "
                         f"(xmin, xmax, ymin, ymax, zmin, zmax), got the single point {b}")
    if b[0] > b[1] or b[2] > b[3] or b[4] > b[5]:
        raise ValueError(f"region_bounds must be (xmin, xmax, ymin, ymax, zmin, zmax) "
                         f"with min <= max, got {b}")
    return np.array(b, np.float64)


def selective_refinement(fc, values: dict, progress=None):
    """Figure 11 on a fan cloud, from the values of ``FAN_PARAMS + REDUCE_PARAMS`` (but
    ``mesh``) ``+ SELECTIVE_PARAMS``: the hierarchy down to ``n_points``/``keep``, its coarsest
    level smoothed ``smooth_iterations`` times, the removed points inside the region
    reinserted (fans built with the fan parameters). The filter and ``fancloud selective``
    call it."""
    region = region_of(values)
    target = target_count(fc.n_points, **_amount(values))
    h = hierarchy(fc, target, **_reduce_values(values),
                  progress=None if progress is None else lambda f, m: progress(0.9 * f, m))
    coarse = h.level(target)
    if values["smooth_iterations"]:
        coarse = laplacian_smooth(coarse, values["smooth_iterations"])
    return h.selective(region, base=coarse, **fan_values(values))


@with_parameters(FAN_PARAMS + INPUT_PARAMS + REDUCE_PARAMS[:-1] + SELECTIVE_PARAMS)
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
        values = self.parameters
        region_of(values)  # a bad region fails before the fans are built
        fc, kind = input_fan_cloud(dataset, fan_values(values),
                                   lambda f, m: self._progress(0.3 * f, m),
                                   keep_unreferenced=values["keep_unreferenced"])
        out = fancloud_to_vtk(selective_refinement(
            fc, values, lambda f, m: self._progress(0.3 + 0.7 * f, m)))
        mark_input(out, kind, fc)
        self._progress(1.0, "done")
        return out
