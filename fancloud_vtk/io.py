"""Read point clouds and meshes from files into plain numpy arrays.

Supported formats: PLY (ascii and binary, via ``plyfile``), Wavefront OBJ, VTK XML
PolyData (``.vtp``) and UnstructuredGrid (``.vtu``), legacy VTK (``.vtk``), STL (ascii and
binary, ``.stl``; coincident corners merged into shared vertices), column text (``.xyz``,
``.pts``, ``.txt``) and numpy ``.npy``. VTK is imported lazily and only for the VTK formats
and STL; pyvista is never imported. VTK bit arrays are read as uint8 0/1; a per-point array
that cannot be kept (e.g. a VTK string array) is dropped with a :class:`DroppedArrayWarning`
naming it and the reason.

Examples
--------
>>> cloud = read_point_cloud("bunny.ply")  # doctest: +SKIP
>>> cloud.points.shape, sorted(cloud.point_data)  # doctest: +SKIP
"""

from __future__ import annotations

import io
import os
import re
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from fancloud_vtk.core.validation import FileReadError  # the core raises it too: one class

__all__ = [
    "SUPPORTED_FORMATS",
    "DroppedArrayWarning",
    "FileReadError",
    "PointCloudFile",
    "read_point_chunks",
    "read_point_cloud",
]

#: Format names accepted by :func:`read_point_cloud` (also the recognised file extensions).
SUPPORTED_FORMATS: tuple[str, ...] = (
    "ply",
    "obj",
    "vtp",
    "vtu",
    "vtk",
    "stl",
    "xyz",
    "pts",
    "txt",
    "npy",
    "las",
    "laz",
)

_UNIT_NORMAL_TOL = 1e-2


class DroppedArrayWarning(UserWarning):
    """A per-point array of the file was not read: the message names the file, the array
    and the reason (e.g. a VTK string array, a length other than the number of points, a
    PLY list property)."""


def _warn_dropped(path: str, name: str, reason: str, stacklevel: int) -> None:
    """Warn that point array ``name`` of ``path`` was dropped; ``stacklevel`` counts from
    the caller of this function (as for :func:`warnings.warn`)."""
    warnings.warn(
        f"{path!r}: point array {name!r} dropped: {reason}",
        DroppedArrayWarning,
        stacklevel=stacklevel + 1,
    )


@dataclass(frozen=True, eq=False)
class PointCloudFile:
    """Contents of a point-cloud or mesh file.

    Compared by identity (``eq=False``): element-wise array comparison has no single truth
    value.

    Attributes
    ----------
    points : numpy.ndarray
        ``(n, 3)`` float64, C-contiguous.
    point_data : dict of str to numpy.ndarray
        Every per-point array (first axis of length ``n``). Normals are stored under
        ``"Normals"`` (float64 ``(n, 3)``), colours under ``"RGB"`` (uint8 ``(n, 3)``) or
        ``"RGBA"`` (uint8 ``(n, 4)``).
    faces : numpy.ndarray or None
        ``(m, 3)`` int64 triangles (polygons fan-triangulated) when the file has faces,
        else ``None``.
    path : str
        The path that was read.
    """

    points: np.ndarray
    point_data: dict[str, np.ndarray]
    faces: np.ndarray | None
    path: str


# ----------------------------------------------------------------------------- helpers


def _owned(a: np.ndarray, dtype=None) -> np.ndarray:
    """Return a C-contiguous array that owns its memory (copying only when needed)."""
    out = np.asarray(a, dtype=dtype)
    if out.dtype.byteorder not in ("=", "|"):
        out = out.astype(out.dtype.newbyteorder("="))
    if out.base is not None or not out.flags.c_contiguous or not out.flags.writeable:
        out = np.array(out, order="C")
    return out


def _finish(
    path: str,
    points: np.ndarray,
    point_data: dict[str, np.ndarray],
    faces: np.ndarray | None,
) -> PointCloudFile:
    """Validate shapes, check face indices, make every array own its memory."""
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise FileReadError(path, f"points have shape {points.shape}, expected (n, 3)")
    n = points.shape[0]
    if n == 0:
        raise FileReadError(path, "the file contains no points")
    data = {}
    for name, arr in point_data.items():
        arr = np.asarray(arr)
        if arr.ndim == 0 or arr.shape[0] != n:
            raise FileReadError(
                path, f"point array {name!r} has shape {arr.shape}, expected length {n}"
            )
        data[name] = _owned(arr)
    if faces is not None:
        faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        if faces.shape[0] == 0:
            faces = None
        else:
            lo, hi = int(faces.min()), int(faces.max())
            if lo < 0 or hi >= n:
                bad = lo if lo < 0 else hi
                raise FileReadError(
                    path, f"a face references vertex {bad} but there are only {n} vertices"
                )
            faces = _owned(faces)
    return PointCloudFile(
        points=_owned(points, np.float64), point_data=data, faces=faces, path=path
    )


#: VTK's linear surface cells (vtkCellType.h): the cells a mesh file's triangles come from
VTK_TRIANGLE, VTK_TRIANGLE_STRIP, VTK_POLYGON, VTK_PIXEL, VTK_QUAD = 5, 6, 7, 8, 9


def _csr_subset(offsets: np.ndarray, connectivity: np.ndarray, keep: np.ndarray):
    """The cells ``keep`` (a bool mask) of a CSR cell array: (offsets, connectivity)."""
    starts = offsets[:-1][keep]
    sizes = offsets[1:][keep] - starts
    new = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    idx = np.repeat(starts - new[:-1], sizes) + np.arange(new[-1], dtype=np.int64)
    return new, connectivity[idx]


def _strip_triangulate(offsets: np.ndarray, connectivity: np.ndarray) -> np.ndarray:
    """Triangle strips ``(v0, v1, v2, v3, ...)`` as triangles ``(v0, v1, v2)``,
    ``(v2, v1, v3)``, ...: every other one turned so that all keep the first one's
    orientation (as VTK decomposes a strip)."""
    sizes = np.diff(offsets)
    ntri = np.maximum(sizes - 2, 0)
    total = int(ntri.sum())
    strip = np.repeat(np.arange(sizes.size), ntri)
    local = np.arange(total, dtype=np.int64) - (np.cumsum(ntri) - ntri)[strip]
    first = offsets[:-1][strip] + local
    a, b, c = connectivity[first], connectivity[first + 1], connectivity[first + 2]
    odd = local % 2 == 1
    return np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)


def cell_triangles(offsets, connectivity, types) -> np.ndarray:
    """The triangles of the surface cells of a VTK cell array, ``(t, 3)`` int64.

    Triangles, quads and polygons are fan-triangulated from their first
    vertex (right for convex ones, as in the OBJ and PLY readers), pixels
    taken in their counter-clockwise order (0, 1, 3, 2), triangle strips
    decomposed as VTK does; other cells (vertices, lines, volume cells,
    quadratic and higher-order cells) give none.
    ``offsets``/``connectivity``: the cell array in CSR form (VTK 9's
    ``GetOffsetsArray``/``GetConnectivityArray``), ``types`` the cell types.
    """
    offsets = np.asarray(offsets, dtype=np.int64)
    conn = np.asarray(connectivity, dtype=np.int64)
    types = np.asarray(types)
    parts = [np.zeros((0, 3), np.int64)]
    polygons = np.isin(types, (VTK_TRIANGLE, VTK_POLYGON, VTK_QUAD))
    if polygons.any():
        parts.append(_fan_triangulate(*_csr_subset(offsets, conn, polygons)))
    pixels = (types == VTK_PIXEL) & (np.diff(offsets) == 4)
    if pixels.any():
        off, quads = _csr_subset(offsets, conn, pixels)
        parts.append(_fan_triangulate(off, quads.reshape(-1, 4)[:, [0, 1, 3, 2]].ravel()))
    strips = types == VTK_TRIANGLE_STRIP
    if strips.any():
        parts.append(_strip_triangulate(*_csr_subset(offsets, conn, strips)))
    return np.concatenate(parts)


def grid_triangles(grid) -> np.ndarray:
    """The triangles of the 2-d cells of a ``vtkUnstructuredGrid`` (:func:`cell_triangles`),
    ``(t, 3)`` int64, empty if it has none."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

    if grid.GetNumberOfCells() == 0:
        return np.zeros((0, 3), np.int64)
    try:
        types = grid.GetCellTypes()  # VTK >= 9.6: the per-cell types
    except TypeError:  # before: GetCellTypes(vtkCellTypes) fills a summary
        types = grid.GetCellTypesArray()
    plain = vtkUnsignedCharArray()  # whatever array class VTK returns
    plain.DeepCopy(types)
    cells = grid.GetCells()
    return cell_triangles(vtk_to_numpy(cells.GetOffsetsArray()),
                          vtk_to_numpy(cells.GetConnectivityArray()), vtk_to_numpy(plain))


def _fan_triangulate(offsets: np.ndarray, connectivity: np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons given CSR ``offsets`` (m + 1) and flat ``connectivity``.

    Polygon ``(v0, v1, ..., vk)`` becomes triangles ``(v0, vi, vi+1)``; polygons with
    fewer than three vertices are dropped.

    Returns
    -------
    numpy.ndarray
        ``(t, 3)`` int64.
    """
    offsets = np.asarray(offsets, dtype=np.int64)
    conn = np.asarray(connectivity, dtype=np.int64)
    sizes = np.diff(offsets)
    if sizes.size and np.all(sizes == 3):
        return conn[offsets[0] : offsets[-1]].reshape(-1, 3)
    ntri = np.maximum(sizes - 2, 0)
    total = int(ntri.sum())
    if total == 0:
        return np.zeros((0, 3), dtype=np.int64)
    poly = np.repeat(np.arange(sizes.size), ntri)
    first = np.cumsum(ntri) - ntri
    local = np.arange(total, dtype=np.int64) - first[poly] + 1
    start = offsets[:-1][poly]
    return np.stack([conn[start], conn[start + local], conn[start + local + 1]], axis=1)


def _colours_to_uint8(c: np.ndarray) -> np.ndarray | None:
    """Convert colour columns to uint8, or ``None`` if they do not look like colours.

    Integers in 0..255 are kept; uint16 is scaled to 0..255; floats all within [0, 1]
    become ``round(255 * c)``; integral floats in 0..255 are kept as they are.
    """
    c = np.asarray(c)
    if c.size == 0:
        return c.astype(np.uint8)
    if c.dtype == np.uint8:
        return c.copy()
    if np.issubdtype(c.dtype, np.integer):
        if c.dtype == np.uint16 and int(c.max()) > 255:
            return np.rint(c / 257.0).astype(np.uint8)
        if int(c.min()) >= 0 and int(c.max()) <= 255:
            return c.astype(np.uint8)
        return None
    if not np.issubdtype(c.dtype, np.floating):
        return None
    c = c.astype(np.float64)
    if not np.all(np.isfinite(c)):
        return None
    lo, hi = float(c.min()), float(c.max())
    integral = bool(np.all(c == np.rint(c)))
    if integral and lo >= 0 and hi <= 255 and hi > 1:
        return c.astype(np.uint8)
    if lo >= 0 and hi <= 1:
        return np.rint(255.0 * c).astype(np.uint8)
    return None


def _looks_like_unit_vectors(v: np.ndarray) -> bool:
    norms = np.sqrt(np.sum(np.asarray(v, dtype=np.float64) ** 2, axis=1))
    return bool(np.all(np.abs(norms - 1.0) <= _UNIT_NORMAL_TOL))


def _columns_to_cloud(path: str, table: np.ndarray) -> PointCloudFile:
    """Interpret an ``(n, k >= 3)`` numeric table as xyz plus extra columns.

    3: x y z; 4: x y z intensity; 6: x y z nx ny nz (if unit vectors) else x y z r g b;
    7: x y z intensity r g b; 9: x y z nx ny nz r g b. Columns that cannot be interpreted
    are kept as ``"column_<j>"`` (float64).
    """
    k = table.shape[1]
    pts = table[:, :3]
    data: dict[str, np.ndarray] = {}
    used = set(range(3))

    def colour(cols: slice) -> None:
        rgb = _colours_to_uint8(table[:, cols])
        if rgb is not None:
            data["RGB"] = rgb
            used.update(range(cols.start, cols.stop))

    if k == 4:
        data["intensity"] = table[:, 3].astype(np.float64)
        used.add(3)
    elif k == 6:
        if _looks_like_unit_vectors(table[:, 3:6]):
            data["Normals"] = table[:, 3:6].astype(np.float64)
            used.update((3, 4, 5))
        else:
            colour(slice(3, 6))
    elif k == 7:
        data["intensity"] = table[:, 3].astype(np.float64)
        used.add(3)
        colour(slice(4, 7))
    elif k == 9:
        data["Normals"] = table[:, 3:6].astype(np.float64)
        used.update((3, 4, 5))
        colour(slice(6, 9))
    for j in range(3, k):
        if j not in used:
            data[f"column_{j}"] = table[:, j].astype(np.float64)
    return _finish(path, pts, data, None)


def _loadtxt(source, **kwargs) -> np.ndarray:
    """``np.loadtxt`` with its "no data" UserWarning raised (callers catch it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        return np.loadtxt(source, **kwargs)


def _read_bytes(path: str) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise FileReadError(path, f"{exc.strerror or exc}") from exc


def _decode(raw: bytes) -> str:
    """Decode text; undecodable bytes become U+FFFD and later fail as non-numeric tokens."""
    text = raw.decode("utf-8", errors="replace")
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


# ----------------------------------------------------------------------------- PLY

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_PLY_FACE_LISTS = ("vertex_indices", "vertex_index")


def _ply_cast(values: np.ndarray, dtype: str) -> np.ndarray | None:
    """Cast parsed float64 text values to a PLY type, or ``None`` if they do not fit."""
    dt = np.dtype(dtype)
    if dt.kind == "f":
        return values.astype(dt)
    if not np.all(values == np.rint(values)):
        return None
    info = np.iinfo(dt)
    if values.size and (values.min() < info.min or values.max() > info.max):
        return None
    return values.astype(dt)


def _ply_ascii_fast(raw: bytes) -> tuple[np.ndarray, np.ndarray | None] | None:
    """Vectorised reader for ASCII PLY: ``(vertex structured array, triangles)``.

    plyfile parses ASCII PLY one line at a time in Python (seconds per 100k lines); this
    handles the common layouts with numpy and returns ``None`` for anything unusual, in
    which case plyfile reads the file (and reports any error).
    """
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        return None
    body_start = raw.find(b"\n", end)
    header = raw[:end].decode("ascii", errors="replace").splitlines()
    if body_start < 0 or not any(ln.split() == ["format", "ascii", "1.0"] for ln in header):
        return None
    elements: list[tuple[str, int, list[tuple]]] = []
    for line in header[1:]:
        toks = line.split()
        if not toks or toks[0] in ("comment", "obj_info", "format"):
            continue
        if toks[0] == "element" and len(toks) == 3 and toks[2].isdigit():
            elements.append((toks[1], int(toks[2]), []))
        elif toks[0] == "property" and elements and len(toks) == 3 and toks[1] in _PLY_TYPES:
            elements[-1][2].append(("scalar", toks[2], _PLY_TYPES[toks[1]]))
        elif toks[0] == "property" and elements and len(toks) == 5 and toks[1] == "list":
            elements[-1][2].append(("list", toks[4], _PLY_TYPES.get(toks[3], "")))
        else:
            return None
    lines = raw[body_start + 1 :].decode("ascii", errors="replace").splitlines()
    vertex = faces = None
    pos = 0
    for name, count, props in elements:
        seg = lines[pos : pos + count]
        pos += count
        if len(seg) < count:
            return None
        if name == "vertex":
            if vertex is not None or any(kind != "scalar" for kind, _, _ in props):
                return None
            vertex = np.empty(count, dtype=[(p, t) for _, p, t in props])
            if count:
                table = _loadtxt(seg, dtype=np.float64, ndmin=2, comments=None)
                if table.shape != (count, len(props)):
                    return None
                for j, (_, prop, typ) in enumerate(props):
                    col = _ply_cast(table[:, j], typ)
                    if col is None:
                        return None
                    vertex[prop] = col
        elif name == "face" and count:
            faces = _ply_ascii_faces(seg, props)
            if faces is None:
                return None
    return None if vertex is None else (vertex, faces)


def _ply_ascii_faces(seg: list[str], props: list[tuple]) -> np.ndarray | None:
    """Triangles from the ASCII lines of a 'face' element, or ``None`` (use plyfile)."""
    lists = [i for i, (kind, _, _) in enumerate(props) if kind == "list"]
    if len(lists) != 1 or props[lists[0]][1] not in _PLY_FACE_LISTS:
        return None if lists else np.zeros((0, 3), dtype=np.int64)
    before, after = lists[0], len(props) - lists[0] - 1
    ntok = np.fromiter(map(len, map(str.split, seg)), dtype=np.int64, count=len(seg))
    if np.all(ntok == ntok[0]):
        table = _loadtxt(seg, dtype=np.float64, ndmin=2, comments=None)
        k = int(ntok[0]) - before - after - 1
        if k < 0 or table.shape != (len(seg), ntok[0]) or np.any(table[:, before] != k):
            return None
        idx = _ply_cast(table[:, before + 1 : before + 1 + k], "i4")
        if idx is None:
            return None
        offsets = np.arange(len(seg) + 1, dtype=np.int64) * k
        return _fan_triangulate(offsets, idx.ravel())
    if before or after:
        return None
    flat = _fromstring_int(" ".join(seg).encode("ascii"))
    if flat.size != ntok.sum():
        return None
    starts = np.concatenate([[0], np.cumsum(ntok)[:-1]])
    if np.any(flat[starts] != ntok - 1):
        return None
    keep = np.ones(flat.size, dtype=bool)
    keep[starts] = False
    return _fan_triangulate(np.concatenate([[0], np.cumsum(ntok - 1)]), flat[keep])


def _ply_faces_from_column(col: np.ndarray) -> np.ndarray:
    """Triangles from a plyfile face list column (fixed-length or object array)."""
    if col.dtype != object:  # memory-mapped fixed-length lists: (m, k)
        k = col.shape[-1]
        offsets = np.arange(col.shape[0] + 1, dtype=np.int64) * k
        return _fan_triangulate(offsets, np.asarray(col, dtype=np.int64).ravel())
    sizes = np.fromiter(map(len, col), dtype=np.int64, count=col.shape[0])
    flat = (
        np.concatenate([np.asarray(c, dtype=np.int64) for c in col])
        if sizes.sum() > 0
        else np.zeros(0, dtype=np.int64)
    )
    return _fan_triangulate(np.concatenate([[0], np.cumsum(sizes)]), flat)


def _ply_with_plyfile(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    import plyfile

    fixed_tri = {"face": dict.fromkeys(_PLY_FACE_LISTS, 3)}
    try:
        try:
            # Fast path: memory-map (copy-on-write, the file is never modified) with the
            # face lists assumed to be triangles; plyfile checks that assumption.
            ply = plyfile.PlyData.read(path, mmap="c", known_list_len=fixed_tri)
        except plyfile.PlyElementParseError as exc:
            if "unexpected list length" not in str(exc):
                raise
            ply = plyfile.PlyData.read(path, mmap=False)
    except Exception as exc:  # plyfile raises many types on bad input
        raise FileReadError(path, f"not a valid PLY file ({type(exc).__name__}: {exc})") from exc

    elements = {el.name: el for el in ply.elements}
    if "vertex" not in elements:
        names = ", ".join(elements) or "none"
        raise FileReadError(path, f"PLY file has no 'vertex' element (elements: {names})")
    faces = None
    face_el = elements.get("face")
    if face_el is not None and face_el.count > 0:
        fnames = face_el.data.dtype.names or ()
        prop = next((p for p in _PLY_FACE_LISTS if p in fnames), None)
        if prop is not None:
            faces = _ply_faces_from_column(face_el.data[prop])
    return elements["vertex"].data, faces


def _read_ply(path: str) -> PointCloudFile:
    try:
        with open(path, "rb") as fh:
            head = fh.read(1024)
    except OSError as exc:
        raise FileReadError(path, f"{exc.strerror or exc}") from exc
    fast = None
    if b"\nformat ascii " in head:
        try:
            fast = _ply_ascii_fast(_read_bytes(path))
        except (ValueError, UserWarning):
            fast = None  # plyfile reads it and reports the problem precisely
    vdata, faces = fast if fast is not None else _ply_with_plyfile(path)

    names = vdata.dtype.names or ()
    if vdata.shape[0] == 0:
        raise FileReadError(path, "PLY 'vertex' element is empty: the file contains no points")
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise FileReadError(path, f"PLY vertex element lacks propert(ies) {', '.join(missing)}")

    points = np.column_stack([np.asarray(vdata[c], dtype=np.float64) for c in "xyz"])
    # _read_ply <- read_point_cloud <- caller
    return _finish(path, points, _ply_point_data(path, vdata, stacklevel=3), faces)


def _ply_point_data(path: str, vdata, stacklevel: int, warn: bool = True) -> dict:
    """The point arrays of PLY vertex rows (a structured array): ``Normals``, ``RGB`` or
    ``RGBA``, and every other numeric scalar property under its own name (a list or
    non-numeric property is dropped, with a :class:`DroppedArrayWarning` when ``warn``;
    ``stacklevel`` counts from the caller of this function)."""
    names = vdata.dtype.names or ()
    used = {"x", "y", "z"}
    point_data: dict[str, np.ndarray] = {}

    for normal_names in (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z")):
        if all(c in names for c in normal_names):
            point_data["Normals"] = np.column_stack(
                [np.asarray(vdata[c], dtype=np.float64) for c in normal_names]
            )
            used.update(normal_names)
            break

    for prefix in ("", "diffuse_"):
        rgb_names = [prefix + c for c in ("red", "green", "blue")]
        if all(c in names for c in rgb_names):
            alpha = prefix + "alpha"
            cols = rgb_names + ([alpha] if alpha in names else [])
            colours = _colours_to_uint8(np.column_stack([np.asarray(vdata[c]) for c in cols]))
            if colours is not None:
                point_data["RGBA" if len(cols) == 4 else "RGB"] = colours
                used.update(cols)
            break

    for name in names:
        if name in used or name in point_data:
            continue
        field = vdata.dtype.fields[name][0]
        if field.shape != () or field.kind not in "biuf":
            # list properties on vertices are not per-point scalars
            kind = "a list property" if field.kind == "O" or field.shape else f"of type {field}"
            if warn:
                _warn_dropped(path, name, f"{kind}, not a numeric per-point value",
                              stacklevel=stacklevel + 1)
            continue
        point_data[name] = np.array(vdata[name])
    return point_data


# ----------------------------------------------------------------------------- OBJ


class _ObjLines:
    """Byte-level index of an OBJ file's lines, classified without a Python loop."""

    def __init__(self, raw: bytes) -> None:
        if b"\r" in raw:
            raw = raw.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        if not raw.endswith(b"\n"):
            raw += b"\n"
        self._index(raw)
        if np.any((self.c0 == 32) | (self.c0 == 9)):  # indented lines: normalise, rare
            raw = b"\n".join(line.lstrip() for line in raw.split(b"\n")[:-1]) + b"\n"
            self._index(raw)
        self.raw = raw
        sp1 = (self.c1 == 32) | (self.c1 == 9)
        self.is_v = (self.c0 == ord("v")) & sp1
        self.is_vn = (
            (self.c0 == ord("v")) & (self.c1 == ord("n")) & ((self.c2 == 32) | (self.c2 == 9))
        )
        self.is_f = (self.c0 == ord("f")) & sp1
        # Blank every keyword in the working copy: the bodies then parse as plain numbers.
        self.work[self.starts[self.is_v | self.is_vn | self.is_f]] = 32
        self.work[self.starts[self.is_vn] + 1] = 32

    def _index(self, raw: bytes) -> None:
        work = np.frombuffer(raw, dtype=np.uint8).copy()
        nl = np.flatnonzero(work == 10)  # the last byte is a newline
        self.work = work
        self.starts = np.concatenate([[0], nl[:-1] + 1]).astype(np.int64)
        self.lens = nl - self.starts + 1  # including the newline
        last = work.size - 1  # peeking past a short last line lands on its newline
        self.c0 = work[self.starts]
        self.c1 = work[np.minimum(self.starts + 1, last)]
        self.c2 = work[np.minimum(self.starts + 2, last)]

    def block(self, mask: np.ndarray) -> bytes:
        """The selected lines (keyword blanked), each ending in a newline."""
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            return b""
        if idx[-1] - idx[0] + 1 == idx.size:  # one contiguous run: the usual layout
            return self.work[
                self.starts[idx[0]] : self.starts[idx[-1]] + self.lens[idx[-1]]
            ].tobytes()
        return self.work[np.repeat(mask, self.lens)].tobytes()

    def text_line(self, mask: np.ndarray, k: int) -> tuple[int, str]:
        """1-based line number and original text of the ``k``-th line selected by ``mask``."""
        i = int(np.flatnonzero(mask)[k])
        s, n = int(self.starts[i]), int(self.lens[i])
        return i + 1, self.raw[s : s + n - 1].decode("utf-8", errors="replace")


def _obj_error(path: str, lines: _ObjLines, mask: np.ndarray, k: int, what: str) -> FileReadError:
    lineno, text = lines.text_line(mask, k)
    shown = text if len(text) <= 80 else text[:77] + "..."
    return FileReadError(path, f"line {lineno}: {what}: {shown!r}")


def _obj_floats(path: str, lines: _ObjLines, mask: np.ndarray) -> np.ndarray:
    """Parse 'v' / 'vn' bodies into an ``(n, k)`` float64 table (k >= 3 common columns)."""
    block = lines.block(mask).decode("utf-8", errors="replace")
    nrows = int(np.count_nonzero(mask))
    try:
        table = _loadtxt(io.StringIO(block), dtype=np.float64, ndmin=2, comments="#")
        if table.shape[0] == nrows and table.shape[1] >= 3:
            return table
    except (ValueError, UserWarning):
        pass
    # Slow, precise path: ragged rows (e.g. some with colours) or an error to locate.
    rows = []
    for k, body in enumerate(block.split("\n")[:nrows]):
        toks = body.split("#", 1)[0].split()
        if len(toks) < 3:
            raise _obj_error(path, lines, mask, k, "expected at least 3 numbers")
        try:
            rows.append([float(t) for t in toks])
        except ValueError:
            raise _obj_error(path, lines, mask, k, "non-numeric value") from None
    width = min(len(r) for r in rows)
    return np.array([r[:width] for r in rows], dtype=np.float64)


def _fromstring_int(text: bytes) -> np.ndarray:
    """Whitespace-separated integers; raises ValueError on anything else (numpy 1.24+)."""
    with warnings.catch_warnings():
        # numpy < 2 warns (DeprecationWarning) instead of raising on unparsable data.
        warnings.simplefilter("error", DeprecationWarning)
        try:
            return np.fromstring(text, dtype=np.int64, sep=" ")
        except DeprecationWarning as exc:
            raise ValueError(str(exc)) from exc


def _obj_faces_fast(block: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vectorised parse of 'f' bodies whose vertex tokens all share one form.

    Forms: ``v``, ``v/t``, ``v/t/n``, ``v//n``. Returns ``(refs, counts)`` (raw OBJ vertex
    indices, vertices per face line) or ``None`` when the block needs the slow path.
    """
    first = block.split(None, 1)
    if not first:
        return None
    slashes = first[0].count(b"/")
    double = b"//" in first[0]
    if slashes > 2 or (double and slashes != 2):
        return None
    per = 1 if slashes == 0 else (2 if slashes == 1 or double else 3)

    b = np.frombuffer(block, dtype=np.uint8)
    ws = b <= 32
    tok_start = ~ws
    tok_start[1:] &= ws[:-1]
    tok_pos = np.flatnonzero(tok_start)
    ntok = tok_pos.size
    slash = b == ord("/")
    n_double = int(np.count_nonzero(slash[1:] & slash[:-1]))
    if int(np.count_nonzero(slash)) != slashes * ntok or n_double != (ntok if double else 0):
        return None  # mixed token forms
    nl_pos = np.flatnonzero(b == 10)  # the block ends with a newline: one per line
    counts = np.bincount(np.searchsorted(nl_pos, tok_pos), minlength=nl_pos.size)
    if counts.size != nl_pos.size:
        return None
    if slashes:  # 'v/t/n' -> 'v t n', 'v//n' -> 'v  n'
        spaced = b.copy()
        spaced[slash] = 32
        numbers = spaced.tobytes()
    else:
        numbers = block
    try:
        flat = _fromstring_int(numbers)
    except ValueError:
        return None
    if flat.size != ntok * per:
        return None
    return flat[::per], counts.astype(np.int64)


def _obj_faces_slow(
    path: str, lines: _ObjLines, mask: np.ndarray, block: bytes
) -> tuple[np.ndarray, np.ndarray]:
    """Per-line parse of 'f' bodies (mixed token forms); raises naming a bad line."""
    refs: list[int] = []
    counts: list[int] = []
    for k, body in enumerate(block.decode("utf-8", errors="replace").split("\n")[:-1]):
        toks = body.split()
        try:
            refs.extend(int(t.split("/", 1)[0]) for t in toks)
        except ValueError:
            raise _obj_error(path, lines, mask, k, "malformed face vertex") from None
        counts.append(len(toks))
    return np.array(refs, dtype=np.int64), np.array(counts, dtype=np.int64)


def _read_obj(path: str) -> PointCloudFile:
    lines = _ObjLines(_read_bytes(path))
    nv = int(np.count_nonzero(lines.is_v))
    if nv == 0:
        raise FileReadError(path, "OBJ file has no 'v' (vertex) lines: the file contains no points")
    vtable = _obj_floats(path, lines, lines.is_v)
    point_data: dict[str, np.ndarray] = {}
    if vtable.shape[1] >= 6:  # 'v x y z r g b' (MeshLab and others)
        rgb = _colours_to_uint8(vtable[:, 3:6])
        if rgb is not None:
            point_data["RGB"] = rgb
    if int(np.count_nonzero(lines.is_vn)) == nv:
        point_data["Normals"] = _obj_floats(path, lines, lines.is_vn)[:, :3]

    faces = None
    if lines.is_f.any():
        is_f = lines.is_f
        block = lines.block(is_f)
        if b"#" in block:
            block = b"\n".join(line.split(b"#", 1)[0] for line in block.split(b"\n"))
        parsed = _obj_faces_fast(block)
        if parsed is None:
            parsed = _obj_faces_slow(path, lines, is_f, block)
        refs, counts = parsed
        if np.any(refs == 0):
            k = int(np.repeat(np.arange(counts.size), counts)[np.argmax(refs == 0)])
            raise _obj_error(path, lines, is_f, k, "vertex index 0 (OBJ indices start at 1)")
        if np.any(refs < 0):
            # Relative index -k: the k-th vertex defined before this face line.
            v_before = np.cumsum(lines.is_v)[is_f]
            refs = np.where(refs < 0, np.repeat(v_before, counts) + refs, refs - 1)
        else:
            refs = refs - 1
        faces = _fan_triangulate(np.concatenate([[0], np.cumsum(counts)]), refs)
    return _finish(path, vtable[:, :3], point_data, faces)


# ----------------------------------------------------------------------------- VTK


def _clean_vtk_message(msg: str) -> str:
    """Drop VTK's 'ERROR: In file, line N' header and object addresses."""
    lines = [ln.strip() for ln in str(msg).splitlines() if ln.strip()]
    lines = [ln for ln in lines if not re.match(r"^(ERROR|Warning|WARNING): In ", ln)]
    text = lines[0] if lines else str(msg).strip()
    return re.sub(r"\s*\(0x[0-9a-fA-F]+\)", "", text)


def _read_vtk_format(path: str, fmt: str) -> PointCloudFile:
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import (
        vtkCommand,
        vtkLogger,
        vtkOutputWindow,
        vtkStringOutputWindow,
        vtkUnsignedCharArray,
    )
    from vtkmodules.vtkCommonDataModel import vtkPointSet, vtkPolyData

    if fmt == "stl":
        from vtkmodules.vtkIOGeometry import vtkSTLReader

        reader = vtkSTLReader()
        reader.MergingOn()  # STL repeats each triangle's corners: share them
    elif fmt == "vtp":
        from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

        reader = vtkXMLPolyDataReader()
    elif fmt == "vtu":
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

        reader = vtkXMLUnstructuredGridReader()
    else:
        from vtkmodules.vtkIOLegacy import vtkDataSetReader

        reader = vtkDataSetReader()
        for flag in (
            "ReadAllScalarsOn",
            "ReadAllVectorsOn",
            "ReadAllNormalsOn",
            "ReadAllTensorsOn",
            "ReadAllColorScalarsOn",
            "ReadAllTCoordsOn",
            "ReadAllFieldsOn",
        ):
            getattr(reader, flag)()

    reader_errors: list[str] = []
    pipeline_errors: list[str] = []

    def observer(sink: list[str]) -> Callable[..., None]:
        def on_error(_obj, _event, calldata=None) -> None:
            sink.append(str(calldata))

        on_error.CallDataType = "string0"  # type: ignore[attr-defined]
        return on_error

    reader.AddObserver(vtkCommand.ErrorEvent, observer(reader_errors))
    reader.GetExecutive().AddObserver(vtkCommand.ErrorEvent, observer(pipeline_errors))
    reader.SetFileName(path)

    # Objects without our observers (e.g. the XML parser) report through the global output
    # window and the logger: capture the former, mute the latter's stderr sink, and restore
    # both afterwards. (vtkLogger has no getter for the stderr verbosity alone: the current
    # cutoff is the closest available value.)
    previous_window = vtkOutputWindow.GetInstance()
    capture = vtkStringOutputWindow()
    previous_verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    vtkOutputWindow.SetInstance(capture)
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    try:
        reader.Update()
        out = reader.GetOutputDataObject(0)  # may re-run REQUEST_DATA_OBJECT and complain
    finally:
        vtkLogger.SetStderrVerbosity(vtkLogger.ConvertToVerbosity(previous_verbosity))
        vtkOutputWindow.SetInstance(previous_window)
    other_errors = [
        chunk
        for chunk in re.split(r"\n(?=ERROR: In )", capture.GetOutput() or "")
        if chunk.startswith("ERROR")
    ]

    errors = reader_errors + other_errors or pipeline_errors
    if errors:
        reasons = list(dict.fromkeys(_clean_vtk_message(e) for e in errors))
        raise FileReadError(path, f"VTK {type(reader).__name__} failed: {'; '.join(reasons)}")
    if out is None or not out.IsA("vtkPointSet"):
        kind = out.GetClassName() if out is not None else "nothing"
        raise FileReadError(path, f"VTK reader produced {kind}, not a point set")
    out = vtkPointSet.SafeDownCast(out)
    vtk_points = out.GetPoints()
    if vtk_points is None or out.GetNumberOfPoints() == 0:
        raise FileReadError(path, "the file contains no points")
    points = np.array(vtk_to_numpy(vtk_points.GetData()), dtype=np.float64)
    n = points.shape[0]

    point_data: dict[str, np.ndarray] = {}
    pd = out.GetPointData()
    level = 4  # warn at: _read_vtk_format <- a _READERS lambda <- read_point_cloud <- caller
    for i in range(pd.GetNumberOfArrays()):
        abstract = pd.GetAbstractArray(i)
        if abstract is None:
            continue
        name = abstract.GetName() or f"array_{i}"
        kind = abstract.GetClassName()
        arr = pd.GetArray(i)  # None for string / non-numeric arrays
        if arr is None:
            _warn_dropped(path, name, f"a {kind}, not numeric", level)
            continue
        if arr.GetNumberOfTuples() != n:
            reason = f"it has {arr.GetNumberOfTuples()} tuples but the file has {n} points"
            _warn_dropped(path, name, reason, level)
            continue
        if arr.IsA("vtkBitArray"):
            # vtk_to_numpy converts none (older VTK) or only 1-component ones: 0/1 as uint8
            plain = vtkUnsignedCharArray()
            plain.DeepCopy(arr)
            arr = plain
        try:
            values = np.array(vtk_to_numpy(arr))
        except Exception as exc:  # an array type numpy_support does not know
            reason = f"a {kind} cannot be converted to a numpy array ({type(exc).__name__}: {exc})"
            _warn_dropped(path, name, reason, level)
            continue
        point_data[name] = values
    normals = pd.GetNormals()
    if normals is not None and normals.GetNumberOfComponents() == 3:
        point_data["Normals"] = np.array(vtk_to_numpy(normals), dtype=np.float64)
    scalars = pd.GetScalars()
    if (
        scalars is not None
        and scalars.GetDataTypeAsString() == "unsigned char"
        and scalars.GetNumberOfComponents() in (3, 4)
    ):
        key = "RGB" if scalars.GetNumberOfComponents() == 3 else "RGBA"
        point_data.setdefault(key, np.array(vtk_to_numpy(scalars), dtype=np.uint8))

    faces = None
    poly = vtkPolyData.SafeDownCast(out)
    if poly is not None:
        parts = []
        for cells, kind in ((poly.GetPolys(), VTK_POLYGON), (poly.GetStrips(), VTK_TRIANGLE_STRIP)):
            if cells.GetNumberOfCells():
                parts.append(cell_triangles(vtk_to_numpy(cells.GetOffsetsArray()),
                                            vtk_to_numpy(cells.GetConnectivityArray()),
                                            np.full(cells.GetNumberOfCells(), kind)))
        faces = np.concatenate(parts) if parts else None
    elif out.IsA("vtkUnstructuredGrid"):
        faces = grid_triangles(out)
    return _finish(path, points, point_data, faces)


# ----------------------------------------------------------------------------- text / npy


def _text_slow(path: str, lines: list[str], skip: set[int]) -> np.ndarray:
    """Precise (slow) parse of column text; raises naming the offending line."""
    rows: list[list[float]] = []
    width = None
    first_line = 0
    for i, line in enumerate(lines):
        if i in skip:
            continue
        body = line.split("#", 1)[0].strip()
        if not body:
            continue
        toks = body.split()
        try:
            row = [float(t) for t in toks]
        except ValueError:
            bad = next(t for t in toks if not _is_float(t))
            raise FileReadError(path, f"line {i + 1}: non-numeric token {bad!r}") from None
        if width is None:
            width, first_line = len(row), i + 1
        elif len(row) != width:
            raise FileReadError(
                path,
                f"line {i + 1} has {len(row)} columns but line {first_line} has {width} "
                "(ragged rows)",
            )
        rows.append(row)
    if not rows:
        raise FileReadError(path, "the file contains no points (no data lines)")
    return np.array(rows, dtype=np.float64)


def _is_float(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _read_text(path: str) -> PointCloudFile:
    text = _decode(_read_bytes(path))
    if "," in text:
        text = text.replace(",", " ")
    lines = text.split("\n")

    def data_lines(start: int):
        for i in range(start, len(lines)):
            if lines[i].split("#", 1)[0].strip():
                yield i

    it = data_lines(0)
    first = next(it, None)
    if first is None:
        raise FileReadError(path, "the file contains no points (no data lines)")
    skip: set[int] = set()
    toks = lines[first].split("#", 1)[0].split()
    if len(toks) == 1 and re.fullmatch(r"[+]?\d+", toks[0]):
        skip.add(first)  # point-count header, as in .pts files
        if next(it, None) is None:
            raise FileReadError(path, "the file contains no points (only a count line)")
    body = lines[first + 1 :] if skip else lines
    try:
        table = _loadtxt(body, dtype=np.float64, ndmin=2, comments="#")
    except (ValueError, UserWarning):
        table = _text_slow(path, lines, skip)
    if table.shape[1] < 3:
        raise FileReadError(path, f"rows have {table.shape[1]} column(s); need at least 3 (x y z)")
    return _columns_to_cloud(path, table)


def _read_npy(path: str) -> PointCloudFile:
    try:
        arr = np.load(path, allow_pickle=False)
    except Exception as exc:  # ValueError (pickled / bad header), OSError, EOFError...
        raise FileReadError(path, f"not a valid .npy file ({type(exc).__name__}: {exc})") from exc
    if not isinstance(arr, np.ndarray):  # e.g. an .npz archive under a .npy name
        kind = type(arr).__name__
        if hasattr(arr, "close"):
            arr.close()
        raise FileReadError(path, f"expected a single .npy array, got {kind}")
    if (
        arr.dtype.names is not None
        or not np.issubdtype(arr.dtype, np.number)
        or np.issubdtype(arr.dtype, np.complexfloating)
    ):
        raise FileReadError(path, f"array dtype {arr.dtype} is not real numeric")
    if arr.ndim != 2 or arr.shape[1] < 3:
        raise FileReadError(path, f"array has shape {arr.shape}; expected (n, 3) or (n, >=3)")
    return _columns_to_cloud(path, arr)


def _laspy(path: str):
    try:
        import laspy
    except ImportError as exc:
        raise FileReadError(path, 'reading LAS/LAZ needs laspy: pip install "laspy[lazrs]" '
                                  '(or "fancloud-vtk[distributed]")') from exc
    return laspy


def _las_xyz(points) -> np.ndarray:
    """A laspy point record's scaled coordinates as an (n, 3) float64 array."""
    return np.column_stack([np.asarray(points.x, np.float64), np.asarray(points.y, np.float64),
                            np.asarray(points.z, np.float64)])


def _read_las(path: str) -> PointCloudFile:
    laspy = _laspy(path)
    try:
        las = laspy.read(path)
    except Exception as exc:  # laspy raises many types on bad input
        raise FileReadError(path, f"not a valid LAS/LAZ file ({type(exc).__name__}: {exc})") \
            from exc
    points = _las_xyz(las)
    if len(points) == 0:
        raise FileReadError(path, "the LAS/LAZ file contains no points")
    return _finish(path, points, _las_point_data(las, las.point_format), None)


def _las_point_data(points, point_format) -> dict:
    """The point arrays of LAS points: ``RGB`` (8 bits; 16-bit colours shifted down),
    ``intensity``, ``classification``, ``return_number`` where the format has them."""
    names = set(point_format.dimension_names)
    point_data: dict[str, np.ndarray] = {}
    if {"red", "green", "blue"} <= names:
        rgb = np.column_stack([np.asarray(points[c]) for c in ("red", "green", "blue")])
        point_data["RGB"] = (rgb >> 8).astype(np.uint8) if rgb.max(initial=0) > 255 \
            else rgb.astype(np.uint8)
    for name in ("intensity", "classification", "return_number"):
        if name in names:
            point_data[name] = np.array(points[name])
    return point_data



# ----------------------------------------------------------------------------- public


_READERS: dict[str, Callable[[str], PointCloudFile]] = {
    "ply": _read_ply,
    "obj": _read_obj,
    "vtp": lambda p: _read_vtk_format(p, "vtp"),
    "vtu": lambda p: _read_vtk_format(p, "vtu"),
    "vtk": lambda p: _read_vtk_format(p, "vtk"),
    "stl": lambda p: _read_vtk_format(p, "stl"),
    "xyz": _read_text,
    "pts": _read_text,
    "txt": _read_text,
    "npy": _read_npy,
    "las": lambda p: _read_las(p),
    "laz": lambda p: _read_las(p),
}


def read_point_cloud(path: str | os.PathLike[str], *, format: str | None = None) -> PointCloudFile:
    """Read a point cloud (or mesh vertices and triangles) from a file.

    Parameters
    ----------
    path : str or os.PathLike
        File to read; it is never modified.
    format : str, optional
        One of :data:`SUPPORTED_FORMATS` (case-insensitive, a leading dot is allowed);
        by default taken from the file extension.

    Returns
    -------
    PointCloudFile
        Points, per-point arrays and triangles; all arrays own their memory.

    Raises
    ------
    FileReadError
        If the file is missing, a directory, empty, of an unknown format, or cannot be
        parsed; the message names the path and the reason.

    Warns
    -----
    DroppedArrayWarning
        For each per-point array of the file that is not returned (a VTK string array, an
        array whose length is not the number of points, a PLY list property), naming the
        array and the reason. (VTK bit arrays are returned as uint8 0/1.)
    """
    path = os.fspath(path)
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not os.path.exists(path):
        raise FileReadError(path, "no such file")
    if os.path.isdir(path):
        raise FileReadError(path, "is a directory, not a file")
    if os.path.getsize(path) == 0:
        raise FileReadError(path, "the file is empty (0 bytes)")

    supported = ", ".join(SUPPORTED_FORMATS)
    if format is not None:
        fmt = format.lower().lstrip(".")
        if fmt not in _READERS:
            raise FileReadError(path, f"unknown format {format!r}; supported: {supported}")
    else:
        ext = os.path.splitext(path)[1]
        fmt = ext.lower().lstrip(".")
        if fmt not in _READERS:
            shown = repr(ext) if ext else "no extension"
            raise FileReadError(
                path,
                f"unknown file extension ({shown}); supported: {supported} (or pass format=...)",
            )
    return _READERS[fmt](path)


def read_point_chunks(path: str | os.PathLike[str], *, chunk: int = 1_000_000,
                      format: str | None = None, point_data: bool = False) -> Iterator:
    """The points of a file, ``chunk`` at a time, without reading the file whole.

    For clouds larger than memory (:func:`fancloud_vtk.distributed.write_tiled_fans`
    reads its input this way). ``.npy`` is memory-mapped, binary PLY is memory-mapped
    (its vertex element, through ``plyfile``), ascii PLY is read line by line, LAS and LAZ
    through ``laspy``'s chunk iterator. Any other format is read whole by
    :func:`read_point_cloud` and handed out in chunks.

    Parameters
    ----------
    path : str or os.PathLike
        The file (never modified).
    chunk : int, default: 1_000_000
        Points per chunk (the last may be shorter).
    format : str, optional
        As in :func:`read_point_cloud`.
    point_data : bool, default: False
        Also read the point arrays :func:`read_point_cloud` reads: LAS/LAZ ``RGB``,
        ``intensity``, ``classification``, ``return_number``; PLY ``Normals``, ``RGB`` or
        ``RGBA`` and every other numeric vertex property; the other formats' arrays (a
        ``.npy`` file holds coordinates only: none).

    Yields
    ------
    numpy.ndarray or tuple
        ``(m, 3)`` float64 coordinates, in the file's order (not checked for NaN: the
        caller does, knowing the rows' numbers); with ``point_data``, ``(coordinates,
        arrays)``, ``arrays`` a dict of arrays of ``m`` rows, the same names in every
        chunk.

    Raises
    ------
    FileReadError
        As :func:`read_point_cloud` (raised by the first ``next``).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "cloud.npy")
    >>> np.save(path, np.random.default_rng(0).random((2500, 3)))
    >>> [len(c) for c in read_point_chunks(path, chunk=1000)]
    [1000, 1000, 500]
    """
    if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
        raise ValueError(f"chunk must be a positive integer, got {chunk!r}")
    if not isinstance(point_data, bool | np.bool_):
        raise TypeError(f"point_data must be True or False, got {point_data!r}")
    for xyz, arrays in _chunks_with_data(path, int(chunk), format, bool(point_data)):
        yield (xyz, arrays) if point_data else xyz


def _chunks_with_data(path, chunk: int, format, want: bool) -> Iterator:
    """(coordinates, point arrays) chunks of a file; the arrays only when ``want``."""
    path = os.fspath(path)
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    fmt = (format or os.path.splitext(path)[1]).lower().lstrip(".")
    if not os.path.isfile(path) or fmt not in ("npy", "ply", "las", "laz"):
        cloud = read_point_cloud(path, format=format)  # raises the reader's FileReadError
        for i in range(0, len(cloud.points), chunk):
            arrays = {k: v[i:i + chunk] for k, v in cloud.point_data.items()} if want else {}
            yield np.array(cloud.points[i:i + chunk], dtype=np.float64), arrays
        return
    if os.path.getsize(path) == 0:
        raise FileReadError(path, "the file is empty (0 bytes)")
    if fmt == "npy":
        try:
            arr = np.load(path, mmap_mode="r", allow_pickle=False)
        except Exception as exc:
            raise FileReadError(path, f"not a valid .npy file ({type(exc).__name__}: {exc})") \
                from exc
        if arr.dtype.names is not None or arr.dtype.kind not in "iuf" or arr.ndim != 2 \
                or arr.shape[1] < 3:
            raise FileReadError(path, f"expected an (n, >=3) real array, got {arr.dtype} "
                                      f"{arr.shape}")
        if arr.shape[0] == 0:  # as read_point_cloud says it
            raise FileReadError(path, "the file contains no points")
        for i in range(0, len(arr), chunk):
            yield np.array(arr[i:i + chunk, :3], dtype=np.float64), {}
    elif fmt in ("las", "laz"):
        laspy = _laspy(path)
        try:
            reader = laspy.open(path)
        except Exception as exc:
            raise FileReadError(path, f"not a valid LAS/LAZ file ({type(exc).__name__}: "
                                      f"{exc})") from exc
        with reader:
            if reader.header.point_count == 0:
                raise FileReadError(path, "the LAS/LAZ file contains no points")
            for points in reader.chunk_iterator(int(chunk)):
                arrays = _las_point_data(points, reader.header.point_format) if want else {}
                yield _las_xyz(points), arrays
    else:
        yield from _ply_chunks(path, int(chunk), want)


# PLY's scalar property types (both spellings) as numpy types
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def _ply_chunks(path: str, chunk: int, want: bool = False) -> Iterator:
    """A PLY file's vertex coordinates and, when ``want``, point arrays, in chunks
    ``(coordinates, arrays)``: binary memory-mapped, ascii streamed."""
    import plyfile

    with open(path, "rb") as fh:
        head = fh.read(1024)
    if b"\nformat ascii " not in head:
        try:
            ply = plyfile.PlyData.read(path, mmap="r")
            vertex = ply["vertex"].data
        except Exception as exc:
            raise FileReadError(path, f"not a valid PLY file ({type(exc).__name__}: {exc})") \
                from exc
        if len(vertex) == 0 or any(c not in (vertex.dtype.names or ()) for c in "xyz"):
            raise FileReadError(path, "PLY vertex element is empty or lacks x, y, z")
        for i in range(0, len(vertex), chunk):
            rows = vertex[i:i + chunk]
            arrays = _ply_point_data(path, rows, stacklevel=1, warn=i == 0) if want else {}
            yield np.column_stack([np.asarray(rows[c], np.float64) for c in "xyz"]), arrays
        return
    # ascii: the header names the columns; the vertex element must come first
    import itertools

    with open(path, "rb") as fh:
        props: list[str] = []
        types: list[str] = []
        element, count, first = None, 0, None
        for line in fh:
            words = line.split()
            if not words:
                continue
            if words[0] == b"element":
                element = words[1]
                if element == b"vertex":
                    count = int(words[2])
                if first is None:
                    first = element
            elif words[0] == b"property" and element == b"vertex":
                if words[1] == b"list":
                    raise FileReadError(path, "ascii PLY vertex with a list property: read it "
                                              "with read_point_cloud")
                props.append(words[-1].decode())
                types.append(words[1].decode())
            elif words[0] == b"end_header":
                break
        if first != b"vertex" or count == 0 or any(c not in props for c in "xyz"):
            raise FileReadError(path, "ascii PLY: the first element must be a non-empty "
                                      "'vertex' with x, y, z")
        cols = [props.index(c) for c in "xyz"]
        dtype = None
        if want:
            unknown = [t for t in types if t not in _PLY_TYPES]
            if unknown:
                raise FileReadError(path, f"ascii PLY: unknown vertex property type(s) "
                                          f"{', '.join(unknown)}")
            dtype = np.dtype([(p, _PLY_TYPES[t]) for p, t in zip(props, types, strict=True)])
        left = count
        while left:
            lines = list(itertools.islice(fh, min(chunk, left)))
            if not lines:
                raise FileReadError(path, f"ascii PLY ends after {count - left:,} of "
                                          f"{count:,} vertices")
            try:
                block = np.loadtxt(lines, usecols=None if want else cols, ndmin=2,
                                   dtype=np.float64)
            except ValueError as exc:
                raise FileReadError(path, f"ascii PLY vertex rows: {exc}") from exc
            arrays = {}
            if want:
                if block.shape[1] != len(props):
                    raise FileReadError(path, f"ascii PLY vertex rows have {block.shape[1]} "
                                              f"values, the header names {len(props)}")
                rows = np.empty(len(block), dtype)
                for j, p in enumerate(props):
                    rows[p] = block[:, j]
                arrays = _ply_point_data(path, rows, stacklevel=1, warn=False)
                block = block[:, cols]
            left -= len(lines)
            yield block, arrays

