"""Status bits of a controller cycle (``CycleOutput.status``).

Bits below ``FAULT_MASK`` inform; a fault bit means the cycle commanded zero torque.
"""

from ._core import (
    STATUS_FAULT_BAD_SIZE as FAULT_BAD_SIZE,
)
from ._core import (
    STATUS_FAULT_IMPLAUSIBLE_VELOCITY as FAULT_IMPLAUSIBLE_VELOCITY,
)
from ._core import (
    STATUS_FAULT_MASK as FAULT_MASK,
)
from ._core import (
    STATUS_FAULT_NONFINITE_INPUT as FAULT_NONFINITE_INPUT,
)
from ._core import (
    STATUS_FAULT_NONFINITE_OUTPUT as FAULT_NONFINITE_OUTPUT,
)
from ._core import (
    STATUS_FAULT_OUT_OF_RANGE as FAULT_OUT_OF_RANGE,
)
from ._core import (
    STATUS_FORCE_CLAMPED as FORCE_CLAMPED,
)
from ._core import (
    STATUS_NOT_CONVERGED as NOT_CONVERGED,
)
from ._core import (
    STATUS_OK as OK,
)
from ._core import (
    STATUS_PASSIVITY as PASSIVITY,
)
from ._core import (
    STATUS_RAMPING as RAMPING,
)
from ._core import (
    STATUS_SWITCHING as SWITCHING,
)
from ._core import (
    STATUS_TORQUE_CLAMPED as TORQUE_CLAMPED,
)
from ._core import (
    STATUS_WATCHDOG as WATCHDOG,
)
from ._core import status_names as names

__all__ = [
    "FAULT_BAD_SIZE",
    "FAULT_IMPLAUSIBLE_VELOCITY",
    "FAULT_MASK",
    "FAULT_OUT_OF_RANGE",
    "FAULT_NONFINITE_INPUT",
    "FAULT_NONFINITE_OUTPUT",
    "FORCE_CLAMPED",
    "NOT_CONVERGED",
    "OK",
    "RAMPING",
    "SWITCHING",
    "TORQUE_CLAMPED",
    "WATCHDOG",
    "PASSIVITY",
    "names",
]
