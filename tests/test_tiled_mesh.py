"""The mesh in tiles with halos (fancloud_vtk.distributed.tiled_mesh): the triangles and
normals of one process on every cloud and scheduler; a halo too narrow is grown where the
tiles disagree."""

import warnings

import numpy as np
import pytest
from conftest import fingerprint
from dask_helpers import local_cluster
from test_distributed import cube_surface, sphere

import fancloud_vtk.distributed as D
from fancloud_vtk import build_fans, fan_cloud_to_mesh, tiled_fans, tiled_mesh
from fancloud_vtk.data import pymeshlab_sample
from fancloud_vtk.io import read_point_cloud


def rows(triangles) -> np.ndarray:
    """Each triangle from its lowest point on (its way round kept), the rows sorted."""
    t = np.asarray(triangles)
    first = np.argmin(t, axis=1)
    t = t[np.arange(len(t))[:, None], (first[:, None] + np.arange(3)) % 3]
    return t[np.lexsort(t.T[::-1])]


def same_mesh(a, b) -> bool:
    """The same triangles, each the same way round, the same normals and outliers."""
    return (np.array_equal(rows(a.triangles), rows(b.triangles))
            and np.array_equal(a.normals, b.normals) and np.array_equal(a.outliers, b.outliers)
            and all(a.stats[key] == b.stats[key] for key in
                    ("boundary_edges", "holes", "non_manifold_edges", "non_manifold_vertices",
                     "unused_points", "local_rings", "normals_flipped", "pieces_turned")))


def torus(n, seed=6):
    u, v = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, (2, n))
    return np.c_[(1 + 0.35 * np.cos(v)) * np.cos(u), (1 + 0.35 * np.cos(v)) * np.sin(u),
                 0.35 * np.sin(v)]


def sheet_with_gap(n, seed=11):
    """A gently curved open sheet with a gap across it and a round hole: open fans along
    three kinds of boundary."""
    rng = np.random.default_rng(seed)
    uv = rng.random((n, 2))
    uv = uv[((uv[:, 1] < 0.4) | (uv[:, 1] > 0.45))
            & (np.hypot(uv[:, 0] - 0.7, uv[:, 1] - 0.75) > 0.1)]
    return np.c_[uv, 0.2 * np.sin(3 * uv[:, 0]) * np.cos(2 * uv[:, 1])]


def cow():
    """The cow's vertices: a symmetric model (distances tie between mirrored points), thin
    legs (the mesh falls back to the local rings) and one duplicate point."""
    return read_point_cloud(pymeshlab_sample("cow.obj")).points


def one_mesh(points, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # duplicates, a doubtful mesh
        return fan_cloud_to_mesh(build_fans(points), **kw)


def tiled(points, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return tiled_mesh(points, **kw)


CLOUDS = {
    "sphere": lambda: sphere(20_000, seed=7),
    "torus": lambda: torus(20_000),
    "cube": lambda: cube_surface(20_000),
    "sheet_with_gap": lambda: sheet_with_gap(20_000),
}


@pytest.mark.parametrize("name, tiles", [(name, (2, 2, 2)) for name in sorted(CLOUDS)]
                         + [("sphere", (4, 4, 1))])
def test_the_tiled_mesh_is_that_of_one_process(name, tiles):
    points = CLOUDS[name]()
    before = fingerprint(points)
    one = one_mesh(points)
    mesh = tiled(points, tiles=tiles, scheduler="sync")
    assert len(mesh.triangles) == len(one.triangles) > len(points)
    assert same_mesh(mesh, one)
    assert fingerprint(points) == before


def test_the_cow_in_tiles_is_the_cow_of_one_process():
    """Ties between distances are broken in the whole cloud's cell order in every tile
    (the fans of the cow's tiles differed before), and the choice of the local rings is
    made on the stitched mesh."""
    points = cow()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        fans = build_fans(points)
        for tiles in [(2, 2, 2), (4, 1, 1)]:
            fc = tiled_fans(points, tiles=tiles, scheduler="sync")
            assert np.array_equal(fc.ring, fans.ring) and np.array_equal(fc.normals,
                                                                         fans.normals)
    local = []
    for rings in ["auto", "delaunay"]:  # (the cow is small: each tile's halo holds most of it)
        one = one_mesh(points, rings=rings)
        mesh = tiled(points, tiles=(2, 1, 1), rings=rings)
        assert same_mesh(mesh, one), rings
        local.append(mesh.stats["local_rings"])
    assert local == [1, 0]  # auto: the local rings, as in one process
    np.testing.assert_array_equal(mesh.point_data["original_id"],
                                  one.point_data["original_id"])


def test_where_a_tile_chooses_another_filling_round_the_mesh_differs_a_little():
    """The known exception (tiled_mesh's docstring): the filling rounds keep the round best
    over the whole mesh, and a tile counts over its own part. On this torus 4 of 60,000
    triangles differ, inside one tile; the stitched mesh is still a closed 2-manifold
    without crossings, and its checks are counted on it."""
    points = torus(30_000, seed=12)
    one = one_mesh(points)
    mesh = tiled(points, tiles=(2, 2, 1), scheduler="sync")
    differ = np.setdiff1d(D._tri_keys(mesh.triangles), D._tri_keys(one.triangles))
    assert 0 < len(differ) <= 0.001 * len(one.triangles)
    assert len(mesh.triangles) == len(one.triangles) == 2 * len(points)
    assert all(mesh.stats[key] == 0 for key in
               ("boundary_edges", "non_manifold_edges", "non_manifold_vertices",
                "inconsistent_edges", "self_intersections", "unused_points"))
    assert mesh.stats["euler_characteristic"] == 0  # the torus's genus kept


def test_halos_at_and_above_the_default_and_a_narrow_one_grown():
    points = torus(20_000, seed=8)
    one = one_mesh(points)
    default = D.MESH_HALO * D._auto_halo(points, 6)
    for halo in [default, 1.5 * default]:
        mesh = tiled(points, tiles=(2, 2, 1), halo=halo, scheduler="sync")
        assert same_mesh(mesh, one)
        assert mesh.stats["rebuilt"] == 0 and min(mesh.stats["halos"]) == halo
    # a halo of about one spacing: the tiles' bands disagree, and the halos are doubled
    # until they agree
    narrow = tiled(points, tiles=(2, 2, 1), halo=default / 40, scheduler="sync")
    assert narrow.stats["rebuilt"] > 0 and max(narrow.stats["halos"]) > default / 40
    assert same_mesh(narrow, one)


def test_threads_and_a_local_cluster_give_the_same_mesh():
    pytest.importorskip("dask.distributed")
    points = sphere(20_000, seed=9)
    one = one_mesh(points)
    assert same_mesh(tiled(points, tiles=(2, 2, 1), scheduler="threads"), one)
    with local_cluster(2) as (cluster, client):
        assert same_mesh(tiled(points, tiles=(2, 2, 1), scheduler=client), one)


def test_options_and_point_data_pass_through():
    points = sheet_with_gap(20_000, seed=3)
    label = np.arange(len(points))
    kw = dict(close_holes=False, min_component=0, max_hole=16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # holes left open: a doubtful mesh
        one = fan_cloud_to_mesh(build_fans(points, k=8, point_data={"label": label}), **kw)
    mesh = tiled(points, k=8, tiles=(2, 2, 1), scheduler="sync", point_data={"label": label},
                 **kw)
    assert same_mesh(mesh, one)
    np.testing.assert_array_equal(mesh.point_data["label"], label)


@pytest.mark.slow
def test_the_tiled_mesh_of_a_million_points():
    points = torus(1_000_000, seed=10)
    assert same_mesh(tiled(points, tiles=(2, 2, 2)), one_mesh(points))


def test_the_tiled_mesh_of_two_hundred_thousand_points():
    """The quick variant of the test above (CI)."""
    points = torus(200_000, seed=10)
    assert same_mesh(tiled(points, tiles=(2, 2, 2)), one_mesh(points))


@pytest.mark.parametrize("kw, error, match", [
    (dict(rings="fans"), ValueError, "not offered in tiles"),
    (dict(rings="nope"), ValueError, "rings must be one of"),
    (dict(max_hole=2), ValueError, "max_hole"),
    (dict(min_component=-1), ValueError, "min_component"),
    (dict(max_hole_diameter="6"), TypeError, "max_hole_diameter"),
    (dict(halo=-1.0), ValueError, "halo"),
    (dict(tiles=(0, 1, 1)), ValueError, "tiles"),
    (dict(k=2), ValueError, "k must be"),
])
def test_bad_parameters_are_refused(kw, error, match):
    with pytest.raises(error, match=match):
        tiled_mesh(sphere(2_000), scheduler="sync", **kw)


def test_bad_points_are_refused():
    p = sphere(2_000)
    p[5, 1] = np.nan
    with pytest.raises(ValueError, match="NaN|finite"):
        tiled_mesh(p, scheduler="sync")
    with pytest.raises(ValueError, match="k \\+ 1"):
        tiled_mesh(sphere(5), scheduler="sync")


def test_the_mesh_command_in_tiles_writes_the_tiled_mesh(tmp_path, capsys):
    """``fancloud mesh BIG.ply -o OUT.ply --tiles 2,2,1 --workers 2``: a LocalCluster; the
    file written is tiled_mesh's mesh, with the file's colours."""
    pytest.importorskip("dask.distributed")
    from test_distributed import write_ply_rgb

    from fancloud_vtk.cli import main

    points = torus(30_000, seed=12)
    rgb = (np.arange(len(points))[:, None] * [1, 7, 13] % 256).astype(np.uint8)
    write_ply_rgb(tmp_path / "big.ply", points, rgb)
    code = main(["mesh", str(tmp_path / "big.ply"), "-o", str(tmp_path / "tiles.ply"),
                 "--tiles", "2,2,1", "--workers", "2"])
    assert code == 0
    text = capsys.readouterr().out
    assert "tiles built again" in text and "2x2x1" in text
    tiles = read_point_cloud(tmp_path / "tiles.ply")
    mesh = tiled(points, tiles=(2, 2, 1))
    assert np.array_equal(rows(tiles.faces), rows(mesh.triangles))
    np.testing.assert_allclose(tiles.points, points, rtol=0, atol=1e-6)  # (float32 PLY)
    np.testing.assert_array_equal(tiles.point_data["RGB"], rgb)
    for bad, message in [(["--rings", "fans"], "--rings fans does not go with --tiles"),
                         (["--no-orient"], "--no-orient does not go with --tiles"),
                         (["--scheduler", "threads"], "must be a Dask scheduler address")]:
        assert main(["mesh", str(tmp_path / "big.ply"), "-o", str(tmp_path / "x.ply"),
                     "--tiles", "2,2,1", *bad]) == 2
        assert message in capsys.readouterr().err
    assert main(["mesh", str(tmp_path / "big.ply"), "-o", str(tmp_path / "x.ply"),
                 "--workers", "2"]) == 2
    assert "--workers goes with --tiles" in capsys.readouterr().err
