"""Where the time of ``reduce`` or ``refine`` goes: wall time per kernel phase.

Wraps the kernel entry points that ``fancloud_vtk.core.reduction`` and
``fancloud_vtk.core.refinement`` call (``RK.reform_batch``,
``FK.plan_batch``, ...) with timers, runs the call once warm on the bench's
bumpy sphere (``fancloud_vtk.bench.surface_points``) and prints the time
of each phase, its share of the call and how often it ran. Set
``NUMBA_NUM_THREADS=1`` to see the serial work of each phase (the ratio of
the two runs is its parallel scaling).

The speed figures of issues 4 and 5 come from ``fancloud bench reduce`` and
``fancloud bench refine``; this script only splits such a call into its
parts, for the work on them.

Usage::

    python scripts/phase_times.py reduce --n 1000000 --keep 0.176
    python scripts/phase_times.py refine --n 100000 --factor 2
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

#: the kernels each call runs, by module attribute (all called through the module)
PHASES = {
    "reduce": {
        "reduction.CsrK": ["table_from_csr"],
        "reduction.RK": ["build_in_lists", "init_state", "round_candidates",
                         "accept_batch", "reform_batch", "commit_batch", "update_keys",
                         "reduce_steps", "kept_level"],
        "reduction": ["mean_distance"],
    },
    "refine": {
        "refinement.FK": ["update_entropy", "round_candidates", "round_accept", "plan_batch",
                          "commit_batch", "log_batch", "update_cc", "refine_steps"],
        "refinement.CsrK": ["table_from_csr"],
        "refinement.RK": ["compact_level"],
        "refinement": ["_delaunay", "mean_distance"],
    },
}


def _timed(times: Counter, calls: Counter, name: str, f):
    def g(*args, **kwargs):
        t = time.perf_counter()
        try:
            return f(*args, **kwargs)
        finally:
            times[name] += time.perf_counter() - t
            calls[name] += 1
    return g


def phase_times(call: str, n: int, amount: float, seed: int = 0):
    """Run ``call`` ('reduce' or 'refine') on ``n`` bumpy-sphere points, warm, with its
    phases timed. ``amount``: the kept fraction (reduce) or the factor (refine).
    Returns (total seconds, {phase: seconds}, {phase: calls}, result)."""
    import importlib

    from fancloud_vtk import build_fans, reduce, refine
    from fancloud_vtk.bench import surface_points

    if call not in PHASES:
        raise ValueError(f"call must be 'reduce' or 'refine', got {call!r}")

    def run(fc):
        if call == "reduce":
            return reduce(fc, max(4, round(amount * fc.n_points)))
        return refine(fc, factor=amount)

    run(build_fans(surface_points(2000, seed=seed + 1), k=6))  # compile and warm up
    fc = build_fans(surface_points(n, seed=seed), k=6)
    times: Counter = Counter()
    calls: Counter = Counter()
    saved = []
    try:
        for where, names in PHASES[call].items():
            module, _, attr = where.partition(".")
            target = importlib.import_module(f"fancloud_vtk.core.{module}")
            if attr:
                target = getattr(target, attr)
            for name in names:
                f = getattr(target, name)
                saved.append((target, name, f))
                setattr(target, name, _timed(times, calls, name, f))
        t = time.perf_counter()
        result = run(fc)
        total = time.perf_counter() - t
    finally:
        for target, name, f in saved:
            setattr(target, name, f)
    return total, dict(times), dict(calls), result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("call", choices=sorted(PHASES))
    p.add_argument("--n", type=int, default=200_000, help="points (default: 200000)")
    p.add_argument("--keep", type=float, default=0.176, help="reduce: kept fraction")
    p.add_argument("--factor", type=float, default=2.0, help="refine: factor")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    import numba

    amount = a.keep if a.call == "reduce" else a.factor
    total, times, calls, result = phase_times(a.call, a.n, amount, a.seed)
    print(f"{a.call}: {a.n:,} points -> {result.n_points:,}, {total:.3f} s "
          f"({numba.get_num_threads()} numba threads)")
    print("| phase | s | share | calls |\n|---|---:|---:|---:|")
    for name, s in sorted(times.items(), key=lambda kv: -kv[1]):
        print(f"| {name} | {s:.3f} | {s / total:.1%} | {calls[name]} |")
    rest = total - sum(times.values())
    print(f"| (outside these, in Python) | {rest:.3f} | {rest / total:.1%} | |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
