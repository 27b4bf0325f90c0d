"""Numba kernels of the view-dependent fan cloud (paper section 8).

Building the forest (:func:`merge_forest`): a sequence of merges of the
point of lowest entropy ``p`` with its lowest-entropy neighbour ``q`` into a
new node ``r``, whose neighbours are those of ``p`` and ``q`` minus ``p`` and
``q``. The neighbour sets sit in a fixed-width table (``r`` takes ``p``'s
row); the nodes wait in an indexed binary heap keyed by entropy (ties broken
by the smaller id, so the order is deterministic). Locked nodes (the shared
points of terrain blocks) are never merged. The fan of ``r`` at merge time is
its neighbour set sorted around its normal.

After the build (:func:`forest_tables`): the leaves of every node in one
depth-first order (a node's leaves are a contiguous range of it), the depth,
e(r) (the largest distance of a node's leaves from its fan, computed in
parallel over nodes), the monotone error bound and nested bounding spheres.

At run time (:func:`update_front`, :func:`front_triangles`): the front of
active nodes kept from frame to frame, and the distinct triangles of the
active fans, a fan neighbour that is not active being replaced by its active
ancestor or representative.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._entropy_kernels import point_cc, point_terms
from ._mesh_kernels import _tangent

MERGE_ENTROPY = 0
MERGE_HALF_EDGE = 1

FRONT = 1  #: state of a node on the front
REFINED = 2  #: state of a node whose children are shown instead


# -- adjacency --------------------------------------------------------------------------


@njit(cache=True)
def symmetric_adjacency(offsets, ring, n):
    """Neighbour sets ``q in ring(p) or p in ring(q)`` in CSR form (sorted, no repeats)."""
    deg = np.zeros(n + 1, np.int64)
    for p in range(n):
        for a in range(offsets[p], offsets[p + 1]):
            q = ring[a]
            if q != p:
                deg[p + 1] += 1
                deg[q + 1] += 1
    off = np.cumsum(deg)
    fill = off[:-1].copy()
    nb = np.empty(off[n], np.int64)
    for p in range(n):
        for a in range(offsets[p], offsets[p + 1]):
            q = ring[a]
            if q != p:
                nb[fill[p]] = q
                fill[p] += 1
                nb[fill[q]] = p
                fill[q] += 1
    out_off = np.zeros(n + 1, np.int64)
    m = 0
    for p in range(n):
        row = np.sort(nb[off[p]:off[p + 1]])
        last = -1
        for a in range(row.shape[0]):
            if row[a] != last:
                nb[m] = row[a]
                m += 1
                last = row[a]
        out_off[p + 1] = m
    return out_off, nb[:m].copy()


@njit(cache=True)
def restrict_adjacency(adj_off, adj, idx, n):
    """The adjacency among ``idx`` (global ids), renumbered 0..len(idx)-1."""
    local = np.full(n, -1, np.int64)
    for i in range(idx.shape[0]):
        local[idx[i]] = i
    off = np.zeros(idx.shape[0] + 1, np.int64)
    for i in range(idx.shape[0]):
        c = 0
        for a in range(adj_off[idx[i]], adj_off[idx[i] + 1]):
            if local[adj[a]] >= 0:
                c += 1
        off[i + 1] = off[i] + c
    out = np.empty(off[-1], np.int64)
    for i in range(idx.shape[0]):
        c = off[i]
        for a in range(adj_off[idx[i]], adj_off[idx[i] + 1]):
            j = local[adj[a]]
            if j >= 0:
                out[c] = j
                c += 1
    return off, out


@njit(cache=True)
def edges_outside_blocks(offsets, ring, mem_off, mem):
    """Number of fan edges (p, q) with no block holding both p and q; and the first such p."""
    bad = 0
    first = -1
    for p in range(offsets.shape[0] - 1):
        for a in range(offsets[p], offsets[p + 1]):
            q = ring[a]
            ok = False
            for i in range(mem_off[p], mem_off[p + 1]):
                for j in range(mem_off[q], mem_off[q + 1]):
                    if mem[i] == mem[j]:
                        ok = True
                        break
                if ok:
                    break
            if not ok:
                bad += 1
                if first < 0:
                    first = p
    return bad, first


# -- indexed heap with insertion and removal ------------------------------------------


@njit(cache=True)
def _less(key, a, b):
    return key[a] < key[b] or (key[a] == key[b] and a < b)


@njit(cache=True)
def _up(heap, hpos, key, i):
    x = heap[i]
    while i > 0:
        parent = (i - 1) >> 1
        y = heap[parent]
        if not _less(key, x, y):
            break
        heap[i] = y
        hpos[y] = i
        i = parent
    heap[i] = x
    hpos[x] = i


@njit(cache=True)
def _down(heap, hpos, key, i, size):
    x = heap[i]
    while True:
        c = 2 * i + 1
        if c >= size:
            break
        if c + 1 < size and _less(key, heap[c + 1], heap[c]):
            c += 1
        y = heap[c]
        if not _less(key, y, x):
            break
        heap[i] = y
        hpos[y] = i
        i = c
    heap[i] = x
    hpos[x] = i


@njit(cache=True)
def _push(heap, hpos, key, x, size):
    heap[size] = x
    hpos[x] = size
    _up(heap, hpos, key, size)
    return size + 1


@njit(cache=True)
def _remove(heap, hpos, key, x, size):
    i = hpos[x]
    hpos[x] = -1
    size -= 1
    if i == size:
        return size
    y = heap[size]
    heap[i] = y
    hpos[y] = i
    _up(heap, hpos, key, i)
    _down(heap, hpos, key, hpos[y], size)
    return size


@njit(cache=True)
def _rekey(heap, hpos, key, x, value, size):
    old = key[x]
    key[x] = value
    if hpos[x] < 0:
        return size
    if value < old:
        _up(heap, hpos, key, hpos[x])
    else:
        _down(heap, hpos, key, hpos[x], size)
    return size


# -- the merges -------------------------------------------------------------------------


@njit(cache=True)
def _terms(pos, nrm, col, R, rlen, slot, x, dbar):
    s = slot[x]
    return point_terms(pos, nrm, col, x, R[s], rlen[s], dbar)


@njit(cache=True)
def _sorted_ring(pos, nx, ny, nz, r, nbrs, k, is_open, out, ang):
    """``nbrs[:k]`` sorted counter-clockwise around (nx, ny, nz) at r into ``out``.

    An open fan starts after its widest angular gap. ``ang``: scratch of k floats.
    """
    ux, uy, uz, vx, vy, vz = _tangent(nx, ny, nz)
    for a in range(k):
        q = nbrs[a]
        dx = pos[q, 0] - pos[r, 0]
        dy = pos[q, 1] - pos[r, 1]
        dz = pos[q, 2] - pos[r, 2]
        t = np.arctan2(dx * vx + dy * vy + dz * vz, dx * ux + dy * uy + dz * uz)
        b = a
        while b > 0 and ang[b - 1] > t:
            ang[b] = ang[b - 1]
            out[b] = out[b - 1]
            b -= 1
        ang[b] = t
        out[b] = q
    if is_open and k > 1:
        start = 0
        best = -1.0
        for a in range(k):
            b = (a + 1) % k
            gap = ang[b] - ang[a]
            if b == 0:
                gap += 2.0 * np.pi
            if gap > best:
                best = gap
                start = b
        if start != 0:
            for a in range(k):
                nbrs[a] = out[(start + a) % k]
            for a in range(k):
                out[a] = nbrs[a]


@njit(cache=True, nogil=True)
def merge_forest(pos0, nrm0, col0, open0, adj_off, adj, locked0, w, dbar, method, min_alive,
                 width):
    """Merge nodes until ``min_alive`` remain or no pair can merge.

    Inputs are ``m`` nodes (leaves or nodes of an earlier build) with their
    neighbour sets (CSR, local ids). New nodes get ids ``m, m + 1, ...`` in
    merge order. Returns ``(k, child (k, 2), pos (k, 3), nrm (k, 3),
    col (k, c), open (k,), ring_off (k + 1,), ring, alive (m + k,),
    out_off, out_adj)``: the ``k`` new nodes, their children and fans at
    merge time, which nodes are left, and the neighbour sets of those left
    (CSR over the alive ids in increasing order).
    """
    m = pos0.shape[0]
    cap = 2 * m
    nc = col0.shape[1]
    pos = np.empty((cap, 3))
    nrm = np.empty((cap, 3))
    col = np.zeros((cap, nc))
    opn = np.zeros(cap, np.bool_)
    locked = np.zeros(cap, np.bool_)
    pos[:m] = pos0
    nrm[:m] = nrm0
    if nc > 0:
        col[:m] = col0
    opn[:m] = open0
    locked[:m] = locked0
    slot = np.full(cap, -1, np.int64)
    R = np.empty((m, width), np.int32)
    rlen = np.zeros(m, np.int64)
    alive = np.zeros(cap, np.bool_)
    for x in range(m):
        slot[x] = x
        alive[x] = True
        d = adj_off[x + 1] - adj_off[x]
        if d > width:
            d = width  # cannot happen for fans of at most width - 1 neighbours
        for a in range(d):
            R[x, a] = adj[adj_off[x] + a]
        rlen[x] = d
    dist = np.zeros(cap)
    curv = np.zeros(cap)
    cterm = np.zeros(cap)
    key = np.full(cap, np.inf)
    colors = col if nc > 0 else np.zeros((0, 3))
    for x in range(m):
        dist[x], curv[x], cterm[x] = _terms(pos, nrm, colors, R, rlen, slot, x, dbar)
    for x in range(m):
        cc = 0.0
        if w[2] != 0.0:
            s = slot[x]
            cc = point_cc(pos, curv, x, R[s], rlen[s], dbar)
        key[x] = w[0] * dist[x] + w[1] * curv[x] + w[2] * cc + w[3] * cterm[x]
    # the heap orders by hkey <= key: a key that grows is only corrected when it
    # comes to the top (lazy), one that shrinks is sifted up at once
    hkey = key.copy()
    heap = np.empty(cap, np.int64)
    hpos = np.full(cap, -1, np.int64)
    size = 0
    for x in range(m):
        if not locked[x]:
            heap[size] = x
            hpos[x] = size
            size += 1
    for i in range(size // 2 - 1, -1, -1):
        _down(heap, hpos, hkey, i, size)

    child = np.empty((m, 2), np.int64)
    ring_off = np.zeros(m + 1, np.int64)
    ring = np.empty(8 * m + 64, np.int64)
    stamp = np.zeros(cap, np.int64)
    buf = np.empty(2 * width, np.int64)
    srt = np.empty(2 * width, np.int64)
    angbuf = np.empty(2 * width)
    n_alive = m
    k = 0
    while size > 0 and n_alive > min_alive:
        p = heap[0]
        if hkey[p] < key[p]:
            hkey[p] = key[p]
            _down(heap, hpos, hkey, 0, size)
            continue
        size = _remove(heap, hpos, hkey, p, size)
        sp = slot[p]
        # the lowest-entropy neighbour that can merge with p
        q = -1
        for a in range(rlen[sp]):
            y = R[sp, a]
            if locked[y]:
                continue
            if q >= 0 and not _less(key, y, q):
                continue
            # union size
            tag = -(k + 1)
            c = 0
            for b in range(rlen[sp]):
                z = R[sp, b]
                if z != y:
                    stamp[z] = tag
                    c += 1
            sy = slot[y]
            for b in range(rlen[sy]):
                z = R[sy, b]
                if z != p and stamp[z] != tag:
                    c += 1
            for b in range(rlen[sp]):
                stamp[R[sp, b]] = 0
            if c <= width:
                q = y
        if q < 0:
            continue  # p waits outside the heap until its neighbourhood changes
        sq = slot[q]
        size = _remove(heap, hpos, hkey, q, size)
        r = m + k
        # the union of the neighbour sets, minus p and q
        tag = r + 1
        c = 0
        for b in range(rlen[sp]):
            z = R[sp, b]
            if z != q and stamp[z] != tag:
                stamp[z] = tag
                buf[c] = z
                c += 1
        for b in range(rlen[sq]):
            z = R[sq, b]
            if z != p and stamp[z] != tag:
                stamp[z] = tag
                buf[c] = z
                c += 1
        # position, normal, colour of r
        mp = key[p] if key[p] > 0.0 else 0.0
        mq = key[q] if key[q] > 0.0 else 0.0
        if method == MERGE_HALF_EDGE:
            wp, wq = 0.0, 1.0
        elif mp + mq > 0.0:
            wp, wq = mp / (mp + mq), mq / (mp + mq)
        else:
            wp, wq = 0.5, 0.5
        sgn = 1.0
        if nrm[p, 0] * nrm[q, 0] + nrm[p, 1] * nrm[q, 1] + nrm[p, 2] * nrm[q, 2] < 0.0:
            sgn = -1.0
        ln = 0.0
        for d in range(3):
            pos[r, d] = wp * pos[p, d] + wq * pos[q, d]
            nrm[r, d] = (mp + 1e-300) * nrm[p, d] + sgn * (mq + 1e-300) * nrm[q, d]
            ln += nrm[r, d] * nrm[r, d]
        ln = np.sqrt(ln)
        for d in range(3):
            if ln > 1e-12:
                nrm[r, d] /= ln
            else:
                nrm[r, d] = nrm[p, d]
        for d in range(nc):
            col[r, d] = wp * col[p, d] + wq * col[q, d]
        opn[r] = opn[p] or opn[q]
        # the fan of r at merge time
        if k + 1 > child.shape[0]:
            break  # cannot happen: at most m - 1 merges
        child[k, 0] = p
        child[k, 1] = q
        need = ring_off[k] + c
        if need > ring.shape[0]:
            bigger = np.empty(2 * need, np.int64)
            bigger[:ring_off[k]] = ring[:ring_off[k]]
            ring = bigger
        _sorted_ring(pos, nrm[r, 0], nrm[r, 1], nrm[r, 2], r, buf, c, opn[r], srt, angbuf)
        for b in range(c):
            ring[ring_off[k] + b] = srt[b]
        ring_off[k + 1] = need
        # r takes p's row
        for b in range(c):
            R[sp, b] = buf[b]
        rlen[sp] = c
        slot[r] = sp
        slot[p] = -1
        slot[q] = -1
        alive[p] = False
        alive[q] = False
        alive[r] = True
        n_alive -= 1
        # the neighbours see r instead of p and q
        for b in range(c):
            x = buf[b]
            sx = slot[x]
            e = 0
            for a in range(rlen[sx]):
                z = R[sx, a]
                if z != p and z != q:
                    R[sx, e] = z
                    e += 1
            R[sx, e] = r
            rlen[sx] = e + 1
        # entropies of r and its neighbours
        dist[r], curv[r], cterm[r] = _terms(pos, nrm, colors, R, rlen, slot, r, dbar)
        for b in range(c):
            x = buf[b]
            dist[x], curv[x], cterm[x] = _terms(pos, nrm, colors, R, rlen, slot, x, dbar)
        for b in range(-1, c):
            x = r if b < 0 else buf[b]
            cc = 0.0
            if w[2] != 0.0:
                s = slot[x]
                cc = point_cc(pos, curv, x, R[s], rlen[s], dbar)
            value = w[0] * dist[x] + w[1] * curv[x] + w[2] * cc + w[3] * cterm[x]
            key[x] = value
            if locked[x]:
                continue
            if hpos[x] < 0:
                hkey[x] = value
                size = _push(heap, hpos, hkey, x, size)
            elif value < hkey[x]:
                hkey[x] = value
                _up(heap, hpos, hkey, hpos[x])
        k += 1
    # the nodes left and their neighbour sets
    total = m + k
    out_off = np.zeros(total + 1, np.int64)
    for x in range(total):
        out_off[x + 1] = out_off[x] + (rlen[slot[x]] if alive[x] else 0)
    out_adj = np.empty(out_off[total], np.int64)
    for x in range(total):
        if alive[x]:
            s = slot[x]
            row = np.sort(R[s, :rlen[s]].astype(np.int64))
            out_adj[out_off[x]:out_off[x + 1]] = row
    return (k, child[:k].copy(), pos[m:total].copy(), nrm[m:total].copy(),
            col[m:total].copy(), opn[m:total].copy(), ring_off[:k + 1].copy(),
            ring[:ring_off[k]].copy(), alive[:total].copy(), out_off, out_adj)


# -- tables of the built forest ---------------------------------------------------------


@njit(cache=True)
def leaf_order(child):
    """Leaves in depth-first order, each node's range [lo, hi) in it, and its depth.

    Children have smaller ids than their parent, so the roots are the nodes
    without parent and the depth is filled top-down from the highest id.
    """
    n = child.shape[0]
    parent = np.full(n, -1, np.int64)
    for x in range(n):
        if child[x, 0] >= 0:
            parent[child[x, 0]] = x
            parent[child[x, 1]] = x
    depth = np.zeros(n, np.int64)
    for x in range(n - 1, -1, -1):
        if parent[x] >= 0:
            depth[x] = depth[parent[x]] + 1
    lo = np.zeros(n, np.int64)
    hi = np.zeros(n, np.int64)
    order = np.empty(n, np.int64)
    n_leaves = 0
    stack = np.empty(n + 1, np.int64)
    for root in range(n):
        if parent[root] >= 0:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            x = stack[top]
            top -= 1
            if x < 0:  # post-visit of ~x
                x = ~x
                hi[x] = n_leaves
                continue
            lo[x] = n_leaves
            if child[x, 0] < 0:
                order[n_leaves] = x
                n_leaves += 1
                hi[x] = n_leaves
            else:
                top += 1
                stack[top] = ~x
                top += 1
                stack[top] = child[x, 1]
                top += 1
                stack[top] = child[x, 0]
    return parent, depth, order[:n_leaves].copy(), lo, hi


@njit(cache=True)
def _point_triangle(px, py, pz, a, b, c):
    """Distance from p to triangle abc (Ericson's closest point)."""
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    acx, acy, acz = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    apx, apy, apz = px - a[0], py - a[1], pz - a[2]
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        qx, qy, qz = a[0], a[1], a[2]
    else:
        bpx, bpy, bpz = px - b[0], py - b[1], pz - b[2]
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        if d3 >= 0.0 and d4 <= d3:
            qx, qy, qz = b[0], b[1], b[2]
        else:
            vc = d1 * d4 - d3 * d2
            if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                v = d1 / (d1 - d3)
                qx, qy, qz = a[0] + v * abx, a[1] + v * aby, a[2] + v * abz
            else:
                cpx, cpy, cpz = px - c[0], py - c[1], pz - c[2]
                d5 = abx * cpx + aby * cpy + abz * cpz
                d6 = acx * cpx + acy * cpy + acz * cpz
                if d6 >= 0.0 and d5 <= d6:
                    qx, qy, qz = c[0], c[1], c[2]
                else:
                    vb = d5 * d2 - d1 * d6
                    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                        t = d2 / (d2 - d6)
                        qx, qy, qz = a[0] + t * acx, a[1] + t * acy, a[2] + t * acz
                    else:
                        va = d3 * d6 - d5 * d4
                        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                            t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                            qx = b[0] + t * (c[0] - b[0])
                            qy = b[1] + t * (c[1] - b[1])
                            qz = b[2] + t * (c[2] - b[2])
                        else:
                            den = va + vb + vc
                            if den == 0.0:
                                qx, qy, qz = a[0], a[1], a[2]
                            else:
                                v = vb / den
                                t = vc / den
                                qx = a[0] + abx * v + acx * t
                                qy = a[1] + aby * v + acy * t
                                qz = a[2] + abz * v + acz * t
    ex, ey, ez = px - qx, py - qy, pz - qz
    return np.sqrt(ex * ex + ey * ey + ez * ez)


@njit(cache=True)
def _fan_distance(pos, r, nx, ny, nz, ux, uy, uz, vx, vy, vz, ring, k, is_open, ang, x):
    """Distance of leaf x from the fan of r: to the triangle of the angular sector x lies in."""
    dx = pos[x, 0] - pos[r, 0]
    dy = pos[x, 1] - pos[r, 1]
    dz = pos[x, 2] - pos[r, 2]
    if k < 2:
        return np.sqrt(dx * dx + dy * dy + dz * dz)
    a = dx * ux + dy * uy + dz * uz
    b = dx * vx + dy * vy + dz * vz
    if a * a + b * b <= 1e-24 * (dx * dx + dy * dy + dz * dz) or a * a + b * b == 0.0:
        return abs(dx * nx + dy * ny + dz * nz)
    t = np.arctan2(b, a)
    # sector j: between ring[j] and ring[j + 1] counter-clockwise
    n_tri = k - 1 if is_open else k
    sector = -1
    for j in range(n_tri):
        t0 = ang[j]
        t1 = ang[(j + 1) % k]
        span = t1 - t0
        if span < 0.0:
            span += 2.0 * np.pi
        off = t - t0
        if off < 0.0:
            off += 2.0 * np.pi
        if off <= span:
            sector = j
            break
    px, py, pz = pos[x, 0], pos[x, 1], pos[x, 2]
    if sector >= 0:
        return _point_triangle(px, py, pz, pos[r], pos[ring[sector]], pos[ring[(sector + 1) % k]])
    # in the gap of an open fan: the nearer of its two end triangles
    d0 = _point_triangle(px, py, pz, pos[r], pos[ring[0]], pos[ring[1]])
    d1 = _point_triangle(px, py, pz, pos[r], pos[ring[k - 2]], pos[ring[k - 1]])
    return min(d0, d1)


@njit(cache=True, parallel=True)
def node_errors(pos, nrm, child, ring_off, ring, is_open, order, lo, hi, nodes):
    """e(r) for the inner ``nodes``: the largest distance of its leaves from its fan.

    0 on leaves. ``nodes`` in a shuffled order spreads the big nodes over the threads.
    """
    n = pos.shape[0]
    err = np.zeros(n)
    for i in prange(nodes.shape[0]):
        r = nodes[i]
        k = ring_off[r + 1] - ring_off[r]
        fan = ring[ring_off[r]:ring_off[r + 1]]
        nx, ny, nz = nrm[r, 0], nrm[r, 1], nrm[r, 2]
        ux, uy, uz, vx, vy, vz = _tangent(nx, ny, nz)
        ang = np.empty(max(k, 1))
        for j in range(k):
            dx = pos[fan[j], 0] - pos[r, 0]
            dy = pos[fan[j], 1] - pos[r, 1]
            dz = pos[fan[j], 2] - pos[r, 2]
            ang[j] = np.arctan2(dx * vx + dy * vy + dz * vz, dx * ux + dy * uy + dz * uz)
        e = 0.0
        for li in range(lo[r], hi[r]):
            d = _fan_distance(pos, r, nx, ny, nz, ux, uy, uz, vx, vy, vz, fan, k,
                              is_open[r], ang, order[li])
            if d > e:
                e = d
        err[r] = e
    return err


@njit(cache=True)
def bounds_up(pos, child, err, floor):
    """Monotone error bound and nested bounding-sphere radii, bottom-up.

    ``bound[r] = max(e(r), bound[children], floor)`` on inner nodes (0 on
    leaves); ``radius[r]`` contains the children's spheres, with a relative
    margin so that rounding cannot break the nesting.
    """
    n = pos.shape[0]
    bound = np.zeros(n)
    radius = np.zeros(n)
    for r in range(n):
        if child[r, 0] < 0:
            continue
        b = max(err[r], floor)
        rad = 0.0
        for s in range(2):
            c = child[r, s]
            if bound[c] > b:
                b = bound[c]
            dx = pos[c, 0] - pos[r, 0]
            dy = pos[c, 1] - pos[r, 1]
            dz = pos[c, 2] - pos[r, 2]
            rc = np.sqrt(dx * dx + dy * dy + dz * dz) + radius[c]
            if rc > rad:
                rad = rc
        bound[r] = b
        radius[r] = rad * (1.0 + 1e-9) + floor
    return bound, radius


# -- the front ------------------------------------------------------------------------


@njit(cache=True)
def _visible(pos, radius, planes, x):
    for i in range(planes.shape[0]):
        s = (planes[i, 0] * pos[x, 0] + planes[i, 1] * pos[x, 1] + planes[i, 2] * pos[x, 2]
             + planes[i, 3])
        if s < -radius[x]:
            return False
    return True


@njit(cache=True)
def _refine(pos, radius, bound, child, planes, eye, scale, x):
    """Is x refined: inner, in the frustum, bound(x) > d(x) * e_max / d_max.

    d(x) is the distance from the eye to x's bounding sphere (0 inside it),
    so that refining a node never requires refining a node above it.
    """
    if child[x, 0] < 0:
        return False
    if not _visible(pos, radius, planes, x):
        return False
    dx = pos[x, 0] - eye[0]
    dy = pos[x, 1] - eye[1]
    dz = pos[x, 2] - eye[2]
    d = np.sqrt(dx * dx + dy * dy + dz * dz) - radius[x]
    if d < 0.0:
        d = 0.0
    return bound[x] > d * scale


@njit(cache=True)
def _refine_memo(pos, radius, bound, child, planes, eye, scale, memo, tick, x):
    """``_refine`` of x, computed once per frame (``memo[x] == 2 * tick + answer``)."""
    m = memo[x]
    if m >> 1 == tick:
        return (m & 1) == 1
    r = _refine(pos, radius, bound, child, planes, eye, scale, x)
    memo[x] = 2 * tick + (1 if r else 0)
    return r


@njit(cache=True)
def update_front(pos, radius, bound, child, parent, state, front, n_front, planes, eye, scale,
                 memo, tick):
    """Move the front to a new camera; returns (front, active, nodes visited).

    Starting from the previous front, a front node either splits (while its
    children need it), stays, or gives way to its highest ancestor that no
    longer needs refining; only the nodes that change state are visited
    besides the front itself (an ancestor's test is made once per frame:
    ``memo``, ``tick``). ``active``: the front nodes in the frustum.
    """
    out = np.empty(max(2 * n_front + 16, 64), np.int64)
    m = 0
    visited = 0
    stack = np.empty(256, np.int64)
    for i in range(n_front):
        x = front[i]
        if state[x] != FRONT:
            continue
        visited += 1
        if _refine_memo(pos, radius, bound, child, planes, eye, scale, memo, tick, x):
            state[x] = REFINED
            stack[0] = child[x, 1]
            stack[1] = child[x, 0]
            top = 2
            while top > 0:
                top -= 1
                c = stack[top]
                visited += 1
                if _refine_memo(pos, radius, bound, child, planes, eye, scale, memo, tick, c):
                    state[c] = REFINED
                    if top + 2 > stack.shape[0]:
                        bigger = np.empty(2 * stack.shape[0], np.int64)
                        bigger[:top] = stack[:top]
                        stack = bigger
                    stack[top] = child[c, 1]
                    stack[top + 1] = child[c, 0]
                    top += 2
                else:
                    state[c] = FRONT
                    if m >= out.shape[0]:
                        bigger = np.empty(2 * out.shape[0], np.int64)
                        bigger[:m] = out[:m]
                        out = bigger
                    out[m] = c
                    m += 1
            continue
        # the highest ancestor that is no longer refined
        top_node = -1
        y = parent[x]
        while y >= 0:
            visited += 1
            if _refine_memo(pos, radius, bound, child, planes, eye, scale, memo, tick, y):
                break
            top_node = y
            y = parent[y]
        if top_node >= 0:
            state[top_node] = FRONT
            # clear the refined subtree below it
            stack[0] = child[top_node, 0]
            stack[1] = child[top_node, 1]
            sp = 2
            while sp > 0:
                sp -= 1
                c = stack[sp]
                was = state[c]
                state[c] = 0
                visited += 1
                if was == REFINED:
                    if sp + 2 > stack.shape[0]:
                        bigger = np.empty(2 * stack.shape[0], np.int64)
                        bigger[:sp] = stack[:sp]
                        stack = bigger
                    stack[sp] = child[c, 0]
                    stack[sp + 1] = child[c, 1]
                    sp += 2
            x = top_node
        if m >= out.shape[0]:
            bigger = np.empty(2 * out.shape[0], np.int64)
            bigger[:m] = out[:m]
            out = bigger
        out[m] = x
        m += 1
    # drop the entries collapsed after they were written; the active ones in view
    k = 0
    active = np.empty(m, np.int64)
    na = 0
    for i in range(m):
        x = out[i]
        if state[x] == FRONT:
            state[x] = -FRONT  # mark as written once
            out[k] = x
            k += 1
            if _visible(pos, radius, planes, x):
                active[na] = x
                na += 1
    for i in range(k):
        state[out[i]] = FRONT
    return out[:k].copy(), active[:na].copy(), visited


@njit(cache=True)
def active_nodes(pos, radius, planes, front):
    """The front nodes in the frustum (their bounding sphere meets it), in front order."""
    out = np.empty(front.shape[0], np.int64)
    m = 0
    for i in range(front.shape[0]):
        if _visible(pos, radius, planes, front[i]):
            out[m] = front[i]
            m += 1
    return out[:m].copy()


@njit(cache=True)
def _representative(pos, child, parent, state, a, y, up, up_tick, tick):
    """The active stand-in for fan neighbour y of the front node a.

    Below the front, the front ancestor is remembered for the frame
    (``up[y]`` valid when ``up_tick[y] == tick``) along the whole path walked.
    """
    if state[y] == 0:
        z = y
        while state[z] == 0 and up_tick[z] != tick:
            z = parent[z]
            if z < 0:
                return -1
        top = up[z] if state[z] == 0 else z
        while y != z:
            up[y] = top
            up_tick[y] = tick
            y = parent[y]
        return top
    while state[y] == REFINED:  # above the front: the child nearer to a
        c0 = child[y, 0]
        c1 = child[y, 1]
        d0 = 0.0
        d1 = 0.0
        for d in range(3):
            d0 += (pos[c0, d] - pos[a, d]) ** 2
            d1 += (pos[c1, d] - pos[a, d]) ** 2
        y = c0 if d0 <= d1 else c1
    return y


@njit(cache=True)
def _has_pair(mring, moff, v, s, t, closed):
    """Do s and t follow each other (either way) in v's mapped fan?"""
    a0 = moff[v]
    k = moff[v + 1] - a0
    last = k if closed[v] else k - 1
    for j in range(last):
        u = mring[a0 + j]
        w = mring[a0 + (j + 1) % k]
        if (u == s and w == t) or (u == t and w == s):
            return True
    return False


@njit(cache=True)
def _extras(mring, aidx, na):
    """Stand-ins that are not active yet: numbered ``na, na + 1, ...`` in ``aidx``."""
    extra = np.empty(64, np.int64)
    ne = 0
    for a in range(mring.shape[0]):
        y = mring[a]
        if y >= 0 and aidx[y] < 0:
            if ne >= extra.shape[0]:
                bigger = np.empty(2 * extra.shape[0], np.int64)
                bigger[:ne] = extra[:ne]
                extra = bigger
            extra[ne] = y
            aidx[y] = na + ne
            ne += 1
    return extra[:ne].copy()


@njit(cache=True)
def front_triangles(pos, child, parent, state, active, aidx, is_open, ring_off, ring, up,
                    up_tick, tick):
    """Distinct triangles of the active fans; returns (triangles, extra points).

    ``aidx[x]`` is x's index in ``active`` (or -1). A fan neighbour that is
    not active is replaced by its active ancestor or representative. A
    stand-in that is a front node outside the frustum joins the points as an
    *extra* (index ``len(active) + j``, its ``aidx`` set here; it draws no fan
    of its own), so the front has no ragged edge at the border of the view.
    A triangle is written once, by the smallest of its points whose fan holds it.
    Serial on purpose: a frame's work is a few milliseconds, where waking
    threads on a loaded machine costs more than it saves.
    """
    na = active.shape[0]
    moff = np.zeros(na + 1, np.int64)
    for i in range(na):
        x = active[i]
        moff[i + 1] = moff[i] + ring_off[x + 1] - ring_off[x]
    mring = np.empty(moff[na], np.int64)
    for i in range(na):
        x = active[i]
        for j in range(ring_off[x + 1] - ring_off[x]):
            mring[moff[i] + j] = _representative(pos, child, parent, state, x,
                                                 ring[ring_off[x] + j], up, up_tick, tick)
    extra = _extras(mring, aidx, na)
    ne = extra.shape[0]
    for a in range(mring.shape[0]):
        y = mring[a]
        mring[a] = aidx[y] if y >= 0 else -1
    # extras hold no fan: empty mapped rings after the active ones
    moff2 = np.empty(na + ne + 1, np.int64)
    moff2[:na + 1] = moff
    for e in range(ne):
        moff2[na + 1 + e] = moff[na]
    closed = np.zeros(na + ne, np.bool_)
    for i in range(na):
        closed[i] = not is_open[active[i]]
    tri = np.empty((moff[na], 3), np.int64)
    c = 0
    for i in range(na):
        k = moff2[i + 1] - moff2[i]
        last = k if closed[i] else k - 1
        base = moff2[i]
        for j in range(last):
            s = mring[base + j]
            t = mring[base + (j + 1) % k]
            if s < 0 or t < 0 or s == t or s == i or t == i:
                continue
            if (s < i and _has_pair(mring, moff2, s, i, t, closed)) or \
                    (t < i and _has_pair(mring, moff2, t, i, s, closed)):
                continue
            # the same triangle twice in this fan (a fan folding over stand-ins)
            dup = False
            for jj in range(j):
                s2 = mring[base + jj]
                t2 = mring[base + (jj + 1) % k]
                if (s2 == s and t2 == t) or (s2 == t and t2 == s):
                    dup = True
                    break
            if dup:
                continue
            tri[c, 0] = i
            tri[c, 1] = s
            tri[c, 2] = t
            c += 1
    return tri[:c].copy(), extra
