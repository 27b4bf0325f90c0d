"""Built-in data: sample files shipped inside other packages (nothing is downloaded)."""

from __future__ import annotations

import os

import numpy as np


def pymeshlab_sample(name: str) -> str:
    """Path of a sample mesh shipped inside pymeshlab (``bunny.obj``, ``bone.ply``, ...)."""
    try:
        import pymeshlab
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise ImportError("the sample meshes come with pymeshlab: pip install pymeshlab") from exc
    path = os.path.join(os.path.dirname(pymeshlab.__file__), "tests", "sample_meshes", name)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"pymeshlab ships no sample {name!r} (looked at {path})")
    return path


def bunny_path() -> str:
    """The Stanford bunny (28,088 points, a closed mesh) shipped with pymeshlab."""
    return pymeshlab_sample("bunny.obj")


#: Metres per degree of latitude (the DEM's grid is in degrees).
_M_PER_DEG = 111_320.0


def jacksboro_terrain(shape=None):
    """The Jacksboro fault DEM shipped with matplotlib, in metres.

    Returns ``(heights, spacing, origin)``: a ``(ny, nx)`` float64 grid of
    elevations (m), the grid spacing ``(dx, dy)`` in metres (the DEM's
    degrees converted at its latitude) and the origin ``(0, 0)``. With
    ``shape=(ny, nx)`` the grid is resampled (cubic splines) to that many
    points over the same area, e.g. ``(1000, 1000)`` for a million points.
    """
    from matplotlib.cbook import get_sample_data

    dem = get_sample_data("jacksboro_fault_dem.npz")
    z = np.asarray(dem["elevation"], dtype=np.float64)
    lat = np.radians(0.5 * (float(dem["ymin"]) + float(dem["ymax"])))
    dx = float(dem["dx"]) * _M_PER_DEG * float(np.cos(lat))
    dy = float(dem["dy"]) * _M_PER_DEG
    if shape is not None:
        from scipy.ndimage import zoom

        ny, nx = (int(v) for v in shape)
        if ny < 2 or nx < 2:
            raise ValueError(f"shape must be at least (2, 2), got {shape!r}")
        fy, fx = ny / z.shape[0], nx / z.shape[1]
        dx, dy = dx * (z.shape[1] - 1) / (nx - 1), dy * (z.shape[0] - 1) / (ny - 1)
        z = zoom(z, (fy, fx), order=3)
    return z, (dx, dy), (0.0, 0.0)
