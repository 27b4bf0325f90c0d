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
    """Hash of a PyVista dataset's points and point/field arrays."""
    parts = [np.asarray(ds.points)]
    for name in sorted(ds.point_data.keys()):
        parts.append(np.asarray(ds.point_data[name]))
    for name in sorted(ds.field_data.keys()):
        parts.append(np.asarray(ds.field_data[name]))
    return fingerprint(*parts) + f"{ds.n_cells}"


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
