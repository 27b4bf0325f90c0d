"""View-dependent fan clouds (paper section 8): forest, error bound, front, blocks."""

import numpy as np
import pytest

from fancloud_vtk import (
    FanCloudInputError,
    ViewDependentFanCloud,
    build_fans,
    point_blocks,
    terrain_blocks,
    terrain_fan_cloud,
    terrain_path,
)
from fancloud_vtk.core import _vdfc_kernels as VK
from fancloud_vtk.core.vdfc import Camera

N = 64
SPACING = 4.0 / N


def _heights(n=N, seed=1):
    rng = np.random.default_rng(seed)
    x = np.linspace(0, 4, n)
    return 0.5 * np.add.outer(np.sin(1.3 * x), np.cos(x)) + 0.01 * rng.normal(size=(n, n))


@pytest.fixture(scope="module")
def terrain():
    return terrain_fan_cloud(_heights(), spacing=SPACING)


@pytest.fixture(scope="module")
def forest(terrain):
    return ViewDependentFanCloud.build(terrain)


OBLIQUE = ((2.0, -3.0, 2.5), (2.0, 2.0, 0.0), (0.0, 0.0, 1.0), 50.0)
ABOVE = ((2.0, 2.0, 12.0), (2.0, 2.0, 0.0), (0.0, 1.0, 0.0), 60.0)


def _fresh(vd):
    """A second forest with the same nodes (its own front state)."""
    return ViewDependentFanCloud(
        positions=vd.positions, normals=vd.normals, children=vd.children,
        ring_offsets=vd.ring_offsets, ring=vd.ring, open=vd.open, error=vd.error,
        bound=vd.bound, radius=vd.radius, merge=vd.merge, weights=vd.weights)


def _tri_set(tri):
    return {tuple(sorted(t)) for t in np.asarray(tri).tolist()}


# -- the height field and its blocks ------------------------------------------------


def test_terrain_fan_cloud_is_the_grid_triangulation():
    z = _heights(12)
    fc = terrain_fan_cloud(z, spacing=(0.5, 0.25), origin=(1.0, 2.0))
    assert fc.n_points == 144
    assert np.allclose(fc.points[13], [1.5, 2.25, z[1, 1]])
    assert len(fc.triangles()) == 2 * 11 * 11
    assert fc.fan_sizes.max() == 6 and fc.n_open == 4 * 11
    assert (fc.normals[:, 2] > 0).all()
    # every fan edge goes both ways (the fans agree: one triangulation)
    edges = {(p, q) for p in range(fc.n_points) for q in fc.neighbours(p).tolist()}
    assert all((q, p) in edges for p, q in edges)


@pytest.mark.parametrize("bad, match", [
    (np.zeros(5), "2-d grid"),
    (np.zeros((1, 5)), "2-d grid"),
    (np.array([[0.0, 1.0], [np.nan, 2.0]]), "NaN"),
    (np.array([["a", "b"], ["c", "d"]]), "real numbers"),
])
def test_terrain_fan_cloud_rejects_bad_heights(bad, match):
    with pytest.raises((FanCloudInputError, TypeError), match=match):
        terrain_fan_cloud(bad)


def test_terrain_fan_cloud_rejects_bad_spacing():
    with pytest.raises(FanCloudInputError, match="spacing"):
        terrain_fan_cloud(np.zeros((3, 3)), spacing=0)


def test_terrain_blocks_share_their_boundary():
    blocks = terrain_blocks((20, 30), (10, 10))
    assert len(blocks) == 2 * 3
    count = np.zeros(600, int)
    for b in blocks:
        count[b] += 1
    assert (count >= 1).all()
    ii, jj = np.divmod(np.arange(600), 30)
    shared = (count >= 2).reshape(20, 30)
    # the shared points are whole inner rows and columns: one row and two columns here
    rows = np.flatnonzero(shared.all(axis=1))
    cols = np.flatnonzero(shared.all(axis=0))
    assert len(rows) == 1 and len(cols) == 2
    expect = np.zeros((20, 30), bool)
    expect[rows] = True
    expect[:, cols] = True
    assert np.array_equal(shared, expect)
    assert count.max() == 4  # the corners of four blocks


# -- the forest -----------------------------------------------------------------------


def test_forest_structure(forest, terrain):
    vd = forest
    n = terrain.n_points
    assert vd.n_leaves == n and len(vd.roots) == 1
    assert vd.n_nodes == 2 * n - 1
    inner = ~vd.is_leaf
    assert (vd.children[inner] < np.arange(vd.n_nodes)[inner, None]).all()
    assert (vd.error[vd.is_leaf] == 0).all() and (vd.error[inner] >= 0).all()
    # the leaves keep the input fans; a node's leaves are its children's
    assert np.array_equal(vd.ring[:terrain.offsets[-1]], terrain.ring)
    r = int(vd.roots[0])
    assert len(vd.leaves(r)) == n
    c0, c1 = vd.children[r]
    assert sorted(vd.leaves(r)) == sorted(np.concatenate([vd.leaves(c0), vd.leaves(c1)]))
    # the bound is monotone and the spheres hold the descendants
    par = vd.parent
    has = par >= 0
    assert (vd.bound[par[has]] >= vd.bound[has]).all()
    for node in (r, c0, c1, int(np.flatnonzero(inner)[10])):
        d = np.linalg.norm(vd.positions[vd.leaves(node)] - vd.positions[node], axis=1)
        assert d.max() <= vd.radius[node]


def test_entropy_merge_places_the_weighted_mean_and_half_edge_a_child(terrain):
    vd = ViewDependentFanCloud.build(terrain, "half_edge")
    inner = np.flatnonzero(~vd.is_leaf)
    c = vd.children[inner]
    on_q = np.isclose(vd.positions[inner], vd.positions[c[:, 1]]).all(axis=1)
    on_p = np.isclose(vd.positions[inner], vd.positions[c[:, 0]]).all(axis=1)
    assert (on_p | on_q).all()
    # away from the boundary r is at q; on it, at the open child
    inside = ~vd.open[c].any(axis=1)
    assert on_q[inside].all() and inside.sum() > len(inner) // 2
    ve = ViewDependentFanCloud.build(terrain, "entropy")
    inner = np.flatnonzero(~ve.is_leaf)
    a, b = ve.positions[ve.children[inner, 0]], ve.positions[ve.children[inner, 1]]
    r = ve.positions[inner]
    # r on the segment between its children (at the open one on the boundary)
    t = np.einsum("ij,ij->i", r - a, b - a) / np.einsum("ij,ij->i", b - a, b - a)
    assert ((t > -1e-9) & (t < 1 + 1e-9)).all()
    assert np.allclose(a + t[:, None] * (b - a), r)


@pytest.mark.parametrize("merge", ["entropy", "half_edge"])
@pytest.mark.parametrize("blocked", [False, True])
def test_merges_on_the_boundary_keep_it_and_its_corners_where_they_are(terrain, merge,
                                                                        blocked):
    blocks = terrain_blocks((N, N), (21, 21)) if blocked else None
    vd = ViewDependentFanCloud.build(terrain, merge, blocks=blocks)
    inner = np.flatnonzero(~vd.is_leaf & vd.open)
    p = vd.positions[inner]
    top = (N - 1) * SPACING
    x0, x1 = np.isclose(p[:, 0], 0), np.isclose(p[:, 0], top)
    y0, y1 = np.isclose(p[:, 1], 0), np.isclose(p[:, 1], top)
    assert len(inner) > 20 and (x0 | x1 | y0 | y1).all()
    # every merged node on the boundary is at one of the points it stands for, and a
    # node that holds a corner of the grid is at one of its corners
    corners = np.array([0, N - 1, N * (N - 1), N * N - 1])
    par = vd.parent
    for c in corners:
        x = par[c]
        while x >= 0:
            held = vd.positions[np.intersect1d(vd.leaves(x), corners)]
            assert (held == vd.positions[x]).all(axis=1).any(), (c, x)
            x = par[x]
    leaf_pos = {tuple(v) for v in vd.positions[:vd.n_leaves].tolist()}
    assert all(tuple(v) in leaf_pos for v in p.tolist())


@pytest.mark.parametrize("blocked", [False, True])
def test_the_front_covers_the_whole_grid_borders_included(terrain, blocked):
    from fancloud_vtk.bench.vdfc import _surface_errors

    heights = _heights()
    blocks = terrain_blocks((N, N), (21, 21)) if blocked else None
    vd = ViewDependentFanCloud.build(terrain, blocks=blocks)
    want = np.ones((N, N), bool)
    for cam, e_max in ((ABOVE, 0.05), (ABOVE, 0.2), (ABOVE, 0.5), (OBLIQUE, 0.05),
                       (OBLIQUE, 0.5)):
        front = vd.front_arrays(cam, e_max)
        _, _, hits = _surface_errors(front.points, front.triangles, heights,
                                     (SPACING, SPACING), (0.0, 0.0), want)
        eye, planes = Camera.of(cam).frustum()
        seen = np.all(terrain.points @ planes[:, :3].T + planes[:, 3] >= 0, axis=1)
        assert seen.sum() > 100
        assert (hits.ravel()[seen] > 0).all(), (cam, e_max, int((hits.ravel()[seen] == 0).sum()))


def test_the_front_covers_the_view_to_its_edge_on_a_rough_terrain():
    # a fractional Brownian terrain, rough at every scale: fans of different levels meet at
    # the view's edge, where the fans beyond the view must fill what those in view leave
    # (before they drew: 2 points in view under no triangle in this fly-through)
    from fancloud_vtk.bench.vdfc import _surface_errors, default_e_max, terrain

    heights, spacing, origin, _ = terrain(200, "fractal", seed=0)
    fc = terrain_fan_cloud(heights, spacing=spacing, origin=origin)
    vd = ViewDependentFanCloud.build(fc)
    cams = terrain_path(vd.bounds(), 40)
    d_max = vd.default_d_max(cams[0])
    e0 = default_e_max(heights, spacing, "fractal")
    want = np.ones(heights.shape, bool)
    missed = seen_all = 0
    for e_max in (e0 / 4, e0, 4 * e0):  # one incremental front through all of them
        for cam in cams:
            front = vd.front_arrays(cam, e_max, d_max)
            _, _, hits = _surface_errors(front.points, front.triangles, heights, spacing,
                                         origin, want)
            _, planes = Camera.of(cam).frustum()
            seen = np.all(fc.points @ planes[:, :3].T + planes[:, 3] >= 0, axis=1)
            missed += int((hits.ravel()[seen] == 0).sum())
            seen_all += int(seen.sum())
            assert np.isin(np.arange(front.n_points), front.triangles).all()  # all drawn
    assert seen_all > 1_000_000 and missed == 0


def _sector_plane_distance(vd, node, x):
    """e(r)'s distance, written out: the plane of the fan triangle whose sector holds x."""
    from fancloud_vtk.core._geometry_kernels import tangent

    r = vd.positions[node]
    n = vd.normals[node]
    u = np.array(tangent(*n)[:3])
    v = np.array(tangent(*n)[3:])
    fan = vd.ring[vd.ring_offsets[node]:vd.ring_offsets[node + 1]]
    d = x - r
    if len(fan) < 2:
        return abs(d @ n)
    q = vd.positions[fan] - r
    ang = np.arctan2(q @ v, q @ u)
    t = np.arctan2(d @ v, d @ u)
    k = len(fan)

    def plane(j):
        a, b = vd.positions[fan[j]] - r, vd.positions[fan[(j + 1) % k]] - r
        c = np.cross(a, b)
        c = c / np.linalg.norm(c) if np.linalg.norm(c) > 1e-12 * np.linalg.norm(a) \
            * np.linalg.norm(b) else n
        return abs(d @ c)

    for j in range(k - 1 if vd.open[node] else k):
        span = (ang[(j + 1) % k] - ang[j]) % (2 * np.pi)
        if (t - ang[j]) % (2 * np.pi) <= span:
            return plane(j)
    return min(plane(0), plane(k - 2))


def test_errors_vanish_on_a_plane_and_measure_the_fan_distance():
    x = np.linspace(0, 1, 30)
    plane = np.add.outer(0.3 * x, -0.2 * x)
    vd = ViewDependentFanCloud.build(terrain_fan_cloud(plane, spacing=1 / 29))
    assert vd.error.max() < 1e-9
    # a bumpy surface: e(r) is the largest distance of the leaves from the plane of the
    # fan triangle whose angular sector holds them
    bumps = 0.2 * np.add.outer(np.sin(6 * x), np.cos(5 * x))
    vb = ViewDependentFanCloud.build(terrain_fan_cloud(bumps, spacing=1 / 29))
    root = int(vb.roots[0])
    assert vb.error[root] > 0.01
    for node in [*np.flatnonzero(~vb.is_leaf)[::37], root]:
        leaves = vb.positions[vb.leaves(node)]
        expect = max(_sector_plane_distance(vb, node, p) for p in leaves)
        assert vb.error[node] == pytest.approx(expect, rel=1e-9, abs=1e-12)


def test_every_node_error_is_the_largest_leaf_distance_on_a_noisy_open_cloud():
    """e(r) skips the leaves whose bound (|d.n| plus the tangential offset times the fan's
    largest tilt) is under the largest distance so far: on every inner node of a noisy
    half sphere (open fans at its rim, tilted fans), the result is the full maximum."""
    rng = np.random.default_rng(5)
    p = rng.normal(size=(1500, 3))
    p[:, 2] = np.abs(p[:, 2])
    p /= np.linalg.norm(p, axis=1)[:, None]
    p += 0.01 * rng.normal(size=p.shape)
    vd = ViewDependentFanCloud.build(build_fans(p))
    assert vd.open.any()
    for node in np.flatnonzero(~vd.is_leaf):
        leaves = vd.positions[vd.leaves(node)]
        expect = max(_sector_plane_distance(vd, node, x) for x in leaves)
        assert vd.error[node] == pytest.approx(expect, rel=1e-9, abs=1e-12)


def test_symmetric_adjacency_is_the_sorted_union_of_both_directions():
    """Rows sorted, no repeats, no self loops; a row of 300 neighbours (a high valence,
    sorted another way than the short rows) too."""
    rng = np.random.default_rng(2)
    n = 400
    sizes = rng.integers(0, 8, n)
    sizes[7] = 300
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    ring = rng.integers(0, n, offsets[-1]).astype(np.int64)
    off, nb = VK.symmetric_adjacency(offsets, ring, n)
    want = [set() for _ in range(n)]
    for q in range(n):
        for x in ring[offsets[q]:offsets[q + 1]]:
            if x != q:
                want[q].add(int(x))
                want[int(x)].add(q)
    for q in range(n):
        assert nb[off[q]:off[q + 1]].tolist() == sorted(want[q])


def test_forest_of_build_fans_and_of_a_mesh():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(3000, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    vd = ViewDependentFanCloud.build(build_fans(p))
    assert vd.n_leaves == 3000 and len(vd.roots) >= 1
    assert vd.n_nodes == 2 * 3000 - len(vd.roots)
    cam = ((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0)
    front = vd.front_arrays(cam, 1e-9)
    # the whole sphere is in view: every point (the back side too)
    assert front.n_points == 3000


# -- the front -----------------------------------------------------------------------


def _scratch(vd, cam, e_max, d_max):
    """Refined and front nodes by the definition, top-down from the roots."""
    eye, planes = Camera.of(cam).frustum()
    d = np.maximum(np.linalg.norm(vd.positions - eye, axis=1) - vd.radius, 0.0)
    vis = ((vd.positions @ planes[:, :3].T + planes[:, 3]) >= -vd.radius[:, None]).all(axis=1)
    refine = ~vd.is_leaf & vis & (vd.bound > d * e_max / d_max)
    return refine, vis, d


@pytest.mark.parametrize("cam", [OBLIQUE, ABOVE])
@pytest.mark.parametrize("e_max", [0.002, 0.02, 0.2])
def test_front_error_bound_and_minimal(forest, cam, e_max):
    vd = _fresh(forest)
    d_max = 8.0
    front = vd.front_arrays(cam, e_max, d_max)
    refine, vis, d = _scratch(vd, cam, e_max, d_max)
    ids = front.point_data["node_id"]
    in_view = ids[:front.stats["in_view"]]
    # every active inner node keeps its error: e(r) <= bound <= d(r) / d_max * e_max
    inner = in_view[~vd.is_leaf[in_view]]
    assert (vd.error[inner] <= d[inner] * e_max / d_max + 1e-15).all()
    assert not refine[in_view].any()
    # every refined node violates the bound (the front is minimal) and its parent is refined
    refined = np.flatnonzero(vd._state == VK.REFINED)
    assert refine[refined].all()
    assert (vd.bound[refined] > d[refined] * e_max / d_max).all()
    assert all(vd.parent[x] < 0 or refine[vd.parent[x]] for x in refined)
    # the front nodes are exactly the children of refined nodes (or roots) not refined
    front_nodes = np.flatnonzero(vd._state == VK.FRONT)
    expect = np.flatnonzero(~refine & ((vd.parent < 0) | refine[np.maximum(vd.parent, 0)]))
    assert np.array_equal(np.sort(front_nodes), expect)
    # point arrays: the contract
    assert set(front.point_data) >= {"node_id", "level", "error"}
    assert np.array_equal(front.point_data["level"], vd.level[ids])
    assert np.array_equal(front.point_data["error"], vd.error[ids])
    assert np.allclose(front.points, vd.positions[ids])


def test_no_active_point_outside_the_frustum(forest):
    vd = _fresh(forest)
    cam = ((1.0, -0.5, 1.0), (2.5, 2.5, 0.0), (0.0, 0.0, 1.0), 30.0)
    front = vd.front_arrays(cam, 0.01, 8.0)
    eye, planes = Camera.of(cam).frustum()
    ids = front.point_data["node_id"]
    n_in = front.stats["in_view"]
    signed = (vd.positions[ids] @ planes[:, :3].T + planes[:, 3]).min(axis=1)
    # in view: the node's sphere (which holds its original points) meets the frustum
    assert (signed[:n_in] >= -vd.radius[ids[:n_in]]).all()
    # the others stand in for fan neighbours just over the border: within one fan of a
    # point in view (a front triangle joins them), or of such a border point (its fan
    # draws what reaches into the view)
    border = np.arange(n_in, len(ids))
    assert len(border) > 0
    tri = front.triangles
    first = {}
    for b in border:
        with_b = tri[(tri == b).any(axis=1)].ravel()
        a = np.unique(with_b[with_b < n_in])
        if len(a):
            reach = np.linalg.norm(vd.positions[ids[a]] - vd.positions[ids[b]], axis=1) \
                + vd.radius[ids[a]]
            assert signed[b] >= -reach.min() - 1e-12
            first[b] = reach.min()
    for b in border:
        if b in first:
            continue
        with_b = tri[(tri == b).any(axis=1)].ravel()
        a = [x for x in np.unique(with_b) if x in first]
        assert a, "a border point that no fan in view nor next to the view reaches"
        reach = min(np.linalg.norm(vd.positions[ids[x]] - vd.positions[ids[b]]) + first[x]
                    for x in a)
        assert signed[b] >= -reach - 1e-12
    assert len(first) > 0 and np.isin(border, tri).all()  # each border point is drawn
    # points well outside the view are never active
    far_out = (vd.positions[:vd.n_leaves] @ planes[:, :3].T + planes[:, 3]).min(axis=1) < -0.5
    assert far_out.sum() > 100
    assert not np.isin(np.flatnonzero(far_out), ids).any()


def test_density_grows_toward_the_viewer(forest):
    vd = _fresh(forest)
    cam = ((2.0, -1.0, 1.0), (2.0, 3.0, 0.0), (0.0, 0.0, 1.0), 50.0)
    front = vd.front_arrays(cam, 0.05, 8.0)
    eye, planes = Camera.of(cam).frustum()
    ids = front.point_data["node_id"][:front.stats["in_view"]]
    leaves = vd.positions[:vd.n_leaves]
    seen = (leaves @ planes[:, :3].T + planes[:, 3]).min(axis=1) >= 0
    dl = np.linalg.norm(leaves[seen] - eye, axis=1)
    da = np.linalg.norm(vd.positions[ids] - eye, axis=1)
    cuts = np.quantile(dl, [1 / 3, 2 / 3])
    # active points per unit area = active points / original points in each distance band
    near = (da < cuts[0]).sum() / (dl < cuts[0]).sum()
    far = (da >= cuts[1]).sum() / (dl >= cuts[1]).sum()
    assert near > 1.6 * far


def test_tiny_e_max_gives_the_original_fans_and_huge_the_roots(forest, terrain):
    vd = _fresh(forest)
    front = vd.front_arrays(ABOVE, 1e-300)
    assert front.n_points == terrain.n_points
    ids = front.point_data["node_id"]
    assert np.array_equal(np.sort(ids), np.arange(terrain.n_points))
    assert np.allclose(front.points, terrain.points[ids])
    assert _tri_set(ids[front.triangles]) == _tri_set(terrain.triangles())
    assert front.stats["triangles_per_point"] == pytest.approx(
        len(terrain.triangles()) / terrain.n_points)
    top = vd.front_arrays(ABOVE, 1e300)
    assert np.array_equal(top.point_data["node_id"], vd.roots)
    assert (top.point_data["level"] == 0).all()


def test_incremental_front_equals_the_front_from_scratch(forest):
    vd = _fresh(forest)
    other = _fresh(forest)
    path = terrain_path(vd.bounds(), 25, height=0.3)
    rng = np.random.default_rng(3)
    for i, cam in enumerate(path):
        e_max = 0.01 * (1 + 0.5 * np.sin(i))
        inc = vd.front_arrays(cam, e_max, 8.0)
        other._rep = None  # no stand-ins remembered from earlier frames: every walk anew
        new = other.front_arrays(cam, e_max, 8.0, incremental=False)
        assert np.array_equal(inc.point_data["node_id"], new.point_data["node_id"])
        assert np.array_equal(inc.triangles, new.triangles)
        assert inc.stats["visited"] <= new.stats["visited"] + len(new.points)
    # a jump back to the start still matches
    cam = path[0]
    jitter = (tuple(np.add(cam[0], rng.normal(scale=0.01, size=3))), *cam[1:])
    a = vd.front_arrays(jitter, 0.01, 8.0)
    other._rep = None
    b = other.front_arrays(jitter, 0.01, 8.0, incremental=False)
    assert np.array_equal(a.point_data["node_id"], b.point_data["node_id"])
    assert np.array_equal(a.triangles, b.triangles)


def test_the_frame_counter_starts_again_before_its_32_bit_memo_overflows(forest):
    vd = _fresh(forest)
    other = _fresh(forest)
    path = terrain_path(vd.bounds(), 6, height=0.3)
    vd.front_arrays(path[0], 0.01, 8.0)
    vd._tick = 2**30 - 2  # the memo holds 2 tick + answer: near the int32 limit
    for cam in path[1:]:
        inc = vd.front_arrays(cam, 0.01, 8.0)
        assert 0 < vd._tick < 2**30 and vd._memo.min() >= -2  # no wrap-around
        new = other.front_arrays(cam, 0.01, 8.0, incremental=False)
        assert np.array_equal(inc.point_data["node_id"], new.point_data["node_id"])
        assert np.array_equal(inc.triangles, new.triangles)
    assert vd._tick < 10  # it started again


def test_parallel_front_triangles_equal_the_serial_ones(forest, monkeypatch):
    import fancloud_vtk.core.vdfc as vdfc_module

    path = terrain_path(forest.bounds(), 12, height=0.3)
    fronts = {}
    for threshold in (0, 10**9):  # every front on all threads; every front serially
        monkeypatch.setattr(vdfc_module, "PARALLEL_FRONT", threshold)
        vd = _fresh(forest)
        fronts[threshold] = [vd.front_arrays(cam, 0.004, 8.0, superfluous=bool(i % 2))
                             for i, cam in enumerate(path)]
    for a, b in zip(*fronts.values(), strict=True):
        assert a.stats["border"] > 0  # the extras are numbered in the same order too
        assert np.array_equal(a.point_data["node_id"], b.point_data["node_id"])
        assert np.array_equal(a.triangles, b.triangles)


def test_superfluous_triangles_go_and_leave_one_cover(forest):
    """Where fans of different levels meet, doubly covered quads keep one diagonal's pair."""
    vd = _fresh(forest)
    plain = vd.front_arrays(OBLIQUE, 0.01, 8.0)
    vd2 = _fresh(forest)
    lean = vd2.front_arrays(OBLIQUE, 0.01, 8.0, superfluous=True)
    assert np.array_equal(plain.point_data["node_id"], lean.point_data["node_id"])
    assert lean.stats["distinct"] == plain.stats["triangles"]
    assert 0 < lean.stats["triangles"] < plain.stats["triangles"]
    assert abs(lean.stats["triangles_per_point"] - 2.0) < abs(
        plain.stats["triangles_per_point"] - 2.0)
    assert _tri_set(lean.triangles) <= _tri_set(plain.triangles)  # a subset, nothing new
    # no doubly covered convex quad is left: on an edge x-y with triangles x y u and
    # x y v (u, v on opposite sides of x-y, and x, y of u-v), neither u v x nor u v y
    # is still drawn
    tris = _tri_set(lean.triangles)
    by_edge = {}
    for t in tris:
        a, b, c = sorted(t)
        for e, w in (((a, b), c), ((b, c), a), ((a, c), b)):
            by_edge.setdefault(e, []).append(w)
    pts, nrm = lean.points, lean.normals

    def apart(a, b, c, d):  # c and d on opposite sides of a-b, seen along the normals
        n = nrm[a] + nrm[b]
        e = pts[b] - pts[a]
        return np.dot(np.cross(e, pts[c] - pts[a]), n) * np.dot(
            np.cross(e, pts[d] - pts[a]), n) < 0

    left = 0
    for (x, y), ws in by_edge.items():
        for i, u in enumerate(ws):
            for v in ws[i + 1:]:
                if apart(x, y, u, v) and apart(u, v, x, y) and (
                        tuple(sorted((u, v, x))) in tris or tuple(sorted((u, v, y))) in tris):
                    left += 1
    assert left == 0
    # every point still has a triangle, and no place of the terrain loses its cover
    assert len(np.unique(lean.triangles)) == len(np.unique(plain.triangles))
    from fancloud_vtk.bench.vdfc import _surface_errors

    fine = np.zeros((4 * N, 4 * N))  # samples 4 x finer than the grid (heights unused)
    everywhere = np.ones(fine.shape, bool)
    cover = [_surface_errors(f.points, f.triangles, fine, (SPACING / 4, SPACING / 4),
                             (0.0, 0.0), everywhere)[2] > 0 for f in (plain, lean)]
    assert cover[0].sum() > 0.5 * fine.size
    assert not (cover[0] & ~cover[1]).any()
    with pytest.raises(ValueError, match="superfluous must be True or False"):
        vd2.front_arrays(OBLIQUE, 0.01, 8.0, superfluous="yes")


def test_triangles_per_point_about_two(forest):
    vd = _fresh(forest)
    for e_max in (0.003, 0.03):
        front = vd.front_arrays(OBLIQUE, e_max, 8.0)
        assert 1.6 < front.stats["triangles_per_point"] < 2.4
        tri = front.triangles
        assert tri.min() >= 0 and tri.max() < front.n_points
        assert (tri[:, 0] != tri[:, 1]).all() and (tri[:, 1] != tri[:, 2]).all()
        assert len(_tri_set(tri)) == len(tri)  # distinct


# -- blocks ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def blocked(terrain):
    blocks = terrain_blocks((N, N), (21, 21))
    return ViewDependentFanCloud.build(terrain, blocks=blocks, workers=2), blocks


def test_blocks_never_merge_their_shared_points_before_uniting(blocked, terrain):
    vb, blocks = blocked
    assert vb.n_leaves == terrain.n_points and len(vb.roots) == 1
    count = np.zeros(terrain.n_points, int)
    for b in blocks:
        count[b] += 1
    shared = np.flatnonzero(count >= 2)
    home = np.full(terrain.n_points, -1)
    for i, b in enumerate(blocks):
        home[b[count[b] == 1]] = i
    # a node with a shared point below it spans more than one block, or came after uniting
    first_united = min(vb.parent[s] for s in shared)
    for node in np.flatnonzero(~vb.is_leaf):
        leaves = vb.leaves(node)
        if node < first_united:
            assert count[leaves].max() == 1, "a block merged a shared point"
            assert len(np.unique(home[leaves])) == 1, "a block merged across its boundary"


def _uncovered(points, tri, q):
    """Which of the (x, y) samples q no triangle covers, seen from above."""
    a, b, c = (points[tri[:, j], :2] for j in range(3))
    covered = np.zeros(len(q), bool)

    def side(o, u):  # (u - o) x (q - o), samples by triangles
        return ((u[None, :, 0] - o[None, :, 0]) * (q[:, None, 1] - o[None, :, 1])
                - (u[None, :, 1] - o[None, :, 1]) * (q[:, None, 0] - o[None, :, 0]))

    d = np.stack([side(a, b), side(b, c), side(c, a)])
    covered = ~(((d < 0).any(axis=0)) & ((d > 0).any(axis=0)))
    return ~covered.any(axis=1)


def test_blocks_leave_no_crack_for_random_cameras(blocked, terrain):
    """Seen from above, the front's fans cover the terrain across the block boundaries:
    a crack (blocks disagreeing on a shared point) would leave a gap there."""
    vb, blocks = blocked
    vd = _fresh(vb)
    rng = np.random.default_rng(7)
    size = terrain.points[:, 0].max()
    # over the whole grid, its border included, and across the block boundaries (every
    # 21 spacings)
    q = rng.uniform(0.0, size, size=(2000, 2))
    lines = SPACING * 21 * np.arange(1, 3)
    near = (np.abs(q[:, :1] - lines).min(axis=1) < SPACING) | (
        np.abs(q[:, 1:] - lines).min(axis=1) < SPACING)
    assert near.sum() > 100
    sizes = []
    for _ in range(6):
        eye = (rng.uniform(1, 3), rng.uniform(1, 3), rng.uniform(8, 14))
        cam = (eye, (2.0, 2.0, 0.0), (0.0, 1.0, 0.0), 70.0)
        front = vd.front_arrays(cam, rng.uniform(0.002, 0.05), 8.0)
        sizes.append(len(front.points))
        assert not _uncovered(front.points, front.triangles, q).any()
    # coarse and fine fronts, all far from the leaves (every block merged and united)
    assert min(sizes) < 200 and max(sizes) > 500 and max(sizes) < terrain.n_points / 2


def test_blocks_equal_the_plain_forest_where_no_boundary_is_involved(blocked, terrain):
    vb, blocks = blocked
    count = np.zeros(terrain.n_points, int)
    for b in blocks:
        count[b] += 1
    # the forest without blocks, following the influence of the (would-be) shared points
    vp = ViewDependentFanCloud.build(terrain, influence=count >= 2)
    assert vb.influenced is not None and vb.influenced[:terrain.n_points][count >= 2].all()
    twin = {tuple(np.sort(vb.leaves(r))): r for r in np.flatnonzero(~vb.is_leaf)}
    clean = [r for r in np.flatnonzero(~vp.is_leaf) if not vp.influenced[r]]
    assert len(clean) > 0.05 * vp.n_leaves
    for r in clean:
        t = twin[tuple(np.sort(vp.leaves(r)))]
        assert np.array_equal(vp.positions[r], vb.positions[t])
        assert vp.error[r] == vb.error[t] and vp.bound[r] == vb.bound[t]
        assert vp.radius[r] == vb.radius[t]
        assert sorted(vp.leaves(vp.children[r, 0]).tolist()) in (
            sorted(vb.leaves(vb.children[t, 0]).tolist()),
            sorted(vb.leaves(vb.children[t, 1]).tolist()))
    # so, for any camera, those nodes are refined in one forest exactly when in the other
    ids_p = np.array(clean)
    ids_b = np.array([twin[tuple(np.sort(vp.leaves(r)))] for r in clean])
    rng = np.random.default_rng(11)
    for _ in range(4):
        eye = (rng.uniform(0, 4), rng.uniform(-4, 0), rng.uniform(1, 4))
        cam = (eye, (rng.uniform(1, 3), rng.uniform(1, 3), 0.0), (0, 0, 1), 50.0)
        e_max = rng.uniform(0.002, 0.05)
        rp = _scratch(vp, cam, e_max, 8.0)[0]
        rb = _scratch(vb, cam, e_max, 8.0)[0]
        assert np.array_equal(rp[ids_p], rb[ids_b])


def test_blocks_must_tile_the_data(terrain):
    blocks = terrain_blocks((N, N), (32, 32))
    with pytest.raises(ValueError, match="do not tile"):
        ViewDependentFanCloud.build(terrain, blocks=blocks[:-1])
    # blocks that touch without sharing their boundary points
    ii, jj = np.divmod(np.arange(N * N), N)
    left, right = np.flatnonzero(jj < 32), np.flatnonzero(jj >= 32)
    with pytest.raises(ValueError, match="share"):
        ViewDependentFanCloud.build(terrain, blocks=[left, right])
    with pytest.raises(ValueError, match="outside"):
        ViewDependentFanCloud.build(terrain, blocks=[np.arange(N * N + 1)])


# -- extra objects, saving ------------------------------------------------------------


def test_extra_object_joins_the_forest(forest):
    rng = np.random.default_rng(0)
    cube = rng.uniform(-1, 1, size=(1500, 3))
    axis = np.argmax(np.abs(cube), axis=1)
    cube[np.arange(1500), axis] = np.sign(cube[np.arange(1500), axis])
    building = build_fans(cube * 0.2 + [2.0, 2.0, 1.0])
    both = forest.add_object(building)
    assert both.n_leaves == forest.n_leaves + 1500
    assert len(both.roots) == len(forest.roots) + len(ViewDependentFanCloud.build(building).roots)
    front = both.front_arrays(ABOVE, 1e-300)
    ids = front.point_data["node_id"]
    assert len(ids) == both.n_leaves
    assert (ids >= forest.n_nodes).sum() == 1500
    # the object's fans are among the triangles, renumbered
    assert front.triangles.max() < front.n_points


def test_save_and_load(forest, tmp_path):
    path = tmp_path / "forest.npz"
    forest.save(path)
    back = ViewDependentFanCloud.load(path)
    for name in ("positions", "children", "ring_offsets", "ring", "open", "error", "bound",
                 "radius"):
        assert np.array_equal(getattr(back, name), getattr(forest, name)), name
    a = _fresh(forest).front_arrays(OBLIQUE, 0.01, 8.0)
    b = back.front_arrays(OBLIQUE, 0.01, 8.0)
    assert np.array_equal(a.point_data["node_id"], b.point_data["node_id"])
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="not a view-dependent"):
        ViewDependentFanCloud.load(tmp_path / "other.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="cannot read"):
        ViewDependentFanCloud.load(tmp_path / "junk.npz")


# -- bad input -----------------------------------------------------------------------


@pytest.mark.parametrize("cam, match", [
    (((0, 0, 5), (0, 0, 0), (0, 1, 0), 0.0), "view angle"),
    (((0, 0, 5), (0, 0, 0), (0, 1, 0), 180.0), "view angle"),
    (((0, 0, 5), (0, 0, 5), (0, 1, 0), 40.0), "looks at nothing"),
    (((0, 0, 5), (0, 0, 0), (0, 0, 1), 40.0), "parallel"),
    (((0, 0, np.nan), (0, 0, 0), (0, 1, 0), 40.0), "finite"),
    (((0, 0, 5), (0, 0, 0), (0, 1, 0)), "camera tuple"),
    (((0, 0, 5), (0, 0, 0), (0, 1, 0), 40.0, -1.0), "aspect"),
])
def test_bad_cameras(forest, cam, match):
    with pytest.raises(ValueError, match=match):
        forest.front_arrays(cam, 0.01)


def test_camera_objects(forest):
    from vtkmodules.vtkRenderingCore import vtkCamera

    cam = vtkCamera()
    cam.SetPosition(*OBLIQUE[0])
    cam.SetFocalPoint(*OBLIQUE[1])
    cam.SetViewUp(*OBLIQUE[2])
    cam.SetViewAngle(OBLIQUE[3])
    a = _fresh(forest).front_arrays(cam, 0.01, 8.0)
    b = _fresh(forest).front_arrays(OBLIQUE, 0.01, 8.0)
    assert np.array_equal(a.point_data["node_id"], b.point_data["node_id"])
    cam.ParallelProjectionOn()
    with pytest.raises(ValueError, match="parallel projection"):
        forest.front_arrays(cam, 0.01)
    with pytest.raises(TypeError, match="camera"):
        forest.front_arrays(42, 0.01)


@pytest.mark.parametrize("e_max", [0, -1.0, np.nan, np.inf])
def test_bad_e_max(forest, e_max):
    with pytest.raises(ValueError, match="e_max"):
        forest.front_arrays(OBLIQUE, e_max)


def test_bad_build_arguments(terrain):
    with pytest.raises(ValueError, match="merge"):
        ViewDependentFanCloud.build(terrain, "collapse")
    with pytest.raises(ValueError, match="n_roots"):
        ViewDependentFanCloud.build(terrain, n_roots=0)
    with pytest.raises(ValueError, match="colour"):
        ViewDependentFanCloud.build(terrain, weights=(1, 1, 0, 1))
    with pytest.raises(TypeError):
        ViewDependentFanCloud.build(np.zeros((10, 3)))


def test_input_is_not_modified(terrain):
    before = {k: getattr(terrain, k).copy() for k in ("points", "offsets", "ring", "normals")}
    vd = ViewDependentFanCloud.build(terrain, blocks=terrain_blocks((N, N), (32, 32)))
    vd.front_arrays(OBLIQUE, 0.01)
    for k, v in before.items():
        assert np.array_equal(getattr(terrain, k), v), k


def test_colours_follow_the_merges():
    z = _heights(30)
    rgb = np.zeros((30, 30, 3), np.uint8)
    rgb[:, :15] = (255, 0, 0)
    rgb[:, 15:] = (0, 0, 255)
    fc = terrain_fan_cloud(z, spacing=0.1, point_data={"RGB": rgb})
    vd = ViewDependentFanCloud.build(fc)
    front = vd.front_arrays(((1.5, -3, 3), (1.5, 1.5, 0), (0, 0, 1), 50.0), 0.05)
    col = front.point_data["RGB"]
    assert col.dtype == np.uint8 and col.shape == (front.n_points, 3)
    # merged colours are mixes of red and blue
    assert (col[:, 1] == 0).all() and (col.astype(int)[:, [0, 2]].sum(axis=1) >= 250).all()


def test_terrain_path():
    path = terrain_path((0, 10, 0, 4, 0, 1), 10)
    eyes = np.array([c[0] for c in path])
    assert len(path) == 10 and (np.diff(eyes[:, 0]) > 0).all()
    assert (eyes[:, 2] > 1).all()
    with pytest.raises(ValueError, match="n_frames"):
        terrain_path((0, 10, 0, 4, 0, 1), 1)
    with pytest.raises(ValueError, match="bounds"):
        terrain_path((0, 10, 0), 5)


# -- blocks of point sets ---------------------------------------------------------------


def _terrain_points(seed=3):
    """The test terrain's grid points as a point set, shuffled (fans from build_fans)."""
    rng = np.random.default_rng(seed)
    pts = terrain_fan_cloud(_heights(), spacing=SPACING).points
    return build_fans(pts[rng.permutation(len(pts))])


def test_point_blocks_tile_the_cloud_and_hold_every_fan_edge():
    fc = _terrain_points()
    blocks = point_blocks(fc, 9)
    # a terrain is thin in z: columns, 3 x 3 of them
    assert len(blocks) == 9
    member = np.zeros((len(blocks), fc.n_points), bool)
    for i, b in enumerate(blocks):
        assert (np.diff(b) > 0).all()
        member[i, b] = True
    assert member.any(axis=0).all()
    src = np.repeat(np.arange(fc.n_points), fc.fan_sizes)
    assert (member[:, src] & member[:, fc.ring]).any(axis=0).all()  # every fan edge
    shared = member.sum(axis=0) >= 2
    assert 0 < shared.sum() < 0.3 * fc.n_points
    # a closed surface is cut in 3-d
    rng = np.random.default_rng(0)
    p = rng.normal(size=(3000, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    assert len(point_blocks(build_fans(p), 8)) == 8
    assert len(point_blocks(fc, 1)) == 1
    for bad in (0, -2, 2.5, True):
        with pytest.raises(ValueError, match="n_blocks"):
            point_blocks(fc, bad)


def test_a_point_set_forest_in_blocks_covers_the_ground_and_keeps_its_shared_points():
    fc = _terrain_points()
    blocks = point_blocks(fc, 9)
    vd = ViewDependentFanCloud.build(fc, blocks=blocks, workers=2)
    assert vd.n_leaves == fc.n_points and len(vd.roots) == 1
    count = np.zeros(fc.n_points, int)
    for b in blocks:
        count[b] += 1
    first_united = min(vd.parent[s] for s in np.flatnonzero(count >= 2))
    for node in np.flatnonzero(~vd.is_leaf):
        if node < first_united:
            assert count[vd.leaves(node)].max() == 1, "a block merged a shared point"
    # away from the outer border: build_fans leaves a few border points of a point set
    # with closed fans (10 of 252 here), and merges with those may cut a corner
    rng = np.random.default_rng(5)
    size = fc.points[:, 0].max()
    q = rng.uniform(2 * SPACING, size - 2 * SPACING, size=(1500, 2))
    for e_max in (0.01, 0.05, 0.2):
        front = vd.front_arrays(ABOVE, e_max)
        assert not _uncovered(front.points, front.triangles, q).any(), e_max


def test_the_vdfc_verb_cuts_a_point_set_into_blocks_by_block_size():
    from fancloud_vtk.core import verbs

    fc = _terrain_points()
    src = verbs.Source(points=fc.points)
    one = verbs.vdfc(src)
    cut = verbs.vdfc(src, {"block_size": 20})  # about 4096 / 400: 10 blocks
    assert one.n_leaves == cut.n_leaves == fc.n_points
    # the same points, another merge order: the blocks were used
    assert not np.array_equal(one.children, cut.children)


# -- fans made invalid by merges (the paper's Figure 14) ------------------------------


def test_a_fan_turned_round_is_found_folded(forest, terrain):
    """folded_fans: a merged node's fan sorted at merge time folds only past a gap of more
    than 180 degrees; the grid's own fans never fold; a node whose ring is turned round
    (clockwise about its normal) is found, and only it."""
    folded = forest.folded_fans()
    assert folded.dtype == bool and folded.shape == (forest.n_nodes,)
    assert not folded[forest.is_leaf].any()
    inner = np.flatnonzero(~forest.is_leaf & ~forest.open)
    x = int(inner[np.argmax(np.diff(forest.ring_offsets)[inner])])
    ring = forest.ring.copy()
    a, b = forest.ring_offsets[x], forest.ring_offsets[x + 1]
    ring[a:b] = ring[a:b][::-1]
    turned = ViewDependentFanCloud(
        positions=forest.positions, normals=forest.normals, children=forest.children,
        ring_offsets=forest.ring_offsets, ring=ring, open=forest.open, error=forest.error,
        bound=forest.bound, radius=forest.radius, merge=forest.merge,
        weights=forest.weights)
    again = turned.folded_fans()
    assert again[x] and np.array_equal(np.delete(again, x), np.delete(folded, x))


def test_folded_front_triangles_are_those_turned_against_their_fans_point(forest):
    """Front.folded_triangles: a triangle (p, a, b) folds when it turns against p's
    normal; the full-resolution front of the grid has none, and a triangle written the
    other way round is found."""
    from fancloud_vtk.core.vdfc import Front

    vd = _fresh(forest)
    front = vd.front_arrays(ABOVE, e_max=1e-9)
    assert front.n_points == forest.n_leaves and not front.folded_triangles().any()
    tri = front.triangles.copy()
    tri[0] = tri[0, [0, 2, 1]]
    mask = Front(front.points, tri, front.normals).folded_triangles()
    assert mask[0] and not mask[1:].any()


def test_a_boundary_neighbours_stand_in_stays_on_the_boundary():
    # node 2 merged the open (boundary) point 0 and the inner point 1, and is refined; the
    # front node 3 is nearer to 1. For an inner ring entry the stand-in is the nearer child;
    # for an end of 3's open fan (its neighbour along the boundary) the open child: else the
    # fan leaves the strip along the boundary between them uncovered (the topobathy DEM)
    pos = np.array([[0.0, 2.0, 0.0], [-0.5, 0.3, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    child = np.array([[-1, -1], [-1, -1], [0, 1], [-1, -1]])
    parent = np.array([2, 2, -1, -1])
    state = np.array([VK.FRONT, VK.FRONT, VK.REFINED, VK.FRONT], np.int8)
    is_open = np.array([True, False, True, True])
    assert VK._representative(pos, child, parent, state, 3, 2, is_open, False) == 1
    assert VK._representative(pos, child, parent, state, 3, 2, is_open, True) == 0
    is_open[1] = True  # both on the boundary: the nearer again
    assert VK._representative(pos, child, parent, state, 3, 2, is_open, True) == 1


def test_folded_front_triangles_are_written_the_way_their_neighbours_run():
    # the bunny's points: merges leave some fans invalid (Fig. 14) and their triangles
    # turned; the front writes them the other way round (they showed their backs as dark
    # specks in a render) and counts them
    from fancloud_vtk.bench.vdfc import object_e_max, orbit_path, scanned_object

    points, _ = scanned_object("bunny")
    vd = ViewDependentFanCloud.build(build_fans(points))
    cam = orbit_path(vd.bounds(), 8)[4]
    front = vd.front_arrays(cam, object_e_max(points))
    assert front.stats["folded"] > 0
    assert not front.folded_triangles().any()
    again = vd.front_arrays(cam, object_e_max(points), incremental=False)
    assert again.stats["folded"] == front.stats["folded"]
    assert np.array_equal(again.triangles, front.triangles)
