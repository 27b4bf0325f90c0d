"""Smoke test of ``fancloud bench refine`` (paper section 7) on tiny sizes."""

import json

import numpy as np
from test_bench import _is_number, _tables

from fancloud_vtk.bench.metrics import signed_volume
from fancloud_vtk.bench.refine import CYCLE_COLUMNS
from fancloud_vtk.bench.report import COLUMNS
from fancloud_vtk.cli import main as cli_main

PNG = b"\x89PNG\r\n\x1a\n"


def test_signed_volume_of_a_cube():
    v = np.array([[x, y, z] for x in (0, 2) for y in (0, 2) for z in (0, 2)], float)
    # outward-oriented triangles of the cube [0, 2]^3 (vertex index = 4x + 2y + z)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tri = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    assert np.isclose(signed_volume(v, tri), 8.0)
    assert np.isclose(signed_volume(v, np.asarray(tri)[:, ::-1]), -8.0)


def test_bench_refine_smoke(tmp_path, capsys):
    out = tmp_path / "bench"
    argv = ["bench", "refine", "--n", "3000", "--cycles", "2", "--repeat", "1",
            "--samples", "1", "--out", str(out), "-q"]
    assert cli_main(argv) == 0

    text = (out / "refine.md").read_text()
    assert text in capsys.readouterr().out
    for name in ("refine_cycles.png", "refine_cycles_error.png"):
        assert (out / name).read_bytes()[:8] == PNG, name
    (header, figures), (cheader, cycles) = _tables(text)
    assert tuple(header) == COLUMNS
    by_name = {row["figure"]: row for row in figures}
    for name in ("speed: build_fans, 2n points", "speed: refine n -> 2n",
                 "speed: refine n -> 2n, exact=True"):
        assert _is_number(by_name[name]["measured"]), by_name[name]
        assert float(by_name[name]["measured"]) > 0
    ratio = by_name["speed: ratio refine / build_fans(2n)"]
    assert float(ratio["measured"]) > 0 and ratio["verdict"] in ("yes", "NO")
    hmax = by_name["cycles: Hausdorff max after cycle 2"]
    assert 0 < float(hmax["measured"]) < 0.05 and hmax["verdict"] in ("yes", "NO")
    hmean = by_name["cycles: Hausdorff mean after cycle 2"]
    assert 0 < float(hmean["measured"]) < float(hmax["measured"])
    vol = by_name["cycles: volume change after cycle 2"]
    assert abs(float(vol["measured"])) < 5 and vol["verdict"] in ("yes", "NO")

    assert tuple(cheader) == CYCLE_COLUMNS
    assert [row["cycle"] for row in cycles] == ["0", "1", "2"]
    for row in cycles:
        for key in ("points", "triangles", "Hausdorff max", "Hausdorff mean",
                    "volume change (%)"):
            assert _is_number(row[key]), (key, row)
    assert cycles[0]["volume change (%)"] == "+0.000"
    assert cycles[-1]["points"] == cycles[0]["points"]

    raw = json.loads((out / "refine.json").read_text())
    assert raw["speed"]["n"] == 3000 and raw["speed"]["refined_points"] == 6000
    assert len(raw["cycles"]["states"]) == 3


def test_bench_refine_one_part(tmp_path, capsys):
    out = tmp_path / "bench"
    assert cli_main(["bench", "refine", "--part", "speed", "--n", "2000", "--repeat", "1",
                     "--out", str(out), "-q"]) == 0
    text = (out / "refine.md").read_text()
    assert "speed: ratio refine / build_fans(2n)" in text and "cycles:" not in text
    assert not (out / "refine_cycles.png").exists()
