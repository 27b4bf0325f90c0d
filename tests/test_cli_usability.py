"""The ``fancloud`` command for a new user: negative option values, --version, a quiet progress
bar, no VTK warnings when rendering offscreen, a demo help that says what it runs."""

import io
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import pyvista as pv
import tqdm
from shapes import sphere

import fancloud_vtk
from fancloud_vtk import load
from fancloud_vtk.cli import _join_negative_values, _Progress, _value_options, main, make_parser

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def cloud(tmp_path_factory):
    path = tmp_path_factory.mktemp("usability") / "sphere.npy"
    np.save(path, sphere(2000, seed=31))
    return path


def _heights(n=30):
    x = np.linspace(0, 3, n)
    return 0.5 * np.add.outer(np.sin(x), np.cos(1.2 * x))


@pytest.fixture(scope="module")
def dem(tmp_path_factory):
    """A small height field, 3 x 3 units (spacing 0.1)."""
    path = tmp_path_factory.mktemp("usability") / "dem.npz"
    np.savez(path, elevation=_heights(), dx=0.1, dy=0.1)
    return path


# --- option values that start with '-' ------------------------------------------------------

def _subparsers():
    sub = next(a for a in make_parser()._actions if a.dest == "command")
    return {name: p for name, p in sub.choices.items() if name != "bench"}


#: what each command needs besides the option under test
REQUIRED = {"fans": ["-o", "o.vtp"], "mesh": ["-o", "o.ply"], "entropy": ["-o", "o.vtp"],
            "reduce": ["-o", "o.vtp"], "refine": ["-o", "o.vtp"], "selective": ["-o", "o.vtp"],
            "vdfc": [], "demo": []}
AMOUNT = {"reduce": ["--n", "5"], "refine": ["--factor", "2"], "selective": ["--keep", "0.5"]}
AMOUNT_FLAGS = ("--keep", "--n", "--n-points", "--factor")


def _negative_value(action) -> str:
    """A value starting with '-' that the option's type accepts."""
    kind = getattr(action.type, "__name__", "")
    if kind.endswith("comma-separated numbers"):  # a vector: cli._vector(size)
        return ",".join(["-1.5"] * int(kind.split()[0]))
    if action.dest == "camera":
        return "-3,0,0;0,0,0;0,0,1;40"
    if action.type is int:
        return "-2"
    return "-.25" if action.type is float else "-1.png"


def _cases():
    for command, parser in _subparsers().items():
        for flag, action in _value_options(parser).items():
            if action.choices is None and flag not in ("-h", "--help"):
                yield pytest.param(command, flag, action, id=f"{command} {flag}")


@pytest.mark.parametrize(("command", "flag", "action"), list(_cases()))
def test_every_option_takes_a_value_starting_with_minus(command, flag, action, capsys):
    value = _negative_value(action)
    argv = [command, *(["IN"] if command != "demo" else []), *REQUIRED[command]]
    if flag not in AMOUNT_FLAGS:
        argv += AMOUNT.get(command, [])
    parser = make_parser()
    if action.dest == "tiles":  # no tiling starts with '-': the value reaches its own check
        with pytest.raises(SystemExit):
            parser.parse_args(_join_negative_values(parser, [*argv, flag, "-1,1,1"]))
        assert "expected 'auto' or three positive integers X,Y,Z, got '-1,1,1'" in \
            capsys.readouterr().err
        return
    args = parser.parse_args(_join_negative_values(parser, [*argv, flag, value]))
    expected = action.type(value) if action.type is not None else value
    assert getattr(args, action.dest) == expected


def test_the_cases_cover_the_reported_options():
    flags = {(c, f) for c, f, _ in (p.values for p in _cases())}
    assert {("selective", "--region-center"), ("vdfc", "--camera"), ("vdfc", "--spacing"),
            ("reduce", "--weights"), ("reduce", "--keep"), ("fans", "-o"), ("fans", "--output"),
            ("fans", "--max-angle"), ("fans", "--k")} <= flags


def test_joining_keeps_everything_else():
    parser = make_parser()
    argv = ["vdfc", "IN", "--came", "-3,0,0;0,0,0;0,0,1;40", "-q", "--e-max", "-1",
            "--color-array", "--k", "--", "-2"]
    assert _join_negative_values(parser, argv) == [
        "vdfc", "IN", "--came=-3,0,0;0,0,0;0,0,1;40", "-q", "--e-max=-1",
        "--color-array", "--k", "--", "-2"]  # a value is its option's; nothing after '--'
    # flags without a value, unknown options and values not like a number are left alone
    argv = ["fans", "IN", "--no-orient", "-3", "--bogus", "-1", "-o", "-x.vtp"]
    assert _join_negative_values(parser, argv) == argv
    assert _join_negative_values(parser, ["--version"]) == ["--version"]
    assert _join_negative_values(parser, ["bench", "fans", "--n", "-1"]) == \
        ["bench", "fans", "--n", "-1"]


def test_without_joining_argparse_fails():
    # the reason for the joining: argparse alone takes the list for an option
    parser = _subparsers()["selective"]
    with pytest.raises(SystemExit):
        parser.parse_args(["IN", "-o", "o.vtp", "--n", "5", "--region-center", "-0.1,0.3,0.7"])


def test_selective_with_a_negative_region_center(cloud, tmp_path, capsys):
    # the reported command: the same result as the '=' spelling argparse always accepted
    out, ref = tmp_path / "sel.vtp", tmp_path / "ref.vtp"
    common = [str(cloud), "--n", "500", "--region-radius", "0.5"]
    assert main(["selective", "-o", str(out), *common, "--region-center", "-0.1,0.3,0.7"]) == 0
    printed = capsys.readouterr()
    assert printed.err == ""
    added = int(re.search(r"^reinserted in the region +(\d+)$", printed.out, re.M).group(1))
    assert added > 0
    assert main(["selective", "-o", str(ref), *common, "--region-center=-0.1,0.3,0.7", "-q"]) == 0
    got, expected = load(out), load(ref)
    assert got.n_points == 500 + added
    np.testing.assert_array_equal(got.points, expected.points)
    np.testing.assert_array_equal(got.point_data["original_id"],
                                  expected.point_data["original_id"])


def test_vdfc_with_a_negative_camera_position(dem, tmp_path, capsys):
    out = tmp_path / "front.vtp"
    assert main(["vdfc", str(dem), "--camera", "-1,-2,2;1.5,1.5,0;0,0,1;40", "--e-max", "0.02",
                 "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "height field 30 x 30" in printed and str(out) in printed
    assert out.stat().st_size > 0
    # a position the parser mangled would not give the same front as the '=' spelling
    ref = tmp_path / "ref.vtp"
    assert main(["vdfc", str(dem), "--camera=-1,-2,2;1.5,1.5,0;0,0,1;40", "--e-max", "0.02",
                 "-o", str(ref), "-q"]) == 0
    np.testing.assert_array_equal(pv.read(out).points, pv.read(ref).points)


# --- --version ----------------------------------------------------------------------------

def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out == f"fancloud {fancloud_vtk.__version__}\n"
    assert fancloud_vtk.__version__[0].isdigit()


# --- the progress bar ---------------------------------------------------------------------

class _CountingBar(tqdm.tqdm):
    """A bar that draws (to a buffer, as on a terminal) and counts its redraws."""

    monitor_interval = 0  # no monitor thread
    redraws = 0

    def __init__(self, *args, **kwargs):
        kwargs["disable"] = kwargs.get("disable") or False
        self.buffer = io.StringIO()
        super().__init__(*args, file=self.buffer, **kwargs)
        self.redraws = 0

    def refresh(self, *args, **kwargs):
        self.redraws += 1
        return super().refresh(*args, **kwargs)


@pytest.fixture
def progress(monkeypatch):
    """A _Progress drawing on a counting bar, with a clock the test moves."""
    monkeypatch.setattr(tqdm, "tqdm", _CountingBar)
    now = [0.0]
    bar = _Progress("fans", quiet=False)
    bar.clock = lambda: now[0]
    bar.bar.redraws = 0  # (tqdm draws once when made)
    return bar, now


def test_progress_burst_is_drawn_once_then_closed_on_the_final_state(progress):
    bar, _ = progress
    for i in range(10_000):  # a burst: no time passes
        assert bar(i / 9_999, "building fans") is False
    assert bar.bar.redraws == 1
    text = bar.bar.buffer.getvalue()
    bar.close()
    assert bar.bar.redraws == 2 and bar.bar.n == 100  # the held-back final state
    assert "100%" in bar.bar.buffer.getvalue()[len(text):] and "building fans" in text


def test_progress_is_drawn_at_most_ten_times_a_second(progress):
    bar, now = progress
    messages = ("neighbours", "fans", "merge", "write")
    for i in range(10_000):  # 10 s, one call a millisecond
        now[0] = i * 1e-3
        bar(i / 10_000, messages[i // 2_500])
    assert 50 <= bar.bar.redraws <= 10 * 10 + 1
    assert bar.bar.desc.startswith("write")
    bar.close()


def test_progress_redraws_only_on_a_change(progress):
    bar, now = progress
    for i in range(1_000):  # the same state for 1000 s
        now[0] = float(i)
        bar(0.5, "fans")
    assert bar.bar.redraws == 1
    now[0] += 1
    bar(0.5, "mesh")  # a new message is drawn
    now[0] += 1
    bar(0.51, "mesh")  # a new percentage too
    assert bar.bar.redraws == 3
    bar.close()
    assert bar.bar.redraws == 3  # nothing held back


def test_quiet_progress_never_draws(monkeypatch):
    monkeypatch.setattr(tqdm, "tqdm", _CountingBar)
    bar = _Progress("fans", quiet=True)
    for i in range(10_000):
        bar(i / 9_999, "fans")
    bar.close()
    assert bar.bar.redraws == 0 and bar.bar.buffer.getvalue() == ""


# --- offscreen rendering without a display ------------------------------------------------

def test_a_rendered_frame_prints_no_vtk_warning(dem, tmp_path):
    png = tmp_path / "frame.png"
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    res = subprocess.run(
        [sys.executable, "-m", "fancloud_vtk.cli", "vdfc", str(dem), "--camera",
         "-1,-2,2;1.5,1.5,0;0,0,1;40", "--e-max", "0.02", "--size", "160x120", "-o", str(png)],
        capture_output=True, text=True, timeout=300, env=env,
    )
    assert res.returncode == 0, res.stderr
    assert png.read_bytes()[:8] == PNG
    assert "WARN" not in res.stderr and "X server" not in res.stderr, res.stderr
    assert res.stderr.strip() == "", res.stderr


# --- the demo's help ------------------------------------------------------------------------

def test_demo_help_names_every_panel(capsys):
    with pytest.raises(SystemExit):
        main(["demo", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for panel in ("fan cloud", "mesh", "reductions", "selective refinement", "refinement x4",
                  "terrain", "Jacksboro", "view-dependent"):
        assert panel in text, panel
    with pytest.raises(SystemExit):
        main(["--help"])
    listing = " ".join(capsys.readouterr().out.split())
    assert "terrain (view-dependent fan cloud)" in listing
    assert "terrain" in " ".join(sys.modules["fancloud_vtk.cli"].__doc__.split())
