"""Triangle mesh from a fan cloud (paper section 4).

:func:`fan_cloud_to_mesh` follows the paper's three steps, with a first
step before them and a last one after:

0. **Delaunay rings** (``rings='delaunay'``, and the first try of the default
   ``'auto'``; ``rings='fans'`` skips it and uses the fans as they are, the
   paper's literal behaviour). Fans built by the angle
   criterion on irregular samples agree poorly (on 20,000 random sphere
   points, 87% of their distinct triangles belong to one fan only), so
   every fan's ring is replaced by its local Delaunay ring in its tangent
   plane, from its two fan rings within reach (no new neighbour search):
   closed fans by the hull of the inverted candidates, open fans by the hull with the
   point itself (an open Delaunay fan). Where the mesh grown from them comes
   apart (``'auto'``), the mesh is made again from **local triangulation
   rings** (``rings='local'``: each point's nearest candidates thinned spoke
   by spoke by a 3D circumcircle rule, :mod:`._local_ring_kernels`) and the
   better of the two is kept (docs/mesh.md, section 1b).
1. **Distinct triangles.** All fan triangles ``(p, q_j, q_{j+1})``; the same
   three points are counted once, with the number of fans that contain the
   triangle (its *count*) and the orientation most of those fans give it.
   Where two fans run a shared triangle opposite ways round (normals the
   propagation of :func:`~fancloud_vtk.build_fans` got wrong across a thin
   part), the normals are first oriented again by the triangles the fans
   share (``normals_flipped``; docs/mesh.md, section 2b).
2. **Superfluous triangles out.** Where a quadrilateral is covered by both
   of its diagonals' triangulations (three or four fan triangles), one
   triangulation stays: a complete one over an incomplete one, then the one
   more fans agree on, then the better-shaped one (larger smallest angle).
3. **A 2-manifold grown** from what remains: the uncontested triangles
   (in all three fans, alone on their edges) at once, then the rest one
   at a time, most fans first, each joining through an edge of the mesh:
   never a third triangle on an edge, never a second fan of triangles
   around a vertex (non-manifold vertex), every interior edge run once in
   each direction (consistent orientation). Topological as in the paper,
   with one geometric test: at a vertex already in the mesh, the new
   corner must lie in the vertex's gap (seen along its normal), so no
   triangle folds over another. Two fronts may meet at a boundary vertex
   (inside its gap); what stays pinched there is cut off (``pinch_cut``).
4. **Holes closed.** Boundary loops that are holes, not the real boundary
   (at most ``max_hole`` edges and fewer than half of their edges joining
   two open fans across a gap; a loop of three edges always; a loop with no
   open fan and unused points of closed fans inside, whatever its size;
   never a loop along open fans wider than ``max_hole_diameter`` local
   spacings: a gap of the sampling), are triangulated: a star around the
   loop's one unused point, a Delaunay fill with its unused points, or ear
   clipping; a hole that cannot be closed is
   widened by the triangles around it and tried again (undone if the
   retries do not close it either). Points still unused but lying over a
   triangle are split into it (1 -> 3).
5. **Self-intersections removed** (``remove_self_intersections``): of
   each intersecting pair the worse triangle goes, the holes are closed
   again (a refill that crosses more than it repairs is undone), three
   rounds; what still intersects then goes for good.

The counts of every stage and the checks of the result (boundary edges,
holes, non-manifold edges and vertices, inconsistent edges,
self-intersections) are in :attr:`TriangleMesh.stats`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np

from . import _component_kernels as CK
from . import _csr_kernels as CsrK
from . import _edge_kernels as EdgeK
from . import _fill_kernels as FillK
from . import _local_ring_kernels as LRK
from . import _mesh_kernels as MK
from . import _normal_kernels as NK
from . import _ring_kernels as RingK
from .model import FanCloud

#: largest Delaunay ring kept (a point keeps its fan's ring past that); on
#: the local triangulation rings (``rings='local'``): nearest candidates, fold allowed
#: between two triangles, angular gap that opens a ring
LOCAL_NEAR = 16
LOCAL_REACH = 3.0
DELAUNAY_REACH = 3.0
LOCAL_FOLD = 0.5 * np.pi
LOCAL_BORDER = 0.9 * np.pi
#: the choices of ``rings``
RINGS = ("auto", "delaunay", "local", "fans")
#: random samples 99.99% of the rings have at most 12 points
MAX_RING = 16
#: The largest boundary loop (in edges) the last hole filling triangulates in space
#: (its cost grows with the cube of the loop's length).
MAX_FILL = 160
#: Rounds of the last hole filling and point insertion (at most) ...
#: An unused point goes into a triangle at most this many local spacings from it.
INSERT_FAR = 1.0
#: A fill of the last hole filling is kept when its longest edge is at most this many
#: local spacings (the median over the loop's points).
FILL_MAX_EDGE = 4.0
FILL_ROUNDS = 12
#: ... and they stop after this many rounds that do not improve on the best one.
FILL_PATIENCE = 3


@dataclass(eq=False)
class TriangleMesh:
    """A triangle mesh over the points of a fan cloud.

    Attributes
    ----------
    points : numpy.ndarray
        ``(n, 3)`` float64, the fan cloud's points (all of them, used or not).
    triangles : numpy.ndarray
        ``(m, 3)`` int64, counter-clockwise around the surface normal.
    normals : numpy.ndarray
        ``(n, 3)`` unit point normals of the fan cloud, those the mesh
        stage orients again negated (``stats['normals_flipped']``).
    point_data : dict
        The fan cloud's passthrough point arrays.
    stats : dict
        Counts of every stage and checks of the result (see
        :func:`fan_cloud_to_mesh`).
    outliers : numpy.ndarray
        Indices of the points judged outliers (in no triangle on purpose:
        stray points and small isolated pieces), increasing.
    """

    points: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray
    point_data: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    outliers: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n_triangles(self) -> int:
        return int(len(self.triangles))


def fan_cloud_to_mesh(
    fancloud: FanCloud,
    *,
    rings: str = "auto",
    close_holes: bool = True,
    max_hole: int = 32,
    max_hole_diameter: float = 6.0,
    remove_self_intersections: bool = True,
    min_component: int = 20,
    self_intersections: bool = True,
) -> TriangleMesh:
    """A consistently oriented 2-manifold triangle mesh from a fan cloud (section 4).

    Parameters
    ----------
    fancloud : FanCloud
        From :func:`fancloud_vtk.build_fans` (or read from a ``.vtp``).
    rings : {'auto', 'delaunay', 'local', 'fans'}, default: 'auto'
        Where the triangles come from. ``'fans'``: the fan cloud's own fans,
        as in the paper. Fans that are the one-rings of a 2-manifold (every
        fan triangle in the fans of its three points, no edge in more than
        two triangles: the fan cloud of a triangle mesh, or its reduction
        with ``removal='retriangulate'``) give that 2-manifold as it is:
        no stage below changes it, and self-intersections are counted (with
        a :class:`DoubtfulMeshWarning`), not removed. On irregularly
        (randomly) sampled surfaces the fans agree poorly: most of their
        triangles belong to one fan only (measured on 20,000 random points
        of a sphere: 87% of the distinct triangles), so the grown mesh keeps
        many holes. ``'delaunay'``: every fan's ring is first replaced by
        its local Delaunay ring in its tangent plane, taken from its two fan
        rings (no new neighbour search; an open fan gets an open Delaunay
        fan); neighbouring points then agree on most triangles.
        ``'local'``: every ring is replaced by its local triangulation ring
        (:mod:`~fancloud_vtk.core._local_ring_kernels`): the nearest points
        of its two fan rings, thinned spoke by spoke by a 3D circumcircle
        rule; the normals are taken again from those rings' triangles and
        the rings found again (docs/mesh.md, section 1b). The mesh's
        normals are then those normals, turned to run with its triangles.
        ``'auto'`` (default): the Delaunay rings; where the mesh made from
        them comes apart (a piece of the fan cloud in several pieces of the
        mesh: a leg, a tail or an ear a few points round) or leaves more
        than a tenth of the points out (outliers apart), the mesh is also
        made from the local rings, and the one with fewer pieces cut off
        (then fewer unused points, then fewer boundary edges) is kept
        (``stats['local_rings']`` says which: 1 for the local rings).
    close_holes : bool, default: True
        Triangulate the holes the growing leaves inside the surface:
        boundary loops of at most ``max_hole`` edges that do not run along
        the real boundary (at least half of their edges joining two open
        fans across their gaps); those stay open.
    max_hole : int, default: 32
        Largest boundary loop (in edges) that counts as a hole to close;
        a loop with no open fan and unused points of closed fans inside is
        closed whatever its number of edges.
    max_hole_diameter : float, default: 6.0
        Largest hole along open fans closed, in local spacings (an addition
        to the paper): a loop of which at least a quarter of the points have
        open fans and whose bounding-box diagonal exceeds this many times
        the median spacing of its points (each point's median distance to
        its fan neighbours) is a gap of the sampling and stays open. (Loops
        through closed fans are surface that the fans claim, left by the
        growing: they are closed.)
        A loop of three edges is always closed. ``0``: no limit.
    remove_self_intersections : bool, default: True
        Find the triangles that intersect another one and remove the worse
        of each pair (the one in more pairs, then the larger; an addition to
        the paper: its growing is purely topological and lets a few
        triangles fold over others, Figure 7), close the holes this leaves
        again (``close_holes``), and repeat (three rounds); what still
        intersects then is removed and its hole left open. The result
        has no self-intersection. With ``close_holes`` too, the holes
        still open are then triangulated in space without crossings
        (the smallest largest dihedral angle, then the least area; a hole
        whose fill needs an edge longer than ``FILL_MAX_EDGE`` = 4 local
        spacings stays open) and the points still unused are put in at the
        nearest triangle or edge (docs/mesh.md, section 6b). Costs one
        intersection test of the whole mesh when there is none.
    min_component : int, default: 20
        Outliers (an addition to the paper): a piece of the mesh with fewer
        points than this and fewer than a tenth of the largest piece's, in a
        cluster of such pieces (within 5 local spacings of each other) with
        fewer points than this in all and no point within 5 local spacings
        of a larger piece (a stray cluster), is removed; its points, and the points left in no
        triangle that no fan of a point of the mesh holds (stray points),
        are judged outliers: ``stats["outliers"]`` counts them (the field array
        ``mesh_outliers`` of the VTK output) and
        :attr:`TriangleMesh.outliers` lists them. ``0``: keep every piece.
    self_intersections : bool, default: True
        Count self-intersecting triangle pairs in ``stats`` (0 without a
        test when ``remove_self_intersections`` is on).

    Returns
    -------
    TriangleMesh
        ``stats`` holds ``fan_triangles`` (all fan triangles), ``distinct``,
        ``after_superfluous``, ``uncontested`` (accepted before growing),
        ``normals_flipped`` (normals oriented again where fans run a shared
        triangle opposite ways round: docs/mesh.md, section 2b),
        ``grown``, ``final`` (triangle counts of the
        stages), ``pinch_cut`` (triangles cut off at pinched vertices after
        growing), ``holes_closed``, ``points_inserted`` (unused points put
        into a closed hole) and the checks of the final mesh from
        :func:`fancloud_vtk.core.mesh_stats.mesh_statistics`
        (``boundary_edges``, ``holes``, ``non_manifold_edges``,
        ``non_manifold_vertices``, ``inconsistent_edges``,
        ``self_intersections``, ``unused_points``, ...), and ``timings``.

    Raises
    ------
    TypeError
        ``fancloud`` is not a :class:`~fancloud_vtk.FanCloud`.
    ValueError
        An empty fan cloud, or one whose arrays are inconsistent (ring
        indices out of range, ...).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, fan_cloud_to_mesh
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(3000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> mesh = fan_cloud_to_mesh(build_fans(p))
    >>> mesh.n_triangles == 2 * 3000 - 4, mesh.stats["boundary_edges"]
    (True, 0)
    """
    if not isinstance(fancloud, FanCloud):
        raise TypeError(
            f"fan_cloud_to_mesh needs a FanCloud (from build_fans), got {type(fancloud).__name__}"
        )
    fancloud.validate()
    n = fancloud.n_points
    if n == 0:
        raise ValueError("the fan cloud is empty: no points to mesh")
    max_hole_diameter = _check_mesh_options(rings, min_component, max_hole, max_hole_diameter)
    timings = {}
    stats = {}
    # Work on the points in a spatially coherent order (the fan grid's cell
    # order): the fan cloud's own order may be random, and every stage walks
    # rings and neighbours. Triangles are mapped back at the end.
    t0 = time.perf_counter()
    source = fancloud
    spatial, fancloud = _spatial_order(fancloud)
    plain = fancloud
    timings["reorder"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    if rings in ("auto", "delaunay"):
        fans = _delaunay_fans(fancloud)
        timings["delaunay_rings"] = time.perf_counter() - t0
    elif rings == "local":
        fans, fancloud = _local_fans(fancloud)
        timings["local_rings"] = time.perf_counter() - t0
    else:
        fans = fancloud
    fans, fancloud, flip, tri, count, n_fan = _distinct(fans, fancloud, rings != "fans", stats,
                                                       timings, t0)
    if rings == "fans" and _one_rings(fans, tri, count, n_fan):
        return _manifold_of_rings(source, spatial, fancloud, tri, stats, timings,
                                  self_intersections)
    triangles, cand = _grow(fancloud, tri, count, stats, timings)
    opts = (close_holes, max_hole, max_hole_diameter, remove_self_intersections)

    def finish(fancloud, triangles, cand, stats, timings):
        """Steps 4 and 5 and the outliers: (triangles, outliers)."""
        triangles = _finish(fancloud, triangles, cand, opts, stats, timings)
        t0 = time.perf_counter()
        triangles, outliers = _outliers(fancloud, triangles, min_component)
        stats["outliers"] = len(outliers)
        stats["final"] = len(triangles)
        timings["outliers"] = time.perf_counter() - t0
        return triangles, outliers

    local_normals = rings == "local"
    stats["local_rings"] = int(local_normals)
    triangles, outliers = finish(fancloud, triangles, cand, stats, timings)
    cut = 0
    if rings == "auto":
        # where the mesh from the Delaunay rings comes apart (a leg or a tail a few points
        # round) or leaves many points out, the mesh is made again from the local
        # triangulation rings (judged in 3D), and the better of the two is kept
        t0 = time.perf_counter()
        cut, _ = _cut_pieces(plain, triangles, {})
        if not cut:
            used = np.zeros(n, bool)
            used[triangles.ravel()] = True
            cut = int(n - used.sum() - len(outliers) > 0.1 * n)
        timings["cut_check"] = time.perf_counter() - t0
    if cut:
        t0 = time.perf_counter()
        local_stats = dict(stats)
        local_timings = {}
        fans2, plain2 = _local_fans(plain)
        local_timings["local_rings"] = time.perf_counter() - t0
        fans2, fancloud2, flip2, tri2, count2, _ = _distinct(
            fans2, plain2, True, local_stats, local_timings, t0)
        triangles2, cand2 = _grow(fancloud2, tri2, count2, local_stats, local_timings)
        triangles2, outliers2 = finish(fancloud2, triangles2, cand2, local_stats, local_timings)
        for key, value in local_timings.items():
            timings["local_" + key if key != "local_rings" else key] = value
        if _score(plain, triangles2, outliers2) < _score(plain, triangles, outliers):
            local_stats["local_rings"] = 1
            local_stats.pop("timings", None)
            stats.update(local_stats)
            fancloud, flip, triangles, outliers = fancloud2, flip2, triangles2, outliers2
            local_normals = True

    return _conclude(source, spatial, fancloud, triangles, outliers, flip, local_normals, stats,
                     timings, close_holes, remove_self_intersections, self_intersections)


def _check_mesh_options(rings, min_component, max_hole, max_hole_diameter) -> float:
    """ValueError/TypeError for a bad option of :func:`fan_cloud_to_mesh`; returns
    ``max_hole_diameter`` as a float."""
    if rings not in RINGS:
        raise ValueError(f"rings must be one of {', '.join(map(repr, RINGS))}, got {rings!r}")
    if (isinstance(min_component, bool) or not isinstance(min_component, int | np.integer)
            or min_component < 0):
        raise ValueError(f"min_component must be an integer >= 0, got {min_component!r}")
    if isinstance(max_hole, bool) or not isinstance(max_hole, int | np.integer) or max_hole < 3:
        raise ValueError(f"max_hole must be an integer of at least 3 edges, got {max_hole!r}")
    number = int | float | np.number
    if isinstance(max_hole_diameter, bool) or not isinstance(max_hole_diameter, number):
        raise TypeError(f"max_hole_diameter must be a number, got {max_hole_diameter!r}")
    max_hole_diameter = float(max_hole_diameter)
    if not 0.0 <= max_hole_diameter <= 1e6:
        raise ValueError(f"max_hole_diameter must be between 0 and 1e6, got {max_hole_diameter}")
    return max_hole_diameter


def _conclude(source, spatial, fancloud, triangles, outliers, flip, local_normals, stats,
              timings, close_holes, remove_self_intersections, self_intersections):
    """The checks of the final mesh, its closed pieces turned outward, the warnings, and
    the :class:`TriangleMesh` (``fancloud``: in the order ``spatial`` of ``source``, with
    the normals the triangles were grown with)."""
    t0 = time.perf_counter()
    from .mesh_stats import mesh_statistics

    count = self_intersections and not remove_self_intersections
    stats.update(mesh_statistics(fancloud.points, triangles, self_intersections=count))
    if remove_self_intersections and self_intersections:
        stats["self_intersections"] = 0  # none is left: the last round only removes
    stats["cut_pieces"], stats["cut_points"] = _cut_pieces(fancloud, triangles, stats)
    triangles, turned, stats["pieces_turned"] = _outward(fancloud.points, triangles, stats)
    if turned.any() and not local_normals:
        flip = flip ^ turned
    timings["checks"] = time.perf_counter() - t0
    stats["timings"] = timings
    _warn_if_doubtful(fancloud, triangles, stats, holes=close_holes, stacklevel=4)
    if local_normals:  # the normals of the local rings' triangles, running with the mesh's
        return _mesh_of(source, spatial, triangles, stats, outliers,
                        normals=_along(fancloud.normals, fancloud.points, triangles))
    return _mesh_of(source, spatial, triangles, stats, outliers, flip)


# -- the mesh of a part of a cloud (fancloud_vtk.distributed.tiled_mesh) ----------------
#
# Every stage after the orientation decides from what lies near: the growing, the holes,
# the self-intersections, the filling. Its ties are broken by the points' order, so a part
# of the cloud meshed in the whole cloud's spatial order (``rank``) with the whole cloud's
# orientation (``flip``) gives the whole cloud's triangles away from the part's edge.


def _ordered(fc: FanCloud, order: np.ndarray) -> FanCloud:
    """``fc`` relabelled so that point i is fc's point ``order[i]`` (geometry and rings)."""
    pos = np.empty(len(order), np.int64)
    pos[order] = np.arange(len(order))
    offsets, ring = RingK.relabel_rings(fc.offsets, fc.ring, order, pos)
    return FanCloud(fc.points[order], offsets, ring, fc.normals[order], fc.open[order],
                    fc.rotated[order])


def _mesh_rings(fc: FanCloud, kind: str) -> tuple[FanCloud, FanCloud]:
    """(rings, fan cloud) the triangles come from: ``kind`` 'delaunay' or 'local'."""
    if kind == "delaunay":
        return _delaunay_fans(fc), fc
    return _local_fans(fc)


def _mesh_flip(fancloud: FanCloud, rank: np.ndarray, kind: str) -> np.ndarray:
    """The normals the mesh of the rings ``kind`` orients again (a mask in ``fancloud``'s
    order): the whole cloud's step of :func:`_distinct`."""
    order = np.argsort(rank, kind="stable")
    fans, fc = _mesh_rings(_ordered(fancloud, order), kind)
    flip = _distinct(fans, fc, True, {}, {}, time.perf_counter())[2]
    out = np.zeros(len(order), bool)
    out[order] = flip
    return out


def _mesh_part(fancloud: FanCloud, rank, flip, kind: str, opts):
    """The triangles (indices of ``fancloud``, oriented) of the part ``fancloud`` of a
    cloud, grown and finished as the whole cloud's mesh is (``rank``, ``flip``: the whole
    cloud's, at these points; ``opts`` as :func:`_finish` takes them), before the outliers;
    and the normals the triangles were grown with (in ``fancloud``'s order)."""
    order = np.argsort(rank, kind="stable")
    fans, fc = _mesh_rings(_ordered(fancloud, order), kind)
    f = flip[order]
    if f.any():
        fans = _flipped(fans, f)
        fc = _flipped(fc, f)
    tri, count, _, _ = MK.distinct_triangles(fans.offsets, fans.ring, fans.open)
    stats, timings = {}, {}
    triangles, cand = _grow(fc, tri, count, stats, timings)
    triangles = _finish(fc, triangles, cand, opts, stats, timings)
    normals = np.empty_like(fc.normals)
    normals[order] = fc.normals
    return order[triangles], normals


def _delaunay_fans(fancloud: FanCloud) -> FanCloud:
    """Every fan's ring replaced by its local Delaunay ring (``rings='delaunay'``); the
    fan cloud is in its spatial order."""
    width = max(MAX_RING, int(fancloud.fan_sizes.max(initial=0)))
    counts, table = RingK.delaunay_rings(
        fancloud.points,
        fancloud.normals,
        fancloud.offsets,
        fancloud.ring,
        fancloud.open,
        width,
        2 * numba.get_num_threads(),
        np.zeros(0, np.int64),  # already in the grid's order
        RingK.NOT_STEEP,
        DELAUNAY_REACH,
    )
    offsets, ring = RingK.compact_rings(counts, table)
    return FanCloud(fancloud.points, offsets, ring, fancloud.normals, fancloud.open,
                    fancloud.rotated)


def _distinct(fans: FanCloud, fancloud: FanCloud, orient: bool, stats, timings, t0):
    """The distinct triangles of the rings ``fans`` (step 1), after orienting the normals
    again where two fans run a shared triangle opposite ways (``orient``). Returns
    (fans, fancloud, flip, tri, count, n_fan), both fan clouds with the flipped normals."""
    n = fancloud.n_points
    flip = np.zeros(n, bool)
    tri, count, n_fan, n_mixed = MK.distinct_triangles(fans.offsets, fans.ring, fans.open)
    if orient and n_mixed:
        # fans that run a shared triangle opposite ways: orient the normals again by the
        # triangles the fans share (section 2b of docs/mesh.md)
        t1 = time.perf_counter()
        flip = _shared_orientation(fans, fancloud)
        if flip.any():
            fans = _flipped(fans, flip)
            fancloud = _flipped(fancloud, flip)
            tri, count, n_fan, _ = MK.distinct_triangles(fans.offsets, fans.ring, fans.open)
        timings["orientation"] = time.perf_counter() - t1
    stats["normals_flipped"] = int(flip.sum())
    stats["fan_triangles"] = int(n_fan)
    stats["distinct"] = len(tri)
    timings["distinct"] = time.perf_counter() - t0
    return fans, fancloud, flip, tri, count, n_fan


def _local_fans(fc: FanCloud) -> tuple[FanCloud, FanCloud]:
    """The local triangulation rings of every point, with the normals they give:
    the rings are found once with the fan cloud's normals, the normals replaced by
    those of the rings' triangles, and the rings found again. Returns (rings, fan
    cloud with the new normals)."""
    first = _local_rings(fc, fc)
    fc = _ring_normals(fc, first)
    return _local_rings(fc, fc), fc


def _outward(points, triangles, stats):
    """Closed pieces of the mesh turned outward: a piece with no boundary edge whose
    signed volume is negative runs inside out (its orientation came from normals that
    pointed inward on most of it: a thin part cut off); its triangles are reversed.
    Returns (triangles, the points of the turned pieces, how many pieces)."""
    n = len(points)
    turned = np.zeros(n, bool)
    if len(triangles) == 0:
        return triangles, turned, 0
    triangles = np.ascontiguousarray(triangles, dtype=np.int64)
    origin = points.mean(axis=0)
    if stats.get("components", 1) <= 1:
        if (stats.get("boundary_edges", 0) or CK.piece_volumes(
                points, triangles, np.zeros(0, np.int64), 1, origin)[0] >= 0.0):
            return triangles, turned, 0
        turned[triangles.ravel()] = True
        return np.ascontiguousarray(triangles[:, ::-1]), turned, 1
    label = CK.vertex_components(triangles, n)
    piece = label[triangles[:, 0]]
    total = CK.piece_volumes(points, triangles, piece, n, origin)
    open_piece = np.zeros(n, bool)
    if stats.get("boundary_edges", 0):
        from .mesh_stats import boundary_loops

        for loop in boundary_loops(triangles):
            open_piece[label[loop[0]]] = True
    inside_out = (total < 0.0) & ~open_piece
    if not inside_out.any():
        return triangles, turned, 0
    rev = inside_out[piece]
    triangles = triangles.copy()
    triangles[rev] = triangles[rev][:, ::-1]
    turned[triangles[rev].ravel()] = True
    return np.ascontiguousarray(triangles), turned, int(inside_out.sum())


def _along(normals, points, triangles) -> np.ndarray:
    """``normals`` turned to run with the triangles: negated where they point against
    the area-weighted normal of the triangles around the point."""
    face = np.cross(points[triangles[:, 1]] - points[triangles[:, 0]],
                    points[triangles[:, 2]] - points[triangles[:, 0]])
    around = np.zeros_like(normals)
    for j in range(3):
        np.add.at(around, triangles[:, j], face)
    out = normals.copy()
    out[np.einsum("ij,ij->i", around, normals) < 0] *= -1.0
    return out


def _score(fc: FanCloud, triangles, outliers) -> tuple[int, int, int]:
    """How far a mesh is from one piece per piece of the fan cloud, using every point
    that is not an outlier, closed: (pieces cut off, points unused, boundary edges);
    lower is better."""
    cut, _ = _cut_pieces(fc, triangles, {})
    unused = fc.n_points - len(np.unique(triangles)) - len(outliers)
    e = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                                triangles[:, [2, 0]]]), axis=1)
    _, once = np.unique(e[:, 0] * fc.n_points + e[:, 1], return_counts=True)
    return cut, unused, int((once == 1).sum())


def _ring_normals(fc: FanCloud, fans: FanCloud) -> FanCloud:
    """``fc`` with each normal replaced by the area-weighted normal of its ring's
    triangles in ``fans`` (turned to agree with the old one)."""
    n = fc.n_points
    sizes = fans.fan_sizes
    centre = np.repeat(np.arange(n), sizes)
    a = fans.ring
    nxt = np.arange(len(a)) + 1
    last = fans.offsets[1:] - 1
    nxt[last[sizes > 0]] = fans.offsets[:-1][sizes > 0]
    b = a[nxt]
    real = np.ones(len(a), bool)
    real[last[(sizes > 0) & fans.open]] = False
    P = fc.points
    cr = np.cross(P[a] - P[centre], P[b] - P[centre])
    cr[~real] = 0.0
    nn = np.zeros((n, 3))
    np.add.at(nn, centre, cr)
    length = np.linalg.norm(nn, axis=1)
    ok = length > 0
    nn[ok] /= length[ok, None]
    nn[~ok] = fc.normals[~ok]
    nn[np.einsum("ij,ij->i", nn, fc.normals) < 0] *= -1.0
    return FanCloud(fc.points, fc.offsets, fc.ring, nn, fc.open, fc.rotated)


def _grow(fancloud: FanCloud, tri, count, stats, timings):
    """Steps 2 and 3: the superfluous triangles out, a 2-manifold grown from the rest.
    Returns (triangles, cand): ``cand`` the candidates and their edges, for the hole
    closing."""
    n = fancloud.n_points
    t0 = time.perf_counter()
    quality = MK.min_angles(fancloud.points, tri) / 60.0
    edge_uv, tri_edge, edge_off, edge_tri = EdgeK.build_edges(tri, n)
    v_edge_off, v_edges = CsrK.vertex_edges(edge_uv, n)
    quads = MK.find_quads(
        fancloud.points, fancloud.normals, tri, edge_uv, edge_off, edge_tri, v_edge_off, v_edges
    )
    alive = np.ones(len(tri), bool)
    MK.resolve_quads(quads, count, quality, alive, True)
    stats["after_superfluous"] = int(alive.sum())
    timings["superfluous"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    priority = -(count.astype(np.float64) + 0.5 * quality)
    level = count.max(initial=1) - count  # 0: in the most fans
    # uncontested triangles all three of whose fans agree join at once (the
    # growing would accept each of them anyway: it is the only choice on its
    # edges); the growing then decides the contested rest
    pre = MK.uncontested(tri, alive, count, tri_edge, len(edge_uv), 3)
    stats["uncontested"] = int(pre.sum())
    accepted, out_tri = MK.grow_manifold(
        tri,
        alive,
        pre,
        priority,
        level,
        tri_edge,
        edge_uv,
        edge_off,
        edge_tri,
        n,
        True,
        fancloud.points,
        fancloud.normals,
        v_edge_off,
        v_edges,
    )
    triangles = out_tri[accepted]
    keep = np.ones(len(triangles), bool)
    stats["pinch_cut"] = MK.split_pinched(triangles, keep, n)
    triangles = triangles[keep]
    stats["grown"] = len(triangles)
    timings["grow"] = time.perf_counter() - t0

    cand = (tri, count, edge_uv, edge_off, edge_tri, v_edge_off, v_edges)
    return triangles, cand


def _finish(fancloud: FanCloud, triangles, cand, opts, stats, timings):
    """Steps 4 and 5 after the growing: the holes closed, the self-intersections removed
    and their holes filled in space, the unused points put in (``opts``: close_holes,
    max_hole, max_hole_diameter, remove_self_intersections). Returns the triangles."""
    close_holes, max_hole, max_hole_diameter, remove_self_intersections = opts
    t0 = time.perf_counter()
    stats["holes_closed"] = 0
    stats["points_inserted"] = 0
    if close_holes:
        triangles, closed, inserted = _close_holes(fancloud, triangles, cand, max_hole,
                                                   max_hole_diameter)
        split = 1
        while split:  # two points over one triangle: the second goes in next round
            triangles, split = _insert_unused(fancloud, triangles)
            inserted += split
        stats["holes_closed"] = closed
        stats["points_inserted"] = inserted
    timings["close_holes"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    stats["self_intersections_removed"] = 0
    if remove_self_intersections:
        refill = None
        if close_holes:
            def refill(tris):
                tris, _, _ = _close_holes(fancloud, tris, cand, max_hole, max_hole_diameter)
                split = 1
                while split:
                    tris, split = _insert_unused(fancloud, tris)
                return tris

        triangles, stats["self_intersections_removed"] = _remove_intersections(
            fancloud, triangles, refill
        )
    timings["self_intersections"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    if close_holes and remove_self_intersections:
        triangles, filled, inserted = _fill_rounds(fancloud, triangles, max_hole_diameter)
        stats["holes_closed"] += filled
        stats["points_inserted"] += inserted
        triangles, attached = _attach_to_boundary(fancloud, triangles)
        stats["points_inserted"] += attached
    timings["fill_in_space"] = time.perf_counter() - t0
    return triangles


def _local_rings(fc: FanCloud, fans: FanCloud, which=None) -> FanCloud:
    """``fans`` with the rings of the points ``which`` (all: None) replaced by their local
    triangulation rings (:mod:`._local_ring_kernels`, candidates from the fan cloud
    ``fc``); a point whose ring fails keeps its ring of ``fans``."""
    n = fc.n_points
    which = np.arange(n) if which is None else np.asarray(which, np.int64)
    width = max(MAX_RING, int(fc.fan_sizes.max(initial=0)))
    counts, table, is_open = LRK.local_rings(
        fc.points, fc.normals, fc.offsets, fc.ring, width, LOCAL_NEAR, LOCAL_REACH, LOCAL_FOLD,
        LOCAL_BORDER, 2 * numba.get_num_threads(), which)
    sizes = fans.fan_sizes.copy()
    ok = counts >= 0
    sizes[which[ok]] = counts[ok]
    op = fans.open.copy()
    op[which[ok]] = is_open[ok]
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(sizes, out=offsets[1:])
    ring = np.empty(offsets[-1], np.int64)
    mine = np.zeros(n, bool)
    mine[which[ok]] = True
    rest = np.flatnonzero(~mine)
    src = np.repeat(fans.offsets[rest] - offsets[rest], sizes[rest]) + np.repeat(
        offsets[rest], sizes[rest]) + (np.arange(sizes[rest].sum()) - np.repeat(
        np.cumsum(sizes[rest]) - sizes[rest], sizes[rest]))
    dst = src - np.repeat(fans.offsets[rest] - offsets[rest], sizes[rest])
    ring[dst] = fans.ring[src]
    w = which[ok]
    if len(w):
        rows = np.repeat(np.flatnonzero(ok), counts[ok])
        cols = np.arange(counts[ok].sum()) - np.repeat(np.cumsum(counts[ok]) - counts[ok],
                                                        counts[ok])
        ring[np.repeat(offsets[w], counts[ok]) + cols] = table[rows, cols]
    return FanCloud(fc.points, offsets, ring, fc.normals, op, fc.rotated)


def _mesh_of(source: FanCloud, spatial, triangles, stats, outliers, flip=None,
             normals=None) -> TriangleMesh:
    """The mesh of ``triangles`` (indices in the spatial order ``spatial``) on a copy of
    the source fan cloud's points, normals and point data; the normals ``flip`` (in the
    spatial order) negates are negated. ``normals`` (in the spatial order), when given,
    replace the source's."""
    if normals is None:
        normals = source.normals.copy()
        if flip is not None and flip.any():
            normals[spatial[flip]] *= -1.0
    else:
        out = np.empty_like(source.normals)
        out[spatial] = normals
        normals = out
    return TriangleMesh(
        source.points.copy(),
        np.ascontiguousarray(spatial[triangles], dtype=np.int64),
        normals,
        {k: v.copy() for k, v in source.point_data.items()},
        stats,
        np.sort(spatial[outliers]),
    )


def _one_rings(fans: FanCloud, tri, count, n_fan) -> bool:
    """The fans are the one-rings of a 2-manifold: every fan triangle is in the fans of
    all three of its points (none in fewer), and no edge has more than two triangles."""
    if len(tri) == 0 or n_fan != 3 * len(tri) or not (count == 3).all():
        return False
    e = np.sort(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    n = fans.n_points
    _, cnt = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
    return bool(cnt.max() <= 2)


def _manifold_of_rings(source, spatial, fancloud, tri, stats, timings, self_intersections):
    """The mesh of fans that are one-rings (:func:`_one_rings`): their triangles, as
    they are (the fan cloud of a triangle mesh, or a reduction of it by retriangulation).
    Nothing is removed or grown: self-intersections are counted (and warned of), not
    removed, which would open the surface."""
    import warnings

    from .mesh_stats import mesh_statistics

    t0 = time.perf_counter()
    for key in ("after_superfluous", "uncontested", "grown", "final"):
        stats[key] = len(tri)
    for key in ("normals_flipped", "pinch_cut", "holes_closed", "points_inserted",
                "self_intersections_removed", "outliers", "cut_pieces", "cut_points",
                "local_rings", "pieces_turned"):
        stats[key] = 0  # (one-rings: the mesh's pieces are the fans' pieces)
    stats.update(mesh_statistics(fancloud.points, tri, self_intersections=self_intersections))
    timings["checks"] = time.perf_counter() - t0
    stats["timings"] = timings
    if stats.get("self_intersections", 0) > 0:
        warnings.warn(
            f"fan_cloud_to_mesh: the fans are the one-rings of a 2-manifold, taken as they "
            f"are; {stats['self_intersections']} pairs of its triangles intersect",
            DoubtfulMeshWarning, stacklevel=3)
    return _mesh_of(source, spatial, tri, stats, np.empty(0, np.int64))


def _shared_orientation(fans: FanCloud, fancloud: FanCloud) -> np.ndarray:
    """The normals to negate (a mask) so that neighbouring fans run the triangles they
    share the same way round (docs/mesh.md, section 2b).

    ``fans``: the Delaunay rings; ``fancloud``: the fan cloud's own fans (the same
    points and normals), called where two fans run a shared triangle opposite ways
    round. The points are oriented again by
    :func:`~._normal_kernels.orient_by_evidence`: every shared triangle a vote of 1,
    and the fan neighbours' normals a weak vote where no triangle decides; in each
    connected component the orientation most of it had (by area) is kept.
    """
    n = fans.n_points
    vote = NK.shared_triangle_votes(fans.offsets, fans.ring, fans.open)
    # one graph: the Delaunay rings with their votes, the fans with their normals' agreement
    weak = NK.agreement_weights(fancloud.points, fancloud.normals, fancloud.offsets,
                                fancloud.ring, NK.SHARED_WEAK)
    owner = np.r_[np.repeat(np.arange(n), np.diff(fans.offsets)),
                  np.repeat(np.arange(n), np.diff(fancloud.offsets))]
    order = np.argsort(owner, kind="stable")
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(owner, minlength=n), out=offsets[1:])
    nbr = np.r_[fans.ring, fancloud.ring][order]
    weight = np.r_[vote.astype(np.float64), weak][order]
    flipped, comp, n_comp = NK.orient_by_evidence(offsets, nbr, weight)
    sizes = np.diff(fans.offsets)
    src = np.repeat(np.arange(n), sizes)
    d2 = np.einsum("ij,ij->i", fans.points[fans.ring] - fans.points[src],
                   fans.points[fans.ring] - fans.points[src])
    area = np.bincount(src, d2, n) / np.maximum(sizes, 1)
    against = np.bincount(comp, np.where(flipped, area, 0.0), n_comp)
    total = np.bincount(comp, area, n_comp)
    return flipped ^ (2.0 * against > total)[comp]


def _flipped(fc: FanCloud, flip: np.ndarray) -> FanCloud:
    """``fc`` with the normals of ``flip`` negated and their rings reversed (an open
    fan keeps its gap, between its last and first neighbour)."""
    sizes = np.diff(fc.offsets)
    src = np.repeat(np.arange(fc.n_points), sizes)
    pos = np.arange(len(fc.ring))
    rev = fc.offsets[src] + fc.offsets[src + 1] - 1 - pos
    ring = fc.ring[np.where(flip[src], rev, pos)]
    normals = np.where(flip[:, None], -fc.normals, fc.normals)
    return FanCloud(fc.points, fc.offsets, ring, normals, fc.open, fc.rotated)


def _spatial_order(fc: FanCloud):
    """(order, the fan cloud relabelled so that point i is fc's point order[i]).

    The order is the fan construction's grid order (cells in Morton order).
    Only the geometry and the rings are carried over (no point data).
    """
    from .fans import Grid as _Grid

    grid = _Grid(fc.points)
    order = grid.order
    offsets, ring = RingK.relabel_rings(fc.offsets, fc.ring, order, grid.pos)
    return order, FanCloud(
        grid.sorted_points, offsets, ring, fc.normals[order], fc.open[order], fc.rotated[order]
    )


# -- stages --------------------------------------------------------------------


def _ring_spacing(fc: FanCloud, which: np.ndarray) -> np.ndarray:
    """The local spacing of the points ``which``: each one's median distance to its fan
    neighbours (0 for a point without any)."""
    sizes = fc.fan_sizes[which]
    start = np.zeros(len(which) + 1, np.int64)
    np.cumsum(sizes, out=start[1:])
    src = np.repeat(which, sizes)
    # the ring entries of the points which, in their order
    idx = np.repeat(fc.offsets[which] - start[:-1], sizes) + np.arange(start[-1])
    d = np.linalg.norm(fc.points[fc.ring[idx]] - fc.points[src], axis=1)
    d = d[np.lexsort((d, np.repeat(np.arange(len(which)), sizes)))]
    out = np.zeros(len(which))
    has = sizes > 0
    lo = start[:-1] + np.maximum(sizes - 1, 0) // 2
    hi = start[:-1] + sizes // 2
    out[has] = 0.5 * (d[lo[has]] + d[hi[has]])
    return out


def _loop_small(fc: FanCloud, loop_off, loop_verts, max_diameter) -> np.ndarray:
    """Per loop: its bounding-box diagonal is at most max_diameter median spacings."""
    sizes = np.diff(loop_off)
    if max_diameter <= 0.0:
        return np.ones(len(sizes), bool)
    starts = loop_off[:-1]
    p = fc.points[loop_verts]
    diag = np.linalg.norm(
        np.maximum.reduceat(p, starts, axis=0) - np.minimum.reduceat(p, starts, axis=0), axis=1
    )
    s = _ring_spacing(fc, loop_verts)
    lid = np.repeat(np.arange(len(sizes)), sizes)
    s = s[np.lexsort((s, lid))]
    med = 0.5 * (s[starts + (sizes - 1) // 2] + s[starts + sizes // 2])
    return diag <= max_diameter * med


def _close_holes(fc: FanCloud, triangles, cand, max_hole, max_diameter=0.0, rounds=4):
    """Triangulate the small boundary loops that are holes, not the real boundary.

    A loop with a single unused point inside gets a star around it; with
    unused points (or when the star fails), the loop and those points get a
    Delaunay triangulation in the loop's mean tangent plane, kept only if
    it has every loop edge; otherwise (and for loops with no unused point:
    most of them, in one numba call) the loop is clipped ear by ear. A loop
    that cannot be closed is widened by the triangles around it and tried
    again (``rounds`` attempts in all); if the last attempt leaves a widened
    hole open, the result is the state after a round's fills with the
    largest area (the widening undone). ``cand`` holds the candidate triangles, their
    counts and their edges (``tri, count, edge_uv, edge_off, edge_tri,
    v_edge_off, v_edges``, see :func:`fan_cloud_to_mesh`). A loop wider than
    ``max_diameter`` local spacings is not taken when at least a quarter of
    its points have open fans. Returns
    (triangles, holes closed, points inserted).
    """
    n = fc.n_points
    closed = inserted = 0
    widened = np.zeros(n, bool)  # around holes that were widened: any size goes
    # of the states before a widening, the one with the largest area: a widened hole that
    # the retries do not close leaves less, and the widening is then undone
    best = None
    for last in range(rounds - 1, -1, -1):
        vt_off, vt = CsrK.vertex_triangles(triangles, n)
        loop_off, loop_verts = MK.boundary_loops_manifold(triangles, vt_off, vt, n)
        sizes = np.diff(loop_off)
        if len(sizes) == 0:
            break
        starts = loop_off[:-1]
        any_open = np.add.reduceat(fc.open[loop_verts].astype(np.int64), starts) > 0
        any_wide = np.add.reduceat(widened[loop_verts].astype(np.int64), starts) > 0
        used = np.zeros(n, bool)
        used[triangles.ravel()] = True
        unused = np.flatnonzero(~used & ~fc.open)
        # a loop with unused points of closed fans inside is surface they claim: a hole,
        # whatever its size
        every = np.ones(len(sizes), bool)
        inside = np.zeros(len(sizes), bool)
        inside[list(_points_inside(fc, unused, loop_verts, sizes, every))] = True
        # a wide loop along many open fans is a gap of the sampling: it stays open
        n_open = np.add.reduceat(fc.open[loop_verts].astype(np.int64), starts)
        small = _loop_small(fc, loop_off, loop_verts, max_diameter) | (4 * n_open < sizes)
        take = (sizes == 3) | (((sizes <= max_hole) | any_wide | inside) & ~any_open)
        for i in np.flatnonzero(any_open & ((sizes <= max_hole) | any_wide) & (sizes > 3) & small):
            take[i] = not _on_real_boundary(fc, loop_verts[starts[i] : loop_off[i + 1]])
        ids = np.flatnonzero(take)
        if len(ids) == 0:
            break
        # again among the taken loops only: a point between a taken and an untaken loop
        # goes to the taken one
        interior = _points_inside(fc, unused, loop_verts, sizes, take)
        edges = (triangles, vt_off, vt)
        new = []
        failed = []
        plain = take.copy()  # loops for the ear clipping
        for i, pts in interior.items():
            loop = loop_verts[starts[i] : loop_off[i + 1]]
            tris = _star(fc, loop, pts[0], edges) if len(pts) == 1 else None
            if tris is None:
                tris = _delaunay_fill(fc, loop, pts, edges)
            if tris is None:  # the points inside are split in afterwards
                continue
            plain[i] = False
            new.append(np.array(tris, np.int64))
            closed += 1
            inserted += len({int(v) for t in tris for v in t} - set(loop.tolist()))
        if plain.any():
            sel = np.repeat(plain, sizes)
            p_sizes = sizes[plain]
            p_off = np.zeros(len(p_sizes) + 1, np.int64)
            np.cumsum(p_sizes, out=p_off[1:])
            out = np.empty((int((p_sizes - 2).sum()), 3), np.int64)
            ok = np.zeros(len(p_sizes), bool)
            MK.clip_ears(
                fc.points,
                fc.normals,
                p_off,
                loop_verts[sel],
                triangles,
                vt_off,
                vt,
                *cand,
                n,
                out,
                ok,
            )
            new.append(out[np.repeat(ok, p_sizes - 2)])
            closed += int(ok.sum())
            bad = np.flatnonzero(plain)[~ok]
            failed.extend(loop_verts[starts[i] : loop_off[i + 1]] for i in bad)
        new = [t for t in new if len(t)]
        if new:
            triangles = np.vstack([triangles, *new])
        if not failed or last == 0:
            break
        area = _area(fc.points, triangles)  # only where a widening follows
        if best is None or area >= best[0]:
            best = (area, triangles, closed, inserted)
        # widen the holes that failed by the triangles around them, and retry
        around = np.zeros(n, bool)
        around[np.concatenate(failed)] = True
        keep = ~around[triangles].any(axis=1)
        widened[triangles[~keep].ravel()] = True
        MK.split_pinched(triangles, keep, n)  # only kept triangles count: one compaction
        triangles = triangles[keep]
    if best is None or _area(fc.points, triangles) >= best[0]:
        return triangles, closed, inserted
    vt_off, vt = CsrK.vertex_triangles(triangles, n)
    loop_off, loop_verts = MK.boundary_loops_manifold(triangles, vt_off, vt, n)
    if len(triangles) and not widened[loop_verts].any():
        return triangles, closed, inserted  # the widened holes are closed
    return best[1:]  # (a widening that ate every triangle is undone too)


class DoubtfulMeshWarning(UserWarning):
    """The mesh is probably not what the points describe (see the message)."""


def _outliers(fc: FanCloud, triangles, min_component, far=5.0):
    """(triangles without the stray pieces, the outlier points), see ``min_component``.

    A piece is stray when it is small (fewer than ``min_component`` points and
    a tenth of the largest piece's), and so is the cluster of small pieces it
    belongs to (small pieces with points within ``far`` times their local
    spacing of each other, the median fan-ring distance), and no point of the
    cluster has a point of a piece that is not small that near: a cluster off
    the surface, not a bit of the surface that the growing left apart.
    """
    n = fc.n_points
    drop = np.zeros(len(triangles), bool)
    if min_component > 0 and len(triangles):
        label = CK.vertex_components(np.ascontiguousarray(triangles), n)
        size = np.bincount(label[label >= 0], minlength=n)
        small = (size < min_component) & (10 * size < size.max())
        cand = np.flatnonzero((label >= 0) & small[np.maximum(label, 0)])
        if len(cand):
            from scipy.spatial import cKDTree

            # past the piece's own points, a margin: the nearest others may be unused points
            kq = min(int(size[label[cand]].max()) + 16, n)
            d, j = cKDTree(fc.points).query(fc.points[cand], k=kq)
            d = d.reshape(len(cand), -1)
            j = j.reshape(len(cand), -1)
            # near: within far times the smaller local spacing of the two points (a stray
            # cluster's own spacing may be coarse; the surface's next to it is not)
            near = np.unique(j)
            spacing = np.zeros(n)
            spacing[near] = _ring_spacing(fc, near)
            spacing[cand] = _ring_spacing(fc, cand)
            lim = far * np.minimum(spacing[cand][:, None], spacing[j])
            lim[spacing[j] == 0] = far * spacing[cand][np.nonzero(spacing[j] == 0)[0]]
            lj = np.maximum(label[j], 0)
            other = (label[j] >= 0) & (lj != label[cand][:, None]) & (d <= lim)
            # small pieces near each other are one cluster (the growing or the filling may
            # have cut a cluster, or a bit of surface, in pieces): a union of their labels
            group = np.arange(n)

            def root(x):
                while group[x] != x:
                    group[x] = group[group[x]]
                    x = group[x]
                return x

            rows, cols = np.nonzero(other & small[lj])
            for a, b in zip(label[cand][rows].tolist(), lj[rows, cols].tolist(), strict=True):
                ra, rb = root(a), root(b)
                if ra != rb:
                    group[ra] = rb
            top = np.array([root(x) for x in range(n)]) if len(rows) else group
            total = np.bincount(top, weights=size, minlength=n)
            close = np.zeros(n, bool)  # per group: a point near a piece that is not small
            close[top[label[cand][(other & ~small[lj]).any(axis=1)]]] = True
            stray = small & ~close[top] & (total[top] < min_component)
            drop = stray[label[triangles[:, 0]]]
    in_small = np.zeros(n, bool)
    in_small[triangles[drop].ravel()] = True
    triangles = triangles[~drop]
    used = np.zeros(n, bool)
    used[triangles.ravel()] = True
    held = np.zeros(n, bool)  # in the fan of a point of the mesh
    held[fc.ring[np.repeat(used, fc.fan_sizes)]] = True
    return triangles, np.flatnonzero(~used & (~held | in_small))


def _cut_pieces(fc: FanCloud, triangles, stats) -> tuple[int, int]:
    """(pieces, points) the mesh has cut off the pieces of the fan cloud.

    A piece of the fan cloud (points joined by chains of fan edges) should
    give one piece of the mesh (points joined by chains of triangles). Where
    the sampling is too coarse for the fans (a leg or an ear a few points
    round, the poles of a UV sphere), the growing may cut it into several.
    Counted: the mesh's pieces beyond the largest in each fan piece, and
    their points. (0, 0) without looking further when the triangles are one
    edge-connected piece (``stats['components']``; without it, the triangles' pieces
    are counted here).
    """
    if stats.get("components", 2) <= 1 or len(triangles) == 0:
        return 0, 0
    n = fc.n_points
    mesh = CK.vertex_components(np.ascontiguousarray(triangles), n)
    used = mesh >= 0
    if "components" not in stats and (mesh[used] == mesh[used][0]).all():
        return 0, 0  # one piece
    fan = CK.fan_components(fc.offsets, fc.ring, n)[used]
    mesh = mesh[used]
    pair, size = np.unique(fan * n + mesh, return_counts=True)
    owner = pair // n
    # per fan piece, the size of its largest mesh piece
    largest = np.zeros(n, np.int64)
    np.maximum.at(largest, owner, size)
    pieces = len(pair) - len(np.unique(owner))
    return int(pieces), int(size.sum() - largest[np.unique(owner)].sum())


def _warn_if_doubtful(fc: FanCloud, triangles, stats, holes=True, stacklevel=3) -> None:
    """A :class:`DoubtfulMeshWarning` for each sign that the mesh is not the surface
    (holes between closed fans only when they were to be closed: ``holes``)."""
    import warnings

    n = fc.n_points
    said = []
    unused = stats["unused_points"] - stats["outliers"]
    if unused > max(10, 0.01 * n):
        said.append(f"{unused} points ({100 * unused / n:.1f}%) are in no triangle and not "
                    "judged outliers")
    if stats["outliers"] > max(10, 0.01 * n):
        said.append(f"{stats['outliers']} points ({100 * stats['outliers'] / n:.1f}%) "
                    "were judged outliers (stray points or small isolated pieces)")
    if holes and stats["boundary_edges"] > max(10, 0.01 * stats["edges"]):
        e = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        key, cnt = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
        bnd = key[cnt == 1]
        a, b = bnd // n, bnd % n
        unexplained = int(np.count_nonzero(~fc.open[a] & ~fc.open[b]))
        if unexplained > max(10, 0.01 * len(key)):
            said.append(f"{unexplained} boundary edges join points whose fans are closed "
                        "(holes the fans do not explain: the sampling may be too coarse, "
                        "anisotropic or thin for k neighbours)")
    cut = stats.get("cut_points", 0)
    if cut > max(10, 0.01 * n) or stats.get("cut_pieces", 0) >= 10:
        said.append(f"{cut} points ({100 * cut / n:.1f}%) are in {stats['cut_pieces']} pieces "
                    "of the mesh cut off the surface the fans join them to (thin parts, such "
                    "as legs or ears a few points round, sampled too coarsely for k "
                    "neighbours)")
    removed = stats.get("self_intersections_removed", 0)
    if removed > max(10, 0.01 * max(len(triangles), 1)):
        said.append(f"{removed} self-intersecting triangles were removed")
    for text in said:
        warnings.warn(f"fan_cloud_to_mesh: {text}", DoubtfulMeshWarning,
                      stacklevel=stacklevel)


def _remove_intersections(fc: FanCloud, triangles, refill, rounds=3):
    """Remove the triangles that intersect others; refill the holes; repeat.

    Each round removes the worse triangle of every intersecting pair (the
    one in more pairs, then the larger; and what is left pinched at a
    vertex), then ``refill(triangles)`` closes the holes
    again, if given; after ``rounds`` refills, what still intersects is
    removed for good. Returns (triangles, number removed in all).
    """
    from .mesh_stats import self_intersecting_pairs

    n = fc.n_points
    removed = 0
    before = None  # (triangles before the last refill, the pairs they had)
    for r in range(rounds + 1):
        pairs = self_intersecting_pairs(fc.points, triangles)
        if before is not None and len(pairs) > before[1]:
            # the refill crossed more than it repaired (a widened hole clipped across
            # the surface): back to the mesh before it; the last filling takes its holes
            triangles = before[0]
            break
        if len(pairs) == 0:
            break
        # of each pair the worse triangle goes: the one in more pairs, then the larger
        hits = np.bincount(pairs.ravel(), minlength=len(triangles))
        a, b, c = (fc.points[triangles[:, j]] for j in range(3))
        area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
        first = (hits[pairs[:, 0]] > hits[pairs[:, 1]]) | (
            (hits[pairs[:, 0]] == hits[pairs[:, 1]]) & (area[pairs[:, 0]] >= area[pairs[:, 1]])
        )
        bad = np.zeros(len(triangles), bool)
        bad[np.where(first, pairs[:, 0], pairs[:, 1])] = True
        removed += int(bad.sum())
        keep = ~bad
        MK.split_pinched(triangles, keep, n)  # only kept triangles count: one compaction
        triangles = triangles[keep]
        if r == rounds or refill is None:
            break
        before = (triangles, len(pairs))
        triangles = refill(triangles)
    return triangles, removed


def _meets(points, base, new) -> np.ndarray:
    """Per row of ``new``: does it intersect a triangle of ``base`` or another row of ``new``
    (as :func:`~fancloud_vtk.core.mesh_stats.self_intersecting_pairs` tests a pair)?"""
    from .mesh_stats import AREA_TOL, INTERSECTION_TOL

    if len(new) == 0:
        return np.zeros(0, bool)
    if len(base) > 64 * len(new):  # only the base triangles within reach of the new ones
        base = np.ascontiguousarray(base, dtype=np.int64)
        cb, reach = FillK.centroids_reach(points, base)
        cn = points[new].mean(axis=1)
        rn = np.linalg.norm(points[new] - cn[:, None], axis=2).max(axis=1)
        base = base[FillK.near_seeds(cb, cn, rn + reach)]
    both = np.ascontiguousarray(np.vstack([base, new]), dtype=np.int64)
    return FillK.meets(points, both, len(base), INTERSECTION_TOL, AREA_TOL)


def _longest(points, triangles) -> float:
    """The longest edge of some triangles."""
    p = points[triangles]
    return float(np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).max())


def _fill_in_space(fc: FanCloud, triangles, max_diameter, state):
    """The last hole filling: triangulate in space the holes still open, without crossings.

    Runs after the self-intersections are removed. A boundary loop that is a
    hole (as :func:`_close_holes` judges: not along the real boundary, not a
    wide gap along open fans) and has at most :data:`MAX_FILL` edges is
    triangulated over its own vertices by :func:`._fill_kernels.fill_loop`
    (the smallest largest dihedral angle, then the least area); when that
    fill crosses a mesh triangle near the loop, again with only triangles
    that cross none (:func:`._fill_kernels._clear`). A fill is kept when
    its triangles cross nothing and its longest edge is at most
    :data:`FILL_MAX_EDGE` local spacings. Pieces of at most four points
    and triangles none of whose edges is shared (hanging at a vertex: a
    loop would wrap them twice) are taken out first: their points are
    then inserted like other unused points. ``state``: :func:`_open_state` of the
    triangles. Returns (triangles, holes filled, the triangles that stand in the way of
    a fill).
    """
    from scipy.spatial import cKDTree

    from .mesh_stats import AREA_TOL, INTERSECTION_TOL, _triangle_frames

    n = fc.n_points
    pts = fc.points
    none = np.zeros(0, np.int64)
    vt_off, vt, loop_off, loop_verts, _ = state
    if len(loop_off) < 2:
        return triangles, 0, none
    # pieces of at most four points, and triangles hanging at a vertex (their three
    # half-edges on the boundary)
    label = CK.vertex_components(np.ascontiguousarray(triangles), n)
    size = np.bincount(label[label >= 0], minlength=n)
    drop = size[label[triangles[:, 0]]] <= 4
    sizes = np.diff(loop_off)
    nxt = np.roll(loop_verts, -1)
    nxt[loop_off[1:] - 1] = loop_verts[loop_off[:-1]]
    half = loop_verts * n + nxt
    on_loop = np.zeros(n, bool)
    on_loop[loop_verts] = True
    cand = np.flatnonzero(on_loop[triangles].all(axis=1))
    keys = triangles[cand] * n + np.roll(triangles[cand], -1, axis=1)
    drop[cand[np.isin(keys, half).all(axis=1)]] = True
    if drop.any():
        triangles = triangles[~drop]
        if len(triangles) == 0:
            return triangles, 0, none
        vt_off, vt, loop_off, loop_verts, _ = _open_state(fc, triangles)
        sizes = np.diff(loop_off)
        if len(sizes) == 0:
            return triangles, 0, none
    starts = loop_off[:-1]
    n_open = np.add.reduceat(fc.open[loop_verts].astype(np.int64), starts)
    small = _loop_small(fc, loop_off, loop_verts, max_diameter) | (4 * n_open < sizes)
    which = np.flatnonzero(sizes <= MAX_FILL)
    if len(which) == 0:
        return triangles, 0, none
    # the triangles near the loops: a tree of their centroids only (the mesh may be large
    # and its holes few)
    triangles = np.ascontiguousarray(triangles, dtype=np.int64)
    cen, reach = FillK.centroids_reach(pts, triangles)
    lid = np.repeat(np.arange(len(sizes)), sizes)
    centre = np.add.reduceat(pts[loop_verts], starts) / sizes[:, None]
    extent = np.zeros(len(sizes))
    np.maximum.at(extent, lid, np.linalg.norm(pts[loop_verts] - centre[lid], axis=1))
    sub = np.flatnonzero(FillK.near_seeds(cen, centre[which], extent[which] + reach))
    tree = cKDTree(cen[sub])
    # the triangles' boxes as the intersection test pads them: only a triangle whose box
    # meets a loop's box can cross that loop's fill (its triangles lie in the loop's box);
    # the ball around the loop's centre holds them all, but where a few triangles are
    # long (``reach`` is the largest) it holds most of the mesh, and every fill was
    # tested against all of it (minutes on 5,000 points of a few noisy blobs)
    _, _, box_lo, box_hi, _ = _triangle_frames(pts, triangles, AREA_TOL, INTERSECTION_TOL)
    added = []
    # the box of each fill's padded triangles
    added_lo, added_hi = np.empty((len(which), 3)), np.empty((len(which), 3))
    blockers = []
    unchecked = (np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)),
                 np.zeros((0, 3)), np.zeros(0, bool), 0.0, 0.0)
    for i in which:
        loop = np.ascontiguousarray(loop_verts[starts[i] : loop_off[i + 1]])
        if n_open[i] and (not small[i] or _on_real_boundary(fc, loop)):
            continue
        c = centre[i]
        near = np.sort(sub[tree.query_ball_point(c, extent[i] + reach)])
        llo, lhi = pts[loop].min(axis=0), pts[loop].max(axis=0)
        pad = 2.0 * INTERSECTION_TOL * float(np.linalg.norm(lhi - llo)) * (1.0 + 1e-9) + 1e-300
        near = near[np.all(box_lo[near] <= lhi + pad, axis=1)
                    & np.all(box_hi[near] >= llo - pad, axis=1)]
        m_add = len(added)
        meet = np.flatnonzero(np.all(added_lo[:m_add] <= lhi + pad, axis=1)
                              & np.all(added_hi[:m_add] >= llo - pad, axis=1))
        local = np.vstack([triangles[near], *[added[j] for j in meet],
                           np.zeros((1, 3), np.int64)])
        local = np.ascontiguousarray(local, dtype=np.int64)
        h_loop = float(np.median(_ring_spacing(fc, loop)))
        free = FillK.fill_loop(pts, loop, triangles, vt_off, vt, np.pi,
                               *unchecked)
        if len(free) and _longest(pts, free) > FILL_MAX_EDGE * h_loop:
            continue  # a fill this coarse would bridge: the hole stays
        if len(free) and not _meets(pts, local[:-1], free).any():
            added_lo[len(added)], added_hi[len(added)] = _padded_box(pts, free)
            added.append(free)  # the best fill crosses nothing
            continue
        frames = _triangle_frames(pts, local, AREA_TOL, INTERSECTION_TOL)
        tris = FillK.fill_loop(pts, loop, triangles, vt_off, vt, np.pi,
                               local, *frames, INTERSECTION_TOL, AREA_TOL)
        if len(tris) and _longest(pts, tris) <= FILL_MAX_EDGE * h_loop \
                and not _meets(pts, local[:-1], tris).any():
            added_lo[len(added)], added_hi[len(added)] = _padded_box(pts, tris)
            added.append(tris)
            continue
        # what stands in the way: the mesh triangles that the best fill would cross
        if len(free):
            hit = _meets(pts, free, triangles[near])
            if 0 < hit.sum() <= len(loop):
                blockers.append(np.asarray(near, np.int64)[hit])
    if added:
        triangles = np.vstack([triangles, *added])
    blocked = np.unique(np.concatenate(blockers)) if blockers else np.zeros(0, np.int64)
    return triangles, len(added), blocked


def _padded_box(points, tris) -> tuple[np.ndarray, np.ndarray]:
    """The box of some triangles, each padded as the intersection test pads it."""
    from .mesh_stats import AREA_TOL, INTERSECTION_TOL, few_triangle_frames

    _, _, t_lo, t_hi, _ = few_triangle_frames(points, np.ascontiguousarray(tris, np.int64),
                                              AREA_TOL, INTERSECTION_TOL)
    return t_lo.min(axis=0), t_hi.max(axis=0)


def _open_state(fc: FanCloud, triangles):
    """(vt_off, vt, loop_off, loop_verts, unused points) of a mesh."""
    n = fc.n_points
    vt_off, vt = CsrK.vertex_triangles(triangles, n)
    loop_off, loop_verts = MK.boundary_loops_manifold(triangles, vt_off, vt, n)
    used = np.zeros(n, bool)
    used[triangles.ravel()] = True
    return vt_off, vt, loop_off, loop_verts, int(np.count_nonzero(~used))


def _fill_rounds(fc: FanCloud, triangles, max_diameter):
    """Rounds of :func:`_fill_in_space` and point insertion; between rounds, the triangles
    that stand in the way of a hole's fill are taken out (the hole widened), and the
    round that leaves the fewest boundary edges plus twice the unused points is the
    result. At most :data:`FILL_ROUNDS` rounds; they stop when a round changes nothing,
    or after :data:`FILL_PATIENCE` rounds without a better one. Returns (triangles,
    holes filled, points inserted)."""
    state = _open_state(fc, triangles)
    score = len(state[3]) + 2 * state[4]
    if score == 0 or len(triangles) == 0:
        return triangles, 0, 0
    best = (score, triangles, 0, 0)
    filled_all = inserted_all = stale = 0
    tried = np.zeros(fc.n_points, bool)  # an insertion at the nearest triangle failed
    before = triangles
    for r in range(FILL_ROUNDS):
        triangles, filled, blocked = _fill_in_space(fc, triangles, max_diameter, state)
        triangles, inserted = _insert_unused_checked(fc, triangles)
        # a point that failed is tried again only where the mesh around it changed
        tried &= ~_near_changes(fc, before, triangles, tried)
        triangles, nearest, failed = _insert_nearest(fc, triangles, skip=tried)
        tried |= failed
        before = triangles
        filled_all += filled
        inserted_all += inserted + nearest
        state = _open_state(fc, triangles)
        score = len(state[3]) + 2 * state[4]
        if score < best[0]:
            best = (score, triangles, filled_all, inserted_all)
            stale = 0
        else:
            stale += 1
        if (r == FILL_ROUNDS - 1 or score == 0 or stale == FILL_PATIENCE
                or (filled + inserted + nearest == 0 and len(blocked) == 0)):
            break
        if len(blocked):
            keep = np.ones(len(triangles), bool)
            keep[blocked] = False
            triangles = triangles[keep]
            keep = np.ones(len(triangles), bool)
            MK.split_pinched(triangles, keep, fc.n_points)
            triangles = triangles[keep]
            state = _open_state(fc, triangles)
    return best[1], best[2], best[3]


def _near_changes(fc: FanCloud, old, new, points) -> np.ndarray:
    """Which of the ``points`` (mask) have a triangle made or removed between the meshes
    ``old`` and ``new`` within three local spacings and three times the largest
    triangle's reach (what an insertion there could cross)."""
    from scipy.spatial import cKDTree

    near = np.zeros(fc.n_points, bool)
    which = np.flatnonzero(points)
    if len(which) == 0:
        return near
    a = np.sort(old, axis=1)
    b = np.sort(new, axis=1)
    rows = np.vstack([a, b])
    _, inv, cnt = np.unique(rows, axis=0, return_inverse=True, return_counts=True)
    changed = rows[cnt[inv.ravel()] == 1]  # in one mesh only
    if len(changed) == 0:
        return near
    c = fc.points[changed].mean(axis=1)
    reach = np.linalg.norm(fc.points[changed] - c[:, None], axis=2).max()
    h = _ring_spacing(fc, which)
    hit = cKDTree(c).query_ball_point(fc.points[which], 3.0 * h + 3.0 * reach)
    near[which[np.array([len(x) > 0 for x in hit], bool)]] = True
    return near


def _insert_unused_checked(fc: FanCloud, triangles):
    """:func:`_insert_unused`, undoing each insertion whose three triangles would cross
    the mesh; repeated while points go in. Returns (triangles, points inserted)."""
    n = fc.n_points
    skip = np.zeros(n, bool)
    inserted = 0
    while True:
        out, count = MK.insert_unused(
            fc.points, fc.normals, fc.offsets, fc.ring, triangles, n, skip
        )
        if count == 0:
            return triangles, inserted
        kept = out[: len(out) - 3 * count]
        new = out[len(out) - 3 * count :]
        bad = _meets(fc.points, kept, new).reshape(-1, 3).any(axis=1)
        # and the point far from the triangle it splits (a spike): farther than
        # INSERT_FAR local spacings from its plane
        split = new.reshape(-1, 3, 3)
        p = split[:, 0, 2]
        a, b, c = (fc.points[split[:, k, 0]] for k in range(3))
        nrm = np.cross(b - a, c - a)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1), 1e-300)[:, None]
        off = np.abs(np.einsum("ij,ij->i", fc.points[p] - a, nrm))
        # the local spacing: p's, or the split triangle's (the median of its corners') when
        # smaller (a stray point has a wide ring)
        corners = _ring_spacing(fc, split[:, :, 0].ravel()).reshape(-1, 3)
        h = np.minimum(_ring_spacing(fc, p), np.median(corners, axis=1))
        bad |= off > INSERT_FAR * h
        # and a coarse result: a new triangle with an edge over FILL_MAX_EDGE local spacings
        q = fc.points[new].reshape(-1, 3, 3, 3)
        longest = np.linalg.norm(q - np.roll(q, 1, axis=2), axis=3).max(axis=(1, 2))
        bad |= longest > FILL_MAX_EDGE * h
        if bad.any():
            # undo: the split triangle (a, b, c) from its three (a, b, p), (b, c, p), (c, a, p)
            undo = new.reshape(-1, 3, 3)[bad]
            skip[undo[:, 0, 2]] = True
            restored = undo[:, :, 0]
            new = new.reshape(-1, 3, 3)[~bad].reshape(-1, 3)
            kept = np.vstack([kept, restored])
        triangles = np.vstack([kept, new])
        inserted += int((~bad).sum())


def _insert_nearest(fc: FanCloud, triangles, far=None, edge=0.1, tries=8, skip=None):
    """Put each point still unused into the mesh near it.

    For unused point p, the ``tries`` triangles nearest to p (within two
    local spacings) are tried in order of distance: a triangle whose closest
    point to p lies inside it (barycentric coordinates at least ``edge``) is
    split in three at p; otherwise its edges, nearest to p first, are split
    at p with the triangles on them. A split is made when p is at most
    ``far`` local spacings from it (p's median distance to its fan neighbours,
    or the triangle's, the median of its corners', when smaller), the
    triangle's longest edge is at most :data:`FILL_MAX_EDGE` of them, every new triangle
    faces the way the one it replaces did, and the new triangles cross
    nothing (:func:`_meets`). One point at a time, in increasing order; the
    points ``skip`` (mask) are not tried. Returns (triangles, points inserted,
    the points tried in vain).
    """
    from scipy.spatial import cKDTree

    from .mesh_stats import AREA_TOL, INTERSECTION_TOL

    far = INSERT_FAR if far is None else far
    n = fc.n_points
    pts = fc.points
    used = np.zeros(n, bool)
    used[triangles.ravel()] = True
    todo = np.flatnonzero(~used if skip is None else ~used & ~skip)
    failed = np.zeros(n, bool)
    if len(todo) == 0 or len(triangles) == 0:
        return triangles, 0, failed
    spacing = _ring_spacing(fc, todo)
    m = len(triangles)
    tris = np.empty((m + 4 * len(todo), 3), np.int64)  # the mesh, then the triangles made
    tris[:m] = triangles
    alive = np.zeros(len(tris), bool)
    alive[:m] = True
    top = m
    # a tree of the centroids of the triangles within reach of the points only (the mesh
    # may be large and its unused points few)
    cen, reach = FillK.centroids_reach(pts, np.ascontiguousarray(triangles, dtype=np.int64))
    sub = np.flatnonzero(FillK.near_seeds(cen, pts[todo], 2.0 * spacing + 3.0 * reach))
    # per point: the 16 mesh triangles nearest (by centroid) within 2 spacings and the
    # reach, and those within 2 spacings and three reaches (what a split could cross)
    knn_off = np.zeros(len(todo) + 1, np.int64)
    ball_off = np.zeros(len(todo) + 1, np.int64)
    knn = ball = np.zeros(0, np.int64)
    if len(sub):
        tree = cKDTree(cen[sub])
        k = min(16, len(sub))
        d, idx = tree.query(pts[todo], k=k)
        d, idx = d.reshape(len(todo), k), idx.reshape(len(todo), k)
        keep = (idx < len(sub)) & (d < (2.0 * spacing + reach)[:, None])  # as the bound cuts
        np.cumsum(keep.sum(axis=1), out=knn_off[1:])
        knn = sub[idx[keep]]
        near = tree.query_ball_point(pts[todo], 2.0 * spacing + 3.0 * reach)
        np.cumsum([len(x) for x in near], out=ball_off[1:])
        ball = sub[np.concatenate([np.asarray(x, np.int64) for x in near])]
    # the local spacing of every corner that can come up: of the triangles found, and
    # of the points themselves (corners of the triangles made)
    corner = np.unique(np.concatenate([triangles[knn].ravel(), triangles[ball].ravel(), todo]))
    vspacing = np.zeros(n)
    vspacing[corner] = _ring_spacing(fc, corner)
    top, inserted, failed_todo = FillK.insert_nearest(
        pts, tris, alive, m, todo, spacing, vspacing, knn_off, knn, ball_off, ball, float(far),
        float(edge), int(tries), float(FILL_MAX_EDGE), INTERSECTION_TOL, AREA_TOL)
    failed[todo[failed_todo]] = True
    return tris[:top][alive[:top]], inserted, failed


#: Rounds of :func:`_attach_to_boundary` (a point attached makes new boundary edges for the
#: next one of a sparse row).
ATTACH_ROUNDS = 8
#: An ear of :func:`_attach_to_boundary` faces as the triangle it extends: the cosine of the
#: angle between their normals is at least this ...
ATTACH_MIN_DOT = 0.5
#: ... and the sine of its smallest angle is at least this.
ATTACH_MIN_SINE = 0.1


def _attach_to_boundary(fc: FanCloud, triangles):
    """Join the points still unused beside the mesh's boundary to it, one ear each.

    A sparse row of samples beside a boundary (a grazing stretch of a range
    scan) lies over no triangle, so no split takes it in. Unused point p
    gets the triangle (b, a, p) on a boundary edge a -> b of a triangle
    (a, b, c), of the 8 boundary edges nearest to p (by midpoint) the first
    for which: the ear faces as (a, b, c) does (cosine at least
    :data:`ATTACH_MIN_DOT`, which puts p across the edge from c), the sine of
    its smallest angle is at least :data:`ATTACH_MIN_SINE`, its longest edge
    is at most :data:`FILL_MAX_EDGE` local spacings (p's, or the edge's
    corners' median when smaller: a stray point has a wide ring, so an
    outlier is never attached), and it crosses no triangle. An edge takes
    one ear per round; rounds repeat while points attach. Returns
    (triangles, points attached).
    """
    from scipy.spatial import cKDTree

    from .mesh_stats import AREA_TOL, INTERSECTION_TOL

    n = fc.n_points
    pts = fc.points
    attached = 0
    for _ in range(ATTACH_ROUNDS):
        if len(triangles) == 0:
            break
        used = np.zeros(n, bool)
        used[triangles.ravel()] = True
        todo = np.flatnonzero(~used)
        if len(todo) == 0:
            break
        tri = np.ascontiguousarray(triangles, dtype=np.int64)
        # an ear's edges are at most FILL_MAX_EDGE times the smaller of p's spacing and its
        # edge's: the reach is bounded by p's, and by twice the largest spacing of the fan
        # neighbours of the points (the surface's around them; a stray point's is wide)
        h_p = _ring_spacing(fc, todo)
        around = np.unique(fc.ring[np.concatenate(
            [np.arange(fc.offsets[p], fc.offsets[p + 1]) for p in todo.tolist()])])
        cap = 2.0 * _ring_spacing(fc, around).max(initial=0.0)
        reach = FILL_MAX_EDGE * np.minimum(h_p, cap)
        # only the triangles within reach (with both triangles of every edge there)
        cen, t_reach = FillK.centroids_reach(pts, tri)
        near_t = np.flatnonzero(FillK.near_seeds(cen, pts[todo], reach + 2.0 * t_reach))
        local = tri[near_t]
        half = np.concatenate([local[:, [0, 1]], local[:, [1, 2]], local[:, [2, 0]]])
        third = np.concatenate([local[:, 2], local[:, 0], local[:, 1]])
        key = half[:, 0] * n + half[:, 1]
        bnd = ~np.isin(key, half[:, 1] * n + half[:, 0])
        if not bnd.any():
            break
        be, bc = half[bnd], third[bnd]
        mid = pts[be].mean(axis=1)
        near_e = FillK.near_seeds(mid, pts[todo], reach)
        if not near_e.any():
            break
        sub = np.flatnonzero(near_e)
        etree = cKDTree(mid[sub])
        ttree = cKDTree(cen[near_t]) if len(near_t) else None
        taken = set()
        made = []
        for i, p in enumerate(todo.tolist()):
            k = min(8, len(sub))
            d, idx = etree.query(pts[p], k=k)
            for dist, j in zip(np.atleast_1d(d), np.atleast_1d(idx), strict=True):
                if j >= len(sub) or dist > reach[i]:
                    break
                e = sub[j]
                a, b, c = int(be[e, 0]), int(be[e, 1]), int(bc[e])
                if (a, b) in taken:
                    continue
                ear = np.array([[b, a, p]], np.int64)
                if not _ear_ok(fc, a, b, c, p, h_p[i]):
                    continue
                base = tri[near_t[ttree.query_ball_point(pts[p], reach[i] + t_reach)]] \
                    if ttree is not None else np.zeros((0, 3), np.int64)
                if made:
                    base = np.vstack([base, np.array(made, np.int64)])
                both = np.ascontiguousarray(np.vstack([base, ear]), dtype=np.int64)
                if FillK.meets(pts, both, len(base), INTERSECTION_TOL, AREA_TOL).any():
                    continue
                made.append([b, a, p])
                taken.update({(a, b), (b, p), (p, a)})
                break
        if not made:
            break
        attached += len(made)
        triangles = np.vstack([tri, np.array(made, np.int64)])
    return triangles, attached


def _ear_ok(fc: FanCloud, a, b, c, p, h_p) -> bool:
    """The shape tests of an ear (b, a, p) on the boundary edge a -> b of (a, b, c)."""
    pa, pb, pc, pp = (fc.points[x] for x in (a, b, c, p))
    n_abc = np.cross(pb - pa, pc - pa)
    n_ear = np.cross(pa - pb, pp - pb)
    s_abc, s_ear = np.linalg.norm(n_abc), np.linalg.norm(n_ear)
    if s_abc == 0.0 or s_ear == 0.0 or n_abc @ n_ear < ATTACH_MIN_DOT * s_abc * s_ear:
        return False
    sides = np.array([np.linalg.norm(pa - pb), np.linalg.norm(pp - pa), np.linalg.norm(pb - pp)])
    # the sine of the smallest angle: twice the area over the two longer sides' product
    longer = np.sort(sides)[1:]
    if s_ear / (longer[0] * longer[1]) < ATTACH_MIN_SINE:
        return False
    h = min(h_p, float(np.median(_ring_spacing(fc, np.array([a, b])))))
    return sides.max() <= FILL_MAX_EDGE * h


def _area(points, triangles) -> float:
    """The area of a triangle mesh."""
    return float(CK.mesh_area(points, np.ascontiguousarray(triangles, dtype=np.int64)))


def _points_inside(fc: FanCloud, points, loop_verts, sizes, which) -> dict:
    """The ``points`` (unused, closed fans) inside the loops ``which`` (mask): each goes
    to the loop that most of its fan neighbours are on. {loop: [points]}."""
    loop_of = np.full(fc.n_points, -1, np.int64)
    on = np.repeat(which, sizes)
    loop_of[loop_verts[on]] = np.repeat(np.arange(len(sizes)), sizes)[on]
    inside = {}
    for p in points.tolist():
        near = loop_of[fc.neighbours(p)]
        near = near[near >= 0]
        if len(near):
            inside.setdefault(int(np.bincount(near).argmax()), []).append(p)
    return inside


def _insert_unused(fc: FanCloud, triangles):
    """Put each unused point into the triangle it lies over (1 -> 3 split).

    Such points were left under a closed part of the surface (a hole closed
    without them); one beside the mesh (on a real boundary) lies over no
    triangle and stays unused. The triangle is the one among those around
    the point's two fan rings that contains its projection along its normal
    (largest smallest barycentric coordinate); see
    :func:`~fancloud_vtk.core._mesh_kernels.insert_unused`. Returns
    (triangles, points inserted).
    """
    out, inserted = MK.insert_unused(
        fc.points, fc.normals, fc.offsets, fc.ring, triangles, fc.n_points, np.zeros(0, bool)
    )
    return out, int(inserted)


def _on_real_boundary(fc: FanCloud, loop) -> bool:
    """Whether a loop runs along the surface's real boundary.

    An edge (a, b) is a real boundary edge when both fans are open and b
    bounds a's gap (the last or first entry of a's ring), or a bounds b's.
    A loop with at least half of its edges on the real boundary is one; a
    loop elsewhere (its points' fans closed, or open fans it only touches)
    is a hole.
    """
    m = len(loop)
    real = 0
    for j in range(m):
        a, b = int(loop[j]), int(loop[(j + 1) % m])
        if fc.open[a] and fc.open[b]:
            ra, rb = fc.neighbours(a), fc.neighbours(b)
            if (len(ra) and b in (ra[0], ra[-1])) or (len(rb) and a in (rb[0], rb[-1])):
                real += 1
    return 2 * real >= m


def _tangent_basis(normal):
    """Two unit vectors across a unit normal (``n x e``, then ``n x u``; in plain floats:
    numpy's cross product of two 3-vectors costs more than the rest of a small fill)."""
    nx, ny, nz = (float(x) for x in normal)
    if abs(nx) < 0.9:  # n x (1, 0, 0)
        u = np.array([ny * 0.0 - nz * 0.0, nz * 1.0 - nx * 0.0, nx * 0.0 - ny * 1.0])
    else:  # n x (0, 1, 0)
        u = np.array([ny * 0.0 - nz * 1.0, nz * 0.0 - nx * 0.0, nx * 1.0 - ny * 0.0])
    u /= np.linalg.norm(u)
    ux, uy, uz = (float(x) for x in u)
    return u, np.array([ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux])


def _inside_polygon(xy, polygon):
    """Even-odd test of points xy (m, 2) against a closed polygon (k, 2)."""
    x, y = xy[:, 0][:, None], xy[:, 1][:, None]
    x0, y0 = polygon[:, 0][None, :], polygon[:, 1][None, :]
    x1, y1 = np.roll(polygon[:, 0], -1)[None, :], np.roll(polygon[:, 1], -1)[None, :]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (crosses & (x < xc)).sum(axis=1) % 2 == 1


def _delaunay_fill(fc: FanCloud, loop, pts, edges):
    """Delaunay triangulation of a loop and the unused points in it, in its mean plane."""
    from scipy.spatial import Delaunay, QhullError

    verts = np.concatenate([loop, np.array(pts, np.int64)])
    normal = fc.normals[verts].sum(axis=0)
    length = np.linalg.norm(normal)
    if length == 0:
        return None
    normal = normal / length
    u, v = _tangent_basis(normal)
    rel = fc.points[verts] - fc.points[verts].mean(axis=0)
    xy = np.stack([rel @ u, rel @ v], axis=1)
    try:
        simplices = Delaunay(xy).simplices
    except (QhullError, ValueError):
        return None
    inside = _inside_polygon(xy[simplices].mean(axis=1), xy[: len(loop)])
    simplices = simplices[inside]
    tris = verts[simplices]
    # orient counter-clockwise around the normal
    a, b, c = (fc.points[tris[:, j]] for j in range(3))
    flip = np.einsum("ij,j->i", np.cross(b - a, c - a), normal) < 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    triangles, vt_off, vt = edges
    if not MK.fill_fits(
        np.ascontiguousarray(tris, dtype=np.int64),
        np.ascontiguousarray(loop, dtype=np.int64),
        triangles,
        vt_off,
        vt,
    ):
        return None
    return [tuple(int(x) for x in t) for t in tris]


def _star(fc: FanCloud, loop, p, edges):
    """Triangles (p, b, a) for every boundary half-edge a -> b, if p sees the loop as a star."""
    triangles, vt_off, vt = edges
    loop = np.ascontiguousarray(loop, dtype=np.int64)
    if not MK.star_fits(fc.points, fc.normals, loop, int(p), triangles, vt_off, vt):
        return None
    m = len(loop)
    return [(int(p), int(loop[(j + 1) % m]), int(loop[j])) for j in range(m)]
