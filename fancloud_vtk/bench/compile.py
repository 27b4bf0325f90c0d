"""``fancloud bench compile``: what a new user waits for on the first run.

The numba kernels compile on their first call and are cached on disk
(``cache=True``); a later process loads them. This benchmark runs the same
command -- by default ``fancloud demo`` (the quick start's first command) --
twice in fresh processes with an empty numba cache directory of its own:
the first run compiles, the second loads the cache. Their difference is the
compile time a user meets once. Each run's wall time is measured around the
whole subprocess, as the user sees it.
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time

from fancloud_vtk.bench.common import _log
from fancloud_vtk.bench.report import _row, header, markdown, write_outputs

#: the command timed by default: the quick start's demo, quiet, into a temporary folder
DEFAULT_COMMAND = "demo -q --out {tmp}"


def _run(command: list[str], cache_dir: str, timeout: float) -> float:
    """Seconds of ``python -m fancloud_vtk.cli COMMAND`` with ``NUMBA_CACHE_DIR`` set."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "fancloud_vtk.cli", *command], env=env,
                          capture_output=True, text=True, timeout=timeout, check=False)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"fancloud {shlex.join(command)} failed (exit {proc.returncode}):\n"
                           + proc.stderr[-3000:])
    return elapsed


def run_compile(args, argv: list[str]) -> dict:
    """Time the command cold (empty cache) and warm (cached), write and print the table."""
    t_start = time.perf_counter()
    res = {**header(["compile", *argv]), "args": {"command": args.command,
                                                  "repeat": args.repeat}}
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as tmp:
        command = shlex.split(args.command.format(tmp=tmp))
        _log(args.quiet, f"cold run (empty numba cache): fancloud {shlex.join(command)}")
        cold = _run(command, cache, args.timeout)
        warm = []
        for i in range(args.repeat):
            _log(args.quiet, f"warm run {i + 1} of {args.repeat}")
            warm.append(_run(command, cache, args.timeout))
    res.update(cold=cold, warm=warm, compile=cold - min(warm))
    shown = f"fancloud {args.command.format(tmp='TMP')}"
    res["elapsed"] = time.perf_counter() - t_start
    rows = [
        _row("first run, empty numba cache", shown, "fresh process, wall time",
             f"{cold:.1f}", "s"),
        _row("later run, cached kernels", shown,
             f"fresh process, wall time, best of {args.repeat}", f"{min(warm):.1f}", "s"),
        _row("numba compile time (first run minus later run)", shown, "", f"{cold - min(warm):.1f}",
             "s"),
    ]
    res["rows"] = rows
    text = markdown("fancloud bench compile: the first run's numba compile", res, rows)
    md, js = write_outputs(args.out, "compile", text, res)
    print(text)
    print(f"written: {md}, {js}")
    return res


def _cmd_compile(args, argv) -> int:
    run_compile(args, argv)
    return 0


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``compile`` on the subparsers of ``fancloud bench``."""
    p = sub.add_parser("compile", help="the first run's numba compile time (cold vs cached)",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--command", default=DEFAULT_COMMAND,
                   help="the fancloud command timed, {tmp} a temporary folder (default: "
                        "%(default)r)")
    p.add_argument("--repeat", type=int, default=1,
                   help="cached runs, best kept (default: %(default)s)")
    p.add_argument("--timeout", type=float, default=3600.0,
                   help="seconds allowed per run (default: %(default)s)")
    p.add_argument("--out", default="bench_out", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_compile)
    return p
