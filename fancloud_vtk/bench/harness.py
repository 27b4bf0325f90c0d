"""The subprocesses of every benchmark, and the timing of the ones in this process.

One child entry point, :func:`child_main` (the command :data:`_CHILD`), in two modes:

``task LOADER PARAMS-JSON``
    Call ``LOADER`` (``module:function``) with the parameters once and print its
    result as JSON on stdout (:func:`run_task`: the fresh processes of ``bench fans``:
    memory, thread counts).
``run SPEC-JSON``
    Run one method of a comparison (:mod:`fancloud_vtk.bench.peers`): load it (an
    :class:`ImportError` there means it is missing), warm it up on a small input,
    then for every target ``repeat`` timed runs; ``result.json`` is rewritten before
    and after every timed run and the first result of each target is saved as
    ``out_I.npz``, so a method that is missing, raises, crashes (a segfault) or
    hangs is reported as such instead of taking the benchmark down. The spec's
    ``kind`` says how a method is called: ``mesh`` (``run(points)``, the input an
    ``.npy``, warmed up on ``warmup`` sphere points, one target) or ``reduce``
    (``run(data, target)``, the input an ``.npz`` of :func:`save_reduce_data`,
    warmed up on the ``warmup`` file, one target per vertex count).

The parent side runs a child with a timeout in its own environment
(:func:`child_env`: this package first on the path) and reads back what it wrote:
:func:`run_method` (``bench mesh``) and :func:`run_reduce_method` (``bench
reduce``) give one result per target with a ``status`` (``ok``, ``missing``,
``failed``, ``crashed``, ``timeout``) and a ``message`` for the tables;
:func:`run_python` runs a code string (the first call of ``bench fans``, timed
before anything of the package is imported). :func:`timed` times a call in this
process (``bench fans``, ``refine``, ``vdfc``: best of their repeats).
"""

from __future__ import annotations

import gc
import json
import os
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass

import numpy as np

from fancloud_vtk.bench.common import _plain, _short, surface_points

CHILD_TIMEOUT = 900  #: seconds allowed to one task subprocess (:func:`run_task`)

_CHILD = ("import sys; from fancloud_vtk.bench.harness import child_main; "
          "sys.exit(child_main(sys.argv[1:]))")


# -- timing in this process --------------------------------------------------------------


def timed(fn, *args, **kwargs) -> float:
    """Seconds of one call of ``fn`` (garbage collected first; the result dropped)."""
    gc.collect()
    t0 = time.perf_counter()
    result = fn(*args, **kwargs)
    elapsed = time.perf_counter() - t0
    del result
    return elapsed


# -- the environment, code strings and tasks ---------------------------------------------


def child_env(**extra) -> dict:
    """The environment of a subprocess: this package first on the path, plus ``extra``."""
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    env.update({key: str(value) for key, value in extra.items()})
    return env


def run_python(code: str, args: list[str], env: dict, timeout: float = CHILD_TIMEOUT,
               label: str | None = None) -> dict:
    """Run ``python -c code args`` in a fresh process; its last stdout line as JSON."""
    proc = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True,
                          text=True, timeout=timeout, check=False)
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        what = [label] if label else args[:1]
        raise RuntimeError(f"benchmark subprocess {what} failed (exit {proc.returncode}):\n"
                           + proc.stderr[-3000:])
    return json.loads(lines[-1])


def run_task(loader: str, params: dict, **env) -> dict:
    """``loader(**params)`` (a ``module:function``) in a fresh process, ``env`` added."""
    return run_python(_CHILD, ["task", loader, json.dumps(params)], child_env(**env),
                      label=loader.rpartition(":")[2])


# -- the data of the reduction methods -----------------------------------------------------


def load_reduce_data(path: str) -> dict:
    """The ``data`` dict of a reduction loader from the ``.npz`` the benchmark wrote."""
    with np.load(path) as z:
        colors = z["colors"]
        return {"points": z["points"], "triangles": z["triangles"],
                "colors": colors if len(colors) else None,
                "from_points": bool(z["from_points"])}


def save_reduce_data(path: str, points, triangles, colors, from_points: bool) -> None:
    """Write what :func:`load_reduce_data` reads."""
    np.savez(path, points=np.ascontiguousarray(points, np.float64),
             triangles=np.ascontiguousarray(triangles, np.int64),
             colors=np.zeros((0, 3), np.uint8) if colors is None else np.asarray(colors),
             from_points=np.bool_(from_points))


# -- the child -------------------------------------------------------------------------------


def _import_loader(path: str):
    import importlib

    module, _, attr = path.partition(":")
    return getattr(importlib.import_module(module), attr)


def _write_json(path: str, data: dict) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(data, f, default=str)
    os.replace(tmp, path)


def _load_method(loader: str, res: dict, result_path: str):
    """The method's run function, or None after writing why it is missing or failed."""
    try:
        return _import_loader(loader)()
    except ImportError as exc:
        res.update(status="missing", error=_short(exc))
    except Exception as exc:
        res.update(status="failed", error="loading: " + _short(exc),
                   traceback=traceback.format_exc()[-3000:])
    _write_json(result_path, res)
    return None


def _warm_up(kind: str, run, warmup, res: dict) -> bool:
    """Run the method once on the warm-up input; False when that ends the child.

    A mesh method that fails on the warm-up sphere has failed; a reducer's warm-up
    error is kept (``warmup_error``) and its timed runs report it.
    """
    if kind == "mesh":
        if not warmup:
            return True
        try:
            t0 = time.perf_counter()
            run(surface_points(int(warmup), 1, "sphere"))
            res["warmup_time"] = time.perf_counter() - t0
            res["warmup_points"] = int(warmup)
        except Exception as exc:
            res.update(status="failed", error=_short(exc),
                       traceback=traceback.format_exc()[-3000:])
            return False
        return True
    if warmup:
        warm = load_reduce_data(warmup)
        t0 = time.perf_counter()
        try:
            run(warm, max(4, int(0.3 * len(warm["points"]))))
        except Exception as exc:  # the timed runs will report it
            res["warmup_error"] = _short(exc)
        res["warmup_time"] = time.perf_counter() - t0
    return True


def _save_output(out: dict, path: str) -> None:
    arrays = {"vertices": np.asarray(out["vertices"], dtype=np.float64),
              "triangles": np.asarray(out["triangles"], dtype=np.int64).reshape(-1, 3)}
    for key in ("colors", "original_id"):
        if out.get(key) is not None:
            arrays[key] = np.asarray(out[key])
    tmp = path[: -len(".npz")] + ".tmp.npz"
    np.savez(tmp, **arrays)
    os.replace(tmp, path)


def _run_child(spec: dict) -> int:
    """The ``run`` mode of :func:`child_main`: one method, every target, ``result.json``."""
    kind, out_dir, repeat = spec["kind"], spec["out_dir"], int(spec["repeat"])
    if kind not in ("mesh", "reduce"):
        raise ValueError(f"unknown kind {kind!r}")
    result_path = os.path.join(out_dir, "result.json")
    res = {"name": spec["name"], "status": "running", "runs": []}
    run = _load_method(spec["loader"], res, result_path)
    if run is None:
        return 0
    if kind == "mesh":
        data, targets = np.load(spec["input"]), [None]
    else:
        data, targets = load_reduce_data(spec["input"]), [int(t) for t in spec["targets"]]
    if not _warm_up(kind, run, spec.get("warmup"), res):
        _write_json(result_path, res)
        return 0
    _write_json(result_path, res)
    for i, target in enumerate(targets):
        r = {"target": target, "times": [], "calls": [], "status": "running"}
        res["runs"].append(r)
        try:
            for j in range(repeat):
                res["timed_start_epoch"] = time.time()
                _write_json(result_path, res)
                t0 = time.perf_counter()
                out = run(data) if kind == "mesh" else run(data, target)
                call = time.perf_counter() - t0
                r["calls"].append(call)
                r["times"].append(float(out.get("time", call)))
                if j == 0:
                    _save_output(out, os.path.join(out_dir, f"out_{i}.npz"))
                    r["new_points"] = bool(out.get("new_points", False))
                    r["info"] = _plain(out.get("info", {}))
                del out
                if j < repeat - 1:
                    _write_json(result_path, res)
            r["status"] = "ok"
        except Exception as exc:
            r.update(status="failed", error=_short(exc),
                     traceback=traceback.format_exc()[-3000:])
        _write_json(result_path, res)
    res["status"] = "ok"
    _write_json(result_path, res)
    return 0


def child_main(argv: list[str]) -> int:
    """Entry of every subprocess: ``task LOADER PARAMS-JSON`` or ``run SPEC-JSON``."""
    mode = argv[0]
    if mode == "task":
        print(json.dumps(_import_loader(argv[1])(**json.loads(argv[2]))))
        return 0
    if mode == "run":
        return _run_child(json.loads(argv[1]))
    raise ValueError(f"unknown mode {mode!r}: task or run")


# -- the parent side ---------------------------------------------------------------------------


@dataclass
class _Child:
    """What a method's process left: exit code (None: killed at the timeout), result.json."""

    out_dir: str
    err_path: str
    code: int | None
    wall: float
    ended_epoch: float
    result: dict


def _spawn(method, kind: str, work_dir: str, timeout: float, **spec) -> _Child:
    """Run one method in a fresh process (``child_main run``) with a timeout."""
    out_dir = tempfile.mkdtemp(prefix=f"{method.name.replace(':', '_')}-", dir=work_dir)
    err_path = os.path.join(out_dir, "stderr.txt")
    spec = {**spec, "kind": kind, "name": method.name, "loader": method.loader,
            "out_dir": out_dir}
    cmd = [sys.executable, "-X", "faulthandler", "-c", _CHILD, "run", json.dumps(spec)]
    t0 = time.perf_counter()
    with open(os.path.join(out_dir, "stdout.txt"), "w") as out, open(err_path, "w") as err:
        try:
            code = subprocess.run(cmd, env=child_env(), stdout=out, stderr=err,
                                  timeout=timeout, check=False).returncode
        except subprocess.TimeoutExpired:
            code = None
    wall, ended = time.perf_counter() - t0, time.time()
    result = {}
    result_path = os.path.join(out_dir, "result.json")
    if os.path.isfile(result_path):
        with open(result_path) as f:
            result = json.load(f)
    return _Child(out_dir, err_path, code, wall, ended, result)


def _signal_name(code: int) -> str:
    import signal

    try:
        return signal.Signals(-code).name
    except ValueError:
        return f"signal {-code}"


def _last_line(path: str) -> str:
    """The last line of a child's stderr, or faulthandler's ``Fatal Python error`` line."""
    with open(path, errors="replace") as f:
        lines = [line.strip() for line in f.read().splitlines() if line.strip()]
    fatal = [line for line in lines if line.startswith("Fatal Python error")]
    return (fatal or lines or ["no output on stderr"])[-1][:300]


def _child_status(method, code, child: dict, err_path: str, timeout: float, times: list,
                  repeat: int, requires: dict) -> tuple[str, str]:
    """``(status, message)`` of a method's process from its exit code and ``result.json``.

    ``status`` is ``ok``, ``missing``, ``failed``, ``crashed`` or ``timeout``;
    ``times`` are the timed runs that finished (a timeout after one is ``ok``).
    """
    phase = "while timed" if child.get("timed_start_epoch") else "while loading or warming up"
    if code is None:
        if not times:
            return "timeout", f"timed out after {timeout:g} s ({phase})"
        return "ok", f"ok ({len(times)} of {repeat} runs before the {timeout:g} s timeout)"
    if code < 0:
        return "crashed", f"crashed ({_signal_name(code)}, {phase}): {_last_line(err_path)}"
    if child.get("status") == "missing":
        need = requires.get(method.name, method.loader)
        return "missing", f"missing: {need} not available ({child['error']})"
    if child.get("status") == "failed":
        return "failed", f"failed: {child['error']}"
    if code != 0 or child.get("status") != "ok":
        return "failed", f"failed (exit {code}): {_last_line(err_path)}"
    return "ok", "ok"


def run_method(method, points_path: str, work_dir: str, *, timeout: float, repeat: int = 1,
               warmup: int | None = None) -> dict:
    """Run one surface-reconstruction method (``bench mesh``) in a fresh process.

    ``warmup`` sphere points first (default :data:`~fancloud_vtk.bench.common.WARMUP_POINTS`,
    0: none), then ``repeat`` timed runs on the points of ``points_path`` (``.npy``).
    Returns ``status`` (``ok``, ``missing``, ``failed``, ``crashed`` or ``timeout``),
    ``message`` (for the table), the timed runs and, when a run finished, the mesh
    (``vertices``, ``triangles``).
    """
    from fancloud_vtk.bench.common import WARMUP_POINTS
    from fancloud_vtk.bench.peers import REQUIRES

    warmup = WARMUP_POINTS if warmup is None else warmup
    c = _spawn(method, "mesh", work_dir, timeout, input=points_path, warmup=warmup,
               repeat=repeat)
    child, code = c.result, c.code
    run = (child.get("runs") or [{}])[0]
    times = run.get("times", [])
    res = {"method": method.name, "label": method.label, "call": method.call,
           "new_points": bool(run.get("new_points", method.new_points)), "times": times,
           "time": min(times) if times else None, "warmup_time": child.get("warmup_time"),
           "wall_time": c.wall, "exit_code": code, "info": run.get("info", {})}
    started = child.get("timed_start_epoch")
    if code is None and started and not times:  # the timed run took at least this long
        res["time_lower_bound"] = c.ended_epoch - started
    # one target: the process's status is the run's, unless loading or warming up ended it
    view = child if child.get("status") in ("missing", "failed") else {
        **child, "status": run.get("status", "running"), "error": run.get("error"),
        "traceback": run.get("traceback")}
    status, message = _child_status(method, code, view, c.err_path, timeout, times, repeat,
                                    REQUIRES)
    if status == "failed" and view.get("traceback"):
        res["traceback"] = view["traceback"]
    res.update(status=status, message=message)
    mesh_path = os.path.join(c.out_dir, "out_0.npz")
    if status == "ok" and os.path.isfile(mesh_path):
        with np.load(mesh_path) as z:
            res["vertices"], res["triangles"] = z["vertices"], z["triangles"]
    elif status == "ok":
        res.update(status="failed", message="failed: the method wrote no mesh")
    return res


def run_reduce_method(method, data_path: str, warmup_path: str | None, work_dir: str,
                      targets: list[int], *, timeout: float, repeat: int = 1) -> list[dict]:
    """Run one reducer (``bench reduce``) on every target in a fresh process, one timeout.

    One dict per target: ``status`` (``ok``, ``missing``, ``failed``,
    ``crashed``, ``timeout``), ``message``, ``time`` (best of the timed runs),
    ``times`` and, when it finished, the result's arrays (``vertices``,
    ``triangles``, and ``colors`` / ``original_id`` when the method gave them).
    Targets not reached (a timeout or crash before them) say so.
    """
    from fancloud_vtk.bench.peers import REDUCE_REQUIRES

    c = _spawn(method, "reduce", work_dir, timeout, input=data_path, warmup=warmup_path,
               repeat=repeat, targets=[int(t) for t in targets])
    child, code = c.result, c.code
    runs = child.get("runs", [])
    results = []
    for i, target in enumerate(targets):
        run = runs[i] if i < len(runs) else {}
        times = run.get("times", [])
        res = {"method": method.name, "label": method.label, "call": method.call,
               "target": target, "times": times, "time": min(times) if times else None,
               "calls": run.get("calls", []), "info": run.get("info", {}),
               "warmup_time": child.get("warmup_time"), "process_wall_time": c.wall,
               "exit_code": code}
        path = os.path.join(c.out_dir, f"out_{i}.npz")
        npz = os.path.isfile(path)
        if run.get("status") == "ok":
            status, message = "ok", "ok"
        elif run.get("status") == "failed":
            status, message = "failed", f"failed: {run['error']}"
            res["traceback"] = run.get("traceback")
        elif run and times and npz:  # killed after some of the repeats
            status, message = "ok", f"ok ({len(times)} of {repeat} runs before the process ended)"
        elif run or not runs:  # the target running when the process ended, or none ran
            status, message = _child_status(method, code, child, c.err_path, timeout, [],
                                            repeat, REDUCE_REQUIRES)
            if status == "ok":
                status, message = "failed", f"failed (exit {code}): the target did not finish"
            if run and status == "timeout" and child.get("timed_start_epoch"):
                res["time_lower_bound"] = c.ended_epoch - child["timed_start_epoch"]
        else:  # an earlier target took the process down
            status = "timeout" if code is None else "crashed" if code < 0 else "failed"
            what = {"timeout": f"timed out ({timeout:g} s for all targets)",
                    "crashed": "crashed"}.get(status, f"exited ({code})")
            message = f"not run: the process {what} on an earlier target"
        res.update(status=status, message=message)
        if status == "ok" and npz:
            with np.load(path) as z:
                for key in z.files:
                    res[key] = z[key]
        elif status == "ok":
            res.update(status="failed", message="failed: the method wrote no result")
        results.append(res)
    return results


if __name__ == "__main__":  # pragma: no cover
    sys.exit(child_main(sys.argv[1:]))
