"""The VTK layer: FanCloudFilter in real pipelines, parameters, progress, errors."""

import subprocess
import sys

import numpy as np
import pytest
from conftest import dataset_fingerprint
from shapes import sphere
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkCommand, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
from vtkmodules.vtkIOPLY import vtkPLYReader, vtkPLYWriter
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader, vtkXMLPolyDataWriter

from fancloud_vtk import Cancelled, FanCloudInputError, build_fans, from_vtk
from fancloud_vtk.algorithms import (
    FanCloudEntropyFilter,
    FanCloudFilter,
    FanCloudMeshFilter,
    FanCloudReduceFilter,
    FanCloudSelectiveRefineFilter,
    fancloud_to_vtk,
    is_fancloud,
    run,
)
from fancloud_vtk.algorithms.convert import points_of
from fancloud_vtk.params import (
    ENTROPY_PARAMS,
    FAN_PARAMS,
    INPUT_PARAMS,
    MESH_PARAMS,
    REDUCE_PARAMS,
)

N = 2000


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


@pytest.fixture(scope="module")
def cloud():
    p = sphere(N, seed=11)
    rgb = (np.arange(3 * N) % 256).astype(np.uint8).reshape(N, 3)
    label = (np.arange(N) % 7).astype(np.int32)
    return p, rgb, label


def test_algorithms_layer_imports_no_pyvista():
    code = (
        "import fancloud_vtk.algorithms, fancloud_vtk.core, sys; "
        "bad = sorted(m for m in sys.modules if m.startswith('pyvista')); "
        "assert not bad, bad"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr


def test_filters_import_from_the_top_level_and_only_then_load_vtk():
    code = (
        "import sys, fancloud_vtk; "
        "vtk = lambda: sorted(m for m in sys.modules if m.split('.')[0] in ('vtkmodules', 'vtk')); "
        "assert not vtk(), vtk(); "
        "from fancloud_vtk import FanCloudReduceFilter, FanCloudRefineFilter; "
        "import fancloud_vtk.algorithms as a; "
        "assert FanCloudReduceFilter is a.FanCloudReduceFilter; "
        "assert FanCloudRefineFilter is a.FanCloudRefineFilter; "
        "assert set(fancloud_vtk._FILTERS) == {n for n in a.__all__ if n.endswith('Filter')}; "
        "assert vtk(); "
        "assert 'FanCloudEntropyFilter' in dir(fancloud_vtk); "
        "assert not hasattr(fancloud_vtk, 'NoSuchFilter')"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr


def _write_vtp(path, poly):
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    assert writer.Write() == 1


def _write_ply(path, poly):
    writer = vtkPLYWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    writer.SetArrayName("RGB")  # colours as PLY red/green/blue
    assert writer.Write() == 1


@pytest.mark.parametrize("fmt", ["vtp", "ply"])
def test_reader_fans_normals_mapper_pipeline(cloud, tmp_path, fmt):
    p, rgb, label = cloud
    path = tmp_path / f"cloud.{fmt}"
    if fmt == "vtp":
        _write_vtp(path, point_cloud(p, RGB=rgb, label=label))
        reader = vtkXMLPolyDataReader()
    else:
        _write_ply(path, point_cloud(p.astype(np.float32), RGB=rgb))
        reader = vtkPLYReader()
    reader.SetFileName(str(path))

    fans = FanCloudFilter(k=6)
    fans.SetInputConnection(reader.GetOutputPort())
    normals = vtkPolyDataNormals()
    normals.SetInputConnection(fans.GetOutputPort())
    normals.SplittingOff()  # keep the points one to one
    normals.ConsistencyOff()  # the fan triangles overlap: no manifold to re-orient over
    normals.ComputeCellNormalsOn()
    normals.Update()  # returns None on VTK 9.2 (ParaView 5.11): the output says how it went

    out = normals.GetOutput()
    assert out.GetNumberOfPoints() == N
    cells = out.GetPolys()
    assert cells.GetNumberOfCells() > 2 * N
    assert cells.IsHomogeneous() == 3, "every cell is a triangle"
    # the point arrays pass through the fan filter and the normals filter
    pd = out.GetPointData()
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("RGB")), rgb)
    if fmt == "vtp":
        np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("label")), label)
    assert vtk_to_numpy(pd.GetArray("fan_open")).shape == (N,)
    # the triangles are those of build_fans on the same points
    pts = vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    expected = build_fans(pts).triangles()
    got = vtk_to_numpy(cells.GetConnectivityArray()).reshape(-1, 3)
    np.testing.assert_array_equal(got, expected)
    # the fan triangles are consistently oriented with the fan normals (outward)
    cell_normals = vtk_to_numpy(out.GetCellData().GetNormals())
    centres = pts[got].mean(axis=1)
    assert np.mean(np.einsum("ij,ij->i", cell_normals, centres) > 0) > 0.99

    from vtkmodules.vtkRenderingCore import vtkPolyDataMapper

    mapper = vtkPolyDataMapper()
    mapper.SetInputConnection(normals.GetOutputPort())
    mapper.Update()
    assert mapper.GetInput().GetNumberOfPolys() == cells.GetNumberOfCells()


def test_output_matches_build_fans_and_input_is_unchanged(cloud):
    p, rgb, label = cloud
    poly = point_cloud(p, RGB=rgb, label=label)
    before = dataset_fingerprint(poly)
    mtime = poly.GetMTime()
    fans = FanCloudFilter(k=7, max_angle=80.0)
    fans.SetInputDataObject(0, poly)
    out = run(fans)
    assert is_fancloud(out)
    got = from_vtk(out)
    expected = build_fans(p, k=7, max_angle=80.0, point_data={"RGB": rgb, "label": label})
    for name in ("points", "offsets", "ring", "normals", "open", "rotated"):
        np.testing.assert_array_equal(getattr(got, name), getattr(expected, name), err_msg=name)
    np.testing.assert_array_equal(got.point_data["RGB"], rgb)
    assert dataset_fingerprint(poly) == before
    assert poly.GetMTime() == mtime
    assert poly.GetNumberOfCells() == 0


def test_input_normals_orient_the_fans(cloud):
    p = cloud[0]
    fans = FanCloudFilter()
    fans.SetInputDataObject(0, point_cloud(p, Normals=-p))
    out = from_vtk(run(fans))
    assert np.all(np.einsum("ij,ij->i", out.normals, p) < 0), "inward, as given"
    assert "Normals" not in out.point_data


def _other_value(param):
    """A valid value different from the default."""
    if param.kind == "bool":
        return not param.default
    if param.kind == "choice":
        return next(c for c in param.choices if c != param.default)
    if param.kind == "str":
        return "RGB"
    if param.kind == "vector":
        return tuple(v + 1.0 for v in param.default)
    return param.range[0] if param.default != param.range[0] else param.range[1]


#: every filter with its parameter table: the setter test runs on each
FILTER_PARAMS = (
    [(FanCloudFilter, p) for p in FAN_PARAMS + INPUT_PARAMS]
    + [(FanCloudMeshFilter, p) for p in FAN_PARAMS + INPUT_PARAMS + MESH_PARAMS]
    + [(FanCloudEntropyFilter, p) for p in FAN_PARAMS + INPUT_PARAMS + ENTROPY_PARAMS]
    + [(FanCloudReduceFilter, p) for p in FAN_PARAMS + INPUT_PARAMS + REDUCE_PARAMS]
    + [(FanCloudSelectiveRefineFilter, p) for p in FanCloudSelectiveRefineFilter.PARAMETERS]
)


@pytest.mark.parametrize(("cls", "param"), FILTER_PARAMS,
                         ids=[f"{c.__name__}-{p.name}" for c, p in FILTER_PARAMS])
def test_setters_call_modified_only_on_change(cls, param):
    fans = cls()
    setter = getattr(fans, "Set" + param.vtk_name)
    getter = getattr(fans, "Get" + param.vtk_name)
    assert getter() == param.default
    t0 = fans.GetMTime()
    setter(param.default)
    setattr(fans, param.name, param.default)
    assert fans.GetMTime() == t0, "same value: not modified"
    value = _other_value(param)
    setter(value)
    t1 = fans.GetMTime()
    assert t1 > t0
    assert getter() == value and getattr(fans, param.name) == value
    setattr(fans, param.name, value)
    assert fans.GetMTime() == t1
    setattr(fans, param.name, param.default)
    assert fans.GetMTime() > t1
    assert fans.parameters[param.name] == param.default


def test_numerically_equal_value_is_no_change():
    fans = FanCloudFilter()
    t0 = fans.GetMTime()
    fans.SetK(6.0)
    fans.SetMaxAngle(90)
    fans.SetK(np.int64(6))
    assert fans.GetMTime() == t0
    assert type(fans.GetK()) is int and type(fans.GetMaxAngle()) is float


def test_bad_parameter_values_are_rejected_without_modifying():
    fans = FanCloudFilter()
    t0 = fans.GetMTime()
    with pytest.raises(ValueError, match="k must be between 3 and 64, got 2"):
        fans.SetK(2)
    with pytest.raises(TypeError, match="k must be a number, got 'six'"):
        fans.k = "six"
    with pytest.raises(TypeError, match="k must be an integer, got 6.5"):
        fans.SetK(6.5)
    with pytest.raises(ValueError, match="rule must be one of"):
        fans.SetRule("nearest")
    with pytest.raises(TypeError, match="orient must be True or False"):
        fans.SetOrient("no")
    assert fans.GetMTime() == t0
    assert fans.parameters == {p.name: p.default for p in FAN_PARAMS + INPUT_PARAMS}
    with pytest.raises(TypeError, match="FanCloudFilter has no parameter 'kk'"):
        FanCloudFilter(kk=6)
    with pytest.raises(ValueError, match="max_angle must be between"):
        FanCloudFilter(max_angle=0.0)


def test_progress_events_are_fired(cloud):
    fans = FanCloudFilter()
    fans.SetInputDataObject(0, point_cloud(cloud[0]))
    seen = []
    texts = []

    def on_progress(caller, event):
        seen.append(caller.GetProgress())
        texts.append(caller.GetProgressText())

    fans.AddObserver(vtkCommand.ProgressEvent, on_progress)
    run(fans)
    assert len(seen) >= 3
    assert seen[-1] == 1.0
    assert all(b >= a for a, b in zip(seen, seen[1:], strict=False))
    assert any(0.0 < f < 1.0 for f in seen)
    assert "neighbour search" in texts


def test_abort_cancels_and_the_next_run_works(cloud):
    fans = FanCloudFilter()
    fans.SetInputDataObject(0, point_cloud(cloud[0]))
    state = {"events": 0}

    def abort_once(caller, event):
        state["events"] += 1
        if state["events"] == 2:
            caller.SetAbortExecute(1)

    fans.AddObserver(vtkCommand.ProgressEvent, abort_once)
    with pytest.raises(Cancelled):
        run(fans)
    fans.SetAbortExecute(0)  # VTK >= 9.3 keeps the flag until it is cleared
    assert run(fans).GetNumberOfPolys() > 0


def test_run_raises_the_error_without_printing_it_and_update_prints_it(cloud):
    from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow

    fans = FanCloudFilter()
    fans.SetInputDataObject(0, point_cloud(cloud[0][:5]))
    previous = vtkOutputWindow.GetInstance()
    capture = vtkStringOutputWindow()
    vtkOutputWindow.SetInstance(capture)
    try:
        with pytest.raises(FanCloudInputError, match="needs at least"):
            run(fans)
        assert "needs at least" not in (capture.GetOutput() or "")  # raised, not printed too
        fans.Modified()
        fans.Update()  # as ParaView runs it: the output window is where the error goes
        assert "FanCloudFilter: FanCloudInputError: " in capture.GetOutput()
    finally:
        vtkOutputWindow.SetInstance(previous)


def test_error_in_request_data_is_re_raised_and_a_fixed_input_runs(cloud):
    p = cloud[0].copy()
    p[17] = np.nan
    poly = point_cloud(p)
    fans = FanCloudFilter()
    fans.SetInputDataObject(0, poly)
    for _ in range(2):  # not a stale success the second time
        with pytest.raises(FanCloudInputError, match="NaN or infinite .* first at index 17"):
            run(fans)
        assert isinstance(fans.last_error, FanCloudInputError)
    # fix the input in place: the pipeline sees the modified points
    vtk_to_numpy(poly.GetPoints().GetData())[17] = cloud[0][17]
    poly.GetPoints().Modified()
    out = run(fans)
    assert fans.last_error is None
    assert out.GetNumberOfPoints() == N and out.GetNumberOfPolys() > 2 * N
    # and with a new input object
    bad = point_cloud(cloud[0][:5])
    fans.SetInputDataObject(0, bad)
    with pytest.raises(FanCloudInputError, match=r"needs at least k \+ 1 = 7 distinct points"):
        run(fans)
    fans.SetInputDataObject(0, point_cloud(cloud[0]))
    assert run(fans).GetNumberOfPoints() == N


def test_update_reports_failure_and_plain_update_after_it(cloud):
    p = cloud[0].copy()
    p[3, 1] = np.inf
    fans = FanCloudFilter()
    fans.SetInputDataObject(0, point_cloud(p))
    assert not fans.Update()  # False on VTK >= 9.3, None on 9.2
    assert fans.GetOutputDataObject(0).GetNumberOfPoints() == 0
    with pytest.raises(FanCloudInputError, match="infinite"):
        run(fans)


def test_failures_outside_request_data_are_raised(tmp_path):
    fans = FanCloudFilter()
    with pytest.raises(RuntimeError, match="0 connections"):
        run(fans)
    image = vtkImageData()
    image.SetDimensions(10, 10, 1)
    fans.SetInputDataObject(0, image)
    with pytest.raises(RuntimeError, match="vtkPointSet is required"):
        run(fans)
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(tmp_path / "missing.vtp"))
    fans.SetInputConnection(reader.GetOutputPort())
    with pytest.raises(RuntimeError, match="vtkXMLPolyDataReader: Error opening file"):
        run(fans)


def test_a_fan_cloud_as_input_gives_the_same_fans(cloud):
    first = fancloud_to_vtk(build_fans(cloud[0]))
    fans = FanCloudFilter()
    fans.SetInputDataObject(0, first)
    again = from_vtk(run(fans))
    np.testing.assert_array_equal(again.triangles(), from_vtk(first).triangles())
    assert sorted(again.point_data) == []  # the old fan arrays are not passed through twice


def test_points_of_rejects_non_point_sets():
    with pytest.raises(TypeError, match="expected a vtkPointSet .* got vtkImageData"):
        points_of(vtkImageData())
    with pytest.raises(TypeError, match="got None"):
        points_of(None)
