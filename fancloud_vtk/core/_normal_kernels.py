"""Numba kernels for consistent normal orientation over the fan adjacency.

Hoppe et al. (1992) propagate the orientation along a minimum spanning tree
of the neighbour graph weighted by ``1 - |n_i . n_j|``, so that it crosses
flat regions first and sharp features last. We grow that tree with Prim's
algorithm on a bucketed priority (the weight quantised into ``n_buckets``
levels), which is linear in the number of edges and deterministic; on
ranges of the (spatially ordered) points in parallel, joined afterwards by
the votes of the edges between them.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._heap_kernels import heap_of, heap_update, sift_down
from ._mesh_kernels import _fan_has


@njit(cache=True)
def transpose_rings(ring_tab, counts):
    """In-edges of the ring graph as CSR (t_offsets, t_src), sources ascending."""
    n = ring_tab.shape[0]
    t_off = np.zeros(n + 1, np.int64)
    for p in range(n):
        for j in range(counts[p]):
            t_off[ring_tab[p, j] + 1] += 1
    for i in range(n):
        t_off[i + 1] += t_off[i]
    fill = t_off[:-1].copy()
    t_src = np.empty(t_off[n], np.int64)
    for p in range(n):
        for j in range(counts[p]):
            q = ring_tab[p, j]
            t_src[fill[q]] = p
            fill[q] += 1
    return t_off, t_src


@njit(cache=True)
def _agreement(points, normals, no_plane, a, b):
    """How far the normals of neighbours ``a`` and ``b`` agree, in [-1, 1]: ``n_a . n_b'``,
    with ``n_b'`` the mirror image of ``n_b`` in the plane halfway between the points
    (normal to ``p_b - p_a``), when ``a`` or ``b`` has no plane of its own (``no_plane``:
    its normal is its fan's plane, as at the corners of a cube of eight points, where
    the outward normals of two neighbours may make more than 90 degrees and the mirror
    image of one still agrees with the other, as in the consistent propagation of Koenig
    and Gumhold, 2009); else ``n_a . n_b``. (Mirrored everywhere, noisy normals in thin
    parts would mislead it: measured on the noisy cow of the corpus.)"""
    ex = points[b, 0] - points[a, 0]
    ey = points[b, 1] - points[a, 1]
    ez = points[b, 2] - points[a, 2]
    ee = ex * ex + ey * ey + ez * ez
    na = normals[a, 0] * normals[b, 0] + normals[a, 1] * normals[b, 1] \
        + normals[a, 2] * normals[b, 2]
    if ee == 0.0 or not (no_plane[a] or no_plane[b]):
        return na
    ea = normals[a, 0] * ex + normals[a, 1] * ey + normals[a, 2] * ez
    eb = normals[b, 0] * ex + normals[b, 1] * ey + normals[b, 2] * ez
    return na - 2.0 * ea * eb / ee


@njit(cache=True)
def _bucket(points, normals, no_plane, a, b, n_buckets):
    d = abs(_agreement(points, normals, no_plane, a, b))
    w = 1.0 - d
    if w < 0.0:
        w = 0.0
    bk = int(np.sqrt(w) * n_buckets)
    return min(bk, n_buckets - 1)


@njit(cache=True)
def _prim_range(points, normals, no_plane, ring_tab, counts, t_off, t_src, n_buckets, a, b,
                flipped, component):
    """Hoppe-style propagation over the fan graph restricted to the points a..b-1.

    Sets ``flipped[a:b]`` (True where the normal must be negated) and
    ``component[a:b]`` (components numbered from 0 in order of their lowest
    point); returns the number of components. Edges leaving the range are
    ignored (see :func:`orient_by_propagation` for how ranges are joined).
    """
    m = b - a
    visited = np.zeros(m, np.bool_)
    key = np.full(m, n_buckets, np.int64)  # n_buckets = not queued
    parent = np.full(m, -1, np.int64)
    head = np.full(n_buckets, -1, np.int64)
    nxt = np.full(m, -1, np.int64)
    prv = np.full(m, -1, np.int64)
    n_comp = 0
    for seed in range(m):
        if visited[seed]:
            continue
        comp = n_comp
        n_comp += 1
        key[seed] = 0
        head[0] = seed
        nxt[seed] = -1
        prv[seed] = -1
        lowest = 0
        while True:
            while lowest < n_buckets and head[lowest] < 0:
                lowest += 1
            if lowest == n_buckets:
                break
            v = head[lowest]
            head[lowest] = nxt[v]
            if nxt[v] >= 0:
                prv[nxt[v]] = -1
            key[v] = n_buckets
            visited[v] = True
            gv = a + v
            component[gv] = comp
            u = parent[v]
            if u >= 0:
                gu = a + u
                d = _agreement(points, normals, no_plane, gv, gu)
                if flipped[gu]:
                    d = -d
                flipped[gv] = d < 0.0
            else:
                flipped[gv] = False
            for side in range(2):
                if side == 0:
                    e0, e1 = 0, counts[gv]
                else:
                    e0, e1 = t_off[gv], t_off[gv + 1]
                for e in range(e0, e1):
                    gw = ring_tab[gv, e] if side == 0 else t_src[e]
                    if gw < a or gw >= b:
                        continue
                    w = gw - a
                    if visited[w]:
                        continue
                    bk = _bucket(points, normals, no_plane, gv, gw, n_buckets)
                    if bk >= key[w]:
                        continue
                    if key[w] < n_buckets:  # unlink from its current bucket
                        if prv[w] >= 0:
                            nxt[prv[w]] = nxt[w]
                        else:
                            head[key[w]] = nxt[w]
                        if nxt[w] >= 0:
                            prv[nxt[w]] = prv[w]
                    key[w] = bk
                    parent[w] = v
                    prv[w] = -1
                    nxt[w] = head[bk]
                    if head[bk] >= 0:
                        prv[head[bk]] = w
                    head[bk] = w
                    if bk < lowest:
                        lowest = bk
    return n_comp


@njit(cache=True, parallel=True)
def _orient_ranges(points, normals, no_plane, ring_tab, counts, t_off, t_src, n_buckets, bounds,
                   flipped, component):
    n_ranges = bounds.shape[0] - 1
    n_comp = np.zeros(n_ranges, np.int64)
    for r in prange(n_ranges):
        n_comp[r] = _prim_range(points, normals, no_plane, ring_tab, counts, t_off, t_src,
                                n_buckets,
                                bounds[r], bounds[r + 1], flipped, component)
    return n_comp


@njit(cache=True)
def orient_by_propagation(points, normals, no_plane, ring_tab, counts, t_off, t_src, n_buckets,
                          range_size):
    """Signs that make neighbouring normals agree; return (flipped, component).

    Hoppe et al. (1992) propagate the orientation along a minimum spanning
    tree weighted by ``1 - |n_i . n_j|``; here ``n_i . n_j`` is replaced by
    :func:`_agreement` (``n_j`` mirrored in the plane normal to the edge
    where a point has no plane of its own, at sharp corners). Here the points (in a spatially
    coherent order) are cut into ranges of ``range_size`` points, each range
    is oriented on its own in parallel, and the pieces are joined by a
    maximum spanning tree over the pieces, each pair of touching pieces
    weighted by the vote of all the fan edges between them (sum of
    ``+-|n_i . n_j|``, + where the two normals agree). The result does not
    depend on the number of threads. ``flipped[i]`` is True where normal ``i``
    must be negated (the normals are not modified); ``component[i]`` numbers
    the connected components of the fan graph in order of their lowest point.
    """
    n = normals.shape[0]
    n_ranges = max(1, (n + range_size - 1) // range_size)
    bounds = np.empty(n_ranges + 1, np.int64)
    for r in range(n_ranges + 1):
        bounds[r] = min(n, r * range_size)
    flipped = np.zeros(n, np.bool_)
    local = np.zeros(n, np.int64)
    n_comp = _orient_ranges(points, normals, no_plane, ring_tab, counts, t_off, t_src, n_buckets,
                            bounds, flipped, local)
    first = np.zeros(n_ranges + 1, np.int64)
    for r in range(n_ranges):
        first[r + 1] = first[r] + n_comp[r]
    n_pieces = first[n_ranges]
    piece = np.empty(n, np.int64)
    for r in range(n_ranges):
        for i in range(bounds[r], bounds[r + 1]):
            piece[i] = first[r] + local[i]
    # votes of the edges between pieces, accumulated per (piece, piece) pair
    n_cross = 0
    for p in range(n):
        for j in range(counts[p]):
            if piece[ring_tab[p, j]] != piece[p]:
                n_cross += 1
    pa = np.empty(n_cross, np.int64)
    pb = np.empty(n_cross, np.int64)
    vote = np.empty(n_cross, np.float64)
    c = 0
    for p in range(n):
        for j in range(counts[p]):
            q = ring_tab[p, j]
            if piece[q] == piece[p]:
                continue
            d = _agreement(points, normals, no_plane, p, q)
            if flipped[p] != flipped[q]:
                d = -d
            x, y = piece[p], piece[q]
            if x > y:
                x, y = y, x
            pa[c] = x
            pb[c] = y
            vote[c] = d
            c += 1
    order = np.argsort(pa * n_pieces + pb, kind="mergesort")
    # one edge per pair with the summed vote
    ea = np.empty(n_cross, np.int64)
    eb = np.empty(n_cross, np.int64)
    ev = np.empty(n_cross, np.float64)
    m = 0
    for t in range(n_cross):
        e = order[t]
        if m > 0 and ea[m - 1] == pa[e] and eb[m - 1] == pb[e]:
            ev[m - 1] += vote[e]
        else:
            ea[m] = pa[e]
            eb[m] = pb[e]
            ev[m] = vote[e]
            m += 1
    # Kruskal on the strongest votes first: join pieces, flipping where they disagree
    strength = np.empty(m, np.float64)
    for t in range(m):
        strength[t] = -abs(ev[t])
    by_strength = np.argsort(strength, kind="mergesort")
    uf = np.arange(n_pieces)
    rel = np.zeros(n_pieces, np.bool_)  # flip of a piece relative to its root
    # union-find with parity: rel[x] is x's flip relative to parent[x]
    for t in range(m):
        e = by_strength[t]
        x = ea[e]
        y = eb[e]
        # find roots and parities
        rx = x
        px = False
        while uf[rx] != rx:
            px ^= rel[rx]
            rx = uf[rx]
        ry = y
        py = False
        while uf[ry] != ry:
            py ^= rel[ry]
            ry = uf[ry]
        if rx == ry:
            continue
        disagree = ev[e] < 0.0
        # attach the larger-numbered root below the smaller one (deterministic)
        if rx < ry:
            uf[ry] = rx
            rel[ry] = px ^ py ^ disagree
        else:
            uf[rx] = ry
            rel[rx] = px ^ py ^ disagree
    piece_flip = np.zeros(n_pieces, np.bool_)
    piece_root = np.empty(n_pieces, np.int64)
    for x in range(n_pieces):
        r = x
        f = False
        while uf[r] != r:
            f ^= rel[r]
            r = uf[r]
        piece_flip[x] = f
        piece_root[x] = r
    # components numbered by their lowest point
    comp_id = np.full(n_pieces, -1, np.int64)
    component = np.empty(n, np.int64)
    n_out = 0
    for i in range(n):
        r = piece_root[piece[i]]
        if comp_id[r] < 0:
            comp_id[r] = n_out
            n_out += 1
        component[i] = comp_id[r]
        if piece_flip[piece[i]]:
            flipped[i] = not flipped[i]
    return flipped, component


@njit(cache=True)
def outward_scores(points, normals, flipped, ring_tab, counts, component, n_comp):
    """Per component, the sum of a_i (p_i - c) . n_i with a_i a local area.

    For a closed surface with outward normals this approximates three times
    the enclosed volume (divergence theorem): positive. ``c`` is the
    area-weighted centroid of the component; ``a_i`` the mean squared ring
    distance of point i.
    """
    n = points.shape[0]
    area = np.zeros(n)
    for p in range(n):
        s = 0.0
        for j in range(counts[p]):
            q = ring_tab[p, j]
            for a in range(3):
                d = points[q, a] - points[p, a]
                s += d * d
        area[p] = s / max(counts[p], 1)
    weight = np.zeros(n_comp)
    centre = np.zeros((n_comp, 3))
    for p in range(n):
        c = component[p]
        weight[c] += area[p]
        for a in range(3):
            centre[c, a] += area[p] * points[p, a]
    for c in range(n_comp):
        if weight[c] > 0.0:
            for a in range(3):
                centre[c, a] /= weight[c]
    score = np.zeros(n_comp)
    for p in range(n):
        c = component[p]
        d = 0.0
        for a in range(3):
            d += (points[p, a] - centre[c, a]) * normals[p, a]
        score[c] += -area[p] * d if flipped[p] else area[p] * d
    return score


@njit(cache=True)
def flip_fans(normals, ring_tab, counts, flip):
    """Negate the normals and reverse the rings where ``flip`` (rings stay CCW)."""
    for p in range(normals.shape[0]):
        if not flip[p]:
            continue
        for a in range(3):
            normals[p, a] = -normals[p, a]
        m = counts[p]
        for j in range(m // 2):
            t = ring_tab[p, j]
            ring_tab[p, j] = ring_tab[p, m - 1 - j]
            ring_tab[p, m - 1 - j] = t


# -- orientation by the triangles that neighbouring fans share ---------------

#: weight of one shared fan triangle (run the same way round, or not) against
#: the agreement of two normals (at most ``SHARED_WEAK``): a point is oriented
#: by its normals only where no fan triangle decides
SHARED_WEAK = 0.01


@njit(cache=True, parallel=True)
def shared_triangle_votes(offsets, ring, is_open):
    """Per ring entry ``p -> q`` (CSR ``offsets``, ``ring``): the fan triangles
    of p on the edge pq that q's fan has too, +1 for each that q's fan runs the
    same way round as p's, -1 for each it runs the other way round."""
    n = offsets.shape[0] - 1
    vote = np.zeros(ring.shape[0], np.int64)
    for p in prange(n):
        r0 = offsets[p]
        m = offsets[p + 1] - r0
        if m < 2 or (m == 2 and not is_open[p]):
            continue
        last = m - 1 if is_open[p] else m
        for j in range(last):
            a = ring[r0 + j]
            b = ring[r0 + (j + 1) % m]
            # (p, a, b) is (a, b, p) in a's fan and (b, p, a) in b's, the same way round
            vote[r0 + j] += _fan_has(offsets, ring, is_open, a, b, p)
            vote[r0 + (j + 1) % m] += _fan_has(offsets, ring, is_open, b, p, a)
    return vote


@njit(cache=True)
def _pop(heap, hpos, key, size):
    x = heap[0]
    size -= 1
    if size > 0:
        heap[0] = heap[size]
        hpos[heap[0]] = 0
        sift_down(heap, hpos, key, 0, size)
    hpos[x] = -1
    return x


@njit(cache=True, parallel=True)
def agreement_weights(points, normals, offsets, ring, weak):
    """Per ring entry ``p -> q``: ``weak * n_p . n_q / (1 + 10 s)``, with ``s`` the
    squared slope of the edge against both normals (an edge across a thin part runs
    along them, and its normals' agreement says little)."""
    n = offsets.shape[0] - 1
    weight = np.empty(ring.shape[0])
    for p in prange(n):
        for s in range(offsets[p], offsets[p + 1]):
            q = ring[s]
            ex = points[q, 0] - points[p, 0]
            ey = points[q, 1] - points[p, 1]
            ez = points[q, 2] - points[p, 2]
            ee = ex * ex + ey * ey + ez * ez
            dp = ex * normals[p, 0] + ey * normals[p, 1] + ez * normals[p, 2]
            dq = ex * normals[q, 0] + ey * normals[q, 1] + ez * normals[q, 2]
            slope = (dp * dp + dq * dq) / ee if ee > 0.0 else 0.0
            agree = normals[p, 0] * normals[q, 0] + normals[p, 1] * normals[q, 1] \
                + normals[p, 2] * normals[q, 2]
            weight[s] = weak * agree / (1.0 + 10.0 * slope)
    return weight


@njit(cache=True)
def orient_by_evidence(offsets, nbr, weight):
    """Signs for the normals from weighted sign relations; return (flipped, component,
    n_comp).

    Each entry ``p -> q`` of the CSR graph (``offsets``, ``nbr``) says with
    ``weight`` how strongly p and q keep their normals' relative sign (> 0) or
    want it reversed (< 0). The points are decided one at a time, always the
    undecided point with the largest evidence: the sum, over its decided
    neighbours (entries in either direction), of the weight times the
    neighbour's sign (the greedy order of MeshLib's orientation of local
    triangulations). A point with no evidence starts a new component with its
    sign as it is (the lowest such point first).
    ``flipped[i]``: normal i must be negated; ``component[i]``: its connected
    component of the graph.
    """
    n = offsets.shape[0] - 1
    n_e = nbr.shape[0]
    owner = np.empty(n_e, np.int64)
    for p in range(n):
        for s in range(offsets[p], offsets[p + 1]):
            owner[s] = p
    # in-edges: for each q, the entries that point at it
    t_off = np.zeros(n + 1, np.int64)
    for s in range(n_e):
        t_off[nbr[s] + 1] += 1
    for i in range(n):
        t_off[i + 1] += t_off[i]
    fill = t_off[:-1].copy()
    t_slot = np.empty(n_e, np.int64)
    for s in range(n_e):
        q = nbr[s]
        t_slot[fill[q]] = s
        fill[q] += 1
    sign = np.zeros(n, np.int64)
    component = np.full(n, -1, np.int64)
    evidence = np.zeros(n)
    key = np.zeros(n)  # -|evidence|: the min-heap gives the strongest first
    heap, hpos = heap_of(key, np.ones(n, np.bool_))
    size = n
    n_comp = 0
    while size > 0:
        v = _pop(heap, hpos, key, size)
        size -= 1
        sign[v] = -1 if evidence[v] < 0.0 else 1
        comp = -1
        for s in range(offsets[v], offsets[v + 1]):
            if sign[nbr[s]] != 0:
                comp = component[nbr[s]]
                break
        if comp < 0:
            for i in range(t_off[v], t_off[v + 1]):
                if sign[owner[t_slot[i]]] != 0:
                    comp = component[owner[t_slot[i]]]
                    break
        if comp < 0:
            comp = n_comp
            n_comp += 1
        component[v] = comp
        for s in range(offsets[v], offsets[v + 1]):
            u = nbr[s]
            if sign[u] == 0 and weight[s] != 0.0:
                evidence[u] += weight[s] * sign[v]
                heap_update(heap, hpos, key, u, -abs(evidence[u]), size)
        for i in range(t_off[v], t_off[v + 1]):
            s = t_slot[i]
            u = owner[s]
            if sign[u] == 0 and weight[s] != 0.0:
                evidence[u] += weight[s] * sign[v]
                heap_update(heap, hpos, key, u, -abs(evidence[u]), size)
    return sign < 0, component, n_comp
