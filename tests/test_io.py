"""Tests for fancloud_vtk.io: point-cloud / mesh file readers."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from fancloud_vtk.io import (
    SUPPORTED_FORMATS,
    DroppedArrayWarning,
    FileReadError,
    PointCloudFile,
    read_point_cloud,
)

IO_SOURCE = Path(__file__).resolve().parents[1] / "fancloud_vtk" / "io.py"


# ----------------------------------------------------------------------------- helpers


def read_checked(path, **kwargs) -> PointCloudFile:
    """Read ``path``; check the file is untouched and the result's invariants."""
    before = Path(path).read_bytes()
    cloud = read_point_cloud(path, **kwargs)
    assert Path(path).read_bytes() == before, "reading modified the input file"

    assert isinstance(cloud, PointCloudFile)
    assert cloud.path == os.fspath(path)
    pts = cloud.points
    assert pts.dtype == np.float64 and pts.ndim == 2 and pts.shape[1] == 3
    assert pts.flags.c_contiguous and pts.flags.owndata
    n = pts.shape[0]
    for name, arr in cloud.point_data.items():
        assert arr.shape[0] == n, name
        assert arr.flags.owndata, name
        assert arr.dtype.isnative, name
    if "Normals" in cloud.point_data:
        assert cloud.point_data["Normals"].dtype == np.float64
        assert cloud.point_data["Normals"].shape == (n, 3)
    for key, width in (("RGB", 3), ("RGBA", 4)):
        if key in cloud.point_data:
            assert cloud.point_data[key].dtype == np.uint8
            assert cloud.point_data[key].shape == (n, width)
    if cloud.faces is not None:
        f = cloud.faces
        assert f.dtype == np.int64 and f.ndim == 2 and f.shape[1] == 3
        assert f.flags.c_contiguous and f.flags.owndata
        assert f.min() >= 0 and f.max() < n
    return cloud


def write_ply(path, vertex: np.ndarray, faces=None, *, text=False, byte_order="<", extra=()):
    """Write a PLY with plyfile; ``faces`` is a list of index lists (any lengths)."""
    elements = list(extra) + [PlyElement.describe(vertex, "vertex")]
    if faces is not None:
        fa = np.empty(len(faces), dtype=[("vertex_indices", "O")])
        for i, f in enumerate(faces):
            fa[i] = (np.asarray(f, dtype=np.int32),)
        elements.append(PlyElement.describe(fa, "face"))
    PlyData(elements, text=text, byte_order=byte_order).write(str(path))
    return path


TETRA = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def vertex_array(points, **columns) -> np.ndarray:
    dtype = [("x", "f4"), ("y", "f4"), ("z", "f4")]
    dtype += [(name, np.asarray(col).dtype.str) for name, col in columns.items()]
    v = np.empty(len(points), dtype=dtype)
    for i, c in enumerate("xyz"):
        v[c] = points[:, i]
    for name, col in columns.items():
        v[name] = col
    return v


def sample_mesh_dir() -> str:
    pymeshlab = pytest.importorskip("pymeshlab")
    return os.path.join(os.path.dirname(pymeshlab.__file__), "tests", "sample_meshes")


# ----------------------------------------------------------------------------- PLY


@pytest.mark.parametrize(
    ("text", "byte_order"), [(False, "<"), (False, ">"), (True, "=")], ids=["le", "be", "ascii"]
)
def test_ply_properties_colours_scalars_and_polygon_faces(tmp_path, text, byte_order):
    normals = np.array([[0, 0, -1], [0, -1, 0], [-1, 0, 0], [1, 1, 1] / np.sqrt(3)])
    rgb = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]], dtype=np.uint8)
    vertex = vertex_array(
        TETRA,
        nx=normals[:, 0].astype("f4"),
        ny=normals[:, 1].astype("f4"),
        nz=normals[:, 2].astype("f4"),
        red=rgb[:, 0],
        green=rgb[:, 1],
        blue=rgb[:, 2],
        quality=np.array([0.5, 1.5, 2.5, 3.5], dtype="f4"),
        intensity=np.array([1, 2, 3, 65535], dtype="u2"),
    )
    path = write_ply(
        tmp_path / "mesh.ply", vertex, [[0, 1, 2], [0, 3, 1, 2]], text=text, byte_order=byte_order
    )
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, TETRA)
    np.testing.assert_allclose(cloud.point_data["Normals"], normals, atol=1e-6)
    np.testing.assert_array_equal(cloud.point_data["RGB"], rgb)
    assert cloud.point_data["quality"].dtype == np.float32
    np.testing.assert_array_equal(cloud.point_data["quality"], [0.5, 1.5, 2.5, 3.5])
    assert cloud.point_data["intensity"].dtype == np.uint16
    np.testing.assert_array_equal(cloud.point_data["intensity"], [1, 2, 3, 65535])
    assert set(cloud.point_data) == {"Normals", "RGB", "quality", "intensity"}
    # The quad (0, 3, 1, 2) is fan-triangulated from its first vertex.
    np.testing.assert_array_equal(cloud.faces, [[0, 1, 2], [0, 3, 1], [0, 1, 2]])


def test_ply_all_triangles_fast_path_and_vertex_index_name(tmp_path):
    vertex = vertex_array(TETRA)
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]], dtype=np.int32)
    fa = np.empty(4, dtype=[("vertex_index", "i4", (3,))])
    fa["vertex_index"] = faces
    path = tmp_path / "tri.ply"
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(fa, "face")]).write(
        str(path)
    )
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.faces, faces)


def test_ply_float_colours_with_alpha_become_uint8_rgba(tmp_path):
    colours = np.array([[0.0, 0.5, 1.0, 1.0], [1.0, 0.2, 0.0, 0.25]] * 2, dtype="f4")
    vertex = vertex_array(
        TETRA,
        red=colours[:, 0],
        green=colours[:, 1],
        blue=colours[:, 2],
        alpha=colours[:, 3],
    )
    cloud = read_checked(write_ply(tmp_path / "c.ply", vertex))
    assert "RGB" not in cloud.point_data
    np.testing.assert_array_equal(
        cloud.point_data["RGBA"], np.round(255 * colours.astype(np.float64)).astype(np.uint8)
    )
    assert cloud.faces is None


def test_ply_with_meshlab_camera_element_is_read(tmp_path):
    cam_props = [
        "view_px", "view_py", "view_pz", "x_axisx", "x_axisy", "x_axisz", "y_axisx",
        "y_axisy", "y_axisz", "z_axisx", "z_axisy", "z_axisz", "focal", "scalex", "scaley",
        "centerx", "centery",
    ]  # fmt: skip
    cam = np.zeros(1, dtype=[(p, "f4") for p in cam_props] + [("viewportx", "i4")])
    cam["focal"] = 35.0
    cam["viewportx"] = 640
    edge = np.array([(0, 1), (1, 2)], dtype=[("vertex1", "i4"), ("vertex2", "i4")])
    extra = [PlyElement.describe(cam, "camera"), PlyElement.describe(edge, "edge")]
    vertex = vertex_array(TETRA, flags=np.zeros(4, dtype="i4"))
    for text in (False, True):
        path = write_ply(
            tmp_path / f"cam_{text}.ply", vertex, [[0, 1, 2], [0, 2, 3]], text=text, extra=extra
        )
        assert b"element camera 1" in path.read_bytes()
        cloud = read_checked(path)
        np.testing.assert_array_equal(cloud.points, TETRA)
        np.testing.assert_array_equal(cloud.faces, [[0, 1, 2], [0, 2, 3]])
        assert set(cloud.point_data) == {"flags"}


def test_real_meshlab_range_map_with_camera_element():
    path = os.path.join(sample_mesh_dir(), "rangemaps", "face000.ply")
    if not os.path.exists(path):
        pytest.skip("pymeshlab sample range map not installed")
    assert b"element camera" in Path(path).read_bytes()[:200]
    cloud = read_checked(path)
    assert cloud.points.shape == (85849, 3)
    assert cloud.faces.shape == (166259, 3)
    assert cloud.point_data["quality"].dtype == np.float32


def test_real_bone_ply_has_uint8_colours():
    path = os.path.join(sample_mesh_dir(), "bone.ply")
    cloud = read_checked(path)
    assert cloud.points.shape == (1872, 3)
    assert cloud.faces.shape == (3022, 3)
    # bone.ply stores red, green, blue and alpha (uchar): colours come back as RGBA.
    rgba = cloud.point_data["RGBA"]
    assert rgba.dtype == np.uint8 and rgba.shape == (1872, 4)
    assert "RGB" not in cloud.point_data
    raw = PlyData.read(path)["vertex"].data
    expected = np.column_stack([raw[c] for c in ("red", "green", "blue", "alpha")])
    np.testing.assert_array_equal(rgba, expected)
    assert cloud.point_data["flags"].dtype == np.int32


def test_real_colored_airplane_ply():
    path = os.path.join(sample_mesh_dir(), "colored_airplane.ply")
    cloud = read_checked(path)
    rgba = cloud.point_data["RGBA"]
    assert cloud.points.shape == (7017, 3) and rgba.shape == (7017, 4)
    assert len(np.unique(rgba[:, :3], axis=0)) > 1


def _face_array(faces, before=(), after=()):
    dtype = [(n, "i4") for n in before] + [("vertex_indices", "O")] + [(n, "f4") for n in after]
    fa = np.zeros(len(faces), dtype=dtype)
    for i, f in enumerate(faces):
        fa["vertex_indices"][i] = np.asarray(f, dtype=np.int32)
    for j, n in enumerate([*before, *after]):
        fa[n] = np.arange(len(faces)) * 0.5 + j
    return fa


@pytest.mark.parametrize(
    ("faces", "before", "after"),
    [
        ([[0, 1, 2], [0, 2, 3], [1, 2, 3]], (), ()),
        ([[0, 1, 2], [0, 1, 2, 3], [3, 2, 1, 0, 4]], (), ()),
        ([[0, 1, 2], [0, 2, 3]], ("flags",), ("quality",)),
        ([[0, 1, 2], [0, 1, 2, 3]], (), ("quality",)),
        ([[4, 3, 2, 1]] * 3, (), ()),
    ],
    ids=["triangles", "polygons", "tri+scalars", "poly+scalars", "quads"],
)
def test_ascii_ply_matches_binary_ply(tmp_path, faces, before, after):
    # ASCII PLY has a vectorised reader with plyfile as the fallback; binary always uses
    # plyfile. Both must give the same result.
    rng = np.random.default_rng(3)
    pts = rng.random((5, 3)) * 1000
    vertex = vertex_array(
        pts,
        flags=np.array([0, -1, 2**31 - 1, 5, 6], dtype="i4"),
        red=np.array([0, 1, 2, 254, 255], dtype="u1"),
        green=np.arange(5, dtype="u1"),
        blue=np.arange(5, dtype="u1"),
        weight=rng.random(5),
    )
    cam = np.zeros(1, dtype=[("view_px", "f4"), ("view_py", "f4")])
    fa = PlyElement.describe(_face_array(faces, before, after), "face")
    extra = [PlyElement.describe(cam, "camera")]
    clouds = []
    for text in (True, False):
        path = tmp_path / f"m_{text}.ply"
        PlyData([*extra, PlyElement.describe(vertex, "vertex"), fa], text=text).write(str(path))
        clouds.append(read_checked(path))
    asc, binary = clouds
    np.testing.assert_array_equal(asc.points, binary.points)
    np.testing.assert_array_equal(asc.points, pts.astype(np.float32))
    np.testing.assert_array_equal(asc.faces, binary.faces)
    assert asc.point_data.keys() == binary.point_data.keys() == {"flags", "RGB", "weight"}
    for key, value in binary.point_data.items():
        assert asc.point_data[key].dtype == value.dtype, key
        np.testing.assert_array_equal(asc.point_data[key], value)


def test_large_ascii_ply_is_fast(tmp_path):
    # plyfile alone parses ASCII PLY line by line in Python (~15 s for this file).
    n = 100_000
    rng = np.random.default_rng(4)
    pts = np.round(rng.random((n, 3)), 6)
    tris = rng.integers(0, n, (2 * n, 3))
    header = (
        f"ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n"
        f"property float z\nelement face {2 * n}\nproperty list uchar int vertex_indices\n"
        "end_header\n"
    )
    path = tmp_path / "big_ascii.ply"
    with open(path, "w") as fh:
        fh.write(header)
        fh.write("".join(f"{x} {y} {z}\n" for x, y, z in pts.tolist()))
        fh.write("".join(f"3 {a} {b} {c}\n" for a, b, c in tris.tolist()))
    t0 = time.perf_counter()
    cloud = read_point_cloud(path)
    elapsed = time.perf_counter() - t0
    np.testing.assert_array_equal(cloud.points, pts.astype(np.float32))
    np.testing.assert_array_equal(cloud.faces, tris)
    assert elapsed < 5.0, f"{n}-vertex ASCII PLY took {elapsed:.1f} s"


def test_ascii_ply_malformed_or_short_body_is_an_error(tmp_path):
    path = write_ply(tmp_path / "a.ply", vertex_array(TETRA), [[0, 1, 2]], text=True)
    good = path.read_text()
    path.write_text(good.replace("\n1 0 0", "\n1 zero 0"))
    with pytest.raises(FileReadError, match="not a valid PLY file.*malformed input"):
        read_point_cloud(path)
    path.write_text(good.rsplit("\n", 3)[0] + "\n")
    with pytest.raises(FileReadError, match="not a valid PLY file.*early end-of-file"):
        read_point_cloud(path)


def test_ply_empty_vertex_element_is_an_error(tmp_path):
    path = write_ply(tmp_path / "empty.ply", vertex_array(np.zeros((0, 3))))
    with pytest.raises(FileReadError, match="'vertex' element is empty"):
        read_point_cloud(path)


def test_ply_without_vertex_element_is_an_error(tmp_path):
    other = np.zeros(2, dtype=[("a", "f4")])
    path = tmp_path / "novertex.ply"
    PlyData([PlyElement.describe(other, "camera")]).write(str(path))
    with pytest.raises(FileReadError, match="no 'vertex' element"):
        read_point_cloud(path)


def test_ply_face_index_out_of_range_is_an_error(tmp_path):
    path = write_ply(tmp_path / "bad_face.ply", vertex_array(TETRA), [[0, 1, 7]])
    with pytest.raises(FileReadError, match="references vertex 7 but there are only 4"):
        read_point_cloud(path)


def test_truncated_binary_ply_is_an_error(tmp_path):
    rng = np.random.default_rng(0)
    pts = rng.random((500, 3))
    good = write_ply(tmp_path / "good.ply", vertex_array(pts), [[0, 1, 2, 3]] * 300)
    read_checked(good)
    raw = good.read_bytes()
    for name, cut in (("tri.ply", raw[: len(raw) // 2]), ("header.ply", raw[:40])):
        bad = tmp_path / name
        bad.write_bytes(cut)
        with pytest.raises(FileReadError, match=r"not a valid PLY file") as info:
            read_point_cloud(bad)
        assert info.value.__cause__ is not None
        assert str(bad) in str(info.value)
        assert bad.read_bytes() == cut

    # Triangles only (memory-mapped fast path) must also detect the truncation.
    tri = write_ply(tmp_path / "tri_good.ply", vertex_array(pts), [[0, 1, 2]] * 300)
    raw = tri.read_bytes()
    tri.write_bytes(raw[: len(raw) - 100])
    with pytest.raises(FileReadError, match="early end-of-file"):
        read_point_cloud(tri)


def test_garbage_bytes_with_ply_extension_is_an_error(tmp_path):
    path = tmp_path / "garbage.ply"
    path.write_bytes(np.random.default_rng(1).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    with pytest.raises(FileReadError, match=r"garbage\.ply.*not a valid PLY file"):
        read_point_cloud(path)


# ----------------------------------------------------------------------------- OBJ

OBJ_MIXED = """\
# exported by hand
mtllib scene.mtl
o thing
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 0.5 1
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1
vn 0 0 1
vn 0 0 1
vn 0 0 1
vn 0 0 1
g group1
usemtl red
s off
f 1 2 3
f 1/1 3/2 4/3
f 1/1/1 2/2/2 5/3/5
f 2//2 3//3 5//5
f -5 -4 -3 -2
l 1 2
"""


def test_obj_all_face_token_forms_and_negative_indices(tmp_path):
    path = tmp_path / "mixed.obj"
    path.write_text(OBJ_MIXED)
    cloud = read_checked(path)
    np.testing.assert_array_equal(
        cloud.points, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]]
    )
    np.testing.assert_array_equal(
        cloud.faces, [[0, 1, 2], [0, 2, 3], [0, 1, 4], [1, 2, 4], [0, 1, 2], [0, 2, 3]]
    )
    np.testing.assert_array_equal(cloud.point_data["Normals"], np.tile([0.0, 0, 1], (5, 1)))


@pytest.mark.parametrize(
    "form", ["{v}", "{v}/{v}", "{v}/{v}/{v}", "{v}//{v}", "-{r}", "-{r}//-{r}"]
)
def test_obj_uniform_token_forms(tmp_path, form):
    rng = np.random.default_rng(2)
    pts = rng.random((30, 3))
    tris = rng.integers(0, 30, (40, 3))
    quads = rng.integers(0, 30, (5, 4))
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in pts]
    lines += [f"vt {i} 0" for i in range(31)] + ["vn 0 0 1"] * 31
    for face in [*tris, *quads]:
        toks = [form.format(v=i + 1, r=30 - i) for i in face]
        lines.append("f " + " ".join(toks))
    path = tmp_path / "uniform.obj"
    path.write_text("\n".join(lines) + "\n")
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, pts)
    expected = [*tris.tolist()]
    for q in quads:
        expected += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
    np.testing.assert_array_equal(cloud.faces, expected)
    assert "Normals" not in cloud.point_data  # 31 normals for 30 vertices


def test_obj_relative_indices_refer_to_preceding_vertices(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 0 0\nv 6 0 0\nv 5 1 0\nf -3 -2 -1\n"
    path = tmp_path / "rel.obj"
    path.write_text(text)
    np.testing.assert_array_equal(read_checked(path).faces, [[0, 1, 2], [3, 4, 5]])


def test_obj_vertex_colours_crlf_indentation_and_comments(tmp_path):
    text = (
        "# colours in v lines\r\n"
        "  v 0 0 0 1 0 0\r\n"
        "\tv 1 0 0 0 1 0.5 # trailing comment\r\n"
        "v 0 1 0 0 0 1\r\n"
        "f 1 2 3 # a face\r\n"
    )
    path = tmp_path / "colour.obj"
    path.write_bytes(text.encode())
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, TETRA[:3])
    np.testing.assert_array_equal(
        cloud.point_data["RGB"], [[255, 0, 0], [0, 255, 128], [0, 0, 255]]
    )
    np.testing.assert_array_equal(cloud.faces, [[0, 1, 2]])


def test_obj_point_cloud_without_faces(tmp_path):
    path = tmp_path / "cloud.obj"
    path.write_text("v 1 2 3\nv 4 5 6\nv 7 8 9\n")
    cloud = read_checked(path)
    assert cloud.faces is None
    assert cloud.point_data == {}
    np.testing.assert_array_equal(cloud.points, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])


def test_real_stanford_bunny_obj():
    path = os.path.join(sample_mesh_dir(), "bunny.obj")
    t0 = time.perf_counter()
    cloud = read_checked(path)
    elapsed = time.perf_counter() - t0
    assert cloud.points.shape == (28088, 3)
    assert cloud.faces.shape == (56172, 3)
    assert cloud.point_data["Normals"].shape == (28088, 3)
    # Every vertex is used by some triangle.
    assert np.unique(cloud.faces).size == 28088
    assert elapsed < 2.0, f"bunny.obj took {elapsed:.2f} s"


@pytest.mark.parametrize(
    ("n", "budget"),
    [(200, 5.0), pytest.param(1000, 20.0, marks=pytest.mark.slow)],
    ids=["40k", "1M"],
)
def test_large_grid_obj_is_fast(tmp_path, n, budget):
    xs, ys = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(n * n)])
    idx = np.arange(n * n).reshape(n, n) + 1
    a, b, c = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()
    path = tmp_path / "big.obj"
    with open(path, "w") as fh:
        fh.write("".join(f"v {x:.1f} {y:.1f} 0\n" for x, y, _ in pts.tolist()))
        fh.write("".join("vn 0 0 1\n" for _ in range(n * n)))
        fh.write(
            "".join(
                f"f {i}//{i} {j}//{j} {k}//{k}\n" for i, j, k in np.column_stack([a, b, c]).tolist()
            )
        )
    t0 = time.perf_counter()
    cloud = read_point_cloud(path)
    elapsed = time.perf_counter() - t0
    np.testing.assert_array_equal(cloud.points, pts)
    np.testing.assert_array_equal(cloud.faces, np.column_stack([a, b, c]) - 1)
    assert cloud.point_data["Normals"].shape == (n * n, 3)
    assert elapsed < budget, f"{n * n}-vertex OBJ took {elapsed:.1f} s"


def test_obj_non_numeric_vertex_is_an_error(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(FileReadError, match=r"line 2: non-numeric value: 'v 1 zero 0'"):
        read_point_cloud(path)


def test_obj_malformed_face_and_zero_index_are_errors(tmp_path):
    path = tmp_path / "badface.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 two 3\n")
    with pytest.raises(FileReadError, match=r"line 5: malformed face vertex"):
        read_point_cloud(path)
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 0 1 2\n")
    with pytest.raises(FileReadError, match=r"line 5: vertex index 0"):
        read_point_cloud(path)
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    with pytest.raises(FileReadError, match=r"references vertex 3 but there are only 3"):
        read_point_cloud(path)


def test_obj_without_vertices_is_an_error(tmp_path):
    path = tmp_path / "novert.obj"
    path.write_text("# nothing but comments\nvn 0 0 1\n")
    with pytest.raises(FileReadError, match="no 'v' \\(vertex\\) lines"):
        read_point_cloud(path)


# ----------------------------------------------------------------------------- text


def test_xyz_three_columns_with_comments_and_commas(tmp_path):
    path = tmp_path / "p.xyz"
    path.write_text("# x y z\n0 0 0\n\n1,0,0\n0 1 0  # inline comment\n")
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, TETRA[:3])
    assert cloud.point_data == {} and cloud.faces is None


def test_xyz_six_columns_normals_or_colours(tmp_path):
    normals = np.array([[0, 0, 1], [0.6, 0.8, 0], [0, -1, 0]])
    path = tmp_path / "n.xyz"
    np.savetxt(path, np.hstack([TETRA[:3], normals]))
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.point_data["Normals"], normals)
    assert "RGB" not in cloud.point_data

    int_rgb = np.array([[255, 0, 0], [0, 128, 0], [7, 8, 9]])
    np.savetxt(path, np.hstack([TETRA[:3], int_rgb]), fmt="%g")
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.point_data["RGB"], int_rgb)
    assert "Normals" not in cloud.point_data

    float_rgb = np.array([[1.0, 0.0, 0.0], [0.2, 0.4, 0.6], [0.0, 0.0, 0.0]])
    np.savetxt(path, np.hstack([TETRA[:3], float_rgb]))
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.point_data["RGB"], [[255, 0, 0], [51, 102, 153], [0, 0, 0]])


def test_xyz_nine_columns(tmp_path):
    normals = np.array([[0, 0, 1], [0, 1, 0], [1, 0, 0]])
    rgb = np.array([[10, 20, 30], [40, 50, 60], [70, 80, 255]])
    path = tmp_path / "full.txt"
    np.savetxt(path, np.hstack([TETRA[:3], normals, rgb]), fmt="%g")
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, TETRA[:3])
    np.testing.assert_array_equal(cloud.point_data["Normals"], normals)
    np.testing.assert_array_equal(cloud.point_data["RGB"], rgb)


def test_pts_with_count_header_and_intensity(tmp_path):
    path = tmp_path / "scan.pts"
    path.write_text("3\n0 0 0 -1200 255 0 0\n1 0 0 17 0 255 0\n0 1 0 5 0 0 255\n")
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, TETRA[:3])
    np.testing.assert_array_equal(cloud.point_data["intensity"], [-1200, 17, 5])
    np.testing.assert_array_equal(cloud.point_data["RGB"], 255 * np.eye(3))
    assert cloud.point_data["RGB"].dtype == np.uint8

    path.write_text("2\n0 0 0\n1 2 3\n")
    np.testing.assert_array_equal(read_checked(path).points, [[0, 0, 0], [1, 2, 3]])


def test_text_ragged_rows_is_an_error(tmp_path):
    path = tmp_path / "ragged.xyz"
    path.write_text("# header\n0 0 0\n1 0 0\n1 2 3 4\n")
    with pytest.raises(FileReadError, match=r"line 4 has 4 columns but line 2 has 3"):
        read_point_cloud(path)


def test_text_non_numeric_token_is_an_error(tmp_path):
    path = tmp_path / "words.txt"
    path.write_text("0 0 0\n1 abc 0\n")
    with pytest.raises(FileReadError, match=r"line 2: non-numeric token 'abc'"):
        read_point_cloud(path)
    assert path.read_text() == "0 0 0\n1 abc 0\n"


def test_text_too_few_columns_or_no_data_is_an_error(tmp_path):
    path = tmp_path / "two.xyz"
    path.write_text("0 0\n1 1\n")
    with pytest.raises(FileReadError, match=r"2 column\(s\); need at least 3"):
        read_point_cloud(path)
    path.write_text("# only a comment\n\n")
    with pytest.raises(FileReadError, match="no points"):
        read_point_cloud(path)


# ----------------------------------------------------------------------------- npy


def test_npy_points_and_extra_columns(tmp_path):
    path = tmp_path / "p.npy"
    np.save(path, TETRA.astype(np.float32))
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, TETRA)

    normals = np.array([[0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 0, -1]], dtype=float)
    np.save(path, np.hstack([TETRA, normals]))
    np.testing.assert_array_equal(read_checked(path).point_data["Normals"], normals)

    np.save(path, np.asfortranarray(np.hstack([TETRA, normals, 255 * normals[:, ::-1] ** 2])))
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.point_data["RGB"], 255 * normals[:, ::-1] ** 2)


def test_npy_wrong_shape_or_dtype_is_an_error(tmp_path):
    path = tmp_path / "bad.npy"
    np.save(path, np.zeros((5, 2)))
    with pytest.raises(FileReadError, match=r"shape \(5, 2\); expected \(n, 3\)"):
        read_point_cloud(path)
    np.save(path, np.zeros(6))
    with pytest.raises(FileReadError, match=r"shape \(6,\)"):
        read_point_cloud(path)
    np.save(path, np.array([["a", "b", "c"]]))
    with pytest.raises(FileReadError, match="not real numeric"):
        read_point_cloud(path)
    np.save(path, np.array([[{"a": 1}, 2, 3]], dtype=object))
    with pytest.raises(FileReadError, match="not a valid .npy file"):
        read_point_cloud(path)


def test_npz_archive_named_npy_is_an_error(tmp_path):
    path = tmp_path / "archive.npy"
    with open(path, "wb") as fh:
        np.savez(fh, points=TETRA)
    with pytest.raises(FileReadError, match="expected a single .npy array, got NpzFile"):
        read_point_cloud(path)


# ----------------------------------------------------------------------------- VTK


def _vtk_polydata(with_polys=True):
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], dtype=float)
    poly = vtkPolyData()
    vp = vtkPoints()
    vp.SetData(numpy_to_vtk(pts, deep=True))
    poly.SetPoints(vp)
    if with_polys:
        cells = vtkCellArray()
        for cell in ([0, 1, 4], [0, 1, 2, 3], [2, 3, 4]):
            cells.InsertNextCell(len(cell), cell)
        poly.SetPolys(cells)
    temp = numpy_to_vtk(np.linspace(0.0, 1.0, 5).astype(np.float32), deep=True)
    temp.SetName("temperature")
    poly.GetPointData().AddArray(temp)
    normals = numpy_to_vtk(np.tile([0.0, 0.0, 1.0], (5, 1)).astype(np.float32), deep=True)
    normals.SetName("MyNormals")
    poly.GetPointData().SetNormals(normals)
    ids = numpy_to_vtk(np.arange(10, dtype=np.int64).reshape(5, 2), deep=True)
    ids.SetName("pairs")
    poly.GetPointData().AddArray(ids)
    return poly, pts


def test_vtp_round_trip_arrays_normals_and_triangles(tmp_path):
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    poly, pts = _vtk_polydata()
    for mode in ("SetDataModeToBinary", "SetDataModeToAscii", "SetDataModeToAppended"):
        path = tmp_path / f"mesh_{mode}.vtp"
        writer = vtkXMLPolyDataWriter()
        writer.SetFileName(str(path))
        writer.SetInputData(poly)
        getattr(writer, mode)()
        assert writer.Write() == 1
        cloud = read_checked(path)
        np.testing.assert_array_equal(cloud.points, pts)
        np.testing.assert_array_equal(cloud.faces, [[0, 1, 4], [0, 1, 2], [0, 2, 3], [2, 3, 4]])
        assert cloud.point_data["temperature"].dtype == np.float32
        np.testing.assert_allclose(cloud.point_data["temperature"], np.linspace(0, 1, 5))
        np.testing.assert_array_equal(cloud.point_data["Normals"], np.tile([0.0, 0, 1], (5, 1)))
        np.testing.assert_array_equal(cloud.point_data["pairs"], np.arange(10).reshape(5, 2))


def test_vtp_point_cloud_without_polys_and_colour_scalars(tmp_path):
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    poly, pts = _vtk_polydata(with_polys=False)
    rgb = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [1, 2, 3], [4, 5, 6]], dtype=np.uint8)
    colours = numpy_to_vtk(rgb, deep=True)
    colours.SetName("Colors")
    poly.GetPointData().SetScalars(colours)
    path = tmp_path / "cloud.vtp"
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    writer.Write()
    cloud = read_checked(path)
    assert cloud.faces is None
    np.testing.assert_array_equal(cloud.points, pts)
    np.testing.assert_array_equal(cloud.point_data["RGB"], rgb)
    np.testing.assert_array_equal(cloud.point_data["Colors"], rgb)


@pytest.mark.parametrize("binary", [False, True], ids=["ascii", "binary"])
def test_legacy_vtk_round_trip(tmp_path, binary):
    from vtkmodules.vtkIOLegacy import vtkPolyDataWriter

    poly, pts = _vtk_polydata()
    path = tmp_path / "mesh.vtk"
    writer = vtkPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    if binary:
        writer.SetFileTypeToBinary()
    writer.Write()
    cloud = read_checked(path)
    np.testing.assert_allclose(cloud.points, pts)
    np.testing.assert_array_equal(cloud.faces, [[0, 1, 4], [0, 1, 2], [0, 2, 3], [2, 3, 4]])
    np.testing.assert_allclose(cloud.point_data["temperature"], np.linspace(0, 1, 5), rtol=1e-6)
    np.testing.assert_array_equal(cloud.point_data["Normals"], np.tile([0.0, 0, 1], (5, 1)))
    np.testing.assert_array_equal(cloud.point_data["pairs"], np.arange(10).reshape(5, 2))


def test_vtu_points_and_arrays(tmp_path):
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import VTK_VERTEX, vtkUnstructuredGrid
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    grid = vtkUnstructuredGrid()
    vp = vtkPoints()
    vp.SetData(numpy_to_vtk(TETRA, deep=True))
    grid.SetPoints(vp)
    for i in range(4):
        grid.InsertNextCell(VTK_VERTEX, 1, [i])
    arr = numpy_to_vtk(np.array([1.0, 2.0, 3.0, 4.0]), deep=True)
    arr.SetName("weight")
    grid.GetPointData().AddArray(arr)
    path = tmp_path / "grid.vtu"
    writer = vtkXMLUnstructuredGridWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(grid)
    writer.Write()
    cloud = read_checked(path)
    np.testing.assert_array_equal(cloud.points, TETRA)
    np.testing.assert_array_equal(cloud.point_data["weight"], [1, 2, 3, 4])
    assert cloud.faces is None


@pytest.mark.parametrize("ext", ["vtp", "vtu", "vtk"])
def test_vtk_garbage_is_an_error_and_silent(tmp_path, capfd, ext):
    from vtkmodules.vtkCommonCore import vtkLogger, vtkOutputWindow

    window = vtkOutputWindow.GetInstance()
    verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    path = tmp_path / f"garbage.{ext}"
    path.write_bytes(b"this is not a VTK file\x00\x01\x02")
    reader = {"vtp": "vtkXMLPolyDataReader", "vtu": "vtkXMLUnstructuredGridReader"}.get(
        ext, "vtkDataSetReader"
    )
    with pytest.raises(FileReadError, match=rf"garbage\.{ext}.*VTK {reader} failed: .+") as info:
        read_point_cloud(path)
    assert "0x" not in str(info.value)  # object addresses are stripped
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert vtkOutputWindow.GetInstance() is window
    assert vtkLogger.GetCurrentVerbosityCutoff() == verbosity


def test_truncated_vtp_is_an_error(tmp_path):
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    poly, _ = _vtk_polydata()
    path = tmp_path / "cut.vtp"
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    writer.SetDataModeToAscii()
    writer.Write()
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(FileReadError, match=r"cut\.vtp.*vtkXMLPolyDataReader failed"):
        read_point_cloud(path)


def test_legacy_vtk_image_data_is_not_a_point_set(tmp_path):
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkIOLegacy import vtkStructuredPointsWriter

    image = vtkImageData()
    image.SetDimensions(2, 2, 2)
    path = tmp_path / "image.vtk"
    writer = vtkStructuredPointsWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(image)
    writer.Write()
    with pytest.raises(
        FileReadError, match=r"produced vtk(StructuredPoints|ImageData), not a point set"
    ):
        read_point_cloud(path)


def test_vtk_file_without_points_is_an_error(tmp_path):
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    path = tmp_path / "nothing.vtp"
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(vtkPolyData())
    writer.Write()
    # VTK 9.2's reader itself reports "No Points element ..."; later ones read it empty
    with pytest.raises(FileReadError, match="(?i)no points"):
        read_point_cloud(path)


# ----------------------------------------------------------------------------- STL


def _write_stl_with_vtk(path, poly, binary):
    from vtkmodules.vtkIOGeometry import vtkSTLWriter

    writer = vtkSTLWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    if binary:
        writer.SetFileTypeToBinary()
    else:
        writer.SetFileTypeToASCII()
    assert writer.Write() == 1
    return path


def _stl_ascii(triangles) -> bytes:
    """An ASCII STL of ``triangles`` (``(t, 3, 3)`` corner coordinates), written by hand."""
    lines = ["solid test"]
    for tri in triangles:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {x:.17g} {y:.17g} {z:.17g}" for x, y, z in tri]
        lines += ["    endloop", "  endfacet"]
    return ("\n".join([*lines, "endsolid test", ""])).encode("ascii")


def _stl_binary(triangles) -> bytes:
    """A binary STL of ``triangles``: 80-byte header, uint32 count, 50 bytes per facet."""
    facets = np.zeros(len(triangles), dtype=[("normal", "<f4", 3), ("corners", "<f4", (3, 3)),
                                             ("attribute", "<u2")])
    facets["corners"] = triangles
    header = b"binary STL written by test_io".ljust(80, b" ")
    return header + np.uint32(len(triangles)).astype("<u4").tobytes() + facets.tobytes()


#: two triangles of the unit square (sharing the edge 1-2) and one apart from them
STL_POINTS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [5, 5, 5], [6, 5, 5],
                       [5, 6, 5]], dtype=float)
STL_TRIANGLES = np.array([[0, 1, 2], [2, 1, 3], [4, 5, 6]])


@pytest.mark.parametrize("binary", [False, True], ids=["ascii", "binary"])
def test_stl_written_by_hand_is_an_indexed_triangle_mesh(tmp_path, binary):
    corners = STL_POINTS[STL_TRIANGLES]  # 9 corners, 7 distinct
    path = tmp_path / "hand.stl"
    path.write_bytes(_stl_binary(corners) if binary else _stl_ascii(corners))
    cloud = read_checked(path)
    assert cloud.points.shape == (7, 3) and cloud.faces.shape == (3, 3)
    # the same triangles, corners in the file's order (so the same orientation)
    np.testing.assert_array_equal(cloud.points[cloud.faces], corners)
    assert len(np.unique(cloud.points, axis=0)) == 7
    assert cloud.point_data == {}


@pytest.mark.parametrize("binary", [False, True], ids=["ascii", "binary"])
def test_stl_written_by_vtk_reads_back_shared_vertices(tmp_path, binary):
    from vtkmodules.vtkFiltersSources import vtkSphereSource

    source = vtkSphereSource()
    source.SetThetaResolution(12)
    source.SetPhiResolution(9)
    source.Update()
    sphere = source.GetOutput()
    path = _write_stl_with_vtk(tmp_path / "sphere.stl", sphere, binary)
    assert path.read_bytes().startswith(b"solid") != binary
    cloud = read_checked(path)
    n_points, n_triangles = sphere.GetNumberOfPoints(), sphere.GetNumberOfPolys()
    assert (n_points, n_triangles) == (2 + 12 * 7, 2 * 12 * 7)
    assert cloud.points.shape == (n_points, 3)
    assert cloud.faces.shape == (n_triangles, 3)
    # every vertex is used, each triangle has three distinct ones, and (a closed
    # surface) every edge is shared by exactly two triangles: the corners were merged
    assert set(np.unique(cloud.faces)) == set(range(n_points))
    assert np.all(np.diff(np.sort(cloud.faces, axis=1), axis=1) > 0)
    edges = np.sort(cloud.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)
    np.testing.assert_allclose(np.linalg.norm(cloud.points, axis=1), 0.5, rtol=1e-6)


def test_stl_by_format_override(tmp_path):
    path = tmp_path / "mesh.dat"
    path.write_bytes(_stl_ascii(STL_POINTS[STL_TRIANGLES]))
    cloud = read_checked(path, format="STL")
    assert cloud.points.shape == (7, 3) and cloud.faces.shape == (3, 3)


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (b"this is not an STL file\x00\x01\x02" * 3, r"VTK vtkSTLReader failed: .+"),
        (b"solid x\nthis is not an STL file\n", r"VTK vtkSTLReader failed: .+"),
        (b"solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 zz\n",
         r"VTK vtkSTLReader failed: .+"),
        (_stl_binary(STL_POINTS[STL_TRIANGLES])[:-30], r"VTK vtkSTLReader failed: .+"),
        (b"solid empty\nendsolid empty\n", "the file contains no points"),
        (_stl_binary(np.zeros((0, 3, 3))), "the file contains no points"),
    ],
    ids=["garbage", "bad-ascii", "bad-vertex", "truncated-binary", "no-facets-ascii",
         "no-facets-binary"],
)
def test_bad_or_empty_stl_is_an_error_and_silent(tmp_path, capfd, content, reason):
    from vtkmodules.vtkCommonCore import vtkLogger, vtkOutputWindow

    window = vtkOutputWindow.GetInstance()
    verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    path = tmp_path / "bad.stl"
    path.write_bytes(content)
    with pytest.raises(FileReadError, match=rf"bad\.stl.*{reason}") as info:
        read_point_cloud(path)
    assert "0x" not in str(info.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert vtkOutputWindow.GetInstance() is window
    assert vtkLogger.GetCurrentVerbosityCutoff() == verbosity


def test_stl_mesh_through_the_command(tmp_path, capsys):
    from vtkmodules.vtkFiltersSources import vtkSphereSource

    from fancloud_vtk import load
    from fancloud_vtk.cli import main

    source = vtkSphereSource()
    source.SetThetaResolution(24)
    source.SetPhiResolution(16)
    source.Update()
    src = _write_stl_with_vtk(tmp_path / "sphere.stl", source.GetOutput(), binary=True)
    out = tmp_path / "fans.vtp"
    assert main(["fans", str(src), "-o", str(out), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    fc = load(out)
    np.testing.assert_array_equal(fc.points, read_checked(src).points)


# ----------------------------------------------------------------------------- dropped arrays


def _poly_with_point_arrays(*arrays):
    """:func:`_vtk_polydata` (arrays 'temperature', 'pairs', normals) with ``arrays`` added."""
    poly, pts = _vtk_polydata()
    for arr in arrays:
        poly.GetPointData().AddArray(arr)
    return poly, pts


def _bit_array(name, bits, components=1):
    from vtkmodules.vtkCommonCore import vtkBitArray

    arr = vtkBitArray()
    arr.SetName(name)
    arr.SetNumberOfComponents(components)
    arr.SetNumberOfTuples(len(bits) // components)
    for i, b in enumerate(bits):
        arr.SetValue(i, int(b))
    return arr


def _string_array(name, values):
    from vtkmodules.vtkCommonCore import vtkStringArray

    arr = vtkStringArray()
    arr.SetName(name)
    for v in values:
        arr.InsertNextValue(v)
    return arr


def _write_vtk(poly, path):
    from vtkmodules.vtkIOLegacy import vtkPolyDataWriter
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    writer = vtkXMLPolyDataWriter() if path.suffix == ".vtp" else vtkPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    assert writer.Write() == 1
    return path


BITS = np.array([1, 0, 0, 1, 1], dtype=np.uint8)
BITS3 = (np.arange(15) % 4 == 0).astype(np.uint8).reshape(5, 3)


@pytest.mark.parametrize("ext", ["vtp", "vtk"])
def test_vtk_bit_arrays_are_read_as_uint8(tmp_path, ext):
    # no warning: pytest turns any into an error
    poly, pts = _poly_with_point_arrays(_bit_array("flags", BITS),
                                           _bit_array("flags3", BITS3.ravel(), 3))
    cloud = read_checked(_write_vtk(poly, tmp_path / f"bits.{ext}"))
    np.testing.assert_array_equal(cloud.points, pts)
    assert cloud.point_data["flags"].dtype == np.uint8
    np.testing.assert_array_equal(cloud.point_data["flags"], BITS)
    assert cloud.point_data["flags3"].dtype == np.uint8
    np.testing.assert_array_equal(cloud.point_data["flags3"], BITS3)


@pytest.mark.parametrize("ext", ["vtp", "vtk"])
def test_vtk_string_point_array_is_dropped_with_a_warning(tmp_path, ext):
    poly, pts = _poly_with_point_arrays(_bit_array("flags", BITS),
                                           _string_array("labels", "abcde"))
    path = _write_vtk(poly, tmp_path / f"strings.{ext}")
    with pytest.warns(DroppedArrayWarning) as record:
        cloud = read_checked(path)
    assert len(record) == 1
    message = str(record[0].message)
    assert f"strings.{ext}" in message
    assert "point array 'labels' dropped: a vtkStringArray, not numeric" in message
    assert record[0].filename == __file__  # reported where read_point_cloud was called
    assert "labels" not in cloud.point_data
    np.testing.assert_array_equal(cloud.point_data["flags"], BITS)
    np.testing.assert_allclose(cloud.point_data["temperature"], np.linspace(0, 1, 5))
    np.testing.assert_array_equal(cloud.points, pts)


def test_legacy_vtk_array_of_another_length_is_dropped_with_a_warning(tmp_path):
    from vtkmodules.util.numpy_support import numpy_to_vtk

    short = numpy_to_vtk(np.arange(3.0), deep=True)
    short.SetName("short")
    poly, _ = _poly_with_point_arrays(short)
    path = _write_vtk(poly, tmp_path / "short.vtk")
    with pytest.warns(DroppedArrayWarning,
                      match=r"'short' dropped: it has 3 tuples but the file has 5 points"):
        cloud = read_checked(path)
    assert "short" not in cloud.point_data and "temperature" in cloud.point_data


def test_vtk_array_numpy_cannot_take_is_dropped_with_a_warning(tmp_path, monkeypatch):
    from vtkmodules.util import numpy_support

    path = _write_vtk(_vtk_polydata()[0], tmp_path / "mesh.vtp")
    convert = numpy_support.vtk_to_numpy

    def refuse_temperature(arr):
        if arr.GetName() == "temperature":
            raise TypeError("no numpy type for this array")
        return convert(arr)

    monkeypatch.setattr(numpy_support, "vtk_to_numpy", refuse_temperature)
    with pytest.warns(DroppedArrayWarning, match=r"'temperature' dropped: a vtk\w*Float\w*Array "
                      r"cannot be converted .*TypeError: no numpy type for this array"):
        cloud = read_checked(path)
    assert "temperature" not in cloud.point_data and "pairs" in cloud.point_data


@pytest.mark.parametrize("text", [False, True], ids=["binary", "ascii"])
def test_ply_vertex_list_property_is_dropped_with_a_warning(tmp_path, text):
    v = np.empty(4, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("quality", "f4"),
                           ("neighbours", "O")])
    for i, c in enumerate("xyz"):
        v[c] = TETRA[:, i]
    v["quality"] = [1, 2, 3, 4]
    for i in range(4):
        v["neighbours"][i] = np.array([j for j in range(4) if j != i], dtype=np.int32)
    element = PlyElement.describe(v, "vertex", len_types={"neighbours": "u1"},
                                  val_types={"neighbours": "i4"})
    path = tmp_path / "lists.ply"
    PlyData([element], text=text).write(str(path))
    with pytest.warns(DroppedArrayWarning,
                      match=r"lists\.ply.*'neighbours' dropped: a list property") as record:
        cloud = read_checked(path)
    assert len(record) == 1 and record[0].filename == __file__
    assert "neighbours" not in cloud.point_data
    np.testing.assert_array_equal(cloud.point_data["quality"], [1, 2, 3, 4])


def test_dropped_array_warning_is_public():
    import fancloud_vtk
    import fancloud_vtk.io

    assert fancloud_vtk.DroppedArrayWarning is DroppedArrayWarning
    assert fancloud_vtk.io.DroppedArrayWarning is DroppedArrayWarning
    assert issubclass(DroppedArrayWarning, UserWarning)
    assert "DroppedArrayWarning" in fancloud_vtk.__all__


# ----------------------------------------------------------------------------- generic


def test_missing_file_is_an_error(tmp_path):
    with pytest.raises(FileReadError, match=r"missing\.ply.*no such file"):
        read_point_cloud(tmp_path / "missing.ply")


def test_directory_is_an_error(tmp_path):
    d = tmp_path / "dir.ply"
    d.mkdir()
    with pytest.raises(FileReadError, match="is a directory"):
        read_point_cloud(d)


@pytest.mark.parametrize("ext", SUPPORTED_FORMATS)
def test_empty_file_is_an_error(tmp_path, ext):
    path = tmp_path / f"empty.{ext}"
    path.write_bytes(b"")
    with pytest.raises(FileReadError, match=r"file is empty \(0 bytes\)"):
        read_point_cloud(path)


def test_unknown_extension_lists_supported_formats(tmp_path):
    path = tmp_path / "cloud.e57"
    path.write_text("0 0 0\n")
    with pytest.raises(FileReadError, match=r"unknown file extension \('\.e57'\).*ply.*npy"):
        read_point_cloud(path)
    with pytest.raises(FileReadError, match=r"unknown format 'e57'"):
        read_point_cloud(path, format="e57")
    noext = tmp_path / "cloud"
    noext.write_text("0 0 0\n")
    with pytest.raises(FileReadError, match="no extension"):
        read_point_cloud(noext)


def test_format_override_and_case_insensitive_extension(tmp_path):
    path = tmp_path / "points.dat"
    path.write_text("1 2 3\n4 5 6\n")
    np.testing.assert_array_equal(read_checked(path, format="XYZ").points, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(read_checked(path, format=".txt").points[1], [4, 5, 6])
    upper = write_ply(tmp_path / "MESH.PLY", vertex_array(TETRA))
    np.testing.assert_array_equal(read_checked(upper).points, TETRA)
    np.testing.assert_array_equal(read_checked(str(upper)).points, TETRA)


def test_file_read_error_is_value_error_and_pickles():
    err = FileReadError("/x/y.ply", "broken")
    assert isinstance(err, ValueError)
    assert str(err) == "cannot read '/x/y.ply': broken"
    again = pickle.loads(pickle.dumps(err))
    assert (again.path, again.reason, str(again)) == (err.path, err.reason, str(err))


def test_module_imports_neither_pyvista_nor_vtk_eagerly():
    code = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('fc_io', {str(IO_SOURCE)!r})\n"
        "mod = importlib.util.module_from_spec(spec)\n"
        "sys.modules['fc_io'] = mod\n"
        "spec.loader.exec_module(mod)\n"
        "assert mod.read_point_cloud\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('pyvista', 'vtkmodules', 'vtk')]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_cell_triangles_of_every_surface_cell_kind():
    from fancloud_vtk.io import cell_triangles

    # a triangle, a quad, a pixel, a pentagon, a strip of five points, a line, a tetrahedron
    offsets = [0, 3, 7, 11, 16, 21, 23, 27]
    conn = [0, 1, 2, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 4, 0, 1, 2, 3, 4, 0, 1, 0, 1, 2, 3]
    types = np.array([5, 9, 8, 7, 6, 3, 10], np.uint8)
    expected = [[0, 1, 2], [0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4],  # fans
                [0, 1, 3], [0, 3, 2],  # the pixel, counter-clockwise
                [0, 1, 2], [2, 1, 3], [2, 3, 4]]  # the strip, one orientation
    np.testing.assert_array_equal(cell_triangles(offsets, conn, types), expected)
    assert cell_triangles([0, 2, 6], [0, 1, 0, 1, 2, 3], [3, 10]).shape == (0, 3)


@pytest.mark.parametrize("cells", ["pixels", "triangles"])
def test_vtu_surface_cells_are_the_files_faces(tmp_path, cells):
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkUnstructuredGrid
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    x, y = np.meshgrid(np.arange(6.0), np.arange(5.0))  # a 6 x 5 grid in the plane z = 0
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(30)], axis=1)
    corner = (np.arange(5)[None, :] + 6 * np.arange(4)[:, None]).ravel()
    if cells == "pixels":  # VTK's pixel order: (0, 0), (1, 0), (0, 1), (1, 1)
        conn, kind = np.stack([corner, corner + 1, corner + 6, corner + 7], axis=1), 8
    else:  # two counter-clockwise triangles per square
        conn = np.concatenate([np.stack([corner, corner + 1, corner + 7], axis=1),
                               np.stack([corner, corner + 7, corner + 6], axis=1)])
        kind = 5
    grid = vtkUnstructuredGrid()
    points = vtkPoints()
    points.SetData(numpy_to_vtk(pts, deep=True))
    grid.SetPoints(points)
    array = vtkCellArray()
    for cell in conn:
        array.InsertNextCell(len(cell), [int(i) for i in cell])
    grid.SetCells(kind, array)
    path = tmp_path / "surface.vtu"
    writer = vtkXMLUnstructuredGridWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(grid)
    assert writer.Write() == 1
    src = read_point_cloud(str(path))
    assert src.faces.shape == (2 * 5 * 4, 3)
    p = src.points[src.faces]
    normal_z = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2]
    assert np.all(normal_z > 0)  # every triangle turns the same way
