"""The handle's distances from a mechanism and the directions it constrains, written out in
NumPy from their definitions (docs/scenarios.md, "Distances and metrics"; docs/quality.md),
over a mechanism's parameters as its to_dict() gives them: the reference the core's kinds
(src/kinds/*.cpp, virtmech.distances, virtmech.constrained_directions) are compared with.

p (N, 3): handle positions; s (N, 3): unit stylus directions (the handle frame's +z). The
stylus tip is p + length s. Each function returns (dist, dist_signed, dist_normal,
dist_across), each (N,).
"""

from __future__ import annotations

import numpy as np


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _tip(m: dict, p, s) -> np.ndarray:
    return np.asarray(p, dtype=float) + float(m["length"]) * np.asarray(s, dtype=float)


def _one_sided(height, across, unilateral: bool):
    full = np.hypot(height, across)
    signed = np.where(height < 0.0, -full, full)
    dist = np.hypot(across, np.minimum(height, 0.0)) if unilateral else full
    return dist, signed, height, across


def planar_arm(m: dict, p, s):
    n = _unit(m["normal"])
    w = np.asarray(p, dtype=float) - np.asarray(m["pivot"], dtype=float)
    h = w @ n
    radial = np.linalg.norm(w - np.outer(h, n), axis=1) - float(m["length"])
    dist = np.hypot(radial, h)
    return dist, np.where(radial < 0.0, -dist, dist), h, radial


def probe(m: dict, p, s):
    h = (_tip(m, p, s) - np.asarray(m["plane_point"], dtype=float)) @ _unit(m["plane_normal"])
    dist = np.maximum(-h, 0.0) if m["unilateral"] else np.abs(h)
    return dist, h, h, np.zeros_like(h)


def point_pivot(m: dict, p, s):
    if m["insertion"]:
        s = np.asarray(s, dtype=float)
        w = np.asarray(m["point"], dtype=float) - np.asarray(p, dtype=float)
        along = np.sum(w * s, axis=1)
        line = np.linalg.norm(w - along[:, None] * s, axis=1)
        return line, line, float(m["length"]) - along, line
    n = _unit(m["normal"])
    w = _tip(m, p, s) - np.asarray(m["point"], dtype=float)
    h = w @ n
    return _one_sided(h, np.linalg.norm(w - np.outer(h, n), axis=1), m["unilateral"])


def line_guide(m: dict, p, s):
    d = _unit(m["direction"])
    n = _unit(m["normal"])
    n = _unit(n - (n @ d) * d)
    w = _tip(m, p, s) - np.asarray(m["point"], dtype=float)
    return _one_sided(w @ n, w @ np.cross(n, d), m["unilateral"])


def surface_probe(m: dict, p, s, surface):
    X = _tip(m, p, s)
    _, points, normals = surface.closest_points(X)
    h = np.sum((X - points) * normals, axis=1)
    dist = np.maximum(-h, 0.0) if m["unilateral"] else np.abs(h)
    return dist, h, h, np.zeros_like(h)


def from_curve(m: dict, X, curve):
    _, points = curve.closest_points(np.atleast_2d(X))
    w = X - points
    h = w @ _unit(m["normal"])
    full = np.linalg.norm(w, axis=1)
    return full, full, h, np.sqrt(np.maximum(full**2 - h**2, 0.0))


def constrained(m: dict, at: np.ndarray, shape=None) -> dict[str, np.ndarray]:
    """The directions the mechanism holds its point in, with the point at rest at `at`."""
    t = m["type"]
    if t == "PlanarArm":
        n = _unit(m["normal"])
        r = at - np.asarray(m["pivot"], dtype=float)
        r -= (r @ n) * n
        return {"radial": _unit(r), "normal": n}
    if t == "Probe":
        return {"into the plane": -_unit(m["plane_normal"])}
    if t == "PointPivot":
        return {"x": np.eye(3)[0], "y": np.eye(3)[1], "z": np.eye(3)[2]}
    if t == "LineGuide":
        d = _unit(m["direction"])
        a = _unit(np.cross(d, np.eye(3)[np.argmin(np.abs(d))]))
        return {"across 1": a, "across 2": np.cross(d, a)}
    if t == "SurfaceProbe":
        uv, _ = shape.closest_point(at)
        return {"into the surface": -np.asarray(shape.normal(*uv), dtype=float)}
    u, _ = shape.closest_point(at)
    tangent = np.asarray(shape.tangent(u), dtype=float)
    n = _unit(m["normal"])
    a = n - (n @ tangent) * tangent
    if np.linalg.norm(a) < 1e-6:
        a = np.cross(tangent, np.eye(3)[np.argmin(np.abs(tangent))])
    a = _unit(a)
    return {"along the normal": a, "across": np.cross(tangent, a)}
