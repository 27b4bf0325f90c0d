"""Bad input to the hierarchy: damaged or foreign files, inconsistent arrays, tiny clouds, bad
regions of interest (review D1, D3, D5, D6)."""

import os
import subprocess
import sys

import numpy as np
import pytest
from shapes import sphere

from fancloud_vtk import Hierarchy, build_fans, fan_cloud_of_mesh, hierarchy, load, save
from fancloud_vtk.io import FileReadError

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OFFSETS = ("rem_off", "log_off", "ent_off", "coarse_off")


@pytest.fixture(scope="module")
def hier():
    return hierarchy(build_fans(sphere(2000, seed=5)), 200)


@pytest.fixture(scope="module")
def saved(hier, tmp_path_factory):
    """The hierarchy as .npz, and its arrays as read back by numpy."""
    path = tmp_path_factory.mktemp("h") / "h.npz"
    hier.save(path)
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    return path, data


def _arrays(h):
    return {k: v.copy() for k, v in h.arrays().items()}


def _from(h, arrays, weights=None):
    return Hierarchy.from_arrays(h.source, arrays, h.weights if weights is None else weights,
                                 h.method)


def _write(path, data, **changes):
    np.savez(path, **{**data, **changes})
    return path


# -- D1: offsets, lengths, order, finiteness -------------------------------------


def test_consistent_arrays_still_load(hier):
    back = _from(hier, _arrays(hier))
    for m in (200, 1100, 2000):
        a, b = hier.level(m), back.level(m)
        np.testing.assert_array_equal(a.ring, b.ring)
        np.testing.assert_array_equal(a.point_data["original_id"], b.point_data["original_id"])


def test_hierarchy_without_removals_still_loads():
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    h = hierarchy(fan_cloud_of_mesh(tet, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
    assert (h.n_points, h.n_min) == (4, 4)
    assert _from(h, _arrays(h)).level(4).n_points == 4


def _bad_offsets(off, mode):
    off = off.copy()
    mid = len(off) // 2
    if mode == "negative":
        off[mid] = -10**6
    elif mode == "huge":
        off[mid] = 10**9
    elif mode == "decreasing":
        off[mid] = off[mid + 1] + 1
    elif mode == "not_from_0":
        off += 1
    elif mode == "short":
        off = off[:-1]
    elif mode == "long":
        off = np.append(off, off[-1])
    elif mode == "wrong_end":
        off[-1] += 1
    return off


@pytest.mark.parametrize("mode", ["negative", "huge", "decreasing", "not_from_0", "short",
                                  "long", "wrong_end"])
@pytest.mark.parametrize("name", OFFSETS)
def test_bad_offsets_are_refused(hier, name, mode):
    arrays = _arrays(hier)
    arrays[name] = _bad_offsets(arrays[name], mode)
    with pytest.raises(ValueError, match=f"inconsistent hierarchy: {name} "):
        _from(hier, arrays)


def test_float_offsets_are_refused(hier):
    arrays = _arrays(hier)
    arrays["log_off"] = arrays["log_off"].astype(float)
    with pytest.raises(ValueError, match="inconsistent hierarchy: log_off must hold integers"):
        _from(hier, arrays)


@pytest.mark.parametrize(("name", "change"), [
    ("rem_open", lambda a: a[:-1]),
    ("ent_open", lambda a: a[:-1]),
    ("coarse_open", lambda a: np.append(a, False)),
    ("original_id", lambda a: np.append(a, 0)),
])
def test_arrays_of_the_wrong_length_are_refused(hier, name, change):
    arrays = _arrays(hier)
    arrays[name] = change(arrays[name])
    with pytest.raises(ValueError, match=f"{name}"):
        _from(hier, arrays)


def test_two_dimensional_flags_are_refused(hier):
    arrays = _arrays(hier)
    arrays["ent_open"] = arrays["ent_open"].reshape(1, -1)
    with pytest.raises(ValueError, match=r"inconsistent hierarchy: ent_open has shape \(1, "):
        _from(hier, arrays)


def test_repeated_removal_is_refused(hier):
    arrays = _arrays(hier)
    arrays["order"][1] = arrays["order"][0]
    with pytest.raises(ValueError, match="inconsistent hierarchy: order removes point .* more "
                                         "than once"):
        _from(hier, arrays)


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_non_finite_detail_is_refused(hier, value):
    arrays = _arrays(hier)
    arrays["detail"][7, 2] = value
    with pytest.raises(ValueError, match="inconsistent hierarchy: detail contain NaN"):
        _from(hier, arrays)


def test_non_finite_weights_are_refused(hier):
    with pytest.raises(ValueError, match="inconsistent hierarchy: weights contain NaN"):
        _from(hier, _arrays(hier), weights=(1.0, np.nan, 50.0, 0.0))


def test_ring_naming_a_removed_point_is_refused(hier):
    """Otherwise ``level(n_min)`` fails with an internal error."""
    arrays = _arrays(hier)
    kept = np.ones(hier.n_points, bool)
    kept[hier.order] = False
    first_kept = int(np.flatnonzero(kept)[0])
    at = arrays["coarse_off"][first_kept]
    arrays["coarse_ring"][at] = hier.order[-1]
    with pytest.raises(ValueError, match="inconsistent hierarchy: the coarsest level's ring"):
        _from(hier, arrays)


def test_ring_naming_its_own_point_is_refused(hier):
    arrays = _arrays(hier)
    arrays["ent_ring"][arrays["ent_off"][5]] = arrays["ent_x"][5]
    with pytest.raises(ValueError, match="inconsistent hierarchy: ent_ring of entry 5 "):
        _from(hier, arrays)


@pytest.mark.parametrize(("name", "value"), [
    ("h_log_off", -10**6), ("h_log_off", 10**9), ("h_rem_off", -10**6), ("h_rem_off", 10**9),
    ("h_ent_off", -10**6), ("h_ent_off", 10**9), ("h_coarse_off", 10**9),
])
def test_load_refuses_bad_offsets(saved, tmp_path, name, value):
    path, data = saved
    bad = data[name].copy()
    bad[len(bad) // 2] = value
    bad_path = _write(tmp_path / "bad.npz", data, **{name: bad})
    with pytest.raises(ValueError, match=f"inconsistent hierarchy: {name[2:]} ") as info:
        Hierarchy.load(bad_path)
    assert str(bad_path) in str(info.value)


def test_load_refuses_bad_offsets_in_vtp(hier, tmp_path):
    from vtkmodules.util.numpy_support import vtk_to_numpy

    from fancloud_vtk.algorithms.convert import hierarchy_to_vtk, write_vtp

    data = hierarchy_to_vtk(hier)
    log_off = vtk_to_numpy(data.GetFieldData().GetArray("hierarchy_log_off"))
    log_off[len(log_off) // 2] = -10**6  # a view: changes the VTK array
    path = tmp_path / "bad.vtp"
    write_vtp(data, path)
    with pytest.raises(FileReadError, match="inconsistent hierarchy: log_off decreases") as info:
        load(path)
    assert str(path) in str(info.value)


def test_corrupted_file_does_not_crash_level(saved, tmp_path):
    """The review's segfault: run it in a subprocess so that a crash fails this test only."""
    path, data = saved
    bad = data["h_log_off"].copy()
    bad[900] = -10**6
    bad_path = _write(tmp_path / "bad.npz", data, h_log_off=bad)
    code = (
        "import sys\n"
        "from fancloud_vtk import Hierarchy\n"
        "try:\n"
        f"    h = Hierarchy.load({str(bad_path)!r})\n"
        "except ValueError as exc:\n"
        "    print('refused:', exc)\n"
        "    sys.exit(0)\n"
        "h.level(1500)\n"
        "print('loaded')\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (REPO, os.environ.get("PYTHONPATH")) if p)}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, env=env)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert "refused: " in done.stdout and "inconsistent hierarchy" in done.stdout


# -- D3: unreadable, foreign and missing files -----------------------------------


def _truncated(path, src):
    raw = src.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])


def _flipped(path, src):
    raw = bytearray(src.read_bytes())
    for i in range(len(raw) // 3, len(raw) // 3 + 64):
        raw[i] ^= 0xFF
    path.write_bytes(bytes(raw))


def _foreign(path, src):
    with open(path, "wb") as fh:
        np.savez(fh, a=np.arange(3))


def _garbage(path, src):
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, np.uint8).tobytes())


def _single_array(path, src):
    with open(path, "wb") as fh:
        np.save(fh, np.arange(3))


def _empty(path, src):
    path.write_bytes(b"")


def _directory(path, src):
    path.mkdir()


@pytest.mark.parametrize("make", [_truncated, _flipped, _foreign, _garbage, _single_array,
                                  _empty, _directory])
def test_unreadable_npz_raises_file_read_error(saved, tmp_path, make):
    path = tmp_path / "h.npz"
    make(path, saved[0])
    with pytest.raises(FileReadError) as info:
        Hierarchy.load(path)
    assert isinstance(info.value, ValueError)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(("ext", "read"), [(".npz", Hierarchy.load), (".npz", load),
                                           (".vtp", load)])
def test_missing_file(tmp_path, ext, read):
    path = tmp_path / f"nothing{ext}"
    with pytest.raises(FileReadError, match="no such file") as info:
        read(path)
    # a ValueError like every unreadable file, and a FileNotFoundError as read_vtp raises
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, FileNotFoundError)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("make", [_empty, _directory])
def test_empty_or_directory_vtp_raises_file_read_error(tmp_path, make):
    path = tmp_path / "h.vtp"
    make(path, None)
    with pytest.raises(FileReadError, match="empty|directory") as info:
        load(path)
    assert str(path) in str(info.value)


def test_vtp_is_not_the_core_s_business(hier, tmp_path):
    """The core writes and reads .npz only; .vtp (VTK) is fancloud_vtk.save / load."""
    path = tmp_path / "h.vtp"
    with pytest.raises(ValueError, match=r"fancloud_vtk\.save"):
        hier.save(path)
    assert not path.exists()
    save(hier, path)
    with pytest.raises(ValueError, match=r"fancloud_vtk\.load"):
        Hierarchy.load(path)
    with pytest.raises(ValueError, match=r"\.npz \(Hierarchy\.save\) or \.vtp"):
        hier.save(tmp_path / "h.txt")
    with pytest.raises(ValueError, match=r"\.npz \(Hierarchy\.load\) or \.vtp"):
        Hierarchy.load(tmp_path / "h.txt")


def test_truncated_npz_is_a_value_error(saved, tmp_path):
    path = tmp_path / "h.npz"
    _truncated(path, saved[0])
    with pytest.raises(ValueError, match="not a readable .npz file"):
        Hierarchy.load(path)


def test_foreign_npz_names_a_missing_array(saved, tmp_path):
    path = tmp_path / "h.npz"
    _foreign(path, saved[0])
    with pytest.raises(ValueError, match="not a saved hierarchy"):
        Hierarchy.load(path)


# -- D5: fewer than 4 points -------------------------------------------------------


def test_hierarchy_of_a_triangle():
    fc = fan_cloud_of_mesh(np.eye(3), [[0, 1, 2]])
    with pytest.raises(ValueError, match="a fan cloud needs at least 4"):
        hierarchy(fc)


# -- D6: regions of interest ---------------------------------------------------------


@pytest.mark.parametrize(("region", "match"), [
    (((np.nan, 0.0, 1.0), 0.5), "center must be finite"),
    (((np.inf, 0.0, 1.0), 0.5), "center must be finite"),
    (((0.0, 0.0, 1.0), np.inf), "radius must be finite"),
    (((0.0, 0.0, 1.0), np.nan), "radius > 0"),
    ((np.nan, 1, 0, 1, 0, 1), "NaN"),
    ((0, 1, 0, 1, 0, np.nan), "NaN"),
    ((1, 0, 1, 0, 1, 0), "min <= max"),
    ((0, 1, 0, 1, 1, 0.5), "min <= max"),
    (np.array([0, 1, 1, 0, 0, 1.0]), "min <= max"),
])
def test_bad_regions_are_refused(hier, region, match):
    with pytest.raises(ValueError, match=match):
        hier.selective(region)


def test_open_and_flat_boxes_are_regions(hier):
    every = hier.selective((-np.inf, np.inf, -np.inf, np.inf, -np.inf, np.inf))
    assert every.n_points == hier.n_points
    flat = hier.selective((0, 0, -2, 2, -2, 2))
    assert flat.n_points == hier.n_min


def test_an_edited_base_with_nan_points_is_refused(hier):
    """A coarse level edited in place (a smoothing gone wrong) must not give NaN points."""
    from fancloud_vtk import FanCloudInputError

    base = hier.level(500)
    base.points[3] = np.nan
    with pytest.raises(FanCloudInputError, match="points contain NaN or infinite"):
        hier.level(1500, base=base)
