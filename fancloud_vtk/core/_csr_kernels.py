"""Numba kernels of CSR tables (offsets + indices): rows grouped by key, and the
conversion between CSR rings and fixed-width ring tables."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def csr_of(rows, n_keys):
    """Rows grouped by the keys they hold (CSR): (off, idx), idx in increasing row order.

    ``rows`` is (m, k): row r holds k keys in [0, n_keys); key x's rows are
    ``idx[off[x]:off[x + 1]]`` (a row holding x twice appears twice).
    """
    return csr_of_some(rows, n_keys, np.ones(n_keys, np.bool_))


@njit(cache=True)
def csr_of_some(rows, n_keys, need):
    """:func:`csr_of` with the rows of the keys ``need`` (mask) only; the others are empty.

    For a few keys of a large table: one pass over the rows, no scatter of the rest.
    """
    m, k = rows.shape
    off = np.zeros(n_keys + 1, np.int64)
    for r in range(m):
        for j in range(k):
            x = rows[r, j]
            if need[x]:
                off[x + 1] += 1
    for x in range(n_keys):
        off[x + 1] += off[x]
    fill = off[:-1].copy()
    idx = np.empty(off[n_keys], np.int64)
    for r in range(m):
        for j in range(k):
            x = rows[r, j]
            if need[x]:
                idx[fill[x]] = r
                fill[x] += 1
    return off, idx


@njit(cache=True)
def vertex_edges(edge_uv, n):
    """Edges at every vertex (CSR), each vertex's in increasing edge number."""
    return csr_of(edge_uv, n)


@njit(cache=True)
def vertex_triangles(tri, n):
    """Triangles at every vertex (CSR), in increasing triangle number."""
    return csr_of(tri, n)


@njit(cache=True, parallel=True)
def table_from_csr(offsets, ring, order, rename, width):
    """Fan table: row i holds the ring of point ``order[i]``, renamed by ``rename``.

    ``order``/``rename`` of length 0: the identity. Returns (R int32 (n, width), rlen).
    """
    n = offsets.shape[0] - 1
    R = np.zeros((n, width), np.int32)
    rlen = np.empty(n, np.int64)
    ident = order.shape[0] == 0
    for i in prange(n):
        p = np.int64(i)
        if not ident:
            p = order[i]
        k = offsets[p + 1] - offsets[p]
        rlen[i] = k
        for a in range(k):
            q = ring[offsets[p] + a]
            if not ident:
                q = rename[q]
            R[i, a] = q
    return R, rlen


@njit(cache=True)
def csr_from_table(R, rlen, active, order):
    """CSR rings in input order from a table in work order (row i is input point order[i]);
    inactive points get an empty ring. Returns (offsets, ring) with input indices."""
    n = R.shape[0]
    sizes = np.zeros(n, np.int64)
    for i in range(n):
        if active[i]:
            sizes[order[i]] = rlen[i]
    offsets = np.zeros(n + 1, np.int64)
    for p in range(n):
        offsets[p + 1] = offsets[p] + sizes[p]
    ring = np.empty(offsets[n], np.int64)
    for i in range(n):
        if active[i]:
            at = offsets[order[i]]
            for a in range(rlen[i]):
                ring[at + a] = order[R[i, a]]
    return offsets, ring
