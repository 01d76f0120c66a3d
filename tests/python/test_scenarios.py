"""Scenario files: the shipped ones load, broken ones fail with errors that name the key,
the value and what was expected."""

from __future__ import annotations

import pytest

import virtmech.scenarios as sc

PAPER = [f"{d}-fig{n}" for d in ("omni", "planar3r") for n in (9, 10, 11, 12)]
OMEGA6 = [f"omega6-fig{n}" for n in (9, 10, 11, 12)]
SHAPES = ["omni-surface-nurbs", "omni-surface-sphere", "omni-letter", "omni-trocar", "omni-snap"]
SHIPPED = [*PAPER, *OMEGA6, "omni-fig11-passive", "omni-contact", "arm7-contact",
           "falcon-contact", *SHAPES]

GOOD = """
name = "t"
duration_s = 1.0
[device]
type = "PhantomOmni"
[mechanism]
type = "PlanarArm"
pivot = [-0.07, 0.04, 0.0]
length = 0.08
[[intent]]
action = "twist"
start_s = 0.1
duration_s = 0.5
angle_deg = 10.0
"""


def test_the_papers_figures_ship_on_both_devices():
    assert sorted(sc.names()) == sorted(SHIPPED)
    for name in PAPER:
        s = sc.load(name)
        assert s.name == name
        assert s["device"]["type"] == ("PhantomOmni" if name.startswith("omni") else "Planar3R")
        assert s["mechanism"]["type"] == "PlanarArm"
        assert s["mechanism"]["normal"] == [0.0, 0.0, 1.0]  # the x-y plane, z held
    assert sc.load("omni-fig9")["controller"]["law"] == "null_space"
    assert sc.load("omni-fig10")["controller"]["law"] == "auto"


def test_the_papers_figures_ship_on_a_simulated_omega6_as_on_the_omni():
    # the same figures on the Cartesian device: the same law, gains, start, hand and checks,
    # the circle in the plane the wrist's first axis turns (the SDK's y-z plane)
    for name in OMEGA6:
        s, omni = sc.load(name), sc.load(name.replace("omega6", "omni"))
        assert s["device"]["type"] == "CartesianDevice" and s["device"]["model"] == "omega.6"
        assert s["mechanism"]["type"] == "PlanarArm"
        assert s["mechanism"]["normal"] == [1.0, 0.0, 0.0]
        assert s["mechanism"]["length"] == omni["mechanism"]["length"]
        for key in ("law", "passivity", "kp", "ramp_time_s"):
            assert s["controller"][key] == omni["controller"][key], (name, key)
        assert s["initial"]["theta"] == omni["initial"]["theta"]
        assert s["human"] == omni["human"] and s["intent"] == omni["intent"]
        assert s["checks"] == omni["checks"]
    assert sc.load("falcon-contact")["device"]["model"] == "falcon"


def test_defaults_are_filled_in():
    s = sc.loads(GOOD)
    assert s["sensors"]["counts_per_rev"] == 15000
    assert s["controller"]["period_s"] == 1e-3
    assert s["physics"]["rate_hz"] == 4000.0
    assert s["intent"][0]["axis"] == "normal"


def test_load_by_path(tmp_path):
    p = tmp_path / "x.toml"
    p.write_text(GOOD)
    assert sc.load(p).name == "t"
    assert sc.load(str(p)).name == "t"


def _error(text: str) -> str:
    with pytest.raises(sc.ScenarioError) as e:
        sc.loads(text, "bad.toml")
    return str(e.value)


def test_unknown_key_is_named_with_the_keys_expected():
    msg = _error(GOOD.replace("[device]", "[device]\nstifness = 3"))
    assert msg.startswith("bad.toml: device.stifness: unknown key in [device]")
    assert "expected one of" in msg and "l1" in msg and "max_force" in msg
    msg = _error(GOOD + "\n[human]\nmas_kg = 0.3\n")
    assert "human.mas_kg: unknown key" in msg and "mass_kg" in msg
    msg = _error("colour = 1\n" + GOOD)
    assert "colour: unknown key in the top level" in msg
    msg = _error(GOOD.replace("angle_deg = 10.0", 'angle_deg = 10.0\nforce_frme = "world"'))
    assert "intent[0].force_frme: unknown key" in msg


def test_wrong_type_names_key_value_and_expectation():
    msg = _error(GOOD.replace("duration_s = 1.0", 'duration_s = "long"'))
    assert "duration_s: expected a number" in msg and "'long'" in msg and "str" in msg
    msg = _error(GOOD.replace("pivot = [-0.07, 0.04, 0.0]", "pivot = [-0.07, 0.04]"))
    assert "mechanism.pivot: expected 3 numbers, got 2 values" in msg
    msg = _error(GOOD + '\n[physics]\ngravity = "yes"\n')
    assert "physics.gravity: expected true or false, got str 'yes'" in msg
    msg = _error(GOOD + "\n[sensors]\ncounts_per_rev = 1.5\n")
    assert "sensors.counts_per_rev: expected an integer, got float 1.5" in msg
    msg = _error(GOOD.replace('type = "PhantomOmni"', 'type = "Falcon"'))
    assert (
        "device.type: value 'Falcon' is not allowed; expected one of "
        "'PhantomOmni', 'Planar3R', 'Device', 'CartesianDevice'"
        in msg
    )


def test_out_of_range_names_key_value_and_range():
    msg = _error(GOOD.replace("length = 0.08", "length = -0.08"))
    assert "mechanism.length: value -0.08 is out of range; expected a number > 0" in msg
    msg = _error(GOOD + "\n[sensors]\ndropout_probability = 1.5\n")
    assert (
        "sensors.dropout_probability: value 1.5 is out of range; "
        "expected a number >= 0 and <= 1" in msg
    )
    msg = _error(GOOD + "\n[human]\ndamping = -2\n")
    assert "human.damping: value -2.0 is out of range" in msg
    msg = _error(GOOD + "\n[physics]\nrate_hz = 4500\n")
    assert (
        "physics.rate_hz: value 4500 is out of range; "
        "expected a whole multiple of the control rate 1000 Hz" in msg
    )
    msg = _error(GOOD.replace("duration_s = 0.5", "duration_s = -0.5"))
    assert "intent[0].duration_s: value -0.5 is out of range; expected a number >= 0" in msg


def test_missing_field_is_named():
    msg = _error(GOOD.replace("duration_s = 1.0\n", ""))
    assert "bad.toml: duration_s: missing required field" in msg
    msg = _error(GOOD.replace("length = 0.08\n", ""))
    assert "mechanism.length: missing required field" in msg
    msg = _error(GOOD.replace("angle_deg = 10.0\n", ""))
    assert "intent[0].angle_deg: missing required field" in msg
    msg = _error(GOOD.replace('[mechanism]\ntype = "PlanarArm"\n', "[mechanism]\n"))
    assert "mechanism.type: missing required field; expected one of 'PlanarArm'" in msg
    msg = _error(GOOD.replace('[device]\ntype = "PhantomOmni"\n', ""))
    assert "device: missing required field" in msg or "device.type: missing required field" in msg


def test_not_toml_is_reported():
    msg = _error("name = \n")
    assert msg.startswith("bad.toml: not valid TOML")


def test_unknown_shipped_name_lists_the_known_ones():
    with pytest.raises(sc.ScenarioError, match="omni-fig10"):
        sc.load("omni-fig13")


def test_overrides_are_validated():
    s = sc.load("omni-fig10")
    assert s.with_overrides(duration_s=0.5).duration_s == 0.5
    assert s.with_overrides(sensors={"noise_rad": 1e-4})["sensors"]["noise_rad"] == 1e-4
    with pytest.raises(sc.ScenarioError, match="duration_s: value -1"):
        s.with_overrides(duration_s=-1.0)


def test_every_mistake_is_reported_at_once():
    text = GOOD.replace("length = 0.08", "length = -0.08").replace(
        "[device]", "[device]\nstifness = 3"
    )
    text += '\n[physics]\ngravity = "yes"\n'
    with pytest.raises(sc.ScenarioError) as e:
        sc.loads(text, "bad.toml")
    assert isinstance(e.value, ValueError)
    assert len(e.value.messages) == 3
    msg = str(e.value)
    for key in ("mechanism.length", "device.stifness", "physics.gravity"):
        assert f"bad.toml: {key}:" in msg


def test_directions_must_not_be_zero():
    msg = _error(GOOD.replace("length = 0.08", "length = 0.08\nnormal = [0.0, 0.0, 0.0]"))
    assert "mechanism.normal: value [0.0, 0.0, 0.0] is out of range; expected a non-zero" in msg


@pytest.mark.parametrize("name", ["../../escape", "/abs", "a/b", "a\\\\b", ".x", ""])
def test_names_are_plain_file_names(name):
    msg = _error(GOOD.replace('name = "t"', f'name = "{name}"'))
    assert "name: value" in msg and "expected a plain file name" in msg


def test_a_duration_shorter_than_a_control_period_is_rejected():
    msg = _error(GOOD.replace("duration_s = 1.0", "duration_s = 1e-9"))
    assert "duration_s: value 1e-09 is out of range; expected at least one control period" in msg


def test_defaults_are_not_shared_between_scenarios():
    a = sc.loads(GOOD)
    a["human"]["grip_contacts"].append(9.0)
    assert sc.loads(GOOD)["human"]["grip_contacts"] == [-0.015, -0.05]


def test_the_json_schema_has_every_default_of_the_format():
    schema = sc.json_schema()
    s = sc.loads(GOOD)
    for table in ("controller", "physics", "sensors", "human"):
        props = schema["properties"][table]["properties"]
        for key, value in s[table].items():
            if "default" in props[key]:
                assert props[key]["default"] == value, (table, key)


PROBE = GOOD.replace(
    'type = "PlanarArm"\npivot = [-0.07, 0.04, 0.0]\nlength = 0.08',
    'type = "Probe"\nplane_point = [0.0, -0.07, 0.0]\nplane_normal = NORMAL\nlength = 0.08',
)


@pytest.mark.parametrize(
    "normal",
    [
        [0.342, 0.940, 0.0],  # norm 1.00028: a unit vector written to three digits
        [1.0, 2.747, 0.0],
        [0.0, 3.0, 0.0],
        [1e-200, 0.0, 0.0],  # squares underflow
        [1e300, 1e300, -1e300],  # squares overflow
        [0, 2, 1],  # integers
    ],
)
def test_a_direction_of_any_length_is_read_as_its_unit_vector(normal):
    import numpy as np

    s = sc.loads(PROBE.replace("NORMAL", str(normal)))
    v = np.array(normal, dtype=float)
    expected = (v / np.abs(v).max()) / np.linalg.norm(v / np.abs(v).max())
    got = s["mechanism"]["plane_normal"]
    assert all(isinstance(x, float) for x in got)
    np.testing.assert_allclose(got, expected, rtol=0, atol=2e-16)
    assert abs(np.linalg.norm(got) - 1.0) < 3e-16
    assert s.raw["mechanism"]["plane_normal"] == normal  # the file's own numbers kept


def test_a_direction_along_an_axis_is_kept_exactly():
    for normal in ([0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [0.0, 5.0, 0.0]):
        s = sc.loads(PROBE.replace("NORMAL", str(normal)))
        assert s["mechanism"]["plane_normal"] == [0.0, normal[1] / abs(normal[1] or 1.0),
                                                   normal[2] / abs(normal[2] or 1.0)]


def test_the_core_accepts_a_direction_the_format_normalised():
    pytest.importorskip("mujoco")
    from virtmech.builder import make_mechanism

    s = sc.loads(PROBE.replace("NORMAL", "[0.342, 0.940, 0.0]"))
    probe = make_mechanism(s["mechanism"])  # the core requires |n| within 1e-6 of 1
    assert probe is not None


@pytest.mark.parametrize(
    ("bad", "index"), [("[nan, 1.0, 0.0]", 0), ("[0.0, inf, 0.0]", 1), ("[0.0, 1.0, -inf]", 2)]
)
def test_a_direction_that_is_not_finite_names_the_key(bad, index):
    with pytest.raises(sc.ScenarioError) as e:
        sc.loads(PROBE.replace("NORMAL", bad), "bad.toml")
    assert f"bad.toml: mechanism.plane_normal[{index}]: value" in str(e.value)
    assert "expected a number that is finite" in str(e.value)


def test_an_intents_axis_of_any_length_is_read_as_its_unit_vector():
    s = sc.loads(GOOD.replace('angle_deg = 10.0', 'angle_deg = 10.0\naxis = [0.0, 0.0, 2.0]'))
    assert s["intent"][0]["axis"] == [0.0, 0.0, 1.0]
    with pytest.raises(sc.ScenarioError) as e:
        sc.loads(GOOD.replace('angle_deg = 10.0', 'angle_deg = 10.0\naxis = [0, 0, 0]'), "b.toml")
    assert "b.toml: intent[0].axis: value [0, 0, 0] is out of range; expected a non-zero" in str(
        e.value
    )


WRENCH = GOOD.replace(
    'action = "twist"', 'action = "wrench"\nforce = FORCE\nmoment = MOMENT'
).replace("angle_deg = 10.0\n", "")


@pytest.mark.parametrize(
    ("force", "moment", "key", "bound"),
    [
        ("[0.0, -1e6, 0.0]", "[0.0, 0.0, 0.0]", "intent[0].force[1]", "100"),
        ("[0.0, 0.0, 0.0]", "[20.0, 0.0, 0.0]", "intent[0].moment[0]", "10"),
    ],
)
def test_an_intents_force_beyond_a_hands_is_refused_naming_the_key(force, moment, key, bound):
    with pytest.raises(sc.ScenarioError) as e:
        sc.loads(WRENCH.replace("FORCE", force).replace("MOMENT", moment), "bad.toml")
    msg = str(e.value)
    assert msg.startswith(f"bad.toml: {key}: value ") and "is out of range" in msg
    assert f">= -{bound} and <= {bound}" in msg
    # the largest allowed is accepted
    s = sc.loads(WRENCH.replace("FORCE", "[0.0, -100.0, 0.0]").replace("MOMENT", "[0, 0, 10]"))
    assert s["intent"][0]["force"] == [0.0, -100.0, 0.0]


RAGGED = """
name = "ragged"
duration_s = 1.0
[device]
type = "PhantomOmni"
[mechanism]
type = "SurfaceProbe"
[mechanism.surface]
type = "NurbsSurface"
control_points = [[[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], [[0.0, 0.1, 0.0]]]
degree_u = 1
degree_v = 1
"""


def test_ragged_nurbs_control_points_are_a_mistake_naming_the_key(tmp_path):
    pytest.importorskip("mujoco")
    import subprocess
    import sys

    from virtmech.builder import build

    with pytest.raises(sc.ScenarioError) as e:
        build(sc.loads(RAGGED, "ragged.toml"))
    msg = str(e.value)
    assert msg.startswith("ragged.toml: mechanism.surface.control_points: expected an array")
    assert "(n, m, 3)" in msg and "inhomogeneous" not in msg
    f = tmp_path / "ragged.toml"
    f.write_text(RAGGED)
    r = subprocess.run(
        [sys.executable, "-m", "virtmech", "run", str(f), "--out", str(tmp_path / "o")],
        capture_output=True, text=True, timeout=120,
    )
    assert r.returncode == 2, r.stderr
    assert "mechanism.surface.control_points" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()
