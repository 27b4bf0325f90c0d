"""Numba kernels of removal by retriangulation (a departure from the paper, issue 24).

The paper re-forms every fan that contained a removed point p from the points
that remain. When the fans are the one-rings of a 2-manifold triangle mesh
(the fan cloud of a mesh input), that re-forming may break the manifold:
each neighbour decides alone. Here p's hole (its ring, a polygon around p) is
triangulated once, in p's tangent plane, and every neighbour's ring is
*spliced* from that one triangulation: p is replaced, in the neighbour's ring,
by the neighbour's new triangle partners. The rings then stay the one-rings
of a 2-manifold with the same topology (a disc is replaced by a disc), and a
removal that cannot keep that (a new edge that exists already, a triangle
that folds over, a ring that would close on itself) is refused.

``hole_triangles`` triangulates the hole by ear clipping, best ear first
(the largest smallest angle); ``splice_ring`` gives one neighbour's new ring.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._geometry_kernels import dist2, in_plane, tangent, triangle_cross
from ._grid_kernels import AXIS_MAX, lookup
from .mesh_stats import AREA_TOL, INTERSECTION_TOL, _pair_intersects, few_triangle_frames

#: a new triangle's normal must be within acos(MIN_NORMAL_DOT) of p's normal
#: (78 degrees: a cube corner's faces are 55 degrees from its normal)
MIN_NORMAL_DOT = 0.2
#: an ear whose smallest angle's sine is below this is degenerate
MIN_SINE = 1e-6
#: the crossing test looks at the points around the hole's box within this fraction of its
#: longest spoke (see ``_crosses``)
SPOKE_MARGIN = 0.25
#: a boundary point is removed only where the boundary turns by at most this (degrees)
MAX_BOUNDARY_TURN = 30.0
COS_BOUNDARY_TURN = float(np.cos(np.deg2rad(MAX_BOUNDARY_TURN)))
#: a new triangle may bend against its outside neighbour by this much (degrees) even if
#: the old one bent less (see ``_folds_kept``)
MAX_FOLD = 60.0
COS_MAX_FOLD = float(np.cos(np.deg2rad(MAX_FOLD)))



@njit(cache=True)
def _has(R, rlen, a, b):
    """b is in a's ring (the edge a b exists)."""
    for j in range(rlen[a]):
        if R[a, j] == b:
            return True
    return False


@njit(cache=True)
def _ear(points, nx, ny, nz, xs, ys, poly, alive, m, a, i, b, R, rlen, limit2, last):
    """The quality of the ear (a, i, b) of the polygon (its smallest angle's sine), or -1 if
    it is not a valid ear: not convex in p's plane, another polygon vertex inside it, a
    new edge a b that exists already (unless ``last``: the final triangle's edges are all
    there), longer than ``limit2`` (squared), or a triangle folding against p's normal."""
    ex1 = xs[i] - xs[a]
    ey1 = ys[i] - ys[a]
    ex2 = xs[b] - xs[i]
    ey2 = ys[b] - ys[i]
    if ex1 * ey2 - ey1 * ex2 <= 0.0:
        return -1.0
    # no other vertex inside (or on) the ear, in p's plane
    for j in range(m):
        if not alive[j] or j == a or j == i or j == b:
            continue
        inside = True
        for (u, v) in ((a, i), (i, b), (b, a)):
            if (xs[v] - xs[u]) * (ys[j] - ys[u]) - (ys[v] - ys[u]) * (xs[j] - xs[u]) < 0.0:
                inside = False
                break
        if inside:
            return -1.0
    pa = poly[a]
    pi = poly[i]
    pb = poly[b]
    if not last:
        if _has(R, rlen, pa, pb) or dist2(points, pa, pb) > limit2:
            return -1.0
    return _facing_sine(points, pa, pi, pb, nx, ny, nz)


@njit(cache=True)
def _facing_sine(points, a, b, c, nx, ny, nz):
    """The sine of the triangle a b c's smallest angle, or -1 if it is degenerate (below
    MIN_SINE) or its normal is more than acos(MIN_NORMAL_DOT) from n."""
    cx, cy, cz = triangle_cross(points, a, b, c)
    c2 = np.sqrt(cx * cx + cy * cy + cz * cz)
    if c2 == 0.0 or (cx * nx + cy * ny + cz * nz) < MIN_NORMAL_DOT * c2:
        return -1.0
    la = dist2(points, a, b)
    lb = dist2(points, a, c)
    lc = dist2(points, b, c)
    # sin of the angle opposite the shortest edge = 2 area / (product of the other two)
    if la <= lb and la <= lc:
        s = c2 / np.sqrt(lb * lc)
    elif lb <= lc:
        s = c2 / np.sqrt(la * lc)
    else:
        s = c2 / np.sqrt(la * lb)
    return s if s >= MIN_SINE else -1.0


@njit(cache=True)
def hole_triangles(points, normals, R, rlen, ropen, p, max_edge2, folds, near, xs, ys, alive,
                   tris, star=-1):
    """The triangulation of p's hole: rows of ``tris`` (counter-clockwise around p's
    normal, as the mesh's), returns their number (``rlen[p] - 2``) or -1 if the hole
    cannot be triangulated without breaking the manifold (see the module).

    ``star`` -1: by ear clipping; a ring position j: the star from p's j-th ring point
    (p collapsed into it, ``_quadric_kernels``).

    The hole is p's ring, closed by the edge from its last to its first point when p's
    fan is open (a boundary point: that edge becomes boundary, and the boundary must turn
    by at most ``MAX_BOUNDARY_TURN`` at p). A new edge may be longer than
    ``sqrt(max_edge2)`` only if it is not longer than the hole's longest edge: the longest
    edge of the mesh never grows past the larger of the two. ``folds``: refuse a removal
    that makes a sharper fold than it found (``_folds_kept``). ``near``: (active, lo,
    inv_h, start, table), the points in uniform cells (the reduction's grid, in whose
    order the points are): a removal whose new surface would pass to the other side of a
    point that is not in the hole (another sheet, a thin part's other side) is refused
    (``_crosses``).
    """
    m = rlen[p]
    if m < 3:
        return -1
    ux, uy, uz, vx, vy, vz = tangent(normals[p, 0], normals[p, 1], normals[p, 2])
    nx = normals[p, 0]
    ny = normals[p, 1]
    nz = normals[p, 2]
    longest = 0.0  # the hole's longest edge
    for j in range(m):
        q = R[p, j]
        xs[j], ys[j] = in_plane(points, p, q, ux, uy, uz, vx, vy, vz)
        alive[j] = True
        if j > 0 or not ropen[p]:
            longest = max(longest, dist2(points, q, R[p, (j - 1) % m]))
    limit2 = max(max_edge2, longest)
    poly = R[p]
    if ropen[p]:
        # the closing edge is new: it must not exist, nor be too long; the boundary must
        # turn by at most MAX_BOUNDARY_TURN at p (it stays where it was)
        if _has(R, rlen, poly[m - 1], poly[0]):
            return -1
        a = poly[m - 1]  # the boundary runs a -> p -> b (the hole is on its left)
        b = poly[0]
        ax = points[p, 0] - points[a, 0]
        ay = points[p, 1] - points[a, 1]
        az = points[p, 2] - points[a, 2]
        bx = points[b, 0] - points[p, 0]
        by = points[b, 1] - points[p, 1]
        bz = points[b, 2] - points[p, 2]
        dot = ax * bx + ay * by + az * bz
        la = np.sqrt(ax * ax + ay * ay + az * az)
        lb = np.sqrt(bx * bx + by * by + bz * bz)
        if dot < COS_BOUNDARY_TURN * la * lb:
            return -1
        if dist2(points, poly[0], poly[m - 1]) > limit2:
            return -1
    area = 0.0
    for j in range(m):
        jn = (j + 1) % m
        area += xs[j] * ys[jn] - xs[jn] * ys[j]
    if area <= 0.0:
        return -1
    if star >= 0:
        nt = _star(points, nx, ny, nz, xs, ys, poly, m, star, R, rlen, limit2, p, tris)
    else:
        nt = _ears(points, nx, ny, nz, xs, ys, poly, alive, m, R, rlen, limit2, tris)
    if nt < 0:
        return -1
    if folds and not _folds_kept(points, R, rlen, ropen, p, tris, nt):
        return -1
    if _crosses(points, normals, R, rlen, ropen, p, tris, nt, near):
        return -1
    return nt


@njit(cache=True)
def _star(points, nx, ny, nz, xs, ys, poly, m, j, R, rlen, limit2, p, tris):
    """The star triangulation of the hole ``poly[:m]`` (in p's plane: ``xs``, ``ys``) from
    its j-th point: its number of triangles, or -1 if it is not a triangulation of the
    hole (a triangle turned over in p's plane, or the star winding more than once), a new
    edge exists already or is longer than ``limit2`` (squared), or a triangle is
    degenerate, folds against p's normal or turns over against p's old triangle."""
    q = poly[j]
    swept = 0.0
    nt = 0
    for i in range(1, m - 1):
        a = (j + i) % m
        b = (j + i + 1) % m
        ax = xs[a] - xs[j]
        ay = ys[a] - ys[j]
        bx = xs[b] - xs[j]
        by = ys[b] - ys[j]
        cr = ax * by - ay * bx
        if cr <= 0.0:
            return -1
        swept += np.arctan2(cr, ax * bx + ay * by)
        pa = poly[a]
        pb = poly[b]
        if i >= 2 and (_has(R, rlen, q, pa) or dist2(points, q, pa) > limit2):
            return -1
        if _facing_sine(points, q, pa, pb, nx, ny, nz) < 0.0:
            return -1
        cx, cy, cz = triangle_cross(points, q, pa, pb)
        ox, oy, oz = triangle_cross(points, p, pa, pb)
        if cx * ox + cy * oy + cz * oz <= 0.0:  # turned over against p's old triangle
            return -1
        tris[nt, 0] = q
        tris[nt, 1] = pa
        tris[nt, 2] = pb
        nt += 1
    if swept >= 2.0 * np.pi - 1e-9:
        return -1
    return nt


@njit(cache=True)
def _ears(points, nx, ny, nz, xs, ys, poly, alive, m, R, rlen, limit2, tris):
    """The hole ``poly[:m]`` triangulated by ear clipping, best ear first: its number of
    triangles, or -1 if some step finds no valid ear (``_ear``)."""
    left = m
    nt = 0
    while left > 3:
        best = -1.0
        bi = -1
        ba = -1
        bb = -1
        for i in range(m):
            if not alive[i]:
                continue
            a = (i - 1) % m
            while not alive[a]:
                a = (a - 1) % m
            b = (i + 1) % m
            while not alive[b]:
                b = (b + 1) % m
            q = _ear(points, nx, ny, nz, xs, ys, poly, alive, m, a, i, b, R, rlen, limit2,
                     False)
            if q > best:
                best = q
                bi = i
                ba = a
                bb = b
        if bi < 0:
            return -1
        tris[nt, 0] = poly[ba]
        tris[nt, 1] = poly[bi]
        tris[nt, 2] = poly[bb]
        nt += 1
        alive[bi] = False
        left -= 1
    a = -1
    i = -1
    b = -1
    for j in range(m):
        if alive[j]:
            if a < 0:
                a = j
            elif i < 0:
                i = j
            else:
                b = j
    if _ear(points, nx, ny, nz, xs, ys, poly, alive, m, a, i, b, R, rlen, limit2, True) < 0:
        return -1
    tris[nt, 0] = poly[a]
    tris[nt, 1] = poly[i]
    tris[nt, 2] = poly[b]
    return nt + 1


@njit(cache=True)
def _height_over(points, p, q, nx, ny, nz):
    """The height of q over p's tangent plane (along the unit normal n)."""
    return ((points[q, 0] - points[p, 0]) * nx + (points[q, 1] - points[p, 1]) * ny
            + (points[q, 2] - points[p, 2]) * nz)


@njit(cache=True)
def _height(xs, ys, zs, a, b, c, x, y):
    """The height over (x, y) of the plane through the points a, b, c of (xs, ys, zs),
    if (x, y) lies in their triangle (closed); else nan."""
    d = (ys[b] - ys[c]) * (xs[a] - xs[c]) + (xs[c] - xs[b]) * (ys[a] - ys[c])
    if d == 0.0:
        return np.nan
    la = ((ys[b] - ys[c]) * (x - xs[c]) + (xs[c] - xs[b]) * (y - ys[c])) / d
    lb = ((ys[c] - ys[a]) * (x - xs[c]) + (xs[a] - xs[c]) * (y - ys[c])) / d
    lc = 1.0 - la - lb
    if la < 0.0 or lb < 0.0 or lc < 0.0:
        return np.nan
    return la * zs[a] + lb * zs[b] + lc * zs[c]


@njit(cache=True)
def _crosses(points, normals, R, rlen, ropen, p, tris, nt, near):
    """Whether the hole's new surface (``tris``) crosses another sheet: seen along p's
    normal, p's fan and the new triangles are height fields over the hole; a point that is
    neither p nor in its ring and lies over the hole must not lie between them (it would
    end up on the other side of the surface), and its fan's triangles must not cut the new
    ones. Only points still in the cloud (``active``) count; the points of the same sheet
    around the hole do not lie over it, so this costs little away from thin parts. A sheet
    that p's old fan already cuts (a mesh that intersects itself, as the cow's tail and
    body) does not count: the removal makes no crossing that was not there."""
    active, lo, inv_h, start, table = near
    m = rlen[p]
    ux, uy, uz, vx, vy, vz = tangent(normals[p, 0], normals[p, 1], normals[p, 2])
    nx = normals[p, 0]
    ny = normals[p, 1]
    nz = normals[p, 2]
    # local coordinates: the ring at 0..m-1, p at m
    xs = np.empty(m + 1)
    ys = np.empty(m + 1)
    zs = np.empty(m + 1)
    xs[m] = 0.0
    ys[m] = 0.0
    zs[m] = 0.0
    b0 = points[p].copy()
    b1 = points[p].copy()
    for j in range(m):
        q = R[p, j]
        xs[j], ys[j] = in_plane(points, p, q, ux, uy, uz, vx, vy, vz)
        zs[j] = _height_over(points, p, q, nx, ny, nz)
        for c in range(3):
            b0[c] = min(b0[c], points[q, c])
            b1[c] = max(b1[c], points[q, c])
    # the new triangles by ring position
    tloc = np.empty((nt, 3), np.int64)
    for t in range(nt):
        for c in range(3):
            for j in range(m):
                if R[p, j] == tris[t, c]:
                    tloc[t, c] = j
    # the box of the hole, and around it by a quarter of the longest spoke: triangles of
    # points there may reach over the hole (without the margin two tori 0.3 edges apart
    # crossed in 4 places at keep 0.2; a whole spoke doubles the cost and finds no more)
    spoke = 0.0
    for j in range(m):
        spoke = max(spoke, xs[j] * xs[j] + ys[j] * ys[j] + zs[j] * zs[j])
    spoke = SPOKE_MARGIN * np.sqrt(spoke)
    i0 = np.empty(3, np.int64)
    i1 = np.empty(3, np.int64)
    for c in range(3):
        i0[c] = min(max(int((b0[c] - spoke - lo[c]) * inv_h), 0), AXIS_MAX)
        i1[c] = min(max(int((b1[c] + spoke - lo[c]) * inv_h), 0), AXIS_MAX)
    n_old = m - 1 if ropen[p] else m
    old = np.empty((n_old, 3), np.int64)  # p's fan
    for j in range(n_old):
        old[j, 0] = p
        old[j, 1] = R[p, j]
        old[j, 2] = R[p, (j + 1) % m]
    for iz in range(i0[2], i1[2] + 1):
        for iy in range(i0[1], i1[1] + 1):
            for ix in range(i0[0], i1[0] + 1):
                cell = lookup(table, ix, iy, iz)
                if cell < 0:
                    continue
                for q in range(start[cell], start[cell + 1]):
                    if q == p or not active[q]:
                        continue
                    inside = True
                    near_box = True
                    for c in range(3):
                        if points[q, c] < b0[c] or points[q, c] > b1[c]:
                            inside = False
                            if (points[q, c] < b0[c] - spoke
                                    or points[q, c] > b1[c] + spoke):
                                near_box = False
                    if not near_box:
                        continue
                    mine = False
                    for j in range(m):
                        if R[p, j] == q:
                            mine = True
                            break
                    if mine:
                        continue
                    if not inside:  # around the box: only its triangles can reach in
                        # (not those of the ring's own neighbours: the same sheet, whose
                        # folds _folds_kept watches)
                        if (not _in_two_ring(R, rlen, p, q)
                                and _cuts(points, R, rlen, ropen, p, q, tris, nt, b0, b1)
                                and not _cuts(points, R, rlen, ropen, p, q, old, n_old, b0,
                                              b1)):
                            return True
                        continue
                    x, y = in_plane(points, p, q, ux, uy, uz, vx, vy, vz)
                    z = _height_over(points, p, q, nx, ny, nz)
                    h_old = np.nan
                    for j in range(n_old):
                        h_old = _height(xs, ys, zs, m, j, (j + 1) % m, x, y)
                        if not np.isnan(h_old):
                            break
                    if np.isnan(h_old):
                        # beside the hole: its triangles may still reach over it
                        if (not _in_two_ring(R, rlen, p, q)
                                and _cuts(points, R, rlen, ropen, p, q, tris, nt, b0, b1)
                                and not _cuts(points, R, rlen, ropen, p, q, old, n_old, b0,
                                              b1)):
                            return True
                        continue
                    h_new = np.nan
                    for t in range(nt):
                        h_new = _height(xs, ys, zs, tloc[t, 0], tloc[t, 1], tloc[t, 2], x, y)
                        if not np.isnan(h_new):
                            break
                    if np.isnan(h_new):
                        continue
                    if ((min(h_old, h_new) < z < max(h_old, h_new)
                         # q is over the hole: its triangles must not cut the new ones
                         or _cuts(points, R, rlen, ropen, p, q, tris, nt, b0, b1))
                            and not _cuts(points, R, rlen, ropen, p, q, old, n_old, b0, b1)):
                        return True
    return False


@njit(cache=True)
def hole_box_cells(points, R, rlen, p, lo, inv_h):
    """The integer cell ranges (i0, i1: 3 each) of the box of p and its ring."""
    i0 = np.empty(3, np.int64)
    i1 = np.empty(3, np.int64)
    for c in range(3):
        b0 = points[p, c]
        b1 = points[p, c]
        for j in range(rlen[p]):
            b0 = min(b0, points[R[p, j], c])
            b1 = max(b1, points[R[p, j], c])
        i0[c] = min(max(int((b0 - lo[c]) * inv_h), 0), AXIS_MAX)
        i1[c] = min(max(int((b1 - lo[c]) * inv_h), 0), AXIS_MAX)
    return i0, i1


@njit(cache=True)
def _slot(keys, key):
    """The slot of ``key`` in the open-addressing table ``keys`` (-1: empty)."""
    mask = keys.shape[0] - 1
    h = ((key ^ (key >> 29)) * 0x5851F42D4C957F2D) & mask
    while keys[h] != -1 and keys[h] != key:
        h = (h + 1) & mask
    return h


@njit(cache=True)
def defer_overlaps(points, R, rlen, acc, lo, inv_h, defer):
    """Of removals made together (a round), in order, ``defer`` those whose hole's box
    meets a cell of an earlier one's that goes ahead: each checks its new triangles
    against the surface as it was, so two neighbours in space (not in the rings: on two
    sheets) must not change it at once."""
    n_acc = acc.shape[0]
    lo_c = np.empty((n_acc, 3), np.int64)
    hi_c = np.empty((n_acc, 3), np.int64)
    total = 0
    for i in range(n_acc):
        i0, i1 = hole_box_cells(points, R, rlen, acc[i], lo, inv_h)
        lo_c[i] = i0
        hi_c[i] = i1
        total += (i1[0] - i0[0] + 1) * (i1[1] - i0[1] + 1) * (i1[2] - i0[2] + 1)
    size = 16
    while size < 2 * total:
        size *= 2
    keys = np.full(size, -1, np.int64)
    for i in range(n_acc):
        clash = False
        for iz in range(lo_c[i, 2], hi_c[i, 2] + 1):
            for iy in range(lo_c[i, 1], hi_c[i, 1] + 1):
                for ix in range(lo_c[i, 0], hi_c[i, 0] + 1):
                    key = ix | (iy << 21) | (iz << 42)
                    if keys[_slot(keys, key)] == key:
                        clash = True
        defer[i] = clash
        if clash:
            continue
        for iz in range(lo_c[i, 2], hi_c[i, 2] + 1):
            for iy in range(lo_c[i, 1], hi_c[i, 1] + 1):
                for ix in range(lo_c[i, 0], hi_c[i, 0] + 1):
                    key = ix | (iy << 21) | (iz << 42)
                    keys[_slot(keys, key)] = key


@njit(cache=True)
def _in_two_ring(R, rlen, p, q):
    """q is in the ring of a point of p's ring."""
    for j in range(rlen[p]):
        r = R[p, j]
        for a in range(rlen[r]):
            if R[r, a] == q:
                return True
    return False


@njit(cache=True)
def _reaches(points, p, q, a, b, b0, b1):
    """The triangle q a b has no point p and meets the box b0..b1."""
    if a == p or b == p:
        return False
    for c in range(3):
        if (max(points[q, c], points[a, c], points[b, c]) < b0[c]
                or min(points[q, c], points[a, c], points[b, c]) > b1[c]):
            return False
    return True


@njit(cache=True)
def _cuts(points, R, rlen, ropen, p, q, tris, nt, b0, b1):
    """Whether a triangle of q's fan (one without p) intersects a new triangle (all of
    which lie in the box ``b0``..``b1``)."""
    k = rlen[q]
    n_q = k - 1 if ropen[q] else k
    # first without allocating: most points around the hole have no triangle in its box
    m = 0
    for j in range(n_q):
        if _reaches(points, p, q, R[q, j], R[q, (j + 1) % k], b0, b1):
            m += 1
    if m == 0:
        return False
    local = np.empty((nt + m, 3), np.int64)
    for t in range(nt):
        for c in range(3):
            local[t, c] = tris[t, c]
    m = nt
    for j in range(n_q):
        a = R[q, j]
        b = R[q, (j + 1) % k]
        if not _reaches(points, p, q, a, b, b0, b1):
            continue
        local[m, 0] = q
        local[m, 1] = a
        local[m, 2] = b
        m += 1
    if m == nt:
        return False
    local = local[:m]
    normal, longest, _, _, flat = few_triangle_frames(points, local, AREA_TOL, INTERSECTION_TOL)
    for t in range(nt):
        if flat[t]:
            continue
        for u in range(nt, m):
            if flat[u]:
                continue
            if _pair_intersects(points, local, normal, longest, t, u, INTERSECTION_TOL):
                return True
    return False


@njit(cache=True)
def _unit_normal(points, a, b, c):
    cx, cy, cz = triangle_cross(points, a, b, c)
    s = np.sqrt(cx * cx + cy * cy + cz * cz)
    if s == 0.0:
        return 0.0, 0.0, 0.0
    return cx / s, cy / s, cz / s


@njit(cache=True)
def _folds_kept(points, R, rlen, ropen, p, tris, nt):
    """Across every edge u v of the hole, the new triangle bends against the triangle
    outside (u o v) by no more than the old one (p u v) did, or than MAX_FOLD: a removal
    never makes a sharper fold than it found (folds turn into self-intersections)."""
    m = rlen[p]
    for j in range(m - 1 if ropen[p] else m):
        u = R[p, j]
        v = R[p, (j + 1) % m]
        # o: the point before v in u's ring (the triangle u o v outside the hole)
        o = -1
        k = rlen[u]
        for a in range(k):
            if R[u, a] == v:
                if a > 0:
                    o = R[u, a - 1]
                elif not ropen[u]:
                    o = R[u, k - 1]
                break
        if o < 0 or o == p:
            continue
        # the new triangle holding the edge u -> v
        t = -1
        for s in range(nt):
            for c in range(3):
                if tris[s, c] == u and tris[s, (c + 1) % 3] == v:
                    t = s
        if t < 0:
            return False
        ox, oy, oz = _unit_normal(points, u, o, v)
        tx, ty, tz = _unit_normal(points, tris[t, 0], tris[t, 1], tris[t, 2])
        px, py, pz = _unit_normal(points, p, u, v)
        new = tx * ox + ty * oy + tz * oz
        old = px * ox + py * oy + pz * oz
        if new < min(old, COS_MAX_FOLD):
            return False
    return True


@njit(cache=True)
def splice_ring(R, rlen, ropen, x, p, tris, nt, out):
    """x's ring with p replaced by x's partners in the hole's triangulation ``tris[:nt]``,
    written to ``out``; returns its size, or -1 if the rings do not fit together (x's ring
    does not hold p between the points the triangulation says, or the new ring would
    repeat a point, be too long, or close on fewer than 3 points)."""
    k = rlen[x]
    width = out.shape[0]
    j = -1
    for a in range(k):
        if R[x, a] == p:
            j = a
            break
    if j < 0:
        return -1
    # where p sits in x's ring must agree with p's ring: an edge x p on the boundary (p
    # at an end of x's open ring) is one of the two boundary edges of p's open ring
    at_end = ropen[x] and (j == 0 or j == k - 1)
    if ropen[p] and x == R[p, 0]:
        if not (ropen[x] and j == k - 1):
            return -1
    elif ropen[p] and x == R[p, rlen[p] - 1]:
        if not (ropen[x] and j == 0):
            return -1
    elif at_end:
        return -1
    # x's triangles in the triangulation, chained: (x, b, c) means b then c around x
    start = -1
    n_x = 0
    for t in range(nt):
        for c in range(3):
            if tris[t, c] == x:
                n_x += 1
                b = tris[t, (c + 1) % 3]
                # the chain starts at a b that is no triangle's c
                first = True
                for s in range(nt):
                    for e in range(3):
                        if tris[s, e] == x and tris[s, (e + 2) % 3] == b:
                            first = False
                if first:
                    start = b
    if n_x == 0 or start < 0:
        return -1
    # the chain, at most n_x + 1 points
    chain = np.empty(n_x + 1, np.int64)
    chain[0] = start
    length = 1
    cur = start
    for _ in range(n_x):
        nxt = -1
        for t in range(nt):
            for c in range(3):
                if tris[t, c] == x and tris[t, (c + 1) % 3] == cur:
                    nxt = tris[t, (c + 2) % 3]
        if nxt < 0:
            return -1
        chain[length] = nxt
        length += 1
        cur = nxt
    # the window of x's ring that p's removal replaces: p and its ring neighbours
    closed = not ropen[x]
    if closed:
        if k < 3:
            return -1
        before = R[x, (j - 1) % k]
        after = R[x, (j + 1) % k]
        if before != chain[0] or after != chain[length - 1]:
            return -1
        size = k - 3 + length
        if size < 3 or size > width:
            return -1
        # the ring from chain[0] on: the chain, then the rest of x's ring
        for a in range(length):
            out[a] = chain[a]
        for a in range(k - 3):
            out[length + a] = R[x, (j + 2 + a) % k]
    else:
        lo = j - 1 if j > 0 else j
        hi = j + 1 if j < k - 1 else j
        if j > 0 and R[x, j - 1] != chain[0]:
            return -1
        if j < k - 1 and R[x, j + 1] != chain[length - 1]:
            return -1
        size = lo + length + (k - 1 - hi)
        if size < 2 or size > width:
            return -1
        for a in range(lo):
            out[a] = R[x, a]
        for a in range(length):
            out[lo + a] = chain[a]
        for a in range(hi + 1, k):
            out[lo + length + a - hi - 1] = R[x, a]
    # no point twice
    for a in range(size):
        for b in range(a + 1, size):
            if out[a] == out[b]:
                return -1
    return size




@njit(cache=True)
def _boxes_meet(points, local, t, u):
    for c in range(3):
        if (max(points[local[t, 0], c], points[local[t, 1], c], points[local[t, 2], c])
                < min(points[local[u, 0], c], points[local[u, 1], c], points[local[u, 2], c])):
            return False
        if (min(points[local[t, 0], c], points[local[t, 1], c], points[local[t, 2], c])
                > max(points[local[u, 0], c], points[local[u, 1], c], points[local[u, 2], c])):
            return False
    return True


@njit(cache=True)
def folds_onto_ring(points, R, rlen, ropen, p, tris, nt):
    """Whether a new triangle (``tris[:nt]``) intersects a triangle of a fan of p's ring
    that p's old fan did not intersect: a fold of the surface onto itself next to the hole
    (the crossing test leaves the ring's own fans to this). Only with the quadric key,
    which has no fold rule."""
    m = rlen[p]
    n_old = m - 1 if ropen[p] else m
    n_ring = 0
    for j in range(m):
        n_ring += rlen[R[p, j]]
    # the new triangles, p's old fan, then the ring's triangles without p (each once: a
    # triangle of two ring points is kept by the first of them in p's ring)
    local = np.empty((nt + n_old + n_ring, 3), np.int64)
    for t in range(nt):
        for c in range(3):
            local[t, c] = tris[t, c]
    for j in range(n_old):
        local[nt + j, 0] = p
        local[nt + j, 1] = R[p, j]
        local[nt + j, 2] = R[p, (j + 1) % m]
    n = nt + n_old
    for j in range(m):
        r = R[p, j]
        k = rlen[r]
        for a in range(k - 1 if ropen[r] else k):
            u = R[r, a]
            v = R[r, (a + 1) % k]
            if u == p or v == p:
                continue
            dup = False
            for jj in range(j):
                if R[p, jj] == u or R[p, jj] == v:
                    dup = True
                    break
            if not dup:
                local[n, 0] = r
                local[n, 1] = u
                local[n, 2] = v
                n += 1
    local = local[:n]
    normal, longest, _, _, flat = few_triangle_frames(points, local, AREA_TOL, INTERSECTION_TOL)
    for u in range(nt + n_old, n):
        if (not flat[u] and _meets_any(points, local, normal, longest, flat, 0, nt, u)
                and not _meets_any(points, local, normal, longest, flat, nt, nt + n_old, u)):
            return True
    return False


@njit(cache=True)
def _meets_any(points, local, normal, longest, flat, lo, hi, u):
    """Whether triangle u of ``local`` intersects one of its triangles lo..hi-1."""
    for t in range(lo, hi):
        if (not flat[t] and _boxes_meet(points, local, t, u)
                and _pair_intersects(points, local, normal, longest, t, u, INTERSECTION_TOL)):
            return True
    return False
