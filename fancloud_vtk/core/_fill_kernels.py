"""Numba kernels of the last hole filling of the mesh (:mod:`fancloud_vtk.core.mesh`).

A boundary loop that the tangent-plane fillers (stars, Delaunay fills, ears)
could not close is triangulated in space by dynamic programming over its
sub-polygons, as Liepa does for mesh holes (P. Liepa, *Filling holes in
meshes*, SGP 2003): of all the triangulations that use only the loop's
vertices, the one whose largest dihedral angle (between neighbouring new
triangles, and between a new triangle and the mesh triangle on a loop edge)
is the smallest, then the one of least area. A diagonal that is already an
edge of the mesh is not used (it would be a third triangle on that edge).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._edge_kernels import has_edge
from ._geometry_kernels import triangle_cross
from .mesh_stats import (
    _box_summary,
    _boxes_apart,
    _longest_edge_normal,
    _pair_intersects,
    few_triangle_frames,
)


@njit(cache=True)
def _angle(n1, n2):
    """The angle between two (unnormalised) normals, in [0, pi]; pi for a degenerate one."""
    l1 = np.sqrt(n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2])
    l2 = np.sqrt(n2[0] * n2[0] + n2[1] * n2[1] + n2[2] * n2[2])
    if l1 == 0.0 or l2 == 0.0:
        return np.pi
    c = (n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]) / (l1 * l2)
    return np.arccos(min(1.0, max(-1.0, c)))


@njit(cache=True)
def _third(triangles, vt_off, vt, a, b):
    """(third vertex, +1 if the triangle runs a -> b, -1 if b -> a) of a triangle on edge a-b;
    (-1, 0) if there is none."""
    for i in range(vt_off[a], vt_off[a + 1]):
        t = vt[i]
        for k in range(3):
            if triangles[t, k] == a:
                nb = triangles[t, (k + 1) % 3]
                pb = triangles[t, (k + 2) % 3]
                if nb == b:
                    return pb, 1
                if pb == b:
                    return nb, -1
    return -1, 0


#: cells per axis of the grid over the triangles near a loop (:func:`_near_grid`), at most
GRID_SIDE = 32


@njit(cache=True)
def _near_grid(lo, hi, n):
    """A grid of cubic cells over the boxes ``lo[:n]``, ``hi[:n]``: ``(origin, cell, side,
    offsets, members)``, each box listed in every cell it overlaps (CSR).

    Cells the mean largest side of the boxes, at most ``GRID_SIDE`` per axis
    (``side`` of them).
    """
    if n == 0:
        return np.zeros(3), 1.0, 1, np.zeros(2, np.int64), np.empty(0, np.int64)
    origin, span, mean = _box_summary(lo[:n], hi[:n])
    cell = max(mean, span / GRID_SIDE)
    if cell <= 0.0:
        cell = 1.0
    side = min(GRID_SIDE, int(span / cell) + 1)
    counts = np.zeros(side * side * side + 1, np.int64)
    members = np.empty(0, np.int64)
    fill = counts
    for sweep in range(2):
        if sweep == 1:
            for c in range(1, counts.shape[0]):
                counts[c] += counts[c - 1]
            members = np.empty(counts[-1], np.int64)
            fill = counts.copy()
        for t in range(n):
            i0, i1, j0, j1, k0, k1 = _cells(lo, hi, t, origin, cell, side)
            for i in range(i0, i1 + 1):
                for j in range(j0, j1 + 1):
                    for k in range(k0, k1 + 1):
                        c = (i * side + j) * side + k
                        if sweep == 0:
                            counts[c + 1] += 1
                        else:
                            members[fill[c]] = t
                            fill[c] += 1
    return origin, cell, side, counts, members


@njit(cache=True)
def _cells(lo, hi, t, origin, cell, side):
    """The first and last cell on each axis (clamped to the grid) of box ``t``."""
    out = np.empty(6, np.int64)
    for d in range(3):
        a = int(np.floor((lo[t, d] - origin[d]) / cell))
        b = int(np.floor((hi[t, d] - origin[d]) / cell))
        out[2 * d] = min(max(a, 0), side - 1)
        out[2 * d + 1] = min(max(b, 0), side - 1)
    return out[0], out[1], out[2], out[3], out[4], out[5]


@njit(cache=True)
def _clear(points, a, b, c, tri, normal, longest, lo, hi, flat, tol, area_tol, grid, seen):
    """Does triangle (a, b, c) have an area and meet none of ``tri`` but its last row?

    ``tri``: the mesh triangles near a loop and a last free row; ``normal``,
    ``longest``, ``lo``, ``hi``, ``flat``: their frames from
    :func:`fancloud_vtk.core.mesh_stats._triangle_frames` (the last row's
    are overwritten). A pair is tested as
    :func:`~fancloud_vtk.core.mesh_stats.self_intersecting_pairs` tests it:
    sharing a vertex or an edge without overlapping is allowed. ``grid``:
    :func:`_near_grid` of the rows but the last; only the rows in the cells
    the triangle's box overlaps are tested (``seen``: a row's last call, so
    that each is tested once; ``seen[-1]`` counts the calls).
    """
    slot = tri.shape[0] - 1
    tri[slot, 0] = a
    tri[slot, 1] = b
    tri[slot, 2] = c
    best, nx, ny, nz, nn = _longest_edge_normal(points, tri, slot)
    if nn <= area_tol * best or nn == 0.0:
        return False
    length = np.sqrt(best)
    normal[slot, 0] = nx / nn
    normal[slot, 1] = ny / nn
    normal[slot, 2] = nz / nn
    longest[slot] = length
    pad = 2.0 * tol * length
    for d in range(3):
        x0 = points[a, d]
        x1 = points[b, d]
        x2 = points[c, d]
        lo[slot, d] = min(x0, x1, x2) - pad
        hi[slot, d] = max(x0, x1, x2) + pad
    origin, cell, side, offsets, members = grid
    seen[-1] += 1
    stamp = seen[-1]
    i0, i1, j0, j1, k0, k1 = _cells(lo, hi, slot, origin, cell, side)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                cc = (i * side + j) * side + k
                for r in range(offsets[cc], offsets[cc + 1]):
                    t = members[r]
                    if seen[t] == stamp:
                        continue
                    seen[t] = stamp
                    if flat[t]:
                        continue
                    if _boxes_apart(lo, hi, t, slot):
                        continue
                    if _pair_intersects(points, tri, normal, longest, slot, t, tol):
                        return False
    return True


@njit(cache=True)
def fill_loop(points, loop, triangles, vt_off, vt, max_angle, near, normal, longest, lo, hi,
              flat, tol, area_tol):
    """Triangulate one boundary loop of a mesh (see the module docstring).

    ``loop``: the loop's vertices in order (``m >= 3``). Returns ``(m - 2, 3)``
    triangles oriented like the mesh around them (each loop edge is run
    against the mesh triangle on it), or an empty array when no
    triangulation exists without a mesh edge as a diagonal, with a repeated
    vertex in a triangle, or with every dihedral angle at most
    ``max_angle`` (radians). With ``near`` not empty (the mesh triangles
    near the loop and a free last row, with their frames ``normal`` ...
    ``flat``, see :func:`_clear`), only triangles that cross none of them
    are used.
    """
    m = loop.shape[0]
    empty = np.empty((0, 3), np.int64)
    if m < 3:
        return empty
    # the orientation: a loop edge runs with its mesh triangle, so new triangles run against
    sign = 0
    n_near = max(near.shape[0] - 1, 0)
    grid = _near_grid(lo, hi, n_near)
    seen = np.zeros(n_near + 1, np.int64)
    third = np.full(m, -1, np.int64)  # the mesh triangle's third vertex on loop edge (j, j+1)
    for j in range(m):
        a = loop[j]
        b = loop[(j + 1) % m]
        c, d = _third(triangles, vt_off, vt, a, b)
        third[j] = c
        if sign == 0 and d != 0:
            sign = -d
    if sign == 0:
        sign = 1
    big = np.inf
    ang = np.full((m, m), big)
    area = np.full((m, m), big)
    apex = np.full((m, m), -1, np.int64)
    for i in range(m - 1):
        ang[i, i + 1] = 0.0
        area[i, i + 1] = 0.0
    for span in range(2, m):
        for i in range(0, m - span):
            j = i + span
            vi = loop[i]
            vj = loop[j]
            if vi == vj:
                continue
            # the diagonal i-j (the closing edge 0-(m-1) is a loop edge)
            if not (i == 0 and j == m - 1) and has_edge(triangles, vt_off, vt, vi, vj):
                continue
            best_a = big
            best_s = big
            best_k = -1
            for k in range(i + 1, j):
                if ang[i, k] == big or ang[k, j] == big:
                    continue
                vk = loop[k]
                if vk == vi or vk == vj:
                    continue
                nx, ny, nz = triangle_cross(points, vi, vk, vj)
                n = (sign * nx, sign * ny, sign * nz)
                s = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
                if s == 0.0:
                    continue
                worst = max(ang[i, k], ang[k, j])
                # across i-k: the sub-polygon's triangle, or the mesh triangle on a loop edge
                for side in range(2):
                    e0 = i if side == 0 else k
                    e1 = k if side == 0 else j
                    if e1 == e0 + 1:
                        t = third[e0]
                        if t < 0:
                            continue
                        # the mesh triangle's normal, as it runs (d: +1 e0 -> e1, -1 e1 -> e0)
                        mx, my, mz = triangle_cross(points, loop[e0], loop[e1], t)
                        _, d = _third(triangles, vt_off, vt, loop[e0], loop[e1])
                        mn = (d * mx, d * my, d * mz)
                    else:
                        q = apex[e0, e1]
                        mx, my, mz = triangle_cross(points, loop[e0], loop[q], loop[e1])
                        mn = (sign * mx, sign * my, sign * mz)
                    worst = max(worst, _angle(n, mn))
                if span == m - 1:  # the closing loop edge (m-1, 0)
                    t = third[m - 1]
                    if t >= 0:
                        mx, my, mz = triangle_cross(points, loop[m - 1], loop[0], t)
                        _, d = _third(triangles, vt_off, vt, loop[m - 1], loop[0])
                        mn = (d * mx, d * my, d * mz)
                        worst = max(worst, _angle(n, mn))
                if worst > max_angle:
                    continue
                total = area[i, k] + area[k, j] + s
                if not ((worst < best_a - 1e-2) or (worst <= best_a + 1e-2 and total < best_s)):
                    continue
                if near.shape[0] and not _clear(
                    points, vi, vk, vj, near, normal, longest, lo, hi, flat, tol, area_tol,
                    grid, seen
                ):
                    continue
                # the smallest largest angle (to a hundredth of a radian), then the least area
                if (worst < best_a - 1e-2) or (worst <= best_a + 1e-2 and total < best_s):
                    best_a = worst
                    best_s = total
                    best_k = k
            if best_k >= 0:
                ang[i, j] = best_a
                area[i, j] = best_s
                apex[i, j] = best_k
    if apex[0, m - 1] < 0:
        return empty
    out = np.empty((m - 2, 3), np.int64)
    stack = np.empty((m, 2), np.int64)
    top = 0
    stack[0, 0] = 0
    stack[0, 1] = m - 1
    top = 1
    row = 0
    while top > 0:
        top -= 1
        i = stack[top, 0]
        j = stack[top, 1]
        if j - i < 2:
            continue
        k = apex[i, j]
        if sign > 0:
            out[row, 0] = loop[i]
            out[row, 1] = loop[k]
            out[row, 2] = loop[j]
        else:
            out[row, 0] = loop[j]
            out[row, 1] = loop[k]
            out[row, 2] = loop[i]
        row += 1
        stack[top, 0] = i
        stack[top, 1] = k
        top += 1
        stack[top, 0] = k
        stack[top, 1] = j
        top += 1
    return out


@njit(cache=True)
def closest_on_triangles(x, corners):
    """Barycentric coordinates ``(k, 3)`` of the points of triangles ``corners`` ``(k, 3, 3)``
    closest to the point ``x`` (Ericson, *Real-Time Collision Detection*, 5.1.5)."""
    k = corners.shape[0]
    out = np.zeros((k, 3))
    for t in range(k):
        a = corners[t, 0]
        b = corners[t, 1]
        c = corners[t, 2]
        ab = b - a
        ac = c - a
        ap = x - a
        d1 = ab @ ap
        d2 = ac @ ap
        if d1 <= 0.0 and d2 <= 0.0:
            out[t, 0] = 1.0
            continue
        bp = x - b
        d3 = ab @ bp
        d4 = ac @ bp
        if d3 >= 0.0 and d4 <= d3:
            out[t, 1] = 1.0
            continue
        vc = d1 * d4 - d3 * d2
        if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            v = d1 / (d1 - d3)
            out[t, 0] = 1.0 - v
            out[t, 1] = v
            continue
        cp = x - c
        d5 = ab @ cp
        d6 = ac @ cp
        if d6 >= 0.0 and d5 <= d6:
            out[t, 2] = 1.0
            continue
        vb = d5 * d2 - d1 * d6
        if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            w = d2 / (d2 - d6)
            out[t, 0] = 1.0 - w
            out[t, 2] = w
            continue
        va = d3 * d6 - d5 * d4
        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            out[t, 1] = 1.0 - w
            out[t, 2] = w
            continue
        denom = 1.0 / (va + vb + vc)
        v = vb * denom
        w = vc * denom
        out[t, 0] = 1.0 - v - w
        out[t, 1] = v
        out[t, 2] = w
    return out


@njit(cache=True)
def meets(points, tri, n_base, tol, area_tol):
    """Per row ``r >= n_base`` of ``tri``: does it intersect another row (as
    :func:`~fancloud_vtk.core.mesh_stats.self_intersecting_pairs` tests a pair;
    rows below ``n_base`` are not tested against each other)?"""
    normal, longest, lo, hi, flat = few_triangle_frames(points, tri, area_tol, tol)
    m = tri.shape[0]
    hit = np.zeros(m - n_base, np.bool_)
    for r in range(n_base, m):
        if flat[r]:
            continue
        for t in range(m):
            if t == r or flat[t]:
                continue
            if _boxes_apart(lo, hi, t, r):
                continue
            if _pair_intersects(points, tri, normal, longest, r, t, tol):
                hit[r - n_base] = True
                break
    return hit


@njit(cache=True, parallel=True)
def centroids_reach(points, triangles):
    """(centroids ``(m, 3)``, reach): each triangle's centroid, and the largest distance of
    a corner from its triangle's centroid (what a triangle can touch around its centroid)."""
    m = triangles.shape[0]
    cen = np.empty((m, 3))
    far = np.zeros(m)
    for t in prange(m):
        a = triangles[t, 0]
        b = triangles[t, 1]
        c = triangles[t, 2]
        for d in range(3):
            cen[t, d] = (points[a, d] + points[b, d] + points[c, d]) / 3.0
        r = 0.0
        for k in range(3):
            v = triangles[t, k]
            s = 0.0
            for d in range(3):
                e = points[v, d] - cen[t, d]
                s += e * e
            r = max(r, s)
        far[t] = r
    reach = 0.0
    for t in range(m):
        reach = max(reach, far[t])
    return cen, np.sqrt(reach)


@njit(cache=True, parallel=True)
def near_seeds(x, seeds, radius):
    """Mask of the points ``x`` ``(m, 3)`` within ``radius[i]`` of some ``seeds[i]`` (a grid
    of cells as wide as the largest radius, so a point is compared with the seeds of its
    own and the 26 neighbouring cells only)."""
    m = x.shape[0]
    s = seeds.shape[0]
    out = np.zeros(m, np.bool_)
    if s == 0 or m == 0:
        return out
    lo = np.empty(3)
    hi = np.empty(3)
    for d in range(3):
        lo[d] = seeds[:, d].min()
        hi[d] = seeds[:, d].max()
    r = radius.max()
    # at most about 1e5 cells a side, whatever the radius (the keys stay in int64)
    r = max(r, (hi - lo).max() * 1e-5, 1e-300)
    dims = np.empty(3, np.int64)
    for d in range(3):
        dims[d] = np.int64((hi[d] - lo[d]) / r) + 1
    keys = np.empty(s, np.int64)
    for i in range(s):
        c0 = min(np.int64((seeds[i, 0] - lo[0]) / r), dims[0] - 1)
        c1 = min(np.int64((seeds[i, 1] - lo[1]) / r), dims[1] - 1)
        c2 = min(np.int64((seeds[i, 2] - lo[2]) / r), dims[2] - 1)
        keys[i] = (c2 * dims[1] + c1) * dims[0] + c0
    order = np.argsort(keys, kind="mergesort")
    sk = keys[order]
    for t in prange(m):
        f0 = (x[t, 0] - lo[0]) / r
        f1 = (x[t, 1] - lo[1]) / r
        f2 = (x[t, 2] - lo[2]) / r
        if (f0 < -1.0 or f1 < -1.0 or f2 < -1.0 or f0 >= dims[0] + 1.0
                or f1 >= dims[1] + 1.0 or f2 >= dims[2] + 1.0):
            continue
        i0 = np.int64(np.floor(f0))
        i1 = np.int64(np.floor(f1))
        i2 = np.int64(np.floor(f2))
        found = False
        for c2 in range(max(i2 - 1, 0), min(i2 + 1, dims[2] - 1) + 1):
            for c1 in range(max(i1 - 1, 0), min(i1 + 1, dims[1] - 1) + 1):
                for c0 in range(max(i0 - 1, 0), min(i0 + 1, dims[0] - 1) + 1):
                    key = (c2 * dims[1] + c1) * dims[0] + c0
                    j = np.searchsorted(sk, key)
                    while j < s and sk[j] == key:
                        q = order[j]
                        e = 0.0
                        for d in range(3):
                            g = x[t, d] - seeds[q, d]
                            e += g * g
                        if e <= radius[q] * radius[q]:
                            found = True
                            break
                        j += 1
                    if found:
                        break
                if found:
                    break
            if found:
                break
        out[t] = found
    return out


@njit(cache=True)
def _faces_like(points, tri, rows, n_rows, o):
    """Do the first ``n_rows`` triangles ``rows`` face the way triangle ``o`` of ``tri``
    does (positive dot product of the unnormalised normals)?"""
    ref = triangle_cross(points, tri[o, 0], tri[o, 1], tri[o, 2])
    for r in range(n_rows):
        c = triangle_cross(points, rows[r, 0], rows[r, 1], rows[r, 2])
        if c[0] * ref[0] + c[1] * ref[1] + c[2] * ref[2] <= 0.0:
            return False
    return True


@njit(cache=True)
def _segment_distance(points, p, a, b):
    """Distance from point ``p`` to the segment ``ab`` (indices into ``points``)."""
    ab = points[b] - points[a]
    t = ((points[p] - points[a]) @ ab) / max(ab @ ab, 1e-300)
    t = min(1.0, max(0.0, t))
    return np.sqrt(np.sum((points[a] + t * ab - points[p]) ** 2))


@njit(cache=True)
def _split_crosses(points, tris, around, n_around, old, n_old, new, n_new, tol, area_tol):
    """Do the new triangles cross a triangle of ``around`` (not in ``old``) or each other?"""
    both = np.empty((n_around + n_new, 3), np.int64)
    k = 0
    for i in range(n_around):
        t = around[i]
        skip = False
        for j in range(n_old):
            if old[j] == t:
                skip = True
        if skip:
            continue
        both[k] = tris[t]
        k += 1
    for i in range(n_new):
        both[k + i] = new[i]
    hit = meets(points, both[: k + n_new], k, tol, area_tol)
    return hit.any()


@njit(cache=True)
def _set_row(rows, r, a, b, c):
    """Row ``r`` of ``rows`` becomes the triangle (a, b, c)."""
    rows[r, 0] = a
    rows[r, 1] = b
    rows[r, 2] = c


@njit(cache=True)
def _alive_rows(off, idx, i, alive, m, top):
    """The triangles of row ``i`` of the CSR list (``off``, ``idx``), then those made so
    far (``m`` to ``top``), that are alive."""
    out = np.empty(off[i + 1] - off[i] + top - m, np.int64)
    k = 0
    for a in range(off[i], off[i + 1]):
        if alive[idx[a]]:
            out[k] = idx[a]
            k += 1
    for t in range(m, top):
        if alive[t]:
            out[k] = t
            k += 1
    return out[:k]


@njit(cache=True)
def insert_nearest(points, tris, alive, m, todo, spacing, vspacing, knn_off, knn, ball_off,
                   ball, far, edge, tries, max_edge, tol, area_tol):
    """The loop of :func:`fancloud_vtk.core.mesh._insert_nearest` over the points ``todo``.

    ``tris``: the mesh (``m`` rows) and room for the triangles made; ``alive``
    its mask (changed here). ``spacing[i]``: the local spacing of
    ``todo[i]``; ``vspacing[v]``: vertex v's (its median ring distance),
    for every corner that can come up. ``knn`` (CSR): the mesh triangles
    nearest to each point, in order of distance, within the search bound;
    ``ball`` (CSR): the mesh triangles a split there could cross. Returns
    (rows used in ``tris``, points inserted, failed mask over ``todo``).
    """
    top = m
    inserted = 0
    failed = np.zeros(todo.shape[0], np.bool_)
    new = np.empty((4, 3), np.int64)
    old = np.empty(2, np.int64)
    for i in range(todo.shape[0]):
        p = todo[i]
        h = spacing[i]
        # the candidates: the nearest mesh triangles, then the triangles made so far
        cand = _alive_rows(knn_off, knn, i, alive, m, top)
        n_cand = cand.shape[0]
        if n_cand == 0:
            continue
        corners = np.empty((n_cand, 3, 3))
        for c in range(n_cand):
            for j in range(3):
                corners[c, j] = points[tris[cand[c], j]]
        bary = closest_on_triangles(points[p], corners)
        dist = np.empty(n_cand)
        ok = np.zeros(n_cand, np.bool_)
        for c in range(n_cand):
            q = bary[c, 0] * corners[c, 0] + bary[c, 1] * corners[c, 1] \
                + bary[c, 2] * corners[c, 2]
            dist[c] = np.sqrt(np.sum((q - points[p]) ** 2))
            longest = 0.0
            for j in range(3):
                longest = max(longest, np.sqrt(np.sum((corners[c, j] - corners[c, (j + 1) % 3])
                                                      ** 2)))
            s0 = vspacing[tris[cand[c], 0]]
            s1 = vspacing[tris[cand[c], 1]]
            s2 = vspacing[tris[cand[c], 2]]
            med = max(min(s0, s1), min(max(s0, s1), s2))
            local = min(h, med)
            ok[c] = dist[c] <= far * local and longest <= max_edge * local
        order = np.flatnonzero(ok)
        if order.shape[0] == 0:
            continue
        # by distance, then triangle number
        key_d = dist[order]
        key_t = cand[order]
        for a in range(1, order.shape[0]):
            j = a
            while j > 0 and (key_d[j - 1] > key_d[j]
                             or (key_d[j - 1] == key_d[j] and key_t[j - 1] > key_t[j])):
                key_d[j - 1], key_d[j] = key_d[j], key_d[j - 1]
                key_t[j - 1], key_t[j] = key_t[j], key_t[j - 1]
                order[j - 1], order[j] = order[j], order[j - 1]
                j -= 1
        failed[i] = True  # unless a split below is made
        around = _alive_rows(ball_off, ball, i, alive, m, top)
        n_around = around.shape[0]
        done = False
        for r in range(min(tries, order.shape[0])):
            c = order[r]
            t = cand[c]
            a0 = tris[t, 0]
            b0 = tris[t, 1]
            c0 = tris[t, 2]
            if bary[c, 0] >= edge and bary[c, 1] >= edge and bary[c, 2] >= edge:
                n_sides = 1  # one option: the 1 -> 3 split
            else:
                n_sides = 3
            sides = np.arange(3)
            if n_sides == 3:  # the edges, nearest to p first (stable)
                sd = np.empty(3)
                for k in range(3):
                    sd[k] = _segment_distance(points, p, tris[t, (k + 1) % 3],
                                              tris[t, (k + 2) % 3])
                for a in range(1, 3):
                    j = a
                    while j > 0 and sd[sides[j - 1]] > sd[sides[j]]:
                        sides[j - 1], sides[j] = sides[j], sides[j - 1]
                        j -= 1
            for si in range(n_sides):
                if n_sides == 1:
                    old[0] = t
                    n_old = 1
                    _set_row(new, 0, a0, b0, p)
                    _set_row(new, 1, b0, c0, p)
                    _set_row(new, 2, c0, a0, p)
                    n_new = 3
                    if not _faces_like(points, tris, new, 3, t):
                        continue
                else:
                    k = sides[si]
                    u = tris[t, (k + 1) % 3]
                    v = tris[t, (k + 2) % 3]
                    w = tris[t, k]
                    old[0] = t
                    n_old = 1
                    _set_row(new, 0, w, u, p)
                    _set_row(new, 1, v, w, p)
                    n_new = 2
                    # the triangle on the other side: it runs v -> u
                    s = -1
                    for a in range(n_around):
                        g = around[a]
                        if g == t:
                            continue
                        for j in range(3):
                            if tris[g, j] == v and tris[g, (j + 1) % 3] == u:
                                s = g
                        if s >= 0:
                            break
                    if not _faces_like(points, tris, new, 2, t):
                        continue
                    if s >= 0:
                        z = tris[s, 0]
                        for j in range(3):
                            if tris[s, j] != u and tris[s, j] != v:
                                z = tris[s, j]
                        old[1] = s
                        n_old = 2
                        _set_row(new, 2, u, z, p)
                        _set_row(new, 3, z, v, p)
                        n_new = 4
                        if not _faces_like(points, tris, new[2:], 2, s):
                            continue
                if _split_crosses(points, tris, around, n_around, old, n_old, new, n_new,
                                  tol, area_tol):
                    continue
                for j in range(n_old):
                    alive[old[j]] = False
                for j in range(n_new):
                    tris[top + j] = new[j]
                    alive[top + j] = True
                top += n_new
                inserted += 1
                done = True
                break
            if done:
                failed[i] = False
                break
    return top, inserted, failed
