"""What the ``fancloud`` command and the demo print: the progress bar and the summaries.

Its own module so that the demo (which the command runs) and the command share it
without importing each other.
"""

from __future__ import annotations

import time


class _Progress:
    """A tqdm bar driven by the core's progress callback (hidden when not a terminal).

    The core may call back thousands of times a second: the bar is redrawn only when the
    shown percentage or message changes, and at most once every ``interval`` seconds; a
    change held back is drawn by the next call after the interval, or by :meth:`close`.
    """

    #: the shortest time between two redraws (seconds)
    interval = 0.1
    #: the clock of the throttle (a test may set its own)
    clock = staticmethod(time.monotonic)

    def __init__(self, desc: str, quiet: bool):
        from tqdm import tqdm

        self.bar = tqdm(total=100, desc=desc, disable=True if quiet else None, leave=False,
                        bar_format="{l_bar}{bar}| {elapsed}")
        self._shown = None  # (percent, message) drawn last
        self._pending = None  # a newer state not drawn yet
        self._drawn_at = -float("inf")

    def __call__(self, fraction: float, message: str) -> bool:
        if self.bar.disable:
            return False
        state = (round(100 * fraction), message)
        if state == self._shown:
            self._pending = None
            return False
        now = self.clock()
        if now - self._drawn_at < self.interval:
            self._pending = state
        else:
            self._draw(state, now)
        return False

    def _draw(self, state, now: float) -> None:
        percent, message = state
        if self._shown is None or message != self._shown[1]:
            self.bar.set_description(message, refresh=False)
        self.bar.n = percent
        self.bar.refresh()
        self._shown, self._pending, self._drawn_at = state, None, now

    def close(self):
        if self._pending is not None:  # the final state, even if drawn just before
            self._draw(self._pending, self.clock())
        self.bar.close()


def _dropped(fc) -> int | None:
    """How many unreferenced vertices of a mesh input were dropped (None: not a mesh)."""
    from fancloud_vtk.core.entropy import UNREFERENCED_DROPPED

    return fc.info.get(UNREFERENCED_DROPPED)


def _print_mesh_summary(mesh, elapsed, path=None, extra=()) -> None:
    """The stage counts (and per point) and the checks of a mesh; ``extra``: more rows."""
    s = mesh.stats
    n = max(len(mesh.points), 1)
    rows = [("points", f"{len(mesh.points):,}")]
    for key, label in (("fan_triangles", "fan triangles"), ("distinct", "distinct"),
                       ("after_superfluous", "after superfluous removal"),
                       ("grown", "grown 2-manifold"), ("final", "final (holes closed)")):
        if key in s:  # (a mesh grown in tiles has no counts of the stages in between)
            rows.append((label, f"{s[key]:,} ({s[key] / n:.3f} per point)"))
    for key in ("normals_flipped", "holes_closed", "points_inserted", "self_intersections_removed",
                "boundary_edges", "holes", "non_manifold_edges", "non_manifold_vertices",
                "inconsistent_edges", "self_intersections", "unused_points", "outliers",
                "euler_characteristic"):
        if key in s:  # (a mesh read back from a file may lack the newer counts)
            rows.append((key.replace("_", " "), f"{s[key]:,}"))
    rows.append(("time", f"{elapsed:.2f} s"))
    if path:
        rows.append(("written", str(path)))
    rows.extend(extra)
    _print_rows(rows)


def _print_rows(rows) -> None:
    width = max(len(r[0]) for r in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")


def _print_summary(fc, elapsed, path=None) -> None:
    s = fc.summary()
    rows = [
        ("points", f"{s['points']:,}"),
        ("fans closed", f"{s['fans_closed']:,}"),
        ("fans open", f"{s['fans_open']:,} ({100 * s['fans_open'] / max(s['points'], 1):.2f}%)"),
        ("fans in rotated plane", f"{s['fans_rotated']:,}"),
        ("distinct triangles / point", f"{s['distinct_triangles_per_point']:.2f}"),
        ("duplicates merged", f"{fc.info.get('duplicates_merged', 0):,}"),
    ]
    if _dropped(fc):
        rows.append(("unreferenced dropped", f"{_dropped(fc):,}"))
    rows.append(("time", f"{elapsed:.2f} s"))
    if path:
        rows.append(("written", str(path)))
    _print_rows(rows)
