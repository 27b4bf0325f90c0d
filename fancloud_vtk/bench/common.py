"""What every benchmark shares: sizes, the synthetic points, progress lines, JSON-safe values.

Light on purpose (numpy only): the subprocesses of :mod:`fancloud_vtk.bench.harness`
and the measures of :mod:`fancloud_vtk.bench.metrics` import it.
"""

from __future__ import annotations

import hashlib
import sys

import numpy as np

K = 6  #: neighbours per fan in every measurement (the paper's default)
WARMUP_POINTS = 2_000  #: size of the small cloud for warm-up and first-call runs

_SUFFIXES = {"": 1, "k": 1_000, "m": 1_000_000}


# -- sizes and data ----------------------------------------------------------------

def parse_size(text: str) -> int:
    """``'100k'`` -> 100000, ``'4M'`` -> 4000000, ``'2500'`` -> 2500, ``'1.5M'`` too."""
    s = text.strip().lower()
    suffix = s[-1:] if s[-1:] in ("k", "m") else ""
    try:
        value = float(s[: len(s) - len(suffix)]) * _SUFFIXES[suffix]
    except ValueError as exc:
        raise ValueError(f"not a size: {text!r} (examples: 5000, 100k, 1M)") from exc
    if value < 1 or not float(value).is_integer():
        raise ValueError(f"not a whole positive number of points: {text!r}")
    return int(value)


def parse_sizes(text: str) -> list[int]:
    """A comma-separated list of sizes: ``'100k,1M,4M'``."""
    sizes = [parse_size(part) for part in text.split(",") if part.strip()]
    if not sizes:
        raise ValueError("no sizes given")
    return sizes


def size_label(n: int) -> str:
    """Short label of a size: 100000 -> '100k', 4000000 -> '4M', 2500 -> '2,500'."""
    for div, suffix in ((1_000_000, "M"), (1_000, "k")):
        if n >= div and n % div == 0:
            return f"{n // div}{suffix}"
    return f"{n:,}"


def bumpy_radius(d: np.ndarray) -> np.ndarray:
    """Radius of the bumpy sphere in the unit directions ``d``: 1 + 0.1 sin5x sin5y sin5z."""
    return 1.0 + 0.1 * np.sin(5.0 * d[:, 0]) * np.sin(5.0 * d[:, 1]) * np.sin(5.0 * d[:, 2])


SHAPES = {
    "bumpy": "bumpy sphere r = 1 + 0.1 sin5x sin5y sin5z",
    "sphere": "unit sphere",
}


def surface_points(n: int, seed: int = 0, shape: str = "bumpy", chunk: int = 1 << 20):
    """``n`` random points on a smooth closed surface, in random order (reproducible).

    Directions are normalised standard normal vectors (uniform on the
    sphere), drawn in chunks to keep the memory low; ``'bumpy'`` modulates
    the radius smoothly (:func:`bumpy_radius`). The rows are then shuffled.
    """
    if shape not in SHAPES:
        raise ValueError(f"shape must be one of {sorted(SHAPES)}, got {shape!r}")
    rng = np.random.default_rng(seed)
    out = np.empty((n, 3))
    for lo in range(0, n, chunk):
        d = rng.normal(size=(min(chunk, n - lo), 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        if shape == "bumpy":
            d *= bumpy_radius(d)[:, None]
        out[lo : lo + len(d)] = d
    return out[rng.permutation(n)]


def data_label(n: int, shape: str, seed: int) -> str:
    """How the points of a row were made."""
    return f"{SHAPES[shape]}, {size_label(n)} random points (seed {seed}, shuffled)"


def digest(*arrays) -> str:
    """sha256 of arrays (dtype, shape and bytes)."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


# -- progress and values -------------------------------------------------------------


def _read(path: str) -> str:
    """A text file's contents, or '' when it cannot be read (``/proc`` files off Linux)."""
    try:
        with open(path) as f:
            return f.read()
    except OSError:
        return ""


def _log(quiet: bool, message: str) -> None:
    """A progress line on stderr (``[bench] message``) unless ``quiet``."""
    if not quiet:
        print(f"[bench] {message}", file=sys.stderr, flush=True)


def _short(exc: BaseException, limit: int = 240) -> str:
    """``Type: message`` on one line, without the file path ImportError appends, shortened."""
    import re

    text = " ".join(str(exc).split())
    text = re.sub(r"\s*\((?:unknown location|/[^)]*)\)$", "", text)
    if len(text) > limit:
        text = text[: limit - 3] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _plain(value):
    """numpy scalars and arrays to Python objects (for JSON), recursively through containers."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value.item() if isinstance(value, np.generic) else value
