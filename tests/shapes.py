"""Synthetic point clouds with known truth, for the tests and the benchmarks."""

from __future__ import annotations

import numpy as np


def sphere(n: int, seed: int = 0, radius: float = 1.0) -> np.ndarray:
    """Uniform random (Poisson) sampling of a sphere."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    return radius * p / np.linalg.norm(p, axis=1)[:, None]


def flat_patch(n_inside: int, n_border: int, seed: int = 0):
    """Random points inside the unit square (z = 0) plus points on its border.

    Returns (points, on_border mask).
    """
    rng = np.random.default_rng(seed)
    inside = np.c_[rng.uniform(0.0, 1.0, (n_inside, 2)), np.zeros(n_inside)]
    t = (np.arange(n_border) + 0.5) / n_border * 4.0
    side = np.floor(t).astype(int)
    f = t - side
    border = np.zeros((n_border, 3))
    border[side == 0, 0] = f[side == 0]
    border[side == 1, 0] = 1.0
    border[side == 1, 1] = f[side == 1]
    border[side == 2, 0] = 1.0 - f[side == 2]
    border[side == 2, 1] = 1.0
    border[side == 3, 1] = 1.0 - f[side == 3]
    pts = np.vstack([inside, border])
    mask = np.r_[np.zeros(n_inside, bool), np.ones(n_border, bool)]
    return pts, mask


def cube_surface(n: int, seed: int = 0) -> np.ndarray:
    """Uniform random points on the faces of the cube [-1, 1]^3 (sharp edges)."""
    rng = np.random.default_rng(seed)
    face = rng.integers(0, 6, n)
    uv = rng.uniform(-1.0, 1.0, (n, 2))
    p = np.empty((n, 3))
    axis = face // 2
    sign = np.where(face % 2 == 0, -1.0, 1.0)
    for a in range(3):
        sel = axis == a
        others = [b for b in range(3) if b != a]
        p[sel, a] = sign[sel]
        p[sel, others[0]] = uv[sel, 0]
        p[sel, others[1]] = uv[sel, 1]
    return p


def distance_to_cube(p: np.ndarray) -> np.ndarray:
    """Distance of points to the surface of the cube [-1, 1]^3."""
    q = np.abs(p) - 1.0
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(q.max(axis=1), 0.0)
    return np.abs(outside + inside)


def density_jump(n_dense: int, seed: int = 0, ratio: float = 10.0) -> np.ndarray:
    """A flat square whose sampling density jumps by ``ratio`` across x = 0.5."""
    rng = np.random.default_rng(seed)
    n_sparse = int(n_dense / ratio)
    dense = np.c_[rng.uniform(0.0, 0.5, n_dense), rng.uniform(0, 1, n_dense)]
    sparse = np.c_[rng.uniform(0.5, 1.0, n_sparse), rng.uniform(0, 1, n_sparse)]
    xy = np.vstack([dense, sparse])
    return np.c_[xy, 0.05 * np.sin(3 * xy[:, 0]) * np.cos(2 * xy[:, 1])]


def torus(n: int, seed: int = 0, big: float = 1.0, small: float = 0.35) -> np.ndarray:
    """Area-uniform random points on a torus (rejection sampling)."""
    rng = np.random.default_rng(seed)
    out = []
    while sum(len(o) for o in out) < n:
        u = rng.uniform(0, 2 * np.pi, 2 * n)
        v = rng.uniform(0, 2 * np.pi, 2 * n)
        keep = rng.uniform(0, 1, 2 * n) < (big + small * np.cos(v)) / (big + small)
        u, v = u[keep], v[keep]
        out.append(np.c_[(big + small * np.cos(v)) * np.cos(u),
                         (big + small * np.cos(v)) * np.sin(u), small * np.sin(v)])
    return np.vstack(out)[:n]
