"""The reference servo cycle."""

from __future__ import annotations

from typing import Any

import numpy as np

from .kinematics import NpChain, NpDevice, gram_pinv, pose_error
from .placement import place


def soft_null(J: np.ndarray, w: np.ndarray, F: np.ndarray) -> np.ndarray:
    """N(W) F with the soft rank (docs/theory.md, 5): F - S (A_phi^+)^T J^T F, A = S J, S =
    sqrt(W), A_phi^+ = V diag(phi_i / sigma_i) U^T, phi_i = smoothstep((sigma_i / |A|_F -
    1e-5) / (1e-3 - 1e-5)); every phi_i is 1 away from a singular pose (then N = I - P)."""
    S = np.sqrt(w)
    A = S[:, None] * J
    frob = np.linalg.norm(A)
    if not frob > 0:
        return F.copy()
    U, sigma, Vt = np.linalg.svd(A, full_matrices=False)
    t = np.clip((sigma / frob - 1e-5) / (1e-3 - 1e-5), 0.0, 1.0)
    phi = t * t * (3.0 - 2.0 * t)
    g = np.divide(phi, sigma, out=np.zeros_like(sigma), where=phi > 0)
    return F - S * (U @ (g * (Vt @ (J.T @ F))))


class NpController:
    """The servo cycle (docs/theory.md: placements, eq. 26's filters, the projection onto
    what the device renders, the safety layer) in NumPy, configured from a core
    Controller's resolved model; the placements are the reference's own (placement.py).

    global_search: place from the mechanism's seeds too, every cycle (the least cost wins),
    not only from the last placement."""

    def __init__(self, controller: Any, device: NpDevice, mechanism: NpChain,
                 global_search: bool = False):
        md = controller.model
        self.dev, self.mech = device, mechanism
        self.kp, self.kv = np.asarray(md["kp"]), np.asarray(md["kv"])
        self.w_a = np.asarray(md["w_a"])
        L = md["length_scale"]
        U = np.array([1.0, 1.0, 1.0, L * L, L * L, L * L])
        self.w_e = np.asarray(md["w_e"]) + 1e-6 * U
        self.w_e_star = np.asarray(md["w_e_star"]) + 1e-6 * U
        self.L = L
        self.under_actuated = bool(md["under_actuated_term"])
        self.relative = md["error_velocity"] == "relative"
        self.ramp_cycles = int(md["ramp_cycles"])
        self.max_force, self.max_torque = md["max_force"], md["max_torque"]
        self.theta = mechanism.home.copy()
        self.theta_star = mechanism.home.copy()
        self.global_search = global_search
        self.converged = True
        self.wrench = np.zeros(6)
        self.first = True
        self.ramp_count = 0

    def _rate(self, J: np.ndarray, W: np.ndarray, v: np.ndarray) -> np.ndarray:
        if not self.relative:
            return -v
        theta_dot = gram_pinv(J, W)[0] @ (J.T @ (W * v))
        return J @ theta_dot - v

    def step(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """One cycle from the device's joint state. Returns the joint torques; the wrench at
        the handle (after safety) is left in `self.wrench`, and `self.converged` tells
        whether both placements converged."""
        dev, mech = self.dev, self.mech
        T_R, J_R = dev.forward_jacobian(q)
        v_R = J_R @ dq
        self.theta, converged = place(mech, T_R, self.w_e, self.theta, self.global_search)
        self.converged = converged
        T_V, J_V = mech.forward_jacobian(self.theta)
        e = pose_error(T_V, T_R)
        F = self.kp * e + self.kv * self._rate(J_V, self.w_e, v_R)
        WJ_A = self.w_a[:, None] * J_V
        H_Ap, rank_v = gram_pinv(J_V, self.w_a)
        f = soft_null(J_V, self.w_a, F)
        if self.under_actuated:
            # the range term leaves out the share of its directions the soft rank's null
            # filter renders (docs/theory.md, 5): together, eq. 26 with the hard cut
            f = F - WJ_A @ (H_Ap @ (J_V.T @ F))
            if self.first:
                self.theta_star = self.theta.copy()
            self.theta_star, converged = place(mech, T_R, self.w_e_star, self.theta_star,
                                               self.global_search)
            self.converged = self.converged and converged
            T_s, J_s = mech.forward_jacobian(self.theta_star)
            e_s = pose_error(T_s, T_R)
            Fs = self.kp * e_s + self.kv * self._rate(J_s, self.w_e_star, v_R)
            # P at the nearest placement, or at the un-powered one where the nearest is
            # singular and that one is not (docs/theory.md, section 6)
            if rank_v < min(int((self.w_a > 0).sum()), mech.dof):
                G_s, rank_s = gram_pinv(J_s, self.w_a)
                if rank_s > rank_v:
                    WJ_s = self.w_a[:, None] * J_s
                    f = f + WJ_s @ (G_s @ (J_s.T @ Fs))
                    Fs = None
            if Fs is not None:
                f = f + WJ_A @ (H_Ap @ (J_V.T @ Fs))
        else:
            self.theta_star = self.theta.copy()
        self.first = False
        passive = ~dev.actuated
        if passive.any():
            Jp = J_R[:, passive].copy()
            Jp[3:] *= self.L
            y = gram_pinv(Jp, np.ones(6))[0] @ (J_R[:, passive].T @ f)
            delta = Jp @ y
            delta[3:] *= self.L
            f = f - delta
        scale = 1.0
        fn, mn = np.linalg.norm(f[:3]), np.linalg.norm(f[3:])
        if fn > self.max_force:
            scale = min(scale, self.max_force / fn)
        if mn > self.max_torque:
            scale = min(scale, self.max_torque / mn)
        ramp = min(1.0, (self.ramp_count + 1) / self.ramp_cycles)
        if self.ramp_count < self.ramp_cycles:
            self.ramp_count += 1
        f = f * (scale * ramp)
        self.wrench = f
        tau = J_R.T @ f
        tau[passive] = 0.0
        a = np.abs(tau)
        over = dev.actuated & (a > dev.torque_limit)
        if over.any():
            tau = tau * (dev.torque_limit[over] / a[over]).min()
        return tau
