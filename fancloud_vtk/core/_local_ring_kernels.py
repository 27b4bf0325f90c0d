"""Numba kernels of the local triangulation rings (``rings='local'`` of the mesh).

A point's ring is found as surface triangulators that work point by point
find it: its nearest candidates (from its two rings in the fan cloud, within
reach: :func:`._ring_kernels.within_reach`), sorted by angle in the tangent
plane, form a first fan; then, one at a time, the spoke whose removal gains
the most leaves it, until every spoke left is *stable*. A spoke ``p-c``
between ``d`` (before) and ``b`` (after) is stable when removing it would
leave a triangle wider than pi, when the quadrilateral ``p b c d`` unfolded
about ``p-c`` is not convex, or when ``p-c`` is the better diagonal by the
3D circumcircle rule and the two triangles fold less than ``crit``. Its gain
is the circumcircle profit (relative to the nearest candidate's squared
distance), the fold beyond ``crit``, the sine of ``c``'s angle out of the
tangent plane, and how far ``c``'s normal and the two triangles' normal turn
from ``p``'s. Unlike the tangent-plane Delaunay ring, it judges triangles in
3D, so on a thin part (a leg, a tail, an ear) a candidate across the part
does not win by its projection. The first angular gap wider than ``border``
makes the ring open.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._geometry_kernels import TWO_PI, atan2_2pi, dist2, tangent
from ._ring_kernels import two_rings, two_rings_cap, within_reach

#: a triangle whose circumradius is more than this many times its inradius's double is
#: degenerate: its longest spoke goes first
DEGENERATE = 1e3
#: candidates whose normal makes more than this cosine with the point's are dropped
FACING = -0.3
INF = np.inf


@njit(cache=True)
def _sub(points, i, j):
    return (points[i, 0] - points[j, 0], points[i, 1] - points[j, 1],
            points[i, 2] - points[j, 2])


@njit(cache=True)
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True)
def _circum_d2(points, a, b, c):
    """Squared circumcircle diameter of triangle abc (inf when degenerate)."""
    abx, aby, abz = _sub(points, b, a)
    acx, acy, acz = _sub(points, c, a)
    bcx, bcy, bcz = _sub(points, c, b)
    cx, cy, cz = _cross(abx, aby, abz, acx, acy, acz)
    k2 = cx * cx + cy * cy + cz * cz
    if k2 <= 0.0:
        return INF
    return ((abx * abx + aby * aby + abz * abz) * (acx * acx + acy * acy + acz * acz)
            * (bcx * bcx + bcy * bcy + bcz * bcz)) / k2


@njit(cache=True)
def _aspect(points, a, b, c):
    """Circumradius over twice the inradius (1 for an equilateral triangle)."""
    la = np.sqrt(dist2(points, b, c))
    lb = np.sqrt(dist2(points, a, c))
    lc = np.sqrt(dist2(points, a, b))
    s = 0.5 * (la + lb + lc)
    k2 = s * (s - la) * (s - lb) * (s - lc)
    if k2 <= 0.0:
        return INF
    return la * lb * lc * s / (8.0 * k2)


@njit(cache=True)
def _unfold_convex(points, a, b, c, d):
    """Is the quadrilateral a b c d, unfolded flat about its diagonal a-c, convex?"""
    ux, uy, uz = _sub(points, c, a)
    lac = np.sqrt(ux * ux + uy * uy + uz * uz)
    if lac <= 0.0:
        return False
    ux /= lac
    uy /= lac
    uz /= lac
    bx, by, bz = _sub(points, b, a)
    dx, dy, dz = _sub(points, d, a)
    tb = bx * ux + by * uy + bz * uz
    td = dx * ux + dy * uy + dz * uz
    hb = np.sqrt(max(bx * bx + by * by + bz * bz - tb * tb, 0.0))
    hd = np.sqrt(max(dx * dx + dy * dy + dz * dz - td * td, 0.0))
    if hb + hd <= 0.0:
        return False
    x = tb + (td - tb) * hb / (hb + hd)
    return 0.0 < x < lac


@njit(cache=True)
def _order_by(key, tie, order, m):
    """``order[:m]``: 0..m-1 sorted by ``key``, then ``tie`` (insertion sort: m is a
    few dozen)."""
    for t in range(m):
        order[t] = t
    for t in range(1, m):
        v = order[t]
        j = t - 1
        while j >= 0 and (key[order[j]] > key[v]
                          or (key[order[j]] == key[v] and tie[order[j]] > tie[v])):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = v


@njit(cache=True)
def _spoke(points, normals, p, cand, ang, prv, nxt, i, border, crit, normalizer):
    """(stable, gain) of removing spoke ``p - cand[i]`` from the fan."""
    d = cand[prv[i]]
    c = cand[i]
    b = cand[nxt[i]]
    if border == i or border == prv[i]:
        # a spoke at the open side goes only if its triangle is degenerate and it is
        # the longer of the two
        o = d if border == i else b
        if dist2(points, c, p) < dist2(points, o, p):
            return True, 0.0
        if _aspect(points, p, o, c) <= DEGENERATE:
            return True, 0.0
        return False, INF
    gap = ang[nxt[i]] - ang[prv[i]]
    if gap < 0.0:
        gap += TWO_PI
    if gap > np.pi:
        return True, 0.0
    lc = dist2(points, c, p)
    if ((lc > dist2(points, b, p) and _aspect(points, p, b, c) > DEGENERATE)
            or (lc > dist2(points, d, p)
                and _aspect(points, p, c, d) > DEGENERATE)):
        return False, INF
    npx, npy, npz = normals[p, 0], normals[p, 1], normals[p, 2]
    ncx, ncy, ncz = normals[c, 0], normals[c, 1], normals[c, 2]
    turned = npx * ncx + npy * ncy + npz * ncz
    if turned >= 0.0 and not _unfold_convex(points, p, b, c, d):
        return True, 0.0
    now = max(_circum_d2(points, p, c, d), _circum_d2(points, c, p, b))
    flipped = max(_circum_d2(points, b, d, p), _circum_d2(points, d, b, c))
    profit = now - flipped
    if profit == 0.0 and min(p, c) > min(b, d):
        profit = -1.0
    # the fold between triangles (p, c, b) and (p, d, c) (counter-clockwise: b after c)
    abx, aby, abz = _sub(points, b, p)
    acx, acy, acz = _sub(points, c, p)
    adx, ady, adz = _sub(points, d, p)
    n1x, n1y, n1z = _cross(acx, acy, acz, abx, aby, abz)
    n2x, n2y, n2z = _cross(adx, ady, adz, acx, acy, acz)
    cx, cy, cz = _cross(n1x, n1y, n1z, n2x, n2y, n2z)
    fold = np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz),
                      n1x * n2x + n1y * n2y + n1z * n2z) - crit
    if profit < 0.0 and fold <= 0.0:
        return True, 0.0
    gain = 0.0
    if profit > 0.0:
        gain += profit / normalizer
    if fold > 0.0:
        gain += fold
    length = np.sqrt(lc)
    if length <= 0.0:
        return False, INF
    gain += abs(acx * npx + acy * npy + acz * npz) / length
    gain += 5.0 * (1.0 - turned)
    sx = n1x + n2x
    sy = n1y + n2y
    sz = n1z + n2z
    sl = np.sqrt(sx * sx + sy * sy + sz * sz)
    if sl > 0.0:
        tw = (sx * ncx + sy * ncy + sz * ncz) / sl
        if tw < 0.0:
            return False, INF
        gain += 5.0 * (1.0 - tw)
    return False, gain


@njit(cache=True)
def local_ring(points, normals, p, cand, m, n_near, reach, crit, border_angle, dist, ang,
               order, pid, prv, nxt, stable, gain, out):
    """p's local triangulation ring into ``out``; returns (size, open), size -1 when p
    keeps its fan (fewer than two spokes left, or a ring longer than ``out``).

    ``cand[:m]``: the candidates; the ``n_near`` nearest within ``reach`` (see
    :func:`._ring_kernels.within_reach`) make the first fan.
    """
    # drop facing and coincident candidates
    mm = 0
    for t in range(m):
        q = cand[t]
        dn = (normals[q, 0] * normals[p, 0] + normals[q, 1] * normals[p, 1]
              + normals[q, 2] * normals[p, 2])
        d2 = dist2(points, q, p)
        if dn < FACING or d2 <= 0.0:
            continue
        cand[mm] = q
        mm += 1
    mm = within_reach(points, p, cand, mm, dist, ang, reach)
    _order_by(dist, cand, order, mm)  # by distance, then point
    k = min(mm, n_near)
    if k < 2:
        return -1, False
    ux, uy, uz, vx, vy, vz = tangent(normals[p, 0], normals[p, 1], normals[p, 2])
    # the k nearest, by angle: their ranks in dist order are order[:k]
    for t in range(k):
        q = cand[order[t]]
        dx = points[q, 0] - points[p, 0]
        dy = points[q, 1] - points[p, 1]
        dz = points[q, 2] - points[p, 2]
        x = dx * ux + dy * uy + dz * uz
        y = dx * vx + dy * vy + dz * vz
        if t == 0:
            normalizer = x * x + y * y
        ang[t] = atan2_2pi(y, x)
        pid[t] = q
    if normalizer <= 0.0:
        normalizer = 1.0
    _order_by(ang, pid, order, k)  # by angle, then point
    # fan positions 0..k-1 by angle
    for t in range(k):
        cand[t] = pid[order[t]]
        gain[t] = ang[order[t]]
    for t in range(k):
        ang[t] = gain[t]
        prv[t] = (t - 1) % k
        nxt[t] = (t + 1) % k
    border = -1
    for t in range(k):
        g = ang[(t + 1) % k] - ang[t] if t + 1 < k else ang[0] + TWO_PI - ang[t]
        if g > border_angle:
            border = t
            break
    for t in range(k):
        s, g = _spoke(points, normals, p, cand, ang, prv, nxt, t, border, crit, normalizer)
        stable[t] = s
        gain[t] = g
    alive = k
    while True:
        best = -1
        for t in range(k):  # alive positions are those linked: prv[nxt[t]] == t
            if prv[t] >= 0 and not stable[t] and (best < 0 or gain[t] > gain[best]):
                best = t
        if best < 0:
            break
        a = prv[best]
        b = nxt[best]
        nxt[a] = b
        prv[b] = a
        prv[best] = -1
        alive -= 1
        if alive < 2:
            return -1, False
        if best == border:
            border = a
        s, g = _spoke(points, normals, p, cand, ang, prv, nxt, a, border, crit, normalizer)
        stable[a] = s
        gain[a] = g
        s, g = _spoke(points, normals, p, cand, ang, prv, nxt, b, border, crit, normalizer)
        stable[b] = s
        gain[b] = g
    if alive > out.shape[0] or (border < 0 and alive < 3):
        return -1, False
    start = 0
    while prv[start] < 0:
        start += 1
    if border >= 0:
        start = nxt[border]
    t = start
    for h in range(alive):
        out[h] = cand[t]
        t = nxt[t]
    return alive, border >= 0


@njit(cache=True, parallel=True)
def local_rings(points, normals, offsets, ring, max_ring, n_near, reach, crit, border_angle,
                n_chunks, which):
    """Every point's local triangulation ring: (counts, table, open).

    Candidates: p's fan neighbours and theirs. ``table[p, :counts[p]]`` is the
    ring, counter-clockwise about p's normal, from the first point after the
    open side when ``open[p]``. A ring longer than ``max_ring`` or a point left
    with fewer than two spokes keeps its fan (count -1 in the table:
    the caller copies the fan's ring).
    """
    n = points.shape[0]
    w = which.shape[0]
    counts = np.zeros(w, np.int64)
    is_open = np.zeros(w, np.bool_)
    table = np.empty((w, max_ring), np.int64)
    n_chunks = max(1, min(w, n_chunks))
    cap = two_rings_cap(offsets, ring, which, 16)
    for ch in prange(n_chunks):
        cand = np.empty(cap, np.int64)
        dist = np.empty(cap)
        ang = np.empty(cap)
        order = np.empty(cap, np.int64)
        pid = np.empty(cap, np.int64)
        prv = np.empty(cap, np.int64)
        nxt = np.empty(cap, np.int64)
        stable = np.empty(cap, np.bool_)
        gain = np.empty(cap)
        stamp = np.full(n, -1, np.int32)
        for i in range((w * ch) // n_chunks, (w * (ch + 1)) // n_chunks):
            p = which[i]
            m = two_rings(offsets, ring, p, stamp, cand)
            h, op = local_ring(points, normals, p, cand, m, n_near, reach, crit, border_angle,
                               dist, ang, order, pid, prv, nxt, stable, gain, table[i])
            counts[i] = h
            is_open[i] = op
    return counts, table, is_open
