"""Real time of `virtmech view`'s simulation: the scenario's device and controller at 1 kHz
with MuJoCo at the scenario's physics rate, stepped by the viewer's pacer (a background
thread running the cycles that are due every 5 ms of wall time) while the hand's target
moves on a circle, as a mouse would drag it.

    .venv/bin/python bench/view_realtime.py          # omni-fig11, planar3r-fig11, arm7-contact
    .venv/bin/python bench/view_realtime.py omni-fig11 --seconds 10 --server

Prints per scenario: the wall time of each stretch of cycles (median, 99th percentile,
largest) and cycles per stretch, the real-time factor (simulated over wall time over the
run: 1.00 is real time), the share of one core the stepping takes, and the headroom (how
many times faster than real time the same stretches run back to back). --server also
serves the viewer (viser, the view's 30 Hz loop, the state endpoint; no browser attached)
while measuring.
"""

from __future__ import annotations

import argparse
import math
import socket
import time

import numpy as np


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def measure(name: str, seconds: float, server: bool) -> dict:
    from virtmech.view.live import LiveSim, Pacer

    viewer = None
    if server:
        from virtmech.view.server import ViewServer

        port = free_port()
        while True:  # the state endpoint takes port + 1
            try:
                viewer = ViewServer(name, port=port).start()
                break
            except Exception:
                port = free_port()
        pacer = viewer.pacer
    else:
        pacer = Pacer(LiveSim(name))
        pacer.start()
    sim = pacer.sim
    p0 = sim.target_p.copy()
    k0, wall0 = sim.k, time.perf_counter()
    pacer.chunk_times.clear()
    t_end = wall0 + seconds
    while time.perf_counter() < t_end:  # the target on a 1 cm circle at 0.5 Hz
        a = 2 * math.pi * 0.5 * (time.perf_counter() - wall0)
        sim.set_target(p0 + 0.01 * np.array([math.cos(a) - 1.0, math.sin(a), 0.0]))
        time.sleep(1 / 60)
    wall = time.perf_counter() - wall0
    cycles = sim.k - k0
    chunks = np.array(pacer.chunk_times)
    if viewer is not None:
        viewer.stop()
    else:
        pacer.stop()
    # headroom: the same work back to back, 5 cycles a stretch
    t0 = time.perf_counter()
    n = 2000
    for _ in range(n // 5):
        sim.step(5)
    headroom = n * sim.T / (time.perf_counter() - t0)
    return {
        "scenario": name,
        "rtf": cycles * sim.T / wall,
        "load": chunks.sum() / wall,
        "median_ms": 1e3 * float(np.median(chunks)),
        "p99_ms": 1e3 * float(np.percentile(chunks, 99)),
        "max_ms": 1e3 * float(chunks.max()),
        "cycles_per_chunk": cycles / len(chunks),
        "headroom": headroom,
        "physics_hz": 1.0 / (sim.T / sim.nsub),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenarios", nargs="*", default=["omni-fig11", "planar3r-fig11", "arm7-contact"])
    p.add_argument("--seconds", type=float, default=5.0, help="wall time per scenario [s]")
    p.add_argument("--server", action="store_true", help="also serve the viewer meanwhile")
    args = p.parse_args()
    print(
        f"{'scenario':<16} {'physics':>8} {'real time':>9} {'load':>6} {'stretch median':>14} "
        f"{'p99':>7} {'max':>7} {'cycles':>6} {'headroom':>8}"
    )
    for name in args.scenarios:
        r = measure(name, args.seconds, args.server)
        print(
            f"{r['scenario']:<16} {r['physics_hz']:>6.0f}Hz {r['rtf']:>8.3f}x "
            f"{100 * r['load']:>5.1f}% "
            f"{r['median_ms']:>11.3f} ms {r['p99_ms']:>4.2f}ms {r['max_ms']:>4.2f}ms "
            f"{r['cycles_per_chunk']:>6.1f} {r['headroom']:>7.1f}x"
        )


if __name__ == "__main__":
    main()
