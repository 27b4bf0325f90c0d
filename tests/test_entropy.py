"""Entropy (paper section 5): the four terms on shapes with known truth."""

import numpy as np
import pytest
from shapes import flat_patch

from fancloud_vtk import build_fans, entropy, fan_cloud_of_mesh, fan_cloud_to_mesh
from fancloud_vtk.core.model import FanCloud


def fibonacci_sphere(n: int) -> np.ndarray:
    """Nearly uniform points on the unit sphere (a regular sampling)."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5**0.5) * i
    return np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)]


@pytest.fixture(scope="module")
def sphere_fans():
    return build_fans(fibonacci_sphere(4000))


def test_sphere_curvature_terms_nearly_constant(sphere_fans):
    e = entropy(sphere_fans)
    # the normal turns at the same rate everywhere: M_curv * dbar is ~ the mean d_j / radius
    assert e.curv.std() < 0.05 * e.curv.mean()
    assert abs(e.curv.mean() - e.mean_distance) < 0.05 * e.mean_distance
    # ... so its change between neighbours is small against it, everywhere
    assert e.cc.mean() < 0.1 * e.curv.mean()
    assert e.cc.max() < 0.15 * e.curv.mean()
    assert e.dist.std() < 0.1 and abs(e.dist.mean() - 1.0) < 1e-9


def test_plane_has_no_curvature():
    pts, _ = flat_patch(3000, 200, seed=1)
    e = entropy(build_fans(pts))
    assert np.abs(e.curv).max() < 1e-12
    assert np.abs(e.cc).max() < 1e-12
    assert np.all(e.dist > 0)


def test_scale_invariant(sphere_fans):
    fc = sphere_fans
    big = FanCloud(fc.points * 1000.0, fc.offsets, fc.ring, fc.normals, fc.open, fc.rotated)
    for w in [(1, 1, 50, 0), (1, 0, 0, 0), (0, 1, 0, 0)]:
        np.testing.assert_allclose(entropy(big, w).total, entropy(fc, w).total, rtol=1e-9)


def test_colour_edge_raises_colour_term_exactly_along_it():
    pts, _ = flat_patch(3000, 200, seed=2)
    red = pts[:, 0] < 0.5
    rgb = np.where(red[:, None], [255, 0, 0], [0, 0, 255]).astype(np.uint8)
    fc = build_fans(pts, point_data={"RGB": rgb})
    e = entropy(fc, (1, 1, 50, 1))
    across = np.array([np.any(red[fc.neighbours(i)] != red[i]) for i in range(fc.n_points)])
    assert across.any() and not across.all()
    assert np.all(e.col[across] > 0)
    assert np.all(e.col[~across] == 0)
    # the total carries it
    e0 = entropy(fc, (1, 1, 50, 0))
    np.testing.assert_allclose(e.total - e0.total, e.col)


def _raw_terms(fc: FanCloud, e):
    """Unscaled M_dist and M_curv (the scaling uses each cloud's own mean distance)."""
    return e.dist * e.mean_distance, e.curv / e.mean_distance, e.cc / e.mean_distance**2


def test_mesh_and_fan_cloud_agree_where_the_rings_agree():
    fc = build_fans(fibonacci_sphere(3000))
    mesh = fan_cloud_to_mesh(fc)
    e_fans = entropy(fc)
    e_mesh = entropy(mesh)  # the mesh's one-rings are the fans, its normals the fan normals
    one_rings = fan_cloud_of_mesh(mesh.points, mesh.triangles, normals=mesh.normals)
    same = np.array([set(fc.neighbours(i)) == set(one_rings.neighbours(i))
                     for i in range(fc.n_points)])
    assert same.mean() > 0.5
    d1, c1, cc1 = _raw_terms(fc, e_fans)
    d2, c2, cc2 = _raw_terms(one_rings, e_mesh)
    np.testing.assert_allclose(d1[same], d2[same], rtol=1e-12)
    np.testing.assert_allclose(c1[same], c2[same], rtol=1e-12)
    # M_cc also needs the neighbours' rings to agree
    both = same & np.array([same[fc.neighbours(i)].all() for i in range(fc.n_points)])
    assert both.any()
    np.testing.assert_allclose(cc1[both], cc2[both], rtol=1e-9, atol=1e-12)


def test_terms_are_returned_on_their_own(sphere_fans):
    e = entropy(sphere_fans, (2, 3, 5, 0))
    np.testing.assert_allclose(e.total, 2 * e.dist + 3 * e.curv + 5 * e.cc)
    assert set(e.as_dict()) == {"entropy", "entropy_dist", "entropy_curv", "entropy_cc",
                                "entropy_col"}
    assert np.all(e.col == 0)


@pytest.mark.parametrize("weights", [(1, 1, 50), (1, 1, 50, 0, 0), (1, -1, 0, 0),
                                     (0, 0, 0, 0), (1, np.nan, 0, 0), "1,1,50,0"])
def test_bad_weights(sphere_fans, weights):
    with pytest.raises(ValueError, match="weights"):
        entropy(sphere_fans, weights)


def test_bad_colours(sphere_fans):
    n = sphere_fans.n_points
    with pytest.raises(ValueError, match="rows"):
        entropy(sphere_fans, colors=np.zeros((n - 1, 3)))
    with pytest.raises(ValueError, match="shape"):
        entropy(sphere_fans, colors=np.zeros((n, 2)))
    with pytest.raises(ValueError, match="no colours"):
        entropy(sphere_fans, (1, 1, 50, 1))
    with pytest.raises(ValueError, match="no point array"):
        entropy(sphere_fans, colors="RGB")
    with pytest.raises(TypeError, match="FanCloud"):
        entropy(np.zeros((10, 3)))


def test_input_not_modified(sphere_fans):
    before = [a.copy() for a in (sphere_fans.points, sphere_fans.ring, sphere_fans.normals)]
    rgb = np.full((sphere_fans.n_points, 3), 0.5)
    rgb_before = rgb.copy()
    entropy(sphere_fans, (1, 1, 50, 1), colors=rgb)
    for a, b in zip(before, (sphere_fans.points, sphere_fans.ring, sphere_fans.normals),
                    strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(rgb, rgb_before)
