"""`virtmech bench` with the NumPy reference cycle of this source checkout (tests/reference)
timed beside the core: the same mathematics written the obvious way in NumPy, its
placements solved on their own, over the same cycles; the report adds its median, the
core's speedup over it and the largest torque difference.

    python bench/numpy_baseline.py [virtmech bench's arguments]

The reference is not shipped with the package (the tests compare the core with it); this
script is how a checkout measures against it. scripts/bench.sh runs it.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import reference  # noqa: E402
from virtmech import bench  # noqa: E402

if __name__ == "__main__":
    raise SystemExit(bench.main(sys.argv[1:], reference=reference))
