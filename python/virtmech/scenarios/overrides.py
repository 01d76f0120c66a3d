"""Scenario overrides: one dotted key of a scenario's raw TOML table set to a value before
the scenario is validated. This is what ``virtmech run --set KEY=VALUE`` and ``virtmech
sweep --grid KEY=V1,V2,...`` do (docs/sweeps.md).

Keys are dotted paths into the file's tables: ``controller.kp``, ``human.stiffness``,
``duration_s``; an array (of tables or of numbers) is indexed by position from 0:
``intent.1.force`` (or ``intent[1].force``, as the validation messages write it),
``mechanism.pivot.0``. A table the file does not write (``[sensors]``) is created. Values
on the command line are TOML values (``300``, ``1e-4``, ``true``, ``[0.3, 0.1, 0]``,
``"null_space"``); a word that is not one (``null_space``) is taken as a string.

    >>> import virtmech.scenarios as sc
    >>> s = sc.load("planar3r-fig9")
    >>> t = sc.validate(sc.apply_overrides(s.raw, {"human.stiffness": 300}), s.source)
    >>> t["human"]["stiffness"]
    300.0
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from typing import Any

from .schema import ScenarioError, _show

__all__ = [
    "apply_overrides",
    "override",
    "parse_assignment",
    "parse_grid",
    "parse_value",
    "split_values",
    "value_text",
]

#: a dotted key: names and array positions, e.g. controller.kp, intent.1.force, intent[1].force
_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.([A-Za-z_][A-Za-z0-9_]*|\d+)|\[\d+\])*")


def _parts(key: str) -> list[str]:
    if not isinstance(key, str) or not _KEY.fullmatch(key):
        raise ScenarioError(
            f"{key!r}: not a scenario key; expected a dotted path of names and array "
            "positions, e.g. controller.kp, human.stiffness, intent.1.force"
        )
    return re.sub(r"\[(\d+)\]", r".\1", key).split(".")


def _kind(v: Any) -> str:
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return f"an array of {len(v)} values"
    return f"a {type(v).__name__} ({_show(v)})"


def override(raw: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    """Sets the dotted `key` of the raw scenario table `raw` (as parsed from TOML, before
    validation) to `value`, in place, and returns `raw`. Tables along the path that the
    file does not write are created; an array is indexed by position (``intent.1.force``).
    Whether the key exists and the value fits is for `validate` to say, as for a file;
    here a ScenarioError names the key when the path itself cannot be followed (a
    position past the end of an array, a name where an array is, a value where a table
    should be)."""
    parts = _parts(key)
    cur: Any = raw
    for i, part in enumerate(parts):
        here = ".".join(parts[: i + 1])
        last = i == len(parts) - 1
        if isinstance(cur, dict):
            if part.isdigit():
                raise ScenarioError(
                    f"{key}: {'.'.join(parts[:i]) or 'the top level'} is a table, not an "
                    f"array; expected a key name after it, not the position {part}"
                )
            if last:
                cur[part] = copy.deepcopy(value)
            elif part not in cur and parts[i + 1].isdigit():
                raise ScenarioError(
                    f"{key}: {here} is not written in the scenario, so it has no entry "
                    f"{parts[i + 1]}; expected the whole array, e.g. {here}=[...]"
                )
            else:
                cur = cur.setdefault(part, {})
        elif isinstance(cur, list):
            if not part.isdigit():
                raise ScenarioError(
                    f"{key}: {'.'.join(parts[:i])} is an array of {len(cur)} values; expected "
                    f"a position 0 to {len(cur) - 1} after it, not {part!r}"
                )
            k = int(part)
            if k >= len(cur):
                raise ScenarioError(
                    f"{key}: no entry {k} in {'.'.join(parts[:i])}, which has {len(cur)} "
                    + (f"(positions 0 to {len(cur) - 1})" if cur else "(none)")
                )
            if last:
                cur[k] = copy.deepcopy(value)
            else:
                cur = cur[k]
        else:
            parent = ".".join(parts[:i])
            raise ScenarioError(
                f"{key}: {parent} is {_kind(cur)}, not a table or an array; expected a key "
                f"that ends at {parent}, not {here}"
            )
    return raw


def apply_overrides(raw: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A deep copy of the raw scenario table with every dotted key of `overrides` set (in
    order, see `override`); validate it with ``virtmech.scenarios.validate``. Raises one
    ScenarioError listing every key whose path cannot be followed."""
    out = copy.deepcopy(dict(raw))
    errors: list[str] = []
    for key, value in overrides.items():
        try:
            override(out, key, value)
        except ScenarioError as e:
            errors += e.messages
    if errors:
        raise ScenarioError(*errors)
    return out


# ---------------------------------------------------------------------------------------
# the command line's KEY=VALUE and KEY=V1,V2,...


def _toml():
    from . import _toml

    return _toml()


def parse_value(text: str) -> Any:
    """A value written on the command line, read as a TOML value (``300`` an integer,
    ``0.5`` and ``1e-4`` floats, ``true``, ``[0.3, 0.1, 0]`` an array, ``"x"`` a string);
    a bare word that is no TOML value (``null_space``, ``auto``) is that string. Text that
    starts like an array, a table or a quoted string but is not one is a ScenarioError."""
    s = text.strip()
    if not s:
        raise ScenarioError("empty value; expected a TOML value such as 300, true or [0, 0, 1]")
    try:
        return _toml().loads(f"v = {s}")["v"]
    except Exception as e:  # tomllib.TOMLDecodeError
        if s[0] in "[{\"'" or not re.fullmatch(r"[A-Za-z0-9_.+-]+", s):
            raise ScenarioError(
                f"{s!r} is not a TOML value ({e}); expected e.g. 300, 1e-4, true, "
                '[0.3, 0.1, 0] or "text"'
            ) from None
        return s


def value_text(v: Any) -> str:
    """A value as the command line writes it (TOML; a string bare): the inverse of
    parse_value for the values a scenario holds."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return v
    if isinstance(v, list):
        return "[" + ", ".join(value_text(x) for x in v) + "]"
    return repr(v) if isinstance(v, float) else str(v)


def split_values(text: str) -> list[str]:
    """``V1,V2,...`` split at the commas outside brackets, braces and quotes:
    ``[0,0,0],[0.01,0,0]`` is two values."""
    parts, depth, quote, start = [], 0, "", 0
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts]


def parse_assignment(text: str, flag: str = "--set", many: bool = False) -> tuple[str, Any]:
    """``KEY=VALUE`` (or, with many=True, ``KEY=V1,V2,...``) as (key, value) or (key, list of
    values); a ScenarioError naming the flag and the text when it is not one, listing every
    value that is not a TOML value."""
    key, values, errors = _parse(text, flag, many)
    if errors:
        raise ScenarioError(*errors)
    return (key, values) if many else (key, values[0])


def parse_grid(texts, flag: str = "--grid") -> tuple[dict[str, list], list[str]]:
    """``KEY=V1,V2,...`` texts as ({key: [values]}, [mistakes]): every text read as far as it
    can be (a key keeps the values that are TOML values), so that the values can still be
    checked and every mistake reported at once."""
    grid: dict[str, list] = {}
    errors: list[str] = []
    for text in texts:
        key, values, errs = _parse(text, flag, True)
        errors += errs
        if key is None:
            continue
        if key in grid:
            errors.append(f"{flag} {key}: given twice; expected each key once")
            continue
        if values:
            grid[key] = values
    return grid, errors


def _parse(text: str, flag: str, many: bool) -> tuple[str | None, list, list[str]]:
    key, sep, rhs = text.partition("=")
    key = key.strip()
    form = "KEY=V1,V2,..." if many else "KEY=VALUE"
    if not sep or not key:
        example = "controller.law=null_space,under_actuated" if many else "human.stiffness=300"
        return None, [], [f"{flag} {text!r}: expected {form}, e.g. {flag} {example}"]
    try:
        _parts(key)
    except ScenarioError as e:
        return None, [], [f"{flag} {text!r}: {e}"]
    values, errors = [], []
    for t in split_values(rhs) if many else [rhs]:
        try:
            values.append(parse_value(t))
        except ScenarioError as e:
            errors.append(f"{flag} {key}={t}: {e}")
    return key, values, errors
