"""Numba kernels of the triangle mesh from a fan cloud (paper section 4).

:mod:`fancloud_vtk.core.mesh` drives them. Triangles are rows of vertex
indices; an undirected edge ``(u, v)`` with ``u < v`` is packed as
``u * n + v`` and numbered by its rank among the sorted packed edges.

The primitives other stages share are beside it, by concept: geometry
(:mod:`._geometry_kernels`), rings (:mod:`._ring_kernels`, the Delaunay rings
too), CSR tables (:mod:`._csr_kernels`), the edge table (:mod:`._edge_kernels`)
and the heap (:mod:`._heap_kernels`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._csr_kernels import csr_of, csr_of_some
from ._edge_kernels import has_edge
from ._geometry_kernels import (
    atan2_2pi,
    in_plane,
    min_angle_cos,
    opposite,
    tangent,
    tangent_frames,
    triangle_cross,
)


@njit(cache=True)
def _triangle_on(tri, edge_off, edge_tri, v_edge_off, v_edges, edge_uv, u, v, x):
    """The candidate triangle with vertices u, v, x (through the edge u-v), or -1."""
    e = -1
    for i in range(v_edge_off[u], v_edge_off[u + 1]):
        f = v_edges[i]
        if edge_uv[f, 0] + edge_uv[f, 1] - u == v:
            e = f
            break
    if e < 0:
        return -1
    for i in range(edge_off[e], edge_off[e + 1]):
        t = edge_tri[i]
        if tri[t, 0] == x or tri[t, 1] == x or tri[t, 2] == x:
            return t
    return -1


@njit(cache=True)
def _quads_at(points, normals, tri, edge_uv, edge_off, edge_tri, v_edge_off, v_edges, e, out, row):
    """The doubly covered quads on edge e (see :func:`find_quads`); written from ``row`` on
    when ``out`` has rows, else only counted. Returns their number."""
    x = edge_uv[e, 0]
    y = edge_uv[e, 1]
    c = 0
    for i in range(edge_off[e], edge_off[e + 1]):
        t1 = edge_tri[i]
        u = tri[t1, 0] + tri[t1, 1] + tri[t1, 2] - x - y
        for j in range(i + 1, edge_off[e + 1]):
            t2 = edge_tri[j]
            v = tri[t2, 0] + tri[t2, 1] + tri[t2, 2] - x - y
            if u == v or not opposite(points, normals, x, y, u, v):
                continue
            t3 = _triangle_on(tri, edge_off, edge_tri, v_edge_off, v_edges, edge_uv, u, v, x)
            t4 = _triangle_on(tri, edge_off, edge_tri, v_edge_off, v_edges, edge_uv, u, v, y)
            if t3 < 0 and t4 < 0:
                continue
            if out.shape[0] > 0:
                out[row + c, 0] = t1
                out[row + c, 1] = t2
                out[row + c, 2] = t3
                out[row + c, 3] = t4
            c += 1
    return c


@njit(cache=True, parallel=True)
def find_quads(points, normals, tri, edge_uv, edge_off, edge_tri, v_edge_off, v_edges):
    """Quadrilaterals covered by both diagonals' triangulations.

    For every edge (x, y) with two triangles x y u and x y v on it, the
    triangles u v x and u v y of the other diagonal are looked up through
    the edge u-v. Returns rows ``(t_xyu, t_xyv, t_uvx, t_uvy)`` with -1 for a
    missing triangle, for every quad where at least one of the other
    diagonal's triangles exists, and u and v lie on opposite sides of x y
    (a real quadrilateral, not two triangles folded onto each other); in
    order of the edge x-y.
    """
    n_edges = edge_uv.shape[0]
    per = np.zeros(n_edges + 1, np.int64)
    none = np.empty((0, 4), np.int64)
    for e in prange(n_edges):
        per[e + 1] = _quads_at(
            points, normals, tri, edge_uv, edge_off, edge_tri, v_edge_off, v_edges, e, none, 0
        )
    for e in range(n_edges):
        per[e + 1] += per[e]
    out = np.empty((per[n_edges], 4), np.int64)
    for e in prange(n_edges):
        if per[e + 1] > per[e]:
            _quads_at(
                points,
                normals,
                tri,
                edge_uv,
                edge_off,
                edge_tri,
                v_edge_off,
                v_edges,
                e,
                out,
                per[e],
            )
    return out


@njit(cache=True, parallel=True)
def min_angles(points, tri):
    """Smallest angle of every triangle in degrees (0 for a degenerate one)."""
    m = tri.shape[0]
    out = np.empty(m)
    for t in prange(m):
        cs = min_angle_cos(points, tri[t, 0], tri[t, 1], tri[t, 2])
        out[t] = np.degrees(np.arccos(min(max(cs, -1.0), 1.0)))
    return out


@njit(cache=True)
def resolve_quads(quads, count, quality, alive, partial):
    """Keep one triangulation of each doubly covered quadrilateral (``alive`` updated).

    A diagonal whose two triangles both exist beats one with a single
    triangle; between two complete diagonals, the one more fans agree on
    (summed counts) wins, then the better-shaped one (larger smallest
    angle). Quads are visited in order; one whose triangles were already
    removed by an earlier decision is re-evaluated with what is left.
    Returns the number of triangles removed.
    """
    removed = 0
    for r in range(quads.shape[0]):
        a1 = quads[r, 0]
        a2 = quads[r, 1]
        b1 = quads[r, 2]
        b2 = quads[r, 3]
        a_full = alive[a1] and alive[a2]
        b_has1 = b1 >= 0 and alive[b1]
        b_has2 = b2 >= 0 and alive[b2]
        if not (b_has1 or b_has2):
            continue
        if not a_full:
            continue  # the first diagonal already lost a triangle: nothing doubly covered
        b_full = b_has1 and b_has2
        if not b_full and not partial:
            continue
        keep_a = True
        if b_full:
            sa = count[a1] + count[a2]
            sb = count[b1] + count[b2]
            if sb > sa:
                keep_a = False
            elif sb == sa:
                qa = min(quality[a1], quality[a2])
                qb = min(quality[b1], quality[b2])
                if qb > qa:
                    keep_a = False
        if keep_a:
            if b_has1:
                alive[b1] = False
                removed += 1
            if b_has2:
                alive[b2] = False
                removed += 1
        else:
            alive[a1] = False
            alive[a2] = False
            removed += 2
    return removed


# -- growing a 2-manifold ---------------------------------------------------


@njit(cache=True)
def _angle_at(points, frames, v, w):
    """Angle of w around v in v's tangent plane, in [0, 2 pi) (the fast polynomial atan2)."""
    dx = points[w, 0] - points[v, 0]
    dy = points[w, 1] - points[v, 1]
    dz = points[w, 2] - points[v, 2]
    return atan2_2pi(
        dx * frames[v, 3] + dy * frames[v, 4] + dz * frames[v, 5],
        dx * frames[v, 0] + dy * frames[v, 1] + dz * frames[v, 2],
    )


@njit(cache=True)
def _wrap(d):
    """A difference of two angles in [0, 2 pi), taken into [0, 2 pi) (as ``d % (2 pi)``)."""
    return d + 2.0 * np.pi if d < 0.0 else d


@njit(cache=True)
def _in_gap(points, frames, v, a, b, v_edge_off, v_edges, edge_uv, edge_used, edge_fwd, wi, wa):
    """Whether the corner (v, a, b) lies in a gap of the triangles around v.

    Seen along v's normal, a gap runs counter-clockwise from a boundary edge
    entering v to the next boundary edge leaving it. The corner, from a to
    b counter-clockwise, must fit in one (touching its ends is fine).
    ``wi`` (2, 8) int and ``wa`` (2, 8) float are scratch.
    """
    two_pi = 2.0 * np.pi
    w_in = wi[0]
    w_out = wi[1]
    a_in = wa[0]
    a_out = wa[1]
    n_in = 0
    n_out = 0
    for i in range(v_edge_off[v], v_edge_off[v + 1]):
        e = v_edges[i]
        if edge_used[e] != 1:
            continue
        w = edge_uv[e, 1] if edge_uv[e, 0] == v else edge_uv[e, 0]
        if (edge_uv[e, 0] == v) == (edge_fwd[e] == 1):  # the mesh runs v -> w: leaving
            if n_out == 8:
                return True  # a crowded vertex: leave it to the edge checks
            w_out[n_out] = w
            a_out[n_out] = _angle_at(points, frames, v, w)
            n_out += 1
        else:
            if n_in == 8:
                return True
            w_in[n_in] = w
            a_in[n_in] = _angle_at(points, frames, v, w)
            n_in += 1
    if n_in == 0 or n_out == 0:
        return True  # no gap: the edge checks decide
    ang_a = _angle_at(points, frames, v, a)
    ang_b = _angle_at(points, frames, v, b)
    for k in range(n_in):
        base = a_in[k]
        # the gap ends at the first leaving boundary edge counter-clockwise
        dout = two_pi
        end = -1
        for q in range(n_out):
            d = two_pi if w_out[q] == w_in[k] else _wrap(a_out[q] - base)
            if d <= dout:
                dout = d
                end = w_out[q]
        if a == w_in[k] and b == end:
            return True  # it closes the gap
        da = 0.0 if a == w_in[k] else _wrap(ang_a - base)
        db = dout if b == end else _wrap(ang_b - base)
        if da < db <= dout:
            return True
    return False


@njit(cache=True)
def _try_add(
    t,
    tri,
    tri_edge,
    edge_uv,
    edge_used,
    edge_fwd,
    v_count,
    v_bnd,
    pinch,
    flip,
    points,
    frames,
    v_edge_off,
    v_edges,
    wi,
    wa,
):
    """Whether triangle t can join the mesh, and with which orientation.

    ``tri[t]`` is its preferred orientation; ``edge_fwd[e]`` is 1 when the
    accepted triangle on edge e runs from its smaller to its larger vertex.
    Returns 0 (no), 1 (as it is) or 2 (reversed; only with ``flip``: the
    candidates are oriented by consistent normals, so a triangle that would
    have to turn over to fit folds onto the mesh). Conditions: no edge gets a
    third triangle; every edge shared with the mesh is run in the opposite
    direction (consistent orientation); every vertex already in the mesh is
    reached through an edge already in the mesh (else it would get a second
    fan of triangles: a non-manifold vertex). With ``pinch``, a vertex on
    the mesh boundary may also be touched by a corner only, when the
    triangle shares an edge elsewhere and lies in the vertex's gap (seen
    along its normal): two fronts meeting at a vertex, whose gap the
    following triangles usually fill (what they leave is cut off afterwards,
    see :func:`split_pinched`).
    """
    want = 0  # 0 undecided, 1 as is, 2 reversed
    for j in range(3):
        e = tri_edge[t, j]
        if edge_used[e] >= 2:
            return 0
        if edge_used[e] == 1:
            a = tri[t, j]
            fwd_here = a == edge_uv[e, 0]  # this triangle as is runs u -> v
            # consistent: the new triangle must run the edge the other way
            need = 2 if fwd_here == (edge_fwd[e] == 1) else 1
            if need == 2 and not flip:
                return 0  # it would have to turn over: it folds onto the mesh
            if want == 0:
                want = need
            elif want != need:
                return 0
    for j in range(3):
        v = tri[t, j]
        if v_count[v] == 0:
            continue
        e_in = tri_edge[t, (j + 2) % 3]  # edge (prev, v)
        e_out = tri_edge[t, j]  # edge (v, next)
        if edge_used[e_in] == 0 and edge_used[e_out] == 0:
            if not (pinch and want != 0 and v_bnd[v] > 0):
                return 0
        # the corner at v must lie in the gap of v's triangles (no overlap)
        if v_bnd[v] == 2 and edge_used[e_in] == 1 and edge_used[e_out] == 1:
            continue  # it fills v's one gap, between its two boundary edges
        if v_bnd[v] > 0 and not _in_gap(
            points,
            frames,
            v,
            tri[t, (j + 1) % 3],
            tri[t, (j + 2) % 3],
            v_edge_off,
            v_edges,
            edge_uv,
            edge_used,
            edge_fwd,
            wi,
            wa,
        ):
            return 0
    if want == 0:
        want = 1
    return want


@njit(cache=True)
def _accept(t, how, tri, tri_edge, edge_uv, edge_used, edge_fwd, v_count, v_bnd, out_tri):
    if how == 2:
        a, b, c = tri[t, 0], tri[t, 2], tri[t, 1]
    else:
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
    out_tri[t, 0] = a
    out_tri[t, 1] = b
    out_tri[t, 2] = c
    for j in range(3):
        e = tri_edge[t, j]
        if edge_used[e] == 0:
            s = tri[t, j] if how == 1 else tri[t, (j + 1) % 3]
            edge_fwd[e] = 1 if s == edge_uv[e, 0] else 0
            v_bnd[edge_uv[e, 0]] += 1
            v_bnd[edge_uv[e, 1]] += 1
        else:
            v_bnd[edge_uv[e, 0]] -= 1
            v_bnd[edge_uv[e, 1]] -= 1
        edge_used[e] += 1
        v_count[tri[t, j]] += 1


@njit(cache=True)
def grow_manifold(
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
    pinch,
    points,
    normals,
    v_edge_off,
    v_edges,
):
    """Grow a consistently oriented 2-manifold from the candidate triangles.

    The triangles of ``pre`` (uncontested, see ``fan_cloud_to_mesh``) are
    accepted first, all at once. Then, and from the best triangle (lowest
    ``priority``) for pieces they do not reach, candidates that share an
    edge with the mesh join one at a time, whenever
    :func:`_try_add` allows them: those of the best ``level`` first (0 is
    best: the most fans), first come first served within a level, so the
    front advances through neighbouring triangles (few cache misses). A
    candidate refused because a vertex would become non-manifold is looked
    at again when the mesh around it changes. When nothing more can join,
    the best candidate (by ``priority``) whose vertices are all new seeds
    another piece. Returns (accepted, out_tri): the accepted mask and the
    triangles in their final orientation.
    """
    m = tri.shape[0]
    n_edges = edge_uv.shape[0]
    edge_used = np.zeros(n_edges, np.int64)
    edge_fwd = np.zeros(n_edges, np.int64)
    v_count = np.zeros(n, np.int64)
    v_bnd = np.zeros(n, np.int64)  # boundary edges (one triangle) at each vertex
    accepted = np.zeros(m, np.bool_)
    dead = ~alive.copy()
    out_tri = tri.copy()
    n_levels = 1
    for t in range(m):
        n_levels = max(n_levels, level[t] + 1)
    cap = m + 1  # a candidate waits in at most one queue at a time
    queue = np.empty((n_levels, cap), np.int64)
    head = np.zeros(n_levels, np.int64)
    tail = np.zeros(n_levels, np.int64)
    frames = tangent_frames(normals)
    wi = np.empty((2, 8), np.int64)  # scratch of _in_gap
    wa = np.empty((2, 8))
    queued = np.zeros(m, np.bool_)  # waiting now: no second copy
    # the triangles accepted beforehand, and the candidates beside them
    size = 0
    for t in range(m):
        if pre[t] and not dead[t]:
            _accept(t, 1, tri, tri_edge, edge_uv, edge_used, edge_fwd, v_count, v_bnd, out_tri)
            accepted[t] = True
    for t in range(m):
        if not accepted[t]:
            continue
        for j in range(3):
            e = tri_edge[t, j]
            for i in range(edge_off[e], edge_off[e + 1]):
                c = edge_tri[i]
                if not dead[c] and not accepted[c] and not queued[c]:
                    lc = level[c]
                    queue[lc, tail[lc] % cap] = c
                    tail[lc] += 1
                    size += 1
                    queued[c] = True
    # the seeds, in priority order, are sorted when first needed, and only
    # those that can still seed (all vertices new: that never comes back)
    seeds = np.empty(0, np.int64)
    sorted_seeds = False
    s_next = 0
    while True:
        if size == 0:
            if not sorted_seeds:
                sorted_seeds = True
                fresh = np.zeros(m, np.bool_)
                for t in range(m):
                    fresh[t] = (
                        not dead[t]
                        and not accepted[t]
                        and v_count[tri[t, 0]] == 0
                        and v_count[tri[t, 1]] == 0
                        and v_count[tri[t, 2]] == 0
                    )
                seeds = np.flatnonzero(fresh)
                seeds = seeds[np.argsort(priority[seeds], kind="mergesort")]
            # a new seed: the best live candidate whose vertices are all new
            while s_next < seeds.shape[0]:
                t = seeds[s_next]
                s_next += 1
                if dead[t] or accepted[t]:
                    continue
                if (
                    v_count[tri[t, 0]] == 0
                    and v_count[tri[t, 1]] == 0
                    and v_count[tri[t, 2]] == 0
                    and not queued[t]
                ):
                    lv = level[t]
                    queue[lv, tail[lv] % cap] = t
                    tail[lv] += 1
                    size += 1
                    queued[t] = True
                    break
            if size == 0:
                break
        lv = 0
        while head[lv] == tail[lv]:
            lv += 1
        t = queue[lv, head[lv] % cap]
        head[lv] += 1
        size -= 1
        queued[t] = False
        if dead[t] or accepted[t]:
            continue
        how = _try_add(
            t,
            tri,
            tri_edge,
            edge_uv,
            edge_used,
            edge_fwd,
            v_count,
            v_bnd,
            pinch,
            False,
            points,
            frames,
            v_edge_off,
            v_edges,
            wi,
            wa,
        )
        if how == 0:
            # refused for good when an edge is full; else it may fit later
            for j in range(3):
                if edge_used[tri_edge[t, j]] >= 2:
                    dead[t] = True
            continue
        _accept(t, how, tri, tri_edge, edge_uv, edge_used, edge_fwd, v_count, v_bnd, out_tri)
        accepted[t] = True
        # the candidates on its edges may join now
        for j in range(3):
            e = tri_edge[t, j]
            for i in range(edge_off[e], edge_off[e + 1]):
                c = edge_tri[i]
                if c != t and not dead[c] and not accepted[c] and not queued[c]:
                    lc = level[c]
                    queue[lc, tail[lc] % cap] = c
                    tail[lc] += 1
                    size += 1
                    queued[c] = True
    return accepted, out_tri


# -- Delaunay rings ----------------------------------------------------------


@njit(cache=True)
def _root(parent, x):
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@njit(cache=True)
def _pinched_at(triangles, keep, vt_off, vt, v, parent, size):
    """Union the kept triangles around v that share an edge at v; return the fan count.

    ``parent``/``size`` are scratch of at least the number of triangles at v;
    afterwards ``parent`` holds the fan of each (by its root position).
    """
    a0 = vt_off[v]
    k = vt_off[v + 1] - a0
    for i in range(k):
        parent[i] = i
        size[i] = 0
    for i in range(k):
        ti = vt[a0 + i]
        if not keep[ti]:
            continue
        for j in range(i + 1, k):
            tj = vt[a0 + j]
            if not keep[tj]:
                continue
            shared = False
            for x in range(3):
                w = triangles[ti, x]
                if w == v:
                    continue
                for y in range(3):
                    if triangles[tj, y] == w:
                        shared = True
            if shared:
                ri = _root(parent, i)
                rj = _root(parent, j)
                if ri != rj:
                    parent[max(ri, rj)] = min(ri, rj)
    n_fans = 0
    for i in range(k):
        if keep[vt[a0 + i]]:
            r = _root(parent, i)
            if size[r] == 0:
                n_fans += 1
            size[r] += 1
    return n_fans


@njit(cache=True, parallel=True)
def _pinched_vertices(triangles, keep, vt_off, vt, n):
    """Whether each vertex has two or more fans of kept triangles (in parallel)."""
    out = np.zeros(n, np.bool_)
    n_chunks = min(max(n, 1), 64)
    for ch in prange(n_chunks):
        width = 1
        for v in range((n * ch) // n_chunks, (n * (ch + 1)) // n_chunks):
            width = max(width, vt_off[v + 1] - vt_off[v])
        parent = np.empty(width, np.int64)
        size = np.empty(width, np.int64)
        for v in range((n * ch) // n_chunks, (n * (ch + 1)) // n_chunks):
            if vt_off[v + 1] - vt_off[v] >= 2:
                out[v] = _pinched_at(triangles, keep, vt_off, vt, v, parent, size) >= 2
    return out


@njit(cache=True)
def split_pinched(triangles, keep, n):
    """Cut non-manifold vertices: keep only the largest fan of triangles around each.

    A vertex whose triangles form several edge-connected fans (two fronts
    that met at a corner and never closed the gap between them) keeps its
    largest fan (ties: the one with the lowest triangle number); the other
    triangles are dropped (``keep`` updated), leaving small holes for the
    hole closing. Dropping a triangle can split another vertex's fan, so
    the vertices of dropped triangles are looked at again, until none is
    pinched. Returns the number dropped.

    Vertices are looked at in increasing order; the first pass visits only
    those found pinched beforehand (in parallel) or touched by a drop: the
    fans of any other vertex are as they were, so the result is that of
    visiting every vertex.
    """
    vt_off, vt = csr_of(triangles, n)
    width = 1
    for v in range(n):
        width = max(width, vt_off[v + 1] - vt_off[v])
    parent = np.empty(width, np.int64)
    size = np.empty(width, np.int64)
    pinched = _pinched_vertices(triangles, keep, vt_off, vt, n)
    mark = np.zeros(n, np.bool_)
    dropped = 0
    todo = np.arange(n)
    first = True
    while todo.shape[0] > 0:
        nxt = []
        for v in todo:
            if first and not pinched[v] and not mark[v]:
                continue  # its triangles are as they were: one fan
            mark[v] = False
            if vt_off[v + 1] - vt_off[v] < 2:
                continue
            if _pinched_at(triangles, keep, vt_off, vt, v, parent, size) < 2:
                continue
            a0 = vt_off[v]
            k = vt_off[v + 1] - a0
            best = -1
            for i in range(k):
                if keep[vt[a0 + i]] and size[i] > 0 and (best < 0 or size[i] > size[best]):
                    best = i
            for i in range(k):
                t = vt[a0 + i]
                if keep[t] and _root(parent, i) != best:
                    keep[t] = False
                    dropped += 1
                    for j in range(3):
                        w = triangles[t, j]
                        if not mark[w]:
                            mark[w] = True
                            nxt.append(w)
        todo = np.array(nxt, np.int64)
        first = False
    return dropped


# -- holes -------------------------------------------------------------------


@njit(cache=True)
def clip_ears(
    points,
    normals,
    loop_off,
    loop_verts,
    triangles,
    vt_off,
    vt,
    cand_tri,
    cand_count,
    edge_uv,
    edge_off,
    edge_tri,
    v_edge_off,
    v_edges,
    n,
    out,
    ok,
):
    """Triangulate boundary loops by clipping the best ear first.

    Loop ``i`` is ``loop_verts[loop_off[i]:loop_off[i + 1]]`` along the
    mesh's boundary half-edges; its ``L - 2`` triangles go to ``out`` from
    row ``loop_off[i] - 2 i`` on, counter-clockwise around the normals
    (against the boundary half-edges). An ear (a, b, c) is convex in b's
    tangent plane, holds no other loop point there, and its new edge a-c is
    neither in the mesh (``triangles``, with the triangles at each vertex in
    ``vt_off``/``vt``) nor made earlier for this loop; the best ear is a fan
    triangle (the most fans: ``cand_count`` of the candidate triangle found
    through its edge a-c in the candidates' edges, see :func:`build_edges`
    and :func:`vertex_edges`), then the one with the largest smallest angle.
    ``ok[i]`` is False for a loop that cannot be closed so.
    """
    n_loops = loop_off.shape[0] - 1
    for i in range(n_loops):
        L = loop_off[i + 1] - loop_off[i]
        poly = np.empty(L, np.int64)
        for j in range(L):
            poly[j] = loop_verts[loop_off[i + 1] - 1 - j]  # reversed: counter-clockwise
        diag = np.empty(max(L, 1), np.int64)
        nd = 0
        row = loop_off[i] - 2 * i
        m = L
        good = True
        while m > 3:
            best = -1
            best_cnt = -1
            best_cos = 2.0
            for j in range(m):
                a = poly[(j - 1 + m) % m]
                b = poly[j]
                c = poly[(j + 1) % m]
                key = min(a, c) * n + max(a, c)
                if has_edge(triangles, vt_off, vt, a, c):
                    continue
                dup = False
                for t in range(nd):
                    if diag[t] == key:
                        dup = True
                        break
                if dup:
                    continue
                ux, uy, uz, vx, vy, vz = tangent(normals[b, 0], normals[b, 1], normals[b, 2])
                ax, ay = in_plane(points, b, a, ux, uy, uz, vx, vy, vz)
                cx, cy = in_plane(points, b, c, ux, uy, uz, vx, vy, vz)
                # convex at b: (b - a) x (c - b) > 0, with b at the origin
                if (-ax) * cy - (-ay) * cx <= 0.0:
                    continue
                inside = False
                for k in range(m):
                    q = poly[k]
                    if q == a or q == b or q == c:
                        continue
                    qx, qy = in_plane(points, b, q, ux, uy, uz, vx, vy, vz)
                    # inside or on the counter-clockwise triangle a, b(0), c
                    if (
                        (0.0 - ax) * (qy - ay) - (0.0 - ay) * (qx - ax) >= 0.0
                        and (cx - 0.0) * (qy - 0.0) - (cy - 0.0) * (qx - 0.0) >= 0.0
                        and (ax - cx) * (qy - cy) - (ay - cy) * (qx - cx) >= 0.0
                    ):
                        inside = True
                        break
                if inside:
                    continue
                t_c = _triangle_on(
                    cand_tri, edge_off, edge_tri, v_edge_off, v_edges, edge_uv, a, c, b
                )
                cnt = cand_count[t_c] if t_c >= 0 else 0
                cs = min_angle_cos(points, a, b, c)
                if cnt > best_cnt or (cnt == best_cnt and cs < best_cos):
                    best = j
                    best_cnt = cnt
                    best_cos = cs
            if best < 0:
                good = False
                break
            a = poly[(best - 1 + m) % m]
            b = poly[best]
            c = poly[(best + 1) % m]
            out[row, 0] = a
            out[row, 1] = b
            out[row, 2] = c
            row += 1
            diag[nd] = min(a, c) * n + max(a, c)
            nd += 1
            for j in range(best, m - 1):
                poly[j] = poly[j + 1]
            m -= 1
        if good:
            a, b, c = poly[0], poly[1], poly[2]
            fx, fy, fz = triangle_cross(points, a, b, c)
            agree = 0.0
            for v in (a, b, c):
                agree += fx * normals[v, 0] + fy * normals[v, 1] + fz * normals[v, 2]
            if agree <= 0.0:
                good = False
            else:
                out[row, 0] = a
                out[row, 1] = b
                out[row, 2] = c
        ok[i] = good


# -- distinct triangles -----------------------------------------------------


@njit(cache=True)
def _fan_has(offsets, ring, is_open, c, x, y):
    """+1 if c's fan has the triangle (c, x, y), -1 if it has (c, y, x), else 0."""
    r0 = offsets[c]
    m = offsets[c + 1] - r0
    last = m if not is_open[c] else m - 1
    for j in range(max(last, 0)):
        u = ring[r0 + j]
        w = ring[r0 + (j + 1) % m]
        if u == x and w == y:
            return 1
        if u == y and w == x:
            return -1
    return 0


@njit(cache=True)
def _fan_triangle(offsets, ring, is_open, p, j):
    """(a, b, count, vote, owned) of the j-th triangle (p, a, b) of p's fan.

    ``owned``: p is the smallest point whose fan has the triangle (so it
    is emitted once, from there); ``vote`` sums +1 for every fan that runs
    it as p's fan does, -1 for the opposite.
    """
    r0 = offsets[p]
    m = offsets[p + 1] - r0
    a = ring[r0 + j]
    b = ring[r0 + (j + 1) % m]
    count = 1
    vote = 1
    owned = True
    ha = _fan_has(offsets, ring, is_open, a, b, p)  # (a, b, p) is (p, a, b) turned
    if ha != 0:
        count += 1
        vote += ha
        if a < p:
            owned = False
    hb = _fan_has(offsets, ring, is_open, b, p, a)  # (b, p, a) is (p, a, b) turned
    if hb != 0:
        count += 1
        vote += hb
        if b < p:
            owned = False
    return a, b, count, vote, owned


@njit(cache=True, parallel=True)
def distinct_triangles(offsets, ring, is_open):
    """Distinct fan triangles, oriented by most of their fans, and their counts.

    Every triangle is emitted once, by the smallest point whose fan has it,
    in fan order (the order of first appearance, fan by fan); a tie in the
    orientation vote keeps that fan's orientation. Returns (tri, count,
    n_fan_triangles, n_mixed): ``n_mixed`` counts the triangles that two
    fans run opposite ways round (their normals disagree).
    """
    n = offsets.shape[0] - 1
    per = np.zeros(n + 1, np.int64)
    n_fan = np.zeros(n, np.int64)
    for p in prange(n):
        m = offsets[p + 1] - offsets[p]
        k = m if not is_open[p] else m - 1
        if m < 2:
            k = 0
        n_fan[p] = max(k, 0)
        c = 0
        for j in range(max(k, 0)):
            _, _, _, _, owned = _fan_triangle(offsets, ring, is_open, p, j)
            if owned:
                c += 1
        per[p + 1] = c
    for p in range(n):
        per[p + 1] += per[p]
    tri = np.empty((per[n], 3), np.int64)
    count = np.empty(per[n], np.int64)
    mixed = np.zeros(n, np.int64)
    for p in prange(n):
        t = per[p]
        for j in range(n_fan[p]):
            a, b, cnt, vote, owned = _fan_triangle(offsets, ring, is_open, p, j)
            if not owned:
                continue
            if abs(vote) != cnt:
                mixed[p] += 1
            tri[t, 0] = p
            if vote >= 0:
                tri[t, 1] = a
                tri[t, 2] = b
            else:
                tri[t, 1] = b
                tri[t, 2] = a
            count[t] = cnt
            t += 1
    return tri, count, n_fan.sum(), mixed.sum()


@njit(cache=True, parallel=True)
def boundary_loops_manifold(triangles, vt_off, vt, n):
    """Boundary loops of a vertex-manifold mesh: (loop_off, loop_verts).

    A half-edge a -> b is on the boundary when no triangle runs b -> a.
    In a vertex-manifold mesh every boundary vertex starts exactly one
    boundary half-edge, so following them gives the loops, each along the
    mesh's boundary half-edges, started at its smallest vertex, loops in
    order of that vertex.
    """
    m = triangles.shape[0]
    on_boundary = np.zeros((m, 3), np.bool_)
    for t in prange(m):
        for j in range(3):
            a = triangles[t, j]
            b = triangles[t, (j + 1) % 3]
            twin = False
            for i in range(vt_off[b], vt_off[b + 1]):
                s = vt[i]
                for k in range(3):
                    if triangles[s, k] == b and triangles[s, (k + 1) % 3] == a:
                        twin = True
                if twin:
                    break
            on_boundary[t, j] = not twin
    nxt = np.full(n, -1, np.int64)
    for t in range(m):
        for j in range(3):
            if on_boundary[t, j]:
                nxt[triangles[t, j]] = triangles[t, (j + 1) % 3]
    seen = np.zeros(n, np.bool_)
    loop_off = [0]
    verts = []
    for v in range(n):
        if nxt[v] < 0 or seen[v]:
            continue
        x = v
        while x >= 0 and not seen[x]:
            seen[x] = True
            verts.append(x)
            x = nxt[x]
        loop_off.append(len(verts))
    return np.array(loop_off, np.int64), np.array(verts, np.int64)


@njit(cache=True, parallel=True)
def uncontested(tri, alive, count, tri_edge, n_edges, min_count):
    """Live triangles in at least ``min_count`` fans that no other candidate contests.

    Each of their edges carries at most two live candidates, and where two
    of them share an edge they run it in opposite directions.
    """
    m = tri.shape[0]
    per_edge = np.zeros(n_edges, np.int64)
    for t in range(m):
        if alive[t]:
            for j in range(3):
                per_edge[tri_edge[t, j]] += 1
    pre = np.zeros(m, np.bool_)
    for t in prange(m):
        if alive[t] and count[t] >= min_count:
            ok = True
            for j in range(3):
                if per_edge[tri_edge[t, j]] > 2:
                    ok = False
            pre[t] = ok
    # +1 for each pre triangle running its edge from the smaller vertex, -1 else
    flow = np.zeros(n_edges, np.int64)
    times = np.zeros(n_edges, np.int64)
    for t in range(m):
        if pre[t]:
            for j in range(3):
                e = tri_edge[t, j]
                times[e] += 1
                flow[e] += 1 if tri[t, j] < tri[t, (j + 1) % 3] else -1
    out = np.zeros(m, np.bool_)
    for t in prange(m):
        if pre[t]:
            ok = True
            for j in range(3):
                e = tri_edge[t, j]
                if times[e] == 2 and flow[e] != 0:
                    ok = False
            out[t] = ok
    return out


# -- unused points -------------------------------------------------------------


@njit(cache=True)
def insert_unused(points, normals, offsets, ring, triangles, n, skip):
    """Put each unused point into the triangle it lies over (1 -> 3 split).

    For unused point p (in increasing order, those with ``skip[p]`` left
    out; ``skip`` may be empty), the candidates are the
    triangles at p's fan neighbours and theirs; the one containing p's
    projection along p's normal best (largest smallest barycentric
    coordinate, ties: the lowest triangle number) is split, if p lies
    strictly inside it. The new triangles are no candidates for the other
    points of this call (call again for those). Returns (triangles,
    points inserted): the triangles not split, then the new ones.
    """
    m = triangles.shape[0]
    used = np.zeros(n, np.bool_)
    for t in range(m):
        for j in range(3):
            used[triangles[t, j]] = True
    if skip.shape[0]:
        for p in range(n):
            used[p] = used[p] or skip[p]
    n_todo = 0
    for p in range(n):
        if not used[p]:
            n_todo += 1
    if n_todo == 0 or m == 0:
        return triangles, 0
    # the triangles at the vertices the unused points look at only (their fan
    # neighbours and theirs): the mesh may be large and its unused points few
    need = np.zeros(n, np.bool_)
    for p in range(n):
        if used[p]:
            continue
        for a in range(offsets[p], offsets[p + 1]):
            q = ring[a]
            need[q] = True
            for b in range(offsets[q], offsets[q + 1]):
                need[ring[b]] = True
    vt_off, vt = csr_of_some(triangles, n, need)
    alive = np.ones(m, np.bool_)
    v_stamp = np.full(n, -1, np.int64)
    t_stamp = np.full(m, -1, np.int64)
    extra = np.empty((3 * n_todo, 3), np.int64)
    n_extra = 0
    near = np.empty(64, np.int64)
    for p in range(n):
        if used[p]:
            continue
        # p's fan neighbours and theirs
        k = 0
        for a in range(offsets[p], offsets[p + 1]):
            q = ring[a]
            for b in range(offsets[q] - 1, offsets[q + 1]):
                s = q if b < offsets[q] else ring[b]
                if v_stamp[s] == p:
                    continue
                v_stamp[s] = p
                if k == near.shape[0]:
                    bigger = np.empty(2 * k, np.int64)
                    bigger[:k] = near
                    near = bigger
                near[k] = s
                k += 1
        nx = normals[p, 0]
        ny = normals[p, 1]
        nz = normals[p, 2]
        xx = points[p, 0]
        xy = points[p, 1]
        xz = points[p, 2]
        best = -np.inf
        best_t = -1
        for i in range(k):
            v = near[i]
            for c in range(vt_off[v], vt_off[v + 1]):
                t = vt[c]
                if t_stamp[t] == p or not alive[t]:
                    continue
                t_stamp[t] = p
                a = triangles[t, 0]
                b = triangles[t, 1]
                cc = triangles[t, 2]
                # signed areas of (a, b, x), (b, c, x), (c, a, x) and (a, b, c) along n
                w = np.inf
                for e in range(3):
                    u = a if e == 0 else (b if e == 1 else cc)
                    z = b if e == 0 else (cc if e == 1 else a)
                    ex = points[z, 0] - points[u, 0]
                    ey = points[z, 1] - points[u, 1]
                    ez = points[z, 2] - points[u, 2]
                    dx = xx - points[u, 0]
                    dy = xy - points[u, 1]
                    dz = xz - points[u, 2]
                    w = min(
                        w,
                        (ey * dz - ez * dy) * nx
                        + (ez * dx - ex * dz) * ny
                        + (ex * dy - ey * dx) * nz,
                    )
                ex = points[b, 0] - points[a, 0]
                ey = points[b, 1] - points[a, 1]
                ez = points[b, 2] - points[a, 2]
                dx = points[cc, 0] - points[a, 0]
                dy = points[cc, 1] - points[a, 1]
                dz = points[cc, 2] - points[a, 2]
                area = (
                    (ey * dz - ez * dy) * nx + (ez * dx - ex * dz) * ny + (ex * dy - ey * dx) * nz
                )
                if area <= 0.0:
                    continue
                score = w / area
                if score > best or (score == best and t < best_t):
                    best = score
                    best_t = t
        if best_t < 0 or best <= 0.0:
            continue  # p lies over no triangle: splitting one would fold
        alive[best_t] = False
        a = triangles[best_t, 0]
        b = triangles[best_t, 1]
        cc = triangles[best_t, 2]
        extra[n_extra, 0] = a
        extra[n_extra, 1] = b
        extra[n_extra, 2] = p
        extra[n_extra + 1, 0] = b
        extra[n_extra + 1, 1] = cc
        extra[n_extra + 1, 2] = p
        extra[n_extra + 2, 0] = cc
        extra[n_extra + 2, 1] = a
        extra[n_extra + 2, 2] = p
        n_extra += 3
    if n_extra == 0:
        return triangles, 0
    n_alive = 0
    for t in range(m):
        if alive[t]:
            n_alive += 1
    out = np.empty((n_alive + n_extra, 3), np.int64)
    r = 0
    for t in range(m):
        if alive[t]:
            out[r, 0] = triangles[t, 0]
            out[r, 1] = triangles[t, 1]
            out[r, 2] = triangles[t, 2]
            r += 1
    out[n_alive:] = extra[:n_extra]
    return out, n_extra // 3


@njit(cache=True)
def star_fits(points, normals, loop, p, triangles, vt_off, vt):
    """Whether the triangles (p, b, a) over a loop's half-edges a -> b make a star around p.

    Seen along p's normal, the loop, run backwards, must turn once
    counter-clockwise around p in steps under pi, and no edge p-a may be
    in the mesh already (``triangles``, with the triangles at each vertex in
    ``vt_off``/``vt``).
    """
    m = loop.shape[0]
    ux, uy, uz, vx, vy, vz = tangent(normals[p, 0], normals[p, 1], normals[p, 2])
    ang = np.empty(m)
    for j in range(m):
        dx = points[loop[j], 0] - points[p, 0]
        dy = points[loop[j], 1] - points[p, 1]
        dz = points[loop[j], 2] - points[p, 2]
        ang[j] = np.arctan2(dx * vx + dy * vy + dz * vz, dx * ux + dy * uy + dz * uz)
    two_pi = 2.0 * np.pi
    total = 0.0
    for j in range(m):
        step = (ang[j] - ang[(j + 1) % m]) % two_pi
        if step >= np.pi:
            return False
        total += step
    if abs(total - two_pi) > 1e-6 + 1e-5 * two_pi:
        return False
    for j in range(m):
        if has_edge(triangles, vt_off, vt, p, loop[j]):
            return False
    return True


@njit(cache=True)
def _runs(tris, a, b):
    """Whether a triangle of ``tris`` runs the edge a -> b."""
    for t in range(tris.shape[0]):
        for i in range(3):
            if tris[t, i] == a and tris[t, (i + 1) % 3] == b:
                return True
    return False


@njit(cache=True)
def _loop_runs(loop, a, b):
    """Whether the loop runs the edge a -> b."""
    m = loop.shape[0]
    for j in range(m):
        if loop[j] == a and loop[(j + 1) % m] == b:
            return True
    return False


@njit(cache=True)
def fill_fits(tris, loop, triangles, vt_off, vt):
    """Whether triangles filling a loop make a disk that joins the mesh manifoldly.

    Every loop edge a -> b must be run b -> a by a fill triangle; every
    inner edge of the fill must have two fill triangles and must not be in
    the mesh (``triangles``, with the triangles at each vertex in
    ``vt_off``/``vt``). The searches return at their first hit: written as
    flags set in full loops, LLVM 14's loop vectorizer (numba 0.57-0.60)
    aborts the process compiling them for some CPUs (AMD Zen 3, generic).
    """
    m = loop.shape[0]
    for j in range(m):
        if not _runs(tris, loop[(j + 1) % m], loop[j]):
            return False
    for t in range(tris.shape[0]):
        for i in range(3):
            x = tris[t, i]
            y = tris[t, (i + 1) % 3]
            if _loop_runs(loop, y, x):
                continue
            if not _loop_runs(loop, x, y) and not _runs(tris, y, x):
                return False  # an inner edge with one triangle: not a disk
            if has_edge(triangles, vt_off, vt, x, y):
                return False  # an inner edge that exists elsewhere: non-manifold
    return True
