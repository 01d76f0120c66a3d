"""The simulation's servo-rate loop in Python, cycle by cycle: the readable reference the C++
loop (sim/src/servo_loop.cpp, virtmech.sim.inner.ServoLoop) is tested against, in one test
(tests/python/test_sim_engine.py). It is not shipped and no product path runs it.

It takes what virtmech.sim.inner.ServoLoop takes and writes the same log columns, by name
(plan columns: virtmech.sim.human.PLAN_COLUMNS; log columns: virtmech.sim.log.log_columns).
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from virtmech.sim.human import PLAN_INDEX, plan_slice

from .hand import HandTarget, hand_wrench
from .sensors import Sensors


class PyServoLoop:
    def __init__(self, controller, model, data, *, log_columns, **kw):
        self.ctrl, self.m, self.d, self.dev = controller, model, data, controller.device
        self.Cinv = np.asarray(kw["coupling_inv"], dtype=float)
        self.CT = np.linalg.inv(self.Cinv).T
        self.c0 = np.asarray(kw["coupling_offset"], dtype=float)
        self.act = np.asarray(kw["actuated"], dtype=int)
        self.nsub, self.T = int(kw["substeps"]), float(kw["period_s"])
        self.comp = list(zip(kw["comp_bodies"], kw["comp_masses"]))
        self.g = np.asarray(kw["gravity"], dtype=float)
        self.sensors = Sensors(kw["sensors"], self.dev.dof, self.T, None)
        self.jacp = np.zeros((3, model.nv))
        self.col = {name: i for i, name in enumerate(log_columns)}
        # the hand's body: its mass and inertia zeroed while the plan says it has let go
        self.hand = int(kw.get("hand_body", -1))
        self.attached = True
        self.control_time_s = 0.0  # wall time in the controller's step
        if self.hand > 0:
            self.hand_mass = float(model.body_mass[self.hand])
            self.hand_inertia = model.body_inertia[self.hand].copy()

    def _attach(self, attached: bool) -> None:
        self.attached = attached
        if self.hand > 0:
            self.m.body_mass[self.hand] = self.hand_mass if attached else 0.0
            self.m.body_inertia[self.hand] = self.hand_inertia if attached else 0.0
            mujoco.mj_setConst(self.m, mujoco.MjData(self.m))

    def run(self, k0: int, plan, noise, dropout, log) -> None:
        m, d, n, c = self.m, self.d, self.dev.dof, self.col
        for r, row in enumerate(plan):
            t = (k0 + r) * self.T
            attached = row[PLAN_INDEX["hand_attached"]] != 0.0
            if attached != self.attached:
                self._attach(attached)
            for s in range(self.nsub):
                mujoco.mj_step1(m, d)  # kinematics at the current state
                q, dq = self.Cinv @ (d.qpos - self.c0), self.Cinv @ d.qvel
                T, J = self.dev.forward(q), self.dev.jacobian(q)
                if s == 0:  # sensors, controller, motors (held for the cycle)
                    T_h, q0, dq0 = T, q, dq
                    qm, dqm = self.sensors.read(q, noise[r], dropout[r] != 0.0)
                    t0 = time.perf_counter()
                    out = self.ctrl.step(qm, dqm, t)
                    self.control_time_s += time.perf_counter() - t0
                    cmd = out.torque.copy()
                    g_s = np.zeros(m.nv)
                    for b, mass in self.comp:  # gravity compensation
                        mujoco.mj_jacBodyCom(m, d, self.jacp, None, b)
                        g_s += self.jacp.T @ (mass * self.g)
                    cmd[self.act] -= (self.CT @ g_s)[self.act]
                    d.ctrl[:] = cmd[self.act]
                    force, moment = row[plan_slice("fx", 3)], row[plan_slice("mx", 3)]
                    if row[PLAN_INDEX["force_in_handle"]] != 0.0:
                        force, moment = T_h[:3, :3] @ force, T_h[:3, :3] @ moment
                    target = HandTarget(
                        p=row[plan_slice("ax", 3)],
                        R=row[plan_slice("R00", 9)].reshape(3, 3),
                        v=row[plan_slice("vx", 3)],
                        w=row[plan_slice("wx", 3)],
                        **{k: row[PLAN_INDEX[k]] for k in ("k_t", "b_t", "k_r", "b_r")},
                        force=force,
                        segment=int(row[PLAN_INDEX["segment"]]),
                        moment=moment,
                        attached=attached,
                    )
                tw = J @ dq
                W = hand_wrench(target, T, tw)  # the hand, every physics step
                if s == 0:
                    tw0, W0 = tw, W
                d.qfrc_applied[:] = self.Cinv.T @ (J.T @ W)
                mujoco.mj_step2(m, d)  # actuation, dynamics, integration
            motor = np.zeros(n)
            motor[self.act] = d.actuator_force
            fields = {
                "t": [t], "q0": q0, "dq0": dq0, "qm0": qm, "dqm0": dqm, "px": T_h[:3, 3],
                "sx": T_h[:3, 2], "vx": tw0, "fx": out.wrench, "tau0": out.torque,
                "tau_motor0": motor, "status": [out.status], "ramp": [out.ramp],
                "iterations": [out.iterations], "iterations_star": [out.iterations_star],
                "theta0": out.theta, "theta_star0": out.theta_star, "e0": out.error,
                "e_dot0": out.error_dot, "e_star0": out.error_star,
                "e_star_dot0": out.error_star_dot, "f_null0": out.wrench_null,
                "f_range0": out.wrench_range, "fhx": W0, "ax": row[plan_slice("ax", 3)],
                "segment": [row[PLAN_INDEX["segment"]]],
                "member": [0.0],  # one controller: its mechanism is member 0
            }  # fmt: skip
            for first, v in fields.items():
                log[r, c[first] : c[first] + len(v)] = v
