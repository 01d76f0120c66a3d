"""Shared fixtures and helpers for the Python tests."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm


def random_within(rng: np.random.Generator, lower, upper, span: float = 1.0) -> np.ndarray:
    """Joint values uniform within limits (+-span where a limit is infinite)."""
    lo = np.where(np.isfinite(lower), lower, -span)
    hi = np.where(np.isfinite(upper), upper, span)
    return rng.uniform(lo, hi)


def numeric_jacobian(fk, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of a pose function: rows [v; w] in world axes."""
    cols = []
    for i in range(len(x)):
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        cols.append(vm.pose_error(fk(xp), fk(xm)) / (2 * h))
    return np.array(cols).T


def six_dof_arm() -> vm.Device:
    """A fully actuated 6R arm with a spherical wrist."""
    axes = [(0, 0, 1), (0, 1, 0), (0, 1, 0), (1, 0, 0), (0, 1, 0), (1, 0, 0)]
    offsets = [(0, 0, 0.1), (0, 0, 0.05), (0.25, 0, 0), (0.1, 0, 0), (0.15, 0, 0), (0, 0, 0)]
    joints = [vm.Joint("revolute", a, o, -2.5, 2.5) for a, o in zip(axes, offsets)]
    handle = np.eye(4)
    handle[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]  # stylus along +x
    handle[:3, 3] = [0.05, 0, 0]
    return vm.Device(
        joints,
        [True] * 6,
        handle=handle,
        torque_limit=[20.0] * 6,
        max_force=40.0,
        max_torque=4.0,
        stiffness=800.0,
        damping=2.0,
        name="Arm6R",
    )


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
