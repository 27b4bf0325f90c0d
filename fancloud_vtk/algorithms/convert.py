"""Conversions between the core's numpy arrays and VTK data objects.

Imports numpy and ``vtkmodules`` only (never pyvista), so that ParaView's
VTK 9.2 can load it.

The fan cloud as ``vtkPolyData`` (public contract, see docs/data_model.md):

* points: the cloud's points (float64);
* polys: the fan cloud's distinct triangles;
* point arrays ``Normals`` (float64, unit; also the active normals),
  ``fan_open`` (uint8, 1 where the fan is open), ``fan_rotated`` (uint8, 1
  where the fan was built in the rotated plane), and every passthrough array;
* field arrays ``fan_offsets`` and ``fan_ring`` (int64, CSR rings).
"""

from __future__ import annotations

import os

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkCommand, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

from fancloud_vtk.core.model import FanCloud

NORMALS = "Normals"
FAN_OPEN = "fan_open"
FAN_ROTATED = "fan_rotated"
FAN_OFFSETS = "fan_offsets"
FAN_RING = "fan_ring"
RESERVED = (NORMALS, FAN_OPEN, FAN_ROTATED)


def _to_vtk_array(arr: np.ndarray, name: str):
    arr = np.ascontiguousarray(arr)
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8)
    out = numpy_to_vtk(arr, deep=1)
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


def points_of(dataset) -> np.ndarray:
    """The points of a ``vtkPointSet`` as an (n, 3) numpy copy (float64)."""
    if dataset is None or not dataset.IsA("vtkPointSet"):
        kind = "None" if dataset is None else dataset.GetClassName()
        raise TypeError(f"expected a vtkPointSet (points with coordinates), got {kind}")
    vp = dataset.GetPoints()
    if vp is None or vp.GetNumberOfPoints() == 0:
        return np.empty((0, 3), np.float64)
    return np.array(vtk_to_numpy(vp.GetData()), dtype=np.float64, copy=True).reshape(-1, 3)


def fancloud_to_vtk(fc: FanCloud) -> vtkPolyData:
    """The fan cloud as ``vtkPolyData``: points, distinct triangles, arrays."""
    out = vtkPolyData()
    out.SetPoints(numpy_points(fc.points))
    out.SetPolys(triangle_cells(fc.triangles()))
    pd = out.GetPointData()
    for name, arr in fc.point_data.items():
        if name in RESERVED:
            continue
        pd.AddArray(_to_vtk_array(arr, name))
    pd.SetNormals(_to_vtk_array(fc.normals, NORMALS))
    pd.AddArray(_to_vtk_array(fc.open.astype(np.uint8), FAN_OPEN))
    pd.AddArray(_to_vtk_array(fc.rotated.astype(np.uint8), FAN_ROTATED))
    fd = out.GetFieldData()
    fd.AddArray(_to_vtk_array(fc.offsets.astype(np.int64), FAN_OFFSETS))
    fd.AddArray(_to_vtk_array(fc.ring.astype(np.int64), FAN_RING))
    return out


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
    normals = np.asarray(arrays.pop(NORMALS), dtype=np.float64).reshape(n, 3)
    open_ = arrays.pop(FAN_OPEN).astype(bool).reshape(n)
    rotated = arrays.pop(FAN_ROTATED, np.zeros(n, np.uint8)).astype(bool).reshape(n)
    return FanCloud(points, offsets, ring, normals, open_, rotated, arrays)


class _ErrorCatcher:
    """Collects the messages of VTK ErrorEvents raised by an object."""

    def __init__(self, obj):
        self.messages = []
        obj.AddObserver(vtkCommand.ErrorEvent, self)

    def __call__(self, caller, event, calldata=None):
        self.messages.append(str(calldata) if calldata else event)

    __call__.CallDataType = "string0"


def write_vtp(polydata, path) -> None:
    """Write ``vtkPolyData`` to an XML ``.vtp`` file (binary, appended)."""
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    writer = vtkXMLPolyDataWriter()
    errors = _ErrorCatcher(writer)
    writer.SetFileName(os.fspath(path))
    writer.SetInputData(polydata)
    if writer.Write() != 1 or errors.messages:
        raise OSError(f"could not write {path}: {'; '.join(errors.messages) or 'VTK error'}")


def read_vtp(path) -> vtkPolyData:
    """Read an XML ``.vtp`` file; ``OSError``/``ValueError`` naming the problem."""
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"no such file: {path}")
    reader = vtkXMLPolyDataReader()
    errors = _ErrorCatcher(reader)
    errors_exec = _ErrorCatcher(reader.GetExecutive())
    reader.SetFileName(path)
    reader.Update()
    messages = errors.messages + errors_exec.messages
    if messages:
        raise ValueError(f"could not read {path}: {messages[0].strip()}")
    out = vtkPolyData()
    out.ShallowCopy(reader.GetOutput())
    return out
