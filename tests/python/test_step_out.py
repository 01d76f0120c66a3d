"""Controller.step(q, dq, out=..., torque=...) fills caller-owned objects: a Python servo loop
creates no object per cycle."""

from __future__ import annotations

import itertools
import tracemalloc

import numpy as np
import pytest

import virtmech as vm


def controller():
    return vm.Controller(vm.PhantomOmni(), vm.Probe([0, -0.05, 0], [0, 1, 0], 0.1))


def test_out_and_torque_are_filled_in_place_with_the_cycle_results():
    a, b = controller(), controller()
    out, tau = vm.CycleOutput(), np.full(6, np.nan)
    rng = np.random.default_rng(2)
    for _ in range(50):
        q = np.array([0.1, 0.5, 0.2, 0.0, 0.6, 0.0]) + rng.normal(scale=0.05, size=6)
        dq = rng.normal(scale=0.1, size=6)
        ret = a.step(q, dq, out=out, torque=tau)
        ref = b.step(q, dq)
        assert ret is out
        assert np.array_equal(tau, ref.torque) and np.array_equal(out.torque, ref.torque)
        assert np.array_equal(out.wrench, ref.wrench) and out.status == ref.status


def test_an_empty_output_holds_no_stale_numbers():
    """Before its first cycle an output reads as no force at all: zero vectors, identity
    poses, no joints, full scales, status ok (VM_CYCLE_OUTPUT's first values)."""
    out = vm.CycleOutput()
    for name in ("wrench", "wrench_null", "wrench_range", "wrench_unrendered",
                 "wrench_passivity", "error", "error_dot", "error_star", "error_star_dot"):
        assert np.array_equal(getattr(out, name), np.zeros(6)), name
    for name in ("handle_pose", "mechanism_pose", "mechanism_pose_star"):
        assert np.array_equal(getattr(out, name), np.eye(4)), name
    assert out.torque.shape == (0,) and out.theta.shape == (0,) and out.active.shape == (0,)
    assert (out.ramp, out.limit_scale, out.passivity_scale, out.energy) == (0.0, 1.0, 1.0, 0.0)
    assert out.status == 0 and out.status_names == [] and not out.fault


def peak_bytes_over(f, cycles):
    """Peak of Python-traced memory above its level before `cycles` calls of f, and the
    change in the level after them."""
    for _ in range(10):
        f()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        for _ in itertools.repeat(None, cycles):
            f()
        current, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return peak - base, current - base


def test_a_servo_loop_with_out_creates_no_object_per_cycle():
    c = controller()
    q, dq = np.array([0.1, 0.5, 0.2, 0.0, 0.6, 0.0]), np.zeros(6)
    out, tau = vm.CycleOutput(), np.zeros(6)
    step = c.step
    noop_peak, _ = peak_bytes_over(lambda: None, 1000)  # the measuring loop itself
    peak, grown = peak_bytes_over(lambda: step(q, dq, out=out, torque=tau), 1000)
    fresh_peak, _ = peak_bytes_over(lambda: step(q, dq), 1000)
    assert grown == 0
    # a fresh CycleOutput per call shows; with out= nothing of that size is made (what is
    # left is NumPy's transient buffer record while q, dq are read)
    assert fresh_peak - noop_peak >= 500
    assert peak - noop_peak <= 128


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"torque": np.zeros(5)}, "torque: expected a writable, contiguous float64 array"),
        ({"torque": np.zeros(6, np.float32)}, "torque: expected"),
        ({"torque": np.zeros(12)[::2]}, "torque: expected"),
        ({"out": 3}, "out: expected a virtmech.CycleOutput"),
    ],
)
def test_wrong_out_or_torque_names_the_parameter(kw, match):
    with pytest.raises(TypeError, match=match):
        controller().step(np.zeros(6) + 0.3, np.zeros(6), **kw)
