"""Numba kernels for consistent normal orientation over the fan adjacency.

Hoppe et al. (1992) propagate the orientation along a minimum spanning tree
of the neighbour graph weighted by ``1 - |n_i . n_j|``, so that it crosses
flat regions first and sharp features last. We grow that tree with Prim's
algorithm on a bucketed priority (the weight quantised into ``n_buckets``
levels), which is linear in the number of edges and deterministic.
"""

from __future__ import annotations

import numpy as np
from numba import njit


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
def _bucket(normals, a, b, n_buckets):
    d = abs(normals[a, 0] * normals[b, 0] + normals[a, 1] * normals[b, 1]
            + normals[a, 2] * normals[b, 2])
    w = 1.0 - d
    if w < 0.0:
        w = 0.0
    bk = int(np.sqrt(w) * n_buckets)
    return min(bk, n_buckets - 1)


@njit(cache=True)
def orient_by_propagation(normals, ring_tab, counts, t_off, t_src, n_buckets):
    """Signs that make neighbouring normals agree; return (flipped, component).

    ``flipped[i]`` is True where normal ``i`` must be negated (the normals
    are not modified); ``component[i]``
    numbers the connected components of the fan graph in order of their
    lowest point index.
    """
    n = normals.shape[0]
    visited = np.zeros(n, np.bool_)
    flipped = np.zeros(n, np.bool_)
    component = np.full(n, -1, np.int64)
    key = np.full(n, n_buckets, np.int64)  # n_buckets = not queued
    parent = np.full(n, -1, np.int64)
    head = np.full(n_buckets, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    prv = np.full(n, -1, np.int64)
    n_comp = 0
    for seed in range(n):
        if visited[seed]:
            continue
        comp = n_comp
        n_comp += 1
        # queue the seed in bucket 0
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
            # unlink v
            head[lowest] = nxt[v]
            if nxt[v] >= 0:
                prv[nxt[v]] = -1
            key[v] = n_buckets
            visited[v] = True
            component[v] = comp
            u = parent[v]
            if u >= 0:
                d = (normals[v, 0] * normals[u, 0] + normals[v, 1] * normals[u, 1]
                     + normals[v, 2] * normals[u, 2])
                if flipped[u]:
                    d = -d
                if d < 0.0:
                    flipped[v] = True
            # relax out- and in-neighbours
            for side in range(2):
                if side == 0:
                    e0, e1 = 0, counts[v]
                else:
                    e0, e1 = t_off[v], t_off[v + 1]
                for e in range(e0, e1):
                    w = ring_tab[v, e] if side == 0 else t_src[e]
                    if visited[w]:
                        continue
                    b = _bucket(normals, v, w, n_buckets)
                    if b >= key[w]:
                        continue
                    if key[w] < n_buckets:  # unlink from its current bucket
                        if prv[w] >= 0:
                            nxt[prv[w]] = nxt[w]
                        else:
                            head[key[w]] = nxt[w]
                        if nxt[w] >= 0:
                            prv[nxt[w]] = prv[w]
                    key[w] = b
                    parent[w] = v
                    prv[w] = -1
                    nxt[w] = head[b]
                    if head[b] >= 0:
                        prv[head[b]] = w
                    head[b] = w
                    if b < lowest:
                        lowest = b
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
