"""Numba kernels of the entropy (paper section 5) and of one-rings of triangle meshes."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _dist(points, a, b):
    dx = points[a, 0] - points[b, 0]
    dy = points[a, 1] - points[b, 1]
    dz = points[a, 2] - points[b, 2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def point_terms(points, normals, colors, p, nbrs, k, dbar):
    """Scale-invariant (M_dist, M_curv, M_col) of p with fan neighbours ``nbrs[:k]``.

    ``M_dist / dbar``, ``M_curv * dbar`` and ``M_col * dbar`` (the notes'
    scaling). A neighbour normal pointing away from p's is flipped first
    (orientation is not curvature). Neighbours at distance 0 are skipped.
    ``colors`` has 0 rows when there is no colour (M_col is then 0).
    """
    if k == 0:
        return 0.0, 0.0, 0.0
    has_col = colors.shape[0] > 0
    s_d = 0.0
    s_c = 0.0
    s_col = 0.0
    for a in range(k):
        q = nbrs[a]
        d = _dist(points, p, q)
        if d <= 0.0:
            continue
        s_d += d
        sgn = 1.0
        if (normals[q, 0] * normals[p, 0] + normals[q, 1] * normals[p, 1]
                + normals[q, 2] * normals[p, 2]) < 0.0:
            sgn = -1.0
        ex = sgn * normals[q, 0] - normals[p, 0]
        ey = sgn * normals[q, 1] - normals[p, 1]
        ez = sgn * normals[q, 2] - normals[p, 2]
        s_c += np.sqrt(ex * ex + ey * ey + ez * ez) / d
        if has_col:
            cx = colors[q, 0] - colors[p, 0]
            cy = colors[q, 1] - colors[p, 1]
            cz = colors[q, 2] - colors[p, 2]
            s_col += np.sqrt(cx * cx + cy * cy + cz * cz) / d
    return s_d / k / dbar, s_c / k * dbar, s_col / k * dbar


@njit(cache=True)
def point_cc(points, curv, p, nbrs, k, dbar):
    """Scale-invariant M_cc of p: ``dbar * mean |curv(q) - curv(p)| / d`` (curv already scaled)."""
    if k == 0:
        return 0.0
    s = 0.0
    for a in range(k):
        q = nbrs[a]
        d = _dist(points, p, q)
        if d > 0.0:
            s += abs(curv[q] - curv[p]) / d
    return s / k * dbar


@njit(cache=True)
def mean_distance(points, offsets, ring):
    """dbar: the mean distance of a point to its fan neighbours, over all fans."""
    s = 0.0
    for p in range(points.shape[0]):
        for a in range(offsets[p], offsets[p + 1]):
            s += _dist(points, p, ring[a])
    m = offsets[points.shape[0]]
    return s / m if m > 0 else 0.0


@njit(cache=True, parallel=True)
def entropy_terms(points, normals, colors, offsets, ring, dbar):
    """The four scale-invariant terms for every fan: (dist, curv, cc, col), each (n,)."""
    n = points.shape[0]
    dist = np.zeros(n)
    curv = np.zeros(n)
    col = np.zeros(n)
    cc = np.zeros(n)
    for p in prange(n):
        nb = ring[offsets[p]:offsets[p + 1]]
        dist[p], curv[p], col[p] = point_terms(points, normals, colors, p, nb, len(nb), dbar)
    for p in prange(n):
        nb = ring[offsets[p]:offsets[p + 1]]
        cc[p] = point_cc(points, curv, p, nb, len(nb), dbar)
    return dist, curv, cc, col


# -- one-rings of a triangle mesh -------------------------------------------------


@njit(cache=True)
def one_rings(triangles, n):
    """Every vertex's one-ring as a fan: ``(offsets, ring, open, ok)``.

    The ring follows the triangles around the vertex counter-clockwise (the
    triangles' own orientation): for each triangle ``(v, a, b)`` at v, b
    follows a. A boundary vertex (a neighbour that starts the chain but
    follows nobody) gets an open fan from that neighbour round to the last.
    ``ok[v]`` is False where the triangles at v do not form one fan
    (non-manifold or inconsistently oriented); the ring there lists the
    neighbours in chain order as far as they go and the caller sorts them.
    """
    m = triangles.shape[0]
    deg = np.zeros(n + 1, np.int64)
    for t in range(m):
        for c in range(3):
            deg[triangles[t, c] + 1] += 1
    for v in range(n):
        deg[v + 1] += deg[v]
    # per vertex the (a, b) pairs of its triangles
    pa = np.empty(deg[n], np.int64)
    pb = np.empty(deg[n], np.int64)
    fill = deg[:n].copy()
    for t in range(m):
        for c in range(3):
            v = triangles[t, c]
            pa[fill[v]] = triangles[t, (c + 1) % 3]
            pb[fill[v]] = triangles[t, (c + 2) % 3]
            fill[v] += 1
    offsets = np.zeros(n + 1, np.int64)
    ring = np.empty(2 * deg[n], np.int64)  # a boundary vertex has one more neighbour
    is_open = np.zeros(n, np.bool_)
    ok = np.ones(n, np.bool_)
    pos = 0
    for v in range(n):
        lo = deg[v]
        hi = deg[v + 1]
        k = hi - lo
        offsets[v] = pos
        if k == 0:
            continue
        # a start: an a that is no b (boundary), else the smallest a
        start = -1
        n_starts = 0
        for i in range(lo, hi):
            is_b = False
            for j in range(lo, hi):
                if pb[j] == pa[i]:
                    is_b = True
                    break
            if not is_b:
                n_starts += 1
                if start < 0 or pa[i] < pa[start]:
                    start = i
        if n_starts > 1:
            ok[v] = False
        if start < 0:
            start = lo
            for i in range(lo + 1, hi):
                if pa[i] < pa[start]:
                    start = i
        else:
            is_open[v] = True
        used = 0
        cur = start
        ring[pos] = pa[cur]
        pos += 1
        while True:
            used += 1
            nxt_v = pb[cur]
            if not is_open[v] and nxt_v == pa[start]:
                break
            ring[pos] = nxt_v
            pos += 1
            nxt = -1
            for j in range(lo, hi):
                if pa[j] == nxt_v:
                    if nxt >= 0:
                        ok[v] = False
                    nxt = j
                    break
            if nxt < 0 or used >= k:
                break
            cur = nxt
        if used != k:
            ok[v] = False
        if not is_open[v] and used == k and pb[cur] != pa[start]:
            ok[v] = False
    offsets[n] = pos
    return offsets, ring[:pos], is_open, ok
