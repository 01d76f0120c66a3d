"""The ``virtmech`` command (also ``python -m virtmech``).

virtmech demo [--out DIR] [--only NAME...]   every shipped scenario, summary.json, index.html
virtmech run SCENARIO [--out DIR]     one scenario (a TOML path or a shipped name)
             [--seed N] [--duration S]
             [--set KEY=VALUE ...]    set scenario keys (dotted: controller.law=null_space)
             [--format csv|parquet]   the log as log.csv (default) or log.parquet (pyarrow)
virtmech sweep SCENARIO --grid KEY=V1,V2,... [--grid ...]   a grid of runs in parallel:
             [--out DIR] [--backend process|ray] [--address ADDR] [--workers N]
             [--duration S] [--set KEY=VALUE ...] [--metric NAME]
                                      sweep.parquet, sweep.json, sweep.png (docs/sweeps.md)
virtmech scenarios                    the shipped scenarios
virtmech schema                       the JSON Schema of the scenario format
virtmech bench [ARGS...]              benchmarks (virtmech.bench)
virtmech view [SCENARIO | LOG_DIR]    a live 3-D viewer in the browser, the mouse as the hand;
             [--port P] [--open]      or a run's log played back (docs/viewer.md)
virtmech drive SCENARIO --device openhaptics|forcedimension
             [--library PATH] [--device-name NAME] [--duration S] [--out DIR]
             [--format csv|parquet] [--watchdog-ms MS] [--figures] [--view PORT]
             [--quiet]                the scenario's mechanism on a real device
                                      (docs/devices.md, "Running on a real Touch" and
                                      "Running on a Force Dimension device")
virtmech ros2 SCENARIO [--duration S] [--set KEY=VALUE ...] [--ros-args ...]
                                      the scenario's renderer as a ROS 2 node (docs/ros2.md)
virtmech ros2-sim SCENARIO [--lockstep] [--command TOPIC] [--duration S] [--out DIR]
             [--seed N] [--set KEY=VALUE ...] [--ros-args ...]
                                      the scenario's simulated device as a ROS 2 driver

A mistake in the input (a scenario, a flag, a path; virtmech.errors.UserError) is reported
as one message on stderr, with exit status 2; a device fault (drive) with exit status 1.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from .errors import UserError
from .sim.logio import LOG_FORMATS  # --format: csv, or parquet (needs pyarrow)

SEED_MAX = 2**63 - 1


def _require_sim(command: str) -> None:
    """The [sim] extra's packages, or a UserError saying how to install them."""
    for module in ("mujoco", "matplotlib", "tqdm"):
        try:
            __import__(module)
        except ImportError:
            raise UserError(
                f"virtmech {command}: the simulation needs the [sim] extra ({module} is not "
                "installed); install it with: pip install 'virtmech[sim]'"
            ) from None


def _out_dir(path: str | Path, flag: str = "--out") -> Path:
    """The output folder, created; a UserError naming the flag if it cannot be."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".virtmech-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as e:
        raise UserError(
            f"{flag} {path}: cannot create or write the output folder ({e.strerror or e}); "
            "expected a folder you can write to"
        ) from None
    return out


def _can_make(path: str | Path, flag: str = "--out") -> None:
    """A UserError naming the flag unless `path` is a folder, or can be made one, to write in;
    nothing is made (for a folder made later: virtmech drive, once the servo runs)."""
    there = Path(path).absolute()
    while not there.exists():
        there = there.parent
    why = "not a folder" if not there.is_dir() else None
    if why is None and not os.access(there, os.W_OK | os.X_OK):
        why = "not writable"
    if why:
        raise UserError(
            f"{flag} {path}: cannot create or write the output folder ({there} is {why}); "
            "expected a folder you can write to"
        )


def _require_format(fmt: str) -> None:
    """A UserError saying how to install pyarrow if `fmt` needs it and it is missing."""
    if fmt == "parquet":
        from .sim.logio import require_pyarrow

        try:
            require_pyarrow()
        except ImportError as e:
            raise UserError(f"--format parquet: {e}") from None


def _run_one(scenario, out_dir, seed, progress: bool, fmt: str = "csv", chunk_s=None) -> dict:
    """Runs a scenario into out_dir (checked as --out; virtmech.runner writes the log,
    run.json and the figures); returns the metrics. The scenario's objects are built first,
    so that a mistake the format cannot see (an array of the wrong shape) leaves no folder."""
    from .builder import preflight
    from .runner import run_scenario

    preflight(scenario)
    out = _out_dir(out_dir)
    earlier = _earlier_log(out)
    metrics = run_scenario(
        scenario, seed=seed, progress=progress, out=out, fmt=fmt, chunk_s=chunk_s
    ).metrics
    if earlier is not None and earlier.name != f"log.{fmt}" and earlier.is_file():
        earlier.unlink()  # it would stand beside this run's log as if it were this run's
        print(f"virtmech: {out}: removed the earlier run's {earlier.name}", file=sys.stderr)
    return metrics


def _earlier_log(out: Path) -> Path | None:
    """The log of the run written in `out` before (the one its run.json names), said on
    stderr; None where there is none."""
    try:
        named = json.loads((out / "run.json").read_text(encoding="utf-8")).get("log_file")
    except (OSError, ValueError, AttributeError):
        return None
    print(f"virtmech: {out}: replacing the run written there before", file=sys.stderr)
    return out / named if named in {f"log.{f}" for f in LOG_FORMATS} else None


def cmd_scenarios(args) -> int:
    from . import scenarios as sc

    names = sc.names()  # the paper's figures first, fig9 before fig10
    w = max(map(len, names))
    for name in names:
        s = sc.load(name)
        first = " ".join(s.data["description"].split())
        first = first.split(": ", 1)[0]
        print(f"{name:<{w}}  {s.duration_s:5.1f} s  {first}")
    return 0


def cmd_schema(args) -> int:
    from .scenarios import json_schema

    print(json.dumps(json_schema(), indent=2))
    return 0


def _sets(texts) -> tuple[dict, list[str]]:
    """--set KEY=VALUE texts as ({key: value}, [mistakes]): the texts that can be read, and
    a message for each that cannot (or that gives a key again)."""
    from .scenarios import ScenarioError, parse_assignment

    out, errors = {}, []
    for text in texts or ():
        try:
            key, value = parse_assignment(text, "--set")
        except ScenarioError as e:
            errors += e.messages
            continue
        if key in out:
            errors.append(f"--set {key}: given twice; expected each key once")
        out[key] = value
    return out, errors


def _with_sets(s, texts) -> tuple:
    """The scenario with the --set keys, the keys' values, and every mistake of those flags
    (each --set on its own first, so that its message names it)."""
    from . import scenarios as sc

    sets, errors = _sets(texts)
    if sets:
        for key, value in sets.items():
            try:
                s.with_keys({key: value})
            except sc.ScenarioError as e:
                errors += [f"--set {key}={sc.value_text(value)}: {m}" for m in e.messages]
        if not errors:
            try:
                s = s.with_keys(sets)
            except sc.ScenarioError as e:  # the keys are valid one by one, not together
                errors += [f"--set: {m}" for m in e.messages]
    return s, sets, errors


def _set_and_duration(s, args) -> tuple:
    """The scenario with the --set keys and --duration, and every mistake of those flags."""
    from . import scenarios as sc

    s, sets, errors = _with_sets(s, args.set)
    if args.duration is not None:
        try:
            s = s.with_overrides(duration_s=args.duration)
        except sc.ScenarioError as e:
            errors += [f"--duration {args.duration:g}: {m}" for m in e.messages]
    args.set_values = sets  # for sweep.json
    return s, errors


def cmd_run(args) -> int:
    from . import scenarios as sc

    _require_sim("run")
    s, errors = _set_and_duration(sc.load(args.scenario), args)
    if errors:
        raise UserError(*errors)
    _require_format(args.format)
    out = Path(args.out) if args.out else Path("out") / s.name
    t0 = time.perf_counter()
    m = _run_one(s, out, args.seed, not args.quiet, args.format)
    from .viz.figures import SHAPED

    figures = "plane.png, time.png" + (
        ", scene.png" if s.data["mechanism"]["type"] in SHAPED else ""
    )
    print(
        f"{s.name}: wrote {out}/log.{args.format}, run.json, {figures} "
        f"({time.perf_counter() - t0:.2f} s wall)"
    )
    _print_metrics({s.name: m})
    return 0


def cmd_sweep(args) -> int:
    from . import scenarios as sc
    from .sim.output import METRICS
    from .sweep import check_backend, check_grid, format_table, run_grid, write_sweep

    _require_sim("sweep")
    check_backend(args.backend, args.workers)
    s, errors = _set_and_duration(sc.load(args.scenario), args)
    if args.metric not in METRICS:
        errors.append(
            f"--metric {args.metric}: no such metric; expected one of {', '.join(METRICS)}"
        )
    grid, mistakes = sc.parse_grid(args.grid)
    # every point checked (and each value of each key on its own) before anything runs
    scenarios = check_grid(s, grid, errors=errors + mistakes)
    out = _out_dir(args.out or Path("out") / f"{s.name}-sweep")
    t0 = time.perf_counter()
    table = run_grid(
        s.name, grid, scenarios, args.backend, args.workers, args.address, not args.quiet
    )
    wall = time.perf_counter() - t0
    write_sweep(table, out, s, grid, args, wall)
    failed = table.num_rows - sum(table.column("ok").to_pylist())
    print(
        f"{s.name}: {table.num_rows} runs ({args.backend}) in {wall:.1f} s wall; wrote "
        f"{out}/sweep.parquet, sweep.json, sweep.png"
        + (f"; {failed} failed (see the error column)" if failed else "")
    )
    print(format_table(table, list(grid)))
    return 0


def cmd_quality(args) -> int:
    from . import quality as Q
    from . import scenarios as sc

    _require_sim("quality")
    s, errors = _set_and_duration(sc.load(args.scenario), args)
    members = [s.data["mechanism"], *((s.data.get("set") or {}).get("members") or [])]
    for i, m in enumerate(members):
        if m["type"] not in Q.QUALITY_MECHANISMS:
            key = "mechanism" if i == 0 else f"set.members[{i - 1}]"
            errors.append(
                f"{args.scenario}: {key}.type {m['type']!r}: quality measures "
                f"{', '.join(Q.QUALITY_MECHANISMS)}"
            )
    if not errors:  # what run checks before it simulates, before anything is written
        from .builder import preflight

        try:
            preflight(s)
        except sc.ScenarioError as e:
            errors += e.messages
    if errors:
        raise UserError(*errors)
    out = _out_dir(args.out or Path("out") / f"{s.name}-quality")
    t0 = time.perf_counter()
    grid = (Q.MAP_KP, Q.MAP_KV) if args.map else None
    result = Q.measure_scenario(s, workers=args.workers, stability_map_grid=grid)
    files = Q.write_report(result, out)
    if args.json:
        print(Q.to_json(result))
    else:
        print("\n".join(Q.summary_lines(result)))
        print(f"wrote {out}/{', '.join(files)} ({time.perf_counter() - t0:.1f} s wall)")
    return 0


#: the summary table's columns: metric (virtmech.sim.output.METRICS), heading on two lines
#: (what, then the unit), width, format, scale from the metric's SI unit
SUMMARY_COLUMNS = (
    ("time_to_1mm_s", "to 1 mm", "[s]", 8, ".3f", 1.0),
    ("dist_max_after_m", "max after", "[mm]", 10, ".3f", 1e3),
    ("force_max_n", "max |f|", "[N]", 8, ".2f", 1.0),
    ("torque_fraction_max", "max tau", "/ limit", 8, ".2f", 1.0),
    ("passive_torque_max", "tau unpowered", "[N·m]", 14, ".2g", 1.0),
    ("energy_to_user_j", "work on user", "[mJ]", 13, ".2f", 1e3),
    ("real_time_factor", "x real", "time", 7, ".1f", 1.0),
)

#: what the summary table's columns say, printed under it
SUMMARY_NOTES = """\
to 1 mm: time_to_1mm_s; max after: dist_max_after_m; max |f|: force_max_n; max tau / limit:
torque_fraction_max; tau unpowered: passive_torque_max, the largest torque on a joint without
a motor (the Omni's gimbal), 0 as eq. 8 requires; work on user: energy_to_user_j, > 0 where
the device gave the user energy (the energy tank, on in omni-fig11-passive, keeps it near 0).
Definitions: docs/scenarios.md, "Distances and metrics"; every metric: run.json, summary.json"""


def _print_metrics(runs: dict) -> None:
    """The runs' headline metrics as a table in the paper's figure order, then what its
    columns say."""
    from .scenarios import paper_order

    w = max([16, *map(len, runs)])  # the names' column
    head = [f"{'scenario':<{w}}", f"{'':<{w}}"]
    for _, what, unit, width, _, _ in SUMMARY_COLUMNS:
        head[0] += f" {what:>{width}}"
        head[1] += f" {unit:>{width}}"
    print(head[0])
    print(head[1])
    missing: dict[str, list[str]] = {}  # name -> why its n/a cells do not apply

    def cell(name: str, key: str, width: int, fmt: str, scale: float = 1.0) -> str:
        v = runs[name][key]
        if v is None or v != v:  # None or NaN: the metric does not apply to the run
            why = (runs[name].get("notes") or {}).get(key, "")
            if why not in missing.setdefault(name, []):
                missing[name].append(why)
            return f"{'n/a':>{width}}"
        text = f"{v * scale:{width}{fmt}}"
        return text.replace("-", " ") if float(text) == 0.0 else text  # no "-0.00"

    for name in paper_order(runs):
        print(
            f"{name:<{w}}"
            + "".join(
                f" {cell(name, key, width, fmt, scale)}"
                for key, _, _, width, fmt, scale in SUMMARY_COLUMNS
            )
        )
    for name, whys in missing.items():
        for why in whys:  # the run's notes (run.json), else the general reason
            print(f"{name}: {why or 'n/a: the metric does not apply to that run'}")
    print(SUMMARY_NOTES)


def cmd_demo(args) -> int:
    from . import scenarios as sc

    _require_sim("demo")
    from .sim.output import write_summary
    from .viz import write_index

    known = sc.names()
    unknown = [n for n in args.only or () if n not in known]
    if unknown:
        raise UserError(
            f"--only: no shipped scenario named {', '.join(map(repr, unknown))}; expected "
            f"names from `virtmech scenarios`: {', '.join(known)}"
        )
    _require_format(args.format)
    out = _out_dir(args.out)
    names = list(dict.fromkeys(args.only)) if args.only else known  # each once, as given
    runs, entries = {}, []
    t0 = time.perf_counter()
    for name in names:
        s = sc.load(name)
        m = _run_one(s, out / name, None, not args.quiet, fmt=args.format)
        runs[name] = m
        entries.append(
            {
                "name": name,
                "description": " ".join(s.data["description"].split()),
                "dir": name,
                "log": f"log.{args.format}",
                "metrics": m,
            }
        )
    write_summary(runs, out / "summary.json")
    index = write_index(out, entries)
    _print_metrics(runs)
    print(
        f"virtmech demo: {len(names)} scenarios in {time.perf_counter() - t0:.1f} s; "
        f"report: {index}"
    )
    return 0


def cmd_view(args) -> int:
    _require_sim("view")
    try:
        import viser  # noqa: F401
    except ImportError:
        raise UserError(
            "virtmech view: the viewer needs the [view] extra (viser is not installed); "
            "install it with: pip install 'virtmech[view]'"
        ) from None
    from .view import serve

    return serve(
        args.source,
        port=args.port,
        host=args.host,
        state_port=args.state_port,
        open_browser=args.open,
        record_dir=args.record_dir,
        seed=args.seed,
    )


def cmd_drive(args) -> int:
    from . import drive
    from . import scenarios as sc

    try:
        scenario, note = drive.load(args.scenario)
    except sc.ScenarioError as e:
        raise UserError(*e.messages) from None
    _require_format(args.format)
    # made by drive.run once the device is open and the servo about to start: a run refused
    # before (an option, the library, another device) leaves no folder
    out = Path(args.out or Path("out") / f"{scenario.name}-drive")
    _can_make(out)
    if note and not args.quiet:
        print(f"virtmech drive: note: {note}", file=sys.stderr)
    try:
        r = drive.run(
            scenario,
            device=args.device,
            library=args.library,
            device_name=args.device_name,
            duration_s=args.duration,
            out=out,
            fmt=args.format,
            watchdog_ms=args.watchdog_ms,
            figures=args.figures,
            quiet=args.quiet,
            view_port=args.view,
        )
    except drive.DeviceFault as e:
        print(f"virtmech drive: {e}", file=sys.stderr)
        return 1
    st, dev = r.stats, r.info
    if st:
        print(
            f"{scenario.name}: drove {dev.get('model') or 'the device'} for "
            f"{st['elapsed_s']:.2f} s: {st['ticks']} ticks at {st['rate_hz']:.1f} Hz, "
            f"{st['late']} late, worst tick {st['worst_tick_us']:.0f} us; wrote "
            f"{out}/{', '.join(r.files)}"
        )
    print(f"virtmech drive: {r.message}", file=sys.stderr if r.exit_code else sys.stdout)
    return r.exit_code


def cmd_ros2(args) -> int:
    from . import drive
    from .ros2.runtime import require_ros

    require_ros("ros2")
    scenario, _ = drive.load(args.scenario)  # what a real device needs of the scenario
    scenario, _, errors = _with_sets(scenario, args.set)
    if args.duration is not None and not args.duration > 0:
        errors.append(f"--duration {args.duration:g}: expected a number of seconds > 0")
    if errors:
        raise UserError(*errors)
    from .ros2 import node

    return node.run(scenario, args.ros_args, args.duration)


def cmd_ros2_sim(args) -> int:
    from . import scenarios as sc
    from .ros2.runtime import require_ros

    _require_sim("ros2-sim")
    require_ros("ros2-sim")
    s, errors = _set_and_duration(sc.load(args.scenario), args)
    for flag, v in (("--timeout", args.timeout), ("--wait", args.wait)):
        if not v >= 0 or (flag == "--timeout" and not v > 0):
            errors.append(f"{flag} {v:g}: expected a number of seconds > 0")
    if errors:
        raise UserError(*errors)
    out = _out_dir(args.out) if args.out else None
    from .ros2 import sim_node

    return sim_node.run(
        s,
        args.ros_args,
        seed=args.seed,
        command=args.command_topic,
        lockstep=args.lockstep,
        timeout_s=args.timeout,
        wait_s=args.wait,
        velocity=args.velocity,
        out=out,
    )


def cmd_bench(argv: list[str]) -> int:
    from . import bench  # imported only when asked for

    return int(bench.main(argv))


def _integer(what: str, lo: int, hi: int | None = None):
    """An argparse type: an integer from lo to hi (None: no bound); else "expected <what>"."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if v < lo or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text}")
        return v

    return parse


_seed = _integer("an integer 0 to 2**63-1", 0, SEED_MAX)
_port = _integer("a port number 1 to 65534", 1, 65534)
_workers = _integer("a whole number >= 1", 1)


FORMAT_HELP = (
    "the log's file: csv (log.csv, default) or parquet (log.parquet; needs pyarrow: "
    "pip install 'virtmech[parquet]')"
)


class _Parser(argparse.ArgumentParser):
    """argparse's errors (usage, then the message; exit status 2) without the usage block:
    one line naming the flag, the value and what was expected, and where to read more."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def _add_demo(sub) -> None:
    """`virtmech demo`: every shipped scenario and the report."""
    d = sub.add_parser("demo", help="run every shipped scenario and write the report")
    d.add_argument("--out", default="out/demo", help="output folder (default: out/demo)")
    d.add_argument("--only", nargs="+", metavar="NAME", help="run only these scenarios")
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    d.add_argument("--format", choices=LOG_FORMATS, default="csv", help=FORMAT_HELP)


def _add_run(sub) -> None:
    """`virtmech run`: one scenario."""
    r = sub.add_parser("run", help="run one scenario (a TOML file or a shipped name)")
    r.add_argument("scenario", help="SCENARIO.toml or a name from `virtmech scenarios`")
    r.add_argument("--out", help="output folder (default: out/<name>)")
    r.add_argument("--seed", type=_seed, help="random seed, 0 to 2**63-1 (default: the scenario's)")
    r.add_argument("--duration", type=float, help="override duration_s [s]")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--format", choices=LOG_FORMATS, default="csv", help=FORMAT_HELP)
    r.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="set a scenario key, e.g. --set human.stiffness=300 --set controller.law=null_space "
        "(a dotted path; arrays by position: intent.1.force=[0,0,1]; values are TOML; "
        "repeatable)",
    )


def _add_sweep(sub) -> None:
    """`virtmech sweep`: a grid of runs."""
    w = sub.add_parser(
        "sweep", help="run a scenario over a grid of key values in parallel (docs/sweeps.md)"
    )
    w.add_argument("scenario", help="SCENARIO.toml or a name from `virtmech scenarios`")
    w.add_argument(
        "--grid",
        action="append",
        required=True,
        metavar="KEY=V1,V2,...",
        help="a key and its values (TOML, split at commas outside brackets: "
        "'mechanism.pivot=[0.3,0.1,0],[0.31,0.1,0]'); repeat for a Cartesian product",
    )
    w.add_argument("--out", help="output folder (default: out/<name>-sweep)")
    w.add_argument(
        "--backend",
        choices=("process", "ray"),
        default="process",
        help="process: a local process pool (default); ray: Ray tasks "
        '(pip install "virtmech[cluster]")',
    )
    w.add_argument("--address", help="the Ray cluster to connect to (default: a local Ray)")
    w.add_argument(
        "--workers", type=_workers, help="processes (Ray: tasks at once); default: all cores"
    )
    w.add_argument("--duration", type=float, help="override duration_s [s] at every point")
    w.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="set a key at every point (as run)"
    )
    w.add_argument(
        "--metric",
        default="dist_max_m",
        help="the metric sweep.png shows for two keys (a heat map) or more (default: "
        "dist_max_m; one key: six main metrics)",
    )
    w.add_argument("--quiet", action="store_true", help="no progress bar")


def _add_quality(sub) -> None:
    """`virtmech quality`: the rendering measured."""
    qp = sub.add_parser(
        "quality",
        help="measure the rendering: stiffness, forces along free motion, motor work, limit "
        "cycles, fidelity, stability map (docs/quality.md)",
    )
    qp.add_argument("scenario", help="SCENARIO.toml or a name: its device, mechanism, gains, hand")
    qp.add_argument("--out", help="output folder (default: out/<name>-quality)")
    qp.add_argument("--json", action="store_true", help="print the result as JSON")
    qp.add_argument(
        "--map", action="store_true", help="also the Kp x Kv stability map (about 10 s more)"
    )
    qp.add_argument("--workers", type=_workers, default=1, help="processes (default: 1)")
    qp.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="set a scenario key (as run)"
    )
    qp.set_defaults(duration=None)


def _add_view(sub) -> None:
    """`virtmech view`: the live viewer, or a run played back."""
    v = sub.add_parser(
        "view",
        help="a live 3-D viewer in the browser, the mouse as the hand; or a run's log played "
        "back (docs/viewer.md)",
    )
    v.add_argument(
        "source",
        nargs="?",
        default="omni-fig11",
        metavar="SCENARIO | LOG_DIR",
        help="a shipped scenario's name, a scenario file, or a folder written by `virtmech run` "
        "to play back (default: omni-fig11)",
    )
    v.add_argument("--port", type=_port, default=8080, help="the page's port (default: 8080)")
    v.add_argument(
        "--state-port",
        type=_port,
        help="the port of GET /state, the viewer's state as JSON (default: --port + 1)",
    )
    v.add_argument(
        "--host", default="127.0.0.1", help="the address to listen on (default: 127.0.0.1)"
    )
    v.add_argument("--open", action="store_true", help="open the page in a web browser")
    v.add_argument(
        "--no-browser",
        action="store_true",
        help="do not open a browser (the default; for scripts that say so)",
    )
    v.add_argument(
        "--record-dir",
        default="out/view",
        help="where the record button writes its runs (default: out/view)",
    )
    v.add_argument(
        "--seed", type=_seed, help="random seed of the sensor noise (default: the scenario's)"
    )


def _add_drive(sub) -> None:
    dr = sub.add_parser(
        "drive", help="render a scenario's mechanism on a real haptic device (docs/devices.md)"
    )
    dr.add_argument(
        "scenario",
        help="SCENARIO.toml or a shipped name: its [device], [mechanism] (or [set]) and "
        "[controller]",
    )
    dr.add_argument(
        "--device",
        choices=("openhaptics", "forcedimension"),
        default="openhaptics",
        help="the device's SDK: openhaptics (Touch, PHANTOM Omni; the default) or "
        "forcedimension (omega.3/6/7, sigma.7, Novint Falcon: [device] type = "
        "\"CartesianDevice\")",
    )
    dr.add_argument(
        "--library",
        metavar="PATH",
        help="the SDK's library (default: libHD.so on the loader's path, then /opt/OpenHaptics; "
        "libdhd.so on the loader's path)",
    )
    dr.add_argument(
        "--device-name",
        metavar="NAME",
        help="the device's name in the Touch setup tool (default: the default device)",
    )
    dr.add_argument("--duration", type=float, help="stop after this many seconds (default: Ctrl-C)")
    dr.add_argument("--out", help="output folder (default: out/<name>-drive)")
    dr.add_argument("--format", choices=LOG_FORMATS, default="csv", help=FORMAT_HELP)
    dr.add_argument(
        "--watchdog-ms",
        type=float,
        default=5.0,
        help="a tick this late zeroes the force, which then ramps in again (default: 5)",
    )
    dr.add_argument("--figures", action="store_true", help="also plane.png and time.png")
    dr.add_argument(
        "--view",
        type=_port,
        metavar="PORT",
        help="the viewer follows the device at http://127.0.0.1:PORT (needs the [view] extra)",
    )
    dr.add_argument("--quiet", action="store_true", help="no status line")


ROS_ARGS_HELP = (
    "everything after --ros-args goes to ROS 2: remappings (-r joint_states:=/phantom/"
    "joint_states), parameters (-p watchdog_s:=0.05, --params-file FILE); docs/ros2.md"
)


def _add_ros2(sub) -> None:
    """`virtmech ros2`: the renderer as a ROS 2 node."""
    r = sub.add_parser(
        "ros2",
        help="render a scenario's mechanism on a device served by a ROS 2 driver (docs/ros2.md)",
        epilog=ROS_ARGS_HELP,
    )
    r.add_argument(
        "scenario",
        help="SCENARIO.toml or a shipped name: its [device], [mechanism] (or [set]) and "
        "[controller]",
    )
    r.add_argument("--duration", type=float, help="stop after this many seconds (default: Ctrl-C)")
    r.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="set a scenario key (as run)"
    )


def _add_ros2_sim(sub) -> None:
    """`virtmech ros2-sim`: the simulated device as a ROS 2 driver."""
    from .ros2.sim_node import COMMANDS as ROS_COMMANDS

    r = sub.add_parser(
        "ros2-sim",
        help="serve a scenario's simulated device (MuJoCo, its hand) as a ROS 2 driver: "
        "joint_states out, the rendering node's commands in (docs/ros2.md)",
        epilog=ROS_ARGS_HELP,
    )
    r.add_argument("scenario", help="SCENARIO.toml or a name from `virtmech scenarios`")
    r.add_argument(
        "--command",
        dest="command_topic",
        choices=ROS_COMMANDS,
        default="joint_command",
        help="the topic whose commands drive the device (default: joint_command)",
    )
    r.add_argument(
        "--lockstep",
        action="store_true",
        help="each cycle waits for the command answering its joint state (a reproducible run "
        "at any load); default: real time",
    )
    r.add_argument(
        "--timeout",
        type=float,
        default=1.0,
        help="lockstep: the longest wait for a command [s] (default: 1); then the last one holds",
    )
    r.add_argument(
        "--wait",
        type=float,
        default=10.0,
        help="wait this long for the command topic's publisher before starting [s] (default: 10)",
    )
    r.add_argument(
        "--velocity", action="store_true", help="joint_states carry the sensed velocity too"
    )
    r.add_argument("--duration", type=float, help="override duration_s [s]")
    r.add_argument("--seed", type=_seed, help="random seed, 0 to 2**63-1 (default: the scenario's)")
    r.add_argument("--out", help="write log.csv and run.json (with the metrics) to this folder")
    r.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="set a scenario key (as run)"
    )


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = _Parser(
        prog="virtmech",
        description="virtmech: haptic devices rendered as virtual mechanisms (Luecke & Beckman).",
    )
    p.add_argument("--version", action="version", version=f"virtmech {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in (
        _add_demo, _add_run, _add_sweep, _add_quality, _add_view, _add_drive, _add_ros2,
        _add_ros2_sim,
    ):
        add(sub)
    sub.add_parser("scenarios", help="list the shipped scenarios")
    sub.add_parser("schema", help="print the JSON Schema of the scenario format")
    sub.add_parser("bench", help="benchmarks (arguments go to virtmech.bench)", add_help=False)
    return p


COMMANDS = {
    "demo": cmd_demo,
    "run": cmd_run,
    "scenarios": cmd_scenarios,
    "schema": cmd_schema,
    "sweep": cmd_sweep,
    "quality": cmd_quality,
    "view": cmd_view,
    "drive": cmd_drive,
    "ros2": cmd_ros2,
    "ros2-sim": cmd_ros2_sim,
}


def _split_ros_args(argv: list[str]) -> tuple[list[str], list[str]]:
    """A ROS 2 command's arguments and, from --ros-args on, ROS 2's own."""
    if argv and argv[0] in ("ros2", "ros2-sim") and "--ros-args" in argv:
        i = argv.index("--ros-args")
        return argv[:i], argv[i:]
    return argv, []


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status: 0, 2 for a mistake in the input (one
    message on stderr), 141 when stdout is closed early (`virtmech scenarios | head -3`)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv and argv[0] == "bench":
            return cmd_bench(argv[1:])
        p = build_parser()
        argv, ros_args = _split_ros_args(argv)
        args = p.parse_args(argv)
        args.ros_args = ros_args
        _refuse_empty(args)
        if args.command in COMMANDS:
            rc = COMMANDS[args.command](args)
        else:
            p.print_help()
            rc = 0
        sys.stdout.flush()  # here, so that a closed pipe is reported here
        return rc
    except UserError as e:
        where = f"virtmech {args.command}" if "args" in locals() and args.command else "virtmech"
        msg = str(e)
        if not msg.startswith("virtmech"):
            n = len(e.messages)
            msg = f"{where}: " + (msg if n == 1 else f"{n} mistakes:\n  " + "\n  ".join(e.messages))
        print(msg, file=sys.stderr)
        return 2
    except BrokenPipeError:
        _quiet_stdout()
        return 141  # 128 + SIGPIPE, as a program killed by the closed pipe
    except KeyboardInterrupt:
        print("virtmech: interrupted", file=sys.stderr)
        return 130


#: arguments that may not be empty: what an empty one would mean instead (a mistake)
_NOT_EMPTY = (
    ("out", "--out", "a folder name (empty: the current folder)"),
    ("record_dir", "--record-dir", "a folder name"),
    ("scenario", "SCENARIO", "a scenario file or a shipped scenario's name"),
    ("source", "SCENARIO | LOG_DIR", "a scenario or a run's folder"),
)


def _refuse_empty(args) -> None:
    """A UserError for an empty --out, SCENARIO, ... (given as '' on the command line)."""
    for attr, flag, expected in _NOT_EMPTY:
        value = getattr(args, attr, None)
        if isinstance(value, str) and not value.strip():
            raise UserError(f"{flag} {value!r}: expected {expected}")


def _quiet_stdout() -> None:
    """After a BrokenPipeError: stdout pointed at /dev/null so that Python's flush at exit
    does not fail again (and print a second error)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout replaced (e.g. by a test's capture)
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
