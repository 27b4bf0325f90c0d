"""Conversions between the core's numpy arrays and VTK data objects.

Imports numpy and ``vtkmodules`` only (never pyvista), so that ParaView's
VTK 9.2 can load it.

The fan cloud as ``vtkPolyData`` (public contract, see docs/data_model.md):

* points: the cloud's points (float64);
* polys: the fan cloud's distinct triangles;
* point arrays ``Normals`` (float64, unit; also the active normals),
  ``fan_open`` (uint8, 1 where the fan is open), ``fan_rotated`` (uint8, 1
  where the fan was built in the rotated plane), and every passthrough array
  (bool arrays as uint8, float16 as float32, arrays of more than two axes
  flattened to ``(n, components)``: VTK has no such arrays);
* field arrays ``fan_offsets`` and ``fan_ring`` (int64, CSR rings).
"""

from __future__ import annotations

import os
import re
from contextlib import contextmanager

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import VTK_FLOAT, VTK_UNSIGNED_CHAR, vtkCommand, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

from fancloud_vtk.core.entropy import UNREFERENCED_DROPPED
from fancloud_vtk.core.mesh import TriangleMesh
from fancloud_vtk.core.model import COLOR_NAMES, FanCloud

NORMALS = "Normals"
FAN_OPEN = "fan_open"
FAN_ROTATED = "fan_rotated"
FAN_OFFSETS = "fan_offsets"
FAN_RING = "fan_ring"
RESERVED = (NORMALS, FAN_OPEN, FAN_ROTATED)


def _to_vtk_array(arr: np.ndarray, name: str):
    """A deep VTK copy of ``arr`` named ``name``.

    bool becomes uint8 and float16 float32 (VTK has neither); non-native byte
    order is swapped; more than two axes are flattened to ``(n, components)``.
    Other kinds VTK cannot hold (complex, strings, objects) raise a
    ``TypeError`` naming the array.
    """
    arr = np.asarray(arr)
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8)
    elif arr.dtype == np.float16:
        arr = arr.astype(np.float32)
    if arr.dtype.kind not in "biuf":
        raise TypeError(
            f"point array {name!r} has dtype {arr.dtype}, which VTK cannot store; "
            "convert it to a real numeric type first"
        )
    if not arr.dtype.isnative:
        arr = arr.astype(arr.dtype.newbyteorder("="))
    if arr.ndim > 2:
        arr = arr.reshape(arr.shape[0], -1)
    out = numpy_to_vtk(np.ascontiguousarray(arr), deep=1)
    out.SetName(name)
    return out


def numpy_points(points: np.ndarray) -> vtkPoints:
    """``vtkPoints`` holding a copy of ``points`` with their dtype."""
    vp = vtkPoints()
    vp.SetData(numpy_to_vtk(np.ascontiguousarray(points), deep=1))
    return vp


def triangle_cells(tri: np.ndarray) -> vtkCellArray:
    """``vtkCellArray`` of triangles from an ``(m, 3)`` index array."""
    tri = np.ascontiguousarray(tri, dtype=np.int64)
    cells = vtkCellArray()
    offsets = np.arange(0, 3 * len(tri) + 1, 3, dtype=np.int64)
    cells.SetData(numpy_to_vtk(offsets, deep=1), numpy_to_vtk(tri.ravel(), deep=1))
    return cells


def point_arrays(dataset) -> dict[str, np.ndarray]:
    """Every named point array of a VTK dataset as a numpy copy."""
    pd = dataset.GetPointData()
    out = {}
    for i in range(pd.GetNumberOfArrays()):
        arr = pd.GetAbstractArray(i)
        name = arr.GetName()
        if not name or arr.IsA("vtkDataArray") == 0:
            continue
        out[name] = np.array(vtk_to_numpy(arr), copy=True)
    return out


def pop_normals(arrays: dict) -> np.ndarray | None:
    """Take the ``Normals`` point array out of ``arrays`` if it has 3 components.

    Any other ``Normals`` array stays among the passthrough arrays.
    """
    normals = arrays.pop(NORMALS, None)
    if normals is not None and (normals.ndim != 2 or normals.shape[1] != 3):
        arrays[NORMALS] = normals
        return None
    return normals


def points_of(dataset) -> np.ndarray:
    """The points of a ``vtkPointSet`` as an (n, 3) numpy copy (float64)."""
    if dataset is None or not dataset.IsA("vtkPointSet"):
        kind = "None" if dataset is None else dataset.GetClassName()
        raise TypeError(f"expected a vtkPointSet (points with coordinates), got {kind}")
    vp = dataset.GetPoints()
    if vp is None or vp.GetNumberOfPoints() == 0:
        return np.empty((0, 3), np.float64)
    return np.array(vtk_to_numpy(vp.GetData()), dtype=np.float64, copy=True).reshape(-1, 3)


def _triangle_polydata(points, triangles, normals, point_data) -> vtkPolyData:
    """Points, triangles as polys, the passthrough point arrays and ``Normals``."""
    out = vtkPolyData()
    out.SetPoints(numpy_points(points))
    out.SetPolys(triangle_cells(triangles))
    pd = out.GetPointData()
    for name, arr in point_data.items():
        if name in RESERVED:
            continue
        pd.AddArray(_to_vtk_array(arr, name))
    pd.SetNormals(_to_vtk_array(normals, NORMALS))
    return out


def fancloud_to_vtk(fc: FanCloud) -> vtkPolyData:
    """The fan cloud as ``vtkPolyData``: points, distinct triangles, arrays.

    The fan cloud of a triangle mesh also gets the field array
    ``unreferenced_dropped`` (from its ``info``, see :func:`add_unreferenced_field`).
    """
    out = _triangle_polydata(fc.points, fc.triangles(), fc.normals, fc.point_data)
    pd = out.GetPointData()
    pd.AddArray(_to_vtk_array(fc.open.astype(np.uint8), FAN_OPEN))
    pd.AddArray(_to_vtk_array(fc.rotated.astype(np.uint8), FAN_ROTATED))
    fd = out.GetFieldData()
    fd.AddArray(_to_vtk_array(fc.offsets.astype(np.int64), FAN_OFFSETS))
    fd.AddArray(_to_vtk_array(fc.ring.astype(np.int64), FAN_RING))
    add_unreferenced_field(out, fc.info.get(UNREFERENCED_DROPPED))
    return out


def add_unreferenced_field(dataset, dropped: int | None) -> None:
    """The one-value int64 field array ``unreferenced_dropped``: how many vertices of a
    triangle mesh input no triangle used and were dropped (0 with ``keep_unreferenced``;
    ``None``, the input was no mesh: no array). The value is ``info["unreferenced_dropped"]``
    of the input's fan cloud."""
    if dropped is not None:
        dataset.GetFieldData().AddArray(
            _to_vtk_array(np.array([dropped], np.int64), UNREFERENCED_DROPPED))


def front_to_vtk(front) -> vtkPolyData:
    """A view-dependent front (``core.vdfc.Front``) as ``vtkPolyData``.

    Points, distinct triangles, ``Normals`` and the point arrays ``node_id``,
    ``level``, ``error`` (and the colours).
    """
    return _triangle_polydata(front.points, front.triangles, front.normals, front.point_data)


def is_fancloud(dataset) -> bool:
    """True if the dataset carries the fan cloud arrays (``fan_offsets``, ``fan_ring``)."""
    fd = dataset.GetFieldData()
    return bool(fd.GetArray(FAN_OFFSETS) is not None and fd.GetArray(FAN_RING) is not None)


def fancloud_from_vtk(dataset) -> FanCloud:
    """Fan cloud from ``vtkPolyData`` made by :func:`fancloud_to_vtk`.

    Raises ``ValueError`` naming the missing or inconsistent array.
    """
    points = points_of(dataset)
    n = len(points)
    fd = dataset.GetFieldData()
    missing = [name for name in (FAN_OFFSETS, FAN_RING) if fd.GetArray(name) is None]
    arrays = point_arrays(dataset)
    missing += [name for name in (NORMALS, FAN_OPEN) if name not in arrays]
    if missing:
        raise ValueError(
            f"not a fan cloud: the dataset has no {', '.join(missing)} array(s); "
            "build one with build_fans / FanCloudFilter / dataset.fancloud.fans()"
        )
    offsets = np.array(vtk_to_numpy(fd.GetArray(FAN_OFFSETS)), dtype=np.int64, copy=True)
    ring = np.array(vtk_to_numpy(fd.GetArray(FAN_RING)), dtype=np.int64, copy=True)
    normals = np.asarray(arrays.pop(NORMALS), dtype=np.float64)
    if normals.shape != (n, 3):
        raise ValueError(f"{NORMALS} point array must have shape ({n}, 3), got {normals.shape}")
    flags = {}
    for name in (FAN_OPEN, FAN_ROTATED):
        arr = arrays.pop(name, None)
        if arr is None:  # fan_rotated is optional (all False)
            arr = np.zeros(n, np.uint8)
        if arr.shape != (n,):
            raise ValueError(f"{name} point array must have shape ({n},), got {arr.shape}")
        flags[name] = arr.astype(bool)
    open_, rotated = flags[FAN_OPEN], flags[FAN_ROTATED]
    return FanCloud(points, offsets, ring, normals, open_, rotated, arrays)


class _ErrorCatcher:
    """Collects the messages of VTK ErrorEvents raised by an object.

    ``CallDataType`` must be an attribute of the observer itself (not of its
    ``__call__``) for VTK to pass the message text.
    """

    CallDataType = "string0"

    def __init__(self, *objects):
        self.messages: list[str] = []
        for obj in objects:
            obj.AddObserver(vtkCommand.ErrorEvent, self)

    def __call__(self, caller, event, calldata=None):
        self.messages.append(clean_vtk_message(calldata) if calldata else event)


def clean_vtk_message(message: str) -> str:
    """The first line of a VTK error that says something, without file/line and addresses."""
    lines = [ln.strip() for ln in str(message).splitlines() if ln.strip()]
    lines = [ln for ln in lines if not re.match(r"^(ERROR|Warning|WARNING): In ", ln)]
    text = lines[0] if lines else str(message).strip()
    return re.sub(r"\s*\(0x[0-9a-fA-F]+\)", "", text)


@contextmanager
def _quiet_vtk():
    """Hold back VTK's global error output (stderr) while the caller raises its own error."""
    from vtkmodules.vtkCommonCore import vtkLogger, vtkOutputWindow, vtkStringOutputWindow

    previous_window = vtkOutputWindow.GetInstance()
    previous_verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    capture = vtkStringOutputWindow()
    vtkOutputWindow.SetInstance(capture)
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    try:
        yield capture
    finally:
        vtkLogger.SetStderrVerbosity(vtkLogger.ConvertToVerbosity(previous_verbosity))
        vtkOutputWindow.SetInstance(previous_window)


def _first_errors(catcher: _ErrorCatcher, capture) -> list[str]:
    """Error messages of the observed objects, then those only the output window saw."""
    window = [
        clean_vtk_message(chunk)
        for chunk in re.split(r"\n(?=ERROR: In )", capture.GetOutput() or "")
        if chunk.startswith("ERROR")
    ]
    return list(dict.fromkeys(catcher.messages + window))


def write_vtp(polydata, path) -> None:
    """Write ``vtkPolyData`` to an XML ``.vtp`` file (binary, appended).

    Raises ``OSError`` naming the path and the reason.
    """
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"could not write {path}: no such directory {folder}")
    if os.path.isdir(path):
        raise IsADirectoryError(f"could not write {path}: it is a directory")
    writer = vtkXMLPolyDataWriter()
    errors = _ErrorCatcher(writer, writer.GetExecutive())
    writer.SetFileName(path)
    writer.SetInputData(polydata)
    with _quiet_vtk() as capture:
        ok = writer.Write()
    messages = _first_errors(errors, capture)
    if ok != 1 or messages:
        raise OSError(f"could not write {path}: {'; '.join(messages) or 'VTK error'}")


def read_vtp(path) -> vtkPolyData:
    """Read an XML ``.vtp`` file; ``OSError``/``ValueError`` naming the problem."""
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"no such file: {path}")
    reader = vtkXMLPolyDataReader()
    errors = _ErrorCatcher(reader, reader.GetExecutive())
    reader.SetFileName(path)
    with _quiet_vtk() as capture:
        reader.Update()
    messages = _first_errors(errors, capture)
    if messages:
        raise ValueError(f"could not read {path}: {messages[0]}")
    out = vtkPolyData()
    out.ShallowCopy(reader.GetOutput())
    return out


#: prefix of the field arrays that carry a mesh's statistics (one value each)
MESH_STATS_PREFIX = "mesh_"


def mesh_to_vtk(mesh: TriangleMesh) -> vtkPolyData:
    """A triangle mesh as ``vtkPolyData``: all points, the triangles, point arrays, stats.

    Every point of the fan cloud stays (point arrays pass through one to
    one); ``Normals`` are the fan cloud's normals. The statistics are field
    arrays ``mesh_<name>`` with one value each (``mesh_final``,
    ``mesh_boundary_edges``, ``mesh_holes``, ...).
    """
    out = _triangle_polydata(mesh.points, mesh.triangles, mesh.normals, mesh.point_data)
    fd = out.GetFieldData()
    for key, value in mesh.stats.items():
        if isinstance(value, bool | int | float | np.integer | np.floating):
            dtype = np.float64 if isinstance(value, float | np.floating) else np.int64
            fd.AddArray(_to_vtk_array(np.array([value], dtype), MESH_STATS_PREFIX + key))
    return out


#: mesh file formats ``write_mesh`` knows, by extension
MESH_FORMATS = (".vtp", ".ply", ".obj", ".stl", ".vtk")


def write_mesh(polydata, path) -> None:
    """Write a triangle mesh by extension: .vtp, .ply, .obj, .stl or .vtk (legacy).

    A ``.ply`` keeps the normals (as float32) and a uint8 RGB(A) colour array
    (the first of ``RGB``, ``RGBA``, ``Colors``, ...) as red/green/blue(/alpha).

    Raises ``ValueError`` for another extension and ``OSError`` naming the
    path and the reason when writing fails.
    """
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext == ".vtp":
        write_vtp(polydata, path)
        return
    if ext not in MESH_FORMATS:
        raise ValueError(f"cannot write {path}: the mesh format must be one of {MESH_FORMATS}")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"could not write {path}: no such directory {folder}")
    if ext == ".ply":
        from vtkmodules.vtkIOPLY import vtkPLYWriter as Writer
    elif ext == ".obj":
        from vtkmodules.vtkIOGeometry import vtkOBJWriter as Writer
    elif ext == ".stl":
        from vtkmodules.vtkIOGeometry import vtkSTLWriter as Writer
    else:
        from vtkmodules.vtkIOLegacy import vtkPolyDataWriter as Writer
    writer = Writer()
    errors = _ErrorCatcher(writer, writer.GetExecutive())
    writer.SetFileName(path)
    if ext in (".ply", ".stl", ".vtk"):
        writer.SetFileTypeToBinary()
    if ext == ".ply":
        polydata = _ply_ready(polydata, writer)
    writer.SetInputData(polydata)
    with _quiet_vtk() as capture:
        ok = writer.Write()
    messages = _first_errors(errors, capture)
    if ok != 1 or messages:
        raise OSError(f"could not write {path}: {'; '.join(messages) or 'VTK error'}")


def _ply_ready(polydata, writer):
    """What ``vtkPLYWriter`` needs to keep the normals and the colours.

    It writes float32 normals only (it drops float64 ones with a warning),
    and colours only when told the array's name: a shallow copy with float32
    ``Normals``; the first uint8 RGB(A) array of ``COLOR_NAMES`` is set as
    the colours (with alpha for four components).
    """
    out = vtkPolyData()
    out.ShallowCopy(polydata)
    pd = out.GetPointData()
    normals = pd.GetNormals()
    if normals is not None and normals.GetDataType() != VTK_FLOAT:
        pd.SetNormals(_to_vtk_array(vtk_to_numpy(normals).astype(np.float32),
                                    normals.GetName() or NORMALS))
    for name in COLOR_NAMES:
        arr = pd.GetArray(name)
        if (arr is not None and arr.GetDataType() == VTK_UNSIGNED_CHAR
                and arr.GetNumberOfComponents() in (3, 4)):
            writer.SetArrayName(name)
            writer.SetEnableAlpha(arr.GetNumberOfComponents() == 4)
            break
    return out


# -- the three kinds of input of the entropy and reduction filters ------------------

#: field array (a string) saying which kind of input a filter took
INPUT_KIND = "fancloud_input"
KIND_FANS, KIND_MESH, KIND_POINTS = "fan cloud", "triangle mesh", "point set"


def triangles_of(dataset) -> np.ndarray | None:
    """The dataset's surface cells as ``(m, 3)`` triangles, or ``None`` if it has none.

    Polygons and triangle strips of a ``vtkPolyData`` are triangulated
    (``vtkTriangleFilter``), and so are the 2-d cells of a
    ``vtkUnstructuredGrid`` (triangles, quads, polygons, pixels, strips:
    :func:`fancloud_vtk.io.grid_triangles`); vertices, lines and volume cells
    are not surface cells.
    """
    if dataset is not None and dataset.IsA("vtkUnstructuredGrid"):
        from fancloud_vtk.io import grid_triangles

        tri = grid_triangles(dataset)
        return tri if len(tri) else None
    if dataset is None or not dataset.IsA("vtkPolyData"):
        return None
    if dataset.GetNumberOfPolys() == 0 and dataset.GetNumberOfStrips() == 0:
        return None
    polys = dataset.GetPolys()
    if dataset.GetNumberOfStrips() == 0 and polys.IsHomogeneous() == 3:
        conn = vtk_to_numpy(polys.GetConnectivityArray())
        return np.array(conn, dtype=np.int64).reshape(-1, 3)
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter

    surface = vtkPolyData()
    surface.SetPoints(dataset.GetPoints())
    surface.SetPolys(polys)
    surface.SetStrips(dataset.GetStrips())
    tri = vtkTriangleFilter()
    tri.PassVertsOff()
    tri.PassLinesOff()
    tri.SetInputData(surface)
    tri.Update()
    out = tri.GetOutput().GetPolys()
    if out.GetNumberOfCells() == 0:
        return None
    conn = vtk_to_numpy(out.GetConnectivityArray())
    return np.array(conn, dtype=np.int64).reshape(-1, 3)


def input_fan_cloud(dataset, fan_values: dict, progress=None, *,
                    keep_unreferenced: bool = False) -> tuple[FanCloud, str]:
    """The fan cloud of a filter's input and which kind of input it was.

    * a fan cloud (``fan_offsets``/``fan_ring`` arrays): its rings as they are;
    * a triangle mesh (polys or strips of a polydata, 2-d cells of an
      unstructured grid: :func:`triangles_of`): every vertex's one-ring is its
      fan, its ``Normals`` point array (if any) the normals; the vertices that
      no triangle uses are dropped unless ``keep_unreferenced``;
    * any other point set: the fans are built with ``fan_values``.

    See :func:`fan_cloud_of_arrays`, which the ``fancloud`` command calls on
    the arrays of a file.
    """
    if is_fancloud(dataset):
        return fancloud_from_vtk(dataset), KIND_FANS
    return fan_cloud_of_arrays(*_input_arrays(dataset), fan_values, progress,
                               keep_unreferenced=keep_unreferenced)


def point_fans(dataset, fan_values: dict, progress=None, *,
               keep_unreferenced: bool = False) -> FanCloud:
    """The fans built from the points of a filter's input (``FanCloudFilter``,
    ``FanCloudMeshFilter``), with ``fan_values``: :func:`fans_of_points`."""
    return fans_of_points(*_input_arrays(dataset), fan_values, progress,
                          keep_unreferenced=keep_unreferenced)


def fan_cloud_of_arrays(points, normals, point_data, triangles, fan_values: dict,
                        progress=None, *, keep_unreferenced: bool = False
                        ) -> tuple[FanCloud, str]:
    """The fan cloud of an input that is not a fan cloud, from its arrays, and its kind.

    With ``triangles`` (a triangle mesh) every vertex's one-ring is its fan
    (:func:`~fancloud_vtk.core.entropy.fan_cloud_of_mesh`: the vertices that
    no triangle uses are dropped unless ``keep_unreferenced``; ``normals``
    with a zero vector count as unknown); without, the fans of the points are
    built with ``fan_values``.
    """
    from fancloud_vtk.core.entropy import fan_cloud_of_mesh

    if triangles is None:
        return _built_fans(points, normals, point_data, fan_values, progress), KIND_POINTS
    if normals is not None and not (np.linalg.norm(normals, axis=1) > 0).all():
        normals = None  # "unknown" zero normals: take the mesh's own
    return fan_cloud_of_mesh(points, triangles, normals=normals, point_data=point_data,
                             keep_unreferenced=keep_unreferenced), KIND_MESH


def fans_of_points(points, normals, point_data, triangles, fan_values: dict, progress=None,
                   *, keep_unreferenced: bool = False) -> FanCloud:
    """The fans built from an input's points with ``fan_values``, its cells unused but for
    one thing: of a triangle mesh (``triangles`` given) only the vertices of its triangles
    are taken, unless ``keep_unreferenced``
    (:func:`~fancloud_vtk.core.entropy.drop_unreferenced`: a warning, the point array
    ``original_id``, the count in ``info["unreferenced_dropped"]``)."""
    from fancloud_vtk.core.entropy import drop_unreferenced

    if triangles is None:
        return _built_fans(points, normals, point_data, fan_values, progress)
    mesh = drop_unreferenced(points, triangles, normals, point_data,
                             keep_unreferenced=keep_unreferenced, stacklevel=2)
    fc = _built_fans(mesh.points, mesh.normals, mesh.point_data, fan_values, progress)
    fc.info[UNREFERENCED_DROPPED] = mesh.dropped
    return fc


def _input_arrays(dataset):
    """(points, normals or None, the other point arrays, triangles or None) of an input."""
    points = points_of(dataset)
    arrays = point_arrays(dataset)
    normals = pop_normals(arrays)
    return points, normals, arrays, triangles_of(dataset)


def _built_fans(points, normals, arrays, fan_values, progress) -> FanCloud:
    from fancloud_vtk.core.fans import build_fans

    return build_fans(points, normals=normals, point_data=arrays, progress=progress,
                      **fan_values)


def mark_input(dataset, kind: str, source: FanCloud) -> None:
    """The field arrays of a filter's output that tell its input: ``fancloud_input`` (the
    kind, :func:`input_fan_cloud`) and, for a triangle mesh, ``unreferenced_dropped``
    (:func:`add_unreferenced_field`; ``source`` is the input's fan cloud)."""
    add_string_field(dataset, INPUT_KIND, kind)
    add_unreferenced_field(dataset, source.info.get(UNREFERENCED_DROPPED))


def add_string_field(dataset, name: str, value: str) -> None:
    """A one-value string field array (e.g. ``fancloud_input``)."""
    from vtkmodules.vtkCommonCore import vtkStringArray

    arr = vtkStringArray()
    arr.SetName(name)
    arr.InsertNextValue(value)
    dataset.GetFieldData().AddArray(arr)


def string_field(dataset, name: str) -> str | None:
    """The first value of a string field array, or ``None``."""
    arr = dataset.GetFieldData().GetAbstractArray(name)
    if arr is None or not arr.IsA("vtkStringArray") or arr.GetNumberOfValues() == 0:
        return None
    return arr.GetValue(0)


# -- the hierarchy of a reduction as vtkPolyData ----------------------------------

HIERARCHY_PREFIX = "hierarchy_"


def hierarchy_to_vtk(h) -> vtkPolyData:
    """The finest fan cloud of a :class:`~fancloud_vtk.Hierarchy` plus field arrays
    ``hierarchy_<name>`` (removal order, rings, detail, log, coarse level), the
    weights and the method."""
    out = fancloud_to_vtk(h.source)
    fd = out.GetFieldData()
    for name, arr in h._arrays().items():
        arr = np.asarray(arr)
        if arr.dtype == np.bool_:
            arr = arr.astype(np.uint8)
        fd.AddArray(_to_vtk_array(arr.reshape(len(arr), -1) if arr.ndim > 1 else arr,
                                  HIERARCHY_PREFIX + name))
    fd.AddArray(_to_vtk_array(np.array(h.weights, np.float64), HIERARCHY_PREFIX + "weights"))
    add_string_field(out, HIERARCHY_PREFIX + "method", h.method)
    return out


def hierarchy_from_vtk(dataset):
    """A :class:`~fancloud_vtk.Hierarchy` from ``vtkPolyData`` made by :func:`hierarchy_to_vtk`."""
    from fancloud_vtk.core.reduction import _HIER_ARRAYS, Hierarchy

    fd = dataset.GetFieldData()
    arrays = {}
    for name in (*_HIER_ARRAYS, "weights"):
        arr = fd.GetArray(HIERARCHY_PREFIX + name)
        if arr is None:
            raise ValueError(f"not a saved hierarchy: no field array {HIERARCHY_PREFIX}{name}")
        arrays[name] = np.array(vtk_to_numpy(arr), copy=True)
    method = string_field(dataset, HIERARCHY_PREFIX + "method")
    if method is None:
        raise ValueError(f"not a saved hierarchy: no field array {HIERARCHY_PREFIX}method")
    for name in ("rem_open", "ent_open", "coarse_open"):
        arrays[name] = arrays[name].astype(bool)
    weights = tuple(arrays.pop("weights").tolist())
    fc = fancloud_from_vtk(dataset)
    fc.point_data.pop(ORIGINAL_ID_NAME, None)
    return Hierarchy.from_arrays(fc, arrays, weights, method)


ORIGINAL_ID_NAME = "original_id"
