"""Start-up shim for ParaView 5.11 on Python 3.11 (Debian bookworm's ``paraview`` package).

ParaView 5.11's Python plugin loader (``paraview/detail/pythonalgorithm.py``) calls
``inspect.getargspec``, which Python 3.11 removed: loading any Python plugin fails
with an ``AttributeError`` before the plugin's own code runs, so the fix cannot live
in the plugin file. Python imports ``sitecustomize`` at start-up from the first folder
of ``sys.path`` that has one; put this folder first on ``PYTHONPATH``::

    PYTHONPATH=/path/to/filters:$VENV/lib/python3.11/site-packages pvpython ...

The shim adds ``inspect.getargspec`` (as ``inspect.getfullargspec``, whose first four
fields are ``getargspec``'s) when it is missing, and then runs the ``sitecustomize``
it shadows, if there is one further down ``sys.path``. It does nothing on Pythons
that still have ``getargspec`` and is harmless outside ParaView.
"""

import inspect
import os
import sys

if not hasattr(inspect, "getargspec"):
    inspect.getargspec = inspect.getfullargspec


def _run_shadowed() -> None:
    here = os.path.dirname(os.path.abspath(__file__))
    for folder in sys.path:
        path = os.path.join(folder or os.getcwd(), "sitecustomize.py")
        if os.path.abspath(folder or os.getcwd()) == here or not os.path.isfile(path):
            continue
        with open(path, encoding="utf-8") as fh:
            code = compile(fh.read(), path, "exec")
        exec(code, {"__name__": "sitecustomize", "__file__": path})
        return


_run_shadowed()
