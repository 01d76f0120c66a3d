"""Figures of a run in the paper's style, drawn for what the mechanism is: the handle as a
thick line where the mechanism is seen clearest (a PlanarArm's circle face-on, a Probe's
plane edge-on, ...), force arrows at one scale for every figure (FORCE_SCALE_M_PER_N);
time plots of force and of the distances of sim.geometry (a PlanarArm: from the circle;
a Probe: the tip's height above its plane and the force along the normal against Kp times
the depth; a PointPivot or LineGuide: the tip from its point or line)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from ..shapes import curve_points, shape_from_dict, surface_grid
from ..sim.geometry import geometry_of


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plane_basis(normal) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """In-plane axes (u, v) for viewing a plane face-on from +normal: u is world x projected
    into the plane (world y if x is normal to it), v = n x u."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    u = np.array([1.0, 0.0, 0.0]) - n[0] * n
    if np.linalg.norm(u) < 1e-6:
        u = np.array([0.0, 1.0, 0.0]) - n[1] * n
    u /= np.linalg.norm(u)
    return u, np.cross(n, u), n


#: one force scale for every figure of every report: an arrow of 10 mm is 1 N
FORCE_SCALE_M_PER_N = 0.010


def _mechanism(result) -> dict:
    return result.info.get("mechanism") or result.scenario.data["mechanism"]


def _length(mech: dict) -> float:
    return float(mech.get("length", 0.08))


def _spread_axis(X: np.ndarray, n: np.ndarray, fallback) -> np.ndarray:
    """The unit direction, normal to n, along which the points X spread most (else
    `fallback` projected normal to n; else plane_basis's u)."""
    W = X - X.mean(axis=0)
    W = W - np.outer(W @ n, n)
    if np.abs(W).max() > 1e-6:
        _, _, vt = np.linalg.svd(W, full_matrices=False)
        u = vt[0] - (vt[0] @ n) * n
        if u @ np.asarray(fallback if fallback is not None else u) < 0:
            u = -u
        return u / np.linalg.norm(u)
    if fallback is not None:
        u = np.asarray(fallback, dtype=float) - (np.asarray(fallback) @ n) * n
        if np.linalg.norm(u) > 1e-9:
            return u / np.linalg.norm(u)
    return plane_basis(n)[0]


class _View:
    """How a mechanism is seen in the plane figure: axes (u, v), a title, and its drawing."""

    def __init__(self, u, v, title: str, draw=None, anchors=()):
        self.u, self.v, self.title, self.draw = np.asarray(u), np.asarray(v), title, draw
        self.anchors = [np.asarray(a, dtype=float) for a in anchors]  # kept in the frame


def _view_planar_arm(m: dict, P, tips) -> _View:
    u, v, _ = plane_basis(m["normal"])
    c, L = np.asarray(m["pivot"], dtype=float), _length(m)

    def draw(ax, uv):
        a = np.linspace(0, 2 * np.pi, 400)
        pc = uv(c)[0]
        ax.plot(
            pc[0] + L * np.cos(a),
            pc[1] + L * np.sin(a),
            ls="--",
            color="0.6",
            lw=1,
            label="constraint circle (virtual mechanism path)",
        )
        ax.plot(*pc, marker="o", color="k", ms=5)
        ax.annotate("pivot", pc, textcoords="offset points", xytext=(6, -12), fontsize=8)

    return _View(u, v, "the circle's plane seen face-on", draw, [c])


def _view_probe(m: dict, P, tips) -> _View:
    n = np.asarray(m["plane_normal"], dtype=float)
    n /= np.linalg.norm(n)
    u = _spread_axis(tips, n, m.get("tangent"))
    c = np.asarray(m["plane_point"], dtype=float)

    def draw(ax, uv):
        h0 = float(c @ n)
        ax.axhline(h0, color="0.3", lw=1.5, label="the plane (edge-on)")
        lo = ax.get_ylim()[0] if ax.get_ylim()[0] < h0 else h0 - 0.01
        ax.axhspan(
            min(lo, h0 - 0.01),
            h0,
            color="0.85",
            alpha=0.5,
            zorder=0,
            label="behind the plane" + (" (the tip may not go)" if m.get("unilateral") else ""),
        )

    return _View(u, n, "the plane seen edge-on (its normal up)", draw, [c])


def _view_point_pivot(m: dict, P, tips) -> _View:
    n = np.asarray(m["normal"], dtype=float)
    n /= np.linalg.norm(n)
    u = _spread_axis(P, n, m.get("tangent"))
    c = np.asarray(m["point"], dtype=float)

    def draw(ax, uv):
        pc = uv(c)[0]
        if m.get("unilateral"):
            ax.plot(
                [pc[0], pc[0]],
                [pc[1], pc[1] + 2 * _length(m)],
                color="0.6",
                ls="--",
                lw=1,
                label="where the tip may lift off (along the normal)",
            )
        ax.plot(*pc, marker="o", color="k", ms=6, ls="none", label="the pivot point")

    return _View(u, n, "seen from the side (the point's normal up)", draw, [c])


def _view_line_guide(m: dict, P, tips) -> _View:
    d = np.asarray(m["direction"], dtype=float)
    d /= np.linalg.norm(d)
    n = np.asarray(m["normal"], dtype=float)
    n = n - (n @ d) * d
    n /= np.linalg.norm(n)
    c = np.asarray(m["point"], dtype=float)

    def draw(ax, uv):
        ax.axhline(float(c @ n), color="0.3", lw=1.5, label="the line")

    return _View(d, n, "the line and its normal (seen across)", draw, [c])


def _shape_of(m: dict):
    return shape_from_dict(m["surface"] if "surface" in m else m["curve"])


def _view_surface_probe(m: dict, P, tips) -> _View:
    surface = _shape_of(m)
    # seen from the side, the normal where the run's tip was closest to the surface up
    uv_, _ = surface.closest_point(np.median(tips, axis=0))
    n = np.asarray(surface.normal(*uv_), dtype=float)
    u = _spread_axis(tips, n, None)

    def draw(ax, uv):
        G = uv(surface_grid(surface).reshape(-1, 3))
        ax.plot(G[:, 0], G[:, 1], ls="none", marker=".", ms=1.5, color="0.6",
                label="the surface (its points, seen from the side)")

    return _View(u, n, "the surface seen from the side (its normal at the tip up)", draw,
                 [surface.closest_point(tips[0])[1]])


def _view_curve(m: dict, P, tips) -> _View:
    curve = _shape_of(m)
    u, v, _ = plane_basis(m.get("normal", [0.0, 0.0, 1.0]))

    def draw(ax, uv):
        C = uv(curve_points(curve, 400))
        ax.plot(C[:, 0], C[:, 1], ls="--", color="0.45", lw=1.2, label="the curve")
        ax.plot(*C[0], marker="s", color="0.3", ms=5, ls="none", label="its ends (stops)")
        ax.plot(*C[-1], marker="s", color="0.3", ms=5, ls="none")

    return _View(u, v, "face-on, seen from the side the hand is on", draw,
                 [curve.evaluate(curve.lower), curve.evaluate(curve.upper)])


def _view_default(m: dict, P, tips) -> _View:
    u, v, _ = plane_basis([0.0, 0.0, 1.0])
    return _View(u, v, "world x-y")


#: mechanism type -> its view in the plane figure
VIEWS = {
    "PlanarArm": _view_planar_arm,
    "Probe": _view_probe,
    "PointPivot": _view_point_pivot,
    "LineGuide": _view_line_guide,
    "SurfaceProbe": _view_surface_probe,
    "CurveGuide": _view_curve,
    "HandlePath": _view_curve,
}


# ---------------------------------------------------------------------------------------
# long logs: read block by block, drawn from a bounded selection of rows

#: a log longer than this many rows is drawn from a selection of about this many rows per
#: figure: in every one of equal bins of cycles, the cycles where each plotted quantity is
#: smallest and largest (a min/max envelope, so peaks are kept), plus the snapshots
MAX_POINTS = 20000

#: the log's columns the figures read
FIGURE_COLUMNS = (
    ["t", "px", "py", "pz", "sx", "sy", "sz", "fx", "fy", "fz"]
    + ["ff1x", "ff1y", "ff1z", "ff2x", "ff2y", "ff2z", "fhx", "fhy", "fhz"]
    + ["dist", "dist_normal", "dist_across", "arm_pos_angle", "arm_stylus_angle"]
    + ["theta0", "theta_star0", "status", "member"]
)
#: columns the selection adds: the cumulative activity (_snapshot_indices) and the
#: PlanarArm's angles unwrapped over the whole run
EXTRA_COLUMNS = ["_activity", "_arm_pos_unwrapped", "_arm_stylus_unwrapped"]


class _Selection:
    """Rows of a run's log (the columns FIGURE_COLUMNS + EXTRA_COLUMNS), with the run's
    scenario and info: what the figures draw, in place of the whole log."""

    def __init__(self, result, rows: np.ndarray, decimated: bool):
        self.scenario, self.info = result.scenario, result.info
        self.columns = FIGURE_COLUMNS + EXTRA_COLUMNS
        self.log, self.decimated = rows, decimated

    def col(self, name: str) -> np.ndarray:
        return self.log[:, self.columns.index(name)]

    def cols(self, *names: str) -> np.ndarray:
        return self.log[:, [self.columns.index(n) for n in names]]

    @property
    def t(self) -> np.ndarray:
        return self.col("t")

    @property
    def n_cycles(self) -> int:
        return int(self.log.shape[0])


def _quantities(result, kind: str):
    """The plotted quantities of figure `kind` ("plane" or "time") as functions of a
    block of rows (a _Selection-like view), one value per row."""
    mech = _mechanism(result)
    L = _length(mech)
    resist = any(s["action"] == "resist" for s in result.scenario.data["intent"])

    def F(b):
        return b.cols("fx", "fy", "fz")

    def fmag(b):
        return np.linalg.norm(F(b), axis=1)

    q = [fmag]
    if kind == "plane":
        for c in "xyz":
            q.append(lambda b, c=c: b.col("p" + c))  # the handle's position
            q.append(lambda b, c=c: b.col("p" + c) + L * b.col("s" + c))  # the tip's
        return q
    q += [
        lambda b: np.linalg.norm(b.cols("fhx", "fhy", "fhz"), axis=1),
        lambda b: b.col("dist"),
    ]
    if mech["type"] == "PlanarArm":
        n = np.asarray(mech["normal"], dtype=float)
        n /= np.linalg.norm(n)

        def tangent(b):
            w = b.cols("px", "py", "pz") - np.asarray(mech["pivot"])
            w = w - np.outer(w @ n, n)
            return np.cross(n, w / np.linalg.norm(w, axis=1)[:, None])

        def along(b):
            return np.sum(F(b) * tangent(b), axis=1)

        def across(b):
            tan = tangent(b)
            return np.linalg.norm(F(b) - np.sum(F(b) * tan, axis=1)[:, None] * tan, axis=1)

        q += [along, across]
        q += [lambda b, c=c: b.col(c) for c in EXTRA_COLUMNS[1:] + ["theta0", "theta_star0"]]
    else:
        key = "plane_normal" if "plane_normal" in mech else "normal"
        nn = np.asarray(mech.get(key, [0.0, 0.0, 1.0]), dtype=float)
        nn /= np.linalg.norm(nn)
        q += [
            lambda b: b.col("dist_normal"),
            lambda b: b.col("dist_across"),
            lambda b: F(b) @ nn,
        ]
    if resist:
        normal = np.asarray(mech.get("normal", mech.get("plane_normal", [0.0, 0.0, 1.0])))

        def across_stylus(b, cols):
            a = np.cross(normal.astype(float), b.cols("sx", "sy", "sz"))
            return np.sum(b.cols(*cols) * a, axis=1)

        for cols in (("ff1x", "ff1y", "ff1z"), ("ff2x", "ff2y", "ff2z"), ("fx", "fy", "fz")):
            q.append(lambda b, cols=cols: across_stylus(b, cols))
    return q


class _Rows:
    """A block of rows with named columns (what _quantities' functions read)."""

    def __init__(self, data: np.ndarray, columns: list[str]):
        self.data, self.c = data, {n: i for i, n in enumerate(columns)}

    def col(self, name: str) -> np.ndarray:
        return self.data[:, self.c[name]]

    def cols(self, *names: str) -> np.ndarray:
        return self.data[:, [self.c[n] for n in names]]


def select_rows(
    result, kind: str, max_points: int | None = None, block_rows: int | None = None
) -> _Selection:
    """The rows figure `kind` draws, read block by block (result.blocks): every row if the
    log has at most `max_points`, else, in each of max_points / (2 x quantities) equal
    bins of cycles, the rows where each quantity of the figure (_quantities) is smallest
    and largest (max_points: default MAX_POINTS). Memory: one block, the selection and
    less than one bin of rows."""
    max_points = MAX_POINTS if max_points is None else int(max_points)
    mech = _mechanism(result)
    L = _length(mech)
    N = result.n_cycles
    columns = FIGURE_COLUMNS + EXTRA_COLUMNS
    c = {n: i for i, n in enumerate(FIGURE_COLUMNS)}
    qf = _quantities(result, kind)
    bins = max(1, max_points // (2 * len(qf) + 1))
    size = 1 if N <= max_points else -(-N // bins)  # rows per bin
    kept: list[np.ndarray] = []
    carry = carry_q = None
    prev = None  # the previous block's last row
    act_last = 0.0
    unwrapped_last = np.zeros(2)
    for B in result.blocks(FIGURE_COLUMNS, block_rows):
        if len(B) == 0:
            continue
        P, S = B[:, c["px"] : c["px"] + 3], B[:, c["sx"] : c["sx"] + 3]
        ang = B[:, [c["arm_pos_angle"], c["arm_stylus_angle"]]]
        if prev is not None:  # continue the activity and the unwrapping across blocks
            P = np.vstack([prev[[c["px"], c["py"], c["pz"]]], P])
            S = np.vstack([prev[[c["sx"], c["sy"], c["sz"]]], S])
        step = np.linalg.norm(np.diff(P, axis=0), axis=1) + L * np.linalg.norm(
            np.diff(S, axis=0), axis=1
        )
        act = np.cumsum(np.concatenate([[act_last], step]))
        act = act[1:] if prev is not None else act
        if prev is None:
            unw = np.unwrap(ang, axis=0)
        else:
            raw = prev[[c["arm_pos_angle"], c["arm_stylus_angle"]]]
            unw = np.unwrap(np.vstack([raw, ang]), axis=0)[1:] + (unwrapped_last - raw)
        ext = np.column_stack([B, act, unw])
        prev, act_last, unwrapped_last = B[-1].copy(), float(act[-1]), unw[-1].copy()
        if size == 1:
            kept.append(ext)
            continue
        rows = _Rows(ext, columns)
        Q = np.column_stack([f(rows) for f in qf])
        if carry is not None:
            ext, Q = np.vstack([carry, ext]), np.vstack([carry_q, Q])
        m = len(ext) // size
        if m:
            kept.append(ext[_extremes(Q[: m * size], size)])
        carry, carry_q = ext[m * size :], Q[m * size :]
    if carry is not None and len(carry):
        kept.append(carry[_extremes(carry_q, len(carry))])
    rows = np.concatenate(kept) if kept else np.empty((0, len(columns)))
    return _Selection(result, rows, decimated=size > 1)


def _extremes(Q: np.ndarray, size: int) -> np.ndarray:
    """Row indices (sorted, unique) of the smallest and largest value of every column of
    Q within each bin of `size` consecutive rows (len(Q) a multiple of size)."""
    m = len(Q) // size
    R = Q.reshape(m, size, Q.shape[1])
    base = (np.arange(m) * size)[:, None]
    lo = np.argmin(np.where(np.isnan(R), np.inf, R), axis=1) + base
    hi = np.argmax(np.where(np.isnan(R), -np.inf, R), axis=1) + base
    # and each bin's first row, so that the time axis is covered evenly
    return np.unique(np.concatenate([lo.ravel(), hi.ravel(), base[:, 0]]))


def _snapshot_indices(result, count: int = 6) -> np.ndarray:
    """Cycles to draw: evenly spaced in "activity" (handle travel plus stylus turning, times
    the probe length), so that fast phases get as many snapshots as slow ones; plus the
    first and last cycles and the cycle of the largest force."""
    n = result.n_cycles
    act = result.col("_activity")  # cumulative over every cycle of the run (select_rows)
    idx = {0, n - 1}
    if act[-1] > 1e-6:
        for a in np.linspace(0, act[-1], count)[1:-1]:
            idx.add(int(np.searchsorted(act, a)))
    else:
        idx.update(np.linspace(0, n - 1, count).round().astype(int).tolist())
    f = np.linalg.norm(result.cols("fx", "fy", "fz"), axis=1)
    idx.add(int(np.argmax(f)))
    # drop near-duplicates (less than 2 % of the activity apart)
    out: list[int] = []
    for k in sorted(idx):
        if not out or act[k] - act[out[-1]] > 0.02 * max(act[-1], 1e-9) or k == n - 1:
            out.append(k)
    return np.array(out)


def _no_overlap(fig, texts: list) -> list:
    """Removes the texts (in priority order) that would overlap one kept before; returns
    the window extents of those kept."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    kept = []
    for txt in texts:
        bb = txt.get_window_extent(r).expanded(1.08, 1.15)
        if any(bb.overlaps(k) for k in kept):
            txt.remove()
        else:
            kept.append(bb)
    return [tuple(float(x) for x in k.extents) for k in kept]


def distinct_strokes(order, strokes: dict, tol: float) -> list:
    """The keys of `order` whose stroke (a segment, 2 x 2) does not lie mostly on one kept
    before it: a stroke is dropped when more than 4/5 of it, or of a kept one, is within
    `tol` of the other."""

    def near(a, b) -> float:  # the share of segment a within tol of segment b
        pts = a[0] + np.linspace(0.0, 1.0, 101)[:, None] * (a[1] - a[0])
        d = b[1] - b[0]
        w = np.clip((pts - b[0]) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
        return float(np.mean(np.linalg.norm(pts - (b[0] + w[:, None] * d), axis=1) <= tol))

    kept: list = []
    for k in order:
        if all(near(strokes[k], strokes[j]) <= 0.8 and near(strokes[j], strokes[k]) <= 0.8
               for j in kept):
            kept.append(k)
    return kept


def readable_on_white(colour, contrast: float = 4.5) -> tuple:
    """`colour` darkened, keeping its hue, until its contrast ratio against white reaches
    `contrast` (WCAG 2: (1 + 0.05) / (L + 0.05), L the relative luminance; 4.5 is the
    minimum for text): viridis' light yellows become readable labels."""
    rgb = np.asarray(colour[:3], dtype=float)

    def luminance(c) -> float:
        lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
        return float(lin @ [0.2126, 0.7152, 0.0722])

    while 1.05 / (luminance(rgb) + 0.05) < contrast:
        rgb = rgb * 0.9
    return (*rgb.tolist(), *colour[3:])


def vector_text(x) -> str:
    """A direction for an axis label: (0.97, 0, -0.242), three decimals, no "-0"."""
    return "(" + ", ".join(f"{c:g}" for c in np.round(np.asarray(x, dtype=float), 3) + 0.0) + ")"


class _PlaneFigure:
    """plane_figure's drawing, stage by stage, over the rows it draws."""

    def __init__(self, plt, result, force_scale: float):
        self.plt, self.result = plt, result
        self.mech = mech = _mechanism(result)
        self.L = L = _length(mech)
        self.P = result.cols("px", "py", "pz")
        self.S = result.cols("sx", "sy", "sz")
        self.F = result.cols("fx", "fy", "fz")
        self.F1 = result.cols("ff1x", "ff1y", "ff1z")
        self.F2 = result.cols("ff2x", "ff2y", "ff2z")
        self.tips = self.P + L * self.S
        self.view = VIEWS.get(mech["type"], _view_default)(mech, self.P, self.tips)
        self.u, self.v = self.view.u, self.view.v
        self.contacts = result.info.get("grip_contacts", [-0.015, -0.05])
        self.resist = any(s["action"] == "resist" for s in result.scenario.data["intent"])
        # a PlanarArm's tip is its pivot; a HandlePath holds the handle itself
        self.draw_tip = mech["type"] not in ("PlanarArm", "HandlePath")
        self.grip_len = max(0.45 * L, abs(min(self.contacts)) + 0.01)
        self.scale = float(force_scale)
        self.t = result.t
        self.cmap = plt.get_cmap("viridis")

    def uv(self, x):
        x = np.atleast_2d(x)
        return np.stack([x @ self.u, x @ self.v], axis=1)

    def paths(self, ax):
        """The handle's and the tip's paths."""
        self.hp = hp = self.uv(self.P)
        ax.plot(hp[:, 0], hp[:, 1], color="0.35", lw=0.8, label="handle path")
        if self.draw_tip:
            tp = self.uv(self.tips)
            ax.plot(tp[:, 0], tp[:, 1], color="tab:brown", lw=0.8, ls="--", label="tip path")

    def moments(self):
        """The drawn moments: a stroke lying mostly on one drawn before hides it and piles
        its time label on the other's, so strokes are kept in priority order (the first,
        the last, the largest force, then in time)."""
        P, S, L = self.P, self.S, self.L
        idx = _snapshot_indices(self.result)
        F_mag = np.linalg.norm(self.F, axis=1)
        first = [int(idx[0]), int(idx[-1]), int(idx[np.argmax(F_mag[idx])])]
        strokes = {int(k): self.uv(np.array([P[k] - self.grip_len * S[k], P[k] + 0.08 * L * S[k]]))
                   for k in idx}
        frame = np.vstack([self.hp] + list(strokes.values()))
        tol = 0.02 * float(np.ptp(frame, axis=0).max())
        self.rank = {k: (first.index(k) if k in first else 3, k) for k in strokes}
        return np.array(sorted(distinct_strokes(sorted(strokes, key=self.rank.get), strokes, tol)))

    def arrow(self, ax, at, force, color, lw, **kw):
        f = self.uv(force)[0] * self.scale
        if np.hypot(*f) > 1e-4 * self.L:
            ax.annotate("", xy=at + f, xytext=at,
                        arrowprops=dict(arrowstyle="-|>", color=color, lw=lw), **kw)

    def stroke(self, ax, k: int, c, last: bool):
        """The handle at cycle k (thick), its virtual probe (dotted), the device's force,
        and at the last moment of a resisting run the finger forces."""
        p, s, L = self.P[k], self.S[k], self.L
        back = self.uv(np.array([p - self.grip_len * s, p + 0.08 * L * s]))
        ax.plot(back[:, 0], back[:, 1], color=c, lw=5, solid_capstyle="round")
        probe = self.uv(np.array([p, p + L * s]))
        ax.plot(probe[:, 0], probe[:, 1], color=c, lw=0.8, ls=":")
        if self.draw_tip:
            ax.plot(*probe[1], marker="o", ms=3, color=c)
        self.arrow(ax, self.uv(p)[0], self.F[k], "crimson", 2.0, zorder=6)
        if self.resist and last:
            for cnt, Ff, col in ((self.contacts[0], self.F1[k], "tab:blue"),
                                 (self.contacts[1], self.F2[k], "tab:green")):
                self.arrow(ax, self.uv(p + cnt * s)[0], Ff, col, 1.3)
        return (k, self.uv(p - self.grip_len * s)[0], c)

    def legend_proxies(self, ax):
        ax.plot([], [], color=self.cmap(0.5), lw=5,
                label="handle (thick) and virtual probe (dotted)")
        mm = self.scale * 1e3
        ax.plot([], [], color="crimson", lw=1.6,
                label=f"device force (1 N = {mm:.3g} mm, the same in every figure)")
        if self.resist:
            ax.plot([], [], color="tab:blue", lw=1.3,
                    label="finger forces at the end (1: nearer the handle origin)")
            ax.plot([], [], color="tab:green", lw=1.3, label="finger 2 force")

    def frame(self, ax):
        """Frames the action: the handle path, the drawn handles, the tips and the
        mechanism (drawn by its view)."""
        uv = self.uv
        pts = [self.hp, uv(self.P - self.grip_len * self.S)] + [uv(a) for a in self.view.anchors]
        if self.draw_tip:
            pts.append(uv(self.tips))
        allp = np.vstack(pts)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        pad = 0.12 * max(hi - lo) + 0.004
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        if self.view.draw is not None:
            self.view.draw(ax, uv)
            ax.set_xlim(lo[0] - pad, hi[0] + pad)
            ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal", adjustable="box")

    def titles(self, fig, ax, norm) -> str:
        ax.set_xlabel(f"u [m]  (u = {vector_text(self.u)})")
        ax.set_ylabel(f"v [m]  (v = {vector_text(self.v)})")
        r = self.result
        desc = r.scenario.data["description"].split(":")[0].strip()
        title = textwrap.fill(f"{r.scenario.name}: {desc}", 70) + f"\n{self.view.title}"
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2,
                  frameon=False)
        ax.grid(alpha=0.25)
        sm = self.plt.cm.ScalarMappable(norm=norm, cmap=self.cmap)
        fig.colorbar(
            sm, ax=ax, shrink=0.5, fraction=0.04, pad=0.02, label="time of the drawn handle [s]"
        )
        return title

    def time_labels(self, fig, ax, labels):
        """The time labels: the first, the last and the largest force first; none
        overlapping. Returns the kept labels' window extents."""
        order = sorted(labels, key=lambda x: self.rank[x[0]])
        box = dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8)
        texts = []
        for k, pos, c in order:
            away = self.uv(-self.S[k])[0]  # past the handle's end, away from the probe
            away = away / max(float(np.hypot(*away)), 1e-12)
            texts.append(
                ax.annotate(f"{self.t[k]:.2f} s", pos, fontsize=7, color=readable_on_white(c),
                            textcoords="offset points", xytext=tuple(12 * away), ha="center",
                            va="center", bbox=box, zorder=8)
            )
        return _no_overlap(fig, texts)


def plane_figure(
    result,
    path: str | Path,
    force_scale: float = FORCE_SCALE_M_PER_N,
    max_points: int | None = None,
    block_rows: int | None = None,
) -> dict:
    """The handle seen where the mechanism is clearest (VIEWS: a PlanarArm's circle
    face-on, a Probe's plane edge-on, a PointPivot from the side, a LineGuide across): its
    path, the handle as a thick line at moments of the run with the virtual probe to its tip,
    the device's force as arrows (`force_scale` m per N, the same in every figure); on runs
    where the user resists, the two finger forces. Returns what it drew:
    {"title", "force_scale_m_per_n", "time_labels": kept labels' window extents, "rows":
    how many of the log's rows it drew}. The log is read block by block: a log of more than
    `max_points` rows is drawn from the rows select_rows picks."""
    plt = _plt()
    from matplotlib.colors import Normalize

    result = select_rows(result, "plane", max_points, block_rows)
    d = _PlaneFigure(plt, result, force_scale)
    fig, ax = plt.subplots(figsize=(7.0, 7.0), dpi=110, layout="constrained")
    d.paths(ax)
    idx = d.moments()
    norm = Normalize(0.0, max(float(d.t[-1]), 1e-9))
    labels = [d.stroke(ax, k, d.cmap(norm(d.t[k])), k == idx[-1]) for k in idx]
    d.legend_proxies(ax)
    d.frame(ax)
    title = d.titles(fig, ax, norm)
    kept = d.time_labels(fig, ax, labels)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return {
        "title": title,
        "force_scale_m_per_n": d.scale,
        "time_labels": kept,
        "rows": result.n_cycles,
    }


# ---------------------------------------------------------------------------------------
# time plots: one panel per quantity the mechanism has, no empty panels


def _panel_force(ax, result, mech, t, F) -> None:
    fmag = np.linalg.norm(F, axis=1)
    ax.plot(t, fmag, color="crimson", label="|f| device")
    if mech["type"] == "PlanarArm":
        n = np.asarray(mech["normal"], dtype=float)
        n /= np.linalg.norm(n)
        w = result.cols("px", "py", "pz") - np.asarray(mech["pivot"])
        w = w - np.outer(w @ n, n)
        rad = w / np.linalg.norm(w, axis=1)[:, None]
        tan = np.cross(n, rad)
        ft = np.sum(F * tan, axis=1)
        ax.plot(t, ft, color="tab:orange", lw=0.9, label="along the path")
        ax.plot(
            t,
            np.linalg.norm(F - ft[:, None] * tan, axis=1),
            color="tab:purple",
            lw=0.9,
            label="across the path",
        )
    fh = np.linalg.norm(result.cols("fhx", "fhy", "fhz"), axis=1)
    ax.plot(t, fh, color="0.5", lw=0.8, ls="--", label="|f| hand")
    ax.set_ylabel("force [N]")
    top = max(float(fmag.max()), float(fh.max()), 0.1)
    ax.set_ylim(min(ax.get_ylim()[0], -0.05 * top), 1.08 * top)


def _panel_distance_log(ax, result, mech, t, F) -> None:
    """dist (from where the mechanism allows) on a log scale, with the 1 mm line."""
    from ..sim.geometry import geometry_of

    g = geometry_of(mech)
    floor = 1e-3  # [mm]: the plot's floor on its log scale
    dmm = np.maximum(result.col("dist") * 1e3, floor)
    ax.plot(t, dmm, color="k")
    ax.axhline(1.0, color="tab:red", ls="--", lw=0.8, label="1 mm")
    what = f"{g.point} distance from\n{g.target}" if g else "distance from the\nnearest placement"
    ax.set_ylabel(f"{what} [mm]")
    ax.set_yscale("log")
    ax.set_ylim(floor, max(30.0, 2 * float(dmm.max())))


def _panel_angles(ax, result, mech, t, F) -> None:
    # unwrapped over the whole run (select_rows)
    ax.plot(t, np.degrees(result.col("_arm_pos_unwrapped")), label="handle position")
    sty = np.degrees(result.col("_arm_stylus_unwrapped"))
    ax.plot(t, sty, lw=3.5, alpha=0.45, label="handle (stylus) angle")
    ax.plot(t, np.degrees(result.col("theta_star0")), ls="--", label="mechanism θ* (eq. 25)")
    ax.plot(t, np.degrees(result.col("theta0")), ls=":", label="mechanism θ (nearest)")
    ax.set_ylabel("angle on the\ncircle [deg]")


def _panel_tip_height(ax, result, mech, t, F) -> None:
    """The tip's signed height above the surface (the log's dist_normal)."""
    h = result.col("dist_normal")
    ax.plot(t, h * 1e3, color="k", lw=1.0, label="tip height")
    g = geometry_of(mech)
    target = g.target if g is not None else "the mechanism"
    ax.axhline(0.0, color="tab:red", ls="--", lw=0.8, label=target)
    if mech.get("unilateral"):  # a bilateral mechanism has no side the tip may not go to
        ax.fill_between(
            t, h * 1e3, 0.0, where=h < 0, color="tab:red", alpha=0.15, label="tip behind it"
        )
    if mech["type"] not in ("Probe", "SurfaceProbe"):
        ax.plot(
            t, result.col("dist_across") * 1e3, color="tab:blue", lw=0.9, label="tip offset across"
        )
    what = target if mech["type"] in ("Probe", "SurfaceProbe") else "it, along its normal"
    ax.set_ylabel(f"tip height above\n{what} [mm]")


def _panel_normal_force(ax, result, mech, t, F) -> None:
    """Force along the normal against Kp times the depth (unilateral: the surface pushes
    only while the tip is behind it): the plane's normal, or a surface's at the tip's
    closest point."""
    if mech["type"] == "SurfaceProbe":
        surface = _shape_of(mech)
        tips = result.cols("px", "py", "pz") + _length(mech) * result.cols("sx", "sy", "sz")
        normals = surface.closest_points(tips)[2]
        along, what = np.sum(F * normals, axis=1), "the surface's normal"
    else:
        key = "plane_normal" if "plane_normal" in mech else "normal"
        n = np.asarray(mech[key], dtype=float)
        along, what = F @ (n / np.linalg.norm(n)), "the normal"
    h = result.col("dist_normal")
    kp = float(result.info["controller_model"]["kp"][0])  # the resolved Kp along x
    depth = np.maximum(-h, 0.0) if mech.get("unilateral") else -h
    ax.plot(t, along, color="crimson", label=f"device force along {what}")
    ax.plot(t, kp * depth, color="0.3", ls=":", lw=1.2, label=f"Kp × depth (Kp = {kp:g} N/m)")
    ax.set_ylabel("force along the\nnormal [N]")


def _panel_member(ax, result, mech, t, F) -> None:
    """A mechanism set: the member rendered (-1: none) and the switching blends."""
    member = result.col("member")
    ax.step(t, member, where="post", color="k", lw=1.2, label="member rendered (-1: none)")
    switching = (result.col("status").astype(int) & 64) != 0  # virtmech.status.SWITCHING
    ax.fill_between(t, -1.2, member.max() + 0.2, where=switching, step="post",
                    color="tab:orange", alpha=0.3, label="switching (force rate-limited)")
    ax.set_ylabel("mechanism set\nmember")
    ax.set_yticks(np.arange(-1, int(member.max()) + 1))


def _panel_fingers(ax, result, mech, t, F) -> None:
    S = result.cols("sx", "sy", "sz")
    F1 = result.cols("ff1x", "ff1y", "ff1z")
    F2 = result.cols("ff2x", "ff2y", "ff2z")
    normal = mech.get("normal", mech.get("plane_normal", [0.0, 0.0, 1.0]))
    across = np.cross(np.asarray(normal, dtype=float), S)
    ax.plot(t, np.sum(F1 * across, axis=1), color="tab:blue", label="finger 1 (across stylus)")
    ax.plot(t, np.sum(F2 * across, axis=1), color="tab:green", label="finger 2 (across stylus)")
    ax.plot(t, np.sum(F * across, axis=1), color="crimson", lw=0.8, label="device (across stylus)")
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set_ylabel("force [N]")


#: mechanism type -> the panels after the force (a type not listed: the distance alone)
PANELS = {
    "PlanarArm": (_panel_distance_log, _panel_angles),
    "Probe": (_panel_tip_height, _panel_normal_force),
    "PointPivot": (_panel_distance_log, _panel_tip_height),
    "LineGuide": (_panel_distance_log, _panel_tip_height),
    "SurfaceProbe": (_panel_tip_height, _panel_normal_force),
    "CurveGuide": (_panel_distance_log, _panel_tip_height),
    "HandlePath": (_panel_distance_log,),
}


def time_figure(
    result, path: str | Path, max_points: int | None = None, block_rows: int | None = None
) -> dict:
    """Force over time (for a PlanarArm also along and across the path), then the panels
    of PANELS for the mechanism (a PlanarArm: distance from the circle and angles on it; a
    Probe: the tip's height above its plane and the force along the normal against Kp times
    the depth; a PointPivot or LineGuide: the tip's distance and height), and, where the user
    resists, the finger forces across the stylus. Returns {"panels": the y labels, "rows":
    how many of the log's rows it drew}. The log is read block by block: a log of more than
    `max_points` rows is drawn from the rows select_rows picks (each curve's smallest and
    largest value in every bin of cycles)."""
    plt = _plt()
    mech = _mechanism(result)
    result = select_rows(result, "time", max_points, block_rows)
    t = result.t
    F = result.cols("fx", "fy", "fz")
    resist = any(s["action"] == "resist" for s in result.scenario.data["intent"])
    panels = [_panel_force, *PANELS.get(mech["type"], (_panel_distance_log,))]
    if result.info.get("set_members"):
        panels.append(_panel_member)
    if resist:
        panels.append(_panel_fingers)
    rows = len(panels)
    fig, axes = plt.subplots(rows, 1, figsize=(9.5, 2.1 * rows + 0.6), dpi=110, sharex=True,
                             layout="constrained")
    axes = np.atleast_1d(axes)
    for ax, panel in zip(axes, panels):
        panel(ax, result, mech, t, F)
        ax.grid(alpha=0.3)
        # beside the panel, where it covers none of its curves
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(f"{result.scenario.name}", fontsize=10)
    fig.savefig(path)
    out = {"panels": [ax.get_ylabel() for ax in axes], "rows": result.n_cycles}
    plt.close(fig)
    return out


#: mechanisms whose geometry a plane view cannot show whole: a 3-D figure (scene.png)
SHAPED = ("SurfaceProbe", "CurveGuide", "HandlePath")


#: the world's axes by name
AXIS_NAMES = "xyz"


def world_up(scenario) -> np.ndarray:
    """The unit vector up in the scenario's world: against gravity (the PHANTOM Omni's
    OpenHaptics frame: +y; other devices: +z)."""
    from ..builder import make_device
    from ..sim.model import world_gravity

    g = world_gravity(make_device(scenario.data["device"]))
    return -g / np.linalg.norm(g)


def scene_axes(up) -> tuple[list[int], np.ndarray]:
    """The world's axes drawn as a 3-D plot's (X, Y, Z): Z the world axis nearest `up` (its
    sign turned so that Z points up), X and Y the other two in cyclic order (a right-handed
    plot of the same world: for up = +y, (X, Y, Z) = (z, x, y)). Returns the world axis of
    each plot axis and its sign (X, Y, Z) = sign * world[axes]."""
    up = np.asarray(up, dtype=float)
    k = int(np.argmax(np.abs(up)))
    axes = [(k + 1) % 3, (k + 2) % 3, k]
    sign = np.ones(3)
    if up[k] < 0:  # turn two axes: Z up, the plot still right-handed
        sign[1:] = -1.0
    return axes, sign


def _horizontal(v, up) -> np.ndarray:
    """v (a vector or rows of vectors) without its part along up."""
    v = np.asarray(v, dtype=float)
    return v - np.multiply.outer(v @ up, up)


def scene_view(mech: dict, tips, S, up) -> tuple[np.ndarray, float]:
    """Where the 3-D figure is seen from: the camera's unit direction (world, from the scene
    toward the camera) and its elevation [deg]. A surface from the hand's side (the side the
    stylus leans toward, or the user's side for a stylus near vertical), 25° above, across
    the tip's main motion, turned 30° so that depth shows; a curve from the side its normal
    points to (the hand's), between 20° and 60° above."""
    up = np.asarray(up, dtype=float)
    hand = _horizontal(-np.mean(S, axis=0), up)  # where the hand holds the stylus from
    if np.linalg.norm(hand) < 0.3:  # a stylus within 17° of vertical: the user's side, the
        hand = np.roll(up, 1)  # axis after up (+z, toward the user, in OpenHaptics' frame)
    hand /= np.linalg.norm(hand)
    if "surface" in mech:
        W = _horizontal(tips - tips.mean(axis=0), up)
        if np.abs(W).max() > 1e-6:
            d = np.linalg.svd(W, full_matrices=False)[2][0]
            side = np.cross(up, _horizontal(d, up))
            c = side if side @ hand >= 0 else -side
            c = c / np.linalg.norm(c) if np.linalg.norm(c) > 1e-9 else hand
        else:
            c = hand
        turn = np.radians(30.0)  # about up: c cos + (up x c) sin
        c = c * np.cos(turn) + np.cross(up, c) * np.sin(turn)
        elev = 25.0
    else:
        n = np.asarray(mech.get("normal", up), dtype=float)
        n /= np.linalg.norm(n)
        elev = float(np.clip(np.degrees(np.arcsin(np.clip(n @ up, -1, 1))), 20.0, 60.0))
        h = _horizontal(n, up)
        c = h / np.linalg.norm(h) if np.linalg.norm(h) > 0.2 else hand
        turn = np.radians(30.0)
        c = c * np.cos(turn) + np.cross(up, c) * np.sin(turn)
    e = np.radians(elev)
    return np.cos(e) * c + np.sin(e) * up, elev


def scene_figure(result, path: str | Path, max_points: int | None = None,
                 block_rows: int | None = None) -> dict:
    """The mechanism's surface or curve in 3-D with the handle's and the tip's paths, the
    tip coloured where it touches (dist_normal <= 0 for a probe on a surface) and the
    stylus at moments of the run. The world's up (against gravity: +y in the Omni's
    OpenHaptics frame) is drawn up, the three axes at one scale, seen from the hand's side
    (scene_view). Returns {"rows": the log's rows, "axes": the world axis of each plot axis
    (X, Y, Z), "sign": their signs, "elev", "azim": the view [deg]}."""
    plt = _plt()
    from matplotlib.ticker import MaxNLocator

    result = select_rows(result, "plane", max_points, block_rows)
    mech = _mechanism(result)
    shape = _shape_of(mech)
    L = 0.0 if mech["type"] == "HandlePath" else _length(mech)
    P = result.cols("px", "py", "pz")
    S = result.cols("sx", "sy", "sz")
    tips = P + L * S
    up = world_up(result.scenario)
    axes, sign = scene_axes(up)

    def plot(X):  # world points (..., 3) -> the plot's coordinates
        return np.asarray(X)[..., axes] * sign

    fig = plt.figure(figsize=(7.0, 6.4), dpi=110)
    ax = fig.add_subplot(projection="3d")
    if "surface" in mech:
        G = plot(surface_grid(shape, 20))
        ax.plot_wireframe(G[..., 0], G[..., 1], G[..., 2], color="0.6", lw=0.5,
                          label="the surface")
        touching = result.col("dist_normal") <= 0.0
        shape_pts = G.reshape(-1, 3)
    else:
        C = plot(curve_points(shape, 300))
        ax.plot(C[:, 0], C[:, 1], C[:, 2], color="0.35", ls="--", lw=1.2, label="the curve")
        touching = result.col("dist") <= 1e-3
        shape_pts = C
    hp, tp = plot(P), plot(tips)
    ax.plot(hp[:, 0], hp[:, 1], hp[:, 2], color="0.3", lw=0.8, label="handle path")
    if L > 0:
        ax.plot(tp[:, 0], tp[:, 1], tp[:, 2], color="tab:brown", lw=0.8, ls=":",
                label="tip path")
        ax.scatter(*tp[touching].T, s=2, color="crimson",
                   label="tip touching" if "surface" in mech else "tip within 1 mm of it")
    grip = 0.4 * _length(mech)
    for n, k in enumerate(_snapshot_indices(result)):
        seg = plot(np.array([P[k] - grip * S[k], P[k] + L * S[k]]))
        ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color="tab:blue", lw=2.0, alpha=0.7,
                label=None if n else "the stylus at moments of the run (hand end to tip)")
    # one scale on every axis: a cube around the shape and the paths
    X = np.vstack([hp, tp, shape_pts])
    c = (X.max(axis=0) + X.min(axis=0)) / 2
    r = 0.52 * float(np.ptp(X, axis=0).max()) + 0.005
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    names = [("−" if sg < 0 else "") + AXIS_NAMES[a] for a, sg in zip(axes, sign)]
    ax.set_xlabel(f"{names[0]} [m]")
    ax.set_ylabel(f"{names[1]} [m]")
    ax.set_zlabel(f"{names[2]} [m]  (up)")
    cam, elev = scene_view(mech, tips, S, up)
    cp = plot(cam)
    azim = float(np.degrees(np.arctan2(cp[1], cp[0])))
    ax.view_init(elev=elev, azim=azim)
    ax.set_title(f"{result.scenario.name}: {mech['type']} in 3-D, {AXIS_NAMES[axes[2]]} up",
                 fontsize=10)
    fig.tight_layout(rect=(0.0, 0.1, 1.0, 1.0))
    fig.legend(*ax.get_legend_handles_labels(), fontsize=7, loc="lower center", ncol=2,
               frameon=False)
    fig.savefig(path)
    plt.close(fig)
    return {"rows": result.n_cycles, "axes": axes, "sign": sign.tolist(), "elev": elev,
            "azim": azim}


def write_figures(
    result,
    out_dir: str | Path,
    force_scale: float = FORCE_SCALE_M_PER_N,
    max_points: int | None = None,
    block_rows: int | None = None,
) -> list[Path]:
    """plane.png and time.png of a run in out_dir (created); one force scale for all. The
    log is read block by block (`block_rows` at a time; see plane_figure, time_figure)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plane_figure(result, out / "plane.png", force_scale, max_points, block_rows)
    time_figure(result, out / "time.png", max_points, block_rows)
    written = [out / "plane.png", out / "time.png"]
    if _mechanism(result)["type"] in SHAPED:
        scene_figure(result, out / "scene.png", max_points, block_rows)
        written.append(out / "scene.png")
    return written
