"""Smoke tests of ``fancloud bench fans`` and ``fancloud bench mesh`` on tiny sizes."""

import ast
import importlib.util
import json
import os
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

import fancloud_vtk
from fancloud_vtk.bench import parse_size, parse_sizes, size_label, surface_points
from fancloud_vtk.bench.report import COLUMNS, HEADER_KEYS
from fancloud_vtk.cli import main as cli_main


@pytest.mark.parametrize(
    ("text", "n"), [("5000", 5000), ("5k", 5000), ("100K", 100_000), ("4M", 4_000_000),
                    ("1.5M", 1_500_000)],
)
def test_parse_size(text, n):
    assert parse_size(text) == n
    assert parse_size(size_label(n)) == n


@pytest.mark.parametrize("text", ["", "abc", "0", "1.5k5", "0.5"])
def test_parse_size_rejects(text):
    with pytest.raises(ValueError):
        parse_size(text)


def test_parse_sizes():
    assert parse_sizes("100k, 1M,4M") == [100_000, 1_000_000, 4_000_000]


def test_surface_points_reproducible_and_shuffled():
    a = surface_points(3000, seed=1)
    assert np.array_equal(a, surface_points(3000, seed=1))
    assert not np.array_equal(a, surface_points(3000, seed=2))
    r = np.linalg.norm(surface_points(3000, seed=1, shape="sphere"), axis=1)
    assert np.allclose(r, 1.0)
    assert 0.85 < np.linalg.norm(a, axis=1).min() < np.linalg.norm(a, axis=1).max() < 1.15


def _table(text):
    """Header and rows of the Markdown table in ``text`` as lists of cells."""
    lines = [line for line in text.splitlines() if line.startswith("|")]
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in lines]
    return cells[0], cells[2:]


def _is_number(text):
    try:
        float(text.replace(",", ""))
    except ValueError:
        return False
    return True


def test_bench_fans_smoke(tmp_path, capsys):
    out = tmp_path / "bench"
    argv = ["bench", "fans", "--sizes", "5k", "--repeat", "1", "--check-size", "5k",
            "--no-cold-compile", "--out", str(out), "-q"]
    assert cli_main(argv) == 0

    md = out / "fans.md"
    assert md.is_file()
    text = md.read_text()
    assert text in capsys.readouterr().out
    for word in ("cores", "numpy", "scipy", "numba"):
        assert word in text
    header, rows = _table(text)
    assert tuple(header) == COLUMNS
    by_figure = {}
    for row in rows:
        assert len(row) == len(COLUMNS)
        by_figure.setdefault(row[0], []).append(dict(zip(COLUMNS, row, strict=True)))

    numeric = {
        "speed: peer": "s",
        "speed: build_fans": "s",
        "speed: ratio ours/peer": "x",
        "speed: throughput build_fans": "points/s",
        "memory: peak RSS growth during build_fans": "B/point",
        "memory: FanCloud.nbytes() / n": "B/point",
        "first call: build_fans": "s",
        "quality: open fans (closed surface)": "%",
    }
    for figure, unit in numeric.items():
        assert figure in by_figure, figure
        for row in by_figure[figure]:
            assert _is_number(row["measured"]), row
            assert float(row["measured"].replace(",", "")) >= 0
            assert row["unit"] == unit
    for row in by_figure["speed: peer"] + by_figure["memory: FanCloud.nbytes() / n"]:
        assert "5k random points" in row["data"]
    assert "first call: build_fans, cold compile" not in by_figure  # --no-cold-compile
    assert by_figure["first call: build_fans"][0]["verdict"] in (
        "cached", "compiled (cache cold/stale)")

    quality = by_figure["quality: open fans (closed surface)"]
    assert len(quality) == 4  # default and paper rule, on the 5k points and on the bunny
    assert sum("bunny" in row["data"] for row in quality) == 2
    assert sum("rule='paper'" in row["parameters"] for row in quality) == 2
    repro = by_figure["reproducibility: sha256 of offsets, ring, normals, open"]
    assert repro[0]["measured"] in ("identical", "different")
    assert "NUMBA_NUM_THREADS=1" in repro[0]["parameters"]
    assert "NUMBA_NUM_THREADS=2" in repro[0]["parameters"]

    raw = json.loads((out / "fans.json").read_text())
    _assert_header(raw, argv[1:])
    assert raw["args"]["sizes"] == [5000]
    assert len(raw["speed"][0]["ours_times"]) == 1
    assert raw["memory"][0]["peak"] >= raw["memory"][0]["rss_before"] > 0
    assert raw["machine"]["cores"] >= 1


def _assert_header(raw: dict, argv: list[str]) -> None:
    """The header every result JSON starts with (fancloud_vtk.bench.report.header)."""
    assert list(raw)[:len(HEADER_KEYS)] == list(HEADER_KEYS)
    assert raw["argv"] == argv
    assert raw["command"] == shlex.join(["fancloud", "bench", *argv])
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d.*", raw["date"])
    m = raw["machine"]
    assert m["cpu"] and m["cores"] >= 1 and m["memory_bytes"] > 0
    assert len(m["load_average"]) == 3
    sw = raw["software"]
    for key in ("python", "numpy", "scipy", "numba", "vtk", "fancloud_vtk"):
        assert sw[key], key
    commit = raw["commit"]
    assert commit is None or (re.fullmatch(r"[0-9a-f]{40}", commit["sha"])
                              and isinstance(commit["dirty"], bool))


def test_commit_of_this_checkout():
    from fancloud_vtk.bench.report import commit_info

    commit = commit_info()
    if not (Path(fancloud_vtk.__file__).parent.parent / ".git").exists():
        pytest.skip("not a git checkout")
    assert re.fullmatch(r"[0-9a-f]{40}", commit["sha"]) and commit["dirty"] in (True, False)


def test_bench_requires_a_mode(capsys):
    from fancloud_vtk.bench import main

    with pytest.raises(SystemExit):
        main([])


# -- bench mesh ---------------------------------------------------------------------------

#: Loaders of the ``--methods module:function`` protocol that go wrong in every way.
_FAKE_PEERS = '''
import time


def load_missing():
    import no_such_package_for_the_bench  # noqa: F401


def load_fail():
    def run(points):
        raise RuntimeError("this method always fails")
    return run


def load_crash():
    def run(points):
        import ctypes
        ctypes.string_at(0)  # segmentation fault
    return run


def load_hang():
    def run(points):
        time.sleep(3600)
    return run
'''


@pytest.fixture
def fake_peers(tmp_path, monkeypatch):
    """A module ``fake_bench_peers`` on the path of the benchmark's subprocesses."""
    folder = tmp_path / "fake"
    folder.mkdir()
    (folder / "fake_bench_peers.py").write_text(_FAKE_PEERS)
    old = [p for p in [os.environ.get("PYTHONPATH")] if p]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(folder), *old]))
    return "fake_bench_peers"


def test_parse_data():
    from fancloud_vtk.bench.mesh import parse_data

    assert parse_data(["bunny", "sphere", "5k,2000"], 100) == [
        ("bunny", None), ("sphere", 100), ("sphere", 5000), ("sphere", 2000)]
    with pytest.raises(ValueError):
        parse_data(["torus"], 100)


def _tables(text):
    """Every Markdown table in ``text``: a list of (header, rows as dicts)."""
    tables, block = [], []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            block.append([c.strip() for c in line.strip("|").split("|")])
        elif block:
            header = block[0]
            tables.append((header, [dict(zip(header, r, strict=True)) for r in block[2:]]))
            block = []
    return tables


def test_bench_mesh_smoke(tmp_path, capsys, fake_peers):
    from fancloud_vtk.bench.mesh import COMPARE_COLUMNS

    out = tmp_path / "bench"
    argv = ["bench", "mesh", "--data", "3000", "--methods", "ours", "meshlib", "ball-pivoting",
            f"{fake_peers}:load_missing", "--timeout", "900", "--samples", "2",
            "--out", str(out), "-q"]
    assert cli_main(argv) == 0

    text = (out / "mesh.md").read_text()
    assert text in capsys.readouterr().out
    assert (out / "mesh.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    tables = _tables(text)
    header, figures = tables[0]
    assert tuple(header) == COLUMNS
    names = {row["figure"] for row in figures}
    assert {"mesh: non-manifold edges", "mesh: non-manifold vertices",
            "mesh: triangles per point (closed surface)",
            "mesh: self-intersecting triangle pairs", "speed: time ours / MeshLib",
            "speed: ball pivoting time / ours"} <= names
    for row in figures:
        assert row["verdict"] in ("yes", "NO", "not measured", ""), row

    header, compare = tables[1]
    assert tuple(header) == COMPARE_COLUMNS
    by_method = {row["method"]: row for row in compare}
    assert len(by_method) == 4
    ours = by_method["fancloud_vtk (this project)"]
    assert ours["status"] == "ok", ours
    missing = by_method[f"{fake_peers}:load_missing"]
    assert missing["status"].startswith(f"missing: {fake_peers}:load_missing not available "
                                        "(ModuleNotFoundError"), missing
    assert missing["time (s)"] == "-"
    # MeshLib comes with the bench extra; the plain test install reports it missing
    have_meshlib = importlib.util.find_spec("meshlib") is not None
    if not have_meshlib:
        row = by_method["MeshLib triangulatePointCloud"]
        assert row["status"].startswith("missing: meshlib"), row
    for label in ("MeshLib triangulatePointCloud", "pymeshlab ball pivoting"):
        if label.startswith("MeshLib") and not have_meshlib:
            continue
        row = by_method[label]
        assert row["status"].startswith("ok"), row
        assert float(row["time (s)"]) > 0
        assert int(row["triangles"].replace(",", "")) > 3000
        if "statistics:" not in row["status"]:  # mesh_statistics available
            assert float(row["triangles / point"]) > 1.0
            assert float(row["triangles / point"]) <= 2.0
            assert int(row["non-manifold edges"].replace(",", "")) >= 0
        assert 0 <= float(row["distance mean"]) <= float(row["distance max"]) < 0.01

    raw = json.loads((out / "mesh.json").read_text())
    _assert_header(raw, argv[1:])
    assert raw["args"]["data"] == ["sphere:3000"]
    methods = raw["datasets"][0]["methods"]
    assert [m["method"] for m in methods][:3] == ["ours", "meshlib", "ball-pivoting"]
    if have_meshlib:
        assert methods[1]["status"] == "ok" and methods[1]["n_triangles"] > 3000
        assert methods[1]["distance"]["samples"] == 2 * 3000
        assert raw["peers"]["meshlib"] is None or methods[1]["time"] > 0


# the timeout counts from the child's start, imports included: generous where the method
# does not hang (a loaded machine, the other test process compiling, starts slowly)
@pytest.mark.parametrize(("loader", "timeout", "status", "message"), [
    ("load_fail", 300, "failed", "failed: RuntimeError: this method always fails"),
    ("load_crash", 300, "crashed", "crashed (SIGSEGV"),
    ("load_hang", 10, "timeout", "timed out after 10 s"),
])
def test_bench_mesh_reports_broken_methods(tmp_path, fake_peers, loader, timeout, status,
                                           message):
    from fancloud_vtk.bench.harness import run_method
    from fancloud_vtk.bench.mesh import compare_rows
    from fancloud_vtk.bench.peers import method_for

    points = tmp_path / "points.npy"
    np.save(points, surface_points(500, seed=0, shape="sphere"))
    r = run_method(method_for(f"{fake_peers}:{loader}"), str(points), str(tmp_path),
                   timeout=timeout, warmup=0)
    assert r["status"] == status
    assert r["message"].startswith(message), r["message"]
    assert "vertices" not in r and r["time"] is None
    row = compare_rows({"methods": [r]})[0]
    assert row["status"] == r["message"]
    if status == "timeout":  # killed while timed (no warm-up): at least this long
        assert 0 < r["time_lower_bound"] <= timeout + 0.5
        assert row["time (s)"].startswith("> ")
    else:
        assert row["time (s)"] == "-"


# -- bench reduce -------------------------------------------------------------------------

#: Reducers of the ``--methods module:function`` protocol of ``bench reduce``.
_FAKE_REDUCERS = '''
import time


def load_fail_second():
    def run(data, target):
        if target > 100:
            raise RuntimeError("too many points for this method")
        return {"vertices": data["points"][:target], "triangles": data["triangles"][:0],
                "info": {"points_only": True}}
    return run


def load_hang_second():
    def run(data, target):
        if target > 100:
            time.sleep(3600)
        return {"vertices": data["points"][:target], "triangles": data["triangles"][:0],
                "info": {"points_only": True}}
    return run
'''


def test_parse_reduce_data():
    from fancloud_vtk.bench.reduce import parse_reduce_data

    assert parse_reduce_data(["bunny", "bone,5k"]) == [
        ("bunny", None), ("bone", None), ("bumpy", 5000)]
    with pytest.raises(ValueError):
        parse_reduce_data(["torus"])


def test_bench_reduce_smoke(tmp_path, capsys, fake_peers):
    from fancloud_vtk.bench.reduce import TABLE_COLUMNS

    out = tmp_path / "bench"
    argv = ["bench", "reduce", "--data", "3000", "--keep", "0.3", "--curve", "--methods",
            "ours-shape", "fast-simplification", "ours-colour", f"{fake_peers}:load_missing",
            "--timeout", "900", "--samples", "1", "--out", str(out), "-q"]
    assert cli_main(argv) == 0

    text = (out / "reduce.md").read_text()
    assert text in capsys.readouterr().out
    assert (out / "reduce_curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (out / "reduce_bunny.png").exists()  # no bunny in --data
    tables = _tables(text)
    header, figures = tables[0]
    assert tuple(header) == COLUMNS
    by_name = {row["figure"]: row for row in figures}
    speed = by_name["speed: time ours reduce / fast-simplification"]
    assert _is_number(speed["measured"]) and float(speed["measured"]) > 0, speed
    assert speed["target"] == speed["verdict"] == ""  # judged at 1M and keep 0.176 only
    # end to end beside the reduce call alone: never shorter
    total = by_name["speed: time ours end to end / fast-simplification"]
    assert float(total["measured"]) >= float(speed["measured"]), (total, speed)
    assert "+ reduce + fan_cloud_to_mesh" in total["parameters"]
    quality = by_name["quality: mean Hausdorff ours (1,1,50,0) / quadric edge collapse"]
    assert quality["verdict"].startswith("not measured: not run"), quality

    header, rows = tables[1]
    assert tuple(header) == TABLE_COLUMNS
    by_method = {row["method"]: row for row in rows}
    assert len(rows) == 4
    ours = by_method["ours entropy (1,1,50,0)"]
    assert ours["status"] == "ok", ours
    assert ours["target"] == ours["kept vertices"] == "900"  # exact count
    assert float(ours["time (s)"]) > 0 and "(build_fans)" in ours["+ fans (s)"]
    assert 0 < float(ours["Hausdorff mean"]) <= float(ours["Hausdorff max"]) < 0.1
    assert 0 < float(ours["feature mean"]) <= float(ours["feature max"])
    fs = by_method["fast-simplification"]
    assert fs["status"] == "ok", fs
    assert abs(int(fs["kept vertices"].split()[0].replace(",", "")) - 900) <= 9
    assert 0 < float(fs["Hausdorff mean"]) < 0.1
    assert by_method["ours entropy (1,1,50,1) + colour"]["status"] == (
        "skipped: the input has no colour (or one uniform colour)")
    missing = by_method[f"{fake_peers}:load_missing"]
    assert missing["status"].startswith(f"missing: {fake_peers}:load_missing not available")
    assert missing["time (s)"] == "-"

    raw = json.loads((out / "reduce.json").read_text())
    assert raw["args"]["data"] == ["bumpy:3000"] and raw["args"]["keep"] == [0.3]
    ds = raw["datasets"][0]
    assert ds["fractions"] == [0.3]  # --curve alone: no extra fractions
    results = {r["method"]: r for r in ds["results"]}
    assert results["ours-shape"]["measures"]["vertices_are_input_points"] is True
    assert results["ours-shape"]["info"]["prepare"] == "build_fans"
    assert results["fast-simplification"]["measures"]["forward_mean"] > 0


@pytest.mark.parametrize(("loader", "timeout", "status", "message"), [
    ("load_fail_second", 60, "failed", "failed: RuntimeError: too many points for this method"),
    ("load_hang_second", 10, "timeout", "timed out after 10 s (while timed)"),
])
def test_bench_reduce_reports_each_fraction(tmp_path, monkeypatch, loader, timeout, status,
                                            message):
    from fancloud_vtk.bench.harness import run_reduce_method, save_reduce_data
    from fancloud_vtk.bench.peers import reduce_method_for

    folder = tmp_path / "fake"
    folder.mkdir()
    (folder / "fake_bench_reducers.py").write_text(_FAKE_REDUCERS)
    monkeypatch.setenv("PYTHONPATH", str(folder))
    data = tmp_path / "data.npz"
    save_reduce_data(str(data), surface_points(500, seed=0), np.zeros((1, 3), np.int64), None,
                     True)
    results = run_reduce_method(reduce_method_for(f"fake_bench_reducers:{loader}"), str(data),
                                None, str(tmp_path), [50, 200, 300], timeout=timeout)
    assert [r["status"] for r in results[:2]] == ["ok", status]
    assert len(results[0]["vertices"]) == 50
    assert results[1]["message"].startswith(message), results[1]["message"]
    if status == "failed":  # the next fraction still runs
        assert results[2]["status"] == "failed"
    else:  # the process was killed: the next fraction says so
        assert results[2]["status"] == "timeout"
        assert results[2]["message"].startswith("not run: the process timed out")
        assert 0 < results[1]["time_lower_bound"] <= timeout + 0.5


def test_reduce_colour_rows_one_per_colour_setting():
    """Each of ours with the colour weight that ran gets its own row against the best peer;
    one that did not run gets none, but the paper's setting says it was not run."""
    from fancloud_vtk.bench.reduce import _colour_rows

    def result(method, rms, status="ok"):
        return {"method": method, "label": method, "keep": 0.42, "status": status,
                "message": "", "measures": {"colour_rms": rms}}

    data = "airplane"
    ds = {"results": [result("ours-colour", 0.02), result("ours-colour-distance", 0.004),
                      result("fast-simplification", 0.008), result("quadric", 0.01),
                      result("ours-shape", 0.001)]}
    rows = {r["figure"]: r for r in _colour_rows(ds, data, 0.42, judged=True)}
    assert set(rows) == {"colour: error ours (1,1,50,1) / best peer",
                         "colour: error ours (1,0,0,1) / best peer"}
    paper = rows["colour: error ours (1,1,50,1) / best peer"]
    assert float(paper["measured"]) == pytest.approx(0.02 / 0.008, rel=1e-3)
    assert paper["verdict"] == "NO" and "fast-simplification 2.04" in paper["parameters"]
    spacing = rows["colour: error ours (1,0,0,1) / best peer"]
    assert float(spacing["measured"]) == pytest.approx(0.5, rel=1e-3)
    assert spacing["verdict"] == "yes"
    # not judged at this fraction: no target, no verdict
    assert all(r["target"] == r["verdict"] == ""
               for r in _colour_rows(ds, data, 0.42, judged=False))

    ds["results"] = ds["results"][2:]  # neither of ours with colour ran
    (only,) = _colour_rows(ds, data, 0.42, judged=True)
    assert only["figure"] == "colour: error ours (1,1,50,1) / best peer"
    assert only["measured"] == "n/a" and only["verdict"].startswith("not measured: not run")


def test_reduce_quality_rows_add_the_error_method_and_the_subset_reference():
    """Mean Hausdorff rows: the figure's (ours (1,1,50,0)), ours error against the same target,
    and the quadric collapse on input vertices as a reference without one; only those that
    ran."""
    from fancloud_vtk.bench.reduce import _quality_rows

    def result(method, mean, feature=1e-4):
        return {"method": method, "label": method, "keep": 0.176, "status": "ok",
                "message": "", "measures": {"hausdorff_mean": mean, "feature_mean": feature}}

    ds = {"results": [result("ours-shape", 4e-4), result("ours-error", 1.8e-4),
                      result("quadric-subset", 1.5e-4), result("quadric", 1e-4)]}
    rows = {r["figure"]: r for r in _quality_rows(ds, "bunny", 0.176, judged=True)}
    shape = rows["quality: mean Hausdorff ours (1,1,50,0) / quadric edge collapse"]
    assert float(shape["measured"]) == pytest.approx(4.0) and shape["verdict"] == "NO"
    error = rows["quality: mean Hausdorff ours error / quadric edge collapse"]
    assert float(error["measured"]) == pytest.approx(1.8) and error["target"] == "<= 1.5"
    subset = rows["reference: mean Hausdorff quadric edge collapse on input vertices / "
                  "quadric edge collapse"]
    assert float(subset["measured"]) == pytest.approx(1.5)
    assert subset["target"] == subset["verdict"] == ""
    assert "quadric-subset 0.00015" in subset["parameters"]
    ds["results"] = [r for r in ds["results"] if r["method"] not in ("ours-error",
                                                                       "quadric-subset")]
    assert len(_quality_rows(ds, "bunny", 0.176, judged=True)) == 2


# -- the package ---------------------------------------------------------------------------


def _bench_parser_cases():
    """(mode, flag, value) of every bench option taking one value, with a value that
    starts with '-' and that its type takes."""
    import argparse

    from fancloud_vtk.bench import make_parser

    sub = next(a for a in make_parser()._actions if isinstance(a, argparse._SubParsersAction))
    values = {None: "-0.1,0.3,0.7", int: "-3", float: "-1e3"}  # -1e3: not a number to argparse
    for mode, parser in sub.choices.items():
        for action in parser._actions:
            if (action.option_strings and action.nargs is None and action.type in values
                    and action.choices is None):
                yield mode, action.option_strings[-1], values[action.type], action


@pytest.mark.parametrize(("mode", "flag", "value", "action"),
                         [pytest.param(*c, id=f"{c[0]}{c[1]}") for c in _bench_parser_cases()])
def test_bench_options_take_values_starting_with_minus(mode, flag, value, action):
    from fancloud_vtk._argv import join_negative_values
    from fancloud_vtk.bench import make_parser

    parser = make_parser()
    args = parser.parse_args(join_negative_values(parser, [mode, flag, value]))
    expected = action.type(value) if action.type is not None else value
    assert getattr(args, action.dest) == expected


def test_bench_negative_values_reach_the_benchmark(tmp_path, capsys):
    # argparse alone stops at "expected one argument"; joined, the bench's own checks speak
    rc = cli_main(["bench", "vdfc", "--e-max", "-1e3", "--out", str(tmp_path), "-q"])
    assert rc == 2
    assert "--e-max > 0" in capsys.readouterr().err
    # --camera abbreviates --cameras (an int): the value is that option's, and not an int
    with pytest.raises(SystemExit):
        cli_main(["bench", "vdfc", "--camera", "-3,0,0;0,0,0;0,0,1;40"])
    err = capsys.readouterr().err
    assert "invalid int value: '-3,0,0;0,0,0;0,0,1;40'" in err
    assert "expected one argument" not in err


def test_bench_imports_neither_cli_nor_demo():
    """No import in fancloud_vtk/bench/ (top level or in a function) of the command line or
    the demo: they sit on top of the bench, not under it."""
    folder = Path(fancloud_vtk.__file__).parent / "bench"
    files = sorted(folder.glob("*.py"))
    assert {"harness.py", "metrics.py", "peers.py", "report.py", "fans.py", "mesh.py",
            "reduce.py", "refine.py", "vdfc.py"} <= {f.name for f in files}
    banned = ("fancloud_vtk.cli", "fancloud_vtk.demo")
    found = []
    for path in files:
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: resolve against fancloud_vtk.bench
                    base = ["fancloud_vtk", "bench"][: 2 - (node.level - 1)]
                    module = ".".join([*base, *([node.module] if node.module else [])])
                else:
                    module = node.module or ""
                names = [module, *(f"{module}.{a.name}" for a in node.names)]
            elif (isinstance(node, ast.Call) and node.args
                  and isinstance(node.args[0], ast.Constant)
                  and isinstance(node.args[0].value, str)
                  and getattr(node.func, "attr", getattr(node.func, "id", "")) in (
                      "import_module", "__import__")):
                names = [node.args[0].value]
            for name in names:
                if any(name == b or name.startswith(b + ".") for b in banned):
                    found.append(f"{path.name}:{node.lineno}: {name}")
    assert not found, found


def test_metrics_import_alone():
    """The measures load without the benchmarks (the tests and the demo use them)."""
    import subprocess
    import sys

    code = ("import sys; import fancloud_vtk.bench.metrics; "
            "print(sorted(m for m in sys.modules if m.startswith('fancloud_vtk.bench')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == str(["fancloud_vtk.bench", "fancloud_vtk.bench.common",
                               "fancloud_vtk.bench.metrics"])


def test_bench_compile_times_a_cold_and_a_cached_run(tmp_path, capsys):
    # a command that compiles nothing keeps the test short; the plumbing is the same
    out = tmp_path / "out"
    assert cli_main(["bench", "compile", "--command=--version", "--out", str(out), "-q"]) == 0
    res = json.loads((out / "compile.json").read_text())
    assert set(HEADER_KEYS) <= set(res)
    assert res["cold"] > 0 and len(res["warm"]) == 1
    assert res["compile"] == pytest.approx(res["cold"] - res["warm"][0])
    assert [r["figure"] for r in res["rows"]][-1].startswith("numba compile time")
    assert "fancloud bench compile" in capsys.readouterr().out


def test_bench_compile_reports_a_failing_command(tmp_path, capsys):
    assert cli_main(["bench", "compile", "--command", "no-such-command", "--out", str(tmp_path),
                     "-q"]) == 2
    assert "fancloud no-such-command failed" in capsys.readouterr().err


def test_a_result_is_written_with_its_header_and_its_rows(tmp_path):
    from fancloud_vtk.bench.report import header, write_outputs

    res = header(["fans"])
    with pytest.raises(ValueError, match="rows"):
        write_outputs(str(tmp_path), "x", "text", res)
    with pytest.raises(ValueError, match="header keys"):
        write_outputs(str(tmp_path), "x", "text", {"rows": []})
    md, js = write_outputs(str(tmp_path), "x", "text", {**res, "rows": []})
    assert json.loads(Path(js).read_text())["rows"] == []


def test_bench_tiles_compares_the_tiles_with_one_process(tmp_path, capsys):
    """Small: one process, Dask's threads and out of core from a file on a one-worker
    LocalCluster (the cluster mode is the same plumbing as threads with a LocalCluster,
    tested in test_distributed.py); the fan clouds' digests agree; the out-of-core run is
    extrapolated."""
    out = tmp_path / "bt"
    assert cli_main(["bench", "tiles", "--sizes", "30k", "--tiles", "2,2,1", "--modes", "one",
                     "threads", "files", "--workers", "1", "--tile-points", "10000",
                     "--extrapolate", "1M", "--extrapolate-workers", "2,4",
                     "--reduce", "20k", "--mesh", "20k", "--out", str(out), "-q"]) == 0
    res = json.loads((out / "tiles.json").read_text())
    by_figure = {r["figure"]: r for r in res["rows"]}
    same = by_figure["tiles: same fan cloud as one process, tiled_fans 2x2x1, Dask threads"]
    assert same["measured"] == "yes" and same["verdict"] == "yes"
    assert float(by_figure["tiles: wall time, one process, build_fans"]["measured"]) > 0
    assert "tiles: ratio tiled_fans 2x2x1, Dask threads / one process" in by_figure
    assert {r["mode"] for r in res["runs"]} == {"one", "threads", "files", "blocks", "file",
                                               "cluster"}
    for name in ("tiled_mesh 2x2x1, Dask threads",
                 "tiled_mesh 2x2x1, LocalCluster 1 workers x 1 thread"):  # the mesh in tiles
        assert by_figure[f"tiles: same mesh as one process, {name}"]["measured"] == "yes"
        assert float(by_figure[f"tiles: mesh wall time, {name} / one process"]["measured"]) > 0
    mean = by_figure["tiles: reduction mean distance, tiled_reduce 2x2x1, Dask threads / "
                     "one process"]
    assert float(mean["measured"]) > 0 and mean["verdict"] in ("yes", "NO")
    # the reduction of the points' .npy file, read in chunks: the array's
    file = by_figure["tiles: reduction of the file the array's, tiled_reduce 2x2x1 of an .npy "
                     "file (read in chunks of 100,000, out of core), Dask threads"]
    assert file["measured"] == "yes" and file["verdict"] == "yes"
    files = "write_tiled_fans from .npy (out of core), LocalCluster 1 workers x 1 thread"
    assert by_figure[f"tiles: same fan cloud as one process, {files}"]["measured"] == "yes"
    ext = [e for e in res["extrapolation"]]
    assert [e["workers"] for e in ext] == [2, 4] and ext[0]["n"] == 1_000_000
    assert ext[0]["time"] > ext[1]["time"] > 0 and ext[0]["tiles"] >= 30
    assert "tiles: extrapolated wall time, 1M points, 4 workers" in by_figure
    assert "fancloud bench tiles" in capsys.readouterr().out
