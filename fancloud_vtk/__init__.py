"""fancloud-vtk: fan clouds (one small triangle fan per point) as VTK filters.

The core (:mod:`fancloud_vtk.core`) works on numpy arrays; the VTK algorithms
(:mod:`fancloud_vtk.algorithms`) wrap it for VTK pipelines and ParaView; the
PyVista accessor ``dataset.fancloud`` and the ``fancloud`` command forward to
those. The filters import from here too (``from fancloud_vtk import
FanCloudReduceFilter``), and so do the VTK conversion and the files
(``to_vtk``, ``from_vtk``, ``save``, ``load``, from
:mod:`fancloud_vtk.algorithms.convert`); VTK is loaded on that first use, so
``import fancloud_vtk`` alone needs no VTK.
"""

from .core.entropy import Entropy, UnreferencedVerticesWarning, entropy, fan_cloud_of_mesh
from .core.fans import Cancelled, DuplicatePointsWarning, build_fans
from .core.hierarchy import Hierarchy
from .core.mesh import DoubtfulMeshWarning, TriangleMesh, fan_cloud_to_mesh
from .core.model import FanCloud, find_color_array
from .core.reduction import hierarchy, laplacian_smooth, reduce
from .core.refinement import refine, refine_hierarchy
from .core.validation import FanCloudInputError
from .core.vdfc import (
    ViewDependentFanCloud,
    point_blocks,
    terrain_blocks,
    terrain_fan_cloud,
    terrain_path,
)
from .distributed import (
    read_tiles,
    tile_boxes,
    tiled_fans,
    tiled_mesh,
    tiled_reduce,
    tiled_vdfc,
    write_tiled_fans,
)
from .io import DroppedArrayWarning

__version__ = "0.1.0"

#: the VTK algorithms (fancloud_vtk.algorithms), imported on first use
_FILTERS = (
    "FanCloudEntropyFilter",
    "FanCloudFilter",
    "FanCloudMeshFilter",
    "FanCloudReduceFilter",
    "FanCloudRefineFilter",
    "FanCloudSelectiveRefineFilter",
    "FanCloudViewDependentFilter",
)
#: the VTK conversion and files (fancloud_vtk.algorithms.convert), imported on first use
_VTK_IO = ("from_vtk", "load", "save", "to_vtk")


def __getattr__(name: str):
    if name in _FILTERS:
        from . import algorithms

        return getattr(algorithms, name)
    if name in _VTK_IO:
        from .algorithms import convert

        return getattr(convert, name)
    raise AttributeError(f"module 'fancloud_vtk' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_FILTERS) | set(_VTK_IO))


__all__ = [
    "Cancelled",
    "DoubtfulMeshWarning",
    "DroppedArrayWarning",
    "DuplicatePointsWarning",
    "Entropy",
    "FanCloud",
    "FanCloudEntropyFilter",
    "FanCloudFilter",
    "FanCloudInputError",
    "FanCloudMeshFilter",
    "FanCloudReduceFilter",
    "FanCloudRefineFilter",
    "FanCloudSelectiveRefineFilter",
    "FanCloudViewDependentFilter",
    "Hierarchy",
    "TriangleMesh",
    "UnreferencedVerticesWarning",
    "ViewDependentFanCloud",
    "build_fans",
    "entropy",
    "fan_cloud_of_mesh",
    "fan_cloud_to_mesh",
    "find_color_array",
    "from_vtk",
    "hierarchy",
    "laplacian_smooth",
    "load",
    "point_blocks",
    "reduce",
    "refine",
    "refine_hierarchy",
    "save",
    "terrain_blocks",
    "terrain_fan_cloud",
    "terrain_path",
    "read_tiles",
    "tile_boxes",
    "tiled_fans",
    "tiled_mesh",
    "tiled_reduce",
    "tiled_vdfc",
    "to_vtk",
    "write_tiled_fans",
]
