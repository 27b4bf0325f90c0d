"""Refinement through the fronts: the VTK filter, the accessor, the command."""

import numpy as np
import pytest
import pyvista as pv
from conftest import dataset_fingerprint
from shapes import sphere

from fancloud_vtk import build_fans, refine, save
from fancloud_vtk.algorithms import FanCloudRefineFilter, fancloud_from_vtk, run
from fancloud_vtk.cli import main


@pytest.fixture(scope="module")
def points():
    p = sphere(2500, seed=7)
    rgb = (np.abs(p) * 255).astype(np.uint8)
    return p, rgb


def _kinds(points):
    p, rgb = points
    cloud = pv.PolyData(p)
    cloud["RGB"] = rgb
    cloud["label"] = np.arange(len(p))
    cloud["value"] = p[:, 2].copy()
    fans = cloud.fancloud.fans()
    mesh = fans.fancloud.mesh()
    mesh.field_data.clear()
    return {"point set": cloud, "fan cloud": fans, "triangle mesh": mesh}


@pytest.mark.parametrize("kind", ["point set", "fan cloud", "triangle mesh"])
def test_refine_takes_three_kinds_and_says_which(points, kind):
    data = _kinds(points)[kind]
    before = dataset_fingerprint(data)
    out = data.fancloud.refine(factor=2)
    assert dataset_fingerprint(data) == before, "input untouched"
    assert out is not data and out.n_points == 2 * data.n_points
    assert out["fancloud_input"][0] == kind
    n0 = data.n_points
    np.testing.assert_array_equal(out.points[:n0], data.points)
    ids = out["original_id"]
    np.testing.assert_array_equal(ids[:n0], np.arange(n0))
    assert (ids[n0:] == -1).all()
    assert out["RGB"].dtype == np.uint8
    np.testing.assert_array_equal(out["RGB"][:n0], data["RGB"])
    np.testing.assert_array_equal(out["label"][:n0], data["label"])
    assert set(out["label"][n0:]) <= set(data["label"])  # taken from a parent
    # a float array is interpolated: z on the sphere, z of the new point (nearly)
    np.testing.assert_allclose(out["value"][n0:], out.points[n0:, 2], atol=0.02)
    assert out.fancloud.is_fan_cloud


def test_fan_cloud_input_equals_the_core(points):
    fans = _kinds(points)["fan cloud"]
    out = fans.fancloud.refine(n_points=4000)
    core = refine(fans.fancloud.to_fancloud(), n_points=4000)
    got = fancloud_from_vtk(out)
    np.testing.assert_array_equal(got.points, core.points)
    np.testing.assert_array_equal(got.ring, core.ring)


def test_filter_parameters_and_mesh_output(points):
    src = pv.PolyData(points[0])
    alg = FanCloudRefineFilter()
    assert alg.GetFactor() == 2.0 and alg.n_points == 0
    alg.SetFactor(1.5)
    alg.SetMesh(True)
    alg.SetInputDataObject(0, src)
    out = pv.wrap(run(alg))
    assert out.n_points == round(1.5 * src.n_points)
    assert out.n_cells > 2 * out.n_points - 10  # a closed surface: about 2n triangles
    alg.SetNPoints(10)
    with pytest.raises(ValueError, match="smaller than the cloud"):
        run(alg)


def test_accessor_checks_keywords(points):
    cloud = pv.PolyData(points[0])
    with pytest.raises(TypeError, match="keep"):
        cloud.fancloud.refine(keep=0.5)
    with pytest.raises(ValueError, match="factor"):
        cloud.fancloud.refine(factor=1.0)
    with pytest.raises(ValueError, match="n_points or factor, not both"):
        cloud.fancloud.refine(n_points=1000, factor=3.0)


def test_cli_refine(points, tmp_path, capsys):
    p, rgb = points
    src = tmp_path / "in.vtp"
    save(build_fans(p, point_data={"RGB": rgb}), src)
    out = tmp_path / "fine.vtp"
    assert main(["refine", str(src), "-o", str(out), "--factor", "2", "-q"]) == 0
    fine = pv.read(out)
    assert fine.n_points == 5000 and (fine["original_id"] == -1).sum() == 2500
    mesh_out = tmp_path / "fine.ply"
    assert main(["refine", str(src), "-o", str(mesh_out), "--n", "3000", "--mesh",
                 "--no-move", "--weights", "1,0,0,0"]) == 0
    assert pv.read(mesh_out).n_points == 3000
    assert "refined" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--factor", "1"], "factor must be a number > 1"),
        (["--factor", "0.5"], "factor"),
        (["--n", "100"], "smaller than the cloud"),
        (["--factor", "2", "--weights", "1,1,0,1"], "colour weight"),
    ],
)
def test_cli_bad_input(points, tmp_path, capsys, args, message):
    src = tmp_path / "in.vtp"
    save(build_fans(points[0]), src)
    assert main(["refine", str(src), "-o", str(tmp_path / "o.vtp"), *args]) == 2
    assert message in capsys.readouterr().err


def test_cli_needs_an_amount(points, tmp_path, capsys):
    src = tmp_path / "in.vtp"
    save(build_fans(points[0]), src)
    with pytest.raises(SystemExit):
        main(["refine", str(src), "-o", str(tmp_path / "o.vtp")])
    assert "--factor" in capsys.readouterr().err
