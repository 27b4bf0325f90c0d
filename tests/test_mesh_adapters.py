"""The mesh stage's fronts: FanCloudMeshFilter in VTK pipelines, ``.fancloud.mesh()``,
``fancloud mesh`` and the demo's mesh (paper section 4, Figure 8)."""

import inspect
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import pyvista as pv
from conftest import dataset_fingerprint
from shapes import sphere
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkCommand, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
from vtkmodules.vtkIOPLY import vtkPLYReader, vtkPLYWriter
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader, vtkXMLPolyDataWriter

from fancloud_vtk import (
    Cancelled,
    DoubtfulMeshWarning,
    FanCloudInputError,
    build_fans,
    fan_cloud_to_mesh,
    load,
)
from fancloud_vtk.algorithms import FanCloudFilter, FanCloudMeshFilter, fancloud_to_vtk, run
from fancloud_vtk.cli import main
from fancloud_vtk.params import FAN_PARAMS, INPUT_PARAMS, MESH_PARAMS

N = 3000
CLOSED = 2 * N - 4  # triangles of a closed genus-0 mesh over N points


@pytest.fixture(scope="module")
def cloud():
    p = sphere(N, seed=41)
    rgb = (np.arange(3 * N) % 256).astype(np.uint8).reshape(N, 3)
    label = (np.arange(N) % 7).astype(np.int32)
    return p, rgb, label


@pytest.fixture(scope="module")
def expected(cloud):
    """The core's mesh of the cloud's fans: what every front must give."""
    return fan_cloud_to_mesh(build_fans(cloud[0]))


def point_cloud(points, **arrays) -> vtkPolyData:
    """A vtkPolyData with points only (no cells) and the given point arrays."""
    poly = vtkPolyData()
    vp = vtkPoints()
    vp.SetData(numpy_to_vtk(np.ascontiguousarray(points), deep=1))
    poly.SetPoints(vp)
    for name, values in arrays.items():
        arr = numpy_to_vtk(np.ascontiguousarray(values), deep=1)
        arr.SetName(name)
        poly.GetPointData().AddArray(arr)
    return poly


def field(poly, name):
    """One value of a field array (``mesh_<name>``)."""
    return vtk_to_numpy(poly.GetFieldData().GetArray("mesh_" + name))[0]


def triangles_of(poly) -> np.ndarray:
    cells = poly.GetPolys()
    assert cells.IsHomogeneous() == 3, "every cell is a triangle"
    return vtk_to_numpy(cells.GetConnectivityArray()).reshape(-1, 3)


# -- FanCloudMeshFilter in VTK pipelines ---------------------------------------------


@pytest.mark.parametrize("fmt", ["vtp", "ply"])
def test_reader_mesh_normals_pipeline(cloud, tmp_path, fmt):
    p, rgb, label = cloud
    path = tmp_path / f"cloud.{fmt}"
    if fmt == "vtp":
        writer, reader = vtkXMLPolyDataWriter(), vtkXMLPolyDataReader()
        writer.SetInputData(point_cloud(p, RGB=rgb, label=label))
    else:
        writer, reader = vtkPLYWriter(), vtkPLYReader()
        writer.SetInputData(point_cloud(p.astype(np.float32), RGB=rgb))
        writer.SetArrayName("RGB")  # colours as PLY red/green/blue
    writer.SetFileName(str(path))
    assert writer.Write() == 1
    reader.SetFileName(str(path))

    mesh = FanCloudMeshFilter()
    mesh.SetInputConnection(reader.GetOutputPort())
    normals = vtkPolyDataNormals()
    normals.SetInputConnection(mesh.GetOutputPort())
    normals.SplittingOff()  # keep the points one to one
    normals.ComputeCellNormalsOn()
    assert normals.Update()

    out = normals.GetOutput()
    assert out.GetNumberOfPoints() == N
    tri = triangles_of(out)
    # closed: a genus-0 2-manifold over every point
    assert len(tri) == CLOSED
    assert field(out, "holes") == 0 and field(out, "final") == CLOSED
    assert field(out, "boundary_edges") == 0 and field(out, "non_manifold_edges") == 0
    # point arrays pass through one to one, with their dtypes
    pd = out.GetPointData()
    got_rgb = vtk_to_numpy(pd.GetArray("RGB"))
    assert got_rgb.dtype == np.uint8
    np.testing.assert_array_equal(got_rgb, rgb)
    if fmt == "vtp":
        np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("label")), label)
    # the triangles are the core's on the same points
    pts = vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    np.testing.assert_array_equal(tri, fan_cloud_to_mesh(build_fans(pts)).triangles)
    # counter-clockwise around the outward normals
    cell_normals = vtk_to_numpy(out.GetCellData().GetNormals())
    assert np.all(np.einsum("ij,ij->i", cell_normals, pts[tri].mean(axis=1)) > 0)


def test_fan_cloud_input_reuses_its_rings(cloud, expected):
    p, rgb, label = cloud
    fans = FanCloudFilter()
    fans.SetInputDataObject(0, point_cloud(p, RGB=rgb, label=label))
    mesh = FanCloudMeshFilter(k=8)  # fan parameters do not apply to a fan cloud
    mesh.SetInputConnection(fans.GetOutputPort())
    out = run(mesh)
    np.testing.assert_array_equal(triangles_of(out), expected.triangles)
    assert field(out, "final") == CLOSED and field(out, "holes") == 0
    pd = out.GetPointData()
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("RGB")), rgb)
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("label")), label)
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetNormals()), expected.normals)
    assert pd.GetArray("fan_open") is None  # the fan arrays stay with the fan cloud
    # on points, the fan parameters do apply
    direct = FanCloudMeshFilter(k=8)
    direct.SetInputDataObject(0, point_cloud(p))
    np.testing.assert_array_equal(
        triangles_of(run(direct)), fan_cloud_to_mesh(build_fans(p, k=8)).triangles
    )


def test_input_is_unchanged(cloud):
    p, rgb, label = cloud
    for poly in (point_cloud(p, RGB=rgb, label=label), fancloud_to_vtk(build_fans(p))):
        before = dataset_fingerprint(pv.wrap(poly))
        mtime = poly.GetMTime()
        mesh = FanCloudMeshFilter()
        mesh.SetInputDataObject(0, poly)
        out = run(mesh)
        vtk_to_numpy(out.GetPoints().GetData())[:] = 0  # the output shares no input buffer
        vtk_to_numpy(out.GetPointData().GetNormals())[:] = 0
        assert dataset_fingerprint(pv.wrap(poly)) == before
        assert poly.GetMTime() == mtime


# (the setter test of every filter, this one included, is in test_algorithms.py)


def test_bad_parameter_values_are_rejected_without_modifying():
    mesh = FanCloudMeshFilter()
    t0 = mesh.GetMTime()
    with pytest.raises(ValueError,
                       match=r"rings must be one of \['auto', 'delaunay', 'local', 'fans'\]"):
        mesh.SetRings("voronoi")
    with pytest.raises(ValueError, match="max_hole must be between 3 and"):
        mesh.max_hole = 2
    with pytest.raises(TypeError, match="close_holes must be True or False"):
        mesh.SetCloseHoles("yes")
    assert mesh.GetMTime() == t0
    assert mesh.parameters == {p.name: p.default for p in FAN_PARAMS + INPUT_PARAMS + MESH_PARAMS}
    with pytest.raises(TypeError, match="FanCloudMeshFilter has no parameter 'holes'"):
        FanCloudMeshFilter(holes=True)


def test_a_parameter_change_reruns_the_pipeline(cloud):
    mesh = FanCloudMeshFilter()
    mesh.SetInputDataObject(0, point_cloud(cloud[0]))
    assert field(run(mesh), "holes_closed") > 0
    mesh.SetCloseHoles(False)
    out = run(mesh)
    assert field(out, "holes_closed") == 0
    assert field(out, "final") == field(out, "grown") == out.GetNumberOfPolys()
    distinct = field(out, "distinct")
    mesh.SetRings("fans")
    with pytest.warns(DoubtfulMeshWarning):  # the paper's fans leave points out, and it says so
        assert field(run(mesh), "distinct") != distinct  # (the same output object, updated)


def test_core_errors_surface_through_run(cloud):
    fc = fancloud_to_vtk(build_fans(cloud[0]))
    ring = vtk_to_numpy(fc.GetFieldData().GetArray("fan_ring"))
    good = int(ring[10])
    ring[10] = N + 5
    mesh = FanCloudMeshFilter()
    mesh.SetInputDataObject(0, fc)
    for _ in range(2):  # not a stale success the second time
        with pytest.raises(ValueError, match=f"fan_ring entry 10 is {N + 5}, out of range"):
            run(mesh)
        assert isinstance(mesh.last_error, ValueError)
    ring[10] = good
    fc.GetFieldData().GetArray("fan_ring").Modified()
    fc.Modified()
    assert run(mesh).GetNumberOfPolys() == CLOSED and mesh.last_error is None
    # an error of the fan construction on points, too
    p = cloud[0].copy()
    p[7] = np.nan
    mesh.SetInputDataObject(0, point_cloud(p))
    with pytest.raises(FanCloudInputError, match="NaN or infinite .* first at index 7"):
        run(mesh)


def test_progress_and_abort(cloud):
    mesh = FanCloudMeshFilter()
    mesh.SetInputDataObject(0, point_cloud(cloud[0]))
    seen, texts = [], []

    def on_progress(caller, event):
        seen.append(caller.GetProgress())
        texts.append(caller.GetProgressText())

    tag = mesh.AddObserver(vtkCommand.ProgressEvent, on_progress)
    run(mesh)
    assert seen[-1] == 1.0 and any(0.0 < f < 1.0 for f in seen)
    assert all(b >= a for a, b in zip(seen, seen[1:], strict=False))
    assert "neighbour search" in texts and "mesh" in texts
    mesh.RemoveObserver(tag)

    def abort_at_mesh(caller, event):
        if caller.GetProgressText() == "mesh":
            caller.SetAbortExecute(1)

    tag = mesh.AddObserver(vtkCommand.ProgressEvent, abort_at_mesh)
    mesh.Modified()  # run again
    with pytest.raises(Cancelled, match="meshing was cancelled"):
        run(mesh)
    mesh.RemoveObserver(tag)
    mesh.SetAbortExecute(0)
    assert run(mesh).GetNumberOfPolys() == CLOSED


# -- the accessor -------------------------------------------------------------------


@pytest.fixture
def pv_cloud(cloud):
    """A fresh PyVista cloud with uint8 colours and int labels."""
    c = pv.PolyData(cloud[0].copy())  # pv.PolyData would share the array
    c.point_data["RGB"] = cloud[1]
    c.point_data["label"] = cloud[2].astype(np.int64)
    return c


def test_accessor_mesh_in_a_fresh_process_without_importing_the_package():
    code = textwrap.dedent(
        f"""
        import sys
        import numpy as np
        import pyvista as pv
        assert "fancloud_vtk" not in sys.modules
        rng = np.random.default_rng(0)
        points = rng.normal(size=({N}, 3))
        points /= np.linalg.norm(points, axis=1)[:, None]
        m = pv.PolyData(points).fancloud.mesh()
        assert isinstance(m, pv.PolyData) and m.is_all_triangles
        assert m.n_points == {N} and m.n_cells == {CLOSED}, m.n_cells
        assert int(m.field_data["mesh_holes"][0]) == 0
        print("ok")
        """
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"


def test_accessor_mesh_is_new_and_keeps_the_arrays(pv_cloud, expected):
    before = dataset_fingerprint(pv_cloud)
    out = pv_cloud.fancloud.mesh()
    assert isinstance(out, pv.PolyData) and out is not pv_cloud
    assert out.n_points == N and out.is_all_triangles and out.n_cells == CLOSED
    np.testing.assert_array_equal(out.regular_faces, expected.triangles)
    np.testing.assert_array_equal(out.points, pv_cloud.points)
    assert out.point_data["RGB"].dtype == np.uint8
    np.testing.assert_array_equal(out.point_data["RGB"], pv_cloud.point_data["RGB"])
    np.testing.assert_array_equal(out.point_data["label"], pv_cloud.point_data["label"])
    assert out.field_data["mesh_holes"][0] == 0
    assert out.field_data["mesh_final"][0] == CLOSED
    # the input is untouched, and the output shares none of its buffers
    assert dataset_fingerprint(pv_cloud) == before
    assert pv_cloud.n_cells == N and "Normals" not in pv_cloud.point_data
    out.points[:] = 0
    out.point_data["RGB"][:] = 0
    assert dataset_fingerprint(pv_cloud) == before


def test_accessor_mesh_of_a_fan_cloud(pv_cloud, expected):
    fans = pv_cloud.fancloud.fans()
    before = dataset_fingerprint(fans)
    out = fans.fancloud.mesh()
    assert dataset_fingerprint(fans) == before
    np.testing.assert_array_equal(out.regular_faces, expected.triangles)
    assert sorted(out.point_data) == ["Normals", "RGB", "label"]
    assert not out.fancloud.is_fan_cloud


def test_accessor_mesh_signature():
    sig = inspect.signature(pv.PolyData().fancloud.mesh)
    params = list(sig.parameters.values())
    table = FAN_PARAMS + INPUT_PARAMS + MESH_PARAMS
    assert [p.name for p in params] == [p.name for p in table] + ["progress_bar"]
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params)
    doc = pv.PolyData().fancloud.mesh.__doc__
    assert "max_hole : int, default: 32" in doc and "{params}" not in doc


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"holes": True}, TypeError, r"unknown parameter\(s\) \['holes'\]; known:"),
        ({"rings": "voronoi"}, ValueError,
         r"rings must be one of \['auto', 'delaunay', 'local', 'fans'\]"),
        ({"max_hole": 2}, ValueError, "max_hole must be between 3 and"),
        ({"k": 2}, ValueError, "k must be between 3 and 64, got 2"),
        ({"close_holes": "yes"}, TypeError, "close_holes must be True or False"),
    ],
)
def test_accessor_bad_keywords(pv_cloud, kwargs, error, match):
    before = dataset_fingerprint(pv_cloud)
    with pytest.raises(error, match=match):
        pv_cloud.fancloud.mesh(**kwargs)
    with pytest.raises(TypeError, match="positional"):
        pv_cloud.fancloud.mesh(6)
    assert dataset_fingerprint(pv_cloud) == before


def test_accessor_core_error_and_progress_bar(pv_cloud, capsys):
    pytest.importorskip("tqdm")
    out = pv_cloud.fancloud.mesh(progress_bar=True, self_intersections=False)
    assert out.n_cells == CLOSED
    assert "Meshing" in capsys.readouterr().err
    pv_cloud.points[12] = [np.nan, 0.0, 0.0]
    with pytest.raises(FanCloudInputError, match="first at index 12"):
        pv_cloud.fancloud.mesh(progress_bar=True)


# -- the command --------------------------------------------------------------------


@pytest.fixture(scope="module")
def xyz(cloud, tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "cloud.xyz"
    np.savetxt(path, cloud[0], fmt="%.17g")
    return path


@pytest.mark.parametrize("ext", ["ply", "obj", "vtp", "stl"])
def test_cli_mesh_formats(xyz, tmp_path, ext, capsys):
    out = tmp_path / f"mesh.{ext}"
    assert main(["mesh", str(xyz), "-o", str(out)]) == 0
    back = pv.read(out)
    assert back.n_cells == CLOSED and back.is_all_triangles
    printed = capsys.readouterr().out
    assert str(out) in printed
    if ext == "vtp":
        assert back["mesh_holes"][0] == 0 and back["mesh_final"][0] == CLOSED


def test_cli_summary_has_the_stage_counts(xyz, tmp_path, capsys, expected):
    assert main(["mesh", str(xyz), "-o", str(tmp_path / "m.ply")]) == 0
    printed = capsys.readouterr().out
    s = expected.stats
    for label, key in (("fan triangles", "fan_triangles"), ("distinct", "distinct"),
                       ("after superfluous removal", "after_superfluous"),
                       ("grown 2-manifold", "grown"), (r"final \(holes closed\)", "final")):
        value = f"{s[key]:,} ({s[key] / N:.3f} per point)"
        assert re.search(rf"^{label} +{re.escape(value)}$", printed, re.MULTILINE), label
    for label in ("holes", "non manifold edges", "non manifold vertices",
                  "self intersections", "boundary edges"):
        assert re.search(rf"^{label} +0$", printed, re.MULTILINE), label
    assert re.search(r"^time +\d+\.\d\d s$", printed, re.MULTILINE)
    assert main(["mesh", str(xyz), "-o", str(tmp_path / "q.ply"), "--quiet"]) == 0
    assert capsys.readouterr().out == ""


def test_cli_colours_and_normals_reach_the_ply(cloud, tmp_path, capsys):
    from plyfile import PlyData, PlyElement

    p, rgb, _ = cloud
    v = np.empty(N, dtype=[("x", "f8"), ("y", "f8"), ("z", "f8"),
                           ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    for i, c in enumerate("xyz"):
        v[c] = p[:, i]
    for i, c in enumerate(("red", "green", "blue")):
        v[c] = rgb[:, i]
    src = tmp_path / "cloud.ply"
    PlyData([PlyElement.describe(v, "vertex")]).write(str(src))
    out = tmp_path / "mesh.ply"
    assert main(["mesh", str(src), "-o", str(out), "-q"]) == 0
    back = pv.read(out)
    assert back.n_cells == CLOSED
    np.testing.assert_array_equal(back.point_data["RGB"], rgb)
    normals = back.point_data["Normals"]
    assert np.all(np.einsum("ij,ij->i", normals, p) > 0.9)


def test_cli_mesh_of_a_fan_cloud_written_by_fans(xyz, tmp_path, capsys):
    fans = tmp_path / "fans.vtp"
    assert main(["fans", str(xyz), "-o", str(fans), "-q"]) == 0
    out = tmp_path / "mesh.vtp"
    args = ["mesh", str(fans), "-o", str(out), "--k", "8", "--no-close-holes", "-q"]
    assert main(args) == 0
    back = pv.read(out)
    expected = fan_cloud_to_mesh(load(fans), close_holes=False)
    np.testing.assert_array_equal(back.regular_faces, expected.triangles)
    assert back["mesh_holes_closed"][0] == 0
    assert capsys.readouterr().out == ""


def test_cli_wrong_output_extension(xyz, tmp_path, capsys):
    out = tmp_path / "mesh.txt"
    assert main(["mesh", str(xyz), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("fancloud mesh: error: the output must be a .vtp or .ply")
    assert "mesh.txt" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    res = subprocess.run(
        [sys.executable, "-m", "fancloud_vtk.cli", "mesh", str(xyz), "-o", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert res.returncode == 2 and res.stdout == ""
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert res.stderr.startswith("fancloud mesh: error: ") and "Traceback" not in res.stderr


# -- the demo -------------------------------------------------------------------------


def test_demo_writes_the_fans_and_the_mesh(tmp_path, capsys):
    from fancloud_vtk.demo import run_demo

    summary = run_demo(str(tmp_path), quiet=True)
    n = summary["points"]
    for key in ("vtp", "png", "mesh_ply", "mesh_png"):
        assert (tmp_path / summary[key].rsplit("/", 1)[-1]).stat().st_size > 1000, key
    assert summary["mesh_ply"].endswith("bunny_mesh.ply")
    assert summary["mesh_png"].endswith("bunny_mesh.png")
    mesh = summary["mesh"]
    assert mesh["final"] == 2 * n - 4 and mesh["holes"] == 0
    assert mesh["non_manifold_edges"] == mesh["non_manifold_vertices"] == 0
    assert summary["mesh_time"] > 0
    assert pv.read(summary["mesh_ply"]).n_cells == 2 * n - 4
    printed = capsys.readouterr().out
    assert "grown 2-manifold" in printed and "bunny_mesh.png" in printed
    assert "bunny_fans.vtp" in printed
    # the reduction panel (Figures 9 and 11)
    red = summary["reduction"]
    assert red["reduce_(1, 0, 0, 0)"]["points"] == red["reduce_(1, 1, 50, 0)"]["points"] \
        == round(0.176 * n)
    assert red["selective"]["coarse"] == round(0.15 * n) < red["selective"]["refined"] < n
    for key in ("reduce_png", "selective_png"):
        assert (tmp_path / red[key].rsplit("/", 1)[-1]).stat().st_size > 1000, key
    assert "Figure 11" in printed


def test_write_mesh_ply_leaves_the_polydata_alone(expected, tmp_path):
    from fancloud_vtk.algorithms.convert import mesh_to_vtk, write_mesh

    poly = mesh_to_vtk(expected)
    before = dataset_fingerprint(pv.wrap(poly))
    write_mesh(poly, tmp_path / "m.ply")
    assert dataset_fingerprint(pv.wrap(poly)) == before
    assert poly.GetPointData().GetNormals().GetDataType() == 11  # still float64
    back = pv.read(tmp_path / "m.ply")
    np.testing.assert_allclose(back.point_data["Normals"], expected.normals, atol=1e-6)
