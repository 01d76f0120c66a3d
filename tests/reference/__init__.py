"""A NumPy reference implementation of virtmech's servo cycle, for tests and benchmarks run
from a source checkout (it is not shipped with the package).

It computes the cycle the obvious way: chain kinematics with 4x4 products, placements solved
on their own to their own tolerance (placement.py: Newton on the placement's stationarity
condition, no closed forms, no iteration counts from the core), eigen-decomposition
pseudo-inverses for the filters, the projection and the clamps. Tests compare the core with
it where the core converges; `virtmech bench` times it as the NumPy column.

`reference.sim_loop` (imported on its own: it needs MuJoCo) is the simulation's servo-rate
loop in Python, the reference of the C++ loop in one test.
"""

from .controller import NpController
from .kinematics import CASES, NpChain, NpDevice, case_models, pose_error, so3_log
from .placement import place, place_from, weighted_cost

__all__ = ["CASES", "NpChain", "NpController", "NpDevice", "case_models", "place", "place_from",
           "pose_error", "so3_log", "weighted_cost"]
