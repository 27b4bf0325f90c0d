"""The corpus of real and realistic data (``fancloud_vtk.corpus``) and its bench (issue 22)."""

import importlib.util
import json

import numpy as np
import pytest

from fancloud_vtk.bench.metrics import MeshDistance
from fancloud_vtk.corpus import (
    DENSITY_RATIO,
    KINDS,
    corpus,
    corpus_names,
    distance_to_mesh,
    median_spacing,
    model,
    range_scan,
    rasterize,
    resample,
)


def icosphere(level: int = 3, centre=(0.0, 0.0, 0.0), radius: float = 1.0):
    """A sphere: an octahedron subdivided ``level`` times, projected (outward triangles)."""
    pts = [np.array(v, float) for v in
           ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]
    tri = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5),
           (0, 3, 5)]
    for _ in range(level):
        mid, new = {}, []

        def middle(a, b, mid=mid):
            key = (min(a, b), max(a, b))
            if key not in mid:
                pts.append((pts[a] + pts[b]) / 2)
                mid[key] = len(pts) - 1
            return mid[key]

        for a, b, c in tri:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            new += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        tri = new
    p = np.array(pts)
    p /= np.linalg.norm(p, axis=1)[:, None]
    return p * radius + np.asarray(centre, float), np.array(tri, dtype=np.int64)


def first_hits(eye, points, ref_points, ref_triangles, eps=1e-7):
    """Möller-Trumbore: for each point, whether the open segment eye -> point (shortened by
    ``eps`` of its length) crosses a triangle."""
    a, b, c = (ref_points[ref_triangles[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    blocked = np.zeros(len(points), dtype=bool)
    for i, p in enumerate(points):
        d = p - eye
        h = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, h)
        ok = np.abs(det) > 1e-15
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = eye - a
        u = inv * np.einsum("ij,ij->i", s, h)
        q = np.cross(s, e1)
        v = inv * (q @ d)
        t = inv * np.einsum("ij,ij->i", e2, q)
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > eps) & (t < 1 - eps)
        blocked[i] = hit.any()
    return blocked


def containing_triangle(points, ref_points, ref_triangles):
    """For each point, the triangle it lies on (inside it, nearest its plane)."""
    a, b, c = (ref_points[ref_triangles[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    n2 = np.einsum("ij,ij->i", n, n)
    out = np.empty(len(points), dtype=np.int64)
    for i, x in enumerate(points):
        # barycentric coordinates of x's projection on every triangle's plane
        w = x - a
        u = np.einsum("ij,ij->i", np.cross(w, c - a), n) / n2
        v = np.einsum("ij,ij->i", np.cross(b - a, w), n) / n2
        inside = (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9)
        plane = np.abs(np.einsum("ij,ij->i", w, n)) / np.sqrt(n2)
        out[i] = np.argmin(np.where(inside, plane, np.inf))
    return out


@pytest.fixture(scope="module")
def cow():
    return model("cow")


# -- models ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["airplane", "bone"])
def test_model_keeps_only_referenced_vertices(name):
    from fancloud_vtk.data import pymeshlab_sample
    from fancloud_vtk.io import read_point_cloud

    e = model(name)
    f = read_point_cloud(pymeshlab_sample(f"{name}.obj" if name == "airplane" else "bone.ply"))
    used = np.zeros(len(f.points), dtype=bool)
    used[f.faces.ravel()] = True
    assert not used.all()  # the file has unreferenced vertices ...
    assert len(e.points) == np.count_nonzero(used)  # ... and the corpus none of them
    assert np.array_equal(np.unique(e.ref_triangles), np.arange(len(e.points)))
    assert np.array_equal(e.ref_points[e.ref_triangles], f.points[f.faces])  # same triangles
    corpus_rows = {tuple(p) for p in e.points}
    file_rows = {tuple(q) for q in f.points[used]}
    stray = [tuple(p) for p in f.points[~used] if tuple(p) not in file_rows]
    assert stray and not any(p in corpus_rows for p in stray)
    assert e.kind == "model" and e.closed and len(e.outliers) == 0
    assert e.points is e.ref_points


def test_model_face_scan_and_names():
    assert model("cube.obj").name == "cube"
    e = model("face000")  # the real range scan: its own mesh is the reference
    assert e.kind == "scan" and not e.closed
    assert len(e.points) == len(np.unique(e.ref_triangles)) < 85_849
    assert model("bunny10k_textured").closed is False


# -- resampling --------------------------------------------------------------------------------


def test_resample_deterministic(cow):
    for mode in ("uniform", "density", "noisy"):
        a = resample(cow.ref_points, cow.ref_triangles, 2000, mode, seed=3)
        b = resample(cow.ref_points, cow.ref_triangles, 2000, mode, seed=3)
        c = resample(cow.ref_points, cow.ref_triangles, 2000, mode, seed=4)
        assert a.points.shape == (2000, 3) and a.kind == mode
        assert np.array_equal(a.points, b.points)
        assert not np.array_equal(a.points, c.points)
        assert a.ref_points is not None and len(a.outliers) == 0


def test_resample_lies_on_the_surface(cow):
    distance = MeshDistance(cow.ref_points, cow.ref_triangles)
    diag = np.linalg.norm(np.ptp(cow.ref_points, axis=0))
    for mode in ("uniform", "density"):
        e = resample(cow.ref_points, cow.ref_triangles, 3000, mode, seed=1)
        assert distance(e.points).max() < 1e-9 * diag
        assert distance_to_mesh(e.points[:200], e.ref_points, e.ref_triangles).max() < 1e-9 * diag


@pytest.mark.parametrize("sigma", [0.1, 0.4])
def test_resample_noise_is_sigma_spacings(sigma):
    p, t = icosphere(4)  # convex: the distance is the noise outwards, at most it inwards
    e = resample(p, t, 4000, "noisy", sigma=sigma, seed=2)
    h = e.info["spacing"]
    assert h == pytest.approx(median_spacing(resample(p, t, 4000, seed=2).points))
    d = MeshDistance(p, t)(e.points)
    expected = sigma * h * np.sqrt(2 / np.pi)  # mean |N(0, sigma h)|
    assert 0.85 * expected < d.mean() < 1.05 * expected
    assert d.max() < 6 * sigma * h


def test_density_ramp_is_ten_fold():
    # a flat 1 x 0.3 strip: the density along x, its longest axis
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 0.3, 0], [0, 0.3, 0]], float)
    t = np.array([[0, 1, 2], [0, 2, 3]])
    e = resample(p, t, 20_000, "density", seed=5)
    counts, edges = np.histogram(e.points[:, 0], bins=10, range=(0, 1))
    slope = np.polyfit(0.5 * (edges[1:] + edges[:-1]), np.log10(counts), 1)[0]
    assert 0.9 < slope < 1.1  # 10x over the length
    assert counts[-1] / counts[0] == pytest.approx(DENSITY_RATIO ** 0.9, rel=0.15)
    u, _ = np.histogram(resample(p, t, 20_000, seed=5).points[:, 0], bins=10, range=(0, 1))
    assert u.max() / u.min() < 1.2  # uniform stays uniform


# -- range scans ------------------------------------------------------------------------------


def test_scan_sees_only_the_front_of_a_sphere():
    p, t = icosphere(3)
    eye = np.array([0.5, 4.0, 1.0])
    e = range_scan(p, t, viewpoint=eye, target=(0, 0, 0), resolution=(64, 64), dropout=0,
                   depth_noise=0, outlier_clusters=0)
    assert len(e.outliers) == 0 and len(e.points) > 300
    # no point on a back face: every point's triangle (outward normals) faces the eye
    on = containing_triangle(e.points, p, t)
    a, b, c = (p[t[on, k]] for k in range(3))
    assert (np.einsum("ij,ij->i", np.cross(b - a, c - a), eye - e.points) > 0).all()
    assert (e.points @ eye).min() > 0  # the near hemisphere only
    assert not first_hits(eye, e.points, p, t).any()  # nothing in front of any point
    assert MeshDistance(p, t)(e.points).max() < 1e-9


def test_scan_deterministic_outliers_off_the_surface(cow):
    kwargs = {"resolution": (96, 96), "fov": 20.0, "seed": 7}
    e = range_scan(cow.ref_points, cow.ref_triangles, **kwargs)
    again = range_scan(cow.ref_points, cow.ref_triangles, **kwargs)
    other = range_scan(cow.ref_points, cow.ref_triangles, **{**kwargs, "seed": 8})
    assert np.array_equal(e.points, again.points)
    assert np.array_equal(e.outliers, again.outliers)
    assert not np.array_equal(e.info["viewpoint"], other.info["viewpoint"])
    assert e.kind == "scan" and e.closed and e.ref_points is not None
    assert len(e.outliers) == 3 * 15
    assert np.array_equal(e.outliers, np.arange(len(e.points) - 45, len(e.points)))
    assert 0 < e.info["lost_pixels"] < e.info["hit_pixels"]
    h = e.info["spacing"]
    d = MeshDistance(cow.ref_points, cow.ref_triangles)(e.points) / h
    inliers = np.ones(len(e.points), bool)
    inliers[e.outliers] = False
    assert 10 <= d[e.outliers].min() and d[e.outliers].max() <= 50
    assert d[inliers].max() < 5 * 0.1  # within 5 sigma of the depth noise
    assert d[inliers].mean() > 0.01  # and noisy
    # without noise the hits are visible from the scanner: nothing on a back face
    clean = range_scan(cow.ref_points, cow.ref_triangles, **kwargs, depth_noise=0,
                       outlier_clusters=0)
    assert not first_hits(clean.info["viewpoint"], clean.points[::7], cow.ref_points,
                          cow.ref_triangles).any()


def test_scan_of_two_spheres_has_an_occlusion_gap():
    pa, ta = icosphere(3, centre=(0, 0, 0), radius=1.0)  # in front
    pb, tb = icosphere(3, centre=(0, 0, -4), radius=2.0)  # behind, larger
    p = np.concatenate([pa, pb])
    t = np.concatenate([ta, tb + len(pa)])
    eye = np.array([0.0, 0.0, 8.0])
    e = range_scan(p, t, viewpoint=eye, target=(0, 0, -2), resolution=(96, 96), dropout=0,
                   depth_noise=0, outlier_clusters=0)
    on_b = np.abs(np.linalg.norm(e.points - (0, 0, -4), axis=1) - 2.0) < 0.05
    on_a = np.abs(np.linalg.norm(e.points, axis=1) - 1.0) < 0.05
    assert on_a.sum() > 100 and on_b.sum() > 100 and (on_a | on_b).all()
    # distance of the ray eye -> point to the front sphere's centre
    d = e.points[on_b] - eye
    gap = np.linalg.norm(np.cross(d, -eye), axis=1) / np.linalg.norm(d, axis=1)
    assert gap.min() > 0.95  # no ray to the back sphere passes through the front one ...
    assert gap.min() < 1.2  # ... and the back sphere is seen right up to its shadow
    assert not first_hits(eye, e.points[on_b], p, t).any()


def test_rasterize_depth_is_the_hit():
    p, t = icosphere(2)
    z = rasterize(p, t, viewpoint=(0, 0, 5), target=(0, 0, 0), resolution=(40, 30), fov=30)
    assert z.depth.shape == z.triangle.shape == (30, 40) and z.rays.shape == (30, 40, 3)
    x, flat = z.points()
    assert len(x) == np.count_nonzero(z.triangle >= 0) > 100
    assert MeshDistance(p, t)(x).max() < 1e-9
    i, j, depth = z.project(x)
    assert np.array_equal(np.floor(i).astype(int) * 40 + np.floor(j).astype(int), flat)
    assert np.allclose(depth, z.depth.ravel()[flat])


# -- the lists ---------------------------------------------------------------------------------


def test_corpus_small_lists_and_determinism():
    entries = corpus("small")
    assert [e.name for e in entries] == corpus_names("small")
    assert set(corpus_names("small")) < set(corpus_names("full"))
    kinds = {e.kind for e in entries}
    assert kinds == set(KINDS)
    for e in entries:
        assert e.points.dtype == np.float64 and e.points.shape[1] == 3
        assert e.ref_triangles.dtype == np.int64 and len(np.unique(e.ref_triangles)) == len(
            e.ref_points)
        assert (len(e.outliers) > 0) == (e.kind == "scan")
        if e.kind in ("uniform", "density", "noisy"):
            assert 5000 <= len(e.points) <= 10_000
    scans = [e for e in entries if e.kind == "scan"]
    assert len(scans) == 2 and all(128 <= e.info["resolution"][0] <= 192 for e in scans)
    (a,) = corpus("small", seed=0, only=["cow-scan-1"])
    (b,) = corpus("small", seed=1, only=["cow-scan-1"])
    same = next(e for e in entries if e.name == "cow-scan-1")
    assert np.array_equal(a.points, same.points) and not np.array_equal(a.points, b.points)
    assert [e.name for e in corpus("full", only=["bunny10k*", "cube"])] == [
        "cube", "bunny10k_textured", "bunny10k-scan-1"]


# -- bad arguments -----------------------------------------------------------------------------


def test_bad_arguments_raise_value_error(cow):
    p, t = cow.ref_points, cow.ref_triangles
    bad = [
        lambda: model("teapot"),
        lambda: corpus("medium"),
        lambda: corpus("small", only=["no-such-entry"]),
        lambda: corpus("small", seed=-1),
        lambda: resample(p, t, 0),
        lambda: resample(p, t, 10, "blurred"),
        lambda: resample(p, t, 10, "noisy", sigma=-0.1),
        lambda: resample(p, t, 10, seed=1.5),
        lambda: resample(p[:, :2], t, 10),
        lambda: resample(p, t + len(p), 10),
        lambda: resample(p, t.astype(float), 10),
        lambda: resample(np.zeros((3, 3)), [[0, 1, 2]], 10),  # zero area
        lambda: range_scan(p, t, dropout=1.0),
        lambda: range_scan(p, t, depth_noise=-1),
        lambda: range_scan(p, t, resolution=(0, 10)),
        lambda: range_scan(p, t, resolution=(10.5, 10)),
        lambda: range_scan(p, t, fov=0),
        lambda: range_scan(p, t, fov=180),
        lambda: range_scan(p, t, outlier_clusters=-1),
        lambda: range_scan(p, t, outlier_clusters=2, cluster_size=0),
        lambda: range_scan(p, t, viewpoint=(0, 0, 0), target=(0, 0, 0)),
        lambda: range_scan(p, t, viewpoint=(0, 0, 10), target=(0, 0, 20)),  # looks away
        lambda: range_scan(p, t, viewpoint=(0, 0, np.nan)),
    ]
    for i, call in enumerate(bad):
        with pytest.raises(ValueError):
            call()
            pytest.fail(f"case {i} did not raise")


# -- the bench ---------------------------------------------------------------------------------


def test_parse_corpus_data():
    from fancloud_vtk.bench.mesh import parse_data

    assert parse_data(["corpus-small", "bunny,corpus"], 10) == [
        ("corpus-small", None), ("bunny", None), ("corpus", None)]


def test_measure_corpus_counts_outliers_apart():
    """The corpus figures of a mesh, without a subprocess: a scan meshed by hand."""
    from fancloud_vtk.bench.mesh import _measure_corpus, corpus_data, corpus_rows

    p, t = icosphere(3)
    e = range_scan(p, t, viewpoint=(0, 0, 5), target=(0, 0, 0), resolution=(48, 48), seed=1,
                   outlier_clusters=2, cluster_size=4)
    data = corpus_data(e)
    data["diag"] = float(np.linalg.norm(np.ptp(e.points, axis=0)))
    n = len(e.points)
    # two triangles over scan points far apart, one with an outlier; two crossing triangles
    far = [0, n // 4, n // 2, 3 * n // 4, n - len(e.outliers) - 1]
    tri = np.array([[far[0], far[1], far[2]], [far[3], far[4], e.outliers[0]]])
    verts = e.points.copy()
    extra = np.array([[0.0, 0.0, 1.5], [0.1, 0.0, 1.5], [0.0, 0.1, 1.5],
                      [0.03, 0.03, 1.4], [0.03, 0.03, 1.6], [0.5, 0.5, 1.5]])
    verts = np.concatenate([verts, extra])
    tri = np.concatenate([tri, [[n, n + 1, n + 2], [n + 3, n + 4, n + 5]]])
    assert len(set(far)) == 5
    r = {"method": "hand", "label": "by hand", "status": "ok", "message": "ok", "time": 0.1,
         "new_points": False, "n_triangles": len(tri), "n_vertices": len(verts),
         "stats": {"boundary_edges": 9, "holes": 3, "non_manifold_edges": 0,
                   "non_manifold_vertices": 0, "components": 4},
         "distance": {"mean": 0.0, "max": 1.0}}
    render = _measure_corpus(r, data, verts, tri, True)
    c = r["corpus"]
    assert c["self_intersecting_faces"] == 2 and r["stats"]["self_intersections"] == 1
    assert np.array_equal(render["bad"], [2, 3])
    assert c["unused_outliers"] == len(e.outliers) - 1
    assert c["unused_points"] == n - len(e.outliers) - 5
    assert len(render["tri_distance"]) == len(tri)
    assert c["distance_max_spacings"] == pytest.approx(1.0 / data["corpus"]["spacing"])
    row = corpus_rows({"methods": [r], "corpus": data["corpus"]})[0]
    assert row["unused outliers"] == f"{len(e.outliers) - 1:,}"
    assert row["self-intersecting faces"] == "2" and row["pieces"] == "4"
    assert json.dumps(data["corpus"])  # the JSON part has no arrays


def test_bench_mesh_on_the_corpus(tmp_path, capsys):
    from fancloud_vtk.bench.mesh import CORPUS_COLUMNS
    from fancloud_vtk.cli import main as cli_main

    out = tmp_path / "bench"
    argv = ["bench", "mesh", "--data", "corpus-small", "--corpus-entries", "bone",
            "--methods", "ours", "meshlib", "--samples", "1", "--timeout", "120",
            "--out", str(out), "-q"]
    assert cli_main(argv) == 0
    text = (out / "mesh.md").read_text()
    assert text in capsys.readouterr().out
    assert "## bone (model)" in text and "closed" in text
    header = "| " + " | ".join(CORPUS_COLUMNS) + " |"
    lines = text.splitlines()
    at = lines.index(header)
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in lines[at + 2:at + 4]]
    ours = dict(zip(CORPUS_COLUMNS, rows[0], strict=True))
    assert ours["method"] == "fancloud_vtk (this project)" and ours["status"].startswith("ok")
    assert ours["unused outliers"] == "n/a"  # not a scan
    assert "closed, 1 piece." in text  # the bone's own mesh
    assert ours["pieces"] == "1"
    for key in ("self-intersecting faces", "unused points", "boundary edges",
                "non-manifold edges", "non-manifold vertices"):
        assert int(ours[key].replace(",", "")) >= 0
    assert 0 <= float(ours["distance mean (h)"]) <= float(ours["distance max (h)"])
    have_meshlib = importlib.util.find_spec("meshlib") is not None
    meshlib = dict(zip(CORPUS_COLUMNS, rows[1], strict=True))
    assert meshlib["status"].startswith("ok" if have_meshlib else "missing")
    assert (out / "corpus_bone.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    raw = json.loads((out / "mesh.json").read_text())
    (ds,) = raw["datasets"]
    assert ds["corpus"]["name"] == "bone" and ds["corpus"]["closed"] is True
    assert ds["render"] == "corpus_bone.png"
    assert ds["methods"][0]["corpus"]["self_intersecting_faces"] >= 0
