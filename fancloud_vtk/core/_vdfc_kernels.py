"""Numba kernels of the view-dependent fan cloud (paper section 8).

Building the forest (:func:`merge_forest`): a sequence of merges of the
point of lowest entropy ``p`` with its lowest-entropy neighbour ``q`` into a
new node ``r``, whose neighbours are those of ``p`` and ``q`` minus ``p`` and
``q``. The build tables are indexed by slot (``r`` takes ``p``'s slot, so the
slots keep the input's spatial order): the neighbour sets sit in a
fixed-width table of slots; the nodes wait in an indexed 4-ary heap of
(entropy, id) pairs (ties broken by the smaller id, so the order is
deterministic). Locked nodes (the shared
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

import sys

import numpy as np
from numba import njit, prange

try:  # the huge-page hint below needs numba's code generation internals
    from llvmlite import ir
    from numba import types
    from numba.core import cgutils
    from numba.extending import intrinsic
except ImportError:  # pragma: no cover - other numba versions: no hint
    intrinsic = None

from ._geometry_kernels import dist2, min_angle_cos, opposite, tangent, triangle_cross
from ._mesh_kernels import resolve_quads

MERGE_ENTROPY = 0
MERGE_HALF_EDGE = 1

FRONT = 1  #: state of a node on the front
REFINED = 2  #: state of a node whose children are shown instead


# -- adjacency --------------------------------------------------------------------------


@njit(cache=True, parallel=True)
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
    # every row sorted and without repeats, in place, in parallel
    size = np.empty(n, np.int64)
    for p in prange(n):
        s = off[p]
        e = off[p + 1]
        if e - s > 64:
            nb[s:e] = np.sort(nb[s:e])
        else:
            for a in range(s + 1, e):  # insertion sort: rows are short
                x = nb[a]
                b = a - 1
                while b >= s and nb[b] > x:
                    nb[b + 1] = nb[b]
                    b -= 1
                nb[b + 1] = x
        m = 0
        last = -1
        for a in range(s, e):
            if nb[a] != last:
                nb[s + m] = nb[a]
                m += 1
                last = nb[a]
        size[p] = m
    out_off = np.zeros(n + 1, np.int64)
    for p in range(n):
        out_off[p + 1] = out_off[p] + size[p]
    out = np.empty(out_off[n], np.int64)
    for p in prange(n):
        for a in range(size[p]):
            out[out_off[p] + a] = nb[off[p] + a]
    return out_off, out


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
def _other_blocks(label, offsets, ring, x, seen):
    """The distinct blocks of x's fan neighbours other than x's own, into ``seen``
    (at most its length); returns how many."""
    c = 0
    lx = label[x]
    for j in range(offsets[x], offsets[x + 1]):
        b = label[ring[j]]
        if b == lx:
            continue
        dup = False
        for e in range(c):
            if seen[e] == b:
                dup = True
                break
        if not dup and c < seen.shape[0]:
            seen[c] = b
            c += 1
    return c


@njit(cache=True)
def point_block_members(label, offsets, ring, n_blocks):
    """Blocks of points that share their boundary: point x is in its own block
    ``label[x]`` and in the block of each of its fan neighbours, so that every fan edge
    (x, y) has both points in y's block. Returns ``(off (n_blocks + 1,), members)``:
    block b's points, ascending, are ``members[off[b]:off[b + 1]]``."""
    n = label.shape[0]
    seen = np.empty(64, np.int64)
    count = np.zeros(n_blocks + 1, np.int64)
    for x in range(n):
        count[label[x] + 1] += 1
        for e in range(_other_blocks(label, offsets, ring, x, seen)):
            count[seen[e] + 1] += 1
    for b in range(n_blocks):
        count[b + 1] += count[b]
    members = np.empty(count[n_blocks], np.int64)
    fill = count[:n_blocks].copy()
    for x in range(n):
        members[fill[label[x]]] = x
        fill[label[x]] += 1
        for e in range(_other_blocks(label, offsets, ring, x, seen)):
            members[fill[seen[e]]] = x
            fill[seen[e]] += 1
    return count, members


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


# -- the merges: tables by slot, an indexed 4-ary heap ---------------------------------

# the head of a slot's row in the neighbour table R (int32), then its neighbour slots
_LEN = 0  # number of neighbours
_FLAGS = 1  # _LOCKED | _OPEN
_ID = 2  # the node id in the slot (-1: none)
_HEAD = 4  # first neighbour column
_LOCKED = 1
_OPEN = 2
_TAINT = 4  # built from, or next to, a marked node (see merge_forest)
_CORNER = 8  # open, at a corner of the boundary (``open0 == 2``, see merge_forest)
#: ``open0`` codes of :func:`merge_forest`: closed, open, open at a corner.
CLOSED, OPEN, CORNER = 0, 1, 2


if sys.platform.startswith("linux") and intrinsic is not None:
    @intrinsic
    def _madvise(typingctx, addr, length, advice):
        sig = types.int32(types.uintp, types.uintp, types.int32)

        def codegen(context, builder, signature, args):
            ptr_t = ir.IntType(8).as_pointer()
            fnty = ir.FunctionType(ir.IntType(32), [ptr_t, ir.IntType(64), ir.IntType(32)])
            fn = cgutils.get_or_insert_function(builder.module, fnty, "madvise")
            return builder.call(fn, [builder.inttoptr(args[0], ptr_t), args[1], args[2]])

        return sig, codegen

    @njit(cache=True)
    def _huge_pages(a):
        """Ask Linux for transparent huge pages on the 2 MiB pages inside a's (untouched) buffer.

        The merges jump about in tables of hundreds of MB: with 4 KiB pages
        nearly every access is also a TLB miss. Only a hint (errors ignored).
        """
        start = a.ctypes.data
        end = start + a.size * a.itemsize
        lo = (start + (1 << 21) - 1) & ~((1 << 21) - 1)
        hi = end & ~((1 << 21) - 1)
        if hi > lo:
            _madvise(np.uintp(lo), np.uintp(hi - lo), np.int32(14))  # MADV_HUGEPAGE
else:
    @njit(cache=True)
    def _huge_pages(a):
        """No-op away from Linux (or without numba's internals)."""


@njit(cache=True)
def _hbase(hbuf):
    """Root index that puts every group of 4 children on one 64-byte line."""
    return (((64 - hbuf.ctypes.data % 64) % 64) // 16 + 3) % 4


@njit(cache=True)
def _iup(hv, hk, hpos, base, i, key, tag):
    """Place (key, tag) at i or above in the indexed 4-ary heap."""
    mask = np.int64(0xFFFFFFFF)
    while i > 0:
        par = (i - 1) >> 2
        e = 2 * (base + par)
        pk = hk[e]
        pt = hv[e + 1]
        if not (key < pk or (key == pk and tag < pt)):
            break
        f = 2 * (base + i)
        hv[f] = hv[e]
        hv[f + 1] = pt
        hpos[pt & mask] = i
        i = par
    f = 2 * (base + i)
    hk[f] = key
    hv[f + 1] = tag
    hpos[tag & mask] = i


@njit(cache=True)
def _idown(hv, hk, hpos, base, i, key, tag, size):
    """Place (key, tag) at i or below in the indexed 4-ary heap of ``size`` entries."""
    mask = np.int64(0xFFFFFFFF)
    while True:
        c = 4 * i + 1
        if c >= size:
            break
        e = c + 4
        if e > size:
            e = size
        bc = c
        bk = hk[2 * (base + c)]
        bt = hv[2 * (base + c) + 1]
        for j in range(c + 1, e):
            jk = hk[2 * (base + j)]
            jt = hv[2 * (base + j) + 1]
            if jk < bk or (jk == bk and jt < bt):
                bc = j
                bk = jk
                bt = jt
        if not (bk < key or (bk == key and bt < tag)):
            break
        f = 2 * (base + i)
        hk[f] = bk
        hv[f + 1] = bt
        hpos[bt & mask] = i
        i = bc
    f = 2 * (base + i)
    hk[f] = key
    hv[f + 1] = tag
    hpos[tag & mask] = i


@njit(cache=True)
def _iremove(hv, hk, hpos, base, i, size):
    """Remove the entry at i; returns the new size."""
    mask = np.int64(0xFFFFFFFF)
    hpos[hv[2 * (base + i) + 1] & mask] = -1
    size -= 1
    if i == size:
        return size
    lk = hk[2 * (base + size)]
    lt = hv[2 * (base + size) + 1]
    if i > 0:
        par = (i - 1) >> 2
        pk = hk[2 * (base + par)]
        if lk < pk or (lk == pk and lt < hv[2 * (base + par) + 1]):
            _iup(hv, hk, hpos, base, i, lk, lt)
            return size
    _idown(hv, hk, hpos, base, i, lk, lt, size)
    return size


@njit(cache=True)
def _ikey(hv, hk, hpos, base, s, key, size):
    """Change the key of slot s's entry."""
    i = hpos[s]
    f = 2 * (base + i)
    old = hk[f]
    tag = hv[f + 1]
    if key < old:
        _iup(hv, hk, hpos, base, i, key, tag)
    elif key > old:
        _idown(hv, hk, hpos, base, i, key, tag, size)


@njit(cache=True)
def _terms(F, C, R, s, dbar):
    """``point_terms`` of the node in slot s (same arithmetic, on the slot tables).

    A copy, not a call: ``point_terms`` on strided views of ``F`` gives the
    same bits but made the 1M-point build about 9% slower (measured).
    """
    k = R[s, _LEN]
    if k == 0:
        return 0.0, 0.0, 0.0
    has_col = C.shape[0] > 0
    s_d = 0.0
    s_c = 0.0
    s_col = 0.0
    px, py, pz = F[s, 0], F[s, 1], F[s, 2]
    nx, ny, nz = F[s, 3], F[s, 4], F[s, 5]
    for a in range(k):
        q = R[s, _HEAD + a]
        dx = px - F[q, 0]
        dy = py - F[q, 1]
        dz = pz - F[q, 2]
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d <= 0.0:
            continue
        s_d += d
        sgn = 1.0
        if (F[q, 3] * nx + F[q, 4] * ny + F[q, 5] * nz) < 0.0:
            sgn = -1.0
        ex = sgn * F[q, 3] - nx
        ey = sgn * F[q, 4] - ny
        ez = sgn * F[q, 5] - nz
        s_c += np.sqrt(ex * ex + ey * ey + ez * ez) / d
        if has_col:
            cx = C[q, 0] - C[s, 0]
            cy = C[q, 1] - C[s, 1]
            cz = C[q, 2] - C[s, 2]
            s_col += np.sqrt(cx * cx + cy * cy + cz * cz) / d
    return s_d / k / dbar, s_c / k * dbar, s_col / k * dbar


@njit(cache=True)
def _cc(F, R, s, dbar):
    """``point_cc`` of the node in slot s (same arithmetic, curvature terms in ``F[:, 7]``)."""
    k = R[s, _LEN]
    if k == 0:
        return 0.0
    acc = 0.0
    for a in range(k):
        q = R[s, _HEAD + a]
        dx = F[s, 0] - F[q, 0]
        dy = F[s, 1] - F[q, 1]
        dz = F[s, 2] - F[q, 2]
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d > 0.0:
            acc += abs(F[q, 7] - F[s, 7]) / d
    return acc / k * dbar


@njit(cache=True)
def _sorted_ring(F, s, nbrs, k, is_open, out, ang):
    """``nbrs[:k]`` (slots) sorted counter-clockwise around slot s's normal into ``out``.

    An open fan starts after its widest angular gap. ``ang``: scratch of k floats.
    """
    ux, uy, uz, vx, vy, vz = tangent(F[s, 3], F[s, 4], F[s, 5])
    for a in range(k):
        q = nbrs[a]
        dx = F[q, 0] - F[s, 0]
        dy = F[q, 1] - F[s, 1]
        dz = F[q, 2] - F[s, 2]
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


@njit(cache=True)
def _open_sector(F, R, s, ids, ang):
    """The angle an open node's fan covers: 2 pi minus the widest angular gap between
    its neighbours around its normal (pi on a straight boundary, pi / 2 at a square
    corner). ``ids``, ``ang``: scratch of at least its neighbour count."""
    k = R[s, _LEN]
    if k < 2:
        return 0.0
    for a in range(k):
        ids[a] = R[s, _HEAD + a]
    _sorted_ring(F, s, ids, k, False, ids, ang)  # in place: each entry is read first
    widest = ang[0] + 2.0 * np.pi - ang[k - 1]
    for a in range(k - 1):
        if ang[a + 1] - ang[a] > widest:
            widest = ang[a + 1] - ang[a]
    return 2.0 * np.pi - widest


@njit(cache=True)
def _boundary_weights(F, R, sp, sq, kp, kq, ids, ang):
    """Where r goes when p or q is open (on the boundary): (wp, wq), or (-1, -1) when
    neither is. r takes the open node's position, so that the boundary never moves
    inwards; of two open nodes, the one whose fan covers the smaller angle (the sharper
    corner of the boundary; a node marked as a corner first; on a tie, the larger entropy,
    then q)."""
    op = (R[sp, _FLAGS] & _OPEN) != 0
    oq = (R[sq, _FLAGS] & _OPEN) != 0
    if not (op or oq):
        return -1.0, -1.0
    if op and not oq:
        return 1.0, 0.0
    if oq and not op:
        return 0.0, 1.0
    cp = (R[sp, _FLAGS] & _CORNER) != 0
    cq = (R[sq, _FLAGS] & _CORNER) != 0
    if cp and not cq:
        return 1.0, 0.0
    if cq and not cp:
        return 0.0, 1.0
    ap = _open_sector(F, R, sp, ids, ang)
    aq = _open_sector(F, R, sq, ids, ang)
    if ap < aq - 1e-9 or (abs(ap - aq) <= 1e-9 and kp > kq):
        return 1.0, 0.0
    return 0.0, 1.0


@njit(cache=True)
def _key_of(w, dist, curv, cc, cterm):
    """The entropy of a node from its four terms."""
    return w[0] * dist + w[1] * curv + w[2] * cc + w[3] * cterm


@njit(cache=True, nogil=True)
def merge_forest(pos0, nrm0, col0, open0, adj_off, adj, locked0, w, dbar, method, min_alive,
                 width, taint0):
    """Merge nodes until ``min_alive`` remain or no pair can merge.

    Inputs are ``m`` nodes (leaves or nodes of an earlier build) with their
    neighbour sets (CSR, local ids); ``open0`` is ``CLOSED``, ``OPEN`` (on the
    boundary) or ``CORNER`` (open, at a corner of the boundary) per node, and
    so is the returned ``open`` of the new nodes. A merge with an open node
    puts r at an open node's position (:func:`_boundary_weights`): the
    boundary of the forest's fronts stays where the points' boundary is.
    New nodes get ids ``m, m + 1, ...`` in merge order. Returns ``(k,
    child (k, 2), pos (k, 3), nrm (k, 3), col (k, c), open (k,),
    ring_off (k + 1,), ring, alive (m + k,),
    out_off, out_adj)``: the ``k`` new nodes, their children and fans at
    merge time, which nodes are left, and the neighbour sets of those left
    (CSR over the alive ids in increasing order), then ``taint (k,)`` of the
    new nodes when made and ``alive_taint (m + k,)`` of the nodes left.

    ``taint0`` marks input nodes whose influence is followed: a merge is
    tainted when p, q, a neighbour of either, or a neighbour of a neighbour
    of p (whose entropies chose q) is tainted; a tainted merge taints r and
    r's neighbours. What no taint reaches was built from the same data in
    the same order whatever happened at the marked nodes (the blocks' check).

    Internally every table is indexed by *slot*: node x of the input sits in
    slot x and a merged node takes the slot of its p, so that the slots keep
    the input's spatial order and a merge touches nearby memory. ``F`` holds
    a slot's position, normal, entropy and curvature term (one cache line),
    ``R`` its neighbour slots behind a head of (count, flags, node id).
    """
    m = pos0.shape[0]
    nc = col0.shape[1]
    stride = ((_HEAD + width + 15) // 16) * 16
    # per slot: pos, nrm, key, curv (one 64-byte line when aligned)
    fbuf = np.empty(m * 8 + 8)
    _huge_pages(fbuf)
    fo = ((64 - fbuf.ctypes.data % 64) % 64) // 8
    F = fbuf[fo:fo + 8 * m].reshape((m, 8))
    rbuf = np.empty(m * stride + 16, np.int32)
    _huge_pages(rbuf)
    ro = ((64 - rbuf.ctypes.data % 64) % 64) // 4
    R = rbuf[ro:ro + m * stride].reshape((m, stride))
    C = np.empty((m if nc > 0 else 0, nc))
    for s in range(m):
        x = s  # the input's node x in slot x
        for d in range(3):
            F[s, d] = pos0[x, d]
            F[s, 3 + d] = nrm0[x, d]
        for d in range(nc):
            C[s, d] = col0[x, d]
        deg = adj_off[x + 1] - adj_off[x]
        if deg > width:
            deg = width  # cannot happen for fans of at most width - 1 neighbours
        for a in range(deg):
            R[s, _HEAD + a] = adj[adj_off[x] + a]
        R[s, _LEN] = deg
        fl = 0
        if locked0[x]:
            fl |= _LOCKED
        if open0[x]:
            fl |= _OPEN
        if open0[x] == CORNER:
            fl |= _CORNER
        if taint0[x]:
            fl |= _TAINT
        R[s, _FLAGS] = fl
        R[s, _ID] = x
    Cc = C if nc > 0 else np.zeros((0, 3))
    dist = np.empty(m)
    cterm = np.empty(m)
    for s in range(m):
        dist[s], F[s, 7], cterm[s] = _terms(F, Cc, R, s, dbar)
    for s in range(m):
        cc = 0.0
        if w[2] != 0.0:
            cc = _cc(F, R, s, dbar)
        F[s, 6] = _key_of(w, dist[s], F[s, 7], cc, cterm[s])
    dist = np.empty(0)
    cterm = np.empty(0)
    # the heap: an indexed 4-ary heap of (key, id << 32 | slot), the position of
    # every slot's entry in hpos (-1: not in the heap)
    hbuf = np.empty(2 * m + 16, np.int64)
    _huge_pages(hbuf)
    hb = _hbase(hbuf)
    hk = hbuf.view(np.float64)
    hpos = np.full(m, -1, np.int32)
    size = 0
    for s in range(m):
        if not (R[s, _FLAGS] & _LOCKED):
            hk[2 * (hb + size)] = F[s, 6]
            hbuf[2 * (hb + size) + 1] = (np.int64(s) << 32) | s
            hpos[s] = size
            size += 1
    for i in range((size - 2) // 4, -1, -1):
        f = 2 * (hb + i)
        _idown(hbuf, hk, hpos, hb, i, hk[f], hbuf[f + 1], size)

    child = np.empty((m, 2), np.int64)
    opos = np.empty((m, 3))
    onrm = np.empty((m, 3))
    ocol = np.zeros((m, nc))
    oopn = np.zeros(m, np.uint8)
    otaint = np.zeros(m, np.bool_)
    track = taint0.any()
    ring_off = np.zeros(m + 1, np.int64)
    ring = np.empty(8 * m + 64, np.int64)
    buf = np.empty(2 * width + 2, np.int64)
    srt = np.empty(2 * width + 2, np.int64)
    angbuf = np.empty(2 * width + 2)
    skip = np.zeros(2 * width + 2, np.bool_)
    tdist = np.empty(2 * width + 2)
    tcterm = np.empty(2 * width + 2)
    n_alive = m
    k = 0
    mask = np.int64(0xFFFFFFFF)
    while size > 0 and n_alive > min_alive:
        tag = hbuf[2 * hb + 1]
        size = _iremove(hbuf, hk, hpos, hb, 0, size)
        sp = tag & mask
        p = tag >> 32
        kp = F[sp, 6]
        lp = R[sp, _LEN]
        # the lowest-entropy neighbour that can merge with p
        sq = -1
        for a in range(lp):
            skip[a] = False
        while True:
            best = -1
            bk = 0.0
            bi = 0
            for a in range(lp):
                if skip[a]:
                    continue
                y = R[sp, _HEAD + a]
                if R[y, _FLAGS] & _LOCKED:
                    continue
                yk = F[y, 6]
                if best < 0 or yk < bk or (yk == bk and R[y, _ID] < bi):
                    best = a
                    bk = yk
                    bi = R[y, _ID]
            if best < 0:
                break
            y = R[sp, _HEAD + best]
            ly = R[y, _LEN]
            if lp - 1 + ly <= width:  # the union cannot be larger
                sq = y
                break
            c = lp - 1
            for b in range(ly):
                z = R[y, _HEAD + b]
                if z == sp:
                    continue
                found = False
                for e in range(lp):
                    if R[sp, _HEAD + e] == z:
                        found = True
                        break
                if not found:
                    c += 1
            if c <= width:
                sq = y
                break
            skip[best] = True
        if sq < 0:
            continue  # p waits outside the heap until its neighbourhood changes
        q = np.int64(R[sq, _ID])
        tainted = False
        if track:
            tainted = ((R[sp, _FLAGS] | R[sq, _FLAGS]) & _TAINT) != 0
            for b in range(R[sq, _LEN]):
                if R[R[sq, _HEAD + b], _FLAGS] & _TAINT:
                    tainted = True
            for b in range(lp):
                y = R[sp, _HEAD + b]
                if R[y, _FLAGS] & _TAINT:
                    tainted = True
                for e in range(R[y, _LEN]):
                    if R[R[y, _HEAD + e], _FLAGS] & _TAINT:
                        tainted = True
        if hpos[sq] >= 0:
            size = _iremove(hbuf, hk, hpos, hb, hpos[sq], size)
        r = m + k
        # the union of the neighbour sets, minus p and q
        c = 0
        for b in range(lp):
            z = R[sp, _HEAD + b]
            if z != sq:
                buf[c] = z
                c += 1
        lq = R[sq, _LEN]
        for b in range(lq):
            z = R[sq, _HEAD + b]
            if z == sp:
                continue
            found = False
            for e in range(lp):
                if R[sp, _HEAD + e] == z:
                    found = True
                    break
            if not found:
                buf[c] = z
                c += 1
        # position, normal, colour of r
        kq = F[sq, 6]
        mp = kp if kp > 0.0 else 0.0
        mq = kq if kq > 0.0 else 0.0
        wp, wq = _boundary_weights(F, R, sp, sq, kp, kq, srt, angbuf)
        if wp >= 0.0:
            pass  # on the boundary: r at the open node (docs/vdfc.md)
        elif method == MERGE_HALF_EDGE:
            wp, wq = 0.0, 1.0
        elif mp + mq > 0.0:
            wp, wq = mp / (mp + mq), mq / (mp + mq)
        else:
            wp, wq = 0.5, 0.5
        sgn = 1.0
        if F[sp, 3] * F[sq, 3] + F[sp, 4] * F[sq, 4] + F[sp, 5] * F[sq, 5] < 0.0:
            sgn = -1.0
        ln = 0.0
        x0 = wp * F[sp, 0] + wq * F[sq, 0]
        x1 = wp * F[sp, 1] + wq * F[sq, 1]
        x2 = wp * F[sp, 2] + wq * F[sq, 2]
        n0 = (mp + 1e-300) * F[sp, 3] + sgn * (mq + 1e-300) * F[sq, 3]
        n1 = (mp + 1e-300) * F[sp, 4] + sgn * (mq + 1e-300) * F[sq, 4]
        n2 = (mp + 1e-300) * F[sp, 5] + sgn * (mq + 1e-300) * F[sq, 5]
        ln = n0 * n0
        ln += n1 * n1
        ln += n2 * n2
        ln = np.sqrt(ln)
        if ln > 1e-12:
            n0 /= ln
            n1 /= ln
            n2 /= ln
        else:
            n0, n1, n2 = F[sp, 3], F[sp, 4], F[sp, 5]
        for d in range(nc):
            C[sp, d] = wp * C[sp, d] + wq * C[sq, d]
            ocol[k, d] = C[sp, d]
        is_open = ((R[sp, _FLAGS] | R[sq, _FLAGS]) & _OPEN) != 0
        F[sp, 0], F[sp, 1], F[sp, 2] = x0, x1, x2
        F[sp, 3], F[sp, 4], F[sp, 5] = n0, n1, n2
        opos[k, 0], opos[k, 1], opos[k, 2] = x0, x1, x2
        onrm[k, 0], onrm[k, 1], onrm[k, 2] = n0, n1, n2
        corner = ((R[sp, _FLAGS] & _CORNER) != 0 and wp == 1.0) \
            or ((R[sq, _FLAGS] & _CORNER) != 0 and wq == 1.0)
        oopn[k] = CORNER if corner else (OPEN if is_open else CLOSED)
        child[k, 0] = p
        child[k, 1] = q
        need = ring_off[k] + c
        if need > ring.shape[0]:
            bigger = np.empty(2 * need, np.int64)
            bigger[:ring_off[k]] = ring[:ring_off[k]]
            ring = bigger
        _sorted_ring(F, sp, buf, c, is_open, srt, angbuf)
        for b in range(c):
            ring[ring_off[k] + b] = R[srt[b], _ID]
        ring_off[k + 1] = need
        # r takes p's slot
        for b in range(c):
            R[sp, _HEAD + b] = buf[b]
        R[sp, _LEN] = c
        R[sp, _ID] = r
        R[sp, _FLAGS] = (_OPEN if is_open else 0) | (_TAINT if tainted else 0) \
            | (_CORNER if corner else 0)
        otaint[k] = tainted
        R[sq, _ID] = -1
        R[sq, _FLAGS] = 0
        n_alive -= 1
        # the neighbours see r instead of p and q
        for b in range(c):
            sx = buf[b]
            if tainted:
                R[sx, _FLAGS] |= _TAINT
            e = 0
            for a in range(R[sx, _LEN]):
                z = R[sx, _HEAD + a]
                if z != sp and z != sq:
                    R[sx, _HEAD + e] = z
                    e += 1
            R[sx, _HEAD + e] = sp
            R[sx, _LEN] = e + 1
        # entropies of r and its neighbours
        tdist[0], F[sp, 7], tcterm[0] = _terms(F, Cc, R, sp, dbar)
        for b in range(c):
            sx = buf[b]
            tdist[b + 1], F[sx, 7], tcterm[b + 1] = _terms(F, Cc, R, sx, dbar)
        for b in range(-1, c):
            sx = sp if b < 0 else buf[b]
            cc = 0.0
            if w[2] != 0.0:
                cc = _cc(F, R, sx, dbar)
            value = _key_of(w, tdist[b + 1], F[sx, 7], cc, tcterm[b + 1])
            F[sx, 6] = value
            if R[sx, _FLAGS] & _LOCKED:
                continue
            if hpos[sx] < 0:
                size += 1
                _iup(hbuf, hk, hpos, hb, size - 1, value, (np.int64(R[sx, _ID]) << 32) | sx)
            else:
                _ikey(hbuf, hk, hpos, hb, sx, value, size)
        k += 1
    # the nodes left and their neighbour sets
    total = m + k
    alive = np.zeros(total, np.bool_)
    slot_of = np.full(total, -1, np.int64)
    for s in range(m):
        x = R[s, _ID]
        if x >= 0:
            alive[x] = True
            slot_of[x] = s
    alive_taint = np.zeros(total, np.bool_)
    for x in range(total):
        if alive[x]:
            alive_taint[x] = (R[slot_of[x], _FLAGS] & _TAINT) != 0
    out_off = np.zeros(total + 1, np.int64)
    for x in range(total):
        out_off[x + 1] = out_off[x] + (R[slot_of[x], _LEN] if alive[x] else 0)
    out_adj = np.empty(out_off[total], np.int64)
    for x in range(total):
        if alive[x]:
            s = slot_of[x]
            row = np.empty(R[s, _LEN], np.int64)
            for a in range(R[s, _LEN]):
                row[a] = R[R[s, _HEAD + a], _ID]
            out_adj[out_off[x]:out_off[x + 1]] = np.sort(row)
    return (k, child[:k].copy(), opos[:k].copy(), onrm[:k].copy(),
            ocol[:k].copy(), oopn[:k].copy(), ring_off[:k + 1].copy(),
            ring[:ring_off[k]].copy(), alive, out_off, out_adj, otaint[:k].copy(), alive_taint)


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


_PSEUDO_EPS = 1e-9  # pseudo-angle margin below which the sector test falls back to arctan2


@njit(cache=True)
def _pseudo_angle(y, x):
    """The "diamond angle" of (x, y) != 0: in [0, 4), increasing with arctan2(y, x) mod 2 pi."""
    if y >= 0.0:
        if x >= 0.0:
            return y / (x + y)
        return 1.0 - x / (y - x)
    if x < 0.0:
        return 2.0 - y / (-x - y)
    return 3.0 + x / (x - y)


@njit(cache=True)
def _sector(t, ang, f0, k, n_tri, period):
    """First sector j (between ring j and j + 1 counter-clockwise) holding angle t, or -1.

    The ring's angles are ``ang[f0:f0 + k]``.
    """
    for j in range(n_tri):
        t0 = ang[f0 + j]
        t1 = ang[f0 + j + 1] if j + 1 < k else ang[f0]  # no integer modulo: it is slow
        span = t1 - t0
        if span < 0.0:
            span += period
        off = t - t0
        if off < 0.0:
            off += period
        if off <= span:
            return j
    return -1


@njit(cache=True)
def _plane_normal(pos, a, b, c, nx, ny, nz, out, i):
    """``out[i]``: the unit normal of triangle abc (a degenerate one: (nx, ny, nz))."""
    ex, ey, ez = pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]
    fx, fy, fz = pos[c, 0] - pos[a, 0], pos[c, 1] - pos[a, 1], pos[c, 2] - pos[a, 2]
    cx = ey * fz - ez * fy
    cy = ez * fx - ex * fz
    cz = ex * fy - ey * fx
    ln = np.sqrt(cx * cx + cy * cy + cz * cz)
    scale = (ex * ex + ey * ey + ez * ez) * (fx * fx + fy * fy + fz * fz)
    if ln * ln <= 1e-24 * scale or ln == 0.0:
        out[i, 0], out[i, 1], out[i, 2] = nx, ny, nz
    else:
        out[i, 0], out[i, 1], out[i, 2] = cx / ln, cy / ln, cz / ln


@njit(cache=True)
def _fan_distance(pos, r, px, py, pz, nx, ny, nz, ux, uy, uz, vx, vy, vz, ring, f0, k, is_open,
                  pa, ang, pn):
    """Distance of the point p from the fan of r: to the plane of the triangle of the
    angular sector p lies in (the fan as the piecewise-planar surface it stands for).

    The fan is ``ring[f0:f0 + k]``; ``pa[f0:f0 + k]`` its pseudo-angles, ``ang[f0:f0 + k]``
    its angles, filled on first need (``ang[f0]`` is nan until then).
    """
    dx = px - pos[r, 0]
    dy = py - pos[r, 1]
    dz = pz - pos[r, 2]
    if k < 2:  # no triangle: the tangent plane of r
        return abs(dx * nx + dy * ny + dz * nz)
    a = dx * ux + dy * uy + dz * uz
    b = dx * vx + dy * vy + dz * vz
    if a * a + b * b <= 1e-24 * (dx * dx + dy * dy + dz * dz) or a * a + b * b == 0.0:
        return abs(dx * nx + dy * ny + dz * nz)
    n_tri = k - 1 if is_open else k
    t = _pseudo_angle(b, a)
    # the sector by pseudo-angle, unless p is that near a ring direction that the
    # rounding of arctan2 could put it on the other side
    near = False
    for j in range(k):
        g = abs(t - pa[f0 + j])
        if g < _PSEUDO_EPS or g > 4.0 - _PSEUDO_EPS:
            near = True
            break
    if not near:
        sector = _sector(t, pa, f0, k, n_tri, 4.0)
    else:
        if np.isnan(ang[f0]):
            for j in range(k):
                q = ring[f0 + j]
                ex = pos[q, 0] - pos[r, 0]
                ey = pos[q, 1] - pos[r, 1]
                ez = pos[q, 2] - pos[r, 2]
                ang[f0 + j] = np.arctan2(ex * vx + ey * vy + ez * vz, ex * ux + ey * uy + ez * uz)
        sector = _sector(np.arctan2(b, a), ang, f0, k, n_tri, 2.0 * np.pi)
    if sector >= 0:
        g = f0 + sector
        return abs(dx * pn[g, 0] + dy * pn[g, 1] + dz * pn[g, 2])
    # in the gap of an open fan: the nearer of its two end triangles' planes
    g = f0 + k - 2
    return min(abs(dx * pn[f0, 0] + dy * pn[f0, 1] + dz * pn[f0, 2]),
               abs(dx * pn[g, 0] + dy * pn[g, 1] + dz * pn[g, 2]))


@njit(cache=True, parallel=True)
def node_errors(pos, nrm, child, ring_off, ring, is_open, order, lo, hi, nodes):
    """e(r) for the inner ``nodes``: the largest distance of its leaves from its fan.

    0 on leaves. ``nodes`` in a shuffled order spreads the big nodes over the threads.
    The nodes go in chunks, each with its own scratch for one fan (no allocation per
    node, no table the size of all fans).
    """
    n = pos.shape[0]
    err = np.zeros(n)
    # the leaves' positions in leaf order: a node's leaves are one contiguous run
    lp = np.empty((order.shape[0], 3))
    for i in prange(order.shape[0]):
        x = order[i]
        lp[i, 0] = pos[x, 0]
        lp[i, 1] = pos[x, 1]
        lp[i, 2] = pos[x, 2]
    width = 1
    for r in range(n):
        width = max(width, ring_off[r + 1] - ring_off[r])
    n_nodes = nodes.shape[0]
    n_chunks = min(256, max(1, n_nodes))
    for chunk in prange(n_chunks):
        fan = np.empty(width, np.int64)
        pa = np.empty(width)  # the fan's pseudo-angles
        ang = np.empty(width)  # its angles, filled on first need (nan: not yet)
        pn = np.empty((width, 3))  # unit normal of each sector's triangle
        for i in range(chunk * n_nodes // n_chunks, (chunk + 1) * n_nodes // n_chunks):
            r = nodes[i]
            f0 = ring_off[r]
            k = ring_off[r + 1] - f0
            nx, ny, nz = nrm[r, 0], nrm[r, 1], nrm[r, 2]
            ux, uy, uz, vx, vy, vz = tangent(nx, ny, nz)
            for j in range(k):
                fan[j] = ring[f0 + j]
            for j in range(k):
                q = fan[j]
                dx = pos[q, 0] - pos[r, 0]
                dy = pos[q, 1] - pos[r, 1]
                dz = pos[q, 2] - pos[r, 2]
                a = dx * ux + dy * uy + dz * uz
                b = dx * vx + dy * vy + dz * vz
                pa[j] = _pseudo_angle(b, a) if a != 0.0 or b != 0.0 else 0.0
                ang[j] = np.nan
                _plane_normal(pos, r, q, fan[j + 1] if j + 1 < k else fan[0], nx, ny, nz, pn, j)
            opn = is_open[r]
            # a leaf's distance from any sector's plane is at most |d.n| + |d_t| tilt, with
            # d_t its offset along the tangent plane and tilt the largest sine between a
            # sector's normal and n: the leaves under that bound cannot raise e
            tilt = 0.0
            for j in range(k):
                c = pn[j, 0] * nx + pn[j, 1] * ny + pn[j, 2] * nz
                t2 = pn[j, 0] * pn[j, 0] + pn[j, 1] * pn[j, 1] + pn[j, 2] * pn[j, 2] - c * c
                if t2 > tilt:
                    tilt = t2
            tilt = np.sqrt(tilt)
            e = 0.0
            for li in range(lo[r], hi[r]):
                dx = lp[li, 0] - pos[r, 0]
                dy = lp[li, 1] - pos[r, 1]
                dz = lp[li, 2] - pos[r, 2]
                dn = abs(dx * nx + dy * ny + dz * nz)
                a = dx * ux + dy * uy + dz * uz
                b = dx * vx + dy * vy + dz * vz
                dt = np.sqrt(a * a + b * b)
                if dn + dt * tilt + 1e-9 * (dn + dt) < e:
                    continue
                d = _fan_distance(pos, r, lp[li, 0], lp[li, 1], lp[li, 2], nx, ny, nz, ux, uy,
                                  uz, vx, vy, vz, fan, 0, k, opn, pa, ang, pn)
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


@njit(cache=True, parallel=True)
def front_decisions(pos, radius, bound, child, parent, front, planes, eye, scale, memo, tick,
                    n_chunks):
    """What every front node does for the new camera: (decision, ancestors tested, in view).

    The decision is -2 when the node splits, else the highest ancestor that
    no longer needs refining, to which it gives way (-1: none, it stays; then
    whether it is in the frustum is known too).
    These tests depend on the camera only, so they run in ``n_chunks``
    ranges of the front in parallel (two threads may both make an
    ancestor's test and write the same ``memo``); :func:`update_front`
    then moves the front serially.
    """
    n_front = front.shape[0]
    dec = np.empty(n_front, np.int64)
    walk = np.zeros(n_front, np.int64)
    vis = np.zeros(n_front, np.bool_)
    for ch in prange(n_chunks):
        for i in range(n_front * ch // n_chunks, n_front * (ch + 1) // n_chunks):
            x = front[i]
            if _refine_memo(pos, radius, bound, child, planes, eye, scale, memo, tick, x):
                dec[i] = -2
                continue
            top_node = -1
            y = parent[x]
            w = 0
            while y >= 0:
                w += 1
                if _refine_memo(pos, radius, bound, child, planes, eye, scale, memo, tick, y):
                    break
                top_node = y
                y = parent[y]
            dec[i] = top_node
            walk[i] = w
            if top_node < 0:
                vis[i] = _visible(pos, radius, planes, x)
    return dec, walk, vis


@njit(cache=True)
def _push(out, ovis, m, x, v):
    """Append x (in view: v) at m, growing the arrays when full."""
    if m >= out.shape[0]:
        bigger = np.empty(2 * out.shape[0], np.int64)
        bigger[:m] = out[:m]
        out = bigger
        more = np.empty(out.shape[0], np.bool_)
        more[:m] = ovis[:m]
        ovis = more
    out[m] = x
    ovis[m] = v
    return out, ovis


@njit(cache=True)
def update_front(pos, radius, bound, child, parent, state, front, planes, eye, scale, memo,
                 tick, dec, walk, vis):
    """Move the front to a new camera; returns (front, active, nodes visited).

    Starting from the previous front, a front node either splits (while its
    children need it), stays, or gives way to its highest ancestor that no
    longer needs refining (``dec``, ``walk``: :func:`front_decisions`); only
    the nodes that change state are visited besides the front itself (an
    ancestor's test is made once per frame: ``memo``, ``tick``).
    ``active``: the front nodes in the frustum (``vis``: of the nodes that
    stay, from :func:`front_decisions`).
    """
    n_front = front.shape[0]
    out = np.empty(max(2 * n_front + 16, 64), np.int64)
    ovis = np.empty(out.shape[0], np.bool_)
    m = 0
    visited = 0
    stack = np.empty(256, np.int64)
    for i in range(n_front):
        x = front[i]
        if state[x] != FRONT:
            continue
        visited += 1 + walk[i]
        if dec[i] == -2:
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
                    out, ovis = _push(out, ovis, m, c, _visible(pos, radius, planes, c))
                    m += 1
            continue
        # the highest ancestor that is no longer refined
        top_node = dec[i]
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
            out, ovis = _push(out, ovis, m, top_node, _visible(pos, radius, planes, top_node))
        else:
            out, ovis = _push(out, ovis, m, x, vis[i])
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
            if ovis[i]:
                active[na] = x
                na += 1
    for i in range(k):
        state[out[i]] = FRONT
    return out[:k].copy(), active[:na].copy(), visited


@njit(cache=True)
def _representative(pos, child, parent, state, a, y, is_open, border):
    """The active stand-in for fan neighbour y of the front node a.

    The walks are short (one or two levels on average: the front is graded),
    so nothing is remembered between calls. With ``border`` (y is an end of
    a's open fan: a neighbour along the boundary), the walk down takes the
    open child where one child is open and the other not: the boundary
    neighbour's stand-in stays on the boundary (the nearer child may be an
    inner point, and the fan would leave the boundary strip between them
    uncovered: seen on the topobathy DEM's outer border).
    """
    while state[y] == 0:  # below the front: its front ancestor
        y = parent[y]
        if y < 0:
            return -1
    while state[y] == REFINED:  # above the front: the child nearer to a
        c0 = child[y, 0]
        c1 = child[y, 1]
        if border and is_open[c0] != is_open[c1]:
            y = c0 if is_open[c0] else c1
            continue
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
    a1 = moff[v + 1]
    if a1 - a0 < 2:
        return False
    for j in range(a0, a1 - 1):
        u = mring[j]
        w = mring[j + 1]
        if (u == s and w == t) or (u == t and w == s):
            return True
    if closed[v]:  # the closing pair (last, first)
        u = mring[a1 - 1]
        w = mring[a0]
        if (u == s and w == t) or (u == t and w == s):
            return True
    return False


@njit(cache=True)
def _stand_in(pos, child, parent, state, is_open, ring, rep, x, s0, j, k):
    """The stand-in of entry j of the k of front node x's ring (from ``s0``): the one
    ``rep`` remembers while it is a front node, else found again (and remembered); -1
    for none. The ends of an open fan's ring are its neighbours along the boundary."""
    y = rep[s0 + j]
    if state[y] != FRONT:
        y = _representative(pos, child, parent, state, x, ring[s0 + j], is_open,
                            is_open[x] and (j == 0 or j == k - 1))
        if y >= 0:
            rep[s0 + j] = y
    return y


@njit(cache=True)
def _number_new(mring, q0, q1, aidx, extra, ne, na):
    """Number the stand-ins not yet points in ``mring[q0:q1]`` (written ``-2 - node``):
    each new one becomes extra ``ne`` (point ``na + ne``, its ``aidx`` set), in the order
    of first use. Returns (extra, ne): ``extra`` grown when full."""
    for q in range(q0, q1):
        v = mring[q]
        if v < -1:
            y = -2 - v
            v = aidx[y]
            if v < 0:
                if ne >= extra.shape[0]:
                    bigger = np.empty(2 * extra.shape[0], np.int64)
                    for e in range(ne):
                        bigger[e] = extra[e]
                    extra = bigger
                extra[ne] = y
                v = na + ne
                aidx[y] = v
                ne += 1
            mring[q] = v
    return extra, ne


@njit(cache=True)
def _folded(pos, nrm, active, extra, na, i, s, t):
    """Does the triangle (i, s, t) of front points (``active`` then ``extra``) turn
    against i's normal, beyond round-off (:meth:`Front.folded_triangles`)?"""
    p = active[i] if i < na else extra[i - na]
    a = active[s] if s < na else extra[s - na]
    b = active[t] if t < na else extra[t - na]
    cx, cy, cz = triangle_cross(pos, p, a, b)
    det = cx * nrm[p, 0] + cy * nrm[p, 1] + cz * nrm[p, 2]
    return det < -1e-9 * np.sqrt(dist2(pos, p, a) * dist2(pos, p, b))


@njit(cache=True)
def _beyond(pos, planes, a, b, c):
    """Do the nodes a, b and c all lie outside one of the frustum's planes?"""
    for k in range(planes.shape[0]):
        out = True
        for x in (a, b, c):
            if planes[k, 0] * pos[x, 0] + planes[k, 1] * pos[x, 1] + planes[k, 2] * pos[x, 2] \
                    + planes[k, 3] >= 0.0:
                out = False
                break
        if out:
            return True
    return False


@njit(cache=True, parallel=True)
def front_triangles(pos, nrm, child, parent, state, active, aidx, is_open, ring_off, ring,
                    rep, n_chunks, with_held, planes):
    """Distinct triangles of the active fans; returns (triangles, held, extra points).

    ``aidx[x]`` is x's index in ``active`` (or -1). A fan neighbour that is
    not active is replaced by its active ancestor or representative.
    ``rep`` (parallel to ``ring``, kept between frames) remembers each ring
    entry's last stand-in: it is still the stand-in while it is a front node
    (the front ancestor of a node is unique, and the walk down to the nearer
    child passes only refined nodes, which a front node below keeps refined),
    so after a small camera move most walks are skipped. A stand-in that is a
    front node outside the frustum joins the points as an *extra* (index
    ``len(active) + j`` in the order of first use, its ``aidx`` set here), so
    the front has no ragged edge at the border of the view. An extra's fan
    (its stand-ins found as above; one that is not yet a point is numbered
    after the extras, in the order of first use, draws no fan, and is left
    out again if no triangle drawn uses it)
    draws its triangles but those wholly beyond one of the frustum's
    ``planes`` (as :meth:`Camera.frustum` gives them): where the fans in view
    leave a gap towards the points beyond the view's edge, it covers the gap
    as fans in view cover each other's (without it a few points in view,
    near its edge, were under no triangle: docs/vdfc.md). A triangle is
    written once, by the smallest of its points whose fan holds it, in the
    order of the fans; ``held``: how many of its points' fans hold it (1 to
    3; all 1 unless ``with_held``). A triangle (i, s, t) that turns against
    i's normal (``nrm``: a fan made invalid by merges, the paper's Figure 14)
    is written the other way round, (i, t, s), so that it runs as its
    neighbours do (drawn as it came, it shows its back: dark specks in a
    render); the last value returned counts them.

    The stand-ins and the triangles run in ``n_chunks`` ranges of fans in
    parallel (1: serially; the result is the same): each fan writes only its
    own ring entries and its own rows, compacted at the end.
    """
    na = active.shape[0]
    moff = np.zeros(na + 1, np.int64)
    for ch in prange(n_chunks):  # the fan sizes (scattered reads), then their sums
        for i in range(na * ch // n_chunks, na * (ch + 1) // n_chunks):
            x = active[i]
            moff[i + 1] = ring_off[x + 1] - ring_off[x]
    for i in range(na):
        moff[i + 1] += moff[i]
    n = moff[na]
    mring = np.empty(n, np.int64)
    closed = np.empty(na, np.bool_)
    pending = np.zeros(na, np.bool_)  # fans with a new stand-in outside the view
    # stand-ins (a new one outside the view: -2 - its node, numbered below in order)
    for ch in prange(n_chunks):
        lo = na * ch // n_chunks
        hi = na * (ch + 1) // n_chunks
        for i in range(lo, hi):
            x = active[i]
            closed[i] = not is_open[x]
            s0 = ring_off[x]
            k = moff[i + 1] - moff[i]
            for j in range(k):
                y = _stand_in(pos, child, parent, state, is_open, ring, rep, x, s0, j, k)
                if y < 0:
                    mring[moff[i] + j] = -1
                else:
                    v = aidx[y]
                    if v < 0:
                        v = -2 - y
                        pending[i] = True
                    mring[moff[i] + j] = v
    extra = np.empty(64, np.int64)
    ne = 0
    for i in range(na):  # numbered in the order of first use, as a serial pass would
        if pending[i]:
            extra, ne = _number_new(mring, moff[i], moff[i + 1], aidx, extra, ne, na)
    # the extras' fans too (their stand-ins as above; a new one, a front node beyond the
    # view that no fan in view reaches, is numbered after them and draws no fan): they
    # draw their triangles but those wholly beyond the view (below), so that the view's
    # edge is covered where the fans in view leave a gap towards the points beyond it
    nx = ne  # the extras with a fan
    moff2 = np.empty(na + nx + 1, np.int64)
    for i in range(na + 1):
        moff2[i] = moff[i]
    for e in range(nx):
        y = extra[e]
        moff2[na + 1 + e] = moff2[na + e] + ring_off[y + 1] - ring_off[y]
    n2 = moff2[na + nx]
    if nx:
        grown = np.empty(n2, np.int64)
        for q in range(n):
            grown[q] = mring[q]
        mring = grown
    for ch in prange(n_chunks):
        for e in range(nx * ch // n_chunks, nx * (ch + 1) // n_chunks):
            y = extra[e]
            s0 = ring_off[y]
            b = moff2[na + e]
            k = moff2[na + e + 1] - b
            for j in range(k):
                z = _stand_in(pos, child, parent, state, is_open, ring, rep, y, s0, j, k)
                if z < 0:
                    mring[b + j] = -1
                else:
                    v = aidx[z]
                    mring[b + j] = v if v >= 0 else -2 - z
    extra, ne = _number_new(mring, moff2[na], n2, aidx, extra, ne, na)
    ex = np.empty(ne, np.int64)
    for e in range(ne):
        ex[e] = extra[e]
    extra = ex
    moff3 = np.empty(na + ne + 1, np.int64)  # the last extras' fans are empty
    for i in range(na + nx + 1):
        moff3[i] = moff2[i]
    for e in range(nx, ne):
        moff3[na + 1 + e] = n2
    moff2 = moff3
    closed2 = np.zeros(na + ne, np.bool_)
    for i in range(na):
        closed2[i] = closed[i]
    for e in range(nx):
        closed2[na + e] = not is_open[extra[e]]
    n = n2
    nf = na + nx  # the fans drawn
    tri = np.empty((n, 3), np.int64)
    hold = np.empty(n, np.int64)
    cnt = np.zeros(nf, np.int64)
    folded = np.zeros(nf, np.int64)
    for ch in prange(n_chunks):
        lo = nf * ch // n_chunks
        hi = nf * (ch + 1) // n_chunks
        for i in range(lo, hi):
            k = moff2[i + 1] - moff2[i]
            last = k if closed2[i] else k - 1
            base = moff2[i]
            c = base
            for j in range(last):
                s = mring[base + j]
                t = mring[base + j + 1] if j + 1 < k else mring[base]
                if s < 0 or t < 0 or s == t or s == i or t == i:
                    continue
                if i >= na and s >= na and t >= na and _beyond(pos, planes, extra[i - na],
                                                               extra[s - na], extra[t - na]):
                    continue  # an extra's triangle wholly beyond the view
                if (s < i and _has_pair(mring, moff2, s, i, t, closed2)) or \
                        (t < i and _has_pair(mring, moff2, t, i, s, closed2)):
                    continue
                dup = False
                for jj in range(j):
                    s2 = mring[base + jj]
                    t2 = mring[base + jj + 1]
                    if (s2 == s and t2 == t) or (s2 == t and t2 == s):
                        dup = True
                        break
                if dup:
                    continue
                tri[c, 0] = i
                tri[c, 1] = s
                tri[c, 2] = t
                if _folded(pos, nrm, active, extra, na, i, s, t):
                    tri[c, 1] = t  # drawn the way its neighbours run
                    tri[c, 2] = s
                    folded[i] += 1
                h = 1  # the fans that hold it: i's, and the larger points' that do
                if with_held:
                    if s > i and _has_pair(mring, moff2, s, i, t, closed2):
                        h += 1
                    if t > i and _has_pair(mring, moff2, t, i, s, closed2):
                        h += 1
                hold[c] = h
                c += 1
            cnt[i] = c - base
    at = np.empty(nf + 1, np.int64)  # where each fan's rows go
    at[0] = 0
    for i in range(nf):
        at[i + 1] = at[i] + cnt[i]
    out = np.empty((at[nf], 3), np.int64)
    held = np.empty(at[nf], np.int64)
    for ch in prange(n_chunks):
        for i in range(nf * ch // n_chunks, nf * (ch + 1) // n_chunks):
            b = moff2[i]
            for r in range(cnt[i]):
                out[at[i] + r, 0] = tri[b + r, 0]
                out[at[i] + r, 1] = tri[b + r, 1]
                out[at[i] + r, 2] = tri[b + r, 2]
                held[at[i] + r] = hold[b + r]
    if ne > nx:  # the last extras that no triangle drawn uses are left out
        new = np.full(ne - nx, -1, np.int64)
        for r in range(at[na], at[nf]):  # only the extras' fans reach them
            for k in range(3):
                v = out[r, k] - na - nx
                if v >= 0:
                    new[v] = 0
        kept = nx
        for e in range(nx, ne):
            if new[e - nx] == 0:
                new[e - nx] = na + kept
                extra[kept] = extra[e]
                kept += 1
            else:
                aidx[extra[e]] = -1
        for r in range(at[na], at[nf]):
            for k in range(3):
                v = out[r, k] - na - nx
                if v >= 0:
                    out[r, k] = new[v]
        extra = extra[:kept].copy()
    return out, held, extra, folded.sum()


@njit(cache=True, parallel=True)
def front_superfluous(pos, nrm, tri, held, n_chunks):
    """Which front triangles stay when superfluous ones go (paper section 4).

    A convex quadrilateral x u y v covered by both triangulations, x y u +
    x y v and u v x and/or u v y (stand-ins make fans of different levels
    overlap so), keeps one: the complete diagonal, then the one more fans hold
    (``held``: 1 to 3), then the better-shaped (``resolve_quads`` of the
    mesh). Quads are found through the edges, indexed by their smaller
    vertex (in ``n_chunks`` ranges in parallel), and resolved in the order of
    that vertex. Returns ``alive``.
    """
    n = pos.shape[0]
    m = tri.shape[0]
    # the edges of every triangle, under their smaller vertex: (other vertex, triangle)
    off = np.zeros(n + 1, np.int64)
    for t in range(m):
        for k in range(3):
            a = tri[t, k]
            b = tri[t, k + 1] if k < 2 else tri[t, 0]
            off[min(a, b) + 1] += 1
    for v in range(n):
        off[v + 1] += off[v]
    other = np.empty(3 * m, np.int64)
    etri = np.empty(3 * m, np.int64)
    fill = off[:n].copy()
    for t in range(m):
        for k in range(3):
            a = tri[t, k]
            b = tri[t, k + 1] if k < 2 else tri[t, 0]
            lo = min(a, b)
            other[fill[lo]] = max(a, b)
            etri[fill[lo]] = t
            fill[lo] += 1
    # a doubly covered quad has a triangle fewer than three fans hold, at x or y
    suspect = np.zeros(n, np.bool_)
    for ch in prange(n_chunks):  # threads may both write True to a point: the same value
        for t in range(m * ch // n_chunks, m * (ch + 1) // n_chunks):
            if held[t] < 3:
                suspect[tri[t, 0]] = True
                suspect[tri[t, 1]] = True
                suspect[tri[t, 2]] = True
    # the doubly covered quads, per smaller vertex x, in one pass: chunk ch writes from
    # room[ch] on, room enough for every pair of x's edge entries (pages never written
    # are never touched), and the chunks' rows are joined in order
    room = np.zeros(n_chunks + 1, np.int64)
    for ch in range(n_chunks):
        r = 0
        for x in range(n * ch // n_chunks, n * (ch + 1) // n_chunks):
            d = off[x + 1] - off[x]
            r += d * (d - 1) // 2
        room[ch + 1] = room[ch] + r
    found = np.empty((room[n_chunks], 4), np.int64)
    count = np.zeros(n_chunks, np.int64)
    for ch in prange(n_chunks):
        ys = np.empty(64, np.int64)
        ts = np.empty(64, np.int64)
        c = room[ch]
        for x in range(n * ch // n_chunks, n * (ch + 1) // n_chunks):
            d = off[x + 1] - off[x]
            if d < 2:
                continue
            near = suspect[x]  # a quad here needs x or one of its y to be suspect
            if not near:
                for q in range(off[x], off[x + 1]):
                    if suspect[other[q]]:
                        near = True
                        break
            if not near:
                continue
            if d > ys.shape[0]:
                ys = np.empty(2 * d, np.int64)
                ts = np.empty(2 * d, np.int64)
            # x's edges sorted by their other vertex (insertion sort: a few entries)
            g = 0
            for q in range(off[x], off[x + 1]):
                yv = other[q]
                tv = etri[q]
                j = g
                while j > 0 and (ys[j - 1] > yv or (ys[j - 1] == yv and ts[j - 1] > tv)):
                    ys[j] = ys[j - 1]
                    ts[j] = ts[j - 1]
                    j -= 1
                ys[j] = yv
                ts[j] = tv
                g += 1
            i = 0
            while i < g:
                y = ys[i]
                e = i + 1
                while e < g and ys[e] == y:
                    e += 1
                if e - i >= 2 and (suspect[x] or suspect[y]):
                    for i1 in range(i, e):
                        t1 = ts[i1]
                        u = tri[t1, 0] + tri[t1, 1] + tri[t1, 2] - x - y
                        for i2 in range(i1 + 1, e):
                            t2 = ts[i2]
                            v = tri[t2, 0] + tri[t2, 1] + tri[t2, 2] - x - y
                            if u == v:
                                continue
                            lo = min(u, v)
                            hi = max(u, v)
                            t3 = -1
                            t4 = -1
                            for q in range(off[lo], off[lo + 1]):
                                if other[q] != hi:
                                    continue
                                t = etri[q]
                                w = tri[t, 0] + tri[t, 1] + tri[t, 2] - lo - hi
                                if w == x and (t3 < 0 or t < t3):
                                    t3 = t
                                elif w == y and (t4 < 0 or t < t4):
                                    t4 = t
                            if t3 < 0 and t4 < 0:
                                continue
                            # a convex quad: each diagonal separates the other's ends
                            # (else u v x or u v y covers what x y u + x y v do not)
                            if not opposite(pos, nrm, x, y, u, v) \
                                    or not opposite(pos, nrm, u, v, x, y):
                                continue
                            found[c, 0] = t1
                            found[c, 1] = t2
                            found[c, 2] = t3
                            found[c, 3] = t4
                            c += 1
                i = e
        count[ch] = c - room[ch]
    total = 0
    for ch in range(n_chunks):
        total += count[ch]
    rows = np.empty((total, 4), np.int64)
    r = 0
    for ch in range(n_chunks):
        for q in range(room[ch], room[ch] + count[ch]):
            for k in range(4):
                rows[r, k] = found[q, k]
            r += 1
    # the shapes of the quads' triangles only (resolve_quads reads no others)
    quality = np.zeros(m)
    for q in prange(total):
        for k in range(4):
            t = rows[q, k]
            if t >= 0:
                quality[t] = -min_angle_cos(pos, tri[t, 0], tri[t, 1], tri[t, 2])
    alive = np.ones(m, np.bool_)
    resolve_quads(rows, held, quality, alive, True)
    return alive


@njit(cache=True, parallel=True)
def front_points(active, extra, aidx, pos, nrm, level, err, n_chunks):
    """The front's points in order (``active`` then ``extra``): node ids, positions,
    normals, levels and errors gathered in ``n_chunks`` ranges in parallel, and
    their ``aidx`` entries cleared (-1) for the next frame."""
    na = active.shape[0]
    n = na + extra.shape[0]
    ids = np.empty(n, np.int64)
    p = np.empty((n, 3), pos.dtype)
    q = np.empty((n, 3), nrm.dtype)
    lv = np.empty(n, level.dtype)
    e = np.empty(n, err.dtype)
    for ch in prange(n_chunks):
        for i in range(n * ch // n_chunks, n * (ch + 1) // n_chunks):
            x = active[i] if i < na else extra[i - na]
            ids[i] = x
            aidx[x] = -1
            for d in range(3):
                p[i, d] = pos[x, d]
                q[i, d] = nrm[x, d]
            lv[i] = level[x]
            e[i] = err[x]
    return ids, p, q, lv, e


@njit(cache=True)
def inner_postorder(child, n_leaves):
    """New ids for the merged nodes: depth-first post-order of the forest, from ``n_leaves``.

    Children keep smaller ids than their parents, and the nodes of one
    subtree (which lie close together in space) get neighbouring ids, so that
    the walks of the front touch neighbouring memory. Returns ``new_of_old``
    (leaves keep their ids).
    """
    n = child.shape[0]
    parent = np.full(n, -1, np.int64)
    for x in range(n):
        if child[x, 0] >= 0:
            parent[child[x, 0]] = x
            parent[child[x, 1]] = x
    new = np.arange(n)
    nxt = n_leaves
    stack = np.empty(n + 1, np.int64)
    for root in range(n):
        if parent[root] >= 0 or child[root, 0] < 0:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            x = stack[top]
            top -= 1
            if x < 0:
                new[~x] = nxt
                nxt += 1
                continue
            top += 1
            stack[top] = ~x
            for s in range(2):
                c = child[x, s]
                if child[c, 0] >= 0:
                    top += 1
                    stack[top] = c
    return new


@njit(cache=True, parallel=True)
def renumbered(new, pos, nrm, col, child, ring_off, ring, opn):
    """The node tables with node ``x`` moved to ``new[x]`` (children, rings renamed)."""
    n = new.shape[0]
    old = np.empty(n, np.int64)
    for x in range(n):
        old[new[x]] = x
    pos2 = np.empty_like(pos)
    nrm2 = np.empty_like(nrm)
    col2 = np.empty_like(col)
    child2 = np.empty_like(child)
    opn2 = np.empty_like(opn)
    off2 = np.zeros(n + 1, np.int64)
    for y in range(n):
        x = old[y]
        off2[y + 1] = off2[y] + ring_off[x + 1] - ring_off[x]
    ring2 = np.empty(off2[n], np.int64)
    for y in prange(n):
        x = old[y]
        for d in range(3):
            pos2[y, d] = pos[x, d]
            nrm2[y, d] = nrm[x, d]
        for d in range(col.shape[1]):
            col2[y, d] = col[x, d]
        for s in range(2):
            c = child[x, s]
            child2[y, s] = new[c] if c >= 0 else -1
        opn2[y] = opn[x]
        a = off2[y]
        for j in range(ring_off[x], ring_off[x + 1]):
            ring2[a] = new[ring[j]]
            a += 1
    return pos2, nrm2, col2, child2, off2, ring2, opn2
