"""VTK-free core: numpy arrays in and out, one module per stage of the paper.

Numba kernels sit beside the stage that uses them (``_fan_kernels`` for
:mod:`.fans`, ``_normal_kernels`` for the normal orientation).
"""

import os as _os

if not {"NUMBA_THREADING_LAYER_PRIORITY", "NUMBA_THREADING_LAYER"} & set(_os.environ):
    # Try OpenMP and numba's own work queue before TBB: a too-old TBB on the
    # system only makes numba warn and fall back anyway.
    import numba as _numba

    _numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]
