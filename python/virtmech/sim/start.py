"""The start pose of a simulated run: the device's joints q0 whose handle sits where the
scenario's [initial] table puts it (on the mechanism at joint 0 = `theta`, moved by
`offset`; or `q` given), found by the core's inverse kinematics (virtmech.reach)."""

from __future__ import annotations

import math

import numpy as np

import virtmech as vm

# start-pose seeds by device name, in order of preference (the Omni's gimbal branches)
_SEEDS = {
    "PhantomOmni": [
        [0.0, 0.4, 0.2] + g
        for g in (
            [-1.5, 0.3, 1.5],
            [1.5, 0.3, -1.5],
            [0, 0.3, 0],
            [-1.5, 0.3, -1.5],
            [1.5, 0.3, 1.5],
        )
    ],
    "Planar3R": [[0.3, 1.5, -1.0], [-0.3, -1.5, 1.0]],
}


def seeds(device) -> list[np.ndarray]:
    """Where the search for a start pose starts, in order of preference: the device's own
    seeds, its home, then four fixed draws within its limits (any device)."""
    lo = np.where(np.isfinite(device.lower), device.lower, -np.pi)
    hi = np.where(np.isfinite(device.upper), device.upper, np.pi)
    draws = np.random.default_rng(0).uniform(lo, hi, size=(4, device.dof))
    named = [np.array(s, dtype=float) for s in _SEEDS.get(device.name, [])]
    return named + [np.asarray(device.home, dtype=float)] + list(draws)


def _given(q, device) -> np.ndarray:
    """initial.q checked against the device: its joints' count and range."""
    q = np.asarray(q, dtype=float)
    if q.shape != (device.dof,):
        raise ValueError(f"initial.q: expected {device.dof} joint values, got {q.size}")
    lo, hi = np.asarray(device.lower), np.asarray(device.upper)
    for i in np.flatnonzero((q < lo) | (q > hi)):
        raise ValueError(
            f"initial.q[{i}]: {q[i]:g} is outside the device's joint range "
            f"[{lo[i]:g}, {hi[i]:g}]; expected a start pose the device can be in"
        )
    return q


def initial_joints(scenario: dict, device, mechanism) -> np.ndarray:
    """The start pose q0 of the scenario's [initial] table (`scenario`: its data): `q`
    as given (checked against the device's joint range), else the device's joints whose
    handle sits on the mechanism at joint 0 = theta (the stylus as at stylus_theta, where
    given), moved by offset; a ValueError naming the key when the device cannot be there."""
    ini = scenario["initial"]
    if ini.get("q") is not None:
        return _given(ini["q"], device)
    theta = mechanism.home.copy()
    theta[0] = ini["theta"]
    T = mechanism.forward(theta)
    if ini.get("stylus_theta") is not None:
        th2 = theta.copy()
        th2[0] = ini["stylus_theta"]
        T[:3, :3] = mechanism.forward(th2)[:3, :3]
    T[:3, 3] += np.asarray(ini["offset"])
    q, err, _ = vm.reach(device, T, seeds(device), mechanism.length_scale)
    if np.linalg.norm(err[:3]) > 1e-6 or np.linalg.norm(err[3:]) > 1e-5:
        raise ValueError(
            f"initial: the device cannot reach the start pose (position error "
            f"{np.linalg.norm(err[:3]) * 1e3:.3g} mm, orientation error "
            f"{math.degrees(np.linalg.norm(err[3:])):.3g} deg); move the mechanism or the start"
        )
    return q
