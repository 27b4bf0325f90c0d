"""Numba kernels of fan construction (paper section 3).

Everything here works on plain arrays; :mod:`fancloud_vtk.core.fans` drives it.

Per point ``p`` the kernel works on a *candidate pool*: its exact nearest
neighbours in order of increasing distance (stage 1 takes them from the
27 grid cells around ``p``, as far as they are certified, see
:mod:`._grid_kernels`; stage 2, for the few fans that need more, from wider
blocks of cells). It then

1. fits the least-squares plane through ``p`` and its ``k`` nearest
   neighbours (smallest eigenvector of the 3x3 covariance),
2. sorts the projections of the candidates by angle around ``p``,
3. enforces the angle criterion (no gap between consecutive neighbours above
   ``max_gap``) by neighbour replacement, with one of two rules:

   * ``RULE_COVER`` (default): grow the pool one candidate at a time in order
     of distance; as soon as the first ``m`` candidates contain a subset of at
     most ``k`` directions without a gap above ``max_gap``, take the smallest
     such subset (it contains candidate ``m``, found exactly by a greedy walk
     around the circle that starts at it) and fill it up to ``k`` with the
     nearest remaining candidates. So the farthest neighbour of the fan is as
     near as any valid fan allows.
   * ``RULE_PAPER``: the literal rule: replace the farthest of the ``k``
     nearest by the ``(k+1)``-st, ``(k+2)``-nd, ... nearest neighbour.

4. if that fails, rotates the plane by 90 degrees around the axis through the
   projections of the two neighbours bounding the largest gap and tries again
   (sharp edges, paper Figure 5),
5. if that fails too, returns the ``k`` nearest neighbours as an open fan
   whose gap (the largest) lies between the last and first ring entry.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import _grid_kernels as G
from ._geometry_kernels import TWO_PI, atan2_2pi, dist2, triangle_cross

RULE_COVER = 0
RULE_PAPER = 1

STATUS_CLOSED = 0
STATUS_ROTATED = 1
STATUS_OPEN = 2
STATUS_RETRY = 3  # pool exhausted without a valid fan: retry with the exact pool

#: the 2k nearest have no plane when their scatter's smallest eigenvalue exceeds this
#: fraction of the middle one (a flat sample with noise of half its spacing stays near 0.25)
NO_PLANE = 0.95



@njit(cache=True)
def _eigenvalues(a00, a01, a02, a11, a12, a22):
    """(smallest, middle, largest) eigenvalues of a symmetric 3x3 matrix, by the
    trigonometric method (Smith 1961); all three equal when it is a multiple of I."""
    q = (a00 + a11 + a22) / 3.0
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    b00 = a00 - q
    b11 = a11 - q
    b22 = a22 - q
    p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1
    if p2 <= 1e-300:
        return q, q, q
    pp = np.sqrt(p2 / 6.0)
    det = (
        b00 * (b11 * b22 - a12 * a12)
        - a01 * (a01 * b22 - a12 * a02)
        + a02 * (a01 * a12 - b11 * a02)
    ) / (pp * pp * pp)
    r = 0.5 * det
    if r <= -1.0:
        phi = np.pi / 3.0
    elif r >= 1.0:
        phi = 0.0
    else:
        phi = np.arccos(r) / 3.0
    small = q + 2.0 * pp * np.cos(phi + 2.0 * np.pi / 3.0)
    large = q + 2.0 * pp * np.cos(phi)
    return small, 3.0 * q - small - large, large


@njit(cache=True)
def _smallest_eigvec(a00, a01, a02, a11, a12, a22):
    """Unit eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix."""
    lam, _, large = _eigenvalues(a00, a01, a02, a11, a12, a22)
    return _eigvec_of(a00, a01, a02, a11, a12, a22, lam, large)


@njit(cache=True)
def _eigvec_of(a00, a01, a02, a11, a12, a22, lam, large):
    """Unit eigenvector of the smallest eigenvalue ``lam`` (the largest: ``large``) of a
    symmetric 3x3 matrix; (0, 0, 1) when all three are equal."""
    if lam == large:
        return 0.0, 0.0, 1.0
    # rows of (A - lam I); the eigenvector is the largest cross product of two rows
    r0x, r0y, r0z = a00 - lam, a01, a02
    r1x, r1y, r1z = a01, a11 - lam, a12
    r2x, r2y, r2z = a02, a12, a22 - lam
    c0x = r0y * r1z - r0z * r1y
    c0y = r0z * r1x - r0x * r1z
    c0z = r0x * r1y - r0y * r1x
    c1x = r0y * r2z - r0z * r2y
    c1y = r0z * r2x - r0x * r2z
    c1z = r0x * r2y - r0y * r2x
    c2x = r1y * r2z - r1z * r2y
    c2y = r1z * r2x - r1x * r2z
    c2z = r1x * r2y - r1y * r2x
    n0 = c0x * c0x + c0y * c0y + c0z * c0z
    n1 = c1x * c1x + c1y * c1y + c1z * c1z
    n2 = c2x * c2x + c2y * c2y + c2z * c2z
    if n0 >= n1 and n0 >= n2 and n0 > 0.0:
        s = 1.0 / np.sqrt(n0)
        return c0x * s, c0y * s, c0z * s
    if n1 >= n2 and n1 > 0.0:
        s = 1.0 / np.sqrt(n1)
        return c1x * s, c1y * s, c1z * s
    if n2 > 0.0:
        s = 1.0 / np.sqrt(n2)
        return c2x * s, c2y * s, c2z * s
    # (A - lam I) has rank <= 1: any vector orthogonal to its non-zero row
    if r0x * r0x + r0y * r0y + r0z * r0z > 0.0:
        rx, ry, rz = r0x, r0y, r0z
    elif r1x * r1x + r1y * r1y + r1z * r1z > 0.0:
        rx, ry, rz = r1x, r1y, r1z
    else:
        rx, ry, rz = r2x, r2y, r2z
    return _orthogonal_unit(rx, ry, rz)


@njit(cache=True)
def _orthogonal_unit(x, y, z):
    """A unit vector orthogonal to (x, y, z) (any, deterministic)."""
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax <= ay and ax <= az:
        ux, uy, uz = 0.0, -z, y
    elif ay <= az:
        ux, uy, uz = -z, 0.0, x
    else:
        ux, uy, uz = -y, x, 0.0
    s = np.sqrt(ux * ux + uy * uy + uz * uz)
    if s == 0.0:
        return 1.0, 0.0, 0.0
    return ux / s, uy / s, uz / s


@njit(cache=True)
def _plane_basis(nx, ny, nz):
    """Orthonormal u, v with (u, v, n) right-handed."""
    ux, uy, uz = _orthogonal_unit(nx, ny, nz)
    vx = ny * uz - nz * uy
    vy = nz * ux - nx * uz
    vz = nx * uy - ny * ux
    return ux, uy, uz, vx, vy, vz


@njit(cache=True)
def _angle(points, p, q, ux, uy, uz, vx, vy, vz):
    """Angle in [0, 2 pi) of q's projection around p in the plane spanned by u, v."""
    dx = points[q, 0] - points[p, 0]
    dy = points[q, 1] - points[p, 1]
    dz = points[q, 2] - points[p, 2]
    return atan2_2pi(dx * vx + dy * vy + dz * vz, dx * ux + dy * uy + dz * uz)


@njit(cache=True)
def _angles_from(points, p, pool, lo, hi, nx, ny, nz, ang):
    """ang[lo:hi]: angles of pool[lo:hi] around p in the plane with normal n."""
    ux, uy, uz, vx, vy, vz = _plane_basis(nx, ny, nz)
    for i in range(lo, hi):
        ang[i] = _angle(points, p, pool[i], ux, uy, uz, vx, vy, vz)


@njit(cache=True)
def _angles(points, p, pool, m, nx, ny, nz, ang):
    """Angles of the first m candidates' projections around p (plane normal n)."""
    _angles_from(points, p, pool, 0, m, nx, ny, nz, ang)


@njit(cache=True)
def _sort_by_angle(ang, ids, m, order):
    """order[:m] = ids[:m] sorted by ang (insertion sort; ties by pool rank)."""
    for i in range(m):
        order[i] = ids[i]
    for i in range(1, m):
        v = order[i]
        a = ang[v]
        j = i - 1
        while j >= 0 and (ang[order[j]] > a or (ang[order[j]] == a and order[j] > v)):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = v


@njit(cache=True)
def _max_gap(ang, order, m):
    """Largest cyclic gap between consecutive angles and the position after it."""
    best = TWO_PI - ang[order[m - 1]] + ang[order[0]]
    pos = 0
    for i in range(1, m):
        g = ang[order[i]] - ang[order[i - 1]]
        if g > best:
            best = g
            pos = i
    return best, pos


@njit(cache=True)
def _greedy_cover(ang, sorted_ids, m, start, max_gap, k, chosen):
    """Fewest directions containing ``sorted_ids[start]`` with no gap above max_gap.

    ``sorted_ids[:m]`` are pool ranks sorted by angle. Walks counter-clockwise
    from ``start``, always jumping to the farthest direction within
    ``max_gap``; for a fixed first element this is optimal. Returns the number
    chosen (written to ``chosen``), or -1 when more than ``k`` are needed or a
    gap cannot be bridged.
    """
    a0 = ang[sorted_ids[start]]
    cur = start
    count = 1
    chosen[0] = sorted_ids[start]
    travelled = 0.0  # angle from the start to cur, counter-clockwise
    while True:
        if TWO_PI - travelled <= max_gap:
            return count
        best = -1
        best_t = 0.0
        j = cur
        for _ in range(m - 1):
            j += 1
            if j == m:
                j = 0
            if j == start:
                break
            t = ang[sorted_ids[j]] - a0
            if j < start:
                t += TWO_PI
            if t - travelled <= max_gap:
                best = j
                best_t = t
            else:
                break
        if best < 0:
            return -1
        if count == k:
            return -1
        chosen[count] = sorted_ids[best]
        count += 1
        cur = best
        travelled = best_t


@njit(cache=True)
def _try_plane(points, p, pool, dist, n_sorted, n_avail, m_pool, k, nx, ny, nz, max_gap, rule,
               ang, scratch, out):
    """Find a fan in the plane with normal n; return its size or -1.

    ``out`` receives pool ranks in counter-clockwise order. ``pool[:n_sorted]``
    is in order of distance; the rest (up to ``n_avail``) is sorted lazily, as
    far as it is used, by the squared distances in ``dist``. At most the
    ``m_pool`` nearest are tried.
    """
    kk = min(k, m_pool)
    _angles(points, p, pool, kk, nx, ny, nz, ang)
    ids = scratch[0]
    srt = scratch[1]
    chosen = scratch[2]
    for i in range(kk):
        ids[i] = i
    _sort_by_angle(ang, ids, kk, srt)
    if kk >= 3:
        g, _ = _max_gap(ang, srt, kk)
        if g <= max_gap:
            for i in range(kk):
                out[i] = srt[i]
            return kk
    if m_pool <= kk:
        return -1
    if rule == RULE_PAPER:
        # the k-1 nearest stay; the farthest is replaced by the next nearest
        for c in range(n_sorted, m_pool):
            G.select_nearest(pool, dist, c, n_avail)
        _angles_from(points, p, pool, kk, m_pool, nx, ny, nz, ang)
        for c in range(kk, m_pool):
            ids[kk - 1] = c
            _sort_by_angle(ang, ids, kk, srt)
            g, _ = _max_gap(ang, srt, kk)
            if g <= max_gap:
                for i in range(kk):
                    out[i] = srt[i]
                return kk
        return -1
    # RULE_COVER: grow the prefix; srt holds the prefix sorted by angle, and
    # ``bad`` counts its gaps above max_gap (the cover search needs none)
    bad = 0
    if ang[srt[0]] - ang[srt[kk - 1]] + TWO_PI > max_gap:
        bad += 1
    for i in range(1, kk):
        if ang[srt[i]] - ang[srt[i - 1]] > max_gap:
            bad += 1
    m = kk
    ux, uy, uz, vx, vy, vz = _plane_basis(nx, ny, nz)
    for c in range(kk, min(n_avail, m_pool)):
        if c >= n_sorted:
            G.select_nearest(pool, dist, c, n_avail)
        # insert candidate c into the angle-sorted prefix
        a = _angle(points, p, pool[c], ux, uy, uz, vx, vy, vz)
        ang[c] = a
        j = m - 1
        while j >= 0 and ang[srt[j]] > a:
            j -= 1
        start = j + 1
        # the gap (prev, next) that a splits; the one across 0 gets 2 pi added
        if start == 0 or start == m:
            prev_a = ang[srt[m - 1]]
            next_a = ang[srt[0]] + TWO_PI
            if start == 0:
                a_rel = a + TWO_PI
            else:
                a_rel = a
        else:
            prev_a = ang[srt[j]]
            next_a = ang[srt[start]]
            a_rel = a
        if next_a - prev_a > max_gap:
            bad -= 1
        if a_rel - prev_a > max_gap:
            bad += 1
        if next_a - a_rel > max_gap:
            bad += 1
        for i in range(m, start, -1):
            srt[i] = srt[i - 1]
        srt[start] = c
        m += 1
        if bad > 0:
            continue
        cnt = _greedy_cover(ang, srt, m, start, max_gap, k, chosen)
        if cnt > 0:
            # fill up with the nearest remaining candidates of the prefix
            for i in range(cnt):
                ids[i] = chosen[i]
            total = cnt
            for r in range(m):
                if total >= k:
                    break
                used = False
                for i in range(cnt):
                    if chosen[i] == r:
                        used = True
                        break
                if not used:
                    ids[total] = r
                    total += 1
            _sort_by_angle(ang, ids, total, out)
            return total
    return -1


@njit(cache=True)
def _plane_normal(points, p, pool, k):
    """Least-squares plane normal through p and its k nearest candidates."""
    return _smallest_eigvec(*_covariance(points, p, pool, k))


@njit(cache=True)
def _covariance(points, p, pool, k):
    """The six entries (00, 01, 02, 11, 12, 22) of the scatter matrix of p and its k
    nearest candidates ``pool[:k]`` about their centroid (p < 0: of ``pool[:k]`` alone)."""
    first = -1 if p >= 0 else 0
    cnt = k - first
    cx = cy = cz = 0.0
    for i in range(first, k):
        q = p if i < 0 else pool[i]
        cx += points[q, 0]
        cy += points[q, 1]
        cz += points[q, 2]
    cx /= cnt
    cy /= cnt
    cz /= cnt
    a00 = a01 = a02 = a11 = a12 = a22 = 0.0
    for i in range(first, k):
        q = p if i < 0 else pool[i]
        dx = points[q, 0] - cx
        dy = points[q, 1] - cy
        dz = points[q, 2] - cz
        a00 += dx * dx
        a01 += dx * dy
        a02 += dx * dz
        a11 += dy * dy
        a12 += dy * dz
        a22 += dz * dz
    return a00, a01, a02, a11, a12, a22


#: two layers among a point's ``n_normal`` nearest (two sheets closer than the
#: spacing: the two sides of a thin part, see :func:`other_sheet`): each layer holds
#: at least ``SHEET_MIN`` points (the point in its own), the layers' own planes are
#: parallel (``|cos|`` at least ``SHEET_PARALLEL``), and across the point's layer's
#: plane they stand apart by ``SHEET_GAP`` spacings (the distance along the
#: least-squares plane of the quarter-nearest of them) and by ``SHEET_CLEAR`` times
#: their thickness (the RMS offset from their own planes). Then the candidates
#: beyond the middle of that gap, on the other layer's side, do not enter the fan.
SHEET_GAP = 0.4
SHEET_MIN = 4
SHEET_PARALLEL = 0.9
SHEET_CLEAR = 4.0
#: ... and the other layer surrounds the point: no angle between its points, seen
#: from the point in its layer's plane, wider than this (radians; 108 degrees)
SHEET_SURROUND = 0.6 * np.pi


@njit(cache=True)
def other_sheet(points, p, pool, n_near, m_surround):
    """(side, limit): the candidates q with ``side * (q - p) . n > limit`` lie on another
    sheet than p (see :data:`SHEET_GAP`), ``n`` the normal returned last; side 0: p's
    ``n_near`` nearest (``pool[:n_near]``) form one sheet. ``m_surround`` (at least
    ``n_near``) candidates are looked at for the surround test of
    :data:`SHEET_SURROUND`. Returns (side, limit, nx, ny, nz).

    The least-squares plane of two layers tilts towards the side where the other
    layer has more points, so p's layer is found apart: of the planes through p and
    two of its nearest that has all the other points on one side, the one that
    holds the most points (within ``SHEET_GAP / 4`` spacings, the spacing: the
    median distance of the neighbours along the least-squares plane), refitted to
    them; the rest is the other layer.
    Only where the offsets from the least-squares plane span the gap at all.
    """
    m = n_near + 1
    ids = np.empty(m, np.int64)
    off = np.empty(m)
    tan = np.empty(n_near)
    nx, ny, nz = _plane_normal(points, p, pool, n_near)
    lo = hi = 0.0
    for i in range(n_near):
        q = pool[i]
        dx = points[q, 0] - points[p, 0]
        dy = points[q, 1] - points[p, 1]
        dz = points[q, 2] - points[p, 2]
        o = dx * nx + dy * ny + dz * nz
        tan[i] = np.sqrt(max(dx * dx + dy * dy + dz * dz - o * o, 0.0))
        lo = min(lo, o)
        hi = max(hi, o)
    tan.sort()
    spacing = tan[n_near // 2]
    if spacing <= 0.0 or hi - lo < SHEET_GAP * tan[n_near // 4]:
        return 0, 0.0, nx, ny, nz
    tol = 0.25 * SHEET_GAP * spacing
    best = 0
    bx = by = bz = 0.0
    for i in range(n_near):
        qi = pool[i]
        for j in range(i + 1, n_near):
            qj = pool[j]
            cx, cy, cz = triangle_cross(points, p, qi, qj)
            cn = np.sqrt(cx * cx + cy * cy + cz * cz)
            # a well-shaped triangle only (a sliver's plane is any plane)
            if cn <= 0.25 * np.sqrt(dist2(points, qi, p) * dist2(points, qj, p)):
                continue
            cx /= cn
            cy /= cn
            cz /= cn
            c = 1
            above = below = 0
            for t in range(n_near):
                q = pool[t]
                o = ((points[q, 0] - points[p, 0]) * cx + (points[q, 1] - points[p, 1]) * cy
                     + (points[q, 2] - points[p, 2]) * cz)
                if abs(o) <= tol:
                    c += 1
                elif o > 0.0:
                    above += 1
                else:
                    below += 1
            # a layer: the points off the plane all on one side of it
            if c > best and (above == 0 or below == 0):
                best = c
                bx, by, bz = cx, cy, cz
    if best < SHEET_MIN or m - best < SHEET_MIN:
        return 0, 0.0, nx, ny, nz
    # p's layer (the plane's points) refitted; the others the other layer
    n_own = 1
    ids[0] = p
    n_oth = 0
    oth = np.empty(n_near, np.int64)
    for t in range(n_near):
        q = pool[t]
        o = ((points[q, 0] - points[p, 0]) * bx + (points[q, 1] - points[p, 1]) * by
             + (points[q, 2] - points[p, 2]) * bz)
        if abs(o) <= tol:
            ids[n_own] = q
            n_own += 1
        else:
            oth[n_oth] = q
            n_oth += 1
    ax, ay, az = _smallest_eigvec(*_covariance(points, -1, ids, n_own))
    cx, cy, cz = _smallest_eigvec(*_covariance(points, -1, oth, n_oth))
    if abs(ax * cx + ay * cy + az * cz) < SHEET_PARALLEL:
        return 0, 0.0, nx, ny, nz
    # across p's layer's plane: the other layer on one side, clear of p's
    mean_own = 0.0
    for i in range(n_own):
        q = ids[i]
        off[i] = ((points[q, 0] - points[p, 0]) * ax + (points[q, 1] - points[p, 1]) * ay
                  + (points[q, 2] - points[p, 2]) * az)
        mean_own += off[i]
    mean_own /= n_own
    mean_oth = 0.0
    for i in range(n_oth):
        q = oth[i]
        off[n_own + i] = ((points[q, 0] - points[p, 0]) * ax + (points[q, 1] - points[p, 1]) * ay
                          + (points[q, 2] - points[p, 2]) * az)
        mean_oth += off[n_own + i]
    mean_oth /= n_oth
    side = 1 if mean_oth > mean_own else -1
    edge_own = -np.inf
    spread = 0.0
    for i in range(n_own):
        edge_own = max(edge_own, side * off[i])
        spread += (off[i] - mean_own) ** 2
    edge_oth = np.inf
    for i in range(n_own, m):
        edge_oth = min(edge_oth, side * off[i])
        spread += (off[i] - mean_oth) ** 2
    apart = edge_oth - edge_own
    if apart < SHEET_GAP * tan[n_near // 4] or apart < SHEET_CLEAR * np.sqrt(spread / m):
        return 0, 0.0, nx, ny, nz
    limit = edge_own + 0.5 * apart
    # the other layer lies over p: its points (within half the gap of its mean
    # offset) among the first ``m_surround`` candidates surround p in p's plane (at
    # a sharp corner the first rows of the other faces may lie in a plane parallel
    # to p's face, but to one side of p)
    ux, uy, uz, vx, vy, vz = _plane_basis(ax, ay, az)
    ang = np.empty(m_surround)
    n_ang = 0
    for i in range(m_surround):
        q = pool[i]
        o = ((points[q, 0] - points[p, 0]) * ax + (points[q, 1] - points[p, 1]) * ay
             + (points[q, 2] - points[p, 2]) * az)
        if side * o > limit and abs(o - mean_oth) <= 0.5 * apart:  # in the other layer
            ang[n_ang] = _angle(points, p, q, ux, uy, uz, vx, vy, vz)
            n_ang += 1
    srt = np.sort(ang[:n_ang])
    widest = srt[0] + TWO_PI - srt[n_ang - 1]
    for i in range(1, n_ang):
        widest = max(widest, srt[i] - srt[i - 1])
    if widest > SHEET_SURROUND:
        return 0, 0.0, nx, ny, nz
    return side, limit, ax, ay, az


@njit(cache=True)
def drop_other_sheet(points, p, pool, dist, m, side, limit, nx, ny, nz):
    """Remove from ``pool[:m]`` (and ``dist``, if it has entries) the candidates beyond
    ``limit`` on ``side`` (see :func:`other_sheet`), keeping the order of the others.
    Returns how many are left."""
    c = 0
    for i in range(m):
        q = pool[i]
        o = ((points[q, 0] - points[p, 0]) * nx + (points[q, 1] - points[p, 1]) * ny
             + (points[q, 2] - points[p, 2]) * nz)
        if side * o > limit:
            continue
        pool[c] = q
        if dist.shape[0] > i:
            dist[c] = dist[i]
        c += 1
    return c


@njit(cache=True)
def _point_normal(points, p, pool, m_pool, n_normal, nx, ny, nz):
    """(normal stored for p, no plane): least-squares plane of its n_normal nearest,
    signed like n.

    When those points lie about as much across as along any plane (the
    smallest eigenvalue of their scatter above :data:`NO_PLANE` times the
    middle one: a corner of a cube, or a cloud of a few points), they have
    no plane: n (the fan's own plane) is kept.
    """
    a00, a01, a02, a11, a12, a22 = _covariance(points, p, pool, min(n_normal, m_pool))
    small, mid, large = _eigenvalues(a00, a01, a02, a11, a12, a22)
    if small > NO_PLANE * mid:
        return nx, ny, nz, True
    ax, ay, az = _eigvec_of(a00, a01, a02, a11, a12, a22, small, large)
    if ax * nx + ay * ny + az * nz < 0.0:
        return -ax, -ay, -az, False
    return ax, ay, az, False


@njit(cache=True)
def _fan_one(points, p, pool, dist, n_sorted, n_avail, m_pool, k, max_gap, rule, rotate, final,
             n_normal, ang, scratch, ring_out):
    """Fan of point p from its candidate pool. Returns (size, status, nx, ny, nz, no plane:
    the normal is the fan's plane, see :func:`_point_normal`)."""
    out = scratch[3]
    kk = min(k, m_pool)
    nx, ny, nz = _plane_normal(points, p, pool, kk)
    cnt = _try_plane(points, p, pool, dist, n_sorted, n_avail, m_pool, k, nx, ny, nz, max_gap,
                     rule, ang, scratch, out)
    if cnt > 0:
        for i in range(cnt):
            ring_out[i] = pool[out[i]]
        nx, ny, nz, flat = _point_normal(points, p, pool, m_pool, n_normal, nx, ny, nz)
        return cnt, STATUS_CLOSED, nx, ny, nz, flat
    if not final:
        return 0, STATUS_RETRY, nx, ny, nz, False
    # the k nearest, sorted by angle in the least-squares plane
    ids = scratch[0]
    srt = scratch[1]
    _angles(points, p, pool, kk, nx, ny, nz, ang)
    for i in range(kk):
        ids[i] = i
    _sort_by_angle(ang, ids, kk, srt)
    g, pos = _max_gap(ang, srt, kk)
    # the rotated attempt and the open fan want the whole pool in order of distance
    for c in range(n_sorted, m_pool):
        G.select_nearest(pool, dist, c, n_avail)
    if rotate and kk >= 2:
        # axis through the projections of the neighbours bounding the largest gap
        a = srt[(pos - 1 + kk) % kk]
        b = srt[pos]
        qa = pool[a]
        qb = pool[b]
        dx = points[qb, 0] - points[qa, 0]
        dy = points[qb, 1] - points[qa, 1]
        dz = points[qb, 2] - points[qa, 2]
        dn = dx * nx + dy * ny + dz * nz
        dx -= dn * nx
        dy -= dn * ny
        dz -= dn * nz
        s = np.sqrt(dx * dx + dy * dy + dz * dz)
        if s > 0.0:
            dx /= s
            dy /= s
            dz /= s
            # rotating the plane by 90 degrees about the axis turns n into axis x n
            rx = dy * nz - dz * ny
            ry = dz * nx - dx * nz
            rz = dx * ny - dy * nx
            s = np.sqrt(rx * rx + ry * ry + rz * rz)
            rx /= s
            ry /= s
            rz /= s
            cnt = _try_plane(
                points, p, pool, dist, m_pool, m_pool, m_pool, k, rx, ry, rz, max_gap, rule,
                ang, scratch, out,
            )
            if cnt > 0:
                for i in range(cnt):
                    ring_out[i] = pool[out[i]]
                return cnt, STATUS_ROTATED, rx, ry, rz, False
        # back to the least-squares plane for the open fan
        _angles(points, p, pool, kk, nx, ny, nz, ang)
        for i in range(kk):
            ids[i] = i
        _sort_by_angle(ang, ids, kk, srt)
        g, pos = _max_gap(ang, srt, kk)
    # open fan: start right after the largest gap
    for i in range(kk):
        ring_out[i] = pool[srt[(pos + i) % kk]]
    nx, ny, nz, flat = _point_normal(points, p, pool, m_pool, n_normal, nx, ny, nz)
    return kk, STATUS_OPEN, nx, ny, nz, flat


@njit(cache=True)
def local_spacing(points, p, pool, k, ang, scratch):
    """p's local spacing: the distance of its k-th nearest neighbour (``pool`` in order of
    distance), corrected for the angle its k nearest cover around it.

    Where p's k nearest fill only part of the circle around it (a point on a
    boundary: a half plane; a corner: a quarter), its k-th nearest lies
    farther than inside the surface, by the square root of the part covered.
    That part is ``(2 pi - g) / (2 pi - pi / 2)`` (at most 1) with g the
    largest angular gap of the k nearest in their least-squares plane, so
    the spacing of a point on a straight boundary is about that of the
    points inside.
    """
    nx, ny, nz = _plane_normal(points, p, pool, k)
    _angles(points, p, pool, k, nx, ny, nz, ang)
    ids = scratch[0]
    srt = scratch[1]
    for i in range(k):
        ids[i] = i
    _sort_by_angle(ang, ids, k, srt)
    g, _ = _max_gap(ang, srt, k)
    q = pool[k - 1]
    dk2 = 0.0
    for a in range(3):
        d = points[q, a] - points[p, a]
        dk2 += d * d
    f = (TWO_PI - g) / (TWO_PI - 0.5 * np.pi)
    if f > 1.0:
        f = 1.0
    if f < 0.05:
        f = 0.05
    return np.sqrt(dk2 * f)


@njit(cache=True)
def reach_limit(points, p, pool, m, k, lim):
    """Number of the candidates ``pool[:m]`` (in order of distance) within distance ``lim``
    of p, at least k: the sampling-aware limit of a fan (issue 22).

    A neighbour much farther than the local sampling allows never enters a
    fan: across a gap of the sampling, towards a stray cluster, the fan
    stays open instead.
    """
    lim2 = lim * lim
    cnt = k
    while cnt < m:
        q = pool[cnt]
        d2 = 0.0
        for a in range(3):
            d = points[q, a] - points[p, a]
            d2 += d * d
        if d2 > lim2:
            break
        cnt += 1
    return cnt


@njit(cache=True, parallel=True)
def fans_from_grid(points, lo, h, start, cell_xyz, table, c_lo, c_hi, k, cap, max_gap,
                   rule, rotate, n_normal, n_sort, max_block, n_chunks, reach, sheets, ring_tab,
                   counts, status, normals, spacing, no_plane):
    """Stage 1: fans of the points of cells ``c_lo:c_hi``, neighbours from the grid.

    ``points`` are in cell order (see :mod:`._grid_kernels`). Each point's
    pool is the set of points of the 27 cells around its cell that lie
    within its safe radius: exactly its nearest neighbours, in a
    spatially coherent block of memory. A point whose pool holds at least
    ``cap`` candidates gets its final fan here (closed, rotated or open);
    one with fewer, whose fan needs more candidates, gets STATUS_RETRY.
    The work is split into ``n_chunks`` parts (a few per thread); the result
    does not depend on it. With ``reach > 0`` only candidates within
    ``reach`` times the distance of the k-th nearest neighbour are tried
    (see :func:`local_spacing` and :func:`reach_limit`). ``spacing[p]``
    receives p's local spacing (points sent to stage 2 get theirs there);
    ``no_plane[p]``, whether p's normal is its fan's plane (:func:`_point_normal`).
    With ``sheets``, the candidates on another sheet than p's (:func:`other_sheet`)
    are left out of its pool.
    """
    n_cells = c_hi - c_lo
    n_chunks = max(1, min(n_cells, n_chunks))
    for ch in prange(n_chunks):
        b0 = c_lo + (n_cells * ch) // n_chunks
        b1 = c_lo + (n_cells * (ch + 1)) // n_chunks
        width = 256
        cand = np.empty(width, np.int64)
        pool = np.empty(width, np.int64)
        dist = np.empty(width, np.float64)
        ang = np.empty(width, np.float64)
        scratch = np.empty((4, width), np.int64)
        ring_out = np.empty(k, np.int64)
        for c in range(b0, b1):
            m = G.block_size(start, cell_xyz, table, c, 1)
            if m > max_block:
                # a crowded block (clustered data, far outliers): stage 2's kd-tree
                for p in range(start[c], start[c + 1]):
                    status[p] = STATUS_RETRY
                    counts[p] = 0
                continue
            if m > width:
                width = 2 * m
                cand = np.empty(width, np.int64)
                pool = np.empty(width, np.int64)
                dist = np.empty(width, np.float64)
                ang = np.empty(width, np.float64)
                scratch = np.empty((4, width), np.int64)
            m = G.gather_block(start, cell_xyz, table, c, 1, cand)
            for p in range(start[c], start[c + 1]):
                r = G.safe_radius(points, p, lo, h, cell_xyz, c, 1)
                m_cert = G.certify(points, p, cand, m, r, pool, dist)
                if m_cert < n_normal or m_cert < k:
                    status[p] = STATUS_RETRY
                    counts[p] = 0
                    continue
                # sort about the n_sort nearest now (the radius from the density
                # of the certified pool), the rest lazily if the fan needs them
                n_sorted = G.sort_within(pool, dist, m_cert, r * r * n_sort / m_cert)
                if n_sorted < n_normal:
                    G.select_sorted(pool, dist, n_sorted, n_normal, m_cert)
                    n_sorted = n_normal
                final = m_cert >= cap
                m_lim = m_cert
                if reach > 0.0:
                    spacing[p] = local_spacing(points, p, pool, k, ang, scratch)
                    lim2 = (reach * spacing[p]) ** 2
                    m_lim = 0
                    for a in range(m_cert):
                        m_lim += dist[a] <= lim2
                    # the k nearest always count, as in reach_limit: a fan of fewer
                    # candidates has no plane (with a small reach this happened)
                    m_lim = max(m_lim, k)
                    # every point within the limit is certified: the pool is complete
                    final = m_lim >= cap or r * r >= lim2
                m_pool = min(cap, m_lim)
                side = 0
                if sheets:
                    side, limit, sx, sy, sz = other_sheet(points, p, pool, n_normal,
                                                          min(m_cert, 3 * n_normal))
                if side != 0:
                    # the whole pool in order of distance, then the other sheet out
                    G.sort_pool(pool, dist, m_cert)
                    n_sorted = m_cert
                    m_near = drop_other_sheet(points, p, pool, dist, m_pool, side, limit,
                                              sx, sy, sz)
                    m_rest = drop_other_sheet(points, p, pool[m_pool:], dist[m_pool:],
                                              m_cert - m_pool, side, limit, sx, sy, sz)
                    for a in range(m_rest):
                        pool[m_near + a] = pool[m_pool + a]
                        dist[m_near + a] = dist[m_pool + a]
                    m_pool = m_near
                    m_cert = m_near + m_rest
                    n_sorted = m_cert
                    if m_pool < k:
                        status[p] = STATUS_RETRY
                        counts[p] = 0
                        continue
                cnt, s, nx, ny, nz, flat = _fan_one(
                    points, p, pool, dist, n_sorted, m_cert, m_pool, k, max_gap, rule, rotate,
                    final, n_normal, ang, scratch, ring_out,
                )
                no_plane[p] = flat
                status[p] = s
                counts[p] = cnt
                normals[p, 0] = nx
                normals[p, 1] = ny
                normals[p, 2] = nz
                for j in range(cnt):
                    ring_tab[p, j] = ring_out[j]


@njit(cache=True, parallel=True)
def fans_from_pool(points, which, pools, k, max_gap, rule, rotate, n_normal, reach, sheets,
                   ring_tab, counts, status, normals, spacing, no_plane):
    """Stage 2: fans of the points ``which`` from exact candidate pools.

    ``pools[i]`` are the nearest neighbours of ``which[i]`` (self first),
    in order of distance, padded with a negative index. ``reach`` and
    ``spacing`` as in :func:`fans_from_grid` (with ``reach`` 0 the pools
    are taken as they are and ``spacing`` is left alone); ``sheets`` too.
    """
    width = pools.shape[1]
    n = which.shape[0]
    n_chunks = min(n, 256)
    for c in prange(n_chunks):
        b0 = (n * c) // n_chunks
        b1 = (n * (c + 1)) // n_chunks
        pool = np.empty(width, np.int64)
        pool_dist = np.zeros(width, np.float64)  # unused: exact pools come sorted
        ang = np.empty(width, np.float64)
        scratch = np.empty((4, width), np.int64)
        ring_out = np.empty(k, np.int64)
        for i in range(b0, b1):
            p = which[i]
            m = 0
            for a in range(width):
                q = pools[i, a]
                if q >= 0 and q != p:
                    pool[m] = q
                    m += 1
            if sheets and m > n_normal:
                side, limit, sx, sy, sz = other_sheet(points, p, pool, n_normal,
                                                      min(m, 3 * n_normal))
                if side != 0:
                    m = drop_other_sheet(points, p, pool, pool_dist[:0], m, side, limit,
                                         sx, sy, sz)
            if reach > 0.0 and m >= k:
                spacing[p] = local_spacing(points, p, pool, k, ang, scratch)
                m = reach_limit(points, p, pool, m, k, reach * spacing[p])
            cnt, s, nx, ny, nz, flat = _fan_one(
                points, p, pool, pool_dist, m, m, m, k, max_gap, rule, rotate, True, n_normal,
                ang, scratch, ring_out,
            )
            no_plane[p] = flat
            status[p] = s
            counts[p] = cnt
            normals[p, 0] = nx
            normals[p, 1] = ny
            normals[p, 2] = nz
            for j in range(cnt):
                ring_tab[p, j] = ring_out[j]


@njit(cache=True, parallel=True)
def to_input_order(order, pos, ring_tab, counts, normals):
    """Rings (CSR) and normals in the input order from the cell-ordered tables.

    ``order[s]`` is the input index of sorted point ``s`` and ``pos`` its
    inverse; ring entries are translated to input indices.
    """
    n = order.shape[0]
    offsets = np.zeros(n + 1, np.int64)
    for i in range(n):
        offsets[i + 1] = offsets[i] + counts[pos[i]]
    ring = np.empty(offsets[n], np.int64)
    out_normals = np.empty((n, 3), np.float64)
    for i in prange(n):
        s = pos[i]
        o = offsets[i]
        for j in range(counts[s]):
            ring[o + j] = order[ring_tab[s, j]]
        out_normals[i, 0] = normals[s, 0]
        out_normals[i, 1] = normals[s, 1]
        out_normals[i, 2] = normals[s, 2]
    return offsets, ring, out_normals


@njit(cache=True, parallel=True)
def to_cell_order(pos, offsets, ring, normals, flags, width):
    """The inverse of :func:`to_input_order`: the rings (CSR, input indices) as the
    cell-ordered table ``ring_tab`` (n, width) with ``counts``, the normals and a per-point
    flag array in the cell order (``pos[i]``: the place of input point i)."""
    n = pos.shape[0]
    ring_tab = np.full((n, width), -1, np.int64)
    counts = np.zeros(n, np.int64)
    out_normals = np.empty((n, 3), np.float64)
    out_flags = np.zeros(n, np.bool_)
    for i in prange(n):
        s = pos[i]
        o = offsets[i]
        counts[s] = offsets[i + 1] - o
        for j in range(offsets[i + 1] - o):
            ring_tab[s, j] = pos[ring[o + j]]
        out_normals[s, 0] = normals[i, 0]
        out_normals[s, 1] = normals[i, 1]
        out_normals[s, 2] = normals[i, 2]
        out_flags[s] = flags[i]
    return ring_tab, counts, out_normals, out_flags

