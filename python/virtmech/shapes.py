"""Curves and surfaces from their parameters, as a scenario file or ``to_dict()`` gives
them: ``{"type": "NurbsSurface", "control_points": ..., ...}`` (docs/geometry.md).

NURBS weights default to ones; knots default to the clamped uniform vector of the degree
(the curve or surface passes through its first and last control points)."""

from __future__ import annotations

from typing import Any

import numpy as np

import virtmech as vm

#: the shape types by kind
SURFACES = ("NurbsSurface", "Sphere", "Cylinder", "Plane")
CURVES = ("NurbsCurve",)


def clamped_uniform_knots(n: int, degree: int) -> np.ndarray:
    """n + degree + 1 knots: degree + 1 zeros, evenly spaced interior knots, degree + 1 ones."""
    interior = np.linspace(0.0, 1.0, n - degree + 1)[1:-1]
    return np.r_[np.zeros(degree + 1), interior, np.ones(degree + 1)]


def shape_from_dict(d: dict[str, Any]):
    """A vm curve or surface from its parameters (the keys of its constructor and "type")."""
    t = d.get("type")
    kw = {k: v for k, v in d.items() if k != "type"}
    if t == "NurbsCurve":
        P = np.asarray(kw["control_points"], dtype=float)
        degree = int(kw.get("degree", 3))
        w = kw.get("weights")
        knots = kw.get("knots")
        return vm.NurbsCurve(
            P,
            np.ones(len(P)) if w is None else w,
            clamped_uniform_knots(len(P), degree) if knots is None else knots,
            degree,
        )
    if t == "NurbsSurface":
        P = np.asarray(kw["control_points"], dtype=float)
        if P.ndim != 3 or P.shape[2] != 3:
            raise ValueError(
                f"control_points: expected nu x nv points of 3 numbers, got shape {P.shape}"
            )
        nu, nv = P.shape[:2]
        du, dv = int(kw.get("degree_u", 3)), int(kw.get("degree_v", 3))
        w = kw.get("weights")
        ku, kv = kw.get("knots_u"), kw.get("knots_v")
        return vm.NurbsSurface(
            P,
            np.ones((nu, nv)) if w is None else w,
            clamped_uniform_knots(nu, du) if ku is None else ku,
            clamped_uniform_knots(nv, dv) if kv is None else kv,
            du,
            dv,
        )
    if t in ("Sphere", "Cylinder", "Plane"):
        return getattr(vm, t)(**kw)
    raise ValueError(f"type: expected one of {', '.join(SURFACES + CURVES)}, got {t!r}")


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
