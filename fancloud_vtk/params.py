"""Each filter's parameters, described once.

The VTK algorithms' properties and ``SetX``/``GetX`` methods, the accessor's
keyword checks, the ``fancloud`` command's options, the ParaView plugin's
property decorators (later) and the parameter tables in ``docs/`` are all
derived from these tables. The core functions spell the same keywords and
defaults; ``tests/test_params.py`` checks that they agree.

Pure Python: no numpy, no VTK.
"""

from __future__ import annotations

import math
import numbers
import sys
from dataclasses import dataclass


@dataclass(frozen=True)
class Param:
    """One filter parameter."""

    name: str  #: keyword of the core function and the accessor
    kind: str  #: 'int', 'float', 'bool', 'choice', 'str' or 'vector' (of floats)
    default: object
    doc: str
    range: tuple | None = None  #: inclusive (lo, hi) for numbers (each entry of a vector)
    choices: tuple | None = None  #: allowed values for 'choice'
    size: int = 1  #: number of entries of a 'vector'

    @property
    def vtk_name(self) -> str:
        """CamelCase name for ``SetX``/``GetX`` and ParaView: ``max_angle`` -> ``MaxAngle``."""
        if len(self.name) == 1:
            return self.name.upper()
        return "".join(part.capitalize() for part in self.name.split("_"))

    @property
    def cli_flag(self) -> str:
        """Command line option: ``max_angle`` -> ``--max-angle``."""
        return "--" + self.name.replace("_", "-")

    def check(self, value):
        """``value`` converted to the parameter type; ``ValueError``/``TypeError`` if not.

        Numbers must be real numbers (Python or numpy, not strings or bools),
        ``int`` parameters integral ones (``6.0`` is accepted as ``6``); bools
        accept ``True``/``False``/``0``/``1`` and numpy bools.
        """
        if self.kind == "bool":
            if isinstance(value, _bool_types()) or (
                isinstance(value, numbers.Integral) and value in (0, 1)
            ):
                return bool(value)
            raise TypeError(f"{self.name} must be True or False, got {value!r}")
        if self.kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                raise ValueError(f"{self.name} must be one of {list(self.choices)}, got {value!r}")
            return value
        if self.kind == "str":
            if not isinstance(value, str):
                raise TypeError(f"{self.name} must be a string, got {value!r}")
            return value
        if self.kind == "vector":
            return self._check_vector(value)
        if isinstance(value, _bool_types()) or not isinstance(value, numbers.Real):
            raise TypeError(f"{self.name} must be a number, got {value!r}")
        if self.kind == "int":
            if isinstance(value, numbers.Integral):
                out = int(value)
            elif math.isfinite(value) and float(value).is_integer():
                out = int(value)
            else:
                raise TypeError(f"{self.name} must be an integer, got {value!r}")
        else:
            out = float(value)
            if math.isnan(out):
                raise ValueError(f"{self.name} must be a number, got NaN")
        if self.range is not None and not self.range[0] <= out <= self.range[1]:
            lo, hi = self.range
            raise ValueError(f"{self.name} must be between {lo} and {hi}, got {out}")
        return out


    def _check_vector(self, value) -> tuple:
        if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
            raise TypeError(f"{self.name} must be {self.size} numbers, got {value!r}")
        values = list(value)
        if len(values) != self.size:
            raise ValueError(f"{self.name} must be {self.size} numbers, got {len(values)}: "
                             f"{value!r}")
        scalar = Param(self.name, "float", 0.0, self.doc, range=self.range)
        return tuple(scalar.check(v) for v in values)


def _bool_types() -> tuple[type, ...]:
    """``numpy.bool_`` when numpy is already imported (this module does not import it)."""
    np = sys.modules.get("numpy")
    return (bool,) if np is None else (bool, np.bool_)


def check_params(table: tuple[Param, ...], values: dict) -> dict:
    """Validate keyword arguments against a table; complete them with defaults."""
    known = {p.name: p for p in table}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise TypeError(f"unknown parameter(s) {unknown}; known: {sorted(known)}")
    return {p.name: p.check(values.get(p.name, p.default)) for p in table}


def markdown_table(table: tuple[Param, ...]) -> str:
    """The parameter table in Markdown (used for docs/)."""
    rows = [
        "| keyword | VTK / ParaView | CLI | type | default | range | meaning |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in table:
        rng = p.range if p.range else (" / ".join(map(str, p.choices)) if p.choices else "")
        rows.append(
            f"| `{p.name}` | `Set{p.vtk_name}` | `{p.cli_flag}` | {p.kind} | `{p.default!r}` "
            f"| {rng} | {p.doc} |"
        )
    return "\n".join(rows)


#: Parameters of fan construction (paper section 3): build_fans, FanCloudFilter,
#: dataset.fancloud.fans(), ``fancloud fans``.
FAN_PARAMS: tuple[Param, ...] = (
    Param("k", "int", 6, "neighbours per fan (the paper's k)", range=(3, 64)),
    Param(
        "max_angle", "float", 90.0,
        "largest angle in degrees between consecutive fan neighbours (angle criterion)",
        range=(1.0, 179.0),
    ),
    Param(
        "max_replacements", "int", 42,
        "threshold on neighbour replacements: candidates up to the k + max_replacements "
        "nearest are tried",
        range=(0, 1000),
    ),
    Param(
        "rule", "choice", "cover",
        "replacement rule: 'cover' (nearest subset without a gap, default) or 'paper' "
        "(the literal rule: replace the farthest neighbour by the next nearest)",
        choices=("cover", "paper"),
    ),
    Param(
        "rotate_sharp_edges", "bool", True,
        "retry failed fans in the plane rotated by 90 degrees about the gap's axis (Figure 5)",
    ),
    Param(
        "reach", "float", 5.0,
        "sampling-aware limit (an addition to the paper): a candidate farther than reach "
        "times the point's local spacing (the distance of its k-th nearest neighbour, "
        "corrected for the angle the k nearest cover; the larger of the two points' "
        "spacings for a fan still open) never enters a fan, which stays open (its k "
        "nearest always do): gaps in the sampling and stray clusters are not bridged; 0: off",
        range=(0.0, 1e6),
    ),
    Param(
        "separate_sheets", "bool", False,
        "two sheets closer than the spacing (an addition to the paper): where a point's "
        "nearest neighbours form two parallel layers, the other layer's points do not "
        "enter its fan, so the two sides of a thin part are not joined (off by default: "
        "see docs/fans.md section 6c)",
    ),
    Param(
        "orient", "bool", True,
        "orient normals consistently by propagation (outward on closed surfaces) when the "
        "input has no normals",
    ),
)

#: How every verb reads a triangle mesh input (a polydata with polygons or strips, an
#: unstructured grid with 2-d cells, a mesh file): fan_cloud_of_mesh, every filter, every
#: accessor verb, every ``fancloud`` command that reads a dataset.
INPUT_PARAMS: tuple[Param, ...] = (
    Param(
        "keep_unreferenced", "bool", False,
        "keep the vertices of a triangle mesh input that no triangle uses, as plain points "
        "(default: drop them, with an UnreferencedVerticesWarning, their count in the field "
        "array unreferenced_dropped and the point array original_id)",
    ),
)

#: Parameters of the mesh from a fan cloud (paper section 4): fan_cloud_to_mesh,
#: FanCloudMeshFilter (with FAN_PARAMS for point input), dataset.fancloud.mesh(),
#: ``fancloud mesh``.
MESH_PARAMS: tuple[Param, ...] = (
    Param(
        "rings", "choice", "auto",
        "where the triangles come from: 'delaunay' (each fan's local Delaunay ring "
        "in its tangent plane, from its two fan rings), 'local' (each point's local "
        "triangulation ring, judged in 3D), 'auto' (the Delaunay rings, and where their "
        "mesh comes apart the better of the two meshes; default) or 'fans' (the fans "
        "themselves, as in the paper)",
        choices=("auto", "delaunay", "local", "fans"),
    ),
    Param(
        "close_holes", "bool", True,
        "triangulate the holes the growing leaves inside the surface (loops of at most "
        "max_hole edges that do not run along the real boundary of open fans); real "
        "boundaries stay open",
    ),
    Param(
        "max_hole", "int", 32,
        "largest boundary loop, in edges, that counts as a hole to close (a loop with no open "
        "fan and unused points of closed fans inside is closed whatever its size)",
        range=(3, 100_000),
    ),
    Param(
        "max_hole_diameter", "float", 6.0,
        "largest hole along open fans closed, in local spacings (an addition to the paper): "
        "a loop a quarter of whose points have open fans and whose bounding-box diagonal "
        "exceeds this many times the median fan-ring distance of its points is a gap of the "
        "sampling and stays open; 0: no limit",
        range=(0.0, 1e6),
    ),
    Param(
        "remove_self_intersections", "bool", True,
        "remove the triangles that intersect others (an addition to the paper), close the "
        "holes again and repeat (three rounds), then remove what still intersects: the mesh "
        "has no self-intersection; with close_holes, the holes still open are then filled in "
        "space without crossings (a hole whose fill needs an edge longer than 4 local "
        "spacings stays open) and unused points are put in at the nearest triangle",
    ),
    Param(
        "min_component", "int", 20,
        "outliers (an addition to the paper): a piece of the mesh with fewer points and "
        "fewer than a tenth of the largest piece's, in a cluster of such pieces with fewer "
        "points in all and no larger piece within 5 local spacings (a stray cluster), is "
        "removed; its points and the stray "
        "points in no triangle and no fan of the mesh count as outliers (field array "
        "mesh_outliers); 0: keep every piece",
        range=(0, 2**62),
    ),
    Param(
        "self_intersections", "bool", True,
        "count self-intersecting triangle pairs in the mesh statistics (0 without a test "
        "when remove_self_intersections is on)",
    ),
)

_WEIGHTS = Param(
    "weights", "vector", (1.0, 1.0, 50.0, 0.0),
    "entropy weights (a1, a2, a3, a4) of distance, curvature, curvature change and colour; "
    "(1, 0, 0, 0) gives an almost uniform reduction",
    range=(0.0, 1e12), size=4,
)
_COLOR_ARRAY = Param(
    "color_array", "str", "",
    "name of the point array with the colours for the colour term ('': the first of RGB, "
    "RGBA, Colors, ... that the input has)",
)

#: Parameters of the entropy (paper section 5): entropy, FanCloudEntropyFilter,
#: dataset.fancloud.entropy(), ``fancloud entropy`` (with FAN_PARAMS for point input).
ENTROPY_PARAMS: tuple[Param, ...] = (_WEIGHTS, _COLOR_ARRAY)

#: Parameters of the reduction (paper sections 5 and 6): reduce, FanCloudReduceFilter,
#: dataset.fancloud.reduce(), ``fancloud reduce`` (with FAN_PARAMS for point input).
REDUCE_PARAMS: tuple[Param, ...] = (
    Param("keep", "float", 0.42, "fraction of the points to keep (used when n_points is 0)",
          range=(1e-9, 1.0)),
    Param("n_points", "int", 0, "number of points to keep (0: use keep)", range=(0, 2**62)),
    _WEIGHTS,
    Param(
        "method", "choice", "entropy",
        "what each removal minimises: 'entropy' (the point of lowest entropy) or 'error' (the "
        "point whose removal changes the surface least: on a triangle mesh the quadric error "
        "of collapsing it into a ring point, as Garland-Heckbert's; on fans built from points "
        "the largest distance from its ring's plane of the point and of the removed points "
        "it carries, the paper's e(r))",
        choices=("entropy", "error"),
    ),
    _COLOR_ARRAY,
    Param("exact", "bool", False,
          "remove strictly one point at a time, lowest key first, from a heap (the paper's "
          "order; slower) instead of in rounds of non-overlapping lowest-key removals"),
    Param("max_spacing", "float", 4.0,
          "spacing bound (an addition to the paper): no removal may give a fan an edge longer "
          "than this many uniform spacings at the target count (and than its longest edge "
          "before), so no region is left unsampled whatever the weights; 0: no bound",
          range=(0.0, 1e6)),
    Param("error_step", "float", 2.0,
          "error guard of the entropy order on a triangle mesh (an addition to the paper): "
          "removals go in levels of their quadric error, each level this many times the last, "
          "the entropy deciding the order within a level, so no removal costs much more error "
          "than the target needs; 0: no guard (the entropy order alone)",
          range=(0.0, 1e6)),
    Param("removal", "choice", "auto",
          "how a removal mends the fans around the removed point: 'retriangulate' (a "
          "departure from the paper: its hole is triangulated once and the neighbours' rings "
          "spliced from that, so a mesh's one-rings stay a 2-manifold of the same topology; "
          "removals that cannot keep that are refused), 'reform' (each fan re-formed on its "
          "own, the paper) or 'auto' (retriangulate a triangle mesh input, re-form fans "
          "built from points)",
          choices=("auto", "retriangulate", "reform")),
    Param("mesh", "bool", False,
          "output the triangle mesh of the reduced fan cloud (fan_cloud_to_mesh) instead of "
          "the fan cloud"),
)

#: Parameters of the selective refinement (paper section 6, Figure 11):
#: FanCloudSelectiveRefineFilter (with REDUCE_PARAMS for the coarse level).
SELECTIVE_PARAMS: tuple[Param, ...] = (
    Param("smooth_iterations", "int", 0,
          "Laplacian smoothing steps applied to the coarse level before refining (Figure 11)",
          range=(0, 10_000)),
    Param("region", "choice", "sphere", "shape of the region of interest: 'sphere' or 'box'",
          choices=("sphere", "box")),
    Param("region_center", "vector", (0.0, 0.0, 0.0), "centre of the sphere region",
          range=(-1e300, 1e300), size=3),
    Param("region_radius", "float", 0.0, "radius of the sphere region (must be set: > 0)",
          range=(0.0, 1e300)),
    Param("region_bounds", "vector", (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
          "box region (xmin, xmax, ymin, ymax, zmin, zmax)", range=(-1e300, 1e300), size=6),
)

#: Parameters of the refinement (paper section 7): refine, FanCloudRefineFilter,
#: dataset.fancloud.refine(), ``fancloud refine`` (with FAN_PARAMS for point input).
REFINE_PARAMS: tuple[Param, ...] = (
    Param("factor", "float", 2.0,
          "the result has round(factor * n) points (used when n_points is 0); > 1",
          range=(1.0, 1e6)),
    Param("n_points", "int", 0, "number of points of the result (0: use factor); at least the "
          "input's", range=(0, 2**62)),
    Param(
        "weights", "vector", (1.0, 1.0, 0.0, 0.0),
        "entropy weights (a1, a2, a3, a4) that decide where points go and how the parents are "
        "weighted; the default leaves out the curvature change, which would pile points up "
        "where the normals are noisy",
        range=(0.0, 1e12), size=4,
    ),
    _COLOR_ARRAY,
    Param("move", "bool", True,
          "move each new point along its normal so that its mean curvature is its parents' "
          "entropy-weighted one (False: leave it on the triangle of its parents)"),
    Param("exact", "bool", False,
          "insert strictly one point at a time, highest entropy first, from a heap (the "
          "paper's order; slower) instead of in rounds of non-overlapping insertions"),
    Param("mesh", "bool", False,
          "output the triangle mesh of the refined fan cloud (fan_cloud_to_mesh) instead of "
          "the fan cloud"),
)

#: Parameters of the view-dependent fan cloud (paper section 8):
#: ViewDependentFanCloud.build and front, FanCloudViewDependentFilter,
#: dataset.fancloud.vdfc(), ``fancloud vdfc`` (with FAN_PARAMS for point input).
VDFC_PARAMS: tuple[Param, ...] = (
    Param("e_max", "float", 0.0,
          "largest error allowed at the range of sight d_max, in data units; nearer nodes "
          "get proportionally less (0: 0.1% of the diagonal of the bounds)",
          range=(0.0, 1e300)),
    Param("d_max", "float", 0.0,
          "range of sight (0: from the eye to the farthest corner of the bounds)",
          range=(0.0, 1e300)),
    Param("merge", "choice", "entropy",
          "how two points merge: 'entropy' (at their entropy-weighted mean) or 'half_edge' "
          "(at the lower-entropy neighbour: a half-edge collapse)",
          choices=("entropy", "half_edge")),
    Param("weights", "vector", (1.0, 1.0, 0.0, 0.0),
          "entropy weights (a1, a2, a3, a4) of the merge order",
          range=(0.0, 1e12), size=4),
    _COLOR_ARRAY,
    Param("n_roots", "int", 1, "stop merging when this many nodes are left", range=(1, 2**62)),
    Param("block_size", "int", 0,
          "cut the data into blocks that share their boundary points, built in parallel "
          "(0: one block): a height field (image data) into blocks of about this many cells "
          "a side, a point set or mesh into spatial blocks of about its square points",
          range=(0, 2**31)),
    Param("aspect", "float", 0.0,
          "width / height of the view (0: 1, or the viewer's when it follows a plotter)",
          range=(0.0, 1e6)),
    Param("superfluous", "bool", False,
          "also remove the front's superfluous triangles (a convex quadrilateral covered by "
          "both diagonals' triangles keeps one pair, paper section 4): about 2.0 triangles "
          "per point instead of 2.15, at about twice the update time"),
)


def _without(table: tuple[Param, ...], *names: str) -> tuple[Param, ...]:
    return tuple(p for p in table if p.name not in names)


#: Every verb's parameters: the verb layer (:mod:`fancloud_vtk.core.verbs`) checks
#: its values against these, the VTK algorithm of the verb has exactly these
#: properties, the accessor verb these keywords and the ``fancloud`` command these
#: options (the amount -- keep, factor, n_points -- as one group of which one is given).
VERB_PARAMS: dict[str, tuple[Param, ...]] = {
    "fans": FAN_PARAMS + INPUT_PARAMS,
    "mesh": FAN_PARAMS + INPUT_PARAMS + MESH_PARAMS,
    "entropy": FAN_PARAMS + INPUT_PARAMS + ENTROPY_PARAMS,
    "reduce": FAN_PARAMS + INPUT_PARAMS + REDUCE_PARAMS,
    "hierarchy": FAN_PARAMS + INPUT_PARAMS + _without(REDUCE_PARAMS, "keep", "mesh"),
    "selective": FAN_PARAMS + INPUT_PARAMS + _without(REDUCE_PARAMS, "mesh") + SELECTIVE_PARAMS,
    "refine": FAN_PARAMS + INPUT_PARAMS + REFINE_PARAMS,
    "vdfc": FAN_PARAMS + INPUT_PARAMS + VDFC_PARAMS,
}

#: The verbs whose result size is given either by ``n_points`` or by this fraction
#: (``n_points`` 0: the fraction is used).
AMOUNTS: dict[str, str] = {"reduce": "keep", "selective": "keep", "refine": "factor"}
