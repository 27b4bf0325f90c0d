"""The last hole filling of the mesh (issue 22): holes the tangent-plane fillers leave are
triangulated in space without crossings, unused points go in, and coarse holes stay open."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from shapes import sphere

from fancloud_vtk import build_fans, fan_cloud_to_mesh
from fancloud_vtk.core import _csr_kernels as CsrK
from fancloud_vtk.core import _fill_kernels as FillK
from fancloud_vtk.core import mesh as ME
from fancloud_vtk.core.mesh_stats import (
    boundary_loops,
    mesh_statistics,
    self_intersecting_pairs,
)
from fancloud_vtk.corpus import corpus

NO_OBSTACLE = (np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)),
               np.zeros((0, 3)), np.zeros(0, bool), 0.0, 0.0)


def _fill(points, loop, mesh, near=None):
    vt_off, vt = CsrK.vertex_triangles(mesh, len(points))
    loop = np.asarray(loop, np.int64)
    if near is None:
        return FillK.fill_loop(points, loop, mesh, vt_off, vt, np.pi, *NO_OBSTACLE)
    from fancloud_vtk.core.mesh_stats import AREA_TOL, INTERSECTION_TOL, _triangle_frames

    local = np.vstack([near, np.zeros((1, 3), np.int64)]).astype(np.int64)
    frames = _triangle_frames(points, local, AREA_TOL, INTERSECTION_TOL)
    return FillK.fill_loop(points, loop, mesh, vt_off, vt, np.pi, local, *frames,
                           INTERSECTION_TOL, AREA_TOL)


def test_a_planar_loop_is_filled_against_its_boundary_half_edges():
    # a square 0-1-2-3 with a mesh triangle on each side, outside; the loop runs
    # along the mesh's boundary half-edges 0->1->2->3
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0.5, -1, 0], [2, 0.5, 0], [0.5, 2, 0], [-1, 0.5, 0]], float)
    mesh = np.array([[0, 4, 1], [1, 5, 2], [2, 6, 3], [3, 7, 0]], np.int64)
    # the mesh's half-edges run 0->4->1, so 1->0 is free: the loop is 1, 0, 3, 2
    out = _fill(p, [1, 0, 3, 2], mesh)
    assert out.shape == (2, 3)
    both = np.vstack([mesh, out])
    assert [len(x) for x in boundary_loops(both)] == [8]  # only the outer loop is left
    s = mesh_statistics(p, both)
    assert s["inconsistent_edges"] == 0 and s["non_manifold_edges"] == 0
    # the fill faces the way the mesh does (+z)
    a, b, c = (p[out[:, j]] for j in range(3))
    assert (np.cross(b - a, c - a)[:, 2] > 0).all()


def test_a_diagonal_already_in_the_mesh_is_not_used():
    # the square's diagonal 0-2 is an edge of a mesh triangle elsewhere (above the plane):
    # the fill must take the other diagonal
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 3]], float)
    mesh = np.array([[0, 2, 4], [0, 1, 4]], np.int64)
    out = _fill(p, [3, 2, 1, 0], mesh)
    assert len(out) == 2
    assert not any({0, 2} <= set(t) for t in out.tolist())


def test_an_obstacle_is_avoided_or_the_loop_refused():
    # a skew square: 0 and 2 raised. The fill over diagonal 0-2 is a ridge (z = 0.5 at the
    # centre), the one over 1-3 a valley (z = 0). A small wall at the ridge's centre makes
    # the fill take the valley, one at the valley's centre the ridge; with both, no fill.
    p = np.array([[0, 0, 0.5], [1, 0, 0], [1, 1, 0.5], [0, 1, 0],
                  [0.45, 0.55, 0.3], [0.55, 0.45, 0.3], [0.5, 0.5, 0.6],
                  [0.45, 0.55, -0.1], [0.55, 0.45, -0.1], [0.5, 0.5, 0.1]], float)
    none = np.zeros((0, 3), np.int64)
    valley = np.array([[7, 8, 9]], np.int64)
    out = _fill(p, [0, 1, 2, 3], none, near=valley)
    assert len(out) == 2 and all({0, 2} <= set(t) for t in out.tolist())
    ridge = np.array([[4, 5, 6]], np.int64)
    out = _fill(p, [0, 1, 2, 3], none, near=ridge)
    assert len(out) == 2
    assert all({1, 3} <= set(t) for t in out.tolist())
    assert len(self_intersecting_pairs(p, np.vstack([ridge, out]))) == 0
    both = np.array([[4, 5, 6], [7, 8, 9]], np.int64)
    assert len(_fill(p, [0, 1, 2, 3], none, near=both)) == 0


def _sphere_mesh(n=3000, seed=4):
    fc = build_fans(sphere(n, seed=seed))
    return fc, fan_cloud_to_mesh(fc).triangles


def test_a_hole_with_a_point_inside_is_filled_and_the_point_put_back():
    """The star of one point taken out: the loop is filled in space, and the point goes
    back in; the sphere is closed again, 2n - 4 triangles, no crossing."""
    fc, tri = _sphere_mesh()
    star = (tri == 0).any(axis=1)
    cut = tri[~star]
    out, filled, inserted = ME._fill_rounds(fc, cut, 6.0)
    assert filled >= 1 and inserted == 1
    s = mesh_statistics(fc.points, out, self_intersections=True)
    assert s["boundary_edges"] == 0 and s["unused_points"] == 0
    assert s["self_intersections"] == 0 and s["non_manifold_edges"] == 0
    assert len(out) == 2 * fc.n_points - 4


def test_a_coarse_hole_stays_open():
    """A hole whose fill needs edges longer than FILL_MAX_EDGE local spacings is not
    filled in space (it would bridge), and nothing else is changed."""
    fc, tri = _sphere_mesh()
    c = fc.points[0]
    h = float(np.median(ME._ring_spacing(fc, np.arange(fc.n_points))))
    # every triangle with a corner within 6 spacings of point 0: a hole about 12 wide
    near = (np.linalg.norm(fc.points[tri] - c, axis=2) < 6 * h).any(axis=1)
    cut = tri[~near]
    (loop,) = boundary_loops(cut)
    out, filled, _ = ME._fill_rounds(fc, cut, 6.0)
    assert filled == 0
    assert len(boundary_loops(out)) == 1
    assert len(self_intersecting_pairs(fc.points, out)) == 0


def test_nothing_to_fill_costs_nothing():
    fc, tri = _sphere_mesh()
    out, filled, inserted = ME._fill_rounds(fc, tri, 6.0)
    assert out is tri and filled == 0 and inserted == 0


@pytest.fixture(scope="module")
def cow():
    (e,) = corpus("small", only=["cow"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fc = build_fans(e.points)
        return fc, fan_cloud_to_mesh(fc)


def test_the_cow_keeps_fewer_holes_and_unused_points_than_meshlib_with_no_crossing(cow):
    """Before the last filling the cow's mesh had 632 boundary edges in 44 holes and 55
    unused points (docs/bench/mesh_corpus_small at a7be1ba); MeshLib leaves 209 and 19
    (the same file)."""
    fc, mesh = cow
    s = mesh.stats
    assert s["boundary_edges"] <= 209
    assert s["unused_points"] <= 19
    assert len(self_intersecting_pairs(mesh.points, mesh.triangles)) == 0
    assert s["non_manifold_edges"] == 0 and s["non_manifold_vertices"] == 0
    assert s["inconsistent_edges"] == 0


def test_a_stray_cluster_cut_in_two_pieces_is_still_stray():
    """Two small pieces near each other and far from the surface are one stray cluster:
    both go, their points are outliers (each piece alone was once kept because the other
    piece was near it). A small piece near the surface stays."""
    from scipy.spatial import Delaunay

    surface = sphere(3000, seed=5)
    g = np.stack(np.meshgrid(np.arange(4.0), np.arange(4.0)), -1).reshape(-1, 2)
    cluster = np.column_stack([0.03 * g, np.zeros(len(g))]) + [3.0, 0.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fc = build_fans(np.vstack([surface, cluster]))
        sphere_tri = fan_cloud_to_mesh(build_fans(surface)).triangles
    ids = np.arange(3000, 3000 + len(g))
    pieces = []
    for cols in ([0, 1], [2, 3]):  # two pieces of 8 points, one spacing apart
        sel = np.flatnonzero(np.isin(g[:, 0], cols))
        pieces.append(ids[sel][Delaunay(g[sel]).simplices])
    tri = np.vstack([sphere_tri, *pieces])
    out, outliers = ME._outliers(fc, tri, 20)
    assert np.array_equal(out, sphere_tri)
    assert set(ids.tolist()) <= set(outliers.tolist())
    # one piece alone beside the sphere (within 5 spacings of it) is kept
    near = np.column_stack([0.03 * g, np.zeros(len(g))]) + [1.0 + 0.03, 0.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fc = build_fans(np.vstack([surface, near]))
    out, _ = ME._outliers(fc, np.vstack([sphere_tri, pieces[0]]), 20)
    assert len(out) == len(sphere_tri) + len(pieces[0])


def test_a_sparse_row_beside_a_boundary_joins_it_and_a_far_point_does_not():
    """A row of points beside a plane patch's edge, a little sparser than the patch, gets
    one ear per point on the boundary; a point 50 spacings off stays out."""
    from scipy.spatial import Delaunay

    g = np.stack(np.meshgrid(np.arange(10.0), np.arange(10.0)), -1).reshape(-1, 2)
    row = np.column_stack([np.arange(0.5, 9.0, 2.0), np.full(5, 11.0)])
    far = np.array([[4.5, 60.0]])
    pts = np.column_stack([np.vstack([g, row, far]), np.zeros(len(g) + 6)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fc = build_fans(pts)
    tri = Delaunay(g).simplices.astype(np.int64)
    n = fc.n_points
    assert n == len(pts)
    # oriented as the fans' normals
    a, b, c = (pts[tri[:, k]] for k in range(3))
    up = np.cross(b - a, c - a) @ fc.normals[0] > 0
    tri[~up] = tri[~up][:, [0, 2, 1]]
    out, attached = ME._attach_to_boundary(fc, tri)
    assert attached == 5
    used = np.zeros(n, bool)
    used[out.ravel()] = True
    assert used[100:105].all() and not used[105]
    assert np.array_equal(out[: len(tri)], tri)
    assert len(self_intersecting_pairs(pts, out)) == 0
    assert mesh_statistics(pts, out)["non_manifold_edges"] == 0


def test_the_grid_over_the_near_triangles_finds_every_crossing():
    """_clear looks only in the grid cells a triangle's box overlaps: the same answers as
    testing every near triangle, on random triangles of all sizes."""
    from fancloud_vtk.core.mesh_stats import AREA_TOL, INTERSECTION_TOL, _triangle_frames

    rng = np.random.default_rng(3)
    # small triangles all over a box, and candidates small (a point and two near it) or not
    centres = rng.uniform(0, 10, (150, 1, 3))
    pts = (centres + rng.uniform(-0.6, 0.6, (150, 3, 3))).reshape(-1, 3)
    near = np.arange(450).reshape(150, 3)
    local = np.ascontiguousarray(np.vstack([near, np.zeros((1, 3), np.int64)]))
    frames = _triangle_frames(pts, local, AREA_TOL, INTERSECTION_TOL)
    grid = FillK._near_grid(frames[2], frames[3], len(near))
    assert grid[2] > 1  # a grid, not one cell
    seen = np.zeros(len(near) + 1, np.int64)
    order = np.argsort(((pts[:, None] - pts[None]) ** 2).sum(-1), axis=1)
    agree = crossing = 0
    for i in range(300):
        a = int(rng.integers(0, 450))
        b, c = (order[a, 1:3] if i % 2 else rng.integers(0, 450, 2)).tolist()
        if len({a, b, c}) < 3:
            continue
        got = FillK._clear(pts, a, b, c, local, *frames, INTERSECTION_TOL, AREA_TOL, grid, seen)
        both = np.vstack([near, [[a, b, c]]])
        meets = any(len(near) in pair for pair in map(tuple, self_intersecting_pairs(pts, both)))
        assert got == (not meets)
        agree += 1
        crossing += meets
    assert agree > 250 and 0 < crossing < agree  # both answers were tested
