"""The one scenario builder: a validated scenario turned into everything a run needs.

    rig = build(scenario)                   # a simulated run: the device, the mechanism (or
                                            # the set), the controller, the start pose, the
                                            # hand, the sensors, the MuJoCo model and state
    rig = build(scenario, simulated=False)  # what a real device needs: no MuJoCo, no start

Every command that runs a scenario builds it here and nowhere else: ``virtmech run``,
``demo``, ``sweep`` and ``quality`` (through virtmech.runner), ``view`` (the live
simulation) and ``drive`` (a real device). A mistake in the scenario surfaces as a
ScenarioError naming its file and key (`built`).

The pieces, in the order they are built (each from its scenario table):

- ``[device]``  -> ``rig.device``          (a virtmech device)
- ``[mechanism]`` and ``[[set.members]]`` -> ``rig.mechanisms`` (member 0 first)
- ``[controller]`` -> ``rig.controller``  (member 0's) and ``rig.renderer`` (the controller,
  or a MechanismSet of every member with the same settings)
- ``[initial]`` -> ``rig.q0``             (the start pose, by the core's placement)
- ``[human]``, ``[sensors]``, ``[physics]`` -> ``rig.human``, ``rig.sensors``, ``rig.sim``
  (the MuJoCo model, its data at the start pose, the coupling, the gravity compensation)
- ``rig.servo_loop()``, ``rig.intent()``, ``rig.derived_columns()``, ``rig.info()``: the
  simulation loop over them, the hand's plan, the log's derived columns, run.json's
  description.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

import virtmech as vm

__all__ = [
    "Rig",
    "SimModel",
    "build",
    "built",
    "controller_kwargs",
    "make_device",
    "make_mechanism",
    "preflight",
]


# ---------------------------------------------------------------------------------------
# scenario tables -> core objects


def built(scenario, table: str, make: Callable[[], Any]) -> Any:
    """make(), a constructor's ValueError or TypeError (its message starts with the
    parameter's name: a value out of range, an array of the wrong shape) reported as a
    ScenarioError naming the scenario's file and key."""
    from .scenarios import ScenarioError

    try:
        return make()
    except (ValueError, TypeError) as e:
        msg = str(e)
        head, sep, rest = msg.partition(": ")
        head = head.strip()
        if sep and (head == table or head.startswith((table + ".", table + "["))):
            key, msg = head, rest
        elif sep and re.fullmatch(r"[A-Za-z_]\w*(\[\d+\])?", head):
            key, msg = f"{table}.{head}", rest
        else:
            key = table
        raise ScenarioError(f"{scenario.source}: {key}: {msg}") from None


def make_device(d: dict):
    """A vm device from a scenario's [device] table: its kind's parameters (virtmech.kinds;
    the MuJoCo model's keys aside)."""
    from .scenarios.format import DEVICE_PHYSICS

    return vm.make_device({k: v for k, v in d.items() if k not in DEVICE_PHYSICS})


def make_mechanism(m: dict):
    """A vm mechanism from a scenario's [mechanism] table (or a [[set.members]] entry): its
    kind's parameters (virtmech.kinds)."""
    return vm.make_mechanism(m)


def controller_kwargs(c: dict) -> dict:
    """vm.Controller's keyword arguments from a scenario's [controller] table (every row of
    the settings table the table holds: virtmech.CONTROLLER_SETTINGS)."""
    return {r["name"]: c[r["name"]] for r in vm.CONTROLLER_SETTINGS if r["name"] in c}


def _renderer(S: dict, device, controller, mechanisms: list, kw: dict | None = None):
    """The controller itself, or with [[set.members]] a vm.MechanismSet of every mechanism
    (member 0: the [mechanism]), each with the [controller] settings (or vm.Controller's
    keywords `kw`)."""
    if len(mechanisms) == 1:
        return controller
    st = S["set"]
    settings = {r["name"]: st[r["name"]] for r in vm.SET_SETTINGS if r["name"] in st}
    s = vm.MechanismSet(device, len(mechanisms), period_s=S["controller"]["period_s"], **settings)
    s.add(controller)
    kw = controller_kwargs(S["controller"]) if kw is None else kw
    for mech in mechanisms[1:]:
        s.add(vm.Controller(device, mech, **kw))
    return s


# ---------------------------------------------------------------------------------------
# the rig


@dataclass
class SimModel:
    """The MuJoCo side of a simulated run: the physical parameters, the MJCF and its compiled
    model and data (at the start pose), the coupling s = C q + c0 of device and chain
    coordinates, and what the simulated driver compensates."""

    phys: Any  # virtmech.sim.model.DeviceModel
    built: Any  # virtmech.sim.model.BuiltModel
    model: Any  # mujoco.MjModel
    data: Any  # mujoco.MjData
    substeps: int
    gravity: np.ndarray  # the world's gravity as the model has it [m/s^2] (zero: off)
    gravity_world: np.ndarray  # the device's world gravity, for the compensation
    gravity_compensation: bool
    comp_bodies: list[int]  # the device's bodies whose weight the motors carry
    hand_body: int

    @property
    def coupling(self):
        return self.built.coupling


@dataclass
class Rig:
    """Everything a run of one scenario needs (see the module's docstring)."""

    scenario: Any
    seed: int
    device: Any
    mechanisms: list
    controller: Any
    renderer: Any
    period_s: float
    human: Any = None  # virtmech.sim.human.HandImpedance
    sensors: Any = None  # virtmech.sim.sensors.SensorSettings
    q0: np.ndarray | None = None
    sim: SimModel | None = None
    columns: list[str] = field(default_factory=list)

    @property
    def mechanism(self):
        """The [mechanism] (member 0 of a set)."""
        return self.mechanisms[0]

    @property
    def is_set(self) -> bool:
        return len(self.mechanisms) > 1

    @property
    def width(self) -> int:
        """The log's theta columns: the largest member's joints."""
        return max(m.dof for m in self.mechanisms)

    @property
    def data(self) -> dict:
        return self.scenario.data

    # -- variants ------------------------------------------------------------------------

    def with_controller(self, **settings: Any) -> Rig:
        """The same rig (device, mechanisms, MuJoCo model and state) with a new controller
        and renderer: the scenario's [controller] settings with `settings` changed (vm.
        Controller's keywords). A ValueError names the setting the controller refuses."""
        from dataclasses import replace

        c = {**self.data["controller"]}
        kw = {**controller_kwargs(c), **settings}
        controller = vm.Controller(self.device, self.mechanism, **kw)
        S = {**self.data, "controller": {**c, **kw}}
        return replace(
            self, controller=controller,
            renderer=_renderer(S, self.device, controller, self.mechanisms, kw),
        )

    # -- simulation ----------------------------------------------------------------------

    def reset_state(self) -> None:
        """The MuJoCo state at the start pose, at rest."""
        import mujoco

        sim, cp = self._sim(), self._sim().coupling
        sim.data.qpos[:] = cp.C @ self.q0 + cp.c0
        sim.data.qvel[:] = 0.0
        mujoco.mj_forward(sim.model, sim.data)

    def servo_loop(self, sensors=None, renderer=None):
        """The C++ simulation loop (virtmech.sim.inner.ServoLoop) over the rig's renderer
        (or `renderer`), model and data, with the rig's sensor settings (or `sensors`)."""
        from .sim import inner

        sim = self._sim()
        comp = sim.comp_bodies if sim.gravity_compensation else []
        act_idx = np.flatnonzero(np.asarray(self.device.actuated, dtype=bool))
        return inner.ServoLoop(
            controller=self.renderer if renderer is None else renderer,
            model=sim.model,
            data=sim.data,
            coupling_inv=sim.coupling.Cinv,
            coupling_offset=sim.coupling.c0,
            actuated=[int(i) for i in act_idx],
            substeps=sim.substeps,
            period_s=self.period_s,
            comp_bodies=[int(b) for b in comp],
            comp_masses=[float(sim.model.body_mass[b]) for b in comp],
            gravity=sim.gravity_world,
            sensors=self.sensors if sensors is None else sensors,
            hand_body=sim.hand_body,
            log_columns=self.columns,
        )

    def intent(self):
        """The hand's plan from the scenario's [[intent]] timeline, from the start pose."""
        from .sim.human import Intent

        S = self.data
        return built(
            self.scenario,
            "intent",
            lambda: Intent(
                S["intent"], self.human, self.mechanism, self.device.forward(self.q0),
                self.period_s,
            ),
        )

    def derived_columns(self):
        """The log's columns that follow from each row alone (virtmech.sim.log)."""
        from .sim.log import DerivedColumns

        return DerivedColumns(
            self.columns, self.mechanisms, self.data["human"]["grip_contacts"]
        )

    def info(self, human: dict | None = None, sensors=None) -> dict:
        """run.json's description of the run (the hand's and the sensors' settings as given,
        where they changed since the build)."""
        from .sim.log import versions

        sim = self._sim()
        members = [m.to_dict() for m in self.mechanisms]
        info: dict[str, Any] = {
            "device": self.device.to_dict(),
            "device_physics": sim.phys.to_dict(),
            "mechanism": members[0],
        }
        if self.is_set:
            info["set_members"] = members
            info["set"] = dict(self.data["set"], members=len(members))
        info.update(
            {
                "controller_model": {
                    k: (v.tolist() if isinstance(v, np.ndarray) else v)
                    for k, v in self.controller.model.items()
                },
                "human": {**self.human.to_dict(), **(human or {})},
                "grip_contacts": list(self.data["human"]["grip_contacts"]),
                "sensors": (self.sensors if sensors is None else sensors).to_dict(),
                "physics": {
                    "timestep_s": self.period_s / sim.substeps,
                    "substeps": sim.substeps,
                    "gravity": sim.gravity.tolist(),
                    "gravity_compensation": sim.gravity_compensation,
                    "integrator": "implicitfast",
                    "engine": "compiled",
                },
                "initial_q": self.q0.tolist(),
                "seed": self.seed,
                "versions": versions(),
                "mjcf": sim.built.xml,
            }
        )
        return info

    def _sim(self) -> SimModel:
        if self.sim is None:
            raise RuntimeError("the rig was built with simulated=False: it has no simulation")
        return self.sim


def _sim_model(scenario, rig: Rig) -> SimModel:
    import mujoco

    from .sim.model import HandBody, build_mjcf, compile_model, device_physics, world_gravity

    S = scenario.data
    device, human = rig.device, rig.human
    phys = device_physics(S["device"])
    gravity_on = S["physics"]["gravity"]
    g_world = world_gravity(device)
    gravity = g_world if gravity_on else np.zeros(3)
    substeps = int(round(S["physics"]["rate_hz"] * rig.period_s))
    mjcf = build_mjcf(
        device,
        params=phys,
        hand=HandBody(human.mass_kg, human.inertia),
        gravity=gravity,
        timestep=rig.period_s / substeps,
    )
    model = compile_model(mjcf)
    body = lambda name: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)  # noqa: E731
    return SimModel(
        phys=phys,
        built=mjcf,
        model=model,
        data=mujoco.MjData(model),
        substeps=substeps,
        gravity=gravity,
        gravity_world=g_world,
        gravity_compensation=bool(gravity_on and S["physics"]["gravity_compensation"]),
        comp_bodies=[body(b) for b in mjcf.device_bodies],
        hand_body=body("hand"),
    )


def _rendering(scenario) -> tuple:
    """The device, the mechanisms, member 0's controller and the renderer."""
    S = scenario.data
    device = built(scenario, "device", lambda: make_device(S["device"]))
    mechanism = built(scenario, "mechanism", lambda: make_mechanism(S["mechanism"]))
    controller = built(
        scenario,
        "controller",
        lambda: vm.Controller(device, mechanism, **controller_kwargs(S["controller"])),
    )
    members = (S.get("set") or {}).get("members") or []
    mechanisms = [mechanism] + [
        built(scenario, "set", lambda m=m: make_mechanism(m)) for m in members
    ]
    renderer = built(scenario, "set", lambda: _renderer(S, device, controller, mechanisms))
    return device, mechanisms, controller, renderer


def build(scenario, seed: int | None = None, simulated: bool = True) -> Rig:
    """Everything a run of `scenario` (a Scenario, a shipped name or a TOML path) needs; see
    the module's docstring. `seed` overrides the scenario's. simulated=False: the
    rendering only (device, mechanisms, controller, renderer, hand and sensor settings), for
    a real device; no MuJoCo is imported."""
    from . import scenarios as sc
    from .sim.human import HandImpedance
    from .sim.log import log_columns
    from .sim.sensors import SensorSettings
    from .sim.start import initial_joints

    if not isinstance(scenario, sc.Scenario):
        scenario = sc.load(scenario)
    S = scenario.data
    device, mechanisms, controller, renderer = _rendering(scenario)
    rig = Rig(
        scenario=scenario,
        seed=S["seed"] if seed is None else int(seed),
        device=device,
        mechanisms=mechanisms,
        controller=controller,
        renderer=renderer,
        period_s=float(S["controller"]["period_s"]),
        human=HandImpedance(**{k: S["human"][k] for k in HandImpedance().to_dict()}),
        sensors=SensorSettings(**S["sensors"]),
    )
    rig.columns = log_columns(device.dof, rig.width)
    if not simulated:
        return rig
    rig.q0 = built(scenario, "initial", lambda: initial_joints(S, device, rig.mechanism))
    rig.sim = _sim_model(scenario, rig)
    rig.reset_state()
    return rig


def preflight(scenario) -> None:
    """What a run checks before it simulates, without simulating: the device, the
    mechanisms, the controller (and set) built, the start pose reached and the hand's plan
    made from it ([[intent]]); the same ScenarioError naming the file and the key as a run
    would raise (virtmech sweep checks every point of a grid so before any run starts)."""
    from .sim.start import initial_joints

    rig = build(scenario, simulated=False)
    rig.q0 = built(scenario, "initial", lambda: initial_joints(rig.data, rig.device, rig.mechanism))
    rig.intent()
