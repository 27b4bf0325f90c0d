"""Fans in tiles with halos (fancloud_vtk.distributed): the fan cloud of one process, bit for
bit, on every scheduler; the halo grows where a fan needs it."""

import numpy as np
import pytest
from conftest import fingerprint

import fancloud_vtk.distributed as D
from fancloud_vtk import FanCloudInputError, build_fans, tile_boxes, tiled_fans


def same(a, b) -> bool:
    """The two fan clouds are the same, array for array (rings, normals, flags)."""
    return (np.array_equal(a.offsets, b.offsets) and np.array_equal(a.ring, b.ring)
            and np.array_equal(a.normals, b.normals) and np.array_equal(a.open, b.open)
            and np.array_equal(a.rotated, b.rotated))


def sphere(n, seed=0):
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1)[:, None]


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
    distributed = pytest.importorskip("dask.distributed")
    points = sphere(40_000, seed=3)
    one = build_fans(points)
    assert same(tiled_fans(points, tiles=(2, 2, 1), scheduler="threads"), one)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
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


def test_duplicates_nan_and_bad_scheduler_are_refused():
    points = sphere(1000)
    with pytest.raises(FanCloudInputError, match="duplicate"):
        tiled_fans(np.vstack([points, points[:3]]))
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
    import os
    import signal
    import threading
    import time

    distributed = pytest.importorskip("dask.distributed")
    points = sphere(400_000, seed=7)
    one = build_fans(points)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        tiled_fans(points[:20_000], tiles=(2, 1, 1), scheduler=client)  # kernels loaded
        pids = client.run(os.getpid)
        out = {}
        run = threading.Thread(target=lambda: out.setdefault(
            "fc", tiled_fans(points, tiles=(4, 2, 1), scheduler=client)))
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
    assert same(out["fc"], one)
