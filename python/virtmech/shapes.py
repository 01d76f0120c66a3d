"""Curves and surfaces from their parameters, as a scenario file or ``to_dict()`` gives
them: ``{"type": "NurbsSurface", "control_points": ..., ...}`` (docs/geometry.md; the
core's shape kinds: NURBS weights default to ones, knots to the clamped uniform vector of
the degree), and points of them for drawing."""

from __future__ import annotations

from typing import Any

import numpy as np

import virtmech as vm


def shape_from_dict(d: dict[str, Any]):
    """A vm curve or surface from its parameters (its kind's, with "type": virtmech.kinds)."""
    return vm.make_shape(d, "shape")


def surface_grid(surface, count: int = 24, unbounded: float = 0.1) -> np.ndarray:
    """Points of a surface on a count x count grid of its parameters, (count, count, 3); an
    unbounded parameter over +-`unbounded` (metres for a plane or a cylinder's axis)."""
    lo, hi = np.asarray(surface.lower, float), np.asarray(surface.upper, float)
    lo = np.where(np.isfinite(lo), lo, -unbounded)
    hi = np.where(np.isfinite(hi), hi, unbounded)
    us, vs = np.linspace(lo[0], hi[0], count), np.linspace(lo[1], hi[1], count)
    return np.array([[surface.evaluate(u, v) for v in vs] for u in us])


def curve_points(curve, count: int = 200) -> np.ndarray:
    """count points of a curve evenly in its parameter, (count, 3)."""
    return np.array([curve.evaluate(u) for u in np.linspace(curve.lower, curve.upper, count)])
