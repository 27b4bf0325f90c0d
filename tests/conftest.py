import hashlib
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

#: CI=true runs the quick variants of the scale tests
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def fingerprint(*arrays) -> str:
    """Hash of arrays (values, dtype, shape): compare before and after a call."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def dataset_fingerprint(ds) -> str:
    """Hash of a VTK dataset's points and point/field arrays (PyVista's datasets are VTK's:
    plain VTK calls, so that the VTK-layer tests run without PyVista too)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    parts = [vtk_to_numpy(ds.GetPoints().GetData())] if ds.GetPoints() is not None else []
    for data in (ds.GetPointData(), ds.GetFieldData()):
        arrays = {data.GetArrayName(i): data.GetAbstractArray(i)
                  for i in range(data.GetNumberOfArrays())}
        for name in sorted(arrays):
            a = arrays[name]
            parts.append(vtk_to_numpy(a) if hasattr(a, "GetNumberOfComponents")
                         and a.IsNumeric() else np.array(
                             [a.GetValue(j) for j in range(a.GetNumberOfValues())], str))
    return fingerprint(*parts) + f"{ds.GetNumberOfCells()}"


@pytest.fixture(scope="session")
def bunny():
    """The pymeshlab bunny: points, faces and the mesh's outward vertex normals."""
    from fancloud_vtk.data import bunny_path
    from fancloud_vtk.io import read_point_cloud

    src = read_point_cloud(bunny_path())
    p, f = src.points, src.faces
    tri_n = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    vn = np.zeros_like(p)
    for j in range(3):
        np.add.at(vn, f[:, j], tri_n)
    vn /= np.linalg.norm(vn, axis=1)[:, None]
    return p, f, vn


def pytest_collection_modifyitems(config, items):
    """With CI=true, the slow scale variants give way to their quick variants."""
    if not IN_CI:
        return
    skip = pytest.mark.skip(reason="slow scale variant: CI (CI=true) runs the quick variant")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
