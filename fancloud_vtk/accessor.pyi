"""Type stub for :mod:`fancloud_vtk.accessor` (the ``dataset.fancloud`` accessor).

At run time ``FanCloudAccessor.fans`` takes ``**params`` checked against
``fancloud_vtk.params.FAN_PARAMS``, and ``FanCloudAccessor.mesh`` against
``FAN_PARAMS + MESH_PARAMS``; this stub spells those keywords out so editors
complete and check them. The ``fans`` and ``mesh`` signatures between the
markers are generated from the tables by ``scripts/gen_docs.py``; do not
edit them by hand.

PyVista attaches the accessor at run time, and its ``DataObject.__getattr__``
is typed ``-> Any``, so a type checker sees ``mesh.fancloud`` as ``Any``.
Annotate to get completion and checking::

    from fancloud_vtk.accessor import FanCloudAccessor

    acc: FanCloudAccessor = cloud.fancloud
    fans = acc.fans(k=6)
    mesh = acc.mesh(rings="fans")
"""

from typing import Literal

import pyvista as pv

from fancloud_vtk.core.model import FanCloud

class FanCloudAccessor:
    """Fan cloud verbs on any PyVista dataset: ``dataset.fancloud.<verb>()``."""

    def __init__(self, dataset: pv.DataSet) -> None: ...
    @property
    def is_fan_cloud(self) -> bool:
        """True if the dataset carries a fan cloud (``fan_offsets``/``fan_ring`` arrays)."""
    def to_fancloud(self) -> FanCloud:
        """The dataset's fan cloud as a :class:`fancloud_vtk.FanCloud` (arrays copied)."""
    # BEGIN GENERATED fans (scripts/gen_docs.py from fancloud_vtk.params.FAN_PARAMS)
    def fans(
        self,
        *,
        k: int = 6,
        max_angle: float = 90.0,
        max_replacements: int = 42,
        rule: Literal["cover", "paper"] = "cover",
        rotate_sharp_edges: bool = True,
        orient: bool = True,
        progress_bar: bool = False,
    ) -> pv.PolyData:
        """Build the fan cloud of the dataset's points (paper section 3); a new PolyData."""
    # END GENERATED fans
    # BEGIN GENERATED mesh (scripts/gen_docs.py from FAN_PARAMS + MESH_PARAMS)
    def mesh(
        self,
        *,
        k: int = 6,
        max_angle: float = 90.0,
        max_replacements: int = 42,
        rule: Literal["cover", "paper"] = "cover",
        rotate_sharp_edges: bool = True,
        orient: bool = True,
        rings: Literal["delaunay", "fans"] = "delaunay",
        close_holes: bool = True,
        max_hole: int = 32,
        self_intersections: bool = True,
        progress_bar: bool = False,
    ) -> pv.PolyData:
        """Triangle mesh of the dataset's fan cloud or points (paper section 4); a new PolyData."""
    # END GENERATED mesh
