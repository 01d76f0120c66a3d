"""One table per fact: the controller's and the mechanism set's settings, the names of the
enumerations and the log's columns each come from one table in the core, which the C++
structs, the bindings, the scenario format, its JSON Schema and docs/scenarios.md all
read. These tests check the places against each other and against the core's behaviour."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import virtmech as vm
import virtmech.scenarios as sc
from virtmech.scenarios import docs
from virtmech.scenarios.schema import ScenarioError

ROOT = Path(__file__).resolve().parents[2]

SCENARIO = """
name = "t"
duration_s = 0.1
[device]
type = "PhantomOmni"
[mechanism]
type = "PlanarArm"
pivot = [0.0, 0.0, -0.05]
length = 0.05
"""


def omni_arm():
    return vm.PhantomOmni(), vm.PlanarArm([0, 0, -0.05], [0, 0, 1], 0.05)


def test_docs_tables_are_made_from_the_cores_tables():
    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    assert "<!-- table: controller -->" in text and "<!-- table: mechanism -->" in text
    assert docs.render(text) == text, "run: python -m virtmech.scenarios.docs docs/scenarios.md"


def test_a_changed_document_is_told_apart(tmp_path):
    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    bad = tmp_path / "scenarios.md"
    row = "| `period_s` | number | 0.001 |"
    bad.write_text(text.replace(row, row.replace("0.001", "0.002")))
    assert docs.main([str(bad), "--check"]) == 1
    assert docs.main([str(bad)]) == 0 and bad.read_text() == text


def test_every_controller_setting_is_a_scenario_key_with_the_structs_default():
    names = [r["name"] for r in vm.CONTROLLER_SETTINGS]
    assert len(names) == 28 and len(set(names)) == 28
    props = sc.json_schema()["properties"]["controller"]["properties"]
    assert sorted(props) == sorted(names)
    data = sc.loads(SCENARIO)["controller"]
    struct = vm.ControllerSettings()  # the C++ struct's own member initialisers
    for r in vm.CONTROLLER_SETTINGS:
        value = getattr(struct, r["name"])
        if r["kind"] == "vector6":
            assert value is None and r["name"] not in data
        elif r["kind"] == "choice":
            assert value.name == r["default"] == data[r["name"]] == props[r["name"]]["default"]
        else:
            assert value == r["default"] == data[r["name"]] == props[r["name"]]["default"]


@pytest.mark.parametrize(
    "key, value, check",
    [
        ("watchdog_s", 0.02, lambda m, dev: m["watchdog_s"] == 0.02),
        ("max_torque", 0.05, lambda m, dev: m["max_torque"] == 0.05),
        ("max_iterations_initial", 7, lambda m, dev: m["max_iterations_initial"] == 7),
        ("length_scale", 0.2, lambda m, dev: np.isclose(m["w_e_star"][3], 0.04)),
        ("range_margin_rad", 0.2,
         lambda m, dev: np.allclose(np.asarray(m["q_min"])[np.isfinite(dev.lower)],
                                    dev.lower[np.isfinite(dev.lower)] - 0.2)),
        ("error_velocity", "handle", lambda m, dev: m["error_velocity"] == "handle"),
    ],
)
def test_a_setting_written_in_a_scenario_reaches_the_controller(key, value, check):
    from virtmech.builder import controller_kwargs, make_device, make_mechanism

    s = sc.loads(SCENARIO).with_keys({f"controller.{key}": value})
    dev = make_device(s["device"])
    c = vm.Controller(dev, make_mechanism(s["mechanism"]), **controller_kwargs(s["controller"]))
    assert check(c.model, dev)


def _outside(r) -> list:
    """Values just outside a numeric row's range."""
    out = [r["min"] if r["min_exclusive"] else r["min"] - 1.0]
    if math.isfinite(r["max"]):
        out.append(r["max"] * 2 + 1)
    return out


NUMERIC = [r for r in vm.CONTROLLER_SETTINGS if r["kind"] in ("number", "integer")]


@pytest.mark.parametrize("row", NUMERIC, ids=lambda r: r["name"])
def test_a_setting_outside_its_range_is_refused_by_the_core_and_the_format_alike(row):
    dev, arm = omni_arm()
    name = row["name"]
    for bad in _outside(row):
        bad = int(bad) if row["kind"] == "integer" else bad
        with pytest.raises(ValueError, match=rf"^{name}: expected"):
            vm.Controller(dev, arm, **{name: bad})
        with pytest.raises(ScenarioError, match=rf"controller\.{name}: value .* is out of range"):
            sc.loads(SCENARIO).with_keys({f"controller.{name}": bad})
    inside = row["default"] if row["default"] != row["min"] or not row["min_exclusive"] else 1
    vm.Controller(dev, arm, **{name: inside})


def test_nan_and_inf_are_refused_where_the_table_says():
    dev, arm = omni_arm()
    with pytest.raises(ValueError, match="period_s"):
        vm.Controller(dev, arm, period_s=float("nan"))
    with pytest.raises(ValueError, match="ramp_time_s"):
        vm.Controller(dev, arm, ramp_time_s=float("inf"))  # a ramp that never ends
    c = vm.Controller(dev, arm, passivity_max_energy_j=float("inf"))  # the table's "no cap"
    assert c.model["passivity_max_energy_j"] == float("inf")


def test_the_enumerations_are_bound_with_the_names_users_write():
    assert [e.name for e in vm.ControlLaw] == ["auto", "null_space", "under_actuated"]
    assert [e.name for e in vm.ErrorVelocity] == ["relative", "handle"]
    assert {e.name for e in vm.Passivity} == {"energy_tank", "off"}
    dev, arm = omni_arm()
    by_enum = vm.Controller(dev, arm, law=vm.ControlLaw.null_space, passivity=vm.Passivity.off)
    by_name = vm.Controller(dev, arm, law="null_space", passivity="off")
    assert by_enum.model["law"] == by_name.model["law"] == "null_space"
    assert by_enum.model["passivity"] == "off" and not by_enum.model["under_actuated_term"]
    s = vm.ControllerSettings()
    s.law = "under_actuated"
    assert s.law == vm.ControlLaw.under_actuated
    names = "'auto', 'null_space' or 'under_actuated'"
    with pytest.raises(ValueError, match=rf"law: expected {names}, got 'pd'"):
        s.law = "pd"
    with pytest.raises(TypeError, match="law"):
        s.law = 3


def test_a_settings_object_and_keywords_combine():
    dev, arm = omni_arm()
    s = vm.ControllerSettings()
    s.kp = [100.0] * 6
    s.ramp_time_s = 0.05
    c = vm.Controller(dev, arm, s, ramp_time_s=0.1)  # the keyword wins
    assert np.allclose(c.model["kp"], 100.0) and c.model["ramp_cycles"] == 100
    with pytest.raises(TypeError, match="unexpected keyword argument 'kpp'"):
        vm.Controller(dev, arm, kpp=[1] * 6)
    with pytest.raises(ValueError, match=r"kp: expected an array of shape \(6,\)"):
        s.kp = [1, 2]
    with pytest.raises(TypeError, match="ramp_time_s: expected a number"):
        s.ramp_time_s = "fast"


def test_the_set_settings_come_from_their_table():
    names = [r["name"] for r in vm.SET_SETTINGS]
    props = sc.json_schema()["properties"]["set"]["properties"]
    assert sorted(props) == sorted(["members"] + [n for n in names if n != "period_s"])
    struct = vm.MechanismSetSettings()
    for r in vm.SET_SETTINGS:
        assert getattr(struct, r["name"]) == r["default"]
        if r["name"] != "period_s":
            assert props[r["name"]]["default"] == r["default"]
    dev = vm.PhantomOmni()
    for r in vm.SET_SETTINGS:
        with pytest.raises(ValueError, match=rf"^{r['name']}: expected"):
            vm.MechanismSet(dev, 2, **{r["name"]: -1.0})
    s = vm.MechanismSet(dev, 2, snap_distance=0.002, release_distance=0.004)
    assert s.capacity == 2


def test_the_log_columns_and_units_come_from_one_table():
    pytest.importorskip("mujoco")
    from virtmech.sim import geometry, inner
    from virtmech.sim.log import UNITS, log_columns

    table = inner._log_table()
    for n, m in ((1, 1), (3, 4), (6, 6)):
        cols = log_columns(n, m)
        assert len(cols) == len(set(cols))
        assert cols[cols.index("q0"):cols.index("q0") + n] == [f"q{i}" for i in range(n)]
        k = cols.index("theta0")
        assert cols[k:k + m] == [f"theta{i}" for i in range(m)]
    first = log_columns(1, 1)
    assert [r["first"] for r in table] == [c for c in first if c in {r["first"] for r in table}]
    derived = [r["field"] for r in table if r["derived"]]
    assert tuple(derived[:4]) == geometry.COLUMNS  # the core's distance columns, in order
    assert set(inner.LOG_FIELDS) == {r["field"] for r in table if not r["derived"]}
    assert UNITS["vx"] == "m/s" and UNITS["wx"] == "rad/s" and UNITS["q"] == "rad"
    assert "iterations" not in UNITS
