"""The ``fancloud`` command: a front that reads, forwards and writes.

``fancloud fans IN -o OUT.vtp [--k 6 ...]``
    Build the fan cloud of a point cloud or mesh file.
``fancloud mesh IN -o OUT.{ply,obj,vtp,stl} [...]``
    Triangle mesh (paper section 4) of a fan cloud .vtp or of any point cloud.
``fancloud entropy IN -o OUT.vtp [--weights a1,a2,a3,a4] [...]``
    The entropy of every point (paper section 5) as point arrays.
``fancloud reduce IN -o OUT (--keep F | --n N) [--weights ...] [--method entropy|error] [--mesh]``
    Reduction by entropy to an exact number of points (paper section 5).
``fancloud refine IN -o OUT (--factor F | --n N) [--weights ...] [--mesh]``
    Refinement beyond the input resolution (paper section 7).
``fancloud selective IN -o OUT.vtp (--keep F | --n N) --region-center X,Y,Z --region-radius R``
    Reduce, smooth the coarse level (``--smooth-iterations S``) and reinsert only
    the points of a region of interest (a sphere, or ``--region box
    --region-bounds ...``; paper section 6, Figure 11).
``fancloud vdfc IN (--camera C -o frame.png|front.vtp | --flythrough DIR) [--e-max E]``
    The view-dependent fan cloud (paper section 8): its front for a camera, or
    a fly-through with per-frame front sizes and update times.
``fancloud demo [--out DIR]``
    The main job on built-in data: the fan cloud of the Stanford bunny shipped
    with pymeshlab, its triangle mesh, its reductions, selective refinement and
    refinement; then the view-dependent fan cloud of matplotlib's Jacksboro
    fault DEM (the terrain panel). Everything written and rendered offscreen
    to PNG in DIR.
``fancloud bench fans [...]``
    The benchmark of fan construction (see ``fancloud bench fans --help``).
``fancloud --version``
    The version.

An option's value may start with ``-`` (``--region-center -0.1,0.3,0.7``,
``--camera "-3,0,0;0,0,0;0,0,1;40"``): see
:func:`fancloud_vtk._argv.join_negative_values`.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

from fancloud_vtk import __version__
from fancloud_vtk._argv import join_negative_values as _join_negative_values
from fancloud_vtk._argv import value_options as _value_options  # noqa: F401  (tests)
from fancloud_vtk._console import (  # noqa: F401  (_Progress: tests and the demo use it)
    _dropped,
    _print_mesh_summary,
    _print_rows,
    _print_summary,
    _Progress,
)
from fancloud_vtk.params import VERB_PARAMS, Param, check_params


def _vector(size: int):
    """argparse type: ``'1,1,50,0'`` -> (1.0, 1.0, 50.0, 0.0)."""

    def parse(text: str) -> tuple:
        try:
            values = tuple(float(v) for v in text.split(","))
        except ValueError:
            msg = f"not {size} comma-separated numbers: {text!r}"
            raise argparse.ArgumentTypeError(msg) from None
        if len(values) != size:
            raise argparse.ArgumentTypeError(f"need {size} comma-separated numbers, got {text!r}")
        return values

    parse.__name__ = f"{size} comma-separated numbers"
    return parse


def _add_params(parser: argparse.ArgumentParser, table: tuple[Param, ...], flags=None) -> None:
    """Options derived from a parameter table (``flags``: other option strings by name)."""
    flags = flags or {}
    for p in table:
        names = flags.get(p.name, (p.cli_flag,))
        doc = p.doc.replace("%", "%%")  # argparse formats help strings with %
        if p.kind == "vector":
            parser.add_argument(*names, dest=p.name, type=_vector(p.size), default=p.default,
                                metavar=",".join(["X"] * p.size),
                                help=f"{doc} (default: {','.join(map(str, p.default))})")
        elif p.kind == "str":
            parser.add_argument(*names, dest=p.name, default=p.default,
                                help=f"{doc} (default: {p.default!r})")
        elif p.kind == "bool":
            parser.add_argument(
                p.cli_flag, dest=p.name, default=p.default,
                action=argparse.BooleanOptionalAction, help=f"{doc} (default: {p.default})",
            )
        else:
            kind = {"int": int, "float": float, "choice": str}[p.kind]
            parser.add_argument(
                *names, dest=p.name, type=kind, default=p.default, choices=p.choices,
                help=f"{doc} (default: {p.default})",
            )


def _params(args, table) -> dict:
    return {p.name: getattr(args, p.name) for p in table}


def _quiet_offscreen_rendering() -> None:
    """Keep VTK's log on stderr to errors before rendering offscreen.

    Without a display VTK logs warnings such as ``vtkXOpenGLRenderWindow ... WARN| bad X
    server connection. DISPLAY=`` and renders offscreen all the same; a command prints its
    own messages only. (For the command-line process: nothing is restored.)
    """
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)


def _read_source(path: str):
    """A file as the verbs' :class:`~fancloud_vtk.core.verbs.Source`: a fan cloud ``.vtp``
    as it is; any other point cloud or mesh file as its points, ``Normals``, other point
    arrays and triangles (if it has faces)."""
    from fancloud_vtk.core.verbs import Source
    from fancloud_vtk.io import read_point_cloud

    if path.lower().endswith(".vtp"):
        from fancloud_vtk.algorithms.convert import fancloud_from_vtk, is_fancloud, read_vtp
        from fancloud_vtk.io import FileReadError

        try:
            data = read_vtp(path)
        except ValueError as exc:  # (a missing file is an OSError: it passes)
            reason = str(exc).removeprefix(f"could not read {path}: ")
            raise FileReadError(path, reason) from None
        if is_fancloud(data):
            return Source(fancloud=fancloud_from_vtk(data))
    src = read_point_cloud(path)
    data = dict(src.point_data)
    normals = data.pop("Normals", None)
    faces = src.faces if src.faces is not None and len(src.faces) else None
    return Source(points=src.points, normals=normals, point_data=data, triangles=faces)


def _run_verb(verb: str, args, values: dict, amount: dict | None = None, write=None):
    """Read ``args.input``, run the verb on it and ``write(result)``, under one progress bar
    (reading, the verb's stages, writing); (result, read time, verb time). ``values``: the
    verb's options; ``amount``: the amount options as given."""
    from fancloud_vtk.core import verbs

    if amount is not None:  # keep/factor or n_points: exactly one was given (argparse)
        values = {**values, "n_points": amount.get("n_points") or 0,
                  **{k: v for k, v in amount.items() if k != "n_points" and v is not None}}
    values = verbs.check_values(verb, values)
    progress = _Progress(verb, args.quiet)
    try:
        progress(0.0, f"read {os.path.basename(args.input)}")
        t0 = time.perf_counter()
        source = _read_source(args.input)
        t1 = time.perf_counter()
        result = verbs.VERBS[verb](source, values, lambda f, m: progress(0.1 + 0.8 * f, m))
        t2 = time.perf_counter()
        if write is not None:
            progress(0.9, f"write {os.path.basename(args.output)}")
            write(result)
            progress(1.0, "done")
    finally:
        progress.close()
    return result, t1 - t0, t2 - t1


def _input_row(kind: str, fc, n_points=None, dropped=None) -> tuple[str, str]:
    """The summary row of the input: its kind, points and dropped unreferenced vertices
    (of the fan cloud ``fc``, or ``n_points`` and ``dropped`` when ``fc`` is None)."""
    if fc is not None:
        n_points, dropped = fc.n_points, _dropped(fc)
    more = f" ({dropped:,} unreferenced vertices dropped)" if dropped else ""
    return "input", f"{kind}, {n_points:,} points{more}"


def _check_output(path: str, ext: str | tuple[str, ...]) -> None:
    """Fail before any work when ``path`` cannot be the output (``main`` prints it, exit 2)."""
    exts = (ext,) if isinstance(ext, str) else ext
    if not path.lower().endswith(exts):
        raise ValueError(f"the output must be a {' or '.join(exts)} file, got {path!r}")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"cannot write {path!r}: no such directory {folder!r}")


def _parse_tiles(text: str):
    """``--tiles``: "auto" or "X,Y,Z" (tiles along each axis)."""
    if text == "auto":
        return "auto"
    try:
        t = tuple(int(v) for v in text.split(","))
    except ValueError:
        t = ()
    if len(t) != 3 or min(t) < 1:
        raise argparse.ArgumentTypeError(f"expected 'auto' or three positive integers X,Y,Z, "
                                         f"got {text!r}")
    return t


def cmd_fans_tiled(args) -> int:
    """``fancloud fans BIG -o OUTDIR --tiles ...``: the fan cloud in tiles on Dask, the input
    read in chunks, one ``.vtp`` per tile plus ``index.json`` and ``fans.vtpd``."""
    from fancloud_vtk.distributed import write_tiled_fans

    values = _params(args, VERB_PARAMS["fans"])
    _check_scheduler(args)
    if os.path.exists(args.output) and not os.path.isdir(args.output):
        raise ValueError(f"with --tiles the output is a folder, and {args.output!r} is a file")
    if args.input.lower().endswith((".obj", ".vtp", ".vtk", ".vtu", ".stl")) \
            or args.input.lower().endswith(".ply") and _ply_has_faces(args.input):
        warnings.warn(f"{os.path.basename(args.input)}: with --tiles the points and their "
                      "arrays are read, not faces: vertices that no face uses are kept",
                      UserWarning, stacklevel=2)
    fan_options = {key: values[key] for key in ("k", "max_angle", "max_replacements", "rule",
                                                "rotate_sharp_edges", "reach",
                                                "separate_sheets")}
    progress = _Progress("fans in tiles", args.quiet)
    t0 = time.perf_counter()
    try:
        index = write_tiled_fans(args.input, args.output, tiles=args.tiles,
                                 tile_points=args.tile_points, scheduler=args.scheduler,
                                 workers=args.workers, chunk=args.chunk, progress=progress,
                                 **fan_options)
    finally:
        progress.close()
    elapsed = time.perf_counter() - t0
    if not args.quiet:
        tiles = index["tile_list"]
        n = index["n_points"]
        n_open = sum(t["open"] for t in tiles)
        _print_rows([
            ("points", f"{n:,}"),
            ("tiles", "x".join(str(v) for v in index["tiles"])
             + f" ({sum(1 for t in tiles if t['file'])} written)"),
            ("points per tile", f"{max(t['owned'] for t in tiles):,} at most"),
            ("halo", f"{min(t['halo'] for t in tiles):.4g} to {max(t['halo'] for t in tiles):.4g}"),
            ("duplicates merged", f"{index['duplicates_merged']:,}"),
            ("fans open", f"{n_open:,} "
             f"({100 * n_open / max(n - index['duplicates_merged'], 1):.2f}%)"),
            ("tiles flipped", f"{sum(t['flipped'] for t in tiles):,}"),
            ("point arrays", ", ".join(index["point_arrays"]) or "none"),
            ("time", f"{elapsed:.2f} s"),
            ("written", os.path.join(args.output, "index.json") + " (+ fans.vtpd, tile_*.vtp)"),
        ])
    return 0


def cmd_fans(args) -> int:
    from fancloud_vtk.algorithms.convert import fancloud_to_vtk, write_vtp

    if args.tiles is not None:
        return cmd_fans_tiled(args)
    _tiles_only(args)
    _check_output(args.output, ".vtp")
    result, _, elapsed = _run_verb(
        "fans", args, _params(args, VERB_PARAMS["fans"]),
        write=lambda r: write_vtp(fancloud_to_vtk(r.fancloud), args.output))
    if not args.quiet:
        _print_summary(result.fancloud, elapsed, args.output)
    return 0


def cmd_mesh(args) -> int:
    from fancloud_vtk.algorithms.convert import MESH_FORMATS, result_to_vtk, write_mesh

    if args.tiles is not None:
        return cmd_mesh_tiled(args)
    _tiles_only(args)
    _check_output(args.output, MESH_FORMATS)
    result, t_read, t_mesh = _run_verb(
        "mesh", args, _params(args, VERB_PARAMS["mesh"]),
        write=lambda r: write_mesh(result_to_vtk(r, mark=False), args.output))
    if not args.quiet:
        dropped = result.unreferenced_dropped
        extra = [("unreferenced dropped", f"{dropped:,}")] if dropped else []
        _print_mesh_summary(result.mesh, t_read + t_mesh, args.output, extra)
    return 0


def cmd_entropy(args) -> int:
    from fancloud_vtk.algorithms.convert import source_to_vtk, write_vtp
    from fancloud_vtk.algorithms.entropy import entropy_output
    from fancloud_vtk.core.verbs import KIND_MESH

    _check_output(args.output, ".vtp")

    def write(result):
        # a mesh file whose vertices all stay: the mesh with the arrays, as the filter gives
        source = result.input
        keeps_input = result.kind == KIND_MESH and result.source.n_points == len(source.points)
        write_vtp(entropy_output(result, source_to_vtk(source) if keeps_input else None),
                  args.output)

    result, t_read, t_ent = _run_verb("entropy", args, _params(args, VERB_PARAMS["entropy"]),
                                      write=write)
    fc, ent = result.source, result.entropy
    if not args.quiet:
        rows = [_input_row(result.kind, fc), ("weights", str(ent.weights)),
                ("mean neighbour distance", f"{ent.mean_distance:.6g}")]
        for name, arr in ent.as_dict().items():
            rows.append((name, f"min {arr.min():.4g}  mean {arr.mean():.4g}  max {arr.max():.4g}"))
        rows += [("time", f"{t_read + t_ent:.2f} s"), ("written", args.output)]
        _print_rows(rows)
    return 0


def _vdfc_options() -> tuple:
    """``fancloud vdfc``'s options from its table: the aspect comes from --size."""
    return tuple(p for p in VERB_PARAMS["vdfc"] if p.name != "aspect")


def _amount_options(verb: str) -> tuple:
    """The verb's options but its amount (--keep | --factor | --n: a group of their own)."""
    return tuple(p for p in VERB_PARAMS[verb] if p.name not in ("keep", "factor", "n_points"))


#: what ``fancloud reduce --tiles`` passes to tiled_reduce (the others must keep their default)
TILED_REDUCE_OPTIONS = ("k", "max_angle", "max_replacements", "rule", "rotate_sharp_edges",
                        "reach", "separate_sheets", "weights", "method", "max_spacing",
                        "error_step")


def cmd_reduce_tiled(args) -> int:
    """``fancloud reduce BIG -o OUT --keep F --tiles ...``: the reduction in blocks on Dask
    (:func:`fancloud_vtk.distributed.tiled_reduce`, the file read in chunks and sorted into
    the blocks' files), written as one fan cloud
    (or, with ``--mesh``, its mesh made in this process)."""
    from fancloud_vtk import fan_cloud_to_mesh
    from fancloud_vtk.algorithms.convert import (
        MESH_FORMATS,
        fancloud_to_vtk,
        mesh_to_vtk,
        write_mesh,
        write_vtp,
    )
    from fancloud_vtk.distributed import tiled_reduce

    _check_output(args.output, MESH_FORMATS if args.mesh else ".vtp")
    _check_scheduler(args)
    values = _params(args, _amount_options("reduce"))
    for p in _amount_options("reduce"):
        if p.name not in TILED_REDUCE_OPTIONS and p.name != "mesh" \
                and values[p.name] != p.default:
            raise ValueError(f"--{p.name.replace('_', '-')} does not go with --tiles (the "
                             f"blocks reduce points: {', '.join(TILED_REDUCE_OPTIONS)})")
    if args.input.lower().endswith((".obj", ".vtp", ".vtk", ".vtu", ".stl")) \
            or args.input.lower().endswith(".ply") and _ply_has_faces(args.input):
        warnings.warn(f"{os.path.basename(args.input)}: with --tiles the points are "
                      "reduced, not the mesh (its faces are left out): vertices that no face "
                      "uses are kept", UserWarning, stacklevel=2)
    progress = _Progress("reduce in tiles", args.quiet)
    t0 = time.perf_counter()
    try:  # the file read in chunks; duplicates merged (the first of each kept): original_id
        # gives the file's rows; the file's point arrays go with the kept points
        small = tiled_reduce(args.input, n_points=args.n_points, keep=args.keep,
                             tiles=args.tiles, tile_points=args.tile_points,
                             scheduler=args.scheduler, workers=args.workers, progress=progress,
                             **{name: values[name] for name in TILED_REDUCE_OPTIONS})
    finally:
        progress.close()
    t_reduce = time.perf_counter() - t0
    n = small.info["input_points"]
    rows = [("input", f"points, {n:,}"),
            ("kept", f"{small.n_points:,} ({100 * small.n_points / n:.1f}%)"),
            ("weights", str(tuple(args.weights))), ("method", args.method),
            ("tiles", "x".join(str(v) for v in small.info["tiles"])),
            ("fans built again", f"{small.info['fans_rebuilt']:,}"),
            ("time: reduction in tiles (read included)", f"{t_reduce:.2f} s")]
    if args.mesh:
        mesh = fan_cloud_to_mesh(small)
        write_mesh(mesh_to_vtk(mesh), args.output)
        rows += [("triangles", f"{mesh.n_triangles:,}"), ("holes", f"{mesh.stats['holes']}")]
    else:
        write_vtp(fancloud_to_vtk(small), args.output)
    rows.append(("written", args.output))
    if not args.quiet:
        _print_rows(rows)
    return 0


def cmd_mesh_tiled(args) -> int:
    """``fancloud mesh BIG -o OUT --tiles ...``: the mesh grown in tiles with halos on Dask
    (:func:`fancloud_vtk.distributed.tiled_mesh`), the same mesh as one process's, written
    as one file; the points are read whole."""
    from fancloud_vtk.algorithms.convert import MESH_FORMATS, mesh_to_vtk, write_mesh
    from fancloud_vtk.distributed import _auto_tiles, _client_for, tiled_mesh
    from fancloud_vtk.io import read_point_cloud

    _check_output(args.output, MESH_FORMATS)
    _check_scheduler(args)
    values = _params(args, VERB_PARAMS["mesh"])
    if not values["orient"]:
        raise ValueError("--no-orient does not go with --tiles (the mesh is oriented)")
    if values["rings"] == "fans":
        raise ValueError("--rings fans does not go with --tiles (whether the fans are the "
                         "one-rings of a 2-manifold is a question about all of them)")
    t0 = time.perf_counter()
    src = read_point_cloud(args.input)
    points, data = src.points, dict(src.point_data)
    dropped = 0
    if src.faces is not None and len(src.faces) and not values["keep_unreferenced"]:
        used = np.zeros(len(points), bool)  # the vertices a face uses, as the verb does
        used[src.faces.ravel()] = True
        dropped = int((~used).sum())
        points = points[used]
        data = {name: arr[used] for name, arr in data.items()}
    data.pop("Normals", None)  # the mesh's normals are its own
    t_read = time.perf_counter() - t0
    tiles = args.tiles
    if isinstance(tiles, str):
        tiles = tuple(int(v) for v in _auto_tiles(len(points), points.min(axis=0),
                                                   points.max(axis=0), args.tile_points))
    client, close = _client_for(args.scheduler, args.workers)
    t0 = time.perf_counter()
    try:
        names = ("k", "max_angle", "max_replacements", "rule", "rotate_sharp_edges", "reach",
                 "separate_sheets", "rings", "close_holes", "max_hole", "max_hole_diameter",
                 "remove_self_intersections", "min_component", "self_intersections")
        mesh = tiled_mesh(points, tiles=tiles, scheduler=client, point_data=data,
                          **{name: values[name] for name in names})
    finally:
        if close is not None:
            close()
    t_mesh = time.perf_counter() - t0
    write_mesh(mesh_to_vtk(mesh), args.output)
    if not args.quiet:
        extra = [("unreferenced dropped", f"{dropped:,}")] if dropped else []
        extra += [("tiles", "x".join(str(v) for v in mesh.stats["tiles"])),
                  ("halo", f"{min(mesh.stats['halos']):.4g} to "
                           f"{max(mesh.stats['halos']):.4g}"),
                  ("tiles built again", f"{mesh.stats['rebuilt']:,}")]
        _print_mesh_summary(mesh, t_read + t_mesh, args.output, extra)
    return 0


def _ply_has_faces(path) -> bool:
    """Does the PLY file's header declare a non-empty face element? (A point cloud's does
    not; an unreadable file is left to the reader.)"""
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536)
    except OSError:
        return False
    for line in head.split(b"end_header", 1)[0].splitlines():
        words = line.split()
        if len(words) == 3 and words[0] == b"element" and words[1] == b"face":
            return words[2] != b"0"
    return False


def _check_scheduler(args) -> None:
    """--scheduler is an address (a Dask scheduler name such as 'threads' is not one)."""
    if args.scheduler is not None and "://" not in args.scheduler:
        raise ValueError("--scheduler must be a Dask scheduler address such as "
                         f"tcp://host:8786, got {args.scheduler!r}")


def _tiles_only(args) -> None:
    """The tile options without --tiles: a usage error."""
    for option in ("scheduler", "workers"):
        if getattr(args, option) is not None:
            raise ValueError(f"--{option} goes with --tiles")


def cmd_reduce(args) -> int:
    if args.tiles is not None:
        return cmd_reduce_tiled(args)
    _tiles_only(args)

    def rows(fc, small):
        return [("kept", f"{small.n_points:,} ({100 * small.n_points / fc.n_points:.1f}%)"),
                ("weights", str(tuple(args.weights))), ("method", args.method)]

    return _fan_cloud_verb(args, "reduce", "reduction", {"keep": args.keep}, rows)


def cmd_refine(args) -> int:
    def rows(fc, fine):
        return [("refined", f"{fine.n_points:,} (x{fine.n_points / fc.n_points:.2f})"),
                ("weights", str(tuple(args.weights)))]

    return _fan_cloud_verb(args, "refine", "refinement", {"factor": args.factor}, rows)


def cmd_selective(args) -> int:
    def rows(fc, out):
        added = out.info["reinserted"]
        return [("coarse level", f"{out.n_points - added:,} points"),
                ("smoothing steps", str(args.smooth_iterations)),
                ("reinserted in the region", f"{added:,}"),
                ("result", f"{out.n_points:,} points")]

    return _fan_cloud_verb(args, "selective", "selective refinement", {"keep": args.keep}, rows)


def _fan_cloud_verb(args, verb: str, stage: str, amount: dict, describe) -> int:
    """Run a verb that gives a fan cloud on the input (fan cloud, mesh or points), write the
    result (its mesh with ``--mesh``) and print the summary: the input,
    ``describe(fc, result)``, the times. The options (the amount and the region too) are
    checked before the input is read."""
    from fancloud_vtk.algorithms.convert import (
        MESH_FORMATS,
        result_to_vtk,
        write_mesh,
        write_vtp,
    )
    from fancloud_vtk.core import verbs

    as_mesh = getattr(args, "mesh", False)
    _check_output(args.output, MESH_FORMATS if as_mesh else ".vtp")
    values = _params(args, _amount_options(verb))
    if verb == "selective":
        from fancloud_vtk.core.reduction import target_count

        # the amount (all but "larger than the cloud") and the region, before any work
        target_count(sys.maxsize, n_points=args.n_points, keep=args.keep)
        verbs.region_of(verbs.check_values(verb, values))
    write = write_mesh if as_mesh else write_vtp
    result, t_read, t_verb = _run_verb(verb, args, values,
                                       {"n_points": args.n_points, **amount},
                                       write=lambda r: write(result_to_vtk(r), args.output))
    fc, out = result.source, result.fancloud
    rows = [_input_row(result.kind, fc), *describe(fc, out),
            ("time: read", f"{t_read:.2f} s"), (f"time: {stage}", f"{t_verb:.2f} s")]
    if as_mesh:
        rows += [("triangles", f"{result.mesh.n_triangles:,}"),
                 ("holes", f"{result.mesh.stats['holes']}")]
    rows.append(("written", args.output))
    if not args.quiet:
        _print_rows(rows)
    return 0


def _parse_camera(text: str, aspect: float):
    """``"px,py,pz;fx,fy,fz;ux,uy,uz;angle"`` as a camera tuple."""
    parts = [p.strip() for p in text.split(";")]
    if len(parts) != 4:
        raise ValueError('--camera must be "px,py,pz;fx,fy,fz;ux,uy,uz;angle" (4 groups '
                         f"separated by ';'), got {text!r}")
    vecs = []
    for name, part in zip(("position", "focal point", "view up"), parts[:3], strict=True):
        try:
            v = tuple(float(x) for x in part.split(","))
        except ValueError:
            raise ValueError(f"--camera {name} must be three numbers, got {part!r}") from None
        if len(v) != 3:
            raise ValueError(f"--camera {name} must be three numbers, got {part!r}")
        vecs.append(v)
    try:
        angle = float(parts[3])
    except ValueError:
        raise ValueError(f"--camera view angle must be a number, got {parts[3]!r}") from None
    return (*vecs, angle, aspect)


def _parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size must be WIDTHxHEIGHT, e.g. 800x600, got {text!r}") from None
    if w < 16 or h < 16:
        raise ValueError(f"--size must be at least 16x16, got {text!r}")
    return w, h


def _height_field_npz(path: str, spacing):
    """(heights, spacing) of a height field ``.npz``: its ``elevation``, ``heights``, ...

    or else its first 2-d array; the spacing from ``dx`` and ``dy`` if it has them.
    """
    with np.load(path, allow_pickle=False) as z:
        names = [k for k in ("elevation", "heights", "height", "z") if k in z.files]
        names += [k for k in z.files if z[k].ndim == 2 and k not in names]
        if not names:
            raise ValueError(f"{path} holds no 2-d array of heights")
        heights = np.asarray(z[names[0]], dtype=np.float64)
        if spacing is None and "dx" in z.files and "dy" in z.files:
            spacing = (float(z["dx"]), float(z["dy"]))
    return heights, (1.0, 1.0) if spacing is None else spacing


def _load_forest(args, values):
    """(forest, description) of the ``fancloud vdfc`` input."""
    from fancloud_vtk.core import verbs
    from fancloud_vtk.core.vdfc import FORMAT, ViewDependentFanCloud

    path = args.input
    if path == "jacksboro" or path.lower().endswith(".npz"):
        if path == "jacksboro":
            from fancloud_vtk.data import jacksboro_terrain

            heights, spacing, _ = jacksboro_terrain()
        else:
            if not os.path.isfile(path):
                raise OSError(f"no such file: {path}")
            with np.load(path, allow_pickle=False) as z:
                is_forest = "format" in z.files and str(z["format"]) == FORMAT
            if is_forest:
                vd = ViewDependentFanCloud.load(path)
                return vd, f"saved forest, {vd.n_leaves:,} points"
            heights, spacing = _height_field_npz(path, args.spacing)
        source = verbs.Source(heights=(heights, spacing, (0.0, 0.0)))
        vd = verbs.vdfc(source, values)
        return vd, f"height field {heights.shape[0]} x {heights.shape[1]}"
    vd = verbs.vdfc(_read_source(path), values)
    return vd, _input_row(vd.fancloud_input, None, vd.n_leaves, vd.unreferenced_dropped)[1]


def cmd_vdfc(args) -> int:
    from fancloud_vtk.algorithms.vdfc import e_max_of, flythrough
    from fancloud_vtk.core.vdfc import Camera

    if (args.camera is None) == (args.flythrough is None):
        raise ValueError("give either --camera C with -o frame.png|front.vtp, or --flythrough DIR")
    w, h = _parse_size(args.size)
    camera = _parse_camera(args.camera, w / h) if args.camera is not None else None
    if camera is not None:
        Camera.of(camera)
        if args.output is None:
            raise ValueError("--camera needs -o frame.png or -o front.vtp")
        _check_output(args.output, (".png", ".vtp"))
    values = check_params(VERB_PARAMS["vdfc"], {
        **_params(args, _vdfc_options()), "aspect": w / h})
    t0 = time.perf_counter()
    vd, what = _load_forest(args, values)
    t1 = time.perf_counter()
    if args.save_forest:
        vd.save(args.save_forest)
    e_max = e_max_of(vd, values["e_max"])
    d_max = values["d_max"] or None
    rows = [("input", what), ("forest", f"{vd.n_nodes:,} nodes, {len(vd.roots):,} roots"),
            ("time: forest", f"{t1 - t0:.2f} s"), ("e_max", f"{e_max:.6g}")]
    if camera is not None:
        if args.output.lower().endswith(".vtp"):
            from fancloud_vtk.algorithms.convert import add_unreferenced_field, to_vtk, write_vtp

            front = vd.front_arrays(camera, e_max, d_max, superfluous=values["superfluous"])
            poly = to_vtk(front)
            add_unreferenced_field(poly, getattr(vd, "unreferenced_dropped", None))
            write_vtp(poly, args.output)
            stats = front.stats
            front_ms = 1e3 * stats["seconds"]
        else:
            import shutil
            import tempfile

            _quiet_offscreen_rendering()
            with tempfile.TemporaryDirectory() as tmp:
                row = flythrough(vd, [camera], e_max, tmp, d_max=d_max, size=(w, h),
                                 superfluous=values["superfluous"])[0]
                shutil.move(os.path.join(tmp, "frame_0000.png"), args.output)
            stats = row
            front_ms = row["front_ms"]
        rows += [("active points", f"{stats['active']:,}"),
                 ("triangles", f"{stats['triangles']:,} "
                               f"({stats['triangles_per_point']:.2f} per point)"),
                 ("time: front", f"{front_ms:.1f} ms"), ("written", args.output)]
    else:
        from fancloud_vtk.core.vdfc import terrain_path

        cams = terrain_path(vd.bounds(), args.frames, aspect=w / h)
        _quiet_offscreen_rendering()
        progress = _Progress("fly-through", args.quiet)
        try:
            frames = flythrough(vd, cams, e_max, args.flythrough, d_max=d_max, size=(w, h),
                                superfluous=values["superfluous"], progress=progress)
        finally:
            progress.close()
        ms = np.array([f["front_ms"] for f in frames])
        act = np.array([f["active"] for f in frames])
        tpp = np.array([f["triangles_per_point"] for f in frames])
        rows += [("frames", f"{len(frames)}"),
                 ("active points", f"mean {act.mean():,.0f}  min {act.min():,}  max {act.max():,}"),
                 ("triangles per point", f"mean {tpp.mean():.2f}  min {tpp.min():.2f}  "
                                         f"max {tpp.max():.2f}"),
                 ("front update", f"mean {ms.mean():.2f} ms  max {ms.max():.2f} ms"),
                 ("written", os.path.join(args.flythrough, "frame_*.png, frames.csv"))]
    if args.save_forest:
        rows.append(("forest written", args.save_forest))
    if not args.quiet:
        _print_rows(rows)
    return 0


def cmd_demo(args) -> int:
    from fancloud_vtk.demo import run_demo

    _quiet_offscreen_rendering()
    run_demo(args.out, quiet=args.quiet)
    return 0


def cmd_bench(args) -> int:
    from fancloud_vtk.bench import main as bench_main

    return bench_main(args.bench_args)


def _add_tile_options(p, title: str, work: str):
    """--tiles, --tile-points, --scheduler, --workers (fans and reduce); the group."""
    tiled = p.add_argument_group(title)
    tiled.add_argument("--tiles", type=_parse_tiles, default=None, metavar="auto|X,Y,Z",
                       help=f"{work} in tiles: 'auto' (about N / --tile-points tiles) or X,Y,Z")
    tiled.add_argument("--tile-points", type=int, default=2_000_000,
                       help="with --tiles auto: points per tile (default: %(default)s)")
    tiled.add_argument("--scheduler", default=None, metavar="ADDR",
                       help="a Dask scheduler address (default: a LocalCluster on this machine)")
    tiled.add_argument("--workers", type=int, default=None,
                       help="the LocalCluster's worker processes (default: the CPU count)")
    return tiled


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fancloud", description="Fan clouds: one triangle fan per point (VTK / PyVista)."
    )
    parser.add_argument("--version", action="version", version=f"fancloud {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("fans", help="build the fan cloud of a point cloud or mesh file")
    p.add_argument("input", help="input file: .ply .obj .stl .vtp .vtk .vtu .xyz .pts .txt .npy "
                                 ".las .laz")
    p.add_argument("-o", "--output", required=True,
                   help="output fan cloud (.vtp); with --tiles an output folder")
    _add_params(p, VERB_PARAMS["fans"])
    tiled = _add_tile_options(
        p, "tiles (a cloud larger than memory: read in chunks, built in tiles on Dask, "
        "written per tile)", "build")
    tiled.add_argument("--chunk", type=int, default=1_000_000,
                       help="points read at a time (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_fans)

    p = sub.add_parser("mesh", help="triangle mesh (a 2-manifold) from a fan cloud or points")
    p.add_argument("input", help="a fan cloud .vtp, or a point cloud / mesh file (fans are built)")
    p.add_argument("-o", "--output", required=True, help="output mesh (.ply .obj .vtp .stl .vtk)")
    _add_params(p, VERB_PARAMS["mesh"])
    _add_tile_options(p, "tiles (the mesh grown in tiles with halos on Dask: the same mesh "
                      "as one process's; the points are read whole)", "grow the mesh")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_mesh)

    p = sub.add_parser("entropy", help="entropy of every point (a fan cloud .vtp with arrays)")
    p.add_argument("input", help="a fan cloud .vtp, a mesh file (one-rings) or a point cloud")
    p.add_argument("-o", "--output", required=True, help="output fan cloud with entropy (.vtp)")
    _add_params(p, VERB_PARAMS["entropy"])
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_entropy)

    p = sub.add_parser("reduce", help="reduce to an exact number of points by entropy")
    p.add_argument("input", help="a fan cloud .vtp, a mesh file (one-rings) or a point cloud")
    p.add_argument("-o", "--output", required=True,
                   help="output fan cloud (.vtp), or with --mesh a mesh (.ply .obj .vtp .stl .vtk)")
    amount = p.add_mutually_exclusive_group(required=True)
    amount.add_argument("--keep", type=float, default=None, help="fraction of points to keep")
    amount.add_argument("--n", "--n-points", dest="n_points", type=int, default=None,
                        help="number of points to keep")
    _add_params(p, _amount_options("reduce"))
    _add_tile_options(p, "tiles (the reduction in blocks with halos on Dask, the input read "
                      "in chunks: fancloud_vtk.distributed.tiled_reduce; one output file)",
                      "reduce")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_reduce)

    p = sub.add_parser("refine", help="refine beyond the input resolution by entropy")
    p.add_argument("input", help="a fan cloud .vtp, a mesh file (one-rings) or a point cloud")
    p.add_argument("-o", "--output", required=True,
                   help="output fan cloud (.vtp), or with --mesh a mesh (.ply .obj .vtp .stl .vtk)")
    amount = p.add_mutually_exclusive_group(required=True)
    amount.add_argument("--factor", type=float, default=None,
                        help="the result has round(F * n) points (F > 1)")
    amount.add_argument("--n", "--n-points", dest="n_points", type=int, default=None,
                        help="number of points of the result")
    _add_params(p, _amount_options("refine"))
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_refine)

    p = sub.add_parser("selective", help="reduce, smooth the coarse level, refine only a region "
                                         "of interest (Figure 11)")
    p.add_argument("input", help="a fan cloud .vtp, a mesh file (one-rings) or a point cloud")
    p.add_argument("-o", "--output", required=True, help="output fan cloud (.vtp)")
    amount = p.add_mutually_exclusive_group(required=True)
    amount.add_argument("--keep", type=float, default=None,
                        help="fraction of points in the coarse level")
    amount.add_argument("--n", "--n-points", dest="n_points", type=int, default=None,
                        help="number of points in the coarse level")
    _add_params(p, _amount_options("selective"))
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_selective)

    p = sub.add_parser("vdfc", help="view-dependent fan cloud: the front for a camera, or a "
                                    "fly-through (paper section 8)")
    p.add_argument("input", help="a height field .npz (a 2-d array: elevation/heights/...; dx and "
                                 "dy if present), 'jacksboro' (matplotlib's DEM), a forest .npz "
                                 "(--save-forest), a fan cloud .vtp, a mesh or a point cloud")
    p.add_argument("--camera", help='"px,py,pz;fx,fy,fz;ux,uy,uz;angle" (view angle in degrees)')
    p.add_argument("-o", "--output", help="with --camera: frame.png (rendered) or front.vtp")
    p.add_argument("--flythrough", metavar="DIR",
                   help="fly over the bounds (terrain_path) and write DIR/frame_*.png and "
                        "DIR/frames.csv (per-frame front size and update time)")
    p.add_argument("--frames", type=int, default=120, help="frames of the fly-through")
    p.add_argument("--size", default="800x600", help="image size WIDTHxHEIGHT")
    p.add_argument("--spacing", type=_vector(2), default=None,
                   help="grid spacing dx,dy of a height field .npz without dx/dy (default 1,1)")
    p.add_argument("--save-forest", metavar="F.npz", help="also save the forest")
    _add_params(p, _vdfc_options())
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_vdfc)

    p = sub.add_parser(
        "demo", help="the bunny (fans, mesh, reduction, refinement) and a terrain "
                     "(view-dependent fan cloud): built, saved, rendered",
        description="The main job on built-in data, written and rendered offscreen to PNG in "
                    "the output folder: the fan cloud of the Stanford bunny (pymeshlab's), its "
                    "triangle mesh, its reductions by entropy (Figure 9), the selective "
                    "refinement of its head (Figure 11) and its refinement x4 (section 7); "
                    "then the terrain panel: the view-dependent fan cloud of matplotlib's "
                    "Jacksboro fault DEM, its front for one viewpoint (Figures 15 and 16).")
    p.add_argument("--out", default="fancloud_demo", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_demo)

    # the benchmark has its own parser (fancloud_vtk.bench): --help goes to it
    p = sub.add_parser("bench", help="benchmarks (fancloud bench fans --help)", add_help=False)
    p.add_argument("bench_args", nargs=argparse.REMAINDER, help="benchmark and its options")
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = make_parser()
    if argv[:1] == ["bench"]:
        # everything after "bench" (--help too) belongs to the benchmark's parser
        args = argparse.Namespace(command="bench", func=cmd_bench, bench_args=argv[1:])
    else:
        args = parser.parse_args(_join_negative_values(parser, argv))

    def show_warning(message, category, filename, lineno, file=None, line=None):
        # one line naming the problem, not the source line that warned
        print(f"fancloud {args.command}: warning: {message}", file=sys.stderr)

    try:
        with warnings.catch_warnings():
            warnings.showwarning = show_warning
            return args.func(args)
    except (ValueError, TypeError, OSError, RuntimeError) as exc:
        print(f"fancloud {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except MemoryError as exc:
        print(f"fancloud {args.command}: error: out of memory: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
