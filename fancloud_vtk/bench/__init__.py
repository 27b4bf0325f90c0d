"""``fancloud bench``: benchmarks, each a subcommand writing a Markdown table and raw JSON.

``fancloud bench fans [--sizes 100k,1M,4M] [--repeat 3] [--out bench_out] [--quick]``
    Fan construction: speed against a peer baseline (a scipy ``cKDTree``
    build plus a 7-nearest-neighbour query of every point), peak memory,
    the size of the fan cloud, the first-call (numba compile) time, the
    fraction of open fans on closed surfaces, and whether the rings are
    bit-identical whatever the number of threads. Writes ``fans.md`` (also
    printed) and ``fans.json`` to ``--out`` (:mod:`fancloud_vtk.bench.fans`).

``fancloud bench mesh [--data bunny sphere 1M ...] [--methods ...] [--timeout 600]``
    Triangle meshes from the same points: this project (``build_fans`` +
    ``fan_cloud_to_mesh``) against MeshLib's ``triangulatePointCloud``,
    pymeshlab's ball pivoting and screened Poisson, and VTK's
    ``vtkSurfaceReconstructionFilter``. Per method: time, triangles per point,
    non-manifold edges and vertices, boundary edges, holes, self-intersecting
    triangle pairs, unused points and the distance to the reference surface;
    our stage counts beside the paper's. Each method runs in its own process
    with a timeout (:mod:`fancloud_vtk.bench.harness`): a missing, failing,
    crashing or hanging method is a row saying so. Writes ``mesh.md`` (also
    printed), ``mesh.json`` and ``mesh.png`` (one bar panel per metric).
    ``--data corpus-small`` / ``corpus`` (:mod:`fancloud_vtk.corpus`): real
    models, resamplings and simulated range scans, each against its own
    mesh, with a table per entry (self-intersecting faces, unused points and
    outliers, boundary and non-manifold counts, distances in median
    spacings) and a render ``corpus_NAME.png`` of its worst regions.

``fancloud bench reduce [--data bunny bone 1M ...] [--keep 0.42 0.176] [--quick]``
    Reduction at equal vertex counts: ``reduce`` against fast-simplification,
    pymeshlab's quadric edge collapse and Poisson-disk points, and VTK's
    ``vtkQuadricDecimation``; time, Hausdorff, feature and colour error
    (:mod:`fancloud_vtk.bench.reduce`). Writes ``reduce.md`` (also printed),
    ``reduce.json``, ``reduce_curves.png`` and ``reduce_bunny.png``.

``fancloud bench refine [--part speed cycles] [--n 100000] [--cycles 10] [--quick]``
    Refinement (:mod:`fancloud_vtk.bench.refine`): ``refine`` n -> 2n points
    against ``build_fans`` of 2n points in the same process, and the paper's
    Figure 12 (the bunny reduced to half and refined back, ten times:
    Hausdorff distance and volume per cycle). Writes ``refine.md`` (also
    printed), ``refine.json``, ``refine_cycles.png`` and
    ``refine_cycles_error.png``.

``fancloud bench vdfc [--part build frames peers] [--n 1000] [--frames 300] [--e-max 20]``
    View-dependent fan clouds (:mod:`fancloud_vtk.bench.vdfc`) on the
    Jacksboro DEM (1000 x 1000: a million points): the forest's build time
    against ``build_fans``; a fly-through's front update time, active points
    and triangles per point; the screen-space error of the fronts against
    ``vtkGreedyTerrainDecimation`` and fast-simplification at the same
    triangle count. Writes ``vdfc.md`` (also printed), ``vdfc.json``,
    ``vdfc_frames.csv``, ``vdfc_frames.png``, ``frames/frame_*.png`` and
    ``vdfc_peers.png``.

``fancloud bench tiles [--sizes 1M,10M] [--tiles 2,2,2] [--workers 2]``
    The fans of a large cloud in tiles on Dask (:func:`fancloud_vtk.tiled_fans`)
    against ``build_fans`` in one process (:mod:`fancloud_vtk.bench.tiles`):
    wall time, throughput, peak memory of the process and of each worker of
    a LocalCluster, and whether the fan cloud is the same. Writes
    ``tiles.md`` and ``tiles.json``.

``fancloud bench compile [--command "demo -q --out {tmp}"] [--repeat 1]``
    What a new user waits for once: the command (by default the demo) run
    twice in fresh processes with an empty numba cache of its own; the
    first run compiles the kernels, the second loads them
    (:mod:`fancloud_vtk.bench.compile`). Writes ``compile.md`` and
    ``compile.json``.

Everything in the tables is measured in the run; only the targets (the
issue's figures) are constants. Measurements that need a fresh process
(first call, memory, thread counts, the peers) run in subprocesses of the
same Python (:mod:`fancloud_vtk.bench.harness`). Every result JSON starts
with the machine, the software, the commit, the command and the date
(:func:`fancloud_vtk.bench.report.header`).

The package: :mod:`~fancloud_vtk.bench.common` (sizes, synthetic points),
:mod:`~fancloud_vtk.bench.harness` (subprocesses and timing),
:mod:`~fancloud_vtk.bench.metrics` (the measures, importable on their own),
:mod:`~fancloud_vtk.bench.peers` (the compared methods),
:mod:`~fancloud_vtk.bench.report` (tables, Markdown, JSON and their header), and
one module per benchmark, each registering its subcommand (``add_parser``) in
:func:`make_parser`. Nothing here imports :mod:`fancloud_vtk.cli` or
:mod:`fancloud_vtk.demo`.
"""

from __future__ import annotations

import argparse
import sys

from fancloud_vtk.bench.common import (
    WARMUP_POINTS,
    K,
    parse_size,
    parse_sizes,
    size_label,
    surface_points,
)

__all__ = ["K", "WARMUP_POINTS", "main", "make_parser", "parse_size", "parse_sizes",
           "size_label", "surface_points"]

#: The benchmarks, in the order of ``fancloud bench --help``: modules with ``add_parser(sub)``.
BENCHMARKS = ("fans", "mesh", "reduce", "refine", "vdfc", "tiles", "compile")


def make_parser() -> argparse.ArgumentParser:
    """``fancloud bench MODE ...``: one subcommand per benchmark (:data:`BENCHMARKS`)."""
    import importlib

    parser = argparse.ArgumentParser(prog="fancloud bench", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    for name in BENCHMARKS:
        importlib.import_module(f"{__name__}.{name}").add_parser(sub)
    return parser


def main(argv=None) -> int:
    """Run a benchmark: ``main(['fans', '--sizes', '100k,1M'])``.

    An option's value may start with ``-`` (``--e-max -1e3``, ``--out -1,2``): it is
    joined to its option as in the ``fancloud`` command
    (:func:`fancloud_vtk._argv.join_negative_values`).
    """
    from fancloud_vtk._argv import join_negative_values

    argv = list(sys.argv[1:] if argv is None else argv)
    parser = make_parser()
    args = parser.parse_args(join_negative_values(parser, argv))
    if args.repeat < 1:
        raise ValueError("--repeat must be at least 1")
    if args.mode == "mesh" and (args.timeout <= 0 or args.samples < 0):
        raise ValueError("--timeout must be positive and --samples not negative")
    return args.func(args, argv[1:])
