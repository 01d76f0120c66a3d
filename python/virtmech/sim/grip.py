"""The grip of the paper's Figs. 2 and 12: two finger contacts on the stylus whose forces
hold the handle in static balance against the device's force and moment.

Contacts sit on the stylus axis at signed distances s1, s2 [m] from the handle origin
(negative: toward the hand). With F_R, M_R the device's wrench at the handle origin and z
the stylus axis, statics gives

    F1 + F2 = -F_R,        s1 z x F1 + s2 z x F2 = -M_R.

Only the force components perpendicular to the stylus carry moment, so with X = (-M_R) x z

    F2_perp = (X + s1 F_R_perp) / (s2 - s1),   F1_perp = -F_R_perp - F2_perp,

and the axial load (statically indeterminate between two contacts) is shared equally. The
moment about the stylus itself cannot be carried by forces on its axis and is returned as
the grip's twisting moment (0 on the Omni and the Planar3R, whose handles render none).
With both contacts on the same side of the handle origin the two perpendicular forces point
opposite ways: the bent pencil of the paper's Fig. 12.
"""

from __future__ import annotations

import numpy as np


def finger_forces_batch(p: np.ndarray, z: np.ndarray, wrench: np.ndarray, contacts=(-0.015, -0.05)):
    """`finger_forces` for N poses at once: handle positions p (N, 3), unit stylus axes
    z (N, 3) and device wrenches (N, 6). Returns (p1, F1, p2, F2, m_axial) with shapes
    (N, 3) x 4 and (N,)."""
    s1, s2 = float(contacts[0]), float(contacts[1])
    p, z, wrench = (np.asarray(a, dtype=float) for a in (p, z, wrench))
    F_R, M_R = wrench[:, :3], wrench[:, 3:6]
    F_par = np.einsum("ij,ij->i", F_R, z)[:, None] * z
    F_perp = F_R - F_par
    X = np.cross(-M_R, z)
    F2p = (X + s1 * F_perp) / (s2 - s1)
    F1p = -F_perp - F2p
    F1 = F1p - 0.5 * F_par
    F2 = F2p - 0.5 * F_par
    m_axial = -np.einsum("ij,ij->i", M_R, z)
    return p + s1 * z, F1, p + s2 * z, F2, m_axial


def finger_forces(T: np.ndarray, wrench: np.ndarray, contacts=(-0.015, -0.05)):
    """Finger contact points and forces for the device wrench (6,) at handle pose T (4, 4).

    Returns (p1, F1, p2, F2, m_axial): contact positions (3,), forces (3,) [N] the fingers
    apply to the handle, and the moment about the stylus they must add by friction [N·m].
    """
    T = np.asarray(T, dtype=float)
    w = np.asarray(wrench, dtype=float)[None, :6]
    p1, F1, p2, F2, m = finger_forces_batch(T[None, :3, 3], T[None, :3, 2], w, contacts)
    return p1[0], F1[0], p2[0], F2[0], float(m[0])
