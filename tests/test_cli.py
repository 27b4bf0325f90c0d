"""The ``fancloud`` command: reads, forwards to the core, writes; clear errors, exit code 2."""

import re
import subprocess
import sys

import numpy as np
import pytest
from plyfile import PlyData, PlyElement
from shapes import sphere

from fancloud_vtk import build_fans, load, save
from fancloud_vtk.cli import main

N = 2000


@pytest.fixture(scope="module")
def points():
    return sphere(N, seed=31)


def write_ply(path, p, rgb=None):
    dtype = [("x", "f8"), ("y", "f8"), ("z", "f8")]
    if rgb is not None:
        dtype += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    v = np.empty(len(p), dtype=dtype)
    for i, c in enumerate("xyz"):
        v[c] = p[:, i]
    if rgb is not None:
        for i, c in enumerate(("red", "green", "blue")):
            v[c] = rgb[:, i]
    PlyData([PlyElement.describe(v, "vertex")]).write(str(path))
    return path


def write_input(tmp_path, fmt, p):
    path = tmp_path / f"cloud.{fmt}"
    if fmt == "ply":
        write_ply(path, p, (np.arange(3 * len(p)) % 256).astype(np.uint8).reshape(-1, 3))
    elif fmt == "xyz":
        np.savetxt(path, p, fmt="%.17g")
    else:
        np.save(path, p)
    return path


def run_cli(*args):
    """The command in a fresh process, as a user runs it."""
    return subprocess.run(
        [sys.executable, "-m", "fancloud_vtk.cli", *map(str, args)],
        capture_output=True, text=True, timeout=300,
    )


@pytest.mark.parametrize("fmt", ["ply", "xyz", "npy"])
def test_fans_on_each_input_format(tmp_path, points, fmt, capsys):
    src = write_input(tmp_path, fmt, points)
    out = tmp_path / "fans.vtp"
    assert main(["fans", str(src), "-o", str(out), "--k", "6"]) == 0
    fc = load(out)
    np.testing.assert_array_equal(fc.points, points)
    expected = build_fans(points, k=6)
    np.testing.assert_array_equal(fc.ring, expected.ring)
    np.testing.assert_array_equal(fc.open, expected.open)
    if fmt == "ply":
        assert fc.point_data["RGB"].dtype == np.uint8
    printed = capsys.readouterr().out
    assert "points" in printed and "2,000" in printed and str(out) in printed


def test_parameters_are_forwarded(tmp_path, points, capsys):
    src = write_input(tmp_path, "npy", points)
    out = tmp_path / "fans.vtp"
    args = ["fans", str(src), "-o", str(out), "--k", "8", "--max-angle", "75",
            "--max-replacements", "30", "--no-rotate-sharp-edges", "--quiet"]
    assert main(args) == 0
    assert capsys.readouterr().out == "", "--quiet prints nothing"
    fc = load(out)
    expected = build_fans(points, k=8, max_angle=75.0, max_replacements=30,
                          rotate_sharp_edges=False)
    np.testing.assert_array_equal(fc.ring, expected.ring)
    assert np.all(fc.fan_sizes[~fc.open] == 8)


def test_the_command_in_a_subprocess(tmp_path, points):
    src = write_input(tmp_path, "ply", points)
    out = tmp_path / "fans.vtp"
    res = run_cli("fans", src, "-o", out, "--k", "6")
    assert res.returncode == 0, res.stderr
    assert "distinct triangles / point" in res.stdout
    assert load(out).n_points == N


def test_duplicates_warn_in_one_line_and_are_mapped(tmp_path, points):
    src = tmp_path / "dup.xyz"
    np.savetxt(src, np.vstack([points, points[[3, 8, 8]]]), fmt="%.17g")
    out = tmp_path / "fans.vtp"
    res = run_cli("fans", src, "-o", out)
    assert res.returncode == 0, res.stderr
    assert res.stderr.startswith("fancloud fans: warning: 3 duplicate point(s) merged")
    assert len(res.stderr.strip().splitlines()) == 1
    assert re.search(r"^duplicates merged +3$", res.stdout, re.MULTILINE)
    fc = load(out)
    np.testing.assert_array_equal(fc.point_data["original_id"], np.arange(N))


def _assert_clean_error(rc, err, *fragments):
    assert rc == 2
    assert err.startswith("fancloud fans: error: "), err
    for fragment in fragments:
        assert fragment in err, err
    assert "Traceback" not in err


def test_wrong_output_extension(tmp_path, points, capsys):
    src = write_input(tmp_path, "npy", points)
    out = tmp_path / "fans.ply"
    rc = main(["fans", str(src), "-o", str(out)])
    _assert_clean_error(rc, capsys.readouterr().err, "the output must be a .vtp file", "fans.ply")
    assert not out.exists()


def test_output_folder_missing(tmp_path, points, capsys):
    src = write_input(tmp_path, "npy", points)
    rc = main(["fans", str(src), "-o", str(tmp_path / "nowhere" / "fans.vtp")])
    _assert_clean_error(rc, capsys.readouterr().err, "no such directory", "nowhere")


def test_missing_input(tmp_path, capsys):
    rc = main(["fans", str(tmp_path / "absent.ply"), "-o", str(tmp_path / "o.vtp")])
    _assert_clean_error(rc, capsys.readouterr().err, "absent.ply", "no such file")


@pytest.mark.parametrize("fmt", ["ply", "npy", "vtp"])
def test_truncated_input(tmp_path, points, fmt, capsys):
    if fmt == "vtp":
        src = tmp_path / "cloud.vtp"
        save(build_fans(points), src)
    else:
        src = write_input(tmp_path, fmt, points)
    data = src.read_bytes()
    src.write_bytes(data[: len(data) // 2])
    rc = main(["fans", str(src), "-o", str(tmp_path / "o.vtp")])
    _assert_clean_error(rc, capsys.readouterr().err, f"cannot read '{src}'")
    assert not (tmp_path / "o.vtp").exists()


def test_unreadable_text_and_unknown_extension(tmp_path, capsys):
    bad = tmp_path / "bad.xyz"
    bad.write_text("1 2 3\n4 five 6\n")
    rc = main(["fans", str(bad), "-o", str(tmp_path / "o.vtp")])
    _assert_clean_error(rc, capsys.readouterr().err, "bad.xyz", "non-numeric token 'five'")
    odd = tmp_path / "cloud.abc"
    odd.write_text("1 2 3\n")
    rc = main(["fans", str(odd), "-o", str(tmp_path / "o.vtp")])
    _assert_clean_error(rc, capsys.readouterr().err, "unknown file extension ('.abc')")


def test_points_that_give_no_fan_cloud(tmp_path, points, capsys):
    p = points.copy()
    p[5] = np.inf
    src = tmp_path / "inf.npy"
    np.save(src, p)
    rc = main(["fans", str(src), "-o", str(tmp_path / "o.vtp")])
    _assert_clean_error(rc, capsys.readouterr().err, "infinite", "index 5")
    src = tmp_path / "few.xyz"
    np.savetxt(src, points[:4])
    rc = main(["fans", str(src), "-o", str(tmp_path / "o.vtp")])
    _assert_clean_error(rc, capsys.readouterr().err, "at least k + 1 = 7")


def test_errors_in_a_subprocess_have_no_traceback(tmp_path, points):
    src = write_input(tmp_path, "ply", points)
    src.write_bytes(src.read_bytes()[:300])
    res = run_cli("fans", src, "-o", tmp_path / "o.vtp")
    _assert_clean_error(res.returncode, res.stderr, "cloud.ply")
    res = run_cli("fans", src, "-o", tmp_path / "o.txt")
    _assert_clean_error(res.returncode, res.stderr, ".vtp")


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--k", "2.5"], "argument --k: invalid int value: '2.5'"),
        (["--rule", "fastest"], "argument --rule: invalid choice: 'fastest'"),
        (["--bogus"], "unrecognized arguments: --bogus"),
        (None, "the following arguments are required: -o/--output"),
    ],
    ids=["float-k", "bad-choice", "unknown-flag", "missing-output"],
)
def test_argument_errors_exit_2(tmp_path, extra, message, capsys):
    args = ["fans", str(tmp_path / "in.npy")]
    if extra is not None:
        args += [*extra, "-o", str(tmp_path / "o.vtp")]
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: fancloud") and message in err


def test_out_of_range_parameter_exits_2(tmp_path, points, capsys):
    src = write_input(tmp_path, "npy", points)
    rc = main(["fans", str(src), "-o", str(tmp_path / "o.vtp"), "--k", "100"])
    _assert_clean_error(rc, capsys.readouterr().err, "k must be between 3 and 64, got 100")


def test_bench_help_lists_the_benchmarks(capsys):
    from fancloud_vtk.cli import main

    with pytest.raises(SystemExit) as done:
        main(["bench", "--help"])
    assert done.value.code == 0
    assert "fans" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["fans", "mesh", "entropy", "reduce", "refine", "vdfc",
                                     "demo", "bench"])
def test_every_command_prints_its_help(command, capsys):
    # a parameter's text with a '%' ("0.1% of the diagonal") once broke argparse's help
    with pytest.raises(SystemExit) as done:
        main([command, "--help"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith("usage: fancloud " + command)
