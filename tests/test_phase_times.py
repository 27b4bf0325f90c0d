"""scripts/phase_times.py: the phases it times are the kernels the calls really run."""

import importlib.util
from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def phase_times():
    path = Path(__file__).resolve().parent.parent / "scripts" / "phase_times.py"
    spec = importlib.util.spec_from_file_location("phase_times", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("call, amount, phases, n_out", [
    ("reduce", 0.5, {"reform_batch", "commit_batch", "accept_batch", "init_state"}, 1500),
    ("refine", 2.0, {"plan_batch", "commit_batch", "round_accept", "_delaunay"}, 6000),
])
def test_phase_times_split_the_call_and_put_the_kernels_back(phase_times, call, amount, phases,
                                                             n_out):
    from fancloud_vtk.core import reduction, refinement

    before = (reduction.RK.reform_batch, refinement.FK.plan_batch, refinement._delaunay)
    total, times, calls, result = phase_times.phase_times(call, 3000, amount)
    assert result.n_points == n_out
    assert phases <= set(times)
    assert all(calls[name] >= 1 for name in phases)
    assert 0 < sum(times.values()) <= total
    assert (reduction.RK.reform_batch, refinement.FK.plan_batch, refinement._delaunay) == before


def test_phase_times_refuses_an_unknown_call(phase_times):
    with pytest.raises(ValueError, match="call must be 'reduce' or 'refine'"):
        phase_times.phase_times("smooth", 3000, 0.5)
