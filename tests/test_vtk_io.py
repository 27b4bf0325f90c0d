"""The VTK conversion and the files of the core's objects: ``fancloud_vtk.to_vtk``,
``from_vtk``, ``save`` and ``load`` (fancloud_vtk.algorithms.convert), round trips and
errors. The core itself has no VTK method left. Plain VTK only (``vtk_helpers``): these
tests also run on ParaView 5.11's VTK 9.2, which has no PyVista (``.ci/paraview``)."""

import numpy as np
import pytest
from conftest import fingerprint
from shapes import sphere
from vtk_helpers import (
    field_array,
    field_names,
    point_array,
    points_poly,
    read_any,
    triangles,
    write_vtp,
)
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkPolyData

import fancloud_vtk
from fancloud_vtk import (
    FanCloud,
    Hierarchy,
    TriangleMesh,
    ViewDependentFanCloud,
    build_fans,
    fan_cloud_to_mesh,
    from_vtk,
    hierarchy,
    load,
    save,
    terrain_fan_cloud,
    to_vtk,
)
from fancloud_vtk.algorithms import convert
from fancloud_vtk.core.vdfc import Front
from fancloud_vtk.io import FileReadError

N = 1500
CAMERA = ((3.0, -4.0, 3.0), (3.0, 3.0, 0.0), (0, 0, 1), 45.0)


@pytest.fixture(scope="module")
def fans():
    p = sphere(N, seed=7)
    rng = np.random.default_rng(3)
    data = {"RGB": rng.integers(0, 256, (N, 3)).astype(np.uint8),
            "label": rng.integers(-3, 3, N).astype(np.int16),
            "weight": rng.random(N)}
    return build_fans(p, point_data=data)


@pytest.fixture(scope="module")
def hier(fans):
    return hierarchy(fans, 300)


@pytest.fixture(scope="module")
def mesh(fans):
    return fan_cloud_to_mesh(fans)


@pytest.fixture(scope="module")
def front():
    z = np.add.outer(np.sin(np.linspace(0, 6, 60)), np.cos(np.linspace(0, 6, 60)))
    vd = ViewDependentFanCloud.build(terrain_fan_cloud(z, spacing=0.1))
    return vd, vd.front_arrays(CAMERA, e_max=0.05)


def _fc_arrays(fc: FanCloud):
    return [fc.points, fc.offsets, fc.ring, fc.normals, fc.open, fc.rotated,
            *(fc.point_data[k] for k in sorted(fc.point_data))]


def same_fancloud(a: FanCloud, b: FanCloud) -> bool:
    return sorted(a.point_data) == sorted(b.point_data) and \
        fingerprint(*_fc_arrays(a)) == fingerprint(*_fc_arrays(b))


def same_levels(a: Hierarchy, b: Hierarchy, levels) -> None:
    assert (a.n_points, a.n_min, a.weights, a.method) == (b.n_points, b.n_min, b.weights,
                                                         b.method)
    for m in levels:
        assert same_fancloud(a.level(m), b.level(m)), m


# -- the package exports them lazily ------------------------------------------------------


def test_exported_from_the_package():
    for name in ("to_vtk", "from_vtk", "save", "load"):
        assert getattr(fancloud_vtk, name) is getattr(convert, name)
        assert name in fancloud_vtk.__all__ and name in dir(fancloud_vtk)
        assert getattr(convert, name).__doc__.count("Examples") == 1


def test_the_core_objects_have_no_vtk_methods():
    for name in ("to_vtk", "from_vtk", "save", "load"):
        assert not hasattr(FanCloud, name), name
    assert not hasattr(Front, "to_vtk") and not hasattr(TriangleMesh, "to_vtk")
    assert not hasattr(ViewDependentFanCloud, "front")  # front_arrays + to_vtk


# -- fan clouds ---------------------------------------------------------------------------


def test_fan_cloud_round_trips_losslessly(fans, tmp_path):
    poly = to_vtk(fans)
    assert isinstance(poly, vtkPolyData) and poly.GetNumberOfPoints() == N
    assert same_fancloud(fans, from_vtk(poly))
    for name in ("fans.vtp", "FANS.VTP"):
        path = tmp_path / name
        save(fans, path)
        back = load(path)
        assert isinstance(back, FanCloud) and same_fancloud(fans, back)
        assert same_fancloud(fans, load(str(path)))
        assert same_fancloud(fans, from_vtk(read_any(path)))


def test_a_pyvista_dataset_converts_too(fans):
    pv = pytest.importorskip("pyvista", reason="PyVista is not there (ParaView's VTK 9.2)")
    assert same_fancloud(fans, from_vtk(pv.wrap(to_vtk(fans))))


# -- hierarchies --------------------------------------------------------------------------


def test_hierarchy_converts_to_vtk_and_back(hier):
    poly = to_vtk(hier)
    assert convert.is_hierarchy(poly) and convert.is_fancloud(poly)
    back = from_vtk(poly)
    assert isinstance(back, Hierarchy)
    same_levels(hier, back, (300, 800, N))
    assert not convert.is_hierarchy(to_vtk(hier.level(800)))
    # the marker alone decides: its finest fan cloud is still a fan cloud
    assert isinstance(from_vtk(to_vtk(hier.source)), FanCloud)


@pytest.mark.parametrize("ext", [".npz", ".vtp"])
def test_hierarchy_round_trips_through_files(hier, tmp_path, ext):
    path = tmp_path / f"lod{ext}"
    save(hier, path)
    back = load(path)
    assert isinstance(back, Hierarchy)
    same_levels(hier, back, (300, 700, N))
    if ext == ".npz":  # the core's own file, the same arrays
        same_levels(hier, Hierarchy.load(path), (300, N))


def test_a_hierarchy_vtp_with_a_partial_marker_says_what_is_missing(hier):
    poly = to_vtk(hier)
    poly.GetFieldData().RemoveArray("hierarchy_detail")
    with pytest.raises(ValueError, match="not a saved hierarchy: no field array "
                                         "hierarchy_detail"):
        from_vtk(poly)


# -- meshes and fronts --------------------------------------------------------------------


def test_mesh_to_vtk_keeps_points_triangles_arrays_and_stats(mesh, fans):
    poly = to_vtk(mesh)
    assert poly.GetNumberOfPoints() == N
    np.testing.assert_array_equal(triangles(poly), mesh.triangles)
    np.testing.assert_array_equal(point_array(poly, "Normals"), mesh.normals)
    np.testing.assert_array_equal(point_array(poly, "RGB"), fans.point_data["RGB"])
    assert int(field_array(poly, "mesh_holes")[0]) == mesh.stats["holes"]


@pytest.mark.parametrize("ext", [".vtp", ".ply", ".obj", ".stl", ".vtk"])
def test_mesh_saves_in_every_mesh_format(mesh, tmp_path, ext):
    path = tmp_path / f"mesh{ext}"
    save(mesh, path)
    back = read_any(path)
    assert back.GetNumberOfCells() == mesh.n_triangles
    if ext != ".stl":  # STL repeats the corners of every triangle
        assert back.GetNumberOfPoints() == N


def test_a_mesh_file_is_not_a_fan_cloud(mesh, tmp_path):
    path = tmp_path / "mesh.vtp"
    save(mesh, path)
    with pytest.raises(FileReadError, match="not a fan cloud") as info:
        load(path)
    assert str(path) in str(info.value)


def test_front_to_vtk_and_save(front, tmp_path):
    vd, fr = front
    poly = to_vtk(fr)
    assert poly.GetNumberOfPoints() == fr.n_points
    assert poly.GetNumberOfCells() == len(fr.triangles)
    for name in ("node_id", "level", "error"):
        np.testing.assert_array_equal(point_array(poly, name), fr.point_data[name])
    # a front is a TriangleMesh but converts as a front: no mesh statistics
    assert not [n for n in field_names(poly) if n.startswith("mesh_")]
    path = tmp_path / "front.vtp"
    save(fr, path)
    got = vtk_to_numpy(convert.read_vtp(path).GetPointData().GetArray("node_id"))
    np.testing.assert_array_equal(got, fr.point_data["node_id"])


# -- errors -------------------------------------------------------------------------------


@pytest.mark.parametrize("obj", [None, object(), np.zeros((3, 3)), "fans.vtp"])
def test_to_vtk_refuses_other_objects(obj):
    with pytest.raises(TypeError, match="to_vtk converts a FanCloud, Hierarchy, "
                                        "TriangleMesh or Front"):
        to_vtk(obj)


def test_to_vtk_of_a_forest_is_a_type_error(front):
    with pytest.raises(TypeError, match="got ViewDependentFanCloud"):
        to_vtk(front[0])


@pytest.mark.parametrize("obj", [None, np.zeros((4, 3)), {"points": 1}])
def test_from_vtk_refuses_what_is_no_vtk_dataset(obj):
    with pytest.raises(TypeError, match="from_vtk needs a vtkPolyData"):
        from_vtk(obj)


def test_from_vtk_of_a_plain_cloud_names_the_missing_arrays(fans):
    with pytest.raises(ValueError, match="not a fan cloud: the dataset has no fan_offsets"):
        from_vtk(points_poly(fans.points))


def test_save_errors(fans, hier, mesh, front, tmp_path):
    with pytest.raises(ValueError, match=r"a fan cloud is saved as \.vtp"):
        save(fans, tmp_path / "fans.ply")
    with pytest.raises(ValueError, match=r"a hierarchy is saved as \.vtp or \.npz"):
        save(hier, tmp_path / "lod.ply")
    with pytest.raises(ValueError, match="the mesh format must be one of"):
        save(mesh, tmp_path / "mesh.xyz")
    with pytest.raises(TypeError, match=r"got ViewDependentFanCloud \(it saves itself"):
        save(front[0], tmp_path / "forest.npz")
    with pytest.raises(TypeError, match="save writes a FanCloud, Hierarchy or TriangleMesh"):
        save(np.zeros((3, 3)), tmp_path / "a.vtp")
    for obj, name in ((fans, "x.vtp"), (hier, "x.npz"), (hier, "x.vtp"), (mesh, "x.ply")):
        with pytest.raises(FileNotFoundError, match="no such directory"):
            save(obj, tmp_path / "missing" / name)
    (tmp_path / "folder.vtp").mkdir()
    with pytest.raises(IsADirectoryError, match="it is a directory"):
        save(fans, tmp_path / "folder.vtp")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder.vtp"]  # nothing written


def test_load_errors(fans, tmp_path):
    with pytest.raises(ValueError, match=r"load reads a fan cloud or a hierarchy from \.vtp"):
        load(tmp_path / "cloud.ply")
    missing = tmp_path / "absent.vtp"
    with pytest.raises(FileNotFoundError, match="no such file") as info:
        load(missing)
    assert isinstance(info.value, FileReadError) and str(missing) in str(info.value)
    empty = tmp_path / "empty.vtp"
    empty.write_bytes(b"")
    with pytest.raises(FileReadError, match=r"the file is empty \(0 bytes\)"):
        load(empty)
    (tmp_path / "folder.vtp").mkdir()
    with pytest.raises(FileReadError, match="is a directory"):
        load(tmp_path / "folder.vtp")
    good = tmp_path / "fans.vtp"
    save(fans, good)
    damaged = tmp_path / "damaged.vtp"
    damaged.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(ValueError, match=r"could not read .*damaged\.vtp: "):
        load(damaged)
    plain = tmp_path / "plain.vtp"
    write_vtp(points_poly(fans.points), plain)
    with pytest.raises(FileReadError, match="not a fan cloud"):
        load(plain)
    with pytest.raises(FileReadError, match="not a saved hierarchy"):
        np.savez(tmp_path / "other.npz", a=np.arange(3))
        load(tmp_path / "other.npz")


# -- the Examples sections run (tests/test_examples.py lists the modules it runs) --------


@pytest.mark.parametrize("name", ["fancloud_vtk.algorithms.convert", "fancloud_vtk.core.hierarchy"])
def test_docstring_examples(name):
    import doctest
    import importlib

    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} docstring example(s) of {name} failed"
    assert result.attempted > 0, f"{name} has no runnable example"
