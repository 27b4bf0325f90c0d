"""Refinement beyond the input resolution (paper section 7).

:func:`refine` inserts points where the entropy is highest: for p of highest
entropy, its fan neighbour q1 of highest entropy and q2 (the higher of q1's
two neighbours in p's fan), the new point r starts at the entropy-weighted
combination of p, q1, q2 and moves along its normal until the mean
curvature of its fan (the cotangent mean curvature normal, Meyer et al.
2003) equals the entropy-weighted mean curvature of p, q1 and q2. Its fan
and the fans it enters are re-formed locally, the entropies around it
updated, and the next insertion taken from a priority queue. The inserted
points go on top of the removal :class:`~fancloud_vtk.Hierarchy` (reversed,
an insertion is a removal), so ``level()`` reaches above the input size
(:func:`refine_hierarchy`). See docs/refinement.md.
"""

from __future__ import annotations

import numbers

import numpy as np

from . import _csr_kernels as CsrK
from . import _reduction_kernels as RK
from . import _refinement_kernels as FK
from . import _ring_kernels as RingK
from ._entropy_kernels import mean_distance
from .entropy import as_colors, as_fan_cloud, check_weights
from .fans import Cancelled, Grid
from .hierarchy import MIN_WIDTH, ORIGINAL_ID, Hierarchy, RoundMarks, stacked
from .model import FanCloud, find_color_array
from .validation import FanCloudInputError

#: refinement's default entropy weights: distance and curvature. The curvature-change term
#: divides the noise of the curvature by the distance, so inserting next to a point raises its
#: entropy instead of lowering it and the insertions would pile up (docs/refinement.md)
REFINE_WEIGHTS = (1.0, 1.0, 0.0, 0.0)
#: a round of the refinement looks at this fraction of the points (highest entropy first)
ROUND_FRACTION = 1 / 16
#: no point is inserted closer to a neighbour than this fraction of the mean fan-neighbour
#: distance the result would have if it were uniform (the curvature terms, divided by the
#: distance, would otherwise call for ever closer points where the normals are noisy)
MIN_GAP = 0.25
#: the most insertions planned together in one round
MAX_ROUND = 16384
#: and at most this many bytes of their re-formed rings (a round's scratch holds up to
#: ``width`` rings of ``width`` entries per insertion, ``width`` the largest fan + 8: a
#: vertex with 1,000 neighbours would otherwise ask for 62 GiB)
ROUND_BYTES = 1 << 28
#: the rings are int32
MAX_POINTS = np.iinfo(np.int32).max


def refine_target(n: int, n_points=None, factor=None) -> int:
    """The number of points after refinement, from exactly one of ``n_points`` and ``factor``."""
    if (n_points is None) == (factor is None):
        raise ValueError("give exactly one of n_points (a count) and factor (> 1)")
    if factor is not None:
        if isinstance(factor, bool) or not isinstance(factor, numbers.Real) \
                or not np.isfinite(factor) or not factor > 1:
            raise ValueError(f"factor must be a number > 1, got {factor!r}")
        target = round(float(factor) * n)
        if target > MAX_POINTS:
            raise ValueError(f"factor {factor!r} asks for {target} points: at most {MAX_POINTS}")
        return int(target)
    if isinstance(n_points, bool) or not isinstance(n_points, numbers.Integral):
        raise ValueError(f"n_points must be an integer, got {n_points!r}")
    if int(n_points) < n:
        raise ValueError(
            f"n_points ({int(n_points)}) is smaller than the cloud ({n} points): refinement "
            "only adds points (reduce() removes them)"
        )
    if int(n_points) > MAX_POINTS:
        raise ValueError(f"n_points ({int(n_points)}) is more than the {MAX_POINTS} supported")
    return int(n_points)


def _report(progress, fraction, message):
    if progress is not None and progress(float(fraction), message):
        raise Cancelled("the refinement was cancelled")


class _Log:
    """The growing record of the insertions (CSR rings; parents and weights)."""

    def __init__(self, m: int, width: int):
        self.par = np.zeros((m, 3), np.int64)
        self.wts = np.zeros((m, 3))
        self.nx_per = np.zeros(m, np.int64)
        self.rr = np.empty(8 * m + 16, np.int32)
        self.rr_off = np.zeros(m + 1, np.int64)
        self.ex = np.empty(8 * m + 16, np.int32)
        self.ex_open = np.empty(8 * m + 16, bool)
        self.ex_off = np.zeros(8 * m + 17, np.int64)
        self.er = np.empty(48 * m + 64, np.int32)
        #: [ring entries, fans, fan entries, insertions]
        self.counters = np.zeros(4, np.int64)

    def arrays_in(self):
        """The growing arrays as the kernels take them."""
        return self.rr, self.rr_off, self.ex, self.ex_open, self.ex_off, self.er

    def bundle(self) -> FK.InsertLog:
        """The record as the one-at-a-time kernel takes it."""
        return FK.InsertLog(self.par, self.wts, self.nx_per, *self.arrays_in())

    def set(self, arrays):
        self.rr, self.ex, self.ex_open, self.ex_off, self.er = arrays


def _insert(fc: FanCloud, target: int, w, rgb, dbar, move, exact, progress, rings, seq,
            strict=False):
    """Run the insertions; returns the arrays of the refined cloud and the log (with the
    rings a hierarchy needs if ``rings``; the exact mode always logs them). ``seq``: the
    points in an order to compute their first entropies in (space order is faster)."""
    n0 = fc.n_points
    m = target - n0
    width = max(MIN_WIDTH, int(fc.fan_sizes.max(initial=0)) + 8)
    round_cap = 0 if exact else max(1, min(MAX_ROUND, max(64, m), ROUND_BYTES // (4 * width**2)))
    n_alloc = target + round_cap
    pts = np.zeros((n_alloc, 3))
    pts[:n0] = fc.points
    nrm = np.zeros((n_alloc, 3))
    nrm[:n0] = fc.normals
    col = np.zeros((n_alloc, 3)) if rgb is not None else np.zeros((0, 3))
    if rgb is not None:
        col[:n0] = rgb
    none = np.zeros(0, np.int64)
    R = np.zeros((n_alloc, width), np.int32)
    R0, rlen0 = CsrK.table_from_csr(fc.offsets, fc.ring, none, none, width)
    R[:n0] = R0
    rlen = np.zeros(n_alloc, np.int64)
    rlen[:n0] = rlen0
    ropen = np.zeros(n_alloc, bool)
    ropen[:n0] = fc.open
    dist = np.zeros(n_alloc)
    curv = np.zeros(n_alloc)
    cc = np.zeros(n_alloc)
    colt = np.zeros(n_alloc)
    M = np.zeros(n_alloc)
    wa = np.array(w)
    # the finest spacing allowed: a quarter of the mean spacing the target count would have
    gap = MIN_GAP * dbar * np.sqrt(n0 / target)
    FK.update_entropy(pts, nrm, col, R, rlen, dist, curv, cc, colt, M, wa, dbar, seq)
    blocked = np.zeros(n_alloc, bool)
    log = _Log(m, width)
    cloud = RK.Cloud(pts, nrm, col)
    rings = FK.Rings(R, rlen, ropen)
    terms = FK.Terms(dist, curv, cc, colt, M)
    n_cur = n0
    if exact:
        chunk = max(1000, m // 50)
        while n_cur < target:
            before = n_cur
            out = FK.refine_steps(cloud, rings, terms, wa, dbar, move, gap, strict, n_cur,
                                  min(target, n_cur + chunk), log.bundle(), log.counters, blocked)
            n_cur = int(out[0])
            log.set(out[1:])
            _report(progress, (n_cur - n0) / max(m, 1), "refinement")
            if n_cur == before:
                break
    else:
        import numba

        n_chunks = 2 * numba.get_num_threads()
        marks = RoundMarks(n_alloc)
        stamp = np.zeros(n_alloc, np.int64)
        buf = _Buffers(round_cap, width)
        no_cc = not wa[2] > 0.0
        tag = 0
        while n_cur < target:
            want = max(64, int(n_cur * ROUND_FRACTION))
            cands = FK.round_candidates(M, rlen, ropen, blocked, n_cur, want)
            if len(cands) == 0:
                break
            n_acc = FK.round_accept(cands, R, rlen, M, marks.mark, marks.next_tag(),
                                    min(round_cap, target - n_cur), buf.acc, buf.pq)
            acc, pq = buf.acc[:n_acc], buf.pq[:n_acc]
            b = buf.view(n_acc)
            FK.plan_batch(pts, nrm, col, R, rlen, ropen, M, acc, pq, target, move, gap, strict,
                          n_chunks, dist, curv, colt, dbar, *b)
            ok = b[1] > 0
            blocked[acc[~ok]] = True
            n_ok = int(ok.sum())
            final = np.full(n_acc, -1, np.int64)
            final[ok] = n_cur + np.arange(n_ok)
            plans = FK.Plans(*b)
            _, _, xlist, _, _, _, n_xs, par, wts = plans
            FK.commit_batch(cloud, rings, target, final, plans, terms, wa, blocked)
            log.set(FK.log_batch(R, rlen, ropen, final, xlist, n_xs, par, wts, log.par, log.wts,
                                 log.nx_per, n0, *log.arrays_in(), log.counters, rings))
            n_cur += n_ok
            if not no_cc:
                tag += 1
                FK.update_cc(pts, R, rlen, dist, curv, cc, colt, M, wa, dbar,
                             FK.changed_of(final, xlist, n_xs, stamp, tag))
            _report(progress, (n_cur - n0) / max(m, 1), "refinement")
    if n_cur < target:
        why = (f"the refinement stopped at {n_cur} points (asked for {target}): every closed "
               "fan left refused its insertion (a new point would be closer to a neighbour "
               f"than {MIN_GAP} of the mean spacing, or its fan would not change p's")
        if move:
            why += (f"; or the parents' normals are more than {FK.SHARP_ANGLE:g} degrees apart, "
                    "at a sharp edge or corner, where the mean-curvature move does not apply: "
                    "move=False inserts there, or refine a finer sampling")
        raise FanCloudInputError(why + ")")
    return pts[:target], nrm[:target], R[:target], rlen[:target], ropen[:target], log


class _Buffers:
    """Per-round scratch of the planned insertions."""

    def __init__(self, cap: int, width: int):
        self.acc = np.empty(cap, np.int64)
        self.pq = np.empty((cap, 2), np.int64)
        self.ring_r = np.empty((cap, width), np.int32)
        self.ring_h = np.empty(cap, np.int64)
        self.xlist = np.empty((cap, width), np.int64)
        self.xrings = np.empty((cap, width, width), np.int32)
        self.xlen = np.empty((cap, width), np.int64)
        self.xopen = np.empty((cap, width), bool)
        self.n_xs = np.empty(cap, np.int64)
        self.par = np.empty((cap, 3), np.int64)
        self.wts = np.empty((cap, 3))

    def view(self, k: int):
        return (self.ring_r[:k], self.ring_h[:k], self.xlist[:k], self.xrings[:k],
                self.xlen[:k], self.xopen[:k], self.n_xs[:k], self.par[:k], self.wts[:k])


def _point_data(point_data: dict, n0: int, par: np.ndarray, wts: np.ndarray,
                color_name=None) -> dict:
    """The input's point arrays extended to the inserted points.

    Float arrays and the colour array (``color_name``, default: the one of
    the usual names) are the parents' weighted combination (a uint8 colour
    rounded); other arrays (integers, labels, bools) take p's value;
    ``original_id`` is -1 (no input point).
    """
    m = len(par)
    if color_name is None:
        color_name = find_color_array(point_data)
    out = {}
    for key, v in point_data.items():
        v = np.asarray(v)
        if key == ORIGINAL_ID:
            out[key] = np.concatenate([v.astype(np.int64), np.full(m, -1, np.int64)])
            continue
        full = np.empty((n0 + m,) + v.shape[1:], v.dtype)
        full[:n0] = v
        if v.dtype.kind == "f" or (key == color_name and v.dtype.kind in "iu"):
            vals = np.zeros((n0 + m, int(np.prod(v.shape[1:], dtype=np.int64))))
            vals[:n0] = v.reshape(n0, -1)
            FK.interpolate(vals, n0, par, wts)
            new = vals[n0:].reshape((m,) + v.shape[1:])
            if v.dtype.kind in "iu":
                info = np.iinfo(v.dtype)
                new = np.clip(np.rint(new), info.min, info.max)
            full[n0:] = new
        else:
            # the value of p, which may be an inserted point itself: in insertion order
            src = par[:, 0].copy()
            for j in range(m):
                s = src[j]
                while s >= n0:
                    s = src[s - n0]
                src[j] = s
            full[n0:] = v[src]
        out[key] = full
    return out


def refine(fancloud, n_points=None, factor=None, *, weights=REFINE_WEIGHTS, colors=None,
           move=True, exact=False, return_hierarchy=False, progress=None):
    """Refine a fan cloud beyond its resolution: insert points by entropy (section 7).

    Again and again, at p of highest entropy: q1 is p's fan neighbour of
    highest entropy and q2 the higher of q1's two neighbours in p's fan;
    the new point r is ``(M(p) p + M(q1) q1 + M(q2) q2) / (M(p) + M(q1) +
    M(q2))`` moved along its normal until the cotangent mean curvature of
    its fan equals the same weighted combination of p's, q1's and q2's
    (docs/refinement.md). r's fan and the fans it enters are re-formed
    locally (local Delaunay rings, no neighbour search), their entropies
    updated, and the next p taken from the top. The fan cloud of a triangle
    mesh keeps its one-rings: each insertion splices r into its ring points'
    rings only where they all stay the one-rings of one mesh, so the result
    has the input's topology and boundary (docs/refinement.md).

    Parameters
    ----------
    fancloud : FanCloud or TriangleMesh
        The input; it needs closed fans (insertions happen only at points
        with a closed fan).
    n_points : int, optional
        Points of the result (at least the input's).
    factor : float, optional
        Instead of ``n_points``: the result has ``round(factor * n)`` points;
        > 1.
    weights : sequence of 4 float, default: (1, 1, 0, 0)
        Entropy weights (see :func:`~fancloud_vtk.entropy`); they decide
        where points go and how the parents are weighted. The default has
        no curvature-change term: it divides the curvature's noise by the
        distance, so an insertion next to a point would raise that point's
        entropy instead of lowering it, and the insertions would pile up
        (docs/refinement.md).
    colors : None, str or numpy.ndarray, optional
        Colours for the colour term (default: the input's colour array of
        the usual names, RGB, RGBA, Colors, ...). A name also makes that
        point array the colour array of the result (combined like floats,
        rounded if it is integer).
    move : bool, default: True
        Move the new points along their normals by the mean curvature.
        False leaves them at the weighted combination (inside the triangle
        p q1 q2, so on the chord: for comparison).
    exact : bool, default: False
        One insertion at a time from an indexed heap (the paper's order).
        Default: in rounds, each inserting together the highest-entropy
        points whose neighbourhoods do not overlap (the same local
        operations, in parallel).
    return_hierarchy : bool, default: False
        Also return the :class:`~fancloud_vtk.Hierarchy` whose levels go
        from the input (its coarsest) to the result (its finest).
    progress : callable, optional
        ``progress(fraction, message)``; returning True cancels.

    Returns
    -------
    FanCloud or (FanCloud, Hierarchy)
        The input's points (unchanged, first) and the inserted ones after
        them. Point arrays come along: floats (and the colour array, rounded
        if it is integer) are the parents' entropy-weighted combination;
        integer, label and bool arrays take p's value; ``original_id`` is
        the input point's index (or the input's own ``original_id``) and
        -1 for inserted points.

    Raises
    ------
    ValueError
        Neither or both of ``n_points`` and ``factor``; ``factor <= 1``;
        ``n_points`` below the cloud's size; bad weights or colours; a
        fan cloud with no closed fan; a refinement that gets stuck.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, refine
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> fine = refine(build_fans(p), factor=2)
    >>> fine.n_points
    4000
    >>> r = np.linalg.norm(fine.points[2000:], axis=1)
    >>> bool(abs(r - 1).max() < 0.01)
    True
    """
    fc = as_fan_cloud(fancloud)
    n0 = fc.n_points
    target = refine_target(n0, n_points, factor)
    w = check_weights(weights)
    rgb = as_colors(colors, fc.point_data, n0)
    if w[3] > 0 and rgb is None:
        raise ValueError(
            "the colour weight a4 is > 0 but the input has no colours "
            "(no RGB/RGBA/Colors point array; pass colors=)"
        )
    closed = (~fc.open) & (fc.fan_sizes >= 3)
    if not closed.any():
        raise FanCloudInputError(
            "the fan cloud has no closed fans: refinement inserts points inside closed fans "
            "(build the fans with boundaries off, or refine a surface with an interior)"
        )
    dbar = mean_distance(fc.points, fc.offsets, fc.ring)
    if not dbar > 0:
        raise FanCloudInputError("the fans have no neighbours at a distance > 0: nothing to refine")
    _report(progress, 0.0, "refinement: setting up")
    seq = Grid(fc.points).order  # a spatial order to work in (the fan grid's)
    # the one-rings of a mesh agree already; their local Delaunay rings need not (a mesh far
    # from Delaunay, as a low-poly model), so a mesh keeps its rings and its insertions keep
    # them agreeing (strict)
    strict = fc.info.get("source") == "triangle mesh"

    def insert(strict):
        work = fc if strict else _delaunay(fc, seq)
        return work, _insert(work, target, w, rgb, dbar, bool(move), bool(exact), progress,
                             bool(return_hierarchy), seq, strict)

    try:
        work, (pts, nrm, R, rlen, ropen, log) = insert(strict)
    except FanCloudInputError as exc:
        if not strict:
            raise
        # too few insertions keep the rings agreeing (fans of very thin triangles, as around
        # a vertex of valence 2000): the local Delaunay rings, as for fans built from points
        # (if they stop too, their error is the one to raise)
        import warnings

        from .mesh import DoubtfulMeshWarning

        strict = False
        work, (pts, nrm, R, rlen, ropen, log) = insert(strict)
        warnings.warn(DoubtfulMeshWarning(
            f"refining this triangle mesh while keeping its one-rings stopped early ({exc}); "
            "refined from local Delaunay rings instead, which need not agree: the mesh of the "
            "result may differ from the input's topology"), stacklevel=2)
    m = target - n0
    ids, offsets, ring, ok = RK.compact_level(R, rlen, np.ones(target, bool))
    if not ok:
        raise RuntimeError("internal error: a refined fan refers to a point that is not there")
    par, wts = log.par, log.wts
    pdata = _point_data(fc.point_data, n0, par, wts, colors if isinstance(colors, str) else None)
    if ORIGINAL_ID not in pdata:
        pdata[ORIGINAL_ID] = np.concatenate([np.arange(n0, dtype=np.int64),
                                             np.full(m, -1, np.int64)])
    rotated = np.concatenate([fc.rotated, np.zeros(m, bool)])
    out = FanCloud(np.ascontiguousarray(pts), offsets, ring, np.ascontiguousarray(nrm), ropen,
                   rotated, pdata, {"refined_from": n0})
    if strict:  # still the one-rings of a mesh (a further reduction or refinement keeps them)
        out.info["source"] = "triangle mesh"
    _report(progress, 1.0, "refinement: done")
    if not return_hierarchy:
        return out
    return out, _hierarchy(fc, work, _changed_rings(fc, work), out, log, w)


def refine_hierarchy(hierarchy: Hierarchy, n_points=None, factor=None, **kwargs) -> Hierarchy:
    """A hierarchy with refined levels above its finest (paper section 7).

    The finest level of ``hierarchy`` is refined by :func:`refine` (same
    parameters) and the insertions go on top: the new hierarchy's
    ``level(m)`` reaches from ``hierarchy.n_min`` up to the refined count,
    and its levels up to the old ``hierarchy.n_points`` are those of
    ``hierarchy``, which is not changed.

    Parameters
    ----------
    hierarchy : Hierarchy
        The levels to build on (from :func:`~fancloud_vtk.hierarchy`,
        ``reduce(..., return_hierarchy=True)`` or this function).
    n_points : int, optional
        Points of the new finest level (at least ``hierarchy.n_points``).
    factor : float, optional
        Instead of ``n_points``: ``round(factor * hierarchy.n_points)``
        points; > 1.
    **kwargs
        The other parameters of :func:`refine` (``weights``, ``colors``,
        ``move``, ``exact``, ``progress``); not ``return_hierarchy``.

    Returns
    -------
    Hierarchy
        From ``hierarchy.n_min`` to the refined count; inserted points have
        ``original_id`` -1.

    Raises
    ------
    TypeError
        ``hierarchy`` is not a :class:`~fancloud_vtk.Hierarchy`, or
        ``return_hierarchy`` is given.
    ValueError
        As :func:`refine`.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, hierarchy, refine_hierarchy
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> h = refine_hierarchy(hierarchy(build_fans(p), 500), factor=2)
    >>> h.n_min, h.n_points, h.level(3000).n_points
    (500, 4000, 3000)
    """
    if not isinstance(hierarchy, Hierarchy):
        raise TypeError(f"refine_hierarchy needs a Hierarchy, got {type(hierarchy).__name__} "
                        "(refine() refines a fan cloud or a mesh)")
    if "return_hierarchy" in kwargs:
        raise TypeError("refine_hierarchy always returns a Hierarchy (no return_hierarchy=)")
    _, upper = refine(hierarchy.level(hierarchy.n_points), n_points, factor,
                      return_hierarchy=True, **kwargs)
    return stacked(upper, hierarchy)


def _delaunay(fc: FanCloud, seq) -> FanCloud:
    """The fan cloud with every fan replaced by its local Delaunay ring (as the mesh does): an
    inserted point must split one triangle of the fans around it, so they must agree
    (docs/refinement.md). ``seq``: the points in a spatial order (faster; same rings)."""
    import numba


    width = max(MIN_WIDTH, int(fc.fan_sizes.max(initial=0)))
    counts, table = RingK.delaunay_rings(fc.points, fc.normals, fc.offsets, fc.ring, fc.open, width,
                                      2 * numba.get_num_threads(), seq, RingK.STEEP)
    offsets, ring = RingK.compact_rings(counts, table)
    return FanCloud(fc.points, offsets, ring, fc.normals, fc.open, fc.rotated, fc.point_data)


def _changed_rings(fc: FanCloud, work: FanCloud) -> np.ndarray:
    """The points whose rings :func:`_delaunay` changed."""
    offsets, ring = work.offsets, work.ring
    sizes = np.diff(offsets)
    same = sizes == fc.fan_sizes
    # compare the rings entry by entry where the sizes agree
    own = np.repeat(same, sizes)
    owner = np.repeat(np.arange(fc.n_points), sizes)[own]
    old_own = np.repeat(same, fc.fan_sizes)
    diff = ring[own] != fc.ring[old_own]
    same[np.unique(owner[diff])] = False
    return np.flatnonzero(~same)


def _hierarchy(fc: FanCloud, work: FanCloud, changed, out: FanCloud, log: _Log, w) -> Hierarchy:
    """The levels from the input (coarsest) to the refined cloud: the insertions reversed.

    The first insertion's log also carries the Delaunay rings of the points
    whose fans :func:`_delaunay` changed, before its own (undo applies them
    in order), so the input level keeps the input's rings exactly.
    """
    n0, n = fc.n_points, out.n_points
    m = n - n0
    c = log.counters
    rr, rr_off = log.rr[: c[0]], log.rr_off
    ex, ex_open, ex_off, er = log.ex[: c[1]], log.ex_open[: c[1]], log.ex_off[: c[1] + 1], \
        log.er[: c[2]]
    if m and len(changed):
        # prepend the Delaunay rings as log entries of insertion 0
        d_sizes = work.fan_sizes[changed]
        d_off = np.zeros(len(changed) + 1, np.int64)
        np.cumsum(d_sizes, out=d_off[1:])
        _, d_ring = _reversed_csr(work.offsets, work.ring, changed)
        ex = np.concatenate([changed.astype(ex.dtype), ex])
        ex_open = np.concatenate([work.open[changed], ex_open])
        er = np.concatenate([d_ring.astype(er.dtype), er])
        ex_off = np.concatenate([d_off, ex_off[1:] + d_off[-1]])
        log.nx_per = log.nx_per.copy()
        log.nx_per[0] += len(changed)
    # which log entries (re-formed fans) belong to insertion j: per[j]:per[j + 1]
    per = np.zeros(m + 1, np.int64)
    np.cumsum(log.nx_per[:m], out=per[1:])
    detail = FK.insertion_detail(out.points, out.normals, n0, rr, rr_off)
    rev = np.arange(m - 1, -1, -1)
    rem_off, rem_ring = _reversed_csr(rr_off, rr, rev)
    # log entries reversed insertion by insertion (each insertion's entries keep their order)
    ent_idx = np.concatenate([np.arange(per[j], per[j + 1]) for j in rev]) if m else \
        np.zeros(0, np.int64)
    log_off = np.zeros(m + 1, np.int64)
    np.cumsum((per[1:] - per[:-1])[rev], out=log_off[1:])
    ent_off, ent_ring = _reversed_csr(ex_off, er, ent_idx)
    coarse_off = np.concatenate([fc.offsets, np.full(m, fc.offsets[-1], np.int64)])
    return Hierarchy(
        source=out, order=n0 + rev, rem_off=rem_off, rem_ring=rem_ring,
        rem_open=np.zeros(m, bool), detail=detail[rev], log_off=log_off, ent_x=ex[ent_idx],
        ent_open=ex_open[ent_idx], ent_off=ent_off, ent_ring=ent_ring, coarse_off=coarse_off,
        coarse_ring=fc.ring, coarse_open=np.concatenate([fc.open, np.zeros(m, bool)]),
        weights=w, method="entropy")


def _reversed_csr(off, vals, idx):
    """CSR rows ``idx`` of (off, vals), in that order."""
    sizes = (off[1:] - off[:-1])[idx]
    new_off = np.zeros(len(idx) + 1, np.int64)
    np.cumsum(sizes, out=new_off[1:])
    if len(idx) == 0:
        return new_off, vals[:0].copy()
    starts = off[idx]
    pos = np.arange(new_off[-1]) - np.repeat(new_off[:-1], sizes) + np.repeat(starts, sizes)
    return new_off, vals[pos]
