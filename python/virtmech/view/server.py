"""`virtmech view`: the viser server, its controls and plots, the simulation or replay
behind it, and the state endpoint.

Threads: viser's (the web server and its callbacks), the simulation's (virtmech.view.live.
Pacer: control cycles against the wall clock), the view's (scene and plots at `fps`), and
the state endpoint's (a small http.server on `state_port`, by default the viewer's port
+ 1, answering GET /state with `ViewServer.state()` as JSON). Controls never touch the
simulation directly: they queue a call that the simulation's thread runs between two
stretches of cycles.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import math
import socket
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..jsonable import jsonable
from .live import LAWS, LiveSim, Pacer, Settings
from .scene import Scene, camera_for, rot_of, up_of, wxyz_of

#: the gizmo's size [m]
GIZMO_SCALE = 0.05
#: the camera's vertical field of view [rad]
FOV = math.radians(45.0)
#: playback speeds offered in replay
SPEEDS = ("0.1", "0.25", "0.5", "1", "2", "4")


def check_port(host: str, port: int, label: str | None = None) -> None:
    """A UserError starting with `label` (default "--port PORT") unless `port` can be
    bound on `host` now."""
    label = label or f"--port {port}"
    if not 1 <= port <= 65535:
        raise UserError(f"{label}: expected a port number 1 to 65535")
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind((host, port))
    except OSError as e:
        # the host is at fault where it does not resolve or is no address of this machine
        if isinstance(e, socket.gaierror) or e.errno == errno.EADDRNOTAVAIL:
            raise UserError(
                f"--host {host}: cannot listen on it ({e.strerror or e}); expected an address "
                "of this machine (127.0.0.1: this machine only; 0.0.0.0: every interface)"
            ) from None
        raise UserError(
            f"{label}: cannot listen on {host}:{port} ({e.strerror or e}); expected a free port"
        ) from None


class _StateHandler(BaseHTTPRequestHandler):
    viewer: ViewServer  # set on the subclass made per server

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        if self.path.split("?")[0].rstrip("/") not in ("/state", ""):
            self.send_error(404, "GET /state")
            return
        body = json.dumps(jsonable(self.viewer.state(), infinity="null")).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Access-Control-Allow-Origin", "*")
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args) -> None:  # quiet
        pass


class ViewServer:
    """The viewer: `source` a scenario (a shipped name or a TOML file: live simulation), a
    folder written by `virtmech run` (replay), or a virtmech.view.device.DeviceFeed (a
    driven device, followed live). `start()` serves it on http://host:port;
    `state()` is what GET http://host:state_port/state answers; `stop()` ends it."""

    def __init__(
        self,
        source: str | Path,
        *,
        port: int = 8080,
        host: str = "127.0.0.1",
        state_port: int | None = None,
        fps: float = 30.0,
        record_dir: str | Path = "out/view",
        seed: int | None = None,
    ):
        from .device import DeviceFeed
        from .replay import Replay, is_log_dir

        self.source = str(source)
        self.host, self.port = host, int(port)
        self.state_port = self.port + 1 if state_port is None else int(state_port)
        self.fps = float(fps)
        self.record_dir = Path(record_dir)
        self.replay: Replay | None = None
        self.pacer: Pacer | None = None
        if isinstance(source, DeviceFeed):  # a driven device (virtmech drive --view)
            self.mode = "device"
            self.replay = source
            self.name = source.name
            self.source = f"device: {source.name}"
        elif is_log_dir(source):
            self.mode = "replay"
            self.replay = Replay(source)
            self.name = self.replay.name
        else:
            self.mode = "live"
            sim = LiveSim(source, seed=seed)  # a ScenarioError (UserError) if it is wrong
            self.pacer = Pacer(sim)
            self.pacer.on_error = lambda e: self._note(f"failed: {e}")
            self.name = sim.scenario.name
        self.server = None
        self._http: ThreadingHTTPServer | None = None
        self._stop = threading.Event()
        self._view_thread: threading.Thread | None = None
        self._scene: Scene | None = None
        self._scene_sim = None  # the LiveSim the scene was built for
        self._guard = False  # True while the code sets GUI values (no callbacks)
        self._pending_settings: Settings | None = None
        self._frame_times: list[float] = []
        self.frame_rate = 0.0
        self._gui: dict = {}
        self._gizmo = None
        self._R0 = np.eye(3)  # the handle's orientation when the gizmo was centred
        self.camera: dict = {}
        # replay
        self.play_t = 0.0
        self.playing = False
        self.speed = 1.0
        self.recording: str | None = None
        self.messages: list[str] = []

    # -------------------------------------------------------------------------------------
    # life

    def start(self) -> ViewServer:
        import viser

        check_port(self.host, self.port)
        handler = type("Handler", (_StateHandler,), {"viewer": self})
        try:
            self._http = ThreadingHTTPServer((self.host, self.state_port), handler)
        except OSError as e:
            raise UserError(
                f"--state-port {self.state_port}: cannot listen on {self.host}:"
                f"{self.state_port} ({e.strerror or e}); expected a free port"
            ) from None
        self._http.daemon_threads = True
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # viser's banner: we print ours
                self.server = viser.ViserServer(host=self.host, port=self.port, verbose=False)
            if self.server.get_port() != self.port:  # viser moved on: the port was taken
                raise UserError(f"--port {self.port}: the port was taken; expected a free port")
            self.server.gui.configure_theme(control_width="medium", show_share_button=False)
            self.server.gui.main_panel.dock_right()  # beside the 3-D view, not over it
            # no shadows: most of the cost of a frame in a software-rendered browser
            self.server.scene.configure_default_lights(enabled=True, cast_shadow=False)
            # no environment map either (its filtering is slow there too): ambient light
            self.server.scene.configure_environment_map(hdri=None)
            self.server.scene.add_light_ambient("/light/ambient", intensity=1.2)
            self._build_gui()
            self._build_scene()
        except BaseException:
            self._http.server_close()
            self._http = None
            if self.server is not None:
                self.server.stop()
                self.server = None
            raise
        threading.Thread(
            target=self._http.serve_forever, name="virtmech-view-state", daemon=True
        ).start()
        if self.pacer is not None:
            self.pacer.start()
        self._view_thread = threading.Thread(
            target=self._view_loop, name="virtmech-view", daemon=True
        )
        self._view_thread.start()
        return self

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    @property
    def state_url(self) -> str:
        return f"http://{self.host}:{self.state_port}/state"

    def stop(self) -> None:
        """Stops the simulation (a recording under way is written), the view, the state
        endpoint and viser's server; a second call does nothing."""
        self._stop.set()
        if self.pacer is not None:
            self.pacer.stop()
            rec = self.pacer.sim.stop_recording()
            if rec is not None:
                rec.finish()
        if self._view_thread is not None:
            self._view_thread.join(timeout=5)
            self._view_thread = None
        http, self._http = self._http, None
        if http is not None:
            http.shutdown()
            http.server_close()
        server, self.server = self.server, None
        if server is not None:
            with contextlib.redirect_stdout(io.StringIO()):  # viser's "Server stopped"
                server.stop()

    # -------------------------------------------------------------------------------------
    # state

    @property
    def sim(self) -> LiveSim | None:
        return self.pacer.sim if self.pacer is not None else None

    def frame(self) -> dict:
        """The current frame (the simulation's last snapshot, or the replay's frame)."""
        if self.replay is not None:
            return self.replay.frame(self.play_t)
        sim = self.sim
        with sim.lock:
            return sim.snapshot

    def state(self) -> dict:
        """Handle pose, target pose, the commanded wrench and its parts, the placements, sim
        time, real-time factor, frame rate and the settings (JSON-able)."""
        f = self.frame()
        T = f["handle"]
        tR = f["target_R"]
        out = {
            "mode": self.mode,
            "source": self.source,
            "scenario": self.name,
            "t": f["t"],
            "cycles": f["cycles"],
            "handle": {
                "position": T[:3, 3],
                "wxyz": wxyz_of(T[:3, :3]),
                "stylus": T[:3, 2],
            },
            "target": {
                "position": f["target_p"],
                "wxyz": None if tR is None else wxyz_of(tR),
            },
            "wrench": f["wrench"],
            "wrench_null": f["wrench_null"],
            "wrench_range": f["wrench_range"],
            "mechanism_pose": f["mechanism_pose"],
            "mechanism_pose_star": f["mechanism_pose_star"],
            "theta": f["theta"],
            "theta_star": f["theta_star"],
            "dist": f["dist"],
            "status": f["status"],
            "energy_tank_j": f["energy_tank_j"],
            "work_j": f["work_j"],
            "frame_rate_hz": self.frame_rate,
            "camera": self.camera,
            "gizmo_scale": GIZMO_SCALE,
            "clients": len(self.server.get_clients()) if self.server is not None else 0,
            "messages": list(self.messages[-5:]),
        }
        if self.mode == "live":
            p = self.pacer
            out.update(
                paused=p.paused,
                real_time_factor=p.rtf,
                sim_load=p.load,
                recording=self.recording,
                settings=self.sim.settings.to_dict(),
                error=None if p.error is None else repr(p.error),
            )
        else:
            out.update(
                playing=self.playing,
                speed=self.speed,
                duration=self.replay.duration,
                real_time_factor=self.speed if self.playing else 0.0,
                logged_handle_position=f["logged_handle_p"],
                logged_stylus=f["logged_stylus"],
            )
        return out

    def set_target(self, position, wxyz=None) -> None:
        """Moves the hand's target (as the gizmo does): its position [m] and, if given, its
        orientation (a quaternion w, x, y, z)."""
        p = np.asarray(position, dtype=float)
        R = None if wxyz is None else rot_of(wxyz)
        self.sim.set_target(p, R)
        if self._gizmo is not None:
            self._guard = True
            try:
                self._gizmo.position = tuple(p)
                if R is not None:
                    self._gizmo.wxyz = tuple(wxyz_of(R @ self._R0.T))
                self._gui["target"].value = tuple(float(v) for v in p)
            finally:
                self._guard = False

    def recentre(self) -> None:
        """The target (and the gizmo, its axes along the world's) to the handle's pose."""
        T = self.frame()["handle"]
        self._R0 = T[:3, :3].copy()
        self.set_target(T[:3, 3], wxyz_of(T[:3, :3]))

    def seek(self, t: float) -> None:
        """Replay: shows the frame at time t [s]."""
        self.play_t = float(min(max(t, 0.0), self.replay.duration))
        if "timeline" in self._gui:
            self._set_gui("timeline", self.play_t)

    # -------------------------------------------------------------------------------------
    # the GUI

    def _set_gui(self, key: str, value) -> None:
        self._guard = True
        try:
            self._gui[key].value = value
        finally:
            self._guard = False

    def _note(self, text: str) -> None:
        self.messages.append(text)
        if self.server is not None:
            for client in self.server.get_clients().values():
                client.add_notification(title="virtmech view", body=text, auto_close_seconds=6.0)

    def _build_gui(self) -> None:
        gui = self.server.gui
        self._gui["status"] = gui.add_markdown("starting ...")
        if self.mode == "live":
            self._build_live_gui()
        elif self.mode == "replay":
            self._build_replay_gui()
        with gui.add_folder("Plots (the last seconds)"):
            ser = [{"label": "t [s]"}]

            def plot(title: str, series: list, floor: tuple[float, float]):
                """A plot over t whose y axis spans at least `floor` (uPlot's soft limits: a
                tick every 0.2 or more, so that its 3-decimal labels never repeat; a
                resting flicker shows at its true size), wide enough for a sign, with room
                above its top label."""
                return gui.add_uplot(
                    data=(np.zeros(2),) * (1 + len(series)),
                    series=tuple(ser + series),
                    title=title,
                    aspect=2.0,
                    scales={
                        "x": {"time": False},
                        "y": {"range": {"min": {"soft": floor[0], "mode": 1},
                                        "max": {"soft": floor[1], "mode": 1}}},
                    },
                    axes=({}, {"size": PLOT_AXIS_PX}),
                    padding=(12, 12, 0, 0),  # room above the top label (not cut in half)
                )

            self._plots = {
                "force": plot(
                    "force at the handle",
                    [
                        {"label": "|f| [N]", "stroke": "rgb(220,30,30)", "width": 2},
                        {"label": "null [N]", "stroke": "rgb(20,160,60)", "width": 1.5},
                        {"label": "range [N]", "stroke": "rgb(230,60,220)", "width": 1.5},
                    ],
                    PLOT_FLOORS["force"],
                ),
                "dist": plot(
                    "distance from the mechanism",
                    [{"label": "dist [mm]", "stroke": "rgb(40,110,230)", "width": 2}],
                    PLOT_FLOORS["dist"],
                ),
                "energy": plot(
                    "energy",
                    [
                        {"label": "work on hand [mJ]", "stroke": "rgb(200,120,0)", "width": 2},
                        {"label": "tank [mJ]", "stroke": "rgb(90,90,90)", "width": 1.5},
                    ],
                    PLOT_FLOORS["energy"],
                ),
            }
            self._gui["plots_note"] = gui.add_markdown(self._plots_note())

    def _plots_note(self) -> str:
        """What the plots show at rest, for this run's encoders and gains."""
        counts = None
        if self.mode == "live":
            counts = self.sim.scenario.data["sensors"]["counts_per_rev"]
        else:
            counts = (self.replay.info.get("scenario") or {}).get("sensors", {}).get(
                "counts_per_rev"
            )
        enc = (
            f"{counts} counts per revolution ({2e3 * np.pi / counts:.2f} mrad)"
            if counts
            else "their counts per revolution"
        )
        (f0, f1), (d0, d1), (e0, e1) = (PLOT_FLOORS[k] for k in ("force", "dist", "energy"))
        return (
            f"<small>Each y axis spans at least force {f0:g} to {f1:g} N, distance {d0:g} to "
            f"{d1:g} mm, energy {e0:g} to {e1:g} mJ. At rest |f| flickers by a few "
            "hundredths of a newton: the encoders "
            f"read the joints in steps of one count, {enc}; the handle dithers across one "
            "count, and the spring Kp (and the damper Kv on the velocity read from the "
            "counts) turns each step into a step of force. Finer encoders ([sensors] "
            "counts_per_rev) steady it.</small>"
        )

    def _build_live_gui(self) -> None:
        self._add_live_controls()
        self._wire_settings()
        self._wire_live_buttons()

    def _add_live_controls(self) -> None:
        """The live mode's folders: the simulation, the controller, the hand, the sensors."""
        from .. import scenarios as sc

        gui, g = self.server.gui, self._gui
        sim = self.sim
        s = sim.settings
        with gui.add_folder("Simulation"):
            names = sc.names()
            options = names if self.name in names else [self.name, *names]
            g["scenario"] = gui.add_dropdown("scenario", options=options, initial_value=self.name)
            g["pause"] = gui.add_checkbox("pause", initial_value=False)
            g["reset"] = gui.add_button("reset")
            g["record"] = gui.add_button("record")
            g["recentre"] = gui.add_button("target to handle")
        with gui.add_folder("Controller"):
            g["law"] = gui.add_dropdown(
                "law (26 / 11)",
                options=list(LAWS),
                initial_value=s.law,
                hint="auto: eq. 26 on an under-actuated device; under_actuated: eq. 26; "
                "null_space: eq. 11",
            )
            g["kp"] = gui.add_slider("kp [N/m]", min=0.0, max=3000.0, step=10.0, initial_value=s.kp)
            g["kv"] = gui.add_slider("kv [N·s/m]", min=0.0, max=10.0, step=0.1, initial_value=s.kv)
            g["passivity"] = gui.add_checkbox("passivity (energy tank)", initial_value=s.passivity)
        with gui.add_folder("Hand (the mouse)"):
            g["target"] = gui.add_vector3(
                "target [m]", initial_value=tuple(float(v) for v in sim.target_p), step=0.001
            )
            g["hand_stiffness"] = gui.add_slider(
                "stiffness [N/m]", min=0.0, max=1000.0, step=10.0, initial_value=s.hand_stiffness
            )
            g["hand_damping"] = gui.add_slider(
                "damping [N·s/m]", min=0.0, max=20.0, step=0.5, initial_value=s.hand_damping
            )
            g["hand_rot_stiffness"] = gui.add_slider(
                "rot. stiffness [N·m/rad]",
                min=0.0,
                max=5.0,
                step=0.05,
                initial_value=s.hand_rot_stiffness,
            )
            g["hand_rot_damping"] = gui.add_slider(
                "rot. damping [N·m·s/rad]",
                min=0.0,
                max=0.1,
                step=0.001,
                initial_value=s.hand_rot_damping,
            )
        with gui.add_folder("Sensors"):
            g["noise_mrad"] = gui.add_slider(
                "noise [mrad]", min=0.0, max=2.0, step=0.01, initial_value=s.noise_rad * 1e3
            )
            g["delay_cycles"] = gui.add_slider(
                "delay [cycles]", min=0, max=20, step=1, initial_value=s.delay_cycles
            )

    def _wire_settings(self) -> None:
        """The controls that change the settings: each change sent to the simulation, which
        applies the latest between stretches."""
        g = self._gui

        def settings_changed(_):
            if self._guard:
                return
            new = Settings(
                law=g["law"].value,
                kp=float(g["kp"].value),
                kv=float(g["kv"].value),
                passivity=bool(g["passivity"].value),
                hand_stiffness=float(g["hand_stiffness"].value),
                hand_damping=float(g["hand_damping"].value),
                hand_rot_stiffness=float(g["hand_rot_stiffness"].value),
                hand_rot_damping=float(g["hand_rot_damping"].value),
                noise_rad=float(g["noise_mrad"].value) * 1e-3,
                delay_cycles=int(g["delay_cycles"].value),
            )

            # a slider dragged sends many values: the simulation applies the latest once
            self._pending_settings = new

            def apply(sim: LiveSim):
                latest, self._pending_settings = self._pending_settings, None
                if latest is None:
                    return
                try:
                    sim.apply(latest)
                except ValueError as e:
                    self._note(f"not applied: {e}")
                    self._refresh_settings_gui(sim)

            self.pacer.call(apply)

        for key in (
            "law",
            "kp",
            "kv",
            "passivity",
            "hand_stiffness",
            "hand_damping",
            "hand_rot_stiffness",
            "hand_rot_damping",
            "noise_mrad",
            "delay_cycles",
        ):
            g[key].on_update(settings_changed)

    def _wire_live_buttons(self) -> None:
        """Pause, reset, the scenario, record, the target to the handle, the target typed."""
        g = self._gui

        @g["pause"].on_update
        def _(_):
            self.pacer.paused = bool(g["pause"].value)

        @g["reset"].on_click
        def _(_):
            self._restart(self.sim.scenario, keep_settings=True)

        @g["scenario"].on_update
        def _(_):
            if self._guard:
                return
            self._restart(g["scenario"].value, keep_settings=False)

        @g["record"].on_click
        def _(_):
            self.toggle_recording()

        @g["recentre"].on_click
        def _(_):
            self.recentre()

        @g["target"].on_update
        def _(_):
            if self._guard:
                return
            p = np.asarray(g["target"].value, dtype=float)
            self.sim.set_target(p)
            if self._gizmo is not None:
                self._guard = True
                try:
                    self._gizmo.position = p
                finally:
                    self._guard = False

    def _refresh_settings_gui(self, sim: LiveSim) -> None:
        s, g = sim.settings, self._gui
        self._guard = True
        try:
            g["law"].value = s.law
            g["kp"].value = s.kp
            g["kv"].value = s.kv
            g["passivity"].value = s.passivity
            g["hand_stiffness"].value = s.hand_stiffness
            g["hand_damping"].value = s.hand_damping
            g["hand_rot_stiffness"].value = s.hand_rot_stiffness
            g["hand_rot_damping"].value = s.hand_rot_damping
            g["noise_mrad"].value = s.noise_rad * 1e3
            g["delay_cycles"].value = s.delay_cycles
            g["target"].value = tuple(float(v) for v in sim.target_p)
        finally:
            self._guard = False

    def _restart(self, scenario, keep_settings: bool) -> None:
        """A new simulation of `scenario` (name or Scenario), in the simulation's thread."""

        def restart(old: LiveSim):
            rec = old.stop_recording()
            if rec is not None:
                self._finish_recording(rec)
            try:
                new = LiveSim(scenario, seed=old.seed if keep_settings else None)
                if keep_settings:
                    new.apply(old.settings)
            except (ValueError, UserError) as e:
                self._note(f"cannot start {scenario}: {e}")
                return None
            self.name = new.scenario.name
            return new

        self.pacer.call(restart)

    def toggle_recording(self) -> str | None:
        """Starts recording into record_dir/<scenario>-<time> (returns the folder), or stops
        and writes run.json and the figures (returns None)."""
        if self.recording is None:
            folder = self.record_dir / f"{self.name}-{time.strftime('%Y%m%d-%H%M%S')}"
            self.recording = str(folder)

            def start(sim: LiveSim):
                try:
                    sim.start_recording(folder)
                except OSError as e:
                    self.recording = None
                    self._gui["record"].label = "record"
                    self._note(f"cannot record to {folder}: {e}")

            self.pacer.call(start)
            self._gui["record"].label = "stop recording"
            self._note(f"recording to {folder}")
            return str(folder)
        self.recording = None
        self._gui["record"].label = "record"

        def stop(sim: LiveSim):
            rec = sim.stop_recording()
            if rec is not None:
                self._finish_recording(rec)

        self.pacer.call(stop)
        return None

    def _finish_recording(self, rec) -> None:
        def run():
            try:
                folder = rec.finish()
                self._note(f"wrote {folder}/log.csv, run.json, plane.png, time.png")
            except Exception as e:  # reported in the page
                self._note(f"recording not written: {e}")

        threading.Thread(target=run, name="virtmech-view-record", daemon=True).start()

    def _build_replay_gui(self) -> None:
        gui, g = self.server.gui, self._gui
        r = self.replay
        with gui.add_folder("Replay"):
            g["timeline"] = gui.add_slider(
                "time [s]", min=0.0, max=max(r.duration, r.T), step=r.T, initial_value=0.0
            )
            g["play"] = gui.add_button("play / pause")
            g["speed"] = gui.add_dropdown("speed", options=list(SPEEDS), initial_value="1")
            g["loop"] = gui.add_checkbox("loop", initial_value=True)

        @g["timeline"].on_update
        def _(_):
            if not self._guard:
                self.play_t = float(g["timeline"].value)

        @g["play"].on_click
        def _(_):
            if not self.playing and self.play_t >= r.duration:
                self.play_t = 0.0
            self.playing = not self.playing

        @g["speed"].on_update
        def _(_):
            self.speed = float(g["speed"].value)

    # -------------------------------------------------------------------------------------
    # the scene

    def _build_scene(self) -> None:
        sc = self.server.scene
        if self.mode == "live":
            sim = self.sim
            model, mech, md, name = sim.model, sim.mech, sim.mech.to_dict(), sim.device.name
        else:
            r = self.replay
            model, mech, md, name = r.model, r.mech, r.mech.to_dict(), r.device.name
        up = up_of(model) if self.mode == "live" else up_of_replay(self.replay)
        if self._scene is not None:
            self._scene.remove()
        sc.set_up_direction(tuple(float(v) for v in up))
        frame = self.frame()
        members = ()
        if self.mode == "live":
            members = tuple(
                (self.sim.scenario.data.get("set") or {}).get("members") or ()
            )
        self._scene = Scene(self.server, model, mech, md, up, members)
        self._scene.update(frame)
        fov = FOV
        position, look_at = camera_for(model, frame, md, up, name, fov)
        self.camera = {"position": position, "look_at": look_at, "up": up, "fov": fov}
        cam = self.server.initial_camera
        cam.position, cam.look_at = tuple(position), tuple(look_at)
        cam.up = tuple(float(v) for v in up)
        cam.fov = fov
        for client in self.server.get_clients().values():
            client.camera.position, client.camera.look_at = position, look_at
        self._grid = sc.add_grid(
            "/grid",
            width=0.4,
            height=0.4,
            cell_size=0.02,
            section_size=0.1,
            plane="xz" if abs(up[1]) > 0.9 else ("yz" if abs(up[0]) > 0.9 else "xy"),
            position=tuple(look_at - 0.12 * up),
        )
        if self.mode == "live":
            # the gizmo's axes are the world's; the target's orientation is the gizmo's
            # rotation applied to the handle's orientation when it was centred (_R0)
            T = frame["handle"]
            self._R0 = T[:3, :3].copy()
            self._gizmo = sc.add_transform_controls(
                "/hand/gizmo",
                scale=GIZMO_SCALE,
                position=tuple(T[:3, 3]),
                depth_test=False,
            )

            @self._gizmo.on_update
            def _(_):
                if self._guard:
                    return
                g = self._gizmo
                p = np.asarray(g.position, dtype=float)
                self.sim.set_target(p, rot_of(g.wxyz) @ self._R0)
                self._set_gui("target", tuple(float(v) for v in p))

            self._scene_sim = self.sim
            self._refresh_settings_gui(self.sim)
            if self._gui["scenario"].value != self.name:
                self._set_gui("scenario", self.name)

    # -------------------------------------------------------------------------------------
    # the view's loop

    def _view_loop(self) -> None:
        period = 1.0 / self.fps
        tick = 0
        last = time.perf_counter()
        while not self._stop.is_set():
            t0 = time.perf_counter()
            try:
                self._tick(tick, t0 - last)
            except Exception as e:  # shown in the page, the loop goes on
                self.messages.append(f"view: {e!r}")
                time.sleep(0.2)
            last = t0
            tick += 1
            now = time.perf_counter()
            self._frame_times.append(now)
            while self._frame_times and now - self._frame_times[0] > 1.0:
                self._frame_times.pop(0)
            if len(self._frame_times) > 1:
                span = self._frame_times[-1] - self._frame_times[0]
                self.frame_rate = (len(self._frame_times) - 1) / span if span > 0 else 0.0
            self._stop.wait(max(0.0, period - (now - t0)))

    def _tick(self, tick: int, dt: float) -> None:
        if self.mode == "live" and self.sim is not self._scene_sim:
            self._build_scene()  # a reset or another scenario
        if self.mode == "device":
            self.play_t = self.replay.duration  # the device's latest tick
        if self.mode == "replay" and self.playing:
            t = self.play_t + self.speed * dt
            if t >= self.replay.duration:
                if self._gui["loop"].value:
                    t = 0.0
                else:
                    t, self.playing = self.replay.duration, False
            self.play_t = t
            self._set_gui("timeline", round(t / self.replay.T) * self.replay.T)
        f = self.frame()
        with self.server.atomic():
            self._scene.update(f)
        if tick % 3 == 0:
            self._update_plots(f)
        if tick % 6 == 0:
            self._update_status(f)

    def _update_plots(self, f: dict) -> None:
        H = self.sim.history_rows() if self.mode == "live" else self.replay.history(f["t"])
        if len(H) < 2:
            return
        t = H[:, 0]
        self._plots["force"].data = (t, H[:, 1], H[:, 2], H[:, 3])
        self._plots["dist"].data = (t, H[:, 4] * 1e3)
        tank = np.nan_to_num(H[:, 6] * 1e3, nan=0.0)
        self._plots["energy"].data = (t, H[:, 5] * 1e3, tank)

    def _update_status(self, f: dict) -> None:
        w = np.asarray(f["wrench"])
        lines = [f"**{self.name}** ({self.mode})", ""]
        if self.mode == "live":
            p = self.pacer
            state = "paused" if p.paused else f"real time x {p.rtf:.2f}"
            lines.append(f"t = {f['t']:.2f} s, {state}, view {self.frame_rate:.0f} fps")
            lines.append(f"simulation load {100 * p.load:.0f} % of one core")
            if self.recording:
                lines.append(f"recording to `{self.recording}`")
        elif self.mode == "device":
            lines.append(f"t = {f['t']:.2f} s, the device live, view {self.frame_rate:.0f} fps")
        else:
            lines.append(
                f"t = {f['t']:.3f} / {self.replay.duration:.3f} s, "
                f"{'playing x ' + format(self.speed, 'g') if self.playing else 'stopped'}, "
                f"view {self.frame_rate:.0f} fps"
            )
        lines.append(
            f"|f| = {np.linalg.norm(w[:3]):.2f} N, dist = {f['dist'] * 1e3:.2f} mm"
            + (f", status: {', '.join(f['status'])}" if f["status"] else "")
        )
        if self.mode == "live" and self.pacer.error is not None:
            lines.append(f"simulation stopped: {self.pacer.error!r}")
        self._gui["status"].content = "  \n".join(lines)

    # -------------------------------------------------------------------------------------

    def wait(self) -> None:
        """Blocks until stop() (or Ctrl-C in the caller)."""
        while not self._stop.wait(0.2):
            pass


#: each plot's y axis spans at least this (soft limits, in the plot's unit)
PLOT_FLOORS = {"force": (0.0, 1.0), "dist": (0.0, 1.0), "energy": (-0.1, 0.1)}
#: the plots' y axes' width [CSS px]: room for a sign and four digits
PLOT_AXIS_PX = 60


def up_of_replay(replay) -> np.ndarray:
    from ..sim.model import world_gravity

    g = world_gravity(replay.device)
    return -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0, 0, 1.0])
