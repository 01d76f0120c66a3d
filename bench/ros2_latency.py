"""End-to-end message latency of the ROS 2 pair: `virtmech ros2-sim` (the simulated device as a
driver) against `virtmech ros2` (the renderer) over Fast DDS on loopback, in real time (a
joint state every period of the wall clock) and in lockstep (each cycle waits for its answer).

    .venv/bin/python bench/ros2_latency.py                     # omni-fig11, 10 s each mode
    .venv/bin/python bench/ros2_latency.py omni-fig11 --seconds 3.5 --mode lockstep

Prints per mode: the joint states sent and the commands that answered them, the round trip
(a joint state published to the command with its stamp received: DDS both ways and the
node's work; median, 99th percentile), the node's processor time per joint state (median,
99th percentile), the cycles the device ran behind the wall clock (real time), and the
largest distance from the mechanism against `virtmech run`'s over the same time. The pair
runs in a DDS domain of its own, discovery on this machine only. Needs the [ros2] extra.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import re
import signal
import subprocess
import sys
import tempfile
from pathlib import Path


def _env() -> dict:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(random.randint(150, 230))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def _virtmech(args: list[str], env: dict) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "virtmech", *args], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def measure(scenario: str, seconds: float, lockstep: bool, folder: Path) -> dict:
    env = _env()
    node = _virtmech(["ros2", scenario, "--ros-args", "-p", "marker_rate_hz:=0.0"], env)
    sim_args = ["ros2-sim", scenario, "--duration", str(seconds), "--out", str(folder),
                "--wait", "60"]
    sim = _virtmech(sim_args + (["--lockstep"] if lockstep else []), env)
    sim_out, sim_err = sim.communicate()
    node.send_signal(signal.SIGTERM)
    node_out, node_err = node.communicate(timeout=60)
    if sim.returncode != 0 or node.returncode != 0:
        raise SystemExit(f"ros2-sim: {sim_err.strip()}\nros2: {node_err.strip()}")
    run = json.loads((folder / "run.json").read_text())
    work = re.search(r"processor time per joint state median (\d+) µs, p99 (\d+) µs", node_out)
    return {
        **run["ros2_sim"],
        "dist_max_mm": run["metrics"]["dist_max_m"] * 1e3,
        "work_median_us": float(work.group(1)) if work else float("nan"),
        "work_p99_us": float(work.group(2)) if work else float("nan"),
    }


def reference_mm(scenario: str, seconds: float, folder: Path) -> float:
    from virtmech import scenarios as sc
    from virtmech.runner import run_scenario

    s = sc.load(scenario).with_overrides(duration_s=seconds)
    folder.mkdir(parents=True)
    return run_scenario(s, out=folder).metrics["dist_max_m"] * 1e3


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenario", nargs="?", default="omni-fig11")
    p.add_argument("--seconds", type=float, default=10.0, help="simulated time per mode [s]")
    p.add_argument("--mode", choices=["both", "realtime", "lockstep"], default="both")
    a = p.parse_args(argv)
    modes = {"both": (False, True), "realtime": (False,), "lockstep": (True,)}[a.mode]
    print(f"{platform.node()}: {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; Python "
          f"{platform.python_version()}; {a.scenario}, {a.seconds:g} s")
    with tempfile.TemporaryDirectory() as tmp:
        ref = reference_mm(a.scenario, a.seconds, Path(tmp) / "ref")
        print(f"virtmech run: dist max {ref:.3f} mm")
        print("mode       joint states  answered  round trip median  p99 [ms]  node work "
              "median  p99 [µs]  behind  dist max [mm]")
        for lockstep in modes:
            r = measure(a.scenario, a.seconds, lockstep, Path(tmp) / str(lockstep))
            print(f"{'lockstep' if lockstep else 'real time':<10} {r['cycles']:>12} "
                  f"{r['round_trip_count']:>9} {r['round_trip_median_ms']:>18.3f} "
                  f"{r['round_trip_p99_ms']:>9.3f} {r['work_median_us']:>17.0f} "
                  f"{r['work_p99_us']:>9.0f} {r['realtime_behind']:>7} "
                  f"{r['dist_max_mm']:>14.3f}   (load {os.getloadavg()[0]:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
