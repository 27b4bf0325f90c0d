"""The parameter table agrees with every front: core, VTK filter, CLI, accessor, docs."""

import inspect

import numpy as np
import pytest
import pyvista as pv

import fancloud_vtk.algorithms as algorithms
from fancloud_vtk import build_fans, fan_cloud_of_mesh, fan_cloud_to_mesh, tiled_fans, tiled_mesh
from fancloud_vtk.accessor import FanCloudAccessor
from fancloud_vtk.algorithms import FanCloudFilter
from fancloud_vtk.cli import make_parser
from fancloud_vtk.params import (
    FAN_PARAMS,
    INPUT_PARAMS,
    MESH_PARAMS,
    Param,
    check_params,
    markdown_table,
)

IDS = [p.name for p in FAN_PARAMS]


def _fans_parser():
    parser = make_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices["fans"]


@pytest.mark.parametrize("param", FAN_PARAMS, ids=IDS)
def test_core_keyword_and_default(param):
    sig = inspect.signature(build_fans)
    assert param.name in sig.parameters
    assert sig.parameters[param.name].default == param.default
    assert type(sig.parameters[param.name].default) is type(param.default)


@pytest.mark.parametrize("param", FAN_PARAMS, ids=IDS)
def test_filter_setter_getter_and_property(param):
    alg = FanCloudFilter()
    assert callable(getattr(alg, "Set" + param.vtk_name))
    assert getattr(alg, "Get" + param.vtk_name)() == param.default
    assert getattr(alg, param.name) == param.default
    assert param.doc in getattr(FanCloudFilter, param.name).__doc__


@pytest.mark.parametrize("param", FAN_PARAMS, ids=IDS)
def test_cli_flag_and_default(param):
    parser = _fans_parser()
    action = next(a for a in parser._actions if a.dest == param.name)
    assert param.cli_flag in action.option_strings
    assert action.default == param.default
    args = parser.parse_args(["in.ply", "-o", "out.vtp"])
    assert getattr(args, param.name) == param.default
    assert param.cli_flag in parser.format_help()


@pytest.mark.parametrize("param", FAN_PARAMS, ids=IDS)
def test_accessor_signature_and_docstring(param):
    sig = inspect.signature(FanCloudAccessor.fans)
    p = sig.parameters[param.name]
    assert p.kind is inspect.Parameter.KEYWORD_ONLY
    assert p.default == param.default
    line = f"{param.name} : {param.kind}, default: {param.default!r}"
    assert line in FanCloudAccessor.fans.__doc__
    assert param.name in inspect.signature(pv.PolyData().fancloud.fans).parameters


def test_no_front_has_extra_parameters():
    names = {p.name for p in FAN_PARAMS}
    input_names = {p.name for p in INPUT_PARAMS}
    accessor = set(inspect.signature(FanCloudAccessor.fans).parameters) - {"self", "progress_bar"}
    assert accessor == names | input_names
    assert set(FanCloudFilter().parameters) == names | input_names
    core_only = {"points", "normals", "point_data", "workers", "progress"}
    assert set(inspect.signature(build_fans).parameters) - core_only == names


#: the core functions that repeat the table's keywords in their signatures (spelled out,
#: for help() and the editors): each with the table's rows it takes
CORE_KEYWORDS = [
    (fan_cloud_to_mesh, MESH_PARAMS),
    (tiled_fans, FAN_PARAMS),
    (tiled_mesh, tuple(p for p in FAN_PARAMS if p.name != "orient") + MESH_PARAMS),
]


@pytest.mark.parametrize("fn, table", CORE_KEYWORDS, ids=[f.__name__ for f, _ in CORE_KEYWORDS])
def test_core_functions_repeat_the_table_keywords(fn, table):
    """The keywords that fan_cloud_to_mesh, tiled_fans and tiled_mesh share with the verbs
    have the table's defaults, of the table's types, keyword-only (but k)."""
    sig = inspect.signature(fn).parameters
    for param in table:
        assert param.name in sig, (fn.__name__, param.name)
        p = sig[param.name]
        assert p.default == param.default and type(p.default) is type(param.default), param.name
        assert p.kind is inspect.Parameter.KEYWORD_ONLY or param.name == "k", param.name


#: every filter, accessor verb and command that reads a dataset
FILTERS = [name for name in algorithms.__all__ if name.endswith("Filter")]
VERBS = ["fans", "mesh", "entropy", "reduce", "selective", "refine", "vdfc"]


@pytest.mark.parametrize("param", INPUT_PARAMS, ids=[p.name for p in INPUT_PARAMS])
def test_input_parameters_reach_every_front(param):
    """INPUT_PARAMS (how a triangle mesh input is read): the core's keyword, every filter's
    setter, every accessor verb's keyword and every command's flag, with one default."""
    sig = inspect.signature(fan_cloud_of_mesh)
    assert sig.parameters[param.name].default == param.default
    assert sig.parameters[param.name].kind is inspect.Parameter.KEYWORD_ONLY
    for name in FILTERS:
        alg = getattr(algorithms, name)()
        assert getattr(alg, "Get" + param.vtk_name)() == param.default, name
        assert callable(getattr(alg, "Set" + param.vtk_name)), name
    for verb in VERBS:
        p = inspect.signature(getattr(FanCloudAccessor, verb)).parameters[param.name]
        assert p.kind is inspect.Parameter.KEYWORD_ONLY and p.default == param.default, verb
        assert f"{param.name} : {param.kind}, default: {param.default!r}" in \
            getattr(FanCloudAccessor, verb).__doc__
    sub = next(a for a in make_parser()._actions if a.dest == "command")
    for command in VERBS:
        action = next(a for a in sub.choices[command]._actions if a.dest == param.name)
        assert param.cli_flag in action.option_strings and action.default == param.default
    args = sub.choices["mesh"].parse_args(["in.ply", "-o", "o.ply", param.cli_flag])
    assert getattr(args, param.name) is True


def test_cli_flags_reach_the_values():
    args = _fans_parser().parse_args(
        ["in.ply", "-o", "o.vtp", "--k", "9", "--max-angle", "60.5", "--max-replacements", "7",
         "--rule", "paper", "--no-rotate-sharp-edges", "--no-orient"]
    )
    assert (args.k, args.max_angle, args.max_replacements, args.rule) == (9, 60.5, 7, "paper")
    assert args.rotate_sharp_edges is False and args.orient is False


def test_names():
    by_name = {p.name: p for p in FAN_PARAMS}
    assert by_name["k"].vtk_name == "K"
    assert by_name["max_angle"].vtk_name == "MaxAngle"
    assert by_name["max_angle"].cli_flag == "--max-angle"
    assert by_name["rotate_sharp_edges"].vtk_name == "RotateSharpEdges"


def test_defaults_pass_their_own_check():
    for p in FAN_PARAMS:
        assert p.check(p.default) == p.default
        if p.range:
            assert p.range[0] <= p.default <= p.range[1]
        if p.choices:
            assert p.default in p.choices


def test_markdown_table_renders():
    table = markdown_table(FAN_PARAMS)
    lines = table.splitlines()
    assert lines[0].startswith("| keyword | VTK / ParaView | CLI |")
    assert len(lines) == 2 + len(FAN_PARAMS)
    assert all(line.count("|") == 8 for line in lines[2:])
    row = "| `max_angle` | `SetMaxAngle` | `--max-angle` | float | `90.0` | (1.0, 179.0) |"
    assert row in table
    assert "cover / paper" in table


INT = Param("n", "int", 5, "a count", range=(1, 10))
FLOAT = Param("x", "float", 0.5, "a fraction", range=(0.0, 1.0))
BOOL = Param("flag", "bool", True, "a switch")
CHOICE = Param("mode", "choice", "a", "a mode", choices=("a", "b"))


@pytest.mark.parametrize(
    ("param", "value", "expected"),
    [
        (INT, 7, 7), (INT, 7.0, 7), (INT, np.int32(3), 3),
        (FLOAT, 1, 1.0), (FLOAT, np.float32(0.25), 0.25),
        (BOOL, False, False), (BOOL, 1, True), (BOOL, np.bool_(False), False),
        (CHOICE, "b", "b"),
    ],
)
def test_check_converts(param, value, expected):
    out = param.check(value)
    assert out == expected and type(out) is type(expected)


@pytest.mark.parametrize(
    ("param", "value", "error", "match"),
    [
        (INT, 0, ValueError, "n must be between 1 and 10, got 0"),
        (INT, 2.5, TypeError, "n must be an integer, got 2.5"),
        (INT, "3", TypeError, "n must be a number, got '3'"),
        (INT, "three", TypeError, "n must be a number, got 'three'"),
        (INT, None, TypeError, "n must be a number, got None"),
        (INT, True, TypeError, "n must be a number, got True"),
        (INT, float("inf"), TypeError, "n must be an integer, got inf"),
        (FLOAT, float("nan"), ValueError, "x must be a number, got NaN"),
        (FLOAT, 1.5, ValueError, "x must be between 0.0 and 1.0, got 1.5"),
        (FLOAT, [0.5], TypeError, r"x must be a number, got \[0.5\]"),
        (BOOL, 2, TypeError, "flag must be True or False, got 2"),
        (BOOL, "yes", TypeError, "flag must be True or False, got 'yes'"),
        (CHOICE, "c", ValueError, r"mode must be one of \['a', 'b'\], got 'c'"),
        (CHOICE, ["a"], ValueError, "mode must be one of"),
    ],
)
def test_check_rejects_with_the_parameter_name(param, value, error, match):
    with pytest.raises(error, match=match):
        param.check(value)


def test_check_params_fills_defaults_and_rejects_unknown():
    values = check_params(FAN_PARAMS, {"k": 8})
    assert values == {**{p.name: p.default for p in FAN_PARAMS}, "k": 8}
    with pytest.raises(TypeError, match=r"unknown parameter\(s\) \['K', 'angle'\]; known: "):
        check_params(FAN_PARAMS, {"K": 8, "angle": 3})


def test_generated_docs_are_up_to_date():
    """docs/api.md and the accessor stub match the parameter tables and __all__."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "scripts" / "gen_docs.py"
    done = subprocess.run([sys.executable, str(script), "--check"], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
