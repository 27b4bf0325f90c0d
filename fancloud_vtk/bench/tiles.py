"""``fancloud bench tiles``: the fans of a large cloud in tiles on Dask against one process,
the reduction in blocks (``tiled_reduce``) and the mesh in tiles (``tiled_mesh``, with
``--mesh N``) against one process's.

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
import hashlib
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
#: one process, Dask's threads, a LocalCluster, and out of core: write_tiled_fans from an
#: .npy file on a LocalCluster
MODES = ("one", "threads", "cluster", "files")


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
    from fancloud_vtk.distributed import _client_for

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
        t0 = time.perf_counter()
        client, close = _client_for(None, workers)
        out["cluster_start"] = time.perf_counter() - t0
        try:
            tiled_fans(small, tiles=tuple(tiles), scheduler=client)
            before = _peak_mb()
            out["times"] = [_timed(tiled_fans, pts, tiles=tuple(tiles), scheduler=client)
                            for _ in range(repeat)]
            fc = tiled_fans(pts, tiles=tuple(tiles), scheduler=client)
            out["worker_peak_mb"] = sorted(client.run(_peak_mb).values())
        finally:
            close()
    out["time"] = min(out["times"])
    out["peak_mb"] = _peak_mb()
    out["peak_before_mb"] = before
    out["digest"] = digest(fc.offsets, fc.ring, fc.normals, fc.open, fc.rotated)
    for key in ("halos", "rebuilt", "tile_points", "timings"):
        if key in fc.info:
            out[key] = fc.info[key]
    out["fans_open"] = int(np.count_nonzero(fc.open))
    return out


def child_save_points(n: int, seed: int, path: str) -> dict:
    """The benchmark's points written to ``path`` (.npy), in a process of its own."""
    import numpy as np

    np.save(path, surface_points(n, seed, "bumpy"))
    return {"path": path}


def _noop(x):
    return x


def child_files(n: int, seed: int, path: str, tile_points: int, workers: int,
                chunk: int) -> dict:
    """Out of core: ``write_tiled_fans`` of the ``.npy`` at ``path`` on a fresh LocalCluster
    (timed end to end: the two passes over the file, the tiles, the agreement, the files);
    then the scheduler's cost per task (no-op tasks), and the folder read back for the
    digest (after the memory was read)."""
    import os
    import shutil
    import tempfile

    from fancloud_vtk.distributed import _client_for, read_tiles, write_tiled_fans

    t0 = time.perf_counter()
    client, close = _client_for(None, workers)
    out = {"mode": "files", "n": n, "cluster_start": time.perf_counter() - t0}
    folder = tempfile.mkdtemp(prefix="fancloud_tiles_")
    try:
        small = os.path.join(folder, "small.npy")
        child_save_points(20_000, seed + 1, small)
        write_tiled_fans(small, os.path.join(folder, "warm"), tiles=(2, 1, 1),
                         scheduler=client)  # kernels loaded in every worker
        before = _peak_mb()
        t0 = time.perf_counter()
        index = write_tiled_fans(path, os.path.join(folder, "out"), tile_points=tile_points,
                                 scheduler=client, chunk=chunk)
        out["time"] = time.perf_counter() - t0
        out["times"] = [out["time"]]
        out["peak_mb"] = _peak_mb()
        out["peak_before_mb"] = before
        out["worker_peak_mb"] = sorted(client.run(_peak_mb).values())
        out["bytes"] = sum(os.path.getsize(os.path.join(folder, "out", f))
                           for f in os.listdir(os.path.join(folder, "out")))
        # the scheduler's own cost per task: 200 no-op tasks, submitted and gathered
        t0 = time.perf_counter()
        client.gather(client.map(_noop, range(200), pure=False))
        out["task_overhead"] = (time.perf_counter() - t0) / 200
        out["tiles"] = index["tiles"]
        out["phases"] = index["timings"]
        out["tile_list"] = [{k: t[k] for k in ("owned", "built", "ghosts", "seconds",
                                              "worker_peak_mb", "flipped", "halo")}
                            for t in index["tile_list"]]
        fc = read_tiles(os.path.join(folder, "out"))
        out["digest"] = digest(fc.offsets, fc.ring, fc.normals, fc.open, fc.rotated)
        out["fans_open"] = int(fc.open.sum())
    finally:
        close()
        shutil.rmtree(folder, ignore_errors=True)
    return out


#: the torus of the blocked reduction: radii (its exact distance is known)
TORUS = (1.0, 0.35)


def torus_points(n: int, seed: int = 0):
    """``n`` points uniform by area on :data:`TORUS` (rejection sampling), and the
    distance to it."""
    import numpy as np

    big, small = TORUS
    rng = np.random.default_rng(seed)
    out, got = [], 0
    while got < n:
        u, v = rng.random((2, 2 * n)) * 2 * np.pi
        ok = rng.random(2 * n) * (big + small) < big + small * np.cos(v)
        u, v = u[ok], v[ok]
        out.append(np.c_[(big + small * np.cos(v)) * np.cos(u),
                         (big + small * np.cos(v)) * np.sin(u), small * np.sin(v)])
        got += len(u)

    def distance(x):
        return np.abs(np.hypot(np.hypot(x[:, 0], x[:, 1]) - big, x[:, 2]) - small)
    return np.concatenate(out)[:n], distance


def child_reduce(n: int, seed: int, keep: float, tiles: list, mode: str) -> dict:
    """The reduction of ``n`` torus points to ``keep``: ``build_fans`` + ``reduce`` in one
    process, or ``tiled_reduce`` in blocks on Dask's threads; timed end to end (warm), then
    the result's fans' distance to the torus and the share of points kept near the blocks'
    inner faces against elsewhere."""
    import os
    import shutil
    import tempfile

    import numpy as np

    from fancloud_vtk import build_fans, reduce, tile_boxes, tiled_reduce
    from fancloud_vtk.bench.metrics import surface_distance
    from fancloud_vtk.distributed import _auto_halo

    pts, distance = torus_points(n, seed)
    small_pts = torus_points(20_000, seed + 1)[0]
    tmp = tempfile.mkdtemp(prefix="fancloud_bench_reduce_")
    halo = {}
    if mode == "one":
        def run(p):
            return reduce(build_fans(p), keep=keep)
    elif mode == "file":  # the points written to .npy (not timed), read in chunks
        def run(p):
            path = os.path.join(tmp, f"p{len(p)}.npy")
            if not os.path.exists(path):
                np.save(path, p)
            return tiled_reduce(path, keep=keep, tiles=tuple(tiles), scheduler="threads",
                                chunk=100_000, **halo)
    else:
        def run(p):
            return tiled_reduce(p, keep=keep, tiles=tuple(tiles), scheduler="threads", **halo)
    run(small_pts)  # kernels loaded
    if mode != "one":  # the array's default halo, given to both: the same blocks
        halo["halo"] = _auto_halo(pts, 6)
        if mode == "file":
            np.save(os.path.join(tmp, f"p{len(pts)}.npy"), pts)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    t0 = time.perf_counter()
    fc = run(pts)
    out = {"mode": mode, "n": n, "time": time.perf_counter() - t0, "kept": fc.n_points,
           "peak_before_mb": before,
           "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}
    if mode != "one":
        h = hashlib.sha1()
        for a in (fc.points, fc.offsets, fc.ring, fc.normals, fc.open,
                  fc.point_data["original_id"]):
            h.update(np.ascontiguousarray(a).tobytes())
        out["digest"] = h.hexdigest()
    shutil.rmtree(tmp, ignore_errors=True)
    d = surface_distance(fc.points, fc.triangles(), distance, 400_000, seed)
    out["mean"], out["max"] = d["mean"], d["max"]
    lo, _, _ = tile_boxes(pts, tuple(tiles))
    faces = [(a, c) for a in range(3) for c in np.unique(lo[:, a]) if c > pts[:, a].min()]
    width = 0.03

    def near(x):
        return np.any([np.abs(x[:, a] - c) < width for a, c in faces], axis=0)
    out["share_near"] = float(near(fc.points).sum() / near(pts).sum())
    out["share_far"] = float((~near(fc.points)).sum() / (~near(pts)).sum())
    out["fans_rebuilt"] = int(fc.info.get("fans_rebuilt", 0))
    return out


def child_mesh(n: int, seed: int, tiles: list, mode: str, workers: int) -> dict:
    """The mesh of ``n`` bumpy-sphere points: ``fan_cloud_to_mesh(build_fans(p))`` in one
    process, or ``tiled_mesh`` on Dask's threads or on a LocalCluster; timed end to end
    (warm), then a digest of its triangles (each from its lowest point, sorted) and normals,
    and the triangles themselves' keys for the difference."""
    import warnings

    import numpy as np

    from fancloud_vtk import build_fans, fan_cloud_to_mesh, tiled_mesh
    from fancloud_vtk.distributed import _client_for, _tri_keys

    pts = surface_points(n, seed, "bumpy")
    small = surface_points(20_000, seed + 1, "bumpy")
    client = close = None
    out = {"mode": mode, "n": n}
    if mode == "one":
        def run(p):
            return fan_cloud_to_mesh(build_fans(p))
    elif mode == "threads":
        def run(p):
            return tiled_mesh(p, tiles=tuple(tiles), scheduler="threads")
    else:
        t0 = time.perf_counter()
        client, close = _client_for(None, workers)
        out["cluster_start"] = time.perf_counter() - t0

        def run(p):
            return tiled_mesh(p, tiles=tuple(tiles), scheduler=client)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            run(small)  # kernels loaded (on the cluster, in every worker)
            before = _peak_mb()
            t0 = time.perf_counter()
            mesh = run(pts)
            out["time"] = time.perf_counter() - t0
        out["peak_before_mb"] = before
        out["peak_mb"] = _peak_mb()
        if client is not None:
            out["worker_peak_mb"] = sorted(client.run(_peak_mb).values())
    finally:
        if close is not None:
            close()
    keys = np.sort(_tri_keys(mesh.triangles))
    h = hashlib.sha1()
    for a in (keys, mesh.normals, mesh.outliers):
        h.update(np.ascontiguousarray(a).tobytes())
    out["digest"] = h.hexdigest()
    out["keys"] = keys.tolist()
    out["triangles"] = len(mesh.triangles)
    for key in ("boundary_edges", "non_manifold_edges", "self_intersections", "rebuilt"):
        if key in mesh.stats:
            out[key] = int(mesh.stats[key])
    return out


def _mesh_rows(args, tiles, got) -> list[dict]:
    import numpy as np

    data = data_label(args.mesh, "bumpy", args.seed)
    one = got["one"]
    rows = []
    t = "x".join(str(v) for v in tiles)
    names = {"one": "one process, fan_cloud_to_mesh(build_fans)",
             "threads": f"tiled_mesh {t}, Dask threads",
             "cluster": f"tiled_mesh {t}, LocalCluster {args.workers} workers x 1 thread"}
    ref = np.asarray(one["keys"], np.int64)
    for mode, r in got.items():
        extra = f"; cluster start {r['cluster_start']:.1f} s (not in the time)" \
            if "cluster_start" in r else ""
        if "rebuilt" in r:
            extra += f"; {r['rebuilt']} tile(s) built again"
        rows.append(_row(f"tiles: mesh wall time, {names[mode]}", data,
                         "end to end (fans included), warm, best of 1" + extra,
                         _num(r["time"]), "s"))
        rows.append(_row(f"tiles: mesh peak memory, {names[mode]}", data,
                         f"the calling process (before the call {r['peak_before_mb']:.0f} MiB)",
                         _num(r["peak_mb"]), "MiB"))
        if "worker_peak_mb" in r:
            rows.append(_row(f"tiles: mesh peak memory per worker, {names[mode]}", data,
                             "largest of the workers; all: " + ", ".join(
                                 f"{x:.0f}" for x in r["worker_peak_mb"]) + " MiB",
                             _num(max(r["worker_peak_mb"])), "MiB"))
        if mode == "one":
            continue
        rows.append(_row(f"tiles: mesh wall time, {names[mode]} / one process", data,
                         "wall times above", f"{r['time'] / one['time']:.3f}", "x"))
        keys = np.asarray(r["keys"], np.int64)
        differ = len(np.setxor1d(keys, ref))
        same = r["digest"] == one["digest"]
        rows.append(_row(f"tiles: same mesh as one process, {names[mode]}", data,
                         f"digest of the triangles (each the same way round), normals and "
                         f"outliers; triangles in one mesh only: {differ:,} of "
                         f"{one['triangles']:,}", "yes" if same else "no", "", "yes",
                         "yes" if same else "NO"))
    return rows


def _reduce_rows(args, tiles, one, blocks, file=None) -> list[dict]:
    big, small = TORUS
    data = (f"torus R = {big}, r = {small}, {size_label(args.reduce)} points uniform by area "
            f"(seed {args.seed}); keep {args.keep}")
    name = f"tiled_reduce {tiles[0]}x{tiles[1]}x{tiles[2]}, Dask threads"
    rows = []
    for label, r in (("one process, build_fans + reduce", one), (name, blocks)):
        rows.append(_row(f"tiles: reduction wall time, {label}", data,
                         "end to end, warm, best of 1", _num(r["time"]), "s"))
        rows.append(_row(f"tiles: reduction, mean distance to the torus, {label}", data,
                         "the result's fan triangles, 400,000 area samples; max "
                         f"{r['max']:.3g}", f"{r['mean']:.4g}", ""))
    rows.append(_row(f"tiles: reduction wall time, {name} / one process", data,
                     "wall times above", f"{blocks['time'] / one['time']:.3f}", "x"))
    ratio = blocks["mean"] / one["mean"]
    rows.append(_row(f"tiles: reduction mean distance, {name} / one process", data,
                     f"{blocks['fans_rebuilt']:,} fans built again along the blocks' faces",
                     f"{ratio:.3f}", "x", "<= 1.05", "yes" if ratio <= 1.05 else "NO"))
    rows.append(_row(f"tiles: reduction max distance, {name} / one process", data,
                     "the largest of the samples and vertices",
                     f"{blocks['max'] / one['max']:.3f}", "x"))
    if file is not None:
        fname = f"tiled_reduce {tiles[0]}x{tiles[1]}x{tiles[2]} of an .npy file (read in chunks " \
                "of 100,000, out of core), Dask threads"
        rows.append(_row(f"tiles: reduction wall time, {fname}", data,
                         "end to end, warm, best of 1; the file written before (not timed); "
                         "both tiled runs given the array's default halo",
                         _num(file["time"]), "s"))
        rows.append(_row(f"tiles: reduction wall time, {fname} / the array's", data,
                         "wall times above", f"{file['time'] / blocks['time']:.3f}", "x"))
        for label, r in ((name, blocks), (fname, file)):
            rows.append(_row(f"tiles: reduction peak memory, {label}", data,
                             f"the calling process (before the call "
                             f"{r['peak_before_mb']:.0f} MiB; its points included)",
                             _num(r["peak_mb"]), "MiB"))
        same = file["digest"] == blocks["digest"]
        rows.append(_row(f"tiles: reduction of the file the array's, {fname}", data,
                         "digest of the kept points, their fans, normals, open flags and "
                         "original_id", "yes" if same else "no", "", "yes",
                         "yes" if same else "NO"))
    for label, r in (("one process", one), (name, blocks)):
        seam = r["share_near"] / r["share_far"]
        rows.append(_row(f"tiles: reduction, share kept within 0.03 of the blocks' inner faces "
                         f"/ elsewhere, {label}", data,
                         f"{r['share_near']:.4f} / {r['share_far']:.4f} (1: no seam)",
                         f"{seam:.3f}", ""))
    return rows


def extrapolate(run: dict, n_target: int, workers: list[int]) -> list[dict]:
    """The out-of-core run's wall time extrapolated to ``n_target`` points on each number
    of workers (the model and its assumptions: :data:`MODEL`)."""
    import math

    n = run["n"]
    tiles = run["tile_list"]
    ph = run["phases"]
    scan_rate = ph["scan"] / n  # seconds per point, one pass
    sort_rate = ph["sort"] / n  # seconds per point (re-sorts of rebuilt tiles included)
    owned = max(t["owned"] for t in tiles)
    per_tile = max(t["seconds"] for t in tiles)  # the slowest tile, at the same tile size
    flipped = sum(t["flipped"] for t in tiles)
    per_flip = ph["agree"] / max(flipped, 1)
    m_target = math.ceil(n_target / owned)  # tiles of the same size
    out = []
    for w in workers:
        waves = math.ceil(m_target / w)
        parts = {
            "scan": scan_rate * n_target,
            "sort": sort_rate * n_target,
            "tiles": waves * per_tile,
            "scheduler": m_target * run["task_overhead"],
            "agree": math.ceil(m_target / 2 / w) * per_flip,
        }
        out.append({"n": n_target, "workers": w, "tiles": m_target, "parts": parts,
                    "time": sum(parts.values()), "worker_peak_mb": max(run["worker_peak_mb"])})
    return out


#: the assumptions of :func:`extrapolate`, printed with its rows
MODEL = ("extrapolated from the measured out-of-core run: the two passes over the input "
         "(scan, and the sort into the tiles' files, re-sorts for rebuilt tiles included) "
         "run in the calling process and scale with the points; "
         "tiles keep the measured run's size (the most points a tile owned), so a tile's "
         "time is the slowest measured tile's and a worker's memory the measured peak; "
         "tiles run in waves of one per worker (each worker one core, all seeing the output "
         "folder on a disk fast enough); the scheduler costs the measured no-op task time "
         "per tile; half the tiles flipped in the agreement (the measured time per flipped "
         "tile); the cluster's start is left out")


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
    import os
    import tempfile

    files_run = None
    for n in args.sizes:
        got = {}
        for mode in args.modes:
            _log(args.quiet, f"{size_label(n)} points: {mode}")
            if mode == "files":
                with tempfile.TemporaryDirectory(prefix="fancloud_bench_tiles_") as tmp:
                    path = os.path.join(tmp, "points.npy")
                    run_task(f"{_HERE}:child_save_points",
                             {"n": n, "seed": args.seed, "path": path})
                    got[mode] = run_task(f"{_HERE}:child_files", {
                        "n": n, "seed": args.seed, "path": path,
                        "tile_points": args.tile_points, "workers": args.workers,
                        "chunk": 1_000_000})
                files_run = got[mode]
            else:
                got[mode] = run_task(f"{_HERE}:child_tiles", {"n": n, "seed": args.seed,
                                                              "tiles": tiles, "mode": mode,
                                                              "workers": args.workers,
                                                              "repeat": args.repeat})
            runs.append(got[mode])
        rows += _rows(n, args, tiles, got)
    if args.reduce:
        got = {}
        for mode in ("one", "blocks", "file"):
            _log(args.quiet, f"reduction of {size_label(args.reduce)} torus points: {mode}")
            got[mode] = run_task(f"{_HERE}:child_reduce", {
                "n": args.reduce, "seed": args.seed, "keep": args.keep, "tiles": tiles,
                "mode": mode})
            runs.append(got[mode])
        rows += _reduce_rows(args, tiles, got["one"], got["blocks"], got["file"])
    if args.mesh:
        got = {}
        for mode in ("one", "threads", "cluster"):
            _log(args.quiet, f"mesh of {size_label(args.mesh)} points: {mode}")
            got[mode] = run_task(f"{_HERE}:child_mesh", {
                "n": args.mesh, "seed": args.seed, "tiles": tiles, "mode": mode,
                "workers": args.workers})
        rows += _mesh_rows(args, tiles, got)
        runs += [{k: v for k, v in r.items() if k != "keys"} for r in got.values()]
    if files_run is not None and args.extrapolate:
        res["extrapolation"] = extrapolate(files_run, args.extrapolate,
                                           args.extrapolate_workers)
        for e in res["extrapolation"]:
            parts = ", ".join(f"{k} {v:.1f} s" for k, v in e["parts"].items())
            rows.append(_row(f"tiles: extrapolated wall time, {size_label(e['n'])} points, "
                             f"{e['workers']} workers", f"{e['tiles']} tiles of the "
                             f"{size_label(files_run['n'])} run's size",
                             f"model (see notes): {parts}", _num(e["time"]), "s"))
    res["runs"] = runs
    res["rows"] = rows
    res["elapsed"] = time.perf_counter() - t_start
    notes = ["each mode in a fresh process; points made before the timing; a small fan "
             "cloud first (kernels loaded, on the cluster in every worker); the cluster's "
             "start timed apart",
             "peak memory: the process's peak resident set (ru_maxrss), the points and the "
             "result included; on the cluster also each worker's",
             "files: write_tiled_fans of an .npy file written beforehand (not timed), "
             f"--tile-points {args.tile_points}, on a LocalCluster of --workers processes; "
             "its fan cloud read back with read_tiles (not timed) for the digest"]
    if "extrapolation" in res:
        notes.append(MODEL)
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
                        f"{args.workers} workers x 1 thread",
             "files": f"write_tiled_fans from .npy (out of core), LocalCluster "
                      f"{args.workers} workers x 1 thread"}
    for mode, r in got.items():
        extra = ""
        if "rebuilt" in r:
            extra = (f"; halos {min(r['halos']):.3g} to {max(r['halos']):.3g}, "
                     f"{r['rebuilt']} tile(s) built again")
        if "cluster_start" in r:
            extra += f"; cluster start {r['cluster_start']:.1f} s (not in the time)"
        if "phases" in r:
            t = r["tiles"]
            extra += (f"; {t[0]}x{t[1]}x{t[2]} tiles; " + ", ".join(
                f"{k} {v:.1f} s" for k, v in r["phases"].items() if k != "total")
                + f"; {r['bytes'] / 2**20:.0f} MiB written")
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
                   help="one process, Dask threads, LocalCluster, out of core from a file "
                        "(default: all)")
    p.add_argument("--workers", type=int, default=2,
                   help="LocalCluster worker processes (default: %(default)s)")
    p.add_argument("--repeat", type=int, default=1,
                   help="timed calls per mode, best kept (default: %(default)s)")
    p.add_argument("--tile-points", type=int, default=2_000_000,
                   help="files mode: points per tile (tiles='auto'; default: %(default)s)")
    p.add_argument("--extrapolate", type=lambda t: 0 if t == "0" else parse_sizes(t)[0],
                   default=100_000_000,
                   help="files mode: extrapolate its time to this many points "
                        "(default: 100M; 0: no extrapolation)")
    p.add_argument("--extrapolate-workers", type=lambda t: [int(x) for x in t.split(",")],
                   default=[2, 8, 32], help="workers of the extrapolation (default: 2,8,32)")
    p.add_argument("--reduce", type=lambda t: 0 if t == "0" else parse_sizes(t)[0],
                   default=200_000, help="the blocked reduction (tiled_reduce) against one "
                   "process on this many torus points, in the --tiles blocks (default: 200k; "
                   "0: not run)")
    p.add_argument("--mesh", type=lambda t: 0 if t == "0" else parse_sizes(t)[0], default=0,
                   help="the mesh in tiles (tiled_mesh) against one process on this many "
                   "bumpy-sphere points, in the --tiles tiles, on threads and on the "
                   "LocalCluster (default: 0, not run)")
    p.add_argument("--keep", type=float, default=0.2,
                   help="the blocked reduction's kept fraction (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--out", default="bench_out", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_tiles)
    return p
