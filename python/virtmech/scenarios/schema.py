"""A small schema engine for scenario files: every error names the key (as a dotted path),
the value found and what was expected, and every error of a file is reported at once (one
per key: a key's first mistake)."""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass, field
from typing import Any

from ..errors import UserError


class ScenarioError(UserError, ValueError):
    """A scenario file that does not match the format of docs/scenarios.md; `messages` holds
    one line per mistake, str() all of them, one per line."""


_MISSING = object()


def _show(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


def _where(path: str) -> str:
    return path or "(top level)"


@dataclass
class Field:
    """One key: kind in {number, integer, bool, string, vector, table, tables, choice-or-vector}."""

    kind: str
    required: bool = False
    default: Any = _MISSING
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = False
    max_exclusive: bool = False
    choices: tuple[str, ...] | None = None
    length: int | None = None  # vectors
    min_length: int | None = None
    children: dict[str, Field] | None = None  # tables
    variants: dict[str, dict[str, Field]] | None = None  # tables keyed by "type"/"action"
    variant_key: str | None = None
    doc: str = ""
    element: Field | None = None  # vectors of vectors
    nonzero: bool = False  # vectors: a direction, not all zero, returned normalised
    pattern: str | None = None  # strings: a regular expression the whole string matches
    extra: dict = field(default_factory=dict)

    # -------------------------------------------------------------------------------
    def _range_text(self) -> str:
        parts = []
        if self.min is not None:
            parts.append(f"{'>' if self.min_exclusive else '>='} {self.min:g}")
        if self.max is not None:
            parts.append(f"{'<' if self.max_exclusive else '<='} {self.max:g}")
        return " and ".join(parts)

    def _check_range(self, path: str, x: float) -> None:
        bad = False
        if self.min is not None:
            bad |= x <= self.min if self.min_exclusive else x < self.min
        if self.max is not None:
            bad |= x >= self.max if self.max_exclusive else x > self.max
        if bad or (isinstance(x, float) and not math.isfinite(x)):
            raise ScenarioError(
                f"{path}: value {_show(x)} is out of range; expected a number "
                f"{self._range_text() or 'that is finite'}"
            )

    def _number(self, path: str, v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ScenarioError(
                f"{path}: expected a number{' ' + rng if (rng := self._range_text()) else ''}, "
                f"got {type(v).__name__} {_show(v)}"
            )
        self._check_range(path, float(v))
        return float(v)

    def _integer(self, path: str, v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise ScenarioError(f"{path}: expected an integer, got {type(v).__name__} {_show(v)}")
        self._check_range(path, v)
        return int(v)

    def _bool(self, path: str, v: Any) -> bool:
        if not isinstance(v, bool):
            raise ScenarioError(
                f"{path}: expected true or false, got {type(v).__name__} {_show(v)}"
            )
        return v

    def _string(self, path: str, v: Any) -> str:
        if not isinstance(v, str):
            raise ScenarioError(f"{path}: expected a string, got {type(v).__name__} {_show(v)}")
        if self.choices and v not in self.choices:
            raise ScenarioError(
                f"{path}: value {_show(v)} is not allowed; expected one of "
                + ", ".join(repr(c) for c in self.choices)
            )
        if self.pattern is not None and not re.fullmatch(self.pattern, v):
            raise ScenarioError(f"{path}: value {_show(v)} is not allowed; expected {self.doc}")
        return v

    def _vector(self, path: str, v: Any) -> list:
        n = f"{self.length} numbers" if self.length else "a list of numbers"
        if not isinstance(v, list):
            raise ScenarioError(f"{path}: expected {n}, got {type(v).__name__} {_show(v)}")
        if self.length is not None and len(v) != self.length:
            raise ScenarioError(f"{path}: expected {n}, got {len(v)} values {_show(v)}")
        if self.min_length is not None and len(v) < self.min_length:
            raise ScenarioError(
                f"{path}: expected at least {self.min_length} values, got {len(v)} {_show(v)}"
            )
        if self.element is not None:
            return [self.element.check(f"{path}[{i}]", x) for i, x in enumerate(v)]
        out = [self._number(f"{path}[{i}]", x) for i, x in enumerate(v)]
        if self.nonzero:
            return _direction(path, v, out)
        return out

    def _axis(self, path: str, v: Any) -> str | list[float]:
        """A choice string or a 3-vector."""
        if isinstance(v, str):
            return Field("string", choices=self.choices).check(path, v)
        if isinstance(v, list):
            return Field("vector", length=3, nonzero=True).check(path, v)
        raise ScenarioError(
            f"{path}: expected one of {', '.join(repr(c) for c in self.choices or ())} "
            "or 3 numbers, "
            f"got {type(v).__name__} {_show(v)}"
        )

    def _table(self, path: str, v: Any) -> dict:
        return check_table(path, v, self)

    def _tables(self, path: str, v: Any) -> list[dict]:
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            raise ScenarioError(f"{path}: expected an array of tables ([[{path}]]), got {_show(v)}")
        out, errors = [], []
        for i, x in enumerate(v):
            try:
                out.append(check_table(f"{path}[{i}]", x, self))
            except ScenarioError as e:
                errors += e.messages
        if errors:
            raise ScenarioError(*errors)
        return out

    def check(self, path: str, v: Any) -> Any:
        """v checked against this field (defaults filled in, directions normalised); raises a
        ScenarioError naming `path`, the value and what was expected."""
        checker = _CHECKERS.get(self.kind)
        if checker is None:
            raise AssertionError(self.kind)
        return checker(self, path, v)


#: each kind's check
_CHECKERS = {
    "number": Field._number,
    "integer": Field._integer,
    "bool": Field._bool,
    "string": Field._string,
    "vector": Field._vector,
    "axis": Field._axis,
    "table": Field._table,
    "tables": Field._tables,
}


def _direction(path: str, v: Any, x: list[float]) -> list[float]:
    """A direction's numbers (each finite) as a unit vector x / |x|; a ScenarioError naming
    the key if they are all zero. Scaled by the largest first, so that no square overflows
    or underflows: any finite non-zero vector has a direction (and one along an axis stays
    exactly itself)."""
    top = max(abs(c) for c in x)
    if top == 0.0:
        raise ScenarioError(
            f"{path}: value {_show(v)} is out of range; expected a non-zero vector (a direction)"
        )
    u = [c / top for c in x]
    norm = math.sqrt(sum(c * c for c in u))
    return [c / norm for c in u]


def check_table(path: str, v: Any, spec: Field) -> dict:
    """The table v checked against spec, defaults filled in; raises one ScenarioError listing
    every mistake found (unknown keys, missing keys, bad values)."""
    if not isinstance(v, dict):
        raise ScenarioError(f"{_where(path)}: expected a table, got {type(v).__name__} {_show(v)}")
    children = dict(spec.children or {})
    if spec.variants is not None:
        key = spec.variant_key
        assert key is not None
        kpath = f"{path}.{key}" if path else key
        if key not in v:
            raise ScenarioError(
                f"{kpath}: missing required field; expected one of "
                + ", ".join(repr(c) for c in spec.variants)
            )
        name = Field("string", choices=tuple(spec.variants)).check(kpath, v[key])
        children[key] = Field("string", required=True, choices=tuple(spec.variants))
        children.update(spec.variants[name])
    out: dict = {}
    errors: list[str] = []
    for k in v:
        if k not in children:
            where = f"[{path}]" if path else "the top level"
            errors.append(
                f"{path + '.' if path else ''}{k}: unknown key in {where}; expected one of "
                + ", ".join(sorted(children))
            )
    for k, f in children.items():
        kpath = f"{path}.{k}" if path else k
        try:
            if k in v:
                out[k] = f.check(kpath, v[k])
            elif f.required:
                errors.append(f"{kpath}: missing required field ({f.doc or f.kind})")
            elif f.kind == "table":
                out[k] = check_table(kpath, {}, f)
            elif f.default is not _MISSING:
                out[k] = copy.deepcopy(f.default)
        except ScenarioError as e:
            errors += e.messages
    if errors:
        raise ScenarioError(*errors)
    return out


# ---------------------------------------------------------------------------------------
# JSON Schema (for editors' completion and checking), from the same Fields


def _json_number(f: Field, integer: bool = False) -> dict:
    out: dict = {"type": "integer" if integer else "number"}
    if f.min is not None:
        out["exclusiveMinimum" if f.min_exclusive else "minimum"] = f.min
    if f.max is not None:
        out["exclusiveMaximum" if f.max_exclusive else "maximum"] = f.max
    return out


def json_schema_of(f: Field) -> dict:
    """The JSON Schema (draft 2020-12) of one Field."""
    k = f.kind
    if k == "number":
        out = _json_number(f)
    elif k == "integer":
        out = _json_number(f, integer=True)
    elif k == "bool":
        out = {"type": "boolean"}
    elif k == "string":
        out = {"type": "string"}
        if f.choices:
            out["enum"] = list(f.choices)
        if f.pattern:
            out["pattern"] = f"^{f.pattern}$"
    elif k == "vector":
        items = json_schema_of(f.element) if f.element is not None else {"type": "number"}
        out = {"type": "array", "items": items}
        if f.length is not None:
            out["minItems"] = out["maxItems"] = f.length
        if f.min_length is not None:
            out["minItems"] = f.min_length
    elif k == "axis":
        out = {
            "anyOf": [
                {"type": "string", "enum": list(f.choices or ())},
                {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
            ]
        }
    elif k in ("table", "tables"):
        out = _json_table(f)
        if k == "tables":
            out = {"type": "array", "items": out}
    else:  # pragma: no cover
        raise AssertionError(k)
    if f.doc:
        out["description"] = f.doc
    if f.default is not _MISSING:
        out["default"] = f.default
    return out


def _json_object(children: dict[str, Field]) -> dict:
    return {
        "type": "object",
        "properties": {k: json_schema_of(c) for k, c in children.items()},
        "required": [k for k, c in children.items() if c.required],
        "additionalProperties": False,
    }


def _json_table(f: Field) -> dict:
    if f.variants is None:
        return _json_object(f.children or {})
    key = f.variant_key
    assert key is not None
    variants = []
    for name, children in f.variants.items():
        v = _json_object({key: Field("string", required=True), **(f.children or {}), **children})
        v["properties"][key] = {"const": name}
        v["title"] = f"{key} = {name!r}"
        variants.append(v)
    return {
        "type": "object",
        "required": [key],
        "properties": {key: {"enum": list(f.variants)}},
        "oneOf": variants,
    }
