"""Triangle mesh inputs: vertices of any valence.

A vertex of valence 2,000 (the centre of a fan-triangulated 2,000-gon, the
apexes of a cone, the poles of a fine UV sphere) goes through every stage: no
fixed per-vertex cap (``build_edges`` raised beyond 256 neighbours, the local
Delaunay rings took at most 255 candidates).
"""

import numpy as np
import pytest
import pyvista as pv

from fancloud_vtk import (
    ViewDependentFanCloud,
    entropy,
    fan_cloud_of_mesh,
    fan_cloud_to_mesh,
    reduce,
    refine,
)
from fancloud_vtk.core import _mesh_kernels as MK

VALENCE = 2000
CAMERA = ((3.0, -4.0, 2.5), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0)


def fan_disc(n: int = VALENCE):
    """A 2,000-gon fan-triangulated from its centre (point 0, valence n)."""
    a = 2 * np.pi * np.arange(n) / n
    points = np.vstack([[0.0, 0.0, 0.0], np.column_stack([np.cos(a), np.sin(a), np.zeros(n)])])
    tri = np.array([[0, 1 + i, 1 + (i + 1) % n] for i in range(n)], np.int64)
    return points, tri


def bicone(n: int = VALENCE):
    """Two cones on one rim of n points: closed, both apexes (0 and n + 1) of valence n."""
    a = 2 * np.pi * np.arange(n) / n
    points = np.vstack([[0.0, 0.0, 1.0], np.column_stack([np.cos(a), np.sin(a), np.zeros(n)]),
                        [0.0, 0.0, -1.0]])
    top = [[0, 1 + i, 1 + (i + 1) % n] for i in range(n)]
    bottom = [[n + 1, 1 + (i + 1) % n, 1 + i] for i in range(n)]
    return points, np.array(top + bottom, np.int64)


def edges_of(tri):
    """The undirected edges (u < v) of triangles, sorted: the reference of build_edges."""
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


# -- high valence ------------------------------------------------------------------------


@pytest.mark.parametrize("shape", ["disc", "sphere"])
def test_build_edges_fits_any_valence(shape):
    """The edges of a mesh with a vertex of valence 2,000 (it raised beyond 256), and of an
    ordinary mesh the same as ever: every edge once, in order, every side mapped to it."""
    if shape == "disc":
        points, tri = fan_disc()
    else:
        s = pv.Sphere(theta_resolution=30, phi_resolution=30)
        points, tri = np.asarray(s.points), s.regular_faces.astype(np.int64)
    edge_uv, tri_edge, edge_off, edge_tri = MK.build_edges(tri, len(points))
    np.testing.assert_array_equal(edge_uv, edges_of(tri))
    for j in range(3):
        side = np.sort(np.column_stack([tri[:, j], tri[:, (j + 1) % 3]]), axis=1)
        np.testing.assert_array_equal(edge_uv[tri_edge[:, j]], side)
    assert edge_off[-1] == 3 * len(tri)
    if shape == "disc":
        assert len(edge_uv) == 2 * VALENCE


def test_delaunay_ring_of_a_vertex_of_valence_2000():
    """The local Delaunay ring of the disc's centre takes all its 2,000 neighbours (the
    candidates stopped at 255)."""
    points, tri = fan_disc()
    fc = fan_cloud_of_mesh(points, tri)
    counts, table = MK.delaunay_rings(fc.points, fc.normals, fc.offsets, fc.ring, fc.open,
                                      VALENCE, 2, np.zeros(0, np.int64), MK.NOT_STEEP)
    assert counts[0] == VALENCE
    assert sorted(table[0, :VALENCE]) == list(range(1, VALENCE + 1))


@pytest.mark.parametrize("rings", ["fans", "delaunay"])
def test_mesh_of_a_fan_disc(rings):
    points, tri = fan_disc()
    mesh = fan_cloud_to_mesh(fan_cloud_of_mesh(points, tri), rings=rings)
    assert {tuple(t) for t in np.sort(mesh.triangles, axis=1)} == \
        {tuple(t) for t in np.sort(tri, axis=1)}
    assert mesh.stats["boundary_edges"] == VALENCE
    assert mesh.stats["non_manifold_edges"] == 0


def test_a_vertex_of_valence_2000_through_every_stage():
    """Both apexes of the bicone keep their valence through entropy, reduce (and its
    mesh), refine and the view-dependent forest."""
    points, tri = bicone()
    fc = fan_cloud_of_mesh(points, tri)
    assert fc.fan_sizes[0] == VALENCE and fc.fan_sizes[-1] == VALENCE
    assert np.isfinite(entropy(fc).total).all()

    small = reduce(fc, n_points=1950)
    assert small.n_points == 1950 and small.fan_sizes.max() > 256
    mesh = fan_cloud_to_mesh(small, rings="fans")
    assert mesh.stats["holes"] == 0 and mesh.stats["non_manifold_edges"] == 0

    fine = refine(fc, n_points=2100, move=False, exact=True)
    assert fine.n_points == 2100 and fine.fan_sizes.max() > 256

    vd = ViewDependentFanCloud.build(fc)
    assert len(vd.roots) == 1 and vd.n_nodes == 2 * len(points) - 1
    front = vd.front_arrays(CAMERA, 0.05)
    assert len(front.triangles) > 0


def test_accessor_reduce_to_a_mesh_keeps_a_vertex_of_valence_2000():
    """The quick variant of the sphere below: the reduced disc's centre keeps more than 256
    neighbours into the mesh (build_edges raised)."""
    points, tri = fan_disc()
    disc = pv.PolyData.from_regular_faces(points, tri)
    small = disc.fancloud.reduce(n_points=1950, mesh=True)
    assert small.n_points == 1950
    assert int(small["mesh_non_manifold_edges"][0]) == 0
    assert str(small["fancloud_input"][0]) == "triangle mesh"


@pytest.mark.slow
def test_fine_uv_sphere_reduces_to_a_mesh():
    """The poles of a 1000 x 1002 UV sphere (valence 1,000) through reduce(mesh=True)."""
    sphere = pv.Sphere(theta_resolution=1000, phi_resolution=1002)
    small = sphere.fancloud.reduce(keep=0.176, mesh=True)
    assert small.n_points == round(0.176 * sphere.n_points)
    assert int(small["mesh_holes"][0]) == 0
    assert int(small["mesh_non_manifold_edges"][0]) == 0
