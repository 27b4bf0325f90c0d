"""``fancloud bench vdfc``: view-dependent fan clouds (paper section 8) on a terrain.

``fancloud bench vdfc [--part build frames peers] [--data jacksboro] [--n 1000] [--repeat 2]
[--frames 300] [--e-max 20] [--out DIR] [--quick]``

The data (``--data``, :func:`terrain`): the Jacksboro fault DEM shipped with
matplotlib, resampled to an ``--n`` x ``--n`` grid
(:func:`fancloud_vtk.data.jacksboro_terrain`; 1000: a million points, about
30 m apart, heights in metres); or matplotlib's other DEM (``topobathy``,
resampled the same way) or a fractional Brownian surface (``fractal``,
``--seed``), as a fan cloud (:func:`~fancloud_vtk.terrain_fan_cloud`).
``--e-max`` is 20 m on Jacksboro by default, and the same fraction of the
ground's diagonal on the others (:func:`default_e_max`). ``--data bunny``: a
scanned object as a point set (the Stanford bunny's points, fans from
``build_fans``), on which only the build part (the forest in point blocks
against ``build_fans``) and the frames part (cameras circling it,
:func:`orbit_path`) run: the screen-space error and the cover are measured
on a height field's grid. Every call is made
once on a 40 x 40 terrain first (numba compiled), then timed in this
process.

build
    Best of ``--repeat``: ``build_fans(fc.points)`` against
    ``ViewDependentFanCloud.build(fc)``, without and with blocks
    (``terrain_blocks(shape, (b, b))`` with ``b = --block``, by default an
    eighth of the side: 64 blocks built in parallel threads, each small
    enough for its merge tables to stay in the cache; and 2 x 2 blocks for
    information). The target: the forest (with blocks) builds in
    at most 3 times the time of the fans.
frames
    A smooth fly-through (:func:`~fancloud_vtk.terrain_path`, ``--frames``
    cameras) with ``e_max = --e-max`` and ``d_max`` the default range of
    sight of the first camera, kept for the path: per frame the front
    update time (``Front.stats["seconds"]``: the whole ``front_arrays`` call,
    incremental from the previous frame, with its phases), the time to make
    the ``vtkPolyData`` of it, the active points and the triangles per
    active point; the same path again with superfluous triangles removed
    (``superfluous=True``: its time and triangles per point), and again
    with every front kernel on one thread (for the ratio); then
    ``flythrough`` offscreen on
    ``--render-frames`` cameras spread over the path (PNG frames in
    ``DIR/frames``).
peers
    At the front's mean triangle count T of the fly-through: the whole
    terrain reduced to T triangles by VTK's ``vtkGreedyTerrainDecimation``
    and by ``fast_simplification.simplify`` (on the grid's triangles).
    For ``--cameras`` cameras along the path, the screen-space error of
    the three surfaces drawn (ours: the front's triangles for that camera;
    theirs: the reduced mesh), all measured by the same code: for the
    original points in the view frustum (at most ``--samples`` of them), the
    vertical distance to the drawn surface (its triangles rasterised onto
    the grid, linear interpolation) divided by the point's distance to the
    eye. Points under no triangle are counted and left out.

Writes ``vdfc.md`` (also printed), ``vdfc.json``, ``vdfc_frames.csv``,
``vdfc_frames.png`` (update time and active points per frame),
``frames/frame_*.png`` and ``vdfc_peers.png`` (the three surfaces from one
camera).
"""

from __future__ import annotations

import argparse
import csv
import gc
import os
import time

import numba
import numpy as np
from numba import njit

from fancloud_vtk.bench.common import _log
from fancloud_vtk.bench.harness import timed
from fancloud_vtk.bench.report import (
    _num,
    _ok,
    _row,
    header,
    markdown,
    table_lines,
    write_outputs,
)
from fancloud_vtk.core.vdfc import PARALLEL_FRONT

#: The issue's targets for ``bench vdfc``.
TARGET_BUILD_RATIO = 3.0  #: forest build (blocks) / build_fans
TARGET_MEAN_MS = 10.0  #: mean front update per frame, ms
TARGET_MAX_MS = 50.0  #: slowest front update, ms
TARGET_TPP = 2.0  #: triangles per active point
TPP_TOLERANCE = 0.1  #: |mean triangles per point - 2| allowed
TARGET_SSE_RATIO = 1.0  #: our screen-space error / the best peer's, at the same triangles

PARTS = ("build", "frames", "peers", "merges")
DEFAULT_N, QUICK_N = 1000, 200
DEFAULT_FRAMES, QUICK_FRAMES = 300, 30
#: e_max in metres at d_max (the range of sight, about 35.6 km on the DEM):
#: on the 1000 x 1000 grid the front holds about 3% of the points on average.
DEFAULT_E_MAX = 20.0
WARM_SIDE = 40
RENDER_SIZE = (640, 480)

PEER_COLUMNS = ("surface", "points", "triangles", "triangles in view (mean)", "time (s)",
                "SSE max", "SSE p99", "SSE mean", "SSE max, worst layer", "points in view",
                "under no triangle")
SURFACES = ("ours (front)", "vtkGreedyTerrainDecimation", "fast-simplification")


#: The height fields ``--data`` names (:func:`terrain`).
TERRAINS = ("jacksboro", "topobathy", "fractal")
#: The scanned objects ``--data`` names (:func:`scanned_object`): point sets, no heights.
OBJECTS = ("bunny",)
#: A point set's forest is built in one block per this many points (64 at 1M, as the
#: terrain's blocks).
POINTS_PER_BLOCK = 15_625
#: The fractal terrain: grid spacing (m), relief (m) and Hurst exponent of its spectrum.
FRACTAL_SPACING, FRACTAL_RELIEF, FRACTAL_HURST = 30.0, 1000.0, 0.7


def terrain(side: int, data: str = "jacksboro", seed: int = 0):
    """(heights, (dx, dy), origin, label) of the height field ``data`` on a side x side grid.

    ``jacksboro``: the Jacksboro fault DEM shipped with matplotlib (30 x 32 km, heights
    236 to 1,076 m), resampled by cubic splines. ``topobathy``: matplotlib's other DEM,
    topography and bathymetry of the coast around Vancouver Island (4 by 2 degrees,
    about 290 x 220 km, heights -1,437 to 2,205 m, a 120 x 91 grid), resampled the same
    way: smooth at the grid's scale, one large relief. ``fractal``: a fractional Brownian
    surface (spectral synthesis: random phases, amplitudes falling as the frequency to
    the power ``-(FRACTAL_HURST + 1)``, ``seed``), on a grid ``FRACTAL_SPACING`` m apart
    with ``FRACTAL_RELIEF`` m from lowest to highest: rough at every scale.
    """
    if data == "jacksboro":
        from fancloud_vtk.data import jacksboro_terrain

        heights, spacing, origin = jacksboro_terrain((side, side))
        label = (f"Jacksboro DEM {side} x {side} ({side * side:,} points, "
                 f"{spacing[0]:.1f} x {spacing[1]:.1f} m)")
    elif data == "topobathy":
        heights, spacing, origin = _topobathy(side)
        label = (f"topobathy DEM {side} x {side} ({side * side:,} points, "
                 f"{spacing[0]:.0f} x {spacing[1]:.0f} m)")
    elif data == "fractal":
        heights = _fractal(side, seed)
        spacing, origin = (FRACTAL_SPACING, FRACTAL_SPACING), (0.0, 0.0)
        label = (f"fractal terrain {side} x {side} ({side * side:,} points, "
                 f"{FRACTAL_SPACING:.0f} m apart, H {FRACTAL_HURST:g}, seed {seed})")
    else:
        raise ValueError(f"unknown terrain {data!r}; one of {', '.join(TERRAINS)}")
    return heights, spacing, origin, label


def _topobathy(side: int):
    """matplotlib's ``topobathy.npz`` on a side x side grid, in metres: (heights, spacing,
    origin)."""
    from matplotlib.cbook import get_sample_data
    from scipy.ndimage import zoom

    from fancloud_vtk.data import _M_PER_DEG

    dem = get_sample_data("topobathy.npz")
    z = np.asarray(dem["topo"], dtype=np.float64)
    lon, lat = np.asarray(dem["longitude"], float), np.asarray(dem["latitude"], float)
    mid = np.radians(0.5 * (lat[0] + lat[-1]))
    width = abs(lon[-1] - lon[0]) * _M_PER_DEG * float(np.cos(mid))
    height = abs(lat[-1] - lat[0]) * _M_PER_DEG
    z = zoom(z, (side / z.shape[0], side / z.shape[1]), order=3)
    return z, (width / (side - 1), height / (side - 1)), (0.0, 0.0)


def _fractal(side: int, seed: int) -> np.ndarray:
    """A side x side fractional Brownian surface with relief ``FRACTAL_RELIEF``."""
    rng = np.random.default_rng(seed)
    fy = np.fft.fftfreq(side)[:, None]
    fx = np.fft.rfftfreq(side)[None, :]
    f = np.hypot(fx, fy)
    f[0, 0] = 1.0
    amp = f ** -(FRACTAL_HURST + 1.0)
    amp[0, 0] = 0.0
    spec = amp * np.exp(2j * np.pi * rng.random(amp.shape))
    z = np.fft.irfft2(spec, s=(side, side))
    z -= z.min()
    return z * (FRACTAL_RELIEF / z.max())


def default_e_max(heights, spacing, data: str) -> float:
    """``--e-max`` by default: 20 m on Jacksboro (``DEFAULT_E_MAX``); on another height
    field the same fraction of the ground's diagonal (20 m in Jacksboro's 43.7 km)."""
    if data == "jacksboro":
        return DEFAULT_E_MAX
    ref = _jacksboro_diagonal()
    ny, nx = heights.shape
    diag = np.hypot(spacing[0] * (nx - 1), spacing[1] * (ny - 1))
    return float(f"{DEFAULT_E_MAX * diag / ref:.3g}")


def _jacksboro_diagonal() -> float:
    from fancloud_vtk.data import jacksboro_terrain

    jh, (jx, jy), _ = jacksboro_terrain()
    return float(np.hypot(jx * (jh.shape[1] - 1), jy * (jh.shape[0] - 1)))


def scanned_object(data: str):
    """(points, label) of a scanned object: ``bunny``, the Stanford bunny's points
    (pymeshlab's ``bunny.obj``, a real range scan merged into one cloud)."""
    if data != "bunny":
        raise ValueError(f"unknown scanned object {data!r}; one of {', '.join(OBJECTS)}")
    from fancloud_vtk.data import bunny_path
    from fancloud_vtk.io import read_point_cloud

    pts = read_point_cloud(bunny_path()).points
    return pts, f"Stanford bunny (pymeshlab bunny.obj), {len(pts):,} points, a point set"


def object_e_max(points) -> float:
    """``--e-max`` by default on a scanned object: Jacksboro's 20 m in its 43.7 km ground
    diagonal, as a fraction of the object's bounding-box diagonal."""
    diag = float(np.linalg.norm(np.ptp(points, axis=0)))
    return float(f"{DEFAULT_E_MAX * diag / _jacksboro_diagonal():.3g}")


def orbit_path(bounds, n_frames: int, *, distance: float = 1.2, turns: float = 1.0,
               view_angle: float = 30.0, aspect: float = 4 / 3) -> list[tuple]:
    """Cameras circling an object: the eye ``distance`` times the bounding-box diagonal
    from its centre, ``turns`` times round the z axis while it rises from 20 degrees
    below the centre's height to 40 degrees above, always looking at the centre."""
    b = np.asarray(bounds, dtype=np.float64)
    centre = 0.5 * (b[::2] + b[1::2])
    r = distance * float(np.linalg.norm(b[1::2] - b[::2]))
    cams = []
    for u in np.linspace(0.0, 1.0, n_frames, endpoint=False):
        az = 2 * np.pi * turns * u
        el = np.radians(-20.0 + 60.0 * u)
        eye = centre + r * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                     np.sin(el)])
        cams.append((tuple(float(v) for v in eye), tuple(float(v) for v in centre),
                     (0.0, 0.0, 1.0), float(view_angle), float(aspect)))
    return cams


def measure_point_build(points, repeat: int, quiet: bool) -> dict:
    """Best times of build_fans(points) and of the forest of its fan cloud in point blocks
    (:func:`~fancloud_vtk.point_blocks`, one per ``POINTS_PER_BLOCK`` points)."""
    n_blocks = max(1, len(points) // POINTS_PER_BLOCK)
    fans, forest = [], []
    for i in range(repeat):
        _log(quiet, f"  build: run {i + 1} of {repeat}")
        gc.collect()
        _time_point_set(points, n_blocks, fans, forest)
    return {"n": len(points), "blocks": n_blocks, "build_fans_times": fans,
            "forest_times": forest, "build_fans": min(fans), "forest": min(forest),
            "ratio": min(forest) / min(fans)}


def point_build_rows(b: dict, data: str, repeat: int) -> list[dict]:
    best = f"best of {repeat}, warm (same process)"
    blocks = (f"blocks=point_blocks(fc, {b['blocks']})" if b["blocks"] > 1 else
              "no blocks (fewer points than two blocks hold)")
    return [
        _row("build: build_fans", data, f"build_fans(points), k=6; {best}; runs "
             + ", ".join(_num(t) for t in b["build_fans_times"]) + " s",
             _num(b["build_fans"]), "s"),
        _row("build: forest, the points as a point set", data,
             f"ViewDependentFanCloud.build(fc, {blocks}); {best}; runs "
             + ", ".join(_num(t) for t in b["forest_times"]) + " s",
             _num(b["forest"]), "s"),
        _row("build: ratio forest / build_fans, the points as a point set", data,
             "best times above", f"{b['ratio']:.2f}", "x", f"<= {TARGET_BUILD_RATIO:g}",
             _ok(b["ratio"] <= TARGET_BUILD_RATIO)),
    ]


def grid_triangles(ny: int, nx: int) -> np.ndarray:
    """The triangles of the grid of :func:`terrain_fan_cloud` (diagonals (i, j)-(i+1, j+1))."""
    i, j = np.meshgrid(np.arange(ny - 1), np.arange(nx - 1), indexing="ij")
    a = (i * nx + j).ravel()
    b, c, d = a + 1, a + nx + 1, a + nx
    return np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])]).astype(
        np.int64)


def _warm(quiet: bool) -> None:
    """Every call once on a small terrain: numba compiles before anything is timed."""
    from fancloud_vtk import (
        ViewDependentFanCloud,
        build_fans,
        terrain_blocks,
        terrain_fan_cloud,
        terrain_path,
    )

    _log(quiet, f"warm-up on a {WARM_SIDE} x {WARM_SIDE} terrain")
    h, sp, org, _ = terrain(WARM_SIDE)
    fc = terrain_fan_cloud(h, spacing=sp, origin=org)
    build_fans(fc.points)
    ViewDependentFanCloud.build(fc, blocks=terrain_blocks(h.shape, (WARM_SIDE // 2,) * 2))
    vd = ViewDependentFanCloud.build(fc)
    for cam in terrain_path(vd.bounds(), 4):
        f = vd.front_arrays(cam, 5.0)
    _surface_errors(f.points, f.triangles, h, sp, org, np.ones(h.shape, np.bool_))


# -- build ---------------------------------------------------------------------------------


def measure_build(fc, shape, repeat: int, quiet: bool, block: int | None = None) -> dict:
    """Best times of build_fans(points) and of the forest: without blocks, with blocks of
    ``block`` cells a side (default: an eighth of the grid's side), and with 2 x 2 blocks."""
    from fancloud_vtk import ViewDependentFanCloud, build_fans, terrain_blocks

    side = shape[0]
    block = block or max(1, side // 8)
    blocks = terrain_blocks(shape, (block, block))
    halves = terrain_blocks(shape, (max(1, side // 2), max(1, shape[1] // 2)))
    fans, plain, blocked, halved = [], [], [], []
    # the same points as a point set: in a random order, fans from build_fans, blocks
    # from point_blocks (as many as the terrain's)
    points = fc.points[np.random.default_rng(0).permutation(fc.n_points)]
    p_fans, p_blocked = [], []
    for i in range(repeat):
        _log(quiet, f"  build: run {i + 1} of {repeat}")
        fans.append(timed(build_fans, fc.points))
        plain.append(timed(ViewDependentFanCloud.build, fc))
        blocked.append(timed(ViewDependentFanCloud.build, fc, blocks=blocks))
        halved.append(timed(ViewDependentFanCloud.build, fc, blocks=halves))
        gc.collect()
        _time_point_set(points, len(blocks), p_fans, p_blocked)
    return {"n": fc.n_points, "blocks": len(blocks), "block_shape": [block, block],
            "half_blocks": len(halves), "half_block_shape": [side // 2, shape[1] // 2],
            "build_fans_times": fans, "forest_times": plain, "forest_blocks_times": blocked,
            "forest_halves_times": halved,
            "build_fans": min(fans), "forest": min(plain), "forest_blocks": min(blocked),
            "forest_halves": min(halved),
            "ratio": min(plain) / min(fans), "ratio_blocks": min(blocked) / min(fans),
            "ratio_halves": min(halved) / min(fans),
            "point_fans_times": p_fans, "point_forest_times": p_blocked,
            "point_fans": min(p_fans), "point_forest": min(p_blocked),
            "ratio_points": min(p_blocked) / min(p_fans)}


def _time_point_set(points, n_blocks: int, fans: list, forest: list) -> None:
    """One run: ``build_fans(points)`` and the forest of its fan cloud in ``n_blocks`` point
    blocks (no blocks for 1), their times appended to ``fans`` and ``forest``."""
    from fancloud_vtk import ViewDependentFanCloud, build_fans, point_blocks

    def point_forest(pfc):
        if n_blocks == 1:
            return ViewDependentFanCloud.build(pfc)
        return ViewDependentFanCloud.build(pfc, blocks=point_blocks(pfc, n_blocks))

    t0 = time.perf_counter()
    pfc = build_fans(points)
    fans.append(time.perf_counter() - t0)
    forest.append(timed(point_forest, pfc))


def build_rows(b: dict, data: str, repeat: int) -> list[dict]:
    best = f"best of {repeat}, warm (same process)"

    def runs(key):
        return "runs " + ", ".join(_num(t) for t in b[f"{key}_times"]) + " s"

    blocks = f"blocks=terrain_blocks(shape, ({b['block_shape'][0]}, {b['block_shape'][1]})): " \
             f"{b['blocks']} blocks in threads"
    halves = (f"blocks=terrain_blocks(shape, ({b['half_block_shape'][0]}, "
              f"{b['half_block_shape'][1]})): {b['half_blocks']} blocks in threads")
    return [
        _row("build: build_fans", data, f"build_fans(fc.points), k=6; {best}; "
             f"{runs('build_fans')}", _num(b["build_fans"]), "s"),
        _row("build: forest, no blocks", data, f"ViewDependentFanCloud.build(fc); {best}; "
             f"{runs('forest')}", _num(b["forest"]), "s"),
        _row("build: forest, blocks", data, f"ViewDependentFanCloud.build(fc, {blocks}); "
             f"{best}; {runs('forest_blocks')}", _num(b["forest_blocks"]), "s"),
        _row("build: ratio forest (blocks) / build_fans", data,
             "best times above; the compared ratio: the terrain's forest with blocks",
             f"{b['ratio_blocks']:.2f}", "x", f"<= {TARGET_BUILD_RATIO:g}",
             _ok(b["ratio_blocks"] <= TARGET_BUILD_RATIO)),
        _row("build: ratio forest (no blocks) / build_fans", data,
             "best times above; for information", f"{b['ratio']:.2f}", "x"),
        _row("build: ratio forest / build_fans, the points as a point set", data,
             "the grid's points in a random order; build_fans(points) (runs "
             + ", ".join(_num(t) for t in b["point_fans_times"])
             + f" s) against ViewDependentFanCloud.build(fc, blocks=point_blocks(fc, "
             f"{b['blocks']})), point_blocks timed with it (runs "
             + ", ".join(_num(t) for t in b["point_forest_times"]) + f" s); {best}",
             f"{b['ratio_points']:.2f}", "x", f"<= {TARGET_BUILD_RATIO:g}",
             _ok(b["ratio_points"] <= TARGET_BUILD_RATIO)),
        _row("build: forest, 2 x 2 blocks", data, f"ViewDependentFanCloud.build(fc, {halves}); "
             f"{best}; {runs('forest_halves')}; ratio to build_fans "
             f"{b['ratio_halves']:.2f}; for information (bigger blocks: deeper heaps, fewer "
             "cache hits)", _num(b["forest_halves"]), "s"),
    ]


# -- frames --------------------------------------------------------------------------------


def run_frames(vd, cams, e_max: float, d_max: float, quiet: bool,
               superfluous: bool = False) -> dict:
    """The fly-through: per frame the front update time, active points, triangles."""
    from fancloud_vtk.algorithms.convert import to_vtk

    vd.reset_front()
    gc.collect()
    frames = []
    for i, cam in enumerate(cams):
        front = vd.front_arrays(cam, e_max, d_max, superfluous=superfluous)
        t0 = time.perf_counter()
        to_vtk(front)
        ms_vtk = 1e3 * (time.perf_counter() - t0)
        s = front.stats
        frames.append({"frame": i, "ms": 1e3 * s["seconds"], "active": s["active"],
                       "in_view": s["in_view"], "border": s["border"],
                       "triangles": s["triangles"], "tpp": s["triangles_per_point"],
                       "front": s["front"], "visited": s["visited"],
                       "ms_update": 1e3 * s["seconds_update"],
                       "ms_triangles": 1e3 * s["seconds_triangles"],
                       "ms_points": 1e3 * s["seconds_points"], "ms_vtk": ms_vtk})
    _log(quiet, f"  frames: {len(frames)} fronts, mean "
         f"{np.mean([f['ms'] for f in frames[1:] or frames]):.1f} ms")
    rest = frames[1:] or frames
    phases = {"default": {
        "update_front": float(np.mean([f["ms_update"] for f in rest])),
        "front_triangles": float(np.mean([f["ms_triangles"] for f in rest])),
        "front_points": float(np.mean([f["ms_points"] for f in rest])),
        "to_vtk": float(np.mean([f["ms_vtk"] for f in rest])),
        "total": float(np.mean([f["ms"] for f in rest])),
        "max_total": float(max(f["ms"] for f in rest))}}
    vd.reset_front()
    return {"frames": frames, "phases": phases, "e_max": e_max, "d_max": d_max}


def _equal_front(vd, cam, d_max: float, target: int, e_max: float):
    """The front of ``vd`` for ``cam`` whose triangle count is nearest ``target``: e_max
    searched by bisection on a log scale (non-incremental fronts); (front, e_max)."""
    lo, hi = e_max / 64.0, e_max * 64.0
    best = None
    for _ in range(24):
        mid = float(np.sqrt(lo * hi))
        front = vd.front_arrays(cam, mid, d_max, incremental=False)
        if best is None or abs(front.n_triangles - target) < abs(best[0].n_triangles - target):
            best = (front, mid)
        if front.n_triangles == target or hi / lo < 1.0001:
            break
        if front.n_triangles > target:  # too fine: a larger e_max
            lo = mid
        else:
            hi = mid
    return best


def merges_sse(fc, forests, heights, spacing, origin, cams, e_max, d_max, n_cams, samples,
               seed) -> dict:
    """The paper's Fig. 13 as a measure: the screen-space error of the entropy forest's
    front and of the half-edge forest's front with the same triangle count (its e_max
    searched), over ``n_cams`` cameras of the fly-through, on points sampled in view."""
    ny, nx = heights.shape
    rng = np.random.default_rng(seed)
    idx = _spread(len(cams), n_cams)
    per = {m: {"sse": [], "worst": [], "missed": 0, "triangles": [], "e_max": []}
           for m in forests}
    in_view = 0
    for k in idx:
        cam = cams[k]
        sel, want, dist = _in_view(fc.points, cam, samples, rng, (ny, nx))
        in_view += len(sel)
        ref = forests["entropy"].front_arrays(cam, e_max, d_max, incremental=False)
        fronts = {"entropy": (ref, e_max)}
        fronts["half_edge"] = _equal_front(forests["half_edge"], cam, d_max, ref.n_triangles,
                                           e_max)
        for m, (front, e) in fronts.items():
            best, worst, hits = _surface_errors(front.points, front.triangles, heights,
                                                spacing, origin, want)
            ok = hits.ravel()[sel] > 0
            p = per[m]
            p["sse"].append(best.ravel()[sel][ok] / dist[ok])
            p["worst"].append(worst.ravel()[sel][ok] / dist[ok])
            p["missed"] += int((~ok).sum())
            p["triangles"].append(front.n_triangles)
            p["e_max"].append(e)
    for forest in forests.values():
        forest.reset_front()
    out = {"cameras": [int(k) for k in idx], "in_view": in_view, "samples": samples}
    for m, p in per.items():
        sse = np.concatenate(p["sse"])
        worst = np.concatenate(p["worst"])
        out[m] = {"triangles": float(np.mean(p["triangles"])), "missed": p["missed"],
                  "e_max": [float(x) for x in p["e_max"]],
                  "sse_max": float(sse.max()), "sse_p99": float(np.percentile(sse, 99)),
                  "sse_mean": float(sse.mean()), "worst_max": float(worst.max()),
                  "worst_p99": float(np.percentile(worst, 99))}
    return out


def run_merges(fc, vd, cams, e_max: float, d_max: float) -> dict:
    """The paper's Figures 13 and 14: the forest of entropy merges (``vd``) against one of
    half-edge collapses, over the same fly-through at the same e_max: fans folded at merge
    time (:meth:`ViewDependentFanCloud.folded_fans`), front triangles per frame and of them
    the folded ones (``Front.stats["folded"]``, written the other way round)."""
    from fancloud_vtk import ViewDependentFanCloud

    out = {}
    for merge, forest in (("entropy", vd), ("half_edge", None)):
        if forest is None:
            forest = ViewDependentFanCloud.build(fc, merge)
        folded = forest.folded_fans()
        inner = ~forest.is_leaf
        forest.reset_front()
        tris, bad, tpp = [], [], []
        for cam in cams:
            front = forest.front_arrays(cam, e_max, d_max)
            tris.append(front.n_triangles)
            bad.append(int(front.stats["folded"]))
            tpp.append(front.stats["triangles_per_point"])
        forest.reset_front()
        out.setdefault("forests", {})[merge] = forest
        out[merge] = {"merged": int(inner.sum()), "folded": int(folded[inner].sum()),
                      "folded_leaves": int(folded[~inner].sum()),
                      "triangles": float(np.mean(tris)), "folded_triangles": float(np.mean(bad)),
                      "folded_triangles_max": int(max(bad)),
                      "folded_share": float(np.sum(bad) / max(np.sum(tris), 1)),
                      "tpp": float(np.mean(tpp))}
    return out


def merge_rows(m: dict, data: str, e_max: float) -> list[dict]:
    rows = []
    names = {"entropy": "entropy merges (the default)", "half_edge": "half-edge collapses"}
    for merge in names:
        r = m[merge]
        rows.append(_row(f"merges: fans folded at merge time (Fig. 14), {names[merge]}", data,
                         f"of {r['merged']:,} merged nodes "
                         f"({100 * r['folded'] / max(r['merged'], 1):.3f}%); input fans "
                         f"folded: {r['folded_leaves']}", f"{r['folded']:,}", ""))
        rows.append(_row(f"merges: folded front triangles per frame, mean, {names[merge]}",
                         data, f"the fly-through at e_max {e_max:g} m; of "
                         f"{r['triangles']:,.0f} triangles per frame on average "
                         f"({100 * r['folded_share']:.2f}%); max {r['folded_triangles_max']:,}; "
                         f"triangles per active point {r['tpp']:.3f}",
                         f"{r['folded_triangles']:.1f}", ""))
    sse = m.get("sse")
    if sse:
        cams = f"{len(sse['cameras'])} cameras of the fly-through, {sse['in_view']:,} points " \
               "sampled in view"
        for merge in names:
            r = sse[merge]
            how = (f"at e_max {e_max:g} m" if merge == "entropy" else
                   "e_max searched per camera for the entropy front's triangle count ("
                   + ", ".join(f"{x:.3g}" for x in r["e_max"]) + " m)")
            rows.append(_row(f"merges: screen-space error p99 at equal triangles (Fig. 13), "
                             f"{names[merge]}", data,
                             f"{cams}; {r['triangles']:,.0f} triangles per front, {how}; "
                             f"max {r['sse_max']:.3g}, mean {r['sse_mean']:.3g}; every layer "
                             f"drawn: p99 {r['worst_p99']:.3g}, max {r['worst_max']:.3g}; "
                             f"points under no triangle {r['missed']:,}",
                             f"{r['sse_p99']:.3g}", ""))
        ratio = sse["half_edge"]["sse_p99"] / sse["entropy"]["sse_p99"]
        rows.append(_row("merges: screen-space error p99 at equal triangles (Fig. 13), "
                         "half-edge collapses / entropy merges", data,
                         f"{cams}; max: "
                         f"{sse['half_edge']['sse_max'] / sse['entropy']['sse_max']:.3f}",
                         f"{ratio:.3f}", "x"))
    return rows


def frame_summary(fr: dict, n: int) -> dict:
    frames = fr["frames"]
    rest = frames[1:] or frames
    ms = np.array([f["ms"] for f in rest])
    act = np.array([f["active"] for f in frames])
    tpp = np.array([f["tpp"] for f in frames])
    tri = np.array([f["triangles"] for f in frames])
    return {"mean_ms": float(ms.mean()), "max_ms": float(ms.max()),
            "p95_ms": float(np.percentile(ms, 95)), "median_ms": float(np.median(ms)),
            "first_ms": frames[0]["ms"], "active_mean": float(act.mean()),
            "active_min": int(act.min()), "active_max": int(act.max()),
            "active_pct": 100.0 * float(act.mean()) / n, "tpp_mean": float(tpp.mean()),
            "tpp_min": float(tpp.min()), "tpp_max": float(tpp.max()),
            "triangles_mean": float(tri.mean()),
            "visited_mean": float(np.mean([f["visited"] for f in rest]))}


def frame_rows(fr: dict, s: dict, data: str, render: dict | None,
               lean: dict | None = None, serial: dict | None = None) -> list[dict]:
    nf = len(fr["frames"])
    unit = fr.get("unit", "m")
    d_max = f"{fr['d_max']:,.0f}" if fr["d_max"] >= 100 else f"{fr['d_max']:.4g}"
    path = (f"{fr.get('path', 'terrain_path')}(bounds, {nf}), e_max {fr['e_max']:g} {unit} "
            f"at d_max {d_max} {unit} (refine while e(r) > e_max d(r) / d_max)")
    upd = f"{path}; Front.stats['seconds'] of frames 2..{nf} (incremental)"
    rows = [
        _row("frames: front update, mean", data,
             f"{upd}; median {s['median_ms']:.1f}, p95 {s['p95_ms']:.1f} ms; "
             f"{s['visited_mean']:,.0f} nodes visited per update",
             f"{s['mean_ms']:.2f}", "ms", f"<= {TARGET_MEAN_MS:g}",
             _ok(s["mean_ms"] <= TARGET_MEAN_MS)),
        _row("frames: front update, max", data, upd, f"{s['max_ms']:.2f}", "ms",
             f"<= {TARGET_MAX_MS:g}", _ok(s["max_ms"] <= TARGET_MAX_MS)),
        _row("frames: first front (from the roots)", data, f"{path}; frame 1",
             f"{s['first_ms']:.2f}", "ms"),
        _row("frames: active points, mean", data,
             f"{path}; min {s['active_min']:,}, max {s['active_max']:,}; "
             f"{s['active_pct']:.2f}% of the points on average", f"{s['active_mean']:,.0f}",
             "points"),
        _row("frames: triangles per active point, mean", data,
             f"{path}; distinct front triangles / active points (in view and border); "
             f"min {s['tpp_min']:.3f}, max {s['tpp_max']:.3f} over {nf} frames",
             f"{s['tpp_mean']:.3f}", "", f"{TARGET_TPP:g} +- {TPP_TOLERANCE:g}",
             _ok(abs(s["tpp_mean"] - TARGET_TPP) <= TPP_TOLERANCE)),
    ]
    if lean is not None:
        again = f"{path}; the same fly-through with front_arrays(..., superfluous=True)"
        rows += [
            _row("frames, superfluous removed: front update, mean", data,
                 f"{again}; frames 2..{nf}; max {lean['max_ms']:.1f} ms", f"{lean['mean_ms']:.2f}",
                 "ms", f"<= {TARGET_MEAN_MS:g}", _ok(lean["mean_ms"] <= TARGET_MEAN_MS)),
            _row("frames, superfluous removed: triangles per active point, mean", data,
                 f"{again}; min {lean['tpp_min']:.3f}, max {lean['tpp_max']:.3f}",
                 f"{lean['tpp_mean']:.3f}", "", f"{TARGET_TPP:g} +- {TPP_TOLERANCE:g}",
                 _ok(abs(lean["tpp_mean"] - TARGET_TPP) <= TPP_TOLERANCE)),
        ]
    if serial is not None:
        rows.append(_row(
            "frames, one thread: front update, mean", data,
            f"{path}; the same fly-through with every front kernel serial "
            f"(PARALLEL_FRONT never reached); max {serial['max_ms']:.1f} ms; ratio to the "
            f"default {serial['mean_ms'] / max(s['mean_ms'], 1e-12):.2f}; for information",
            f"{serial['mean_ms']:.2f}", "ms"))
    if render is not None and render.get("rows"):
        r = render["rows"]
        w, h = render["size"]
        rows.append(_row("render: fly-through frame, mean", data,
                         f"fancloud_vtk.algorithms.vdfc.flythrough, {len(r)} cameras spread "
                         f"over the path, {w} x {h} offscreen VTK; max "
                         f"{max(x['render_ms'] for x in r):.1f} ms; front update (not "
                         f"incremental: the cameras are far apart) mean "
                         f"{np.mean([x['front_ms'] for x in r]):.1f} ms",
                         f"{np.mean([x['render_ms'] for x in r]):.1f}", "ms"))
    return rows


def phase_notes(phases: dict, n_frames: int) -> list[str]:
    """The phases of the front update, from ``Front.stats`` of the fly-through."""
    ph = phases["default"]
    return [f"front update phases (Front.stats, mean ms over frames 2..{n_frames}): moving "
            f"the front {ph['update_front']:.2f}, the active fans' triangles "
            f"{ph['front_triangles']:.2f}, the points' arrays {ph['front_points']:.2f}; "
            f"total {ph['total']:.2f} (max {ph['max_total']:.2f}); then the vtkPolyData "
            f"(Front.to_vtk, not in the total) {ph['to_vtk']:.2f}. From {PARALLEL_FRONT:,} "
            f"front nodes the nodes' tests, the triangles and the points' arrays run on "
            f"{numba.get_num_threads()} numba threads; the front's moves are serial"]


def frames_chart(fr: dict, s: dict, path: str, label: str) -> str:
    """Front update time and active points per frame (matplotlib Agg)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    frames = fr["frames"]
    x = [f["frame"] for f in frames]
    fig = Figure(figsize=(11, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax, aa = fig.subplots(1, 2)
    ax.plot(x, [f["ms"] for f in frames], linewidth=1, label="front update")
    ax.axhline(TARGET_MEAN_MS, color="orange", linestyle="--", linewidth=1,
               label=f"target mean {TARGET_MEAN_MS:g} ms")
    ax.axhline(TARGET_MAX_MS, color="red", linestyle="--", linewidth=1,
               label=f"target max {TARGET_MAX_MS:g} ms")
    ax.axhline(s["mean_ms"], color="tab:blue", linestyle=":", linewidth=1,
               label=f"mean {s['mean_ms']:.1f} ms")
    ax.set_xlabel("frame")
    ax.set_ylabel("ms")
    ax.set_title("front update per frame (frame 0: from the roots)", fontsize=10)
    ax.legend(fontsize=8)
    aa.plot(x, [f["active"] for f in frames], color="tab:green", linewidth=1,
            label="active points")
    aa.set_xlabel("frame")
    aa.set_ylabel("active points", color="tab:green")
    at = aa.twinx()
    at.plot(x, [f["tpp"] for f in frames], color="tab:purple", linewidth=1)
    at.set_ylabel("triangles per active point", color="tab:purple")
    aa.set_title("active points and triangles per point", fontsize=10)
    for a in (ax, aa):
        a.grid(True, alpha=0.3)
    fig.suptitle(f"fancloud bench vdfc: fly-through over the {label}, e_max "
                 f"{fr['e_max']:g} {fr.get('unit', 'm')}", fontsize=10)
    fig.savefig(path, dpi=90)
    return path


def run_render(vd, cams, e_max: float, d_max: float, count: int, out_dir: str) -> dict:
    """``flythrough`` on ``count`` cameras spread over the path, PNG frames in ``out_dir``;
    ``{"error": ...}`` if the offscreen render fails (a machine without GL)."""
    from fancloud_vtk.algorithms.vdfc import flythrough

    idx = np.unique(np.round(np.linspace(0, len(cams) - 1, count)).astype(int))
    sub = [cams[i] for i in idx]
    try:
        rows = flythrough(vd, sub, e_max, out_dir, d_max=d_max, size=RENDER_SIZE)
    except Exception as exc:  # an offscreen render can fail on a machine without GL
        return {"error": f"{type(exc).__name__}: {exc}"}
    finally:
        vd.reset_front()
    return {"rows": rows, "path_frames": idx.tolist(), "size": list(RENDER_SIZE),
            "dir": out_dir}


# -- peers ---------------------------------------------------------------------------------


@njit(cache=True)
def _raster(verts, tris, heights, ox, oy, dx, dy, want, best, worst, hits):
    """Rasterise triangles onto the grid: |surface height - grid height| at wanted nodes.

    ``best`` / ``worst``: the smallest / largest deviation over the
    triangles above a node (they differ only where the surface folds over
    itself); ``hits``: how many triangles cover it (edges and vertices
    count for every triangle that holds them).
    """
    ny, nx = heights.shape
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        x0, y0, z0 = verts[a, 0], verts[a, 1], verts[a, 2]
        x1, y1, z1 = verts[b, 0], verts[b, 1], verts[b, 2]
        x2, y2, z2 = verts[c, 0], verts[c, 1], verts[c, 2]
        det = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if det == 0.0:
            continue  # vertical: no height
        xmin, xmax = min(x0, x1, x2), max(x0, x1, x2)
        ymin, ymax = min(y0, y1, y2), max(y0, y1, y2)
        j0 = max(0, int(np.ceil((xmin - ox) / dx - 1e-9)))
        j1 = min(nx - 1, int(np.floor((xmax - ox) / dx + 1e-9)))
        i0 = max(0, int(np.ceil((ymin - oy) / dy - 1e-9)))
        i1 = min(ny - 1, int(np.floor((ymax - oy) / dy + 1e-9)))
        tol = 1e-9
        for i in range(i0, i1 + 1):
            y = oy + i * dy
            for j in range(j0, j1 + 1):
                if not want[i, j]:
                    continue
                x = ox + j * dx
                l1 = ((x - x0) * (y2 - y0) - (x2 - x0) * (y - y0)) / det
                l2 = ((x1 - x0) * (y - y0) - (x - x0) * (y1 - y0)) / det
                l0 = 1.0 - l1 - l2
                if l0 < -tol or l1 < -tol or l2 < -tol:
                    continue
                d = abs(l0 * z0 + l1 * z1 + l2 * z2 - heights[i, j])
                if hits[i, j] == 0 or d < best[i, j]:
                    best[i, j] = d
                if hits[i, j] == 0 or d > worst[i, j]:
                    worst[i, j] = d
                hits[i, j] += 1


def _surface_errors(verts, tris, heights, spacing, origin, want):
    """(best, worst, hits) grids of a triangle surface against the heights at ``want``."""
    best = np.zeros(heights.shape)
    worst = np.zeros(heights.shape)
    hits = np.zeros(heights.shape, np.int32)
    _raster(np.ascontiguousarray(verts, dtype=np.float64),
            np.ascontiguousarray(tris, dtype=np.int64), heights, float(origin[0]),
            float(origin[1]), float(spacing[0]), float(spacing[1]), want, best, worst, hits)
    return best, worst, hits


def view_sample(points, cam, samples: int, rng) -> np.ndarray:
    """Indices of the original points inside the camera's frustum, at most ``samples``."""
    from fancloud_vtk.core.vdfc import Camera

    _, planes = Camera.of(cam).frustum()
    inside = np.all(points @ planes[:, :3].T + planes[:, 3] >= 0, axis=1)
    idx = np.flatnonzero(inside)
    if len(idx) > samples:
        idx = np.sort(rng.choice(idx, samples, replace=False))
    return idx


def _spread(n_frames: int, n_cams: int) -> np.ndarray:
    """``n_cams`` frames spread over the fly-through (its ends left out)."""
    return np.unique(np.round(np.linspace(0, n_frames - 1, n_cams + 2)[1:-1]).astype(int))


def _in_view(points, cam, samples: int, rng, shape):
    """Grid points in view (a sample): (their indices, a grid mask of them, their distance
    to the eye)."""
    sel = view_sample(points, cam, samples, rng)
    want = np.zeros(shape[0] * shape[1], np.bool_)
    want[sel] = True
    dist = np.linalg.norm(points[sel] - np.asarray(cam[0], dtype=np.float64), axis=1)
    return sel, want.reshape(shape), dist


def greedy_terrain(heights, spacing, origin, n_triangles: int):
    """vtkGreedyTerrainDecimation to ``n_triangles``: (vertices, triangles, seconds)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersHybrid import vtkGreedyTerrainDecimation

    from fancloud_vtk.algorithms.vdfc import image_of_heights

    img = image_of_heights(heights, spacing, origin)
    g = vtkGreedyTerrainDecimation()
    g.SetInputData(img)
    g.SetErrorMeasureToNumberOfTriangles()
    g.SetNumberOfTriangles(int(n_triangles))
    t0 = time.perf_counter()
    g.Update()
    seconds = time.perf_counter() - t0
    out = g.GetOutput()
    v = np.array(vtk_to_numpy(out.GetPoints().GetData()), dtype=np.float64)
    polys = out.GetPolys()
    conn = vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64)
    off = vtk_to_numpy(polys.GetOffsetsArray()).astype(np.int64)
    if len(off) > 1 and not (np.diff(off) == 3).all():
        raise RuntimeError("vtkGreedyTerrainDecimation returned cells that are not triangles")
    return v, conn.reshape(-1, 3), seconds


def fast_simplify(points, triangles, n_triangles: int):
    """fast_simplification.simplify to ``n_triangles``: (vertices, triangles, seconds)."""
    import fast_simplification

    t0 = time.perf_counter()
    v, f = fast_simplification.simplify(points, triangles, target_count=int(n_triangles))
    seconds = time.perf_counter() - t0
    return np.asarray(v, np.float64), np.asarray(f, np.int64), seconds


def run_peers(vd, fc, heights, spacing, origin, cams, fr: dict, s: dict, n_cams: int,
              samples: int, seed: int, quiet: bool) -> dict:
    """Screen-space errors of our fronts and of the two peers at the same triangle count."""
    budget = int(round(s["triangles_mean"]))
    ny, nx = heights.shape
    _log(quiet, f"  peers: reduce to {budget:,} triangles")
    peers = {}
    try:
        peers[SURFACES[1]] = greedy_terrain(heights, spacing, origin, budget)
    except Exception as exc:
        peers[SURFACES[1]] = f"{type(exc).__name__}: {exc}"
    try:
        peers[SURFACES[2]] = fast_simplify(fc.points, grid_triangles(ny, nx), budget)
    except Exception as exc:  # e.g. fast-simplification not installed
        peers[SURFACES[2]] = f"{type(exc).__name__}: {exc}"
    rng = np.random.default_rng(seed)
    idx = _spread(len(cams), n_cams)
    e_max, d_max = fr["e_max"], fr["d_max"]
    per = {name: {"sse": [], "worst": [], "in_view": 0, "missed": 0, "tri_view": []}
           for name in SURFACES}
    cam_rows = []
    vd.reset_front()
    for k in idx:
        cam = cams[k]
        sel, want, dist = _in_view(fc.points, cam, samples, rng, (ny, nx))
        front = vd.front_arrays(cam, e_max, d_max)
        surfaces = {SURFACES[0]: (front.points, front.triangles)}
        surfaces.update({name: p[:2] for name, p in peers.items() if not isinstance(p, str)})
        row = {"frame": int(k), "in_view": len(sel)}
        for name, (v, t) in surfaces.items():
            best, worst, hits = _surface_errors(v, t, heights, spacing, origin, want)
            h = hits.ravel()[sel]
            ok = h > 0
            sse = best.ravel()[sel][ok] / dist[ok]
            p = per[name]
            p["sse"].append(sse)
            p["worst"].append(worst.ravel()[sel][ok] / dist[ok])
            p["in_view"] += len(sel)
            p["missed"] += int((~ok).sum())
            p["tri_view"].append(_triangles_in_view(v, t, cam))
            row[name] = {"triangles": len(t), "missed": int((~ok).sum()),
                         "sse_max": float(sse.max()) if len(sse) else None,
                         "sse_p99": float(np.percentile(sse, 99)) if len(sse) else None}
        cam_rows.append(row)
    vd.reset_front()
    out = {"budget": budget, "cameras": cam_rows, "samples": samples, "surfaces": {},
           "threshold": e_max / d_max}
    for name in SURFACES:
        p = per[name]
        peer = peers.get(name)
        if isinstance(peer, str):
            out["surfaces"][name] = {"error": peer}
            continue
        sse = np.concatenate(p["sse"]) if p["sse"] else np.zeros(0)
        worst = np.concatenate(p["worst"]) if p["worst"] else np.zeros(0)
        entry = {"in_view": p["in_view"], "missed": p["missed"],
                 "triangles_in_view": float(np.mean(p["tri_view"])),
                 "sse_max": float(sse.max()) if len(sse) else None,
                 "sse_p99": float(np.percentile(sse, 99)) if len(sse) else None,
                 "sse_mean": float(sse.mean()) if len(sse) else None,
                 "worst_max": float(worst.max()) if len(worst) else None,
                 "worst_p99": float(np.percentile(worst, 99)) if len(worst) else None}
        if peer is None:  # ours
            entry.update(points=s["active_mean"], triangles=s["triangles_mean"], seconds=None,
                         cam_triangles=float(np.mean([r[name]["triangles"]
                                                      for r in cam_rows])))
        else:
            entry.update(points=len(peer[0]), triangles=len(peer[1]), seconds=peer[2])
        out["surfaces"][name] = entry
    out["views"] = {name: peers[name][:2] for name in SURFACES[1:]
                    if not isinstance(peers.get(name), str)}
    out["view_camera"] = int(idx[len(idx) // 2])
    return out


def _triangles_in_view(v, t, cam) -> int:
    """Triangles with a vertex inside the frustum."""
    from fancloud_vtk.core.vdfc import Camera

    _, planes = Camera.of(cam).frustum()
    inside = np.all(v @ planes[:, :3].T + planes[:, 3] >= 0, axis=1)
    return int(inside[t].any(axis=1).sum())


def _sci(x) -> str:
    return "n/a" if x is None else f"{x:.3g}"


def peer_rows(pr: dict, data: str, n_cams: int) -> list[dict]:
    sur = pr["surfaces"]
    how = (f"{n_cams} cameras along the path; vertical distance to the drawn surface / "
           f"distance to the eye, over the original points in the frustum (<= "
           f"{pr['samples']:,} sampled per camera); the front's threshold e_max / d_max = "
           f"{pr['threshold']:.3g}")
    rows = []
    # the headline compares every layer drawn (a front's overlapping fans may put more than
    # one layer over a point: the farthest counts), and the points under no triangle
    for key, label in (("worst_max", "max over every layer drawn"),
                       ("worst_p99", "99th percentile over every layer drawn"),
                       ("sse_max", "max, nearest layer"),
                       ("sse_p99", "99th percentile, nearest layer")):
        for name in SURFACES:
            e = sur[name]
            if "error" in e:
                rows.append(_row(f"peers: screen-space error {label}, {name}", data,
                                 f"failed: {e['error']}", "n/a", "rad"))
                continue
            size = (f"{e['triangles']:,.0f} triangles (mean of the fronts)"
                    if name == SURFACES[0] else
                    f"{e['points']:,} points, {e['triangles']:,} triangles, reduced in "
                    f"{e['seconds']:.2f} s")
            rows.append(_row(f"peers: screen-space error {label}, {name}", data,
                             f"{size}; {how}; {e['missed']:,} of {e['in_view']:,} points "
                             "under no triangle", _sci(e[key]), "rad"))
        ours = sur[SURFACES[0]].get(key)
        theirs = [(sur[n][key], n) for n in SURFACES[1:] if sur[n].get(key) is not None]
        if ours is not None and theirs and key.startswith("worst"):
            best, who = min(theirs)
            ratio = ours / best if best > 0 else float("inf")
            rows.append(_row(f"peers: ratio ours / best peer, SSE {label}", data,
                             f"best peer: {who}, at {pr['budget']:,} triangles (our mean); "
                             "points under no triangle are not in the ratio: see the row "
                             "below", f"{ratio:.3g}", "x", f"< {TARGET_SSE_RATIO:g}",
                             _ok(ratio < TARGET_SSE_RATIO)))
    if "error" not in sur[SURFACES[0]]:
        e = sur[SURFACES[0]]
        peers_missed = [sur[n]["missed"] / max(sur[n]["in_view"], 1) for n in SURFACES[1:]
                        if "error" not in sur[n]]
        share = e["missed"] / max(e["in_view"], 1)
        fewest = min(peers_missed) if peers_missed else None
        rows.append(_row("peers: points under no triangle, ours (front)", data,
                         f"{e['missed']:,} of {e['in_view']:,} sampled points in view; the "
                         f"fewest of a peer: {_sci(None if fewest is None else 100 * fewest)}%",
                         f"{100 * share:.3g}", "%",
                         "" if fewest is None else "<= the fewest of a peer",
                         "" if fewest is None else _ok(share <= fewest)))
    return rows


def peer_table(pr: dict) -> list[str]:
    rows = []
    for name in SURFACES:
        e = pr["surfaces"][name]
        if "error" in e:
            rows.append(dict(zip(PEER_COLUMNS, [name, "failed", e["error"][:80]]
                                 + ["-"] * (len(PEER_COLUMNS) - 3), strict=True)))
            continue
        cells = (name, f"{e['points']:,.0f}", f"{e['triangles']:,.0f}",
                 f"{e['triangles_in_view']:,.0f}",
                 "-" if e["seconds"] is None else f"{e['seconds']:.2f}",
                 _sci(e["sse_max"]), _sci(e["sse_p99"]), _sci(e["sse_mean"]),
                 _sci(e["worst_max"]), f"{e['in_view']:,}", f"{e['missed']:,}")
        rows.append(dict(zip(PEER_COLUMNS, cells, strict=True)))
    return table_lines(PEER_COLUMNS, rows)


def render_peers(vd, pr: dict, cams, fr: dict, path: str) -> str:
    """The three surfaces from one camera, side by side (pyvista off_screen)."""
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    k = pr["view_camera"]
    cam = cams[k]
    vd.reset_front()
    front = vd.front_arrays(cam, fr["e_max"], fr["d_max"])
    vd.reset_front()
    surf = [(SURFACES[0], front.points, front.triangles)]
    surf += [(name, v, t) for name, (v, t) in pr["views"].items()]
    w, h = RENDER_SIZE
    pl = pv.Plotter(off_screen=True, shape=(1, len(surf)), window_size=(w * len(surf), h),
                    border=False)
    for i, (name, v, t) in enumerate(surf):
        pl.subplot(0, i)
        e = pr["surfaces"][name]
        pl.add_text(f"{name}: {len(t):,} triangles\nSSE max {_sci(e['sse_max'])}, "
                    f"p99 {_sci(e['sse_p99'])}", font_size=9)
        pl.add_mesh(pv.PolyData.from_regular_faces(v, t), color="#d8c8a8", show_edges=True,
                    edge_color="#5c5345", line_width=0.3)
        pl.camera.position, pl.camera.focal_point, pl.camera.up = cam[0], cam[1], cam[2]
        pl.camera.view_angle = cam[3]
        pl.renderer.ResetCameraClippingRange()
    pl.screenshot(path)
    pl.close()
    return path


# -- the run -------------------------------------------------------------------------------


def run_vdfc(args, argv: list[str]) -> dict:
    """``bench vdfc``: the parts asked for; tables, JSON and figures."""
    from fancloud_vtk import ViewDependentFanCloud, terrain_fan_cloud, terrain_path

    t_start = time.perf_counter()
    quiet = args.quiet
    side = args.n if args.n is not None else (QUICK_N if args.quick else DEFAULT_N)
    n_frames = args.frames if args.frames is not None else (
        QUICK_FRAMES if args.quick else DEFAULT_FRAMES)
    if side < 16 or n_frames < 2 or args.cameras < 1 or args.samples < 1 \
            or args.render_frames < 0 or not (args.e_max is None or args.e_max > 0):
        raise ValueError("--n must be at least 16, --frames at least 2, --cameras and "
                         "--samples at least 1, --render-frames not negative and --e-max > 0")
    parts = list(dict.fromkeys(args.part))
    if args.data in OBJECTS:
        return run_object(args, argv, parts, n_frames)
    _warm(quiet)
    heights, spacing, origin, data = terrain(side, args.data, args.seed)
    e_max = args.e_max if args.e_max is not None else default_e_max(heights, spacing,
                                                                     args.data)
    res = {**header(["vdfc", *argv]),
           "args": {"part": parts, "data": args.data, "n": side, "repeat": args.repeat,
                    "frames": n_frames, "e_max": e_max, "cameras": args.cameras,
                    "samples": args.samples,
                    "render_frames": args.render_frames, "seed": args.seed},
           "build": None, "frames": None, "render": None, "peers": None, "merges": None}
    fc = terrain_fan_cloud(heights, spacing=spacing, origin=origin)
    res["data"] = data
    rows, written, notes = [], [], []
    if "build" in parts:
        _log(quiet, f"build: {data}")
        res["build"] = measure_build(fc, heights.shape, args.repeat, quiet, args.block)
        rows += build_rows(res["build"], data, args.repeat)
    fr = s = None
    if "frames" in parts or "peers" in parts:
        _log(quiet, "forest for the fly-through")
        vd = ViewDependentFanCloud.build(fc)
        cams = terrain_path(vd.bounds(), n_frames)
        d_max = vd.default_d_max(cams[0])
        _log(quiet, f"frames: {n_frames} cameras, e_max {e_max:g} m")
        fr = run_frames(vd, cams, e_max, d_max, quiet)
        s = frame_summary(fr, fc.n_points)
        res["frames"] = {**fr, "summary": s}
        if "frames" in parts:
            _log(quiet, "frames again, superfluous triangles removed")
            lean = frame_summary(run_frames(vd, cams, e_max, d_max, quiet, True),
                                 fc.n_points)
            res["frames"]["superfluous"] = lean
            _log(quiet, "frames again, every front kernel on one thread")
            import fancloud_vtk.core.vdfc as vdfc_module

            saved = vdfc_module.PARALLEL_FRONT
            vdfc_module.PARALLEL_FRONT = 2**62  # never split: the serial path, same result
            try:
                res["frames"]["serial"] = frame_summary(
                    run_frames(vd, cams, e_max, d_max, quiet), fc.n_points)
            finally:
                vdfc_module.PARALLEL_FRONT = saved
    render = None
    if "frames" in parts:
        if args.render_frames:
            _log(quiet, f"render: flythrough of {args.render_frames} frames")
            render = run_render(vd, cams, e_max, d_max, args.render_frames,
                                os.path.join(args.out, "frames"))
            res["render"] = render
        rows += frame_rows(fr, s, data, render, res["frames"].get("superfluous"),
                           res["frames"].get("serial"))
        notes += phase_notes(fr["phases"], n_frames)
    if "merges" in parts:
        _log(quiet, "merges: entropy merges against half-edge collapses, folded fans")
        if fr is None:
            vd = ViewDependentFanCloud.build(fc)
            cams = terrain_path(vd.bounds(), n_frames)
            d_max = vd.default_d_max(cams[0])
        merges = run_merges(fc, vd, cams, e_max, d_max)
        merges["sse"] = merges_sse(fc, merges.pop("forests"), heights, spacing, origin, cams,
                                   e_max, d_max, args.cameras, args.samples, args.seed)
        res["merges"] = merges
        rows += merge_rows(merges, data, e_max)
    pr = None
    if "peers" in parts:
        _log(quiet, f"peers: {args.cameras} cameras")
        pr = run_peers(vd, fc, heights, spacing, origin, cams, fr, s, args.cameras,
                       args.samples, args.seed, quiet)
        rows += peer_rows(pr, data, args.cameras)
        res["peers"] = {k: v for k, v in pr.items() if k != "views"}
        notes.append(
            "peers: the whole terrain reduced to the fronts' mean triangle count by "
            "vtkGreedyTerrainDecimation (SetErrorMeasureToNumberOfTriangles, on the height "
            "image) and fast_simplification.simplify(points, grid triangles, target_count); "
            "the screen-space error (SSE) of a point: |height of the drawn surface at its (x, y) "
            "- its height| / its distance to the eye, the surface's triangles rasterised onto "
            "the grid (the same code for the three); where triangles overlap, the nearest "
            "layer ('worst layer': the farthest)")
    res["elapsed"] = time.perf_counter() - t_start
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    res["load_average_end"] = load
    notes.insert(0, "load average at the end " + (", ".join(f"{x:.2f}" for x in load) if load
                                                  else "unknown"))
    if fr is not None:
        notes.insert(1, f"e_max {e_max:g} m" + (
            ": chosen so that the 1000 x 1000 terrain's front holds a few per cent of the "
            "points (about 3% on average)" if args.data == "jacksboro" and args.e_max is None
            else " (given)" if args.e_max is not None else
            ": Jacksboro's 20 m scaled by the ground's diagonal (the default)"))
    res["rows"] = rows
    text = markdown("fancloud bench vdfc: view-dependent fan clouds (paper section 8)", res,
                    rows, notes)
    if pr is not None:
        text += "\n".join(["", f"## Screen-space error at {pr['budget']:,} triangles", "",
                           *peer_table(pr)]) + "\n"
    if render is not None and render.get("rows"):
        mid = render["rows"][len(render["rows"]) // 2]["frame"]
        text += "\n".join(["", "## A frame of the fly-through", "",
                           f"![frame {mid}](frames/frame_{mid:04d}.png)", ""])
    written += write_outputs(args.out, "vdfc", text, res)
    if fr is not None:
        written.append(_frames_csv(fr, os.path.join(args.out, "vdfc_frames.csv")))
    if "frames" in parts:
        written.append(frames_chart(fr, s, os.path.join(args.out, "vdfc_frames.png"), data))
        if render is not None and render.get("rows"):
            written.append(f"{render['dir']}/frame_*.png ({len(render['rows'])})")
        elif render is not None:
            written.append(f"(frames not rendered: {render['error']})")
    if pr is not None:
        try:
            written.append(render_peers(vd, pr, cams, fr, os.path.join(args.out,
                                                                       "vdfc_peers.png")))
        except Exception as exc:  # an offscreen render can fail on a machine without GL
            written.append(f"(vdfc_peers.png not rendered: {type(exc).__name__}: {exc})")
    print(text)
    print("written: " + ", ".join(written))
    return res


def run_object(args, argv: list[str], parts: list[str], n_frames: int) -> dict:
    """``bench vdfc`` on a scanned object (a point set): the build and frames parts, the
    cameras on :func:`orbit_path`. The peers and merges parts measure the screen-space
    error on a height field's grid: not on an object."""
    from fancloud_vtk import ViewDependentFanCloud, build_fans

    t_start = time.perf_counter()
    quiet = args.quiet
    skipped = [p for p in parts if p not in ("build", "frames")]
    parts = [p for p in parts if p in ("build", "frames")]
    if not parts:
        raise ValueError(f"--data {args.data} is a point set: only the parts build and "
                         "frames run on it (peers and merges need a height field)")
    _warm(quiet)
    points, data = scanned_object(args.data)
    e_max = args.e_max if args.e_max is not None else object_e_max(points)
    res = {**header(["vdfc", *argv]),
           "args": {"part": parts, "data": args.data, "repeat": args.repeat,
                    "frames": n_frames, "e_max": e_max, "render_frames": args.render_frames,
                    "seed": args.seed},
           "data": data, "build": None, "frames": None, "render": None, "peers": None,
           "merges": None}
    rows, notes, written = [], [], []
    if "build" in parts:
        _log(quiet, f"build: {data}")
        res["build"] = measure_point_build(points, args.repeat, quiet)
        rows += point_build_rows(res["build"], data, args.repeat)
    if "frames" in parts:
        fc = build_fans(points)
        vd = ViewDependentFanCloud.build(fc)
        cams = orbit_path(vd.bounds(), n_frames)
        d_max = vd.default_d_max(cams[0])
        _log(quiet, f"frames: {n_frames} cameras round the object, e_max {e_max:g}")
        fr = run_frames(vd, cams, e_max, d_max, quiet)
        fr.update(path="orbit_path", unit="units")
        s = frame_summary(fr, fc.n_points)
        lean = frame_summary(run_frames(vd, cams, e_max, d_max, quiet, True), fc.n_points)
        res["frames"] = {**fr, "summary": s, "superfluous": lean}
        render = None
        if args.render_frames:
            render = run_render(vd, cams, e_max, d_max, args.render_frames,
                                os.path.join(args.out, "frames"))
            res["render"] = render
        rows += frame_rows(fr, s, data, render, lean)
        notes += phase_notes(fr["phases"], n_frames)
        notes.insert(0, f"e_max {e_max:g} units" + (
            " (given)" if args.e_max is not None else
            ": Jacksboro's 20 m in its 43.7 km ground diagonal, as a fraction of the "
            "object's bounding-box diagonal (the default)"))
    if skipped:
        notes.append(f"not run on a point set: {', '.join(skipped)} (the screen-space error "
                     "is measured on a height field's grid); points under no triangle are "
                     "not measured on an object either")
    res["elapsed"] = time.perf_counter() - t_start
    res["rows"] = rows
    text = markdown("fancloud bench vdfc: view-dependent fan clouds (paper section 8)", res,
                    rows, notes)
    written += write_outputs(args.out, "vdfc", text, res)
    if res["frames"] is not None:
        written.append(_frames_csv(res["frames"], os.path.join(args.out, "vdfc_frames.csv")))
        written.append(frames_chart(res["frames"], res["frames"]["summary"],
                                    os.path.join(args.out, "vdfc_frames.png"), data))
    print(text)
    print("written: " + ", ".join(written))
    return res


def _frames_csv(fr: dict, path: str) -> str:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(fr["frames"][0]))
        w.writeheader()
        w.writerows(fr["frames"])
    return path


def _cmd_vdfc(args, argv) -> int:
    run_vdfc(args, argv)
    return 0


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``vdfc`` on the subparsers of ``fancloud bench``."""
    p = sub.add_parser(
        "vdfc", help="view-dependent fan clouds: forest build, fly-through, screen-space error",
        description="On a height field (the Jacksboro DEM by default): the forest's build "
                    "time against build_fans; a fly-through's front update time, active "
                    "points and triangles per point; "
                    "the screen-space error of the fronts against vtkGreedyTerrainDecimation "
                    "and fast-simplification at the same triangle count. Writes vdfc.md, "
                    "vdfc.json, vdfc_frames.csv, vdfc_frames.png, frames/*.png and "
                    "vdfc_peers.png.")
    p.add_argument("--part", nargs="+", choices=PARTS, default=list(PARTS),
                   help="which parts to run (default: %(default)s)")
    p.add_argument("--n", type=int, default=None,
                   help=f"side of the terrain grid, n x n points (default: {DEFAULT_N}; "
                        f"--quick: {QUICK_N})")
    p.add_argument("--block", type=int, default=None,
                   help="block side in grid cells for the blocked build (default: an eighth "
                        "of the grid's side, 125 at 1000: a block's merge tables, about 4 MB, "
                        "stay in the cache; 2 x 2 blocks are timed as well)")
    p.add_argument("--repeat", type=int, default=2,
                   help="timed runs of the build part, best kept (default: %(default)s)")
    p.add_argument("--frames", type=int, default=None,
                   help=f"cameras of the fly-through (default: {DEFAULT_FRAMES}; --quick: "
                        f"{QUICK_FRAMES})")
    p.add_argument("--data", choices=TERRAINS + OBJECTS, default="jacksboro",
                   help="the height field (default: %(default)s; topobathy: matplotlib's "
                        "other DEM; fractal: a fractional Brownian surface of --seed), or a "
                        "scanned object as a point set (bunny: the build and frames parts, "
                        "cameras circling it)")
    p.add_argument("--e-max", type=float, default=None,
                   help=f"the front's e_max in metres at d_max, the range of sight (default: "
                        f"{DEFAULT_E_MAX:g} on Jacksboro, about 3%% of the points active at n = "
                        f"1000; on other data the same fraction of the ground's diagonal)")
    p.add_argument("--render-frames", type=int, default=10,
                   help="frames rendered to PNG by flythrough, 640 x 480, 0: none "
                        "(default: %(default)s)")
    p.add_argument("--cameras", type=int, default=5,
                   help="cameras of the screen-space error comparison (default: %(default)s)")
    p.add_argument("--samples", type=int, default=200_000,
                   help="original points in view sampled per camera for the screen-space "
                        "error (default: %(default)s)")
    p.add_argument("--quick", action="store_true",
                   help=f"smoke run: --n {QUICK_N}, --frames {QUICK_FRAMES} (unless given)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--out", default="bench_out", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_vdfc)
    return p
