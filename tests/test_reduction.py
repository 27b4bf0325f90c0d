"""Reduction by entropy and the levels of detail (paper sections 5 and 6)."""

import numpy as np
import pytest
from conftest import fingerprint
from scipy.spatial import cKDTree
from shapes import cube_surface, sphere

from fancloud_vtk import (
    Hierarchy,
    build_fans,
    fan_cloud_of_mesh,
    fan_cloud_to_mesh,
    hierarchy,
    load,
    reduce,
    save,
)
from fancloud_vtk.core.reduction import laplacian_smooth


@pytest.fixture(scope="module")
def sphere_fans():
    return build_fans(sphere(4000, seed=3))


CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)


@pytest.fixture(scope="module", params=[1, 2, 3])
def cube_fans(request):
    """Random points on the cube's faces plus its 8 corners."""
    return build_fans(np.vstack([cube_surface(8000, seed=request.param), CORNERS]))


def _arrays(fc):
    return (fc.points, fc.offsets, fc.ring, fc.normals, fc.open, fc.point_data["original_id"])


@pytest.mark.parametrize("n_points", [4, 100, 1234, 3999, 4000])
def test_exact_count(sphere_fans, n_points):
    out = reduce(sphere_fans, n_points)
    assert out.n_points == n_points
    ids = out.point_data["original_id"]
    assert len(np.unique(ids)) == n_points
    np.testing.assert_array_equal(out.points, sphere_fans.points[ids])


def test_keep_fraction_and_fans_are_valid(sphere_fans):
    out = reduce(sphere_fans, keep=0.176)
    assert out.n_points == round(0.176 * 4000)
    out.validate()
    # the kept fans form a closed surface again
    mesh = fan_cloud_to_mesh(out)
    assert mesh.stats["non_manifold_edges"] == 0
    assert mesh.stats["boundary_edges"] == 0
    assert mesh.n_triangles == 2 * out.n_points - 4


@pytest.mark.parametrize("method", ["entropy", "error"])
def test_deterministic(sphere_fans, method):
    a = reduce(sphere_fans, keep=0.3, method=method)
    b = reduce(sphere_fans, keep=0.3, method=method)
    assert fingerprint(*_arrays(a)) == fingerprint(*_arrays(b))


def _corner_and_edge_share(fc, out):
    p = out.points
    d_corner = cKDTree(p).query(CORNERS)[0]
    # points near an edge: two coordinates close to +-1
    near = (np.abs(np.abs(p) - 1) < 0.08).sum(axis=1) >= 2
    return d_corner, near.mean()


def test_cube_keeps_corners_and_edges_with_feature_weights(cube_fans):
    fc = cube_fans
    spacing = cKDTree(fc.points).query(fc.points, 2)[0][:, 1].mean()
    # M_dist grows as the faces thin out while a corner's M_curv falls as its
    # neighbours move away (|n_j - n| / d_j), so far enough down a corner goes
    # too; at 30% (and 42%, the paper's figure) every corner stays
    feat = reduce(fc, keep=0.3, weights=(1, 1, 50, 0))
    dist = reduce(fc, keep=0.3, weights=(1, 0, 0, 0))
    d_feat, edge_feat = _corner_and_edge_share(fc, feat)
    _, edge_dist = _corner_and_edge_share(fc, dist)
    # every corner is kept
    np.testing.assert_array_equal(d_feat, 0.0)
    # edges are kept: a far larger share of the kept points lies on them
    assert edge_feat > 2.0 * edge_dist
    assert edge_feat > 0.3
    assert spacing > 0


def test_distance_only_gives_uniform_spacing(sphere_fans):
    def cv(p):
        d = cKDTree(p).query(p, 2)[0][:, 1]
        return d.std() / d.mean()

    out = reduce(sphere_fans, keep=0.25, weights=(1, 0, 0, 0))
    assert cv(out.points) < 0.6 * cv(sphere_fans.points)


def test_triangle_mesh_input(bunny):
    p, f, _ = bunny
    out = reduce(fan_cloud_of_mesh(p, f), keep=0.2)
    assert out.n_points == round(0.2 * len(p))
    mesh = fan_cloud_to_mesh(out)
    assert mesh.stats["non_manifold_edges"] == 0


def test_level_round_trip_gives_back_the_input(sphere_fans):
    h = hierarchy(sphere_fans, 300)
    assert (h.n_points, h.n_min) == (4000, 300)
    coarse = h.level(300)
    fine = h.level(4000)
    np.testing.assert_array_equal(fine.points, sphere_fans.points)
    np.testing.assert_array_equal(fine.offsets, sphere_fans.offsets)
    np.testing.assert_array_equal(fine.ring, sphere_fans.ring)
    np.testing.assert_array_equal(fine.normals, sphere_fans.normals)
    # any level equals the reduction to that count
    for m in (300, 1000, 2500):
        assert fingerprint(*_arrays(h.level(m))) == fingerprint(*_arrays(reduce(sphere_fans, m)))
    assert coarse.n_points == 300


def test_edited_coarse_level_keeps_its_detail(sphere_fans):
    h = hierarchy(sphere_fans, 500)
    coarse = h.level(500)
    smooth = laplacian_smooth(coarse, 3)
    assert np.abs(smooth.points - coarse.points).max() > 1e-3  # really edited
    fine = h.level(4000, base=smooth)
    ids = fine.point_data["original_id"]
    kept = np.isin(ids, coarse.point_data["original_id"])
    np.testing.assert_array_equal(fine.points[kept], smooth.points)  # the edit stays
    # the reinserted points carry their detail relative to the edited surface
    np.testing.assert_allclose(h.details(fine), h.detail[:, :3], atol=1e-9)
    # and unedited it is exact
    np.testing.assert_allclose(h.details(h.level(4000)), h.detail[:, :3], atol=1e-12)


def test_selective_reinserts_exactly_the_region(sphere_fans):
    h = hierarchy(sphere_fans, 600)
    center, radius = np.array([0.0, 0.0, 1.0]), 0.5
    out = h.selective((center, radius))
    removed = h.order
    inside = np.linalg.norm(sphere_fans.points[removed] - center, axis=1) <= radius
    expected = np.union1d(h.level(600).point_data["original_id"], removed[inside])
    np.testing.assert_array_equal(np.sort(out.point_data["original_id"]), expected)
    # the same with a mask, a callable and a box
    mask = np.zeros(4000, bool)
    mask[removed[inside]] = True
    for region in (mask, lambda q: np.linalg.norm(q - center, axis=1) <= radius):
        got = h.selective(region)
        np.testing.assert_array_equal(np.sort(got.point_data["original_id"]), expected)
    box = h.selective((-2, 2, -2, 2, 0.9, 2))
    in_box = sphere_fans.points[removed, 2] >= 0.9
    assert in_box.any()
    expected = np.union1d(h.level(600).point_data["original_id"], removed[in_box])
    np.testing.assert_array_equal(np.sort(box.point_data["original_id"]), expected)


def test_selective_builds_the_results_fans_with_the_fan_parameters_given(sphere_fans):
    h = hierarchy(sphere_fans, 600)
    region = (np.array([0.0, 0.0, 1.0]), 0.5)
    default = h.selective(region)
    wide = h.selective(region, k=10, max_angle=120.0)
    np.testing.assert_array_equal(wide.points, default.points)
    assert default.fan_sizes.mean() == pytest.approx(6, abs=0.3)
    assert wide.fan_sizes.mean() > 9
    with pytest.raises(TypeError, match="normals"):
        h.selective(region, normals=np.zeros((4000, 3)))


def test_selective_on_an_edited_level(sphere_fans):
    h = hierarchy(sphere_fans, 600)
    smooth = laplacian_smooth(h.level(600), 2)
    out = h.selective((np.array([0.0, 0.0, 1.0]), 0.5), base=smooth)
    ids = out.point_data["original_id"]
    assert 600 < out.n_points < 4000
    coarse_ids = smooth.point_data["original_id"]
    at = np.searchsorted(np.sort(ids), coarse_ids)
    assert np.all(np.sort(ids)[at] == coarse_ids)


@pytest.mark.parametrize("ext", [".npz", ".vtp"])
def test_hierarchy_saves_and_loads(sphere_fans, tmp_path, ext):
    rgb = (np.abs(sphere_fans.points) * 255).astype(np.uint8)
    fc = sphere_fans.copy()
    fc.point_data["RGB"] = rgb
    h = hierarchy(fc, 400, weights=(1, 1, 50, 1))
    path = tmp_path / f"h{ext}"
    if ext == ".npz":  # numpy only, in the core
        h.save(path)
        back = Hierarchy.load(path)
        assert isinstance(load(path), Hierarchy)
    else:  # VTK: fancloud_vtk.save / load
        save(h, path)
        back = load(path)
        assert isinstance(back, Hierarchy)
    assert (back.n_points, back.n_min, back.weights, back.method) == (4000, 400, h.weights,
                                                                     h.method)
    for m in (400, 1500, 4000):
        a, b = h.level(m), back.level(m)
        assert fingerprint(*_arrays(a)) == fingerprint(*_arrays(b))
        np.testing.assert_array_equal(a.point_data["RGB"], b.point_data["RGB"])


def test_chained_reductions_compose_original_id(sphere_fans):
    mid = reduce(sphere_fans, 2000)
    small = reduce(mid, 500)
    ids = small.point_data["original_id"]
    np.testing.assert_array_equal(small.points, sphere_fans.points[ids])


def test_input_is_not_modified(sphere_fans):
    before = fingerprint(sphere_fans.points, sphere_fans.offsets, sphere_fans.ring,
                         sphere_fans.normals, sphere_fans.open)
    reduce(sphere_fans, keep=0.5)
    after = fingerprint(sphere_fans.points, sphere_fans.offsets, sphere_fans.ring,
                        sphere_fans.normals, sphere_fans.open)
    assert before == after


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"keep": 0.0}, "keep"),
        ({"keep": 1.5}, "keep"),
        ({"keep": -0.2}, "keep"),
        ({"keep": True}, "keep"),
        ({"n_points": 4001}, "larger"),
        ({"n_points": 3}, "at least 4"),
        ({"n_points": 10.5}, "integer"),
        ({}, "exactly one"),
        ({"n_points": 100, "keep": 0.5}, "exactly one"),
        ({"keep": 0.5, "weights": (1, 1, 50)}, "weights"),
        ({"keep": 0.5, "weights": (1, -1, 50, 0)}, "weights"),
        ({"keep": 0.5, "colors": np.zeros((10, 3))}, "rows"),
        ({"keep": 0.5, "weights": (1, 1, 50, 1)}, "no colours"),
        ({"keep": 0.5, "method": "quadric"}, "method"),
    ],
)
def test_bad_input(sphere_fans, kwargs, match):
    with pytest.raises(ValueError, match=match):
        reduce(sphere_fans, **kwargs)


def test_bad_levels(sphere_fans):
    h = hierarchy(sphere_fans, 1000)
    with pytest.raises(ValueError, match="outside"):
        h.level(999)
    with pytest.raises(ValueError, match="outside"):
        h.level(4001)
    with pytest.raises(ValueError, match="original_id"):
        h.level(4000, base=sphere_fans)
    with pytest.raises(ValueError, match="coarser"):
        h.level(1500, base=h.level(2000))
    with pytest.raises(ValueError, match="region"):
        h.selective("face")
    with pytest.raises(ValueError, match="one bool"):
        h.selective(np.zeros(10, bool))
    with pytest.raises(TypeError):
        reduce(np.zeros((100, 3)), 10)


def test_same_result_on_one_and_two_threads(sphere_fans):
    import numba

    n_threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = reduce(sphere_fans, keep=0.2)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = reduce(sphere_fans, keep=0.2)
    finally:
        numba.set_num_threads(n_threads)
    assert fingerprint(*_arrays(one)) == fingerprint(*_arrays(two))


@pytest.mark.parametrize("method", ["entropy", "error"])
def test_exact_greedy_order(sphere_fans, method):
    """``exact=True``: strictly one point at a time, lowest key first."""
    h = hierarchy(sphere_fans, 800, method=method, exact=True)
    out = reduce(sphere_fans, 800, method=method, exact=True)
    assert fingerprint(*_arrays(out)) == fingerprint(*_arrays(h.level(800)))
    assert out.n_points == 800
    np.testing.assert_array_equal(h.level(4000).ring, sphere_fans.ring)
    # the same kind of result as the rounds: a closed surface, near-uniform with distance
    mesh = fan_cloud_to_mesh(out)
    assert mesh.n_triangles == 2 * 800 - 4


@pytest.mark.parametrize("weights, method", [((1, 1, 50, 0), "entropy"), ((1, 0, 0, 0), "entropy"),
                                             ((1, 1, 50, 0), "error")])
def test_reduce_without_hierarchy_is_its_coarsest_level(sphere_fans, weights, method):
    """``reduce`` alone records no logs; its result is still the hierarchy's level."""
    out = reduce(sphere_fans, keep=0.176, weights=weights, method=method)
    again, h = reduce(sphere_fans, keep=0.176, weights=weights, method=method,
                      return_hierarchy=True)
    assert fingerprint(*_arrays(out)) == fingerprint(*_arrays(again))
    assert fingerprint(*_arrays(out)) == fingerprint(*_arrays(h.level(out.n_points)))
    assert out.info == again.info
    np.testing.assert_array_equal(out.rotated, again.rotated)


def test_overflowing_in_lists_fall_back_to_one_at_a_time(sphere_fans, monkeypatch):
    """In-lists too short for every point: the rounds leave those points to the one-at-a-time
    fallback, whose logs must land in the hierarchy (levels and round trip stay exact)."""
    from fancloud_vtk.core import reduction

    monkeypatch.setattr(reduction, "IN_WIDTH", 5)
    out, h = reduce(sphere_fans, 600, return_hierarchy=True)
    assert out.n_points == 600
    out.validate()
    assert fingerprint(*_arrays(out)) == fingerprint(*_arrays(reduce(sphere_fans, 600)))
    back = h.level(4000)
    np.testing.assert_array_equal(back.ring, sphere_fans.ring)
    np.testing.assert_array_equal(back.offsets, sphere_fans.offsets)
    mid = h.level(2000)
    mid.validate()
    assert fingerprint(*_arrays(mid)) == fingerprint(*_arrays(reduce(sphere_fans, 2000)))


def test_round_marks_wrap_without_changing_the_result(sphere_fans, monkeypatch):
    """The rounds' uint8 acceptance marks are cleared when their tags wrap: a cycle of two
    tags gives the same reduction and refinement as the full one."""
    from fancloud_vtk import refine
    from fancloud_vtk.core.hierarchy import RoundMarks

    small = reduce(sphere_fans, keep=0.2)
    fine = refine(sphere_fans, factor=1.5)
    monkeypatch.setattr(RoundMarks, "cycle", 2)
    assert fingerprint(*_arrays(reduce(sphere_fans, keep=0.2))) == fingerprint(*_arrays(small))
    again = refine(sphere_fans, factor=1.5)
    np.testing.assert_array_equal(again.points, fine.points)
    np.testing.assert_array_equal(again.ring, fine.ring)


@pytest.mark.parametrize("exact", [False, True])
@pytest.mark.parametrize("with_hierarchy", [False, True])
def test_progress_and_cancel(sphere_fans, exact, with_hierarchy):
    """The reduction reports rising fractions from 0 to 1, and a True from the callback
    cancels it (with or without logs, in rounds or one at a time) and leaves the input."""
    from fancloud_vtk import Cancelled, refine

    seen = []
    reduce(sphere_fans, keep=0.2, exact=exact, return_hierarchy=with_hierarchy,
           progress=lambda f, m: seen.append(f))
    assert seen[0] == 0.0 and seen[-1] == 1.0 and len(seen) > 3
    assert all(b >= a for a, b in zip(seen, seen[1:], strict=False))
    before = fingerprint(*_arrays(reduce(sphere_fans, keep=0.9)))
    ring = sphere_fans.ring.copy()
    with pytest.raises(Cancelled):
        reduce(sphere_fans, keep=0.2, exact=exact, return_hierarchy=with_hierarchy,
               progress=lambda f, m: f > 0.5)
    with pytest.raises(Cancelled):
        refine(sphere_fans, factor=2, exact=exact, return_hierarchy=with_hierarchy,
               progress=lambda f, m: f > 0.5)
    np.testing.assert_array_equal(sphere_fans.ring, ring)
    assert fingerprint(*_arrays(reduce(sphere_fans, keep=0.9))) == before


def test_stable_order_is_a_stable_argsort():
    """The rounds' radix sort orders like a stable argsort: ties by position, -0.0 as 0.0,
    negative, tiny (subnormal) and huge values, and the trivial sizes."""
    from fancloud_vtk.core._reduction_kernels import stable_order

    rng = np.random.default_rng(3)
    cases = [
        rng.random(3000),
        -rng.random(3000),
        rng.integers(-3, 4, 5000).astype(float),  # many ties
        np.array([0.0, -0.0, 1.0, -0.0, 0.0, -1.0]),
        rng.normal(size=4000) * 1e-300,
        rng.normal(size=4000) * 1e300,
        np.r_[rng.random(50), 1e-320, -1e-320, 5e-324, -5e-324],
        np.r_[rng.random(100), np.inf, -np.inf, np.inf],
        np.full(100, 2.5),
        np.zeros(0),
        np.array([7.0]),
    ]
    for v in cases:
        before = v.copy()
        got = stable_order(v)
        assert np.array_equal(got, np.argsort(v, kind="stable"))
        assert np.array_equal(v, before, equal_nan=True)  # the input is left alone


def test_error_key_counts_the_removed_points_a_point_carries():
    """``method='error'``: the cost of removing x is the largest distance from x's ring plane
    of x and of the removed points x carries (the paper's e(r)); a removal passes the point
    and what it carried, each to the nearest of the given heirs."""
    from fancloud_vtk.core._reduction_kernels import _deviation, _pass_on

    # x = 0 in the plane z = 0 with a ring of 6; 7 and 8 are removed points off the plane
    ang = np.arange(6) * np.pi / 3
    pts = np.vstack([[0, 0, 0], np.c_[np.cos(ang), np.sin(ang), np.zeros(6)],
                     [0.2, 0, 0.3], [0.4, 0, -0.5], [0.9, 0.1, 0.05]])
    nrm = np.tile([0.0, 0, 1], (len(pts), 1))
    ring = np.arange(1, 7, dtype=np.int32)
    head = np.full(len(pts), -1, np.int64)
    nxt = np.full(len(pts), -1, np.int64)
    assert _deviation(pts, nrm, 0, ring, 6, head, nxt) == 0.0
    # 9 carries 7 and 8; 9 goes: it and what it carried pass to 0 or 1, the nearer
    head[9], nxt[7], nxt[8] = 7, 8, -1
    _pass_on(pts, head, nxt, 9, np.array([0, 1]), 2)
    carried = {}
    for y in (0, 1, 9):
        d, got = head[y], []
        while d >= 0:
            got.append(int(d))
            d = nxt[d]
        carried[y] = sorted(got)
    assert carried == {0: [7, 8], 1: [9], 9: []}
    assert _deviation(pts, nrm, 0, ring, 6, head, nxt) == pytest.approx(0.5)
    assert _deviation(pts, nrm, 1, ring[:0], 0, head, nxt) == 0.0  # no ring
    # without the entropy path's lists (empty arrays) only the point itself counts
    empty = np.zeros(0, np.int64)
    assert _deviation(pts, nrm, 9, ring, 6, empty, empty) == pytest.approx(0.05)
    # 0 goes with no fan around it: 0 and what it carried pass to the nearer of its ring's
    # first two points 1 and 2 (1 for each: a tie for 0 goes to the smaller index)
    _pass_on(pts, head, nxt, 0, ring, 2)
    d, got = head[1], []
    while d >= 0:
        got.append(int(d))
        d = nxt[d]
    assert head[0] == -1 and head[2] == -1 and sorted(got) == [0, 7, 8, 9]
    assert _deviation(pts, nrm, 1, ring[1:], 5, head, nxt) == pytest.approx(0.5)


def test_error_reduction_bounds_the_deviation_of_the_removed_points():
    """The carried points keep the error method's result near every input point: on 20,000
    bumpy-sphere points at 17.6%, the largest distance of an input point from the mesh of the
    result is 1.4e-3 of the diagonal (with the removed point's own distance as the key, before
    the points carried counted, it was 3.1e-3)."""
    from fancloud_vtk.bench import surface_points
    from fancloud_vtk.bench.metrics import MeshDistance

    p = surface_points(20000, 0, "bumpy")
    out = reduce(build_fans(p), keep=0.176, method="error")
    mesh = fan_cloud_to_mesh(out)
    d = MeshDistance(mesh.points, mesh.triangles)(p)
    assert d.max() <= 2e-3 * np.linalg.norm(p.max(0) - p.min(0))


# -- the spacing bound (issue 24): no region is left unsampled, whatever the weights --------


def _real_mesh_fans(name):
    from fancloud_vtk.core.entropy import fan_cloud_of_mesh
    from fancloud_vtk.data import pymeshlab_sample
    from fancloud_vtk.io import read_point_cloud

    src = read_point_cloud(pymeshlab_sample(name))
    return fan_cloud_of_mesh(src.points, src.faces, keep_unreferenced=False)


def _gap(fc, small, keep):
    """The largest distance from an input point to the nearest kept point, in uniform spacings
    at the target count (the bound's unit)."""
    from fancloud_vtk.core._entropy_kernels import mean_distance

    h = mean_distance(fc.points, fc.offsets, fc.ring) * np.sqrt(1 / keep)
    return cKDTree(small.points).query(fc.points)[0].max() / h


@pytest.mark.parametrize("name", ["cow.obj", "bunny10k_textured.obj", "airplane.obj"])
@pytest.mark.parametrize("keep", [0.3, 0.1])
def test_no_region_is_left_unsampled_on_real_models(name, keep):
    import warnings

    from fancloud_vtk import UnreferencedVerticesWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnreferencedVerticesWarning)  # the airplane's strays
        fc = _real_mesh_fans(name)
    for weights in [(1, 1, 50, 0), (1, 0, 0, 0)]:
        small = reduce(fc, keep=keep, weights=weights)
        assert small.n_points == round(keep * fc.n_points)
        # no new fan edge is longer than 4 spacings (the default bound): every input point
        # is nearer than that to a kept point (measured: at most 2.4)
        assert _gap(fc, small, keep) <= 4.0, (name, keep, weights)


def test_the_cow_loses_its_body_without_the_bound():
    """The paper's reduction (no spacing bound, no error guard) with the default weights
    empties the cow's flat body (issue 24); the bound keeps it sampled, and so does the
    error guard alone."""
    fc = _real_mesh_fans("cow.obj")
    assert _gap(fc, reduce(fc, keep=0.3, max_spacing=0, error_step=0), 0.3) > 4.0
    assert _gap(fc, reduce(fc, keep=0.3, error_step=0), 0.3) < 2.5
    assert _gap(fc, reduce(fc, keep=0.3, max_spacing=0), 0.3) < 2.5
    assert _gap(fc, reduce(fc, keep=0.3), 0.3) < 2.5


def test_error_step_is_checked():
    fc = build_fans(sphere(500, seed=3))
    for bad in (-1.0, 0.5, 1.0, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="error_step"):
            reduce(fc, keep=0.5, error_step=bad)
    with pytest.raises(TypeError, match="error_step"):
        reduce(fc, keep=0.5, error_step="2")


def test_max_spacing_is_checked():
    p = sphere(500, seed=3)
    fc = build_fans(p)
    for bad in (-1.0, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="max_spacing"):
            reduce(fc, keep=0.5, max_spacing=bad)
    with pytest.raises(TypeError, match="max_spacing"):
        reduce(fc, keep=0.5, max_spacing="3")


def _two_colour_sphere():
    """A UV sphere mesh, red below the equator and blue above it (a sharp colour edge)."""
    import pyvista as pv

    from fancloud_vtk import fan_cloud_of_mesh

    m = pv.Sphere(theta_resolution=60, phi_resolution=60).triangulate().clean()
    p = np.asarray(m.points, dtype=np.float64)
    rgb = np.where(p[:, 2:3] < 0, [[255, 0, 0]], [[0, 0, 255]]).astype(np.uint8)
    return p, fan_cloud_of_mesh(p, m.faces.reshape(-1, 4)[:, 1:], point_data={"RGB": rgb})


def test_the_colour_weight_keeps_a_colour_edge_dense_under_the_error_guard():
    """On a mesh, the error guard's levels count the colour loss when a4 > 0, so the kept
    points gather at the colour edge (the equator of a sphere with one colour per half);
    without a colour weight they do not."""
    p, fc = _two_colour_sphere()
    band = np.abs(p[:, 2]) < 0.03  # the rows of points next to the equator
    share = {}
    for w in [(1, 1, 50, 1), (1, 1, 50, 0)]:
        small = reduce(fc, keep=0.2, weights=w)
        kept = small.point_data["original_id"]
        share[w] = band[kept].mean() / band.mean()  # the band's density against the mean
    assert share[(1, 1, 50, 1)] > 2.0 * share[(1, 1, 50, 0)], share
