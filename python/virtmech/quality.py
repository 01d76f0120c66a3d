"""Rendering quality, measured on the simulation: what a user feels.

For a scenario's device, mechanism, controller settings and hand (its intents are replaced),
each measure runs short simulations (virtmech.sim.run) and reduces their logs:

- `stiffness`: rendered stiffness per constrained axis and the deviation under pushes of a
  pure force (0.5 N and 1 N by default), the hand's own stiffness off;
- `free_force`: the force along the free direction while the hand moves along the
  mechanism at constant speeds (0.05 and 0.2 m/s): what a fully actuated device renders as
  zero;
- `work`: the motors' exact work over closed runs (the torque held over each control cycle
  times the joints' displacement), and how far a released handle travels;
- `limit_cycles`: sustained oscillation after a tap, over a grid of hands and a released
  handle;
- `stability_map`: the Kp x Kv plane (Z-width style): which gains stay free of limit cycles;
- `fidelity`: the force the under-actuated device renders against a fully actuated variant
  of it rendering the same mechanism with the same hand, for eq. 11, eq. 26 and the naive
  law (a full six-axis impedance with what the device cannot render dropped).

Every run is independent; `workers` > 1 runs them in a process pool.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from itertools import product
from typing import Any

import numpy as np

import virtmech as vm

#: hand grid of the stability checks (relaxed to tense; Hajian & Howe 1997 fits of the arm
#: and fingertip): mass [kg], damping [N·s/m], stiffness [N/m]
HUMAN_GRID = {
    "mass_kg": (0.05, 0.2, 0.6),
    "damping": (2.0, 5.0, 10.0),
    "stiffness": (50.0, 200.0, 500.0),
}
#: a limit cycle: the force's AC part over the last window above this [N] rms (well above
#: the encoders' quantisation times Kp: 55 µm x 3 N/mm = 0.17 N steps) ...
LIMIT_CYCLE_RMS_N = 0.3
#: ... and not decaying: at least this fraction of the window before
LIMIT_CYCLE_PERSISTENCE = 0.7
#: quiet: the force's AC part at most this [N] rms
QUIET_RMS_N = 0.1
#: the window [s]
LIMIT_CYCLE_WINDOW_S = 0.3

#: how far into a unilateral probe's surface the hand holds the tip's anchor while it moves
#: along it (`free_force`): the hand's 200 N/m presses with about 0.5 N [m]
PRESS_DEPTH_M = 3e-3
#: the speed at which the hand first brings a resting tip down onto the surface [m/s]
APPROACH_SPEED_M_S = 0.02

#: columns a measure reads from each run
_COLUMNS = (
    "t",
    "px",
    "py",
    "pz",
    "sx",
    "sy",
    "sz",
    "vx",
    "vy",
    "vz",
    "fx",
    "fy",
    "fz",
    "mx",
    "my",
    "mz",
    "status",
)


# ---------------------------------------------------------------------------------------
# runs


@dataclass
class Run:
    """What a measure keeps of one simulation: the named columns, tau and q (n columns)."""

    cols: dict[str, np.ndarray]
    tau: np.ndarray
    q: np.ndarray

    @property
    def t(self) -> np.ndarray:
        return self.cols["t"]

    def motor_work(self, k0: int = 0, k1: int | None = None) -> float:
        """The motors' work [J] from control cycle k0 to k1: tau_k held from q_k to q_k+1."""
        k1 = len(self.t) - 1 if k1 is None else k1
        return float(np.sum(self.tau[k0:k1] * np.diff(self.q[k0 : k1 + 1], axis=0)))


def _simulate(raw: dict) -> Run:
    from . import scenarios as sc
    from .runner import run_scenario

    scenario = sc.validate(raw, source=f"quality:{raw.get('name', '?')}")
    r = run_scenario(scenario, keep=_COLUMNS, metrics=False).result
    n = sum(c.startswith("tau") and c[3:].isdigit() for c in r.columns)
    extra = [c for c in ("arm_pos_angle",) if c in r.columns]
    cols = {c: r.col(c) for c in (*_COLUMNS, *extra)}
    tau = r.cols(*[f"tau{i}" for i in range(n)])
    q = r.cols(*[f"q{i}" for i in range(n)])
    return Run(cols, tau, q)


def run_all(raws: Sequence[dict], workers: int | None = 1) -> list[Run]:
    """Simulates every raw scenario, in order; workers > 1 (None: the machine's cores) in a
    process pool (virtmech.pool)."""
    from .pool import run_tasks

    return run_tasks(
        _simulate, list(raws), workers=workers, preload=["virtmech.quality", "virtmech.runner"]
    )


# ---------------------------------------------------------------------------------------
# the scenario a measure varies


class Setup:
    """A scenario's device, mechanism, controller, hand, physics and start: the measures
    replace its intents (and, where they say so, its controller settings and hand)."""

    def __init__(self, scenario, controller: dict | None = None, human: dict | None = None):
        from . import scenarios as sc

        if not isinstance(scenario, sc.Scenario):
            scenario = sc.load(scenario)
        if (scenario.data.get("set") or {}).get("members"):
            raise ValueError(SET_REFUSED.format(scenario=scenario.name))
        self.scenario = scenario
        self.raw = {k: v for k, v in scenario.raw.items() if k not in ("intent", "checks")}
        self.raw.setdefault("controller", {})
        self.raw["controller"] = {**self.raw["controller"], **(controller or {})}
        if human:
            self.raw["human"] = {**self.raw.get("human", {}), **human}
        self.mechanism = scenario.data["mechanism"]
        from .builder import build

        self._mech = build(scenario, simulated=False).mechanism
        self._start: np.ndarray | None = None

    def raw_with(
        self,
        name: str,
        intents: list[dict],
        duration_s: float,
        controller: dict | None = None,
        human: dict | None = None,
    ) -> dict:
        raw = dict(self.raw)
        raw["name"] = f"{self.scenario.name}-{name}".replace(" ", "-")
        raw["intent"] = intents
        raw["duration_s"] = duration_s
        raw["controller"] = {**self.raw["controller"], **(controller or {})}
        if human:
            raw["human"] = {**self.raw.get("human", {}), **human}
        return raw

    # the point the mechanism holds: the handle (PlanarArm, HandlePath) or the stylus tip
    def point(self, run: Run) -> np.ndarray:
        p = np.stack([run.cols["px"], run.cols["py"], run.cols["pz"]], axis=1)
        if self.mechanism["type"] in HANDLE_MECHANISMS:
            return p
        s = np.stack([run.cols["sx"], run.cols["sy"], run.cols["sz"]], axis=1)
        return p + self.mechanism["length"] * s

    def start(self, workers: int | None = 1) -> Run:
        """A short hold: where the handle rests at the start."""
        return run_all([self.raw_with("rest", [_hold(0.0, 0.4)], 0.4)], workers)[0]

    def constrained_axes(self, rest: Run) -> dict[str, np.ndarray]:
        """The directions the mechanism holds its point in, at rest (unit, world axes): its
        kind's (virtmech.constrained_directions)."""
        axes = vm.constrained_directions(self._mech, self.point(rest)[-1])
        if not axes:
            raise ValueError(
                f"mechanism.type: quality measures {', '.join(QUALITY_MECHANISMS)}, "
                f"got {self.mechanism['type']!r}"
            )
        return {name: np.asarray(a, dtype=float) for name, a in axes.items()}

    def contact_point(self, rest: Run) -> np.ndarray | None:
        """For a unilateral probe (Probe, SurfaceProbe), the surface's point under the
        resting tip (its closest point): a push into the surface deforms it only from there
        (a tip resting above it first crosses the gap). None for other mechanisms."""
        m = self.mechanism
        if not m.get("unilateral") or m["type"] not in ("Probe", "SurfaceProbe"):
            return None
        p0 = self.point(rest)[-1]
        if m["type"] == "Probe":
            n = _unit(m["plane_normal"])
            return p0 - ((p0 - np.asarray(m["plane_point"], dtype=float)) @ n) * n
        return np.asarray(_shape(m).closest_point(p0)[1], dtype=float)

    def approach(self, rest: Run, depth_m: float = PRESS_DEPTH_M) -> np.ndarray | None:
        """For a unilateral probe, the offset that takes the resting tip to `depth_m` into
        the surface under it (the hand then presses the tip onto it); None for others."""
        contact = self.contact_point(rest)
        if contact is None:
            return None
        into = next(iter(self.constrained_axes(rest).values()))  # its only axis
        return contact + depth_m * into - self.point(rest)[-1]

    def path(self, rest: Run, distance_m: float, steps: int = 20,
             depth_m: float = 0.0) -> list[list[float]]:
        """Offsets along the mechanism, `distance_m` long, from where its point rests (from
        `depth_m` into the surface under it, for a unilateral probe): a polyline for the
        hand's anchor, straight for planes and lines, on the shape for curves and surfaces
        (at that depth along its normal), so the motion stays along what the mechanism
        leaves free."""
        m = self.mechanism
        p0 = self.point(rest)[-1]
        if m["type"] in ("CurveGuide", "HandlePath"):
            return _along_curve(_shape(m), p0, distance_m, steps)
        if m["type"] == "SurfaceProbe":
            return _along_surface(_shape(m), p0, distance_m, steps, depth_m)
        return [list(_tangent(m) * distance_m)]


#: why a scenario with a MechanismSet is not measured
SET_REFUSED = ("{scenario}: set.members: a Setup measures one mechanism, got a set: "
               "measure_scenario measures each member (member_scenarios)")

#: the mechanisms the measures know, and those of them that hold the handle (not the tip)
QUALITY_MECHANISMS = ("PlanarArm", "Probe", "PointPivot", "LineGuide", "SurfaceProbe",
                      "CurveGuide", "HandlePath")
HANDLE_MECHANISMS = ("PlanarArm", "HandlePath")


def _shape(m: dict):
    from .shapes import shape_from_dict

    return shape_from_dict(m["surface"] if m["type"] == "SurfaceProbe" else m["curve"])


def _along_curve(curve, p0: np.ndarray, distance_m: float, steps: int) -> list[list[float]]:
    """Points of the curve from the one closest to p0, `distance_m` of arc length on
    (toward the end with room for it, else the other), as offsets from that point."""
    u0, c0 = curve.closest_point(p0)
    c0 = np.asarray(c0, dtype=float)
    best = None
    for end in (curve.upper, curve.lower):
        u = np.linspace(u0, end, 4001)
        pts = np.array([curve.evaluate(x) for x in u])
        s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
        if best is None or s[-1] > best[1][-1]:
            best = (pts, s)
        if s[-1] >= distance_m:
            break
    pts, s = best
    targets = np.linspace(0.0, min(distance_m, s[-1]), steps + 1)[1:]
    out = np.stack([np.interp(targets, s, pts[:, k]) for k in range(3)], axis=1)
    return (out - c0).tolist()


def _along_surface(surface, p0: np.ndarray, distance_m: float, steps: int,
                   depth_m: float = 0.0) -> list[list[float]]:
    """Points of the surface from the one closest to p0 along its first parameter's
    direction, stepped on in the tangent plane and brought back onto the surface, each
    `depth_m` into it along its normal there, as offsets from the first such point."""
    uv, c = surface.closest_point(p0)
    x = np.asarray(c, dtype=float)
    direction = _unit(np.asarray(surface.derivatives(*uv, 1)[1][0], dtype=float))  # S_u
    n = np.asarray(surface.normal(*uv), dtype=float)
    start, out = x - depth_m * n, []
    h = distance_m / steps
    # along +S_u, or -S_u where the patch's edge is nearer that way
    if np.linalg.norm(np.asarray(surface.closest_point(x - h * direction)[1]) - x) > \
            np.linalg.norm(np.asarray(surface.closest_point(x + h * direction)[1]) - x):
        direction = -direction
    for _ in range(steps):
        direction = _unit(direction - (direction @ n) * n)
        uv, x_new = surface.closest_point(x + h * direction)
        x_new = np.asarray(x_new, dtype=float)
        if np.linalg.norm(x_new - x) < 0.5 * h:
            break  # at the patch's edge: the path ends there
        direction = _unit(x_new - x)
        x = x_new
        n = np.asarray(surface.normal(*uv), dtype=float)
        out.append((x - depth_m * n - start).tolist())
    return out


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _hold(start: float, duration: float, **kw) -> dict:
    return {"action": "hold", "start_s": start, "duration_s": duration, **kw}


def _push(start: float, duration: float, force, ramp: float = 0.2) -> dict:
    # a push of a pure force: the hand's translational stiffness off (its damping stays,
    # which a static push does not feel), the stylus held in orientation as a hand holds it
    return {
        "action": "push",
        "start_s": start,
        "duration_s": duration,
        "ramp_s": ramp,
        "force": [float(x) for x in force],
        "stiffness": 0.0,
    }


def _window(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    return (t >= t0) & (t < t1)


# ---------------------------------------------------------------------------------------
# the measures


def stiffness(
    setup: Setup,
    forces: Iterable[float] = (0.5, 1.0),
    workers: int | None = 1,
    rest: Run | None = None,
) -> dict:
    """Per constrained axis: the deviation [m] of the mechanism's point along the push under
    each force, and the rendered stiffness [N/m] (force / deviation at the largest force).
    Into a unilateral probe's surface the deviation counts from the surface (the depth), not
    from a resting tip above it."""
    forces = [float(f) for f in forces]
    rest = rest or setup.start(workers)
    axes = setup.constrained_axes(rest)
    contact = setup.contact_point(rest)
    hold_s, push_s, ramp = 0.4, 1.0, 0.2
    raws, keys = [], []
    for name, a in axes.items():
        for f in forces:
            raws.append(
                setup.raw_with(
                    f"push-{name}-{f:g}",
                    [_hold(0.0, hold_s), _push(hold_s, push_s + 0.2, f * a, ramp)],
                    hold_s + push_s,
                )
            )
            keys.append((name, f))
    runs = run_all(raws, workers)
    out: dict[str, Any] = {}
    for (name, f), r in zip(keys, runs):
        x = setup.point(r) @ axes[name]
        before = x[_window(r.t, hold_s - 0.1, hold_s)].mean()
        if contact is not None and name.startswith("into"):
            before = max(before, float(contact @ axes[name]))  # the depth, past any gap
        during = x[_window(r.t, hold_s + push_s - 0.3, hold_s + push_s)].mean()
        d = out.setdefault(name, {"axis": axes[name].tolist(), "deviation_m": {}})
        d["deviation_m"][f"{f:g}"] = float(during - before)
    for d in out.values():
        f = max(forces)
        dev = d["deviation_m"][f"{f:g}"]
        # (a point that moved against the push: the device pushed back, no stiffness to give)
        d["stiffness_n_per_m"] = float(f / dev) if dev > 0 else math.nan
    return out


def free_force(
    setup: Setup,
    speeds: Iterable[float] = (0.05, 0.2),
    distance_m: float = 0.04,
    workers: int | None = 1,
    rest: Run | None = None,
) -> dict:
    """The device's force along the hand's motion [N] while the hand moves `distance_m`
    along the mechanism at each constant speed: mean (+: pushing the hand along) and peak,
    over the cycles at speed, and the median force across the motion. A unilateral probe's
    tip resting above its surface is first brought onto it and slides along it pressed
    PRESS_DEPTH_M in."""
    m = setup.mechanism
    rest = rest or setup.start(workers)
    raws, speeds = [], [float(s) for s in speeds]
    # a unilateral probe's tip first pressed onto its surface, slowly (below every measured
    # speed's threshold), then moved along it at that depth
    approach = setup.approach(rest)
    lead: list[dict] = [_hold(0.0, 0.4)]
    start = 0.4
    if approach is not None:
        down_s = float(np.linalg.norm(approach)) / APPROACH_SPEED_M_S + 0.1
        lead.append({"action": "follow", "start_s": start, "profile": "constant",
                     "speed_m_s": APPROACH_SPEED_M_S, "ramp_s": 0.05,
                     "offsets": [list(approach)]})
        lead.append(_hold(start + down_s, 0.3))
        start += down_s + 0.3
    for v in speeds:
        seg = {
            "action": "follow",
            "start_s": start,
            "profile": "constant",
            "speed_m_s": v,
            "ramp_s": 0.05,
        }
        if m["type"] == "PlanarArm":
            th0 = float(rest.cols["arm_pos_angle"][-1])  # where the handle rests
            seg["theta"] = [th0, th0 + distance_m / m["length"]]
            seg["orientation"] = "path"
        else:
            seg["offsets"] = setup.path(rest, distance_m,
                                        depth_m=PRESS_DEPTH_M if approach is not None else 0.0)
        duration = start + distance_m / v + 0.1 + 0.3
        raws.append(setup.raw_with(f"move-{v:g}", [*lead, seg], duration))
    out = {}
    for v, r in zip(speeds, run_all(raws, workers)):
        vel = np.stack([r.cols["vx"], r.cols["vy"], r.cols["vz"]], axis=1)
        f = np.stack([r.cols["fx"], r.cols["fy"], r.cols["fz"]], axis=1)
        speed = np.linalg.norm(vel, axis=1)
        at = speed > 0.8 * v
        along = np.einsum("ij,ij->i", f[at], vel[at] / speed[at, None])
        across = np.sqrt(np.maximum(np.sum(f[at] ** 2, axis=1) - along**2, 0.0))
        out[f"{v:g}"] = {  # NaN where the handle never reached the speed
            "mean_n": float(along.mean()) if along.size else math.nan,
            "peak_n": float(np.abs(along).max()) if along.size else math.nan,
            # the force across the motion (a pressed probe: the contact force)
            "across_median_n": float(np.median(across)) if along.size else math.nan,
            "cycles": int(at.sum()),
        }
    return out


def _tangent(m: dict) -> np.ndarray:
    """A direction the mechanism's point may move along (probes: in the plane or along the
    line)."""
    if m["type"] == "LineGuide":
        return _unit(m["direction"])
    n = _unit(m.get("plane_normal", m.get("normal", [0, 0, 1])))
    return _unit(np.cross(n, np.eye(3)[np.argmin(np.abs(n))]))


def work(setup: Setup, workers: int | None = 1, rest: Run | None = None) -> dict:
    """The motors' net work [J] over closed runs (from rest to rest): a released handle, taps
    into each constrained axis, and twist strokes of +-20 degrees with a passive hand; how
    far the released handle travels [m] (and [deg] along a PlanarArm)."""
    rest = rest or setup.start(workers)
    axes = setup.constrained_axes(rest)
    runs_spec = {
        "released": (
            [_hold(0.0, 0.5), {"action": "release", "start_s": 0.5}],
            2.5,
        ),
        "twist strokes": (
            [
                _hold(0.0, 0.4, translation="passive"),
                {
                    "action": "twist",
                    "start_s": 0.4,
                    "duration_s": 0.6,
                    "angle_deg": 20.0,
                    "translation": "passive",
                },
                {
                    "action": "twist",
                    "start_s": 1.0,
                    "duration_s": 1.2,
                    "angle_deg": -40.0,
                    "translation": "passive",
                },
                {
                    "action": "twist",
                    "start_s": 2.2,
                    "duration_s": 0.6,
                    "angle_deg": 20.0,
                    "translation": "passive",
                },
                _hold(2.8, 0.7, translation="passive"),
            ],
            3.5,
        ),
    }
    for name, a in axes.items():
        runs_spec[f"tap {name}"] = (
            [_hold(0.0, 0.4), _push(0.4, 0.15, 1.0 * a, ramp=0.05), _hold(0.55, 0.95)],
            1.5,
        )
    runs = run_all(
        [setup.raw_with(k.replace(" ", "-"), i, d) for k, (i, d) in runs_spec.items()], workers
    )
    out = {}
    for name, r in zip(runs_spec, runs):
        entry = {"net_work_j": r.motor_work()}
        if name == "released":
            after = r.t >= 0.5
            p = setup.point(r)
            entry["travel_m"] = float(np.linalg.norm(p[after] - p[after][0], axis=1).max())
            if setup.mechanism["type"] == "PlanarArm":  # (the column is NaN for others)
                ang = np.unwrap(r.cols["arm_pos_angle"][after])
                entry["travel_deg"] = float(np.degrees(np.abs(ang - ang[0]).max()))
        out[name] = entry
    return out


def _release_spec() -> tuple[list[dict], float]:
    return [_hold(0.0, 0.5), {"action": "release", "start_s": 0.5}], 2.0


def _tap_spec(axis: np.ndarray) -> tuple[list[dict], float]:
    return [_hold(0.0, 0.4), _push(0.4, 0.1, 1.0 * axis, ramp=0.03), _hold(0.5, 1.5)], 2.0


def limit_cycle(run: Run) -> dict:
    """Sustained oscillation at the end of a run: the rms of the device force's AC part
    (about its linear trend) in the last window and in the window before it. A limit cycle
    where the last is above LIMIT_CYCLE_RMS_N and has not decayed below
    LIMIT_CYCLE_PERSISTENCE of the one before; quiet where it is at most QUIET_RMS_N."""
    f = np.stack([run.cols["fx"], run.cols["fy"], run.cols["fz"]], axis=1)
    t_end, w = run.t[-1], LIMIT_CYCLE_WINDOW_S

    def rms(t0, t1):  # about the window's linear trend (a drift is no oscillation)
        w_ = _window(run.t, t0, t1)
        t, x = run.t[w_], f[w_]
        A = np.stack([np.ones_like(t), t - t.mean()], axis=1)
        x = x - A @ np.linalg.lstsq(A, x, rcond=None)[0]
        return float(np.sqrt(np.mean(np.sum(x**2, axis=1))))

    last, before = rms(t_end - w, t_end + 1e-9), rms(t_end - 2 * w, t_end - w)
    cycle = last > LIMIT_CYCLE_RMS_N and last >= LIMIT_CYCLE_PERSISTENCE * before
    return {
        "rms_last_n": last,
        "rms_before_n": before,
        "limit_cycle": bool(cycle),
        "quiet": bool(last <= QUIET_RMS_N),
    }


def limit_cycles(
    setup: Setup,
    grid: dict | None = None,
    controller: dict | None = None,
    workers: int | None = 1,
    rest: Run | None = None,
) -> dict:
    """A tap into the first constrained axis for every hand of `grid` (HUMAN_GRID), and a
    released handle: which end in a limit cycle."""
    grid = HUMAN_GRID if grid is None else grid
    rest = rest or setup.start(workers)
    axis = next(iter(setup.constrained_axes(rest).values()))
    names = list(grid)
    hands = [dict(zip(names, v)) for v in product(*(grid[k] for k in names))]
    raws = []
    for i, h in enumerate(hands):
        intents, dur = _tap_spec(axis)
        raws.append(setup.raw_with(f"hand-{i}", intents, dur, controller, human=h))
    intents, dur = _release_spec()
    raws.append(setup.raw_with("released", intents, dur, controller))
    runs = run_all(raws, workers)
    rows = [{**h, **limit_cycle(r)} for h, r in zip(hands, runs[:-1])]
    released = limit_cycle(runs[-1])
    return {
        "hands": rows,
        "released": released,
        "stable": sum(not r["limit_cycle"] for r in rows) + (not released["limit_cycle"]),
        "total": len(rows) + 1,
    }


def stability_map(
    setup: Setup,
    kp: Sequence[float],
    kv: Sequence[float],
    hands: Sequence[dict] | None = None,
    workers: int | None = 1,
) -> dict:
    """For each translational Kp [N/m] x Kv [N·s/m]: stable when no hand of `hands` (the
    grid's lightest and heaviest, least and most damped, stiffest) nor the released handle
    ends in a limit cycle."""
    if hands is None:
        hands = [
            {"mass_kg": m, "damping": b, "stiffness": 500.0}
            for m in (0.05, 0.6)
            for b in (2.0, 10.0)
        ]
    rest = setup.start(workers)
    axis = next(iter(setup.constrained_axes(rest).values()))
    raws, keys = [], []
    for p, v in product(kp, kv):
        ctrl = {"kp": [p, p, p, 0.0, 0.0, 0.0], "kv": [v, v, v, 0.0, 0.0, 0.0]}
        if setup.scenario.data["device"].get("actuated", [True] * 3)[3:] == [True] * 3:
            L2 = setup._mech.length_scale**2
            ctrl = {"kp": [p] * 3 + [p * L2] * 3, "kv": [v] * 3 + [v * L2] * 3}
        for i, h in enumerate(hands):
            intents, dur = _tap_spec(axis)
            raws.append(setup.raw_with(f"map-{p:g}-{v:g}-{i}", intents, dur, ctrl, human=h))
            keys.append((p, v))
        intents, dur = _release_spec()
        raws.append(setup.raw_with(f"map-{p:g}-{v:g}-released", intents, dur, ctrl))
        keys.append((p, v))
    stable = {k: True for k in product(kp, kv)}
    for k, r in zip(keys, run_all(raws, workers)):
        stable[k] = stable[k] and not limit_cycle(r)["limit_cycle"]
    grid = np.array([[stable[(p, v)] for v in kv] for p in kp])
    return {"kp": list(map(float, kp)), "kv": list(map(float, kv)), "stable": grid.tolist()}


#: the laws `fidelity` compares, as controller settings on the under-actuated device
LAWS = ("eq. 11", "eq. 26", "naive", "eq. 26, passive")


def fully_actuated_variant(device: dict) -> dict | None:
    """The keys that make a scenario's [device] table its fully actuated variant, to compare
    renderings with: the Omni with motors on its gimbal too; a Cartesian device that senses
    its wrist but does not drive it (omega.6, omega.7) as the sigma.7, which drives it. None
    where the device has no such variant in the format."""
    import virtmech as vm

    if device["type"] == "PhantomOmni":
        return {"actuated": [True] * 6}
    if device["type"] == "CartesianDevice":
        d = vm.CartesianDevice(device["model"])
        if d.orientation_sensed and not d.torque_actuated:
            full = next(
                m for m in vm.CartesianDevice.MODELS if vm.CartesianDevice(m).torque_actuated
            )
            return {"model": full}
    return None


def fidelity(setup: Setup, workers: int | None = 1) -> dict:
    """The scenario (with its own intents and translational gains) on the device as it is,
    for each law of LAWS, against a fully actuated variant of the device (every joint
    driven) rendering the same mechanism with eq. 11 and the full gains Kp U, Kv U on every
    axis: the relative rms of the force difference, |f - f_full|_rms / |f_full|_rms, over
    the run, and the rms of each. "naive" renders the fully actuated law on the
    under-actuated device and drops what it cannot render."""
    from .builder import make_device

    data = setup.scenario.data
    variant = fully_actuated_variant(data["device"])
    if variant is None:
        raise ValueError(
            "fidelity: needs a device with a fully actuated variant (PhantomOmni, or a "
            f"CartesianDevice omega.6 or omega.7), got {data['device']['type']!r}"
        )
    L = setup._mech.length_scale
    given = setup.raw.get("controller", {})
    device = make_device(data["device"])
    k = float(given["kp"][0]) if "kp" in given else device.stiffness
    b = float(given["kv"][0]) if "kv" in given else device.damping
    U = [1.0, 1.0, 1.0, L * L, L * L, L * L]
    base = {key: v for key, v in given.items() if key not in ("law", "passivity")}
    full = {
        **{key: v for key, v in base.items() if key not in ("kp", "kv", "w_a", "w_e", "w_e_star")},
        "kp": [k * u for u in U],
        "kv": [b * u for u in U],
        "w_a": U,
        "w_e": U,
        "law": "null_space",
        "passivity": "off",
    }
    # the setup's scenario (its hand included) with the scenario's own intents
    raw = {**setup.raw, "intent": setup.scenario.raw.get("intent", [])}
    controllers = {
        "eq. 11": {**base, "law": "null_space", "passivity": "off"},
        "eq. 26": {**base, "law": "under_actuated", "passivity": "off"},
        "naive": full,
        "eq. 26, passive": {**base, "law": "under_actuated", "passivity": "energy_tank"},
    }
    raws = [
        {**raw, "name": f"{raw['name']}-{i}", "controller": c}
        for i, c in enumerate(controllers.values())
    ]
    raws.append(
        {
            **raw,
            "name": f"{raw['name']}-full",
            "controller": full,
            "device": {**raw["device"], **variant},
        }
    )
    runs = run_all(raws, workers)
    ref = runs.pop()
    f_ref = np.stack([ref.cols["fx"], ref.cols["fy"], ref.cols["fz"]], axis=1)
    rms_ref = float(np.sqrt(np.mean(np.sum(f_ref**2, axis=1))))
    out = {"fully actuated": {"force_rms_n": rms_ref}}
    for name, r in zip(controllers, runs):
        f = np.stack([r.cols["fx"], r.cols["fy"], r.cols["fz"]], axis=1)
        diff = float(np.sqrt(np.mean(np.sum((f - f_ref) ** 2, axis=1))))
        out[name] = {
            "force_rms_n": float(np.sqrt(np.mean(np.sum(f**2, axis=1)))),
            "relative_rms_error": diff / rms_ref if rms_ref > 0 else math.inf,
        }
    return out


# ---------------------------------------------------------------------------------------
# the whole report (virtmech quality)

#: the Kp [N/m] x Kv [N·s/m] grid of the stability map by default
MAP_KP = (600.0, 1200.0, 2000.0, 3000.0, 4000.0, 5000.0)
MAP_KV = (0.5, 1.0, 2.0)


def member_scenarios(scenario) -> list:
    """A scenario per member of a set (member 0: the [mechanism]): the set's scenario with
    [mechanism] that member's table and no [set]; the scenario itself if it has no set."""
    import copy

    from . import scenarios as sc

    if not isinstance(scenario, sc.Scenario):
        scenario = sc.load(scenario)
    raw = copy.deepcopy(scenario.raw)
    st = raw.pop("set", None) or {}
    members = st.get("members") or []
    if not members:
        return [scenario]
    return [
        sc.validate({**raw, "mechanism": m, "name": f"{scenario.name}-member{i}"},
                    f"{scenario.source} (member {i})")
        for i, m in enumerate([raw["mechanism"], *members])
    ]


def measure_scenario(
    scenario,
    workers: int | None = 1,
    stability_map_grid: tuple[Sequence[float], Sequence[float]] | None = None,
) -> dict:
    """`measure` of a scenario; of a set, of each member on its own (member_scenarios):
    {"scenario", "members": [each member's measures, with "member" and "mechanism"]}."""
    parts = member_scenarios(scenario)
    if len(parts) == 1:
        return measure(Setup(parts[0]), workers, stability_map_grid)
    members = []
    for i, part in enumerate(parts):
        result = measure(Setup(part), workers, stability_map_grid)
        members.append({"member": i, "mechanism": part.data["mechanism"]["type"], **result})
    return {"scenario": parts[0].name.rsplit("-member", 1)[0], "members": members}


def measure(
    setup: Setup,
    workers: int | None = 1,
    stability_map_grid: tuple[Sequence[float], Sequence[float]] | None = None,
) -> dict:
    """Every measure for one setup (the stability map only when its Kp and Kv values are
    given, as it is the costly one): a dict ready for JSON."""
    rest = setup.start(workers)
    out: dict[str, Any] = {
        "scenario": setup.scenario.name,
        "controller": setup.raw.get("controller", {}),
        "stiffness": stiffness(setup, workers=workers, rest=rest),
        "free_force": free_force(setup, workers=workers, rest=rest),
        "work": work(setup, workers=workers, rest=rest),
        "limit_cycles": limit_cycles(setup, workers=workers, rest=rest),
    }
    if fully_actuated_variant(setup.scenario.data["device"]) is not None:
        out["fidelity"] = fidelity(setup, workers=workers)
    if stability_map_grid is not None:
        out["stability_map"] = stability_map(setup, *stability_map_grid, workers=workers)
    return out


def summary_lines(result: dict) -> list[str]:
    """The report as plain-text lines (the CLI prints them); a set's, member by member."""
    if "members" in result:
        lines = [f"{result['scenario']}: rendering quality of each member of the set"]
        for m in result["members"]:
            lines.append(f"  member {m['member']} ({m['mechanism']}):")
            lines += ["  " + line for line in summary_lines(m)[1:]]
        return lines
    lines = [f"{result['scenario']}: rendering quality"]
    for axis, d in result["stiffness"].items():
        devs = ", ".join(f"{f} N: {v * 1e3:.3f} mm" for f, v in d["deviation_m"].items())
        lines.append(
            f"  stiffness {axis}: {d['stiffness_n_per_m'] / 1e3:.3f} N/mm (deviation {devs})"
        )
    for v, d in result["free_force"].items():
        lines.append(
            f"  force along the motion at {v} m/s: mean {d['mean_n']:+.3f} N, "
            f"peak {d['peak_n']:.3f} N (across it: median {d['across_median_n']:.3f} N)"
        )
    for name, d in result["work"].items():
        extra = ""
        if "travel_deg" in d:
            extra = f", travel {d['travel_deg']:.2f} deg"
        elif "travel_m" in d:
            extra = f", travel {d['travel_m'] * 1e3:.2f} mm"
        lines.append(f"  motors' net work, {name}: {d['net_work_j'] * 1e3:+.3f} mJ{extra}")
    lc = result["limit_cycles"]
    quiet = sum(h["quiet"] for h in lc["hands"]) + lc["released"]["quiet"]
    lines.append(
        f"  free of limit cycles: {lc['stable']}/{lc['total']} (hands of the grid and a "
        f"released handle); quiet (<= {QUIET_RMS_N} N rms): {quiet}/{lc['total']}"
    )
    if "fidelity" in result:
        fa = result["fidelity"]["fully actuated"]["force_rms_n"]
        lines.append(f"  fidelity against the fully actuated device ({fa:.3f} N rms):")
        for law in LAWS:
            d = result["fidelity"][law]
            lines.append(
                f"    {law:16s} relative rms error {d['relative_rms_error']:.3f} "
                f"(force {d['force_rms_n']:.3f} N rms)"
            )
    if "stability_map" in result:
        m = result["stability_map"]
        lines.append("  stability map (Kp N/mm x Kv N·s/m; + free of limit cycles):")
        lines.append("    " + " " * 4 + " ".join(f"{v:>5g}" for v in m["kv"]))
        for kp, row in zip(m["kp"], m["stable"]):
            lines.append(f"    {kp / 1e3:4.1f} " + " ".join(f"{'+' if s else 'x':>5}" for s in row))
    return lines


def to_json(result: dict) -> str:
    """The result as strict JSON: a figure that does not apply (NaN) is null."""
    import json

    from .jsonable import jsonable

    return json.dumps(jsonable(result, infinity="null"), indent=2, allow_nan=False)


def write_report(result: dict, out) -> list[str]:
    """quality.json, fidelity.png, stability_map.png (when measured) and index.html in the
    folder `out`; returns the files written."""
    import html
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = ["quality.json"]
    (out / "quality.json").write_text(to_json(result) + "\n")
    parts = result["members"] if "members" in result else [result]
    for m in parts:
        suffix = f"-member{m['member']}" if "member" in m else ""
        files += _figures(m, out, suffix, plt)
    body = "\n".join(html.escape(line) for line in summary_lines(result))
    imgs = "".join(f'<p><img src="{f}" alt="{f}"></p>' for f in files if f.endswith(".png"))
    (out / "index.html").write_text(
        f"<!doctype html><meta charset='utf-8'><title>{html.escape(result['scenario'])}: "
        f"quality</title><pre>{body}</pre>{imgs}\n"
    )
    files.append("index.html")
    return files


def _figures(result: dict, out, suffix: str, plt) -> list[str]:
    """fidelity.png and stability_map.png (where measured) of one mechanism's result, their
    names ending in `suffix`; returns the files written."""
    files = []
    if "fidelity" in result:
        fig, ax = plt.subplots(figsize=(6, 3.2))
        errs = [result["fidelity"][law]["relative_rms_error"] for law in LAWS]
        ax.bar(LAWS, errs, color=["0.6", "C0", "C3", "C2"])
        ax.set_ylabel("force error / fully actuated (rms)")
        ax.set_title(f"{result['scenario']}: fidelity")
        fig.tight_layout()
        fig.savefig(out / f"fidelity{suffix}.png", dpi=110)
        plt.close(fig)
        files.append(f"fidelity{suffix}.png")
    if "stability_map" in result:
        m = result["stability_map"]
        fig, ax = plt.subplots(figsize=(4.5, 3.6))
        grid = np.asarray(m["stable"], dtype=float)
        ax.imshow(grid, origin="lower", cmap="RdYlGn", vmin=0, vmax=1, aspect="auto")
        ax.set_xticks(range(len(m["kv"])), [f"{v:g}" for v in m["kv"]])
        ax.set_yticks(range(len(m["kp"])), [f"{v / 1e3:g}" for v in m["kp"]])
        ax.set_xlabel("Kv [N·s/m]")
        ax.set_ylabel("Kp [N/mm]")
        ax.set_title("free of limit cycles (green)")
        fig.tight_layout()
        fig.savefig(out / f"stability_map{suffix}.png", dpi=110)
        plt.close(fig)
        files.append(f"stability_map{suffix}.png")
    return files
