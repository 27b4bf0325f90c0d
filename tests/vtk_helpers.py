"""Plain-VTK helpers for the tests of the VTK layer, which also run where there is no
PyVista (ParaView 5.11's VTK 9.2: ``.ci/paraview``)."""

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData


def points_poly(points) -> vtkPolyData:
    """A vtkPolyData with the points and nothing else."""
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    poly = vtkPolyData()
    poly.SetPoints(pts)
    return poly


def read_any(path):
    """A mesh file read with VTK's reader for its extension."""
    from vtkmodules.vtkIOGeometry import vtkOBJReader, vtkSTLReader
    from vtkmodules.vtkIOLegacy import vtkPolyDataReader
    from vtkmodules.vtkIOPLY import vtkPLYReader
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    ext = str(path).rsplit(".", 1)[-1].lower()
    reader = {"vtp": vtkXMLPolyDataReader, "ply": vtkPLYReader, "obj": vtkOBJReader,
              "stl": vtkSTLReader, "vtk": vtkPolyDataReader}[ext]()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def write_vtp(poly, path) -> None:
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    w = vtkXMLPolyDataWriter()
    w.SetFileName(str(path))
    w.SetInputData(poly)
    if not w.Write():
        raise OSError(f"could not write {path}")


def point_array(poly, name) -> np.ndarray:
    return vtk_to_numpy(poly.GetPointData().GetArray(name))


def field_array(poly, name) -> np.ndarray:
    return vtk_to_numpy(poly.GetFieldData().GetAbstractArray(name))


def field_names(poly) -> list[str]:
    fd = poly.GetFieldData()
    return [fd.GetArrayName(i) for i in range(fd.GetNumberOfArrays())]


def triangles(poly) -> np.ndarray:
    """The polygons of an all-triangle polydata as ``(m, 3)``; raises if one is not."""
    polys = poly.GetPolys()
    off = vtk_to_numpy(polys.GetOffsetsArray())
    if not (np.diff(off) == 3).all():
        raise AssertionError("not all cells are triangles")
    return vtk_to_numpy(polys.GetConnectivityArray()).reshape(-1, 3)
