"""Compile the numba kernels once, before the test workers start.

On a fresh clone the kernels are not yet in numba's on-disk cache, and compiling them all
takes minutes of CPU. Left to the tests, each xdist worker, each command the tests start
and each LocalCluster worker compiles the kernels it meets, several at once, the same ones
twice. Run by ``conftest.py`` in the xdist controller, before the workers start: two
processes at once on small data, the fans then the mesh stages in one, and in the other
what needs no point fans (terrain VDFC, the reduction of a mesh) then the reduction,
refinement and VDFC of point fans, whose fan kernels the first has cached by then. The
tests then load the kernels from the cache.
Usage: ``python tests/warm_kernels.py [PART[+PART...]]`` (parts: fans, mesh, levels;
none: the whole warm-up).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import warnings


def _sphere(n, seed=0):
    import numpy as np

    p = np.random.default_rng(seed).normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1)[:, None]


def fans() -> None:
    from fancloud_vtk import build_fans
    from fancloud_vtk.data import bunny_path
    from fancloud_vtk.io import read_point_cloud

    build_fans(_sphere(2000))
    build_fans(_sphere(2000), separate_sheets=True)
    build_fans(read_point_cloud(bunny_path()).points[:3000])


def mesh() -> None:
    import numpy as np

    from fancloud_vtk import build_fans, fan_cloud_to_mesh, tiled_mesh
    from fancloud_vtk.corpus import distance_to_mesh, model, range_scan

    p = _sphere(3000, 1)
    open_patch = p[p[:, 2] > -0.5]  # a hole to fill or keep
    for pts in (p, open_patch):
        fc = build_fans(pts)
        for rings in ("delaunay", "local", "fans"):
            fan_cloud_to_mesh(fc, rings=rings)
    cow = model("cow")
    scan = range_scan(cow.ref_points, cow.ref_triangles, seed=1, resolution=(64, 64))
    fan_cloud_to_mesh(build_fans(scan.points))
    distance_to_mesh(scan.points[:100], cow.ref_points, cow.ref_triangles)
    tiled_mesh(np.ascontiguousarray(p), tiles=(2, 1, 1), scheduler="sync")


def levels() -> None:
    from scipy.spatial import ConvexHull

    from fancloud_vtk import (
        ViewDependentFanCloud,
        build_fans,
        fan_cloud_of_mesh,
        hierarchy,
        reduce,
        refine,
        terrain_blocks,
        terrain_fan_cloud,
    )
    from fancloud_vtk.core.reduction import laplacian_smooth
    from fancloud_vtk.data import jacksboro_terrain

    # first what needs no point fans (the other process compiles those meanwhile)
    heights, spacing, _ = jacksboro_terrain()
    heights = heights[:60, :60]
    t = terrain_fan_cloud(heights, spacing)
    vd = ViewDependentFanCloud.build(t, blocks=terrain_blocks(heights.shape, (30, 30)))
    lo, hi = t.points.min(axis=0), t.points.max(axis=0)
    eye = (lo[0], lo[1], hi[2] + 500.0)
    camera = (eye, tuple((lo + hi) / 2), (0.0, 0.0, 1.0), 50.0, 4 / 3)
    vd.front_arrays(camera, 40.0)
    s = _sphere(1000, 3)
    hull = ConvexHull(s)
    for method in ("entropy", "error"):
        reduce(fan_cloud_of_mesh(s, hull.simplices), keep=0.5, method=method)
    fc = build_fans(_sphere(3000, 2))
    reduce(fc, keep=0.5)
    h = hierarchy(fc, 500)
    coarse = laplacian_smooth(h.level(500), 2)
    h.selective(((0.0, 0.0, 1.0), 0.5), base=coarse)
    refine(reduce(fc, keep=0.3), factor=2)
    vd = ViewDependentFanCloud.build(fc)
    vd.front_arrays(((0.0, -4.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 50.0, 4 / 3), 0.01)


PARTS = {"fans": fans, "mesh": mesh, "levels": levels}


def _run(parts: str) -> None:
    for part in parts.split("+"):
        t0 = time.perf_counter()
        PARTS[part]()
        print(f"{part} {time.perf_counter() - t0:.1f} s", file=sys.stderr)


def warm(python: str = sys.executable) -> tuple[float, str]:
    """The fans and the mesh in one process, the levels in another at once; returns the
    seconds it took and each part's. A part that fails leaves its kernels to the tests
    (and says so)."""
    t0 = time.perf_counter()
    here = os.path.abspath(__file__)

    def start(part):
        return subprocess.Popen([python, here, part], stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)

    parts = []

    def wait(proc, part):
        _, err = proc.communicate()
        lines = err.strip().splitlines()
        parts.extend(x for x in lines if x.split(" ")[0] in PARTS and x.endswith(" s"))
        if proc.returncode:
            print(f"warm_kernels: {part} failed ({lines[-1:]})", file=sys.stderr)

    procs = [(start(part), part) for part in ("fans+mesh", "levels")]
    for proc, part in procs:
        wait(proc, part)
    return time.perf_counter() - t0, ", ".join(parts)


if __name__ == "__main__":
    warnings.simplefilter("ignore")
    _run(sys.argv[1]) if len(sys.argv) > 1 else print("{:.1f} s ({})".format(*warm()))
