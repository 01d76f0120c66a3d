"""The reference placement: the mechanism's joints where its handle best matches a target pose
under weights W (eqs. 18-20), solved on its own, to its own tolerance.

The placement is a stationary point of the weighted pose error, r(theta) = J^T W e = 0 with
e = [p_target - p; log(R_target R^T)] (with isotropic rotation weights r is minus half the
gradient of e^T W e, because the rotation logarithm's Jacobian leaves e_rot itself
unchanged). It is solved by Newton's method on r with the Jacobian of r by central
differences once Gauss-Newton contracts only linearly (its model is poor where a residual
cannot vanish, or in directions settled only by a small weight), Gauss-Newton steps before
that and wherever that matrix is not a descent model; each step capped and backtracked.
It stops when a step moves no joint by more than STEP_TOL (relative to the joint's scale),
with no iteration count taken from anywhere else.
"""

from __future__ import annotations

import numpy as np

from .kinematics import NpChain, pose_error

#: Convergence: the largest step, per joint scale (rad, or the mechanism's length scale).
STEP_TOL = 1e-12
#: Relative central-difference step for the Jacobian of r.
FD_STEP = 1e-6
MAX_ITERATIONS = 200


def _scales(m: NpChain) -> np.ndarray:
    return np.array([1.0 if t == "revolute" else m.length_scale for t in m.types])


def weighted_cost(m: NpChain, target: np.ndarray, W: np.ndarray, theta: np.ndarray) -> float:
    e = pose_error(target, m.forward(theta))
    return float(e @ (W * e))


def place_from(m: NpChain, target: np.ndarray, W: np.ndarray,
               start: np.ndarray) -> tuple[np.ndarray, float, bool]:
    """A stationary placement reached from `start`: (theta, cost, converged)."""
    scale = _scales(m)
    n = m.dof

    def residual(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        T, J = m.forward_jacobian(th)
        e = pose_error(target, T)
        return J, J.T @ (W * e), float(e @ (W * e))

    theta = np.clip(np.asarray(start, float), m.lower, m.upper)
    J, r, cost = residual(theta)
    newton, last_move = False, np.inf
    for _ in range(MAX_ITERATIONS):
        if not np.any(r):
            return theta, cost, True
        delta = None
        if newton:
            K = np.empty((n, n))
            for j in range(n):
                h = FD_STEP * scale[j]
                tp, tm = theta.copy(), theta.copy()
                tp[j] += h
                tm[j] -= h
                K[:, j] = (residual(tp)[1] - residual(tm)[1]) / (2.0 * h)
            hessian = -0.5 * (K + K.T)  # half the cost's Hessian where r is the gradient
            lam = np.linalg.eigvalsh(hessian)
            if lam.min() > 1e-12 * max(lam.max(), 1e-300):
                delta = -np.linalg.solve(K, r)
        if delta is None:
            H = J.T @ (W[:, None] * J)
            H[np.diag_indices(n)] += 1e-12 * (np.trace(H) / n) + 1e-300
            delta = np.linalg.solve(H, r)
        ratio = np.abs(delta / scale).max()
        if ratio > 0.5:  # at most half a radian (or half a length scale) per step
            delta *= 0.5 / ratio
            ratio = 0.5
        alpha, accepted = 1.0, False
        rnorm = float(np.linalg.norm(r))
        while alpha * ratio > STEP_TOL:
            trial = np.clip(theta + alpha * delta, m.lower, m.upper)
            tJ, tr, tcost = residual(trial)
            if tcost < cost or (tcost <= cost * (1.0 + 1e-12) and np.linalg.norm(tr) < rnorm):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:  # no step longer than the tolerance improves cost or residual
            return theta, cost, True
        moved = np.abs((trial - theta) / scale).max()
        theta, J, r, cost = trial, tJ, tr, tcost
        if moved <= STEP_TOL:
            return theta, cost, True
        # Gauss-Newton while it converges fast; Newton once it contracts only linearly
        newton = newton or moved > 0.1 * last_move
        last_move = moved
    return theta, cost, False


def place(m: NpChain, target: np.ndarray, W: np.ndarray, start: np.ndarray,
          global_search: bool = False) -> tuple[np.ndarray, bool]:
    """The placement from `start`; with `global_search`, also from the mechanism's seeds for
    this target, keeping the least cost (ties: the one from `start`). Returns theta and
    whether it converged."""
    best = place_from(m, target, W, start)
    if global_search and m.seeds is not None:
        for seed in m.seeds(target):
            cand = place_from(m, target, W, seed)
            if cand[2] and cand[1] < best[1] * (1.0 - 1e-9) - 1e-300:
                best = cand
    return best[0], best[2]
