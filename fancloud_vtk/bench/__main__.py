"""``python -m fancloud_vtk.bench MODE ...``: the same as ``fancloud bench MODE ...``."""

import sys

from fancloud_vtk.bench import main

sys.exit(main())
