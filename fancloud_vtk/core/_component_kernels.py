"""Numba kernels over a whole triangle mesh: its connected pieces (union-find over its
vertices) and its area."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._geometry_kernels import triangle_cross


@njit(cache=True)
def _find(parent, x):
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:  # path compression
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@njit(cache=True)
def vertex_components(triangles, n):
    """Label of each of the ``n`` vertices' piece (its smallest vertex); -1 if unused.

    Two vertices are in one piece when a chain of triangles joins them.
    """
    parent = np.arange(n)
    used = np.zeros(n, np.bool_)
    for t in range(triangles.shape[0]):
        a = _find(parent, triangles[t, 0])
        used[triangles[t, 0]] = True
        for j in range(1, 3):
            used[triangles[t, j]] = True
            b = _find(parent, triangles[t, j])
            if a != b:
                if a < b:
                    parent[b] = a
                else:
                    parent[a] = b
                    a = b
    label = np.full(n, -1, np.int64)
    for v in range(n):
        if used[v]:
            label[v] = _find(parent, v)
    return label


@njit(cache=True, parallel=True)
def mesh_area(points, triangles):
    """The total area of the triangles."""
    m = triangles.shape[0]
    out = np.zeros(m)
    for t in prange(m):
        a = triangles[t, 0]
        b = triangles[t, 1]
        c = triangles[t, 2]
        fx, fy, fz = triangle_cross(points, a, b, c)
        out[t] = 0.5 * np.sqrt(fx * fx + fy * fy + fz * fz)
    return out.sum()


@njit(cache=True)
def fan_components(offsets, ring, n):
    """Label of each of the ``n`` points' piece of the fan cloud (its smallest point).

    Two points are in one piece when a chain of fan edges joins them (a point
    is joined to every point of its ring).
    """
    parent = np.arange(n)
    for p in range(n):
        for j in range(offsets[p], offsets[p + 1]):
            a = _find(parent, p)
            b = _find(parent, ring[j])
            if a < b:
                parent[b] = a
            elif b < a:
                parent[a] = b
    label = np.empty(n, np.int64)
    for v in range(n):
        label[v] = _find(parent, v)
    return label


@njit(cache=True)
def piece_volumes(points, triangles, piece, n_pieces, origin):
    """Six times the signed volume under the triangles of each piece (``piece`` per
    triangle; an empty ``piece``: one piece), seen from ``origin``: the sum of
    ``(a - o) . ((b - a) x (c - a))``."""
    out = np.zeros(max(n_pieces, 1))
    one = piece.shape[0] == 0
    for t in range(triangles.shape[0]):
        a = triangles[t, 0]
        cx, cy, cz = triangle_cross(points, a, triangles[t, 1], triangles[t, 2])
        v = ((points[a, 0] - origin[0]) * cx + (points[a, 1] - origin[1]) * cy
             + (points[a, 2] - origin[2]) * cz)
        out[0 if one else piece[t]] += v
    return out
