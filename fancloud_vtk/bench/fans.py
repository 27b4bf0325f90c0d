"""``fancloud bench fans``: fan construction against a k-NN baseline, memory, first call,
open fans and thread reproducibility.

``fancloud bench fans [--sizes 100k,1M,4M] [--repeat 3] [--out bench_out] [--quick]``

Speed against a peer baseline (a scipy ``cKDTree`` build plus a 7-nearest-neighbour
query of every point), peak memory, the size of the fan cloud, the first-call (numba
compile) time, the fraction of open fans on closed surfaces, and whether the rings are
bit-identical whatever the number of threads. The measurements that need a fresh
process (first call, memory, thread counts) run in subprocesses of the same Python
(:func:`fancloud_vtk.bench.harness.run_task`, :func:`child_memory`,
:func:`child_hashes`). Writes ``fans.md`` (also printed) and ``fans.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import gc
import tempfile
import time

import numpy as np

from fancloud_vtk.bench.common import (
    SHAPES,
    WARMUP_POINTS,
    K,
    _log,
    data_label,
    digest,
    parse_size,
    parse_sizes,
    size_label,
    surface_points,
)
from fancloud_vtk.bench.harness import child_env, run_python, run_task, timed
from fancloud_vtk.bench.metrics import (
    SAMPLE_INTERVAL,
    RssSampler,
    hwm_bytes,
    maxrss_bytes,
    reset_peak_rss,
    rss_bytes,
)
from fancloud_vtk.bench.report import _num, _ok, _row, header, markdown, write_outputs

#: The issue's targets for ``bench fans``.
TARGET_RATIO = 1.5  #: build_fans time / peer time
TARGET_PEAK_BPP = 600.0  #: peak RSS growth during build_fans, bytes per point, at 1M
TARGET_NBYTES_BPP = 150.0  #: FanCloud.nbytes() per point (k=6, no colours)
TARGET_OPEN_PCT = 0.1  #: open fans on a closed surface, percent, default rule

PEER_K = K + 1  #: the peer queries the point itself and its k nearest

_HERE = __name__

#: First call in a fresh process: nothing of fancloud_vtk is imported before the clock starts.
_FIRST_CALL = """
import json, sys, time
import numpy as np
n, k = int(sys.argv[1]), int(sys.argv[2])
rng = np.random.default_rng(0)
p = rng.normal(size=(n, 3))
p /= np.linalg.norm(p, axis=1)[:, None]
t0 = time.perf_counter()
from fancloud_vtk import build_fans
t1 = time.perf_counter()
build_fans(p, k=k)
t2 = time.perf_counter()
build_fans(p, k=k)
t3 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "first": t2 - t1, "second": t3 - t2}))
"""


# -- the fresh processes -------------------------------------------------------------------


def child_memory(n: int, shape: str, seed: int, k: int) -> dict:
    """Peak RSS during one build_fans call (in a fresh process).

    Three views of the peak: the background sampler (starved while a kernel
    holds the GIL), ``VmHWM`` reset just before the call (exact, when the
    reset works) and ``getrusage`` (counts only if it rose during the call).
    The largest of those that belong to the call is reported.
    """
    from fancloud_vtk import build_fans

    pts = surface_points(n, seed, shape)
    build_fans(surface_points(WARMUP_POINTS, seed + 1, "sphere"), k=k)  # compile / load
    gc.collect()
    reset = reset_peak_rss()
    before = rss_bytes()
    maxrss_before = maxrss_bytes()
    sampler = RssSampler()
    sampler.start()
    t0 = time.perf_counter()
    fc = build_fans(pts, k=k)
    elapsed = time.perf_counter() - t0
    sampled = sampler.stop()
    hwm = hwm_bytes() if reset else None
    maxrss_after = maxrss_bytes()
    peaks = {"sampler": sampled}
    if hwm is not None:
        peaks["VmHWM"] = hwm
    if maxrss_after > maxrss_before:
        peaks["getrusage"] = maxrss_after
    source = max(peaks, key=peaks.get)
    return {
        "n": n, "rss_before": before, "sampled_peak": sampled, "samples": sampler.samples,
        "hwm_reset": reset, "hwm_after": hwm,
        "maxrss_before": maxrss_before, "maxrss_after": maxrss_after,
        "peak": peaks[source], "peak_source": source, "peaks": peaks,
        "rss_after": rss_bytes(), "time": elapsed,
        "fc_nbytes": fc.nbytes(), "fans_open": fc.n_open,
    }


def child_hashes(n: int, shape: str, seed: int, k: int, workers: int) -> dict:
    """sha256 of the fan cloud's arrays (in a fresh process with its own thread count)."""
    import numba

    from fancloud_vtk import build_fans

    fc = build_fans(surface_points(n, seed, shape), k=k, workers=workers)
    return {
        "numba_threads": numba.get_num_threads(),
        "workers": workers,
        "offsets": digest(fc.offsets),
        "ring": digest(fc.ring),
        "normals": digest(fc.normals),
        "open": digest(fc.open),
    }


# -- the measurements -----------------------------------------------------------------------


def peer_baseline(points: np.ndarray) -> None:
    """The peer: scipy's cKDTree and the 7 nearest neighbours of every point, leaf order."""
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    tree.query(points[tree.indices], k=PEER_K, workers=-1)


def measure_speed(points: np.ndarray, repeat: int, budget: float = float("inf")) -> dict:
    """Interleaved timings (peer, ours, peer, ours, ...) of the peer and build_fans.

    ``repeat`` pairs, fewer if the pairs so far took more than ``budget`` seconds.
    """
    from fancloud_vtk import build_fans

    peer, ours = [], []
    t0 = time.perf_counter()
    while len(ours) < repeat and (not ours or time.perf_counter() - t0 < budget):
        peer.append(timed(peer_baseline, points))
        ours.append(timed(build_fans, points, k=K))
    n = len(points)
    best_peer, best_ours = min(peer), min(ours)
    return {
        "n": n, "peer_times": peer, "ours_times": ours, "peer": best_peer, "ours": best_ours,
        "ratio": best_ours / best_peer, "throughput": n / best_ours,
        "peer_throughput": n / best_peer,
    }


def measure_first_call(cold: bool) -> dict:
    """First build_fans call in fresh processes: numba cache as configured, and empty."""
    out = {"points": WARMUP_POINTS, "default": run_python(
        _FIRST_CALL, [str(WARMUP_POINTS), str(K)], child_env())}
    if cold:
        with tempfile.TemporaryDirectory(prefix="fancloud-numba-") as cache:
            out["cold"] = run_python(_FIRST_CALL, [str(WARMUP_POINTS), str(K)],
                                     child_env(NUMBA_CACHE_DIR=cache))
    default = out["default"]
    # loading cached machine code takes a fraction of a second; compiling takes many
    reference = out["cold"]["first"] if cold else None
    if reference is not None:
        out["cached"] = default["first"] < 0.25 * reference
    else:
        out["cached"] = default["first"] < 20 * max(default["second"], 0.05)
    return out


def open_fraction(points: np.ndarray, **kwargs) -> dict:
    """Open fans (percent) of build_fans on a closed surface, with its parameters."""
    import warnings

    from fancloud_vtk import build_fans

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t0 = time.perf_counter()
        fc = build_fans(points, k=K, **kwargs)
        elapsed = time.perf_counter() - t0
    return {
        "n": fc.n_points, "rule": fc.info["rule"], "fans_open": fc.n_open,
        "open_pct": 100.0 * fc.n_open / fc.n_points, "time": elapsed,
        "duplicates_merged": fc.info.get("duplicates_merged", 0),
        "warnings": [str(w.message) for w in caught],
    }


def measure_quality(points: np.ndarray, label: str) -> list[dict]:
    """Open fans with the default rule and with the paper's literal rule."""
    return [{"data": label, **open_fraction(points)},
            {"data": label, **open_fraction(points, rule="paper")}]


def bunny_points() -> tuple[np.ndarray, str]:
    """The Stanford bunny shipped with pymeshlab (points only) and its label."""
    from fancloud_vtk.data import bunny_path
    from fancloud_vtk.io import read_point_cloud

    pts = read_point_cloud(bunny_path()).points
    return pts, f"Stanford bunny (pymeshlab bunny.obj), {len(pts):,} points"


def measure_reproducibility(n: int, shape: str, seed: int, threads: list[int]) -> dict:
    """Hashes of the rings with different numbers of threads, each in a fresh process."""
    runs = []
    for t in threads:
        workers = 1 if t == 1 else -1
        runs.append(run_task(f"{_HERE}:child_hashes", {"n": n, "shape": shape, "seed": seed,
                                                        "k": K, "workers": workers},
                             NUMBA_NUM_THREADS=t))
    keys = ("offsets", "ring", "normals", "open")
    identical = all(all(r[key] == runs[0][key] for key in keys) for r in runs)
    return {"n": n, "runs": runs, "identical": identical}


def _peak_note(m: dict) -> str:
    """Where the peak came from, and the other views of it (B/point above RSS before)."""
    views = ", ".join(f"{name} {(value - m['rss_before']) / m['n']:.0f}"
                      for name, value in m["peaks"].items())
    notes = [f"{m['samples']} samples every {SAMPLE_INTERVAL * 1000:g} ms"]
    if not m["hwm_reset"]:
        notes.append("VmHWM reset failed")
    if "getrusage" not in m["peaks"]:
        notes.append("getrusage peak predates the call (inherited or earlier)")
    return f"peak from {m['peak_source']} (views: {views}; {'; '.join(notes)})"


def fans_rows(res: dict) -> list[dict]:
    """The rows of the ``bench fans`` table from the raw results."""
    rows = []
    shape, seed, rep = res["args"]["shape"], res["args"]["seed"], res["args"]["repeat"]
    for s in res["speed"]:
        data = data_label(s["n"], shape, seed)
        runs = len(s["ours_times"])
        best = f"best of {runs}, interleaved peer/ours" + (
            f" ({rep} asked, time budget reached)" if runs < rep else "")
        rows += [
            _row("speed: peer", data,
                 f"cKDTree(points) + query(points[tree.indices], k={PEER_K}, workers=-1); {best}",
                 _num(s["peer"]), "s"),
            _row("speed: build_fans", data, f"build_fans(points, k={K}), compiled; {best}",
                 _num(s["ours"]), "s"),
            _row("speed: ratio ours/peer", data, f"k={K}; best times above",
                 f"{s['ratio']:.3f}", "x", f"<= {TARGET_RATIO}",
                 _ok(s["ratio"] <= TARGET_RATIO)),
            _row("speed: throughput build_fans", data, f"k={K}",
                 _num(s["throughput"]), "points/s"),
        ]
    for m in res["memory"]:
        n = m["n"]
        data = data_label(n, shape, seed)
        peak_bpp = (m["peak"] - m["rss_before"]) / n
        at_target = n == 1_000_000
        rows += [
            _row("memory: peak RSS growth during build_fans", data,
                 f"k={K}, fresh process after warm-up; (peak - RSS before) / n; "
                 + _peak_note(m),
                 _num(peak_bpp), "B/point",
                 f"<= {TARGET_PEAK_BPP:g} (at 1M)" if at_target else "",
                 _ok(peak_bpp <= TARGET_PEAK_BPP) if at_target else ""),
            _row("memory: FanCloud.nbytes() / n", data, f"k={K}, no colours",
                 _num(m["fc_nbytes"] / n), "B/point", f"<= {TARGET_NBYTES_BPP:g}",
                 _ok(m["fc_nbytes"] / n <= TARGET_NBYTES_BPP)),
        ]
    fc = res["first_call"]
    small = f"unit sphere, {fc['points']:,} random points (seed 0)"
    d = fc["default"]
    rows.append(_row(
        "first call: build_fans", small,
        f"fresh process, numba cache as configured; import fancloud_vtk {d['import']:.2f} s "
        f"not included; second call {d['second'] * 1000:.0f} ms",
        _num(d["first"]), "s", "", "cached" if fc["cached"] else "compiled (cache cold/stale)"))
    if "cold" in fc:
        c = fc["cold"]
        rows.append(_row("first call: build_fans, cold compile", small,
                         "fresh process, empty NUMBA_CACHE_DIR (compiles every kernel)",
                         _num(c["first"]), "s", "", "compiled"))
    for q in res["quality"]:
        default_rule = q["rule"] == res["default_rule"]
        rule = f"rule='{q['rule']}'" + (" (default)" if default_rule else " (literal paper rule)")
        merged = f"; {q['duplicates_merged']} duplicates merged" if q["duplicates_merged"] else ""
        rows.append(_row("quality: open fans (closed surface)", q["data"],
                         f"k={K}, {rule}{merged}; {q['fans_open']:,} of {q['n']:,}",
                         f"{q['open_pct']:.3f}", "%",
                         f"<= {TARGET_OPEN_PCT:g}" if default_rule else "",
                         _ok(q["open_pct"] <= TARGET_OPEN_PCT) if default_rule else ""))
    r = res["reproducibility"]
    if r is not None:
        confs = ", ".join(f"NUMBA_NUM_THREADS={x['numba_threads']} workers={x['workers']}"
                          for x in r["runs"])
        rows.append(_row("reproducibility: sha256 of offsets, ring, normals, open",
                         data_label(r["n"], shape, seed),
                         f"k={K}; fresh processes: {confs}; ring sha256 "
                         f"{r['runs'][0]['ring'][:12]}",
                         "identical" if r["identical"] else "different", "", "identical",
                         _ok(r["identical"])))
    return rows


def run_fans(args, argv: list[str]) -> dict:
    """``bench fans``: measure, then write and print the table."""
    import inspect

    from fancloud_vtk import build_fans

    t_start = time.perf_counter()
    quiet = args.quiet
    sizes = parse_sizes("100k") if args.quick else parse_sizes(args.sizes)
    repeat = 1 if args.quick else args.repeat
    check_n = parse_size(args.check_size)
    threads = [int(t) for t in args.threads.split(",") if t.strip()]
    res = {
        **header(["fans", *argv]),
        "args": {"sizes": sizes, "repeat": repeat, "shape": args.shape, "seed": args.seed,
                 "check_size": check_n, "threads": threads, "k": K},
        "default_rule": inspect.signature(build_fans).parameters["rule"].default,
    }

    _log(quiet, "first call in fresh processes" + (" (incl. a cold compile)" if args.cold_compile
                                                   else ""))
    res["first_call"] = measure_first_call(args.cold_compile)
    build_fans(surface_points(WARMUP_POINTS, args.seed + 1, "sphere"), k=K)  # warm up here

    # memory first: a child inherits the parent's getrusage peak, so keep the parent small
    res["memory"] = []
    for n in sizes:
        m = run_task(f"{_HERE}:child_memory",
                     {"n": n, "shape": args.shape, "seed": args.seed, "k": K})
        _log(quiet, f"memory {size_label(n)}: peak +{(m['peak'] - m['rss_before']) / n:.0f} "
                    f"B/point, nbytes {m['fc_nbytes'] / n:.0f} B/point")
        res["memory"].append(m)

    res["speed"] = []
    check_points = None
    for n in sizes:
        pts = surface_points(n, args.seed, args.shape)
        s = measure_speed(pts, repeat, args.budget)
        _log(quiet, f"speed {size_label(n)}: peer {s['peer']:.3f} s, build_fans "
                    f"{s['ours']:.3f} s, ratio {s['ratio']:.2f}")
        res["speed"].append(s)
        if n == check_n:
            check_points = pts
        del pts
        gc.collect()

    if check_points is None:
        check_points = surface_points(check_n, args.seed, args.shape)
    res["quality"] = measure_quality(check_points, data_label(check_n, args.shape, args.seed))
    del check_points
    if args.bunny:
        res["quality"] += measure_quality(*bunny_points())
    _log(quiet, "quality: " + ", ".join(f"{q['rule']} {q['open_pct']:.3f}% open"
                                        for q in res["quality"]))
    res["reproducibility"] = None
    if threads:
        res["reproducibility"] = measure_reproducibility(check_n, args.shape, args.seed,
                                                         threads)
        _log(quiet, f"reproducibility: identical={res['reproducibility']['identical']}")

    res["elapsed"] = time.perf_counter() - t_start
    rows = fans_rows(res)
    res["rows"] = rows
    text = markdown("fancloud bench fans: fan construction", res, rows)
    md, js = write_outputs(args.out, "fans", text, res)
    print(text)
    print(f"written: {md}, {js}")
    return res


# -- command line ----------------------------------------------------------------------------


def _cmd_fans(args, argv) -> int:
    run_fans(args, argv)
    return 0


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``fans`` on the subparsers of ``fancloud bench``."""
    p = sub.add_parser("fans", help="fan construction: speed, memory, open fans, threads",
                       description="Benchmark of build_fans against a cKDTree k-NN baseline.")
    p.add_argument("--sizes", default="100k,1M,4M",
                   help="point counts, suffixes k and M (default: %(default)s)")
    p.add_argument("--repeat", type=int, default=3,
                   help="timed runs per size, best kept (default: %(default)s)")
    p.add_argument("--budget", type=float, default=120.0,
                   help="seconds per size after which no further timed pair is started "
                        "(default: %(default)s)")
    p.add_argument("--quick", action="store_true", help="CI smoke run: sizes 100k, repeat 1")
    p.add_argument("--shape", choices=sorted(SHAPES), default="bumpy",
                   help="closed surface sampled (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--check-size", default="100k",
                   help="size for the open-fan and thread checks (default: %(default)s)")
    p.add_argument("--threads", default="1,2",
                   help="NUMBA_NUM_THREADS values compared (1 uses workers=1, others -1; "
                        "empty: skip) (default: %(default)s)")
    p.add_argument("--cold-compile", action=argparse.BooleanOptionalAction, default=True,
                   help="also time a compile with an empty numba cache (about 20 s)")
    p.add_argument("--bunny", action=argparse.BooleanOptionalAction, default=True,
                   help="open fans on the pymeshlab bunny too")
    p.add_argument("--out", default="bench_out", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_fans)
    return p
