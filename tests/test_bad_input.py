"""Bad input: each a clear exception naming the problem, and the input left unchanged."""

import numpy as np
import pytest
import pyvista as pv
from conftest import dataset_fingerprint, fingerprint
from plyfile import PlyData, PlyElement
from shapes import sphere

from fancloud_vtk import (
    DuplicatePointsWarning,
    FanCloudInputError,
    build_fans,
    from_vtk,
    load,
    save,
    to_vtk,
)
from fancloud_vtk.io import FileReadError, read_point_cloud

N = 2000


def good():
    return sphere(N, seed=41)


def with_nan():
    p = good()
    p[17, 1] = np.nan
    return p


def with_inf():
    p = good()
    p[3] = [0.0, -np.inf, 1.0]
    return p


def collinear():
    return np.outer(np.linspace(-1.0, 1.0, 100), [0.3, -0.2, 0.9]) + [1.0, 2.0, 3.0]


def identical():
    return np.tile([0.5, -1.5, 2.0], (100, 1))


#: (points, error type, pattern): rejected by the core and by the accessor
POINT_CASES = {
    "nan": (with_nan, FanCloudInputError, r"NaN or infinite coordinates .* first at index 17"),
    "inf": (with_inf, FanCloudInputError, r"NaN or infinite coordinates .* first at index 3"),
    "too-few": (lambda: good()[:6], FanCloudInputError,
                r"k=6 needs at least k \+ 1 = 7 distinct points, got 6"),
    "empty": (lambda: np.empty((0, 3)), FanCloudInputError, "needs at least .* got 0"),
    "collinear": (collinear, FanCloudInputError, "all points are collinear"),
    "identical": (identical, FanCloudInputError, "all points are identical"),
}

#: arrays that are not an (n, 3) array of real numbers: the core only
ARRAY_CASES = {
    "(n, 2)": (lambda: good()[:, :2], FanCloudInputError, r"shape \(n, 3\), got \(2000, 2\)"),
    "(n, 3, 1)": (lambda: good()[:, :, None], FanCloudInputError,
                  r"shape \(n, 3\), got \(2000, 3, 1\)"),
    "1-D": (lambda: good().ravel(), FanCloudInputError, r"shape \(n, 3\), got \(6000,\)"),
    "scalar": (lambda: np.float64(1.0), FanCloudInputError, r"shape \(n, 3\), got \(\)"),
    "strings": (lambda: good().astype(str), TypeError, "real numbers, got dtype <U"),
    "complex": (lambda: good() + 0j, TypeError, "real numbers, got dtype complex128"),
    "object": (lambda: good().astype(object), TypeError, "real numbers, got dtype object"),
    "ragged": (lambda: [[0.0, 1.0, 2.0], [1.0, 2.0]], TypeError, "must be an .* of numbers"),
}


@pytest.mark.parametrize("case", list(POINT_CASES) + list(ARRAY_CASES))
def test_core_rejects_points(case):
    make, error, match = {**POINT_CASES, **ARRAY_CASES}[case]
    points = make()
    before = _snapshot(points)
    with pytest.raises(error, match=match):
        build_fans(points)
    assert _snapshot(points) == before


def _snapshot(points):
    return repr(points) if isinstance(points, list) else fingerprint(points)


@pytest.mark.parametrize("case", list(POINT_CASES))
def test_accessor_rejects_points_with_the_core_message(case):
    make, error, match = POINT_CASES[case]
    points = make()
    ds = pv.PolyData(points) if len(points) else pv.PolyData()
    before = dataset_fingerprint(ds)
    with pytest.raises(error, match=match):
        ds.fancloud.fans()
    assert dataset_fingerprint(ds) == before


def test_nan_message_shows_the_point():
    with pytest.raises(FanCloudInputError) as info:
        build_fans(with_nan())
    assert "at 1 point(s)" in str(info.value) and "nan" in str(info.value)
    assert isinstance(info.value, ValueError)


def test_rejected_before_any_work_for_bad_parameters():
    p = good()
    before = fingerprint(p)
    for kwargs, error, match in [
        ({"k": 2}, FanCloudInputError, "k must be between 3 and 64"),
        ({"k": 6.5}, TypeError, "k must be an integer"),
        ({"max_angle": 180.0}, FanCloudInputError, r"max_angle must be in \(0, 180\)"),
        ({"max_angle": "wide"}, TypeError, "max_angle must be a number"),
        ({"max_replacements": -1}, FanCloudInputError, "max_replacements must be between"),
        ({"rule": "nearest"}, FanCloudInputError, "rule must be one of"),
    ]:
        with pytest.raises(error, match=match):
            build_fans(p, **kwargs)
    assert fingerprint(p) == before


def test_bad_normals_and_point_data():
    p = good()
    normals = p.copy()
    normals[9] = 0.0
    label = np.arange(N - 1)
    before = fingerprint(p, normals, label)
    with pytest.raises(FanCloudInputError, match="normals has a zero vector at index 9"):
        build_fans(p, normals=normals)
    with pytest.raises(FanCloudInputError, match="normals must have 2000 rows"):
        build_fans(p, normals=normals[:10])
    with pytest.raises(FanCloudInputError, match=r"point array 'label' has shape \(1999,\)"):
        build_fans(p, point_data={"label": label})
    with pytest.raises(TypeError, match="point_data must be a mapping"):
        build_fans(p, point_data=[label])
    assert fingerprint(p, normals, label) == before


def test_k_plus_one_points_is_enough():
    p = good()[:7]
    fc = build_fans(p, k=6)
    assert fc.n_points == 7


# -- duplicates ------------------------------------------------------------------------


def test_duplicated_points_are_merged_and_mapped_back():
    base = good()
    rng = np.random.default_rng(5)
    dup_of = rng.choice(N, 50, replace=False)
    full = np.vstack([base, base[dup_of], base[dup_of[:10]]])  # some points three times
    order = rng.permutation(len(full))
    full = full[order]
    label = np.arange(len(full), dtype=np.int32)
    before = fingerprint(full, label)
    with pytest.warns(DuplicatePointsWarning, match="60 duplicate point") as record:
        fc = build_fans(full, point_data={"label": label})
    assert len(record) == 1
    assert record[0].filename == __file__  # the warning points at the caller's line
    assert fingerprint(full, label) == before
    assert fc.n_points == N and fc.info["duplicates_merged"] == 60
    ids = fc.point_data["original_id"]
    assert ids.dtype == np.int64 and np.all(np.diff(ids) > 0)
    np.testing.assert_array_equal(fc.points, full[ids])
    np.testing.assert_array_equal(fc.point_data["label"], label[ids])
    # the first of each set of identical points is kept, every distinct point once
    _, first = np.unique(full, axis=0, return_index=True)
    np.testing.assert_array_equal(ids, np.sort(first))
    assert fc.n_open == 0
    # the VTK round trip keeps the map
    back = from_vtk(to_vtk(fc))
    np.testing.assert_array_equal(back.point_data["original_id"], ids)


def test_duplicates_leaving_too_few_points():
    p = np.repeat(good()[:5], 3, axis=0)
    before = fingerprint(p)
    with pytest.warns(DuplicatePointsWarning), pytest.raises(
        FanCloudInputError, match="needs at least k \\+ 1 = 7 distinct points, got 5"
    ):
        build_fans(p)
    assert fingerprint(p) == before


# -- files -----------------------------------------------------------------------------


def test_truncated_or_garbage_fan_cloud_files(tmp_path):
    path = tmp_path / "fans.vtp"
    save(build_fans(good()), path)
    data = path.read_bytes()
    for name, content in [("half.vtp", data[: len(data) // 2]), ("head.vtp", data[:200]),
                          ("noise.vtp", bytes(range(256)) * 8)]:
        bad = tmp_path / name
        bad.write_bytes(content)
        with pytest.raises(ValueError, match=f"could not read .*{name}: vtkXMLPolyDataReader"):
            load(bad)
        assert bad.read_bytes() == content


def test_unreadable_point_files_name_the_problem(tmp_path):
    folder = tmp_path / "folder.ply"
    folder.mkdir()
    with pytest.raises(FileReadError, match="is a directory"):
        read_point_cloud(folder)
    empty = tmp_path / "empty.xyz"
    empty.write_bytes(b"")
    with pytest.raises(FileReadError, match="empty"):
        read_point_cloud(empty)


def test_ply_with_a_camera_element_gives_fans(tmp_path):
    p = good()
    vertex = np.empty(N, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("red", "u1"),
                                ("green", "u1"), ("blue", "u1")])
    for i, c in enumerate("xyz"):
        vertex[c] = p[:, i]
    for c in ("red", "green", "blue"):
        vertex[c] = 200
    camera = np.zeros(1, dtype=[(name, "f4") for name in (
        "view_px", "view_py", "view_pz", "x_axisx", "x_axisy", "x_axisz", "y_axisx", "y_axisy",
        "y_axisz", "z_axisx", "z_axisy", "z_axisz", "focal", "scalex", "scaley", "centerx",
        "centery")] + [("viewportx", "i4"), ("viewporty", "i4"), ("k1", "f4")])
    path = tmp_path / "scan.ply"
    PlyData([PlyElement.describe(camera, "camera"), PlyElement.describe(vertex, "vertex")]).write(
        str(path)
    )
    src = read_point_cloud(path)
    fc = build_fans(src.points, point_data=src.point_data)
    assert fc.n_points == N and fc.n_open == 0
    assert fc.colors.dtype == np.uint8 and np.all(fc.colors == 200)
