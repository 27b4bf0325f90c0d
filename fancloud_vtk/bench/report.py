"""The output of every benchmark: the figures table, Markdown, the JSON, and the header
naming the machine, the software, the commit, the command and the date.

Every result written by :func:`write_outputs` starts with :func:`header`: ``argv``,
``command`` (the ``fancloud bench ...`` line as run), ``date``, ``commit`` (``git
rev-parse HEAD`` of the package's checkout and whether its tracked files differ from
it; None when not a git checkout), ``machine`` (CPU, cores, RAM, load) and
``software`` (Python and the libraries' versions).
"""

from __future__ import annotations

import json
import os
import platform
import shlex
import subprocess
import time

import numpy as np

from fancloud_vtk.bench.common import _read

#: The keys every result JSON carries (see :func:`header`).
HEADER_KEYS = ("argv", "command", "date", "commit", "machine", "software")

#: Packages whose versions are in ``software`` (None when not installed).
SOFTWARE = ("scipy", "numba", "vtk", "pyvista", "matplotlib", "pymeshlab", "meshlib",
            "fast-simplification")


# -- the header ----------------------------------------------------------------------


def machine_info() -> dict:
    """CPU, cores, memory, load, platform and numba's thread count."""
    import numba

    cpu = next((line.split(":", 1)[1].strip() for line in _read("/proc/cpuinfo").splitlines()
                if line.startswith("model name")), platform.processor() or "unknown")
    mem = next((int(line.split()[1]) * 1024 for line in _read("/proc/meminfo").splitlines()
                if line.startswith("MemTotal")), None)
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        usable = os.cpu_count()
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "cores_usable": usable,
        "memory_bytes": mem,
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
        "platform": platform.platform(),
        "numba_threads": numba.get_num_threads(),
    }


def package_versions(packages) -> dict:
    """Installed versions of ``packages`` (distribution names; None if not installed)."""
    from importlib import metadata

    out = {}
    for pkg in packages:
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def software_info() -> dict:
    """Python, numpy, fancloud_vtk and the versions of :data:`SOFTWARE`."""
    import fancloud_vtk

    return {"python": platform.python_version(), "numpy": np.__version__,
            **package_versions(SOFTWARE), "fancloud_vtk": fancloud_vtk.__version__}


def _git(root: str, *args: str) -> subprocess.CompletedProcess:
    # read-only, and no optional locks: a benchmark never touches the repository's index
    return subprocess.run(["git", "--no-optional-locks", *args], cwd=root, capture_output=True,
                          text=True, timeout=30, check=False,
                          env={**os.environ, "GIT_OPTIONAL_LOCKS": "0"})


def commit_info() -> dict | None:
    """``{"sha", "dirty"}`` of the git checkout the package runs from; None if it is none.

    ``sha``: ``git rev-parse HEAD``; ``dirty``: whether a tracked file differs from it
    (``git diff-index HEAD``, by the index's file stats: a file touched but unchanged
    counts). None when git is missing or the package is not a tracked file of a checkout
    (an installed copy).
    """
    import fancloud_vtk

    package = os.path.dirname(os.path.abspath(fancloud_vtk.__file__))
    try:
        top = _git(package, "rev-parse", "--show-toplevel")
        if top.returncode != 0:
            return None
        root = top.stdout.strip()
        init = os.path.relpath(os.path.join(package, "__init__.py"), root)
        tracked = _git(root, "ls-files", "--", init)
        head = _git(root, "rev-parse", "HEAD")
        if tracked.returncode != 0 or not tracked.stdout.strip() or head.returncode != 0:
            return None
        dirty = _git(root, "diff-index", "--quiet", "HEAD", "--").returncode != 0
    except (OSError, subprocess.SubprocessError):
        return None
    return {"sha": head.stdout.strip(), "dirty": dirty}


def header(argv: list[str]) -> dict:
    """The first keys of a result (:data:`HEADER_KEYS`); ``argv`` starts with the benchmark."""
    return {"argv": list(argv), "command": shlex.join(["fancloud", "bench", *argv]),
            "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "commit": commit_info(),
            "machine": machine_info(), "software": software_info()}


# -- the table -----------------------------------------------------------------------


COLUMNS = ("figure", "data", "parameters", "measured", "unit", "target", "verdict")


def _row(figure, data, parameters, measured, unit, target="", verdict="") -> dict:
    return dict(zip(COLUMNS, (figure, data, parameters, measured, unit, target, verdict),
                    strict=True))


def _ok(passed: bool) -> str:
    return "yes" if passed else "NO"


def _num(x: float) -> str:
    """A number for the table: 3 significant digits below 1, fewer decimals above."""
    if abs(x) >= 10_000:
        return f"{x:,.0f}"
    if abs(x) >= 100:
        return f"{x:.0f}"
    return f"{x:.2f}" if abs(x) >= 1 else f"{x:.3g}"


def table_lines(columns, rows: list[dict]) -> list[str]:
    """A Markdown table: header, rule and one line per row (``|`` in cells becomes ``/``)."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        lines.append("| " + " | ".join(str(row[c]).replace("|", "/") for c in columns) + " |")
    return lines


def markdown(title: str, res: dict, rows: list[dict], notes=()) -> str:
    """Title, machine and run information (and ``notes``, one line each), then the table."""
    m, s = res["machine"], res["software"]
    mem = f"{m['memory_bytes'] / 2**30:.1f} GiB" if m["memory_bytes"] else "unknown"
    load = ", ".join(f"{x:.2f}" for x in m["load_average"]) if m["load_average"] else "unknown"
    lines = [
        f"# {title}",
        "",
        f"- machine: {m['cpu']}; {m['cores']} cores ({m['cores_usable']} usable); {mem} RAM; "
        f"load average at start {load}",
        f"- software: Python {s['python']}, numpy {s['numpy']}, scipy {s['scipy']}, "
        f"numba {s['numba']} ({m['numba_threads']} threads), fancloud_vtk {s['fancloud_vtk']}; "
        f"{m['platform']}",
        f"- run: `fancloud bench {' '.join(res['argv'])}` on {res['date']}, "
        f"{res['elapsed']:.0f} s in all",
        *(f"- {note}" for note in notes),
        "",
        *table_lines(COLUMNS, rows),
    ]
    return "\n".join(lines) + "\n"


def write_outputs(out_dir: str, name: str, text: str, res: dict) -> tuple[str, str]:
    """``NAME.md`` and ``NAME.json`` in ``out_dir``; their paths.

    ``res`` must start with the :func:`header` (machine, software, commit, command, date)
    and hold its figures as ``rows`` (the table's rows).
    """
    missing = [key for key in HEADER_KEYS if key not in res]
    if missing:
        raise ValueError(f"the result lacks the header keys {missing} (see report.header)")
    if not isinstance(res.get("rows"), list):
        raise ValueError("the result lacks its figures, res['rows'] (what docs/benchmarks.md "
                         "and the README's summary are made from)")
    os.makedirs(out_dir, exist_ok=True)
    md = os.path.join(out_dir, f"{name}.md")
    js = os.path.join(out_dir, f"{name}.json")
    with open(md, "w") as f:
        f.write(text)
    with open(js, "w") as f:
        json.dump(res, f, indent=1, default=str)
    return md, js

