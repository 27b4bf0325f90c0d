"""Entropy and reduction through the fronts: VTK filters, the accessor, the command."""

import numpy as np
import pytest
import pyvista as pv
from conftest import dataset_fingerprint
from shapes import sphere

from fancloud_vtk import Hierarchy, build_fans, reduce, save
from fancloud_vtk.algorithms import (
    FanCloudEntropyFilter,
    FanCloudReduceFilter,
    FanCloudSelectiveRefineFilter,
    fancloud_from_vtk,
    run,
)
from fancloud_vtk.cli import main


@pytest.fixture(scope="module")
def points():
    p = sphere(3000, seed=5)
    rgb = (np.abs(p) * 255).astype(np.uint8)
    return p, rgb


def _kinds(points):
    """The three kinds of input, as PyVista datasets."""
    p, rgb = points
    cloud = pv.PolyData(p)
    cloud["RGB"] = rgb
    cloud["label"] = np.arange(len(p))
    fans = cloud.fancloud.fans()
    mesh = fans.fancloud.mesh()  # every point kept, triangles as polys
    mesh.field_data.clear()
    return {"point set": cloud, "fan cloud": fans, "triangle mesh": mesh}


@pytest.mark.parametrize("kind", ["point set", "fan cloud", "triangle mesh"])
def test_reduce_takes_three_kinds_and_says_which(points, kind):
    data = _kinds(points)[kind]
    before = dataset_fingerprint(data)
    out = data.fancloud.reduce(n_points=700)
    assert dataset_fingerprint(data) == before, "input untouched"
    assert out is not data and out.n_points == 700
    assert out["fancloud_input"][0] == kind
    ids = out["original_id"]
    np.testing.assert_array_equal(out.points, data.points[ids])
    np.testing.assert_array_equal(out["RGB"], data["RGB"][ids])  # point arrays pass through
    np.testing.assert_array_equal(out["label"], data["label"][ids])
    assert out.fancloud.is_fan_cloud


def test_a_triangle_mesh_as_an_unstructured_grid_is_a_mesh(points, tmp_path):
    mesh = _kinds(points)["triangle mesh"]
    grid = mesh.cast_to_unstructured_grid()
    ref = mesh.fancloud.reduce(n_points=700)
    out = grid.fancloud.reduce(n_points=700)
    assert out["fancloud_input"][0] == "triangle mesh"
    np.testing.assert_array_equal(out["original_id"], ref["original_id"])
    assert grid.fancloud.entropy()["fancloud_input"][0] == "triangle mesh"
    # the same from a .vtu file through the command
    path = tmp_path / "mesh.vtu"
    grid.save(path)
    assert main(["reduce", str(path), "-o", str(tmp_path / "o.vtp"), "--n", "700", "-q"]) == 0
    np.testing.assert_array_equal(pv.read(tmp_path / "o.vtp")["original_id"],
                                  ref["original_id"])


def test_fan_cloud_input_reuses_its_rings(points):
    fans = _kinds(points)["fan cloud"]
    out = fans.fancloud.reduce(n_points=900, weights=(1, 0, 0, 0))
    core = reduce(fans.fancloud.to_fancloud(), 900, weights=(1, 0, 0, 0))
    got = fancloud_from_vtk(out)
    np.testing.assert_array_equal(got.ring, core.ring)
    np.testing.assert_array_equal(got.points, core.points)


@pytest.mark.parametrize("kind", ["point set", "fan cloud", "triangle mesh"])
def test_entropy_takes_three_kinds(points, kind):
    data = _kinds(points)[kind]
    out = data.fancloud.entropy(weights=(1, 1, 50, 1))
    assert out["fancloud_input"][0] == kind
    assert out.n_points == data.n_points
    for name in ("entropy", "entropy_dist", "entropy_curv", "entropy_cc", "entropy_col"):
        assert out[name].shape == (data.n_points,)
    assert np.all(out["entropy_col"] > 0)  # the colour varies everywhere
    assert "entropy" not in data.point_data


def _saved(h, tmp_path):
    path = tmp_path / "h.npz"
    h.save(path)
    return path


def test_reduce_to_mesh_and_hierarchy(points, tmp_path):
    cloud = _kinds(points)["point set"]
    mesh = cloud.fancloud.reduce(keep=0.25, mesh=True)
    assert mesh.n_points == 750 and mesh.n_cells > 1400
    assert "mesh_final" in mesh.field_data
    h = cloud.fancloud.hierarchy(300, weights=(1, 0, 0, 0))
    assert isinstance(h, Hierarchy) and h.n_min == 300
    assert h.fancloud_input == "point set"
    assert Hierarchy.load(_saved(h, tmp_path)).fancloud_input is None  # not saved
    fans = _kinds(points)["fan cloud"]
    assert fans.fancloud.hierarchy(2000).fancloud_input == "fan cloud"
    assert h.level(1000).n_points == 1000


def test_accessor_checks_keywords(points):
    cloud = _kinds(points)["point set"]
    with pytest.raises(TypeError, match="unknown"):
        cloud.fancloud.reduce(keep_fraction=0.3)
    with pytest.raises(ValueError, match="keep"):
        cloud.fancloud.reduce(keep=1.5)
    with pytest.raises(ValueError, match="weights"):
        cloud.fancloud.reduce(weights=(1, 1, 50))
    with pytest.raises(ValueError, match="larger"):
        cloud.fancloud.reduce(n_points=10**6)
    with pytest.raises(ValueError, match="n_points or keep, not both"):
        cloud.fancloud.reduce(n_points=100, keep=0.9)
    assert cloud.fancloud.reduce(n_points=0, keep=0.5).n_points == 1500  # 0: not given
    with pytest.raises(ValueError, match="no colours|no point array"):
        pv.PolyData(points[0]).fancloud.entropy(weights=(1, 1, 50, 1))


def test_filters_in_a_pipeline(points):
    from vtkmodules.vtkFiltersSources import vtkSphereSource

    src = vtkSphereSource()
    src.SetThetaResolution(50)
    src.SetPhiResolution(50)
    red = FanCloudReduceFilter(n_points=500, method="error")
    red.SetInputConnection(src.GetOutputPort())
    ent = FanCloudEntropyFilter()
    ent.SetInputConnection(red.GetOutputPort())
    out = pv.wrap(run(ent))
    assert out.n_points == 500 and out["fancloud_input"][0] == "fan cloud"
    red.SetNPoints(400)
    assert pv.wrap(run(ent)).n_points == 400


def test_selective_filter(points):
    p, _ = points
    sel = FanCloudSelectiveRefineFilter(keep=0.2, region_center=(0, 0, 1), region_radius=0.6,
                                        smooth_iterations=1)
    sel.SetInputDataObject(0, pv.PolyData(p))
    out = pv.wrap(run(sel))
    ids = out["original_id"]
    top = np.linalg.norm(p - [0, 0, 1], axis=1) <= 0.6
    assert 600 < out.n_points < 3000
    # near the region's centre every input point is back (away from its rim, which moved)
    assert np.all(np.isin(np.flatnonzero(np.linalg.norm(p - [0, 0, 1], axis=1) < 0.4), ids))
    assert np.isin(ids, np.flatnonzero(top)).sum() > 0.8 * top.sum()
    sel.region_radius = 0.0
    with pytest.raises(ValueError, match="region_radius"):
        run(sel)


def test_accessor_selective_is_the_filter(points):
    p, rgb = points
    cloud = pv.PolyData(p)
    cloud["RGB"] = rgb
    before = dataset_fingerprint(cloud)
    region = {"keep": 0.2, "region_center": (0, 0, 1), "region_radius": 0.6,
              "smooth_iterations": 1}
    got = cloud.fancloud.selective(**region)
    assert dataset_fingerprint(cloud) == before, "input untouched"
    sel = FanCloudSelectiveRefineFilter(**region)
    sel.SetInputDataObject(0, cloud)
    ref = pv.wrap(run(sel))
    np.testing.assert_array_equal(got["original_id"], ref["original_id"])
    np.testing.assert_array_equal(got.points, ref.points)
    np.testing.assert_array_equal(got["RGB"], ref["RGB"])
    assert got["fancloud_input"][0] == "point set" and 600 < got.n_points < 3000
    with pytest.raises(ValueError, match="n_points or keep, not both"):
        cloud.fancloud.selective(n_points=500, keep=0.2, region_radius=1.0)
    with pytest.raises(ValueError, match="region_radius must be > 0"):
        cloud.fancloud.selective(keep=0.2)


def test_selective_filter_builds_its_fans_with_its_fan_parameters(points):
    p, _ = points
    sizes = {}
    for k in (6, 10):
        sel = FanCloudSelectiveRefineFilter(k=k, keep=0.3, region_center=(0, 0, 1),
                                            region_radius=0.5)
        sel.SetInputDataObject(0, pv.PolyData(p))
        fc = fancloud_from_vtk(run(sel))
        sizes[k] = fc.fan_sizes[~fc.open].mean()
    assert sizes[6] == pytest.approx(6, abs=0.3)
    assert sizes[10] > 9  # not the default k=6 of Hierarchy.selective


def test_cli_reduce_and_entropy(points, tmp_path, capsys):
    p, rgb = points
    fc = build_fans(p, point_data={"RGB": rgb})
    src = tmp_path / "in.vtp"
    save(fc, src)
    out = tmp_path / "small.vtp"
    assert main(["reduce", str(src), "-o", str(out), "--n", "800", "--weights", "1,1,50,1",
                 "-q"]) == 0
    small = pv.read(out)
    assert small.n_points == 800 and "original_id" in small.point_data
    mesh_out = tmp_path / "small.ply"
    assert main(["reduce", str(src), "-o", str(mesh_out), "--keep", "0.3", "--mesh",
                 "--method", "error"]) == 0
    assert pv.read(mesh_out).n_points == 900
    assert "fan cloud" in capsys.readouterr().out
    ent = tmp_path / "ent.vtp"
    assert main(["entropy", str(out), "-o", str(ent), "-q"]) == 0
    assert "entropy_cc" in pv.read(ent).point_data


def test_cli_selective_is_the_filter(points, tmp_path, capsys):
    p, rgb = points
    src = tmp_path / "in.vtp"
    save(build_fans(p, point_data={"RGB": rgb}), src)
    out = tmp_path / "sel.vtp"
    region = {"keep": 0.2, "region_center": (0, 0, 1), "region_radius": 0.6,
              "smooth_iterations": 1}
    assert main(["selective", str(src), "-o", str(out), "--keep", "0.2", "--region-center",
                 "0,0,1", "--region-radius", "0.6", "--smooth-iterations", "1"]) == 0
    printed = capsys.readouterr().out
    assert "fan cloud, 3,000 points" in printed and "reinserted in the region" in printed
    got = pv.read(out)
    sel = FanCloudSelectiveRefineFilter(**region)
    sel.SetInputDataObject(0, pv.read(src))
    ref = pv.wrap(run(sel))
    np.testing.assert_array_equal(got["original_id"], ref["original_id"])
    np.testing.assert_array_equal(got.points, ref.points)
    np.testing.assert_array_equal(got["RGB"], ref["RGB"])
    assert 600 < got.n_points < 3000
    # bad options, amounts and regions are refused before anything is read
    missing = str(tmp_path / "missing.vtp")
    for args, message in [(["--n", "500"], "region_radius must be > 0"),
                          (["--n", "0", "--region-radius", "1"], "cannot reduce to 0 points"),
                          (["--keep", "0.2", "--region-radius", "1", "--smooth-iterations", "-1"],
                           "smooth_iterations"),
                          (["--keep", "0.2", "--region", "box"], "region_bounds must be set")]:
        assert main(["selective", missing, "-o", str(out), *args]) == 2
        assert message in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["selective", str(src), "-o", str(out), "--region-radius", "1"])  # no amount
    assert "--keep" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--keep", "1.5"], "keep"),
        (["--n", "3"], "at least 4"),
        (["--keep", "0.5", "--weights", "1,1,50"], "4 comma"),
        (["--keep", "0.5", "--weights", "1,-1,50,0"], "weights"),
    ],
)
def test_cli_bad_input(points, tmp_path, capsys, args, message):
    src = tmp_path / "in.vtp"
    save(build_fans(points[0]), src)
    with pytest.raises(SystemExit) if "comma" in message else _no_raise():
        code = main(["reduce", str(src), "-o", str(tmp_path / "o.vtp"), *args])
        assert code == 2
    assert message in capsys.readouterr().err


class _no_raise:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
