"""Numba kernels of the reduction (paper section 5) and the levels of detail (section 6).

The reduction keeps the fans in a fixed-width table ``R[p, :rlen[p]]`` and,
for every point, the list ``IN[p, :nin[p]]`` of the points whose fans
contain it (``over[p]``: that list overflowed and is found by a scan). A
removal re-forms exactly the fans that contained the removed point, from
their own ring and the removed point's ring (no neighbour search), as the
local Delaunay ring in their tangent plane; the entropies of the points
whose terms change are recomputed and their keys updated in an indexed
binary heap (ties broken by the smaller index, so the order is
deterministic). As in the paper, the entropy is recomputed for the re-formed
fans; M_cc of a fan that did not change keeps its value until it does.
Every removal is logged so that the levels of detail can be walked back:
the removed point's ring and local frame coordinates, and the old rings of
the fans it changed.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import get_num_threads, njit, prange

from ._entropy_kernels import point_cc, point_terms
from ._geometry_kernels import dist2, tangent
from ._heap_kernels import heap_update, sift_down
from ._quadric_kernels import absorb, guard_value, mean_square, quadric_key, star_order
from ._ring_kernels import NOT_STEEP, closed_ring, inversions, open_ring
from ._splice_kernels import folds_onto_ring, hole_triangles, splice_ring

METHOD_ENTROPY = 0
METHOD_ERROR = 1
#: how removals mend the fans: re-formed (the paper), spliced from the hole's
#: triangulation refusing sharper folds, spliced without that rule
SPLICE_OFF, SPLICE_FOLDS, SPLICE_ANY = 0, 1, 2
INF = np.inf

# -- the state of a reduction, as a few named bundles of arrays -----------------------
# (numba passes namedtuples of arrays; the kernels unpack them on entry)

#: the points in work order: positions, normals and colours ((0, 3) without colour)
Cloud = namedtuple("Cloud", ["points", "normals", "colors"])
#: the fans as a table: ring rows (``width`` wide), their lengths, open flags, and which
#: points are still in the cloud
FanTable = namedtuple("FanTable", ["R", "rlen", "ropen", "active"])
#: per point the fans that hold it (rows of ``IN``, ``nin`` of them; ``over``: more than
#: fit, searched instead)
InLists = namedtuple("InLists", ["IN", "nin", "over"])
#: per point the entropy terms and the key the reduction removes by
Terms = namedtuple("Terms", ["dist", "curv", "cc", "col", "key"])
#: the points in the reduction's grid cells, for removals by retriangulation: which are
#: still in the cloud, the grid's origin, inverse cell side, cell starts and hash table
Near = namedtuple("Near", ["active", "lo", "inv_h", "start", "table"])
#: the log of the removals (the hierarchy): removal order, local-frame detail, the removed
#: rings, and the old rings of the fans each removal changed; the last five grow
RemovalLog = namedtuple("RemovalLog", ["order", "detail", "rem_off", "rem_open", "log_off",
                                       "rem_ring", "ent_x", "ent_open", "ent_off", "ent_ring"])
#: method 'error': on fans re-formed, the removed points each remaining point carries
#: (linked lists; else empty); on spliced fans, every point's quadric (``_quadric_kernels``;
#: else (0, 10)) and the centre its coordinates are taken from; ``guard`` (3,): the error
#: guard of the entropy order on spliced fans (see ``reduction._run``): its level (inf: no
#: guard) and the factors of a star's mean squared distance and of the colour loss in a
#: point's guard value; ``rgb``: the colours of the colour loss ((0, 3): none)
Carried = namedtuple("Carried", ["head", "nxt", "quad", "centre", "guard", "rgb"])
#: what ``reform_batch`` gives for a round's accepted removals ``acc`` (``heir``, ``cost``:
#: the ring point each collapses into and its cost, with quadrics)
Batch = namedtuple("Batch", ["acc", "buf_off", "buf", "buf_len", "buf_open", "buf_terms", "ok",
                             "frames", "heir", "cost"])


# -- local frames -------------------------------------------------------------------


@njit(cache=True)
def local_frame(points, nbrs, k, fnx, fny, fnz):
    """(origin, normal, tangent) of a fan ring: 9 floats.

    Origin: the centroid of the ring; normal: the Newell normal of the ring
    polygon (oriented by the ring's counter-clockwise order); tangent: the
    direction to the first ring point in that plane. Falls back to the given
    normal when the ring is degenerate.
    """
    ox = 0.0
    oy = 0.0
    oz = 0.0
    for a in range(k):
        q = nbrs[a]
        ox += points[q, 0]
        oy += points[q, 1]
        oz += points[q, 2]
    ox /= k
    oy /= k
    oz /= k
    nx = 0.0
    ny = 0.0
    nz = 0.0
    for a in range(k):
        q = nbrs[a]
        r = nbrs[(a + 1) % k]
        ax = points[q, 0] - ox
        ay = points[q, 1] - oy
        az = points[q, 2] - oz
        bx = points[r, 0] - ox
        by = points[r, 1] - oy
        bz = points[r, 2] - oz
        nx += ay * bz - az * by
        ny += az * bx - ax * bz
        nz += ax * by - ay * bx
    s = np.sqrt(nx * nx + ny * ny + nz * nz)
    scale = 0.0
    for a in range(k):
        q = nbrs[a]
        dx = points[q, 0] - ox
        dy = points[q, 1] - oy
        dz = points[q, 2] - oz
        scale += dx * dx + dy * dy + dz * dz
    if s <= 1e-12 * scale or s == 0.0:
        nx, ny, nz = fnx, fny, fnz
        s = np.sqrt(nx * nx + ny * ny + nz * nz)
    nx /= s
    ny /= s
    nz /= s
    q = nbrs[0]
    tx = points[q, 0] - ox
    ty = points[q, 1] - oy
    tz = points[q, 2] - oz
    d = tx * nx + ty * ny + tz * nz
    tx -= d * nx
    ty -= d * ny
    tz -= d * nz
    t = np.sqrt(tx * tx + ty * ty + tz * tz)
    if t <= 1e-9 * np.sqrt(scale / k) or t == 0.0:
        tx, ty, tz, _, _, _ = tangent(nx, ny, nz)
    else:
        tx /= t
        ty /= t
        tz /= t
    return ox, oy, oz, nx, ny, nz, tx, ty, tz


@njit(cache=True)
def _to_frame(fr, x, y, z):
    """Coordinates of the vector (x, y, z) in the frame (tangent, normal x tangent, normal)."""
    nx, ny, nz, tx, ty, tz = fr[3], fr[4], fr[5], fr[6], fr[7], fr[8]
    bx = ny * tz - nz * ty
    by = nz * tx - nx * tz
    bz = nx * ty - ny * tx
    return (x * tx + y * ty + z * tz, x * bx + y * by + z * bz, x * nx + y * ny + z * nz)


@njit(cache=True)
def _from_frame(fr, a, b, c):
    nx, ny, nz, tx, ty, tz = fr[3], fr[4], fr[5], fr[6], fr[7], fr[8]
    bx = ny * tz - nz * ty
    by = nz * tx - nx * tz
    bz = nx * ty - ny * tx
    return (a * tx + b * bx + c * nx, a * ty + b * by + c * ny, a * tz + b * bz + c * nz)


# -- the approximation error (method 'error') ------------------------------------------
#
# As the paper's e(r) (section 8: the maximum deviation of all of r's descendants from
# r's fan), the cost of removing x is the largest distance from the plane of x's ring of
# x itself and of every point removed before that x carries. A removed point is carried
# by exactly one remaining point: at a removal, the removed point and the points it
# carried go each to the nearest of the points whose fans it was in (those fans are
# re-formed, so their costs are recomputed anyway). The lists are linked through
# ``head`` (a point's first carried point, -1: none) and ``nxt``.


@njit(cache=True)
def _plane_distance(fr, points, d):
    return abs((points[d, 0] - fr[0]) * fr[3] + (points[d, 1] - fr[1]) * fr[4]
               + (points[d, 2] - fr[2]) * fr[5])


@njit(cache=True)
def _deviation(points, normals, x, ring, k, head, nxt):
    """The cost of removing x with the ring ``ring[:k]``: the largest distance from the
    ring's plane of x and of the points x carries (``head``/``nxt``; none if they are
    empty)."""
    if k == 0:
        return 0.0
    fr = local_frame(points, ring, k, normals[x, 0], normals[x, 1], normals[x, 2])
    e = _plane_distance(fr, points, x)
    if head.shape[0] > 0:
        d = head[x]
        while d >= 0:
            e = max(e, _plane_distance(fr, points, d))
            d = nxt[d]
    return e


@njit(cache=True)
def _heir(points, cands, m, d):
    """The point of ``cands[:m]`` nearest to the point d (ties: the smaller index); -1
    if m is 0."""
    best = -1
    bd = INF
    for a in range(m):
        y = cands[a]
        dx = points[y, 0] - points[d, 0]
        dy = points[y, 1] - points[d, 1]
        dz = points[y, 2] - points[d, 2]
        dd = dx * dx + dy * dy + dz * dz
        if dd < bd or (dd == bd and y < best):
            best = y
            bd = dd
    return best


@njit(cache=True)
def _heirs_of(R, rlen, IN, nin, p):
    """Where p's removal passes p and its carried points: the fans that contain p, or
    (none does) p's ring. (row, count)"""
    if nin[p] > 0:
        return IN[p], nin[p]
    return R[p], rlen[p]


@njit(cache=True)
def _pass_on(points, head, nxt, p, cands, m):
    """p's removal: p and the points it carried go each to its heir among ``cands[:m]``."""
    d = p
    after = head[p]
    head[p] = -1
    while d >= 0:
        y = _heir(points, cands, m, d)
        if y >= 0:
            nxt[d] = head[y]
            head[y] = d
        d = after
        if d >= 0:
            after = nxt[d]


# -- re-forming a fan -----------------------------------------------------------------


@njit(cache=True)
def _add(cand, m, z, skip):
    """``cand[:m]`` with z appended unless it is ``skip`` or there already: the new m.
    (A scan of the few candidates costs less than the cache misses of a stamp array.)"""
    if z == skip:
        return m
    for i in range(m):
        if cand[i] == z:
            return m
    cand[m] = z
    return m + 1


@njit(cache=True)
def _reform(points, normals, R, rlen, ropen, x, p, cand, xs, ys, order, hull, out, max_edge):
    """x's new ring without p, from x's ring and p's: written to ``out``.

    The local Delaunay ring in x's tangent plane: the points whose
    inversions lie on the convex hull of all inversions (see
    ``_ring_kernels.delaunay_rings``). A closed fan whose candidates no longer
    surround x becomes open. Returns (size, open), size -1 if no fan can be
    formed, or if the new ring has an edge longer than ``max_edge`` and than
    x's longest edge now (the spacing bound: the removal would leave a gap).
    """
    m = 0
    for a in range(rlen[x]):
        s = R[x, a]
        if s != p:
            m = _add(cand, m, s, x)
    for a in range(rlen[p]):
        m = _add(cand, m, R[p, a], x)
    h, op = delaunay_fan(points, normals, ropen[x], x, cand, m, xs, ys, order, hull,
                         R.shape[1], NOT_STEEP, out)
    if h > 0 and max_edge < INF:
        limit = max_edge * max_edge
        for a in range(rlen[x]):
            limit = max(limit, dist2(points, x, R[x, a]))
        for a in range(h):
            if dist2(points, x, out[a]) > limit:
                return -1, op
    return h, op


@njit(cache=True)
def fan_scratch(width):
    """Scratch arrays of :func:`delaunay_fan` for rings of at most ``width`` points:
    (cand, xs, ys, order, hull)."""
    cap = 4 * width + 8
    return (np.empty(cap, np.int64), np.empty(cap), np.empty(cap), np.empty(cap, np.int64),
            np.empty(cap + 1, np.int64))


@njit(cache=True)
def hole_scratch(width):
    """Scratch arrays of :func:`~._splice_kernels.hole_triangles` for rings of at most
    ``width`` points: (xs, ys, alive, tris)."""
    return (np.empty(width), np.empty(width), np.empty(width, np.bool_),
            np.empty((width, 3), np.int64))


@njit(cache=True)
def delaunay_fan(points, normals, is_open, x, cand, m, xs, ys, order, hull, width, steep, out):
    """x's local Delaunay ring in its tangent plane among ``cand[:m]``, written to ``out``.

    A closed fan stays closed if its candidates surround x, else (or if it
    was open) it is the open Delaunay fan. ``steep``: see
    ``_mesh_kernels.inversions``. Returns (size, open); size -1 if no fan can
    be formed.
    """
    mm = inversions(points, normals, x, cand, m, xs, ys, steep)
    if not is_open:
        h = closed_ring(xs, ys, mm, cand, hull, width, out)
        if h > 0:
            return h, False
    if mm < 2:
        return -1, True
    return open_ring(xs, ys, mm, cand, order, hull, width, out), True


# -- in-lists (the fans that contain a point) ----------------------------------------


@njit(cache=True)
def _in_add(IN, nin, over, y, x):
    if over[y]:
        return
    if nin[y] == IN.shape[1]:
        over[y] = True
        return
    IN[y, nin[y]] = x
    nin[y] += 1


@njit(cache=True)
def _in_remove(IN, nin, over, y, x):
    if over[y]:
        return
    for i in range(nin[y]):
        if IN[y, i] == x:
            nin[y] -= 1
            IN[y, i] = IN[y, nin[y]]
            return


@njit(cache=True)
def _ring_events(R, rlen, x, ring, k, ev_y, ev_x, ev_add, e):
    """The in-list changes of x's fan becoming ``ring[:k]``, written from ``e`` on: the
    points it drops (x leaves their in-lists), then those it gains. Returns the new end."""
    for a in range(rlen[x]):
        z = R[x, a]
        kept = False
        for b in range(k):
            if ring[b] == z:
                kept = True
                break
        if not kept:
            ev_y[e] = z
            ev_x[e] = x
            ev_add[e] = False
            e += 1
    for b in range(k):
        z = ring[b]
        new = True
        for a in range(rlen[x]):
            if R[x, a] == z:
                new = False
                break
        if new:
            ev_y[e] = z
            ev_x[e] = x
            ev_add[e] = True
            e += 1
    return e


@njit(cache=True)
def _set_ring(R, rlen, IN, nin, over, x, ring, k):
    """x's fan becomes ``ring[:k]``; the in-lists change only where the ring did."""
    room = rlen[x] + k
    ev_y = np.empty(room, np.int64)
    ev_x = np.empty(room, np.int64)
    ev_add = np.empty(room, np.bool_)
    for q in range(_ring_events(R, rlen, x, ring, k, ev_y, ev_x, ev_add, 0)):
        if ev_add[q]:
            _in_add(IN, nin, over, ev_y[q], x)
        else:
            _in_remove(IN, nin, over, ev_y[q], x)
    for b in range(k):
        R[x, b] = ring[b]
    rlen[x] = k


@njit(cache=True, parallel=True)
def build_in_lists(R, rlen, width, n_chunks):
    """Every point's in-list, in increasing order of the fans' points: each of ``n_chunks``
    parts (about one per thread) reads all fans and fills the lists of its range of points."""
    n = R.shape[0]
    IN = np.empty((n, width), np.int32)
    nin = np.zeros(n, np.int32)
    over = np.zeros(n, np.bool_)
    for ch in prange(n_chunks):
        lo = n * ch // n_chunks
        hi = n * (ch + 1) // n_chunks
        for x in range(n):
            for a in range(rlen[x]):
                y = R[x, a]
                if lo <= y < hi:
                    _in_add(IN, nin, over, y, x)
    return IN, nin, over


@njit(cache=True)
def _grow(arr, need):
    if need <= arr.shape[0]:
        return arr
    new = np.empty(max(need, 2 * arr.shape[0]), arr.dtype)
    new[: arr.shape[0]] = arr
    return new


# -- the reduction -----------------------------------------------------------------


@njit(cache=True)
def _key(points, normals, R, rlen, ropen, dist, curv, cc, col, w, method, carried, x):
    if method == METHOD_ERROR:
        if carried.quad.shape[0] > 0:
            return quadric_key(carried.quad, points, carried.centre, R, rlen, ropen, x)
        return _deviation(points, normals, x, R[x], rlen[x], carried.head, carried.nxt)
    if _guarded(carried) and guard_of(points, R, rlen, ropen, carried, x) > carried.guard[0]:
        return INF  # over the error guard: x waits for the guard's next level
    return w[0] * dist[x] + w[1] * curv[x] + w[2] * cc[x] + w[3] * col[x]


@njit(cache=True)
def _guarded(carried):
    """Whether the entropy order's error guard is on (spliced fans with quadrics)."""
    return carried.quad.shape[0] > 0 and carried.guard[0] < INF


@njit(cache=True)
def _colour_loss(rgb, R, rlen, p):
    """What removing p loses of the colours: the squared distance of its colour from the
    mean colour of its ring (0 without colours or ring)."""
    k = rlen[p]
    if rgb.shape[0] == 0 or k == 0:
        return 0.0
    s = 0.0
    for c in range(3):
        m = 0.0
        for a in range(k):
            m += rgb[R[p, a], c]
        d = rgb[p, c] - m / k
        s += d * d
    return s


@njit(cache=True)
def _guard_sum(R, rlen, carried, p, ms):
    """A guard value: the mean squared distance ``ms`` of a star of p and p's colour loss,
    each times its factor (``Carried.guard``)."""
    g = carried.guard[1] * ms
    if carried.guard[2] > 0.0:
        g += carried.guard[2] * _colour_loss(carried.rgb, R, rlen, p)
    return g


@njit(cache=True)
def guard_of(points, R, rlen, ropen, carried, p):
    """p's guard value, with its cheapest star."""
    return _guard_sum(R, rlen, carried, p, guard_value(carried.quad, points, carried.centre, R,
                                                       rlen, ropen, p))


@njit(cache=True)
def _over_guard(points, R, rlen, carried, p, q, c):
    """Whether collapsing p into q at cost c is over the guard's level."""
    if not _guarded(carried):
        return False
    ms = mean_square(carried.quad, points, carried.centre, p, q, c)
    return _guard_sum(R, rlen, carried, p, ms) > carried.guard[0]


@njit(cache=True)
def _retriangulate(points, normals, R, rlen, ropen, p, max_edge2, folds, near, hx, hy, halive,
                   htris, carried, js, costs, key_p, method):
    """p's hole triangulated (``_splice_kernels.hole_triangles``): (number of triangles,
    heir, cost). Without quadrics by ear clipping (heir -1, cost 0); with them the
    cheapest star that keeps the manifold and folds onto none of the ring's fans
    (``_quadric_kernels``; ``js``, ``costs``: scratch), and -2 triangles if it
    costs more than p's key ``key_p`` (p's key must rise to that cost first); -1: none."""
    quad = carried.quad
    if quad.shape[0] == 0:
        return hole_triangles(points, normals, R, rlen, ropen, p, max_edge2, folds, near, hx,
                              hy, halive, htris), -1, 0.0
    m = star_order(quad, points, carried.centre, R, rlen, ropen, p, js, costs)
    for t in range(m):
        nt = hole_triangles(points, normals, R, rlen, ropen, p, max_edge2, folds, near, hx,
                            hy, halive, htris, js[t])
        if nt > 0 and (folds or not folds_onto_ring(points, R, rlen, ropen, p, htris, nt)):
            if method == METHOD_ERROR and costs[t] > key_p:
                return -2, R[p, js[t]], costs[t]
            if method != METHOD_ERROR and _over_guard(points, R, rlen, carried, p,
                                                      R[p, js[t]], costs[t]):
                return -1, -1, INF  # the entropy order's error guard: p waits
            return nt, R[p, js[t]], costs[t]
    if method == METHOD_ERROR or m == 0:
        return -1, -1, INF
    if _over_guard(points, R, rlen, carried, p, R[p, js[0]], costs[0]):
        return -1, -1, INF
    # the entropy order: no star keeps the manifold, ears may (q takes p's planes anyway)
    return hole_triangles(points, normals, R, rlen, ropen, p, max_edge2, folds, near, hx, hy,
                          halive, htris), R[p, js[0]], costs[0]


@njit(cache=True, parallel=True)
def init_state(points, normals, colors, R, rlen, ropen, w, dbar, method, carried):
    """Terms and keys of every point: (dist, curv, cc, col, key) (the heap: :func:`heap_of`).
    ``carried``: see ``Carried``."""
    n = points.shape[0]
    dist = np.zeros(n)
    curv = np.zeros(n)
    cc = np.zeros(n)
    col = np.zeros(n)
    for x in prange(n):
        dist[x], curv[x], col[x] = point_terms(points, normals, colors, x, R[x], rlen[x], dbar)
    key = np.empty(n)
    for x in prange(n):
        cc[x] = point_cc(points, curv, x, R[x], rlen[x], dbar)
        key[x] = _key(points, normals, R, rlen, ropen, dist, curv, cc, col, w, method, carried,
                      x)
        if rlen[x] == 0:
            key[x] = INF  # an isolated point has no fan to re-form: it stays
    return dist, curv, cc, col, key


@njit(cache=True)
def reduce_steps(cloud, w, dbar, max_edge, splice, near, method, fans, inl, terms, heap, hpos,
                 counters, max_steps, target, log, stamp, carried):
    """Remove up to ``max_steps`` points (never below ``target`` active ones).

    ``counters``: [heap size, removals, log entries, ring entries of the log,
    removed-ring entries, stamp tag]. Returns the (possibly grown) growing log
    arrays (``rem_ring, ent_x, ent_open, ent_off, ent_ring``); the removal
    stops early when every remaining point is blocked (its key is inf: no fan
    could be re-formed without it). ``splice`` (not ``SPLICE_OFF``): the fans are the
    one-rings of a 2-manifold mesh, and a removal retriangulates the hole once and
    splices the neighbours' rings from it (``_splice_kernels``) instead of re-forming
    them; ``SPLICE_FOLDS``: refusing removals that sharpen a fold. ``near``: see
    ``_splice_kernels.hole_triangles``.
    """
    points, normals, colors = cloud
    R, rlen, ropen, active = fans
    IN, nin, over = inl
    dist, curv, cc, col, key = terms
    order, detail, rem_off, rem_open, log_off, rem_ring, ent_x, ent_open, ent_off, ent_ring = log
    head, nxt, quad = carried.head, carried.nxt, carried.quad
    n = points.shape[0]
    width = R.shape[1]
    js = np.empty(width, np.int64)
    costs = np.empty(width)
    cand, xs, ys, ordr, hull = fan_scratch(width)
    aff = np.empty(n if n < 4096 else 4096, np.int64)
    new_rings = np.empty((aff.shape[0], width), np.int32)
    new_len = np.empty(aff.shape[0], np.int64)
    new_open = np.empty(aff.shape[0], np.bool_)
    upd = np.empty(aff.shape[0] + 1, np.int64)
    hx, hy, halive, htris = hole_scratch(width)
    size = counters[0]
    steps = 0
    while steps < max_steps and size > target:
        p = heap[0]
        if key[p] == INF:
            break
        # the fans that contain p
        n_aff = 0
        if over[p]:
            for x in range(n):
                if active[x] and x != p:
                    for a in range(rlen[x]):
                        if R[x, a] == p:
                            if n_aff < aff.shape[0]:
                                aff[n_aff] = x
                                n_aff += 1
                            break
        else:
            for i in range(nin[p]):
                aff[n_aff] = IN[p, i]
                n_aff += 1
        # re-form them all (or none)
        ok = True
        heir = -1
        if splice:
            nt = -1
            if not over[p] and n_aff == rlen[p]:  # the fans holding p are its ring's
                nt, heir, c = _retriangulate(points, normals, R, rlen, ropen, p,
                                             max_edge * max_edge, splice == SPLICE_FOLDS, near,
                                             hx, hy, halive, htris, carried, js, costs,
                                             key[p], method)
                if nt == -2:  # a dearer star than p's key: p waits with its true cost
                    heap_update(heap, hpos, key, p, c, size)
                    continue
            ok = nt > 0
            for i in range(n_aff if ok else 0):
                x = aff[i]
                h = splice_ring(R, rlen, ropen, x, p, htris, nt, new_rings[i])
                if h < 0:
                    ok = False
                    break
                new_len[i] = h
                new_open[i] = ropen[x]
        else:
            for i in range(n_aff):
                x = aff[i]
                h, op = _reform(points, normals, R, rlen, ropen, x, p, cand, xs, ys, ordr,
                                hull, new_rings[i], max_edge)
                if h < 0:
                    ok = False
                    break
                new_len[i] = h
                new_open[i] = op
        if not ok:
            heap_update(heap, hpos, key, p, INF, size)
            continue
        # log: the removal, p's ring and frame, the old rings of the fans changed
        r = counters[1]
        k = rlen[p]
        order[r] = p
        fr = local_frame(points, R[p], k, normals[p, 0], normals[p, 1], normals[p, 2])
        d = _to_frame(fr, points[p, 0] - fr[0], points[p, 1] - fr[1], points[p, 2] - fr[2])
        e = _to_frame(fr, normals[p, 0], normals[p, 1], normals[p, 2])
        for c in range(3):
            detail[r, c] = d[c]
            detail[r, 3 + c] = e[c]
        rem_ring = _grow(rem_ring, counters[4] + k)
        for a in range(k):
            rem_ring[counters[4] + a] = R[p, a]
        counters[4] += k
        rem_off[r + 1] = counters[4]
        rem_open[r] = ropen[p]
        ent_x = _grow(ent_x, counters[2] + n_aff)
        ent_open = _grow(ent_open, counters[2] + n_aff)
        ent_off = _grow(ent_off, counters[2] + n_aff + 1)
        for i in range(n_aff):
            x = aff[i]
            e_i = counters[2]
            ent_x[e_i] = x
            ent_open[e_i] = ropen[x]
            ent_ring = _grow(ent_ring, counters[3] + rlen[x])
            for a in range(rlen[x]):
                ent_ring[counters[3] + a] = R[x, a]
            counters[3] += rlen[x]
            counters[2] += 1
            ent_off[counters[2]] = counters[3]
        log_off[r + 1] = counters[2]
        counters[1] += 1
        # remove p: out of the heap and of its neighbours' in-lists
        active[p] = False
        last = heap[size - 1]
        size -= 1
        if size > 0 and last != p:
            heap[0] = last
            hpos[last] = 0
            sift_down(heap, hpos, key, 0, size)
        hpos[p] = -1
        for a in range(k):
            _in_remove(IN, nin, over, R[p, a], p)
        if head.shape[0] > 0:
            if n_aff > 0:
                _pass_on(points, head, nxt, p, aff, n_aff)
            else:
                _pass_on(points, head, nxt, p, R[p], k)
        if heir >= 0 and quad.shape[0] > 0:
            absorb(quad, heir, p)
        # the new rings
        for i in range(n_aff):
            x = aff[i]
            _set_ring(R, rlen, IN, nin, over, x, new_rings[i], new_len[i])
            ropen[x] = new_open[i]
        # entropies of the re-formed fans (the paper's 'recompute M for them')
        counters[5] += 1
        tag = counters[5]
        n_upd = 0
        for i in range(n_aff):
            x = aff[i]
            dist[x], curv[x], col[x] = point_terms(points, normals, colors, x, R[x], rlen[x],
                                                   dbar)
            if stamp[x] != tag:
                stamp[x] = tag
                upd[n_upd] = x
                n_upd += 1
        if heir >= 0 and quad.shape[0] > 0 and method == METHOD_ERROR:
            # the heir's new quadric: its ring's keys too
            if upd.shape[0] < n_upd + rlen[heir]:
                upd = _grow(upd, n_upd + rlen[heir])
            for a in range(rlen[heir]):
                y = R[heir, a]
                if stamp[y] != tag:
                    stamp[y] = tag
                    upd[n_upd] = y
                    n_upd += 1
        for i in range(n_upd):
            y = upd[i]
            if not active[y]:
                continue
            cc[y] = point_cc(points, curv, y, R[y], rlen[y], dbar)
            value = _key(points, normals, R, rlen, ropen, dist, curv, cc, col, w, method,
                         carried, y)
            if rlen[y] == 0:
                value = INF
            heap_update(heap, hpos, key, y, value, size)
        steps += 1
    counters[0] = size
    return rem_ring, ent_x, ent_open, ent_off, ent_ring


# -- levels of detail -----------------------------------------------------------------


@njit(cache=True)
def undo(R, rlen, ropen, active, order, rem_off, rem_ring, rem_open, log_off, ent_x,
         ent_open, ent_off, ent_ring, r_from, r_to):
    """Undo the removals r_from - 1 down to r_to: reinsert the points, restore the fans."""
    for r in range(r_from - 1, r_to - 1, -1):
        p = order[r]
        active[p] = True
        k = rem_off[r + 1] - rem_off[r]
        for a in range(k):
            R[p, a] = rem_ring[rem_off[r] + a]
        rlen[p] = k
        ropen[p] = rem_open[r]
        for e in range(log_off[r], log_off[r + 1]):
            x = ent_x[e]
            k = ent_off[e + 1] - ent_off[e]
            for a in range(k):
                R[x, a] = ent_ring[ent_off[e] + a]
            rlen[x] = k
            ropen[x] = ent_open[e]


@njit(cache=True)
def place(points, normals, order, rem_off, rem_ring, detail, r_from, r_to, moved):
    """Positions (and normals) of the points removed r_from - 1 down to r_to from their detail.

    Each point is put back in the local frame of its ring at removal time,
    taken from the ring's current positions; ``moved[p]`` is set.
    """
    for r in range(r_from - 1, r_to - 1, -1):
        p = order[r]
        nb = rem_ring[rem_off[r]:rem_off[r + 1]]
        fr = local_frame(points, nb, len(nb), normals[p, 0], normals[p, 1], normals[p, 2])
        d = _from_frame(fr, detail[r, 0], detail[r, 1], detail[r, 2])
        e = _from_frame(fr, detail[r, 3], detail[r, 4], detail[r, 5])
        points[p, 0] = fr[0] + d[0]
        points[p, 1] = fr[1] + d[1]
        points[p, 2] = fr[2] + d[2]
        s = np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        if s > 0.0:
            normals[p, 0] = e[0] / s
            normals[p, 1] = e[1] / s
            normals[p, 2] = e[2] / s
        moved[p] = True


@njit(cache=True)
def ring_normals(points, offsets, ring, normals):
    """Newell normals of the rings, turned to the side of ``normals`` (kept where degenerate)."""
    n = points.shape[0]
    out = normals.copy()
    for p in range(n):
        k = offsets[p + 1] - offsets[p]
        if k < 2:
            continue
        nb = ring[offsets[p]:offsets[p + 1]]
        fr = local_frame(points, nb, k, normals[p, 0], normals[p, 1], normals[p, 2])
        s = fr[3] * normals[p, 0] + fr[4] * normals[p, 1] + fr[5] * normals[p, 2]
        sign = -1.0 if s < 0 else 1.0
        out[p, 0] = sign * fr[3]
        out[p, 1] = sign * fr[4]
        out[p, 2] = sign * fr[5]
    return out


@njit(cache=True)
def measure_detail(points, normals, order, rem_off, rem_ring):
    """(r, 3): each removed point's offset in the local frame of its ring at removal time."""
    r_count = order.shape[0]
    out = np.empty((r_count, 3))
    for r in range(r_count):
        p = order[r]
        nb = rem_ring[rem_off[r]:rem_off[r + 1]]
        fr = local_frame(points, nb, len(nb), normals[p, 0], normals[p, 1], normals[p, 2])
        d = _to_frame(fr, points[p, 0] - fr[0], points[p, 1] - fr[1], points[p, 2] - fr[2])
        out[r, 0] = d[0]
        out[r, 1] = d[1]
        out[r, 2] = d[2]
    return out


# -- the reduction in rounds -----------------------------------------------------------
#
# A round takes the lowest keys (a fixed fraction of the points left, in key
# order) and accepts, lowest key first, every point whose neighbourhood N(p) =
# {p} + ring(p) + the fans containing p meets no accepted point's: removals
# that share no fan and read no ring another one changes, so they commute.
# The accepted points are removed in index order (memory order): the fans
# they change are re-formed in parallel, the log and the in-lists written in
# order, the entropies of the re-formed fans recomputed in parallel.


#: bits per digit of :func:`stable_order` (a count array of 2**11 stays in the L1 cache)
ORDER_DIGIT = 11


@njit(cache=True)
def stable_order(v):
    """``np.argsort(v, kind="mergesort")`` for float64 ``v`` without NaN (equal values keep
    their order; -0.0 equals 0.0), by an LSD radix sort on the bits, skipping the digits
    every value shares: several times faster than numba's merge sort."""
    m = v.shape[0]
    keys = np.empty(m, np.uint64)
    bits = (v + 0.0).view(np.uint64)  # + 0.0: -0.0 becomes 0.0
    top = np.uint64(1) << np.uint64(63)
    for i in range(m):  # the bits in the order of the values
        b = bits[i]
        keys[i] = ~b if b & top else b | top
    idx = np.arange(m)
    keys2 = np.empty(m, np.uint64)
    idx2 = np.empty(m, np.int64)
    n_buckets = 1 << ORDER_DIGIT
    count = np.empty(n_buckets, np.int64)
    mask = np.uint64(n_buckets - 1)
    for shift in range(0, 64, ORDER_DIGIT):
        s = np.uint64(shift)
        count[:] = 0
        for i in range(m):
            count[(keys[i] >> s) & mask] += 1
        if m == 0 or count[(keys[0] >> s) & mask] == m:
            continue
        at = 0
        for d in range(n_buckets):
            c = count[d]
            count[d] = at
            at += c
        for i in range(m):
            d = (keys[i] >> s) & mask
            keys2[count[d]] = keys[i]
            idx2[count[d]] = idx[i]
            count[d] += 1
        keys, keys2 = keys2, keys
        idx, idx2 = idx2, idx
    return idx


@njit(cache=True, parallel=True)
def lowest_keys(vals, want):
    """About ``want`` indices of the lowest finite ``vals``, lowest first (ties: smaller index).

    The threshold is the quantile of a fixed sample (every s-th value), so
    the count is near ``want``, not exact, and the choice deterministic;
    every finite value when there are at most ``2 want``. Parallel.
    """
    n = vals.shape[0]
    thr = INF
    if n > 2 * want:
        stride = max(1, n // 8192)
        sample = vals[::stride].copy()
        finite = sample[sample < INF]
        if finite.shape[0] > 0:
            q = min(finite.shape[0] - 1, want // stride)  # a sampled value stands for stride
            thr = np.partition(finite, q)[q]
    n_chunks = 64
    counts = np.zeros(n_chunks + 1, np.int64)
    for ch in prange(n_chunks):
        c = 0
        for x in range((n * ch) // n_chunks, (n * (ch + 1)) // n_chunks):
            if vals[x] <= thr and vals[x] < INF:
                c += 1
        counts[ch + 1] = c
    for ch in range(n_chunks):
        counts[ch + 1] += counts[ch]
    ids = np.empty(counts[n_chunks], np.int64)
    for ch in prange(n_chunks):
        at = counts[ch]
        for x in range((n * ch) // n_chunks, (n * (ch + 1)) // n_chunks):
            if vals[x] <= thr and vals[x] < INF:
                ids[at] = x
                at += 1
    order = stable_order(vals[ids])  # equal keys by index
    return ids[order]


@njit(cache=True, parallel=True)
def round_candidates(key, active, want):
    """About ``want`` active points of lowest (key, index) with a finite key, in that order."""
    n = key.shape[0]
    vals = np.empty(n)
    for x in prange(n):
        vals[x] = key[x] if active[x] else INF
    return lowest_keys(vals, want)


@njit(cache=True)
def first_disjoint(off, reg, mark, tag, limit, out):
    """In order, the regions ``reg[off[i]:off[i + 1]]`` (an empty one is never taken) that
    meet no region taken before, at most ``limit`` of them: their numbers i into ``out``;
    returns how many. Taken regions are marked with ``tag`` in ``mark`` (uint8: it stays
    in the cache). The serial part of a round's acceptance: the regions are gathered
    before, in parallel."""
    m = 0
    for i in range(off.shape[0] - 1):
        if m == limit:
            break
        lo = off[i]
        hi = off[i + 1]
        if lo == hi:
            continue
        clash = False
        for a in range(lo, hi):
            if mark[reg[a]] == tag:
                clash = True
                break
        if clash:
            continue
        for a in range(lo, hi):
            mark[reg[a]] = tag
        out[m] = i
        m += 1
    return m


@njit(cache=True, parallel=True)
def accept_batch(cands, R, rlen, IN, nin, over, mark, tag):
    """Lowest key first, the candidates whose neighbourhoods (the point, its ring, the fans
    that contain it) meet no accepted one's; the points, sorted. ``mark``/``tag``: see
    :func:`first_disjoint`."""
    n_c = cands.shape[0]
    off = np.empty(n_c + 1, np.int64)
    off[0] = 0
    for i in prange(n_c):
        p = cands[i]
        off[i + 1] = 0 if over[p] else 1 + rlen[p] + nin[p]
    for i in range(n_c):
        off[i + 1] += off[i]
    reg = np.empty(off[n_c], np.int32)
    for i in prange(n_c):
        p = cands[i]
        if over[p]:
            continue
        m = off[i]
        reg[m] = p
        for a in range(rlen[p]):
            reg[m + 1 + a] = R[p, a]
        m += 1 + rlen[p]
        for t in range(nin[p]):
            reg[m + t] = IN[p, t]
    chosen = np.empty(n_c, np.int64)
    k = first_disjoint(off, reg, mark, tag, n_c, chosen)
    out = np.empty(k, np.int64)
    for j in range(k):
        out[j] = cands[chosen[j]]
    return np.sort(out)


@njit(cache=True, parallel=True)
def reform_batch(points, normals, colors, dbar, R, rlen, ropen, IN, nin, acc, buf_off, n_chunks,
                 with_frames, cc, w, key_now, max_edge, splice, near, defer, carried, key,
                 method):
    """Phase A: the new fans of every point whose fan contains an accepted point.

    Returns (buf, buf_len, buf_open, buf_terms, ok, frames, heir, cost): buf[buf_off[i] +
    j] the new ring of IN[acc[i], j] and buf_terms[...] the entropy terms
    (dist, curv, col) of that fan (they depend on its ring only, and a fan
    changes at most once a round), and with ``key_now`` its entropy key as
    ``update_keys`` would find it (no M_cc weight: then the key needs no
    other fan's new terms; method 'error' keys come in ``_apply``); ok[i]
    0 if some fan cannot be re-formed (2: a retriangulation deferred to a later
    round, next to an earlier removal of this round; 3: with quadrics, the cheapest
    star that keeps the manifold costs more than acc[i]'s key, which rises to
    cost[i]); heir[i], cost[i]: with quadrics, the point acc[i] collapses into
    and the cost (``_retriangulate``); frames[i] the detail of
    acc[i] (offset and normal in its ring's frame; only ``with_frames``). The
    work is split in ``n_chunks`` parts. ``splice``, ``near``: see
    :func:`reduce_steps`; ``defer``: removals to leave for a later round
    (``_splice_kernels.defer_overlaps``).
    """
    n_acc = acc.shape[0]
    width = R.shape[1]
    total = buf_off[n_acc]
    buf = np.empty((total, width), np.int32)
    buf_len = np.empty(total, np.int64)
    buf_open = np.empty(total, np.bool_)
    buf_terms = np.empty((total, 4))
    ok = np.ones(n_acc, np.int8)  # 1: ok, 0: refused, 2: deferred to a later round
    frames = np.empty((n_acc if with_frames else 0, 6))
    heir = np.full(n_acc, -1, np.int64)
    cost = np.zeros(n_acc)
    for ch in prange(n_chunks):
        cand, xs, ys, ordr, hull = fan_scratch(width)
        hx, hy, halive, htris = hole_scratch(width)
        js = np.empty(width, np.int64)
        costs = np.empty(width)
        for i in range((n_acc * ch) // n_chunks, (n_acc * (ch + 1)) // n_chunks):
            p = acc[i]
            nt = 0
            if splice:
                nt = -1
                if defer[i]:
                    ok[i] = 2
                else:
                    if nin[p] == rlen[p]:  # the fans holding p are its ring's
                        nt, heir[i], cost[i] = _retriangulate(
                            points, normals, R, rlen, ropen, p, max_edge * max_edge,
                            splice == SPLICE_FOLDS, near, hx, hy, halive, htris, carried, js,
                            costs, key[p], method)
                    if nt == -2:
                        ok[i] = 3
                    elif nt < 0:
                        ok[i] = 0
            for j in range(nin[p] if ok[i] == 1 else 0):
                x = IN[p, j]
                if splice:
                    h = splice_ring(R, rlen, ropen, x, p, htris, nt, buf[buf_off[i] + j])
                    op = ropen[x]
                else:
                    h, op = _reform(points, normals, R, rlen, ropen, x, p, cand, xs, ys, ordr,
                                    hull, buf[buf_off[i] + j], max_edge)
                if h < 0:
                    ok[i] = 0
                    break
                b = buf_off[i] + j
                buf_len[b] = h
                buf_open[b] = op
                d, cu, co = point_terms(points, normals, colors, x, buf[b], h, dbar)
                buf_terms[b, 0] = d
                buf_terms[b, 1] = cu
                buf_terms[b, 2] = co
                if key_now:  # as _key (w[2] is 0, cc[x] unchanged this round)
                    buf_terms[b, 3] = w[0] * d + w[1] * cu + w[2] * cc[x] + w[3] * co
            if not with_frames:
                continue
            k = rlen[p]
            fr = local_frame(points, R[p], k, normals[p, 0], normals[p, 1], normals[p, 2])
            d = _to_frame(fr, points[p, 0] - fr[0], points[p, 1] - fr[1], points[p, 2] - fr[2])
            e = _to_frame(fr, normals[p, 0], normals[p, 1], normals[p, 2])
            for c in range(3):
                frames[i, c] = d[c]
                frames[i, 3 + c] = e[c]
    return buf, buf_len, buf_open, buf_terms, ok, frames, heir, cost


@njit(cache=True)
def _plan_commit(rlen, IN, nin, key, acc, ok, cost, limit, counters):
    """Which removals a round makes and where their logs go.

    The first ``limit`` accepted points whose fans can all be re-formed, in
    index order (the others keep their place, with an infinite key, or with
    ok 3 their star's cost). Returns
    (idx into acc, and the running offsets of the removed rings, the log
    entries and the logged rings: each (m + 1,), starting at the totals so far).
    """
    n_acc = acc.shape[0]
    idx = np.empty(n_acc, np.int64)
    m = 0
    for i in range(n_acc):
        if ok[i] != 1:
            if ok[i] == 0:
                key[acc[i]] = INF
            elif ok[i] == 3:
                key[acc[i]] = cost[i]
            continue
        if m == limit:
            break
        idx[m] = i
        m += 1
    rem_at = np.empty(m + 1, np.int64)
    ent_at = np.empty(m + 1, np.int64)
    ring_at = np.empty(m + 1, np.int64)
    rem_at[0] = counters[4]
    ent_at[0] = counters[2]
    ring_at[0] = counters[3]
    for j in range(m):
        p = acc[idx[j]]
        rem_at[j + 1] = rem_at[j] + rlen[p]
        ent_at[j + 1] = ent_at[j] + nin[p]
        s = 0
        for t in range(nin[p]):
            s += rlen[IN[p, t]]
        ring_at[j + 1] = ring_at[j] + s
    return idx[:m], rem_at, ent_at, ring_at


@njit(cache=True, parallel=True)
def _write_logs(R, rlen, ropen, IN, nin, acc, frames, idx, rem_at, ent_at, ring_at, r0, order,
                detail, rem_off, rem_ring, rem_open, log_off, ent_x, ent_open, ent_off, ent_ring):
    """The logs of the removals ``acc[idx]`` (numbers r0, r0 + 1, ...), before any applies."""
    for j in prange(idx.shape[0]):
        i = idx[j]
        p = acc[i]
        r = r0 + j
        order[r] = p
        for c in range(6):
            detail[r, c] = frames[i, c]
        for a in range(rlen[p]):
            rem_ring[rem_at[j] + a] = R[p, a]
        rem_off[r + 1] = rem_at[j + 1]
        rem_open[r] = ropen[p]
        at = ring_at[j]
        for t in range(nin[p]):
            x = IN[p, t]
            e = ent_at[j] + t
            ent_x[e] = x
            ent_open[e] = ropen[x]
            for a in range(rlen[x]):
                ent_ring[at + a] = R[x, a]
            at += rlen[x]
            ent_off[e + 1] = at
        log_off[r + 1] = ent_at[j + 1]


@njit(cache=True, parallel=True)
def _apply(R, rlen, ropen, active, IN, nin, over, key, acc, idx, buf_off, buf, buf_len,
           buf_open, buf_terms, dist, curv, col, key_now, stamp, tag, n_chunks, points, normals,
           carried, heir):
    """Make the removals ``acc[idx]``: fans re-formed (with their entropy terms), in-lists
    kept; the changed fans, once.

    Method 'error' (``head`` not empty): p and the points it carried pass to
    their heirs, then the changed fans get their keys (:func:`_deviation`);
    heirs and changed fans are in p's neighbourhood, which no other removal
    of the round touches. With quadrics, p's heir ``heir[idx[j]]`` takes p's
    quadric (the keys then come from ``update_keys``).

    The same result as making them one after the other, in two parallel
    passes. The accepted points' neighbourhoods (p, its ring, its in-list)
    are disjoint, so the removals touch disjoint rows of ``R``, and p's
    in-list is the one at the start of the round. First each removal, in
    parallel, re-forms its fans and writes the in-list changes they imply
    as events, in the order the serial loop makes them. Then the in-lists
    change: every thread reads all events in order and makes those of its
    own range of points (``n_chunks`` ranges), so each in-list sees the
    serial sequence.
    """
    head, nxt, quad = carried.head, carried.nxt, carried.quad
    m = idx.shape[0]
    ch_off = np.empty(m + 1, np.int64)  # the changed fans of removal j
    ev_off = np.empty(m + 1, np.int64)  # room for its events
    ch_off[0] = 0
    ev_off[0] = 0
    for j in range(m):
        p = acc[idx[j]]
        ch_off[j + 1] = ch_off[j] + nin[p]
        room = rlen[p]
        for t in range(nin[p]):
            room += rlen[IN[p, t]] + buf_len[buf_off[idx[j]] + t]
        ev_off[j + 1] = ev_off[j] + room
    changed = np.empty(ch_off[m], np.int64)
    ev_y = np.empty(ev_off[m], np.int64)
    ev_x = np.empty(ev_off[m], np.int64)
    ev_add = np.empty(ev_off[m], np.bool_)
    ev_n = np.zeros(m, np.int64)
    for j in prange(m):
        i = idx[j]
        p = acc[i]
        active[p] = False
        key[p] = INF
        e = ev_off[j]
        for t in range(nin[p]):  # a copy: p's in-list empties as its fans change
            changed[ch_off[j] + t] = IN[p, t]
        if head.shape[0] > 0:  # method 'error': p and what it carried to their heirs
            row, m_h = _heirs_of(R, rlen, IN, nin, p)
            _pass_on(points, head, nxt, p, row, m_h)
        if quad.shape[0] > 0 and heir[i] >= 0:
            absorb(quad, heir[i], p)
        for a in range(rlen[p]):
            ev_y[e] = R[p, a]
            ev_x[e] = p
            ev_add[e] = False
            e += 1
        for t in range(nin[p]):
            x = changed[ch_off[j] + t]
            b = buf_off[i] + t
            k = buf_len[b]
            e = _ring_events(R, rlen, x, buf[b], k, ev_y, ev_x, ev_add, e)
            for c in range(k):
                R[x, c] = buf[b, c]
            rlen[x] = k
            ropen[x] = buf_open[b]
            dist[x] = buf_terms[b, 0]
            curv[x] = buf_terms[b, 1]
            col[x] = buf_terms[b, 2]
            if head.shape[0] > 0:
                key[x] = INF if k == 0 else _deviation(points, normals, x, buf[b], k, head, nxt)
            elif key_now:
                key[x] = INF if k == 0 else buf_terms[b, 3]
        ev_n[j] = e - ev_off[j]
    n = nin.shape[0]
    for ch in prange(n_chunks):
        lo = n * ch // n_chunks
        hi = n * (ch + 1) // n_chunks
        for j in range(m):
            for e in range(ev_off[j], ev_off[j] + ev_n[j]):
                y = ev_y[e]
                if y < lo or y >= hi:
                    continue
                if ev_add[e]:
                    _in_add(IN, nin, over, y, ev_x[e])
                else:
                    _in_remove(IN, nin, over, y, ev_x[e])
    k = 0
    for t in range(ch_off[m]):
        x = changed[t]
        if stamp[x] != tag:
            stamp[x] = tag
            changed[k] = x
            k += 1
    out = np.empty(k, np.int64)
    for t in range(k):
        out[t] = changed[t]
    return out


def commit_batch(cloud, fans, inl, terms, batch, key_now, limit, counters, log, stamp, carried,
                 write_logs=True):
    """Phase B: log (in parallel) and apply (in index order) the removals a round makes.

    A point whose fans cannot all be re-formed stays, its key set to inf.
    The changed fans get their new entropy terms (``batch.buf_terms``; and
    their keys with ``key_now``). Returns them (each once). ``write_logs``
    False: nothing is logged (and the log counters stay; ``frames`` may be
    empty).
    """
    points, normals, _ = cloud
    R, rlen, ropen, active = fans
    IN, nin, over = inl
    dist, curv, _, col, key = terms
    acc, buf_off, buf, buf_len, buf_open, buf_terms, ok, frames, heir, cost = batch
    order, detail, rem_off, rem_open, log_off, rem_ring, ent_x, ent_open, ent_off, ent_ring = log
    idx, rem_at, ent_at, ring_at = _plan_commit(rlen, IN, nin, key, acc, ok, cost, limit,
                                                counters)
    m = len(idx)
    if write_logs:
        _write_logs(R, rlen, ropen, IN, nin, acc, frames, idx, rem_at, ent_at, ring_at,
                    int(counters[1]), order, detail, rem_off, rem_ring, rem_open, log_off, ent_x,
                    ent_open, ent_off, ent_ring)
        counters[2] = ent_at[m]
        counters[3] = ring_at[m]
        counters[4] = rem_at[m]
    counters[1] += m
    counters[0] -= m
    counters[5] += 1
    return _apply(R, rlen, ropen, active, IN, nin, over, key, acc, idx, buf_off, buf, buf_len,
                  buf_open, buf_terms, dist, curv, col, key_now, stamp, counters[5],
                  get_num_threads() if m > 64 else 1, points, normals, carried, heir)


@njit(cache=True, parallel=True)
def guard_values(points, R, rlen, ropen, ids, carried):
    """The error guard's values (:func:`guard_of`) of the points ``ids``."""
    out = np.empty(ids.shape[0])
    for i in prange(ids.shape[0]):
        out[i] = guard_of(points, R, rlen, ropen, carried, ids[i])
    return out


@njit(cache=True, parallel=True)
def colour_losses(R, rlen, ids, rgb):
    """The colour loss (:func:`_colour_loss`) of the points ``ids``."""
    out = np.empty(ids.shape[0])
    for i in prange(ids.shape[0]):
        out[i] = _colour_loss(rgb, R, rlen, ids[i])
    return out


@njit(cache=True, parallel=True)
def update_keys(points, normals, R, rlen, ropen, dist, curv, cc, col, key, w, method, dbar, ids,
                carried):
    """M_cc and the keys of the fans ``ids`` (after every fan of the round has its terms)."""
    for i in prange(ids.shape[0]):
        y = ids[i]
        cc[y] = point_cc(points, curv, y, R[y], rlen[y], dbar)
        value = _key(points, normals, R, rlen, ropen, dist, curv, cc, col, w, method, carried,
                     y)
        key[y] = INF if rlen[y] == 0 else value


# -- tables and CSR ----------------------------------------------------------------------


@njit(cache=True, parallel=True)
def kept_level(R, rlen, active, order, rank):
    """The kept points of a table in work order (row i is input point ``order[i]``, and
    ``rank`` its inverse) as :func:`compact_level` gives them from the table in input order:
    (ids, offsets, ring), the kept input points in order and their rings renumbered among
    them."""
    n = R.shape[0]
    new = np.full(n, -1, np.int64)  # per input point: its number among the kept
    m = 0
    for p in range(n):
        if active[rank[p]]:
            new[p] = m
            m += 1
    ids = np.empty(m, np.int64)
    sizes = np.empty(m + 1, np.int64)
    sizes[0] = 0
    for p in prange(n):
        j = new[p]
        if j >= 0:
            ids[j] = p
            sizes[j + 1] = rlen[rank[p]]
    offsets = np.cumsum(sizes)
    ring = np.empty(offsets[m], np.int64)
    for j in prange(m):
        i = rank[ids[j]]
        at = offsets[j]
        for a in range(rlen[i]):
            ring[at + a] = new[order[R[i, a]]]
    return ids, offsets, ring


@njit(cache=True)
def compact_level(R, rlen, active):
    """The active points, and their rings as CSR renamed to positions among them.

    Returns (ids, offsets, ring); ``ok`` False if a ring refers to an inactive point.
    """
    n = R.shape[0]
    rank = np.full(n, -1, np.int64)
    m = 0
    total = 0
    for p in range(n):
        if active[p]:
            rank[p] = m
            m += 1
            total += rlen[p]
    ids = np.empty(m, np.int64)
    offsets = np.zeros(m + 1, np.int64)
    ring = np.empty(total, np.int64)
    ok = True
    j = 0
    at = 0
    for p in range(n):
        if not active[p]:
            continue
        ids[j] = p
        for a in range(rlen[p]):
            r = rank[R[p, a]]
            if r < 0:
                ok = False
            ring[at] = r
            at += 1
        offsets[j + 1] = at
        j += 1
    return ids, offsets, ring, ok


@njit(cache=True, parallel=True)
def renamed(arr, perm):
    """``perm[arr]`` as int32 (point indices of the logs, from work to input order)."""
    out = np.empty(arr.shape[0], np.int32)
    for i in prange(arr.shape[0]):
        out[i] = perm[arr[i]]
    return out
