"""The scenario format (docs/scenarios.md): one Field per key, with defaults and ranges.

The [device], [mechanism] and shape tables are the core's kinds (virtmech.kinds: each
kind's parameters, defaults and ranges), [controller] and [set] its settings tables
(virtmech.CONTROLLER_SETTINGS, SET_SETTINGS): this module keeps no copy of a default or a
range of theirs. The format is made when asked (`scenario`), so that kinds a plugin adds
(the top-level `plugins` key) are in it."""

from __future__ import annotations

import math
from typing import Any

from .. import _core
from .schema import Field

INF = float("inf")


def num(default=None, required=False, min=None, max=None, min_exclusive=False, doc=""):
    kw = {} if default is None else {"default": default}
    return Field(
        "number", required=required, min=min, max=max, min_exclusive=min_exclusive, doc=doc, **kw
    )


def vec(n, default=None, required=False, doc="", nonzero=False):
    kw = {} if default is None else {"default": default}
    return Field("vector", length=n, required=required, doc=doc, nonzero=nonzero, **kw)


def opt_vec(n, doc="", nonzero=False):
    return Field("vector", length=n, doc=doc, nonzero=nonzero)


def direction(default=None, required=False, doc="3 numbers, not all zero"):
    """A direction: 3 finite numbers, not all zero, read as the unit vector x / |x|."""
    if default is None and not required:
        return opt_vec(3, doc, nonzero=True)
    return vec(3, default, required, doc, nonzero=True)


#: a scenario's name is the folder its outputs go to: a plain file name, never a path
SAFE_NAME = r"[A-Za-z0-9_-][A-Za-z0-9._-]*"


DEVICE_PHYSICS = {
    "link_mass": num(min=0, doc="arm link mass [kg]"),
    "base_mass": num(min=0, doc="Omni turret mass [kg]"),
    "armature": num(min=0, doc="motor rotor inertia [kg m^2]"),
    "joint_friction": num(min=0, doc="actuated-joint Coulomb friction [N m]"),
    "joint_damping": num(min=0, doc="actuated-joint damping [N m s/rad]"),
    "passive_friction": num(min=0, doc="passive-joint Coulomb friction [N m]"),
    "passive_damping": num(min=0, doc="passive-joint damping [N m s/rad]"),
    "gimbal_mass": num(min=0, doc="gimbal ring mass [kg]"),
    "stylus_mass": num(min=0, doc="stylus mass [kg]"),
    "stylus_com": num(min=-0.2, max=0.2, doc="stylus centre of mass along the stylus [m]"),
}

def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _unit(doc: str, unit: str) -> str:
    return f"{doc} [{unit}]" if unit else doc


def _array(shape: tuple, p: dict, **kw: Any) -> Field:
    """A Field of numbers of `shape` (-1: any size), each within p's range."""
    length = shape[0] if shape[0] >= 0 else None
    if len(shape) == 1:
        return Field("vector", length=length, nonzero=p["nonzero"], min=_finite(p["min"]),
                     max=_finite(p["max"]), min_exclusive=p["min_exclusive"], **kw)
    return Field("vector", length=length, element=_array(shape[1:], p), **kw)


def param_field(p: dict) -> Field:
    """The Field of one parameter of a kind (virtmech.kinds)."""
    kw: dict[str, Any] = {"required": p["required"], "doc": _unit(p["doc"], p["unit"])}
    if "default" in p:
        kw["default"] = p["default"]
    k = p["kind"]
    if k in ("number", "integer"):
        return Field(k, min=_finite(p["min"]), max=_finite(p["max"]),
                     min_exclusive=p["min_exclusive"], **kw)
    if k == "bool":
        return Field("bool", **kw)
    if k == "string":
        return Field("string", choices=tuple(p["choices"]) or None, **kw)
    if k == "array":
        return _array(tuple(p["shape"]), p, **kw)
    if k == "bools":
        n = p["shape"][0]
        return Field("vector", element=Field("bool"), length=n if n >= 0 else None, **kw)
    if k in ("curve", "surface"):
        return Field("table", variant_key="type", variants=kind_fields(k), **kw)
    if k == "tables":
        return Field("tables", children={f["name"]: param_field(f) for f in p["fields"]}, **kw)
    raise AssertionError(k)


def kind_fields(what: str, extra: dict[str, Field] | None = None) -> dict[str, dict[str, Field]]:
    """{kind: {parameter: Field}} of the core's registered kinds of `what` ("mechanism",
    "device", "curve", "surface"), each with the `extra` keys."""
    return {k["name"]: {**{p["name"]: param_field(p) for p in k["params"]}, **(extra or {})}
            for k in _core.kinds(what)}


def setting_field(row: dict) -> Field:
    """The Field of one row of a settings table (virtmech.CONTROLLER_SETTINGS, SET_SETTINGS)."""
    doc = _unit(row["doc"], row["unit"])
    if row["kind"] == "vector6":
        return Field("vector", length=6, min=0, doc=doc)
    if row["kind"] == "choice":
        return Field("string", default=row["default"], choices=tuple(row["choices"]), doc=doc)
    return Field("number" if row["kind"] == "number" else "integer", default=row["default"],
                 min=row["min"], max=_finite(row["max"]), min_exclusive=row["min_exclusive"],
                 doc=doc)


def _device() -> Field:
    return Field("table", required=True, variant_key="type",
                 variants=kind_fields("device", DEVICE_PHYSICS))


def _mechanism() -> Field:
    return Field("table", required=True, variant_key="type", variants=kind_fields("mechanism"))


def _set(mechanism: Field) -> Field:
    """Several mechanisms at once: the [mechanism] is member 0, [[set.members]] the others
    (docs/scenarios.md); a set of one mechanism is that mechanism's controller alone. The
    servo period is the controller's."""
    rows = [r for r in _core.SET_SETTINGS if r["name"] != "period_s"]
    return Field("table", children={
        "members": Field("tables", default=[], variant_key="type", variants=mechanism.variants,
                         doc="the other mechanisms, as [mechanism] tables"),
        **{r["name"]: setting_field(r) for r in rows},
    })


def _controller() -> Field:
    return Field("table", children={r["name"]: setting_field(r) for r in _core.CONTROLLER_SETTINGS})


PHYSICS = Field(
    "table",
    children={
        "rate_hz": num(4000.0, min=100, max=100000, doc="physics steps per second"),
        "gravity": Field("bool", default=True),
        "gravity_compensation": Field("bool", default=True),
    },
)

SENSORS = Field(
    "table",
    children={
        "counts_per_rev": Field("integer", default=15000, min=0, max=10**9),
        "noise_rad": num(0.0, min=0, max=1),
        "delay_cycles": Field("integer", default=0, min=0, max=1000),
        "dropout_probability": num(
            0.0,
            min=0,
            max=1,
        ),
        "velocity_cutoff_hz": num(100.0, min=0, max=1e6),
    },
)

INITIAL = Field(
    "table",
    children={
        "theta": num(0.0, min=-100, max=100, doc="mechanism joint value giving the start pose"),
        "offset": vec(3, [0.0, 0.0, 0.0]),
        "stylus_theta": num(min=-100, max=100),
        "q": Field("vector"),
    },
)

HUMAN = Field(
    "table",
    children={
        "mass_kg": num(0.2, min=0.001, max=5),
        "damping": num(5.0, min=0, max=100),
        "stiffness": num(200.0, min=0, max=5000),
        "inertia": num(2e-4, min=1e-7, max=1),
        "rot_damping": num(0.01, min=0, max=10),
        "rot_stiffness": num(1.0, min=0, max=100),
        "grip_contacts": Field("vector", length=2, default=[-0.015, -0.05]),
    },
)

_MODE = ("passive", "hold")
#: the largest force and moment component an intent may apply: a hand pushing on a held
#: stylus or handle, beyond every device's peak force (a few to 20 N) by far, so that a
#: mistyped unit (1e6) is a named mistake rather than a diverging simulation
MAX_INTENT_FORCE_N = 100.0
MAX_INTENT_MOMENT_NM = 10.0


def _bounded_vec(limit: float, unit: str, required: bool = False) -> Field:
    return Field(
        "vector", length=3, required=required, min=-limit, max=limit,
        doc=f"3 numbers [{unit}], each within ±{limit:g}",
    )


_PUSH = {
    "force": _bounded_vec(MAX_INTENT_FORCE_N, "N"),
    "moment": _bounded_vec(MAX_INTENT_MOMENT_NM, "N m"),
    "force_frame": Field(
        "string", default="world", choices=("world", "handle"),
        doc="the axes of force and moment",
    ),
    "ramp_s": num(0.1, min=0, max=10, doc="a number [s] >= 0"),
}
_COMMON = {
    "start_s": num(required=True, min=0, doc="a number [s] >= 0"),
    "duration_s": num(required=True, min=0, doc="a number [s] >= 0"),
    "translation": Field("string", choices=_MODE),
    "orientation": Field("string", choices=_MODE + ("path",)),
    "stiffness": num(min=0, max=5000),
    "rot_stiffness": num(min=0, max=100),
    **_PUSH,
}
_AXIS = Field("axis", default="normal", choices=("normal", "stylus"))
_OSCILLATION = {
    **_COMMON,
    "axis": _AXIS,
    "amplitude_m": num(min=0, max=1, doc="a number [m] >= 0 (translation along axis)"),
    "amplitude_deg": num(min=-360, max=360, doc="a number [deg] (rotation about axis)"),
}
#: a sine's or chirp's highest frequency [Hz] (the control rate's Nyquist frequency is
#: checked against controller.period_s when the file is read)
_FREQ = {"min": 0, "max": 1e4}
INTENT = Field(
    "tables",
    default=[],
    variant_key="action",
    variants={
        "hold": dict(_COMMON),
        "follow": {
            **_COMMON,
            # required with profile = "min_jerk", not allowed with "constant" (checked with
            # the profile when the file is read)
            "duration_s": num(min=0, doc="a number [s] >= 0"),
            "theta": Field("vector", length=2),
            "offsets": Field("vector", min_length=1, element=Field("vector", length=3)),
            "profile": Field("string", default="min_jerk", choices=("min_jerk", "constant")),
            "speed_m_s": num(
                min=0, min_exclusive=True, max=10, doc="a number [m/s] > 0 (profile constant)"
            ),
        },
        "twist": {
            **_COMMON,
            "angle_deg": num(required=True, min=-720, max=720, doc="a number [deg]"),
            "axis": _AXIS,
        },
        "resist": {
            **_COMMON,
            "angle_deg": num(required=True, min=-720, max=720, doc="a number [deg]"),
            "axis": _AXIS,
        },
        "push": {**_COMMON, "force": _bounded_vec(MAX_INTENT_FORCE_N, "N", required=True)},
        "sine": {
            **_OSCILLATION,
            "frequency_hz": num(required=True, min_exclusive=True, doc="a number [Hz] > 0",
                                **_FREQ),
        },
        "chirp": {
            **_OSCILLATION,
            "f0_hz": num(required=True, doc="a number [Hz] >= 0", **_FREQ),
            "f1_hz": num(required=True, doc="a number [Hz] >= 0", **_FREQ),
        },
        "wrench": {
            "start_s": num(required=True, min=0, doc="a number [s] >= 0"),
            "duration_s": num(required=True, min=0, doc="a number [s] >= 0"),
            **_PUSH,
        },
        "release": {"start_s": num(required=True, min=0, doc="a number [s] >= 0")},
    },
)

CHECKS = Field(
    "table",
    children={
        "settle_s": num(min=0),
        "reach_s": num(min=0),
        "max_distance_m": num(min=0),
        "max_lag_deg": num(min=0),
        "perpendicular_deg": num(min=0),
        "min_free_deg": num(min=0),
        "min_travel_deg": num(min=0),
        "min_force_n": num(min=0),
    },
)

def scenario() -> Field:
    """The whole format, with the kinds registered now."""
    mechanism = _mechanism()
    return Field(
        "table",
        children={
            "name": Field(
                "string",
                required=True,
                pattern=SAFE_NAME,
                doc="a plain file name (letters, digits, '-', '_', '.'; not starting with '.'): "
                "the name of the run's output folder",
            ),
            "description": Field("string", default=""),
            "duration_s": num(
                required=True, min=0, min_exclusive=True, max=3600, doc="a number [s] > 0"
            ),
            "seed": Field("integer", default=0, min=0, max=2**63 - 1),
            "plugins": Field(
                "vector",
                element=Field("string"),
                default=[],
                doc="shared libraries adding kinds of mechanism, device or shape (paths "
                "relative to the scenario file): virtmech.load_plugin",
            ),
            "device": _device(),
            "mechanism": mechanism,
            "controller": _controller(),
            "physics": PHYSICS,
            "sensors": SENSORS,
            "set": _set(mechanism),
            "initial": INITIAL,
            "human": HUMAN,
            "intent": INTENT,
            "checks": CHECKS,
        },
    )
