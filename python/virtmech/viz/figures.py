"""Figures of a run in the paper's style: the plane face-on, the handle drawn as a thick
line, force arrows; time plots of force and distance from the circle (for a Probe: the
tip's height above its plane and the force along the normal against Kp times the depth)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


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


def _mechanism_plane(result):
    m = result.info["mechanism"]
    if m["type"] == "PlanarArm":
        return np.asarray(m["pivot"]), np.asarray(m["normal"]), float(m["length"])
    return None, None, None


def _snapshot_indices(result, count: int = 6) -> np.ndarray:
    """Cycles to draw: evenly spaced in "activity" (handle travel plus stylus turning, times
    the probe length), so that fast phases get as many snapshots as slow ones; plus the
    first and last cycles and the cycle of the largest force."""
    n = result.n_cycles
    P = result.cols("px", "py", "pz")
    S = result.cols("sx", "sy", "sz")
    _, _, L = _mechanism_plane(result)
    L = L or 0.08
    step = np.linalg.norm(np.diff(P, axis=0), axis=1) + L * np.linalg.norm(
        np.diff(S, axis=0), axis=1
    )
    act = np.concatenate([[0.0], np.cumsum(step)])
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


def plane_figure(result, path: str | Path) -> None:
    """The mechanism's plane face-on: the circle and its pivot, the handle path, the handle
    as a thick line with the virtual probe to the pivot, the device's force as arrows; on
    runs where the user resists, the two finger forces."""
    plt = _plt()
    pivot, normal, L = _mechanism_plane(result)
    if normal is None:
        normal = [0.0, 0.0, 1.0]
    u, v, _ = plane_basis(normal)
    P = result.cols("px", "py", "pz")
    S = result.cols("sx", "sy", "sz")
    F = result.cols("fx", "fy", "fz")
    F1 = result.cols("ff1x", "ff1y", "ff1z")
    F2 = result.cols("ff2x", "ff2y", "ff2z")
    contacts = result.info.get("grip_contacts", [-0.015, -0.05])
    resist = any(s["action"] == "resist" for s in result.scenario.data["intent"])

    def uv(x):
        x = np.atleast_2d(x)
        return np.stack([x @ u, x @ v], axis=1)

    L = L if L else 0.08
    grip_len = max(0.45 * L, abs(min(contacts)) + 0.01)
    fmax = max(float(np.linalg.norm(F, axis=1).max()), 1e-9)
    if resist:
        fmax = max(fmax, float(np.linalg.norm(F1, axis=1).max()))
    scale = 0.35 * L / max(fmax, 1.0)  # m per N: small forces look small

    fig, ax = plt.subplots(figsize=(7.0, 7.0), dpi=110)
    if pivot is not None:
        a = np.linspace(0, 2 * np.pi, 400)
        pc = uv(pivot)[0]
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
    hp = uv(P)
    ax.plot(hp[:, 0], hp[:, 1], color="0.35", lw=0.8, label="handle path")
    idx = _snapshot_indices(result)
    cmap = plt.get_cmap("viridis")
    t = result.t
    for j, k in enumerate(idx):
        c = cmap(j / max(len(idx) - 1, 1))
        p, s = P[k], S[k]
        back = uv(np.array([p - grip_len * s, p + 0.08 * L * s]))
        ax.plot(back[:, 0], back[:, 1], color=c, lw=5, solid_capstyle="round")
        probe = uv(np.array([p, p + L * s]))
        ax.plot(probe[:, 0], probe[:, 1], color=c, lw=0.8, ls=":")
        f = uv(F[k])[0] * scale
        pu = uv(p)[0]
        if np.hypot(*f) > 1e-4 * L:
            ax.annotate(
                "",
                xy=pu + f,
                xytext=pu,
                arrowprops=dict(arrowstyle="-|>", color="crimson", lw=2.0),
                zorder=6,
            )
        if resist and k == idx[-1]:
            for cnt, Ff, col in (
                (contacts[0], F1[k], "tab:blue"),
                (contacts[1], F2[k], "tab:green"),
            ):
                pc_ = uv(p + cnt * s)[0]
                ff = uv(Ff)[0] * scale
                if np.hypot(*ff) > 1e-4 * L:
                    ax.annotate(
                        "",
                        xy=pc_ + ff,
                        xytext=pc_,
                        arrowprops=dict(arrowstyle="-|>", color=col, lw=1.3),
                    )
        ax.annotate(
            f"{t[k]:.2f} s",
            uv(p - grip_len * s)[0],
            fontsize=7,
            color=c,
            textcoords="offset points",
            xytext=(3, 3),
        )
    # legend proxies
    ax.plot([], [], color=cmap(0.5), lw=5, label="handle (thick) and virtual probe (dotted)")
    ax.annotate("", xy=(0, 0), xytext=(0, 0))
    ax.plot([], [], color="crimson", lw=1.6, label=f"device force (1 N = {scale * 1e3:.1f} mm)")
    if resist:
        ax.plot(
            [],
            [],
            color="tab:blue",
            lw=1.3,
            label="finger forces at the end (1: nearer the handle origin)",
        )
        ax.plot([], [], color="tab:green", lw=1.3, label="finger 2 force")
    # frame the action: the handle path, the drawn handles and the pivot
    pts = [hp, uv(P - grip_len * S)]
    if pivot is not None:
        pts.append(uv(pivot))
    allp = np.vstack(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    pad = 0.12 * max(hi - lo) + 0.004
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(f"u [m]  (u = {np.round(u, 3).tolist()})")
    ax.set_ylabel(f"v [m]  (v = {np.round(v, 3).tolist()})")
    desc = result.scenario.data["description"].split(":")[0].strip()
    ax.set_title(f"{result.scenario.name}: {desc}\nplane seen face-on", fontsize=10)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    ax.grid(alpha=0.25)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def time_figure(result, path: str | Path) -> None:
    """Force (magnitude; along and across the path), distance from the circle, angles on
    the circle, and, where the user resists, the finger forces across the stylus."""
    plt = _plt()
    pivot, normal, _ = _mechanism_plane(result)
    t = result.t
    P = result.cols("px", "py", "pz")
    F = result.cols("fx", "fy", "fz")
    fmag = np.linalg.norm(F, axis=1)
    resist = any(s["action"] == "resist" for s in result.scenario.data["intent"])
    mech = result.scenario.data["mechanism"]
    probe = mech["type"] == "Probe"  # a plane: the tip's height and the normal force
    rows = (3 if pivot is not None or probe else 1) + (1 if resist else 0)
    fig, axes = plt.subplots(rows, 1, figsize=(7.5, 2.1 * rows + 0.6), dpi=110, sharex=True)
    axes = np.atleast_1d(axes)
    ax = axes[0]
    ax.plot(t, fmag, color="crimson", label="|f| device")
    if pivot is not None:
        n = np.asarray(normal, dtype=float)
        n /= np.linalg.norm(n)
        w = P - pivot
        w = w - np.outer(w @ n, n)
        rad = w / np.linalg.norm(w, axis=1)[:, None]
        tan = np.cross(n, rad)
        ax.plot(t, np.sum(F * tan, axis=1), color="tab:orange", lw=0.9, label="along the path")
        ax.plot(
            t,
            np.linalg.norm(F - np.sum(F * tan, axis=1)[:, None] * tan, axis=1),
            color="tab:purple",
            lw=0.9,
            label="across the path",
        )
    fh = np.linalg.norm(result.cols("fhx", "fhy", "fhz"), axis=1)
    ax.plot(t, fh, color="0.5", lw=0.8, ls="--", label="|f| hand")
    ax.set_ylabel("force [N]")
    top = max(float(fmag.max()), float(fh.max()), 0.1)
    ax.set_ylim(min(ax.get_ylim()[0], -0.05 * top), 1.35 * top)
    ax.legend(fontsize=7, ncol=4, loc="upper right", framealpha=0.9)
    ax.grid(alpha=0.3)
    if probe:
        _probe_panels(result, axes[1], axes[2], mech, t, F)
    if pivot is None:
        _finish_time_figure(fig, axes, result, path, resist, normal, t, F)
        return
    ax = axes[1]
    floor = 1e-3  # [mm]: the plot's floor on its log scale
    dmm = np.maximum(result.col("dist") * 1e3, floor)
    ax.plot(t, dmm, color="k")
    ax.axhline(1.0, color="tab:red", ls="--", lw=0.8, label="1 mm")
    ax.set_ylabel("distance from\nthe circle [mm]")
    ax.set_yscale("log")
    ax.set_ylim(floor, max(30.0, 2 * float(dmm.max())))
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3)
    ax = axes[2]
    if pivot is not None:
        ax.plot(t, np.degrees(np.unwrap(result.col("arm_pos_angle"))), label="handle position")
        sty = np.degrees(np.unwrap(result.col("arm_stylus_angle")))
        ax.plot(t, sty, lw=3.5, alpha=0.45, label="handle (stylus) angle")
        ax.plot(t, np.degrees(result.col("theta_star0")), ls="--", label="mechanism θ* (eq. 25)")
        ax.plot(t, np.degrees(result.col("theta0")), ls=":", label="mechanism θ (nearest)")
        ax.set_ylabel("angle on the\ncircle [deg]")
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.35 * (hi - lo))
        ax.legend(fontsize=7, ncol=2, loc="upper left", framealpha=0.9)
    ax.grid(alpha=0.3)
    _finish_time_figure(fig, axes, result, path, resist, normal, t, F)


def _probe_panels(result, ax_h, ax_f, mech: dict, t, F) -> None:
    """A Probe's plane: the tip's height above it, and the force along its normal against
    Kp times the depth (unilateral: the plane pushes only while the tip is behind it)."""
    n = np.asarray(mech["plane_normal"], dtype=float)
    n /= np.linalg.norm(n)
    P = result.cols("px", "py", "pz")
    S = result.cols("sx", "sy", "sz")
    h = (P - np.asarray(mech["plane_point"])) @ n + mech["length"] * (S @ n)
    ax_h.plot(t, h * 1e3, color="k", lw=1.0)
    ax_h.axhline(0.0, color="tab:red", ls="--", lw=0.8, label="the plane")
    ax_h.fill_between(t, h * 1e3, 0.0, where=h < 0, color="tab:red", alpha=0.15,
                      label="tip behind the plane")
    ax_h.set_ylabel("tip height above\nthe plane [mm]")
    ax_h.legend(fontsize=7, loc="lower left")
    ax_h.grid(alpha=0.3)
    kp = float(result.info["controller_model"]["kp"][0])  # the resolved Kp along x
    depth = np.maximum(-h, 0.0) if mech.get("unilateral") else -h
    ax_f.plot(t, F @ n, color="crimson", label="device force along the normal")
    ax_f.plot(t, kp * depth, color="0.3", ls=":", lw=1.2, label=f"Kp × depth (Kp = {kp:g} N/m)")
    ax_f.set_ylabel("force along the\nnormal [N]")
    lo, hi = ax_f.get_ylim()
    ax_f.set_ylim(lo, hi + 0.35 * (hi - lo))
    ax_f.legend(fontsize=7, ncol=2, loc="upper left", framealpha=0.9)
    ax_f.grid(alpha=0.3)


def _finish_time_figure(fig, axes, result, path, resist: bool, normal, t, F) -> None:
    plt = _plt()
    if resist:
        ax = axes[-1]
        S = result.cols("sx", "sy", "sz")
        F1 = result.cols("ff1x", "ff1y", "ff1z")
        F2 = result.cols("ff2x", "ff2y", "ff2z")
        across = np.cross(np.asarray(normal if normal is not None else [0, 0, 1.0]), S)
        ax.plot(t, np.sum(F1 * across, axis=1), color="tab:blue", label="finger 1 (across stylus)")
        ax.plot(t, np.sum(F2 * across, axis=1), color="tab:green", label="finger 2 (across stylus)")
        ax.plot(
            t, np.sum(F * across, axis=1), color="crimson", lw=0.8, label="device (across stylus)"
        )
        ax.axhline(0, color="0.5", lw=0.6)
        ax.set_ylabel("force [N]")
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.45 * (hi - lo))
        ax.legend(fontsize=7, ncol=3, loc="upper right", framealpha=0.9)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(f"{result.scenario.name}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def write_figures(result, out_dir: str | Path) -> list[Path]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plane_figure(result, out / "plane.png")
    time_figure(result, out / "time.png")
    return [out / "plane.png", out / "time.png"]
