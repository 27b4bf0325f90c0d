"""Fans in tiles with halos (fancloud_vtk.distributed): the fan cloud of one process, bit for
bit, on every scheduler; the halo grows where a fan needs it."""

import warnings

import numpy as np
import pytest
from conftest import fingerprint
from dask_helpers import local_cluster

import fancloud_vtk.distributed as D
from fancloud_vtk import FanCloudInputError, build_fans, tile_boxes, tiled_fans, tiled_reduce


def same(a, b) -> bool:
    """The two fan clouds are the same, array for array (rings, normals, flags)."""
    return (np.array_equal(a.offsets, b.offsets) and np.array_equal(a.ring, b.ring)
            and np.array_equal(a.normals, b.normals) and np.array_equal(a.open, b.open)
            and np.array_equal(a.rotated, b.rotated))


def sphere(n, seed=0):
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1)[:, None]


def write_las(path, points):
    """A LAS file of the points (1e-3 steps) with intensity, classification and colours."""
    laspy = pytest.importorskip("laspy")
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([1e-3, 1e-3, 1e-3])
    header.offsets = np.zeros(3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    las.intensity = np.arange(len(points)) % 5000
    las.classification = np.arange(len(points)) % 7
    las.red = las.green = las.blue = (np.arange(len(points)) % 256) * 256
    las.write(str(path))


def write_ply_rgb(path, points, rgb, faces=None):
    """A binary PLY of the points with 8-bit colours (and triangles, if given)."""
    import plyfile

    v = np.empty(len(points), [(c, "f8") for c in "xyz"]
                 + [(c, "u1") for c in ("red", "green", "blue")])
    for j, c in enumerate("xyz"):
        v[c] = points[:, j]
    for j, c in enumerate(("red", "green", "blue")):
        v[c] = rgb[:, j]
    elements = [plyfile.PlyElement.describe(v, "vertex")]
    if faces is not None:
        f = np.empty(len(faces), [("vertex_indices", "i4", (3,))])
        f["vertex_indices"] = faces
        elements.append(plyfile.PlyElement.describe(f, "face"))
    plyfile.PlyData(elements).write(str(path))


def ramp_with_gap(n, seed=1):
    """A noisy plane whose density falls 1000-fold across it, with a gap 5% wide: open
    fans along the gap and the border, whose gap-directed search reaches far."""
    rng = np.random.default_rng(seed)
    uv = rng.random((n, 2))
    uv[:, 0] **= 3
    uv = uv[(uv[:, 1] < 0.4) | (uv[:, 1] > 0.45)]
    return np.c_[uv, 0.001 * rng.normal(size=len(uv))]


def cube_surface(n, seed=2):
    """Random points on the cube's faces: sharp edges and corners, rotated fans."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(-1, 1, (n, 3))
    axis = rng.integers(0, 3, n)
    p[np.arange(n), axis] = np.sign(p[np.arange(n), axis])
    return p


def terrain_grid(side):
    """A height field on a regular grid: distances tie everywhere."""
    g = np.linspace(0.0, 1.0, side)
    x, y = np.meshgrid(g, g)
    return np.c_[x.ravel(), y.ravel(), 0.1 * np.sin(6 * x.ravel()) * np.cos(5 * y.ravel())]


def kill_a_worker_while(client, call):
    """``call()`` in a thread; the first LocalCluster worker seen busy is killed (SIGKILL)
    while it runs; the call's result (it must finish all the same)."""
    import os
    import signal
    import threading
    import time

    pids = client.run(os.getpid)
    out = {}
    run = threading.Thread(target=lambda: out.setdefault("result", call()))
    run.start()
    killed = None
    deadline = time.monotonic() + 60
    while killed is None and time.monotonic() < deadline and run.is_alive():
        busy = [w for w, tasks in client.processing().items() if tasks]
        if busy:
            killed = pids[busy[0]]
            os.kill(killed, signal.SIGKILL)
        else:
            time.sleep(0.01)
    assert killed is not None, "no tile was running on a worker"
    assert run.is_alive(), "the run had finished before the kill"
    run.join(timeout=300)
    assert not run.is_alive()
    return out["result"]


CLOUDS = {
    "sphere": lambda: sphere(60_000),
    "ramp_with_gap": lambda: ramp_with_gap(60_000),
    "cube": lambda: cube_surface(60_000),
    "terrain_grid": lambda: terrain_grid(200),
}


@pytest.mark.parametrize("tiles", [(2, 2, 2), (4, 4, 1)])
@pytest.mark.parametrize("name", sorted(CLOUDS))
def test_tiled_fans_are_those_of_one_process(name, tiles):
    points = CLOUDS[name]()
    before = fingerprint(points)
    one = build_fans(points)
    fc = tiled_fans(points, tiles=tiles, scheduler="sync")
    assert same(fc, one)
    assert fc.info["fans_open"] == one.info["fans_open"]
    assert sum(owned for owned, _ in fc.info["tile_points"]) == len(points)
    assert fingerprint(points) == before


@pytest.mark.parametrize("name", ["sphere", "ramp_with_gap"])
def test_at_and_above_the_halo_found_nothing_is_rebuilt(name):
    """Starting from no halo, every tile grows its own; given the widest of those (and
    half as much again), no tile is built twice and the result is the same."""
    points = CLOUDS[name]()
    one = build_fans(points)
    grown = tiled_fans(points, tiles=(2, 2, 2), halo=0.0, scheduler="sync")
    assert grown.info["rebuilt"] > 0  # no halo at all is too little: it grew
    assert same(grown, one)
    widest = max(grown.info["halos"])
    for halo in (widest, 1.5 * widest):
        fc = tiled_fans(points, tiles=(2, 2, 2), halo=halo, scheduler="sync")
        assert fc.info["rebuilt"] == 0
        assert same(fc, one)


def test_without_the_margin_the_tiles_differ(monkeypatch):
    """The certification is what makes the tiles agree: with no margin the halo stays at
    0 and many fans along the tiles' faces come out different."""
    points = CLOUDS["ramp_with_gap"]()
    one = build_fans(points)
    monkeypatch.setattr(D, "MARGIN", 0.0)
    monkeypatch.setattr(D, "OPEN_MARGIN", 0.0)
    fc = tiled_fans(points, tiles=(4, 4, 1), halo=0.0, scheduler="sync")
    assert fc.info["rebuilt"] == 0
    differ = (np.diff(fc.offsets) != np.diff(one.offsets)) | (fc.normals != one.normals).any(1)
    assert differ.sum() > 100


def test_threads_and_a_local_cluster_give_the_same_fans():
    pytest.importorskip("dask.distributed")
    points = sphere(40_000, seed=3)
    one = build_fans(points)
    assert same(tiled_fans(points, tiles=(2, 2, 1), scheduler="threads"), one)
    with local_cluster(2) as (cluster, client):
        assert same(tiled_fans(points, tiles=(2, 2, 1), scheduler=client), one)
        # a scheduler address connects a client of its own
        assert same(tiled_fans(points, tiles=(2, 1, 1), scheduler=cluster.scheduler_address),
                    one)


def test_parameters_and_point_data_pass_through():
    points = sphere(20_000, seed=4)
    label = np.arange(len(points))
    kw = dict(k=8, max_angle=80.0, reach=3.0)
    one = build_fans(points, **kw, point_data={"label": label})
    fc = tiled_fans(points, tiles=(2, 2, 2), scheduler="sync", **kw,
                    point_data={"label": label})
    assert same(fc, one)
    np.testing.assert_array_equal(fc.point_data["label"], label)
    unoriented = tiled_fans(points, tiles=(2, 2, 2), scheduler="sync", orient=False)
    assert same(unoriented, build_fans(points, orient=False))


@pytest.mark.slow
@pytest.mark.parametrize("tiles", [(2, 2, 2), (4, 4, 1)])
def test_tiled_fans_of_two_million_points(tiles):
    points = sphere(2_000_000, seed=5)
    assert same(tiled_fans(points, tiles=tiles), build_fans(points))


def test_tiled_fans_of_three_hundred_thousand_points():
    """The quick variant of the test above (CI)."""
    points = sphere(300_000, seed=5)
    assert same(tiled_fans(points, tiles=(2, 2, 2)), build_fans(points))


def test_tile_boxes_cover_the_points_in_morton_order():
    points = np.random.default_rng(6).random((5000, 3)) * [4.0, 2.0, 1.0]
    lo, hi, owner = tile_boxes(points, (2, 2, 2))
    assert lo.shape == hi.shape == (8, 3)
    inside = np.all((points >= lo[owner]) & (points <= hi[owner]), axis=1)
    assert inside.all()
    centres = 0.5 * (lo + hi)
    # Morton order: the first four tiles are the lower half along z
    assert (centres[:4, 2] < centres[4:, 2].min()).all()


@pytest.mark.parametrize("tiles", [(2, 2), (0, 1, 1), (1.5, 1, 1), "auto"])
def test_bad_tiles_are_refused(tiles):
    with pytest.raises(FanCloudInputError, match="tiles"):
        tiled_fans(sphere(1000), tiles=tiles)


@pytest.mark.parametrize("halo, error", [(-1.0, FanCloudInputError),
                                         (float("nan"), FanCloudInputError),
                                         ("wide", TypeError), (True, TypeError)])
def test_bad_halo_is_refused(halo, error):
    with pytest.raises(error, match="halo"):
        tiled_fans(sphere(1000), halo=halo)


def test_duplicates_are_merged_as_build_fans_merges_them():
    """Duplicates: merged (the first of each kept) with build_fans' warning; the same fan
    cloud as build_fans, with its original_id and passthrough arrays."""
    from fancloud_vtk import DuplicatePointsWarning

    points = sphere(3000, seed=4)
    dup = np.vstack([points, points[[3, 8, 8]]])
    value = {"value": np.arange(len(dup), dtype=np.float64)}
    with pytest.warns(DuplicatePointsWarning, match="3 duplicate point"):
        one = build_fans(dup, point_data=value)
    with pytest.warns(DuplicatePointsWarning, match="3 duplicate point"):
        fc = tiled_fans(dup, tiles=(2, 2, 1), point_data=value)
    assert same(fc, one) and fc.info["duplicates_merged"] == 3
    for name in ("original_id", "value"):
        np.testing.assert_array_equal(fc.point_data[name], one.point_data[name])


def test_duplicates_out_of_core_are_merged_as_build_fans_merges_them(tmp_path):
    """A PLY with copies of points read in other chunks (as a LAS file's rounding makes
    them), some in tile halos, one tile owning only copies of two points: the tiles merge
    them (the first row of each kept, with its colours), with build_fans' warning, and
    read_tiles gives build_fans' fan cloud, its original_id included."""
    from fancloud_vtk import DuplicatePointsWarning
    from fancloud_vtk.io import read_point_cloud

    rng = np.random.default_rng(7)
    points = sphere(6_000, seed=7)
    copies = rng.integers(0, len(points), 300)
    corner = np.array([[3.0, 3.0, 3.0], [3.0, 3.0, 3.01]])  # alone in its tile
    rows = np.vstack([points, points[copies], corner, corner, corner])
    rows = rows[rng.permutation(len(rows))]
    rgb = (np.arange(len(rows))[:, None] * [1, 7, 13] % 256).astype(np.uint8)
    write_ply_rgb(tmp_path / "c.ply", rows, rgb)
    cloud = read_point_cloud(tmp_path / "c.ply")
    merged = len(rows) - len(np.unique(rows, axis=0))
    with pytest.warns(DuplicatePointsWarning, match=f"{merged} duplicate point"):
        one = build_fans(cloud.points, point_data=cloud.point_data)
    with pytest.warns(DuplicatePointsWarning, match=f"{merged} duplicate point"):
        index = D.write_tiled_fans(tmp_path / "c.ply", tmp_path / "out", tiles=(2, 2, 1),
                                   scheduler="sync", chunk=1_000)
    assert index["n_points"] == len(rows) and index["duplicates_merged"] == merged
    fc = D.read_tiles(tmp_path / "out")
    assert same(fc, one) and np.array_equal(fc.points, one.points)
    assert fc.info["duplicates_merged"] == merged
    assert sorted(fc.point_data) == sorted(one.point_data)
    for name, arr in one.point_data.items():
        np.testing.assert_array_equal(fc.point_data[name], arr)


def test_nan_and_bad_scheduler_are_refused():
    points = sphere(1000)
    bad = points.copy()
    bad[5, 1] = np.nan
    with pytest.raises(FanCloudInputError):
        tiled_fans(bad)
    with pytest.raises(TypeError, match="scheduler"):
        tiled_fans(points, scheduler=42)
    with pytest.raises(FanCloudInputError):
        tiled_fans(points[:5])


def test_a_worker_killed_mid_run_leaves_the_same_fans():
    """A LocalCluster worker process killed while tiles are running: Dask runs its tiles
    again elsewhere, and the fan cloud is still build_fans'."""
    pytest.importorskip("dask.distributed")
    points = sphere(400_000, seed=7)
    one = build_fans(points)
    with local_cluster(2) as (cluster, client):
        tiled_fans(points[:20_000], tiles=(2, 1, 1), scheduler=client)  # kernels loaded
        out = kill_a_worker_while(client, lambda: tiled_fans(points, tiles=(4, 2, 1),
                                                             scheduler=client))
    assert same(out, one)


# ----------------------------------------------------------------------------- out of core


def tile_folder_files(outdir):
    import os

    return sorted(os.listdir(outdir))


@pytest.mark.parametrize("name, tiles", [("sphere", (2, 2, 2)), ("ramp_with_gap", (4, 4, 1)),
                                         ("cube", (2, 2, 1)), ("terrain_grid", (3, 3, 1))])
def test_tiles_written_and_read_back_are_the_fans_of_one_process(tmp_path, name, tiles):
    """write_tiled_fans streams the points in chunks, writes one file per tile; read_tiles
    gives build_fans' fan cloud bit for bit; each tile's file is a fan cloud of its own
    points (then its ghosts), and its normals agree with its neighbours'."""
    from fancloud_vtk import load

    points = CLOUDS[name]()
    one = build_fans(points)
    index = D.write_tiled_fans(points, tmp_path, tiles=tiles, scheduler="sync", chunk=7_000)
    m = int(np.prod(tiles))
    assert len(index["tile_list"]) == m
    files = [t["file"] for t in index["tile_list"] if t["file"]]
    assert tile_folder_files(tmp_path) == sorted(["index.json", "fans.vtpd", *files])
    assert sum(t["owned"] for t in index["tile_list"]) == len(points)
    assert same(D.read_tiles(tmp_path), one)
    # the tiles as written: their own fans, normals agreeing with one process's up to one
    # sign over the whole cloud (tiles were flipped to agree; a stray point's orientation
    # may differ within a tile), ghosts without fans
    unoriented = D.read_tiles(tmp_path, orient=False)
    assert np.array_equal(np.diff(unoriented.offsets), np.diff(one.offsets))
    dots = np.einsum("ij,ij->i", unoriented.normals, one.normals)
    assert np.abs(np.abs(dots) - 1).max() < 1e-12
    assert max((dots > 0).mean(), (dots < 0).mean()) > 0.999
    # fans.vtpd opens in VTK as one partitioned dataset of the tiles (as ParaView opens it)
    from vtkmodules.vtkIOXML import vtkXMLPartitionedDataSetReader

    reader = vtkXMLPartitionedDataSetReader()
    reader.SetFileName(str(tmp_path / "fans.vtpd"))
    reader.Update()
    parts = reader.GetOutput()
    assert parts.GetNumberOfPartitions() == len(files)
    assert sum(parts.GetPartition(j).GetNumberOfPoints() for j in range(len(files))) == \
        len(points) + sum(t["ghosts"] for t in index["tile_list"])
    tile = load(tmp_path / files[0])
    ghost = tile.point_data["vtkGhostType"]
    own = index["tile_list"][0]["owned"] if index["tile_list"][0]["file"] == files[0] else None
    if own is not None:
        assert (ghost[:own] == 0).all() and (ghost[own:] == 1).all()
        assert (np.diff(tile.offsets)[own:] == 0).all()
        np.testing.assert_array_equal(tile.points, points[tile.point_data["GlobalPointIds"]])


def test_tiles_of_an_open_sheet_are_flipped_to_agree(tmp_path):
    """On an open wavy sheet each tile's own orientation picks a side at random: tiles are
    flipped so that the written normals all agree."""
    from fancloud_vtk import load

    points = terrain_grid(150)
    index = D.write_tiled_fans(points, tmp_path, tiles=(4, 4, 1), scheduler="sync")
    flipped = [t["flipped"] for t in index["tile_list"]]
    unoriented = D.read_tiles(tmp_path, orient=False)
    up = (unoriented.normals[:, 2] > 0).mean()
    assert max(up, 1 - up) > 0.999
    assert any(flipped)  # (each tile's own orientation did not agree by itself)
    # a flipped tile's file was rewritten: its rings reversed with its normals
    for t in index["tile_list"]:
        fc = load(tmp_path / t["file"])
        own = t["owned"]
        tri = fc.fan_triangles()
        a, b, c = fc.points[tri[:, 0]], fc.points[tri[:, 1]], fc.points[tri[:, 2]]
        face = np.cross(b - a, c - a)
        assert (np.einsum("ij,ij->i", face, fc.normals[tri[:, 0]]) > 0).mean() > 0.99
        assert own == int((fc.point_data["vtkGhostType"] == 0).sum())


@pytest.mark.parametrize("fmt", ["npy", "ply", "ply-ascii", "las", "laz", "xyz"])
def test_files_are_read_in_chunks(tmp_path, fmt):
    """read_point_chunks: every format hands out the file's points in order, chunk by
    chunk (npy and binary PLY memory-mapped, ascii PLY streamed, LAS/LAZ through laspy)."""
    from fancloud_vtk.io import read_point_chunks

    points = np.round(sphere(2_500, seed=5) * 1000) / 1000  # LAS stores 1e-3 steps
    path = tmp_path / f"cloud.{fmt.split('-')[0]}"
    if fmt == "npy":
        np.save(path, points)
    elif fmt.startswith("ply"):
        import plyfile

        v = np.empty(len(points), [("x", "f8"), ("y", "f8"), ("z", "f8"), ("q", "u1")])
        v["x"], v["y"], v["z"], v["q"] = points[:, 0], points[:, 1], points[:, 2], 7
        plyfile.PlyData([plyfile.PlyElement.describe(v, "vertex")],
                        text=fmt == "ply-ascii").write(str(path))
    elif fmt in ("las", "laz"):
        write_las(path, points)
    else:
        np.savetxt(path, points)
    # with point_data: the arrays read_point_cloud gives, chunk by chunk
    from fancloud_vtk.io import read_point_cloud

    pairs = list(read_point_chunks(path, chunk=1_000, point_data=True))
    whole = read_point_cloud(path).point_data
    assert all(set(a) == set(whole) for _, a in pairs)
    for name, arr in whole.items():
        got = np.concatenate([a[name] for _, a in pairs])
        assert got.dtype == arr.dtype and np.array_equal(got, arr), name
    assert {"ply": {"q"}, "las": {"intensity", "classification", "return_number", "RGB"},
            }.get(fmt.split("-")[0], {"q"} if fmt == "ply-ascii" else set()) <= set(whole)
    chunks = list(read_point_chunks(path, chunk=1_000))
    assert [len(c) for c in chunks] == [1_000, 1_000, 500]
    assert all(c.dtype == np.float64 and c.shape[1] == 3 for c in chunks)
    np.testing.assert_allclose(np.concatenate(chunks), points, atol=1e-9)
    if fmt in ("las", "laz"):
        from fancloud_vtk.io import read_point_cloud

        np.testing.assert_allclose(read_point_cloud(path).points, points, atol=1e-9)


def test_the_input_point_arrays_go_through_the_tiles(tmp_path):
    """A LAS file's intensity, classification, return number and colours (or an array
    source's point_data) go into the tile files and come back with read_tiles, row for
    row; the fans are still build_fans'."""
    from fancloud_vtk import DroppedArrayWarning, load
    from fancloud_vtk.io import read_point_cloud

    points = np.round(sphere(12_000, seed=6) * 100, 3)  # LAS stores 1e-3 steps
    write_las(tmp_path / "cloud.las", points)
    whole = read_point_cloud(tmp_path / "cloud.las")
    index = D.write_tiled_fans(tmp_path / "cloud.las", tmp_path / "out", tiles=(2, 2, 1),
                               scheduler="sync", chunk=5_000)
    assert index["point_arrays"] == list(whole.point_data)
    fc = D.read_tiles(tmp_path / "out")
    assert same(fc, build_fans(whole.points))
    assert set(fc.point_data) == set(whole.point_data)
    for name, arr in whole.point_data.items():
        assert fc.point_data[name].dtype == arr.dtype and np.array_equal(fc.point_data[name],
                                                                           arr), name
    tile = load(tmp_path / "out" / index["tile_list"][0]["file"])  # a tile file has them
    gid = tile.point_data["GlobalPointIds"]
    np.testing.assert_array_equal(tile.point_data["intensity"], whole.point_data["intensity"][gid])
    # point_data=False: none; an array source brings its own dict; Normals is the fans'
    index = D.write_tiled_fans(tmp_path / "cloud.las", tmp_path / "bare", tiles=(2, 1, 1),
                               scheduler="sync", point_data=False)
    assert index["point_arrays"] == [] and D.read_tiles(tmp_path / "bare").point_data == {}
    heat = np.linspace(0, 1, len(points))
    with pytest.warns(DroppedArrayWarning, match="Normals"):
        D.write_tiled_fans(points, tmp_path / "arr", tiles=(1, 2, 1), scheduler="sync",
                           point_data={"heat": heat, "Normals": points})
    back = D.read_tiles(tmp_path / "arr")
    assert list(back.point_data) == ["heat"] and np.array_equal(back.point_data["heat"], heat)
    with pytest.raises(FanCloudInputError, match="array source"):
        D.write_tiled_fans(tmp_path / "cloud.las", tmp_path / "x", point_data={"heat": heat})
    with pytest.raises(ValueError, match="heat"):
        D.write_tiled_fans(points, tmp_path / "y", point_data={"heat": heat[:10]})


def test_bad_chunked_input_is_refused(tmp_path):
    from fancloud_vtk.io import FileReadError, read_point_chunks

    points = sphere(5_000)
    bad = points.copy()
    bad[3_210, 1] = np.nan
    np.save(tmp_path / "nan.npy", bad)
    with pytest.raises(FanCloudInputError, match="row 3,210"):
        D.write_tiled_fans(tmp_path / "nan.npy", tmp_path / "out", scheduler="sync",
                           chunk=1_000)
    assert not (tmp_path / "out" / "index.json").exists()
    (tmp_path / "text.npy").write_text("not an array")
    with pytest.raises(FileReadError, match="not a valid .npy"):
        D.write_tiled_fans(tmp_path / "text.npy", tmp_path / "out2", scheduler="sync")
    with pytest.raises(FileReadError, match="no such file"):
        list(read_point_chunks(tmp_path / "missing.npy"))
    np.save(tmp_path / "none.npy", np.empty((0, 3)))  # as read_point_cloud says it
    with pytest.raises(FileReadError, match="contains no points"):
        list(read_point_chunks(tmp_path / "none.npy"))
    with pytest.raises(ValueError, match="chunk"):
        list(read_point_chunks(tmp_path / "nan.npy", chunk=0))
    few = np.repeat(points[:4], 50, axis=0)  # 200 rows, 4 distinct points
    with pytest.raises(FanCloudInputError, match="k \\+ 1 = 7 distinct points, got 4"):
        D.write_tiled_fans(few, tmp_path / "few", tiles=(2, 1, 1), scheduler="sync")
    done = D.write_tiled_fans(points, tmp_path / "ok", tiles=(1, 1, 2), scheduler="sync")
    assert done["n_points"] == len(points)
    with pytest.raises(FanCloudInputError, match="already holds"):
        D.write_tiled_fans(points, tmp_path / "ok", scheduler="sync")
    with pytest.raises(FanCloudInputError, match="tile_points"):
        D.write_tiled_fans(points, tmp_path / "tp", tile_points=10, scheduler="sync")
    with pytest.raises(FileReadError, match="no index"):
        D.read_tiles(tmp_path / "dup")


def test_auto_tiles_cut_the_longest_sides():
    t = D._auto_tiles(10_000_000, np.zeros(3), np.array([4.0, 2.0, 0.1]), 1_000_000)
    assert t.prod() >= 10 and t[2] == 1 and t[0] >= t[1]
    assert D._auto_tiles(10, np.zeros(3), np.ones(3), 1_000).tolist() == [1, 1, 1]


def test_the_command_writes_tiles_on_a_local_cluster(tmp_path, capsys):
    """``fancloud fans BIG.npy -o OUTDIR --tiles auto --workers 2``: a LocalCluster, the
    input read in chunks; the folder read back is build_fans'."""
    pytest.importorskip("dask.distributed")
    from fancloud_vtk.cli import main

    points = sphere(60_000, seed=8)
    np.save(tmp_path / "big.npy", points)
    out = tmp_path / "tiles"
    code = main(["fans", str(tmp_path / "big.npy"), "-o", str(out), "--tiles", "auto",
                 "--tile-points", "20000", "--workers", "2", "--chunk", "25000"])
    assert code == 0
    text = capsys.readouterr().out
    assert "tiles" in text and "60,000" in text
    assert "point arrays" in text and "none" in text  # a .npy holds coordinates only
    assert same(D.read_tiles(out), build_fans(points))
    with pytest.raises(SystemExit):  # argparse: exit code 2 and the usage
        main(["fans", str(tmp_path / "big.npy"), "-o", str(out), "--tiles", "1,1"])
    assert "expected 'auto' or three positive integers" in capsys.readouterr().err
    assert main(["fans", str(tmp_path / "big.npy"), "-o", str(tmp_path / "x.vtp"),
                 "--workers", "2"]) == 2
    assert "--workers goes with --tiles" in capsys.readouterr().err


def test_a_worker_killed_while_writing_tiles_leaves_a_complete_folder(tmp_path):
    """A LocalCluster worker killed while tiles run: its tiles run again elsewhere, the
    folder holds the index, the .vtpd and one file per tile, nothing half-written, and it
    reads back as build_fans' fan cloud."""
    pytest.importorskip("dask.distributed")
    points = sphere(300_000, seed=9)
    one = build_fans(points)
    with local_cluster(2) as (cluster, client):
        D.write_tiled_fans(points[:20_000], tmp_path / "warm", tiles=(2, 1, 1),
                           scheduler=client)  # kernels loaded
        index = kill_a_worker_while(client, lambda: D.write_tiled_fans(
            points, tmp_path / "run", tiles=(4, 2, 1), scheduler=client))
    files = [t["file"] for t in index["tile_list"]]
    assert tile_folder_files(tmp_path / "run") == sorted(["index.json", "fans.vtpd", *files])
    assert same(D.read_tiles(tmp_path / "run"), one)


# ----------------------------------------------------------------------------- reduction


def torus(n, seed=0, big=1.0, small=0.35):
    """Points uniform by area on a torus (rejection sampling) and its exact distance."""
    rng = np.random.default_rng(seed)
    out = []
    while sum(len(o) for o in out) < n:
        u, v = rng.random((2, 2 * n)) * 2 * np.pi
        ok = rng.random(2 * n) * (big + small) < big + small * np.cos(v)
        u, v = u[ok], v[ok]
        out.append(np.c_[(big + small * np.cos(v)) * np.cos(u),
                         (big + small * np.cos(v)) * np.sin(u), small * np.sin(v)])

    def distance(x):
        return np.abs(np.hypot(np.hypot(x[:, 0], x[:, 1]) - big, x[:, 2]) - small)
    return np.concatenate(out)[:n], distance


@pytest.mark.parametrize("n, bound", [
    (60_000, 1.10),
    pytest.param(200_000, 1.05, marks=pytest.mark.slow)])
@pytest.mark.parametrize("tiles", [(2, 2, 2), (4, 4, 1)])
def test_blocked_reduction_has_no_seam_and_the_error_of_one_process(tiles, n, bound):
    """tiled_reduce: exactly the target's points; as many kept near the blocks' faces as
    elsewhere (no seam); the mean distance of its fans to the torus within 5% of the
    one-process reduction's at 200,000 points (within 10% at 60,000: the fans built again
    along the faces are a larger share of a small cloud)."""
    from fancloud_vtk import reduce
    from fancloud_vtk.bench.metrics import surface_distance

    points, distance = torus(n)
    one = reduce(build_fans(points), keep=0.2)
    fc = tiled_reduce(points, keep=0.2, tiles=tiles, scheduler="sync")
    fc.validate()
    assert fc.n_points == one.n_points == n // 5
    ids = fc.point_data["original_id"]
    assert len(np.unique(ids)) == len(ids)
    np.testing.assert_array_equal(fc.points, points[ids])
    # no seam: the blocks' inner faces (x = 0, y = 0, and z = 0 for 2 x 2 x 2 on the
    # torus's bounding box) keep the same fraction of their points as elsewhere
    lo, hi, _ = tile_boxes(points, tiles)
    faces = [(a, c) for a in range(3) for c in np.unique(lo[:, a]) if c > points[:, a].min()]
    assert faces
    width = 0.03

    def near(x):
        return np.any([np.abs(x[:, a] - c) < width for a, c in faces], axis=0)
    kept_near = near(fc.points).sum() / near(points).sum()
    kept_far = (~near(fc.points)).sum() / (~near(points)).sum()
    assert abs(kept_near / kept_far - 1) < 0.05
    ours = surface_distance(fc.points, fc.triangles(), distance, 100_000)["mean"]
    theirs = surface_distance(one.points, one.triangles(), distance, 100_000)["mean"]
    assert ours <= bound * theirs
    assert fc.info["fans_rebuilt"] > 0  # the faces' fans were mended (not vacuous)
    # the same on Dask's threads
    again = tiled_reduce(points, keep=0.2, tiles=tiles, scheduler="threads")
    np.testing.assert_array_equal(np.sort(again.point_data["original_id"]), np.sort(ids))


def test_blocked_reduction_passes_the_kept_points_arrays_through(tmp_path, capsys):
    """tiled_reduce(point_data=...) and ``fancloud reduce --tiles``: the kept points keep
    their rows of the input's point arrays (a file's colours too); an array named as the
    fan cloud's own normals is dropped with a warning."""
    from fancloud_vtk import DroppedArrayWarning
    from fancloud_vtk.algorithms.convert import fancloud_from_vtk, read_vtp
    from fancloud_vtk.cli import main

    points, _ = torus(6_000, seed=4)
    heat = np.arange(len(points), dtype=np.float32)
    rgb = (np.arange(len(points) * 3) % 251).astype(np.uint8).reshape(-1, 3)
    with pytest.warns(DroppedArrayWarning, match="Normals"):
        fc = tiled_reduce(points, keep=0.3, tiles=(2, 1, 1), scheduler="sync",
                          point_data={"heat": heat, "RGB": rgb, "Normals": points})
    ids = fc.point_data["original_id"]
    assert set(fc.point_data) == {"heat", "RGB", "original_id"}
    np.testing.assert_array_equal(fc.point_data["heat"], heat[ids])
    np.testing.assert_array_equal(fc.point_data["RGB"], rgb[ids])
    write_ply_rgb(tmp_path / "c.ply", points, rgb)
    assert main(["reduce", str(tmp_path / "c.ply"), "-o", str(tmp_path / "s.vtp"), "--keep",
                 "0.3", "--tiles", "2,1,1", "-q"]) == 0
    capsys.readouterr()
    small = fancloud_from_vtk(read_vtp(str(tmp_path / "s.vtp")))
    np.testing.assert_array_equal(small.point_data["RGB"],
                                  rgb[small.point_data["original_id"]])


def test_blocked_reduction_merges_duplicates_as_build_fans_does():
    """Copies of points: merged first (the first of each kept, build_fans' warning), so
    the result is that of the distinct points, its original_id the input's rows."""
    points, _ = torus(5_000, seed=2)
    ref = tiled_reduce(points, keep=0.3, tiles=(2, 1, 1), scheduler="sync")
    rows = np.concatenate([points[:2_000], points[[5, 9, 5]], points[2_000:]])
    with pytest.warns(D._F.DuplicatePointsWarning, match="3 duplicate point"):
        fc = tiled_reduce(rows, keep=0.3, tiles=(2, 1, 1), scheduler="sync",
                          point_data={"row": np.arange(len(rows))})
    assert same(fc, ref) and fc.info["duplicates_merged"] == 3
    back = np.where(ref.point_data["original_id"] < 2_000, ref.point_data["original_id"],
                    ref.point_data["original_id"] + 3)
    np.testing.assert_array_equal(fc.point_data["original_id"], back)
    np.testing.assert_array_equal(fc.point_data["row"], back)


def test_blocked_reduction_of_a_file_read_in_chunks_is_that_of_the_array(tmp_path):
    """tiled_reduce(path): the points read in chunks and sorted into the blocks' files, the
    same kept points, fans and normals as tiled_reduce of the array (at the same halo); a
    LAS file's arrays go with the kept points, and its copies of points (the rounding of
    its coordinates makes them) are merged as build_fans merges them."""
    from fancloud_vtk import DuplicatePointsWarning
    from fancloud_vtk.io import read_point_cloud

    points, _ = torus(8_000, seed=5)
    np.save(tmp_path / "t.npy", points)
    width = D._auto_halo(points, 6)
    ref = tiled_reduce(points, keep=0.25, tiles=(2, 2, 1), scheduler="sync", halo=width)
    fc = tiled_reduce(tmp_path / "t.npy", keep=0.25, tiles=(2, 2, 1), scheduler="sync",
                      halo=width, chunk=1_500)
    assert same(fc, ref) and np.array_equal(fc.points, ref.points)
    np.testing.assert_array_equal(fc.point_data["original_id"], ref.point_data["original_id"])
    assert fc.info["input_points"] == len(points) and fc.info["duplicates_merged"] == 0

    rows = np.vstack([points, points[:40]])
    write_las(tmp_path / "t.las", rows)
    cloud = read_point_cloud(tmp_path / "t.las")  # its points as the file stores them
    with pytest.warns(DuplicatePointsWarning) as record:
        ref = tiled_reduce(cloud.points, keep=0.25, tiles=(2, 2, 1), scheduler="sync",
                           halo=width, point_data=cloud.point_data)
    with pytest.warns(DuplicatePointsWarning) as again:
        fc = tiled_reduce(tmp_path / "t.las", keep=0.25, tiles=(2, 2, 1), scheduler="sync",
                          halo=width, chunk=2_000)
    assert str(record[0].message) == str(again[0].message)
    assert fc.info["duplicates_merged"] == ref.info["duplicates_merged"] >= 40
    assert same(fc, ref) and sorted(fc.point_data) == sorted(ref.point_data)
    for name, arr in ref.point_data.items():
        np.testing.assert_array_equal(fc.point_data[name], arr)
    with pytest.raises(FanCloudInputError, match="array source"):
        tiled_reduce(tmp_path / "t.las", keep=0.5, point_data={"a": np.zeros(3)})


def test_blocked_reduction_refuses_bad_input():
    points, _ = torus(5_000)
    few = np.repeat(points[:3], 4, axis=0)
    with pytest.raises(FanCloudInputError, match="distinct points, got 3"):
        with pytest.warns(D._F.DuplicatePointsWarning):
            tiled_reduce(few, keep=0.5, scheduler="sync")
    with pytest.raises(ValueError):
        tiled_reduce(points, keep=1.5, scheduler="sync")
    with pytest.raises(FanCloudInputError):
        tiled_reduce(points, keep=0.5, tiles=(0, 1, 1), scheduler="sync")
    bad = points.copy()
    bad[7, 0] = np.inf
    with pytest.raises(FanCloudInputError):
        tiled_reduce(bad, keep=0.5, scheduler="sync")
    with pytest.raises(TypeError, match="scheduler"):
        tiled_reduce(points, keep=0.5, scheduler=42)
    one = tiled_reduce(points, n_points=1_000, tiles=(1, 1, 1), scheduler="sync")
    assert one.n_points == 1_000


def test_the_reduce_command_in_tiles_on_a_scheduler_address(tmp_path, capsys):
    """``fancloud reduce BIG.npy -o OUT --keep 0.2 --tiles ... --scheduler ADDR``: the blocks
    of tiled_reduce on a cluster given by its address, the same points as on Dask's
    synchronous scheduler; ``--mesh`` writes the mesh of the result; options the blocks do
    not take, and --scheduler without --tiles or not an address, are usage errors."""
    pytest.importorskip("dask.distributed")
    from fancloud_vtk import DuplicatePointsWarning
    from fancloud_vtk.algorithms.convert import fancloud_from_vtk, read_vtp
    from fancloud_vtk.cli import main
    from fancloud_vtk.io import read_point_cloud

    points, _ = torus(12_000, seed=3)
    # three duplicates: merged with a warning (the first of each kept), as build_fans does
    np.save(tmp_path / "big.npy", np.concatenate([points, points[[5, 9, 5]]]))
    ref = tiled_reduce(points, keep=0.2, tiles=(2, 1, 1), scheduler="sync")
    with local_cluster(1) as (cluster, _):
        out = tmp_path / "small.vtp"
        with warnings.catch_warnings():  # the command prints them, one line each
            warnings.simplefilter("default", DuplicatePointsWarning)
            assert main(["reduce", str(tmp_path / "big.npy"), "-o", str(out), "--keep", "0.2",
                         "--tiles", "2,1,1", "--scheduler", cluster.scheduler_address]) == 0
        captured = capsys.readouterr()
        assert "2,400 (20.0%)" in captured.out and "2x1x1" in captured.out
        assert captured.err.startswith("fancloud reduce: warning: 3 duplicate point(s) merged")
        fc = fancloud_from_vtk(read_vtp(str(out)))
        np.testing.assert_array_equal(fc.point_data["original_id"],
                                      ref.point_data["original_id"])
        np.testing.assert_array_equal(fc.ring, ref.ring)
        mesh = tmp_path / "small.ply"
        with warnings.catch_warnings():
            warnings.simplefilter("default", DuplicatePointsWarning)
            assert main(["reduce", str(tmp_path / "big.npy"), "-o", str(mesh), "--keep", "0.2",
                         "--tiles", "2,1,1", "--mesh", "-q",
                         "--scheduler", cluster.scheduler_address]) == 0
        cloud = read_point_cloud(mesh)
        assert len(cloud.points) == 2_400 and len(cloud.faces) > 4_000
    for extra, message in [(["--tiles", "2,1,1", "--removal", "reform"],
                            "--removal does not go with --tiles"),
                           (["--tiles", "2,1,1", "--scheduler", "threads"],
                            "--scheduler must be a Dask scheduler address"),
                           (["--workers", "2"], "--workers goes with --tiles")]:
        assert main(["reduce", str(tmp_path / "big.npy"), "-o", str(tmp_path / "x.vtp"),
                     "--keep", "0.2", *extra]) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "x.vtp").exists()


def test_the_fans_command_in_tiles_carries_a_ply_files_colours(tmp_path, capsys):
    """``fancloud fans cloud.ply -o OUT --tiles``: the colours of a PLY point cloud go into
    the tiles, with no warning; a PLY with faces is warned about (its faces are not read)."""
    from fancloud_vtk.cli import main

    points = sphere(8_000, seed=9)
    rgb = (np.arange(len(points) * 3) % 253).astype(np.uint8).reshape(-1, 3)
    write_ply_rgb(tmp_path / "cloud.ply", points, rgb)
    pytest.importorskip("dask.distributed")
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        assert main(["fans", str(tmp_path / "cloud.ply"), "-o", str(tmp_path / "out"),
                     "--tiles", "2,1,1", "--workers", "1"]) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err and "RGB" in captured.out
    np.testing.assert_array_equal(D.read_tiles(tmp_path / "out").point_data["RGB"], rgb)
    from fancloud_vtk.cli import _ply_has_faces

    assert not _ply_has_faces(tmp_path / "cloud.ply")
    write_ply_rgb(tmp_path / "mesh.ply", points, rgb, faces=[[0, 1, 2]])
    assert _ply_has_faces(tmp_path / "mesh.ply")


FOREST = ("positions", "normals", "children", "ring_offsets", "ring", "open", "error",
          "bound", "radius")


def same_forest(a, b) -> bool:
    return all(np.array_equal(getattr(a, name), getattr(b, name)) for name in FOREST)


def test_the_forests_blocks_as_dask_tasks_give_the_forest_of_threads():
    """tiled_vdfc: the blocks of the merge forest as Dask tasks (a point set's spatial
    blocks, a terrain's blocks, a point set whose fans are built in tiles), on the
    synchronous and threaded schedulers and on a LocalCluster of 2 processes: the forest of
    ViewDependentFanCloud.build with the same blocks (threads), array for array."""
    pytest.importorskip("dask.distributed")
    from fancloud_vtk import (
        ViewDependentFanCloud,
        point_blocks,
        terrain_blocks,
        terrain_fan_cloud,
        tiled_vdfc,
    )

    points = sphere(12_000, seed=6)
    fc = build_fans(points)
    blocks = point_blocks(fc, 6)
    one = ViewDependentFanCloud.build(fc, blocks=blocks)
    assert same_forest(tiled_vdfc(fc, blocks=blocks, scheduler="sync"), one)
    assert same_forest(tiled_vdfc(points, n_blocks=6, tiles=(2, 1, 1), scheduler="threads"),
                       one)
    x = np.linspace(0.0, 4.0, 90)
    heights = np.add.outer(np.sin(x), np.cos(1.3 * x))
    terrain = terrain_fan_cloud(heights, spacing=0.05)
    cut = terrain_blocks(heights.shape, (30, 30))
    ref = ViewDependentFanCloud.build(terrain, blocks=cut, merge="half_edge", n_roots=3)
    done = []
    vd = tiled_vdfc(terrain, blocks=cut, merge="half_edge", n_roots=3, scheduler="threads",
                    progress=lambda f, m: done.append(f))
    assert same_forest(vd, ref) and len(vd.roots) == len(ref.roots)
    assert done == sorted(done) and done[-1] == 1.0
    with local_cluster(2) as (cluster, client):
        assert same_forest(tiled_vdfc(fc, blocks=blocks, scheduler=client), one)
