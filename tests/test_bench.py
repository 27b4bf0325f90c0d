"""Smoke test of ``fancloud bench fans`` on tiny sizes, through the command line."""

import json

import numpy as np
import pytest

from fancloud_vtk.bench import COLUMNS, parse_size, parse_sizes, size_label, surface_points
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
    assert raw["args"]["sizes"] == [5000]
    assert len(raw["speed"][0]["ours_times"]) == 1
    assert raw["memory"][0]["peak"] >= raw["memory"][0]["rss_before"] > 0
    assert raw["machine"]["cores"] >= 1


def test_bench_requires_a_mode(capsys):
    from fancloud_vtk.bench import main

    with pytest.raises(SystemExit):
        main([])
