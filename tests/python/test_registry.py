"""The registry of kinds: each kind of mechanism, device and shape is one entry in the core
(src/kinds/), whose parameters make the Python constructors, the scenario format and the
objects of a scenario file, whose describe() is to_dict(), and whose distance measure,
constrained directions and sketch the log, the quality measures and the viewer use. The
distances and directions are checked against NumPy written from their definitions
(tests/reference/distances.py), on random handle poses with fixed seeds."""

from __future__ import annotations

import ctypes.util

import numpy as np
import pytest

import virtmech as vm
from reference import distances as ref


def letter():
    return vm.NurbsCurve([[0, 0, 0], [0.02, 0.03, 0], [0.05, 0.0, 0.01], [0.07, 0.02, 0]],
                         [1, 2, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1], 3)


def patch():
    P = np.array([[[0.04 * i, 0.04 * j, 0.01 * np.sin(i + j)] for j in range(4)]
                  for i in range(4)])
    return vm.NurbsSurface(P, np.ones((4, 4)), [0, 0, 0, 0, 1, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1],
                           3, 3)


TILTED = np.array([0.2, 0.1, 0.97]) / np.linalg.norm([0.2, 0.1, 0.97])


def rotated(p, w) -> np.ndarray:
    """The pose (4, 4) at position p turned by the rotation vector w."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = vm.so3_exp(w), p
    return T


def same(a, b) -> bool:
    """Equal descriptions: the same keys, numbers equal to rounding (a direction given again
    is normalised again)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and a and isinstance(a[0], dict):  # tables (a chain's joints)
        return isinstance(b, list) and len(a) == len(b) and all(map(same, a, b))
    if isinstance(a, (list, float)):
        return np.allclose(a, b, rtol=1e-15, atol=1e-15)
    return a == b


MECHANISMS = {
    "arm": lambda: vm.PlanarArm([0.01, -0.02, 0.03], TILTED, 0.06),
    "probe": lambda: vm.Probe([0, 0, -0.02], [0, 0, 1], 0.08),
    "probe-unilateral": lambda: vm.Probe([0, 0, -0.02], [0, 0.6, 0.8], 0.08, unilateral=True),
    "pivot": lambda: vm.PointPivot([0, 0.01, -0.03], [0, 0, 1], 0.07),
    "pivot-unilateral": lambda: vm.PointPivot([0, 0.01, -0.03], [0, 0, 1], 0.07,
                                              unilateral=True),
    "trocar": lambda: vm.PointPivot([0, 0.01, -0.03], [0, 0, 1], 0.07, insertion=True),
    "line": lambda: vm.LineGuide([0, -0.05, 0], [1, 0, 0], 0.08, [0, 1, 0]),
    "line-unilateral": lambda: vm.LineGuide([0, -0.05, 0], [0.6, 0.8, 0], 0.08, [0, 0, 1],
                                            True),
    "surface": lambda: vm.SurfaceProbe(patch(), 0.06),
    "sphere-unilateral": lambda: vm.SurfaceProbe(vm.Sphere([0, 0, -0.1], 0.05), 0.06, True),
    "curve": lambda: vm.CurveGuide(letter(), 0.07, [0, 0, 1]),
    "path": lambda: vm.HandlePath(letter(), [0, 1, 0]),
}

#: a kind without a distance measure or constrained directions of its own
CHAINS = {
    "chain": lambda: vm.SerialChain(
        [vm.Joint("revolute", [0, 0, 1], lower=-2.0, upper=2.5),
         vm.Joint("prismatic", [1, 0, 0], rotated([0.1, 0.02, 0.05], [0.3, -0.2, 0.4]))],
        handle=rotated([0.0, 0.0, 0.08], [3.0, 0.1, 0.0]),
        base=rotated([0.01, -0.02, 0.1], [0.0, 0.5, 0.0]), length_scale=0.07),
}


def reference_distances(m, p, s):
    d = m.to_dict()
    t = d["type"]
    if t == "PlanarArm":
        return ref.planar_arm(d, p, s)
    if t == "Probe":
        return ref.probe(d, p, s)
    if t == "PointPivot":
        return ref.point_pivot(d, p, s)
    if t == "LineGuide":
        return ref.line_guide(d, p, s)
    if t == "SurfaceProbe":
        return ref.surface_probe(d, p, s, m.surface)
    if t == "CurveGuide":
        return ref.from_curve(d, p + d["length"] * s, m.curve)
    return ref.from_curve(d, p, m.curve)


def random_handles(n: int, seed: int):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-0.12, 0.12, (n, 3))
    s = rng.normal(size=(n, 3))
    return p, s / np.linalg.norm(s, axis=1)[:, None]


@pytest.mark.parametrize("name", sorted(MECHANISMS))
def test_distances_are_the_definitions(name):
    m = MECHANISMS[name]()
    p, s = random_handles(300, seed=len(name))
    got = vm.distances(m, p, s, np.zeros_like(p))
    expected = np.stack(reference_distances(m, p, s), axis=1)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_a_kind_without_a_measure_reports_the_placements_error():
    chain = vm.SerialChain([vm.Joint("revolute", [0, 0, 1]), vm.Joint("prismatic", [1, 0, 0])])
    p, s = random_handles(5, seed=1)
    e = np.random.default_rng(2).normal(size=(5, 3))
    d = vm.distances(chain, p, s, e)
    np.testing.assert_allclose(d[:, 0], np.linalg.norm(e, axis=1), rtol=1e-15)
    np.testing.assert_array_equal(d[:, 0], d[:, 1])
    assert np.isnan(d[:, 2:]).all()


@pytest.mark.parametrize("name", sorted(MECHANISMS))
def test_constrained_directions_are_the_definitions(name):
    m = MECHANISMS[name]()
    at = np.array([0.03, -0.01, 0.02])
    shape = getattr(m, "surface", None) or getattr(m, "curve", None)
    expected = ref.constrained(m.to_dict(), at, shape)
    got = vm.constrained_directions(m, at)
    assert list(got) == list(expected)
    for k in expected:
        np.testing.assert_allclose(got[k], expected[k], atol=1e-14)
        assert abs(np.linalg.norm(got[k]) - 1.0) < 1e-14


@pytest.mark.parametrize("name", sorted(MECHANISMS) + sorted(CHAINS))
def test_to_dict_rebuilds_the_mechanism_through_its_kind(name):
    m = {**MECHANISMS, **CHAINS}[name]()
    d = m.to_dict()
    kind = next(k for k in vm.kinds("mechanism") if k["name"] == d["type"])
    assert list(d) == ["type"] + [p["name"] for p in kind["params"]]
    rebuilt = vm.make_mechanism(d)
    assert type(rebuilt) is type(m) and same(rebuilt.to_dict(), d)
    x = np.asarray(m.home) + 0.05
    np.testing.assert_allclose(rebuilt.forward(x), m.forward(x), rtol=0, atol=1e-15)


def test_shapes_and_devices_describe_themselves_with_their_kinds_keys():
    for shape in (letter(), patch(), vm.Sphere([0, 0, 0], 0.1, axis=[1, 0, 0]),
                  vm.Cylinder([0, 0, 0], [0, 1, 0], 0.05), vm.Plane([0, 0, 0.1], [0, 0, 2])):
        d = shape.to_dict()
        assert same(vm.make_shape(d).to_dict(), d)
    omni = vm.PhantomOmni(l1=0.14)
    assert omni.to_dict()["l1"] == 0.14 and omni.l1 == 0.14


DEVICES = {
    "omni": lambda: vm.PhantomOmni(l1=0.14),
    "planar3r": lambda: vm.Planar3R(0.25, 0.15, base=rotated([0.1, 0.0, -0.05], [0.0, 0.0, 0.7])),
    "cartesian": lambda: vm.make_device({"type": "CartesianDevice", "model": "omega.6"}),
    # no limits given: the description leaves them out, as the scenario format does
    "chain-unlimited": lambda: vm.Device([vm.Joint("revolute", [0, 0, 1])], [True]),
    # uncoupled: the device's joint limits are its chain's
    "chain-limited": lambda: vm.Device(
        [vm.Joint("revolute", [0, 0, 1], lower=-2.0, upper=2.0),
         vm.Joint("prismatic", [1, 0, 0], [0.0, 0.0, 0.1], -0.05, 0.05)],
        [True, False], torque_limit=[3.0, 0.0], max_force=8.0),
    "chain-coupled": lambda: vm.Device(
        [vm.Joint("revolute", [0, 0, 1], lower=-2.0, upper=2.0),
         vm.Joint("revolute", [0, 1, 0], rotated([0.0, 0.0, 0.1], [0.2, 0.0, 0.0]), -1.5, 1.5),
         vm.Joint("prismatic", [0, 0, 1], [0.1, 0.0, 0.0], 0.0, 0.05)],
        [True, True, False], handle=rotated([0.0, 0.0, 0.05], [0.0, 0.3, 0.0]),
        base=rotated([0.0, 0.1, 0.2], [0.1, 0.2, 0.3]), torque_limit=[1.5, 2.0, 0.0],
        max_force=4.0, max_torque=0.5, name="coupled", coupling=[[1, 0, 0], [-1, 1, 0], [0, 0, 1]],
        coupling_offset=[0.0, 0.2, 0.0]),
}


@pytest.mark.parametrize("name", sorted(DEVICES))
def test_to_dict_rebuilds_the_device_through_its_kind(name):
    """A device's description (run.json's) is its kind's parameters, in the kind's order, from
    which make_device rebuilds the same device: the same kinematics, limits and actuation."""
    dev = DEVICES[name]()
    d = dev.to_dict()
    kind = next(k for k in vm.kinds("device") if k["name"] == d["type"])
    names = [p["name"] for p in kind["params"]]
    assert list(d)[1:] == [k for k in names if k in d]
    rebuilt = vm.make_device(d)
    assert type(rebuilt) is type(dev) and same(rebuilt.to_dict(), d)
    q = (np.asarray(dev.lower).clip(-1, 1) + np.asarray(dev.upper).clip(-1, 1)) / 2 + 0.01
    np.testing.assert_allclose(rebuilt.forward(q), dev.forward(q), rtol=0, atol=1e-15)
    for limit in ("lower", "upper", "home", "actuated", "max_velocity"):
        np.testing.assert_array_equal(getattr(rebuilt, limit), getattr(dev, limit), err_msg=limit)
    np.testing.assert_array_equal(rebuilt.torque_limit, dev.torque_limit)
    assert (rebuilt.max_force, rebuilt.max_torque) == (dev.max_force, dev.max_torque)


def test_a_torque_limit_is_never_left_out_of_a_description():
    """One joint's limit given, the other's not: a description cannot hold the missing one
    (JSON has no inf, the kind no "none" per joint), so the constructor refuses the device,
    naming the parameter, rather than make one whose run.json drops a limit."""
    with pytest.raises(ValueError, match=r"torque_limit: .*got inf"):
        vm.Device([vm.Joint("revolute", [0, 0, 1]), vm.Joint("revolute", [0, 1, 0])],
                  [True, True], torque_limit=[1.5, np.inf])
    both = vm.Device([vm.Joint("revolute", [0, 0, 1]), vm.Joint("revolute", [0, 1, 0])],
                     [True, True], torque_limit=[1.5, 2.5])
    np.testing.assert_array_equal(vm.make_device(both.to_dict()).torque_limit, [1.5, 2.5])


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: vm.Device([vm.Joint("revolute", [0, 0, 1])], [True], max_force=5000.0),
         r"^max_force: expected a number > 0 and <= 1000 \[N\], got 5000$"),
        (lambda: vm.Device([vm.Joint("revolute", [0, 0, 1], lower=-2000.0)], [True]),
         r"^joints\[0\]\.lower: expected .*<= 1000 .*got -2000$"),
        (lambda: vm.Device([vm.Joint("revolute", [0, 0, 1])], [True], stiffness=2e6),
         r"^stiffness: expected .*<= 1e\+06 .*got 2e\+06$"),
        (lambda: vm.Planar3R(5.0, 0.2), r"^link1: expected .*<= 2 \[m\], got 5$"),
        (lambda: vm.Planar3R(0.2, 0.2, max_force=3000.0), r"^max_force: .*got 3000$"),
        (lambda: vm.SerialChain([vm.Joint("revolute", [0, 0, 1])], length_scale=50.0),
         r"^length_scale: expected a number > 0 and <= 10 \[m\], got 50$"),
    ],
    ids=["device-force", "device-joint-limit", "device-stiffness", "planar3r-link",
         "planar3r-force", "chain-length-scale"],
)
def test_a_python_constructor_refuses_what_its_kind_refuses(make, message):
    """Device, Planar3R and SerialChain take C++'s arguments, not their kinds' tables, but the
    ranges are the kinds' (one source): a value a scenario file may not hold is refused here
    too, naming the parameter and the value, so every object made rebuilds from run.json."""
    with pytest.raises(ValueError, match=message):
        make()


def test_sketches_draw_the_mechanism_where_it_is():
    arm = MECHANISMS["arm"]()
    s = vm.sketch(arm)
    circle = s["lines"][0]
    d = arm.to_dict()
    w = circle - np.asarray(d["pivot"])
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), d["length"], rtol=1e-12)
    np.testing.assert_allclose(w @ np.asarray(d["normal"]), 0.0, atol=1e-15)
    assert np.allclose(s["points"], [d["pivot"]])
    vertices, faces = vm.sketch(MECHANISMS["surface"]())["meshes"][0]
    assert faces.max() < len(vertices) and len(faces) == 2 * 31 * 31
    # a kind without a sketch of its own: the handle's path as joint 0 sweeps its range
    handle = np.eye(4)
    handle[0, 3] = 0.1
    chain = vm.SerialChain([vm.Joint("revolute", [0, 0, 1])], handle=handle)
    path = vm.sketch(chain)["lines"][0]
    np.testing.assert_allclose(np.linalg.norm(path[:, :2], axis=1), 0.1, rtol=1e-12)


def test_tables_make_objects_and_mistakes_name_the_key():
    m = vm.make_mechanism({"type": "SurfaceProbe", "length": 0.05,
                           "surface": {"type": "Sphere", "center": [0, 0, 0], "radius": 0.1}})
    assert isinstance(m, vm.SurfaceProbe) and isinstance(m.surface, vm.Sphere)
    with pytest.raises(ValueError, match=r"^mechanism\.pivot: expected an array of shape \(3,\)"):
        vm.make_mechanism({"type": "PlanarArm", "pivot": [0, 0], "length": 0.1})
    with pytest.raises(ValueError, match=r"^mechanism\.length: expected a number > 0"):
        vm.make_mechanism({"type": "PlanarArm", "pivot": [0, 0, 0], "length": -0.1})
    with pytest.raises(ValueError, match=r"^mechanism\.type: expected 'PlanarArm', .*got 'Arm'"):
        vm.make_mechanism({"type": "Arm"})
    with pytest.raises(ValueError, match=r"^mechanism\.surface\.radius: expected a number > 0"):
        vm.make_mechanism({"type": "SurfaceProbe",
                           "surface": {"type": "Sphere", "center": [0, 0, 0], "radius": 0}})
    with pytest.raises(ValueError, match=r"^mechanism\.colour: unknown parameter; expected one"):
        vm.make_mechanism({"type": "Probe", "plane_point": [0, 0, 0], "plane_normal": [0, 0, 1],
                           "length": 0.1, "colour": "red"})


def test_a_chain_mechanism_and_devices_from_tables():
    joints = [{"type": "revolute", "axis": [0, 0, 1]},
              {"type": "prismatic", "axis": [1, 0, 0], "origin": [0.1, 0, 0], "lower": 0.0}]
    chain = vm.make_mechanism({"type": "SerialChain", "joints": joints})
    assert chain.joint_types == ["revolute", "prismatic"] and chain.lower[1] == 0.0
    np.testing.assert_allclose(chain.forward([0.0, 0.02])[:3, 3], [0.12, 0, 0], atol=1e-15)
    full = vm.make_device({"type": "PhantomOmni", "actuated": [True] * 6})
    omni = vm.PhantomOmni()
    assert full.name == "PhantomOmni" and full.actuated.all()
    q = np.array([0.1, 0.4, 0.3, 0.2, -0.5, 0.7])
    np.testing.assert_allclose(full.forward(q), omni.forward(q), atol=1e-14)
    assert list(full.torque_limit) == [0.44, 0.44, 0.44, 0.1, 0.1, 0.1]
    assert vm.make_device({"type": "PhantomOmni"}).to_dict() == omni.to_dict()
    with pytest.raises(TypeError, match="another class"):
        vm.PhantomOmni(actuated=[True] * 6)


def test_python_constructors_are_the_kinds_parameters():
    arm = vm.PlanarArm(pivot=[0, 0, 0], length=0.1)  # normal: its kind's default
    assert list(arm.normal) == [0, 0, 1]
    assert vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.1).to_dict() == arm.to_dict()
    with pytest.raises(TypeError, match="unexpected keyword argument 'radius'"):
        vm.PlanarArm([0, 0, 0], length=0.1, radius=1)
    with pytest.raises(TypeError, match="multiple values for argument 'length'"):
        vm.PlanarArm([0, 0, 0], [0, 0, 1], 0.1, length=0.2)
    with pytest.raises(TypeError, match="pivot"):
        vm.PlanarArm(length=0.1)


def test_plugins_that_cannot_be_loaded_are_refused_naming_the_path(tmp_path):
    with pytest.raises(ValueError, match="no-such.so: no such plugin file"):
        vm.load_plugin(str(tmp_path / "no-such.so"))
    text = tmp_path / "text.so"
    text.write_text("not a library")
    with pytest.raises(ValueError, match="text.so: cannot be loaded as a plugin"):
        vm.load_plugin(str(text))
    libm = ctypes.util.find_library("m")
    if libm:  # a library, but no plugin
        import subprocess

        path = subprocess.run(["sh", "-c", f"ldconfig -p | grep -m1 '{libm}' | sed 's/.*=> //'"],
                              capture_output=True, text=True).stdout.strip()
        if path:
            with pytest.raises(ValueError, match="not a virtmech plugin"):
                vm.load_plugin(path)
