"""Numba kernels of the undirected edge table of a triangle list.

An undirected edge ``(u, v)`` with ``u < v`` is numbered by its rank among the
sorted packed edges; every triangle knows its three edges and every edge its
triangles (CSR).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._csr_kernels import csr_of


@njit(cache=True)
def local_neighbours(tri, vt_off, vt, u, buf):
    """Sorted distinct vertices w > u that share a triangle with u, into buf; their number
    (-1 if buf is full: twice the triangles at u always fit)."""
    m = 0
    for i in range(vt_off[u], vt_off[u + 1]):
        t = vt[i]
        for k in range(3):
            w = tri[t, k]
            if w <= u:
                continue
            j = m - 1
            dup = False
            while j >= 0 and buf[j] >= w:  # insertion keeps buf sorted
                if buf[j] == w:
                    dup = True
                    break
                j -= 1
            if dup:
                continue
            if m == buf.shape[0]:
                return -1
            for q in range(m, j + 1, -1):
                buf[q] = buf[q - 1]
            buf[j + 1] = w
            m += 1
    return m


@njit(cache=True, parallel=True)
def build_edges(tri, n):
    """Undirected edges of triangles: (edge_uv, tri_edge, edge_off, edge_tri).

    Edges are numbered in increasing (u, v), u < v; ``tri_edge[t, j]`` is
    the edge between ``tri[t, j]`` and ``tri[t, (j + 1) % 3]``;
    ``edge_tri[edge_off[e]:edge_off[e + 1]]`` the triangles on edge ``e`` in
    increasing order.
    """
    m = tri.shape[0]
    vt_off, vt = csr_of(tri, n)
    # a vertex in k triangles has at most 2k neighbours: the buffers fit the largest
    width = 1
    for u in range(n):
        width = max(width, 2 * (vt_off[u + 1] - vt_off[u]))
    per = np.zeros(n + 1, np.int64)
    n_chunks = min(max(n, 1), 256)
    for ch in prange(n_chunks):
        buf = np.empty(width, np.int64)
        for u in range((n * ch) // n_chunks, (n * (ch + 1)) // n_chunks):
            per[u + 1] = local_neighbours(tri, vt_off, vt, u, buf)
    for u in range(n):
        per[u + 1] += per[u]
    n_edges = per[n]
    edge_uv = np.empty((n_edges, 2), np.int64)
    tri_edge = np.empty((m, 3), np.int64)
    for ch in prange(n_chunks):
        buf = np.empty(width, np.int64)
        for u in range((n * ch) // n_chunks, (n * (ch + 1)) // n_chunks):
            k = local_neighbours(tri, vt_off, vt, u, buf)
            base = per[u]
            for q in range(k):
                edge_uv[base + q, 0] = u
                edge_uv[base + q, 1] = buf[q]
            for i in range(vt_off[u], vt_off[u + 1]):
                t = vt[i]
                for j in range(3):
                    a = tri[t, j]
                    b = tri[t, (j + 1) % 3]
                    if min(a, b) != u:
                        continue
                    w = max(a, b)
                    lo = 0
                    hi = k - 1
                    while lo < hi:
                        mid = (lo + hi) // 2
                        if buf[mid] < w:
                            lo = mid + 1
                        else:
                            hi = mid
                    tri_edge[t, j] = base + lo
    edge_off, edge_tri = csr_of(tri_edge, n_edges)
    return edge_uv, tri_edge, edge_off, edge_tri


@njit(cache=True)
def has_edge(triangles, vt_off, vt, a, c):
    """Whether some triangle has the edge a-c (``vt_off``/``vt``: triangles at each vertex)."""
    for i in range(vt_off[a], vt_off[a + 1]):
        t = vt[i]
        if triangles[t, 0] == c or triangles[t, 1] == c or triangles[t, 2] == c:
            return True
    return False
