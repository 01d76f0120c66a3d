"""Rendering quality on the simulated Omni (virtmech.quality), with the shipped defaults
(energy tank on, Kp 1.2 N/mm) and with the paper's law as written (passivity off), each
figure a claim the simulation could contradict."""

from __future__ import annotations

import json
import subprocess
import sys
from itertools import product

import numpy as np
import pytest

import virtmech as vm
from virtmech import quality as Q

pytest.importorskip("mujoco")

DEFAULT = "omni-fig11-passive"  # the Fig. 11 circle with every controller default
HANDS = [dict(zip(Q.HUMAN_GRID, v)) for v in product(*Q.HUMAN_GRID.values())]


@pytest.fixture(scope="module")
def default():
    s = Q.Setup(DEFAULT)
    assert "kp" not in s.raw["controller"] and "passivity" not in s.raw["controller"]
    rest = s.start()
    return s, rest


@pytest.fixture(scope="module")
def paper_law():
    s = Q.Setup(DEFAULT, controller={"passivity": "off"})
    return s, s.start()


def test_default_gains_render_at_least_1_n_per_mm_and_1_mm_at_1_n(default):
    s, rest = default
    st = Q.stiffness(s, rest=rest)
    assert set(st) == {"radial", "normal"}  # every constrained axis of the circle
    for axis, d in st.items():
        assert d["stiffness_n_per_m"] >= 1000.0, axis
        assert 0.0 < d["deviation_m"]["1"] <= 1e-3, axis
        # linear: half the force, half the deviation (within friction and quantisation)
        assert d["deviation_m"]["0.5"] == pytest.approx(d["deviation_m"]["1"] / 2, rel=0.1)
    assert vm.PhantomOmni().stiffness == pytest.approx(1200.0)


def test_a_probe_pressed_into_its_plane_is_as_stiff():
    import virtmech.scenarios as sc

    on_plane = sc.load("omni-contact").with_keys({"initial.offset": [0.0, 0.0, 0.0]})
    st = Q.stiffness(Q.Setup(on_plane))
    d = st["into the plane"]
    assert d["stiffness_n_per_m"] >= 1000.0
    assert 0.0 < d["deviation_m"]["1"] <= 1e-3


def test_no_hand_of_the_grid_nor_a_released_handle_limit_cycles_at_the_defaults(default):
    s, rest = default
    lc = Q.limit_cycles(s, rest=rest)
    assert lc["total"] == len(HANDS) + 1 == 28
    assert lc["stable"] == lc["total"], [h for h in lc["hands"] if h["limit_cycle"]]


@pytest.mark.parametrize("passivity", ["energy_tank", "off"])
def test_twice_the_default_kp_is_still_free_of_limit_cycles(passivity):
    # the default is at most half of the smallest Kp at which any hand of the grid or the
    # released handle limit-cycles
    kp = 2 * vm.PhantomOmni().stiffness
    s = Q.Setup(DEFAULT, controller={"passivity": passivity})
    m = Q.stability_map(s, kp=[kp], kv=[vm.PhantomOmni().damping], hands=HANDS)
    assert m["stable"] == [[True]]


def test_the_limit_cycle_detector_finds_one_beyond_the_stability_limit():
    s = Q.Setup(DEFAULT, controller={"passivity": "off"})
    m = Q.stability_map(s, kp=[5000.0], kv=[0.5], hands=HANDS[:1])
    assert m["stable"] == [[False]]


def test_the_default_is_passive_a_released_handle_stays_and_closed_runs_give_nothing(default):
    s, rest = default
    w = Q.work(s, rest=rest)
    assert w["released"]["travel_deg"] <= 2.0
    for name, d in w.items():
        assert d["net_work_j"] <= 0.1e-3, name
    assert w["tap radial"]["net_work_j"] < 0  # the user put energy in; damping kept some


def test_the_papers_law_moves_a_released_handle_with_the_motors_energy(paper_law):
    # what the tank prevents: eq. 26 as written walks the released handle along the circle
    s, rest = paper_law
    w = Q.work(s, rest=rest)
    assert w["released"]["travel_deg"] > 20.0
    assert w["released"]["net_work_j"] > 5e-3
    assert w["twist strokes"]["net_work_j"] > 5e-3


def test_no_force_along_the_free_direction_at_the_defaults(default, paper_law):
    s, rest = default
    ff = Q.free_force(s, rest=rest)
    assert abs(ff["0.05"]["mean_n"]) <= 0.05
    assert ff["0.05"]["cycles"] > 500  # the hand moved at speed for more than half a second
    s_off, rest_off = paper_law
    assert Q.free_force(s_off, speeds=[0.05], rest=rest_off)["0.05"]["mean_n"] > 0.1


def test_fidelity_tells_where_eq_26_wins_and_where_it_does_not():
    contact = Q.fidelity(Q.Setup("omni-contact"))
    # a probe pressed on a plane: eq. 11 renders no force at all on the Omni (the push is a
    # range-space force); eq. 26 and the naive law render what the full device does
    assert contact["fully actuated"]["force_rms_n"] > 0.5
    assert contact["eq. 11"]["relative_rms_error"] > 0.99
    assert contact["eq. 26"]["relative_rms_error"] < 0.05
    assert contact["eq. 26, passive"]["relative_rms_error"] < 0.05
    resist = Q.fidelity(Q.Setup("omni-fig12"))
    # a user resisting a twist: eq. 26 pushes more than twice as hard as the full device
    assert resist["eq. 26"]["force_rms_n"] > 2 * resist["fully actuated"]["force_rms_n"]
    assert resist["eq. 26"]["relative_rms_error"] > resist["eq. 11"]["relative_rms_error"]


def test_the_fully_actuated_variant_of_an_omega6_is_the_sigma7():
    assert Q.fully_actuated_variant({"type": "CartesianDevice", "model": "omega.6"}) == {
        "model": "sigma.7"
    }
    assert Q.fully_actuated_variant({"type": "CartesianDevice", "model": "omega.7"}) == {
        "model": "sigma.7"
    }
    for model in ("sigma.7", "falcon", "omega.3"):  # driven where sensed already
        assert Q.fully_actuated_variant({"type": "CartesianDevice", "model": model}) is None
    assert Q.fully_actuated_variant({"type": "PhantomOmni"}) == {"actuated": [True] * 6}


def test_an_omega6_renders_its_stiffness_and_its_fidelity_against_a_sigma7():
    # the omega.6 of the Fig. 11 circle: stiff across the circle; and the Fig. 12 twist,
    # which a sigma.7 resists with a moment the omega.6 cannot give: eq. 26 pushes the
    # handle sideways instead, harder than the sigma.7's force (as on the Omni)
    s = Q.Setup("omega6-fig11")
    st = Q.stiffness(s, rest=s.start())
    assert st["radial"]["stiffness_n_per_m"] >= 0.8 * 500.0
    resist = Q.fidelity(Q.Setup("omega6-fig12"))
    assert set(resist) == {"fully actuated", *Q.LAWS}
    assert resist["fully actuated"]["force_rms_n"] > 0.1
    assert resist["eq. 26"]["force_rms_n"] > resist["fully actuated"]["force_rms_n"]
    assert resist["eq. 11"]["relative_rms_error"] < resist["eq. 26"]["relative_rms_error"]


def test_the_limit_cycle_measure_is_the_ac_rms_of_the_force():
    t = np.arange(0, 2.0, 1e-3)
    f = np.zeros((len(t), 3))
    f[:, 1] = 0.5 * np.sin(2 * np.pi * 40 * t) + 1.0  # 0.5 N amplitude about 1 N
    cols = {"t": t, "fx": f[:, 0], "fy": f[:, 1], "fz": f[:, 2]}
    r = Q.limit_cycle(Q.Run(cols, np.zeros((len(t), 1)), np.zeros((len(t), 1))))
    assert r["rms_last_n"] == pytest.approx(0.5 / np.sqrt(2), rel=5e-3)  # whole periods, +-1
    assert r["limit_cycle"] and not r["quiet"]
    cols["fy"] = 1.0 + 0.5 * np.exp(-t / 0.05) * np.sin(2 * np.pi * 40 * t)  # decays
    r = Q.limit_cycle(Q.Run(cols, np.zeros((len(t), 1)), np.zeros((len(t), 1))))
    assert not r["limit_cycle"] and r["quiet"]


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "virtmech", *args], capture_output=True, text=True, timeout=120
    )


def test_cli_writes_the_report_and_json(tmp_path):
    r = run_cli("quality", "omni-fig11-passive", "--out", str(tmp_path / "q"), "--json")
    assert r.returncode == 0, r.stderr
    result = json.loads(r.stdout)
    assert result["stiffness"]["radial"]["stiffness_n_per_m"] >= 1000.0
    assert set(result["fidelity"]) == {"fully actuated", *Q.LAWS}
    written = sorted(p.name for p in (tmp_path / "q").iterdir())
    assert written == ["fidelity.png", "index.html", "quality.json"]
    assert json.loads((tmp_path / "q" / "quality.json").read_text()) == result


def test_cli_mistakes_exit_2_without_a_traceback(tmp_path):
    r = run_cli(
        "quality", "omni-fig11", "--set", "controller.passivity=tdpa", "--out", str(tmp_path / "q")
    )
    assert r.returncode == 2
    assert "controller.passivity" in r.stderr and "tdpa" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "q").exists()  # nothing written
    for bad in (["no-such-scenario"], ["omni-contact", "--workers", "0"]):
        r = run_cli("quality", *bad, "--out", str(tmp_path / "q"))
        assert r.returncode == 2 and "Traceback" not in r.stderr, bad
        assert bad[-1] in r.stderr
    assert not (tmp_path / "q").exists()
