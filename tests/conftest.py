import hashlib
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

#: GNU OpenMP (numba's "omp" threading layer) keeps its idle threads spinning after each
#: parallel region. Two test workers, each with a thread per core, and the commands and
#: LocalCluster workers they start then spin against each other's threads: a barrier
#: waits for a thread the other process holds, at every round of the reduction. Sleeping
#: idle threads made tests/test_reduction.py, test_retriangulation.py and
#: test_refinement.py on 2 workers take 42 s instead of 452 s on a 2-core machine. Set
#: before numba loads its threading layer; the processes the tests start inherit it.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

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


def _kernels_cached() -> bool:
    """Whether numba's cache holds the fan kernels (a sentinel for all of them)."""
    import glob

    root = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "fancloud_vtk")
    return bool(glob.glob(os.path.join(root, "**", "_fan_kernels.fans_from_grid-*.nbi"),
                          recursive=True))


def pytest_sessionstart(session):
    """With xdist workers and a cold numba cache (a fresh clone, CI), compile the kernels
    first, once (tests/warm_kernels.py): left to the tests, the workers and the processes
    they start compile the same kernels at once. The xdist controller only (its own hook
    starts the workers after this one)."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    if os.environ.get("FANCLOUD_WARM") == "0" or _kernels_cached():
        return
    from warm_kernels import warm

    seconds, parts = warm()
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:  # (pytest's own time starts after this)
        reporter.write_line(f"numba kernels compiled first, in {seconds:.0f} s ({parts}; "
                            "tests/warm_kernels.py)")
