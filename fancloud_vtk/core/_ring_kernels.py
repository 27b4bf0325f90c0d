"""Numba kernels of rings: the local Delaunay ring of a point in its tangent plane.

The mesh (section 4) replaces every fan ring by its Delaunay ring
(:func:`delaunay_rings`); the reduction (section 5) and the refinement
(section 7) re-form the rings around a removed or inserted point with the same
primitives (:func:`inversions`, :func:`closed_ring`, :func:`open_ring`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._geometry_kernels import dist2, tangent

#: a candidate whose normal makes more than 120 degrees with the point's is on the
#: other side of a thin part: never a Delaunay neighbour
FACING = -0.5
#: the refinement's rings also skip a candidate whose normal is more than 60 degrees from
#: the point's and that lies more than 70 degrees out of its tangent plane (seen from the
#: point, over or under it: across a thin part). Projected, it lands next to the point, so
#: its inversion would shadow the real neighbours on that side (``steep`` of
#: :func:`inversions`: this ``tan^2`` of the angle; ``NOT_STEEP`` keeps every candidate).
#: 60 degrees moved new points on a cube's edges up to 1% of the edge (70: 0.8%, as without)
STEEP = np.tan(np.radians(70.0)) ** 2
NOT_STEEP = np.inf
#: a candidate whose normal is more than 60 degrees from the point's (see ``STEEP``)
TURNED = 0.5
#: :func:`within_reach`: candidates are limited to ``reach`` times the distance of this
#: nearest one, and a candidate this many times farther than the one before it (past the
#: third) ends the list
REACH_RANK = 6
JUMP = 3.0


@njit(cache=True)
def hull_ring(xs, ys, m, idx, order, hull):
    """Vertices of the convex hull of (xs, ys)[:m], counter-clockwise, into hull.

    Andrew's monotone chain (strict turns: collinear points dropped).
    Returns the number of hull vertices (-1 for fewer than 3).
    """
    for i in range(m):
        order[i] = i
    for i in range(1, m):  # insertion sort by (x, y, index)
        v = order[i]
        j = i - 1
        while j >= 0 and (
            xs[order[j]] > xs[v]
            or (
                xs[order[j]] == xs[v]
                and (ys[order[j]] > ys[v] or (ys[order[j]] == ys[v] and idx[order[j]] > idx[v]))
            )
        ):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = v
    h = 0
    for t in range(m):  # lower hull
        i = order[t]
        while h >= 2:
            a = hull[h - 2]
            b = hull[h - 1]
            if (xs[b] - xs[a]) * (ys[i] - ys[a]) - (ys[b] - ys[a]) * (xs[i] - xs[a]) > 0.0:
                break
            h -= 1
        hull[h] = i
        h += 1
    lower = h + 1
    for t in range(m - 2, -1, -1):  # upper hull
        i = order[t]
        while h >= lower:
            a = hull[h - 2]
            b = hull[h - 1]
            if (xs[b] - xs[a]) * (ys[i] - ys[a]) - (ys[b] - ys[a]) * (xs[i] - xs[a]) > 0.0:
                break
            h -= 1
        hull[h] = i
        h += 1
    h -= 1  # the first point closes the chain
    if h < 3:
        return -1
    return h


@njit(cache=True)
def inversions(points, normals, p, cand, m, xs, ys, steep):
    """The candidates ``cand[:m]`` in p's tangent plane, inverted: ``q / |q|^2``.

    Candidates on the other side of a thin part (normal at more than 120
    degrees from p's) or at p itself are dropped, and with a finite
    ``steep`` (a ``tan^2``; ``STEEP``) those turned by more than 60 degrees
    that lie steeper than that out of p's tangent plane; the rest are compacted
    in ``cand`` with their inversions in ``xs``, ``ys``. Returns their
    number.
    """
    ux, uy, uz, vx, vy, vz = tangent(normals[p, 0], normals[p, 1], normals[p, 2])
    mm = 0
    for c in range(m):
        q = cand[c]
        dn = (normals[q, 0] * normals[p, 0] + normals[q, 1] * normals[p, 1]
              + normals[q, 2] * normals[p, 2])
        if dn < FACING:
            continue
        dx = points[q, 0] - points[p, 0]
        dy = points[q, 1] - points[p, 1]
        dz = points[q, 2] - points[p, 2]
        x = dx * ux + dy * uy + dz * uz
        y = dx * vx + dy * vy + dz * vz
        r2 = x * x + y * y
        if r2 <= 0.0:
            continue
        h = dx * normals[p, 0] + dy * normals[p, 1] + dz * normals[p, 2]
        if dn < TURNED and h * h > steep * r2:
            continue
        cand[mm] = q
        xs[mm] = x / r2
        ys[mm] = y / r2
        mm += 1
    return mm


@njit(cache=True)
def closed_ring(xs, ys, mm, cand, hull, max_ring, out):
    """A closed Delaunay ring into ``out``: the hull vertices of the inversions,
    counter-clockwise from the smallest point index. -1 if they do not
    surround the point or are more than ``max_ring``.

    Gift wrapping from the smallest (x, y, index): each next vertex is the
    candidate with all others on its left (the farthest of collinear ones,
    so points inside a hull edge are dropped, as in the strict monotone
    chain of ``hull_ring``). One pass over the few candidates per ring
    vertex (about six) costs less than sorting them; at most ``max_ring``
    passes, so float ties cannot make it loop.
    """
    if mm < 3:
        return -1
    s = 0
    for i in range(1, mm):
        if xs[i] < xs[s] or (xs[i] == xs[s] and (
                ys[i] < ys[s] or (ys[i] == ys[s] and cand[i] < cand[s]))):
            s = i
    h = 0
    a = s
    while True:
        if h == max_ring:
            return -1
        hull[h] = a
        h += 1
        ax = xs[a]
        ay = ys[a]
        b = -1
        bx = 0.0
        by = 0.0
        for c in range(mm):
            cx = xs[c] - ax
            cy = ys[c] - ay
            if cx == 0.0 and cy == 0.0:
                continue
            if b < 0:
                b, bx, by = c, cx, cy
                continue
            turn = bx * cy - by * cx
            if turn < 0.0 or (turn == 0.0 and cx * cx + cy * cy > bx * bx + by * by):
                b, bx, by = c, cx, cy
        if b < 0:
            return -1
        a = b
        if a == s:
            break
    if h < 3:
        return -1
    for t in range(h):  # the origin strictly inside
        a = hull[t]
        b = hull[(t + 1) % h]
        if xs[a] * ys[b] - ys[a] * xs[b] <= 0.0:
            return -1
    first = 0
    for t in range(1, h):
        if cand[hull[t]] < cand[hull[first]]:
            first = t
    for t in range(h):
        out[t] = cand[hull[(first + t) % h]]
    return h


@njit(cache=True)
def open_ring(xs, ys, mm, cand, order, hull, max_ring, out):
    """An open Delaunay fan into ``out`` (a boundary point: its Voronoi cell is unbounded).

    Its neighbours are the hull vertices of the inversions and of the point
    itself, in order from just after it round to just before it; the point
    is nudged a hair outward (away from the candidates) so that it stays a
    hull vertex where the boundary is straight. -1 if there is no such fan.
    """
    if mm == 0:
        return -1
    sx = 0.0
    sy = 0.0
    scale = 0.0
    for c in range(mm):
        sx += xs[c]
        sy += ys[c]
        scale = max(scale, abs(xs[c]) + abs(ys[c]))
    s = np.sqrt(sx * sx + sy * sy)
    cand[mm] = -1
    if s > 0.0:
        xs[mm] = -1e-9 * scale * sx / s
        ys[mm] = -1e-9 * scale * sy / s
    else:
        xs[mm] = 0.0
        ys[mm] = 0.0
    h = hull_ring(xs, ys, mm + 1, cand, order, hull)
    at = -1
    for t in range(h):
        if cand[hull[t]] == -1:
            at = t
    if at < 0 or h < 3 or h - 1 > max_ring:
        return -1
    for t in range(h - 1):
        out[t] = cand[hull[(at + 1 + t) % h]]
    return h - 1


@njit(cache=True)
def within_reach(points, p, cand, m, dist, scratch, reach, own=None):
    """Compact ``cand[:m]`` to the candidates within reach of p, their squared distances
    in ``dist``; returns their number. Within reach: no farther than ``reach`` times the
    distance of the :data:`REACH_RANK`-th nearest, and not past a jump (among the
    :data:`REACH_RANK` + 1 nearest, past the third, a candidate more than :data:`JUMP`
    times as far as the one before it ends the list: a few points apart from the rest
    are not joined to the rest; more of them, and the reach holds them apart). ``reach``
    0: all of them (their distances still in ``dist``). ``own`` (n,), if given: the
    candidates it marks with p are kept whatever their distance."""
    for t in range(m):
        dist[t] = dist2(points, cand[t], p)
    if reach <= 0.0 or m == 0:
        return m
    # the REACH_RANK + 1 smallest distances, sorted, in scratch[:top]
    top = 0
    for t in range(m):
        v = dist[t]
        if top == REACH_RANK + 1 and v >= scratch[top - 1]:
            continue
        j = min(top, REACH_RANK) - 1
        while j >= 0 and scratch[j] > v:
            scratch[j + 1] = scratch[j]
            j -= 1
        scratch[j + 1] = v
        top = min(top + 1, REACH_RANK + 1)
    far = reach * reach * scratch[min(m, REACH_RANK) - 1]
    for t in range(2, top - 1):
        if scratch[t + 1] > JUMP * JUMP * scratch[t]:
            far = min(far, scratch[t])
            break
    kept = 0
    for t in range(m):
        if dist[t] <= far or (own is not None and own[cand[t]] == p):
            cand[kept] = cand[t]
            dist[kept] = dist[t]
            kept += 1
    return kept


@njit(cache=True)
def ring_jump(points, offsets, ring, p, scratch):
    """The squared distance of p's fan neighbour before a jump (:func:`within_reach`'s
    rule on p's own ring; ``inf`` if there is none). ``scratch`` holds at least
    :data:`REACH_RANK` + 1 numbers."""
    top = 0
    for a in range(offsets[p], offsets[p + 1]):
        v = dist2(points, ring[a], p)
        if top == REACH_RANK + 1 and v >= scratch[top - 1]:
            continue
        j = min(top, REACH_RANK) - 1
        while j >= 0 and scratch[j] > v:
            scratch[j + 1] = scratch[j]
            j -= 1
        scratch[j + 1] = v
        top = min(top + 1, REACH_RANK + 1)
    for t in range(2, top - 1):
        if scratch[t + 1] > JUMP * JUMP * scratch[t]:
            return scratch[t]
    return np.inf


@njit(cache=True, parallel=True)
def ring_jumps(points, offsets, ring):
    """:func:`ring_jump` of every point."""
    n = points.shape[0]
    out = np.empty(n)
    for p in prange(n):
        scratch = np.empty(REACH_RANK + 1)
        out[p] = ring_jump(points, offsets, ring, p, scratch)
    return out


@njit(cache=True)
def two_rings(offsets, ring, p, stamp, cand):
    """p's fan neighbours and theirs (p left out), each once, into ``cand``; returns
    their number (at most ``len(cand) - 1``). ``stamp`` (n,) marks the points taken for
    p (value p)."""
    cap = cand.shape[0]
    m = 0
    stamp[p] = p
    for a in range(offsets[p], offsets[p + 1]):
        q = ring[a]
        for b in range(offsets[q] - 1, offsets[q + 1]):
            s = q if b < offsets[q] else ring[b]
            if stamp[s] == p or m >= cap - 1:
                continue
            stamp[s] = p
            cand[m] = s
            m += 1
    return m


@njit(cache=True)
def two_rings_cap(offsets, ring, which, least):
    """A candidate buffer size that holds the two rings of every point of ``which``
    (at least ``least``)."""
    cap = least
    for i in range(which.shape[0]):
        p = which[i]
        two = 2
        for a in range(offsets[p], offsets[p + 1]):
            q = ring[a]
            two += 1 + offsets[q + 1] - offsets[q]
        cap = max(cap, two)
    return cap


@njit(cache=True)
def delaunay_ring(
    points, normals, offsets, ring, is_open, p, max_ring, cand, xs, ys, order, hull, stamp, table,
    steep, reach=0.0, own=None, jumps=None,
):
    """Write p's local Delaunay ring to table[p]; return its size, or -1 (keep the fan's ring).

    ``stamp`` (n,) marks the candidates already taken for p (value p). With ``reach``
    (see :func:`within_reach`), ``own`` (n,) and ``jumps`` (:func:`ring_jumps`) given,
    a fan neighbour q of p stays a candidate past the reach when neither p's nor q's
    own ring has a jump before it (the long edges of a mesh, as in a fan-triangulated
    polygon; not a fan that reached from a stray cluster to a surface). ``own`` marks
    them (value p).
    """
    m = two_rings(offsets, ring, p, stamp, cand)
    if reach > 0.0:
        if own is not None:
            for a in range(offsets[p], offsets[p + 1]):
                q = ring[a]
                d = dist2(points, q, p)
                if d <= jumps[p] and d <= jumps[q]:
                    own[q] = p
        m = within_reach(points, p, cand, m, xs, ys, reach, own)
    mm = inversions(points, normals, p, cand, m, xs, ys, steep)
    if is_open:
        return open_ring(xs, ys, mm, cand, order, hull, max_ring, table[p])
    return closed_ring(xs, ys, mm, cand, hull, max_ring, table[p])


@njit(cache=True, parallel=True)
def delaunay_rings(points, normals, offsets, ring, is_open, max_ring, n_chunks, seq, steep,
                   reach=0.0):
    """Each closed fan's ring replaced by its local Delaunay ring.

    The candidates of point p are its fan neighbours and theirs (two rings
    of the fan cloud: no neighbour search). Projected into p's tangent
    plane, p's neighbours in their Delaunay triangulation are the points
    whose inversions ``q / |q|^2`` lie on the convex hull of all
    inversions, in counter-clockwise order (the polar dual of p's Voronoi
    cell). Neighbouring points then mostly agree on their triangles. An
    open fan (a boundary point, unbounded cell) gets the hull vertices of
    the inversions and p itself, in order from just after p: an open
    Delaunay fan. A closed fan whose candidates do not surround it keeps
    its ring. Returns (counts, table): ``table[p, :counts[p]]`` the new
    ring. The work is split in ``n_chunks`` parts (each with an (n,)
    scratch array, so a few: about one per thread); the points are taken in
    the order ``seq`` (empty: 0, 1, ...; a spatial order keeps a point's
    candidates in the cache from the points before it). The result depends
    on neither. Fewer than 2**31 points (the stamps are int32). ``steep``:
    see :func:`inversions`.
    """
    n = points.shape[0]
    counts = np.zeros(n, np.int64)
    table = np.empty((n, max_ring), np.int64)
    n_chunks = max(1, min(n, n_chunks))
    ident = seq.shape[0] == 0
    # the candidate buffers hold every point's two rings (at least 256 entries, as before)
    cap = two_rings_cap(offsets, ring, np.arange(n), 256)
    jumps = ring_jumps(points, offsets, ring) if reach > 0.0 else np.zeros(0)
    for ch in prange(n_chunks):
        cand = np.empty(cap, np.int64)
        xs = np.empty(cap)
        ys = np.empty(cap)
        order = np.empty(cap, np.int64)
        hull = np.empty(cap + 1, np.int64)
        stamp = np.full(n, -1, np.int32)
        own = np.full(n, -1, np.int32)
        for i in range((n * ch) // n_chunks, (n * (ch + 1)) // n_chunks):
            p = i if ident else seq[i]
            h = delaunay_ring(
                points,
                normals,
                offsets,
                ring,
                is_open[p],
                p,
                max_ring,
                cand,
                xs,
                ys,
                order,
                hull,
                stamp,
                table,
                steep,
                reach,
                own,
                jumps,
            )
            if h < 0:  # keep the fan's own ring
                h = offsets[p + 1] - offsets[p]
                for a in range(h):
                    table[p, a] = ring[offsets[p] + a]
            counts[p] = h
    return counts, table


@njit(cache=True)
def compact_rings(counts, table):
    """The rings ``table[p, :counts[p]]`` as CSR: (offsets, ring)."""
    n = counts.shape[0]
    offsets = np.zeros(n + 1, np.int64)
    for p in range(n):
        offsets[p + 1] = offsets[p] + counts[p]
    ring = np.empty(offsets[n], np.int64)
    for p in range(n):
        o = offsets[p]
        for a in range(counts[p]):
            ring[o + a] = table[p, a]
    return offsets, ring


@njit(cache=True, parallel=True)
def relabel_rings(offsets, ring, order, rank):
    """Rings (CSR) of the points taken in ``order``, with indices renamed by ``rank``.

    Point i of the result is point ``order[i]``; ``rank`` is the inverse
    permutation.
    """
    n = order.shape[0]
    out_off = np.zeros(n + 1, np.int64)
    for i in range(n):
        p = order[i]
        out_off[i + 1] = out_off[i] + offsets[p + 1] - offsets[p]
    out = np.empty(out_off[n], np.int64)
    for i in prange(n):
        p = order[i]
        o = out_off[i]
        for j in range(offsets[p], offsets[p + 1]):
            out[o + j - offsets[p]] = rank[ring[j]]
    return out_off, out


@njit(cache=True, parallel=True)
def fan_radii(points, offsets, ring, which, m, n_chunks):
    """Per point ``which[i]``: (its farthest fan neighbour's distance, an upper bound of
    the distance of its ``m``-th nearest point, or -1 when its two rings hold fewer than
    ``m`` other points). The bound is the ``m``-th smallest distance to the points of its
    two rings (:func:`two_rings`): any ``m`` points are no nearer than the ``m`` nearest.
    The work is split in ``n_chunks`` parts, each with an (n,) stamp array."""
    n = points.shape[0]
    n_w = which.shape[0]
    far = np.zeros(n_w)
    bound = np.full(n_w, -1.0)
    cap = two_rings_cap(offsets, ring, which, m + 1)
    n_chunks = max(1, min(n_w, n_chunks))
    for ch in prange(n_chunks):
        stamp = np.full(n, -1, np.int64)
        cand = np.empty(cap, np.int64)
        best = np.empty(m)
        for i in range((n_w * ch) // n_chunks, (n_w * (ch + 1)) // n_chunks):
            p = which[i]
            f = 0.0
            for a in range(offsets[p], offsets[p + 1]):
                f = max(f, dist2(points, p, ring[a]))
            far[i] = np.sqrt(f)
            c = two_rings(offsets, ring, p, stamp, cand)
            if c < m:
                continue
            for j in range(m):
                best[j] = np.inf
            for t in range(c):
                d = dist2(points, p, cand[t])
                if d < best[m - 1]:
                    j = m - 1
                    while j > 0 and best[j - 1] > d:
                        best[j] = best[j - 1]
                        j -= 1
                    best[j] = d
            bound[i] = np.sqrt(best[m - 1])
    return far, bound
