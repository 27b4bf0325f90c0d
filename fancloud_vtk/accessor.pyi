"""Type stub for :mod:`fancloud_vtk.accessor` (the ``dataset.fancloud`` accessor).

At run time ``FanCloudAccessor.fans`` takes ``**params`` checked against
``fancloud_vtk.params.FAN_PARAMS``, ``FanCloudAccessor.mesh`` against
``FAN_PARAMS + MESH_PARAMS``, ``entropy`` and ``reduce`` against
``FAN_PARAMS + ENTROPY_PARAMS`` / ``REDUCE_PARAMS`` / ``REFINE_PARAMS``; this stub spells those
keywords out so editors complete and check them. The verb signatures between
the markers are generated from the tables by ``scripts/gen_docs.py``; do not
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

from fancloud_vtk.core.hierarchy import Hierarchy
from fancloud_vtk.core.model import FanCloud
from fancloud_vtk.core.vdfc import ViewDependentFanCloud

class PyVistaViewDependentFanCloud(ViewDependentFanCloud):
    values: dict
    def front(
        self,
        camera,
        e_max: float | None = None,
        d_max: float | None = None,
        *,
        aspect: float | None = None,
        incremental: bool = True,
    ) -> pv.PolyData: ...
    def filter(self): ...
    def add_to(self, plotter, **mesh_kwargs): ...

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
        reach: float = 5.0,
        separate_sheets: bool = False,
        orient: bool = True,
        keep_unreferenced: bool = False,
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
        reach: float = 5.0,
        separate_sheets: bool = False,
        orient: bool = True,
        keep_unreferenced: bool = False,
        rings: Literal["auto", "delaunay", "local", "fans"] = "auto",
        close_holes: bool = True,
        max_hole: int = 32,
        max_hole_diameter: float = 6.0,
        remove_self_intersections: bool = True,
        min_component: int = 20,
        self_intersections: bool = True,
        progress_bar: bool = False,
    ) -> pv.PolyData:
        """Triangle mesh of the dataset's fan cloud or points (paper section 4); a new PolyData."""
    # END GENERATED mesh
    # BEGIN GENERATED entropy (scripts/gen_docs.py from FAN_PARAMS + ENTROPY_PARAMS)
    def entropy(
        self,
        *,
        k: int = 6,
        max_angle: float = 90.0,
        max_replacements: int = 42,
        rule: Literal["cover", "paper"] = "cover",
        rotate_sharp_edges: bool = True,
        reach: float = 5.0,
        separate_sheets: bool = False,
        orient: bool = True,
        keep_unreferenced: bool = False,
        weights: tuple[float, float, float, float] = (1.0, 1.0, 50.0, 0.0),
        color_array: str = "",
        progress_bar: bool = False,
    ) -> pv.PolyData:
        """The entropy of every point as point arrays (paper section 5); a new PolyData."""
    # END GENERATED entropy
    # BEGIN GENERATED reduce (scripts/gen_docs.py from FAN_PARAMS + REDUCE_PARAMS)
    def reduce(
        self,
        *,
        k: int = 6,
        max_angle: float = 90.0,
        max_replacements: int = 42,
        rule: Literal["cover", "paper"] = "cover",
        rotate_sharp_edges: bool = True,
        reach: float = 5.0,
        separate_sheets: bool = False,
        orient: bool = True,
        keep_unreferenced: bool = False,
        keep: float = 0.42,
        n_points: int = 0,
        weights: tuple[float, float, float, float] = (1.0, 1.0, 50.0, 0.0),
        method: Literal["entropy", "error"] = "entropy",
        color_array: str = "",
        exact: bool = False,
        max_spacing: float = 4.0,
        error_step: float = 2.0,
        removal: Literal["auto", "retriangulate", "reform"] = "auto",
        mesh: bool = False,
        progress_bar: bool = False,
    ) -> pv.PolyData:
        """Reduce to an exact number of points by entropy (paper section 5); a new PolyData."""
    # END GENERATED reduce
    # BEGIN GENERATED refine (scripts/gen_docs.py from FAN_PARAMS + REFINE_PARAMS)
    def refine(
        self,
        *,
        k: int = 6,
        max_angle: float = 90.0,
        max_replacements: int = 42,
        rule: Literal["cover", "paper"] = "cover",
        rotate_sharp_edges: bool = True,
        reach: float = 5.0,
        separate_sheets: bool = False,
        orient: bool = True,
        keep_unreferenced: bool = False,
        factor: float = 2.0,
        n_points: int = 0,
        weights: tuple[float, float, float, float] = (1.0, 1.0, 0.0, 0.0),
        color_array: str = "",
        move: bool = True,
        exact: bool = False,
        mesh: bool = False,
        progress_bar: bool = False,
    ) -> pv.PolyData:
        """Refine beyond the input resolution by entropy (paper section 7); a new PolyData."""
    # END GENERATED refine
    # BEGIN GENERATED selective (scripts/gen_docs.py from FAN, REDUCE, SELECTIVE_PARAMS)
    def selective(
        self,
        *,
        k: int = 6,
        max_angle: float = 90.0,
        max_replacements: int = 42,
        rule: Literal["cover", "paper"] = "cover",
        rotate_sharp_edges: bool = True,
        reach: float = 5.0,
        separate_sheets: bool = False,
        orient: bool = True,
        keep_unreferenced: bool = False,
        keep: float = 0.42,
        n_points: int = 0,
        weights: tuple[float, float, float, float] = (1.0, 1.0, 50.0, 0.0),
        method: Literal["entropy", "error"] = "entropy",
        color_array: str = "",
        exact: bool = False,
        max_spacing: float = 4.0,
        error_step: float = 2.0,
        removal: Literal["auto", "retriangulate", "reform"] = "auto",
        smooth_iterations: int = 0,
        region: Literal["sphere", "box"] = "sphere",
        region_center: tuple[float, float, float] = (0.0, 0.0, 0.0),
        region_radius: float = 0.0,
        region_bounds: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        progress_bar: bool = False,
    ) -> pv.PolyData:
        """Reduce, smooth, refine only a region of interest (Figure 11); a new PolyData."""
    # END GENERATED selective
    # BEGIN GENERATED vdfc (scripts/gen_docs.py from FAN_PARAMS + VDFC_PARAMS)
    def vdfc(
        self,
        *,
        k: int = 6,
        max_angle: float = 90.0,
        max_replacements: int = 42,
        rule: Literal["cover", "paper"] = "cover",
        rotate_sharp_edges: bool = True,
        reach: float = 5.0,
        separate_sheets: bool = False,
        orient: bool = True,
        keep_unreferenced: bool = False,
        e_max: float = 0.0,
        d_max: float = 0.0,
        merge: Literal["entropy", "half_edge"] = "entropy",
        weights: tuple[float, float, float, float] = (1.0, 1.0, 0.0, 0.0),
        color_array: str = "",
        n_roots: int = 1,
        block_size: int = 0,
        aspect: float = 0.0,
        superfluous: bool = False,
        progress_bar: bool = False,
    ) -> PyVistaViewDependentFanCloud:
        """The merge forest of the view-dependent fan cloud (paper section 8)."""
    # END GENERATED vdfc
    def hierarchy(
        self,
        n_points: int | None = None,
        *,
        weights: tuple[float, float, float, float] = (1.0, 1.0, 50.0, 0.0),
        method: Literal["entropy", "error"] = "entropy",
        color_array: str = "",
        exact: bool = False,
        keep_unreferenced: bool = False,
        **fan_params: object,
    ) -> Hierarchy:
        """The levels of detail of the reduction (paper section 6): a Hierarchy."""
