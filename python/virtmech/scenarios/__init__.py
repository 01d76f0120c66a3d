"""Scenarios as data: TOML files describing a device, a virtual mechanism, the controller's
settings, the human and the intent timeline, the sensors and the duration (format:
docs/scenarios.md). The paper's Figs. 9-12 ship as `omni-fig9` ... `planar3r-fig12`.

    >>> import virtmech.scenarios as sc
    >>> sc.names()[:2]
    ['omni-fig9', 'omni-fig10']
    >>> s = sc.load("omni-fig10")
"""

from __future__ import annotations

import copy
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .overrides import (
    apply_overrides,
    override,
    parse_assignment,
    parse_grid,
    parse_value,
    split_values,
    value_text,
)
from .schema import ScenarioError

__all__ = [
    "Scenario",
    "ScenarioError",
    "apply_overrides",
    "json_schema",
    "load",
    "loads",
    "names",
    "override",
    "paper_order",
    "parse_assignment",
    "parse_grid",
    "parse_value",
    "path_of",
    "split_values",
    "validate",
    "value_text",
]

DATA = Path(__file__).resolve().parent / "data"


def _toml():
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    return tomllib


@dataclass
class Scenario:
    """A validated scenario: `data` holds every key with its default filled in."""

    data: dict[str, Any]
    source: str = "<string>"
    raw: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.data["name"]

    @property
    def duration_s(self) -> float:
        return self.data["duration_s"]

    @property
    def seed(self) -> int:
        return self.data["seed"]

    def __getitem__(self, key: str) -> Any:
        return self.data[key]

    def with_overrides(self, **changes: Any) -> Scenario:
        """A re-validated copy with top-level keys replaced or tables merged, e.g.
        ``s.with_overrides(duration_s=1.0, sensors={"noise_rad": 1e-4})``."""
        raw = copy.deepcopy(self.raw)
        for k, v in changes.items():
            if isinstance(v, dict) and isinstance(raw.get(k), dict):
                raw[k].update(v)
            else:
                raw[k] = v
        return validate(raw, self.source)

    def with_keys(self, overrides: dict[str, Any]) -> Scenario:
        """A re-validated copy with dotted keys set (virtmech.scenarios.overrides), e.g.
        ``s.with_keys({"controller.law": "null_space", "intent.1.duration_s": 1.5})``."""
        return validate(apply_overrides(self.raw, overrides), self.source)

    def to_dict(self) -> dict[str, Any]:
        return copy.deepcopy(self.data)

    def __setstate__(self, state: dict) -> None:
        # a scenario sent to another process brings its plugins' kinds with it
        self.__dict__.update(state)
        for path in self.data.get("plugins", []):
            _load_plugin(path)


def _load_plugin(path: str) -> None:
    from .._core import load_plugin

    load_plugin(path)


def _plugins(raw: dict[str, Any], source: str) -> tuple[list[str], list[str]]:
    """The `plugins` of a raw scenario, loaded (paths relative to the scenario's file):
    (their absolute paths, the mistakes naming each). A `plugins` that is not a list of
    strings is left to the format's check."""
    plugins = raw.get("plugins", [])
    if not isinstance(plugins, list) or not all(isinstance(p, str) for p in plugins):
        return [], []
    base = Path(source).parent if Path(source).is_file() else Path.cwd()
    paths, errors = [], []
    for i, p in enumerate(plugins):
        path = str((base / Path(p).expanduser()).resolve())
        try:
            _load_plugin(path)
            paths.append(path)
        except ValueError as e:
            errors.append(f"plugins[{i}]: {e}")
    return paths, errors


def validate(raw: dict[str, Any], source: str = "<string>") -> Scenario:
    """Checks a parsed scenario; raises one ScenarioError listing every mistake (each naming
    the source, the key, the value and what was expected). The checks between keys (e.g. the
    physics rate against the control period) run once every key is valid on its own."""
    from .format import scenario
    from .schema import check_table

    plugins, errors = _plugins(raw, source)
    if errors:
        raise ScenarioError(*[f"{source}: {m}" for m in errors])
    try:
        data = check_table("", raw, scenario())
    except ScenarioError as e:
        raise ScenarioError(*[f"{source}: {m}" for m in e.messages]) from None
    data["plugins"] = plugins
    errors = _consistency_errors(data)
    if errors:
        raise ScenarioError(*[f"{source}: {m}" for m in errors])
    return Scenario(data=data, source=source, raw=copy.deepcopy(raw))


def _consistency_errors(d: dict) -> list[str]:
    errors = []
    c, p = d["controller"], d["physics"]
    sub = p["rate_hz"] * c["period_s"]
    if abs(sub - round(sub)) > 1e-9 or round(sub) < 1:
        errors.append(
            f"physics.rate_hz: value {p['rate_hz']:g} is out of range; expected a "
            f"whole multiple of the control rate {1.0 / c['period_s']:g} Hz"
        )
    if d["duration_s"] < c["period_s"]:
        errors.append(
            f"duration_s: value {d['duration_s']:g} is out of range; expected at least one "
            f"control period (controller.period_s = {c['period_s']:g} s)"
        )
    for i, seg in enumerate(d["intent"]):
        if seg["action"] == "follow" and ("theta" in seg) == ("offsets" in seg):
            errors.append(
                f"intent[{i}]: missing required field; expected exactly one of "
                "'theta' (a path along the mechanism) or 'offsets' (waypoints [m])"
            )
        errors += _intent_errors(i, seg, c["period_s"])
    q = d["initial"].get("q")
    if q is not None:
        n = _dof(d["device"])
        if n is not None and len(q) != n:
            errors.append(
                f"initial.q: expected {n} numbers (one per joint of "
                f"{d['device']['type']}), got {len(q)} values"
            )
    return errors


def _dof(device: dict) -> int | None:
    """The joints of the scenario's device (None where it cannot be built: the run says why)."""
    from .. import _core
    from .format import DEVICE_PHYSICS

    try:
        return _core.make_device({k: v for k, v in device.items() if k not in DEVICE_PHYSICS}).dof
    except (ValueError, TypeError):
        return None


def _intent_errors(i: int, seg: dict, period_s: float) -> list[str]:
    """The checks between an intent segment's keys (its keys are each valid)."""
    errors, at, action = [], f"intent[{i}]", seg["action"]
    if action == "follow":
        if seg["profile"] == "constant":
            if "speed_m_s" not in seg:
                errors.append(
                    f"{at}.speed_m_s: missing required field; expected a number [m/s] > 0 "
                    "with profile = 'constant'"
                )
            if "duration_s" in seg:
                errors.append(
                    f"{at}.duration_s: value {seg['duration_s']:g} not allowed with profile "
                    "= 'constant'; expected no duration_s (it is the path length / speed_m_s "
                    "+ ramp_s)"
                )
        else:
            if "duration_s" not in seg:
                errors.append(
                    f"{at}.duration_s: missing required field (a number [s] >= 0; with "
                    "profile = 'constant' and speed_m_s it follows from the path)"
                )
            if "speed_m_s" in seg:
                errors.append(
                    f"{at}.speed_m_s: value {seg['speed_m_s']:g} not allowed with profile = "
                    f"{seg['profile']!r}; expected profile = 'constant' with it"
                )
    if action in ("sine", "chirp"):
        if ("amplitude_m" in seg) == ("amplitude_deg" in seg):
            errors.append(
                f"{at}: expected exactly one of 'amplitude_m' (translation along axis [m]) or "
                f"'amplitude_deg' (rotation about axis [deg]), got "
                + ("both" if "amplitude_m" in seg else "neither")
            )
        if not seg["duration_s"] > 0:
            errors.append(
                f"{at}.duration_s: value {seg['duration_s']:g} is out of range; expected a "
                f"number [s] > 0 for a {action}"
            )
        for amp, group, default in (("amplitude_m", "translation", "hold"),
                                    ("amplitude_deg", "orientation", "hold")):  # fmt: skip
            if amp in seg and seg.get(group, default) == "passive":
                errors.append(
                    f"{at}.{group}: value 'passive' not allowed with {amp}; expected 'hold' "
                    f"(a passive {group} has no stiffness: the oscillation would not act)"
                )
        nyquist = 0.5 / period_s
        for key in ("frequency_hz", "f0_hz", "f1_hz"):
            if key in seg and seg[key] > nyquist:
                errors.append(
                    f"{at}.{key}: value {seg[key]:g} is out of range; expected at most "
                    f"{nyquist:g} Hz (half the control rate, controller.period_s = "
                    f"{period_s:g} s)"
                )
    if action == "wrench" and "force" not in seg and "moment" not in seg:
        errors.append(
            f"{at}: missing required field; expected 'force' (3 numbers [N]) and/or "
            "'moment' (3 numbers [N m])"
        )
    return errors


def loads(text: str, source: str = "<string>") -> Scenario:
    """A scenario from TOML text."""
    try:
        raw = _toml().loads(text)
    except Exception as e:  # tomllib.TOMLDecodeError
        raise ScenarioError(f"{source}: not valid TOML: {e}") from None
    return validate(raw, source)


def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of the scenario format, made from the same Fields as
    the checks (virtmech.scenarios.format): for editors' completion and checking. The checks
    between keys (validate) are not in it."""
    from .format import scenario
    from .schema import json_schema_of

    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "virtmech scenario",
        "description": "A virtmech scenario file (TOML); format: docs/scenarios.md",
        **json_schema_of(scenario()),
    }


def paper_order(names) -> list[str]:
    """Scenario names in the paper's figure order (fig9, fig10, fig11, fig12 by number, not
    as strings), device by device; names without a figure number after, alphabetically."""
    import re

    def key(name: str):
        m = re.search(r"fig(\d+)", name)
        return (0, name[: m.start()], int(m.group(1)), name) if m else (1, name, 0, name)

    return sorted(names, key=key)


def names() -> list[str]:
    """Names of the shipped scenarios in the paper's figure order (`paper_order`: omni-fig9
    before omni-fig10), then the others alphabetically: as `virtmech scenarios` lists them and
    `virtmech demo` runs them."""
    return paper_order(p.stem for p in DATA.glob("*.toml"))


def path_of(name: str) -> Path:
    """The file of a shipped scenario."""
    p = DATA / f"{name}.toml"
    if not p.exists():
        raise ScenarioError(
            f"{name}: no such shipped scenario; expected one of {', '.join(names())}"
        )
    return p


def load(name_or_path: str | Path) -> Scenario:
    """A shipped scenario by name (see names()) or a scenario file by path."""
    p = Path(name_or_path)
    if not p.suffix and not p.exists():
        p = path_of(str(name_or_path))
    if not p.exists():
        raise ScenarioError(f"{name_or_path}: no such file or shipped scenario")
    if p.is_dir():
        raise ScenarioError(
            f"{name_or_path}: is a folder; expected a scenario file (.toml) or one of the "
            f"shipped names {', '.join(names())}"
        )
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ScenarioError(f"{name_or_path}: cannot be read ({e}); expected a TOML file") from None
    return loads(text, str(p))
