"""What `virtmech view` draws, as viser scene nodes, from a frame (LiveSim.snapshot or
Replay.frame): the device's bodies (the MuJoCo model's geoms at their poses) and joints,
the virtual mechanism as its kind draws itself (virtmech.sketch: a PlanarArm's circle and
pivot, a Probe's plane, a LineGuide's line, a PointPivot's point, ...) with its two
placements (theta: the nearest; theta*: the un-powered), the virtual probe (the handle
moved by the mechanism's length along the stylus), the device's force at the handle and
its null- and range-space parts as arrows (1 N = 10 mm), and the hand's target and its
spring to the handle."""

from __future__ import annotations

import math

import numpy as np

import virtmech as vm

#: colours (RGB 0-255)
DEVICE_RGB = (235, 120, 20)  # links: orange
JOINT_RGB = (90, 45, 10)
MECH_RGB = (40, 110, 230)  # the mechanism and its placement theta
STAR_RGB = (150, 185, 245)  # the placement theta*
PROBE_RGB = (150, 60, 200)  # the virtual probe
FORCE_RGB = (220, 30, 30)
NULL_RGB = (20, 160, 60)
RANGE_RGB = (230, 60, 220)
TARGET_RGB = (245, 190, 0)

#: arrow length per newton [m/N] (as the figures: 1 N = 10 mm)
FORCE_SCALE = 0.01

# MuJoCo geom types (mjtGeom)
_SPHERE, _CAPSULE, _CYLINDER, _BOX = 2, 3, 5, 6


def wxyz_of(R: np.ndarray) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    R = np.asarray(R, dtype=float)
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q)


def rot_of(wxyz) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z) (normalised first)."""
    w, x, y, z = np.asarray(wxyz, dtype=float) / np.linalg.norm(wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _basis(n) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to n and to each other."""
    n = _unit(n)
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    u = _unit(np.cross(n, a))
    return u, np.cross(n, u)


def up_of(model) -> np.ndarray:
    """The scene's up: against the model's gravity (+z without gravity)."""
    g = np.asarray(model.opt.gravity, dtype=float)
    return -_unit(g) if np.linalg.norm(g) > 0 else np.array([0, 0, 1.0])


class Scene:
    """The scene nodes of one device and mechanism; `update(frame)` moves them."""

    def __init__(self, server, model, mechanism, mech_dict: dict, up: np.ndarray,
                 members: tuple = ()):
        self.server = server
        self.model = model
        self.mech = mechanism
        self.md = mech_dict
        self.members = list(members)  # a mechanism set's other members (their to_dict)
        self.L = float(mech_dict.get("length", 0.0) or 0.0)
        self.up = np.asarray(up, dtype=float)
        self.nodes: list = []
        self._build()

    # -------------------------------------------------------------------------------------
    def _add(self, handle):
        self.nodes.append(handle)
        return handle

    def _build(self) -> None:
        sc = self.server.scene
        m = self.model
        self.geoms = []
        for g in range(m.ngeom):
            gtype = int(m.geom_type[g])
            size = np.asarray(m.geom_size[g], dtype=float)
            rgba = np.asarray(m.geom_rgba[g], dtype=float)
            default = np.allclose(rgba[:3], [0.6, 0.6, 0.65])
            rgb = DEVICE_RGB if default else tuple(int(255 * c) for c in rgba[:3])
            root = self._add(sc.add_frame(f"/device/g{g}", show_axes=False))
            if gtype in (_CYLINDER, _CAPSULE) and size[0] > 0:
                sc.add_cylinder(
                    f"/device/g{g}/body",
                    radius=float(size[0]),
                    height=2 * float(size[1]),
                    color=rgb,
                )
                if gtype == _CAPSULE:
                    for k, s in enumerate((-1.0, 1.0)):
                        sc.add_icosphere(
                            f"/device/g{g}/end{k}",
                            radius=float(size[0]),
                            color=rgb,
                            subdivisions=2,
                            position=(0.0, 0.0, s * float(size[1])),
                        )
            elif gtype == _SPHERE:
                sc.add_icosphere(f"/device/g{g}/body", radius=float(size[0]), color=rgb)
            elif gtype == _BOX:
                sc.add_box(f"/device/g{g}/body", dimensions=tuple(2 * size), color=rgb)
            self.geoms.append(root)
        self.joints = [
            self._add(sc.add_icosphere(f"/device/joint{j}", radius=0.0045, color=JOINT_RGB))
            for j in range(m.njnt)
        ]
        self._build_mechanism()
        # the placements theta (nearest) and theta* (un-powered), the mechanism's probe of each
        self.theta = self._add(
            sc.add_frame("/mech/theta", axes_length=0.02, axes_radius=0.0012, origin_radius=0.003)
        )
        self.theta_star = self._add(
            sc.add_frame(
                "/mech/theta_star", axes_length=0.012, axes_radius=0.0008, origin_radius=0.002
            )
        )
        z = np.zeros((2, 2, 3))
        self.mech_links = self._add(
            sc.add_line_segments(
                "/mech/links",
                z,
                np.array([[MECH_RGB] * 2, [STAR_RGB] * 2], dtype=np.uint8),
                thickness=0.0018,
            )
        )
        # the virtual probe: the handle moved by the mechanism's length along the stylus
        self.probe = self._add(
            sc.add_line_segments("/probe/line", np.zeros((1, 2, 3)), PROBE_RGB, thickness=0.0012)
        )
        self.probe_tip = self._add(sc.add_icosphere("/probe/tip", radius=0.0025, color=PROBE_RGB))
        self.handle = self._add(
            sc.add_frame("/handle", axes_length=0.015, axes_radius=0.0008, origin_radius=0.002)
        )
        self.arrows = self._add(
            sc.add_arrows(
                "/forces",
                np.zeros((3, 2, 3)),
                np.array([FORCE_RGB, NULL_RGB, RANGE_RGB], dtype=np.uint8),
                shaft_radius=0.0014,
                head_radius=0.0035,
                head_length=0.007,
            )
        )
        self.target_dot = self._add(
            sc.add_icosphere("/hand/target", radius=0.003, color=TARGET_RGB, opacity=0.8)
        )
        self.spring = self._add(
            sc.add_line_segments("/hand/spring", np.zeros((1, 2, 3)), TARGET_RGB, thickness=0.0008)
        )

    def _build_mechanism(self) -> None:
        members = [vm.make_mechanism(md) for md in self.members]
        for i, mech in enumerate([self.mech, *members]):
            self._draw_mechanism(mech, "/mech" if i == 0 else f"/mech{i}")

    def _draw_mechanism(self, mech, root: str) -> None:
        """The mechanism as its kind draws itself (virtmech.sketch: lines, points, meshes)."""
        sc = self.server.scene
        sketch = vm.sketch(mech)
        for k, line in enumerate(sketch["lines"]):
            seg = np.stack([line[:-1], line[1:]], axis=1)
            self._add(sc.add_line_segments(f"{root}/line{k}", seg, MECH_RGB, thickness=0.0015))
        for k, p in enumerate(sketch["points"]):
            self._add(sc.add_icosphere(f"{root}/point{k}", radius=0.0035, color=MECH_RGB,
                                       position=p))
        for k, (vertices, faces) in enumerate(sketch["meshes"]):
            self._add(
                sc.add_mesh_simple(
                    f"{root}/mesh{k}",
                    vertices=np.asarray(vertices, dtype=np.float32),
                    faces=np.asarray(faces, dtype=np.uint32),
                    color=MECH_RGB,
                    opacity=0.3,
                    side="double",
                )
            )

    def remove(self) -> None:
        for h in reversed(self.nodes):
            try:
                h.remove()
            except Exception:  # already gone with its parent
                pass
        self.nodes = []

    # -------------------------------------------------------------------------------------
    def update(self, f: dict) -> None:
        xpos, xmat = f["geom_xpos"], f["geom_xmat"]
        for g, node in enumerate(self.geoms):
            node.position = xpos[g]
            node.wxyz = wxyz_of(xmat[g])
        for j, node in enumerate(self.joints):
            if "joint_xanchor" in f:
                node.position = f["joint_xanchor"][j]
        T = f["handle"]
        p, s = T[:3, 3], T[:3, 2]
        self.handle.position, self.handle.wxyz = p, wxyz_of(T[:3, :3])
        tip = p + self.L * s
        self.probe.points = np.array([[p, tip]], dtype=np.float32)
        self.probe_tip.position = tip
        links = []
        for node, T_m in (
            (self.theta, f["mechanism_pose"]),
            (self.theta_star, f["mechanism_pose_star"]),
        ):
            if T_m is None or not np.all(np.isfinite(T_m)):
                node.visible = False
                links.append([p, p])
                continue
            node.visible = True
            node.position, node.wxyz = T_m[:3, 3], wxyz_of(T_m[:3, :3])
            links.append([T_m[:3, 3], T_m[:3, 3] + self.L * T_m[:3, 2]])
        self.mech_links.points = np.array(links, dtype=np.float32)
        arrows = [
            [p, p + FORCE_SCALE * np.asarray(w[:3])]
            for w in (f["wrench"], f["wrench_null"], f["wrench_range"])
        ]
        self.arrows.points = np.array(arrows, dtype=np.float32)
        tp = f["target_p"]
        self.target_dot.position = tp
        self.spring.points = np.array([[p, tp]], dtype=np.float32)


def camera_for(model, frame: dict, mech_dict: dict, up: np.ndarray, device_name: str, fov: float):
    """(position, look_at) of a camera (vertical field of view `fov` [rad]) that frames the
    device's bodies, the handle and the mechanism."""
    pts = [np.asarray(frame["geom_xpos"], dtype=float), frame["handle"][None, :3, 3]]
    kind = mech_dict.get("type")
    key = {"PlanarArm": "pivot", "Probe": "plane_point"}.get(kind, "point")
    if key in mech_dict:
        c = np.asarray(mech_dict[key], dtype=float)
        r = float(mech_dict.get("length", 0.0)) if kind == "PlanarArm" else 0.03
        pts.append(c + r * np.vstack([np.eye(3), -np.eye(3)]))
    P = np.vstack(pts)
    center = 0.5 * (P.min(axis=0) + P.max(axis=0))
    radius = float(np.max(np.linalg.norm(P - center, axis=1))) + 0.02
    if device_name == "PhantomOmni":
        front = np.array([0.0, 0.0, 1.0])  # the user sits at +z (OpenHaptics axes)
    else:
        front = center - np.asarray(frame["geom_xpos"], dtype=float)[0]
        front = front - (front @ up) * up
        front = _unit(front) if np.linalg.norm(front) > 1e-9 else _basis(up)[0]
    side = np.cross(up, front)
    d = _unit(1.0 * front + 0.5 * side + 0.45 * up)
    return center + radius / math.sin(0.5 * fov) * d, center
