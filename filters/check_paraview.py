"""Check the ParaView plugin in a real ParaView client (pvpython; ``.ci/paraview`` runs it).

    xvfb-run -a pvpython filters/check_paraview.py --bunny BUNNY.obj [--out DIR]

``fancloud_vtk`` must be importable by pvpython and, on ParaView 5.11 with Python 3.11,
``filters/`` must come first on ``PYTHONPATH`` (``sitecustomize.py``): see
``filters/README.md``. The bunny is a path (pymeshlab's ``bunny.obj``) so that pymeshlab
need not be importable here.

What is checked, each a PASS/FAIL line:

1. the plugin loads; every proxy has exactly its ``VERB_PARAMS`` table as properties
   (plus the front's camera), in the table's order, with its ranges, and a new
   proxy's algorithm holds the table's defaults;
2. reader -> Fan Cloud -> Fan Cloud Mesh -> Fan Cloud Reduce -> Fan Cloud Refine on
   the bunny: every output (``servermanager.Fetch``) is bit-identical to the same
   filters run directly through ``fancloud_vtk.algorithms`` in this process (points,
   cells, point, cell and field arrays);
3. a property changed through the proxy (Reduce ``Keep``) re-executes Reduce and
   Refine, again bit-identical to the direct filters;
4. a filter's error (Selective Refine without a region) leaves an empty output and
   the exception on the algorithm (pvpython itself would exit 0);
5. the view-dependent front follows the camera (``follow_view``): moving the camera
   changes the front, bit-identical to the direct filter for the same cameras;
6. a screenshot (under ``xvfb-run``) is not blank;
7. a state file (.pvsm) loaded in a fresh pvpython gives the same outputs.

Prints ``PASS`` or ``FAIL`` at the end and exits non-zero on failure: pvpython exits 0
after an exception inside ``RequestData``, so every output is checked, never assumed.
Writes ``chain.png``, ``chain.pvsm``, ``trace.py`` and ``expected.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
PLUGIN = os.path.join(HERE, "fancloud_paraview.py")

#: the chain: (registration name, paraview.simple function, verb, parameters set)
CHAIN = (
    ("Fans", "FanCloud", "fans", {}),
    ("Mesh", "FanCloudMesh", "mesh", {}),
    ("Reduce", "FanCloudReduce", "reduce", {"keep": 0.25}),
    ("Refine", "FanCloudRefine", "refine", {"factor": 2.0}),
)
#: the property changed through the proxy (stage, parameter, new value)
CHANGE = ("Reduce", "keep", 0.3)
SIZE = (800, 600)

RESULTS: list[tuple[str, bool, str]] = []


def check(name: str, ok: bool, detail: str = "") -> bool:
    RESULTS.append((name, bool(ok), detail))
    print(f"  {'ok  ' if ok else 'FAIL'} {name}" + (f": {detail}" if detail else ""), flush=True)
    return bool(ok)


def guarded(name: str, func, *args):
    """Run one step; an exception is a failed check, and the next steps still run."""
    try:
        return func(*args)
    except Exception as exc:  # a failed step must not hide the others
        traceback.print_exc()
        check(name, False, f"{type(exc).__name__}: {exc}")
        return None


def finish() -> None:
    failed = [name for name, ok, _ in RESULTS if not ok]
    print("=" * 72)
    if failed or not RESULTS:
        print(f"FAIL: {len(failed)} of {len(RESULTS)} checks failed: {', '.join(failed)}")
    else:
        print(f"PASS: all {len(RESULTS)} checks passed")
    print("=" * 72, flush=True)
    sys.stderr.flush()
    # os._exit: the status is ours, whatever ParaView's finalisation does
    os._exit(1 if failed or not RESULTS else 0)


# -- fingerprints of VTK data ----------------------------------------------------------------


def _digest(array) -> str:
    import numpy as np

    a = np.ascontiguousarray(array)
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()[:20]


def fingerprint(data) -> dict:
    """Counts and a hash of every array (points, cells, point/cell/field data) of polydata."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    out = {"n_points": data.GetNumberOfPoints(), "n_cells": data.GetNumberOfCells()}
    if data.GetPoints() is not None:
        out["points"] = _digest(vtk_to_numpy(data.GetPoints().GetData()))
    for kind in ("Verts", "Lines", "Polys", "Strips"):
        cells = getattr(data, "Get" + kind)()
        if cells is not None and cells.GetNumberOfCells():
            out[kind.lower()] = _digest(vtk_to_numpy(cells.GetConnectivityArray())) + \
                _digest(vtk_to_numpy(cells.GetOffsetsArray()))
    for kind, attrs in (("point", data.GetPointData()), ("cell", data.GetCellData()),
                        ("field", data.GetFieldData())):
        for i in range(attrs.GetNumberOfArrays()):
            arr = attrs.GetAbstractArray(i)
            key = f"{kind}:{arr.GetName()}"
            if arr.IsA("vtkDataArray"):
                out[key] = _digest(vtk_to_numpy(arr))
            else:  # a string array
                values = [arr.GetValue(j) for j in range(arr.GetNumberOfValues())]
                out[key] = hashlib.sha256("\0".join(values).encode()).hexdigest()[:20]
    return out


def same(name: str, got: dict, want: dict) -> bool:
    differ = sorted(k for k in set(got) | set(want) if got.get(k) != want.get(k))
    counts = f"{got.get('n_points')} points, {got.get('n_cells')} cells"
    if differ:
        return check(name, False, f"{counts} (direct: {want.get('n_points')} points, "
                                  f"{want.get('n_cells')} cells); differ: {', '.join(differ)}")
    arrays = len([k for k in got if ":" in k])
    return check(name, True, f"{counts}, {arrays} arrays, bit-identical")


# -- the checks -------------------------------------------------------------------------------


def load_plugin(ns):
    from paraview.simple import LoadPlugin

    LoadPlugin(PLUGIN, ns=ns)
    module = sys.modules.get("fancloud_paraview")
    ok = module is not None and all(name in ns for _, name, _, _ in CHAIN)
    check("plugin loads", ok, f"{PLUGIN}; fancloud_vtk from "
          f"{os.path.dirname(sys.modules['fancloud_vtk'].__file__)}")
    return module


def check_declarations(module, reader, ns):
    """Real ParaView's view of the generated properties: names, order, ranges, defaults."""
    from paraview import servermanager as sm

    from fancloud_vtk.params import VERB_PARAMS

    camera = [name for name, *_ in module.CAMERA_PROPERTIES]
    for verb, cls in module.PROXIES.items():
        label = cls.PV_LABEL
        func = label.replace(" ", "").replace("-", "")  # paraview.simple's name for it
        proxy = ns[func](Input=reader)
        table = VERB_PARAMS[verb]
        want = [p.vtk_name for p in table] + (camera if verb == "vdfc" else [])
        it = sm.vtkSMOrderedPropertyIterator()
        it.SetProxy(proxy.SMProxy)
        it.Begin()
        order = []
        while not it.IsAtEnd():
            if it.GetKey() not in ("Input", "Reload Python Module"):
                order.append(it.GetKey())
            it.Next()
        problems = [] if order == want else [f"properties {order} != {want}"]
        for p in table:
            prop = proxy.GetProperty(p.vtk_name).SMProperty
            if p.range is None or p.kind not in ("int", "float", "vector"):
                continue
            dom = prop.FindDomain("vtkSMIntRangeDomain" if p.kind == "int"
                                  else "vtkSMDoubleRangeDomain")
            hi = min(p.range[1], module.INT_MAX) if p.kind == "int" else p.range[1]
            for i in range(p.size if p.kind == "vector" else 1):
                if (dom.GetMinimum(i), dom.GetMaximum(i)) != (p.range[0], hi):
                    problems.append(f"{p.vtk_name} range {dom.GetMinimum(i)}..{dom.GetMaximum(i)}")
        algorithm = proxy.GetClientSideObject()
        defaults = {p.name: p.default for p in table}
        if algorithm.parameters != defaults:
            wrong = {k: v for k, v in algorithm.parameters.items() if defaults[k] != v}
            problems.append(f"algorithm parameters after creation differ: {wrong}")
        check(f"{label}: properties are VERB_PARAMS[{verb!r}]", not problems,
              "; ".join(problems) or f"{len(want)} properties in the table's order, ranges, "
              "defaults reach the algorithm")
        from paraview.simple import Delete

        Delete(proxy)


def build_chain(reader, ns):
    from fancloud_vtk.params import VERB_PARAMS

    proxies, upstream = {}, reader
    for name, func, verb, params in CHAIN:
        names = {p.name: p.vtk_name for p in VERB_PARAMS[verb]}
        kwargs = {names[k]: v for k, v in params.items()}
        proxies[name] = ns[func](registrationName=name, Input=upstream, **kwargs)
        upstream = proxies[name]
    return proxies


def build_direct(source):
    """The same chain run directly through fancloud_vtk.algorithms."""
    from fancloud_vtk import algorithms as A

    classes = {"fans": A.FanCloudFilter, "mesh": A.FanCloudMeshFilter,
               "reduce": A.FanCloudReduceFilter, "refine": A.FanCloudRefineFilter}
    algs, upstream = {}, None
    for name, _, verb, params in CHAIN:
        alg = classes[verb](**params)
        if upstream is None:
            alg.SetInputDataObject(source)
        else:
            alg.SetInputConnection(upstream.GetOutputPort())
        algs[name] = upstream = alg
    return algs


def compare_chain(proxies, algs, what: str) -> dict:
    from paraview import servermanager

    from fancloud_vtk.algorithms import run

    t0 = time.perf_counter()
    for proxy in proxies.values():
        proxy.UpdatePipeline()
    t_pv = time.perf_counter() - t0
    t0 = time.perf_counter()
    run(list(algs.values())[-1])
    t_direct = time.perf_counter() - t0
    print(f"  ({what}: ParaView {t_pv:.1f} s, direct {t_direct:.1f} s)", flush=True)
    prints = {}
    for name in proxies:
        got = fingerprint(servermanager.Fetch(proxies[name]))
        prints[name] = fingerprint(algs[name].GetOutputDataObject(0))
        same(f"{what}: {name} (Fetch) == direct", got, prints[name])
    return prints


def change_property(proxies, algs, before: dict) -> dict:
    stage, param, value = CHANGE
    from fancloud_vtk.params import VERB_PARAMS

    verb = {name: verb for name, _, verb, _ in CHAIN}[stage]
    vtk_name = {p.name: p.vtk_name for p in VERB_PARAMS[verb]}[param]
    setattr(proxies[stage], vtk_name, value)
    setattr(algs[stage], param, value)
    after = compare_chain(proxies, algs, f"{stage}.{vtk_name} = {value}")
    for name in (stage, CHAIN[-1][0]):
        check(f"{name} re-executed after the change",
              after[name]["n_points"] != before[name]["n_points"],
              f"{before[name]['n_points']} -> {after[name]['n_points']} points")
    return after


def check_error(ns, upstream):
    from paraview import servermanager
    from paraview.simple import Delete

    sel = ns["FanCloudSelectiveRefine"](Input=upstream)  # RegionRadius 0: an error
    sel.UpdatePipeline()
    error = sel.GetClientSideObject().last_error
    n = servermanager.Fetch(sel).GetNumberOfPoints()
    check("an error inside RequestData leaves an empty output", n == 0 and error is not None,
          f"{n} points; last_error = {type(error).__name__}: {error}")
    Delete(sel)


def check_front(module, ns, mesh_proxy, mesh_direct, view):
    """The front follows the view's camera; each front equals the direct filter's."""
    from paraview import servermanager
    from paraview.simple import Hide, Render, ResetCamera, Show

    from fancloud_vtk.algorithms import FanCloudViewDependentFilter, run

    Show(mesh_proxy, view)
    ResetCamera(view)
    Render(view)  # the first Render of a session resets the camera: done before following
    front = ns["FanCloudViewDependentFront"](registrationName="Front", Input=mesh_proxy)
    module.follow_view(front, view)
    front.UpdatePipeline()
    direct = FanCloudViewDependentFilter()
    direct.SetInputConnection(mesh_direct.GetOutputPort())

    def camera_of(proxy):
        return (tuple(proxy.CameraPosition), tuple(proxy.CameraFocalPoint),
                tuple(proxy.CameraViewUp), float(proxy.CameraViewAngle))

    def direct_front():
        direct.SetCamera(camera_of(front))
        direct.aspect = float(front.Aspect)
        return fingerprint(run(direct))

    far = fingerprint(servermanager.Fetch(front))
    same("front, camera 1 (follow_view) == direct", far, direct_front())
    stop = module.follow_view(front, view, live=True)
    Hide(mesh_proxy, view)
    Show(front, view)
    position = [p + 0.8 * (f - p) for p, f in zip(view.CameraPosition, view.CameraFocalPoint,
                                                  strict=True)]
    view.CameraPosition = position  # 5 times nearer: the live observer copies it
    Render(view)
    near = fingerprint(servermanager.Fetch(front))
    check("the front follows the camera (live)", camera_of(front)[0] == tuple(position),
          f"front camera {camera_of(front)[0]}")
    check("moving the camera changes the front", near["n_points"] != far["n_points"],
          f"{far['n_points']} -> {near['n_points']} active points")
    same("front, camera 2 == direct", near, direct_front())
    stop()
    fresh = FanCloudViewDependentFilter()
    fresh.SetInputConnection(mesh_direct.GetOutputPort())
    fresh.SetCamera(camera_of(front))
    fresh.aspect = float(front.Aspect)
    Hide(front, view)
    return front, fingerprint(run(fresh))


def screenshot(view, proxy, path):
    import numpy as np
    from paraview.simple import ResetCamera, SaveScreenshot, Show
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOImage import vtkPNGReader

    display = Show(proxy, view)
    display.SetRepresentationType("Surface With Edges")
    display.ColorArrayName = ["POINTS", ""]  # a solid colour
    display.DiffuseColor = [0.87, 0.72, 0.53]
    display.EdgeColor = [0.25, 0.2, 0.15]
    view.OrientationAxesVisibility = 0
    view.CameraPosition = [0.0, 0.12, 0.55]
    view.CameraFocalPoint = [0.0, 0.12, 0.0]
    view.CameraViewUp = [0.0, 1.0, 0.0]
    ResetCamera(view)
    SaveScreenshot(path, view, ImageResolution=list(SIZE))
    reader = vtkPNGReader()
    reader.SetFileName(path)
    reader.Update()
    image = reader.GetOutput()
    w, h, _ = image.GetDimensions()
    pixels = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(h, w, -1)[..., :3]
    background = pixels[0, 0]
    covered = float(np.mean(np.any(pixels != background, axis=-1)))
    colours = len(np.unique(pixels.reshape(-1, 3), axis=0))
    check("the screenshot is not blank", covered > 0.05 and colours > 16,
          f"{path}: {w}x{h}, {100 * covered:.1f}% of the pixels drawn, {colours} colours")


def save_trace(path, text):
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    print(f"  (trace of the chain: {path})")


def check_state(args, pvsm, expected):
    """Load the state in a fresh pvpython and compare its outputs."""
    cmd = [args.pvpython, os.path.abspath(__file__), "--state", pvsm, "--expect", expected]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    lines = [line for line in proc.stdout.splitlines() if line.strip()]
    for line in lines:
        if line.lstrip().startswith(("ok", "FAIL")):
            print("    [fresh pvpython]" + line)
    ok = proc.returncode == 0 and any(line.startswith("PASS") for line in lines)
    if not ok:
        print(proc.stdout[-4000:], proc.stderr[-4000:], sep="\n")
    check("the state file loads in a fresh pvpython with the same outputs", ok,
          f"{pvsm}, exit {proc.returncode}, {time.perf_counter() - t0:.0f} s")


def main_check(args) -> None:
    import paraview.simple as simple
    from paraview import servermanager

    print(f"check_paraview: ParaView {servermanager.vtkSMProxyManager.GetParaViewSourceVersion()}"
          f", Python {sys.version.split()[0]}", flush=True)
    ns = vars(simple).copy()
    module = load_plugin(ns)
    import numba
    import numpy
    import scipy
    from vtkmodules.vtkCommonCore import vtkVersion

    print(f"  (numpy {numpy.__version__}, scipy {scipy.__version__}, numba {numba.__version__}, "
          f"VTK {vtkVersion.GetVTKVersion()})", flush=True)
    os.makedirs(args.out, exist_ok=True)
    from paraview import smtrace

    smtrace.start_trace()
    reader = simple.OpenDataFile(args.bunny)
    simple.RenameSource("Bunny", reader)
    reader.UpdatePipeline()
    proxies = build_chain(reader, ns)
    source = servermanager.Fetch(reader)
    check("the bunny is read", source.GetNumberOfPoints() > 0,
          f"{args.bunny}: {source.GetNumberOfPoints()} points, {source.GetNumberOfCells()} cells")
    algs = build_direct(source)
    before = guarded("chain", compare_chain, proxies, algs, "chain")
    after = guarded("property change", change_property, proxies, algs, before) \
        if before else None
    save_trace(os.path.join(args.out, "trace.py"), smtrace.stop_trace())
    guarded("declarations", check_declarations, module, reader, ns)
    guarded("error", check_error, ns, proxies["Mesh"])

    view = simple.CreateView("RenderView")
    view.ViewSize = list(SIZE)
    simple.SetActiveView(view)
    result = guarded("front", check_front, module, ns, proxies["Mesh"], algs["Mesh"], view)
    png = os.path.join(args.out, "chain.png")
    guarded("screenshot", screenshot, view, proxies["Refine"], png)

    pvsm = os.path.join(args.out, "chain.pvsm")
    simple.SaveState(pvsm)
    if after and result:
        expected = dict(after)
        expected["Front"] = result[1]
        path = os.path.join(args.out, "expected.json")
        with open(path, "w", encoding="utf-8") as fh:
            json.dump(expected, fh, indent=1)
        guarded("state", check_state, args, pvsm, path)
    else:
        check("the state file loads in a fresh pvpython with the same outputs", False,
              "not run: an earlier step failed")
    finish()


def main_warm(args) -> None:
    """Compile the kernels the check runs, with no ParaView and no X server: the direct
    chain and a front on the bunny. numba caches them beside the installed package, where
    pvpython finds them, so the check's X server is not kept waiting for minutes (a first
    run once lost it after 325 s of compiling: "bad X server connection")."""
    from vtkmodules.vtkIOGeometry import vtkOBJReader

    from fancloud_vtk.algorithms import FanCloudViewDependentFilter, run

    t0 = time.perf_counter()
    reader = vtkOBJReader()
    reader.SetFileName(args.bunny)
    reader.Update()
    algs = build_direct(reader.GetOutput())
    run(list(algs.values())[-1])
    x0, x1, y0, y1, z0, z1 = algs["Mesh"].GetOutputDataObject(0).GetBounds()
    centre = (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * (z0 + z1))
    reach = 3.0 * max(x1 - x0, y1 - y0, z1 - z0)
    front = FanCloudViewDependentFilter()
    front.SetInputConnection(algs["Mesh"].GetOutputPort())
    front.SetCamera(((centre[0], centre[1], centre[2] + reach), centre, (0.0, 1.0, 0.0),
                     30.0))
    run(front)
    print(f"check_paraview --warm: the chain and a front compiled and run in "
          f"{time.perf_counter() - t0:.1f} s", flush=True)


def main_state(args) -> None:
    """The fresh-process half: load the plugin and the state, compare with --expect."""
    import paraview.simple as simple
    from paraview import servermanager

    ns = vars(simple).copy()
    load_plugin(ns)
    simple.LoadState(args.state)
    with open(args.expect, encoding="utf-8") as fh:
        expected = json.load(fh)
    for name, want in expected.items():
        proxy = simple.FindSource(name)
        if not check(f"{name} is in the state", proxy is not None):
            continue
        proxy.UpdatePipeline()
        same(f"{name} from the state == first run", fingerprint(servermanager.Fetch(proxy)),
             want)
    finish()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bunny", help="the bunny mesh (pymeshlab's bunny.obj)")
    parser.add_argument("--out", default=os.path.join(tempfile.gettempdir(),
                                                      "fancloud-paraview"))
    parser.add_argument("--pvpython", default=shutil.which("pvpython") or "pvpython")
    parser.add_argument("--warm", action="store_true",
                        help="only compile the kernels (no ParaView, no X server) and exit")
    parser.add_argument("--state", help=argparse.SUPPRESS)
    parser.add_argument("--expect", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.warm:
        main_warm(args)
        return
    try:
        if args.state:
            main_state(args)
        elif not args.bunny:
            parser.error("--bunny is required")
        else:
            args.bunny = os.path.abspath(args.bunny)  # the state file keeps the path
            main_check(args)
    except SystemExit:
        raise
    except BaseException as exc:
        traceback.print_exc()
        check("check_paraview", False, f"{type(exc).__name__}: {exc}")
    finish()


if __name__ == "__main__":
    main()
