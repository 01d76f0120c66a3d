"""The figures of a run, read back from what matplotlib drew: scene.png draws the world's up
as up at one scale on every axis, the time plots' legends cover none of their curves, the
plane figure's time labels are readable on white and its strokes do not pile up."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")
pytest.importorskip("matplotlib")

import virtmech.scenarios as sc  # noqa: E402
import virtmech.sim as sim  # noqa: E402
from virtmech.viz import figures as F  # noqa: E402

#: the PHANTOM Omni's world is OpenHaptics' frame: x right, y up, z toward the user
OMNI_UP = 1


@pytest.fixture(scope="module")
def runs():
    names = ("omni-surface-nurbs", "omni-surface-sphere", "omni-letter", "omni-trocar",
             "omni-fig9")
    return {n: sim.run(sc.load(n)) for n in names}


@pytest.fixture
def drawn(monkeypatch):
    """The figures saved while the test runs (matplotlib's Figure objects)."""
    from matplotlib.figure import Figure

    figures = []
    save = Figure.savefig

    def keep(self, *args, **kwargs):
        figures.append(self)
        return save(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    return figures


def _line(ax, label: str):
    lines = [ln for ln in ax.get_lines() if ln.get_label() == label]
    assert len(lines) == 1, [ln.get_label() for ln in ax.get_lines()]
    return lines[0]


def _world_axis(values: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The signed world unit vector whose coordinate of P the plot's `values` are."""
    for j in range(3):
        for sign in (1.0, -1.0):
            if np.allclose(values, sign * P[:, j], rtol=0, atol=1e-12):
                return sign * np.eye(3)[j]
    raise AssertionError("the plot's coordinate is none of the world's")


@pytest.mark.parametrize("name", ["omni-surface-nurbs", "omni-surface-sphere", "omni-letter"])
def test_the_scene_draws_the_worlds_up_as_up_at_one_scale(runs, drawn, tmp_path, name):
    r = runs[name]
    F.scene_figure(r, tmp_path / "scene.png")
    ax = drawn[-1].axes[0]
    P = r.cols("px", "py", "pz")
    xs, ys, zs = _line(ax, "handle path").get_data_3d()
    ex, ey, ez = (_world_axis(np.asarray(v), P) for v in (xs, ys, zs))
    assert ez @ np.eye(3)[OMNI_UP] == 1.0  # the plot's vertical is the world's up, pointing up
    np.testing.assert_array_equal(np.cross(ex, ey), ez)  # not a mirror image
    spans = [np.ptp(lim) for lim in (ax.get_xlim(), ax.get_ylim(), ax.get_zlim())]
    assert spans == pytest.approx([spans[0]] * 3, rel=1e-12)  # one scale on every axis
    assert ax.get_box_aspect() == pytest.approx([ax.get_box_aspect()[0]] * 3)
    assert 0 < ax.elev < 90  # seen from above the horizon
    labels = drawn[-1].legends[0].get_texts()
    assert any("stylus" in t.get_text() for t in labels)


def test_the_whole_sphere_is_inside_the_scenes_axes(runs, drawn, tmp_path):
    r = runs["omni-surface-sphere"]
    F.scene_figure(r, tmp_path / "scene.png")
    ax = drawn[-1].axes[0]
    s = r.scenario["mechanism"]["surface"]
    c, radius = np.asarray(s["center"]), s["radius"]
    P = r.cols("px", "py", "pz")
    lims = (ax.get_xlim(), ax.get_ylim(), ax.get_zlim())
    data = _line(ax, "handle path").get_data_3d()
    for lim, values in zip(lims, data):
        e = _world_axis(np.asarray(values), P)
        lo, hi = sorted(e @ c + np.array([-radius, radius]))
        assert min(lim) <= lo and hi <= max(lim)


def test_scene_axes_put_any_axis_up_in_a_right_handed_plot():
    for k in range(3):
        for sign in (1.0, -1.0):
            up = sign * np.eye(3)[k]
            axes, signs = F.scene_axes(up)
            E = np.array([sg * np.eye(3)[a] for a, sg in zip(axes, signs)])  # plot axes, world
            np.testing.assert_array_equal(E[2], up)
            assert np.linalg.det(E) == pytest.approx(1.0)


def _overlap(a, b) -> bool:
    return not (a.x1 <= b.x0 or b.x1 <= a.x0 or a.y1 <= b.y0 or b.y1 <= a.y0)


@pytest.mark.parametrize("name", ["omni-surface-nurbs", "omni-letter", "omni-fig9"])
def test_the_time_plots_legends_lie_beside_their_panels(runs, drawn, tmp_path, name):
    F.time_figure(runs[name], tmp_path / "time.png")
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = drawn[-1]
    canvas = FigureCanvasAgg(fig)  # the figure was closed: drawn again, as saved
    canvas.draw()
    r = canvas.get_renderer()
    for ax in fig.axes:
        legend = ax.get_legend()
        assert legend is not None
        assert not _overlap(legend.get_window_extent(r), ax.get_window_extent(r)), ax.get_ylabel()


def test_only_a_unilateral_mechanism_shows_the_tip_behind_it(runs, drawn, tmp_path):
    shown = {}
    for name in ("omni-surface-nurbs", "omni-letter"):
        F.time_figure(runs[name], tmp_path / f"{name}.png")
        texts = [t.get_text() for ax in drawn[-1].axes for t in ax.get_legend().get_texts()]
        shown[name] = "tip behind it" in texts
    assert shown == {"omni-surface-nurbs": True, "omni-letter": False}


def _contrast_on_white(rgb) -> float:
    """WCAG 2's contrast ratio of a colour against white."""
    c = np.asarray(rgb[:3], dtype=float)
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return 1.05 / (float(lin @ [0.2126, 0.7152, 0.0722]) + 0.05)


def _time_labels(fig) -> list:
    return [t for t in fig.axes[0].texts if t.get_text().endswith(" s")]


def test_the_plane_figures_time_labels_are_readable_on_white(runs, drawn, tmp_path):
    from matplotlib.colors import to_rgba

    F.plane_figure(runs["omni-fig9"], tmp_path / "plane.png")
    labels = _time_labels(drawn[-1])
    assert "3.00 s" in [t.get_text() for t in labels]  # the last moment, viridis' yellow
    for t in labels:
        assert _contrast_on_white(to_rgba(t.get_color())) >= 4.5, t.get_text()


def test_the_trocars_strokes_do_not_pile_up_and_its_axes_read_plainly(runs, drawn, tmp_path):
    info = F.plane_figure(runs["omni-trocar"], tmp_path / "plane.png")
    ax = drawn[-1].axes[0]
    strokes = [np.array(ln.get_xydata()) for ln in ax.get_lines()
               if ln.get_linewidth() == 5 and len(ln.get_xydata()) == 2]  # not the legend's
    assert len(strokes) >= 3
    tol = 1e-3  # [m]: half a stroke's width (5 pt) at this figure's scale

    def share_near(a, b, tol) -> float:
        pts = a[0] + np.linspace(0, 1, 101)[:, None] * (a[1] - a[0])
        d = b[1] - b[0]
        w = np.clip((pts - b[0]) @ d / (d @ d), 0, 1)
        return float(np.mean(np.hypot(*(pts - (b[0] + w[:, None] * d)).T) <= tol))

    for i, a in enumerate(strokes):
        for b in strokes[i + 1 :]:  # a fifth of each shows beside every other
            assert share_near(a, b, tol) <= 0.8 and share_near(b, a, tol) <= 0.8
    boxes = info["time_labels"]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
    assert ax.get_xlabel() == "u [m]  (u = (0.97, 0, -0.242))"  # no "-0.0"
