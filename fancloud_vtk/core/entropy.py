"""Entropy of the points of a fan cloud or a triangle mesh (paper section 5).

For a point p with fan neighbours q_1..q_k (distances d_j, unit normals n,
n_j, colours c, c_j):

* ``M_dist = (1/k) sum d_j``
* ``M_curv = (1/k) sum |n_j - n| / d_j``
* ``M_cc   = (1/k) sum |M_curv(q_j) - M_curv(p)| / d_j``
* ``M_col  = (1/k) sum |c_j - c| / d_j``
* ``M = a1 M_dist + a2 M_curv + a3 M_cc + a4 M_col``

made scale-invariant with the mean neighbour distance ``dbar``: ``M_dist``
divided by ``dbar``, ``M_curv`` and ``M_col`` multiplied by ``dbar``,
``M_cc`` by ``dbar**2`` (see ``docs/entropy.md``). On a triangle mesh a
vertex's one-ring is its fan (:func:`fan_cloud_of_mesh`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import _entropy_kernels as EK
from .model import FanCloud, find_color_array
from .validation import FanCloudInputError, as_normals, as_points

#: the paper's weights for shape features (Figure 9b)
DEFAULT_WEIGHTS = (1.0, 1.0, 50.0, 0.0)


@dataclass(eq=False)
class Entropy:
    """The entropy of every point and its four terms (all scale-invariant).

    Attributes
    ----------
    total : numpy.ndarray
        ``(n,)`` ``M = a1 dist + a2 curv + a3 cc + a4 col``.
    dist, curv, cc, col : numpy.ndarray
        ``(n,)`` the terms ``M_dist``, ``M_curv``, ``M_cc``, ``M_col`` on
        their own (``col`` is 0 without colours).
    weights : tuple of float
        ``(a1, a2, a3, a4)``.
    mean_distance : float
        ``dbar``, the mean distance of a point to its fan neighbours.
    """

    total: np.ndarray
    dist: np.ndarray
    curv: np.ndarray
    cc: np.ndarray
    col: np.ndarray
    weights: tuple
    mean_distance: float

    def as_dict(self) -> dict[str, np.ndarray]:
        """Point arrays by name: ``entropy``, ``entropy_dist``, ``_curv``, ``_cc``, ``_col``."""
        return {
            "entropy": self.total,
            "entropy_dist": self.dist,
            "entropy_curv": self.curv,
            "entropy_cc": self.cc,
            "entropy_col": self.col,
        }


def check_weights(weights) -> tuple[float, float, float, float]:
    """``(a1, a2, a3, a4)`` as floats: four finite, non-negative numbers, not all 0."""
    try:
        w = np.asarray(weights, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"weights must be four numbers (a1, a2, a3, a4), got {weights!r}") from exc
    if w.shape != (4,):
        raise ValueError(
            f"weights must be four numbers (a1, a2, a3, a4) for distance, curvature, "
            f"curvature change and colour, got {w.size} ({weights!r})"
        )
    if not np.isfinite(w).all() or (w < 0).any():
        raise ValueError(f"weights must be finite and non-negative, got {tuple(w.tolist())}")
    if not (w > 0).any():
        raise ValueError("weights must not all be 0")
    return tuple(float(x) for x in w)


def as_colors(colors, point_data: dict, n: int) -> np.ndarray | None:
    """RGB colours as an ``(n, 3)`` float64 array in [0, 1], or ``None``.

    ``colors``: ``None`` (the point array found by
    :func:`~fancloud_vtk.find_color_array`, if any), the name of a point
    array, or an ``(n, 3)`` / ``(n, 4)`` array, uint8 (0..255) or floats
    (in [0, 1]; alpha is ignored).
    """
    if colors is None:
        name = find_color_array(point_data)
        if name is None:
            return None
        colors = point_data[name]
    elif isinstance(colors, str):
        try:
            colors = point_data[find_color_array(point_data, colors)]
        except KeyError as exc:
            raise ValueError(str(exc.args[0])) from None
    arr = np.asarray(colors)
    if arr.dtype == object or arr.dtype.kind not in "biuf":
        raise ValueError(f"colors must be a numeric (n, 3) or (n, 4) array, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in (3, 4):
        raise ValueError(f"colors must have shape (n, 3) or (n, 4), got {arr.shape}")
    if arr.shape[0] != n:
        raise ValueError(f"colors has {arr.shape[0]} rows, expected {n} (one per point)")
    rgb = np.array(arr[:, :3], dtype=np.float64)
    if arr.dtype.kind in "iu" or (rgb.size and rgb.max() > 1.0 + 1e-9):
        rgb /= 255.0
    if not np.isfinite(rgb).all():
        raise ValueError("colors contain NaN or infinite values")
    return np.ascontiguousarray(rgb)


def entropy(fancloud, weights=DEFAULT_WEIGHTS, colors=None) -> Entropy:
    """The entropy of every point of a fan cloud or triangle mesh (section 5).

    Parameters
    ----------
    fancloud : FanCloud or TriangleMesh
        A fan cloud (from :func:`~fancloud_vtk.build_fans`), or a triangle
        mesh whose vertices' one-rings are the fans.
    weights : sequence of 4 float, default: (1, 1, 50, 0)
        ``(a1, a2, a3, a4)`` of distance, curvature, curvature change and
        colour (the paper uses (1, 0, 0, 0), (1, 1, 50, 0) and (1, 1, 50, 1)).
    colors : None, str or numpy.ndarray, optional
        The colours for ``M_col``: by default the point array named ``RGB``,
        ``RGBA``, ``Colors``, ... if there is one; or a point array's name;
        or an ``(n, 3)``/``(n, 4)`` array (uint8, or floats in [0, 1]).

    Returns
    -------
    Entropy
        ``total`` and the terms ``dist``, ``curv``, ``cc``, ``col``, each
        ``(n,)`` and scale-invariant.

    Raises
    ------
    ValueError
        Weights that are not four non-negative numbers; a colour weight
        without colours; colours of the wrong shape; an empty cloud.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import build_fans, entropy
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> e = entropy(build_fans(p))
    >>> e.total.shape, bool(e.curv.std() < 0.5 * e.curv.mean())
    ((2000,), True)
    """
    fc = as_fan_cloud(fancloud)
    w = check_weights(weights)
    rgb = as_colors(colors, fc.point_data, fc.n_points)
    if w[3] > 0 and rgb is None:
        raise ValueError(
            "the colour weight a4 is > 0 but the input has no colours "
            "(no RGB/RGBA/Colors point array; pass colors=)"
        )
    dbar = EK.mean_distance(fc.points, fc.offsets, fc.ring)
    if not dbar > 0:
        raise FanCloudInputError("the fans have no neighbours at a distance > 0: no entropy")
    col_arr = rgb if rgb is not None else np.zeros((0, 3))
    dist, curv, cc, col = EK.entropy_terms(fc.points, fc.normals, col_arr, fc.offsets, fc.ring,
                                           dbar)
    total = w[0] * dist + w[1] * curv + w[2] * cc + w[3] * col
    return Entropy(total, dist, curv, cc, col, w, float(dbar))


# -- triangle meshes as fan clouds -------------------------------------------------


class UnreferencedVerticesWarning(UserWarning):
    """Vertices of a triangle mesh input that no triangle uses were dropped."""


#: the count of dropped unreferenced vertices: a key of ``FanCloud.info`` and the name of
#: the one-value field array of the filters' outputs
UNREFERENCED_DROPPED = "unreferenced_dropped"

#: the point array that maps the points of a result to those of its input (as for merged
#: duplicates and reductions)
ORIGINAL_ID = "original_id"


class ReferencedMesh(NamedTuple):
    """A triangle mesh without the vertices that no triangle uses (:func:`drop_unreferenced`)."""

    points: np.ndarray  #: ``(n', 3)`` the vertices in triangles, in input order
    triangles: np.ndarray  #: ``(m, 3)`` renumbered to the kept vertices
    normals: np.ndarray | None  #: ``(n', 3)`` the kept vertices' normals, if given
    point_data: dict  #: the kept vertices' rows; ``original_id`` when some were dropped
    dropped: int  #: how many vertices were dropped


def drop_unreferenced(points: np.ndarray, triangles: np.ndarray, normals=None, point_data=None,
                      *, keep_unreferenced: bool = False, stacklevel: int = 2) -> ReferencedMesh:
    """A triangle mesh input without the vertices that no triangle uses.

    Such vertices (stray points of a file, construction points of a CAD
    export, often off the surface) would become fan cloud points without a
    fan, or, when fans are built from the points, fans across the surface.
    Every front reads a triangle mesh input through this function: the
    core (:func:`fan_cloud_of_mesh`), the VTK filters and the accessor
    (``fancloud_vtk.algorithms.convert``) and the ``fancloud`` command.

    The kept vertices stay in input order with their rows of ``normals``
    and ``point_data``. When vertices are dropped, an
    :class:`UnreferencedVerticesWarning` says how many (``stacklevel`` as
    for ``warnings.warn``, counted from the caller of this function) and the
    point array ``original_id`` maps the kept vertices to the input's
    (an input's own ``original_id`` is kept, so a chain of steps maps to
    its first input). With ``keep_unreferenced`` (or nothing to drop) the
    arrays come back as they are.

    ``points`` ``(n, 3)``, ``normals`` ``(n, 3)`` or None and
    ``point_data`` (arrays of ``n`` rows) must be checked already; they are
    never modified. ``triangles`` are checked here (``(m, 3)`` integers in
    ``[0, n)``, else a :class:`~fancloud_vtk.core.mesh_stats.MeshInputError`)
    and returned as a new int64 array; without triangles nothing is dropped.
    """
    from .mesh_stats import as_triangles

    point_data = {} if point_data is None else point_data
    n = len(points)
    tri = as_triangles(triangles, n)
    used = np.zeros(n, bool)
    used[tri.ravel()] = True
    n_kept = int(np.count_nonzero(used))
    if keep_unreferenced or n_kept == n or n_kept == 0:
        return ReferencedMesh(points, tri, normals, point_data, 0)
    keep = np.flatnonzero(used)
    new_id = np.full(n, -1, np.int64)
    new_id[keep] = np.arange(n_kept)
    pdata = {name: arr[keep] for name, arr in point_data.items()}
    pdata.setdefault(ORIGINAL_ID, keep.astype(np.int64))
    warnings.warn(
        f"{n - n_kept} of the mesh's {n} vertices are in no triangle and were dropped "
        f"(the keep_unreferenced option keeps them as plain points); the '{ORIGINAL_ID}' point "
        "array maps the result to the input's vertices",
        UnreferencedVerticesWarning,
        stacklevel=stacklevel + 1,
    )
    return ReferencedMesh(points[keep], new_id[tri],
                          None if normals is None else normals[keep], pdata, n - n_kept)


def as_fan_cloud(data) -> FanCloud:
    """A :class:`FanCloud` as it is, or the fan cloud of a :class:`TriangleMesh`."""
    from .mesh import TriangleMesh

    if isinstance(data, FanCloud):
        data.validate()
        if data.n_points == 0:
            raise ValueError("the fan cloud is empty")
        length = np.einsum("ij,ij->i", data.normals, data.normals)
        if not (length > 0.0).all():
            bad = np.flatnonzero(~(length > 0.0))
            raise FanCloudInputError(
                f"the fan cloud has zero normals at {bad.size} point(s), first at index "
                f"{int(bad[0])}: a fan needs a normal"
            )
        return data
    if isinstance(data, TriangleMesh):
        return fan_cloud_of_mesh(data.points, data.triangles, normals=data.normals,
                                 point_data=data.point_data)
    raise TypeError(
        f"expected a FanCloud (from build_fans) or a TriangleMesh, got {type(data).__name__}"
    )


def fan_cloud_of_mesh(points, triangles, *, normals=None, point_data=None,
                      keep_unreferenced: bool = False) -> FanCloud:
    """The fan cloud of a triangle mesh: every vertex's one-ring is its fan.

    Rings follow the triangles counter-clockwise; a boundary vertex gets an
    open fan. Triangles turned the other way round than their neighbours are
    turned back first (:func:`consistent_orientation`; ``info["triangles_turned"]``
    counts them). The normals are ``normals`` if given (unit vectors, one per
    point), else the area-weighted triangle normals, so they follow the
    mesh's orientation. A vertex whose triangles do not form one
    fan (non-manifold) gets its neighbours sorted by angle around its
    normal (closed). Vertices in no triangle are dropped with an
    :class:`UnreferencedVerticesWarning` (see :func:`drop_unreferenced`),
    or with ``keep_unreferenced`` kept with an empty ring.

    Parameters
    ----------
    points : array_like
        ``(n, 3)`` vertex positions.
    triangles : array_like
        ``(m, 3)`` vertex indices, counter-clockwise around the outside.
    normals : array_like, optional
        ``(n, 3)`` vertex normals (default: from the triangles).
    point_data : dict of str to numpy.ndarray, optional
        Point arrays (``n`` rows each), carried by the fan cloud.
    keep_unreferenced : bool, default: False
        Keep the vertices that no triangle uses, as points with an empty
        ring (default: drop them).

    Returns
    -------
    FanCloud
        The vertices with their one-rings as fans; ``info["source"]`` is
        ``'triangle mesh'``, ``info["unreferenced_dropped"]`` the number of
        vertices dropped (then the point array ``original_id`` maps the
        points to the input's vertices).

    Raises
    ------
    ValueError
        Points that are not ``(n, 3)`` finite numbers, triangles that are
        not ``(m, 3)`` integers in range, or no triangles at all.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk import fan_cloud_of_mesh
    >>> points = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    >>> tetra = fan_cloud_of_mesh(points, [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    >>> tetra.fan_sizes.tolist(), bool(tetra.open.any())
    ([3, 3, 3, 3], False)
    >>> bool(np.all(np.sum(tetra.normals * points, axis=1) > 0))  # outward
    True
    """
    from .validation import check_point_data

    pts = as_points(points)
    n = len(pts)
    pdata = check_point_data(point_data, n)
    if normals is not None:
        normals = as_normals(normals, n)
    pts, tri, normals, pdata, dropped = drop_unreferenced(
        pts, triangles, normals, pdata, keep_unreferenced=keep_unreferenced, stacklevel=3)
    if len(tri) == 0:
        raise ValueError("the mesh has no triangles: no one-rings to take as fans")
    n = len(pts)
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    offsets, ring, is_open, ok = EK.one_rings(np.ascontiguousarray(tri, np.int64), n)
    turned = 0
    if not ok.all():  # a vertex whose triangles are no fan: some may be turned the wrong way
        tri, turned = consistent_orientation(tri, n)
        if turned:
            offsets, ring, is_open, ok = EK.one_rings(np.ascontiguousarray(tri, np.int64), n)
    if normals is None:
        normals = _area_normals(pts, tri)
    if not ok.all():
        offsets, ring, is_open = _sorted_rings(pts, normals, tri, offsets, ring, is_open, ok)
    return FanCloud(pts, offsets, ring, normals, is_open, None, pdata,
                    {"source": "triangle mesh", "triangles": int(len(tri)),
                     "triangles_turned": turned, UNREFERENCED_DROPPED: dropped})


def consistent_orientation(triangles, n: int) -> tuple[np.ndarray, int]:
    """The triangles turned to run the same way round as their neighbours; how many turned.

    Mesh files often hold some faces the other way round (an STL or OBJ export
    of parts, a model mended by hand); each vertex's one-ring then falls apart
    into pieces. Over the edges shared by exactly two triangles, a triangle
    whose shared edge runs the same way as its neighbour's is turned, from one
    triangle of each edge-connected piece (breadth first); of the two ways
    round, each piece keeps the one most of its triangles had. A mesh already
    consistent is returned as it is (the same array). A non-orientable piece
    (a Moebius strip) keeps the conflicts that are left.
    """
    tri = np.asarray(triangles, np.int64)
    m = len(tri)
    if m == 0:
        return tri, 0
    # directed half-edges; an undirected edge of exactly two triangles
    a = tri.ravel()
    b = np.roll(tri, -1, axis=1).ravel()
    face = np.repeat(np.arange(m), 3)
    key = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    k = key[order]
    first = np.ones(len(k), bool)
    first[1:] = k[1:] != k[:-1]
    starts = np.flatnonzero(first)
    counts = np.diff(np.append(starts, len(k)))
    pair = starts[counts == 2]
    e0, e1 = order[pair], order[pair + 1]
    same = a[e0] == a[e1]  # the same direction in both: one of the two must turn
    if not same.any():
        return tri, 0
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    f0, f1 = face[e0], face[e1]
    graph = coo_matrix((np.ones(len(f0)), (f0, f1)), shape=(m, m)).tocsr()
    graph = graph + graph.T
    _, label = connected_components(graph, directed=False)
    # the adjacencies (both ways) sorted by key, with 1 where the two triangles disagree
    adj_key = np.concatenate([f0 * m + f1, f1 * m + f0])
    adj_odd = np.concatenate([same, same])
    srt = np.argsort(adj_key, kind="stable")
    adj_key, adj_odd = adj_key[srt], adj_odd[srt]
    flip = np.zeros(m, bool)
    f = flip.view(np.uint8)
    # only the pieces with a disagreement, each on its own subgraph (a breadth-first
    # search of the whole graph per piece made a mesh of many pieces quadratic)
    members = np.argsort(label, kind="stable")
    bounds = np.searchsorted(label[members], np.arange(label.max() + 2))
    for c in np.unique(label[f0[same]]):
        idx = members[bounds[c]:bounds[c + 1]]  # increasing: its first triangle is the root
        visit, pred = breadth_first_order(graph[idx][:, idx], 0, directed=False)
        visit = idx[visit]
        child = visit[1:]
        par = idx[pred.astype(np.int64)[np.searchsorted(idx, child)]]
        odd = adj_odd[np.searchsorted(adj_key, par * m + child)]
        # in breadth-first order a triangle's predecessor comes first
        for v, u, o in zip(child.tolist(), par.tolist(), odd.tolist(), strict=True):
            f[v] = f[u] ^ o
        if flip[visit].sum() * 2 > len(visit):  # keep the way most of them ran
            flip[visit] = ~flip[visit]
    if not flip.any():
        return tri, 0
    out = tri.copy()
    out[flip] = out[flip][:, ::-1]
    return out, int(flip.sum())


def _area_normals(pts, tri):
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    face_n = np.cross(b - a, c - a)  # length: twice the area
    normals = np.zeros((len(pts), 3))
    for col in range(3):
        np.add.at(normals, tri[:, col], face_n)
    length = np.linalg.norm(normals, axis=1)
    flat = length <= 0
    normals[flat] = (0.0, 0.0, 1.0)
    length[flat] = 1.0
    return normals / length[:, None]


def _sorted_rings(pts, normals, tri, offsets, ring, is_open, ok):
    """Rings of the non-manifold vertices replaced by their neighbours sorted by angle."""
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    edges = np.concatenate([edges, edges[:, ::-1]])
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges = edges[order]
    keep = np.ones(len(edges), bool)
    keep[1:] = np.any(edges[1:] != edges[:-1], axis=1)
    edges = edges[keep]
    starts = np.searchsorted(edges[:, 0], np.arange(len(pts) + 1))
    rings = [ring[offsets[v]:offsets[v + 1]] for v in range(len(pts))]
    opens = is_open.copy()
    for v in np.flatnonzero(~ok):
        nb = edges[starts[v]:starts[v + 1], 1]
        nrm = normals[v]
        u = np.cross(nrm, [1.0, 0.0, 0.0])
        if np.linalg.norm(u) < 0.5:
            u = np.cross(nrm, [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        w = np.cross(nrm, u)
        d = pts[nb] - pts[v]
        rings[v] = nb[np.argsort(np.arctan2(d @ w, d @ u), kind="stable")]
        opens[v] = False
    sizes = np.array([len(r) for r in rings], np.int64)
    new_off = np.zeros(len(pts) + 1, np.int64)
    np.cumsum(sizes, out=new_off[1:])
    return new_off, np.concatenate(rings).astype(np.int64), opens
