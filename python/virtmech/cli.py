"""The ``virtmech`` command (also ``python -m virtmech``).

virtmech demo [--out DIR]             every shipped scenario, summary.json, index.html
virtmech run SCENARIO [--out DIR]     one scenario (a TOML path or a shipped name)
             [--engine python]        ... with the simulation loop in Python (the reference)
virtmech scenarios                    the shipped scenarios
virtmech bench [ARGS...]              benchmarks (virtmech.bench)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def _run_one(scenario, out_dir: Path, seed, progress: bool, engine: str = "compiled") -> dict:
    from . import sim
    from .sim.output import metrics, write_run
    from .viz import write_figures

    result = sim.run(scenario, seed=seed, progress=progress, engine=engine)
    write_run(result, out_dir)
    write_figures(result, out_dir)
    return metrics(result)


def cmd_scenarios(args) -> int:
    from . import scenarios as sc

    for name in sc.names():
        s = sc.load(name)
        first = " ".join(s.data["description"].split())
        first = first.split(": ", 1)[0]
        print(f"{name:<16} {s.duration_s:5.1f} s  {first}")
    return 0


def cmd_run(args) -> int:
    from . import scenarios as sc

    try:
        s = sc.load(args.scenario)
        if args.duration is not None:
            s = s.with_overrides(duration_s=args.duration)
    except sc.ScenarioError as e:
        print(f"virtmech run: {e}", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else Path("out") / s.name
    m = _run_one(s, out, args.seed, not args.quiet, args.engine)
    print(f"{s.name}: wrote {out}/log.csv, run.json, plane.png, time.png")
    _print_metrics({s.name: m})
    return 0


def _print_metrics(runs: dict) -> None:
    print(
        f"{'scenario':<16} {'to 1 mm [s]':>11} {'max after [mm]':>14} {'max |f| [N]':>11} "
        f"{'tau/limit':>9} {'passive':>8} {'E [mJ]':>8} {'x real':>7}"
    )
    for name, m in runs.items():
        t1 = m["time_to_1mm_s"]
        print(
            f"{name:<16} {t1:11.3f} {m['dist_max_after_m'] * 1e3:14.3f} {m['force_max_n']:11.2f} "
            f"{m['torque_fraction_max']:9.2f} {m['passive_torque_max']:8.2g} "
            f"{m['energy_to_user_j'] * 1e3:8.2f} {m['real_time_factor']:7.1f}"
        )


def cmd_demo(args) -> int:
    from . import scenarios as sc
    from .sim.output import write_summary
    from .viz import write_index

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = args.only or sc.names()
    runs, entries = {}, []
    t0 = time.perf_counter()
    for name in names:
        s = sc.load(name)
        m = _run_one(s, out / name, None, not args.quiet)
        runs[name] = m
        entries.append(
            {
                "name": name,
                "description": " ".join(s.data["description"].split()),
                "dir": name,
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


def cmd_bench(argv: list[str]) -> int:
    from . import bench  # written for issue 4; imported only when asked for

    return int(bench.main(argv))


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = argparse.ArgumentParser(
        prog="virtmech",
        description="virtmech: haptic devices rendered as virtual mechanisms (Luecke & Beckman).",
    )
    p.add_argument("--version", action="version", version=f"virtmech {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    d = sub.add_parser("demo", help="run every shipped scenario and write the report")
    d.add_argument("--out", default="out/demo", help="output folder (default: out/demo)")
    d.add_argument("--only", nargs="+", metavar="NAME", help="run only these scenarios")
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    r = sub.add_parser("run", help="run one scenario (a TOML file or a shipped name)")
    r.add_argument("scenario", help="SCENARIO.toml or a name from `virtmech scenarios`")
    r.add_argument("--out", help="output folder (default: out/<name>)")
    r.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    r.add_argument("--duration", type=float, help="override duration_s [s]")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument(
        "--engine",
        choices=("compiled", "python"),
        default="compiled",
        help="the simulation loop: compiled (default) or the Python reference (slower)",
    )
    sub.add_parser("scenarios", help="list the shipped scenarios")
    sub.add_parser("bench", help="benchmarks (arguments go to virtmech.bench)", add_help=False)
    return p


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "bench":
        return cmd_bench(argv[1:])
    p = build_parser()
    args = p.parse_args(argv)
    if args.command == "demo":
        return cmd_demo(args)
    if args.command == "run":
        return cmd_run(args)
    if args.command == "scenarios":
        return cmd_scenarios(args)
    p.print_help()
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
