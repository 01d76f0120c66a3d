"""Figures in the paper's style and the HTML report (matplotlib imported lazily).

- ``plane_figure(result, path)``: the mechanism's plane seen face-on, the handle as a thick
  line at moments of the run, the device's force as arrows (Figs. 9-12), finger forces
  where the user resists (Fig. 12).
- ``time_figure(result, path)``: force, distance from the circle, angles over time.
- ``write_figures(result, out_dir)``: both, as ``plane.png`` and ``time.png``.
- ``write_index(out_dir, entries)``: ``index.html`` showing every run's figures and metrics.
"""

from __future__ import annotations

from typing import Any

__all__ = ["plane_figure", "time_figure", "write_figures", "write_index"]


def __getattr__(name: str) -> Any:
    if name in ("plane_figure", "time_figure", "write_figures"):
        from . import figures

        return getattr(figures, name)
    if name == "write_index":
        from .report import write_index

        return write_index
    raise AttributeError(name)
