"""The verbs: one array-level function per filter, which every front calls.

``fans``, ``mesh``, ``entropy``, ``reduce``, ``hierarchy``, ``selective``,
``refine`` and ``vdfc`` take a :class:`Source` (the input as arrays) and the
verb's parameter values (keywords of :data:`fancloud_vtk.params.VERB_PARAMS`,
checked and completed with the defaults here) and return a :class:`Result`.
They do, once for every front, what each front would otherwise do itself:

* input-kind dispatch: a fan cloud is used as it is, a triangle mesh gives
  its one-rings as fans (its unreferenced vertices dropped unless
  ``keep_unreferenced``), any other point set gets its fans built with the
  fan parameters (:func:`source_fan_cloud`);
* the amount: ``n_points`` if not 0, else ``keep`` / ``factor``;
* the optional mesh output (``mesh``) of ``reduce`` and ``refine``;
* point data: the input's arrays travel with the fan cloud, and the count of
  dropped unreferenced vertices with the result's ``info``.

The VTK algorithms (:mod:`fancloud_vtk.algorithms`) convert a VTK dataset to a
:class:`Source`, call the verb and convert the result back; the accessor
forwards to the algorithms; the ``fancloud`` command reads a file into a
:class:`Source` and writes the result. Numpy only: no VTK.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fancloud_vtk.params import AMOUNTS, FAN_PARAMS, VERB_PARAMS, check_params

from .entropy import (
    UNREFERENCED_DROPPED,
    Entropy,
    drop_unreferenced,
    fan_cloud_of_mesh,
)
from .entropy import entropy as _entropy
from .fans import Cancelled, build_fans
from .mesh import TriangleMesh, fan_cloud_to_mesh
from .model import FanCloud

#: which kind of input a verb took (the field array ``fancloud_input`` of the VTK outputs)
KIND_FANS, KIND_MESH, KIND_POINTS = "fan cloud", "triangle mesh", "point set"
KIND_HEIGHT_FIELD = "height field"

#: e_max 0 means this fraction of the diagonal of the bounds (``vdfc``)
AUTO_E_MAX = 1e-3


@dataclass
class Source:
    """The input of a verb as arrays.

    Either ``fancloud`` (a fan cloud, used as it is), or ``heights`` (a height
    field for ``vdfc``: ``(heights, spacing, origin)`` with ``point_data`` of
    the grid's shape), or ``points`` with optional ``normals``, ``point_data``
    and ``triangles`` (a triangle mesh when given).
    """

    points: np.ndarray | None = None
    normals: np.ndarray | None = None
    point_data: dict = field(default_factory=dict)
    triangles: np.ndarray | None = None
    fancloud: FanCloud | None = None
    heights: tuple | None = None

    @property
    def kind(self) -> str:
        """Which kind of input: :data:`KIND_FANS`, :data:`KIND_HEIGHT_FIELD`, ... ."""
        if self.fancloud is not None:
            return KIND_FANS
        if self.heights is not None:
            return KIND_HEIGHT_FIELD
        return KIND_POINTS if self.triangles is None else KIND_MESH


@dataclass
class Result:
    """What a verb gives: the input's fan cloud and kind, and the verb's output."""

    kind: str  #: which kind of input (:data:`KIND_FANS`, ...)
    source: FanCloud  #: the input's fan cloud
    fancloud: FanCloud | None = None  #: the output fan cloud (fans, reduce, refine, ...)
    mesh: TriangleMesh | None = None  #: the output mesh (mesh; reduce/refine with ``mesh``)
    entropy: Entropy | None = None  #: the entropy of the source's points (entropy)
    input: Source | None = None  #: the verb's input as it was given

    @property
    def unreferenced_dropped(self) -> int | None:
        """How many vertices of a mesh input no triangle used (None: not a mesh input)."""
        return self.source.info.get(UNREFERENCED_DROPPED)


def check_values(verb: str, values: dict) -> dict:
    """``values`` checked against the verb's table and completed with its defaults."""
    if verb not in VERB_PARAMS:
        raise ValueError(f"unknown verb {verb!r}; known: {sorted(VERB_PARAMS)}")
    return check_params(VERB_PARAMS[verb], values)


def check_amount(verb: str, params: dict) -> None:
    """Refuse ``n_points`` together with ``keep``/``factor`` among keywords a user gave
    (the verb would take ``n_points`` and drop the other silently)."""
    other = AMOUNTS[verb]
    if params.get("n_points") and other in params:
        raise ValueError(f"give n_points or {other}, not both (got n_points="
                         f"{params['n_points']!r} and {other}={params[other]!r})")


def amount(verb: str, values: dict) -> dict:
    """The core's amount keyword: ``{'n_points': n}`` if ``n_points`` is not 0, else the
    fraction (``{'keep': f}`` or ``{'factor': f}``)."""
    if values["n_points"]:
        return {"n_points": values["n_points"]}
    other = AMOUNTS[verb]
    return {other: values[other]}


def _part(progress, lo: float, hi: float):
    """``progress`` mapped to the part ``[lo, hi]`` of the whole (None stays None)."""
    if progress is None:
        return None
    return lambda f, m: progress(lo + (hi - lo) * f, m)


def _ask(progress, fraction: float, message: str, doing: str) -> None:
    """Report ``fraction`` and ``message``; raise :class:`Cancelled` (``doing`` was
    cancelled) when the caller asks to stop."""
    if progress is not None and progress(fraction, message):
        raise Cancelled(f"{doing} was cancelled")


def fan_values(values: dict) -> dict:
    """The fan parameters (the keywords of ``build_fans``) among a verb's values."""
    return {p.name: values[p.name] for p in FAN_PARAMS}


def _colors(values: dict):
    return values["color_array"] or None


def _built_fans(points, normals, point_data, values, progress) -> FanCloud:
    return build_fans(points, normals=normals, point_data=point_data, progress=progress,
                      **fan_values(values))


def source_fan_cloud(source: Source, values: dict, progress=None) -> tuple[FanCloud, str]:
    """The fan cloud of a verb's input and which kind of input it was.

    * a fan cloud: as it is;
    * a triangle mesh: every vertex's one-ring is its fan
      (:func:`~fancloud_vtk.fan_cloud_of_mesh`; the vertices that no triangle
      uses are dropped unless ``keep_unreferenced``; normals with a zero vector
      count as unknown: the mesh's own are taken);
    * any other point set: its fans, built with the fan parameters.
    """
    kind = source.kind
    if kind == KIND_FANS:
        return source.fancloud, kind
    if kind == KIND_HEIGHT_FIELD:
        from .vdfc import terrain_fan_cloud

        heights, spacing, origin = source.heights
        return terrain_fan_cloud(heights, spacing, origin, point_data=source.point_data), kind
    if kind == KIND_POINTS:
        return _built_fans(source.points, source.normals, source.point_data, values,
                           progress), kind
    normals = source.normals
    if normals is not None and not (np.linalg.norm(normals, axis=1) > 0).all():
        normals = None  # "unknown" zero normals: take the mesh's own
    fc = fan_cloud_of_mesh(source.points, source.triangles, normals=normals,
                           point_data=source.point_data,
                           keep_unreferenced=values["keep_unreferenced"])
    return fc, kind


def source_point_fans(source: Source, values: dict, progress=None) -> tuple[FanCloud, str]:
    """The fans built from the points of a verb's input (``fans``, ``mesh``), and its kind.

    Of a fan cloud its points, normals and point data are taken (its rings are
    built anew). Of a triangle mesh only the vertices of its triangles are
    taken, unless ``keep_unreferenced``
    (:func:`~fancloud_vtk.core.entropy.drop_unreferenced`: a warning, the point
    array ``original_id``, the count in ``info["unreferenced_dropped"]``); its
    triangles are not used.
    """
    kind = source.kind
    if kind == KIND_HEIGHT_FIELD:
        return source_fan_cloud(source, values, progress)
    if kind == KIND_FANS:
        fc = source.fancloud
        return _built_fans(fc.points, fc.normals, fc.point_data, values, progress), kind
    if kind == KIND_POINTS:
        return _built_fans(source.points, source.normals, source.point_data, values,
                           progress), kind
    mesh = drop_unreferenced(source.points, source.triangles, source.normals,
                             source.point_data, keep_unreferenced=values["keep_unreferenced"],
                             stacklevel=3)
    fc = _built_fans(mesh.points, mesh.normals, mesh.point_data, values, progress)
    fc.info[UNREFERENCED_DROPPED] = mesh.dropped
    return fc, kind


def mesh_rings(kind: str) -> str:
    """How to mesh a reduced or refined fan cloud: the re-formed fans of a mesh's one-rings
    are consistent already (``'fans'``); those grown from a point set's fans are not
    everywhere (``'delaunay'``). See docs/entropy.md."""
    return "fans" if kind == KIND_MESH else "delaunay"


def _finish(result: Result, values: dict, progress, at: float) -> Result:
    """The optional mesh of the output fan cloud, and the dropped count carried along."""
    dropped = result.unreferenced_dropped
    if dropped is not None:  # the count travels with the result (a .vtp, field arrays)
        result.fancloud.info[UNREFERENCED_DROPPED] = dropped
    if values.get("mesh"):
        _ask(progress, at, "mesh", "meshing")
        result.mesh = fan_cloud_to_mesh(result.fancloud, rings=mesh_rings(result.kind))
    if progress is not None:
        progress(1.0, "done")
    return result


# -- the verbs ----------------------------------------------------------------------


def fans(source: Source, values: dict | None = None, progress=None) -> Result:
    """The fan cloud of the input's points (paper section 3): ``result.fancloud``.

    The fans are built with the fan parameters (of a fan cloud input anew);
    of a triangle mesh only the vertices of its triangles are taken (unless
    ``keep_unreferenced``).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> p = np.random.default_rng(0).normal(size=(500, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> r = verbs.fans(verbs.Source(points=p), {"k": 6})
    >>> r.kind, r.fancloud.n_points
    ('point set', 500)
    """
    values = check_values("fans", values or {})
    fc, kind = source_point_fans(source, values, progress)
    if progress is not None:
        progress(1.0, "done")
    return Result(kind, fc, fancloud=fc, input=source)


def mesh(source: Source, values: dict | None = None, progress=None) -> Result:
    """The triangle mesh of the input's fan cloud (paper section 4): ``result.mesh``.

    A fan cloud's rings are used as they are; of any other input the fans of
    its points are built first (:func:`source_point_fans`).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> p = np.random.default_rng(0).normal(size=(3000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> verbs.mesh(verbs.Source(points=p)).mesh.n_triangles
    5996
    """
    values = check_values("mesh", values or {})
    if source.kind == KIND_FANS:
        fc, kind = source.fancloud, KIND_FANS
    else:
        fc, kind = source_point_fans(source, values, _part(progress, 0.0, 0.5))
    _ask(progress, 0.5, "mesh", "meshing")  # the mesh stage cannot stop midway: ask before
    from fancloud_vtk.params import MESH_PARAMS

    result = fan_cloud_to_mesh(fc, **{p.name: values[p.name] for p in MESH_PARAMS})
    if progress is not None:
        progress(1.0, "done")
    return Result(kind, fc, mesh=result, input=source)


def entropy(source: Source, values: dict | None = None, progress=None) -> Result:
    """The entropy of every point of the input's fan cloud (paper section 5):
    ``result.entropy`` (of ``result.source``).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> p = np.random.default_rng(0).normal(size=(500, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> r = verbs.entropy(verbs.Source(points=p), {"weights": (1, 0, 0, 0)})
    >>> r.entropy.total.shape
    (500,)
    """
    values = check_values("entropy", values or {})
    fc, kind = source_fan_cloud(source, values, _part(progress, 0.0, 0.8))
    ent = _entropy(fc, values["weights"], colors=_colors(values))
    if progress is not None:
        progress(1.0, "done")
    return Result(kind, fc, entropy=ent, input=source)


def _reduce_values(values: dict) -> dict:
    return {"weights": values["weights"], "method": values["method"],
            "colors": _colors(values), "exact": values["exact"],
            "max_spacing": values["max_spacing"], "removal": values["removal"],
            "error_step": values["error_step"]}


def reduce(source: Source, values: dict | None = None, progress=None) -> Result:
    """The input reduced by entropy to ``n_points`` (if not 0) or ``keep`` of its points
    (paper section 5): ``result.fancloud``, and with ``mesh`` also ``result.mesh``.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> p = np.random.default_rng(0).normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> verbs.reduce(verbs.Source(points=p), {"n_points": 500}).fancloud.n_points
    500
    """
    from .reduction import reduce as _reduce

    values = check_values("reduce", values or {})
    fc, kind = source_fan_cloud(source, values, _part(progress, 0.0, 0.3))
    small = _reduce(fc, **amount("reduce", values), **_reduce_values(values),
                    progress=_part(progress, 0.3, 0.9))
    return _finish(Result(kind, fc, fancloud=small, input=source), values, progress, 0.9)


def hierarchy(source: Source, values: dict | None = None, progress=None):
    """The levels of detail of the reduction (paper section 6), down to ``n_points`` (0: as
    far as it goes): a :class:`~fancloud_vtk.Hierarchy` whose attribute
    ``fancloud_input`` is the kind of input.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> p = np.random.default_rng(0).normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> h = verbs.hierarchy(verbs.Source(points=p), {"n_points": 400})
    >>> h.level(400).n_points, h.fancloud_input
    (400, 'point set')
    """
    from .reduction import hierarchy as _hierarchy

    values = check_values("hierarchy", values or {})
    fc, kind = source_fan_cloud(source, values, _part(progress, 0.0, 0.3))
    h = _hierarchy(fc, values["n_points"] or None, **_reduce_values(values),
                   progress=_part(progress, 0.3, 1.0))
    h.fancloud_input = kind
    return h


def region_of(values: dict):
    """The region of interest of the selective refinement's values (a ``(center, radius)``
    sphere or box bounds) for :meth:`~fancloud_vtk.Hierarchy.selective`."""
    if values["region"] == "sphere":
        if not values["region_radius"] > 0:
            raise ValueError("region_radius must be > 0 for a sphere region of interest")
        return values["region_center"], values["region_radius"]
    b = values["region_bounds"]
    if b[0] == b[1] and b[2] == b[3] and b[4] == b[5]:
        raise ValueError(f"region_bounds must be set for a box region of interest "
                         f"(xmin, xmax, ymin, ymax, zmin, zmax), got the single point {b}")
    if b[0] > b[1] or b[2] > b[3] or b[4] > b[5]:
        raise ValueError(f"region_bounds must be (xmin, xmax, ymin, ymax, zmin, zmax) "
                         f"with min <= max, got {b}")
    return np.array(b, np.float64)


def selective(source: Source, values: dict | None = None, progress=None) -> Result:
    """Figure 11: the hierarchy down to ``n_points``/``keep``, its coarsest level smoothed
    ``smooth_iterations`` times, the removed points inside the region reinserted (fans
    built with the fan parameters): ``result.fancloud``.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> p = np.random.default_rng(0).normal(size=(2000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> r = verbs.selective(verbs.Source(points=p), {"keep": 0.2, "region_center": (0, 0, 1),
    ...                                              "region_radius": 0.5})
    >>> 400 < r.fancloud.n_points < 2000
    True
    """
    from .reduction import hierarchy as _hierarchy
    from .reduction import laplacian_smooth, target_count

    values = check_values("selective", values or {})
    region = region_of(values)  # a bad region fails before the fans are built
    fc, kind = source_fan_cloud(source, values, _part(progress, 0.0, 0.3))
    target = target_count(fc.n_points, **amount("selective", values))
    h = _hierarchy(fc, target, **_reduce_values(values), progress=_part(progress, 0.3, 0.9))
    coarse = h.level(target)
    if values["smooth_iterations"]:
        coarse = laplacian_smooth(coarse, values["smooth_iterations"])
    out = h.selective(region, base=coarse, **fan_values(values))
    return _finish(Result(kind, fc, fancloud=out, input=source), values, progress, 1.0)


def refine(source: Source, values: dict | None = None, progress=None) -> Result:
    """The input refined beyond its resolution by entropy to ``n_points`` (if not 0) or
    ``factor`` times its points (paper section 7): ``result.fancloud``, and with ``mesh``
    also ``result.mesh``.

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> p = np.random.default_rng(0).normal(size=(1000, 3))
    >>> p /= np.linalg.norm(p, axis=1)[:, None]
    >>> verbs.refine(verbs.Source(points=p), {"factor": 2}).fancloud.n_points
    2000
    """
    from .refinement import refine as _refine

    values = check_values("refine", values or {})
    fc, kind = source_fan_cloud(source, values, _part(progress, 0.0, 0.3))
    fine = _refine(fc, **amount("refine", values), weights=values["weights"],
                   colors=_colors(values), move=values["move"], exact=values["exact"],
                   progress=_part(progress, 0.3, 0.9))
    return _finish(Result(kind, fc, fancloud=fine, input=source), values, progress, 0.9)


def vdfc(source: Source, values: dict | None = None, progress=None):
    """The view-dependent fan cloud (paper section 8): the merge forest of the input, a
    :class:`~fancloud_vtk.ViewDependentFanCloud` whose attributes ``fancloud_input`` (the
    kind of input) and ``unreferenced_dropped`` tell its input. With ``block_size`` (if not
    0) a height field is cut into blocks of that many cells a side
    (:func:`~fancloud_vtk.terrain_blocks`), a point set or mesh into spatial blocks of
    about ``block_size**2`` points (:func:`~fancloud_vtk.point_blocks`).

    Examples
    --------
    >>> import numpy as np
    >>> from fancloud_vtk.core import verbs
    >>> z = np.random.default_rng(0).random((30, 40))
    >>> vd = verbs.vdfc(verbs.Source(heights=(z, (1.0, 1.0), (0.0, 0.0))))
    >>> vd.n_leaves, vd.fancloud_input
    (1200, 'height field')
    """
    from .vdfc import ViewDependentFanCloud, point_blocks, terrain_blocks

    values = check_values("vdfc", values or {})
    fc, kind = source_fan_cloud(source, values, progress)
    blocks = None
    size = values["block_size"]
    if kind == KIND_HEIGHT_FIELD and size:
        blocks = terrain_blocks(source.heights[0].shape, size)
    elif size:  # about size x size points a block, as a height field's
        blocks = point_blocks(fc, max(1, int(round(fc.n_points / float(size) ** 2))))
        if len(blocks) == 1:
            blocks = None
    vd = ViewDependentFanCloud.build(fc, values["merge"], weights=values["weights"],
                                     blocks=blocks, n_roots=values["n_roots"],
                                     colors=_colors(values), progress=progress)
    vd.fancloud_input = kind
    vd.unreferenced_dropped = fc.info.get(UNREFERENCED_DROPPED)
    return vd


def e_max_of(vd, e_max: float) -> float:
    """``e_max``, or :data:`AUTO_E_MAX` times the diagonal of the forest's bounds when it
    is 0."""
    if e_max > 0:
        return e_max
    b = np.asarray(vd.bounds(), np.float64).reshape(3, 2)
    return AUTO_E_MAX * float(np.linalg.norm(b[:, 1] - b[:, 0]))


#: the verbs by name, as in :data:`fancloud_vtk.params.VERB_PARAMS`
VERBS = {"fans": fans, "mesh": mesh, "entropy": entropy, "reduce": reduce,
         "hierarchy": hierarchy, "selective": selective, "refine": refine, "vdfc": vdfc}
