"""One verb layer: the filters, the accessor and the command give identical outputs.

Every verb runs three ways on the same input -- the VTK algorithm, the
PyVista accessor and the ``fancloud`` command (in-process, writing a
``.vtp``) -- and the three outputs must agree array for array: points, cells,
point arrays and field arrays (but the mesh's wall-clock timings). The verb
layer itself (:mod:`fancloud_vtk.core.verbs`) is checked against the core
functions it forwards to.
"""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv
from vtkmodules.util.numpy_support import vtk_to_numpy

import fancloud_vtk.accessor  # noqa: F401  (registers dataset.fancloud)
from fancloud_vtk import build_fans, fan_cloud_to_mesh
from fancloud_vtk import reduce as core_reduce
from fancloud_vtk.algorithms import (
    FanCloudEntropyFilter,
    FanCloudFilter,
    FanCloudMeshFilter,
    FanCloudReduceFilter,
    FanCloudRefineFilter,
    FanCloudSelectiveRefineFilter,
    FanCloudViewDependentFilter,
    run,
)
from fancloud_vtk.algorithms.convert import read_vtp
from fancloud_vtk.cli import main
from fancloud_vtk.core import verbs
from fancloud_vtk.params import VERB_PARAMS

N = 1500
CAMERA = ((3.0, -2.0, 1.5), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0)
SIZE = (160, 120)


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(11)
    p = rng.normal(size=(N, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    p[:, 2] *= 0.7  # an ellipsoid: curvature varies, so the entropy is not flat
    return p


@pytest.fixture(scope="module")
def mesh_input():
    return pv.Sphere(theta_resolution=30, phi_resolution=30)


#: verb -> (filter class, keyword values, the same as command options)
CASES = {
    "fans": (FanCloudFilter, {"k": 7}, ["--k", "7"]),
    "mesh": (FanCloudMeshFilter, {"k": 6, "max_hole": 20}, ["--k", "6", "--max-hole", "20"]),
    "entropy": (FanCloudEntropyFilter, {"weights": (1.0, 2.0, 10.0, 0.0)},
                ["--weights", "1,2,10,0"]),
    "reduce": (FanCloudReduceFilter, {"keep": 0.3, "method": "error"},
               ["--keep", "0.3", "--method", "error"]),
    "reduce-mesh": (FanCloudReduceFilter, {"n_points": 500, "mesh": True},
                    ["--n", "500", "--mesh"]),
    "selective": (FanCloudSelectiveRefineFilter,
                  {"keep": 0.25, "region_center": (0.0, 0.0, 0.7), "region_radius": 0.5,
                   "smooth_iterations": 1},
                  ["--keep", "0.25", "--region-center", "0,0,0.7", "--region-radius", "0.5",
                   "--smooth-iterations", "1"]),
    "refine": (FanCloudRefineFilter, {"factor": 1.5}, ["--factor", "1.5"]),
    "refine-mesh": (FanCloudRefineFilter, {"n_points": 2000, "mesh": True},
                    ["--n", "2000", "--mesh"]),
}


def _arrays(data) -> dict:
    out = {}
    for prefix, attrs in (("point:", data.GetPointData()), ("field:", data.GetFieldData())):
        for i in range(attrs.GetNumberOfArrays()):
            arr = attrs.GetAbstractArray(i)
            name = arr.GetName()
            if name.startswith("mesh_timings") or name == "mesh_time":
                continue
            if arr.IsA("vtkStringArray"):
                out[prefix + name] = [arr.GetValue(j) for j in range(arr.GetNumberOfValues())]
            else:
                out[prefix + name] = vtk_to_numpy(arr).copy()
    return out


def _cells(data) -> np.ndarray:
    polys = data.GetPolys()
    return vtk_to_numpy(polys.GetConnectivityArray()).copy()


def assert_same(a, b, what: str) -> None:
    np.testing.assert_array_equal(vtk_to_numpy(a.GetPoints().GetData()),
                                  vtk_to_numpy(b.GetPoints().GetData()), err_msg=what)
    np.testing.assert_array_equal(_cells(a), _cells(b), err_msg=what)
    aa, bb = _arrays(a), _arrays(b)
    assert sorted(aa) == sorted(bb), what
    for name in aa:
        if isinstance(aa[name], list):
            assert aa[name] == bb[name], f"{what}: {name}"
        else:
            np.testing.assert_array_equal(aa[name], bb[name], err_msg=f"{what}: {name}")


def _three_ways(verb_case, dataset, path, tmp_path):
    verb = verb_case.split("-")[0]
    cls, values, options = CASES[verb_case]
    alg = cls(**values)
    alg.SetInputDataObject(0, dataset)
    by_filter = run(alg)
    by_accessor = getattr(dataset.fancloud, verb)(**values)
    out = tmp_path / f"{verb_case}.vtp"
    assert main([verb, str(path), "-o", str(out), *options, "-q"]) == 0
    return by_filter, by_accessor, read_vtp(str(out))


@pytest.mark.parametrize("verb_case", sorted(CASES))
def test_filter_accessor_and_command_agree_on_points(verb_case, points, tmp_path):
    path = tmp_path / "cloud.npy"
    np.save(path, points)
    f, a, c = _three_ways(verb_case, pv.PolyData(points), path, tmp_path)
    assert_same(f, a, f"{verb_case}: filter vs accessor")
    assert_same(f, c, f"{verb_case}: filter vs command")
    assert f.GetNumberOfPoints() > 0


@pytest.mark.parametrize("verb_case", ["entropy", "reduce", "reduce-mesh", "refine", "mesh"])
def test_filter_accessor_and_command_agree_on_a_mesh(verb_case, mesh_input, tmp_path):
    path = tmp_path / "sphere.ply"
    mesh_input.save(path)
    dataset = pv.read(path)  # the points as the file holds them (float32)
    f, a, c = _three_ways(verb_case, dataset, path, tmp_path)
    assert_same(f, a, f"{verb_case}: filter vs accessor")
    assert_same(f, c, f"{verb_case}: filter vs command")


def test_vdfc_front_agrees_three_ways(points, tmp_path):
    path = tmp_path / "cloud.npy"
    np.save(path, points)
    aspect = SIZE[0] / SIZE[1]
    alg = FanCloudViewDependentFilter(e_max=0.02, aspect=aspect)
    alg.SetInputDataObject(0, pv.PolyData(points))
    alg.SetCamera((*CAMERA, aspect))
    by_filter = run(alg)
    vd = pv.PolyData(points).fancloud.vdfc(e_max=0.02, aspect=aspect)
    by_accessor = vd.front((*CAMERA, aspect))
    out = tmp_path / "front.vtp"
    cam = ";".join([",".join(map(str, CAMERA[0])), ",".join(map(str, CAMERA[1])),
                    ",".join(map(str, CAMERA[2])), str(CAMERA[3])])
    assert main(["vdfc", str(path), "--camera", cam, "--e-max", "0.02",
                 "--size", f"{SIZE[0]}x{SIZE[1]}", "-o", str(out), "-q"]) == 0
    by_command = read_vtp(str(out))
    assert by_filter.GetNumberOfPoints() > 0
    assert_same(by_filter, by_accessor, "vdfc: filter vs accessor")
    assert_same(by_filter, by_command, "vdfc: filter vs command")


def test_every_verb_has_a_table_and_a_function():
    assert set(verbs.VERBS) == set(VERB_PARAMS)
    for verb in verbs.VERBS:
        with pytest.raises(TypeError, match="unknown parameter"):
            verbs.VERBS[verb](verbs.Source(points=np.zeros((10, 3))), {"no_such_option": 1})


def test_verbs_forward_to_the_core(points):
    source = verbs.Source(points=points)
    fc = build_fans(points, k=6)
    r = verbs.reduce(source, {"keep": 0.3})
    expected = core_reduce(fc, keep=0.3)
    np.testing.assert_array_equal(r.fancloud.points, expected.points)
    np.testing.assert_array_equal(r.fancloud.ring, expected.ring)
    m = verbs.mesh(source)
    np.testing.assert_array_equal(m.mesh.triangles, fan_cloud_to_mesh(fc).triangles)
    assert r.kind == m.kind == verbs.KIND_POINTS
    # a fan cloud is meshed with its own rings; the fans verb builds them anew
    fc8 = build_fans(points, k=8)
    m8 = verbs.mesh(verbs.Source(fancloud=fc8))
    np.testing.assert_array_equal(m8.mesh.triangles, fan_cloud_to_mesh(fc8).triangles)
    again = verbs.fans(verbs.Source(fancloud=fc8), {"k": 6}).fancloud
    np.testing.assert_array_equal(again.ring, fc.ring)


def test_the_amount_is_one_of_two(points):
    with pytest.raises(ValueError, match="n_points or keep, not both"):
        pv.PolyData(points).fancloud.reduce(keep=0.3, n_points=100)
    with pytest.raises(ValueError, match="n_points or factor, not both"):
        pv.PolyData(points).fancloud.refine(factor=2.0, n_points=4000)
    r = verbs.reduce(verbs.Source(points=points), {"n_points": 400, "keep": 0.9})
    assert r.fancloud.n_points == 400  # n_points wins over the fraction


def test_cancel_stops_a_verb(points):
    from fancloud_vtk import Cancelled

    with pytest.raises(Cancelled):
        verbs.mesh(verbs.Source(points=points), {}, progress=lambda f, m: f >= 0.5)


def test_mesh_input_counts_its_dropped_vertices(mesh_input):
    pts = np.vstack([mesh_input.points, [[5.0, 5.0, 5.0], [6.0, 6.0, 6.0]]])
    tri = mesh_input.faces.reshape(-1, 4)[:, 1:]
    source = verbs.Source(points=pts, triangles=tri)
    with pytest.warns(UserWarning, match="2 "):
        r = verbs.reduce(source, {"keep": 0.5})
    assert r.kind == verbs.KIND_MESH
    assert r.unreferenced_dropped == 2
    assert r.fancloud.info["unreferenced_dropped"] == 2
    assert len(pts) == mesh_input.n_points + 2  # the input arrays are not modified
