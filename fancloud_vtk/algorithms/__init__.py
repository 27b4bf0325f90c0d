"""VTK algorithms (``VTKPythonAlgorithmBase``) over the core.

Imports numpy, ``vtkmodules`` and the core only, never pyvista, so ParaView
5.11 (VTK 9.2) can load it.
"""

from .base import FanCloudAlgorithm, run
from .convert import fancloud_from_vtk, fancloud_to_vtk, is_fancloud
from .fans import FanCloudFilter
from .mesh import FanCloudMeshFilter

__all__ = [
    "FanCloudAlgorithm",
    "FanCloudFilter",
    "FanCloudMeshFilter",
    "fancloud_from_vtk",
    "fancloud_to_vtk",
    "is_fancloud",
    "run",
]
