"""VTK algorithms (``VTKPythonAlgorithmBase``) over the core.

Imports numpy, ``vtkmodules`` and the core only, never pyvista, so ParaView
5.11 (VTK 9.2) can load it.
"""

from .base import FanCloudAlgorithm, run
from .convert import fancloud_from_vtk, fancloud_to_vtk, is_fancloud
from .entropy import FanCloudEntropyFilter
from .fans import FanCloudFilter
from .mesh import FanCloudMeshFilter
from .reduce import FanCloudReduceFilter, FanCloudSelectiveRefineFilter
from .refine import FanCloudRefineFilter
from .vdfc import FanCloudViewDependentFilter, flythrough, follow_camera

__all__ = [
    "FanCloudAlgorithm",
    "FanCloudEntropyFilter",
    "FanCloudFilter",
    "FanCloudMeshFilter",
    "FanCloudReduceFilter",
    "FanCloudRefineFilter",
    "FanCloudSelectiveRefineFilter",
    "FanCloudViewDependentFilter",
    "fancloud_from_vtk",
    "fancloud_to_vtk",
    "flythrough",
    "follow_camera",
    "is_fancloud",
    "run",
]
