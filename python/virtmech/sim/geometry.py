"""How far the handle is from its virtual mechanism, for every kind of mechanism.

Each kind has one function, registered under the mechanism's ``type`` (the ``"type"`` of
``mechanism.to_dict()``), that takes the mechanism's parameters (that dict) and the logged
handle poses (positions p (N, 3) and unit stylus directions s (N, 3), the handle frame's
+z, from the hand toward the tip) and returns four columns of the log [m]:

- ``dist_signed``: the signed distance of the mechanism's point (the handle for a
  PlanarArm, the stylus tip for the probes) from the mechanism's path or surface: its
  size is the distance from the circle, plane, point or line; it is negative on the side
  the mechanism pushes away from (behind a Probe's plane, below a PointPivot's or
  LineGuide's point or line along its normal, inside a PlanarArm's circle).
- ``dist``: the distance from where the mechanism lets that point be (>= 0): the same
  size for a bilateral mechanism; for a unilateral one, zero wherever the tip has lifted
  off (a Probe: the depth behind the plane, or 0).
- ``dist_normal``: the part along the mechanism's normal (a Probe's or PointPivot's tip
  height, a LineGuide's tip height along its normal, a PlanarArm's handle out of its plane).
- ``dist_across``: the rest (a PlanarArm: the radial error r - length; a PointPivot: the
  tip's distance from the normal through the point; a LineGuide: the tip's offset across
  the line in its plane; a Probe: 0, the plane constrains nothing else).

The stylus tip is the handle moved by the mechanism's ``length`` along the stylus:
``tip = p + length * s``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: the columns a distance function returns, in the log's order
COLUMNS = ("dist", "dist_signed", "dist_normal", "dist_across")


@dataclass(frozen=True)
class Distances:
    dist: np.ndarray
    dist_signed: np.ndarray
    dist_normal: np.ndarray
    dist_across: np.ndarray

    def columns(self) -> np.ndarray:
        return np.stack([getattr(self, c) for c in COLUMNS], axis=1)


@dataclass(frozen=True)
class Geometry:
    """One mechanism kind: its distance function and how figures and reports name it."""

    measure: Callable[[dict, np.ndarray, np.ndarray], Distances]
    point: str  # the point measured: "handle" or "tip"
    target: str  # what it is measured from: "the circle", "the plane", ...
    signed_label: str  # the signed distance's name in figures
    negative: str  # what a negative signed distance means


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def tip(m: dict, p: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The stylus tip: the handle moved by the mechanism's length along the stylus."""
    return np.asarray(p, dtype=float) + float(m["length"]) * np.asarray(s, dtype=float)


def _one_sided(height: np.ndarray, across: np.ndarray, unilateral: bool) -> Distances:
    """A point or a line: bilateral, the distance from it; unilateral, from the ray or half
    plane above it along the normal (the tip may lift off toward +normal)."""
    full = np.hypot(height, across)
    signed = np.where(height < 0.0, -full, full)
    dist = np.hypot(across, np.minimum(height, 0.0)) if unilateral else full
    return Distances(dist, signed, height, across)


def planar_arm(m: dict, p: np.ndarray, s: np.ndarray) -> Distances:
    """The handle from the circle of radius `length` about `pivot` in the plane of `normal`."""
    del s
    n = _unit(m["normal"])
    w = np.asarray(p, dtype=float) - np.asarray(m["pivot"], dtype=float)
    h = w @ n
    radial = np.linalg.norm(w - np.outer(h, n), axis=1) - float(m["length"])
    dist = np.hypot(radial, h)
    return Distances(dist, np.where(radial < 0.0, -dist, dist), h, radial)


def probe(m: dict, p: np.ndarray, s: np.ndarray) -> Distances:
    """The tip's signed height above the plane along its normal (negative: behind it)."""
    n = _unit(m["plane_normal"])
    h = (tip(m, p, s) - np.asarray(m["plane_point"], dtype=float)) @ n
    dist = np.maximum(-h, 0.0) if m.get("unilateral") else np.abs(h)
    return Distances(dist, h, h, np.zeros_like(h))


def point_pivot(m: dict, p: np.ndarray, s: np.ndarray) -> Distances:
    """The tip from the point (unilateral: from the ray above it along the normal). With
    insertion (a trocar): the point's distance from the stylus's line (dist, dist_signed,
    dist_across) and how far the tip has gone in past the point along the stylus
    (dist_normal)."""
    if m.get("insertion"):
        s = np.asarray(s, dtype=float)
        w = np.asarray(m["point"], dtype=float) - np.asarray(p, dtype=float)
        along = np.sum(w * s, axis=1)
        line = np.linalg.norm(w - along[:, None] * s, axis=1)
        depth = float(m["length"]) - along  # tip beyond the point along the stylus
        return Distances(line, line, depth, line)
    n = _unit(m["normal"])
    w = tip(m, p, s) - np.asarray(m["point"], dtype=float)
    h = w @ n
    across = np.linalg.norm(w - np.outer(h, n), axis=1)
    return _one_sided(h, across, bool(m.get("unilateral")))


def line_guide(m: dict, p: np.ndarray, s: np.ndarray) -> Distances:
    """The tip from the line (unilateral: from the half plane above it along the normal)."""
    d = _unit(m["direction"])
    n = _unit(m["normal"])
    n = _unit(n - (n @ d) * d)
    w = tip(m, p, s) - np.asarray(m["point"], dtype=float)
    return _one_sided(w @ n, w @ np.cross(n, d), bool(m.get("unilateral")))


def surface_probe(m: dict, p: np.ndarray, s: np.ndarray) -> Distances:
    """The tip's signed height above the surface along the normal at its closest point
    (negative: behind it)."""
    from ..shapes import shape_from_dict

    surface = shape_from_dict(m["surface"])
    X = tip(m, p, s)
    _, points, normals = surface.closest_points(np.atleast_2d(X))  # the shape's own search
    h = np.sum((X - points) * normals, axis=1)
    dist = np.maximum(-h, 0.0) if m.get("unilateral") else np.abs(h)
    return Distances(dist, h, h, np.zeros_like(h))


def _from_curve(m: dict, X: np.ndarray) -> Distances:
    """A point from the curve: the distance, its part along the mechanism's normal and the
    rest."""
    from ..shapes import shape_from_dict

    _, points = shape_from_dict(m["curve"]).closest_points(np.atleast_2d(X))
    w = X - points
    n = _unit(m.get("normal", [0.0, 0.0, 1.0]))
    h = w @ n
    full = np.linalg.norm(w, axis=1)
    across = np.sqrt(np.maximum(full**2 - h**2, 0.0))
    return Distances(full, full, h, across)


def curve_guide(m: dict, p: np.ndarray, s: np.ndarray) -> Distances:
    """The tip from the curve."""
    return _from_curve(m, tip(m, p, s))


def handle_path(m: dict, p: np.ndarray, s: np.ndarray) -> Distances:
    """The handle from the curve."""
    del s
    return _from_curve(m, np.asarray(p, dtype=float))


#: mechanism type -> its geometry (SerialChain and other chains have none: the log then
#: falls back on the nearest placement's position error, see `distances`)
GEOMETRY: dict[str, Geometry] = {
    "PlanarArm": Geometry(
        planar_arm,
        "handle",
        "the circle",
        "handle's distance from the circle",
        "inside the circle",
    ),
    "Probe": Geometry(
        probe, "tip", "the plane", "tip height above the plane", "the tip is behind the plane"
    ),
    "PointPivot": Geometry(
        point_pivot,
        "tip",
        "the point",
        "tip distance from the point",
        "the tip is below the point along its normal",
    ),
    "LineGuide": Geometry(
        line_guide,
        "tip",
        "the line",
        "tip distance from the line",
        "the tip is below the line along its normal",
    ),
    "SurfaceProbe": Geometry(
        surface_probe,
        "tip",
        "the surface",
        "tip height above the surface",
        "the tip is behind the surface",
    ),
    "CurveGuide": Geometry(
        curve_guide, "tip", "the curve", "tip distance from the curve", "(never: unsigned)"
    ),
    "HandlePath": Geometry(
        handle_path, "handle", "the curve", "handle distance from the curve", "(never: unsigned)"
    ),
}


def geometry_of(mechanism: dict) -> Geometry | None:
    return GEOMETRY.get(mechanism["type"])


def distances(mechanism: dict, p: np.ndarray, s: np.ndarray, e_pos: np.ndarray) -> Distances:
    """The four distance columns for handle positions p and stylus directions s (N, 3).
    A mechanism without a registered geometry: the size of the nearest placement's position
    error e_pos (N, 3), unsigned, in dist and dist_signed; its two parts NaN."""
    g = geometry_of(mechanism)
    if g is not None:
        return g.measure(mechanism, np.atleast_2d(p), np.atleast_2d(s))
    d = np.linalg.norm(np.atleast_2d(e_pos), axis=1)
    nan = np.full_like(d, np.nan)
    return Distances(d, d, nan, nan)
