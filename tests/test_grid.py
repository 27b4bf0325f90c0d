"""The uniform-grid neighbour search is exact: same neighbours as a kd-tree."""

import numpy as np
import pytest
from scipy.spatial import cKDTree
from shapes import density_jump, sphere

from fancloud_vtk.core import _grid_kernels as G
from fancloud_vtk.core.fans import Grid


def _clouds():
    rng = np.random.default_rng(11)
    clustered = np.vstack([rng.normal(size=(3000, 3)) * 0.01, rng.normal(size=(300, 3)) * 5])
    outliers = np.vstack([sphere(4000, seed=2), [[40.0, 0, 0], [0, -70.0, 3], [1e3, 1e3, 1e3]]])
    return {
        "sphere": sphere(5000, seed=1),
        "density_jump": density_jump(4000, seed=3),
        "volume": rng.uniform(size=(4000, 3)),
        "clustered": clustered,
        "outliers": outliers,
    }


@pytest.mark.parametrize("name", sorted(_clouds()))
def test_grid_knn_equals_kdtree(name):
    pts = _clouds()[name]
    grid = Grid(pts)
    sp = grid.sorted_points
    assert np.array_equal(np.sort(grid.order), np.arange(len(pts)))
    np.testing.assert_array_equal(sp, pts[grid.order])
    kq = 20
    which = np.arange(len(pts), dtype=np.int64)
    got, _ = grid.knn(which, kq, None, 1)
    dist, want = cKDTree(sp).query(sp, k=kq + 1)
    # same distances (ties may order differently in the tree, never in the grid)
    got_d = np.linalg.norm(sp[got] - sp[:, None, :], axis=2)
    np.testing.assert_allclose(got_d, dist[:, 1:], rtol=0, atol=1e-12)
    assert np.all(got != which[:, None]), "the point itself is never its own neighbour"
    assert np.all(np.diff(got_d, axis=1) >= 0)


def test_cells_hold_their_points_in_morton_order():
    pts = sphere(3000, seed=4)
    grid = Grid(pts)
    inv_h = 1.0 / grid.h
    cell = np.floor((grid.sorted_points - grid.lo) * inv_h).astype(np.int64)
    owner = np.repeat(np.arange(grid.n_cells), np.diff(grid.start))
    np.testing.assert_array_equal(cell, grid.cell_xyz[owner])
    # every cell is found through the hash table
    for r in range(grid.n_cells):
        assert G.lookup(grid.table, *grid.cell_xyz[r]) == r
    assert G.lookup(grid.table, -1, 0, 0) == -1


def test_table_grows_when_the_estimate_is_far_off():
    pts = sphere(5000, seed=5)
    lo = pts.min(axis=0)
    h = 0.05
    small = G.build_grid(pts, lo, 1.0 / h, 2)
    right = G.build_grid(pts, lo, 1.0 / h, 5000)
    for a, b in zip(small[:3], right[:3], strict=True):
        np.testing.assert_array_equal(a, b)


def test_duplicates_are_counted():
    pts = sphere(2000, seed=6)
    with_dups = np.vstack([pts, pts[:7], pts[:2]])
    lo = with_dups.min(axis=0)
    assert G.build_grid(with_dups, lo, 20.0, 100)[-1] == 9
    assert G.build_grid(pts, lo, 20.0, 100)[-1] == 0


def test_far_outlier_does_not_make_the_search_quadratic():
    """A far outlier makes the grid's cells huge; crowded blocks go to the kd-tree."""
    import time

    from fancloud_vtk import build_fans

    p = np.vstack([sphere(30_000, seed=7), [[1e9, 0.0, 0.0]] + sphere(7, seed=8) * 1e-3])
    build_fans(np.vstack([p[:2_000], p[30_000:]]))  # compiled first: the search is timed
    t0 = time.perf_counter()
    fc = build_fans(p)
    elapsed = time.perf_counter() - t0
    assert fc.n_open <= 30, "the sphere's fans are closed as without the outlier"
    ref = build_fans(p[:30_000])
    np.testing.assert_array_equal(fc.ring[: ref.offsets[-1]], ref.ring)
    assert elapsed < 60, f"{elapsed:.1f} s: the search went quadratic"


def test_crowded_cell_duplicates_counted_by_sorting():
    rng = np.random.default_rng(9)
    base = rng.uniform(size=(500, 3))
    pts = np.vstack([base, base[:40], base[100:103]])
    lo = pts.min(axis=0)
    # one cell holds everything: the sort-based count
    assert G.build_grid(pts, lo, 0.5, 4)[-1] == 43

