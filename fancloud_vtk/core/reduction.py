"""Reduction by entropy (paper section 5) and the levels of detail it gives (section 6).

:func:`reduce` removes the point of lowest entropy again and again; the fans
that contained it are re-formed from the points that remain (locally, from
their own ring and the removed point's ring: no neighbour search), the
entropies of the points around them are recomputed, and a priority queue
(an indexed binary heap in a numba kernel) gives the next point.
:func:`hierarchy` (or ``reduce(..., return_hierarchy=True)``) records every
removal in a :class:`Hierarchy`: the removal order, each removed
point's ring and its position in the local frame of that ring, and the
rings its removal changed, so that any level, coarser or finer, can be
recovered, edited coarse levels refined with their detail, and a region of
interest refined selectively.
"""

from __future__ import annotations

import numbers

import numpy as np

from . import _csr_kernels as CsrK
from . import _heap_kernels as HeapK
from . import _quadric_kernels as QK
from . import _reduction_kernels as RK
from . import _splice_kernels as SK
from ._entropy_kernels import mean_distance
from .entropy import DEFAULT_WEIGHTS, as_colors, as_fan_cloud, check_weights
from .fans import Cancelled, Grid
from .hierarchy import METHODS, MIN_WIDTH, Hierarchy, RoundMarks, level_of, source_arrays
from .model import FanCloud
from .validation import FanCloudInputError

#: the smallest fan cloud a reduction may leave
MIN_POINTS = 4
#: columns of the in-lists (points whose fans contain a point); past that a scan
IN_WIDTH = 32


def target_count(n: int, n_points=None, keep=None) -> int:
    """The number of points to keep, from exactly one of ``n_points`` and ``keep``."""
    if (n_points is None) == (keep is None):
        raise ValueError("give exactly one of n_points (a count) and keep (a fraction in (0, 1])")
    if keep is not None:
        if isinstance(keep, bool) or not isinstance(keep, numbers.Real) or not 0 < keep <= 1:
            raise ValueError(f"keep must be a fraction in (0, 1], got {keep!r}")
        n_points = int(round(float(keep) * n))
    if isinstance(n_points, bool) or not isinstance(n_points, numbers.Integral):
        raise ValueError(f"n_points must be an integer, got {n_points!r}")
    n_points = int(n_points)
    if n_points > n:
        raise ValueError(f"n_points ({n_points}) is larger than the cloud ({n} points)")
    if n_points < MIN_POINTS:
        raise ValueError(
            f"cannot reduce to {n_points} points: a fan cloud needs at least {MIN_POINTS}"
        )
    return n_points


#: the spacing bound's default (:func:`hierarchy`): new fan edges of at most 4 uniform
#: spacings (3 already cost the cube a corner at 30% on one of three samplings)
DEFAULT_MAX_SPACING = 4.0


#: the error guard of the entropy order on a mesh (:func:`hierarchy`): each level of the
#: quadric error lets through at least twice the last one's mean squared distance
DEFAULT_ERROR_STEP = 2.0
#: the guard's first level lets through the stars of this fraction of the removals asked
GUARD_START = 0.5
#: levels in a row that may pass with no point waiting for the guard before it gives up
GUARD_STALL = 3


def _max_edge(max_spacing, n: int, target: int) -> float:
    """The longest new fan edge a removal may make, in mean neighbour distances: the bound
    times the uniform spacing at the target count (inf without a bound)."""
    if isinstance(max_spacing, bool) or not isinstance(max_spacing, numbers.Real):
        raise TypeError(f"max_spacing must be a number, got {max_spacing!r}")
    if not 0.0 <= float(max_spacing) < float("inf"):
        raise ValueError(f"max_spacing must be a number >= 0 (0: no bound), got {max_spacing!r}")
    if max_spacing == 0:
        return float("inf")
    return float(max_spacing) * float(np.sqrt(n / max(target, 1)))


def _error_step(error_step) -> float:
    """``error_step`` checked: 0 (no guard) or a number > 1."""
    if isinstance(error_step, bool) or not isinstance(error_step, numbers.Real):
        raise TypeError(f"error_step must be a number, got {error_step!r}")
    if not (error_step == 0 or 1.0 < float(error_step) < float("inf")):
        raise ValueError(f"error_step must be 0 (no guard) or a number > 1, got {error_step!r}")
    return float(error_step)


def _scale(values, q) -> float:
    """The q-quantile of the finite values, or their mean if that is 0 (1 if all are 0)."""
    v = values[np.isfinite(values)]
    if not len(v):
        return 1.0
    s = float(np.quantile(v, q))
    if s <= 0:
        s = float(v.mean())
    return s if s > 0 else 1.0


def _report(progress, fraction, message):
    if progress is not None and progress(float(fraction), message):
        raise Cancelled("the reduction was cancelled")


def hierarchy(fancloud, n_points=None, *, weights=DEFAULT_WEIGHTS, method="entropy", colors=None,
              exact=False, max_spacing=DEFAULT_MAX_SPACING, removal="auto",
              error_step=DEFAULT_ERROR_STEP, progress=None) -> Hierarchy:
    """The removal hierarchy of a fan cloud or triangle mesh, down to ``n_points``.

    Parameters
    ----------
    fancloud : FanCloud or TriangleMesh
        A fan cloud (its rings are used as they are), or a triangle mesh
        (its vertices' one-rings are the fans).
    n_points : int, optional
        The coarsest level to compute. Default: as far as the removal goes
        (at least 4 points stay).
    weights : sequence of 4 float, default: (1, 1, 50, 0)
        Entropy weights (see :func:`~fancloud_vtk.entropy`).
    method : {'entropy', 'error'}, default: 'entropy'
        ``'entropy'`` removes the point of lowest entropy; ``'error'`` the
        point whose removal changes the surface least (the paper's Figure
        10b). When the removals retriangulate (a triangle mesh's fans, see
        ``removal``) that is a quadric error, as Garland and Heckbert's:
        every point holds the planes of the surface it stands for, and p's
        hole becomes the star from the ring point q that minimises
        ``v_q^T (Q_p + Q_q) v_q`` and keeps the manifold (p collapsed into
        q, which takes p's planes). On fans re-formed from points it is the
        largest distance from the plane of p's ring of p and of the removed
        points it carries (each removed point is carried on by the nearest
        of the fans it was in; the paper's e(r) of section 8, the maximum
        deviation of all descendants).
    colors : None, str or numpy.ndarray, optional
        Colours for the colour term (see :func:`~fancloud_vtk.entropy`).
    exact : bool, default: False
        Remove strictly one point at a time, always the lowest key, from an
        indexed heap (the paper's greedy order). Default: in rounds, each
        taking the lowest keys (1/16 of the points left, lowest first) and
        removing together those whose neighbourhoods do not overlap; the
        same local operations, in parallel and in memory order, several
        times faster (docs/entropy.md).
    max_spacing : float, default: 4.0
        The spacing bound (an addition to the paper): no removal may leave a
        gap. A point is not removed while re-forming a fan without it would
        give that fan an edge longer than ``max_spacing`` times the uniform
        spacing at the target count (the mean distance of the fan
        neighbours times ``sqrt(n / target)``) and longer than the fan's
        longest edge before. The entropy still decides the order, so flat
        parts thin out and features stay dense, within the bound.
        ``0``: no bound (the paper's reduction).
    removal : {'auto', 'retriangulate', 'reform'}, default: 'auto'
        How a removal mends the fans around the removed point.
        ``'reform'`` (the paper): every fan that held it is re-formed from
        the points that remain, each on its own. ``'retriangulate'`` (a
        departure from the paper, for fans that are the one-rings of a
        2-manifold mesh): the point's hole is triangulated once, in its
        tangent plane, and each neighbour's ring is spliced from that
        triangulation, so the rings stay the one-rings of a 2-manifold of
        the same topology; a removal that cannot keep that (a new edge that
        exists already, a folding triangle, a boundary turning inward) is
        refused. ``'auto'``: retriangulate the fan cloud of a triangle mesh
        (``info['source'] == 'triangle mesh'``), re-form fans built from
        points.
    error_step : float, default: 2.0
        The error guard of ``method='entropy'`` on retriangulated fans (a
        mesh's one-rings; an addition to the paper): the removals go in
        levels of their quadric error (the mean squared distance of the
        cheapest star, see ``method='error'``, from the surface the point
        and its heir stand for). The first level admits about half of the
        removals asked for; when every point left is over the level, the
        next level is ``error_step`` times higher (or the lowest error that
        waits, if higher). Within a level the entropy decides the order, so
        flat parts still thin out first and features stay dense, but no
        removal costs much more error than the target needs. ``0``: no
        guard (the entropy order alone, the paper). Fans re-formed from
        points carry no quadrics and have no guard.
    progress : callable, optional
        ``progress(fraction, message)``; returning True cancels
        (:class:`~fancloud_vtk.Cancelled`).

    Returns
    -------
    Hierarchy

    Raises
    ------
    ValueError
        A cloud of fewer than 4 points; ``n_points`` larger than the cloud
        or below 4; bad weights, method or colours.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, hierarchy
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> h = hierarchy(build_fans(p), 200)
    >>> h.level(500).n_points, h.level(2000).n_points
    (500, 2000)
    """
    fc = as_fan_cloud(fancloud)
    if n_points is None and fc.n_points < MIN_POINTS:
        raise ValueError(f"cannot build a hierarchy of {fc.n_points} points: a fan cloud needs "
                         f"at least {MIN_POINTS}")
    target = MIN_POINTS if n_points is None else target_count(fc.n_points, n_points, None)
    return _run(fc, target, n_points is not None, weights, method, colors, exact, progress,
                logs=True, max_spacing=max_spacing, removal=removal, error_step=error_step)


#: how a removal mends the fans around it (see :func:`hierarchy`)
REMOVALS = ("auto", "retriangulate", "reform")


def splices(fc: FanCloud, removal) -> bool:
    """Whether removals from ``fc`` retriangulate (``removal``: one of :data:`REMOVALS`)."""
    if removal not in REMOVALS:
        raise ValueError(f"removal must be one of {', '.join(map(repr, REMOVALS))}, "
                         f"got {removal!r}")
    if removal == "auto":
        return fc.info.get("source") == "triangle mesh"
    return removal == "retriangulate"


def _run(fc: FanCloud, target: int, strict: bool, weights, method, colors, exact, progress,
         logs: bool, max_spacing=DEFAULT_MAX_SPACING, removal="auto",
         error_step=DEFAULT_ERROR_STEP):
    """The reduction of ``fc`` to ``target`` points: its :class:`Hierarchy` (``logs``), or
    without logs (nothing recorded but the result) the reduced fan cloud itself, which is
    the same as the hierarchy's coarsest level."""
    n = fc.n_points
    if method not in METHODS:
        raise ValueError(f"method must be 'entropy' or 'error', got {method!r}")
    w = check_weights(weights)
    # the fold rule guards the entropy order; the quadric error already prices a fold (and
    # refusing folds leaves the quadric collapse only costly removals on real models)
    splice = RK.SPLICE_OFF
    if splices(fc, removal):
        splice = RK.SPLICE_ANY if method == "error" else RK.SPLICE_FOLDS
    max_edge = _max_edge(max_spacing, n, target)
    error_step = _error_step(error_step)
    rgb = as_colors(colors, fc.point_data, n)
    if method == "entropy" and w[3] > 0 and rgb is None:
        raise ValueError(
            "the colour weight a4 is > 0 but the input has no colours "
            "(no RGB/RGBA/Colors point array; pass colors=)"
        )
    dbar = mean_distance(fc.points, fc.offsets, fc.ring)
    if not dbar > 0:
        raise FanCloudInputError("the fans have no neighbours at a distance > 0: nothing to reduce")
    max_edge *= dbar
    _report(progress, 0.0, "reduction: setting up")
    import numba

    # work in a spatially coherent order (the fan grid's cells in Morton order)
    grid = Grid(fc.points)
    perm, rank = grid.order, grid.pos
    pts = np.ascontiguousarray(fc.points[perm])
    nrm = np.ascontiguousarray(fc.normals[perm])
    col = np.ascontiguousarray(rgb[perm]) if rgb is not None else np.zeros((0, 3))
    width = max(MIN_WIDTH, int(fc.fan_sizes.max(initial=0)) + 8)
    R, rlen = CsrK.table_from_csr(fc.offsets, fc.ring, perm, rank, width)
    ropen = np.ascontiguousarray(fc.open[perm])
    active = np.ones(n, bool)
    near = RK.Near(active, np.asarray(grid.lo, np.float64), 1.0 / grid.h, grid.start,
                   grid.table)
    IN, nin, over = RK.build_in_lists(R, rlen, IN_WIDTH, numba.get_num_threads())
    # spliced fans: every point's quadric (_quadric_kernels; the hole's star, and method
    # 'error''s key); method 'error' on re-formed fans: the removed points each remaining
    # point carries (_reduction_kernels)
    quadrics = splice != RK.SPLICE_OFF
    m_carry = n if method == "error" and not quadrics else 0
    head = np.full(m_carry, -1, np.int64)
    nxt = np.full(m_carry, -1, np.int64)
    centre = pts.mean(axis=0) if n else np.zeros(3)
    quad = (QK.initial_quadrics(pts, R, rlen, ropen, centre) if quadrics
            else np.zeros((0, 10)))
    # the entropy order's error guard on spliced fans (error_step > 0): removals go in
    # levels of the quadric error of their stars, the entropy deciding the order within a
    # level; the first level lets about half the removals through
    guarded = method == "entropy" and quadrics and error_step > 0
    guard = np.array([np.inf, 1.0, 0.0])
    with_colour = guarded and w[3] > 0 and rgb is not None
    carried = RK.Carried(head, nxt, quad, centre, guard,
                         np.asarray(col, np.float64) if with_colour else np.zeros((0, 3)))
    if guarded and n > target:
        start = min(1.0, GUARD_START * (n - target) / n)
        ids = np.arange(n)
        g = RK.guard_values(pts, R, rlen, ropen, ids, carried)
        if with_colour:
            # the two parts in units of their own first levels, the colour's weighted by a4
            # against a1
            c = RK.colour_losses(R, rlen, ids, col)
            guard[1] = 1.0 / _scale(g, start)
            guard[2] = (w[3] / max(w[0], 1e-12)) / _scale(c, start)
            g = RK.guard_values(pts, R, rlen, ropen, ids, carried)
        g = g[np.isfinite(g)]
        if len(g):
            guard[0] = float(np.quantile(g, start))
    dist, curv, cc, colt, key = RK.init_state(pts, nrm, col, R, rlen, ropen, np.array(w), dbar,
                                              METHODS[method], carried)
    n_remove = n - target
    # the logs (np.empty: pages that a reduction without logs never writes cost nothing)
    order = np.empty(n_remove, np.int64)
    detail = np.empty((n_remove, 6))
    rem_off = np.zeros(n_remove + 1, np.int64)
    rem_ring = np.empty(8 * n_remove + 16, np.int32)
    rem_open = np.zeros(n_remove, bool)
    log_off = np.zeros(n_remove + 1, np.int64)
    ent_x = np.empty(8 * n_remove + 16, np.int32)
    ent_open = np.empty(8 * n_remove + 16, bool)
    ent_off = np.zeros(8 * n_remove + 17, np.int64)
    ent_ring = np.empty(48 * n_remove + 64, np.int32)
    stamp = np.zeros(n, np.int64)
    counters = np.array([n, 0, 0, 0, 0, 0], np.int64)
    wa = np.array(w)
    cloud = RK.Cloud(pts, nrm, col)
    fans = RK.FanTable(R, rlen, ropen, active)
    inl = RK.InLists(IN, nin, over)
    terms = RK.Terms(dist, curv, cc, colt, key)
    log = _Logs(order, detail, rem_off, rem_open, log_off, rem_ring, ent_x, ent_open, ent_off,
                ent_ring)
    chunk = max(1000, n_remove // 50)

    def run(mode):
        """Removals with the splice mode ``mode`` until the target or until every point
        left is blocked."""
        if not exact:
            _rounds(cloud, wa, dbar, max_edge, mode, near, METHODS[method], fans, inl, terms,
                    counters, n_remove, log, stamp, progress, carried, logs)
            return
        heap, hpos = HeapK.heap_of(key, active)
        while counters[1] < n_remove:
            before = counters[1]
            log.grown(RK.reduce_steps(cloud, wa, dbar, max_edge, mode, near,
                                      METHODS[method], fans, inl, terms, heap,
                                      hpos, counters, chunk, target, log.bundle(), stamp,
                                      carried))
            _report(progress, counters[1] / max(n_remove, 1), "reduction")
            if counters[1] == before:
                break  # every remaining point is blocked

    def unblock(blocked=None):
        """The keys of the points left blocked (or of ``blocked``) computed again (under the
        rules now)."""
        if blocked is None:
            blocked = np.flatnonzero(active & np.isinf(key))
        RK.update_keys(pts, nrm, R, rlen, ropen, dist, curv, cc, colt, key, wa,
                       METHODS[method], dbar, blocked, carried)

    modes = [splice]
    if splice == RK.SPLICE_FOLDS:
        # if every point left would sharpen a fold: on without that rule (the manifold and
        # its topology are still kept)
        modes.append(RK.SPLICE_ANY)
    for i, mode in enumerate(modes):
        if counters[1] >= n_remove:
            break
        if i:
            unblock()
        run(mode)
        stalled = 0
        while guarded and counters[1] < n_remove and stalled < GUARD_STALL:
            # the guard's next level: at least error_step times this one, and at least
            # the lowest value of a point that waits for it
            before = counters[1]
            blocked = np.flatnonzero(active & np.isinf(key))
            g = RK.guard_values(pts, R, rlen, ropen, blocked, carried)
            waiting = g[np.isfinite(g) & (g > guard[0])]
            guard[0] = max(guard[0] * error_step, float(waiting.min()) if len(waiting) else 0.0)
            unblock(blocked[g <= guard[0]])  # the others are still over the level
            run(mode)
            stalled = 0 if len(waiting) and counters[1] > before else stalled + 1
    if guarded and counters[1] < n_remove:
        guard[0] = np.inf  # the last removals without the guard (never seen in the tests)
        unblock()
        run(modes[-1])
    rem_ring, ent_x, ent_open, ent_off, ent_ring = (log.rem_ring, log.ent_x, log.ent_open,
                                                    log.ent_off, log.ent_ring)
    r = int(counters[1])
    if strict and r < n_remove:
        raise FanCloudInputError(
            f"the reduction stopped at {n - r} points: no remaining point can be removed "
            f"without breaking a fan (asked for {target})"
        )
    coarse_open = np.zeros(n, bool)
    coarse_open[perm] = ropen
    if not logs:
        # the coarsest level straight from the table: what Hierarchy.level(target) gives
        ids, offsets, ring = RK.kept_level(R, rlen, active, perm, rank)
        _report(progress, 1.0, "reduction: done")
        pdata, original = source_arrays(fc)
        return level_of(fc.points, fc.normals, pdata, original, fc.rotated, ids, offsets, ring,
                         coarse_open)
    # the coarsest level's fans, and everything renamed back to the input's indices
    coarse_off, coarse_ring = CsrK.csr_from_table(R, rlen, active, perm)
    n_ent = int(counters[2])
    h = Hierarchy(
        source=fc,
        order=perm[order[:r]],
        rem_off=rem_off[: r + 1].copy(),
        rem_ring=RK.renamed(rem_ring[: rem_off[r]], perm),
        rem_open=rem_open[:r].copy(),
        detail=detail[:r].copy(),
        log_off=log_off[: r + 1].copy(),
        ent_x=RK.renamed(ent_x[:n_ent], perm),
        ent_open=ent_open[:n_ent].copy(),
        ent_off=ent_off[: n_ent + 1].copy(),
        ent_ring=RK.renamed(ent_ring[: ent_off[n_ent]], perm),
        coarse_off=coarse_off,
        coarse_ring=coarse_ring,
        coarse_open=coarse_open,
        weights=w,
        method=method,
    )
    _report(progress, 1.0, "reduction: done")
    return h


#: a round of the reduction looks at this fraction of the points left (lowest keys first),
#: and at least ROUND_MIN of them; with quadric keys, which spread over orders of magnitude,
#: at fewer (measured on the cow, bone, airplane and bunny at keep 0.42 to 0.1: 1/16 and 64
#: gave up to 8% more mean Hausdorff distance than one at a time, 1/64 and 16 none)
ROUND_FRACTION = 1 / 16
ROUND_MIN = 64
ROUND_FRACTION_QUADRIC = 1 / 64
ROUND_MIN_QUADRIC = 16


class _Logs:
    """The log arrays of a reduction; the last five grow (:meth:`reserve`, or a kernel that
    returns them grown: :meth:`grown`)."""

    def __init__(self, order, detail, rem_off, rem_open, log_off, rem_ring, ent_x, ent_open,
                 ent_off, ent_ring):
        self.order, self.detail, self.rem_off = order, detail, rem_off
        self.rem_open, self.log_off = rem_open, log_off
        self.rem_ring, self.ent_x, self.ent_open = rem_ring, ent_x, ent_open
        self.ent_off, self.ent_ring = ent_off, ent_ring

    def bundle(self) -> RK.RemovalLog:
        """The arrays as the kernels take them (the current growing arrays)."""
        return RK.RemovalLog(self.order, self.detail, self.rem_off, self.rem_open,
                             self.log_off, self.rem_ring, self.ent_x, self.ent_open,
                             self.ent_off, self.ent_ring)

    def grown(self, arrays) -> None:
        """Take the growing arrays a kernel returned (``rem_ring, ent_x, ent_open, ent_off,
        ent_ring``)."""
        self.rem_ring, self.ent_x, self.ent_open, self.ent_off, self.ent_ring = arrays

    @staticmethod
    def _fit(arr, need):
        if need <= len(arr):
            return arr
        out = np.empty(max(need, 2 * len(arr)), arr.dtype)
        out[: len(arr)] = arr
        return out

    def reserve(self, counters, n_rem, n_ent, n_ent_ring):
        self.rem_ring = self._fit(self.rem_ring, counters[4] + n_rem)
        self.ent_x = self._fit(self.ent_x, counters[2] + n_ent)
        self.ent_open = self._fit(self.ent_open, counters[2] + n_ent)
        self.ent_off = self._fit(self.ent_off, counters[2] + n_ent + 1)
        self.ent_ring = self._fit(self.ent_ring, counters[3] + n_ent_ring)


def _rounds(cloud, w, dbar, max_edge, splice, near, method, fans, inl, terms, counters, n_remove,
            logs, stamp, progress, carried, write_logs=True):
    """The reduction in rounds (see ``_reduction_kernels``): each round accepts, lowest key
    first, the candidates whose neighbourhoods do not overlap, and removes them together.
    ``write_logs`` False: the rounds record nothing (the rare one-at-a-time fallback still
    writes its logs, which are then not used)."""
    import numba

    pts, nrm, col = cloud
    R, rlen, ropen, active = fans
    IN, nin, over = inl
    dist, curv, cc, colt, key = terms
    quadrics = carried.quad.shape[0] > 0 and method == RK.METHOD_ERROR  # quadric keys
    n = len(pts)
    n_chunks = 2 * numba.get_num_threads()
    width = R.shape[1]
    # keys straight from the re-form, unless M_cc (which reads other fans' new terms) counts,
    # or quadrics (the heirs' new quadrics change their rings' keys)
    key_now = not (method == RK.METHOD_ENTROPY and w[2] > 0) and not quadrics
    marks = RoundMarks(n)
    while counters[1] < n_remove:
        want = (max(ROUND_MIN_QUADRIC, int(counters[0] * ROUND_FRACTION_QUADRIC)) if quadrics
                else max(ROUND_MIN, int(counters[0] * ROUND_FRACTION)))
        cands = RK.round_candidates(key, active, want)
        if len(cands) == 0:
            break  # every remaining point is blocked
        acc = RK.accept_batch(cands, R, rlen, IN, nin, over, marks.mark, marks.next_tag())
        if len(acc) == 0:
            # only points with overflowing in-lists left: one at a time
            heap, hpos = HeapK.heap_of(key, active)
            logs.grown(RK.reduce_steps(cloud, w, dbar, max_edge, splice, near, method, fans,
                                       inl,
                                       terms, heap,
                                       hpos,
                                       counters, 1, n - n_remove, logs.bundle(), stamp, carried))
            continue
        aff = nin[acc].astype(np.int64)
        buf_off = np.zeros(len(acc) + 1, np.int64)
        np.cumsum(aff, out=buf_off[1:])
        if write_logs:
            logs.reserve(counters, len(acc) * width, int(buf_off[-1]),
                         int(buf_off[-1]) * width)
        defer = np.zeros(len(acc), bool)
        if splice:  # neighbours in space go one after the other (in later rounds)
            SK.defer_overlaps(pts, R, rlen, acc, near.lo, near.inv_h, defer)
        buf, buf_len, buf_open, buf_terms, ok, frames, heir, cost = RK.reform_batch(
            pts, nrm, col, dbar, R, rlen, ropen, IN, nin, acc, buf_off, n_chunks,
            write_logs, cc, w, key_now, max_edge, splice, near, defer, carried, key, method)
        batch = RK.Batch(acc, buf_off, buf, buf_len, buf_open, buf_terms, ok, frames, heir,
                         cost)
        changed = RK.commit_batch(cloud, fans, inl, terms, batch, key_now,
                                  n_remove - counters[1], counters, logs.bundle(), stamp,
                                  carried, write_logs)
        if quadrics:  # the keys of the changed fans and of the heirs' rings
            counters[5] += 1
            changed = QK.with_rings(R, rlen, active, changed, heir[ok == 1], stamp,
                                    counters[5])
            QK.update_quadric_keys(carried.quad, pts, carried.centre, R, rlen, ropen, key,
                                   changed)
        elif not key_now:
            RK.update_keys(pts, nrm, R, rlen, ropen, dist, curv, cc, colt, key, w, method,
                           dbar, changed, carried)
        _report(progress, counters[1] / max(n_remove, 1), "reduction")


def reduce(fancloud, n_points=None, keep=None, *, weights=DEFAULT_WEIGHTS, method="entropy",
           colors=None, exact=False, max_spacing=DEFAULT_MAX_SPACING, removal="auto",
           error_step=DEFAULT_ERROR_STEP, return_hierarchy=False, progress=None):
    """Reduce a fan cloud (or triangle mesh) to ``n_points`` points by entropy (section 5).

    Repeatedly removes the point of lowest entropy (or, with
    ``method='error'``, the point whose removal changes the surface least),
    re-forms the fans that contained it from the points that remain and
    updates the entropies around it, until exactly ``n_points`` remain.

    Parameters
    ----------
    fancloud : FanCloud or TriangleMesh
        The input; a mesh's one-rings are its fans (the result is a fan
        cloud either way: :func:`~fancloud_vtk.fan_cloud_to_mesh` makes it
        a mesh again).
    n_points : int, optional
        Points to keep (at least 4, at most all).
    keep : float, optional
        Fraction of the points to keep, in (0, 1] (instead of ``n_points``).
    weights : sequence of 4 float, default: (1, 1, 50, 0)
        Entropy weights ``(a1, a2, a3, a4)``: distance, curvature, curvature
        change, colour. (1, 0, 0, 0) gives an almost uniform result.
    method : {'entropy', 'error'}, default: 'entropy'
        What the next removal minimises: the entropy, or the surface change
        (on a triangle mesh the quadric error of collapsing the point into a
        ring point; see :func:`hierarchy`).
    colors : None, str or numpy.ndarray, optional
        Colours for the colour term (default: the input's colour array).
    exact : bool, default: False
        One point at a time from a heap instead of in rounds (see
        :func:`hierarchy`).
    max_spacing : float, default: 4.0
        The spacing bound: no removal leaves a gap wider than this many
        uniform spacings at the target count (see :func:`hierarchy`; 0: no
        bound).
    removal : {'auto', 'retriangulate', 'reform'}, default: 'auto'
        How a removal mends the fans around it: re-formed one by one (the
        paper), or the hole retriangulated once and the rings spliced from
        it, which keeps a mesh's one-rings a 2-manifold of the same topology
        (see :func:`hierarchy`). ``'auto'``: retriangulate the fan cloud of a
        triangle mesh, re-form fans built from points.
    error_step : float, default: 2.0
        The error guard of the entropy order on retriangulated fans: removals
        go in levels of quadric error, each ``error_step`` times the last,
        the entropy deciding within a level (see :func:`hierarchy`; 0: no
        guard).
    return_hierarchy : bool, default: False
        Also return the :class:`Hierarchy` of the removals.
    progress : callable, optional
        ``progress(fraction, message)``; returning True cancels.

    Returns
    -------
    FanCloud or (FanCloud, Hierarchy)
        The kept points with their re-formed fans, normals and point arrays,
        and the point array ``original_id`` (the index of each kept point in
        the input; composed with the input's own ``original_id`` if it has
        one).

    Raises
    ------
    ValueError
        Neither or both of ``n_points`` and ``keep``; ``keep`` outside (0, 1];
        ``n_points`` larger than the cloud or below 4; bad weights or colours.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, reduce
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(5000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> small = reduce(build_fans(p), keep=0.176)
    >>> small.n_points
    880
    >>> bool((small.points == p[small.point_data["original_id"]]).all())
    True
    """
    fc = as_fan_cloud(fancloud)
    target = target_count(fc.n_points, n_points, keep)
    if not return_hierarchy:
        # nothing recorded but the result (the hierarchy's coarsest level)
        return _run(fc, target, True, weights, method, colors, exact, progress, logs=False,
                    max_spacing=max_spacing, removal=removal, error_step=error_step)
    h = _run(fc, target, True, weights, method, colors, exact, progress, logs=True,
             max_spacing=max_spacing, removal=removal, error_step=error_step)
    return h.level(target), h


def laplacian_smooth(fancloud: FanCloud, iterations: int = 1, factor: float = 0.5) -> FanCloud:
    """A copy of the fan cloud with every point moved toward the centroid of its ring.

    ``iterations`` steps of ``p += factor * (mean(ring) - p)`` (the global
    smoothing of the paper's Figure 11); the rings stay, the normals follow
    the rings' planes. Points with an empty ring do not move. The edit of a
    coarse level before :meth:`Hierarchy.level` or :meth:`Hierarchy.selective`
    puts the detail back on it.

    Parameters
    ----------
    fancloud : FanCloud
        The fan cloud to smooth (it is not changed).
    iterations : int, default: 1
        Smoothing steps, >= 0.
    factor : float, default: 0.5
        How far each step moves a point toward its ring's centroid, in (0, 1].

    Returns
    -------
    FanCloud
        The smoothed copy, with the same rings and point arrays.

    Raises
    ------
    TypeError
        ``fancloud`` is not a :class:`~fancloud_vtk.FanCloud`.
    ValueError
        ``iterations`` not a whole number >= 0, or ``factor`` outside (0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, laplacian_smooth
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> noisy = build_fans(p * (1 + 0.01 * rng.normal(size=(2000, 1))))
    >>> smooth = laplacian_smooth(noisy, 3)
    >>> r = np.linalg.norm(smooth.points, axis=1)
    >>> bool(r.std() < np.linalg.norm(noisy.points, axis=1).std())
    True
    """
    if not isinstance(fancloud, FanCloud):
        raise TypeError(f"laplacian_smooth needs a FanCloud, got {type(fancloud).__name__}")
    if isinstance(iterations, bool) or not isinstance(iterations, numbers.Integral) \
            or iterations < 0:
        raise ValueError(f"iterations must be a whole number >= 0, got {iterations!r}")
    if not 0 < factor <= 1:
        raise ValueError(f"factor must be in (0, 1], got {factor!r}")
    out = fancloud.copy()
    sizes = out.fan_sizes
    owner = np.repeat(np.arange(out.n_points), sizes)
    has = sizes > 0
    for _ in range(int(iterations)):
        centroid = np.stack([np.bincount(owner, out.points[out.ring, c], out.n_points)
                             for c in range(3)], axis=1)
        centroid[has] /= sizes[has, None]
        out.points[has] += factor * (centroid[has] - out.points[has])
    if iterations:
        nrm = RK.ring_normals(out.points, out.offsets, out.ring, out.normals)
        out.normals[:] = nrm
    return out
