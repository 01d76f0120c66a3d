"""The simulation's inner loop: control cycles with their physics steps, given the hand's
plan (human.py, Intent.plan), the sensor noise and the dropouts of each cycle.

Two implementations of one loop:

- `CompiledLoop` (the default): virtmech._core._SimKernel, C++. It drives MuJoCo through
  the mujoco package already loaded in this process (the addresses of mjModel, mjData and
  of three MuJoCo functions, and NumPy views of mjData's arrays), so no Python runs per
  cycle;
- `PythonLoop`: the same loop in Python, cycle by cycle. It is the readable reference:
  the tests check that both give the same log.

Per control cycle k (t = k T), for each of the `substeps` physics steps:

    mj_step1                                  (kinematics at the current state)
    q, dq   <- device coordinates of the true state: q = Cinv (qpos - c0), dq = Cinv qvel
    first step only:
        qm, dqm <- sensors (noise, quantisation, dropout, delay, filtered difference)
        out     <- controller.step(qm, dqm, t)
        ctrl    <- out.torque - C^T sum_b J_com,b^T m_b g   (on the actuated joints; the
                   motors saturate in MuJoCo at their torque limits) held for the cycle
    qfrc_applied <- Cinv^T J^T w_hand(plan row, handle pose and twist)
    mj_step2                                  (actuation, dynamics, integration)

mj_step1 followed by mj_step2 is mj_step, with the inputs set in between.
"""

from __future__ import annotations

import ctypes
import glob
import os

import numpy as np

import virtmech as vm

from .human import PLAN_COLUMNS, HandTarget, hand_wrench

_mujoco_functions: dict[str, int] | None = None
_mujoco_timer: ctypes.c_void_p | None = None


def mujoco_function_addresses() -> dict[str, int]:
    """Addresses of mj_step1, mj_step2 and mj_jacBodyCom in the MuJoCo library the mujoco
    package loaded (the same library, so the same mjModel and mjData layout)."""
    global _mujoco_functions, _mujoco_timer
    if _mujoco_functions is None:
        import mujoco

        here = os.path.dirname(mujoco.__file__)
        libs = (
            sorted(glob.glob(os.path.join(here, "libmujoco.so*")))
            + sorted(glob.glob(os.path.join(here, "libmujoco*.dylib")))
            + sorted(glob.glob(os.path.join(here, "mujoco.dll")))
        )
        if not libs:
            raise RuntimeError(
                f"the compiled simulation loop needs MuJoCo's shared library next to the mujoco "
                f"package ({here}); none found: run with engine='python'"
            )
        lib = ctypes.CDLL(libs[0])
        _mujoco_functions = {
            name: ctypes.cast(getattr(lib, name), ctypes.c_void_p).value
            for name in ("mj_step1", "mj_step2", "mj_jacBodyCom")
        }
        _mujoco_timer = ctypes.c_void_p.in_dll(lib, "mjcb_time")
    return _mujoco_functions


class _NoMujocoTimer:
    """MuJoCo's global timer callback (which the mujoco package installs to fill
    mjData.timer) switched off while the compiled loop runs, and restored after: it reads the
    clock about twenty times per physics step, 10 % of the simulation's time. mjData.timer is
    not updated by the compiled loop."""

    def __enter__(self):
        self.saved = _mujoco_timer.value if _mujoco_timer is not None else None
        if _mujoco_timer is not None:
            _mujoco_timer.value = None

    def __exit__(self, *exc):
        if _mujoco_timer is not None:
            _mujoco_timer.value = self.saved


class CompiledLoop:
    """The inner loop in C++ (see the module's docstring)."""

    def __init__(self, controller, model, data, **kw):
        f = mujoco_function_addresses()
        self._keep = (model, data)  # the kernel holds raw pointers into these
        self._kernel = vm._core._SimKernel(
            controller,
            model._address,
            data._address,
            f["mj_step1"],
            f["mj_step2"],
            f["mj_jacBodyCom"],
            data.qpos,
            data.qvel,
            data.ctrl,
            data.qfrc_applied,
            data.actuator_force,
            np.ascontiguousarray(kw["coupling_inv"], dtype=float),
            np.ascontiguousarray(kw["coupling_offset"], dtype=float),
            list(kw["actuated"]),
            int(kw["substeps"]),
            float(kw["period_s"]),
            list(kw["comp_bodies"]),
            list(kw["comp_masses"]),
            np.ascontiguousarray(kw["gravity"], dtype=float),
            float(kw["sensors"].step),
            int(kw["sensors"].s.delay_cycles),
            float(kw["sensors"].alpha),
        )

    def run(self, k0: int, plan, noise, dropout, log) -> None:
        with _NoMujocoTimer():
            self._kernel.run(k0, plan, noise, dropout, log)


class PythonLoop:
    """The inner loop in Python, cycle by cycle (see the module's docstring)."""

    def __init__(self, controller, model, data, **kw):
        self.ctrl, self.model, self.data = controller, model, data
        self.device = controller.device
        self.Cinv = np.asarray(kw["coupling_inv"], dtype=float)
        self.CinvT = self.Cinv.T.copy()
        self.CT = np.linalg.inv(self.Cinv).T
        self.c0 = np.asarray(kw["coupling_offset"], dtype=float)
        self.act = np.asarray(kw["actuated"], dtype=int)
        self.nsub = int(kw["substeps"])
        self.T = float(kw["period_s"])
        self.bodies = list(kw["comp_bodies"])
        self.masses = list(kw["comp_masses"])
        self.g = np.asarray(kw["gravity"], dtype=float)
        self.n = self.device.dof
        self.sensors = kw["sensors"]
        self.jacp = np.zeros((3, model.nv))
        assert len(PLAN_COLUMNS) == 27

    @staticmethod
    def _target(row, force) -> HandTarget:
        """The hand's target of a plan row (human.PLAN_COLUMNS), with its push in world axes."""
        return HandTarget(
            p=row[0:3],
            R=row[3:12].reshape(3, 3),
            v=row[12:15],
            w=row[15:18],
            k_t=row[18],
            b_t=row[19],
            k_r=row[20],
            b_r=row[21],
            force=force,
            segment=int(row[26]),
        )

    def run(self, k0: int, plan, noise, dropout, log) -> None:
        import mujoco

        m, d = self.model, self.data
        for r in range(plan.shape[0]):
            t = (k0 + r) * self.T
            row = plan[r]
            for s in range(self.nsub):
                mujoco.mj_step1(m, d)
                q = self.Cinv @ (d.qpos - self.c0)
                dq = self.Cinv @ d.qvel
                T = self.device.forward(q)
                J = self.device.jacobian(q)
                if s == 0:
                    T_h, q0, dq0 = T, q, dq
                    qm, dqm = self.sensors.read(q, noise[r], dropout[r] != 0.0)
                    out = self.ctrl.step(qm, dqm, t)
                    cmd = out.torque.copy()
                    if self.bodies:
                        g_s = np.zeros(m.nv)
                        for b, mass in zip(self.bodies, self.masses):
                            mujoco.mj_jacBodyCom(m, d, self.jacp, None, b)
                            g_s += self.jacp.T @ (mass * self.g)
                        cmd[self.act] -= (self.CT @ g_s)[self.act]
                    d.ctrl[:] = cmd[self.act]
                    force = row[22:25] if row[25] == 0.0 else T_h[:3, :3] @ row[22:25]
                    target = self._target(row, force)
                tw = J @ dq
                W = hand_wrench(target, T, tw)
                if s == 0:
                    tw0, W0 = tw, W
                d.qfrc_applied[:] = self.CinvT @ (J.T @ W)
                mujoco.mj_step2(m, d)
            motor = np.zeros(self.n)
            motor[self.act] = d.actuator_force
            log[r] = np.concatenate(
                (
                    [t],
                    q0,
                    dq0,
                    qm,
                    dqm,
                    T_h[:3, 3],
                    T_h[:3, 2],
                    tw0,
                    out.wrench,
                    out.torque,
                    motor,
                    [out.status, out.ramp, out.iterations, out.iterations_star],
                    out.theta,
                    out.theta_star,
                    out.error,
                    out.error_dot,
                    out.error_star,
                    out.error_star_dot,
                    out.wrench_null,
                    out.wrench_range,
                    W0,
                    row[0:3],
                    [row[26]],
                )
            )


__all__ = ["CompiledLoop", "PythonLoop", "mujoco_function_addresses"]
