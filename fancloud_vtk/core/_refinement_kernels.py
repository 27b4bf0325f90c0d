"""Numba kernels of the refinement beyond the input resolution (paper section 7).

One insertion (``_plan``): p, the point of highest entropy with a closed fan;
q1, its fan neighbour of highest entropy; q2, the higher of q1's two
neighbours in p's ring. The new point r starts at the entropy-weighted
combination r0 of p, q1, q2 (so inside their fan triangle) with the weighted
normal, gets the local Delaunay ring in its tangent plane among the points of
the three fans, and is moved along its normal until the cotangent mean
curvature of its fan matches the entropy-weighted mean curvature of p, q1,
q2 (``_move``; docs/refinement.md). The fans of the points of r's ring are
re-formed from their ring plus r (local Delaunay rings again, no neighbour
search): where r's ring agrees with theirs, r simply takes the place of the
ring points its fan now crosses (``_splice``). ``_commit`` writes the
insertion and ``_log`` records it for the levels of detail (the new ring,
the re-formed rings after it, the parents and weights for the point arrays).

Two drivers: ``refine_steps`` takes one point at a time from an indexed heap
(the paper's order), and the rounds (``round_accept``, ``plan_batch``,
``commit_batch``) insert together, in parallel, the highest-entropy points
whose neighbourhoods do not overlap.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit, prange

from ._entropy_kernels import point_cc, point_terms
from ._heap_kernels import heap_update, sift_down
from ._reduction_kernels import (
    INF,
    _add,
    _grow,
    _to_frame,
    delaunay_fan,
    fan_scratch,
    first_disjoint,
    local_frame,
    lowest_keys,
)
from ._ring_kernels import STEEP, closed_ring, inversions

# -- the state of a refinement, as a few named bundles of arrays (and ``RK.Cloud``) ------

#: the fans as a table: ring rows, their lengths, open flags
Rings = namedtuple("Rings", ["R", "rlen", "ropen"])
#: per point the entropy terms and the entropy M
Terms = namedtuple("Terms", ["dist", "curv", "cc", "col", "M"])
#: the planned insertions of a round (``plan_batch``): the new rings, the fans they change
#: and their new rings, parents and weights
Plans = namedtuple("Plans", ["ring_r", "ring_h", "xlist", "xrings", "xlen", "xopen", "n_xs",
                             "par", "wts"])
#: the record of the insertions: parents, weights, fans changed per insertion, and the
#: rings (CSR; the last four grow)
InsertLog = namedtuple("InsertLog", ["par", "wts", "nx_per", "rr", "rr_off", "ex", "ex_open",
                                     "ex_off", "er"])

#: at most this many mean-curvature iterations (the cotangent weights are re-read each time)
MOVE_ITERATIONS = 3
#: the normal move is at most this fraction of r0's mean distance to its ring
MAX_MOVE = 1.0
#: parents' normals further apart than this angle (degrees) mean a sharp edge between them
SHARP_ANGLE = 22.0
SHARP_COS = np.cos(np.radians(SHARP_ANGLE))


# -- the mean curvature normal (Meyer et al. 2003) ------------------------------------------


@njit(cache=True)
def _curvature(points, x, nb, k, closed, nx, ny, nz, c):
    """(K(x) . n, alpha0) of x's fan ``nb[:k]`` with the cotangent weights.

    K(x) = grad A / (2A) = sum_i c_i (x - x_i) / (4A), c_i = cot a_i + cot b_i
    (the angles opposite the edge x x_i), A the area of the fan; so K(x) is
    ``alpha0 x - sum alpha_i x_i`` with ``alpha0 = sum c_i / (4A)``. An open
    fan has one angle for its two end edges. (0, 0) for a degenerate fan.
    """
    for i in range(k):
        c[i] = 0.0
    area = 0.0
    m = k if closed else k - 1
    for i in range(m):
        a = nb[i]
        b = nb[(i + 1) % k]
        ax = points[a, 0] - points[x, 0]
        ay = points[a, 1] - points[x, 1]
        az = points[a, 2] - points[x, 2]
        bx = points[b, 0] - points[x, 0]
        by = points[b, 1] - points[x, 1]
        bz = points[b, 2] - points[x, 2]
        cx = ay * bz - az * by
        cy = az * bx - ax * bz
        cz = ax * by - ay * bx
        twice = np.sqrt(cx * cx + cy * cy + cz * cz)
        if twice <= 0.0:
            continue
        area += 0.5 * twice
        # angle at a, between x - a and b - a; angle at b, between x - b and a - b
        cot_a = (-ax * (bx - ax) - ay * (by - ay) - az * (bz - az)) / twice
        cot_b = (-bx * (ax - bx) - by * (ay - by) - bz * (az - bz)) / twice
        c[i] += cot_b  # edge x a is opposite the angle at b
        c[(i + 1) % k] += cot_a
    if area <= 0.0:
        return 0.0, 0.0
    s = 0.0
    sx = 0.0
    sy = 0.0
    sz = 0.0
    for i in range(k):
        q = nb[i]
        s += c[i]
        sx += c[i] * (points[x, 0] - points[q, 0])
        sy += c[i] * (points[x, 1] - points[q, 1])
        sz += c[i] * (points[x, 2] - points[q, 2])
    return (sx * nx + sy * ny + sz * nz) / (4.0 * area), s / (4.0 * area)


@njit(cache=True)
def _envelope(points, normals, parents, ox, oy, oz, nx, ny, nz):
    """Where the line r0 + t n meets the parents' tangent planes: (t_pos, t_neg, sharp).

    t_pos: the nearest crossing ahead (inf if none), t_neg: the nearest behind
    (-inf if none); sharp: two parents' normals are more than ``SHARP_ANGLE``
    apart (a sharp edge or corner between them).
    """
    t_pos = INF
    t_neg = -INF
    for j in range(3):
        x = parents[j]
        den = nx * normals[x, 0] + ny * normals[x, 1] + nz * normals[x, 2]
        if abs(den) < 0.1:
            continue
        t = -((ox - points[x, 0]) * normals[x, 0] + (oy - points[x, 1]) * normals[x, 1]
              + (oz - points[x, 2]) * normals[x, 2]) / den
        if t >= 0.0:
            t_pos = min(t_pos, t)
        else:
            t_neg = max(t_neg, t)
    sharp = False
    for j in range(3):
        a = parents[j]
        for k in range(j + 1, 3):
            b = parents[k]
            c = abs(normals[a, 0] * normals[b, 0] + normals[a, 1] * normals[b, 1]
                    + normals[a, 2] * normals[b, 2])
            if c < SHARP_COS:
                sharp = True
    return t_pos, t_neg, sharp


@njit(cache=True)
def _move(points, normals, R, rlen, ropen, r, ring, h, parents, wts, c):
    """Move r along its normal so that its mean curvature is the parents' weighted one.

    The target is ``mu = sum w_j K(parent_j) . n``: each parent's cotangent
    mean curvature normal on its own fan, read along r's normal n (signed, so
    saddles keep their sign). Then r = r0 + t n with the t that solves
    ``K(r) . n = mu`` for the cotangent weights of r's fan, which barely
    change with t (re-read up to ``MOVE_ITERATIONS`` times).

    The parents' tangent planes bound the move: r does not cross the nearest
    of them on its side (a flat face next to an edge stays flat, whatever
    the parents' curvature), and |t| is at most ``MAX_MOVE`` times r0's mean
    distance to its ring. Where the parents' normals are more than
    ``SHARP_ANGLE`` apart, r0 lies on a chord across a sharp edge or corner,
    which no mean curvature describes and which a point there would cut off:
    returns inf (no insertion at p). Else returns t.
    """
    nx = normals[r, 0]
    ny = normals[r, 1]
    nz = normals[r, 2]
    ox = points[r, 0]
    oy = points[r, 1]
    oz = points[r, 2]
    spacing = 0.0
    for i in range(h):
        q = ring[i]
        dx = points[q, 0] - ox
        dy = points[q, 1] - oy
        dz = points[q, 2] - oz
        spacing += np.sqrt(dx * dx + dy * dy + dz * dz)
    limit = MAX_MOVE * spacing / h
    t_pos, t_neg, sharp = _envelope(points, normals, parents, ox, oy, oz, nx, ny, nz)
    if sharp:
        return INF
    mu = 0.0
    for j in range(3):
        x = parents[j]
        kn, _ = _curvature(points, x, R[x], rlen[x], not ropen[x], nx, ny, nz, c)
        mu += wts[j] * kn
    lo = max(t_neg, -limit)
    hi = min(t_pos, limit)
    t = 0.0
    for _ in range(MOVE_ITERATIONS):
        kn, a0 = _curvature(points, r, ring, h, True, nx, ny, nz, c)
        if not a0 > 0.0:
            break
        step = (mu - kn) / a0
        t_new = min(max(t + step, lo), hi)
        if t_new == t:
            break
        t = t_new
        points[r, 0] = ox + t * nx
        points[r, 1] = oy + t * ny
        points[r, 2] = oz + t * nz
        if abs(step) <= 1e-6 * limit:
            break
    return t


# -- one insertion ---------------------------------------------------------------------------


@njit(cache=True)
def _parents(R, rlen, M, p):
    """(q1, q2): p's fan neighbour of highest entropy, and the higher of its two ring
    neighbours in p's fan (ties: the smaller index)."""
    k = rlen[p]
    at = 0
    q1 = R[p, 0]
    for a in range(1, k):
        q = R[p, a]
        if M[q] > M[q1] or (M[q] == M[q1] and q < q1):
            q1 = q
            at = a
    u = R[p, (at + k - 1) % k]
    v = R[p, (at + 1) % k]
    q2 = u if (M[u] > M[v] or (M[u] == M[v] and u < v)) else v
    return q1, q2


@njit(cache=True)
def _reform_with(points, normals, R, rlen, ropen, x, r, cand, xs, ys, ordr, hull, out):
    """x's new ring from its ring plus r: the local Delaunay ring in x's tangent plane.
    Returns (size, open); size -1 if no fan can be formed."""
    m = 0
    for a in range(rlen[x]):
        m = _add(cand, m, R[x, a], x)
    cand[m] = r
    m += 1
    return delaunay_fan(points, normals, ropen[x], x, cand, m, xs, ys, ordr, hull,
                         R.shape[1], STEEP, out)


@njit(cache=True)
def _splice(R, rlen, ropen, x, r, u, v, out):
    """x's ring with r put in between v and u, its neighbours before and after x in r's ring.

    r's ring runs ``u, x, v`` counter-clockwise, so x's runs ``v, r, u``: the
    ring points strictly between v and u (the edges r's fan now crosses, as
    in a Delaunay insertion) go. -1 where that does not apply (x's fan is
    open, or lacks u or v, or more than two points would go): then x's fan
    is re-formed in full.
    """
    k = rlen[x]
    if ropen[x] or k + 1 > R.shape[1]:
        return -1
    iu = -1
    iv = -1
    for a in range(k):
        z = R[x, a]
        if z == u:
            iu = a
        elif z == v:
            iv = a
    if iu < 0 or iv < 0:
        return -1
    kept = (iv - iu) % k + 1  # u ... v, counter-clockwise
    if k - kept > 2:
        return -1
    for a in range(kept):
        out[a] = R[x, (iu + a) % k]
    out[kept] = r
    return kept + 1


@njit(cache=True)
def _plan(points, normals, colors, R, rlen, ropen, M, p, q1, q2, slot, move, gap, strict, cand,
          xs, ys, ordr, hull, c, ring_r, xlist, xrings, xlen, xopen, par, wts):
    """Plan the insertion at p (parents q1, q2: ``_parents``) into the scratch row ``slot``
    (reads the fans, writes only row ``slot`` of points, normals and colours and the output
    buffers).

    Returns (h, nx): r's ring size (0: no insertion possible) and how many
    fans are re-formed (``xlist[:nx]`` with rings ``xrings[i, :xlen[i]]``).
    ``strict`` (the one-rings of a mesh): every point of r's ring must take r by
    splicing, and every neighbour a fan drops must drop that fan's point in turn, so the
    rings stay the one-rings of one mesh; else no insertion at p.
    """
    par[0] = p
    par[1] = q1
    par[2] = q2
    s = M[p] + M[q1] + M[q2]
    if s > 0.0 and s < INF:
        wts[0] = M[p] / s
        wts[1] = M[q1] / s
        wts[2] = M[q2] / s
    else:
        wts[0] = 1.0 / 3.0
        wts[1] = 1.0 / 3.0
        wts[2] = 1.0 / 3.0
    # r0 and its normal (the parents' normals turned to p's side first)
    nx = 0.0
    ny = 0.0
    nz = 0.0
    for d in range(3):
        points[slot, d] = 0.0
    for j in range(3):
        q = par[j]
        sgn = 1.0
        if (normals[q, 0] * normals[p, 0] + normals[q, 1] * normals[p, 1]
                + normals[q, 2] * normals[p, 2]) < 0.0:
            sgn = -1.0
        for d in range(3):
            points[slot, d] += wts[j] * points[q, d]
        nx += wts[j] * sgn * normals[q, 0]
        ny += wts[j] * sgn * normals[q, 1]
        nz += wts[j] * sgn * normals[q, 2]
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    if not norm > 1e-12:
        nx, ny, nz, norm = normals[p, 0], normals[p, 1], normals[p, 2], 1.0
    normals[slot, 0] = nx / norm
    normals[slot, 1] = ny / norm
    normals[slot, 2] = nz / norm
    if colors.shape[0] > 0:
        for d in range(colors.shape[1]):
            colors[slot, d] = (wts[0] * colors[p, d] + wts[1] * colors[q1, d]
                               + wts[2] * colors[q2, d])
    # r's ring: the local Delaunay ring among the points of the three fans
    m = 0
    for j in range(3):
        q = par[j]
        m = _add(cand, m, q, slot)
        for a in range(rlen[q]):
            m = _add(cand, m, R[q, a], slot)
    mm = inversions(points, normals, slot, cand, m, xs, ys, STEEP)
    h = closed_ring(xs, ys, mm, cand, hull, R.shape[1], ring_r)
    if h < 3:
        return 0, 0
    inside = False
    for i in range(h):
        if ring_r[i] == p:
            inside = True
    if not inside:
        return 0, 0  # r is not in p's Delaunay neighbourhood: p's fan is no triangle fan
    if move:
        t = _move(points, normals, R, rlen, ropen, slot, ring_r, h, par, wts, c)
        if t == INF:
            return 0, 0
    for i in range(h):
        q = ring_r[i]
        dx = points[q, 0] - points[slot, 0]
        dy = points[q, 1] - points[slot, 1]
        dz = points[q, 2] - points[slot, 2]
        if dx * dx + dy * dy + dz * dz < gap * gap:
            return 0, 0  # closer than the finest spacing allowed: p is done
    # the fans r enters
    n_x = 0
    for i in range(h):
        x = ring_r[i]
        k = _splice(R, rlen, ropen, x, slot, ring_r[(i + h - 1) % h], ring_r[(i + 1) % h],
                    xrings[n_x])
        op = False
        if k < 0:
            if strict:
                return 0, 0
            k, op = _reform_with(points, normals, R, rlen, ropen, x, slot, cand, xs, ys, ordr,
                                 hull, xrings[n_x])
        if k < 0:
            continue
        has = False
        for a in range(k):
            if xrings[n_x, a] == slot:
                has = True
                break
        if not has:
            continue  # x's fan does not take r: it stays as it is
        xlist[n_x] = x
        xlen[n_x] = k
        xopen[n_x] = op
        n_x += 1
    if strict and not _agree(R, rlen, xlist, xrings, xlen, n_x, h):
        return 0, 0
    for i in range(n_x):
        if xlist[i] == p:
            return h, n_x
    return 0, 0  # p's fan would not change: the same insertion would come again


@njit(cache=True)
def _in(row, k, z):
    for a in range(k):
        if row[a] == z:
            return True
    return False


@njit(cache=True)
def _agree(R, rlen, xlist, xrings, xlen, n_x, h):
    """Whether the planned rings keep the fans the one-rings of one mesh: every point of
    r's ring takes r (``n_x == h``), and a neighbour w that x's new ring drops is in r's
    ring too, with a new ring without x."""
    if n_x != h:
        return False
    for t in range(n_x):
        x = xlist[t]
        for a in range(rlen[x]):
            w = R[x, a]
            if _in(xrings[t], xlen[t], w):
                continue
            u = -1
            for t2 in range(n_x):
                if xlist[t2] == w:
                    u = t2
                    break
            if u < 0 or _in(xrings[u], xlen[u], x):
                return False
    return True


@njit(cache=True)
def _commit(points, normals, colors, R, rlen, ropen, slot, f, ring_r, h, xlist, n_x, xrings, xlen,
            xopen):
    """Make the planned insertion as point ``f`` (rows ``slot`` renamed to ``f``)."""
    if slot != f:
        for d in range(3):
            points[f, d] = points[slot, d]
            normals[f, d] = normals[slot, d]
        if colors.shape[0] > 0:
            for d in range(colors.shape[1]):
                colors[f, d] = colors[slot, d]
    for a in range(h):
        R[f, a] = ring_r[a]
    rlen[f] = h
    ropen[f] = False
    for i in range(n_x):
        x = xlist[i]
        for a in range(xlen[i]):
            z = xrings[i, a]
            R[x, a] = f if z == slot else z
        rlen[x] = xlen[i]
        ropen[x] = xopen[i]


@njit(cache=True)
def _log(R, rlen, ropen, f, xlist, n_x, par, wts, lg_par, lg_wts, lg_nx, j, rr, rr_off, ex,
         ex_open, ex_off, er, counters):
    """Record insertion j (point f, already committed): its ring, the fans it changed (after
    the change), its parents and weights. ``counters``: [ring entries, fans, fan entries]."""
    for t in range(3):
        lg_par[j, t] = par[t]
        lg_wts[j, t] = wts[t]
    lg_nx[j] = n_x
    k = rlen[f]
    rr = _grow(rr, counters[0] + k)
    for a in range(k):
        rr[counters[0] + a] = R[f, a]
    counters[0] += k
    rr_off[j + 1] = counters[0]
    ex = _grow(ex, counters[1] + n_x)
    ex_open = _grow(ex_open, counters[1] + n_x)
    ex_off = _grow(ex_off, counters[1] + n_x + 1)
    for i in range(n_x):
        x = xlist[i]
        ex[counters[1]] = x
        ex_open[counters[1]] = ropen[x]
        er = _grow(er, counters[2] + rlen[x])
        for a in range(rlen[x]):
            er[counters[2] + a] = R[x, a]
        counters[2] += rlen[x]
        counters[1] += 1
        ex_off[counters[1]] = counters[2]
    return rr, ex, ex_open, ex_off, er


@njit(cache=True)
def _eligible(rlen, ropen, x):
    return rlen[x] >= 3 and not ropen[x]


@njit(cache=True)
def _terms(points, normals, colors, R, rlen, dist, curv, col, dbar, x):
    dist[x], curv[x], col[x] = point_terms(points, normals, colors, x, R[x], rlen[x], dbar)


@njit(cache=True)
def _entropy(R, rlen, points, curv, dist, cc, col, M, w, dbar, x):
    cc[x] = point_cc(points, curv, x, R[x], rlen[x], dbar)
    M[x] = w[0] * dist[x] + w[1] * curv[x] + w[2] * cc[x] + w[3] * col[x]


# -- one at a time, from a heap ----------------------------------------------------------------


@njit(cache=True)
def refine_steps(cloud, rings, terms, w, dbar, move, gap, strict, n_cur, n_final, log, counters,
                 blocked_out):
    """Insert points one at a time, always at the highest entropy (an indexed heap on -M),
    until ``n_final`` points. Returns (points reached, rr, ex, ex_open, ex_off, er)."""
    points, normals, colors = cloud
    R, rlen, ropen = rings
    dist, curv, cc, col, M = terms
    lg_par, lg_wts, lg_nx, rr, rr_off, ex, ex_open, ex_off, er = log
    n_alloc = points.shape[0]
    width = R.shape[1]
    cand, xs, ys, ordr, hull = fan_scratch(width)
    c = np.empty(width)
    ring_r = np.empty(width, np.int32)
    xlist = np.empty(width, np.int64)
    xrings = np.empty((width, width), np.int32)
    xlen = np.empty(width, np.int64)
    xopen = np.empty(width, np.bool_)
    par = np.empty(3, np.int64)
    wts = np.empty(3)
    key = np.full(n_alloc, INF)
    for x in range(n_cur):
        if _eligible(rlen, ropen, x):
            key[x] = -M[x]
    heap = np.arange(n_alloc).astype(np.int64)
    hpos = np.arange(n_alloc).astype(np.int64)
    size = n_cur
    for i in range(size // 2 - 1, -1, -1):
        sift_down(heap, hpos, key, i, size)
    upd = np.empty(width + 1, np.int64)
    n0 = n_cur - counters[3]
    while n_cur < n_final:
        p = heap[0]
        if key[p] == INF:
            break
        f = n_cur
        q1, q2 = _parents(R, rlen, M, p)
        h, n_x = _plan(points, normals, colors, R, rlen, ropen, M, p, q1, q2, f, move, gap,
                       strict, cand, xs, ys, ordr, hull, c, ring_r, xlist, xrings, xlen, xopen,
                       par, wts)
        if h == 0:
            blocked_out[p] = True
            heap_update(heap, hpos, key, p, INF, size)
            continue
        _commit(points, normals, colors, R, rlen, ropen, f, f, ring_r, h, xlist, n_x, xrings,
                xlen, xopen)
        j = f - n0
        rr, ex, ex_open, ex_off, er = _log(R, rlen, ropen, f, xlist, n_x, par, wts, lg_par,
                                           lg_wts, lg_nx, j, rr, rr_off, ex, ex_open, ex_off, er,
                                           counters)
        n_cur += 1
        counters[3] += 1
        # entropies of r and of the fans it entered
        upd[0] = f
        for i in range(n_x):
            upd[i + 1] = xlist[i]
        for i in range(n_x + 1):
            x = upd[i]
            _terms(points, normals, colors, R, rlen, dist, curv, col, dbar, x)
        heap[size] = f
        hpos[f] = size
        key[f] = INF
        size += 1
        for i in range(n_x + 1):
            x = upd[i]
            _entropy(R, rlen, points, curv, dist, cc, col, M, w, dbar, x)
            blocked_out[x] = False
            heap_update(heap, hpos, key, x, -M[x] if _eligible(rlen, ropen, x) else INF, size)
    return n_cur, rr, ex, ex_open, ex_off, er


# -- in rounds --------------------------------------------------------------------------------
#
# A round takes the highest entropies (a fraction of the points, highest
# first) and accepts each point p whose insertion region C(p) = {p, q1, q2} +
# their rings meets no accepted point's. An insertion reads the fans of C(p)'s
# points only and changes the fans of some of them only (r's ring is part of
# C(p)), so the accepted insertions read no fan another one writes, and
# commute. They are planned in parallel, numbered in acceptance order and
# committed in parallel.


@njit(cache=True, parallel=True)
def round_accept(cands, R, rlen, M, mark, tag, limit, acc, pq):
    """Highest entropy first, the candidates whose regions meet no accepted one's
    (at most ``limit``), into ``acc`` with their parents (q1, q2) in ``pq``; returns their
    number. The regions are gathered in parallel (packed, in candidate order), then chosen in
    order (``_reduction_kernels.first_disjoint``, with ``mark`` and ``tag``)."""
    n_c = cands.shape[0]
    q = np.empty((n_c, 2), np.int64)
    off = np.empty(n_c + 1, np.int64)
    off[0] = 0
    for i in prange(n_c):
        p = cands[i]
        q1, q2 = _parents(R, rlen, M, p)
        q[i, 0] = q1
        q[i, 1] = q2
        off[i + 1] = 3 + rlen[p] + rlen[q1] + rlen[q2]
    for i in range(n_c):
        off[i + 1] += off[i]
    reg = np.empty(off[n_c], np.int32)
    for i in prange(n_c):
        m = off[i]
        for j in range(3):
            x = cands[i] if j == 0 else q[i, j - 1]
            reg[m] = x
            m += 1
            for a in range(rlen[x]):
                reg[m] = R[x, a]
                m += 1
    chosen = np.empty(n_c, np.int64)
    m = first_disjoint(off, reg, mark, tag, limit, chosen)
    for j in range(m):
        i = chosen[j]
        acc[j] = cands[i]
        pq[j, 0] = q[i, 0]
        pq[j, 1] = q[i, 1]
    return m


@njit(cache=True, parallel=True)
def plan_batch(points, normals, colors, R, rlen, ropen, M, acc, pq, slot0, move, gap, strict,
               n_chunks, dist, curv, col, dbar, ring_r, ring_h, xlist, xrings, xlen, xopen, n_xs,
               par, wts):
    """Plan the accepted insertions in parallel (in ``n_chunks`` parts), insertion i in
    scratch row slot0 + i; the entropy terms of the planned fans (r's in row slot0 + i) go to
    dist, curv, col."""
    n_acc = acc.shape[0]
    width = R.shape[1]
    for ch in prange(n_chunks):
        cand, xs, ys, ordr, hull = fan_scratch(width)
        c = np.empty(width)
        for i in range((n_acc * ch) // n_chunks, (n_acc * (ch + 1)) // n_chunks):
            slot = slot0 + i
            h, n_x = _plan(points, normals, colors, R, rlen, ropen, M, acc[i], pq[i, 0], pq[i, 1],
                           slot, move, gap, strict, cand, xs, ys, ordr, hull, c, ring_r[i],
                           xlist[i], xrings[i], xlen[i], xopen[i], par[i], wts[i])
            ring_h[i] = h
            n_xs[i] = n_x
            if h == 0:
                continue
            # the terms as update_entropy would find them after the commit (row slot is r's)
            dist[slot], curv[slot], col[slot] = point_terms(points, normals, colors, slot,
                                                            ring_r[i], h, dbar)
            for t in range(n_x):
                x = xlist[i, t]
                dist[x], curv[x], col[x] = point_terms(points, normals, colors, x, xrings[i, t],
                                                       xlen[i, t], dbar)


@njit(cache=True, parallel=True)
def commit_batch(cloud, rings, slot0, final, plans, terms, w, blocked):
    """Commit the planned insertions with ``final[i] >= 0`` (their regions are disjoint): the
    fans, the terms of ``plan_batch``, and, when the weight of M_cc is 0, the entropies
    (else ``update_cc`` follows); the changed points are unblocked."""
    points, normals, colors = cloud
    R, rlen, ropen = rings
    ring_r, ring_h, xlist, xrings, xlen, xopen, n_xs, _, _ = plans
    dist, curv, _, col, M = terms
    no_cc = not w[2] > 0.0
    for i in prange(final.shape[0]):
        f = final[i]
        if f < 0:
            continue
        slot = slot0 + i
        _commit(points, normals, colors, R, rlen, ropen, slot, f, ring_r[i], ring_h[i],
                xlist[i], n_xs[i], xrings[i], xlen[i], xopen[i])
        dist[f] = dist[slot]
        curv[f] = curv[slot]
        col[f] = col[slot]
        blocked[f] = False
        if no_cc:
            M[f] = w[0] * dist[f] + w[1] * curv[f] + w[3] * col[f]
        for t in range(n_xs[i]):
            x = xlist[i, t]
            blocked[x] = False
            if no_cc:
                M[x] = w[0] * dist[x] + w[1] * curv[x] + w[3] * col[x]


@njit(cache=True, parallel=True)
def update_cc(points, R, rlen, dist, curv, cc, col, M, w, dbar, ids):
    """M_cc and the entropy of the points ``ids`` (their other terms already up to date)."""
    for i in prange(ids.shape[0]):
        x = ids[i]
        _entropy(R, rlen, points, curv, dist, cc, col, M, w, dbar, x)


@njit(cache=True)
def log_batch(R, rlen, ropen, final, xlist, n_xs, par, wts, lg_par, lg_wts, lg_nx, n0, rr,
              rr_off, ex, ex_open, ex_off, er, counters, rings=True):
    """Log the committed insertions in their numbering order (after ``commit_batch``).

    ``rings`` False: only the parents, weights and counts of changed fans
    (what the point arrays need), not the rings a hierarchy needs.
    """
    for i in range(final.shape[0]):
        f = final[i]
        if f < 0:
            continue
        if not rings:
            j = f - n0
            for t in range(3):
                lg_par[j, t] = par[i, t]
                lg_wts[j, t] = wts[i, t]
            lg_nx[j] = n_xs[i]
            counters[3] += 1
            continue
        rr, ex, ex_open, ex_off, er = _log(R, rlen, ropen, f, xlist[i], n_xs[i], par[i], wts[i],
                                           lg_par, lg_wts, lg_nx, f - n0, rr, rr_off, ex,
                                           ex_open, ex_off, er, counters)
        counters[3] += 1
    return rr, ex, ex_open, ex_off, er


@njit(cache=True)
def changed_of(final, xlist, n_xs, stamp, tag):
    """The new points and the fans they entered, each once."""
    total = 0
    for i in range(final.shape[0]):
        if final[i] >= 0:
            total += 1 + n_xs[i]
    out = np.empty(total, np.int64)
    m = 0
    for i in range(final.shape[0]):
        f = final[i]
        if f < 0:
            continue
        out[m] = f
        stamp[f] = tag
        m += 1
        for t in range(n_xs[i]):
            x = xlist[i, t]
            if stamp[x] != tag:
                stamp[x] = tag
                out[m] = x
                m += 1
    return out[:m]


@njit(cache=True, parallel=True)
def update_entropy(points, normals, colors, R, rlen, dist, curv, cc, col, M, w, dbar, ids):
    """The terms and entropy of the points ``ids`` (M_cc only when its weight is not 0)."""
    for i in prange(ids.shape[0]):
        x = ids[i]
        _terms(points, normals, colors, R, rlen, dist, curv, col, dbar, x)
    if w[2] > 0.0:
        for i in prange(ids.shape[0]):
            x = ids[i]
            _entropy(R, rlen, points, curv, dist, cc, col, M, w, dbar, x)
    else:
        for i in prange(ids.shape[0]):
            x = ids[i]
            M[x] = w[0] * dist[x] + w[1] * curv[x] + w[3] * col[x]


@njit(cache=True, parallel=True)
def round_candidates(M, rlen, ropen, blocked, n_cur, want):
    """About ``want`` eligible points of highest entropy, highest first (ties: smaller index)."""
    vals = np.empty(n_cur)
    for x in prange(n_cur):
        vals[x] = -M[x] if (not blocked[x] and _eligible(rlen, ropen, x)) else INF
    return lowest_keys(vals, want)


# -- levels of detail -------------------------------------------------------------------------


@njit(cache=True)
def insertion_detail(points, normals, n0, rr, rr_off):
    """(m, 6): each inserted point's offset and normal in the local frame of its ring."""
    m = rr_off.shape[0] - 1
    out = np.empty((m, 6))
    for j in range(m):
        p = n0 + j
        nb = rr[rr_off[j]:rr_off[j + 1]]
        fr = local_frame(points, nb, len(nb), normals[p, 0], normals[p, 1], normals[p, 2])
        d = _to_frame(fr, points[p, 0] - fr[0], points[p, 1] - fr[1], points[p, 2] - fr[2])
        e = _to_frame(fr, normals[p, 0], normals[p, 1], normals[p, 2])
        for t in range(3):
            out[j, t] = d[t]
            out[j, 3 + t] = e[t]
    return out


@njit(cache=True)
def interpolate(values, n0, par, wts):
    """Rows n0 + j of ``values`` (float, (N, c)) as the weighted sum of the parents' rows,
    in insertion order (a parent may be an earlier inserted point)."""
    for j in range(par.shape[0]):
        for d in range(values.shape[1]):
            values[n0 + j, d] = (wts[j, 0] * values[par[j, 0], d] + wts[j, 1] * values[par[j, 1], d]
                                 + wts[j, 2] * values[par[j, 2], d])

