"""No numba kernel launches a parallel region from inside another one's parallel loop.

Such a nested launch runs, but every call pays for a thread team: a per-removal helper
that was ``parallel=True`` made the reduction of the cow's mesh take 0.17 s on one thread
and 23 s on two (the bunny's, ``method="error"``: 1 s and 74 s). numba's ``workqueue``
threading layer refuses a nested launch (it aborts the process), so the stages run here in
a child process on that layer with two threads.
"""

import os
import subprocess
import sys
import textwrap

import pytest

from fancloud_vtk.data import pymeshlab_sample

SCRIPT = textwrap.dedent(
    """
    import warnings
    import numpy as np
    import fancloud_vtk as F
    from fancloud_vtk.io import read_point_cloud

    warnings.simplefilter("ignore")  # the cow's own mesh self-intersects: not the point here
    cloud = read_point_cloud({path!r})
    used = np.unique(cloud.faces)
    fans = F.build_fans(cloud.points[used].astype(float))
    F.fan_cloud_to_mesh(fans)
    F.refine(fans, factor=1.5)
    mesh = F.fan_cloud_of_mesh(cloud.points, cloud.faces)
    for method in ("entropy", "error"):
        F.reduce(mesh, keep=0.3, method=method)
        F.reduce(fans, keep=0.3, method=method)
    import numba
    print("layer", numba.threading_layer(), numba.get_num_threads())
    """
)


@pytest.mark.skipif(os.cpu_count() < 2, reason="a nested launch needs two numba threads")
def test_no_kernel_launches_a_parallel_region_inside_another():
    env = dict(os.environ, NUMBA_THREADING_LAYER="workqueue", NUMBA_NUM_THREADS="2")
    run = subprocess.run([sys.executable, "-c", SCRIPT.format(path=pymeshlab_sample("cow.obj"))],
                         env=env, capture_output=True, text=True, timeout=1800)
    assert "Concurrent access has been detected" not in run.stderr, run.stderr[-2000:]
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split()[-3:] == ["layer", "workqueue", "2"]
