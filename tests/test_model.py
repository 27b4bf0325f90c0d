"""The FanCloud data model: the public VTK contract, round trips, validation."""

import numpy as np
import pytest
import pyvista as pv
from shapes import cube_surface
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

from fancloud_vtk import FanCloud, build_fans, from_vtk, load, save, to_vtk

N = 2000


@pytest.fixture(scope="module")
def cube_fc():
    """A small cube cloud: open and rotated fans, colours, labels and other passthroughs."""
    p = cube_surface(N, seed=4)
    rng = np.random.default_rng(1)
    data = {
        "RGB": rng.integers(0, 256, (N, 3)).astype(np.uint8),
        "label": rng.integers(-5, 5, N).astype(np.int32),
        "id64": np.arange(N, dtype=np.int64) * 3_000_000_000,
        "weight": rng.random(N).astype(np.float32),
        "velocity": rng.normal(size=(N, 3)),
    }
    fc = build_fans(p, point_data=data)
    assert fc.n_open > 0 and fc.rotated.any(), "the round trips must cover both flags"
    return fc


def assert_same_fancloud(a: FanCloud, b: FanCloud) -> None:
    """Identical arrays, dtypes and shapes (values compared exactly)."""
    for name in ("points", "offsets", "ring", "normals", "open", "rotated"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype, name
        assert x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)
    assert sorted(a.point_data) == sorted(b.point_data)
    for name, x in a.point_data.items():
        y = b.point_data[name]
        assert (x.dtype, x.shape) == (y.dtype, y.shape), name
        np.testing.assert_array_equal(x, y, err_msg=name)


# -- the public array contract --------------------------------------------------------


def test_to_vtk_public_array_names_and_dtypes(cube_fc):
    out = to_vtk(cube_fc)
    assert isinstance(out, vtkPolyData)
    pd, fd = out.GetPointData(), out.GetFieldData()
    assert pd.GetNormals().GetName() == "Normals"  # also the active normals
    normals = vtk_to_numpy(pd.GetArray("Normals"))
    assert normals.dtype == np.float64 and normals.shape == (N, 3)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    for name in ("fan_open", "fan_rotated"):
        flags = vtk_to_numpy(pd.GetArray(name))
        assert flags.dtype == np.uint8 and flags.shape == (N,), name
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("fan_open")), cube_fc.open)
    offsets = vtk_to_numpy(fd.GetArray("fan_offsets"))
    ring = vtk_to_numpy(fd.GetArray("fan_ring"))
    assert offsets.dtype == np.int64 and offsets.shape == (N + 1,)
    assert ring.dtype == np.int64 and ring.shape == (offsets[-1],)
    rgb = vtk_to_numpy(pd.GetArray("RGB"))
    assert rgb.dtype == np.uint8 and rgb.shape == (N, 3)
    assert vtk_to_numpy(pd.GetArray("label")).dtype == np.int32
    assert vtk_to_numpy(out.GetPoints().GetData()).dtype == np.float64


def test_pyvista_view_of_the_contract(cube_fc):
    mesh = pv.wrap(to_vtk(cube_fc))
    assert isinstance(mesh, pv.PolyData)
    assert mesh.n_points == N
    assert mesh.point_data["Normals"].dtype == np.float64
    assert mesh.point_data["fan_open"].dtype == np.uint8
    assert mesh.field_data["fan_offsets"].dtype == np.int64
    assert mesh.field_data["fan_ring"].dtype == np.int64
    assert mesh.fancloud.is_fan_cloud


def test_polys_are_the_distinct_fan_triangles(cube_fc):
    mesh = pv.wrap(to_vtk(cube_fc))
    assert mesh.is_all_triangles
    faces = mesh.regular_faces
    np.testing.assert_array_equal(faces, cube_fc.triangles())
    keys = {tuple(t) for t in np.sort(faces, axis=1).tolist()}
    assert len(keys) == len(faces), "no triangle twice, whatever its orientation"
    fan_keys = {tuple(t) for t in np.sort(cube_fc.fan_triangles(), axis=1).tolist()}
    assert keys == fan_keys
    assert len(cube_fc.fan_triangles()) > len(faces)  # neighbouring fans share triangles


def test_fan_triangle_counts_and_summary(cube_fc):
    sizes = cube_fc.fan_sizes
    # a closed fan of m neighbours has m triangles, an open one m - 1
    assert len(cube_fc.fan_triangles()) == sizes.sum() - cube_fc.n_open
    s = cube_fc.summary()
    assert s["points"] == N
    assert s["fans_closed"] + s["fans_open"] == N
    assert s["fans_open"] == cube_fc.n_open
    assert s["fans_rotated"] == int(cube_fc.rotated.sum())
    assert s["distinct_triangles"] == len(cube_fc.triangles())
    assert s["distinct_triangles_per_point"] == pytest.approx(s["distinct_triangles"] / N)
    # an open fan's gap is between its last and first neighbour: no triangle there
    i = int(np.flatnonzero(cube_fc.open)[0])
    ring = cube_fc.neighbours(i)
    own = cube_fc.fan_triangles()[cube_fc.fan_triangles()[:, 0] == i]
    assert len(own) == len(ring) - 1
    assert not np.any((own[:, 1] == ring[-1]) & (own[:, 2] == ring[0]))


# -- round trips ------------------------------------------------------------------------


def test_round_trip_through_vtk_polydata(cube_fc):
    assert_same_fancloud(cube_fc, from_vtk(to_vtk(cube_fc)))


def test_round_trip_through_pyvista(cube_fc):
    mesh = pv.wrap(to_vtk(cube_fc))
    back = from_vtk(mesh)
    assert_same_fancloud(cube_fc, back)
    assert_same_fancloud(cube_fc, mesh.fancloud.to_fancloud())


def test_round_trip_through_vtp_file(cube_fc, tmp_path):
    path = tmp_path / "cube_fans.vtp"
    save(cube_fc, path)
    assert_same_fancloud(cube_fc, load(path))
    assert_same_fancloud(cube_fc, load(str(path)))
    # any VTK reader sees the same contract
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    assert_same_fancloud(cube_fc, from_vtk(reader.GetOutput()))
    assert_same_fancloud(cube_fc, from_vtk(pv.read(path)))


def test_round_trip_copies_the_arrays(cube_fc):
    poly = to_vtk(cube_fc)
    back = from_vtk(poly)
    vtk_to_numpy(poly.GetFieldData().GetArray("fan_ring"))[:] = 0
    vtk_to_numpy(poly.GetPointData().GetArray("RGB"))[:] = 0
    assert_same_fancloud(cube_fc, back)
    back.point_data["label"][:] = 99
    assert not np.any(cube_fc.point_data["label"] == 99)


def test_copy_is_deep(cube_fc):
    dup = cube_fc.copy()
    assert_same_fancloud(cube_fc, dup)
    dup.ring[:] = 0
    dup.point_data["RGB"][:] = 0
    assert cube_fc.ring.any() and cube_fc.point_data["RGB"].any()


def test_round_trip_of_arrays_vtk_cannot_hold_as_they_are(cube_fc):
    """bool -> uint8, float16 -> float32, big-endian -> native, (n, 3, 3) -> (n, 9)."""
    fc = cube_fc.copy()
    rng = np.random.default_rng(2)
    flags = rng.random(N) < 0.5
    half = rng.random(N).astype(np.float16)
    big = rng.random(N).astype(">f8")
    tensor = rng.normal(size=(N, 3, 3))
    fc.point_data.update(flags=flags, half=half, big=big, tensor=tensor)
    back = from_vtk(to_vtk(fc)).point_data
    assert back["flags"].dtype == np.uint8
    np.testing.assert_array_equal(back["flags"], flags)
    assert back["half"].dtype == np.float32
    np.testing.assert_array_equal(back["half"], half.astype(np.float32))
    assert back["big"].dtype == np.float64 and back["big"].dtype.isnative
    np.testing.assert_array_equal(back["big"], big)
    np.testing.assert_array_equal(back["tensor"], tensor.reshape(N, 9))


@pytest.mark.parametrize(
    "values", [np.zeros(N, complex), np.array(["a"] * N), np.array([None] * N, dtype=object)],
    ids=["complex", "str", "object"],
)
def test_point_array_vtk_cannot_store_is_a_clear_error(cube_fc, values):
    fc = cube_fc.copy()
    fc.point_data["odd"] = values
    with pytest.raises(TypeError, match="point array 'odd' has dtype"):
        to_vtk(fc)


def test_from_vtk_of_a_plain_cloud_names_the_missing_arrays(cube_fc):
    cloud = pv.PolyData(cube_fc.points)
    assert not cloud.fancloud.is_fan_cloud
    with pytest.raises(ValueError, match="fan_offsets, fan_ring, Normals, fan_open"):
        from_vtk(cloud)
    with pytest.raises(ValueError, match="not a fan cloud"):
        cloud.fancloud.to_fancloud()


@pytest.mark.parametrize(
    ("name", "values", "match"),
    [
        ("Normals", np.zeros((N, 2)), r"Normals point array must have shape \(2000, 3\)"),
        ("fan_open", np.zeros((N, 2), np.uint8), r"fan_open point array must have shape"),
        ("fan_rotated", np.zeros((N, 3), np.uint8), r"fan_rotated point array must have shape"),
    ],
)
def test_from_vtk_with_malformed_fan_arrays(cube_fc, name, values, match):
    mesh = pv.wrap(to_vtk(cube_fc))
    mesh.point_data[name] = values
    with pytest.raises(ValueError, match=match):
        from_vtk(mesh)


def test_from_vtk_with_inconsistent_ring_names_it(cube_fc):
    mesh = pv.wrap(to_vtk(cube_fc))
    ring = mesh.field_data["fan_ring"].copy()
    ring[7] = N + 5
    mesh.field_data["fan_ring"] = ring
    with pytest.raises(ValueError, match="fan_ring entry 7 is 2005, out of range for 2000"):
        from_vtk(mesh)


def test_save_and_load_errors_name_the_problem(cube_fc, tmp_path):
    with pytest.raises(FileNotFoundError, match="no such directory"):
        save(cube_fc, tmp_path / "missing" / "x.vtp")
    with pytest.raises(FileNotFoundError, match="no such file"):
        load(tmp_path / "absent.vtp")
    path = tmp_path / "fans.vtp"
    save(cube_fc, path)
    truncated = tmp_path / "truncated.vtp"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(ValueError, match="could not read .*truncated.vtp: ") as info:
        load(truncated)
    assert "ErrorEvent" not in str(info.value)
    garbage = tmp_path / "garbage.vtp"
    garbage.write_bytes(b"\x00\x01 definitely not XML " * 20)
    with pytest.raises(ValueError, match="could not read .*garbage.vtp"):
        load(garbage)
    plain = tmp_path / "plain.vtp"
    pv.PolyData(cube_fc.points).save(plain)
    with pytest.raises(ValueError, match="not a fan cloud"):
        load(plain)


# -- validation -----------------------------------------------------------------------


def _fields(fc: FanCloud) -> dict:
    return dict(
        points=fc.points.copy(), offsets=fc.offsets.copy(), ring=fc.ring.copy(),
        normals=fc.normals.copy(), open=fc.open.copy(), rotated=fc.rotated.copy(),
        point_data={"label": fc.point_data["label"].copy()},
    )


def _set(key, value_of):
    def change(f):
        f[key] = value_of(f[key])

    return change


def _set_item(key, index, value):
    def change(f):
        f[key][index] = value

    return change


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (_set_item("ring", 5, N), "fan_ring entry 5 is 2000, out of range for 2000 points"),
        (_set_item("ring", 3, -1), "fan_ring entry 3 is -1, out of range"),
        (_set("ring", lambda r: r.astype(np.int32)), "fan_ring must be int64, got int32"),
        (_set("ring", lambda r: r.astype(float)), "fan_ring must be int64, got float64"),
        (_set("ring", lambda r: r[:, None]), "fan_ring must be one-dimensional"),
        (_set("offsets", lambda o: o[:-1]),
         r"fan_offsets must have n \+ 1 = 2001 entries, got 2000"),
        (_set("offsets", lambda o: o.astype(np.int32)), "fan_offsets must be int64"),
        (_set_item("offsets", -1, 5), "fan_offsets must start at 0, never decrease and end at"),
        (_set_item("offsets", 0, 1), "fan_offsets must start at 0"),
        (_set_item("offsets", 10, 10_000), "fan_offsets must start at 0, never decrease"),
        (_set("offsets", list), "fan cloud fan_offsets must be a numpy array, got list"),
        (_set("points", lambda p: p[:, :2]), r"points must be an \(n, 3\) array"),
        (_set("points", lambda p: p.astype(np.float32)), "points must be float64"),
        (_set("points", lambda p: p.tolist()), "points must be a numpy array"),
        (_set("normals", lambda n: n[:-1]),
         r"Normals must be a float64 array of shape \(2000, 3\)"),
        (_set("normals", lambda n: n.astype(np.float32)), "Normals must be a float64 array"),
        (_set("open", lambda o: o.astype(np.uint8)), r"fan_open flags must be a bool array"),
        (_set("rotated", lambda r: r[:-1]), r"fan_rotated flags must be a bool array of shape"),
        (_set("point_data", lambda d: {"label": d["label"][:-1]}),
         r"point array 'label' has shape \(1999,\), expected 2000 rows"),
        (_set("point_data", lambda d: {"label": [1, 2]}), "point array 'label' has shape"),
    ],
)
def test_validate_names_the_bad_array(cube_fc, change, match):
    fields = _fields(cube_fc)
    FanCloud(**fields)  # the unchanged arrays are valid
    change(fields)
    with pytest.raises(ValueError, match=match):
        FanCloud(**fields)


def test_validate_after_changes_in_place(cube_fc):
    fc = cube_fc.copy()
    fc.validate()
    fc.ring[0] = -7
    with pytest.raises(ValueError, match="fan_ring entry 0 is -7"):
        fc.validate()


def test_empty_fan_cloud_is_valid_and_converts():
    fc = FanCloud(np.empty((0, 3)), np.zeros(1, np.int64), np.empty(0, np.int64),
                  np.empty((0, 3)), np.empty(0, bool))
    assert fc.n_points == 0 and len(fc.triangles()) == 0
    assert fc.summary()["distinct_triangles_per_point"] == 0.0
    assert_same_fancloud(fc, from_vtk(to_vtk(fc)))
