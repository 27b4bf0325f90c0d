"""``FanCloudViewDependentFilter`` (paper section 8), camera following and fly-throughs.

The filter builds the merge forest of its input once (again only when the
input or a build parameter changes) and outputs the active front for its
camera. Its camera is a parameter: :meth:`~FanCloudViewDependentFilter.SetCamera`
takes a ``vtkCamera`` (PyVista's too) and the filter is modified whenever
that camera moves, so a viewer that renders the filter's output shows the
front of its own view. :func:`follow_camera` hooks a plotter or renderer so
that the filter follows its active camera and window aspect.
:func:`flythrough` renders a camera path offscreen to PNG frames and records
every frame's front size and update time.

Imports numpy, ``vtkmodules`` and the core only.
"""

from __future__ import annotations

import csv
import os
import time

import numpy as np
from vtkmodules.vtkCommonDataModel import vtkImageData

from fancloud_vtk.core import verbs
from fancloud_vtk.core.vdfc import Camera, ViewDependentFanCloud
from fancloud_vtk.core.verbs import e_max_of
from fancloud_vtk.params import FAN_PARAMS, INPUT_PARAMS, VERB_PARAMS

from .base import FanCloudAlgorithm, with_parameters
from .convert import add_unreferenced_field, point_arrays, source_of, to_vtk, vtk_to_numpy

__all__ = ["FanCloudViewDependentFilter", "build_forest", "e_max_of", "flythrough",
           "follow_camera", "height_field_of_image", "image_of_heights", "source_of_image"]


def height_field_of_image(image, array: str | None = None):
    """(heights (ny, nx), spacing (dx, dy), origin (x0, y0), point arrays) of a 2-d image.

    The heights are the named point array, or the active scalars, or the
    first one-component point array.
    """
    dims = image.GetDimensions()
    flat = [d for d in dims if d > 1]
    if len(flat) != 2 or dims[2] != 1:
        raise ValueError(f"a height field must be a 2-d image in x and y, got dimensions {dims}")
    pd = image.GetPointData()
    arr = pd.GetArray(array) if array else pd.GetScalars()
    if arr is None:
        for i in range(pd.GetNumberOfArrays()):
            cand = pd.GetArray(i)
            if cand is not None and cand.GetNumberOfComponents() == 1:
                arr = cand
                break
    if arr is None or arr.GetNumberOfComponents() != 1:
        raise ValueError("the image has no one-component point array to use as heights")
    nx, ny = dims[0], dims[1]
    heights = np.array(vtk_to_numpy(arr), dtype=np.float64).reshape(ny, nx)
    sx, sy, _ = image.GetSpacing()
    ox, oy, _ = image.GetOrigin()
    others = {k: v.reshape((ny, nx) + v.shape[1:]) for k, v in point_arrays(image).items()
              if k != arr.GetName()}
    return heights, (sx, sy), (ox, oy), others


def source_of_image(image) -> verbs.Source:
    """A 2-d ``vtkImageData`` (a height field) as the verbs' ``Source``."""
    heights, spacing, origin, others = height_field_of_image(image)
    return verbs.Source(heights=(heights, spacing, origin), point_data=others)


def build_forest(dataset, values: dict, progress=None) -> tuple[ViewDependentFanCloud, str]:
    """The forest of a filter input (a height field image, a fan cloud, a mesh or points)
    and which kind of input it was: :func:`fancloud_vtk.core.verbs.vdfc`.

    The forest's attribute ``unreferenced_dropped`` is the number of a mesh's vertices
    that no triangle used and were dropped (``None`` for other inputs; not saved by
    ``save``).
    """
    if isinstance(dataset, vtkImageData) or dataset.IsA("vtkImageData"):
        source = source_of_image(dataset)
    else:
        source = source_of(dataset)
    vd = verbs.vdfc(source, values, progress)
    return vd, vd.fancloud_input


_BUILD = ("merge", "weights", "color_array", "n_roots", "block_size") + \
    tuple(p.name for p in FAN_PARAMS + INPUT_PARAMS)


@with_parameters(VERB_PARAMS["vdfc"])
class FanCloudViewDependentFilter(FanCloudAlgorithm):
    """The view-dependent fan cloud of the input, for a camera (section 8).

    The input is a height field (2-d ``vtkImageData``, its scalars the
    heights), a fan cloud, a triangle mesh or a point set (fans built first
    with this filter's fan parameters). A mesh's vertices that no triangle
    uses are dropped unless ``keep_unreferenced`` (the fronts' field array
    ``unreferenced_dropped`` counts them). The merge forest is built once and
    kept; each update outputs the active front for the camera: the active
    points and their distinct triangles, with point arrays ``node_id``,
    ``level`` and ``error``, ``Normals`` and the colours. The front moves
    incrementally from the previous update.

    The camera: :meth:`SetCamera` (a ``vtkCamera``; the filter is modified
    whenever it moves) or, without one, a camera tuple
    ``(position, focal_point, view_up, view_angle[, aspect])``. In a
    PyVista plotter: ``pl.add_mesh(filter)`` and
    ``follow_camera(pl, filter)``.

    Examples
    --------
    >>> import numpy as np
    >>> from vtkmodules.vtkRenderingCore import vtkCamera
    >>> from fancloud_vtk.algorithms import FanCloudViewDependentFilter, run
    >>> from fancloud_vtk.algorithms.vdfc import image_of_heights
    >>> z = np.add.outer(np.sin(np.linspace(0, 6, 80)), np.cos(np.linspace(0, 6, 80)))
    >>> cam = vtkCamera()
    >>> cam.SetPosition(4, -6, 4); cam.SetFocalPoint(4, 4, 0); cam.SetViewUp(0, 0, 1)
    >>> vd = FanCloudViewDependentFilter(e_max=0.05, d_max=12.0)
    >>> vd.SetInputDataObject(image_of_heights(z, spacing=0.1))
    >>> vd.SetCamera(cam)
    >>> far = run(vd).GetNumberOfPoints()
    >>> 0 < far < 6400
    True
    >>> cam.SetPosition(4, -3, 2.5)  # the camera moves: the filter is modified
    >>> run(vd).GetNumberOfPoints() != far  # a new front
    True
    """

    def __init__(self, **params):
        super().__init__(inputType="vtkDataObject", outputType="vtkPolyData", **params)
        self._camera = None
        self._camera_tuple = None
        self._observer = None
        self._last_view = None
        self._forest = None
        self._forest_key = None
        self.forest: ViewDependentFanCloud | None = None
        self.kind: str | None = None
        #: statistics of the last front (active points, triangles, seconds, ...)
        self.last_stats: dict = {}

    # -- the camera ------------------------------------------------------------
    def SetCamera(self, camera) -> None:
        """The camera whose front is output: a ``vtkCamera`` (followed) or a camera tuple."""
        if self._camera is not None and self._observer is not None:
            self._camera.RemoveObserver(self._observer)
            self._observer = None
        if camera is not None and hasattr(camera, "AddObserver"):
            Camera.of(camera)  # a clear error now rather than inside RequestData
            self._camera, self._camera_tuple = camera, None
            self._observer = camera.AddObserver("ModifiedEvent", self._camera_moved)
        else:
            self._camera = None
            self._camera_tuple = None if camera is None else Camera.of(camera)
        self._last_view = None
        self.Modified()

    def GetCamera(self):
        return self._camera if self._camera is not None else self._camera_tuple

    def _view(self):
        cam = self._camera
        return (cam.GetPosition(), cam.GetFocalPoint(), cam.GetViewUp(), cam.GetViewAngle(),
                cam.GetParallelProjection())

    def _camera_moved(self, *_):
        # the renderer also touches the camera (clipping range) while rendering:
        # only a change of view modifies the filter
        view = self._view()
        if view != self._last_view:
            self._last_view = view
            self.Modified()

    def SetForest(self, forest: ViewDependentFanCloud | None) -> None:
        """Use a forest built (or loaded) elsewhere; the input is then ignored."""
        if forest is not None and not isinstance(forest, ViewDependentFanCloud):
            raise TypeError(f"expected a ViewDependentFanCloud, got {type(forest).__name__}")
        self._forest = forest
        self._forest_key = None
        self.Modified()

    # -- pipeline ------------------------------------------------------------------
    def FillInputPortInformation(self, port, info):
        info.Set(self.INPUT_REQUIRED_DATA_TYPE(), "vtkDataSet")
        info.Set(self.INPUT_IS_OPTIONAL(), 1)
        return 1

    def forest_for(self, dataset) -> ViewDependentFanCloud:
        """The kept forest, built again only when the input or a build parameter changed."""
        if self._forest is not None:
            self.forest, self.kind = self._forest, "forest"
            return self._forest
        if dataset is None:
            raise ValueError("FanCloudViewDependentFilter has no input and no forest "
                             "(SetInputData, SetInputConnection or SetForest)")
        values = self.parameters
        # the wrapper object differs between updates: the modification time names the data
        key = (dataset.GetClassName(), dataset.GetMTime(), tuple((k, values[k]) for k in _BUILD))
        if self.forest is None or key != self._forest_key:
            self.forest, self.kind = build_forest(dataset, values,
                                                  lambda f, m: self._progress(0.9 * f, m))
            self._forest_key = key
        return self.forest

    def execute(self, dataset):
        vd = self.forest_for(dataset)
        camera = self._camera if self._camera is not None else self._camera_tuple
        if camera is None:
            raise ValueError("FanCloudViewDependentFilter has no camera (SetCamera)")
        values = self.parameters
        front = vd.front_arrays(camera, e_max_of(vd, values["e_max"]), values["d_max"] or None,
                                aspect=values["aspect"] or None,
                                superfluous=values["superfluous"])
        self.last_stats = dict(front.stats)
        self._progress(1.0, "front")
        out = to_vtk(front)
        add_unreferenced_field(out, getattr(vd, "unreferenced_dropped", None))
        return out


def image_of_heights(heights, spacing=1.0, origin=(0.0, 0.0), name: str = "height"):
    """A ``vtkImageData`` height field (point scalars ``name``) from a 2-d array."""
    from .convert import _to_vtk_array

    h = np.asarray(heights, dtype=np.float64)
    if h.ndim != 2:
        raise ValueError(f"heights must be a 2-d array, got shape {h.shape}")
    sp = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (2,))
    img = vtkImageData()
    img.SetDimensions(h.shape[1], h.shape[0], 1)
    img.SetSpacing(float(sp[0]), float(sp[1]), 1.0)
    img.SetOrigin(float(origin[0]), float(origin[1]), 0.0)
    img.GetPointData().SetScalars(_to_vtk_array(np.ascontiguousarray(h.ravel()), name))
    return img


# -- following a viewer's camera --------------------------------------------------------


def _renderer_of(viewer):
    if hasattr(viewer, "GetActiveCamera"):
        return viewer
    ren = getattr(viewer, "renderer", None)
    if ren is None or not hasattr(ren, "GetActiveCamera"):
        raise TypeError("follow_camera needs a vtkRenderer or a plotter with a .renderer, got "
                        f"{type(viewer).__name__}")
    return ren


def follow_camera(viewer, algorithm: FanCloudViewDependentFilter) -> int:
    """Make ``algorithm`` follow the active camera (and aspect) of a plotter or renderer.

    ``viewer`` is a ``vtkRenderer`` or a PyVista ``Plotter`` (its
    ``.renderer``). Before every render the filter takes the renderer's
    active camera and aspect; moving the camera modifies the filter, so the
    render shows the front of the new view. Returns the observer id on the
    renderer (``renderer.RemoveObserver(id)`` stops it).
    """
    ren = _renderer_of(viewer)

    def before_render(*_):
        cam = ren.GetActiveCamera()
        if algorithm.GetCamera() is not cam:
            algorithm.SetCamera(cam)
        aspect = float(ren.GetTiledAspectRatio()) if ren.GetRenderWindow() else 1.0
        if aspect > 0:
            algorithm.SetAspect(aspect)
        # pull the new front before the mappers draw
        algorithm.Update()

    before_render()
    return ren.AddObserver("StartEvent", before_render)


# -- fly-throughs -----------------------------------------------------------------------


def flythrough(forest: ViewDependentFanCloud, cameras, e_max: float, out_dir=None, *,
               d_max: float | None = None, size=(640, 480), color="tan",
               superfluous: bool = False, progress=None) -> list[dict]:
    """Render a camera path offscreen; record every frame's front.

    Parameters
    ----------
    forest : ViewDependentFanCloud
    cameras : sequence of camera tuples
        E.g. from :func:`~fancloud_vtk.core.vdfc.terrain_path`.
    e_max, d_max : float
        As for :meth:`ViewDependentFanCloud.front_arrays` (``d_max`` None: the
        default range of sight of the first frame, kept for the whole path).
    out_dir : str, optional
        Folder for ``frame_0000.png``, ... and ``frames.csv`` (None: no files,
        the frames are rendered and timed all the same).
    size : (int, int)
        Width and height of the frames.
    superfluous : bool, default: False
        Remove the fronts' superfluous triangles (see
        :meth:`ViewDependentFanCloud.front_arrays`).

    Returns
    -------
    list of dict
        Per frame: ``frame``, ``active`` points, ``triangles``,
        ``triangles_per_point``, ``front_ms`` (the front update),
        ``render_ms``.
    """
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the render window factory)
    from vtkmodules.vtkCommonColor import vtkNamedColors
    from vtkmodules.vtkIOImage import vtkPNGWriter
    from vtkmodules.vtkRenderingCore import (
        vtkActor,
        vtkPolyDataMapper,
        vtkRenderer,
        vtkRenderWindow,
        vtkWindowToImageFilter,
    )

    cams = [Camera.of(c) for c in cameras]
    if not cams:
        raise ValueError("the camera path is empty")
    w, h = (int(v) for v in size)
    aspect = w / h
    if d_max is None:
        d_max = forest.default_d_max(cams[0])
    if out_dir is not None:
        os.makedirs(out_dir, exist_ok=True)
    ren = vtkRenderer()
    ren.SetBackground(1, 1, 1)
    win = vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetSize(w, h)
    win.AddRenderer(ren)
    mapper = vtkPolyDataMapper()
    mapper.ScalarVisibilityOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetColor(vtkNamedColors().GetColor3d(color))
    ren.AddActor(actor)
    rows = []
    forest.reset_front()
    try:
        for i, cam in enumerate(cams):
            front = forest.front_arrays(cam, e_max, d_max, aspect=aspect,
                                        superfluous=superfluous)
            poly = to_vtk(front)
            mapper.SetInputData(poly)
            vc = ren.GetActiveCamera()
            vc.SetPosition(*cam.position)
            vc.SetFocalPoint(*cam.focal_point)
            vc.SetViewUp(*cam.view_up)
            vc.SetViewAngle(cam.view_angle)
            ren.ResetCameraClippingRange()
            t0 = time.perf_counter()
            win.Render()
            render_ms = 1e3 * (time.perf_counter() - t0)
            if out_dir is not None:
                grab = vtkWindowToImageFilter()
                grab.SetInput(win)
                grab.Update()
                writer = vtkPNGWriter()
                writer.SetFileName(os.path.join(out_dir, f"frame_{i:04d}.png"))
                writer.SetInputConnection(grab.GetOutputPort())
                writer.Write()
            s = front.stats
            rows.append({"frame": i, "active": s["active"], "triangles": s["triangles"],
                         "triangles_per_point": round(s["triangles_per_point"], 4),
                         "front_ms": round(1e3 * s["seconds"], 3),
                         "render_ms": round(render_ms, 3)})
            if progress is not None and progress((i + 1) / len(cams), "fly-through") is True:
                break  # cancelled (the core's convention: the callback returns True)
    finally:
        win.Finalize()
    if out_dir is not None:
        with open(os.path.join(out_dir, "frames.csv"), "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    return rows
