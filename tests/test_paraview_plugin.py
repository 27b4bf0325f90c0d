"""The ParaView plugin (filters/fancloud_paraview.py) declares exactly the parameter tables.

Runs without ParaView: the plugin is imported with a stand-in ``paraview.util.vtkAlgorithm``
whose ``smproxy``/``smproperty``/``smdomain``/``smhint`` record what is declared, the way
ParaView's do (domains and hints attach to the next property decorator; a proxy collects
the decorated functions of its class's own ``__dict__``, sorted by attribute name). Every
filter must have one property per row of its ``VERB_PARAMS`` table, in the table's order,
with its type, default, range, choices and documentation, and the view-dependent front
its camera properties. The real ParaView check is ``filters/check_paraview.py``
(``.ci/paraview``).
"""

from __future__ import annotations

import importlib.util
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from fancloud_vtk import algorithms
from fancloud_vtk.params import VERB_PARAMS

PLUGIN = Path(__file__).resolve().parent.parent / "filters" / "fancloud_paraview.py"
INT_MAX = 2**31 - 1

#: verb -> (filter class, menu label) the plugin must offer
EXPECTED = {
    "fans": (algorithms.FanCloudFilter, "Fan Cloud"),
    "mesh": (algorithms.FanCloudMeshFilter, "Fan Cloud Mesh"),
    "entropy": (algorithms.FanCloudEntropyFilter, "Fan Cloud Entropy"),
    "reduce": (algorithms.FanCloudReduceFilter, "Fan Cloud Reduce"),
    "selective": (algorithms.FanCloudSelectiveRefineFilter, "Fan Cloud Selective Refine"),
    "refine": (algorithms.FanCloudRefineFilter, "Fan Cloud Refine"),
    "vdfc": (algorithms.FanCloudViewDependentFilter, "Fan Cloud View-Dependent Front"),
}
CAMERA = ("CameraPosition", "CameraFocalPoint", "CameraViewUp", "CameraViewAngle")


# -- a stand-in for paraview.util.vtkAlgorithm ----------------------------------------------


def _pending(obj, key: str) -> list:
    items = obj.__dict__.get(key) if isinstance(obj, type) else getattr(obj, key, None)
    if items is None:
        items = []
        setattr(obj, key, items)
    return items


def _take(obj, key: str) -> list:
    items = list(_pending(obj, key))
    _pending(obj, key).clear()
    return items


def _domain(kind: str, **attrs):
    def decorate(obj):
        if kind == "xml":
            ET.fromstring(attrs["xml"])  # ParaView parses it: it must be well-formed
        _pending(obj, "_fake_domains").append((kind, attrs))
        return obj

    return decorate


def _property(kind: str, **attrs):
    def decorate(obj):
        record = {"kind": kind, **attrs, "domains": _take(obj, "_fake_domains"),
                  "hints": _take(obj, "_fake_hints")}
        _pending(obj, "_fake_properties").append(record)
        return obj

    return decorate


class smdomain:
    @staticmethod
    def intrange(**kw):
        return _domain("IntRangeDomain", **kw)

    @staticmethod
    def doublerange(**kw):
        return _domain("DoubleRangeDomain", **kw)

    @staticmethod
    def xml(xmlstr):
        return _domain("xml", xml=xmlstr)

    @staticmethod
    def datatype(dataTypes, **kw):
        return _domain("DataTypeDomain", dataTypes=list(dataTypes), **kw)


class smhint:
    @staticmethod
    def xml(xmlstr):
        def decorate(obj):
            ET.fromstring(xmlstr)
            _pending(obj, "_fake_hints").append(xmlstr)
            return obj

        return decorate


class smproperty:
    @staticmethod
    def intvector(**kw):
        return _property("IntVectorProperty", **kw)

    @staticmethod
    def doublevector(**kw):
        return _property("DoubleVectorProperty", **kw)

    @staticmethod
    def stringvector(**kw):
        return _property("StringVectorProperty", **kw)

    @staticmethod
    def input(**kw):
        return _property("InputProperty", **kw)


class smproxy:
    @staticmethod
    def filter(**kw):
        def decorate(cls):
            props = []
            for key in sorted(cls.__dict__):  # ParaView: the class's own methods, by name
                value = cls.__dict__[key]
                declared = getattr(value, "_fake_properties", None) if callable(value) else None
                if declared:
                    assert len(declared) == 1, f"{key}: more than one property"
                    props.append((key, declared[0]))
            cls._fake_proxy = {**kw, "properties": props,
                               "class_properties": _take(cls, "_fake_properties"),
                               "hints": _take(cls, "_fake_hints")}
            return cls

        return decorate


@pytest.fixture(scope="module")
def plugin():
    fake = types.ModuleType("paraview.util.vtkAlgorithm")
    fake.smproxy, fake.smproperty, fake.smdomain, fake.smhint = smproxy, smproperty, \
        smdomain, smhint
    stubs = {"paraview": types.ModuleType("paraview"),
             "paraview.util": types.ModuleType("paraview.util"),
             "paraview.util.vtkAlgorithm": fake}
    saved = {name: sys.modules.get(name) for name in stubs}
    sys.modules.update(stubs)
    try:
        spec = importlib.util.spec_from_file_location("fancloud_paraview_under_test", PLUGIN)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module
    finally:
        for name, old in saved.items():
            if old is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = old


def _proxy_classes(plugin):
    return {cls.PV_VERB: cls for cls in vars(plugin).values()
            if isinstance(cls, type) and "_fake_proxy" in cls.__dict__}


def _domains(record, kind):
    return [attrs for k, attrs in record["domains"] if k == kind]


def _xml_domains(record):
    return [ET.fromstring(a["xml"]) for a in _domains(record, "xml")]


def _documentation(record) -> str:
    docs = [e.text for e in _xml_domains(record) if e.tag == "Documentation"]
    assert len(docs) == 1, record["name"]
    return docs[0]


def _as_list(values):
    return list(values) if isinstance(values, (list, tuple)) else [values]


# -- the tests ------------------------------------------------------------------------------


def test_one_proxy_per_filter(plugin):
    proxies = _proxy_classes(plugin)
    assert set(proxies) == set(EXPECTED)
    assert set(plugin.PROXIES) == set(EXPECTED)
    for verb, cls in proxies.items():
        base, label = EXPECTED[verb]
        assert issubclass(cls, base), verb  # the algorithm is the filter's own code
        info = cls._fake_proxy
        assert info["label"] == label == cls.PV_LABEL
        assert info["name"] == label.replace(" ", "").replace("-", "")
        assert info["hints"] == ['<ShowInMenu category="Fan Clouds"/>']
        (inp,) = info["class_properties"]
        assert inp["kind"] == "InputProperty" and inp["name"] == "Input"
        (types_,) = _domains(inp, "DataTypeDomain")
        assert "vtkPointSet" in types_["dataTypes"]
    assert "vtkImageData" in _domains(proxies["vdfc"]._fake_proxy["class_properties"][0],
                                      "DataTypeDomain")[0]["dataTypes"]


@pytest.mark.parametrize("verb", sorted(EXPECTED))
def test_properties_are_the_table(plugin, verb):
    cls = _proxy_classes(plugin)[verb]
    props = [record for _, record in cls._fake_proxy["properties"]]
    table = VERB_PARAMS[verb]
    extra = CAMERA if verb == "vdfc" else ()
    # exactly the table's rows, in its order (ParaView sorts by attribute name)
    assert [p["name"] for p in props] == [p.vtk_name for p in table] + list(extra)
    for param, record in zip(table, props, strict=False):
        where = f"{verb}.{param.name}"
        assert record["command"] in cls.__dict__, where
        assert param.doc in _documentation(record), where
        default = _as_list(record["default_values"])
        rng = _domains(record, "IntRangeDomain") + _domains(record, "DoubleRangeDomain")
        xml_tags = [e.tag for e in _xml_domains(record)]
        if param.kind == "int":
            assert record["kind"] == "IntVectorProperty", where
            assert default == [param.default], where
            (r,) = rng
            assert (r["min"], r["max"]) == (param.range[0], min(param.range[1], INT_MAX)), where
        elif param.kind == "bool":
            assert record["kind"] == "IntVectorProperty", where
            assert default == [int(param.default)], where
            assert "BooleanDomain" in xml_tags and not rng, where
        elif param.kind == "float":
            assert record["kind"] == "DoubleVectorProperty", where
            assert default == [param.default], where
            (r,) = rng
            assert (r["min"], r["max"]) == param.range, where
        elif param.kind == "vector":
            assert record["kind"] == "DoubleVectorProperty", where
            assert record["number_of_elements"] == param.size == len(default), where
            assert tuple(default) == param.default, where
            (r,) = rng
            assert r["min"] == [param.range[0]] * param.size, where
            assert r["max"] == [param.range[1]] * param.size, where
        elif param.kind == "choice":
            assert record["kind"] == "StringVectorProperty", where
            assert default == [param.default], where
            (lst,) = [e for e in _xml_domains(record) if e.tag == "StringListDomain"]
            assert tuple(s.get("value") for s in lst) == param.choices, where
        elif param.kind == "str":
            assert record["kind"] == "StringVectorProperty", where
            assert param.name == "color_array", f"{where}: a new string parameter"
            (arrays,) = [e for e in _xml_domains(record) if e.tag == "ArrayListDomain"]
            assert arrays.get("none_string") == plugin.AUTOMATIC
            # the list is the input's point arrays: the Input property has that domain
            (inp,) = cls._fake_proxy["class_properties"]
            inputs = [e for e in _xml_domains(inp) if e.tag == "InputArrayDomain"]
            assert [(e.get("name"), e.get("attribute_type")) for e in inputs] == \
                [(arrays.get("input_domain_name"), "point")], where
            assert default == [plugin.AUTOMATIC] and param.default == "", where
            assert record["hints"] == ["<NoDefault/>"], where
        else:
            pytest.fail(f"{where}: kind {param.kind!r} not checked")
        if param.kind != "vector":
            assert record["number_of_elements"] == 1, where


def test_front_camera_properties(plugin):
    cls = _proxy_classes(plugin)["vdfc"]
    props = {record["name"]: record for _, record in cls._fake_proxy["properties"]}
    for name in CAMERA:
        record = props[name]
        assert record["kind"] == "DoubleVectorProperty"
        assert record["number_of_elements"] == (1 if name == "CameraViewAngle" else 3)
        assert "follow_view" in _documentation(record)
    (angle,) = _domains(props["CameraViewAngle"], "DoubleRangeDomain")
    assert 0 < angle["min"] < angle["max"] < 180


def test_setters_forward_to_the_filter(plugin):
    """ParaView calls the commands with its own value types: ints for bools, '(automatic)'."""
    proxies = _proxy_classes(plugin)
    fans = proxies["fans"]()
    commands = {rec["name"]: rec["command"] for _, rec in type(fans)._fake_proxy["properties"]}
    getattr(fans, commands["MaxAngle"])(45.0)
    getattr(fans, commands["RotateSharpEdges"])(0)
    getattr(fans, commands["Rule"])("paper")
    assert (fans.max_angle, fans.rotate_sharp_edges, fans.rule) == (45.0, False, "paper")
    with pytest.raises(ValueError):
        getattr(fans, commands["K"])(2)  # the table's range, checked by the filter
    red = proxies["reduce"]()
    commands = {rec["name"]: rec["command"] for _, rec in type(red)._fake_proxy["properties"]}
    getattr(red, commands["Weights"])(1.0, 0.0, 0.0, 0.0)
    getattr(red, commands["ColorArray"])("RGB")
    assert red.weights == (1.0, 0.0, 0.0, 0.0) and red.color_array == "RGB"
    getattr(red, commands["ColorArray"])(plugin.AUTOMATIC)
    assert red.color_array == ""
    front = proxies["vdfc"]()
    commands = {rec["name"]: rec["command"] for _, rec in type(front)._fake_proxy["properties"]}
    assert front.GetCamera().view_angle == 30.0
    getattr(front, commands["CameraPosition"])(1.0, 2.0, 3.0)
    getattr(front, commands["CameraViewAngle"])(40.0)
    cam = front.GetCamera()
    assert cam.position == (1.0, 2.0, 3.0) and cam.view_angle == 40.0
