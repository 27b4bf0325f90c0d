"""The ``fancloud`` command: a front that reads, forwards and writes.

``fancloud fans IN -o OUT.vtp [--k 6 ...]``
    Build the fan cloud of a point cloud or mesh file.
``fancloud mesh IN -o OUT.{ply,obj,vtp,stl} [...]``
    Triangle mesh (paper section 4) of a fan cloud .vtp or of any point cloud.
``fancloud demo [--out DIR]``
    The main job on built-in data (the Stanford bunny shipped with pymeshlab).
``fancloud bench fans [...]``
    The benchmark of fan construction (see ``fancloud bench fans --help``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

from fancloud_vtk.params import FAN_PARAMS, MESH_PARAMS, Param


def _add_params(parser: argparse.ArgumentParser, table: tuple[Param, ...]) -> None:
    """Options derived from a parameter table."""
    for p in table:
        if p.kind == "bool":
            parser.add_argument(
                p.cli_flag, dest=p.name, default=p.default,
                action=argparse.BooleanOptionalAction, help=f"{p.doc} (default: {p.default})",
            )
        else:
            kind = {"int": int, "float": float, "choice": str}[p.kind]
            parser.add_argument(
                p.cli_flag, dest=p.name, type=kind, default=p.default, choices=p.choices,
                help=f"{p.doc} (default: {p.default})",
            )


def _params(args, table) -> dict:
    return {p.name: getattr(args, p.name) for p in table}


class _Progress:
    """A tqdm bar driven by the core's progress callback (hidden when not a terminal)."""

    def __init__(self, desc: str, quiet: bool):
        from tqdm import tqdm

        self.bar = tqdm(total=100, desc=desc, disable=True if quiet else None, leave=False,
                        bar_format="{l_bar}{bar}| {elapsed}")

    def __call__(self, fraction: float, message: str) -> bool:
        self.bar.set_description(message)
        self.bar.n = round(100 * fraction)
        self.bar.refresh()
        return False

    def close(self):
        self.bar.close()


def _build(points_file, params, quiet):
    from fancloud_vtk.core.fans import build_fans

    data = dict(points_file.point_data)
    normals = data.pop("Normals", None)
    progress = _Progress("fans", quiet)
    try:
        return build_fans(points_file.points, normals=normals, point_data=data,
                          progress=progress, **params)
    finally:
        progress.close()


def _check_output(path: str, ext: str | tuple[str, ...]) -> None:
    """Fail before any work when ``path`` cannot be the output (``main`` prints it, exit 2)."""
    exts = (ext,) if isinstance(ext, str) else ext
    if not path.lower().endswith(exts):
        raise ValueError(f"the output must be a {' or '.join(exts)} file, got {path!r}")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"cannot write {path!r}: no such directory {folder!r}")


def cmd_fans(args) -> int:
    from fancloud_vtk.io import read_point_cloud

    _check_output(args.output, ".vtp")
    src = read_point_cloud(args.input)
    t0 = time.perf_counter()
    fc = _build(src, _params(args, FAN_PARAMS), args.quiet)
    elapsed = time.perf_counter() - t0
    fc.save(args.output)
    if not args.quiet:
        _print_summary(fc, elapsed, args.output)
    return 0


def _load_fancloud(path, params, quiet):
    """A fan cloud .vtp as it is; any other point cloud or mesh file: its fans, built."""
    from fancloud_vtk.io import read_point_cloud

    if path.lower().endswith(".vtp"):
        from fancloud_vtk.algorithms.convert import fancloud_from_vtk, is_fancloud, read_vtp

        data = read_vtp(path)
        if is_fancloud(data):
            return fancloud_from_vtk(data)
    return _build(read_point_cloud(path), params, quiet)


def cmd_mesh(args) -> int:
    from fancloud_vtk.algorithms.convert import MESH_FORMATS, mesh_to_vtk, write_mesh
    from fancloud_vtk.core.mesh import fan_cloud_to_mesh

    _check_output(args.output, MESH_FORMATS)
    t0 = time.perf_counter()
    fc = _load_fancloud(args.input, _params(args, FAN_PARAMS), args.quiet)
    mesh = fan_cloud_to_mesh(fc, **_params(args, MESH_PARAMS))
    elapsed = time.perf_counter() - t0
    write_mesh(mesh_to_vtk(mesh), args.output)
    if not args.quiet:
        _print_mesh_summary(mesh, elapsed, args.output)
    return 0


def _print_mesh_summary(mesh, elapsed, path=None, extra=()) -> None:
    """The stage counts (and per point) and the checks of a mesh; ``extra``: more rows."""
    s = mesh.stats
    n = max(len(mesh.points), 1)
    rows = [("points", f"{len(mesh.points):,}")]
    for key, label in (("fan_triangles", "fan triangles"), ("distinct", "distinct"),
                       ("after_superfluous", "after superfluous removal"),
                       ("grown", "grown 2-manifold"), ("final", "final (holes closed)")):
        rows.append((label, f"{s[key]:,} ({s[key] / n:.3f} per point)"))
    for key in ("holes_closed", "points_inserted", "boundary_edges", "holes",
                "non_manifold_edges", "non_manifold_vertices", "inconsistent_edges",
                "self_intersections", "unused_points", "euler_characteristic"):
        rows.append((key.replace("_", " "), f"{s[key]:,}"))
    rows.append(("time", f"{elapsed:.2f} s"))
    if path:
        rows.append(("written", str(path)))
    rows.extend(extra)
    _print_rows(rows)


def _print_rows(rows) -> None:
    width = max(len(r[0]) for r in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")


def _print_summary(fc, elapsed, path=None) -> None:
    s = fc.summary()
    rows = [
        ("points", f"{s['points']:,}"),
        ("fans closed", f"{s['fans_closed']:,}"),
        ("fans open", f"{s['fans_open']:,} ({100 * s['fans_open'] / max(s['points'], 1):.2f}%)"),
        ("fans in rotated plane", f"{s['fans_rotated']:,}"),
        ("distinct triangles / point", f"{s['distinct_triangles_per_point']:.2f}"),
        ("duplicates merged", f"{fc.info.get('duplicates_merged', 0):,}"),
        ("time", f"{elapsed:.2f} s"),
    ]
    if path:
        rows.append(("written", str(path)))
    _print_rows(rows)


def cmd_demo(args) -> int:
    from fancloud_vtk.demo import run_demo

    run_demo(args.out, quiet=args.quiet)
    return 0


def cmd_bench(args) -> int:
    from fancloud_vtk.bench import main as bench_main

    return bench_main(args.bench_args)


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fancloud", description="Fan clouds: one triangle fan per point (VTK / PyVista)."
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("fans", help="build the fan cloud of a point cloud or mesh file")
    p.add_argument("input", help="input file: .ply .obj .vtp .vtk .vtu .xyz .pts .txt .npy")
    p.add_argument("-o", "--output", required=True, help="output fan cloud (.vtp)")
    _add_params(p, FAN_PARAMS)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_fans)

    p = sub.add_parser("mesh", help="triangle mesh (a 2-manifold) from a fan cloud or points")
    p.add_argument("input", help="a fan cloud .vtp, or a point cloud / mesh file (fans are built)")
    p.add_argument("-o", "--output", required=True, help="output mesh (.ply .obj .vtp .stl .vtk)")
    _add_params(p, FAN_PARAMS + MESH_PARAMS)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=cmd_mesh)

    p = sub.add_parser("demo", help="fan cloud and mesh of the bunny: built, saved, rendered")
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
        args = parser.parse_args(argv)

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
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
