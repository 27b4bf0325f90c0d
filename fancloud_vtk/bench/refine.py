"""``fancloud bench refine``: refinement by entropy (paper section 7), speed and cycles.

``fancloud bench refine [--part speed cycles] [--n 100k] [--repeat 3] [--cycles 10]
[--out DIR] [--quick]``

speed
    On ``--n`` random points of the unit sphere, in this process and warm
    (every call made once on a small cloud first), best of ``--repeat``:
    ``build_fans`` of 2n points against ``refine(build_fans(n points),
    factor=2)``, only the refinement timed; also ``exact=True`` (one
    insertion at a time). The target: refine no slower than building the
    fans of as many points.
cycles
    The paper's Figure 12 on the Stanford bunny (pymeshlab's bunny.obj, its
    mesh one-rings through ``fan_cloud_of_mesh``): ``--cycles`` times
    ``fc = refine(reduce(fc, keep=0.5), n_points=n)`` with no stored detail.
    After every cycle the result is meshed (``fan_cloud_to_mesh``) and
    measured: the symmetric Hausdorff distance (max and mean) to the bunny's
    surface, as in ``bench reduce``, and the volume against that of the
    meshed input (signed, by the divergence theorem).

Writes ``refine.md`` (also printed), ``refine.json``, ``refine_cycles.png``
(the first and the last state side by side) and ``refine_cycles_error.png``
(Hausdorff and volume per cycle).
"""

from __future__ import annotations

import argparse
import os
import time

from fancloud_vtk.bench.common import (
    WARMUP_POINTS,
    K,
    _log,
    data_label,
    parse_size,
    size_label,
    surface_points,
)
from fancloud_vtk.bench.harness import timed
from fancloud_vtk.bench.metrics import (
    Reference,
    measure_result,
    signed_volume,
    sphere_distance,
)
from fancloud_vtk.bench.reduce import SAMPLES_PER_POINT, reduce_data
from fancloud_vtk.bench.report import (
    _num,
    _ok,
    _row,
    header,
    markdown,
    table_lines,
    write_outputs,
)
from fancloud_vtk.render import render_panels

#: The issue's targets for ``bench refine``.
TARGET_SPEED_RATIO = 1.0  #: refine(n -> 2n) time / build_fans(2n) time
TARGET_HAUSDORFF_MAX = 0.01  #: Hausdorff max after the last cycle, fraction of bbox diagonal
TARGET_VOLUME_PCT = 2.0  #: |volume change| after the last cycle, percent

PARTS = ("speed", "cycles")
DEFAULT_N = 100_000
DEFAULT_CYCLES = 10
KEEP = 0.5  #: each cycle reduces to this fraction, then refines back
QUICK_N, QUICK_CYCLES = 10_000, 3

CYCLE_COLUMNS = ("cycle", "points", "reduced to", "triangles", "holes", "reduce (s)",
                 "refine (s)", "Hausdorff max", "Hausdorff mean", "volume change (%)")


# -- speed ---------------------------------------------------------------------------------


def measure_refine_speed(n: int, repeat: int, seed: int, quiet: bool) -> dict:
    """Best times of build_fans(2n points) and refine(build_fans(n points), factor=2)."""
    from fancloud_vtk import build_fans, refine

    small = build_fans(surface_points(WARMUP_POINTS, seed + 1, "sphere"), k=K)
    refine(small, factor=2)
    refine(small, factor=2, exact=True)
    points_n = surface_points(n, seed, "sphere")
    points_2n = surface_points(2 * n, seed, "sphere")
    fans, plain, exact = [], [], []
    for i in range(repeat):
        _log(quiet, f"  speed {size_label(n)}: run {i + 1} of {repeat}")
        fans.append(timed(build_fans, points_2n, k=K))
        fc = build_fans(points_n, k=K)  # not timed
        plain.append(timed(refine, fc, factor=2))
        exact.append(timed(refine, fc, factor=2, exact=True))
    fine = refine(fc, factor=2)
    d = sphere_distance(fine.points[n:])
    return {"n": n, "n_open": int(fc.n_open), "build_fans_times": fans, "refine_times": plain,
            "exact_times": exact, "build_fans": min(fans), "refine": min(plain),
            "exact": min(exact), "ratio": min(plain) / min(fans),
            "ratio_exact": min(exact) / min(fans), "refined_points": fine.n_points,
            "inserted_max": float(d.max()) if len(d) else None,
            "inserted_mean": float(d.mean()) if len(d) else None}


def speed_rows(s: dict, seed: int, repeat: int) -> list[dict]:
    n = s["n"]
    data_2n = data_label(2 * n, "sphere", seed)
    data_n = data_label(n, "sphere", seed)
    best = f"best of {repeat}, warm (same process)"

    def runs(key):
        return "runs " + ", ".join(_num(t) for t in s[f"{key}_times"]) + " s"

    call = f"refine(build_fans(points, k={K}), factor=2), only refine timed"
    return [
        _row("speed: build_fans, 2n points", data_2n,
             f"build_fans(points, k={K}); {best}; {runs('build_fans')}",
             _num(s["build_fans"]), "s"),
        _row("speed: refine n -> 2n", data_n,
             f"{call}; {s['n_open']:,} open fans; {best}; {runs('refine')}",
             _num(s["refine"]), "s"),
        _row("speed: ratio refine / build_fans(2n)", data_n, "best times above",
             f"{s['ratio']:.3f}", "x", f"<= {TARGET_SPEED_RATIO:g}",
             _ok(s["ratio"] <= TARGET_SPEED_RATIO)),
        _row("speed: refine n -> 2n, exact=True", data_n,
             f"{call.replace('factor=2', 'factor=2, exact=True')} (one insertion at a time); "
             f"{best}; {runs('exact')}; ratio to build_fans(2n) {s['ratio_exact']:.3f}",
             _num(s["exact"]), "s"),
        _row("refine: distance of the inserted points to the sphere", data_n,
             f"max (mean {s['inserted_mean']:.3g}) over the {s['refined_points'] - n:,} "
             "inserted points, radius 1",
             "n/a" if s["inserted_max"] is None else f"{s['inserted_max']:.3g}", ""),
    ]


# -- cycles --------------------------------------------------------------------------------


def _state(cycle: int, fc, ref, v0: float, **extra) -> tuple[dict, object]:
    """The measures of one state: mesh it, Hausdorff to the input surface, volume."""
    from fancloud_vtk import fan_cloud_to_mesh

    mesh = fan_cloud_to_mesh(fc, self_intersections=False)
    r = {"vertices": mesh.points, "triangles": mesh.triangles, "message": "ok"}
    measure_result(r, ref)
    m = r["measures"]
    volume = signed_volume(mesh.points, mesh.triangles)
    return {"cycle": cycle, "points": fc.n_points, "triangles": mesh.n_triangles,
            "holes": int(mesh.stats["holes"]), "hausdorff_max": m["hausdorff_max"],
            "hausdorff_mean": m["hausdorff_mean"], "forward_max": m.get("forward_max"),
            "backward_max": m.get("backward_max"), "volume": volume,
            "volume_change": volume / v0 - 1.0, **extra}, mesh


def run_cycles(cycles: int, keep: float, samples: int, seed: int, quiet: bool) -> dict:
    """``cycles`` reduce-refine cycles of the bunny, every state measured."""
    from fancloud_vtk import build_fans, fan_cloud_of_mesh, fan_cloud_to_mesh, reduce, refine

    data = reduce_data("bunny", None, seed)
    ref = Reference(data, samples, seed)
    # warm-up on a small input of the same kind (mesh one-rings): compiled before the timing
    small = fan_cloud_to_mesh(build_fans(surface_points(WARMUP_POINTS, seed + 1, "sphere"), k=K))
    warm = fan_cloud_of_mesh(small.points, small.triangles)
    refine(reduce(warm, keep=keep), n_points=warm.n_points)
    fc = first = fan_cloud_of_mesh(data["points"], data["triangles"])
    n = fc.n_points
    state, mesh0 = _state(0, fc, ref, 1.0)
    v0 = state["volume"]
    state["volume_change"] = 0.0
    states = [state]
    for c in range(1, cycles + 1):
        t0 = time.perf_counter()
        small = reduce(fc, keep=keep)
        t1 = time.perf_counter()
        fc = refine(small, n_points=n)
        t2 = time.perf_counter()
        state, _ = _state(c, fc, ref, v0, reduced=small.n_points, reduce_time=t1 - t0,
                          refine_time=t2 - t1)
        states.append(state)
        _log(quiet, f"  cycle {c}: Hausdorff max {state['hausdorff_max']:.3g}, mean "
             f"{state['hausdorff_mean']:.3g}, volume {100 * state['volume_change']:+.2f}%")
    return {"label": data["label"], "n": n, "diag": ref.diag, "keep": keep,
            "cycles": cycles, "v0": v0, "mesh0_triangles": mesh0.n_triangles,
            "states": states, "first": first, "last": fc}


def cycle_rows(cy: dict) -> list[dict]:
    """The figures of the last cycle, judged against the targets."""
    last = cy["states"][-1]
    c, data = last["cycle"], cy["label"]
    params = (f"{c} cycles of fc = refine(reduce(fc, keep={cy['keep']:g}), n_points={cy['n']:,}) "
              "from fan_cloud_of_mesh(bunny), no stored detail; meshed with fan_cloud_to_mesh")
    vol = 100.0 * last["volume_change"]
    holes = (f"; its mesh has {last['holes']} hole(s): the volume of an open surface"
             if last["holes"] else "")
    return [
        _row(f"cycles: Hausdorff max after cycle {c}", data, params + "; symmetric",
             f"{last['hausdorff_max']:.3g}", "x bbox diagonal", f"<= {TARGET_HAUSDORFF_MAX:g}",
             _ok(last["hausdorff_max"] <= TARGET_HAUSDORFF_MAX)),
        _row(f"cycles: Hausdorff mean after cycle {c}", data, params + "; mean of both ways",
             f"{last['hausdorff_mean']:.3g}", "x bbox diagonal"),
        _row(f"cycles: volume change after cycle {c}", data,
             params + f"; against the meshed input ({cy['v0']:.5g}){holes}", f"{vol:+.2f}", "%",
             f"abs <= {TARGET_VOLUME_PCT:g}", _ok(abs(vol) <= TARGET_VOLUME_PCT)),
    ]


def cycle_table(cy: dict) -> list[str]:
    rows = []
    for s in cy["states"]:
        first = s["cycle"] == 0
        cells = (str(s["cycle"]), f"{s['points']:,}",
                 "-" if first else f"{s['reduced']:,}", f"{s['triangles']:,}", str(s["holes"]),
                 "-" if first else _num(s["reduce_time"]),
                 "-" if first else _num(s["refine_time"]),
                 f"{s['hausdorff_max']:.3g}", f"{s['hausdorff_mean']:.3g}",
                 f"{100 * s['volume_change']:+.3f}")
        rows.append(dict(zip(CYCLE_COLUMNS, cells, strict=True)))
    return table_lines(CYCLE_COLUMNS, rows)


# -- figures -------------------------------------------------------------------------------


def error_chart(cy: dict, path: str) -> str:
    """Hausdorff max and mean, and the volume change, per cycle (matplotlib Agg)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    states = cy["states"]
    x = [s["cycle"] for s in states]
    fig = Figure(figsize=(11, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax, av = fig.subplots(1, 2)
    for key, label, marker in (("hausdorff_max", "Hausdorff max", "o"),
                               ("hausdorff_mean", "Hausdorff mean", "s")):
        pts = [(c, s[key]) for c, s in zip(x, states, strict=True) if s[key] > 0]
        if pts:
            ax.plot(*zip(*pts, strict=True), marker=marker, label=label)
    ax.axhline(TARGET_HAUSDORFF_MAX, color="red", linestyle="--", linewidth=1,
               label=f"target max {TARGET_HAUSDORFF_MAX:g}")
    ax.set_yscale("log")
    ax.set_xlabel("cycle")
    ax.set_ylabel("fraction of the bounding-box diagonal")
    ax.set_title("symmetric Hausdorff distance to the input bunny", fontsize=10)
    ax.legend(fontsize=8)
    av.plot(x, [100 * s["volume_change"] for s in states], marker="o", color="tab:green")
    for sign in (1, -1):
        av.axhline(sign * TARGET_VOLUME_PCT, color="red", linestyle="--", linewidth=1)
    av.set_xlabel("cycle")
    av.set_ylabel("%")
    av.set_title(f"volume change against the meshed input (target: within "
                 f"\u00b1{TARGET_VOLUME_PCT:g}%)", fontsize=10)
    for a in (ax, av):
        a.grid(True, alpha=0.3)
    fig.suptitle(f"fancloud bench refine: fc = refine(reduce(fc, keep={cy['keep']:g}), "
                 f"n_points={cy['n']:,}) on the bunny, cycle 0 = the input", fontsize=10)
    fig.savefig(path, dpi=90)
    return path


def render_cycles(cy: dict, path: str) -> str:
    """The first state (the input's one-rings, meshed) and the last, side by side."""
    s0, s1 = cy["states"][0], cy["states"][-1]
    render_panels([(f"input: the bunny's one-rings, meshed ({s0['points']:,} points)",
                    cy["first"]),
                   (f"after {s1['cycle']} cycles of reduce to {cy['keep']:g} and refine back\n"
                    f"Hausdorff max {s1['hausdorff_max']:.3g}, mean {s1['hausdorff_mean']:.3g}, "
                    f"volume {100 * s1['volume_change']:+.2f}%", cy["last"])], path)
    return path


# -- the run -------------------------------------------------------------------------------


def run_refine(args, argv: list[str]) -> dict:
    """``bench refine``: the parts asked for; tables, JSON and figures."""
    t_start = time.perf_counter()
    quiet = args.quiet
    n = args.n if args.n is not None else (QUICK_N if args.quick else DEFAULT_N)
    cycles = args.cycles if args.cycles is not None else (
        QUICK_CYCLES if args.quick else DEFAULT_CYCLES)
    if n < 100 or cycles < 1 or args.samples < 1 or not 0 < args.keep < 1:
        raise ValueError("--n must be at least 100, --cycles and --samples at least 1 and "
                         "--keep in (0, 1)")
    parts = list(dict.fromkeys(args.part))
    res = {**header(["refine", *argv]),
           "args": {"part": parts, "n": n, "repeat": args.repeat, "cycles": cycles,
                    "keep": args.keep, "samples": args.samples, "seed": args.seed, "k": K},
           "speed": None, "cycles": None}
    rows, written = [], []
    if "speed" in parts:
        _log(quiet, f"speed: build_fans({size_label(2 * n)}) against refine "
             f"{size_label(n)} -> {size_label(2 * n)}")
        res["speed"] = measure_refine_speed(n, args.repeat, args.seed, quiet)
        rows += speed_rows(res["speed"], args.seed, args.repeat)
    cy = None
    if "cycles" in parts:
        _log(quiet, f"cycles: {cycles} of reduce to {args.keep:g} and refine, bunny")
        cy = run_cycles(cycles, args.keep, args.samples, args.seed, quiet)
        rows += cycle_rows(cy)
        res["cycles"] = {k: v for k, v in cy.items() if k not in ("first", "last")}
    res["elapsed"] = time.perf_counter() - t_start
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    res["load_average_end"] = load
    notes = [
        "load average at the end " + (", ".join(f"{x:.2f}" for x in load) if load
                                      else "unknown") + f"; numba threading layer "
        f"{_threading_layer()}",
        "refine: fancloud_vtk.refine with its default weights (1, 1, 0, 0), "
        "move=True; default mode: parallel rounds; exact=True: one insertion at a time",
    ]
    if cy is not None:
        notes.append(
            f"cycles: Hausdorff as in `bench reduce`: {args.samples} area-uniform samples per "
            "input point on each surface (plus the vertices for the max), unsigned "
            "point-to-triangle distance both ways; max of both, mean = the mean of the two "
            "directions' means; as a fraction of the bounding-box diagonal "
            f"({cy['diag']:.4g}); volume: signed, sum of a.(b x c)/6 over the triangles, "
            "against the volume of fan_cloud_to_mesh(fan_cloud_of_mesh(bunny)); cycle 0 = "
            "that meshed input")
    res["rows"] = rows
    text = markdown("fancloud bench refine: refinement by entropy (paper section 7)", res, rows,
                    notes)
    if cy is not None:
        text += "\n".join(["", f"## Cycles: {cy['label']}", "", *cycle_table(cy)]) + "\n"
    written += write_outputs(args.out, "refine", text, res)
    if cy is not None:
        written.append(error_chart(cy, os.path.join(args.out, "refine_cycles_error.png")))
        try:
            written.append(render_cycles(cy, os.path.join(args.out, "refine_cycles.png")))
        except Exception as exc:  # an offscreen render can fail on a machine without GL
            written.append(f"(refine_cycles.png not rendered: {type(exc).__name__}: {exc})")
    print(text)
    print("written: " + ", ".join(written))
    return res


def _threading_layer() -> str:
    import numba

    try:
        return numba.threading_layer()
    except ValueError:  # no parallel region has run
        return "not initialised"


def _cmd_refine(args, argv) -> int:
    run_refine(args, argv)
    return 0


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``refine`` on the subparsers of ``fancloud bench``."""
    p = sub.add_parser(
        "refine", help="refinement: refine against build_fans; reduce/refine cycles (Fig. 12)",
        description="Speed: refine n -> 2n points against build_fans of 2n points, warm, in "
                    "this process. Cycles: the bunny reduced to half and refined back, again "
                    "and again; Hausdorff distance and volume after each cycle. Writes "
                    "refine.md, refine.json, refine_cycles.png and refine_cycles_error.png.")
    p.add_argument("--part", nargs="+", choices=PARTS, default=list(PARTS),
                   help="which parts to run (default: %(default)s)")
    p.add_argument("--n", type=parse_size, default=None,
                   help=f"points of the sphere for the speed part, refined to 2n (default: "
                        f"{size_label(DEFAULT_N)}; --quick: {size_label(QUICK_N)})")
    p.add_argument("--repeat", type=int, default=3,
                   help="timed runs of the speed part, best kept (default: %(default)s)")
    p.add_argument("--cycles", type=int, default=None,
                   help=f"reduce-refine cycles (default: {DEFAULT_CYCLES}; --quick: "
                        f"{QUICK_CYCLES})")
    p.add_argument("--keep", type=float, default=KEEP,
                   help="fraction each cycle reduces to (default: %(default)s)")
    p.add_argument("--samples", type=int, default=SAMPLES_PER_POINT,
                   help="surface samples per input point on each surface for the distances "
                        "(default: %(default)s)")
    p.add_argument("--quick", action="store_true",
                   help=f"smoke run: --n {size_label(QUICK_N)}, --cycles {QUICK_CYCLES} "
                        "(unless given)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--out", default="bench_out", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_refine)
    return p
