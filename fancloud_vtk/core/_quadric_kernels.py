"""Numba kernels of the quadric key of ``method='error'`` on meshes (issue 24).

As Garland and Heckbert do for vertex pairs, every point holds the quadric of
the planes of the surface it stands for: at the start the planes of its own
fan's triangles, weighted by their areas, and, at a boundary, the planes
through its boundary edges square to their triangles (weighted by the edges'
squared lengths, so that boundaries stay where they are). Removing p hands
its hole the star triangulation from one of its ring points q (the triangles
q r_i r_{i+1}: a half-edge collapse of p into q, whose points are all input
points), and the cost of that is the quadric error of q against the planes p
and q stand for, ``v_q^T (Q_p + Q_q) v_q``. The removal takes the cheapest
star that keeps the manifold (``_splice_kernels.hole_triangles``), and q then
stands for p's planes too: ``Q_q += Q_p``. A point's key is its cheapest
star's cost; a boundary point collapses only along its boundary (into the
first or last point of its open ring).

A quadric is kept as its 10 distinct coefficients (a², ab, ac, ad, b², bc,
bd, c², cd, d²) of the plane (a, b, c, d), in coordinates relative to a
common centre (the cloud's centroid: no cancellation far from the origin).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._geometry_kernels import triangle_cross

#: the weight of a boundary edge's plane against the triangles' planes
BOUNDARY_WEIGHT = 1.0


@njit(cache=True)
def _add_plane(Q, x, a, b, c, d, w):
    Q[x, 0] += w * a * a
    Q[x, 1] += w * a * b
    Q[x, 2] += w * a * c
    Q[x, 3] += w * a * d
    Q[x, 4] += w * b * b
    Q[x, 5] += w * b * c
    Q[x, 6] += w * b * d
    Q[x, 7] += w * c * c
    Q[x, 8] += w * c * d
    Q[x, 9] += w * d * d


@njit(cache=True)
def _plane(points, centre, a, b, c):
    """The unit normal (nx, ny, nz), offset d (relative to ``centre``) and area of the
    triangle a b c; area 0 for a degenerate one."""
    cx, cy, cz = triangle_cross(points, a, b, c)
    s = np.sqrt(cx * cx + cy * cy + cz * cz)
    if s == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    nx = cx / s
    ny = cy / s
    nz = cz / s
    d = -(nx * (points[a, 0] - centre[0]) + ny * (points[a, 1] - centre[1])
          + nz * (points[a, 2] - centre[2]))
    return nx, ny, nz, d, 0.5 * s


@njit(cache=True)
def _edge_plane(points, centre, Q, x, a, b, tnx, tny, tnz):
    """Add to x the plane through the boundary edge a b square to its triangle (normal t)."""
    ex = points[b, 0] - points[a, 0]
    ey = points[b, 1] - points[a, 1]
    ez = points[b, 2] - points[a, 2]
    px = ey * tnz - ez * tny
    py = ez * tnx - ex * tnz
    pz = ex * tny - ey * tnx
    s = np.sqrt(px * px + py * py + pz * pz)
    if s == 0.0:
        return
    px /= s
    py /= s
    pz /= s
    d = -(px * (points[a, 0] - centre[0]) + py * (points[a, 1] - centre[1])
          + pz * (points[a, 2] - centre[2]))
    _add_plane(Q, x, px, py, pz, d, BOUNDARY_WEIGHT * (ex * ex + ey * ey + ez * ez))


@njit(cache=True, parallel=True)
def initial_quadrics(points, R, rlen, ropen, centre):
    """Every point's quadric (n, 10): the planes of its fan's triangles (by area) and of
    its boundary edges (see the module)."""
    n = points.shape[0]
    Q = np.zeros((n, 10))
    for x in prange(n):
        k = rlen[x]
        last = k - 1 if ropen[x] else k
        for j in range(last):
            a = R[x, j]
            b = R[x, (j + 1) % k]
            nx, ny, nz, d, area = _plane(points, centre, x, a, b)
            if area == 0.0:
                continue
            _add_plane(Q, x, nx, ny, nz, d, area)
            if ropen[x] and j == 0:  # the boundary edge x -> R[x, 0]
                _edge_plane(points, centre, Q, x, x, a, nx, ny, nz)
            if ropen[x] and j == last - 1:  # the boundary edge R[x, k - 1] -> x
                _edge_plane(points, centre, Q, x, b, x, nx, ny, nz)
    return Q


@njit(cache=True)
def cost(Q, points, centre, p, q):
    """The quadric error of collapsing p into q: v_q^T (Q_p + Q_q) v_q."""
    x = points[q, 0] - centre[0]
    y = points[q, 1] - centre[1]
    z = points[q, 2] - centre[2]
    return max(_apply_at(Q, p, x, y, z) + _apply_at(Q, q, x, y, z), 0.0)


@njit(cache=True)
def _apply_at(Q, s, x, y, z):
    """v^T Q_s v at v = (x, y, z, 1)."""
    return (Q[s, 0] * x * x + 2.0 * Q[s, 1] * x * y + 2.0 * Q[s, 2] * x * z
            + 2.0 * Q[s, 3] * x + Q[s, 4] * y * y + 2.0 * Q[s, 5] * y * z
            + 2.0 * Q[s, 6] * y + Q[s, 7] * z * z + 2.0 * Q[s, 8] * z + Q[s, 9])


@njit(cache=True)
def eligible(ropen, rlen, p, j):
    """Whether p may collapse into its ring's j-th point (a boundary point: only along
    its boundary)."""
    return not ropen[p] or j == 0 or j == rlen[p] - 1


@njit(cache=True)
def quadric_key(Q, points, centre, R, rlen, ropen, p):
    """p's key: the cost of its cheapest star (inf without a ring)."""
    best = np.inf
    for j in range(rlen[p]):
        if eligible(ropen, rlen, p, j):
            best = min(best, cost(Q, points, centre, p, R[p, j]))
    return best


@njit(cache=True)
def weight(Q, s):
    """The total weight of the planes s stands for (its quadric's trace: the planes'
    normals are unit vectors)."""
    return Q[s, 0] + Q[s, 4] + Q[s, 7]


@njit(cache=True)
def mean_square(Q, points, centre, p, q, c):
    """The cost ``c`` of collapsing p into q as a mean squared distance: over the weight of
    the planes p and q stand for (0 without planes)."""
    wt = weight(Q, p) + weight(Q, q)
    return c / wt if wt > 0.0 else 0.0


@njit(cache=True)
def guard_value(Q, points, centre, R, rlen, ropen, p):
    """The error guard's value of p (``_reduction_kernels``): the mean squared distance
    of its cheapest star (inf without a ring)."""
    best = np.inf
    for j in range(rlen[p]):
        if eligible(ropen, rlen, p, j):
            q = R[p, j]
            best = min(best, mean_square(Q, points, centre, p, q, cost(Q, points, centre, p, q)))
    return best


@njit(cache=True)
def star_order(Q, points, centre, R, rlen, ropen, p, js, costs):
    """p's eligible ring positions, cheapest star first (ties: ring order), in ``js``
    with their costs in ``costs``: returns their number."""
    m = 0
    for j in range(rlen[p]):
        if not eligible(ropen, rlen, p, j):
            continue
        c = cost(Q, points, centre, p, R[p, j])
        at = m
        while at > 0 and costs[at - 1] > c:
            js[at] = js[at - 1]
            costs[at] = costs[at - 1]
            at -= 1
        js[at] = j
        costs[at] = c
        m += 1
    return m


@njit(cache=True)
def absorb(Q, q, p):
    """q now stands for p's planes too."""
    for c in range(10):
        Q[q, c] += Q[p, c]


@njit(cache=True)
def with_rings(R, rlen, active, ids, heirs, stamp, tag):
    """The active points of ``ids`` and ``heirs`` and of the heirs' rings, each once, in a
    fixed order (``heirs`` < 0 are skipped): the keys a round of removals changes (the
    changed fans, and the heirs' rings, whose cost of collapsing into the heir changed)."""
    m = ids.shape[0]
    for i in range(heirs.shape[0]):
        if heirs[i] >= 0:
            m += 1 + rlen[heirs[i]]
    out = np.empty(m, np.int64)
    m = 0
    for i in range(ids.shape[0]):
        x = ids[i]
        if stamp[x] != tag and active[x]:
            stamp[x] = tag
            out[m] = x
            m += 1
    for i in range(heirs.shape[0]):
        h = heirs[i]
        if h < 0:
            continue
        for a in range(-1, rlen[h]):
            y = h if a < 0 else R[h, a]
            if stamp[y] != tag and active[y]:
                stamp[y] = tag
                out[m] = y
                m += 1
    return out[:m]


@njit(cache=True, parallel=True)
def update_quadric_keys(Q, points, centre, R, rlen, ropen, key, ids):
    """The keys of the points ``ids``."""
    for i in prange(ids.shape[0]):
        y = ids[i]
        key[y] = quadric_key(Q, points, centre, R, rlen, ropen, y)
