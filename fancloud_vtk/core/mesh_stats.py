"""Counts that tell how good a triangle mesh is (paper section 4).

The mesh built from a fan cloud is judged by the figures the paper reports:
triangles per point (about 2 for a closed surface: a closed genus-0 mesh
has exactly ``2n - 4`` triangles), boundary loops (holes), edges with three
or more triangles (none, by construction), and the share of triangles that
fold back onto the surface (0.01 %). :func:`mesh_statistics` gives all of
them at once; :func:`boundary_loops` and :func:`self_intersecting_pairs`
give the loops and the intersecting pairs themselves.

Definitions used everywhere in this module
------------------------------------------
* A *half-edge* is an ordered vertex pair ``(t[k], t[(k + 1) % 3])`` of a
  triangle ``t``, numbered ``3 * triangle + k``; an *edge* is an unordered
  vertex pair.
* A triangle with a repeated vertex index (*collapsed*) has no edges: it is
  counted in ``triangles`` and ``degenerate_triangles``, its vertices are not
  ``unused_points``, and it is left out of everything else (edges, holes,
  manifoldness, orientation, components, Euler characteristic,
  self-intersections).
* A triangle is of *zero area* when ``|(b - a) x (c - a)| <= AREA_TOL * L**2``
  (``L`` its longest edge), i.e. its height is at most ``AREA_TOL * L``. It
  keeps its edges (it is part of the topology) but is left out of the
  self-intersection test, having no plane.
* Points with equal coordinates but different indices are different
  vertices; triangles that meet only at such points *touch*, which counts as
  an intersection. Merge duplicate points first (e.g. PyVista's
  ``clean()``).

Examples
--------
>>> import numpy as np
>>> points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
>>> tetra = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
>>> s = mesh_statistics(points, tetra)
>>> s["boundary_edges"], s["holes"], s["euler_characteristic"], s["self_intersections"]
(0, 0, 2, 0)
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from ._csr_kernels import csr_of
from ._fan_kernels import _plane_basis

__all__ = [
    "AREA_TOL",
    "INTERSECTION_TOL",
    "MeshInputError",
    "boundary_loops",
    "mesh_statistics",
    "self_intersecting_pairs",
]

#: a triangle is of zero area when its height is at most ``AREA_TOL`` times its longest edge
AREA_TOL = 1e-12

#: contact tolerance of the intersection test, relative to the longest edge of the pair
INTERSECTION_TOL = 1e-9

#: grid cell side, in mean triangle bounding-box extents
_CELL_FACTOR = 1.5

#: largest mean number of grid cells per triangle before the cells are made larger
_CELLS_PER_TRIANGLE = 6.0

#: cell coordinates are packed into 21 bits per axis of an int64 key
_AXIS_BITS = 21

#: a plain vertex's sectors are this wide and apart at least (pseudo-angle; radians at least)
_PLAIN_MARGIN = 1e-4

#: and its triangles' normals within acos(_PLAIN_TILT) (84 degrees) of their mean
_PLAIN_TILT = 0.1


class MeshInputError(ValueError):
    """The points or triangles given are not a valid triangle mesh."""


# ----------------------------------------------------------------------------- validation


def as_triangles(triangles, n_points: int | None) -> np.ndarray:
    """Return ``triangles`` as a new ``(m, 3)`` int64 array, checking indices."""
    try:
        arr = np.asarray(triangles)
    except Exception as exc:  # ragged lists and the like
        raise MeshInputError(f"triangles must be an (m, 3) integer array: {exc}") from exc
    if arr.dtype.kind not in "iu":
        if arr.size == 0 and arr.dtype.kind == "f":
            arr = arr.astype(np.int64)  # ``np.array([])`` and friends: no triangles
        else:
            raise MeshInputError(
                f"triangles must be an (m, 3) array of integer vertex indices, "
                f"got dtype {arr.dtype}"
            )
    if arr.size == 0 and arr.ndim < 2:
        arr = arr.reshape(0, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise MeshInputError(f"triangles must have shape (m, 3), got {arr.shape}")
    if 3 * arr.shape[0] >= 2**31 - 1:  # half-edges are numbered in 32 bits
        raise MeshInputError(f"too many triangles ({arr.shape[0]:,}; at most 715,827,881)")
    if arr.size:
        lo, hi = arr.min(), arr.max()
        if lo < 0:
            t = int(np.flatnonzero((arr < 0).any(axis=1))[0])
            raise MeshInputError(
                f"triangles contain a negative vertex index ({int(lo)}), "
                f"first in triangle {t}: {arr[t].tolist()}"
            )
        if n_points is not None and hi >= n_points:
            t = int(np.flatnonzero((arr >= n_points).any(axis=1))[0])
            raise MeshInputError(
                f"triangles contain vertex index {int(hi)} out of range for "
                f"{n_points} points, first in triangle {t}: {arr[t].tolist()}"
            )
        if hi > np.iinfo(np.int64).max // 4:
            raise MeshInputError(f"triangles contain a huge vertex index ({int(hi)})")
    return np.array(arr, dtype=np.int64, order="C", copy=True)


def _as_points(points) -> np.ndarray:
    """Return ``points`` as a new C-contiguous ``(n, 3)`` float64 array of finite values."""
    try:
        arr = np.asarray(points)
    except Exception as exc:
        raise MeshInputError(f"points must be an (n, 3) array of numbers: {exc}") from exc
    if arr.dtype.kind not in "iuf":
        raise MeshInputError(
            f"points must be an (n, 3) array of real numbers, got dtype {arr.dtype}"
        )
    if arr.size == 0 and arr.ndim < 2:
        arr = arr.reshape(0, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise MeshInputError(f"points must have shape (n, 3), got {arr.shape}")
    out = np.array(arr, dtype=np.float64, order="C", copy=True)
    finite = np.isfinite(out).all(axis=1)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise MeshInputError(
            f"points contain NaN or infinite coordinates at {bad.size} point(s), "
            f"first at index {int(bad[0])}: {arr[bad[0]].tolist()}"
        )
    return out


def _collapsed(tri: np.ndarray) -> np.ndarray:
    """Triangles with a repeated vertex index."""
    return (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 2] == tri[:, 0])


# ----------------------------------------------------------------------------- topology


@njit(cache=True)
def _edge_key(tri, h):
    """Lower and higher vertex of half-edge ``h``."""
    t = h // 3
    k = h % 3
    a = tri[t, k]
    b = tri[t, (k + 1) % 3]
    return min(a, b), max(a, b)


@njit(cache=True)
def _build_edges(tri, n):
    """Group the half-edges into edges; see :class:`_HalfEdges`.

    A counting sort on the lower vertex, then an insertion sort on the
    higher one inside each (small) bucket: edges come out in increasing
    ``(lo, hi)``, the half-edges of an edge in increasing number. Also
    returns the half-edges ordered by edge (``order``) and where each
    edge's start in it (``at``).
    """
    m = tri.shape[0]
    n_half = 3 * m
    start = np.zeros(n + 1, dtype=np.int64)
    for t in range(m):
        for k in range(3):
            start[min(tri[t, k], tri[t, (k + 1) % 3]) + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    # the half-edges by lower vertex (in increasing number), with their higher vertex
    order = np.empty(n_half, dtype=np.int32)  # 32 bits: half the memory (as_triangles
    high = np.empty(n_half, dtype=np.int32)  # bounds the half-edges below 2**31)
    fill = start[:n].copy()
    for t in range(m):
        for k in range(3):
            a = tri[t, k]
            b = tri[t, (k + 1) % 3]
            lo = min(a, b)
            at = fill[lo]
            order[at] = 3 * t + k
            high[at] = max(a, b)
            fill[lo] = at + 1
    edge = np.empty(n_half, dtype=np.int32)
    count = np.zeros(n_half, dtype=np.int32)
    first = np.empty(n_half, dtype=np.int32)
    at = np.empty(n_half + 1, dtype=np.int32)
    twin = np.full(n_half, -1, dtype=np.int32)
    n_edges = 0
    for v in range(n):
        s = start[v]
        for a in range(s + 1, start[v + 1]):  # stable insertion sort on the higher vertex
            x = order[a]
            hx = high[a]
            b = a - 1
            while b >= s and high[b] > hx:
                order[b + 1] = order[b]
                high[b + 1] = high[b]
                b -= 1
            order[b + 1] = x
            high[b + 1] = hx
        a = s
        while a < start[v + 1]:
            c = a + 1
            while c < start[v + 1] and high[c] == high[a]:
                c += 1
            for q in range(a, c):
                edge[order[q]] = n_edges
            count[n_edges] = c - a
            first[n_edges] = order[a]
            at[n_edges] = a
            if c - a == 2:
                twin[order[a]] = order[a + 1]
                twin[order[a + 1]] = order[a]
            n_edges += 1
            a = c
    at[n_edges] = n_half
    return (
        edge,
        count[:n_edges].copy(),
        first[:n_edges].copy(),
        twin,
        order,
        at[: n_edges + 1].copy(),
    )


@njit(cache=True)
def _find(parent, x):
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:
        parent[x], x = root, parent[x]
    return root


@njit(cache=True)
def _union(parent, a, b):
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra < rb:
        parent[rb] = ra
    elif rb < ra:
        parent[ra] = rb


@njit(cache=True)
def _components_kernel(m, edge, first):
    """Number of edge-connected components of ``m`` triangles."""
    parent = np.arange(m)
    for h in range(3 * m):
        _union(parent, h // 3, first[edge[h]] // 3)
    n = 0
    for t in range(m):
        if parent[t] == t:
            n += 1
    return n


@njit(cache=True)
def _corner_at(tri, h, v):
    """The corner (``3 * triangle + k``) of half-edge ``h``'s triangle at its vertex ``v``."""
    t = h // 3
    k = h % 3
    if tri[t, k] == v:
        return h
    return 3 * t + (k + 1) % 3


@njit(cache=True)
def _umbrella_kernel(tri, edge, first, n):
    """Number of umbrellas around each vertex; see :func:`_umbrellas`."""
    n_half = 3 * tri.shape[0]
    parent = np.arange(n_half)
    for h in range(n_half):
        g = first[edge[h]]
        if g == h:
            continue
        t = h // 3
        k = h % 3
        a = tri[t, k]
        b = tri[t, (k + 1) % 3]
        _union(parent, _corner_at(tri, h, a), _corner_at(tri, g, a))
        _union(parent, _corner_at(tri, h, b), _corner_at(tri, g, b))
    count = np.zeros(n, dtype=np.int64)
    for c in range(n_half):
        if parent[c] == c:
            count[tri[c // 3, c % 3]] += 1
    return count


@njit(cache=True, parallel=True)
def _inconsistent_kernel(tri, count, first, twin):
    """Edges of two triangles that run the same way in both."""
    n = 0
    for e in prange(count.size):
        if count[e] == 2:
            h = first[e]
            g = twin[h]
            if tri[h // 3, h % 3] == tri[g // 3, g % 3]:
                n += 1
    return n


@njit(cache=True, parallel=True)
def _duplicates_kernel(tri, edge, order, at):
    """Triangles whose vertices are those of a lower-numbered triangle.

    Such a triangle has the same first edge: only the triangles on that edge
    are compared.
    """
    n = 0
    for t in prange(tri.shape[0]):
        e = edge[3 * t]
        if at[e + 1] - at[e] < 2:
            continue
        a = tri[t, 0]
        b = tri[t, 1]
        c = tri[t, 2]
        for q in range(at[e], at[e + 1]):
            s = order[q] // 3
            if s >= t:
                break  # in increasing order
            x = tri[s, 0]
            y = tri[s, 1]
            z = tri[s, 2]
            if (
                (x == a or x == b or x == c)
                and (y == a or y == b or y == c)
                and (z == a or z == b or z == c)
            ):
                n += 1
                break
    return n


class _HalfEdges:
    """Half-edge structure of triangles without repeated indices.

    Attributes: ``tri`` the triangles; for each half-edge ``3 * triangle + k``
    (from ``tri[t, k]`` to ``tri[t, (k + 1) % 3]``) its ``edge`` id (edges
    numbered in increasing (lower, higher) vertex) and its ``twin``, the
    other half-edge of an edge with exactly two (else -1); for each edge its
    ``count`` of half-edges and its lowest-numbered half-edge ``first``;
    edge ``e``'s half-edges are ``order[at[e]:at[e + 1]]``.
    """

    def __init__(self, tri: np.ndarray) -> None:
        self.tri = tri
        n = int(tri.max()) + 1 if tri.size else 0
        self.edge, self.count, self.first, self.twin, self.order, self.at = _build_edges(tri, n)


def _components(he: _HalfEdges) -> int:
    """Number of edge-connected components of the triangles."""
    return int(_components_kernel(he.tri.shape[0], he.edge, he.first))


def _umbrellas(he: _HalfEdges, n: int) -> np.ndarray:
    """Number of umbrellas (edge-connected fans of triangles) around each vertex.

    Corner ``3 * t + k`` is triangle ``t`` at vertex ``tri[t, k]``; two corners
    at the same vertex are joined when their triangles share an edge from
    that vertex, whatever the number of triangles on that edge.
    """
    return _umbrella_kernel(he.tri, he.edge, he.first, n)


@njit(cache=True)
def _end_vertex(tri, bnd_half, x):
    """Vertex at end ``x`` of the boundary edges (``2 b`` its start, ``2 b + 1`` its end)."""
    h = bnd_half[x >> 1]
    t = h // 3
    k = h % 3
    if x & 1:
        return tri[t, (k + 1) % 3]
    return tri[t, k]


@njit(cache=True)
def _loop_kernel(tri, edge, count, twin, bnd_half):
    """Chain the boundary edges into loops; see :func:`boundary_loops`.

    Returns the loops' vertices one after another and the offsets of the loops.
    """
    m = tri.shape[0]
    nb = bnd_half.size
    bidx = np.full(3 * m, -1, dtype=np.int64)
    for b in range(nb):
        bidx[bnd_half[b]] = b
    mate = np.full(2 * nb, -1, dtype=np.int64)
    # 1. turn around the vertex through the end's own umbrella
    for x in range(2 * nb):
        if mate[x] != -1:
            continue
        v = _end_vertex(tri, bnd_half, x)
        e = bnd_half[x >> 1]
        found = -1
        for _ in range(3 * m + 1):
            t = e // 3
            j = e % 3
            if tri[t, j] == v:
                f = 3 * t + (j + 2) % 3
            else:
                f = 3 * t + (j + 1) % 3
            c = count[edge[f]]
            if c == 1:
                found = f
                break
            if c != 2:
                break  # a non-manifold edge: the umbrella is ambiguous
            e = twin[f]
        if found >= 0:
            bf = bidx[found]
            y = 2 * bf if tri[found // 3, found % 3] == v else 2 * bf + 1
            if y != x and mate[y] == -1:
                mate[x] = y
                mate[y] = x
    # 2. pair what is left at each vertex: ends arriving with ends leaving, in order
    free = np.flatnonzero(mate == -1)
    fv = np.empty(free.size, dtype=np.int64)
    for i in range(free.size):
        fv[i] = _end_vertex(tri, bnd_half, free[i])
    order = np.argsort(fv, kind="mergesort")  # stable: ends stay in increasing order
    i = 0
    while i < order.size:
        j = i
        while j < order.size and fv[order[j]] == fv[order[i]]:
            j += 1
        ins = np.empty(j - i, dtype=np.int64)
        outs = np.empty(j - i, dtype=np.int64)
        n_in = 0
        n_out = 0
        for q in range(i, j):
            x = free[order[q]]
            if x & 1:
                ins[n_in] = x
                n_in += 1
            else:
                outs[n_out] = x
                n_out += 1
        k = min(n_in, n_out)
        for q in range(k):
            mate[ins[q]] = outs[q]
            mate[outs[q]] = ins[q]
        rest = ins[k:n_in] if n_in > k else outs[k:n_out]
        for q in range(0, rest.size - 1, 2):
            mate[rest[q]] = rest[q + 1]
            mate[rest[q + 1]] = rest[q]
        i = j
    # 3. follow the pairs: open chains (from an unpaired end) first, then closed loops
    visited = np.zeros(nb, dtype=np.bool_)
    verts = np.empty(2 * nb + 1, dtype=np.int64)
    offsets = np.zeros(nb + 1, dtype=np.int64)
    nv = 0
    nl = 0
    for x in range(2 * nb):
        if mate[x] != -1 or visited[x >> 1]:
            continue
        cur = x
        verts[nv] = _end_vertex(tri, bnd_half, cur)
        nv += 1
        while True:
            visited[cur >> 1] = True
            other = cur ^ 1
            verts[nv] = _end_vertex(tri, bnd_half, other)
            nv += 1
            cur = mate[other]
            if cur == -1 or visited[cur >> 1]:
                break
        nl += 1
        offsets[nl] = nv
    for b in range(nb):
        if visited[b]:
            continue
        cur = 2 * b
        while True:
            visited[cur >> 1] = True
            verts[nv] = _end_vertex(tri, bnd_half, cur)
            nv += 1
            cur = mate[cur ^ 1]
            if cur == -1 or visited[cur >> 1]:
                break
        nl += 1
        offsets[nl] = nv
    return verts[:nv], offsets[: nl + 1]


def _loops(he: _HalfEdges) -> list[np.ndarray]:
    bnd_half = np.flatnonzero(he.count[he.edge] == 1)
    if bnd_half.size == 0:
        return []
    verts, offsets = _loop_kernel(he.tri, he.edge, he.count, he.twin, bnd_half)
    return [verts[a:b].copy() for a, b in zip(offsets[:-1], offsets[1:], strict=True)]


def boundary_loops(triangles) -> list[np.ndarray]:
    """Boundary loops of a triangle mesh, each as vertex indices in order.

    A boundary edge is an edge of exactly one triangle (triangles with a
    repeated vertex index are ignored). Each loop follows the direction of
    its boundary half-edges, i.e. turns the way the triangles next to it
    turn: in a patch whose triangles turn counter-clockwise seen from
    above, the outer loop turns counter-clockwise and a loop round a hole
    cut into the patch turns clockwise.

    Parameters
    ----------
    triangles : array_like
        ``(m, 3)`` integer vertex indices; not modified.

    Returns
    -------
    list of numpy.ndarray
        One int64 array per loop. A closed loop of ``k`` boundary edges has
        ``k`` vertices (the first is not repeated at the end); it starts at
        the start of its lowest-numbered boundary half-edge
        (``3 * triangle + k``) and follows that half-edge. An open chain
        (see Notes) of ``k`` edges has ``k + 1`` vertices. Open chains come
        first, then the closed loops, each group in increasing order of its
        lowest boundary half-edge.

    Raises
    ------
    MeshInputError
        If ``triangles`` is not an ``(m, 3)`` integer array of non-negative indices.

    Notes
    -----
    Where several loops pass through one vertex (a pinched vertex, e.g. the
    shared vertex of a bow-tie), each boundary edge arriving at the vertex
    is continued by the boundary edge reached by turning around the vertex
    through the triangles of its own umbrella (across edges with exactly
    two triangles), so the vertex is split umbrella by umbrella: the
    bow-tie has two loops of three vertices. When that turn fails (it meets
    an edge with three or more triangles) the ends left at the vertex are
    paired in increasing order of their half-edge number, an arriving end
    with a leaving one first, then the rest two by two; an end left
    unpaired (a vertex with an odd number of boundary edges) ends an open
    chain. Across inconsistently oriented triangles a loop keeps going and
    runs against some of its half-edges.

    Examples
    --------
    >>> import numpy as np
    >>> [loop.tolist() for loop in boundary_loops(np.array([[0, 1, 2], [0, 2, 3]]))]
    [[0, 1, 2, 3]]
    """
    tri = as_triangles(triangles, None)
    tri = tri[~_collapsed(tri)]
    if tri.size and tri.max() > 2 * tri.size + 1024:
        # sparse vertex numbers (there are no points to bound them): number them densely
        flat = tri.ravel()
        order = np.argsort(flat, kind="stable")
        new = np.ones(flat.size, dtype=bool)
        new[1:] = flat[order][1:] != flat[order][:-1]
        dense = np.empty(flat.size, dtype=np.int64)
        dense[order] = np.cumsum(new) - 1
        ids = flat[order][new]
        return [ids[loop] for loop in _loops(_HalfEdges(dense.reshape(-1, 3)))]
    return _loops(_HalfEdges(tri))


# ----------------------------------------------------------------------------- geometry


@njit(cache=True)
def _longest_edge_normal(points, tri, t):
    """(squared longest edge, cross product at the vertex facing it, its length).

    The cross product of the two edges at the vertex facing the longest
    edge: the most accurate normal of a thin triangle.
    """
    best = -1.0
    kb = 0
    for k in range(3):
        a = tri[t, (k + 1) % 3]
        b = tri[t, (k + 2) % 3]
        d2 = 0.0
        for c in range(3):
            d = points[b, c] - points[a, c]
            d2 += d * d
        if d2 > best:
            best = d2
            kb = k
    o = tri[t, kb]
    a = tri[t, (kb + 1) % 3]
    b = tri[t, (kb + 2) % 3]
    ux = points[a, 0] - points[o, 0]
    uy = points[a, 1] - points[o, 1]
    uz = points[a, 2] - points[o, 2]
    vx = points[b, 0] - points[o, 0]
    vy = points[b, 1] - points[o, 1]
    vz = points[b, 2] - points[o, 2]
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    nn = np.sqrt(nx * nx + ny * ny + nz * nz)
    return best, nx, ny, nz, nn


@njit(cache=True)
def _frame_arrays(m):
    """The arrays of :func:`_triangle_frames` for m triangles (normal, longest, lo, hi,
    flat)."""
    return (np.zeros((m, 3)), np.zeros(m), np.empty((m, 3)), np.empty((m, 3)),
            np.zeros(m, dtype=np.bool_))


@njit(cache=True)
def _frame_of(points, tri, area_tol, tol, t, normal, longest, lo, hi, flat):
    """Row t of :func:`_triangle_frames`, written into its arrays."""
    best, nx, ny, nz, nn = _longest_edge_normal(points, tri, t)
    length = np.sqrt(best)
    longest[t] = length
    if nn <= area_tol * best or nn == 0.0:
        flat[t] = True
    else:
        normal[t, 0] = nx / nn
        normal[t, 1] = ny / nn
        normal[t, 2] = nz / nn
    pad = 2.0 * tol * length
    for c in range(3):
        x0 = points[tri[t, 0], c]
        x1 = points[tri[t, 1], c]
        x2 = points[tri[t, 2], c]
        lo[t, c] = min(x0, x1, x2) - pad
        hi[t, c] = max(x0, x1, x2) + pad


@njit(cache=True, parallel=True)
def _triangle_frames(points, tri, area_tol, tol):
    """Unit normal, longest edge, inflated bounding box, zero-area flag per triangle.

    The normal is the cross product of the two edges at the vertex opposite
    the longest edge (the best-conditioned pair) and keeps the triangle's
    orientation. On all numba threads: for a whole mesh. A kernel that needs
    the frames of a few triangles, many times (per removal, per hole), calls
    :func:`few_triangle_frames` instead: a parallel launch from inside another
    kernel's parallel loop is a nested one, which costs far more than the work
    (it made the reduction of the cow's mesh take 23 s on two threads, 0.17 s on one).
    """
    normal, longest, lo, hi, flat = _frame_arrays(tri.shape[0])
    for t in prange(tri.shape[0]):
        _frame_of(points, tri, area_tol, tol, t, normal, longest, lo, hi, flat)
    return normal, longest, lo, hi, flat


@njit(cache=True)
def few_triangle_frames(points, tri, area_tol, tol):
    """:func:`_triangle_frames` on the calling thread (a few triangles, inside other
    kernels); the same arrays."""
    normal, longest, lo, hi, flat = _frame_arrays(tri.shape[0])
    for t in range(tri.shape[0]):
        _frame_of(points, tri, area_tol, tol, t, normal, longest, lo, hi, flat)
    return normal, longest, lo, hi, flat


@njit(cache=True, parallel=True)
def _flat_count(points, tri, area_tol):
    """Number of triangles of zero area, as ``flat`` of :func:`_triangle_frames`."""
    n = 0
    for t in prange(tri.shape[0]):
        best, nx, ny, nz, nn = _longest_edge_normal(points, tri, t)
        if nn <= area_tol * best or nn == 0.0:
            n += 1
    return n


@njit(cache=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True)
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True)
def _unit(a):
    n = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    if n == 0.0:
        return (0.0, 0.0, 0.0)
    return (a[0] / n, a[1] / n, a[2] / n)


@njit(cache=True)
def _point(points, i, origin):
    return (points[i, 0] - origin[0], points[i, 1] - origin[1], points[i, 2] - origin[2])


@njit(cache=True)
def _row(a, i):
    return (a[i, 0], a[i, 1], a[i, 2])


@njit(cache=True)
def _separates(axis, p0, p1, p2, q0, q1, q2, eps):
    """Do the projections on ``axis`` (unit) leave a gap wider than ``eps``?"""
    a0 = _dot(axis, p0)
    a1 = _dot(axis, p1)
    a2 = _dot(axis, p2)
    b0 = _dot(axis, q0)
    b1 = _dot(axis, q1)
    b2 = _dot(axis, q2)
    amin = min(a0, a1, a2)
    amax = max(a0, a1, a2)
    bmin = min(b0, b1, b2)
    bmax = max(b0, b1, b2)
    return bmin - amax > eps or amin - bmax > eps


@njit(cache=True)
def _unit_axis_separates(axis, p0, p1, p2, q0, q1, q2, eps):
    n = np.sqrt(_dot(axis, axis))
    if n == 0.0:
        return False  # parallel edges: no axis, and none is needed
    u = (axis[0] / n, axis[1] / n, axis[2] / n)
    return _separates(u, p0, p1, p2, q0, q1, q2, eps)


@njit(cache=True)
def _disjoint_intersect(p0, p1, p2, q0, q1, q2, n1, n2, eps):
    """Closed triangles without a shared vertex: do they come within ``eps``?

    Separating-axis test on the two normals, the nine edge-edge cross
    products and the six in-plane edge normals (which make it complete for
    coplanar triangles too). An axis separates only with a gap above
    ``eps``, so touching triangles intersect.
    """
    if _separates(n1, p0, p1, p2, q0, q1, q2, eps):
        return False
    if _separates(n2, p0, p1, p2, q0, q1, q2, eps):
        return False
    ep = (_sub(p1, p0), _sub(p2, p1), _sub(p0, p2))
    eq = (_sub(q1, q0), _sub(q2, q1), _sub(q0, q2))
    for i in range(3):
        for j in range(3):
            if _unit_axis_separates(_cross(ep[i], eq[j]), p0, p1, p2, q0, q1, q2, eps):
                return False
    for i in range(3):
        if _unit_axis_separates(_cross(n1, ep[i]), p0, p1, p2, q0, q1, q2, eps):
            return False
        if _unit_axis_separates(_cross(n2, eq[i]), p0, p1, p2, q0, q1, q2, eps):
            return False
    return True


@njit(cache=True)
def _in_cone(r, a, b, n, tau):
    """Is unit ray ``r`` in the closed cone of unit rays ``a``, ``b`` (turning about ``n``)?

    ``n`` is a unit normal with ``(a x b) . n > 0``; the cone's angle is below
    180 degrees. ``tau`` is the angular tolerance (radians).
    """
    if _dot(_cross(a, r), n) < -tau:
        return False
    if _dot(_cross(r, b), n) < -tau:
        return False
    return _dot(r, a) > 0.0 or _dot(r, b) > 0.0


@njit(cache=True)
def _vertex_pair_intersect(v, a, b, c, d, n1, n2, eps, tau):
    """Triangles ``(v, a, b)`` and ``(v, c, d)`` (only ``v`` shared): overlap beyond ``v``?

    ``n1``, ``n2``: the triangles' unit normals, oriented like ``(a - v) x (b - v)``
    and ``(c - v) x (d - v)``.
    """
    e1 = _sub(a, v)
    e2 = _sub(b, v)
    f1 = _sub(c, v)
    f2 = _sub(d, v)
    dc = _dot(n1, f1)
    dd = _dot(n1, f2)
    da = _dot(n2, e1)
    db = _dot(n2, e2)
    coplanar = (abs(dc) <= eps and abs(dd) <= eps) or (abs(da) <= eps and abs(db) <= eps)
    # one triangle strictly on one side of the other's plane: they meet only at v (the
    # common case, tested before the unit vectors are made)
    if not coplanar and ((dc > eps and dd > eps) or (dc < -eps and dd < -eps)
                         or (da > eps and db > eps) or (da < -eps and db < -eps)):
        return False
    u1 = _unit(e1)
    u2 = _unit(e2)
    w1 = _unit(f1)
    w2 = _unit(f2)
    if coplanar:
        # coplanar: do the two angular sectors at v overlap (or share a ray)?
        n = n1 if (abs(dc) <= eps and abs(dd) <= eps) else n2
        s1 = 1.0 if _dot(n1, n) > 0.0 else -1.0
        s2 = 1.0 if _dot(n2, n) > 0.0 else -1.0
        m1 = (s1 * n[0], s1 * n[1], s1 * n[2])
        m2 = (s2 * n[0], s2 * n[1], s2 * n[2])
        return (
            _in_cone(w1, u1, u2, m1, tau)
            or _in_cone(w2, u1, u2, m1, tau)
            or _in_cone(u1, w1, w2, m2, tau)
            or _in_cone(u2, w1, w2, m2, tau)
        )
    # both meet the line through v common to the planes: on the same side of v?
    u = _unit(_cross(n1, n2))
    if u[0] == 0.0 and u[1] == 0.0 and u[2] == 0.0:
        return False
    mu = (-u[0], -u[1], -u[2])
    if _in_cone(u, u1, u2, n1, tau) and _in_cone(u, w1, w2, n2, tau):
        return True
    return _in_cone(mu, u1, u2, n1, tau) and _in_cone(mu, w1, w2, n2, tau)


@njit(cache=True)
def _edge_pair_intersect(a, b, c, d, n1, n2, eps):
    """Triangles ``(a, b, c)`` and ``(a, b, d)`` sharing edge ``ab``: folded onto each other?

    They intersect beyond the edge only when coplanar (``d`` within ``eps``
    of the first plane or ``c`` within ``eps`` of the second) with ``c`` and
    ``d`` on the same side of the edge, ``d`` more than ``eps`` from the edge
    line in ``c``'s direction or the other way round.
    """
    if abs(_dot(n1, _sub(d, a))) > eps and abs(_dot(n2, _sub(c, a))) > eps:
        return False
    t = _unit(_sub(b, a))
    pc = _sub(c, a)
    pd = _sub(d, a)
    sc = _dot(pc, t)
    sd = _dot(pd, t)
    pc = (pc[0] - sc * t[0], pc[1] - sc * t[1], pc[2] - sc * t[2])
    pd = (pd[0] - sd * t[0], pd[1] - sd * t[1], pd[2] - sd * t[2])
    return _dot(pd, _unit(pc)) > eps or _dot(pc, _unit(pd)) > eps


@njit(cache=True)
def _boxes_apart(lo, hi, i, j):
    """Are the boxes ``i`` and ``j`` (rows of ``lo``, ``hi``) apart along some axis?"""
    return (
        lo[i, 0] > hi[j, 0]
        or lo[j, 0] > hi[i, 0]
        or lo[i, 1] > hi[j, 1]
        or lo[j, 1] > hi[i, 1]
        or lo[i, 2] > hi[j, 2]
        or lo[j, 2] > hi[i, 2]
    )


@njit(cache=True)
def _pair_intersects(points, tri, normal, longest, i, j, tol):
    """Do tested triangles ``i`` and ``j`` intersect (see :func:`self_intersecting_pairs`)?"""
    shared = 0
    si = -1
    sj = -1
    in_j = 0  # bit a: vertex a of i is a vertex of j
    for a in range(3):
        for b in range(3):
            if tri[i, a] == tri[j, b]:
                shared += 1
                si = a
                sj = b
                in_j |= 1 << a
    if shared == 3:
        return True  # the same triangle twice
    eps = tol * max(longest[i], longest[j])
    origin = _row(points, tri[i, 0])
    n1 = _row(normal, i)
    n2 = _row(normal, j)
    if shared == 0:
        return _disjoint_intersect(
            _point(points, tri[i, 0], origin),
            _point(points, tri[i, 1], origin),
            _point(points, tri[i, 2], origin),
            _point(points, tri[j, 0], origin),
            _point(points, tri[j, 1], origin),
            _point(points, tri[j, 2], origin),
            n1,
            n2,
            eps,
        )
    if shared == 1:
        return _vertex_pair_intersect(
            _point(points, tri[i, si], origin),
            _point(points, tri[i, (si + 1) % 3], origin),
            _point(points, tri[i, (si + 2) % 3], origin),
            _point(points, tri[j, (sj + 1) % 3], origin),
            _point(points, tri[j, (sj + 2) % 3], origin),
            n1,
            n2,
            eps,
            tol,
        )
    # shared == 2: the vertex of i not in j, and the vertex of j not in i
    ki = 0
    for a in range(3):
        if not (in_j >> a) & 1:
            ki = a
    kj = 0
    for b in range(3):
        if tri[j, b] != tri[i, 0] and tri[j, b] != tri[i, 1] and tri[j, b] != tri[i, 2]:
            kj = b
    return _edge_pair_intersect(
        _point(points, tri[i, (ki + 1) % 3], origin),
        _point(points, tri[i, (ki + 2) % 3], origin),
        _point(points, tri[i, ki], origin),
        _point(points, tri[j, kj], origin),
        n1,
        n2,
        eps,
    )


@njit(cache=True)
def _box_summary(lo, hi):
    """(low corner of all boxes, largest side of their union, mean largest box side)."""
    origin = np.empty(3)
    top = np.empty(3)
    for k in range(3):
        origin[k] = np.inf
        top[k] = -np.inf
    ext = 0.0
    for t in range(lo.shape[0]):
        e = 0.0
        for k in range(3):
            origin[k] = min(origin[k], lo[t, k])
            top[k] = max(top[k], hi[t, k])
            e = max(e, hi[t, k] - lo[t, k])
        ext += e
    span = max(top[0] - origin[0], top[1] - origin[1], top[2] - origin[2])
    return origin, span, ext / lo.shape[0]


@njit(cache=True, parallel=True)
def _cell_ranges(lo, hi, origin, h):
    """The grid cells (low and high corner) of every box, and how many cells it covers."""
    m = lo.shape[0]
    ilo = np.empty((m, 3), np.int64)
    ihi = np.empty((m, 3), np.int64)
    per = np.empty(m, np.int64)
    for t in prange(m):
        c = 1
        for k in range(3):
            ilo[t, k] = np.int64(np.floor((lo[t, k] - origin[k]) / h))
            ihi[t, k] = np.int64(np.floor((hi[t, k] - origin[k]) / h))
            c *= ihi[t, k] - ilo[t, k] + 1
        per[t] = c
    return ilo, ihi, per


@njit(cache=True, parallel=True)
def _grid_entries(ilo, ihi, offsets):
    """One (cell key, triangle) entry per grid cell a triangle's box overlaps."""
    m = ilo.shape[0]
    total = offsets[m]
    keys = np.empty(total, dtype=np.int64)
    tris = np.empty(total, dtype=np.int32)
    for t in prange(m):
        o = offsets[t]
        for z in range(ilo[t, 2], ihi[t, 2] + 1):
            for y in range(ilo[t, 1], ihi[t, 1] + 1):
                for x in range(ilo[t, 0], ihi[t, 0] + 1):
                    keys[o] = x | (y << 21) | (z << 42)
                    tris[o] = t
                    o += 1
    return keys, tris


@njit(cache=True)
def _number_cells(keys, size):
    """Number the distinct keys in order of first appearance with a hash table of ``size``
    slots (a power of 2); returns (cell per key, number of cells), or (None-like empty
    array, -1) when more than half the slots would fill."""
    m = keys.size
    mask = np.uint64(size - 1)
    limit = size // 2
    table = np.full(size, -1, np.int32)
    cell_key = np.empty(limit, np.int64)
    cell = np.empty(m, np.int32)
    n_cells = 0
    for a in range(m):
        key = keys[a]
        slot = ((np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(32)) & mask
        while True:
            c = table[slot]
            if c < 0:
                if n_cells == limit:
                    return cell[:0], -1
                table[slot] = n_cells
                cell_key[n_cells] = key
                cell[a] = n_cells
                n_cells += 1
                break
            if cell_key[c] == key:
                cell[a] = c
                break
            slot = (slot + np.uint64(1)) & mask
    return cell, n_cells


@njit(cache=True)
def _group_cells(keys):
    """Group equal keys: (each entry's place when the entries of a cell are put together,
    cell starts).

    A hash table numbers the cells in order of first appearance (no sort). It
    starts at about half the number of keys (cells hold several entries) and
    grows when more than half full.
    """
    m = keys.size
    size = 1024
    while size < m // 2:
        size *= 2
    while True:
        cell, n_cells = _number_cells(keys, size)
        if n_cells >= 0:
            break
        size *= 4
    cstart = np.zeros(n_cells + 1, np.int64)
    for a in range(m):
        cstart[cell[a] + 1] += 1
    for c in range(n_cells):
        cstart[c + 1] += cstart[c]
    fill = cstart[:-1].copy()
    pos = cell  # each entry's place in cell order (in place of its cell)
    for a in range(m):
        c = cell[a]
        pos[a] = fill[c]
        fill[c] += 1
    return pos, cstart


@njit(cache=True)
def _cell_pairs(points, tri, normal, longest, plain, blo, bhi, corner, tris, s, e, tol, out, pos):
    """Test the pairs of the cell of entries ``s:e`` whose box overlap starts in this cell.

    Pairs that share a plain vertex (:func:`_plain_vertices`) meet only there and
    are not tested. Writes the intersecting pairs into ``out`` from row ``pos``
    when ``out`` has rows; returns the number found.
    """
    found = 0
    for a in range(s, e):
        i = tris[a]
        for b in range(a + 1, e):
            # each pair is tested once: in the cell holding the low corner of the
            # overlap of the boxes (on each axis, one of the two starts in this cell)
            if corner[a] | corner[b] != 7:
                continue
            if (
                blo[a, 0] > bhi[b, 0]
                or blo[b, 0] > bhi[a, 0]
                or blo[a, 1] > bhi[b, 1]
                or blo[b, 1] > bhi[a, 1]
                or blo[a, 2] > bhi[b, 2]
                or blo[b, 2] > bhi[a, 2]
            ):
                continue
            j = tris[b]
            skip = False
            for x in range(3):
                v = tri[i, x]
                if plain[v] and (v == tri[j, 0] or v == tri[j, 1] or v == tri[j, 2]):
                    skip = True
            if skip:
                continue
            if _pair_intersects(points, tri, normal, longest, i, j, tol):
                if out.shape[0]:
                    out[pos + found, 0] = min(i, j)
                    out[pos + found, 1] = max(i, j)
                found += 1
    return found


@njit(cache=True, parallel=True)
def _count_hits(points, tri, normal, longest, plain, blo, bhi, corner, tris, cstart, tol):
    n_cells = cstart.size - 1
    hits = np.zeros(n_cells, dtype=np.int64)
    none = np.empty((0, 2), dtype=np.int64)
    for c in prange(n_cells):
        hits[c] = _cell_pairs(points, tri, normal, longest, plain, blo, bhi, corner, tris,
                              cstart[c], cstart[c + 1], tol, none, 0)
    return hits


@njit(cache=True)
def _collect_hits(points, tri, normal, longest, plain, blo, bhi, corner, tris, cstart, tol, hits):
    offsets = np.zeros(hits.size + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(hits)
    out = np.empty((offsets[-1], 2), dtype=np.int64)
    for c in range(hits.size):
        if hits[c]:
            _cell_pairs(points, tri, normal, longest, plain, blo, bhi, corner, tris,
                        cstart[c], cstart[c + 1], tol, out, offsets[c])
    return out


@njit(cache=True)
def _pseudo_angle(x, y):
    """A cheap increasing function of the angle of ``(x, y)``, in ``[0, 4)``.

    Its derivative with respect to the angle lies between 1/2 and 1, and it
    grows by 2 from a direction to its opposite.
    """
    if y >= 0.0:
        if x >= 0.0:
            s = x + y
            return y / s if s > 0.0 else 0.0
        return 1.0 - x / (y - x)
    if x < 0.0:
        return 2.0 - y / (-x - y)
    return 3.0 + x / (x - y)


@njit(cache=True)
def _plain_vertex(points, tri, normal, at, s, e, v, margin, tilt, start, end, first, last):
    """Is vertex ``v`` (its triangles ``at[s:e]``) plain? See :func:`_plain_vertices`."""
    k = e - s
    if k == 1:
        return True
    if k > start.size:
        return False
    dx = 0.0
    dy = 0.0
    dz = 0.0
    for a in range(s, e):
        t = at[a]
        dx += normal[t, 0]
        dy += normal[t, 1]
        dz += normal[t, 2]
    dn = np.sqrt(dx * dx + dy * dy + dz * dz)
    if dn < 1e-6:
        return False
    dx /= dn
    dy /= dn
    dz /= dn
    for a in range(s, e):
        t = at[a]
        if normal[t, 0] * dx + normal[t, 1] * dy + normal[t, 2] * dz < tilt:
            return False
    ex, ey, ez, fx, fy, fz = _plane_basis(dx, dy, dz)  # e x f = d
    for a in range(k):
        t = at[s + a]
        c = 0 if tri[t, 0] == v else (1 if tri[t, 1] == v else 2)
        p = tri[t, (c + 1) % 3]
        q = tri[t, (c + 2) % 3]
        px = points[p, 0] - points[v, 0]
        py = points[p, 1] - points[v, 1]
        pz = points[p, 2] - points[v, 2]
        qx = points[q, 0] - points[v, 0]
        qy = points[q, 1] - points[v, 1]
        qz = points[q, 2] - points[v, 2]
        x0 = _pseudo_angle(px * ex + py * ey + pz * ez, px * fx + py * fy + pz * fz)
        x1 = _pseudo_angle(qx * ex + qy * ey + qz * ez, qx * fx + qy * fy + qz * fz)
        # sectors by their start (insertion sort)
        b = a - 1
        while b >= 0 and start[b] > x0:
            start[b + 1] = start[b]
            end[b + 1] = end[b]
            first[b + 1] = first[b]
            last[b + 1] = last[b]
            b -= 1
        start[b + 1] = x0
        end[b + 1] = x1
        first[b + 1] = p
        last[b + 1] = q
    total = 0.0
    for a in range(k):
        width = end[a] - start[a]
        if width < 0.0:
            width += 4.0
        if width < margin or width > 2.0 - margin:
            return False
        nxt = (a + 1) % k
        gap = start[nxt] - end[a]
        if gap < 0.0:
            gap += 4.0
        if last[a] == first[nxt]:
            if gap != 0.0:
                return False
        elif gap < margin:
            return False
        total += width + gap
    return abs(total - 4.0) < 1e-6


@njit(cache=True, parallel=True)
def _plain_vertices(points, tri, normal, n_points, margin, tilt, chunks):
    """Vertices whose triangles' pairs meet only at them (an exact shortcut of the test).

    A vertex is *plain* when its triangles, projected along the mean of their
    unit normals ``d``, cover disjoint angular sectors about it: every normal
    within ``acos(tilt)`` of ``d``, every sector at least ``margin`` wide,
    consecutive sectors either sharing their edge or ``margin`` apart, and
    once round in all (angles as :func:`_pseudo_angle`, which never widens
    one). Two such triangles then meet only at the vertex (or along their
    shared edge, without folding), far from the tolerances of
    :func:`_pair_intersects`, which would find no intersection either.
    """
    off, at = csr_of(tri, n_points)  # the triangles at each vertex
    plain = np.zeros(n_points, np.bool_)
    step = (n_points + chunks - 1) // chunks
    for c in prange(chunks):
        start = np.empty(64)
        end = np.empty(64)
        first = np.empty(64, np.int64)
        last = np.empty(64, np.int64)
        for v in range(c * step, min(n_points, (c + 1) * step)):
            if off[v + 1] > off[v]:
                plain[v] = _plain_vertex(points, tri, normal, at, off[v], off[v + 1], v,
                                         margin, tilt, start, end, first, last)
    return plain


@njit(cache=True, parallel=True)
def _entry_boxes(lo, hi, ilo, keys, tris, pos):
    """The grid entries put in their places ``pos``, with their triangle's box and corner.

    Returns (triangles, boxes' low and high corners in float32 rounded
    outwards, corner bits): bit ``k`` says that the box starts in the
    entry's cell along axis ``k``.
    """
    m = pos.size
    sorted_tris = np.empty(m, np.int32)
    blo = np.empty((m, 3), np.float32)
    bhi = np.empty((m, 3), np.float32)
    corner = np.empty(m, np.uint8)
    for a in prange(m):
        t = tris[a]
        key = keys[a]
        d = pos[a]
        sorted_tris[d] = t
        cell = (key & 0x1FFFFF, (key >> 21) & 0x1FFFFF, key >> 42)
        bits = 0
        for k in range(3):
            x = np.float32(lo[t, k])
            if x > lo[t, k]:
                x = np.nextafter(x, np.float32(-np.inf))
            blo[d, k] = x
            y = np.float32(hi[t, k])
            if y < hi[t, k]:
                y = np.nextafter(y, np.float32(np.inf))
            bhi[d, k] = y
            if ilo[t, k] == cell[k]:
                bits |= 1 << k
        corner[d] = bits
    return sorted_tris, blo, bhi, corner


def _intersecting_pairs(points: np.ndarray, tri: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Pairs among the triangles ``tri[keep]`` (no repeated index), as original indices."""
    ids = np.flatnonzero(keep)
    sub = tri[ids]
    if sub.shape[0] < 2:
        return np.empty((0, 2), dtype=np.int64)
    normal, longest, lo, hi, flat = _triangle_frames(points, sub, AREA_TOL, INTERSECTION_TOL)
    if flat.any():
        ids = ids[~flat]
        sub, normal, longest, lo, hi = (a[~flat] for a in (sub, normal, longest, lo, hi))
        if sub.shape[0] < 2:
            return np.empty((0, 2), dtype=np.int64)
    # uniform grid of cubic cells; each triangle listed in every cell its box overlaps
    origin, span, extent = _box_summary(lo, hi)
    h = _CELL_FACTOR * extent
    h = max(h, span / ((1 << _AXIS_BITS) - 2), np.finfo(float).tiny)
    while True:
        ilo, ihi, per = _cell_ranges(lo, hi, origin, h)
        if per.sum() <= _CELLS_PER_TRIANGLE * per.size or per.max() == 1:
            break
        h *= 1.5
    offsets = np.zeros(per.size + 1, dtype=np.int64)
    np.cumsum(per, out=offsets[1:])
    if offsets[-1] >= 2**31 - 1:
        raise MeshInputError(f"too many triangles to test for intersections ({len(sub):,})")
    keys, tris = _grid_entries(ilo, ihi, offsets)
    pos, cstart = _group_cells(keys)
    tris, blo, bhi, corner = _entry_boxes(lo, hi, ilo, keys, tris, pos)
    del keys, pos
    plain = _plain_vertices(points, sub, normal, points.shape[0], _PLAIN_MARGIN, _PLAIN_TILT,
                            8 * get_num_threads())
    args = (points, sub, normal, longest, plain, blo, bhi, corner, tris, cstart, INTERSECTION_TOL)
    hits = _count_hits(*args)
    local = _collect_hits(*args, hits)
    pairs = ids[local]  # each pair once, i < j (ids increase)
    key = pairs[:, 0] * tri.shape[0] + pairs[:, 1]
    return pairs[np.argsort(key)].reshape(-1, 2)


def self_intersecting_pairs(points, triangles) -> np.ndarray:
    """Pairs of triangles that intersect each other.

    Which pairs intersect, with ``eps = INTERSECTION_TOL * L`` and ``L`` the
    longest edge of the two triangles (triangles are closed sets):

    * sharing no vertex index: they have a point in common, or come within
      ``eps`` of each other (touching counts). The test is a
      separating-axis test (the two normals, the nine edge-edge cross
      products and the six in-plane edge normals); an axis separates only
      with a gap above ``eps``, which also settles coplanar pairs.
    * sharing exactly one vertex ``v``: they have a point other than ``v``
      in common (e.g. an edge of one crosses the other, or they overlap in
      a common plane). If the two other vertices of one triangle are within
      ``eps`` of the other's plane, the pair is coplanar and intersects when
      the angular sectors of the triangles at ``v`` overlap or share a ray;
      otherwise when both triangles reach, on the same side of ``v``, the
      line through ``v`` common to both planes. Angles within
      ``INTERSECTION_TOL`` radians count as touching.
    * sharing an edge: they fold onto each other, i.e. dihedral angle 0: the
      two opposite vertices lie on the same side of the edge and one of them
      is within ``eps`` of the other triangle's plane (and farther than
      ``eps`` from the edge's line). Non-coplanar triangles sharing an edge
      meet only along it.
    * sharing all three vertices (the same triangle twice): always.

    Triangles with a repeated vertex index or zero area (height at most
    ``AREA_TOL`` times the longest edge) are not tested: they have no plane
    (``mesh_statistics`` counts them as degenerate). Vertices with the same
    coordinates but different indices are not shared: triangles meeting at
    them touch, and intersect.

    Candidate pairs come from a uniform grid of cubic cells (side 1.5 mean
    triangle bounding-box extents, made larger when the boxes would fill
    more than 6 cells per triangle on average): each triangle is listed in
    the cells its box overlaps, and a pair is tested once, in the cell
    holding the low corner of the overlap of the boxes. The tests run in
    parallel over the cells. A pair sharing a *plain* vertex is not tested:
    one whose triangles, projected along the mean of their normals (each
    within 84 degrees of it), cover disjoint angular sectors around it, each
    at least ``1e-4`` wide and apart unless they share an edge, once round
    in all. Such triangles meet only at the vertex, or along their shared
    edge unfolded, far from the tolerances above, and the test would find
    no intersection (the result is the same; on a smooth mesh almost every
    vertex is plain, and almost every pair tested shares one).

    Parameters
    ----------
    points : array_like
        ``(n, 3)`` finite coordinates; not modified.
    triangles : array_like
        ``(m, 3)`` integer indices into ``points``; not modified.

    Returns
    -------
    numpy.ndarray
        ``(k, 2)`` int64 triangle indices ``i < j``, rows in increasing order.

    Raises
    ------
    MeshInputError
        If the points are not ``(n, 3)`` finite numbers or the triangles not
        ``(m, 3)`` integer indices in range.

    Examples
    --------
    >>> import numpy as np
    >>> points = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0],
    ...                    [0.5, 0.5, -1], [0.5, 0.5, 1], [3, 3, 0]], float)
    >>> self_intersecting_pairs(points, [[0, 1, 2], [3, 4, 5]]).tolist()
    [[0, 1]]
    """
    pts = _as_points(points)
    tri = as_triangles(triangles, pts.shape[0])
    return _intersecting_pairs(pts, tri, ~_collapsed(tri))


# ----------------------------------------------------------------------------- all counts


def _distinct_rows(rows: np.ndarray) -> int:
    """Number of distinct rows of a non-negative ``(m, 3)`` int64 array."""
    span = int(rows.max()) + 1
    if span < 2_000_000:  # span**3 fits in an int64 key
        key = np.sort((rows[:, 0] * span + rows[:, 1]) * span + rows[:, 2])
        return int(1 + np.count_nonzero(key[1:] != key[:-1]))
    order = np.lexsort(rows.T[::-1])
    s = rows[order]
    return int(1 + np.count_nonzero((s[1:] != s[:-1]).any(axis=1)))


def mesh_statistics(points, triangles, *, self_intersections: bool = True) -> dict:
    """Counts that describe a triangle mesh's quality and topology.

    Parameters
    ----------
    points : array_like
        ``(n, 3)`` finite coordinates; not modified.
    triangles : array_like
        ``(m, 3)`` integer indices into ``points``; not modified.
    self_intersections : bool, default: True
        Count the intersecting triangle pairs (the slowest count); when
        False the count is reported as -1.

    Returns
    -------
    dict
        Integers unless said otherwise:

        ``points``, ``triangles``
            ``n`` and ``m``.
        ``unused_points``
            points in no triangle.
        ``edges``
            distinct unordered vertex pairs of the triangles.
        ``boundary_edges``
            edges of exactly one triangle.
        ``holes``
            boundary loops, as listed by :func:`boundary_loops`.
        ``non_manifold_edges``
            edges of three or more triangles.
        ``non_manifold_vertices``
            vertices with more than one umbrella: their triangles do not
            form one fan (disk or half-disk) connected across edges from
            the vertex. An edge with three or more triangles connects its
            triangles, so it does not by itself split the vertex.
        ``inconsistent_edges``
            edges of exactly two triangles that run in the same direction
            in both (inconsistent orientation).
        ``degenerate_triangles``
            triangles with a repeated vertex index or zero area (height at
            most ``AREA_TOL`` times the longest edge).
        ``duplicate_triangles``
            triangles whose sorted vertex indices equal those of an earlier
            triangle (a triangle present three times counts 2).
        ``self_intersections``
            intersecting triangle pairs, as listed by
            :func:`self_intersecting_pairs`; -1 when not computed.
        ``components``
            edge-connected components of the triangles.
        ``euler_characteristic``
            ``V - E + F`` with ``V`` the vertices used by the triangles.
        ``triangles_per_point`` (float)
            ``m / n`` (0.0 without points).

        Triangles with a repeated vertex index count only in
        ``triangles`` and ``degenerate_triangles`` (and make their
        vertices used); they have no edges.

    Raises
    ------
    MeshInputError
        If the points are not ``(n, 3)`` finite numbers or the triangles not
        ``(m, 3)`` integer indices in range.

    See Also
    --------
    boundary_loops, self_intersecting_pairs

    Examples
    --------
    >>> import numpy as np
    >>> points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    >>> s = mesh_statistics(points, [[0, 1, 2], [0, 2, 3]])
    >>> s["boundary_edges"], s["holes"], s["euler_characteristic"]
    (4, 1, 1)
    """
    pts = _as_points(points)
    tri = as_triangles(triangles, pts.shape[0])
    n = pts.shape[0]
    m = tri.shape[0]
    collapsed = _collapsed(tri)
    good = tri[~collapsed]
    he = _HalfEdges(good)

    used_any = np.zeros(n, dtype=bool)
    used_any[tri.ravel()] = True
    used = np.zeros(n, dtype=bool)
    used[good.ravel()] = True

    count = he.count
    inconsistent = int(_inconsistent_kernel(good, count, he.first, he.twin))

    if m:
        # a collapsed triangle is flat too (zero cross product)
        degenerate = int(_flat_count(pts, tri, AREA_TOL))
        duplicates = int(_duplicates_kernel(good, he.edge, he.order, he.at))
        bad = tri[collapsed]
        if bad.shape[0]:  # a collapsed triangle can only repeat a collapsed one
            duplicates += bad.shape[0] - _distinct_rows(np.sort(bad, axis=1))
    else:
        degenerate = duplicates = 0

    n_edges = int(count.size)
    if self_intersections:
        n_cross = int(_intersecting_pairs(pts, tri, ~collapsed).shape[0])
    else:
        n_cross = -1
    umbrellas = _umbrellas(he, n)
    return {
        "points": int(n),
        "triangles": int(m),
        "unused_points": int(n - np.count_nonzero(used_any)),
        "edges": n_edges,
        "boundary_edges": int(np.count_nonzero(count == 1)),
        "holes": len(_loops(he)),
        "non_manifold_edges": int(np.count_nonzero(count >= 3)),
        "non_manifold_vertices": int(np.count_nonzero(umbrellas > 1)),
        "inconsistent_edges": inconsistent,
        "degenerate_triangles": degenerate,
        "duplicate_triangles": int(duplicates),
        "self_intersections": n_cross,
        "components": _components(he),
        "euler_characteristic": int(np.count_nonzero(used)) - n_edges + int(good.shape[0]),
        "triangles_per_point": float(m / n) if n else 0.0,
    }
