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

This is the one place where the core's objects meet VTK (the core never
imports VTK): :func:`to_vtk` and :func:`from_vtk` convert a ``FanCloud``,
``Hierarchy``, ``TriangleMesh`` or view-dependent ``Front``, :func:`save` and
:func:`load` write and read their files (exported as ``fancloud_vtk.to_vtk``,
``fancloud_vtk.from_vtk``, ``fancloud_vtk.save``, ``fancloud_vtk.load``).
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
from fancloud_vtk.core.hierarchy import HIERARCHY_ARRAYS, ORIGINAL_ID, Hierarchy
from fancloud_vtk.core.mesh import TriangleMesh
from fancloud_vtk.core.model import COLOR_NAMES, FanCloud
from fancloud_vtk.core.validation import FileReadError, readable_file
from fancloud_vtk.core.vdfc import Front
from fancloud_vtk.core.verbs import Result, Source

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


def write_vtp(polydata, path, compressor: str = "zlib") -> None:
    """Write ``vtkPolyData`` to an XML ``.vtp`` file (binary, appended).

    ``compressor``: ``"zlib"`` (default, at level 1: VTK's default level 5 took 3 times as
    long for a file 3% smaller, on a 500,000-point fan cloud), ``"lz4"`` (faster still, a
    file about 1.5 times larger; what the tiles of ``write_tiled_fans`` use) or ``"none"``.
    Raises ``OSError`` naming the path and the reason.
    """
    if compressor not in ("zlib", "lz4", "none"):
        raise ValueError(f"compressor must be 'zlib', 'lz4' or 'none', got {compressor!r}")
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
    if compressor == "zlib":
        writer.SetCompressorTypeToZLib()
        writer.SetCompressionLevel(1)
    elif compressor == "lz4":
        writer.SetCompressorTypeToLZ4()
    else:
        writer.SetCompressorTypeToNone()
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


def source_of(dataset) -> Source:
    """A filter's input as the verbs' :class:`~fancloud_vtk.core.verbs.Source`.

    * a fan cloud (``fan_offsets``/``fan_ring`` arrays): its fan cloud;
    * a triangle mesh (polys or strips of a polydata, 2-d cells of an
      unstructured grid: :func:`triangles_of`): its points, ``Normals`` point
      array, other point arrays and triangles;
    * any other point set: its points and point arrays.
    """
    if is_fancloud(dataset):
        return Source(fancloud=fancloud_from_vtk(dataset))
    arrays = point_arrays(dataset)
    normals = pop_normals(arrays)
    return Source(points=points_of(dataset), normals=normals, point_data=arrays,
                  triangles=triangles_of(dataset))


def source_to_vtk(source: Source) -> vtkPolyData:
    """The points, triangles (if any), ``Normals`` (if any) and point arrays of a verb's
    input of arrays as ``vtkPolyData`` (the mesh a file holds, for the ``fancloud``
    command)."""
    out = vtkPolyData()
    out.SetPoints(numpy_points(source.points))
    if source.triangles is not None:
        out.SetPolys(triangle_cells(source.triangles))
    pd = out.GetPointData()
    for name, arr in source.point_data.items():
        pd.AddArray(_to_vtk_array(np.asarray(arr), name))
    if source.normals is not None:
        pd.SetNormals(_to_vtk_array(np.asarray(source.normals), NORMALS))
    return out


def result_to_vtk(result: Result, mark: bool = True) -> vtkPolyData:
    """A verb's output as ``vtkPolyData``: its mesh if it has one, else its fan cloud,
    with the field arrays that tell the input (:func:`mark_input`; without ``mark`` only
    ``unreferenced_dropped``)."""
    out = mesh_to_vtk(result.mesh) if result.mesh is not None else \
        fancloud_to_vtk(result.fancloud)
    if mark:
        mark_input(out, result.kind, result.source)
    else:
        add_unreferenced_field(out, result.unreferenced_dropped)
    return out


def mark_input(dataset, kind: str, source: FanCloud) -> None:
    """The field arrays of a filter's output that tell its input: ``fancloud_input`` (the
    kind, :attr:`~fancloud_vtk.core.verbs.Result.kind`) and, for a triangle mesh,
    ``unreferenced_dropped`` (:func:`add_unreferenced_field`; ``source`` is the input's fan
    cloud)."""
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
    for name, arr in h.arrays().items():
        arr = np.asarray(arr)
        if arr.dtype == np.bool_:
            arr = arr.astype(np.uint8)
        fd.AddArray(_to_vtk_array(arr.reshape(len(arr), -1) if arr.ndim > 1 else arr,
                                  HIERARCHY_PREFIX + name))
    fd.AddArray(_to_vtk_array(np.array(h.weights, np.float64), HIERARCHY_PREFIX + "weights"))
    add_string_field(out, HIERARCHY_PREFIX + "method", h.method)
    return out


def hierarchy_from_vtk(dataset) -> Hierarchy:
    """A :class:`~fancloud_vtk.Hierarchy` from ``vtkPolyData`` made by :func:`hierarchy_to_vtk`."""
    fd = dataset.GetFieldData()
    arrays = {}
    for name in (*HIERARCHY_ARRAYS, "weights"):
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
    fc.point_data.pop(ORIGINAL_ID, None)
    return Hierarchy.from_arrays(fc, arrays, weights, method)


def is_hierarchy(dataset) -> bool:
    """True if the dataset carries the marker :func:`hierarchy_to_vtk` writes (the field
    array ``hierarchy_method``, or any other ``hierarchy_<name>`` array)."""
    fd = dataset.GetFieldData()
    return any((fd.GetArrayName(i) or "").startswith(HIERARCHY_PREFIX)
               for i in range(fd.GetNumberOfArrays()))


# -- the objects of the core as VTK data and files -----------------------------------


def to_vtk(obj) -> vtkPolyData:
    """A core object as a new ``vtkPolyData``.

    Parameters
    ----------
    obj : FanCloud, Hierarchy, TriangleMesh or Front
        * a :class:`~fancloud_vtk.FanCloud`: points, its distinct fan
          triangles, ``Normals``, ``fan_open``, ``fan_rotated``, the point
          arrays and the field arrays ``fan_offsets`` / ``fan_ring`` (the
          contract of docs/data_model.md; :func:`fancloud_to_vtk`);
        * a :class:`~fancloud_vtk.Hierarchy`: its finest fan cloud so, plus
          the field arrays ``hierarchy_<name>`` (:func:`hierarchy_to_vtk`);
        * a view-dependent front (``ViewDependentFanCloud.front_arrays``):
          its points, triangles, ``Normals`` and point arrays
          (:func:`front_to_vtk`);
        * a :class:`~fancloud_vtk.TriangleMesh`: all its points, its
          triangles, ``Normals``, point arrays and its statistics as field
          arrays ``mesh_<name>`` (:func:`mesh_to_vtk`).

    Returns
    -------
    vtkPolyData
        A deep copy: changing it does not change ``obj``. For PyVista:
        ``pyvista.wrap(to_vtk(obj))``.

    Raises
    ------
    TypeError
        ``obj`` is none of these, or has a point array VTK cannot store
        (complex numbers, strings, Python objects).

    See Also
    --------
    from_vtk : the way back (fan clouds and hierarchies).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, fan_cloud_to_mesh, to_vtk
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(500, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> fc = build_fans(p)
    >>> poly = to_vtk(fc)
    >>> poly.GetNumberOfPoints(), poly.GetFieldData().GetArray("fan_ring") is not None
    (500, True)
    >>> mesh = fan_cloud_to_mesh(fc)
    >>> to_vtk(mesh).GetNumberOfCells() == mesh.n_triangles
    True
    """
    if isinstance(obj, FanCloud):
        return fancloud_to_vtk(obj)
    if isinstance(obj, Hierarchy):
        return hierarchy_to_vtk(obj)
    if isinstance(obj, Front):
        return front_to_vtk(obj)
    if isinstance(obj, TriangleMesh):
        return mesh_to_vtk(obj)
    raise TypeError(f"to_vtk converts a FanCloud, Hierarchy, TriangleMesh or Front, got "
                    f"{type(obj).__name__}")


def from_vtk(dataset) -> FanCloud | Hierarchy:
    """The fan cloud (or hierarchy) that a VTK dataset carries.

    Parameters
    ----------
    dataset : vtkPolyData or pyvista.PolyData
        A dataset made by :func:`to_vtk` (or by a fan cloud filter, or read
        from a ``.vtp`` file they wrote): the fan cloud arrays of
        docs/data_model.md, and for a hierarchy the field arrays
        ``hierarchy_<name>``.

    Returns
    -------
    FanCloud or Hierarchy
        A :class:`~fancloud_vtk.Hierarchy` when the dataset carries the
        hierarchy arrays (:func:`is_hierarchy`), else a
        :class:`~fancloud_vtk.FanCloud`; its arrays are copies.

    Raises
    ------
    TypeError
        ``dataset`` is not a VTK point set.
    ValueError
        It is not a fan cloud (naming the missing arrays), or its arrays are
        inconsistent (naming the array; ``inconsistent hierarchy: ...`` for
        a hierarchy).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, from_vtk, to_vtk
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(500, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> fc = build_fans(p)
    >>> back = from_vtk(to_vtk(fc))
    >>> type(back).__name__, bool(np.array_equal(back.ring, fc.ring))
    ('FanCloud', True)
    """
    if dataset is None or not hasattr(dataset, "IsA") or not dataset.IsA("vtkPointSet"):
        kind = type(dataset).__name__ if not hasattr(dataset, "GetClassName") \
            else dataset.GetClassName()
        raise TypeError(f"from_vtk needs a vtkPolyData (or pyvista.PolyData), got {kind}")
    if is_hierarchy(dataset):
        return hierarchy_from_vtk(dataset)
    return fancloud_from_vtk(dataset)


def _path_of(path) -> str:
    path = os.fspath(path)
    return os.fsdecode(path) if isinstance(path, bytes) else path


def save(obj, path) -> None:
    """Write a fan cloud, a hierarchy or a triangle mesh to a file.

    Parameters
    ----------
    obj : FanCloud, Hierarchy or TriangleMesh
        * a :class:`~fancloud_vtk.FanCloud`: ``.vtp`` (binary XML; every
          array of :func:`to_vtk`, so :func:`load` gives identical arrays
          back);
        * a :class:`~fancloud_vtk.Hierarchy`: ``.vtp`` (its finest fan
          cloud plus the field arrays ``hierarchy_<name>``) or ``.npz``
          (numpy, no pickle: :meth:`Hierarchy.save
          <fancloud_vtk.Hierarchy.save>`, no VTK needed);
        * a :class:`~fancloud_vtk.TriangleMesh` (a view-dependent front
          too): any format of :func:`write_mesh` (``.vtp``, ``.ply``,
          ``.obj``, ``.stl``, ``.vtk``).
    path : str or os.PathLike
        The file; its extension chooses the format.

    Raises
    ------
    TypeError
        ``obj`` is none of these (a ``ViewDependentFanCloud`` saves itself:
        ``vd.save(path)``), or has a point array VTK cannot store.
    ValueError
        An extension the object cannot be written as (a fan cloud needs
        ``.vtp``: ``fan_cloud_to_mesh`` makes a mesh of it for the other
        formats).
    OSError
        Writing failed: a ``FileNotFoundError`` for a missing directory,
        an ``IsADirectoryError`` when ``path`` is one, naming the path.

    See Also
    --------
    load : the way back (fan clouds and hierarchies).

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, load, save
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(500, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> fc = build_fans(p)
    >>> path = os.path.join(tempfile.mkdtemp(), "sphere_fans.vtp")
    >>> save(fc, path)
    >>> bool(np.array_equal(load(path).ring, fc.ring))
    True
    """
    path = _path_of(path)
    ext = os.path.splitext(path)[1].lower()
    if isinstance(obj, Hierarchy):
        if ext == ".npz":
            folder = os.path.dirname(os.path.abspath(path))
            if not os.path.isdir(folder):
                raise FileNotFoundError(f"could not write {path}: no such directory {folder}")
            obj.save(path)
        elif ext == ".vtp":
            write_vtp(hierarchy_to_vtk(obj), path)
        else:
            raise ValueError(f"a hierarchy is saved as .vtp or .npz, got {path!r}")
    elif isinstance(obj, FanCloud):
        if ext != ".vtp":
            raise ValueError(f"a fan cloud is saved as .vtp (only it keeps the fans), got "
                             f"{path!r}; for a mesh file save fan_cloud_to_mesh(fancloud)")
        write_vtp(fancloud_to_vtk(obj), path)
    elif isinstance(obj, TriangleMesh):
        write_mesh(to_vtk(obj), path)
    else:
        hint = " (it saves itself: .save(path), .npz)" if hasattr(obj, "front_arrays") else ""
        raise TypeError(f"save writes a FanCloud, Hierarchy or TriangleMesh, got "
                        f"{type(obj).__name__}{hint}")


def load(path) -> FanCloud | Hierarchy:
    """Read a fan cloud or a hierarchy written by :func:`save`.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.vtp`` file (a fan cloud, or a hierarchy when it carries the
        ``hierarchy_<name>`` arrays: :func:`from_vtk`) or a ``.npz`` file (a
        hierarchy: :meth:`Hierarchy.load <fancloud_vtk.Hierarchy.load>`).

    Returns
    -------
    FanCloud or Hierarchy

    Raises
    ------
    ValueError
        Another extension (point clouds and meshes of other formats:
        :func:`fancloud_vtk.io.read_point_cloud`).
    fancloud_vtk.io.FileReadError
        (a ``ValueError``) naming the path: the file is missing (then also a
        ``FileNotFoundError``), a directory or empty; it holds no fan cloud
        (``not a fan cloud: ...``, naming the missing arrays) or its arrays
        are inconsistent; for ``.npz``, every problem of
        :meth:`Hierarchy.load <fancloud_vtk.Hierarchy.load>`.
    ValueError
        A damaged ``.vtp`` (``could not read <path>: <VTK's reason>``, as
        :func:`read_vtp` raises).

    See Also
    --------
    save : writes these files.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, hierarchy, load, save
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> h = hierarchy(build_fans(p), 300)
    >>> path = os.path.join(tempfile.mkdtemp(), "sphere_lod.vtp")
    >>> save(h, path)
    >>> back = load(path)
    >>> type(back).__name__, bool(np.array_equal(back.level(700).points, h.level(700).points))
    ('Hierarchy', True)
    """
    path = _path_of(path)
    lower = path.lower()
    if lower.endswith(".npz"):
        return Hierarchy.load(path)
    if not lower.endswith(".vtp"):
        raise ValueError(f"load reads a fan cloud or a hierarchy from .vtp (a hierarchy also "
                         f"from .npz), got {path!r}; point clouds and meshes: "
                         "fancloud_vtk.io.read_point_cloud")
    data = read_vtp(readable_file(path))
    try:
        return from_vtk(data)
    except ValueError as exc:
        raise FileReadError(path, str(exc)) from exc
