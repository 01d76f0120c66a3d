"""One conversion of results to JSON-ready values, for every file and message virtmech
writes as JSON (run.json, summaries, the viewer's state)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def jsonable(x: Any, infinity: str = "string") -> Any:
    """x with arrays and tuples as lists and NumPy scalars as Python ones, so that strict
    JSON can hold it: NaN becomes None (null: a value that does not apply); an infinity
    becomes "inf" / "-inf" (infinity="string", for files a person reads: a limit that is
    off) or None (infinity="null", for a browser's JSON.parse)."""
    if infinity not in ("string", "null"):
        raise ValueError(f"infinity: expected 'string' or 'null', got {infinity!r}")
    return _convert(x, infinity == "string")


def _convert(x: Any, inf_as_string: bool) -> Any:
    if isinstance(x, dict):
        return {k: _convert(v, inf_as_string) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_convert(v, inf_as_string) for v in x]
    if isinstance(x, np.ndarray):
        return _convert(x.tolist(), inf_as_string)
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (np.floating, float)):
        v = float(x)
        if math.isnan(v):
            return None
        if math.isinf(v):
            return str(v) if inf_as_string else None
        return v
    if isinstance(x, np.integer):
        return int(x)
    return x
