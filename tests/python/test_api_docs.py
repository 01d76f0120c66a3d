"""help() answers what a user of the Python API asks first: the Controller's settings with
their units, and what every property of a cycle's output is."""

from __future__ import annotations

import re
from pathlib import Path

import virtmech as vm


def _signature_keywords(doc: str) -> list[str]:
    """The keyword-only parameters of the nanobind signature on the docstring's first line."""
    first = doc.splitlines()[0]
    return re.findall(r"(\w+): [^,=]+ = ", first.split("*,", 1)[1])


def test_the_controllers_help_gives_every_setting_and_its_unit():
    doc = vm.Controller.__init__.__doc__
    keywords = _signature_keywords(doc)
    assert "watchdog_s" in keywords and len(keywords) >= 20
    text = doc.split("\n", 1)[1]  # the description, without the signature
    for k in keywords:
        assert re.search(rf"\b{k}\b", text), f"{k} is not described"
    for unit in ("kp: stiffness [N/m", "kv: damping [N·s/m", "watchdog_s: the longest gap",
                 "[s]", "range_margin_rad [rad]", "range_margin_m [m]", "max_force [N]",
                 "max_torque [N·m]", "passivity_fade_j", "[J]", "length_scale: L [m]"):
        assert unit in text, unit
    assert "secondary_weight: the weight of" in text


def _undocumented(cls) -> list[str]:
    """Public attributes whose docstring is missing or only nanobind's signature."""
    out = []
    for name in dir(cls):
        if name.startswith("_"):
            continue
        doc = (getattr(cls, name).__doc__ or "").strip()
        if not doc or doc.startswith("(self)"):
            out.append(name)
    return out


def test_every_property_of_a_cycles_output_has_a_docstring():
    assert _undocumented(vm.CycleOutput) == []
    assert _undocumented(vm.MechanismSetOutput) == []
    doc = vm.CycleOutput.residual.__doc__
    assert "[m]" in doc
    assert "[m/s; rad/s]" in vm.CycleOutput.error_dot.__doc__
    assert "(4, 4)" in vm.CycleOutput.handle_pose.__doc__


def test_the_readme_and_the_docstring_say_the_same_of_the_energy():
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    line = next(ln for ln in readme.splitlines() if ln.startswith("out.energy"))
    assert "the energy tank's level [J]" in line
    assert vm.CycleOutput.energy.__doc__.startswith("The energy tank's level [J]")
