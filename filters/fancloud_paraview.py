"""ParaView plugin: the fan cloud filters, their properties generated from the parameter tables.

Seven filters under **Filters > Fan Clouds**: Fan Cloud, Fan Cloud Mesh, Fan Cloud
Entropy, Fan Cloud Reduce, Fan Cloud Selective Refine, Fan Cloud Refine and Fan Cloud
View-Dependent Front. Each proxy class subclasses the matching
:mod:`fancloud_vtk.algorithms` filter (the algorithm is the same code as in VTK and
PyVista) and its properties are generated from ``fancloud_vtk.params.VERB_PARAMS``: one
ParaView property per table row, with its type, default, range, choices and
documentation, so the plugin cannot disagree with the filters
(``tests/test_paraview_plugin.py`` checks it).

Load it with Tools > Manage Plugins > Load New..., ``LoadPlugin(path, ns=globals())``
in pvpython, or ``PV_PLUGIN_PATH=<this folder>``. ``fancloud_vtk`` (with numpy, scipy
and numba) must be importable by ParaView's Python, and ParaView 5.11 on Python 3.11
also needs ``filters/sitecustomize.py`` on ``PYTHONPATH``: see ``filters/README.md``.

How the properties are generated
--------------------------------
ParaView's decorators (``paraview.util.vtkAlgorithm``) record XML on the function they
decorate, and ``smproxy.filter`` collects the decorated functions it finds in the class's
own ``__dict__``. :func:`fancloud_proxy` therefore builds, for every parameter, a new
setter function, applies the domain, hint and property decorators to it in a loop, and
stores it on the class *before* applying ``smproxy.filter``. ParaView sorts the
properties by attribute name, so each setter is stored as ``_pv_NN_set_<name>`` (the
table's order); it is also the property's ``command`` and forwards to the filter's own
``SetX`` (which checks the value and calls ``Modified()`` only on a change).

The mapping from :class:`fancloud_vtk.params.Param` kinds:

=========  ==================================================================
``int``    ``IntVectorProperty`` with an ``IntRangeDomain`` (the upper bound
           clamped to 2**31 - 1: ParaView's int properties are 32-bit)
``float``  ``DoubleVectorProperty`` with a ``DoubleRangeDomain``
``bool``   ``IntVectorProperty`` with a ``BooleanDomain`` (a check box)
``choice`` ``StringVectorProperty`` with a ``StringListDomain`` (a combo box)
``str``    ``StringVectorProperty``; ``color_array`` gets an ``ArrayListDomain``
           over the input's point arrays, its first entry ``(automatic)``
           standing for the table's ``''``
``vector`` ``DoubleVectorProperty`` of ``size`` elements, the range on each
=========  ==================================================================

The view-dependent front also has the camera as properties (``CameraPosition``,
``CameraFocalPoint``, ``CameraViewUp``, ``CameraViewAngle``: the names of the render
view's own properties) and :func:`follow_view` copies a view's camera into them.
"""

from __future__ import annotations

from xml.sax.saxutils import escape, quoteattr

from paraview.util.vtkAlgorithm import smdomain, smhint, smproperty, smproxy

import fancloud_vtk
from fancloud_vtk import algorithms
from fancloud_vtk.params import VERB_PARAMS, Param

paraview_plugin_name = "FanClouds"
paraview_plugin_version = fancloud_vtk.__version__

#: the Filters menu category
MENU = "Fan Clouds"
#: ParaView's IntVectorProperty holds C ints: larger table bounds are clamped to this
INT_MAX = 2**31 - 1
#: the first entry of the colour array list: the table's '' (the first of RGB, RGBA, ...)
AUTOMATIC = "(automatic)"

#: the view-dependent front's camera properties: (name, number of elements, default, range)
CAMERA_PROPERTIES = (
    ("CameraPosition", 3, (0.0, 0.0, 1.0), None),
    ("CameraFocalPoint", 3, (0.0, 0.0, 0.0), None),
    ("CameraViewUp", 3, (0.0, 1.0, 0.0), None),
    ("CameraViewAngle", 1, 30.0, (1.0, 179.0)),
)
_CAMERA_DOCS = {
    "CameraPosition": "position of the eye whose front is output",
    "CameraFocalPoint": "point the camera looks at",
    "CameraViewUp": "view-up direction of the camera",
    "CameraViewAngle": "vertical view angle of the camera, in degrees",
}
_FOLLOW_DOC = (" Copy a render view's camera into these properties with "
               "fancloud_paraview.follow_view(front, view) in ParaView's Python shell.")


def property_spec(param: Param) -> dict:
    """How one table row is declared in ParaView (also what the tests compare).

    Keys: ``type`` ('int', 'double' or 'string'), ``number_of_elements``,
    ``default_values``, ``range`` (None or (lo, hi), each entry of a vector),
    ``choices``, ``boolean``, ``array_list`` and ``doc``.
    """
    spec = {"number_of_elements": 1, "range": None, "choices": None, "boolean": False,
            "array_list": False, "doc": f"{param.doc} (default: {param.default!r})"}
    if param.kind == "int":
        lo, hi = param.range if param.range else (None, None)
        spec.update(type="int", default_values=int(param.default),
                    range=None if lo is None else (int(lo), min(int(hi), INT_MAX)))
    elif param.kind == "bool":
        spec.update(type="int", default_values=int(bool(param.default)), boolean=True)
    elif param.kind == "float":
        spec.update(type="double", default_values=float(param.default), range=param.range)
    elif param.kind == "vector":
        spec.update(type="double", number_of_elements=param.size,
                    default_values=tuple(float(v) for v in param.default), range=param.range)
    elif param.kind == "choice":
        spec.update(type="string", default_values=param.default, choices=param.choices)
    elif param.kind == "str":
        array_list = param.name == "color_array"
        default = AUTOMATIC if array_list and param.default == "" else param.default
        spec.update(type="string", default_values=default, array_list=array_list)
    else:  # pragma: no cover - a new kind in the table must be mapped here
        raise TypeError(f"no ParaView property for a {param.kind!r} parameter ({param.name})")
    return spec


def _documentation(text: str) -> str:
    return f"<Documentation>{escape(text)}</Documentation>"


def _declare(func, name: str, command: str, spec: dict):
    """Apply the domain, hint and property decorators of ``spec`` to ``func``."""
    n = spec["number_of_elements"]
    if spec["range"] is not None:
        lo, hi = spec["range"]
        bounds = {"min": [lo] * n, "max": [hi] * n} if n > 1 else {"min": lo, "max": hi}
        if spec["type"] == "int":
            func = smdomain.intrange(**bounds)(func)
        else:
            func = smdomain.doublerange(**bounds)(func)
    if spec["boolean"]:
        func = smdomain.xml('<BooleanDomain name="bool"/>')(func)
    if spec["choices"] is not None:
        strings = "".join(f"<String value={quoteattr(c)}/>" for c in spec["choices"])
        func = smdomain.xml(f'<StringListDomain name="list">{strings}</StringListDomain>')(func)
    if spec["array_list"]:
        # the input's point arrays; NoDefault keeps '(automatic)' instead of the first array
        func = smdomain.xml(
            f'<ArrayListDomain name="array_list" input_domain_name="input_array" '
            f'none_string={quoteattr(AUTOMATIC)}>'
            '<RequiredProperties><Property name="Input" function="Input"/></RequiredProperties>'
            "</ArrayListDomain>")(func)
        func = smhint.xml("<NoDefault/>")(func)
    func = smdomain.xml(_documentation(spec["doc"]))(func)
    declare = {"int": smproperty.intvector, "double": smproperty.doublevector,
               "string": smproperty.stringvector}[spec["type"]]
    return declare(name=name, command=command, number_of_elements=n,
                   default_values=spec["default_values"])(func)


def _forward(vtk_setter: str, to_table=None):
    """A new setter function that forwards to the filter's ``SetX``."""

    def set_value(self, *values):
        if to_table is not None:
            values = tuple(to_table(v) for v in values)
        getattr(self, vtk_setter)(*values)

    return set_value


def _color_to_table(value):
    return "" if value == AUTOMATIC else value


def _add_properties(cls, table: tuple[Param, ...]) -> int:
    """Store a decorated setter per table row on ``cls``; return the next index."""
    for index, param in enumerate(table):
        command = f"_pv_{index:02d}_set_{param.name}"
        spec = property_spec(param)
        to_table = _color_to_table if spec["array_list"] else None
        func = _forward("Set" + param.vtk_name, to_table)
        func.__name__ = func.__qualname__ = command
        setattr(cls, command, _declare(func, param.vtk_name, command, spec))
    return len(table)


def _add_camera_properties(cls, first_index: int) -> None:
    for index, (name, n, default, rng) in enumerate(CAMERA_PROPERTIES, start=first_index):
        command = f"_pv_{index:02d}_set_{name}"
        spec = {"type": "double", "number_of_elements": n, "default_values": default,
                "range": rng, "choices": None, "boolean": False, "array_list": False,
                "doc": f"{_CAMERA_DOCS[name]} (default: {default!r}).{_FOLLOW_DOC}"}
        func = _camera_setter(name)
        func.__name__ = func.__qualname__ = command
        setattr(cls, command, _declare(func, name, command, spec))


def _camera_setter(name: str):
    def set_camera_part(self, *values):
        self._pv_camera[name] = tuple(float(v) for v in values) if len(values) > 1 \
            else float(values[0])
        self.SetCamera(self.pv_camera())

    return set_camera_part


def fancloud_proxy(verb: str, label: str, data_types=("vtkPointSet",), camera=False):
    """Class decorator: the ParaView proxy of a fan cloud filter, properties from
    ``VERB_PARAMS[verb]`` (plus the camera properties with ``camera``)."""

    def decorate(cls):
        table = VERB_PARAMS[verb]
        if tuple(getattr(cls, "PARAMETERS", ())) != table:
            raise TypeError(f"{cls.__name__}: its filter's parameters are not VERB_PARAMS"
                            f"[{verb!r}]")
        cls.PV_VERB, cls.PV_LABEL = verb, label
        next_index = _add_properties(cls, table)
        if camera:
            _add_camera_properties(cls, next_index)
        cls = smdomain.datatype(dataTypes=list(data_types), composite_data_supported=False)(cls)
        if any(p.name == "color_array" for p in table):  # the colour array list: point arrays
            cls = smdomain.xml('<InputArrayDomain name="input_array" attribute_type="point" '
                               'optional="1"/>')(cls)
        cls = smproperty.input(name="Input", port_index=0)(cls)
        cls = smhint.xml(f"<ShowInMenu category={quoteattr(MENU)}/>")(cls)
        name = label.replace(" ", "").replace("-", "")
        return smproxy.filter(name=name, label=label)(cls)

    return decorate


# -- the proxies: one per filter -----------------------------------------------------------


@fancloud_proxy("fans", "Fan Cloud")
class FanCloudProxy(algorithms.FanCloudFilter):
    """The fan cloud of the input's points (paper section 3)."""


@fancloud_proxy("mesh", "Fan Cloud Mesh")
class FanCloudMeshProxy(algorithms.FanCloudMeshFilter):
    """A triangle mesh from a fan cloud or points (paper section 4)."""


@fancloud_proxy("entropy", "Fan Cloud Entropy")
class FanCloudEntropyProxy(algorithms.FanCloudEntropyFilter):
    """The entropy of every point and its four terms, as point arrays (paper section 5)."""


@fancloud_proxy("reduce", "Fan Cloud Reduce")
class FanCloudReduceProxy(algorithms.FanCloudReduceFilter):
    """Reduce a fan cloud, mesh or point set by entropy (paper sections 5 and 6)."""


@fancloud_proxy("selective", "Fan Cloud Selective Refine")
class FanCloudSelectiveRefineProxy(algorithms.FanCloudSelectiveRefineFilter):
    """Reduce, smooth, then refine only a region of interest (paper Figure 11)."""


@fancloud_proxy("refine", "Fan Cloud Refine")
class FanCloudRefineProxy(algorithms.FanCloudRefineFilter):
    """Refine a fan cloud, mesh or point set by entropy (paper section 7)."""


@fancloud_proxy("vdfc", "Fan Cloud View-Dependent Front",
                data_types=("vtkPointSet", "vtkImageData"), camera=True)
class FanCloudViewDependentProxy(algorithms.FanCloudViewDependentFilter):
    """The view-dependent front of the input for the camera properties (paper section 8).

    The input is a height field (a 2-d image), a fan cloud, a triangle mesh or points;
    the merge forest is built once, each update outputs the front for the camera.
    """

    def __init__(self, **params):
        super().__init__(**params)
        self._pv_camera = {name: default for name, _, default, _ in CAMERA_PROPERTIES}
        self.SetCamera(self.pv_camera())

    def pv_camera(self) -> tuple:
        """The camera properties as a camera tuple (position, focal point, up, angle)."""
        return tuple(self._pv_camera[name] for name, *_ in CAMERA_PROPERTIES)


#: the proxy classes, by verb
PROXIES = {cls.PV_VERB: cls for cls in (
    FanCloudProxy, FanCloudMeshProxy, FanCloudEntropyProxy, FanCloudReduceProxy,
    FanCloudSelectiveRefineProxy, FanCloudRefineProxy, FanCloudViewDependentProxy)}


# -- following a render view's camera (pvpython / the Python shell) ----------------------


def view_camera(view) -> tuple:
    """``(position, focal point, view up, view angle)`` of a render view."""
    cam = view.GetActiveCamera() if hasattr(view, "GetActiveCamera") else None
    if cam is not None:
        return (tuple(cam.GetPosition()), tuple(cam.GetFocalPoint()),
                tuple(cam.GetViewUp()), float(cam.GetViewAngle()))
    return (tuple(view.CameraPosition), tuple(view.CameraFocalPoint),
            tuple(view.CameraViewUp), float(view.CameraViewAngle))


def follow_view(front, view=None, live: bool = False):
    """Copy ``view``'s camera (and aspect) into the front's camera properties.

    ``front`` is a Fan Cloud View-Dependent Front proxy (``paraview.simple``),
    ``view`` a render view (default: the active one). The next ``Render(view)``
    shows the front of that camera. With ``live=True`` an observer on the view's
    camera copies it again whenever the view changes (the clipping range alone does
    not count), so each render after a camera move shows the new front. Returns a
    function that removes that observer (a no-op without ``live``).

    Example (pvpython or the Python shell)::

        front = FanCloudViewDependentFront(Input=mesh, EMax=0.002)
        Show(front, view)
        stop = fancloud_paraview.follow_view(front, view, live=True)
        view.CameraPosition = [0.1, 0.3, 0.4]; Render(view)   # a new front
        stop()
    """
    if view is None:
        from paraview.simple import GetActiveViewOrCreate

        view = GetActiveViewOrCreate("RenderView")
    last = {}

    def copy(*_):
        cam = view_camera(view)
        if cam == last.get("camera"):
            return
        last["camera"] = cam
        front.CameraPosition = list(cam[0])
        front.CameraFocalPoint = list(cam[1])
        front.CameraViewUp = list(cam[2])
        front.CameraViewAngle = cam[3]
        width, height = (list(view.ViewSize) + [0, 0])[:2]
        if width > 0 and height > 0:
            front.Aspect = width / height

    copy()
    if not live:
        return lambda: None
    camera = view.GetActiveCamera()
    tag = camera.AddObserver("ModifiedEvent", copy)
    return lambda: camera.RemoveObserver(tag)
