"""The fronts of the view-dependent fan cloud: filter, live camera, accessor, command."""

import numpy as np
import pytest
import pyvista as pv
from vtkmodules.vtkRenderingCore import vtkCamera, vtkRenderer, vtkRenderWindow

from fancloud_vtk import ViewDependentFanCloud, terrain_fan_cloud, to_vtk
from fancloud_vtk.accessor import PyVistaViewDependentFanCloud
from fancloud_vtk.algorithms import FanCloudViewDependentFilter, flythrough, follow_camera, run
from fancloud_vtk.algorithms.vdfc import height_field_of_image, image_of_heights
from fancloud_vtk.cli import main as cli_main
from fancloud_vtk.core.vdfc import terrain_path

PNG = b"\x89PNG\r\n\x1a\n"


def _heights(n=50):
    x = np.linspace(0, 5, n)
    return 0.5 * np.add.outer(np.sin(x), np.cos(1.2 * x))


def _camera(pos=(2.5, -3.0, 2.5), focal=(2.5, 2.5, 0.0)):
    cam = vtkCamera()
    cam.SetPosition(*pos)
    cam.SetFocalPoint(*focal)
    cam.SetViewUp(0, 0, 1)
    return cam


def _arrays(poly):
    pd = poly.GetPointData()
    return {pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())}


def test_image_round_trip():
    z = _heights()
    img = image_of_heights(z, spacing=(0.1, 0.2), origin=(1, 2))
    h, sp, org, others = height_field_of_image(img)
    assert np.array_equal(h, z) and sp == (0.1, 0.2) and org == (1.0, 2.0) and not others
    with pytest.raises(ValueError, match="2-d"):
        image_of_heights(np.zeros(4))


def test_filter_follows_its_camera():
    cam = _camera()
    alg = FanCloudViewDependentFilter(e_max=0.02, d_max=8.0)
    alg.SetInputDataObject(image_of_heights(_heights(), spacing=0.1))
    alg.SetCamera(cam)
    out = run(alg)
    assert {"node_id", "level", "error", "Normals"} <= _arrays(out)
    first = out.GetNumberOfPoints()
    forest = alg.forest
    t = alg.GetMTime()
    cam.SetPosition(2.5, -1.0, 1.0)  # the camera moves: the filter is modified
    assert alg.GetMTime() > t
    second = run(alg).GetNumberOfPoints()
    assert second != first
    assert alg.forest is forest  # the forest is kept
    expect = forest.front_arrays(_camera((2.5, -1.0, 1.0)), 0.02, 8.0, incremental=False)
    assert second == expect.n_points
    # a clipping range change is not a move
    t = alg.GetMTime()
    cam.SetClippingRange(0.5, 50)
    assert alg.GetMTime() == t
    # a build parameter rebuilds the forest
    alg.merge = "half_edge"
    run(alg)
    assert alg.forest is not forest and alg.forest.merge == "half_edge"
    assert alg.kind == "height field"


def test_filter_removes_superfluous_triangles_when_asked():
    alg = FanCloudViewDependentFilter(e_max=0.02, d_max=8.0)
    alg.SetInputDataObject(image_of_heights(_heights(), spacing=0.1))
    alg.SetCamera(_camera())
    plain = run(alg).GetNumberOfCells()
    assert alg.last_stats["distinct"] == alg.last_stats["triangles"] == plain
    forest = alg.forest
    alg.superfluous = True  # a front parameter: the forest stays
    lean = run(alg).GetNumberOfCells()
    assert alg.forest is forest
    assert lean == alg.last_stats["triangles"] < alg.last_stats["distinct"] == plain


def test_filter_inputs_and_errors(tmp_path):
    fc = terrain_fan_cloud(_heights(), spacing=0.1)
    cam = ((2.5, -3.0, 2.5), (2.5, 2.5, 0.0), (0, 0, 1), 40.0)
    alg = FanCloudViewDependentFilter(e_max=0.02)
    alg.SetInputDataObject(to_vtk(fc))
    with pytest.raises(ValueError, match="no camera"):
        run(alg)
    alg.SetCamera(cam)
    assert run(alg).GetNumberOfPoints() > 0 and alg.kind == "fan cloud"
    # a forest given directly, no input
    vd = ViewDependentFanCloud.build(fc)
    other = FanCloudViewDependentFilter(e_max=0.02)
    other.SetForest(vd)
    other.SetCamera(cam)
    assert run(other).GetNumberOfPoints() == run(alg).GetNumberOfPoints()
    empty = FanCloudViewDependentFilter()
    empty.SetCamera(cam)
    with pytest.raises(ValueError, match="no input and no forest"):
        run(empty)
    with pytest.raises(ValueError, match="view angle"):
        alg.SetCamera(((0, 0, 1), (0, 0, 0), (0, 1, 0), 0.0))
    with pytest.raises(TypeError, match="ViewDependentFanCloud"):
        other.SetForest("forest")
    with pytest.raises(ValueError):
        FanCloudViewDependentFilter(e_max=-1.0)


def test_follow_camera_in_a_render_window():
    alg = FanCloudViewDependentFilter(e_max=0.02, d_max=8.0)
    alg.SetInputDataObject(image_of_heights(_heights(), spacing=0.1))
    ren = vtkRenderer()
    win = vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetSize(320, 200)
    win.AddRenderer(ren)
    cam = ren.GetActiveCamera()
    cam.SetPosition(2.5, -3.0, 2.5)
    cam.SetFocalPoint(2.5, 2.5, 0.0)
    cam.SetViewUp(0, 0, 1)
    follow_camera(ren, alg)
    win.Render()
    assert alg.GetCamera() is cam
    assert alg.aspect == pytest.approx(320 / 200)
    n0 = alg.last_stats["active"]
    cam.SetPosition(2.5, -0.5, 0.8)
    win.Render()
    assert alg.last_stats["active"] != n0
    win.Finalize()
    with pytest.raises(TypeError, match="renderer"):
        follow_camera(object(), alg)


def test_accessor_vdfc_on_an_image_and_points():
    grid = pv.ImageData(dimensions=(50, 50, 1), spacing=(0.1, 0.1, 1))
    grid["height"] = _heights().ravel()
    vd = grid.fancloud.vdfc(e_max=0.02)
    assert isinstance(vd, PyVistaViewDependentFanCloud) and vd.n_leaves == 2500
    front = vd.front(((2.5, -3.0, 2.5), (2.5, 2.5, 0.0), (0, 0, 1), 40.0))
    assert isinstance(front, pv.PolyData)
    assert {"node_id", "level", "error"} <= set(front.point_data)
    assert front.is_all_triangles and 0 < front.n_points < 2500
    # the verb keeps point data of the input untouched and returns a new object
    assert list(grid.point_data) == ["height"]
    cloud = pv.PolyData(terrain_fan_cloud(_heights(), spacing=0.1).points)
    vp = cloud.fancloud.vdfc(k=6)
    assert vp.n_leaves == 2500
    with pytest.raises(TypeError, match="unknown parameter"):
        grid.fancloud.vdfc(emax=1)


def test_accessor_add_to_plotter():
    grid = pv.ImageData(dimensions=(50, 50, 1), spacing=(0.1, 0.1, 1))
    grid["height"] = _heights().ravel()
    vd = grid.fancloud.vdfc(e_max=0.02, d_max=8.0)
    pl = pv.Plotter(off_screen=True, window_size=(300, 200))
    vd.add_to(pl, color="tan")
    pl.camera_position = [(2.5, -3.0, 2.5), (2.5, 2.5, 0.0), (0, 0, 1)]
    pl.render()
    a = vd.live_filter.last_stats["active"]
    pl.camera.position = (2.5, -0.5, 0.8)
    pl.render()
    assert vd.live_filter.last_stats["active"] != a
    img = pl.screenshot(return_img=True)
    assert img.shape[:2] == (200, 300) and img.std() > 0
    pl.close()


def test_flythrough_writes_frames(tmp_path):
    vd = ViewDependentFanCloud.build(terrain_fan_cloud(_heights(), spacing=0.1))
    cams = terrain_path(vd.bounds(), 4)
    rows = flythrough(vd, cams, 0.02, tmp_path / "fly", size=(160, 120))
    assert [r["frame"] for r in rows] == [0, 1, 2, 3]
    assert all(r["active"] > 0 and r["front_ms"] >= 0 for r in rows)
    for i in range(4):
        assert (tmp_path / "fly" / f"frame_{i:04d}.png").read_bytes()[:8] == PNG
    text = (tmp_path / "fly" / "frames.csv").read_text().splitlines()
    assert text[0].startswith("frame,active,triangles") and len(text) == 5
    with pytest.raises(ValueError, match="empty"):
        flythrough(vd, [], 0.02)


def test_command_vdfc(tmp_path, capsys):
    path = tmp_path / "dem.npz"
    np.savez(path, elevation=_heights(), dx=0.1, dy=0.1)
    cam = "2.5,-3,2.5;2.5,2.5,0;0,0,1;40"
    png, vtp, forest = tmp_path / "f.png", tmp_path / "f.vtp", tmp_path / "forest.npz"
    assert cli_main(["vdfc", str(path), "--camera", cam, "--e-max", "0.02", "-o", str(png),
                     "--size", "200x150", "--save-forest", str(forest)]) == 0
    out = capsys.readouterr().out
    assert "height field 50 x 50" in out and "triangles" in out
    assert png.read_bytes()[:8] == PNG
    assert cli_main(["vdfc", str(forest), "--camera", cam, "--e-max", "0.02", "-o", str(vtp),
                     "-q"]) == 0
    front = pv.read(vtp)
    assert {"node_id", "level", "error"} <= set(front.point_data)
    assert cli_main(["vdfc", str(forest), "--flythrough", str(tmp_path / "fly"),
                     "--frames", "3", "--size", "160x120", "-q"]) == 0
    assert (tmp_path / "fly" / "frame_0002.png").exists()
    # a point cloud file as input
    xyz = tmp_path / "pts.npy"
    np.save(xyz, terrain_fan_cloud(_heights(30), spacing=0.1).points)
    assert cli_main(["vdfc", str(xyz), "--camera", "1.5,-2,2;1.5,1.5,0;0,0,1;40",
                     "-o", str(vtp), "-q"]) == 0


@pytest.mark.parametrize("argv, match", [
    (["--camera", "1,2,3;4,5,6;0,0,1"], "4 groups"),
    (["--camera", "1,2;4,5,6;0,0,1;40", "-o", "x.png"], "three numbers"),
    (["--camera", "0,0,5;0,0,0;0,1,0;40"], "needs -o"),
    ([], "either --camera"),
    (["--camera", "0,0,5;0,0,5;0,1,0;40", "-o", "x.png"], "looks at nothing"),
    (["--camera", "0,0,5;0,0,0;0,1,0;40", "-o", "x.png", "--e-max", "-1"], "e_max"),
    (["--camera", "0,0,5;0,0,0;0,1,0;40", "-o", "x.txt"], "x.txt"),
])
def test_command_vdfc_errors(tmp_path, capsys, argv, match):
    path = tmp_path / "dem.npz"
    np.savez(path, elevation=_heights(20))
    code = cli_main(["vdfc", str(path), *argv])
    err = capsys.readouterr().err
    assert code == 2 and match in err, err


def test_command_vdfc_unreadable(tmp_path, capsys):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"junk")
    assert cli_main(["vdfc", str(bad), "--flythrough", str(tmp_path / "x")]) == 2
    assert "error" in capsys.readouterr().err
