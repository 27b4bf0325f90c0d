"""Uniform-grid neighbour search in numba (paper section 3, step 7: "uniform 3D cells").

The points are bucketed into cubic cells of side ``h``; occupied cells live
in an open-addressing hash table (so the grid costs memory per *occupied*
cell, not per cell of the bounding box) and are numbered in Morton order,
with their points stored contiguously (a counting sort, stable in the input
index). Reordering the points by cell gives a spatially coherent order in
which the candidate pools of consecutive points are close in memory.

Exactness: the candidates of a point ``p`` are the points of the
``(2w+1)^3`` cells around its cell. Any point not among them is farther
from ``p`` than ``r_safe = w h + (distance from p to its cell's nearest
face)``, so the candidates within ``r_safe`` are exactly the nearest
points of the whole cloud, in order. Callers use only those ("certified")
candidates and widen ``w`` when they need more.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: coordinates per axis are packed into 21 bits of an int64 key
AXIS_BITS = 21
AXIS_MAX = (1 << AXIS_BITS) - 1


@njit(cache=True)
def _hash(key, mask):
    h = np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)
    return np.int64(h >> np.uint64(32)) & mask


@njit(cache=True)
def _pack(ix, iy, iz):
    return ix | (iy << AXIS_BITS) | (iz << (2 * AXIS_BITS))


@njit(cache=True)
def _cell_of(points, i, lo, inv_h):
    ix = int((points[i, 0] - lo[0]) * inv_h)
    iy = int((points[i, 1] - lo[1]) * inv_h)
    iz = int((points[i, 2] - lo[2]) * inv_h)
    return min(ix, AXIS_MAX), min(iy, AXIS_MAX), min(iz, AXIS_MAX)


@njit(cache=True)
def _table_size(n):
    size = 16
    while size < 2 * n:
        size *= 2
    return size


@njit(cache=True)
def count_cells(points, lo, inv_h):
    """Number of occupied cells for cell side ``1 / inv_h``."""
    n = points.shape[0]
    size = _table_size(n)
    mask = size - 1
    tab = np.full(size, -1, np.int64)
    n_cells = 0
    for i in range(n):
        ix, iy, iz = _cell_of(points, i, lo, inv_h)
        key = _pack(ix, iy, iz)
        s = _hash(key, mask)
        while tab[s] != -1 and tab[s] != key:
            s = (s + 1) & mask
        if tab[s] == -1:
            tab[s] = key
            n_cells += 1
    return n_cells


@njit(cache=True)
def _spread3(v):
    """Spread the low 21 bits of v to every third bit (for Morton codes)."""
    v &= 0x1FFFFF
    v = (v | (v << 32)) & 0x1F00000000FFFF
    v = (v | (v << 16)) & 0x1F0000FF0000FF
    v = (v | (v << 8)) & 0x100F00F00F00F00F
    v = (v | (v << 4)) & 0x10C30C30C30C30C3
    v = (v | (v << 2)) & 0x1249249249249249
    return v


@njit(cache=True)
def build_grid(points, lo, inv_h, expected_cells):
    """Bucket the points into cells.

    Returns ``(order, start, cell_xyz, table, n_dup)``: the point
    indices sorted by cell (cells in Morton order, points of a cell by
    index); ``start[c]:start[c + 1]`` the points of cell ``c`` in ``order``;
    ``cell_xyz[c]`` its integer coordinates; the hash table of ``[packed
    key, cell number]`` rows; and the number of points identical to an earlier point
    of the same cell (exact duplicates always share a cell).
    """
    n = points.shape[0]
    keys = _point_keys(points, lo, inv_h)
    # the table starts at twice the expected number of cells and doubles
    # (starting over) when it gets more than half full
    size = _table_size(max(expected_cells, 8))
    while True:
        mask = size - 1
        tab_key = np.full(size, -1, np.int64)
        tab_val = np.full(size, -1, np.int64)
        cell_of = np.empty(n, np.int64)
        limit = size // 2
        xyz = np.empty((limit, 3), np.int64)
        counts = np.zeros(limit, np.int64)
        n_cells = 0
        full = False
        for i in range(n):
            key = keys[i]
            s = _hash(key, mask)
            while tab_key[s] != -1 and tab_key[s] != key:
                s = (s + 1) & mask
            if tab_key[s] == -1:
                if n_cells == limit:
                    full = True
                    break
                tab_key[s] = key
                tab_val[s] = n_cells
                xyz[n_cells, 0] = key & AXIS_MAX
                xyz[n_cells, 1] = (key >> AXIS_BITS) & AXIS_MAX
                xyz[n_cells, 2] = key >> (2 * AXIS_BITS)
                n_cells += 1
            c = tab_val[s]
            cell_of[i] = c
            counts[c] += 1
        if not full:
            break
        size *= 4
    morton = np.empty(n_cells, np.int64)
    for c in range(n_cells):
        morton[c] = _spread3(xyz[c, 0]) | (_spread3(xyz[c, 1]) << 1) | (_spread3(xyz[c, 2]) << 2)
    rank_order = np.argsort(morton, kind="mergesort")
    rank = np.empty(n_cells, np.int64)
    for r in range(n_cells):
        rank[rank_order[r]] = r
    start = np.zeros(n_cells + 1, np.int64)
    cell_xyz = np.empty((n_cells, 3), np.int64)
    for c in range(n_cells):
        start[rank[c] + 1] = counts[c]
        cell_xyz[rank[c]] = xyz[c]
    for r in range(n_cells):
        start[r + 1] += start[r]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        r = rank[cell_of[i]]
        order[fill[r]] = i
        fill[r] += 1
    # a compact table for the lookups (fewer cache misses): [key, cell] pairs
    size = _table_size(n_cells)
    mask = size - 1
    table = np.full((size, 2), -1, np.int64)
    for r in range(n_cells):
        key = _pack(cell_xyz[r, 0], cell_xyz[r, 1], cell_xyz[r, 2])
        s = _hash(key, mask)
        while table[s, 0] != -1:
            s = (s + 1) & mask
        table[s, 0] = key
        table[s, 1] = r
    # exact duplicates: compare the points within each cell
    return order, start, cell_xyz, table, _count_duplicates(points, order, start)


@njit(cache=True, parallel=True)
def _point_keys(points, lo, inv_h):
    n = points.shape[0]
    keys = np.empty(n, np.int64)
    for i in prange(n):
        ix, iy, iz = _cell_of(points, i, lo, inv_h)
        keys[i] = _pack(ix, iy, iz)
    return keys


@njit(cache=True, parallel=True)
def _count_duplicates(points, order, start):
    """Points identical to an earlier point of their cell (duplicates share a cell)."""
    n_cells = start.shape[0] - 1
    n_dup = 0
    for r in prange(n_cells):
        if start[r + 1] - start[r] > 16:
            n_dup += _count_duplicates_sorted(points, order[start[r]:start[r + 1]])
            continue
        for a in range(start[r] + 1, start[r + 1]):
            i = order[a]
            for b in range(start[r], a):
                j = order[b]
                if (points[i, 0] == points[j, 0] and points[i, 1] == points[j, 1]
                        and points[i, 2] == points[j, 2]):
                    n_dup += 1
                    break
    return n_dup


@njit(cache=True)
def _count_duplicates_sorted(points, idx):
    """Duplicates among points[idx] by a lexicographic sort (for crowded cells)."""
    m = idx.shape[0]
    o = np.argsort(points[idx, 2], kind="mergesort")
    for a in (1, 0):
        key = np.empty(m)
        for t in range(m):
            key[t] = points[idx[o[t]], a]
        o = o[np.argsort(key, kind="mergesort")]
    n_dup = 0
    for t in range(1, m):
        i = idx[o[t]]
        j = idx[o[t - 1]]
        if points[i, 0] == points[j, 0] and points[i, 1] == points[j, 1] \
                and points[i, 2] == points[j, 2]:
            n_dup += 1
    return n_dup


@njit(cache=True, parallel=True)
def bounds(points):
    """Per-axis minimum and maximum of an (n, 3) array."""
    n = points.shape[0]
    n_chunks = 64
    lo = np.full((n_chunks, 3), np.inf)
    hi = np.full((n_chunks, 3), -np.inf)
    for c in prange(n_chunks):
        for i in range((n * c) // n_chunks, (n * (c + 1)) // n_chunks):
            for a in range(3):
                v = points[i, a]
                if v < lo[c, a]:
                    lo[c, a] = v
                if v > hi[c, a]:
                    hi[c, a] = v
    out_lo = np.empty(3)
    out_hi = np.empty(3)
    for a in range(3):
        out_lo[a] = lo[:, a].min()
        out_hi[a] = hi[:, a].max()
    return out_lo, out_hi


@njit(cache=True, parallel=True)
def reorder(points, order):
    """(points[order], inverse permutation of order)."""
    n = order.shape[0]
    out = np.empty((n, 3), points.dtype)
    pos = np.empty(n, np.int64)
    for s in prange(n):
        i = order[s]
        pos[i] = s
        out[s, 0] = points[i, 0]
        out[s, 1] = points[i, 1]
        out[s, 2] = points[i, 2]
    return out, pos


@njit(cache=True)
def lookup(table, ix, iy, iz):
    """Cell number of the cell with integer coordinates (ix, iy, iz), or -1."""
    if ix < 0 or iy < 0 or iz < 0 or ix > AXIS_MAX or iy > AXIS_MAX or iz > AXIS_MAX:
        return -1
    key = _pack(ix, iy, iz)
    mask = table.shape[0] - 1
    s = _hash(key, mask)
    while True:
        t = table[s, 0]
        if t == key:
            return table[s, 1]
        if t == -1:
            return -1
        s = (s + 1) & mask


@njit(cache=True)
def block_size(start, cell_xyz, table, c, w):
    """Number of points in the (2w+1)^3 cells around cell c."""
    total = 0
    for dz in range(-w, w + 1):
        for dy in range(-w, w + 1):
            for dx in range(-w, w + 1):
                r = lookup(table, cell_xyz[c, 0] + dx, cell_xyz[c, 1] + dy,
                           cell_xyz[c, 2] + dz)
                if r >= 0:
                    total += start[r + 1] - start[r]
    return total


@njit(cache=True)
def gather_block(start, cell_xyz, table, c, w, out):
    """Write the (sorted-order) indices of the points around cell c to out; return the count.

    With the points reordered by cell, cell r holds ``start[r]:start[r+1]``.
    """
    m = 0
    for dz in range(-w, w + 1):
        for dy in range(-w, w + 1):
            for dx in range(-w, w + 1):
                r = lookup(table, cell_xyz[c, 0] + dx, cell_xyz[c, 1] + dy,
                           cell_xyz[c, 2] + dz)
                if r >= 0:
                    for i in range(start[r], start[r + 1]):
                        out[m] = i
                        m += 1
    return m


@njit(cache=True)
def safe_radius(points, p, lo, h, cell_xyz, c, w):
    """Radius within which the (2w+1)^3 block around cell c holds every point near p."""
    best = h
    for a in range(3):
        f = (points[p, a] - lo[a]) - cell_xyz[c, a] * h
        if f < best:
            best = f
        g = h - f
        if g < best:
            best = g
    if best < 0.0:
        best = 0.0
    return w * h + best


@njit(cache=True)
def certify(points, p, cand, m, r_safe, pool, dist):
    """Copy the candidates within r_safe of p (p itself excluded) to pool/dist.

    ``dist`` receives squared distances. Returns the number copied.
    """
    r2 = r_safe * r_safe
    px = points[p, 0]
    py = points[p, 1]
    pz = points[p, 2]
    cnt = 0
    for a in range(m):
        q = cand[a]
        dx = points[q, 0] - px
        dy = points[q, 1] - py
        dz = points[q, 2] - pz
        d = dx * dx + dy * dy + dz * dz
        pool[cnt] = q  # branch-free: written always, kept when certified
        dist[cnt] = d
        cnt += (d <= r2) & (q != p)
    return cnt


@njit(cache=True)
def sort_within(pool, dist, m, r2):
    """Partition pool[:m] so the candidates with squared distance <= r2 come first, sorted.

    Returns their number; the others follow unsorted (select them lazily).
    """
    n1 = 0
    for i in range(m):  # branch-free partition: swap always, advance when inside
        q = pool[i]
        d = dist[i]
        pool[i] = pool[n1]
        dist[i] = dist[n1]
        pool[n1] = q
        dist[n1] = d
        n1 += d <= r2
    sort_pool(pool, dist, n1)
    return n1


@njit(cache=True)
def select_nearest(pool, dist, c, m):
    """Swap the nearest of pool[c:m] (by distance, then index) into position c."""
    best = c
    for i in range(c + 1, m):
        if dist[i] < dist[best] or (dist[i] == dist[best] and pool[i] < pool[best]):
            best = i
    if best != c:
        t = pool[c]
        pool[c] = pool[best]
        pool[best] = t
        d = dist[c]
        dist[c] = dist[best]
        dist[best] = d


@njit(cache=True)
def sort_pool(pool, dist, m):
    """Sort pool[:m] by distance, then index (insertion sort: pools are short)."""
    for i in range(1, m):
        d = dist[i]
        q = pool[i]
        j = i - 1
        while j >= 0 and (dist[j] > d or (dist[j] == d and pool[j] > q)):
            dist[j + 1] = dist[j]
            pool[j + 1] = pool[j]
            j -= 1
        dist[j + 1] = d
        pool[j + 1] = q


@njit(cache=True)
def select_sorted(pool, dist, lo, hi, m):
    """Move the nearest of pool[lo:m] into positions lo..hi-1, in order (ties by index)."""
    for c in range(lo, min(hi, m)):
        select_nearest(pool, dist, c, m)


@njit(cache=True, parallel=True)
def knn_grid(points, lo, h, start, cell_xyz, table, cell_of_sorted, which, kq,
             w_max, max_block, out):
    """Exact ``kq`` nearest neighbours (self excluded) of the points ``which``.

    ``points`` are in cell order and ``cell_of_sorted[i]`` is the cell of
    point ``i``. Writes ``out[j, :kq]`` in order of distance (ties by index)
    and returns a bool array: False where ``w_max`` rings of cells did not
    certify ``kq`` neighbours, or held more than ``max_block`` points (the
    caller uses another search there).
    """
    nq = which.shape[0]
    ok = np.zeros(nq, np.bool_)
    n_chunks = min(nq, 64)
    for ch in prange(n_chunks):
        q0 = (nq * ch) // n_chunks
        q1 = (nq * (ch + 1)) // n_chunks
        cap = 256
        cand = np.empty(cap, np.int64)
        pool = np.empty(cap, np.int64)
        dist = np.empty(cap, np.float64)
        for j in range(q0, q1):
            p = which[j]
            c = cell_of_sorted[p]
            for w in range(1, w_max + 1):
                m = block_size(start, cell_xyz, table, c, w)
                if m > max_block:
                    break  # a crowded block: the caller's kd-tree is faster
                if m > cap:
                    cap = 2 * m
                    cand = np.empty(cap, np.int64)
                    pool = np.empty(cap, np.int64)
                    dist = np.empty(cap, np.float64)
                m = gather_block(start, cell_xyz, table, c, w, cand)
                r = safe_radius(points, p, lo, h, cell_xyz, c, w)
                cnt = certify(points, p, cand, m, r, pool, dist)
                if cnt >= kq:
                    select_sorted(pool, dist, 0, kq, cnt)
                    for a in range(kq):
                        out[j, a] = pool[a]
                    ok[j] = True
                    break
    return ok


def cell_size(points: np.ndarray, lo: np.ndarray, extent: float, target: float) -> float:
    """Cell side giving about ``target`` points per occupied cell.

    Starts from the spacing of a surface (``extent / sqrt(n)``) and corrects
    it twice from the occupancy measured on a sixteenth of the points with
    four times the cell side (the same occupancy on a surface).
    """
    n = len(points)
    sub = points[:: 16] if n >= 16 * 256 else points
    scale = 4.0 if sub is not points else 1.0
    floor = extent / AXIS_MAX * 1.001  # keep every cell coordinate within 21 bits
    h = max(extent / np.sqrt(n) * 2.0, floor)
    for _ in range(2):
        occ = len(sub) / count_cells(sub, lo, 1.0 / (h * scale))
        h = max(h * np.sqrt(target / occ), floor)
    return float(h)
