"""Mesh statistics (fancloud_vtk.core.mesh_stats): exact counts on known meshes and a
brute-force reference for the self-intersection test."""

import numpy as np
import pytest
import pyvista as pv
from conftest import fingerprint

from fancloud_vtk.core.mesh_stats import (
    MeshInputError,
    boundary_loops,
    mesh_statistics,
    self_intersecting_pairs,
)

KEYS = {
    "points",
    "triangles",
    "unused_points",
    "edges",
    "boundary_edges",
    "holes",
    "non_manifold_edges",
    "non_manifold_vertices",
    "inconsistent_edges",
    "degenerate_triangles",
    "duplicate_triangles",
    "self_intersections",
    "components",
    "euler_characteristic",
    "triangles_per_point",
}


def triangles_of(mesh: pv.PolyData) -> np.ndarray:
    return np.asarray(mesh.faces).reshape(-1, 4)[:, 1:].copy()


@pytest.fixture(scope="module")
def sphere():
    mesh = pv.Sphere().clean()
    return np.asarray(mesh.points, dtype=float), triangles_of(mesh)


def is_rotation(a, b) -> bool:
    a, b = list(a), list(b)
    return len(a) == len(b) and any(a == b[k:] + b[:k] for k in range(len(b)))


def grid_patch(nx: int, ny: int):
    """A flat ``nx`` by ``ny`` grid of points, each square cut into two triangles."""
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float), indexing="ij")
    points = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    triangles = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return points, triangles


# ----------------------------------------------------------------------------- known meshes


def test_closed_sphere(sphere):
    points, triangles = sphere
    s = mesh_statistics(points, triangles)
    assert set(s) == KEYS
    assert all(isinstance(s[k], int) for k in KEYS - {"triangles_per_point"})
    assert isinstance(s["triangles_per_point"], float)
    assert s["points"] == len(points) and s["triangles"] == len(triangles)
    assert s["triangles"] == 2 * s["points"] - 4  # closed genus 0
    assert s["edges"] == 3 * len(triangles) // 2
    for key in (
        "unused_points",
        "boundary_edges",
        "holes",
        "non_manifold_edges",
        "non_manifold_vertices",
        "inconsistent_edges",
        "degenerate_triangles",
        "duplicate_triangles",
        "self_intersections",
    ):
        assert s[key] == 0, key
    assert s["components"] == 1
    assert s["euler_characteristic"] == 2
    assert s["triangles_per_point"] == pytest.approx(len(triangles) / len(points))
    assert boundary_loops(triangles) == []


def test_torus_has_euler_characteristic_zero():
    mesh = pv.ParametricTorus().clean().triangulate()
    s = mesh_statistics(mesh.points, triangles_of(mesh))
    assert s["euler_characteristic"] == 0
    assert s["boundary_edges"] == s["holes"] == s["non_manifold_edges"] == 0
    assert s["self_intersections"] == 0
    assert s["components"] == 1


def test_bunny(bunny):
    points, faces, _ = bunny
    s = mesh_statistics(points, faces)
    assert s["points"] == 28_088 and s["triangles"] == 56_172
    assert s["boundary_edges"] == s["holes"] == 0
    assert s["non_manifold_edges"] == s["non_manifold_vertices"] == 0
    assert s["inconsistent_edges"] == s["degenerate_triangles"] == 0
    assert s["duplicate_triangles"] == s["unused_points"] == 0
    assert s["euler_characteristic"] == 2 and s["components"] == 1
    assert s["self_intersections"] == 0  # the pymeshlab bunny has none


def test_flat_grid_patch_has_one_hole():
    nx, ny = 9, 6
    points, triangles = grid_patch(nx, ny)
    s = mesh_statistics(points, triangles)
    assert s["boundary_edges"] == 2 * (nx - 1) + 2 * (ny - 1)
    assert s["holes"] == 1
    assert s["euler_characteristic"] == 1
    assert s["edges"] == (nx - 1) * ny + nx * (ny - 1) + (nx - 1) * (ny - 1)
    assert s["self_intersections"] == 0  # adjacent coplanar triangles do not intersect
    assert s["non_manifold_vertices"] == s["inconsistent_edges"] == 0
    (loop,) = boundary_loops(triangles)
    assert len(loop) == s["boundary_edges"] and len(set(loop.tolist())) == len(loop)
    # consecutive loop vertices are boundary half-edges, in their direction
    half = {
        tuple(e) for t in triangles.tolist() for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))
    }
    for a, b in zip(loop, np.roll(loop, -1), strict=True):
        assert (a, b) in half and (b, a) not in half


@pytest.mark.parametrize("k", [1, 3, 5])
def test_removing_separated_triangles_makes_holes(sphere, k):
    points, triangles = sphere
    s0 = mesh_statistics(points, triangles)
    # pick k triangles that share no vertex
    chosen, used = [], set()
    for t in range(0, len(triangles), 37):
        if not used & set(triangles[t].tolist()):
            chosen.append(t)
            used |= set(triangles[t].tolist())
        if len(chosen) == k:
            break
    s = mesh_statistics(points, np.delete(triangles, chosen, axis=0))
    assert s["holes"] == k
    assert s["boundary_edges"] == 3 * k
    assert s["euler_characteristic"] == 2 - k
    assert s["edges"] == s0["edges"]
    loops = boundary_loops(np.delete(triangles, chosen, axis=0))
    assert sorted(sorted(loop.tolist()) for loop in loops) == sorted(
        sorted(triangles[t].tolist()) for t in chosen
    )
    # each hole is walked against the orientation of the triangle removed from it
    for loop in loops:
        (t,) = [t for t in chosen if set(triangles[t].tolist()) == set(loop.tolist())]
        assert is_rotation(loop, triangles[t][::-1])


def test_bow_tie_has_one_non_manifold_vertex_and_two_loops():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    triangles = np.array([[0, 1, 2], [0, 3, 4]])
    s = mesh_statistics(points, triangles)
    assert s["non_manifold_vertices"] == 1
    assert s["non_manifold_edges"] == 0
    assert s["components"] == 2
    assert s["holes"] == 2 and s["boundary_edges"] == 6
    assert s["self_intersections"] == 0
    assert [loop.tolist() for loop in boundary_loops(triangles)] == [[0, 1, 2], [0, 3, 4]]


def test_pinched_squares_are_split_at_the_shared_vertex():
    # two squares (two triangles each) meeting at vertex 0 only
    points = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 0, 0], [-1, -1, 0], [0, -1, 0]], float
    )
    triangles = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 6]])
    loops = [loop.tolist() for loop in boundary_loops(triangles)]
    assert loops == [[0, 1, 2, 3], [0, 4, 5, 6]]
    s = mesh_statistics(points, triangles)
    assert s["non_manifold_vertices"] == 1 and s["holes"] == 2


def test_three_triangles_on_one_edge():
    points = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], float)
    triangles = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    s = mesh_statistics(points, triangles)
    assert s["non_manifold_edges"] == 1
    assert s["non_manifold_vertices"] == 0  # the edge joins the three triangles' umbrellas
    assert s["boundary_edges"] == 6 and s["edges"] == 7
    assert s["self_intersections"] == 0
    # the three boundary edges at each end of the edge cannot all be paired: one open
    # chain (3 vertices) and one closed loop
    loops = [loop.tolist() for loop in boundary_loops(triangles)]
    assert loops == [[1, 4, 0], [1, 2, 0, 3]]
    assert s["holes"] == 2


def test_one_flipped_triangle_gives_three_inconsistent_edges(sphere):
    points, triangles = sphere
    flipped = triangles.copy()
    flipped[17] = flipped[17][::-1]
    s = mesh_statistics(points, flipped)
    assert s["inconsistent_edges"] == 3
    assert s["boundary_edges"] == s["holes"] == s["non_manifold_edges"] == 0
    assert s["euler_characteristic"] == 2


def test_inconsistent_strip_still_has_one_closed_loop():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    triangles = np.array([[0, 1, 2], [1, 2, 3]])  # edge 1-2 used twice as 1 -> 2
    s = mesh_statistics(points, triangles)
    assert s["inconsistent_edges"] == 1
    (loop,) = boundary_loops(triangles)
    assert sorted(loop.tolist()) == [0, 1, 2, 3] and s["holes"] == 1


def test_degenerate_duplicate_and_unused():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [5, 5, 5], [0.5, 0, 0]], float)
    triangles = np.array(
        [
            [0, 1, 2],
            [2, 1, 0],  # same vertex set: a duplicate (and an intersecting pair)
            [0, 1, 2],  # a third copy: duplicates count 2
            [0, 0, 1],  # repeated index
            [0, 3, 5],  # zero area: collinear
        ]
    )
    s = mesh_statistics(points, triangles)
    assert s["duplicate_triangles"] == 2
    assert s["degenerate_triangles"] == 2
    assert s["unused_points"] == 1  # point 4
    assert s["self_intersections"] == 3  # the three copies, pairwise
    assert self_intersecting_pairs(points, triangles).tolist() == [[0, 1], [0, 2], [1, 2]]


def test_two_spheres_make_two_components(sphere):
    points, triangles = sphere
    both_p = np.concatenate([points, points + [3.0, 0, 0]])
    both_t = np.concatenate([triangles, triangles + len(points)])
    s = mesh_statistics(both_p, both_t)
    assert s["components"] == 2 and s["euler_characteristic"] == 4
    assert s["self_intersections"] == 0
    overlapping = np.concatenate([points, points + [0.5, 0, 0]])
    s = mesh_statistics(overlapping, both_t)
    assert s["self_intersections"] > 0


def test_empty_mesh_and_disabled_intersections(sphere):
    s = mesh_statistics(np.zeros((0, 3)), np.zeros((0, 3), dtype=int))
    assert s["triangles"] == s["edges"] == s["components"] == s["holes"] == 0
    assert s["triangles_per_point"] == 0.0
    s = mesh_statistics(np.zeros((4, 3)), np.zeros((0, 3), dtype=int))
    assert s["unused_points"] == 4 and s["euler_characteristic"] == 0
    assert self_intersecting_pairs(np.zeros((4, 3)), np.zeros((0, 3), dtype=int)).shape == (0, 2)
    points, triangles = sphere
    assert mesh_statistics(points, triangles, self_intersections=False)["self_intersections"] == -1


# ----------------------------------------------------------------------------- intersections


def test_two_crossing_triangles():
    points = np.array(
        [[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, -1], [0.5, 0.5, 1], [3, 3, 0]], float
    )
    assert self_intersecting_pairs(points, [[0, 1, 2], [3, 4, 5]]).tolist() == [[0, 1]]
    assert mesh_statistics(points, [[0, 1, 2], [3, 4, 5]])["self_intersections"] == 1
    lifted = points + np.array([[0, 0, 0]] * 3 + [[0, 0, 1.5]] * 3)
    assert self_intersecting_pairs(lifted, [[0, 1, 2], [3, 4, 5]]).shape == (0, 2)


def test_folded_pair_sharing_an_edge():
    points = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.3, 0.5, 0], [0.5, -1, 0]], float)
    assert self_intersecting_pairs(points, [[0, 1, 2], [1, 0, 3]]).tolist() == [[0, 1]]
    # adjacent coplanar triangles on both sides of the edge do not intersect
    assert self_intersecting_pairs(points, [[0, 1, 2], [1, 0, 4]]).shape == (0, 2)
    # a fold that is not flat (dihedral angle of 0.1 degree) only shares the edge
    tilted = points.copy()
    tilted[3, 2] = 0.5 * np.tan(np.radians(0.1))
    assert self_intersecting_pairs(tilted, [[0, 1, 2], [1, 0, 3]]).shape == (0, 2)


def test_shared_vertex_cases():
    v = [0.0, 0, 0]
    points = np.array(
        [v, [1, 0, 0], [0, 1, 0], [0.2, 0.2, -1], [0.2, 0.2, 1], [-1, 0, 0], [0, -1, 0]], float
    )
    # edge (3, 4) of the second triangle pierces the first one
    assert self_intersecting_pairs(points, [[0, 1, 2], [0, 3, 4]]).tolist() == [[0, 1]]
    # a flat fan: triangles sharing the centre but not overlapping
    angles = np.radians(np.arange(0, 360, 60))
    ring = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(6)])
    fan_p = np.vstack([[0, 0, 0], ring])
    fan_t = np.array([[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)])
    assert self_intersecting_pairs(fan_p, fan_t).shape == (0, 2)
    # coplanar triangles sharing a vertex whose sectors overlap
    overlap = np.array([[0, 1, 3], [0, 2, 4]])  # sectors 0-120 and 60-180 degrees
    assert self_intersecting_pairs(fan_p, overlap).tolist() == [[0, 1]]
    # only touching at the shared vertex, out of plane
    assert self_intersecting_pairs(points, [[0, 1, 2], [0, 5, 6]]).shape == (0, 2)


def test_coplanar_and_touching_triangles_without_shared_vertices():
    points = np.array(
        [
            [0, 0, 0],
            [2, 0, 0],
            [0, 2, 0],  # triangle 0
            [0.5, 0.5, 0],
            [3, 0.5, 0],
            [0.5, 3, 0],  # overlaps 0 in the plane
            [1, 1, 0],
            [3, 1, 0],
            [1, 3, 0],  # its corner on 0's long edge: touches
            [1.1, 1.1, 0],
            [3, 1.1, 0],
            [1.1, 3, 0],  # a gap of 0.14
        ],
        float,
    )
    tri = np.arange(12).reshape(4, 3)
    pairs = self_intersecting_pairs(points, tri)
    got = {tuple(p) for p in pairs.tolist()}
    assert (0, 1) in got and (0, 2) in got and (0, 3) not in got


def test_result_does_not_depend_on_triangle_order(sphere):
    points, triangles = sphere
    rng = np.random.default_rng(3)
    noisy = points + rng.normal(scale=0.02, size=points.shape)
    pairs = self_intersecting_pairs(noisy, triangles)
    assert len(pairs) > 0
    assert np.all(pairs[:, 0] < pairs[:, 1])
    assert np.array_equal(pairs, np.unique(pairs, axis=0))
    perm = rng.permutation(len(triangles))
    again = self_intersecting_pairs(noisy, triangles[perm])
    mapped = np.sort(perm[again], axis=1)
    assert np.array_equal(np.unique(mapped, axis=0), pairs)


@pytest.mark.parametrize("noise", [0.0, 0.002, 0.01, 0.03])
def test_pairs_at_plain_vertices_are_left_out_only_when_they_cannot_intersect(noise, monkeypatch):
    # the shortcut (pairs sharing a vertex whose triangles cover disjoint sectors around
    # it are not tested) finds exactly the pairs that testing every pair finds
    import fancloud_vtk.core.mesh_stats as ms

    mesh = pv.Sphere(theta_resolution=40, phi_resolution=40).clean()
    rng = np.random.default_rng(5)
    points = np.asarray(mesh.points, float)
    points = points + rng.normal(scale=noise, size=points.shape)
    tri = triangles_of(mesh)
    tri = np.vstack([tri, tri[:5], tri[10:15, ::-1]])  # repeated triangles intersect
    plain = ms._plain_vertices(points, tri, ms._triangle_frames(points, tri, ms.AREA_TOL,
                               ms.INTERSECTION_TOL)[0], len(points), ms._PLAIN_MARGIN,
                               ms._PLAIN_TILT, 4)
    assert 0 < plain.sum() < len(points)  # some are plain, not the repeated ones' vertices
    assert not plain[tri[:5]].any()
    got = self_intersecting_pairs(points, tri)
    monkeypatch.setattr(ms, "_PLAIN_TILT", 2.0)  # no vertex is plain: every pair is tested
    assert np.array_equal(got, self_intersecting_pairs(points, tri))
    assert len(got) >= 10


# ----------------------------------------------------------------------------- brute force

DELTA = 1e-6  # reference decisions closer than this to a tie are not compared


def _seg_tri_3d(p, q, a, b, c):
    """Margin of closed segment pq meeting closed triangle abc: > 0 meets, < 0 misses.

    Solves p + t (q - p) = a + u (b - a) + w (c - a) (Cramer's rule); general position.
    """
    d, e1, e2, r = q - p, b - a, c - a, p - a
    det = np.einsum("ij,ij->i", d, np.cross(e1, e2))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -np.einsum("ij,ij->i", r, np.cross(e1, e2)) / det
        u = np.einsum("ij,ij->i", d, np.cross(r, e2)) / det
        w = np.einsum("ij,ij->i", d, np.cross(e1, r)) / det
    margin = np.minimum.reduce([t, 1 - t, u, w, 1 - u - w])
    return np.where(np.abs(det) > 1e-9, margin, 0.0)  # parallel: not sure


def _orient(a, b, c):
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _seg_tri_2d(p, q, a, b, c):
    """Same margin in the plane: an endpoint inside, or a proper crossing of an edge."""
    s = np.sign(_orient(a, b, c))[:, None]

    def inside(x):
        return np.minimum.reduce(
            [_orient(a, b, x) * s[:, 0], _orient(b, c, x) * s[:, 0], _orient(c, a, x) * s[:, 0]]
        )

    def crossing(r, t):
        o1, o2 = _orient(p, q, r), _orient(p, q, t)
        o3, o4 = _orient(r, t, p), _orient(r, t, q)
        return np.minimum(
            -np.sign(o1 * o2) * np.minimum(abs(o1), abs(o2)),
            -np.sign(o3 * o4) * np.minimum(abs(o3), abs(o4)),
        )

    return np.maximum.reduce([inside(p), inside(q), crossing(a, b), crossing(b, c), crossing(c, a)])


def reference_pairs(points, triangles, planar: bool):
    """Brute force over all pairs: (intersecting pairs, pairs whose answer is sure).

    Planar data: points ``(n, 2)``, triangles in the plane. Definitions (general
    position): no shared vertex -- some edge of one meets the other; one shared
    vertex -- the edge opposite it in one meets the other; a shared edge -- only
    when folded flat (planar data: both third vertices on one side); the same
    triangle twice -- always.
    """
    seg_tri = _seg_tri_2d if planar else _seg_tri_3d
    m = len(triangles)
    ii, jj = np.triu_indices(m, 1)
    ti, tj = triangles[ii], triangles[jj]
    in_j = (ti[:, :, None] == tj[:, None, :]).any(axis=2)
    in_i = (tj[:, :, None] == ti[:, None, :]).any(axis=2)
    shared = in_j.sum(axis=1)
    hit = np.zeros(len(ii), dtype=bool)
    sure = np.ones(len(ii), dtype=bool)
    P = points

    k = shared == 0
    margins = []
    for a in range(3):
        for s, o in ((ti[k], tj[k]), (tj[k], ti[k])):
            margins.append(
                seg_tri(P[s[:, a]], P[s[:, (a + 1) % 3]], P[o[:, 0]], P[o[:, 1]], P[o[:, 2]])
            )
    best = np.max(margins, axis=0)
    hit[k], sure[k] = best > 0, np.abs(best) > DELTA

    k = shared == 1
    own = ti[k][~in_j[k]].reshape(-1, 2)
    other = tj[k][~in_i[k]].reshape(-1, 2)
    best = np.maximum(
        seg_tri(P[own[:, 0]], P[own[:, 1]], P[tj[k, 0]], P[tj[k, 1]], P[tj[k, 2]]),
        seg_tri(P[other[:, 0]], P[other[:, 1]], P[ti[k, 0]], P[ti[k, 1]], P[ti[k, 2]]),
    )
    hit[k], sure[k] = best > 0, np.abs(best) > DELTA

    k = shared == 2
    edge = ti[k][in_j[k]].reshape(-1, 2)
    c = ti[k][~in_j[k]]
    d = tj[k][~in_i[k]]
    if planar:
        oc = _orient(P[edge[:, 0]], P[edge[:, 1]], P[c])
        od = _orient(P[edge[:, 0]], P[edge[:, 1]], P[d])
        hit[k] = oc * od > 0
        sure[k] = np.minimum(abs(oc), abs(od)) > DELTA
    else:
        n = np.cross(P[edge[:, 1]] - P[edge[:, 0]], P[c] - P[edge[:, 0]])
        height = np.einsum("ij,ij->i", n, P[d] - P[edge[:, 0]]) / np.linalg.norm(n, axis=1)
        hit[k] = False
        sure[k] = np.abs(height) > DELTA

    hit[shared == 3] = True
    return np.column_stack([ii, jj]), hit, sure


def embed(points2d, seed):
    """Put planar points into a random plane of space."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return np.column_stack([points2d, np.zeros(len(points2d))]) @ q.T + rng.normal(size=3)


def random_soup(rng, m, dim):
    centres = rng.uniform(0, 1, size=(m, 1, dim))
    points = (centres + rng.normal(scale=0.08, size=(m, 3, dim))).reshape(-1, dim)
    return points, np.arange(3 * m).reshape(m, 3)


def jittered_sphere(rng):
    mesh = pv.Sphere(theta_resolution=12, phi_resolution=14).clean()
    points = np.asarray(mesh.points, dtype=float)
    return points + rng.normal(scale=0.06, size=points.shape), triangles_of(mesh)


def jittered_grid(rng):
    points, triangles = grid_patch(12, 12)
    return points[:, :2] + rng.normal(scale=0.3, size=(len(points), 2)), triangles


@pytest.mark.parametrize(
    ("case", "planar"),
    [("soup", False), ("sphere", False), ("soup", True), ("grid", True)],
)
@pytest.mark.parametrize("seed", [0, 1])
def test_matches_brute_force_reference(case, planar, seed):
    rng = np.random.default_rng(seed)
    if case == "soup":
        points, triangles = random_soup(rng, 300, 2 if planar else 3)
    elif case == "sphere":
        points, triangles = jittered_sphere(rng)
    else:
        points, triangles = jittered_grid(rng)
    pairs, hit, sure = reference_pairs(points, triangles, planar)
    assert sure.mean() > 0.995
    space = embed(points, seed) if planar else points
    got = self_intersecting_pairs(space, triangles)
    got_mask = np.zeros(len(pairs), dtype=bool)
    m = len(triangles)
    got_mask[np.searchsorted(pairs[:, 0] * m + pairs[:, 1], got[:, 0] * m + got[:, 1])] = True
    wrong = sure & (got_mask != hit)
    assert not wrong.any(), (pairs[wrong], hit[wrong])
    assert hit[sure].sum() > 10  # the cases do intersect
    if case != "soup":  # the mesh cases exercise shared vertices and (planar) folds
        ti, tj = triangles[pairs[:, 0]], triangles[pairs[:, 1]]
        shared = (ti[:, :, None] == tj[:, None, :]).any(axis=2).sum(axis=1)
        assert (hit & sure & (shared == 1)).sum() > 0
        if planar:
            assert (hit & sure & (shared == 2)).sum() > 0
    assert mesh_statistics(space, triangles)["self_intersections"] == len(got)


# ----------------------------------------------------------------------------- input checks


def test_inputs_are_not_modified(sphere):
    points, triangles = sphere
    points = points + np.random.default_rng(0).normal(scale=0.02, size=points.shape)
    tri32 = triangles.astype(np.int32)
    before = fingerprint(points, triangles, tri32)
    mesh_statistics(points, triangles)
    mesh_statistics(points.astype(np.float32), tri32)
    self_intersecting_pairs(points, tri32)
    boundary_loops(triangles[5:])
    assert fingerprint(points, triangles, tri32) == before
    points.flags.writeable = False
    triangles.flags.writeable = False
    assert mesh_statistics(points, triangles)["triangles"] == len(triangles)


@pytest.mark.parametrize(
    ("points", "triangles", "match"),
    [
        (np.zeros((3, 2)), [[0, 1, 2]], "points must have shape"),
        ([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], "NaN or infinite"),
        ([[0, 0, np.inf], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], "NaN or infinite"),
        ([["a", "b", "c"]] * 3, [[0, 1, 2]], "real numbers"),
        (np.eye(3), [[0, 1]], "triangles must have shape"),
        (np.eye(3), [[0, 1, 3]], "out of range"),
        (np.eye(3), [[0, -1, 2]], "negative"),
        (np.eye(3), [[0.0, 1.0, 2.0]], "integer"),
        (np.eye(3), [[0, 1, 2], [0, 1]], "triangles"),
    ],
)
def test_bad_input(points, triangles, match):
    with pytest.raises(MeshInputError, match=match):
        mesh_statistics(points, triangles)
    with pytest.raises(ValueError, match=match):
        self_intersecting_pairs(points, triangles)


def test_bad_triangles_for_boundary_loops():
    with pytest.raises(MeshInputError, match="negative"):
        boundary_loops([[0, 1, -2]])
    with pytest.raises(MeshInputError, match="integer"):
        boundary_loops(np.ones((2, 3)))


def test_boundary_loops_with_sparse_vertex_numbers():
    big = 10**15
    triangles = np.array([[big, 7, big + 5], [big, big + 5, 3]])
    assert [loop.tolist() for loop in boundary_loops(triangles)] == [[big, 7, big + 5, 3]]
