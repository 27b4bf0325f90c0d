"""The PyVista accessor ``dataset.fancloud``: new outputs, kept arrays, clear errors."""

import inspect
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import pyvista as pv
from conftest import dataset_fingerprint
from shapes import sphere

from fancloud_vtk import DuplicatePointsWarning, FanCloud, FanCloudInputError, build_fans

N = 2000


@pytest.fixture
def cloud():
    """A fresh sphere cloud with uint8 colours and int labels."""
    p = sphere(N, seed=21)
    c = pv.PolyData(p)
    c.point_data["RGB"] = (np.arange(3 * N) % 256).astype(np.uint8).reshape(N, 3)
    c.point_data["label"] = (np.arange(N) % 5).astype(np.int64)
    return c


def test_accessor_loads_in_a_fresh_process_without_importing_the_package():
    code = textwrap.dedent(
        """
        import sys
        import numpy as np
        import pyvista as pv
        assert "fancloud_vtk" not in sys.modules
        rng = np.random.default_rng(0)
        points = rng.normal(size=(2000, 3))
        points /= np.linalg.norm(points, axis=1)[:, None]
        c = pv.PolyData(points)
        f = c.fancloud.fans(k=6)
        assert type(c.fancloud).__module__ == "fancloud_vtk.accessor"
        assert isinstance(f, pv.PolyData) and f.n_points == 2000 and f.n_cells > 4000
        assert f.is_all_triangles
        assert f.field_data["fan_offsets"].dtype == np.int64
        assert f.fancloud.is_fan_cloud and not c.fancloud.is_fan_cloud
        print("ok")
        """
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"


def test_fans_returns_a_new_polydata_and_leaves_the_input_alone(cloud):
    before = dataset_fingerprint(cloud)
    rgb = cloud.point_data["RGB"].copy()
    out = cloud.fancloud.fans(k=6)
    assert isinstance(out, pv.PolyData)
    assert out is not cloud
    assert dataset_fingerprint(cloud) == before
    assert cloud.n_cells == N  # still the vertex cells of a point cloud
    assert "Normals" not in cloud.point_data and not cloud.field_data.keys()
    assert out.n_points == N and out.is_all_triangles and out.n_cells > 2 * N
    np.testing.assert_array_equal(out.points, cloud.points)
    # input point arrays kept, with their dtypes
    assert out.point_data["RGB"].dtype == np.uint8
    np.testing.assert_array_equal(out.point_data["RGB"], rgb)
    assert out.point_data["label"].dtype == np.int64
    np.testing.assert_array_equal(out.point_data["label"], cloud.point_data["label"])
    np.testing.assert_allclose(np.linalg.norm(out.point_data["Normals"], axis=1), 1.0)
    # the output does not share the input's buffers
    out.point_data["RGB"][:] = 0
    out.points[:] = 0
    assert dataset_fingerprint(cloud) == before


def test_fans_equal_the_core_result(cloud):
    out = cloud.fancloud.fans(k=8, max_angle=80.0)
    fc = out.fancloud.to_fancloud()
    assert isinstance(fc, FanCloud)
    core = build_fans(np.asarray(cloud.points), k=8, max_angle=80.0)
    for name in ("offsets", "ring", "normals", "open", "rotated"):
        np.testing.assert_array_equal(getattr(fc, name), getattr(core, name), err_msg=name)
    np.testing.assert_array_equal(out.regular_faces, core.triangles())
    assert sorted(fc.point_data) == ["RGB", "label"]


@pytest.mark.parametrize(
    "make",
    [
        lambda p: pv.PointSet(p),
        lambda p: pv.PolyData(p).cast_to_unstructured_grid(),
        lambda p: pv.wrap(p),
    ],
    ids=["PointSet", "UnstructuredGrid", "wrap"],
)
def test_any_point_set_works(make):
    p = sphere(N, seed=22)
    ds = make(p)
    ds.point_data["value"] = np.arange(N, dtype=np.float32)
    before = dataset_fingerprint(ds)
    out = ds.fancloud.fans()
    assert isinstance(out, pv.PolyData) and out.n_points == N and out.is_all_triangles
    np.testing.assert_array_equal(out.point_data["value"], np.arange(N, dtype=np.float32))
    assert dataset_fingerprint(ds) == before


def test_a_mesh_uses_its_points_only():
    mesh = pv.Sphere(theta_resolution=40, phi_resolution=40)
    before = dataset_fingerprint(mesh)
    out = mesh.fancloud.fans()
    assert out.n_points == mesh.n_points
    # the mesh's own normals orient the fans
    assert np.all(np.einsum("ij,ij->i", out.point_data["Normals"], mesh.point_data["Normals"]) > 0)
    assert dataset_fingerprint(mesh) == before


def test_image_data_is_taken_by_its_points():
    image = pv.ImageData(dimensions=(30, 30, 1), spacing=(0.1, 0.1, 1.0))
    image.point_data["v"] = np.arange(900.0)
    before = dataset_fingerprint(image)
    out = image.fancloud.fans()
    assert out.n_points == 900 and out.n_cells > 0
    np.testing.assert_allclose(np.abs(out.point_data["Normals"][:, 2]), 1.0)
    np.testing.assert_array_equal(out.point_data["v"], np.arange(900.0))
    # the grid's border points have open fans
    xy = np.asarray(out.points)[:, :2]
    border = np.isclose(xy, 0.0).any(axis=1) | np.isclose(xy, 2.9).any(axis=1)
    assert out.point_data["fan_open"][border].all()
    assert dataset_fingerprint(image) == before


def test_progress_bar(cloud, capsys):
    pytest.importorskip("tqdm")
    out = cloud.fancloud.fans(progress_bar=True)
    assert out.n_cells > 2 * N
    assert "Building fans" in capsys.readouterr().err


def test_signature_and_docstring():
    sig = inspect.signature(pv.PolyData().fancloud.fans)
    params = list(sig.parameters.values())
    assert params[-1].name == "progress_bar" and params[-1].default is False
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params)
    doc = pv.PolyData().fancloud.fans.__doc__
    assert "k : int, default: 6" in doc
    assert "{params}" not in doc


def test_unknown_keyword_is_a_type_error(cloud):
    before = dataset_fingerprint(cloud)
    with pytest.raises(TypeError, match=r"unknown parameter\(s\) \['neighbours'\]; known:"):
        cloud.fancloud.fans(neighbours=6)
    with pytest.raises(TypeError, match="positional"):
        cloud.fancloud.fans(6)
    assert dataset_fingerprint(cloud) == before


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"k": 2}, ValueError, "k must be between 3 and 64, got 2"),
        ({"k": 65}, ValueError, "k must be between 3 and 64, got 65"),
        ({"max_angle": 180}, ValueError, "max_angle must be between 1.0 and 179.0"),
        ({"max_replacements": -1}, ValueError, "max_replacements must be between 0 and 1000"),
        ({"rule": "fastest"}, ValueError, r"rule must be one of \['cover', 'paper'\]"),
        ({"k": 6.5}, TypeError, "k must be an integer"),
        ({"k": "6"}, TypeError, "k must be a number"),
        ({"orient": "yes"}, TypeError, "orient must be True or False"),
    ],
)
def test_bad_parameter_values(cloud, kwargs, error, match):
    before = dataset_fingerprint(cloud)
    with pytest.raises(error, match=match):
        cloud.fancloud.fans(**kwargs)
    assert dataset_fingerprint(cloud) == before


def test_core_errors_surface_with_their_message(cloud):
    cloud.points[123] = [np.nan, 0.0, 1.0]
    before = dataset_fingerprint(cloud)
    with pytest.raises(FanCloudInputError) as info:
        cloud.fancloud.fans()
    assert "NaN or infinite coordinates at 1 point(s), first at index 123" in str(info.value)
    assert dataset_fingerprint(cloud) == before
    with pytest.raises(FanCloudInputError, match="first at index 123"):
        cloud.fancloud.fans(progress_bar=True)
    few = pv.PolyData(sphere(6))
    with pytest.raises(FanCloudInputError, match=r"k=6 needs at least k \+ 1 = 7"):
        few.fancloud.fans()
    line = pv.PolyData(np.outer(np.linspace(0, 1, 50), [1.0, 2.0, 3.0]))
    with pytest.raises(FanCloudInputError, match="collinear"):
        line.fancloud.fans()
    with pytest.raises(FanCloudInputError, match=r"needs at least .* got 0"):
        pv.PolyData().fancloud.fans()


def test_duplicates_are_merged_with_an_original_id_map(cloud):
    p = np.asarray(cloud.points)
    doubled = pv.PolyData(np.vstack([p, p[[4, 9, 9]]]))
    doubled.point_data["label"] = np.r_[np.arange(N), [-1, -2, -3]]
    before = dataset_fingerprint(doubled)
    with pytest.warns(DuplicatePointsWarning, match="3 duplicate point"):
        out = doubled.fancloud.fans()
    assert out.n_points == N
    ids = out.point_data["original_id"]
    np.testing.assert_array_equal(out.points, np.asarray(doubled.points)[ids])
    np.testing.assert_array_equal(out.point_data["label"], doubled.point_data["label"][ids])
    assert dataset_fingerprint(doubled) == before


def test_to_fancloud_and_is_fan_cloud(cloud):
    assert not cloud.fancloud.is_fan_cloud
    with pytest.raises(ValueError, match="not a fan cloud"):
        cloud.fancloud.to_fancloud()
    out = cloud.fancloud.fans()
    assert out.fancloud.is_fan_cloud
    fc = out.fancloud.to_fancloud()
    assert fc.n_points == N
    np.testing.assert_array_equal(fc.point_data["RGB"], cloud.point_data["RGB"])
    # a copy: changing the fan cloud leaves the dataset alone
    before = dataset_fingerprint(out)
    fc.ring[:] = 0
    assert dataset_fingerprint(out) == before


def test_fans_of_a_fan_cloud_are_the_same_fans(cloud):
    out = cloud.fancloud.fans()
    again = out.fancloud.fans()
    np.testing.assert_array_equal(again.regular_faces, out.regular_faces)
    np.testing.assert_array_equal(again.point_data["Normals"], out.point_data["Normals"])
