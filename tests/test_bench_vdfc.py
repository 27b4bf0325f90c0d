"""Smoke test of ``fancloud bench vdfc`` (paper section 8) on a tiny terrain."""

import json
import math

import numpy as np
from test_bench import _is_number, _tables

from fancloud_vtk.bench.report import COLUMNS
from fancloud_vtk.bench.vdfc import PEER_COLUMNS, SURFACES, _surface_errors, grid_triangles
from fancloud_vtk.cli import main as cli_main

PNG = b"\x89PNG\r\n\x1a\n"


def test_surface_errors_of_a_plane():
    # the grid's own triangles reproduce its heights; a tilted plane is off by its tilt
    ny, nx = 6, 7
    jj, ii = np.meshgrid(np.arange(nx), np.arange(ny))
    heights = 0.5 * jj + 0.25 * ii
    verts = np.column_stack([jj.ravel() * 2.0, ii.ravel() * 3.0, heights.ravel()])
    tri = grid_triangles(ny, nx)
    assert len(tri) == 2 * (ny - 1) * (nx - 1)
    want = np.ones((ny, nx), np.bool_)
    best, worst, hits = _surface_errors(verts, tri, heights, (2.0, 3.0), (0.0, 0.0), want)
    assert (hits > 0).all() and np.allclose(best, 0) and np.allclose(worst, 0)
    lifted = verts.copy()
    lifted[:, 2] += 1.5
    best, _, hits = _surface_errors(lifted, tri[:1], heights, (2.0, 3.0), (0.0, 0.0), want)
    covered = hits > 0
    assert covered.sum() == 3 and np.allclose(best[covered], 1.5)  # one triangle: 3 nodes


def test_bench_vdfc_smoke(tmp_path, capsys):
    out = tmp_path / "bench"
    argv = ["bench", "vdfc", "--n", "120", "--frames", "8", "--repeat", "1",
            "--render-frames", "2", "--cameras", "2", "--samples", "5000",
            "--out", str(out), "-q"]
    assert cli_main(argv) == 0

    text = (out / "vdfc.md").read_text()
    assert text in capsys.readouterr().out
    for name in ("vdfc_frames.png", "vdfc_peers.png", "frames/frame_0000.png",
                 "frames/frame_0001.png"):
        assert (out / name).read_bytes()[:8] == PNG, name
    (header, figures), (pheader, peers) = _tables(text)
    assert tuple(header) == COLUMNS
    by_name = {row["figure"]: row for row in figures}
    for name in ("build: build_fans", "build: forest, no blocks", "build: forest, blocks",
                 "frames: front update, mean", "frames: front update, max",
                 "frames: active points, mean", "render: fly-through frame, mean"):
        assert _is_number(by_name[name]["measured"]), by_name[name]
        assert float(by_name[name]["measured"].replace(",", "")) > 0
    for name in ("build: ratio forest (blocks) / build_fans", "frames: front update, mean",
                 "frames: front update, max", "frames: triangles per active point, mean",
                 "peers: ratio ours / best peer, SSE max over every layer drawn",
                 "peers: points under no triangle, ours (front)"):
        assert by_name[name]["verdict"] in ("yes", "NO"), by_name[name]
    tpp = float(by_name["frames: triangles per active point, mean"]["measured"])
    assert 1 < tpp < 3
    mean = float(by_name["frames: front update, mean"]["measured"])
    assert mean <= float(by_name["frames: front update, max"]["measured"])
    ours = float(by_name["peers: screen-space error max, nearest layer, ours (front)"]["measured"])
    assert math.isfinite(ours) and ours >= 0
    p99 = float(by_name["peers: screen-space error 99th percentile, nearest layer, ours (front)"]
                ["measured"])
    assert 0 <= p99 <= ours
    # every layer drawn: never below the nearest layer
    worst = float(by_name["peers: screen-space error max over every layer drawn, ours (front)"]
                  ["measured"])
    assert worst >= ours
    assert "no triangle" in by_name["peers: ratio ours / best peer, SSE max over every layer "
                                    "drawn"]["parameters"]

    # Figures 13 and 14: entropy merges against half-edge collapses, folded fans counted
    for merge in ("entropy merges (the default)", "half-edge collapses"):
        for name in (f"merges: fans folded at merge time (Fig. 14), {merge}",
                     f"merges: folded front triangles per frame, mean, {merge}"):
            assert _is_number(by_name[name]["measured"]), by_name[name]
    assert raw_merges(out)["entropy"]["folded"] <= raw_merges(out)["half_edge"]["folded"]
    ratio = by_name["merges: screen-space error p99 at equal triangles (Fig. 13), half-edge "
                    "collapses / entropy merges"]
    assert _is_number(ratio["measured"]) and float(ratio["measured"]) > 0
    sse = raw_merges(out)["sse"]  # the half-edge front held the entropy front's triangles
    assert abs(sse["half_edge"]["triangles"] - sse["entropy"]["triangles"]) \
        <= 0.01 * sse["entropy"]["triangles"]

    assert tuple(pheader) == PEER_COLUMNS
    assert [row["surface"] for row in peers] == list(SURFACES)
    for row in peers:
        for key in ("points", "triangles", "SSE max", "SSE p99", "points in view"):
            assert _is_number(row[key]), (key, row)
    # the front covers nearly every point in view (fans of merged nodes may stop short
    # of the terrain's outer border)
    missed = int(peers[0]["under no triangle"].replace(",", ""))
    assert missed <= 0.05 * int(peers[0]["points in view"].replace(",", ""))

    raw = json.loads((out / "vdfc.json").read_text())
    frames = raw["frames"]["frames"]
    assert len(frames) == 8 and all(f["active"] > 0 for f in frames)
    assert raw["build"]["n"] == 120 * 120 and raw["build"]["blocks"] == 64
    assert raw["build"]["half_blocks"] == 4
    assert len(raw["render"]["rows"]) == 2
    lines = (out / "vdfc_frames.csv").read_text().splitlines()
    assert len(lines) == 9 and lines[0].startswith("frame,")


def raw_merges(out):
    return json.loads((out / "vdfc.json").read_text())["merges"]


def test_bench_vdfc_one_part(tmp_path, capsys):
    out = tmp_path / "bench"
    assert cli_main(["bench", "vdfc", "--part", "build", "--n", "60", "--repeat", "1",
                     "--out", str(out), "-q"]) == 0
    text = (out / "vdfc.md").read_text()
    assert "build: ratio forest (blocks) / build_fans" in text and "frames:" not in text
    assert not (out / "vdfc_frames.png").exists() and not (out / "vdfc_peers.png").exists()


def test_terrains_of_the_bench():
    # the three height fields: their grid, relief and spacing, and e_max scaled to them
    from fancloud_vtk.bench.vdfc import DEFAULT_E_MAX, TERRAINS, default_e_max, terrain

    seen = {}
    for data in TERRAINS:
        heights, spacing, origin, label = terrain(50, data, seed=3)
        assert heights.shape == (50, 50) and np.isfinite(heights).all(), data
        assert np.ptp(heights) > 100 and min(spacing) > 0 and origin == (0.0, 0.0), data
        assert "50 x 50 (2,500 points" in label, label
        seen[data] = default_e_max(heights, spacing, data)
    assert seen["jacksboro"] == DEFAULT_E_MAX
    assert seen["topobathy"] > 5 * DEFAULT_E_MAX  # a ground about 8 times as wide
    # the fractal ground is 30 m a step: 1,470 m wide here, 43.7 km for Jacksboro's diagonal
    assert math.isclose(seen["fractal"], DEFAULT_E_MAX * 1470 * math.sqrt(2) / 43_692, rel_tol=0.01)
    fractal = terrain(50, "fractal", seed=3)[0]
    assert np.array_equal(fractal, terrain(50, "fractal", seed=3)[0])  # a seed, one surface
    assert not np.array_equal(fractal, terrain(50, "fractal", seed=4)[0])
    assert math.isclose(np.ptp(fractal), 1000.0)
    try:
        terrain(50, "moon")
    except ValueError as exc:
        assert "moon" in str(exc) and "jacksboro" in str(exc)
    else:
        raise AssertionError("an unknown terrain was accepted")


def test_bench_vdfc_on_another_terrain(tmp_path, capsys):
    out = tmp_path / "bench"
    assert cli_main(["bench", "vdfc", "--data", "fractal", "--part", "frames", "--n", "60",
                     "--frames", "4", "--render-frames", "0", "--out", str(out), "-q"]) == 0
    raw = json.loads((out / "vdfc.json").read_text())
    assert raw["args"]["data"] == "fractal" and raw["data"].startswith("fractal terrain 60 x 60")
    assert math.isclose(raw["args"]["e_max"], raw["frames"]["e_max"])
    assert "scaled by the ground's diagonal" in (out / "vdfc.md").read_text()
    rows = {r["figure"]: r for r in raw["rows"]}
    assert rows["frames: triangles per active point, mean"]["data"] == raw["data"]


def test_bench_vdfc_on_a_scanned_object(tmp_path, capsys):
    # the bunny as a point set: the build and frames parts, cameras circling it; peers and
    # merges measure on a height field's grid and are left out, and said so
    out = tmp_path / "bench"
    assert cli_main(["bench", "vdfc", "--data", "bunny", "--frames", "4", "--repeat", "1",
                     "--render-frames", "0", "--out", str(out), "-q"]) == 0
    raw = json.loads((out / "vdfc.json").read_text())
    assert raw["args"]["part"] == ["build", "frames"] and raw["data"].startswith("Stanford bunny")
    rows = {r["figure"]: r for r in raw["rows"]}
    ratio = rows["build: ratio forest / build_fans, the points as a point set"]
    assert ratio["verdict"] in ("yes", "NO") and float(ratio["measured"]) > 0
    tpp = float(rows["frames: triangles per active point, mean"]["measured"])
    assert 1 < tpp < 3
    assert "orbit_path(bounds, 4)" in rows["frames: front update, mean"]["parameters"]
    text = (out / "vdfc.md").read_text()
    assert "not run on a point set: peers, merges" in text
    assert (out / "vdfc_frames.png").read_bytes()[:8] == PNG
    capsys.readouterr()
    assert cli_main(["bench", "vdfc", "--data", "bunny", "--part", "peers", "--out",
                     str(out), "-q"]) != 0
    err = capsys.readouterr().err
    assert "point set" in err and "height field" in err


def test_orbit_path_circles_the_object():
    from fancloud_vtk.bench.vdfc import orbit_path

    cams = orbit_path((0, 2, 0, 2, 0, 2), 8)
    centre = np.ones(3)
    dist = [np.linalg.norm(np.subtract(c[0], centre)) for c in cams]
    assert np.allclose(dist, 1.2 * np.sqrt(12)) and all(c[1] == (1.0, 1.0, 1.0) for c in cams)
    heights = [c[0][2] for c in cams]
    assert heights[0] < 1.0 < heights[-1] and np.all(np.diff(heights) > 0)  # it rises
