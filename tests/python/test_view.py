"""virtmech view: the page draws the device in a real browser (Debian's Chromium through
Playwright), dragging the hand's gizmo with the mouse moves the simulated handle and the
device pushes back as eq. 26 says, a replay shows the logged handle pose, a recording is
a `virtmech run` log, and mistakes end with one line and exit status 2.

The browser test does not skip: without Playwright or /usr/bin/chromium it fails (the test
extra installs Playwright, scripts/setup.sh installs Chromium; never `playwright install`).
"""

from __future__ import annotations

import csv
import io
import json
import math
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")
pytest.importorskip("matplotlib")

import virtmech.scenarios as sc  # noqa: E402
from virtmech.cli import main  # noqa: E402
from virtmech.sim.log import log_columns  # noqa: E402

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--use-gl=angle", "--use-angle=swiftshader"]
CHROMIUM_ARGS += ["--enable-unsafe-swiftshader"]
#: the page's notifications (viser's "software rendering" note) hidden over the canvas
HIDE_NOTIFICATIONS = ".mantine-Notifications-root { display: none !important; }"


def free_port_pair() -> int:
    """A port p with p and p + 1 free (the page and the state endpoint)."""
    for _ in range(50):
        with socket.socket() as a:
            a.bind(("127.0.0.1", 0))
            p = a.getsockname()[1]
            if p >= 65535:
                continue
            try:
                with socket.socket() as b:
                    b.bind(("127.0.0.1", p + 1))
            except OSError:
                continue
            return p
    raise RuntimeError("no free pair of ports")


def get_state(port: int) -> dict:
    with urllib.request.urlopen(f"http://127.0.0.1:{port + 1}/state", timeout=5) as r:
        return json.load(r)


def wait_state(port: int, ok, timeout: float = 20.0, what: str = "") -> dict:
    """The first state for which ok(state) holds, polled; fails after `timeout` seconds."""
    t_end = time.monotonic() + timeout
    last = None
    while time.monotonic() < t_end:
        try:
            last = get_state(port)
            if ok(last):
                return last
        except OSError:
            pass
        time.sleep(0.1)
    pytest.fail(f"timed out waiting for {what}; last state: {last}")


def project(X, cam: dict, box: dict) -> tuple[float, float]:
    """Page pixel of the world point X seen by the camera (position, look_at, up, vertical
    fov) on the canvas at `box` (three.js' perspective projection)."""
    pos, look, up = (np.asarray(cam[k], dtype=float) for k in ("position", "look_at", "up"))
    f = look - pos
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    v = np.asarray(X, dtype=float) - pos
    t = math.tan(cam["fov"] / 2)
    nx = (v @ r) / ((v @ f) * t * box["width"] / box["height"])
    ny = (v @ u) / ((v @ f) * t)
    return box["x"] + (nx + 1) / 2 * box["width"], box["y"] + (1 - ny) / 2 * box["height"]


def device_pixels(png: bytes) -> tuple[float, int]:
    """(standard deviation of the grey levels, count of the device's orange pixels)."""
    from matplotlib.image import imread

    img = imread(io.BytesIO(png), format="png")[..., :3] * 255.0
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    orange = (r > 120) & (r - g > 40) & (g - b > 20) & (b < 0.5 * r)
    return float(img.mean(axis=2).std()), int(orange.sum())


#: what the page's uPlot charts drew: each axis's labels, its width and the room above
#: the plot, the measured width of each label [CSS px]
PLOTS_JS = """() => Object.values((window.__viserTestpoints || {}).uplots || {}).map(tp => {
  const u = tp.chart, ctx = u.ctx;
  return {
    title: u.root.querySelector('.u-title')?.textContent,
    points: u.data[0].length,
    top: u.bbox.top / devicePixelRatio,
    axes: u.axes.map(a => {
      ctx.font = a.font[0];
      return {values: a._values || [], size: a._size, gap: a.gap, ticks: a.ticks.size,
              font_px: a.font[1], widths: (a._values || []).map(v => ctx.measureText(v).width)};
    }),
  };
})"""


def check_plots(page) -> None:
    """The plots' y axes at rest: labels that differ and rise up the axis, none wider than
    the axis nor cut at the top, and the page says why |f| flickers at rest."""
    t_end = time.monotonic() + 20
    while True:
        plots = page.evaluate(PLOTS_JS)
        if (len(plots) == 3 and all(p["points"] > 10 for p in plots)) or time.monotonic() > t_end:
            break
        time.sleep(0.3)
    assert sorted(p["title"] for p in plots) == [
        "distance from the mechanism", "energy", "force at the handle"]
    for p in plots:
        y = p["axes"][1]
        shown = [float(v.replace("\u2212", "-").replace(",", "")) for v in y["values"]]
        assert len(shown) >= 2 and all(a < b for a, b in zip(shown, shown[1:])), (p, shown)
        for w in y["widths"]:  # the label, its gap and the tick fit in the axis
            assert w + y["gap"] + y["ticks"] <= y["size"], p
        assert p["top"] >= y["font_px"] / 2, p  # the top label is not cut in half
    text = page.inner_text("body")
    assert "flickers" in text and "counts_per_rev" in text


def test_the_page_draws_the_device_and_the_mouse_moves_the_hand():
    from playwright.sync_api import sync_playwright  # the test extra installs it

    assert CHROMIUM.exists(), (
        f"{CHROMIUM} is missing: install Debian's chromium (apt-get install chromium; "
        "scripts/setup.sh test does so as root)"
    )
    port = free_port_pair()
    proc = subprocess.Popen(
        [sys.executable, "-m", "virtmech", "view", "omni-fig11", "--port", str(port)]
        + ["--no-browser"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            s0 = wait_state(port, lambda s: s["t"] > 0.5, what="the simulation to run")
            page = browser.new_page(viewport={"width": 900, "height": 560})
            page.goto(f"http://127.0.0.1:{port}/", timeout=60000)
            page.wait_for_selector("canvas", timeout=60000)
            page.add_style_tag(content=HIDE_NOTIFICATIONS)
            wait_state(port, lambda s: s["clients"] >= 1, what="the page to connect")
            canvas = page.locator("canvas").first

            # the scene is drawn: not blank, and the device's orange links are there
            t_end = time.monotonic() + 20
            while True:
                spread, orange = device_pixels(canvas.screenshot())
                if orange > 400 or time.monotonic() > t_end:
                    break
                time.sleep(0.3)
            assert spread > 10, f"the canvas is blank (grey-level deviation {spread:.1f})"
            assert orange > 400, f"the device is not drawn ({orange} orange pixels)"
            check_plots(page)

            # the mouse is the hand: drag the gizmo's x arrow 20 mm along +x
            s0 = get_state(port)
            p0 = np.array(s0["target"]["position"])
            h0 = np.array(s0["handle"]["position"])
            box = canvas.bounding_box()
            reach = s0["gizmo_scale"]
            a = project(p0 + [0.7 * reach, 0, 0], s0["camera"], box)
            b = project(p0 + [0.7 * reach + 0.02, 0, 0], s0["camera"], box)
            page.mouse.move(*a)
            page.mouse.down()
            for i in range(1, 11):
                page.mouse.move(a[0] + (b[0] - a[0]) * i / 10, a[1] + (b[1] - a[1]) * i / 10)
                time.sleep(0.03)
            page.mouse.up()
            moved = wait_state(
                port,
                lambda s: np.array(s["target"]["position"])[0] - p0[0] > 0.01,
                timeout=10,
                what="the gizmo to move the target",
            )
            browser.close()
        # the handle settles where the hand's spring and the device's balance
        t_end = time.monotonic() + 10
        prev = moved
        while True:
            time.sleep(0.3)
            s1 = get_state(port)
            step = np.subtract(s1["handle"]["position"], prev["handle"]["position"])
            if np.linalg.norm(step) < 2e-4 or time.monotonic() > t_end:
                break
            prev = s1
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
    assert proc.returncode == 0, err
    assert "Traceback" not in err, err

    target = np.array(s1["target"]["position"])
    assert 0.01 < target[0] - p0[0] < 0.04  # the drag moved the target along x only
    assert np.abs(target[1:] - p0[1:]).max() < 1e-3
    # the handle followed, part of the way: the device holds it near the circle
    h = np.array(s1["handle"]["position"])
    assert h[0] - h0[0] > 0.002
    assert h[0] < target[0]
    # eq. 26 on the Omni's PlanarArm: the force pulls the handle back to the circle,
    # along the way it left it, with the stiffness kp, and is the null- plus the
    # range-space part
    mech = sc.load("omni-fig11").data["mechanism"]
    c, n, L = np.array(mech["pivot"]), np.array(mech["normal"]), mech["length"]
    w = h - c
    w_in = w - (w @ n) * n
    d = h - (c + L * w_in / np.linalg.norm(w_in))  # from the nearest point of the circle
    f = np.array(s1["wrench"][:3])
    kp = s1["settings"]["kp"]
    assert np.linalg.norm(d) > 0.002
    assert f @ -d / (np.linalg.norm(f) * np.linalg.norm(d)) > 0.95, (f, d)
    assert np.linalg.norm(f) == pytest.approx(kp * np.linalg.norm(d), rel=0.2)
    parts = np.add(s1["wrench_null"], s1["wrench_range"])
    np.testing.assert_allclose(s1["wrench"], parts, atol=1e-9)
    assert np.linalg.norm(s1["wrench_range"][:3]) > 0.01  # the gimbal's missing moments
    assert s1["real_time_factor"] > 0.5
    assert s1["frame_rate_hz"] > 5


@pytest.fixture(scope="module")
def logged_run(tmp_path_factory) -> Path:
    """A `virtmech run` folder of omni-fig11, one second long."""
    from virtmech import sim
    from virtmech.sim.output import write_run

    out = tmp_path_factory.mktemp("fig11")
    r = sim.run(sc.load("omni-fig11").with_overrides(duration_s=1.0))
    write_run(r, out)
    return out


def read_log(path: Path) -> tuple[list[str], np.ndarray]:
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def test_replay_shows_the_logged_handle_pose_and_plays_at_its_speed(logged_run):
    from virtmech.view.server import ViewServer

    header, log = read_log(logged_run / "log.csv")
    col = {c: i for i, c in enumerate(header)}
    v = ViewServer(logged_run, port=free_port_pair()).start()
    try:
        assert v.mode == "replay"
        for t in (0.0, 0.4567, 0.75, 1.0):
            v.seek(t)
            s = v.state()
            row = log[np.flatnonzero(log[:, col["t"]] <= t + 1e-9)[-1]]
            assert s["t"] == row[col["t"]]
            # the drawn handle comes from the logged joint values through the device's
            # kinematics; it is where the log says the handle was
            np.testing.assert_allclose(
                s["handle"]["position"], row[[col["px"], col["py"], col["pz"]]], atol=1e-9
            )
            np.testing.assert_allclose(
                s["handle"]["stylus"], row[[col["sx"], col["sy"], col["sz"]]], atol=1e-8
            )
            np.testing.assert_allclose(s["wrench"], row[col["fx"] : col["fx"] + 6])
        assert get_state(v.port)["t"] == 1.0  # GET /state says the same
        v.seek(0.0)
        v.speed = 2.0
        t0 = time.monotonic()
        v.playing = True
        time.sleep(0.4)
        v.playing = False
        wall = time.monotonic() - t0
        assert 1.2 * wall < v.state()["t"] <= 2.0 * wall + 0.1
    finally:
        v.stop()


def test_a_recording_is_a_run_log_that_replays(tmp_path):
    from virtmech.view.live import LiveSim
    from virtmech.view.replay import Replay

    live = LiveSim("omni-fig11")
    live.step(50)
    live.start_recording(tmp_path)
    live.set_target(live.target_p + [0.0, 0.0, 0.01])
    for _ in range(60):
        live.step(5)
    live.stop_recording().finish()
    header, log = read_log(tmp_path / "log.csv")
    assert header == log_columns(live.n, live.m)  # the columns of `virtmech run`
    assert len(log) == 300
    np.testing.assert_allclose(log[:, 0], np.arange(300) * 1e-3, atol=1e-12)
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["name"] == "omni-fig11" and run["cycles"] == 300
    assert run["metrics"]["force_max_n"] > 0.5  # the hand pulled off the circle
    f = Replay(tmp_path).frame(0.2)
    np.testing.assert_allclose(f["handle"][:3, 3], f["logged_handle_p"], atol=1e-9)


def test_mistakes_are_one_line_and_exit_2(tmp_path, capsys):
    r = subprocess.run(
        [sys.executable, "-m", "virtmech", "view", "no-such-scenario", "--port", "8123"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "SCENARIO no-such-scenario" in r.stderr and "omni-fig11" in r.stderr

    assert main(["view", str(tmp_path / "missing") + "/"]) == 2
    assert "LOG_DIR" in capsys.readouterr().err
    assert main(["view", str(tmp_path)]) == 2  # a folder without a run
    assert "no run.json" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # argparse's own error: exit status 2
        main(["view", "omni-fig11", "--port", "70000"])
    assert e.value.code == 2
    assert "--port: expected a port number 1 to 65534, got 70000" in capsys.readouterr().err
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["view", "omni-fig11", "--port", str(port)]) == 2
        err = capsys.readouterr().err
        assert f"--port {port}: cannot listen" in err and err.count("\n") == 1
    # an address that is not this machine's: the host named, not the port
    assert main(["view", "omni-fig11", "--host", "8.8.8.8", "--port", "8173"]) == 2
    err = capsys.readouterr().err
    assert "--host 8.8.8.8: cannot listen on it" in err and "--port" not in err


def test_a_driven_device_s_target_sits_on_the_handle_its_readings_give():
    # a tick whose cycle faulted logs no handle pose of the controller's (px zero): the target
    # still sits where the joint readings put the handle, as the frame's handle does
    from virtmech.builder import build
    from virtmech.view.device import DeviceFeed

    rig = build("omni-fig11", simulated=False)
    feed = DeviceFeed(rig)
    q = np.array([0.05, 0.45, -0.10, 0.20, 0.60, 0.10])
    row = np.zeros((1, len(feed.columns)))
    row[0, feed.col["t"]] = 0.001
    row[0, feed.col["q0"] : feed.col["q0"] + 6] = q
    feed.append(row, list(feed.columns))
    f = feed.frame(0.001)
    handle = rig.device.forward(q)[:3, 3]
    np.testing.assert_array_equal(f["handle"][:3, 3], handle)
    np.testing.assert_array_equal(f["target_p"], handle)
