"""The Examples sections of the public docstrings run and give what they show."""

import doctest
import importlib

import pytest

MODULES = [
    "fancloud_vtk.core.fans",
    "fancloud_vtk.core.mesh",
    "fancloud_vtk.core.entropy",
    "fancloud_vtk.core.reduction",
    "fancloud_vtk.core.hierarchy",
    "fancloud_vtk.core.verbs",
    "fancloud_vtk.core.refinement",
    "fancloud_vtk.core.vdfc",
    "fancloud_vtk.algorithms.convert",
    "fancloud_vtk.algorithms.fans",
    "fancloud_vtk.algorithms.mesh",
    "fancloud_vtk.algorithms.entropy",
    "fancloud_vtk.algorithms.reduce",
    "fancloud_vtk.algorithms.refine",
    "fancloud_vtk.algorithms.vdfc",
    "fancloud_vtk.accessor",
    "fancloud_vtk.distributed",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} docstring example(s) of {name} failed"
    if name.endswith(("reduction", "entropy", "reduce", "refinement", "refine", "vdfc")):
        assert result.attempted > 0, f"{name} has no runnable example"
