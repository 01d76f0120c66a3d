"""The `markers` topic: a visualization_msgs/MarkerArray for RViz of the mechanism (its
shape: a PlanarArm's circle and pivot, a Probe's plane, a LineGuide's line, a PointPivot's
point, a surface, a curve), the handle and the virtual probe, the two placements theta
(nearest) and theta* (un-powered) with their values, and the device's force at the handle
with its null- and range-space parts (1 N = 10 mm, the figures' scale). Colours as
`virtmech view` draws them. Everything in the device's world axes and metres, frame
`frame_id`.

The shapes (namespace ``mechanism``) change only with the scenario: they are sent with
the first array and then once a second (`shapes=True`); the rest every time.
"""

from __future__ import annotations

import math

import numpy as np

from ..view.scene import (
    FORCE_RGB,
    FORCE_SCALE,
    MECH_RGB,
    NULL_RGB,
    PROBE_RGB,
    RANGE_RGB,
    STAR_RGB,
    _unit,
    wxyz_of,
)
from ..view.scene import _basis as _plane_axes

__all__ = ["MarkerBuilder", "outline"]

_LINE_M = 0.0015  # line width [m]


def outline(md: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mechanism's shape from its to_dict(): (line segments (k, 2, 3), triangles (t, 3, 3),
    points (p, 3)) [m]."""
    segs, tris, pts = np.zeros((0, 2, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3))
    kind = md.get("type")
    if kind == "PlanarArm":
        c, n = np.asarray(md["pivot"], dtype=float), _unit(md["normal"])
        u, v = _plane_axes(n)
        a = np.linspace(0.0, 2.0 * math.pi, 97)
        ring = c + md["length"] * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)
        segs, pts = np.stack([ring[:-1], ring[1:]], axis=1), c[None]
    elif kind == "Probe":
        c, n = np.asarray(md["plane_point"], dtype=float), _unit(md["plane_normal"])
        u, v = _plane_axes(n)
        h = 0.08
        k = np.array([c + h * (s * u + t * v) for s, t in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        tris = np.array([[k[0], k[1], k[2]], [k[0], k[2], k[3]]])
        segs = np.stack([k, np.roll(k, -1, axis=0)], axis=1)
    elif kind == "LineGuide":
        p, d = np.asarray(md["point"], dtype=float), _unit(md["direction"])
        segs = np.array([[p - 0.1 * d, p + 0.1 * d]])
    elif kind == "PointPivot":
        pts = np.asarray(md["point"], dtype=float)[None]
    elif kind == "SurfaceProbe":
        from ..shapes import shape_from_dict, surface_grid

        G = surface_grid(shape_from_dict(md["surface"]), 24)
        a, b, c, d = G[:-1, :-1], G[1:, :-1], G[1:, 1:], G[:-1, 1:]
        tris = np.concatenate(
            [np.stack([a, b, c], -2).reshape(-1, 3, 3), np.stack([a, c, d], -2).reshape(-1, 3, 3)]
        )
    elif kind in ("CurveGuide", "HandlePath"):
        from ..shapes import curve_points, shape_from_dict

        P = curve_points(shape_from_dict(md["curve"]))
        segs = np.stack([P[:-1], P[1:]], axis=1)
    return segs, tris, pts


class MarkerBuilder:
    """MarkerArrays of one device and its mechanisms (`mechanisms`: their to_dict(), member
    0 first); `array(stamp, q, cycle, shapes)` fills one."""

    def __init__(self, device, mechanisms: list[dict], frame_id: str):
        from geometry_msgs.msg import Point
        from visualization_msgs.msg import Marker

        self.Marker, self.Point = Marker, Point
        self.device = device
        self.frame_id = frame_id
        self.L = float(mechanisms[0].get("length", mechanisms[0].get("length_scale", 0.05)))
        self.shapes = [outline(md) for md in mechanisms]

    def _marker(self, stamp, ns: str, mid: int, kind: int, rgb, alpha: float = 1.0):
        m = self.Marker()
        m.header.stamp = stamp
        m.header.frame_id = self.frame_id
        m.ns, m.id, m.type, m.action = ns, mid, kind, self.Marker.ADD
        m.pose.orientation.w = 1.0
        m.color.r, m.color.g, m.color.b = (c / 255.0 for c in rgb)
        m.color.a = alpha
        return m

    def _points(self, P) -> list:
        return [self.Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in P]

    def _arrow(self, stamp, ns: str, mid: int, a, b, rgb, width: float = 0.0015):
        m = self._marker(stamp, ns, mid, self.Marker.ARROW, rgb)
        m.points = self._points([a, b])
        m.scale.x, m.scale.y, m.scale.z = width, 2.5 * width, 4.0 * width
        return m

    def _shapes(self, stamp) -> list:
        M, out = self.Marker, []
        for i, (segs, tris, pts) in enumerate(self.shapes):
            if len(segs):
                m = self._marker(stamp, "mechanism", 3 * i, M.LINE_LIST, MECH_RGB)
                m.points = self._points(segs.reshape(-1, 3))
                m.scale.x = _LINE_M
                out.append(m)
            if len(tris):
                m = self._marker(stamp, "mechanism", 3 * i + 1, M.TRIANGLE_LIST, MECH_RGB, 0.3)
                m.points = self._points(tris.reshape(-1, 3))
                m.scale.x = m.scale.y = m.scale.z = 1.0
                out.append(m)
            if len(pts):
                m = self._marker(stamp, "mechanism", 3 * i + 2, M.SPHERE_LIST, MECH_RGB)
                m.points = self._points(pts)
                m.scale.x = m.scale.y = m.scale.z = 0.006
                out.append(m)
        return out

    def array(self, stamp, q: np.ndarray, cycle, shapes: bool = False):
        """The MarkerArray at joints q with the cycle's output `cycle` (a CycleOutput; None:
        the handle alone, a zero command)."""
        from visualization_msgs.msg import MarkerArray

        M = self.Marker
        arr = MarkerArray()
        markers = self._shapes(stamp) if shapes else []
        T = np.asarray(self.device.forward(q))
        p, s = T[:3, 3], T[:3, 2]
        handle = self._marker(stamp, "handle", 0, M.SPHERE, PROBE_RGB)
        handle.pose.position.x, handle.pose.position.y, handle.pose.position.z = map(float, p)
        w, x, y, z = wxyz_of(T[:3, :3])
        handle.pose.orientation.w, handle.pose.orientation.x = float(w), float(x)
        handle.pose.orientation.y, handle.pose.orientation.z = float(y), float(z)
        handle.scale.x = handle.scale.y = handle.scale.z = 0.005
        markers += [handle, self._arrow(stamp, "probe", 0, p, p + self.L * s, PROBE_RGB, 0.001)]
        text = "zero command (stale input)"
        for ns, key, rgb in (
            ("theta", "mechanism_pose", MECH_RGB),
            ("theta_star", "mechanism_pose_star", STAR_RGB),
        ):
            Tm = None if cycle is None else np.asarray(getattr(cycle, key))
            m = self._arrow(stamp, ns, 0, p, p, rgb, 0.002)
            if Tm is not None and np.all(np.isfinite(Tm)):
                m.points = self._points([Tm[:3, 3], Tm[:3, 3] + self.L * Tm[:3, 2]])
            else:
                m.action = M.DELETE
            markers.append(m)
        forces = ("force", "force_null", "force_range")
        for ns, key, rgb in zip(
            forces, ("wrench", "wrench_null", "wrench_range"), (FORCE_RGB, NULL_RGB, RANGE_RGB)
        ):
            f = np.zeros(3) if cycle is None else np.asarray(getattr(cycle, key))[:3]
            markers.append(self._arrow(stamp, ns, 0, p, p + FORCE_SCALE * f, rgb))
        if cycle is not None:
            th = ", ".join(f"{v:.3f}" for v in np.asarray(cycle.theta))
            ts = ", ".join(f"{v:.3f}" for v in np.asarray(cycle.theta_star))
            f = float(np.linalg.norm(np.asarray(cycle.wrench)[:3]))
            text = f"theta [{th}]\ntheta* [{ts}]\n|f| {f:.2f} N"
        label = self._marker(stamp, "values", 0, M.TEXT_VIEW_FACING, (255, 255, 255))
        label.pose.position.x, label.pose.position.y = float(p[0]), float(p[1])
        label.pose.position.z = float(p[2]) + 0.03
        label.scale.z = 0.008
        label.text = text
        markers.append(label)
        arr.markers = markers
        return arr
