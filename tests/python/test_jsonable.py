"""virtmech.jsonable: every JSON virtmech writes (run.json, summaries, quality.json, the
viewer's state) goes through it, and json.dumps(allow_nan=False) must accept the result."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from virtmech.jsonable import jsonable

VALUE = {
    "a": np.array([[1.0, np.nan], [np.inf, -np.inf]]),
    "b": (np.float32(0.5), np.int64(3), np.bool_(True), "s", None),
    "c": [math.nan, math.inf, 2],
}


def test_strict_json_with_infinities_as_strings():
    out = jsonable(VALUE)
    assert out == {"a": [[1.0, None], ["inf", "-inf"]], "b": [0.5, 3, True, "s", None],
                   "c": [None, "inf", 2]}
    json.dumps(out, allow_nan=False)  # raises on NaN or infinity
    assert type(out["b"][1]) is int and type(out["b"][2]) is bool


def test_strict_json_with_infinities_as_null():
    out = jsonable(VALUE, infinity="null")
    assert out["a"] == [[1.0, None], [None, None]] and out["c"] == [None, None, 2]
    json.dumps(out, allow_nan=False)


def test_a_bad_mode_is_named():
    with pytest.raises(ValueError, match="infinity: expected 'string' or 'null', got 'zero'"):
        jsonable(1.0, infinity="zero")
