"""Built-in data: sample files shipped inside other packages (nothing is downloaded)."""

from __future__ import annotations

import os


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
