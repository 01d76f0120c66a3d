"""``virtmech drive``: a scenario's controller on a real haptic device.

    virtmech drive SCENARIO --device openhaptics|forcedimension [--library PATH]
                   [--device-name NAME] [--duration S] [--out DIR] [--format csv|parquet]
                   [--watchdog-ms MS] [--figures] [--view PORT] [--quiet]

openhaptics: the OpenHaptics HD SDK (Touch, PHANTOM Omni), its scheduler running the servo;
forcedimension: the Force Dimension DHD SDK (omega.3/6/7, sigma.7, Novint Falcon; the
scenario's [device] a CartesianDevice), the driver's own servo thread (SCHED_FIFO where
permitted, else a warning and the jitter measured at the end).

1. The scenario's [device], [mechanism] (and [set]) and [controller] say what to render; its
   simulation's sections ([physics], [human], [[intent]], [initial], [checks], [sensors] but
   its velocity_cutoff_hz, the driver's velocity filter) are ignored, with one note.
2. The device is opened and checked against [device] (a mismatch is refused), its
   calibration brought up to date (or the user asked to put the stylus in the inkwell).
3. The controller is built with the device's nominal force limit (the lower of it and the
   scenario's) and a watchdog; the servo starts in the device's scheduler, and the force
   ramps in.
4. Every tick goes to the log (``virtmech run``'s format, plus the driver's columns) and a
   status line shows the rate, |f|, the status, the worst tick and the late ticks.
5. With --view PORT the viewer (virtmech view's, in the browser) follows the device: the real
   handle, the mechanism's placements and the forces, live; the hand gizmo is off.
6. --duration, Ctrl-C or SIGTERM end the run (exit 0); a device error, a stalled servo or
   joint readings implausible for too long end it with one line saying why (exit 1). Either
   way the torque goes to zero, then the scheduler stops and the device is disabled.

The servo is C++ (virtmech._driver: include/virtmech/drivers/); docs/devices.md, "Running on a
real Touch".
"""

from __future__ import annotations

import json
import math
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import virtmech as vm

from .errors import UserError

#: the devices `drive` can drive: their SDKs
DEVICES = ("openhaptics", "forcedimension")
#: a tick later than this after the last one zeroes the force, which then ramps in [ms]
WATCHDOG_MS = 5.0
#: no tick for this long while running is a stalled servo [s]
STALL_S = 0.5
#: how long to wait for the stylus in the inkwell when the device needs it [s]
CALIBRATION_WAIT_S = 30.0
#: how often the records are read and the status line redrawn [s]
POLL_S = 0.02
#: rows of the log written at a time
WRITE_ROWS = 1000
#: the scenario's tables `drive` reads; the others are the simulation's
DRIVE_TABLES = ("device", "mechanism", "set", "controller")
SIM_TABLES = ("physics", "human", "intent", "initial", "checks", "sensors")
#: the driver's columns after those of `virtmech run`'s log
DRIVER_COLUMNS = ["flags", "gap_s", "tick_us", "step_us", "device_error"]
DRIVER_UNITS = {
    "flags": "bits: 1 late, 2 watchdog (zero torque), 4 device error, 8 faults held, "
    "16 stopping, 32 a reading not finite (virtmech._driver.FLAGS)",
    "gap_s": "s (since the last tick, the device's servo clock)",
    "tick_us": "µs (the whole tick: device read, controller, device write)",
    "step_us": "µs (of which the controller's step)",
    "device_error": "the device's error code this tick (0: none)",
}
#: what to do about each OpenHaptics error (docs/devices.md has the whole table)
HD_ADVICE = {
    0x0302: "check the device's cable and power, then start again",
    0x0303: "check the device's name and its connection in the Touch setup tool",
    0x0300: "power the device off and on; if it persists, run the vendor's diagnostic",
    0x0200: "the motors are warm: let the device rest, lower the gains or the force limit",
    0x0201: "the device refused a force above its maximum: lower the gains or max_force",
    0x0202: "a force step too sharp: lower the gains or raise ramp_time_s",
    0x0203: "the handle moved faster than the device allows: move it gently",
    0x0204: "the device's force output failed: check the amplifier and power",
    0x0304: "the device's servo timer failed: close other real-time programs",
}


class DeviceFault(Exception):
    """The device failed or the run ended on a fault: one line saying what and why (exit 1)."""


def _driver_module():
    from . import _driver

    return _driver


# ---------------------------------------------------------------------------------------
# the scenario


def load(source: str | Path) -> tuple[Any, str | None]:
    """The scenario as `drive` reads it (a shipped name or a TOML path): its [device],
    [mechanism], [set] and [controller] validated (name and duration_s optional), and a note
    naming the simulation's sections it ignores (None if there are none)."""
    from . import scenarios as sc

    p = Path(source)
    if not p.suffix and not p.exists():
        p = sc.path_of(str(source))
    if not p.is_file():
        raise sc.ScenarioError(f"{source}: no such file or shipped scenario")
    try:
        raw = sc._toml().loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise sc.ScenarioError(f"{source}: cannot be read ({e}); expected a TOML file") from None
    except Exception as e:  # tomllib.TOMLDecodeError
        raise sc.ScenarioError(f"{source}: not valid TOML: {e}") from None
    if "mechanism" not in raw:
        raise sc.ScenarioError(f"{p}: mechanism: missing required table; expected [mechanism]")
    kept = {k: raw[k] for k in DRIVE_TABLES if k in raw}
    kept["name"] = raw.get("name", p.stem)
    kept["description"] = raw.get("description", "")
    kept["duration_s"] = 1.0  # the run's length is --duration's (or until stopped)
    cutoff = (raw.get("sensors") or {}).get("velocity_cutoff_hz")
    if cutoff is not None:
        kept["sensors"] = {"velocity_cutoff_hz": cutoff}
    scenario = sc.validate(kept, str(p))
    ignored = [
        k
        for k in SIM_TABLES
        if k in raw and not (k == "sensors" and set(raw[k]) <= {"velocity_cutoff_hz"})
    ]
    ignored += [k for k in ("duration_s", "seed") if k in raw]
    note = None
    if ignored:
        note = (
            f"{p.name}: the simulation's {', '.join(_table_name(k) for k in ignored)} "
            "ignored (a device is driven by [device], [mechanism], [set] and [controller])"
        )
    return scenario, note


def _table_name(key: str) -> str:
    return {"intent": "[[intent]]", "duration_s": "duration_s", "seed": "seed"}.get(
        key, f"[{key}]"
    )


def rig_for(scenario, max_force_n: float | None = None, watchdog_s: float | None = None):
    """The scenario's rig for a real device (virtmech.builder.build, simulated=False: the
    device, the mechanisms, the controller and the renderer), its controllers rebuilt with
    the device's force limit and a watchdog (which the scenario format does not carry)
    where given."""
    from .builder import build, built

    rig = build(scenario, simulated=False)
    if max_force_n is None and watchdog_s is None:
        return rig
    settings = {"max_force": max_force_n, "watchdog_s": watchdog_s}
    settings = {k: v for k, v in settings.items() if v is not None}
    return built(scenario, "controller", lambda: rig.with_controller(**settings))


# ---------------------------------------------------------------------------------------
# the log


class LogRows:
    """Tick records (virtmech._driver, one float64 row each) as rows of the log: the
    columns of `virtmech run`'s log (virtmech.sim.log.log_columns; the measured joints are
    also the true ones, the hand's columns NaN: no hand model) then DRIVER_COLUMNS."""

    def __init__(self, rig):
        self.n, self.m = rig.device.dof, rig.width
        self.members = [m.to_dict() for m in rig.mechanisms] if rig.is_set else []
        self.columns = list(rig.columns) + DRIVER_COLUMNS
        self.index = {c: i for i, c in enumerate(self.columns)}
        self.fields = _driver_module().record_fields()
        self.derive = rig.derived_columns()  # its columns: the first of these

    def _put(self, out: np.ndarray, column: str, rec: np.ndarray, field: str, width: int):
        start = self.index[column]
        first = self.fields[field][0]
        out[:, start : start + width] = rec[:, first : first + width]

    def __call__(self, rec: np.ndarray) -> np.ndarray:
        n, m = self.n, self.m
        out = np.full((len(rec), len(self.columns)), np.nan)
        put = self._put
        put(out, "t", rec, "t_s", 1)
        joints = (("q0", "q"), ("qm0", "q"), ("dq0", "dq"), ("dqm0", "dq"), ("tau0", "torque"),
                  ("tau_motor0", "command"))
        for col, fld in joints:
            put(out, col, rec, fld, n)
        put(out, "theta0", rec, "theta", m)
        put(out, "theta_star0", rec, "theta_star", m)
        put(out, "px", rec, "handle_p", 3)
        put(out, "sx", rec, "stylus", 3)
        sixes = (("vx", "twist"), ("fx", "wrench"), ("e0", "error"), ("e_dot0", "error_dot"),
                 ("e_star0", "error_star"), ("e_star_dot0", "error_star_dot"),
                 ("f_null0", "wrench_null"), ("f_range0", "wrench_range"))
        for col, fld in sixes:
            put(out, col, rec, fld, 6)
        for col in ("status", "ramp", "iterations", "iterations_star", "member", *DRIVER_COLUMNS):
            put(out, col, rec, col, 1)
        self.derive(out)
        return out


# ---------------------------------------------------------------------------------------
# the run


@dataclass
class DriveResult:
    """What a run of `drive` did: why it ended ("duration", "interrupted", "device_error",
    "fault_held", "stall"), the exit status (0 or 1), its message, the servo's counters and
    the device's identification, the files written."""

    reason: str
    exit_code: int
    message: str
    stats: dict
    info: dict
    out: Path | None = None
    files: list[str] = field(default_factory=list)
    metrics: dict = field(default_factory=dict)
    #: the servo's measured timing where it ran at normal priority ("": at real-time priority)
    jitter: str = ""


class _Stop:
    """SIGINT and SIGTERM set a flag (the run's end, exit 0) instead of raising."""

    def __init__(self):
        self.signal: int | None = None
        self._old: dict[int, Any] = {}

    def __enter__(self):
        for s in (signal.SIGINT, signal.SIGTERM):
            self._old[s] = signal.signal(s, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        self.signal = signum

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)


class _StatusLine:
    """The live status line on stderr (rich), redrawn a few times a second."""

    def __init__(self, enabled: bool, label: str):
        self.live = None
        self.label = label
        self.last = 0.0
        if enabled:
            from rich.console import Console
            from rich.live import Live

            self.live = Live("", console=Console(stderr=True), refresh_per_second=8)
            self.live.start()

    def update(self, st: dict, force: bool = False) -> None:
        if self.live is None:
            return
        now = time.monotonic()
        if not force and now - self.last < 0.12:
            return
        self.last = now
        from rich.text import Text

        names = ", ".join(vm.status.names(int(st["status"]))) or "ok"
        self.live.update(
            Text(
                f"{self.label}  {st['elapsed_s']:7.2f} s  {st['rate_hz']:7.1f} Hz  "
                f"|f| {st['force_n']:5.2f} N  {names}  worst tick {st['worst_tick_us']:.0f} µs  "
                f"late {st['late']}  watchdog {st['watchdog']}"
            )
        )

    def close(self, st: dict | None) -> None:
        if self.live is not None:
            if st is not None:
                self.update(st, force=True)
            self.live.stop()


def _require_rich() -> None:
    """rich (the status line), or a UserError saying how to install it."""
    try:
        import rich  # noqa: F401
    except ImportError:
        raise UserError(
            "virtmech drive: the status line needs rich, which is not installed; install it "
            "with: pip install 'virtmech[drive]' (or run with --quiet)"
        ) from None


def _opened(driver, device, info_name: str) -> None:
    """driver.open(device) with its errors as the command line reports them."""
    d = _driver_module()
    try:
        driver.open(device)
    except d.LibraryError as e:
        raise UserError(str(e)) from None
    except d.DeviceMismatch as e:
        raise UserError(f"{info_name}: {e}") from None
    except d.DeviceFault as e:
        raise DeviceFault(str(e)) from None


def _calibrated(driver, notify, stop) -> str | None:
    """Calibrates, waiting up to CALIBRATION_WAIT_S for the stylus in the inkwell; None when
    interrupted meanwhile."""
    d = _driver_module()
    t0 = time.monotonic()
    asked = False
    try:
        while True:
            state = driver.calibrate()
            if state != "needs_inkwell":
                return state
            if stop.signal is not None:
                return None
            if not asked:
                notify(
                    "put the stylus in the inkwell: the device needs calibrating "
                    f"(waiting up to {CALIBRATION_WAIT_S:g} s)"
                )
                asked = True
            if time.monotonic() - t0 > CALIBRATION_WAIT_S:
                raise DeviceFault(
                    f"the device is not calibrated after {CALIBRATION_WAIT_S:g} s: put the "
                    "stylus in the inkwell (or run the Touch setup tool's calibration) and "
                    "start again"
                )
            time.sleep(0.2)
    except d.DeviceFault as e:
        raise DeviceFault(str(e)) from None


def _force_limit(S: dict, device, info: dict) -> float:
    """The controller's force limit: the scenario's (0: the device model's), at most the
    device's nominal maximum."""
    limit = float(S["controller"]["max_force"]) or float(device.max_force)
    nominal = float(info.get("nominal_max_force_n", math.nan))
    return min(limit, nominal) if math.isfinite(nominal) and nominal > 0 else limit


def run(
    scenario,
    device: str = "openhaptics",
    library: str | None = None,
    device_name: str | None = None,
    duration_s: float | None = None,
    out: str | Path | None = None,
    fmt: str = "csv",
    watchdog_ms: float = WATCHDOG_MS,
    figures: bool = False,
    quiet: bool = False,
    view_port: int | None = None,
) -> DriveResult:
    """Drives a device with a scenario's controller (a Scenario from `load`) until
    `duration_s` (None: until Ctrl-C or SIGTERM) or a fault; writes the log and run.json in
    `out` (None: none); with `view_port`, the viewer follows the device on that port
    (virtmech.view.device). Raises UserError for a mistake of the input (a missing library, a
    device that does not match the scenario) and DeviceFault for a device that fails before
    the servo runs; a fault while running ends the run (DriveResult.exit_code 1). SIGINT and
    SIGTERM end the run (exit 0) from the moment the device is opened."""
    _check_options(device, watchdog_ms, duration_s, quiet, view_port)
    S = scenario.data

    def notify(message: str) -> None:
        if not quiet:
            print(f"virtmech drive: {message}", file=sys.stderr)

    model = rig_for(scenario).device  # the device model the device is checked against
    driver = _driver_for(device, library, device_name)
    viewer = None
    with _Stop() as stop:
        _opened(driver, model, f"{scenario.source}: [device] {S['device']['type']}")
        try:
            info = dict(driver.info)
            period = float(S["controller"]["period_s"])
            _check_rate(scenario.source, info, period)
            calibration = _calibrated(driver, notify, stop)
            if calibration is not None:
                rig = rig_for(scenario, _force_limit(S, model, info), watchdog_ms * 1e-3)
                cutoff = float(S["sensors"]["velocity_cutoff_hz"])
                rows = LogRows(rig)
                if view_port is not None:  # before the servo: a port taken is a mistake
                    viewer = _viewer(rig, view_port, notify)
            if calibration is None or stop.signal is not None:  # Ctrl-C since the device opened
                message = "stopped (interrupted) before the servo started"
                return DriveResult("interrupted", 0, message, {}, info)
            _start(driver, rig, period, cutoff, scenario.source, notify)
            if out is not None:  # made now: a run refused before the servo writes nothing
                from .cli import _out_dir

                out = _out_dir(out)  # (a folder it cannot make: the servo stops, as below)
            sinks = _sinks(out, fmt, rows.columns, figures)
            if viewer is not None:
                sinks.append(viewer.replay.append)
            result = _serve(driver, scenario.name, rows, stop, duration_s, sinks, quiet)
        finally:
            driver.stop()
            if viewer is not None:
                viewer.stop()
    result.info = {**info, "calibration": calibration}
    if hasattr(driver, "priority_note"):
        result.info["realtime_priority"] = not driver.priority_note
    if getattr(driver, "priority_note", "") and result.stats:
        result.jitter = _jitter(result.stats, period)
        notify(f"warning: the servo thread ran at normal priority: {result.jitter}")
    result.out = Path(out) if out is not None else None
    if out is not None:
        _finish(result, rig, rows, out, fmt, figures, cutoff, watchdog_ms)
    return result


def _check_options(device: str, watchdog_ms: float, duration_s: float | None, quiet: bool,
                   view_port: int | None) -> None:
    """run()'s options, each refused by name (UserError), and the extras they need."""
    if device not in DEVICES:
        raise UserError(f"--device {device}: unknown device; expected one of {', '.join(DEVICES)}")
    if not watchdog_ms > 0:
        raise UserError(f"--watchdog-ms {watchdog_ms:g}: expected a number of milliseconds > 0")
    if duration_s is not None and not duration_s > 0:
        raise UserError(f"--duration {duration_s:g}: expected a number of seconds > 0")
    if not quiet:
        _require_rich()
    if view_port is not None:
        _require_viewer()


def _check_rate(source: str, info: dict, period: float) -> None:
    """The scenario's period against the rate the device's servo runs at (where it says)."""
    rate = float(info.get("update_rate_hz", math.nan))
    if math.isfinite(rate) and abs(rate * period - 1.0) > 0.01:
        raise UserError(
            f"{source}: controller.period_s {period:g}: the device's servo runs "
            f"at {rate:g} Hz (HD_UPDATE_RATE); expected period_s = {1.0 / rate:g}"
        )


def _start(driver, rig, period: float, cutoff: float, source: str, notify) -> None:
    """Starts the servo with the rig's renderer: a device that does not match the scenario is
    a UserError, one that fails a DeviceFault; a servo thread below real-time priority is
    told."""
    d = _driver_module()
    try:
        driver.start(rig.renderer, period_s=period, velocity_cutoff_hz=cutoff)
    except ValueError as e:  # what a device needs of the scenario (a ramp-in, a watchdog)
        raise UserError(f"{source}: [controller] {e}") from None
    except d.DeviceMismatch as e:
        raise UserError(f"{source}: {e}") from None
    except d.DeviceFault as e:
        raise DeviceFault(str(e)) from None
    if getattr(driver, "priority_note", ""):
        notify(f"warning: {driver.priority_note}")


def _driver_for(device: str, library: str | None, device_name: str | None):
    """The driver of the SDK `device` names (DEVICES)."""
    d = _driver_module()
    if device == "forcedimension":
        if device_name:
            raise UserError(
                f"--device-name {device_name}: only --device openhaptics names its device; "
                "the Force Dimension SDK opens the first device it finds"
            )
        return d.ForceDimensionDriver(library or "")
    return d.OpenHapticsDriver(library or "", device_name or "")


def _jitter(stats: dict, period_s: float) -> str:
    """The servo's timing as measured: its worst gap between ticks against the period, and
    its late ticks."""
    return (
        f"worst gap between ticks {stats['worst_gap_s'] * 1e3:.2f} ms for a period of "
        f"{period_s * 1e3:g} ms, {stats['late']} late ticks of {stats['ticks']}"
    )


def _require_viewer() -> None:
    """The viewer's packages, or a UserError saying how to install them."""
    for module, extra in (("viser", "view"), ("mujoco", "view")):
        try:
            __import__(module)
        except ImportError:
            raise UserError(
                f"virtmech drive --view: the viewer needs the [{extra}] extra ({module} is not "
                f"installed); install it with: pip install 'virtmech[{extra}]'"
            ) from None


def _viewer(rig, port: int, notify):
    """The viewer following the device (its feed: viewer.replay), started on `port`."""
    from .view.device import DeviceFeed
    from .view.server import ViewServer, check_port

    check_port("127.0.0.1", port, f"--view {port}")
    check_port("127.0.0.1", port + 1, f"--view {port} (the state endpoint: {port + 1})")
    viewer = ViewServer(DeviceFeed(rig), port=port).start()
    notify(f"the viewer follows the device at {viewer.url} (state: {viewer.state_url})")
    return viewer


def _serve(driver, name: str, rows: LogRows, stop, duration_s, sinks: list, quiet: bool):
    """The normal thread while the servo runs: records to the log (`sinks`), the status
    line, the end of the run."""
    pending, written = [], 0
    status = _StatusLine(not quiet, name)
    reason, st = "duration", {}
    t0 = time.monotonic()
    try:
        while True:
            time.sleep(POLL_S)
            st = driver.stats
            rec = driver.read_records(1 << 14)
            if len(rec):
                pending.append(rows(rec))
            if sum(len(p) for p in pending) >= WRITE_ROWS:
                written += _write(sinks, pending, rows.columns)
            status.update(st)
            if stop.signal is not None:
                reason = "interrupted"
                break
            if st["stop"] != "running":
                reason = st["stop"]
                break
            if driver.stalled(STALL_S):
                reason = "stall"
                break
            # the duration last: a device error in the run's last poll is still named
            if duration_s is not None and st["elapsed_s"] >= duration_s:
                break
        # the end: zero torque, the scheduler stopped, the device disabled (at once, before
        # anything is written), then the records left
        driver.stop()
        wall = time.monotonic() - t0
        rec = driver.read_records(1 << 20)
        if len(rec):
            pending.append(rows(rec))
        written += _write(sinks, pending, rows.columns)
        st = driver.stats
    finally:
        status.close(st or None)
        for s in sinks:
            if hasattr(s, "close"):
                s.close()
    message, code = _ending(reason, st, driver)
    result = DriveResult(reason, code, message, dict(st), {})
    result.stats["wall_time_s"] = wall
    result.stats["rows"] = written
    scratch = [s for s in sinks if isinstance(s, _KeepOpen)]
    result._scratch = scratch[0] if scratch else None  # type: ignore[attr-defined]
    return result


def _sinks(out, fmt: str, columns: list[str], figures: bool) -> list:
    """The log's file, and a scratch file of the columns the metrics (and the figures) read
    after the run."""
    if out is None:
        return []
    from .sim.logio import CsvLog, LogFile, ParquetLog
    from .sim.output import metric_columns

    out = Path(out)
    writer = ParquetLog(out / f"log.{fmt}") if fmt == "parquet" else CsvLog(out / f"log.{fmt}")
    keep = metric_columns(sum(1 for c in columns if c.startswith("tau_motor")))
    if figures:
        from .viz.figures import FIGURE_COLUMNS

        keep = list(dict.fromkeys(keep + list(FIGURE_COLUMNS)))
    return [writer, _KeepOpen(LogFile(out, keep))]


class _KeepOpen:
    """A sink whose close() waits for `really_close` (the metrics read it after the run)."""

    def __init__(self, sink):
        self.sink = sink

    def __call__(self, rows, columns) -> None:
        self.sink(rows, columns)

    def close(self) -> None:
        pass

    def really_close(self) -> None:
        self.sink.close()


def _write(sinks: list, pending: list, columns: list[str]) -> int:
    if not pending:
        return 0
    block = np.concatenate(pending)
    pending.clear()
    for s in sinks:
        s(block, columns)
    return len(block)


def _ending(reason: str, st: dict, driver) -> tuple[str, int]:
    """The run's last line and exit status."""
    at = f"at t = {st.get('elapsed_s', 0.0):.3f} s"
    safe = "torque zeroed, scheduler stopped, device disabled"
    if type(driver).__name__ == "ForceDimensionDriver":
        safe = "force zeroed, servo thread stopped, device stopped and closed"
    if reason == "device_error":
        code = int(st["device_error"])
        advice = HD_ADVICE.get(code) if type(driver).__name__ == "OpenHapticsDriver" else None
        return (
            f"device error {driver.describe_error(code)} {at}: {safe}"
            + (f"; {advice}" if advice else ""),
            1,
        )
    if reason == "fault_held":
        names = ", ".join(vm.status.names(int(st["fault_status"])))
        return (
            f"the joint readings stayed implausible ({names}) {at}: {safe}; check the "
            "device's calibration (stylus in the inkwell, then start again) and that the "
            "scenario's [device] describes this device",
            1,
        )
    if reason == "stall":
        return (
            f"the device's servo stalled (no tick for {STALL_S:g} s) {at}: {safe}; check the "
            "device's connection and that no other program holds it",
            1,
        )
    why = "interrupted" if reason == "interrupted" else "the duration is over"
    return f"stopped ({why}) {at}: {safe}", 0


def _finish(result, rig, rows, out, fmt, figures, cutoff, watchdog_ms):
    """run.json (the device's identification, the measured rate), the metrics where they
    apply, and the figures when asked for."""
    from .sim.log import SimResult
    from .sim.output import metrics, write_run

    out = Path(out)
    scratch = getattr(result, "_scratch", None)
    st = result.stats
    info = {
        "device": rig.device.to_dict(),
        "mechanism": rig.mechanism.to_dict(),
        **(
            {"set_members": rows.members, "set": dict(rig.data["set"], members=len(rows.members))}
            if rig.is_set
            else {}
        ),
        "controller_model": {
            k: (v.tolist() if isinstance(v, np.ndarray) else v)
            for k, v in rig.controller.model.items()
        },
        "versions": {
            "virtmech": vm.__version__,
            "numpy": np.__version__,
            "python": sys.version.split()[0],
        },
        "seed": None,
        "log_file": f"log.{fmt}",
        "drive": {
            "device": result.info,
            "ended": result.reason,
            "message": result.message,
            "ticks": st["ticks"],
            "measured_rate_hz": st["rate_hz"],
            "late_ticks": st["late"],
            "watchdog_trips": st["watchdog"],
            "zero_torque_ticks": st["zero_ticks"],
            "dropped_records": st["dropped"],
            "worst_tick_us": st["worst_tick_us"],
            "worst_gap_s": st["worst_gap_s"],
            "watchdog_s": watchdog_ms * 1e-3,
            "velocity_cutoff_hz": cutoff,
            "units": DRIVER_UNITS,
        },
    }
    sim = SimResult(
        scenario=rig.scenario,
        columns=rows.columns,
        log=np.empty((0, len(rows.columns))),
        sim_time_s=float(st["elapsed_s"]),
        wall_time_s=float(st["wall_time_s"]),
        info=info,
        source=scratch.sink if scratch is not None else None,
    )
    try:
        m = metrics(sim) if st["rows"] > 0 else {}
        write_run(sim, out, log=False, metrics=m)
        result.metrics = m
        result.files = [f"log.{fmt}", "run.json"]
        if figures and st["rows"] > 0:
            from .viz import write_figures

            result.files += [p.name for p in write_figures(sim, out)]
    finally:
        if scratch is not None:
            scratch.really_close()
    # run.json's units for the driver's columns
    path = out / "run.json"
    doc = json.loads(path.read_text(encoding="utf-8"))
    doc["units"].update(DRIVER_UNITS)
    path.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")


__all__ = ["DEVICES", "DeviceFault", "DriveResult", "LogRows", "load", "rig_for", "run"]
