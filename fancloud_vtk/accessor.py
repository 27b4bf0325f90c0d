"""The PyVista accessor ``dataset.fancloud``.

Registered through the ``pyvista.accessors`` entry point, so
``pv.PolyData(points).fancloud.fans()`` works without importing
``fancloud_vtk``. It holds no algorithm: each verb checks its keywords
against the parameter table, runs the VTK algorithm and wraps a *new*
dataset (the input is never modified; its point arrays are kept).
"""

from __future__ import annotations

import inspect

import pyvista as pv

from fancloud_vtk.algorithms.base import run
from fancloud_vtk.algorithms.convert import (
    add_unreferenced_field,
    fancloud_from_vtk,
    is_fancloud,
    source_of,
    to_vtk,
)
from fancloud_vtk.algorithms.entropy import FanCloudEntropyFilter
from fancloud_vtk.algorithms.fans import FanCloudFilter
from fancloud_vtk.algorithms.mesh import FanCloudMeshFilter
from fancloud_vtk.algorithms.reduce import FanCloudReduceFilter, FanCloudSelectiveRefineFilter
from fancloud_vtk.algorithms.refine import FanCloudRefineFilter
from fancloud_vtk.algorithms.vdfc import (
    FanCloudViewDependentFilter,
    build_forest,
    e_max_of,
    follow_camera,
)
from fancloud_vtk.core import verbs
from fancloud_vtk.core.vdfc import ViewDependentFanCloud
from fancloud_vtk.params import VERB_PARAMS, Param


def _point_set(dataset):
    """The dataset itself if it is a ``vtkPointSet``, else its points and point arrays.

    Image data and rectilinear grids keep their points implicitly; the fan
    algorithms only use the points, so these are cast (a new object, the
    input is untouched).
    """
    if dataset.IsA("vtkPointSet"):
        return dataset
    return dataset.cast_to_pointset(pass_cell_data=False)


def _run(algorithm, dataset, progress_bar: bool, message: str) -> pv.PolyData:
    algorithm.SetInputDataObject(0, _point_set(dataset))
    if progress_bar:
        from pyvista.core.utilities.observers import ProgressMonitor

        with ProgressMonitor(algorithm, message=message):
            output = run(algorithm)
    else:
        output = run(algorithm)
    result = pv.PolyData()
    result.ShallowCopy(output)
    return result


class PyVistaViewDependentFanCloud(ViewDependentFanCloud):
    """A :class:`~fancloud_vtk.ViewDependentFanCloud` whose fronts are ``pyvista.PolyData``.

    Returned by ``dataset.fancloud.vdfc()``; it keeps the verb's ``e_max``,
    ``d_max`` and ``aspect`` as the defaults of :meth:`front`, and can put a
    live front into a plotter (:meth:`add_to`).
    """

    @classmethod
    def of(cls, vd: ViewDependentFanCloud, values: dict) -> PyVistaViewDependentFanCloud:
        out = cls.__new__(cls)
        out.__dict__.update(vd.__dict__)
        out.values = dict(values)
        return out

    def front(self, camera, e_max=None, d_max=None, *, aspect=None, incremental=True,
              superfluous=None):
        """The active front for ``camera`` as a new ``pyvista.PolyData``.

        ``e_max``, ``d_max``, ``aspect``, ``superfluous``: as for
        :meth:`fancloud_vtk.ViewDependentFanCloud.front_arrays`; by default the
        values given to ``vdfc()`` (``e_max`` 0: 0.1% of the diagonal).
        """
        e = e_max if e_max is not None else e_max_of(self, self.values["e_max"])
        d = d_max if d_max is not None else (self.values["d_max"] or None)
        a = aspect if aspect is not None else (self.values["aspect"] or None)
        s = superfluous if superfluous is not None else self.values["superfluous"]
        out = pv.wrap(to_vtk(self.front_arrays(camera, e, d, aspect=a, incremental=incremental,
                                               superfluous=s)))
        add_unreferenced_field(out, getattr(self, "unreferenced_dropped", None))
        return out

    def filter(self) -> FanCloudViewDependentFilter:
        """A :class:`~fancloud_vtk.algorithms.FanCloudViewDependentFilter` over this forest."""
        params = {k: v for k, v in self.values.items()
                  if k in {p.name for p in FanCloudViewDependentFilter.PARAMETERS}}
        alg = FanCloudViewDependentFilter(**params)
        alg.SetForest(self)
        return alg

    def add_to(self, plotter, **mesh_kwargs):
        """Show the live front in ``plotter``: it follows the plotter's camera.

        Returns the actor of ``plotter.add_mesh(filter, **mesh_kwargs)``; the
        filter is kept as ``live_filter`` (its ``last_stats`` tell the size
        and update time of the front shown).
        """
        alg = self.filter()
        follow_camera(plotter, alg)
        self.live_filter = alg
        return plotter.add_mesh(alg, **mesh_kwargs)


def _document(table: tuple[Param, ...], returns: str = "pv.PolyData"):
    """Fill ``{params}`` in the docstring and set a signature from the table."""

    def decorate(func):
        lines = []
        for p in table:
            lines.append(f"{p.name} : {p.kind}, default: {p.default!r}")
            lines.append(f"    {p.doc[0].upper()}{p.doc[1:]}.")
        func.__doc__ = func.__doc__.replace("{params}", "\n        ".join(lines))
        params = [inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)]
        params += [
            inspect.Parameter(p.name, inspect.Parameter.KEYWORD_ONLY, default=p.default)
            for p in table
        ]
        params.append(
            inspect.Parameter("progress_bar", inspect.Parameter.KEYWORD_ONLY, default=False)
        )
        func.__signature__ = inspect.Signature(params, return_annotation=returns)
        return func

    return decorate


@pv.register_dataset_accessor("fancloud", pv.DataSet)
class FanCloudAccessor:
    """Fan cloud verbs on any PyVista dataset: ``dataset.fancloud.<verb>()``."""

    def __init__(self, dataset):
        self._dataset = dataset

    @property
    def is_fan_cloud(self) -> bool:
        """True if the dataset carries a fan cloud (``fan_offsets``/``fan_ring`` arrays)."""
        return is_fancloud(self._dataset)

    def to_fancloud(self):
        """The dataset's fan cloud as a :class:`fancloud_vtk.FanCloud` (arrays copied)."""
        return fancloud_from_vtk(self._dataset)

    @_document(VERB_PARAMS["fans"])
    def fans(self, *, progress_bar: bool = False, **params) -> pv.PolyData:
        """Build the fan cloud of the dataset's points (paper section 3).

        Only the points are used (of a triangle mesh only the vertices of its
        triangles, unless ``keep_unreferenced``); every point array is kept,
        and a ``Normals`` point array orients the fan normals.

        Parameters
        ----------
        {params}
        progress_bar : bool, default: False
            Show a progress bar (needs ``tqdm``).

        Returns
        -------
        pyvista.PolyData
            A new dataset: the points, the distinct fan triangles, point arrays
            ``Normals``, ``fan_open``, ``fan_rotated`` and the input's arrays,
            field arrays ``fan_offsets`` and ``fan_ring`` (and, for a triangle
            mesh, ``unreferenced_dropped``: how many of its vertices no triangle
            used and were dropped, with an
            :class:`~fancloud_vtk.UnreferencedVerticesWarning`; the point array
            ``original_id`` then maps the points to the input's).

        Raises
        ------
        TypeError, ValueError
            For unknown or out-of-range parameters and for points that give no
            fan cloud (NaN, fewer than k + 1 points, all collinear, ...).

        See Also
        --------
        fancloud_vtk.build_fans : the same on numpy arrays.

        Examples
        --------
        >>> import pyvista as pv
        >>> cloud = pv.PolyData(pv.Sphere(theta_resolution=60, phi_resolution=60).points)
        >>> fans = cloud.fancloud.fans(k=6)
        >>> int(fans["fan_open"].sum())
        0
        >>> fans.plot(smooth_shading=True)  # doctest: +SKIP
        """
        values = verbs.check_values("fans", params)
        return _run(FanCloudFilter(**values), self._dataset, progress_bar, "Building fans")

    @_document(VERB_PARAMS["mesh"])
    def mesh(self, *, progress_bar: bool = False, **params) -> pv.PolyData:
        """Triangle mesh from the fan cloud (paper section 4): a closed 2-manifold where it can be.

        On a fan cloud (the output of :meth:`fans`) its rings are used as they
        are; on any other dataset the fans of its points are built first with
        the fan parameters. Every point and point array is kept.

        Parameters
        ----------
        {params}
        progress_bar : bool, default: False
            Show a progress bar (needs ``tqdm``).

        Returns
        -------
        pyvista.PolyData
            A new dataset: the points, the mesh triangles (counter-clockwise
            around ``Normals``), the input's point arrays, and the mesh
            statistics as one-value field arrays ``mesh_<name>``
            (``mesh_final``, ``mesh_holes``, ``mesh_boundary_edges``,
            ``mesh_non_manifold_edges``, ``mesh_self_intersections``, ...).

        Raises
        ------
        TypeError, ValueError
            For unknown or out-of-range parameters and for input that gives no
            fan cloud.

        See Also
        --------
        fancloud_vtk.fan_cloud_to_mesh : the same on a FanCloud.

        Examples
        --------
        >>> import pyvista as pv
        >>> from fancloud_vtk.data import bunny_path
        >>> cloud = pv.PolyData(pv.read(bunny_path()).points)
        >>> mesh = cloud.fancloud.mesh()
        >>> mesh.n_cells == 2 * cloud.n_points - 4, int(mesh["mesh_holes"][0])
        (True, 0)
        >>> mesh.plot(smooth_shading=True)  # doctest: +SKIP
        """
        values = verbs.check_values("mesh", params)
        return _run(FanCloudMeshFilter(**values), self._dataset, progress_bar, "Meshing")

    @_document(VERB_PARAMS["entropy"])
    def entropy(self, *, progress_bar: bool = False, **params) -> pv.PolyData:
        """The entropy of every point (paper section 5) as point arrays.

        Three kinds of input: a fan cloud (the output of :meth:`fans`; its
        rings are used), a triangle mesh (every vertex's one-ring is its fan)
        or a plain point set (its fans are built first with the fan
        parameters). The field array ``fancloud_input`` says which it took.

        Parameters
        ----------
        {params}
        progress_bar : bool, default: False
            Show a progress bar (needs ``tqdm``).

        Returns
        -------
        pyvista.PolyData
            A new dataset: the input (for a point set: its fan cloud) with the
            point arrays ``entropy`` (active scalars), ``entropy_dist``,
            ``entropy_curv``, ``entropy_cc`` and ``entropy_col``.

        See Also
        --------
        fancloud_vtk.entropy : the same on a FanCloud or TriangleMesh.

        Examples
        --------
        >>> import pyvista as pv
        >>> from fancloud_vtk.data import bunny_path
        >>> bunny = pv.read(bunny_path())
        >>> ent = bunny.fancloud.entropy()
        >>> str(ent["fancloud_input"][0]), ent.n_points == bunny.n_points
        ('triangle mesh', True)
        >>> ent.plot(scalars="entropy_curv", log_scale=True)  # doctest: +SKIP
        """
        values = verbs.check_values("entropy", params)
        return _run(FanCloudEntropyFilter(**values), self._dataset, progress_bar, "Entropy")

    @_document(VERB_PARAMS["reduce"])
    def reduce(self, *, progress_bar: bool = False, **params) -> pv.PolyData:
        """Reduce to an exact number of points by entropy (paper section 5).

        Repeatedly removes the point of lowest entropy (``method='error'``:
        the point whose removal changes the surface least) and re-forms the
        fans around it. Three kinds of input, as for :meth:`entropy`.

        Parameters
        ----------
        {params}
        progress_bar : bool, default: False
            Show a progress bar (needs ``tqdm``).

        Returns
        -------
        pyvista.PolyData
            A new fan cloud (with ``mesh=True``: its triangle mesh) of the
            kept points, with their point arrays, ``original_id`` (the index
            of each point in the first input of a chain of reductions: an
            input's own ``original_id`` is composed, not replaced) and the
            field array ``fancloud_input``.

        Raises
        ------
        ValueError
            ``n_points`` together with ``keep``; a count or fraction out of
            range, bad weights, method or colour array.

        See Also
        --------
        fancloud_vtk.reduce : the same on a FanCloud or TriangleMesh.
        hierarchy : the levels of detail of the reduction.

        Examples
        --------
        >>> import pyvista as pv
        >>> from fancloud_vtk.data import bunny_path
        >>> bunny = pv.read(bunny_path())
        >>> small = bunny.fancloud.reduce(keep=0.176, mesh=True)
        >>> small.n_points == round(0.176 * bunny.n_points)
        True
        >>> small.plot(smooth_shading=True)  # doctest: +SKIP
        """
        verbs.check_amount("reduce", params)
        values = verbs.check_values("reduce", params)
        return _run(FanCloudReduceFilter(**values), self._dataset, progress_bar, "Reducing")

    @_document(VERB_PARAMS["selective"])
    def selective(self, *, progress_bar: bool = False, **params) -> pv.PolyData:
        """Reduce, smooth the coarse level, refine only a region of interest (Figure 11).

        The dataset is reduced to ``n_points``/``keep`` as by :meth:`reduce`,
        that coarse level is smoothed ``smooth_iterations`` times, every
        removed point is put back on it by its detail in its local frame,
        and those inside the region (a sphere ``region_center`` /
        ``region_radius``, or a box ``region_bounds`` with
        ``region='box'``) are reinserted. For regions of other shapes, or
        other edits of the coarse level, use :meth:`hierarchy` and
        :meth:`fancloud_vtk.Hierarchy.selective`.

        Parameters
        ----------
        {params}
        progress_bar : bool, default: False
            Show a progress bar (needs ``tqdm``).

        Returns
        -------
        pyvista.PolyData
            A new fan cloud: the coarse level's points and the reinserted
            ones (fans built anew with the fan keywords), with their point
            arrays, ``original_id`` and the field array ``fancloud_input``.

        Raises
        ------
        ValueError
            ``n_points`` together with ``keep``; a sphere region without a
            radius > 0, box bounds with a min above a max; the reduction's
            errors.

        See Also
        --------
        hierarchy : the levels of detail, for any region or edit.

        Examples
        --------
        >>> import pyvista as pv
        >>> from fancloud_vtk.data import bunny_path
        >>> bunny = pv.read(bunny_path())
        >>> head = bunny.fancloud.selective(keep=0.15, smooth_iterations=5,
        ...                                 region_center=(0.1, 0.33, 0.36), region_radius=0.14)
        >>> 4213 < head.n_points < bunny.n_points
        True
        >>> head.plot(smooth_shading=True)  # doctest: +SKIP
        """
        verbs.check_amount("selective", params)
        values = verbs.check_values("selective", params)
        return _run(FanCloudSelectiveRefineFilter(**values), self._dataset, progress_bar,
                    "Refining a region")

    @_document(VERB_PARAMS["refine"])
    def refine(self, *, progress_bar: bool = False, **params) -> pv.PolyData:
        """Refine beyond the input resolution by entropy (paper section 7).

        Inserts points where the entropy is highest, each moved along its
        normal so that its mean curvature matches its parents', and re-forms
        the fans around it. Three kinds of input, as for :meth:`entropy`.

        Parameters
        ----------
        {params}
        progress_bar : bool, default: False
            Show a progress bar (needs ``tqdm``).

        Returns
        -------
        pyvista.PolyData
            A new fan cloud (with ``mesh=True``: its triangle mesh): the
            input's points first, then the inserted ones, with the point
            arrays (floats and colours interpolated, others taken from the
            first parent), ``original_id`` (-1 on inserted points) and the
            field array ``fancloud_input``.

        Raises
        ------
        ValueError
            ``n_points`` together with ``factor``; ``factor`` <= 1 or
            ``n_points`` below the input's count; bad weights or colour
            array; no closed fan to refine from
            (:class:`~fancloud_vtk.FanCloudInputError`).

        See Also
        --------
        fancloud_vtk.refine : the same on a FanCloud or TriangleMesh.
        reduce : the other direction.

        Examples
        --------
        >>> import pyvista as pv
        >>> from fancloud_vtk.data import bunny_path
        >>> bunny = pv.read(bunny_path())
        >>> fine = bunny.fancloud.refine(factor=2, mesh=True)
        >>> fine.n_points == 2 * bunny.n_points
        True
        >>> int((fine["original_id"] == -1).sum()) == bunny.n_points
        True
        >>> fine.plot(smooth_shading=True)  # doctest: +SKIP
        """
        verbs.check_amount("refine", params)
        values = verbs.check_values("refine", params)
        return _run(FanCloudRefineFilter(**values), self._dataset, progress_bar, "Refining")

    @_document(VERB_PARAMS["vdfc"], returns="PyVistaViewDependentFanCloud")
    def vdfc(self, *, progress_bar: bool = False, **params) -> PyVistaViewDependentFanCloud:
        """The view-dependent fan cloud: a merge forest and its fronts (paper section 8).

        Builds the merge forest of a height field (a 2-d ``pyvista.ImageData``
        whose active scalars are the heights), a fan cloud, a triangle mesh
        or a point set. Its :meth:`~PyVistaViewDependentFanCloud.front` gives
        the active front for a camera as a ``pyvista.PolyData`` with point
        arrays ``node_id``, ``level`` and ``error``;
        :meth:`~PyVistaViewDependentFanCloud.add_to` shows a front that
        follows a plotter's camera.

        Parameters
        ----------
        {params}
        progress_bar : bool, default: False
            Show a progress bar (needs ``tqdm``).

        Returns
        -------
        PyVistaViewDependentFanCloud
            A :class:`fancloud_vtk.ViewDependentFanCloud` whose fronts are
            ``pyvista.PolyData``. For a triangle mesh, its attribute
            ``unreferenced_dropped`` (and its fronts' field array of that
            name) counts the vertices that no triangle used and were dropped.

        See Also
        --------
        fancloud_vtk.ViewDependentFanCloud.build : the same on a FanCloud.

        Examples
        --------
        >>> import numpy as np
        >>> import pyvista as pv
        >>> z = np.add.outer(np.sin(np.linspace(0, 6, 100)), np.cos(np.linspace(0, 6, 100)))
        >>> grid = pv.ImageData(dimensions=(100, 100, 1), spacing=(0.1, 0.1, 1))
        >>> grid["height"] = z.ravel()
        >>> vd = grid.fancloud.vdfc(e_max=0.02)
        >>> front = vd.front(((5, -5, 4), (5, 5, 0), (0, 0, 1), 40.0))
        >>> sorted(front.point_data.keys())
        ['Normals', 'error', 'level', 'node_id']
        >>> front.n_points < grid.n_points
        True
        >>> pl = pv.Plotter()
        >>> actor = vd.add_to(pl, color="tan")
        >>> pl.show()  # doctest: +SKIP
        """
        values = verbs.check_values("vdfc", params)
        data = self._dataset if self._dataset.IsA("vtkImageData") else \
            _point_set(self._dataset)
        if progress_bar:
            from tqdm import tqdm

            bar = tqdm(total=100, desc="Merge forest")

            def progress(f, m):
                bar.n = int(100 * f)
                bar.refresh()
        else:
            bar, progress = None, None
        try:
            vd, _ = build_forest(data, values, progress)
        finally:
            if bar is not None:
                bar.close()
        return PyVistaViewDependentFanCloud.of(vd, values)

    def hierarchy(self, n_points=None, *, weights=(1.0, 1.0, 50.0, 0.0), method="entropy",
                  color_array="", exact=False, keep_unreferenced=False, **fan_params):
        """The levels of detail of the reduction (paper section 6).

        Parameters
        ----------
        n_points : int, optional
            The coarsest level to compute (default: as far as it goes).
        weights, method, color_array, exact, keep_unreferenced
            As for :meth:`reduce`.
        **fan_params
            Fan parameters (``k``, ...) for a plain point set.

        Returns
        -------
        fancloud_vtk.Hierarchy
            ``level(m)`` gives the fan cloud of any level (a
            :class:`~fancloud_vtk.FanCloud`; ``pv.wrap(fancloud_vtk.to_vtk(fc))`` for
            PyVista), ``level(m, base=edited)`` refines an edited level,
            ``selective(region)`` refines a region of interest. Its
            attribute ``fancloud_input`` says which kind of input it took
            (``'fan cloud'``, ``'triangle mesh'`` or ``'point set'``, as
            the field array of the other verbs; not saved by ``save``).

        Examples
        --------
        >>> import pyvista as pv
        >>> from fancloud_vtk import to_vtk
        >>> from fancloud_vtk.data import bunny_path
        >>> h = pv.read(bunny_path()).fancloud.hierarchy(2000)
        >>> h.fancloud_input
        'triangle mesh'
        >>> coarse = pv.wrap(to_vtk(h.level(2000)))
        >>> coarse.n_points
        2000
        """
        values = verbs.check_values("hierarchy", {
            **fan_params, "n_points": 0 if n_points is None else n_points, "weights": weights,
            "method": method, "color_array": color_array, "exact": exact,
            "keep_unreferenced": keep_unreferenced})
        return verbs.hierarchy(source_of(_point_set(self._dataset)), values)
