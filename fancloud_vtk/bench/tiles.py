"""``fancloud bench tiles``: the fans of a large cloud in tiles on Dask against one process.

For each size, three fresh processes build the fans of the same random points on the
bumpy sphere: ``build_fans`` in one process, ``tiled_fans`` on Dask's threads, and
``tiled_fans`` on a ``dask.distributed.LocalCluster`` of worker processes. Each process
first makes a small fan cloud (the numba kernels load from the cache; on the cluster, in
every worker), then times the call end to end; the points are made before and not timed,
the cluster's start is timed apart. Reported: wall time, throughput (points per second),
the ratio to one process, peak memory (the process's, and each worker's on the cluster),
and whether the fan cloud is the one process's (a digest of every array).
"""

from __future__ import annotations

import argparse
import resource
import time

from fancloud_vtk.bench.common import (
    _log,
    data_label,
    digest,
    parse_sizes,
    size_label,
    surface_points,
)
from fancloud_vtk.bench.harness import run_task
from fancloud_vtk.bench.report import _num, _row, header, markdown, write_outputs

_HERE = "fancloud_vtk.bench.tiles"
MODES = ("one", "threads", "cluster")  #: one process, Dask's threads, a LocalCluster


def _peak_mb() -> float:
    """This process's peak resident memory (MiB; Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _timed(fn, *args, **kwargs) -> float:
    """Seconds of one call (its result dropped before the next)."""
    t0 = time.perf_counter()
    fn(*args, **kwargs)
    return time.perf_counter() - t0


def child_tiles(n: int, seed: int, tiles: list, mode: str, workers: int, repeat: int) -> dict:
    """One mode in this (fresh) process: the timed call (best of ``repeat``) and what it
    gives."""
    import numpy as np

    from fancloud_vtk import build_fans, tiled_fans

    pts = surface_points(n, seed, "bumpy")
    small = surface_points(20_000, seed + 1, "bumpy")
    out = {"mode": mode, "n": n}
    if mode == "one":
        build_fans(small)
        before = _peak_mb()
        out["times"] = [_timed(build_fans, pts) for _ in range(repeat)]
        fc = build_fans(pts)
    elif mode == "threads":
        tiled_fans(small, tiles=tuple(tiles), scheduler="threads")
        before = _peak_mb()
        out["times"] = [_timed(tiled_fans, pts, tiles=tuple(tiles), scheduler="threads")
                        for _ in range(repeat)]
        fc = tiled_fans(pts, tiles=tuple(tiles), scheduler="threads")
    else:
        from dask.distributed import Client, LocalCluster

        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
        out["cluster_start"] = time.perf_counter() - t0
        try:
            tiled_fans(small, tiles=tuple(tiles), scheduler=client)
            before = _peak_mb()
            out["times"] = [_timed(tiled_fans, pts, tiles=tuple(tiles), scheduler=client)
                            for _ in range(repeat)]
            fc = tiled_fans(pts, tiles=tuple(tiles), scheduler=client)
            out["worker_peak_mb"] = sorted(client.run(_peak_mb).values())
        finally:
            client.close()
            cluster.close()
    out["time"] = min(out["times"])
    out["peak_mb"] = _peak_mb()
    out["peak_before_mb"] = before
    out["digest"] = digest(fc.offsets, fc.ring, fc.normals, fc.open, fc.rotated)
    for key in ("halos", "rebuilt", "tile_points", "timings"):
        if key in fc.info:
            out[key] = fc.info[key]
    out["fans_open"] = int(np.count_nonzero(fc.open))
    return out


def run_tiles(args, argv: list[str]) -> dict:
    """Every size in every mode, each in a fresh process; the table."""
    t_start = time.perf_counter()
    tiles = [int(x) for x in args.tiles.split(",")]
    res = {**header(["tiles", *argv]), "args": {"sizes": args.sizes, "tiles": tiles,
                                                "workers": args.workers, "seed": args.seed,
                                                "repeat": args.repeat,
                                                "modes": args.modes}}
    runs = []
    rows = []
    for n in args.sizes:
        got = {}
        for mode in args.modes:
            _log(args.quiet, f"{size_label(n)} points: {mode}")
            got[mode] = run_task(f"{_HERE}:child_tiles", {"n": n, "seed": args.seed,
                                                          "tiles": tiles, "mode": mode,
                                                          "workers": args.workers,
                                                          "repeat": args.repeat})
            runs.append(got[mode])
        rows += _rows(n, args, tiles, got)
    res["runs"] = runs
    res["rows"] = rows
    res["elapsed"] = time.perf_counter() - t_start
    notes = ["each mode in a fresh process; points made before the timing; a small fan "
             "cloud first (kernels loaded, on the cluster in every worker); the cluster's "
             "start timed apart",
             "peak memory: the process's peak resident set (ru_maxrss), the points and the "
             "result included; on the cluster also each worker's"]
    text = markdown("fancloud bench tiles: fans in tiles on Dask against one process", res,
                    rows, notes)
    md, js = write_outputs(args.out, "tiles", text, res)
    print(text)
    print(f"written: {md}, {js}")
    return res


def _rows(n, args, tiles, got) -> list[dict]:
    data = data_label(n, "bumpy", args.seed)
    one = got.get("one")
    rows = []
    names = {"one": "one process, build_fans",
             "threads": f"tiled_fans {tiles[0]}x{tiles[1]}x{tiles[2]}, Dask threads",
             "cluster": f"tiled_fans {tiles[0]}x{tiles[1]}x{tiles[2]}, LocalCluster "
                        f"{args.workers} workers x 1 thread"}
    for mode, r in got.items():
        extra = ""
        if "rebuilt" in r:
            extra = (f"; halos {min(r['halos']):.3g} to {max(r['halos']):.3g}, "
                     f"{r['rebuilt']} tile(s) built again")
        if "cluster_start" in r:
            extra += f"; cluster start {r['cluster_start']:.1f} s (not in the time)"
        rows.append(_row(f"tiles: wall time, {names[mode]}", data,
                         f"end to end, warm, best of {args.repeat}" + extra,
                         _num(r["time"]), "s"))
        rows.append(_row(f"tiles: throughput, {names[mode]}", data, "points per second",
                         _num(n / r["time"]), "points/s"))
        rows.append(_row(f"tiles: peak memory, {names[mode]}", data,
                         f"the calling process (before the call {r['peak_before_mb']:.0f} MiB)",
                         _num(r["peak_mb"]), "MiB"))
        if "worker_peak_mb" in r:
            rows.append(_row(f"tiles: peak memory per worker, {names[mode]}", data,
                             "largest of the workers; all: " + ", ".join(
                                 f"{x:.0f}" for x in r["worker_peak_mb"]) + " MiB",
                             _num(max(r["worker_peak_mb"])), "MiB"))
        if one is not None and mode != "one":
            rows.append(_row(f"tiles: ratio {names[mode]} / one process", data,
                             "wall times above", f"{r['time'] / one['time']:.3f}", "x"))
            same = r["digest"] == one["digest"]
            rows.append(_row(f"tiles: same fan cloud as one process, {names[mode]}", data,
                             "digest of offsets, ring, normals, open, rotated",
                             "yes" if same else "no", "", "yes", "yes" if same else "NO"))
    return rows


def _cmd_tiles(args, argv) -> int:
    run_tiles(args, argv)
    return 0


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``tiles`` on the subparsers of ``fancloud bench``."""
    p = sub.add_parser("tiles", help="fans in tiles on Dask (tiled_fans) against one process",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=parse_sizes, default=parse_sizes("1M,10M"),
                   help="numbers of points, comma-separated (default: 1M,10M)")
    p.add_argument("--tiles", default="2,2,2", help="tiles along x,y,z (default: %(default)s)")
    p.add_argument("--modes", nargs="+", choices=MODES, default=list(MODES),
                   help="one process, Dask threads, LocalCluster (default: all)")
    p.add_argument("--workers", type=int, default=2,
                   help="LocalCluster worker processes (default: %(default)s)")
    p.add_argument("--repeat", type=int, default=1,
                   help="timed calls per mode, best kept (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--out", default="bench_out", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_tiles)
    return p
