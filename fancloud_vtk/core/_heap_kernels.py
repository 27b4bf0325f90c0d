"""Numba kernels of an indexed binary min-heap (``heap`` of items, ``hpos`` their
positions, ``key`` their keys): the exact (one at a time) reduction and
refinement keep their candidates in one."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _less(key, a, b):
    return key[a] < key[b] or (key[a] == key[b] and a < b)


@njit(cache=True)
def sift_up(heap, hpos, key, i):
    x = heap[i]
    while i > 0:
        parent = (i - 1) >> 1
        y = heap[parent]
        if not _less(key, x, y):
            break
        heap[i] = y
        hpos[y] = i
        i = parent
    heap[i] = x
    hpos[x] = i


@njit(cache=True)
def sift_down(heap, hpos, key, i, size):
    x = heap[i]
    while True:
        c = 2 * i + 1
        if c >= size:
            break
        if c + 1 < size and _less(key, heap[c + 1], heap[c]):
            c += 1
        y = heap[c]
        if not _less(key, y, x):
            break
        heap[i] = y
        hpos[y] = i
        i = c
    heap[i] = x
    hpos[x] = i


@njit(cache=True)
def heap_update(heap, hpos, key, x, value, size):
    """Set key[x] = value and restore the heap (x must be in the heap)."""
    old = key[x]
    key[x] = value
    i = hpos[x]
    if value < old:
        sift_up(heap, hpos, key, i)
    else:
        sift_down(heap, hpos, key, i, size)


@njit(cache=True)
def heap_of(key, active):
    """An indexed heap of the active points (the inactive ones after them, outside it)."""
    n = key.shape[0]
    heap = np.empty(n, np.int64)
    hpos = np.empty(n, np.int64)
    m = 0
    for x in range(n):
        if active[x]:
            heap[m] = x
            m += 1
    size = m
    for x in range(n):
        if not active[x]:
            heap[m] = x
            m += 1
    for i in range(n):
        hpos[heap[i]] = i
    for i in range(size // 2 - 1, -1, -1):
        sift_down(heap, hpos, key, i, size)
    return heap, hpos
