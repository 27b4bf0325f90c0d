"""``fancloud bench mesh``: triangle meshes from the same points, ours against the peers.

``fancloud bench mesh [--data bunny sphere 1M ...] [--methods ...] [--timeout 600]``

This project (``build_fans`` + ``fan_cloud_to_mesh``) against MeshLib's
``triangulatePointCloud``, pymeshlab's ball pivoting and screened Poisson, and VTK's
``vtkSurfaceReconstructionFilter`` (:mod:`fancloud_vtk.bench.peers`). Per method:
time, triangles per point, non-manifold edges and vertices, boundary edges, holes,
self-intersecting triangle pairs, unused points and the distance to the reference
surface; our stage counts beside the paper's. Each method runs in its own process
with a timeout (:func:`fancloud_vtk.bench.harness.run_method`): a missing, failing,
crashing or hanging method is a row saying so. Writes ``mesh.md`` (also printed),
``mesh.json`` and ``mesh.png`` (one bar panel per metric). ``--data corpus-small`` /
``corpus`` (:mod:`fancloud_vtk.corpus`): real models, resamplings and simulated range
scans, each against its own mesh, with a table per entry (self-intersecting faces,
unused points and outliers, boundary and non-manifold counts, distances in median
spacings) and a render ``corpus_NAME.png`` of its worst regions.
"""

from __future__ import annotations

import argparse
import fnmatch
import gc
import os
import tempfile
import time

import numpy as np

from fancloud_vtk.bench.common import (
    WARMUP_POINTS,
    K,
    _log,
    _short,
    data_label,
    parse_size,
    size_label,
    surface_points,
)
from fancloud_vtk.bench.harness import run_method
from fancloud_vtk.bench.metrics import (
    MeshDistance,
    mesh_statistics_of,
    sphere_distance,
    surface_distance,
    used_inputs,
)
from fancloud_vtk.bench.peers import METHODS, method_for
from fancloud_vtk.bench.report import (
    _num,
    _ok,
    _row,
    header,
    markdown,
    package_versions,
    table_lines,
    write_outputs,
)

#: The issue's targets for ``bench mesh`` (our method only; the peers are measured, not judged).
TARGET_NON_MANIFOLD = 0  #: non-manifold edges, and non-manifold vertices
#: triangles per point on a closed surface of genus 0: (2 n - 4) / n (Euler's formula), give
#: or take this; about 1.95 to 2.05 for a large n, exactly 1.5 for a cube's 8 corners
TARGET_TPP_TOL = 0.05
TARGET_SELF_PCT = 0.01  #: self-intersecting triangle pairs, percent of the triangles
TARGET_MESHLIB_RATIO = 1.0  #: our time / MeshLib's time ...
MESHLIB_TARGET_SIZES = (100_000, 300_000, 1_000_000)  #: ... at these sizes
TARGET_BPA_SPEEDUP = 10.0  #: ball-pivoting time / our time, at the same sizes

MESH_TIMEOUT = 600.0  #: default seconds allowed to one method (warm-up included)
SAMPLES_PER_POINT = 10  #: surface samples per input point for the distance

#: Stage counts of fan_cloud_to_mesh (keys of its ``.stats``) and the paper's figures (§4).
PAPER_STAGES = (
    ("fan_triangles", "all fan triangles", "about 6 (k n, k = 6)"),
    ("distinct", "distinct triangles", "about 2.5"),
    ("after_superfluous", "after removing superfluous triangles", "about 2.1"),
    ("final", "final mesh", "2 - 4/n (closed genus-0 mesh)"),
)

#: The columns of the per-data comparison table, and the metric of the figure's panels.
COMPARE_COLUMNS = ("method", "time (s)", "triangles", "triangles / point", "non-manifold edges",
                   "non-manifold vertices", "boundary edges", "holes",
                   "self-intersecting pairs", "unused points", "distance mean",
                   "distance max", "status")
PANELS = (
    ("time", "time (s), log scale"), ("triangles_per_point", "triangles per point"),
    ("non_manifold_edges", "non-manifold edges"),
    ("non_manifold_vertices", "non-manifold vertices"), ("boundary_edges", "boundary edges"),
    ("holes", "holes (boundary loops)"), ("self_intersections", "self-intersecting pairs"),
    ("unused_points", "unused points"), ("distance_mean", "distance mean / bbox diagonal"),
    ("distance_max", "distance max / bbox diagonal"),
)

#: ``--data`` names of the corpus lists (:func:`fancloud_vtk.corpus.corpus`).
CORPUS_DATA = {"corpus": "full", "corpus-small": "small"}


def parse_data(tokens: list[str], n: int) -> list[tuple[str, int | None]]:
    """``['bunny', 'sphere', '5k']`` -> ``[('bunny', None), ('sphere', n), ('sphere', 5000)]``.

    ``corpus`` and ``corpus-small`` give ``('corpus', None)`` and
    ``('corpus-small', None)``: every entry of that corpus list.
    """
    out = []
    for token in (t.strip() for text in tokens for t in text.split(",")):
        if not token:
            continue
        low = token.lower()
        if low == "bunny":
            out.append(("bunny", None))
        elif low in CORPUS_DATA:
            out.append((low, None))
        elif low == "sphere":
            out.append(("sphere", n))
        else:
            try:
                out.append(("sphere", parse_size(token)))
            except ValueError as exc:
                raise ValueError(f"--data: {token!r} is not bunny, sphere, corpus, "
                                 "corpus-small or a number of points") from exc
    if not out:
        raise ValueError("--data: nothing given")
    return out


def mesh_data(kind: str, n: int | None, seed: int) -> dict:
    """Points, label and reference surface (a distance function) of one ``--data`` entry."""
    if kind == "bunny":
        from fancloud_vtk.data import bunny_path
        from fancloud_vtk.io import read_point_cloud

        f = read_point_cloud(bunny_path())
        pts = f.points
        return {"kind": kind, "n": len(pts), "points": pts,
                "label": f"Stanford bunny (pymeshlab bunny.obj), {len(pts):,} points",
                "reference": f"the bunny.obj mesh ({len(f.faces):,} triangles), "
                             "vtkImplicitPolyDataDistance",
                "distance": MeshDistance(pts, f.faces)}
    pts = surface_points(n, seed, "sphere")
    return {"kind": kind, "n": n, "points": pts, "label": data_label(n, "sphere", seed),
            "reference": "the unit sphere, | |x| - 1 |", "distance": sphere_distance}


def corpus_data(entry) -> dict:
    """Points, label and reference (the entry's own mesh) of a corpus entry, as :func:`mesh_data`.

    ``corpus`` holds what the corpus table needs: the entry's name and
    kind, whether the reference is closed, its boundary edges, the
    outliers and the median spacing of the input points (the distances'
    unit).
    """
    from fancloud_vtk.core.mesh_stats import mesh_statistics
    from fancloud_vtk.corpus import boundary_edge_count, median_spacing

    pts = entry.points
    ref_boundary = boundary_edge_count(entry.ref_triangles)
    ref_pieces = int(mesh_statistics(entry.ref_points, entry.ref_triangles,
                                     self_intersections=False)["components"])
    closed = "closed" if entry.closed else f"open, {ref_boundary:,} boundary edges"
    info = {key: entry.info[key] for key in ("viewpoint", "target") if key in entry.info}
    return {"kind": "corpus", "n": len(pts), "points": pts,
            "label": f"{entry.name}, {entry.kind}, {len(pts):,} points",
            "reference": f"the model's own mesh ({len(entry.ref_triangles):,} triangles, "
                         f"{closed}), vtkImplicitPolyDataDistance",
            "distance": MeshDistance(entry.ref_points, entry.ref_triangles),
            "ref_points": entry.ref_points, "ref_triangles": entry.ref_triangles,
            "corpus": {"name": entry.name, "kind": entry.kind, "closed": bool(entry.closed),
                       "description": entry.description, "ref_points": len(entry.ref_points),
                       "ref_triangles": len(entry.ref_triangles),
                       "ref_boundary_edges": ref_boundary, "ref_pieces": ref_pieces,
                       "outliers": len(entry.outliers),
                       "spacing": median_spacing(pts),
                       **{k: [float(x) for x in v] for k, v in info.items()}},
            "outliers": np.asarray(entry.outliers, dtype=np.int64)}


def measure_mesh(r: dict, data: dict, samples: int, self_intersections: bool,
                 seed: int) -> dict | None:
    """Statistics and distance of a method's mesh (``r`` from ``run_method``), in place.

    On a corpus entry (:func:`corpus_data`) also the figures of the corpus
    table (:func:`_measure_corpus`); then it returns the arrays the render
    needs (:func:`corpus_render`), else None.
    """
    vertices, triangles = r.pop("vertices", None), r.pop("triangles", None)
    if vertices is None:
        return None
    n = data["n"]
    in_corpus = "corpus" in data
    r["n_vertices"], r["n_triangles"] = len(vertices), len(triangles)
    # on the corpus the pairs themselves are needed: counted once, in _measure_corpus
    r["stats"] = mesh_statistics_of(vertices, triangles, self_intersections and not in_corpus)
    t0 = time.perf_counter()
    d = surface_distance(vertices, triangles, data["distance"], samples * n, seed)
    diag = data["diag"]
    r["distance"] = {**d, "time": time.perf_counter() - t0, "diag": diag,
                     "mean_fraction": None if d["mean"] is None else d["mean"] / diag,
                     "max_fraction": None if d["max"] is None else d["max"] / diag}
    if in_corpus:
        return _measure_corpus(r, data, vertices, triangles, self_intersections)
    return None


def _measure_corpus(r: dict, data: dict, vertices, triangles, self_intersections: bool) -> dict:
    """The corpus table's figures of a method's mesh (``r["corpus"]``); the render's arrays.

    Self-intersecting faces: distinct triangles in a self-intersecting pair
    (the pairs are ``stats["self_intersections"]``). Unused points: input
    points that are no vertex of a triangle, the scan's outliers counted
    apart. Distances in median spacings of the input points.
    """
    c, render = {}, {"vertices": vertices, "triangles": triangles}
    spacing = data["corpus"]["spacing"] or 1.0
    stats = r["stats"]
    if self_intersections and len(triangles):
        try:
            from fancloud_vtk.core.mesh_stats import self_intersecting_pairs

            t0 = time.perf_counter()
            pairs = self_intersecting_pairs(vertices, triangles)
            faces = np.unique(pairs)
            stats["self_intersections"] = int(len(pairs))
            c["self_intersecting_faces"] = int(len(faces))
            c["self_intersections_time"] = time.perf_counter() - t0
            render["bad"] = faces
        except Exception as exc:  # reported in the table, not fatal
            c["error"] = f"self_intersecting_pairs failed ({_short(exc)})"
    elif len(triangles) == 0:
        stats["self_intersections"] = 0
        c["self_intersecting_faces"] = 0
    if not r["new_points"]:
        used = used_inputs(data["points"], vertices, triangles, data["diag"])
        outlier = np.zeros(len(used), dtype=bool)
        outlier[data["outliers"]] = True
        c["unused_points"] = int(np.count_nonzero(~used & ~outlier))
        c["unused_outliers"] = int(np.count_nonzero(~used & outlier))
        render["unused"] = np.flatnonzero(~used & ~outlier)
    d = r["distance"]
    for key in ("mean", "max"):
        c[f"distance_{key}_spacings"] = None if d[key] is None else d[key] / spacing
    if len(triangles):
        render["tri_distance"] = data["distance"](
            np.asarray(vertices)[np.asarray(triangles)].mean(axis=1)) / spacing
    r["corpus"] = c
    return render


def metric(r: dict, key: str):
    """A method's value of a metric (see :data:`PANELS`), or None when not measured/n/a."""
    if r["status"] != "ok":
        return None
    if key == "time":
        return r["time"]
    if key.startswith("distance_"):
        return r.get("distance", {}).get(key.split("_", 1)[1] + "_fraction")
    stats = r.get("stats", {})
    if key == "unused_points" and r["new_points"]:
        return None
    return stats.get(key)


def _cell(r: dict, key: str) -> str:
    if key == "time" and r.get("time_lower_bound"):
        return f"> {_num(r['time_lower_bound'])}"  # killed while timed
    if r["status"] != "ok":
        return "-"
    if key == "unused_points" and r["new_points"]:
        return "n/a"
    value = metric(r, key)
    if value is None:
        return "n/a"
    if key.startswith("distance_"):
        return f"{value:.3g}"
    if key == "triangles_per_point":
        return f"{value:.4f}"
    return _num(value) if isinstance(value, float) else f"{value:,}"


def compare_rows(ds: dict) -> list[dict]:
    """One row per method of a data set for the comparison table."""
    keys = ("time", None, "triangles_per_point", "non_manifold_edges", "non_manifold_vertices",
            "boundary_edges", "holes", "self_intersections", "unused_points",
            "distance_mean", "distance_max")
    rows = []
    for r in ds["methods"]:
        cells = [r["label"]]
        for key in keys:
            if key is None:
                cells.append(f"{r['n_triangles']:,}" if r["status"] == "ok" else "-")
            else:
                cells.append(_cell(r, key))
        status = r["message"]
        if r["status"] == "ok" and "error" in r.get("stats", {}):
            status += f"; statistics: {r['stats']['error']}"
        if r["status"] == "ok" and r["new_points"]:
            status += f" (new points: {r['n_vertices']:,} vertices)"
        cells.append(status)
        rows.append(dict(zip(COMPARE_COLUMNS, cells, strict=True)))
    return rows


#: The columns of the per-model table of a corpus entry (:func:`corpus_rows`).
CORPUS_COLUMNS = ("method", "time (s)", "triangles", "self-intersecting faces",
                  "unused points", "unused outliers", "boundary edges", "holes", "pieces",
                  "non-manifold edges", "non-manifold vertices", "distance mean (h)",
                  "distance max (h)", "status")


def corpus_rows(ds: dict) -> list[dict]:
    """One row per method of a corpus entry: the corpus table (distances in spacings ``h``)."""
    rows = []
    for r in ds["methods"]:
        ok = r["status"] == "ok"
        c, stats = r.get("corpus", {}), r.get("stats", {})

        def count(value, na=False, ok=ok):
            return "-" if not ok else "n/a" if na or value is None else f"{value:,}"

        def spacings(value, ok=ok):
            return "-" if not ok else "n/a" if value is None else _num(value)

        status = r["message"]
        for err in (stats.get("error"), c.get("error")):
            if ok and err:
                status += f"; {err}"
        if ok and r["new_points"]:
            status += f" (new points: {r['n_vertices']:,} vertices)"
        cells = (r["label"], _cell(r, "time"), count(r.get("n_triangles")),
                 count(c.get("self_intersecting_faces")),
                 count(c.get("unused_points"), r["new_points"]),
                 count(c.get("unused_outliers"), r["new_points"] or not ds["corpus"]["outliers"]),
                 count(stats.get("boundary_edges")), count(stats.get("holes")),
                 count(stats.get("components")),
                 count(stats.get("non_manifold_edges")),
                 count(stats.get("non_manifold_vertices")),
                 spacings(c.get("distance_mean_spacings")),
                 spacings(c.get("distance_max_spacings")), status)
        rows.append(dict(zip(CORPUS_COLUMNS, cells, strict=True)))
    return rows


def _corpus_lines(ds: dict) -> list[str]:
    """The section of a corpus entry in ``mesh.md``: what it is, its table, our stages."""
    c = ds["corpus"]
    closed = ("closed" if c["closed"] else f"open ({c['ref_boundary_edges']:,} boundary "
              "edges)")
    if "ref_pieces" in c:
        closed += f", {c['ref_pieces']:,} piece" + ("s" if c["ref_pieces"] != 1 else "")
    outliers = (f", {c['outliers']} of them outliers (stray points off the surface; they "
                "may stay unused)" if c["outliers"] else "")
    lines = [f"## {c['name']} ({c['kind']})", "",
             f"{c['description']}. Input: {ds['n']:,} points{outliers}; median spacing "
             f"h = {c['spacing']:.4g}. Reference: the model's own mesh, "
             f"{c['ref_triangles']:,} triangles on {c['ref_points']:,} vertices, {closed}. "
             "Distances: mesh -> reference, in h. Pieces: edge-connected components of "
             "the triangles."
             + (f" Render: `{ds['render']}`." if ds.get("render") else ""),
             "", *table_lines(CORPUS_COLUMNS, corpus_rows(ds)), ""]
    ours = _find(ds, "ours")
    if ours is not None and ours["status"] == "ok" and ours["info"].get("stages"):
        stages = ", ".join(f"{key} {value / ds['n']:.3f}"
                           for key, value in ours["info"]["stages"].items()
                           if key not in MESH_STAT_KEYS)
        lines += [f"Stages of ours, per point: {stages}.", ""]
    return lines


def _find(ds: dict, name: str) -> dict | None:
    return next((r for r in ds["methods"] if r["method"] == name), None)


def mesh_rows(res: dict) -> list[dict]:
    """The rows of the figures table of ``bench mesh`` (our method, against the targets)."""
    rows = []
    for ds in res["datasets"]:
        data, n = ds["label"], ds["n"]
        ours = _find(ds, "ours")
        if ours is None:
            continue
        call = ours["call"]
        ok = ours["status"] == "ok"
        stats = ours.get("stats", {}) if ok else {}
        missing = ours["message"] if not ok else f"n/a ({stats.get('error', 'not measured')})"
        n_used = stats.get("points") or 0
        euler = 2.0 - 4.0 / n_used if n_used else 2.0
        lo, hi = round(euler - TARGET_TPP_TOL, 4), round(euler + TARGET_TPP_TOL, 4)
        nm = TARGET_NON_MANIFOLD
        si = stats.get("self_intersections")
        tri = stats.get("triangles") or 0
        pct = None if si is None or not tri else 100.0 * si / tri
        corpus = ds.get("corpus")
        # triangles per point of a closed surface: not for an open or scanned one
        closed = corpus is None or (corpus["closed"] and corpus["kind"] != "scan")
        for name, key, value, unit, target, passed, params in (
            ("mesh: non-manifold edges", "non_manifold_edges",
             _count(stats.get("non_manifold_edges")), "edges", f"{nm}",
             _le(stats.get("non_manifold_edges"), nm), call),
            ("mesh: non-manifold vertices", "non_manifold_vertices",
             _count(stats.get("non_manifold_vertices")), "vertices", f"{nm}",
             _le(stats.get("non_manifold_vertices"), nm), call),
            ("mesh: triangles per point (closed surface)", "triangles_per_point",
             _fixed(stats.get("triangles_per_point"), 4), "triangles/point", f"{lo} to {hi}",
             None if stats.get("triangles_per_point") is None
             else lo <= stats["triangles_per_point"] <= hi,
             f"{call}; {tri:,} triangles, {stats.get('points') or 0:,} points" if stats
             else call),
            ("mesh: self-intersecting triangle pairs", "self_intersections",
             _fixed(pct, 4), "% of triangles", f"<= {TARGET_SELF_PCT:g}",
             _le(pct, TARGET_SELF_PCT),
             f"{call}; {si or 0:,} pairs in {tri:,} triangles" if si is not None else
             f"{call}; not computed (--no-self-intersections)" if "self_intersections" in stats
             else call),
        ):
            if key == "triangles_per_point" and not closed:
                continue
            if key not in stats or value is None:
                value = missing if key not in stats else "n/a"
                rows.append(_row(name, data, params, value, unit, target, "not measured"))
            else:
                rows.append(_row(name, data, params, value, unit, target, _ok(passed)))

        mine = _find(ds, "ours-pyvista")
        if mine is not None and (m := _find(ds, "meshlib")) is not None:
            params = (f"best times, warm, each method in its own process; "
                      f"pv.PolyData(points).fancloud.mesh() {_fmt_time(mine)}, {m['label']} "
                      f"{_fmt_time(m)}")
            if mine["status"] == "ok" and m["status"] == "ok":
                v = mine["time"] / m["time"]
                big = n in MESHLIB_TARGET_SIZES
                rows.append(_row("speed: time of the accessor call / MeshLib", data, params,
                                 f"{v:.3f}", "x", f"<= {TARGET_MESHLIB_RATIO:g}" if big else "",
                                 _ok(v <= TARGET_MESHLIB_RATIO) if big else ""))
            else:
                rows.append(_row("speed: time of the accessor call / MeshLib", data, params,
                                 "n/a", "x", "", "not measured"))
        for peer, name, better, target, test in (
            ("meshlib", "speed: time ours / MeshLib", "ratio",
             f"<= {TARGET_MESHLIB_RATIO:g} (at 100k, 300k, 1M)" if n in MESHLIB_TARGET_SIZES
             else "",
             (lambda v: v <= TARGET_MESHLIB_RATIO) if n in MESHLIB_TARGET_SIZES else None),
            # the issues state the speed figures at 100k and 1M points (and 300k for MeshLib)
            ("ball-pivoting", "speed: ball pivoting time / ours", "speedup",
             f">= {TARGET_BPA_SPEEDUP:g} (at 100k, 300k, 1M)" if n in MESHLIB_TARGET_SIZES else "",
             (lambda v: v >= TARGET_BPA_SPEEDUP) if n in MESHLIB_TARGET_SIZES else None),
        ):
            p = _find(ds, peer)
            if p is None:
                continue
            params = (f"best times, warm (after a {WARMUP_POINTS:,}-point run), each method "
                      f"in its own process; ours {_fmt_time(ours)}, {p['label']} "
                      f"{_fmt_time(p)}")
            if ok and p["status"] == "ok":
                v = ours["time"] / p["time"] if better == "ratio" else p["time"] / ours["time"]
                rows.append(_row(name, data, params, f"{v:.3f}", "x", target,
                                 _ok(test(v)) if test else ""))
            elif ok and p.get("time_lower_bound") and better == "speedup":
                v = p["time_lower_bound"] / ours["time"]  # the peer was killed while timed
                rows.append(_row(name, data, params, f"> {v:.1f}", "x", target,
                                 _ok(test(v)) if test else ""))
            else:
                rows.append(_row(name, data, params, "n/a", "x", target, "not measured"))
    return rows


def _count(value) -> str | None:
    return None if value is None else f"{value:,}"


def _fixed(value, digits: int) -> str | None:
    return None if value is None else f"{value:.{digits}f}"


def _le(value, limit) -> bool | None:
    return None if value is None else value <= limit


def _fmt_time(r: dict) -> str:
    return f"{_num(r['time'])} s" if r["status"] == "ok" else r["message"]


#: Keys of mesh_statistics: in the comparison table, so left out of the stage table.
MESH_STAT_KEYS = frozenset((
    "points", "triangles", "unused_points", "edges", "boundary_edges", "holes",
    "non_manifold_edges", "non_manifold_vertices", "inconsistent_edges", "degenerate_triangles",
    "duplicate_triangles", "self_intersections", "components", "euler_characteristic",
    "triangles_per_point",
))


def stage_rows(r: dict, n_points: int) -> list[dict]:
    """Our stage counts per point beside the paper's (from ``fan_cloud_to_mesh(...).stats``).

    In the order of ``.stats`` (the pipeline's); checks of the result
    (:data:`MESH_STAT_KEYS`) are left out.
    """
    paper = {key: (label, text) for key, label, text in PAPER_STAGES}
    rows = []
    for key, value in (r.get("info", {}).get("stages") or {}).items():
        if key in MESH_STAT_KEYS:
            continue
        label, text = paper.get(key, ("", ""))
        rows.append({"stage": f"{label} (`{key}`)" if label else f"`{key}`",
                     "count": f"{value:,}", "per point": f"{value / n_points:.3f}",
                     "paper per point": text})
    return rows


def peer_versions() -> dict:
    """Installed versions of the peers' packages (None if not installed)."""
    return package_versions(("meshlib", "pymeshlab", "vtk", "matplotlib"))


def mesh_markdown(res: dict) -> str:
    """Header and figures table, then per data set the comparison and our stage counts."""
    versions = ", ".join(f"{k} {v or 'not installed'}" for k, v in res["peers"].items())
    a = res["args"]
    notes = [
        f"peers: {versions}",
        f"each method runs in its own process (timeout {a['timeout']:g} s), warmed up on "
        f"{WARMUP_POINTS:,} sphere points, then timed (best of {a['repeat']}); its mesh is then "
        "measured here",
        f"distance: {a['samples']} area-weighted random samples per input point on the "
        "method's surface (plus its vertices for the max), unsigned distance to the reference, "
        "as a fraction of the bounding-box diagonal of the input points",
        "self-intersecting pairs: " + ("fancloud_vtk.core.mesh_stats.mesh_statistics"
                                       if a["self_intersections"]
                                       else "not computed (--no-self-intersections)"),
    ]
    if any("corpus" in ds for ds in res["datasets"]):
        notes.append(
            "corpus (fancloud_vtk.corpus, seed " + str(a["seed"]) + "): the reference is the "
            "entry's own mesh; self-intersecting faces are the distinct triangles of the "
            "self_intersecting_pairs; unused points are input points in no triangle (matched "
            "by position), a scan's outliers counted apart; distances are in median "
            "nearest-neighbour spacings h of the input points; the render of each entry "
            "(corpus_NAME.png) colours the triangles by their centroid's distance to the "
            "reference, self-intersecting ones red, unused points magenta")
    text = markdown("fancloud bench mesh: triangle meshes from point clouds", res, res["rows"],
                    notes)
    lines = [""]
    for ds in res["datasets"]:
        if "corpus" in ds:
            lines += _corpus_lines(ds)
            continue
        lines += [f"## {ds['label']}", "",
                  f"Reference surface: {ds['reference']}; bounding-box diagonal "
                  f"{ds['diag']:.4g}.", "", *table_lines(COMPARE_COLUMNS, compare_rows(ds)), ""]
        ours = _find(ds, "ours")
        if ours is not None and ours["status"] == "ok" and ours["info"].get("stages"):
            info = ours["info"]
            lines += [f"Stage counts of `fan_cloud_to_mesh` (build_fans "
                      f"{info['build_fans_time']:.3f} s + fan_cloud_to_mesh "
                      f"{info['to_mesh_time']:.3f} s; "
                      f"{info['fans_open']:,} open fans):", "",
                      *table_lines(("stage", "count", "per point", "paper per point"),
                                   stage_rows(ours, ds["n"])), ""]
            timings = (info.get("other_stats") or {}).get("timings")
            if isinstance(timings, dict) and timings:
                lines += ["Stage times: " + ", ".join(
                    f"{k} {v:.3f} s" for k, v in timings.items()
                    if isinstance(v, int | float)) + ".", ""]
    lines += ["## Methods", ""]
    seen = []
    for ds in res["datasets"]:
        for r in ds["methods"]:
            if r["method"] not in seen:
                seen.append(r["method"])
                extra = ("; its vertices are new points (unused points: n/a; triangles per "
                         "point: per output vertex)" if r["new_points"] else "")
                lines.append(f"- **{r['label']}** (`{r['method']}`): {r['call']}{extra}")
    return text + "\n".join(lines) + "\n"


def mesh_chart(res: dict, path: str) -> str:
    """A bar chart, one panel per metric: bars per method, grouped by data set (Agg)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    datasets = res["datasets"]
    names = []
    for ds in datasets:
        names += [r["method"] for r in ds["methods"] if r["method"] not in names]
    labels = {r["method"]: r["label"] for ds in datasets for r in ds["methods"]}
    cols = 5
    rows = -(-len(PANELS) // cols)
    fig = Figure(figsize=(4.2 * cols, 3.6 * rows + 0.8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    width = 0.8 / max(len(names), 1)
    colours = [f"C{i}" for i in range(len(names))]
    short = [ds["corpus"]["name"] if "corpus" in ds else
             ds["label"].split(",")[0].replace("Stanford bunny (pymeshlab bunny.obj)", "bunny")
             + (f"\n{size_label(ds['n'])}" if ds["kind"] != "bunny" else "")
             for ds in datasets]
    for ax, (key, title) in zip(axes, PANELS, strict=False):
        top = 0.0
        for j, name in enumerate(names):
            for i, ds in enumerate(datasets):
                r = _find(ds, name)
                if r is None:
                    continue
                x = i - 0.4 + (j + 0.5) * width
                value = metric(r, key)
                if value is not None and (key != "time" or value > 0):
                    ax.bar(x, value, width, color=colours[j])
                    top = max(top, value)
                why = (r["status"] if r["status"] != "ok" else "n/a" if value is None
                       else "0" if value == 0 else "")
                if why:
                    ax.text(x, 0.01, why, rotation=90 if len(why) > 1 else 0, ha="center",
                            va="bottom", fontsize=7, color=colours[j],
                            transform=ax.get_xaxis_transform())
        ax.set_title(title, fontsize=10)
        if len(datasets) > 4:  # many data sets (the corpus): slanted labels
            ax.set_xticks(range(len(datasets)), short, fontsize=7, rotation=45, ha="right",
                          rotation_mode="anchor")
        else:
            ax.set_xticks(range(len(datasets)), short, fontsize=8)
        ax.set_xlim(-0.5, len(datasets) - 0.5)
        if key == "time" and top > 0:
            ax.set_yscale("log")
        elif top == 0:
            ax.set_ylim(0, 1)
        else:
            ax.set_ylim(0, top * 1.08)
        ax.tick_params(axis="y", labelsize=8)
    for ax in axes[len(PANELS):]:
        ax.set_visible(False)
    fig.legend([Patch(color=c) for c in colours], [labels[name] for name in names],
               loc="outside lower center", ncols=min(len(names), 5), fontsize=9)
    fig.suptitle("fancloud bench mesh (missing / failed / timeout written at the bar's place)",
                 fontsize=11)
    fig.savefig(path, dpi=90)
    return path


RENDER_SIZE = 360  #: pixels per side of a panel of the corpus renders
RENDER_FOV = 30.0  #: their field of view, degrees
RENDER_CLIP = 2.0  #: distance (median spacings) at the top of their colour scale


def _render_view(points, triangles, colours, viewpoint, target, up):
    """An RGB image of a mesh with per-triangle colours, flat-shaded (two-sided); the z-buffer."""
    from fancloud_vtk.corpus import rasterize

    img = np.ones((RENDER_SIZE, RENDER_SIZE, 3))
    if len(triangles) == 0:
        return img, None
    z = rasterize(points, triangles, viewpoint=viewpoint, target=target,
                  resolution=(RENDER_SIZE, RENDER_SIZE), fov=RENDER_FOV, up=up)
    a, b, c = (points[triangles[:, k]] for k in range(3))
    normal = np.cross(b - a, c - a)
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    hit = z.triangle >= 0
    t = z.triangle[hit]
    shade = 0.35 + 0.65 * np.abs(normal[t] @ z.forward)
    img[hit] = colours[t] * shade[:, None]
    return img, z


def _fmt(value) -> str:
    return "n/a" if value is None else f"{value:,}"


def _worst_point(mesh: dict) -> np.ndarray | None:
    """Where a mesh is worst: the densest cluster of self-intersecting faces, else the
    triangle farthest from the reference."""
    v, t = np.asarray(mesh["vertices"]), np.asarray(mesh["triangles"])
    if len(t) == 0:
        return None
    bad = mesh.get("bad")
    if bad is not None and len(bad):
        from scipy.spatial import cKDTree

        cent = v[t[bad]].mean(axis=1)
        radius = 0.05 * float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
        counts = [len(x) for x in cKDTree(cent).query_ball_point(cent, radius)]
        return cent[int(np.argmax(counts))]
    if mesh.get("tri_distance") is not None:
        return v[t[int(np.argmax(mesh["tri_distance"]))]].mean(axis=0)
    return None


def corpus_render(ds: dict, meshes: dict, data: dict, path: str) -> str | None:
    """Each method's mesh of a corpus entry, side by side, where it is worst (Agg).

    Columns: the methods with a mesh (at most four, in the order they ran).
    Rows: the whole model (seen from the scanner for a scan, else across
    its thinnest principal axis), then a close-up on the worst region of
    the first method's mesh (its densest cluster of self-intersecting
    faces, else its triangle farthest from the reference), every method
    from the same camera. Triangles are coloured by their centroid's
    distance to the reference (0 to ``RENDER_CLIP`` median spacings),
    self-intersecting ones red; unused input points (not the outliers) are
    magenta dots where visible.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import LinearSegmentedColormap, Normalize
    from matplotlib.figure import Figure

    shown = [(r, meshes[r["method"]]) for r in ds["methods"] if r["method"] in meshes][:4]
    if not shown:
        return None
    ref = np.asarray(data["ref_points"])
    lo, hi = ref.min(axis=0), ref.max(axis=0)
    centre, diag = 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))
    axes3 = np.linalg.eigh(np.cov((ref - centre).T))[1]  # columns: increasing variance
    up = axes3[:, 1]
    c = ds["corpus"]
    if "viewpoint" in c:  # a scan: from its scanner
        direction = np.asarray(c["viewpoint"]) - np.asarray(c["target"])
    else:
        direction = axes3[:, 0] + 0.35 * axes3[:, 1] + 0.25 * axes3[:, 2]
    direction /= np.linalg.norm(direction)
    if abs(direction @ up) > 0.95:
        up = axes3[:, 2]
    distance = 0.4 * diag / np.tan(np.radians(0.5 * RENDER_FOV))
    views = [("whole model", centre + distance * direction, centre)]
    worst = next((w for w in (_worst_point(m) for _, m in shown) if w is not None), None)
    if worst is not None:
        if "viewpoint" in c:
            close = np.asarray(c["viewpoint"]) - worst
        else:
            close = worst - centre
            close = direction if np.linalg.norm(close) < 0.05 * diag else close
        close = close / np.linalg.norm(close)
        views.append(("worst region of the first", worst + 0.4 * diag * close, worst))

    # grey on the surface, through blue to black far from it: red stays for the intersections
    cmap = LinearSegmentedColormap.from_list("distance", ["#d0d0d0", "#3b7dd8", "#0b1f4d"])
    norm = Normalize(0.0, RENDER_CLIP)
    pts = data["points"]
    spacing = c["spacing"] or 1.0
    fig = Figure(figsize=(3.6 * len(shown) + 0.9, 3.75 * len(views) + 0.5),
                 layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(views), len(shown), squeeze=False)
    for col, (r, mesh) in enumerate(shown):
        v = np.asarray(mesh["vertices"], dtype=np.float64)
        t = np.asarray(mesh["triangles"], dtype=np.int64).reshape(-1, 3)
        dist = mesh.get("tri_distance")
        colours = cmap(norm(dist if dist is not None else np.zeros(len(t))))[:, :3]
        if mesh.get("bad") is not None:
            colours[mesh["bad"]] = (0.9, 0.0, 0.0)
        rc = r.get("corpus", {})
        st = r.get("stats", {})
        for row, (what, eye, target) in enumerate(views):
            ax = axes[row, col]
            img, z = _render_view(v, t, colours, eye, target, up if abs(
                (target - eye) @ up) < 0.95 * np.linalg.norm(target - eye) else None)
            ax.imshow(img, interpolation="nearest")
            unused = mesh.get("unused")
            if z is not None and unused is not None and len(unused):
                ii, jj, depth = z.project(pts[unused])
                i, j = np.floor(ii).astype(np.int64), np.floor(jj).astype(np.int64)
                inside = (depth > 0) & (i >= 0) & (j >= 0) & (i < RENDER_SIZE) & (j < RENDER_SIZE)
                seen = np.zeros(len(unused), dtype=bool)
                seen[inside] = depth[inside] <= z.depth[i[inside], j[inside]] + 3 * spacing
                ax.scatter(jj[seen], ii[seen], s=4, c="magenta", linewidths=0)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_xlim(0, RENDER_SIZE)
            ax.set_ylim(RENDER_SIZE, 0)
            if row == 0:
                mean = rc.get("distance_mean_spacings")
                ax.set_title(
                    f"{r['label']}\n{_fmt(rc.get('self_intersecting_faces'))} self-int. faces, "
                    f"{_fmt(rc.get('unused_points'))} unused,\n"
                    f"{_fmt(st.get('boundary_edges'))} boundary edges, mean distance "
                    + ("n/a" if mean is None else f"{mean:.3g} h"), fontsize=8)
            if col == 0:
                ax.set_ylabel(what + (" method's mesh" if row else ""), fontsize=8)
    fig.colorbar(ScalarMappable(norm, cmap), ax=axes.ravel().tolist(), shrink=0.6,
                 label="centroid distance to the reference (h); red: self-intersecting")
    fig.suptitle(f"{c['name']} ({c['kind']}, {ds['n']:,} points): magenta dots are unused "
                 "points", fontsize=10)
    fig.savefig(path, dpi=90)
    return path


def _bench_dataset(data: dict, methods, work: str, args, out_dir: str | None) -> dict:
    """Run every method on one data set, measure; for a corpus entry, render too."""
    pts = data["points"]
    data["diag"] = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    points_path = os.path.join(work, "points.npy")
    np.save(points_path, pts)
    ds = {key: data[key] for key in ("kind", "n", "label", "reference", "diag")}
    if "corpus" in data:
        ds["corpus"] = data["corpus"]
    ds["methods"] = []
    meshes = {}
    for method in methods:
        _log(args.quiet, f"{data['label']}: {method.label} ...")
        r = run_method(method, points_path, work, timeout=args.timeout, repeat=args.repeat)
        mesh = measure_mesh(r, data, args.samples, args.self_intersections, args.seed)
        if mesh is not None:
            meshes[method.name] = mesh
        _log(args.quiet, f"  {r['message']}" + (f", {r['time']:.3f} s" if r["time"] else ""))
        ds["methods"].append(r)
    if "corpus" in data and out_dir is not None and meshes:
        os.makedirs(out_dir, exist_ok=True)
        name = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in data["corpus"]["name"])
        path = os.path.join(out_dir, f"corpus_{name}.png")
        try:
            corpus_render(ds, meshes, data, path)
            ds["render"] = os.path.basename(path)
        except Exception as exc:  # a picture is not worth the run
            ds["render_error"] = f"{type(exc).__name__}: {exc}"
            _log(args.quiet, f"  render failed: {ds['render_error']}")
    return ds


def _mesh_datasets(specs, seed: int, only=None):
    """The data sets of ``--data``, one at a time (a corpus list is one entry at a time)."""
    for kind, n in specs:
        if kind in CORPUS_DATA:
            from fancloud_vtk.corpus import corpus, corpus_names

            which = CORPUS_DATA[kind]
            for name in corpus_names(which):
                if only and not any(fnmatch.fnmatchcase(name, p) for p in only):
                    continue
                (entry,) = corpus(which, seed, only=[name])
                yield corpus_data(entry)
        else:
            yield mesh_data(kind, n, seed)


def run_mesh(args, argv: list[str]) -> dict:
    """``bench mesh``: run every method on the same points, measure, write table, JSON, chart."""
    t_start = time.perf_counter()
    specs = parse_data(args.data, parse_size(args.n))
    only = getattr(args, "corpus_entries", None)
    if only and not any(kind in CORPUS_DATA for kind, _ in specs):
        raise ValueError("--corpus-entries needs --data corpus or corpus-small")
    if only:
        from fancloud_vtk.corpus import corpus_names

        names = {name for kind, _ in specs if kind in CORPUS_DATA
                 for name in corpus_names(CORPUS_DATA[kind])}
        for pattern in only:
            if not any(fnmatch.fnmatchcase(name, pattern) for name in names):
                raise ValueError(f"--corpus-entries: {pattern!r} matches no entry of "
                                 f"{', '.join(sorted(names))}")
    methods = [method_for(m) for m in args.methods]
    res = {
        **header(["mesh", *argv]),
        "args": {"data": [f"{k}" if m is None else f"{k}:{m}" for k, m in specs],
                 "methods": [m.name for m in methods], "timeout": args.timeout,
                 "repeat": args.repeat, "samples": args.samples, "seed": args.seed,
                 "self_intersections": args.self_intersections, "k": K,
                 "corpus_entries": list(only) if only else None},
        "peers": peer_versions(), "datasets": [],
    }
    renders = []
    with tempfile.TemporaryDirectory(prefix="fancloud-bench-mesh-") as work:
        for data in _mesh_datasets(specs, args.seed, only):
            ds = _bench_dataset(data, methods, work, args, args.out)
            if ds.get("render"):
                renders.append(os.path.join(args.out, ds["render"]))
            res["datasets"].append(ds)
            del data
            gc.collect()
    res["elapsed"] = time.perf_counter() - t_start
    res["rows"] = mesh_rows(res)
    text = mesh_markdown(res)
    md, js = write_outputs(args.out, "mesh", text, res)
    png = mesh_chart(res, os.path.join(args.out, "mesh.png"))
    print(text)
    print(f"written: {', '.join([md, js, png, *renders])}")
    return res


# -- command line ----------------------------------------------------------------------------


def _cmd_mesh(args, argv) -> int:
    run_mesh(args, argv)
    return 0


def _method_arg(text: str) -> str:
    try:
        method_for(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc
    return text


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``mesh`` on the subparsers of ``fancloud bench``."""
    p = sub.add_parser(
        "mesh", help="triangle meshes: fan_cloud_to_mesh against MeshLib, pymeshlab, VTK",
        description="Every method meshes the same points, each in its own process with a "
                    "timeout; time, triangles per point, non-manifold edges and vertices, "
                    "boundary edges, holes, self-intersections, unused points and the distance "
                    "to the reference surface. Writes mesh.md, mesh.json and mesh.png.")
    p.add_argument("--data", nargs="+", default=["bunny", "sphere"], metavar="DATA",
                   help="bunny (pymeshlab's bunny.obj points), sphere (--n random points on "
                        "the unit sphere), a number of sphere points (5k, 1M), or corpus / "
                        "corpus-small (the models, resamplings and range scans of "
                        "fancloud_vtk.corpus, each against its own mesh; a table and a "
                        "render per entry); several allowed (default: bunny sphere)")
    p.add_argument("--corpus-entries", nargs="+", default=None, metavar="PATTERN",
                   help="only the corpus entries whose name matches one of these shell "
                        "patterns (cow 'bunny*')")
    p.add_argument("--n", default="100k", help="points of 'sphere' (default: %(default)s)")
    p.add_argument("--methods", nargs="+", default=list(METHODS), type=_method_arg,
                   metavar="METHOD",
                   help=f"subset of {', '.join(METHODS)}, or module:function loaders "
                        "(see fancloud_vtk.bench.peers) (default: all)")
    p.add_argument("--timeout", type=float, default=MESH_TIMEOUT,
                   help="seconds per method and data set, warm-up included; a method still "
                        "running is killed and reported (default: %(default)s)")
    p.add_argument("--repeat", type=int, default=1,
                   help="timed runs per method, best kept (default: %(default)s)")
    p.add_argument("--samples", type=int, default=SAMPLES_PER_POINT,
                   help="surface samples per input point for the distance "
                        "(default: %(default)s)")
    p.add_argument("--self-intersections", action=argparse.BooleanOptionalAction, default=True,
                   help="count self-intersecting triangle pairs (the slowest statistic)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--out", default="bench_out", help="output folder (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_mesh)
    return p
