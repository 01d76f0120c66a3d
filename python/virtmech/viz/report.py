"""index.html: every run's figures and metrics on one page, in the paper's figure order,
with the virtmech version, the git commit, the date and every metric's definition."""

from __future__ import annotations

import datetime
import html
import math
import subprocess
from pathlib import Path

LABELS = [
    ("time_to_1mm_s", "time to 1 mm [s]", 1.0, "{:.3f}"),
    ("dist_rms_after_m", "RMS distance after [mm]", 1e3, "{:.3f}"),
    ("dist_max_after_m", "max distance after [mm]", 1e3, "{:.3f}"),
    ("dist_max_m", "max distance [mm]", 1e3, "{:.3f}"),
    ("penetration_max_m", "max penetration [mm]", 1e3, "{:.3f}"),
    ("force_max_n", "max force [N]", 1.0, "{:.2f}"),
    ("force_rms_n", "RMS force [N]", 1.0, "{:.2f}"),
    ("passive_torque_max", "max torque on unpowered joints [N·m]", 1.0, "{:.3g}"),
    ("torque_fraction_max", "max torque / limit", 1.0, "{:.2f}"),
    ("energy_to_user_j", "work on user [mJ]", 1e3, "{:.2f}"),
    ("real_time_factor", "× real time", 1.0, "{:.1f}"),
]


def _fmt(v, scale, fmt, note: str | None = None) -> str:
    """A table cell: the value, or "n/a" with the reason as its tooltip and text."""
    if v is None or (isinstance(v, float) and math.isnan(v)) or isinstance(v, str):
        why = note or "n/a: not defined for this run"
        return f'<span class="na" title="{html.escape(why)}">{html.escape(why)}</span>'
    text = fmt.format(v * scale)
    return html.escape(text.lstrip("-") if float(text) == 0.0 else text)  # no "-0.00"


def _git(where: Path, *args: str) -> str:
    try:
        return subprocess.run(
            ["git", "-C", str(where), *args],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def git_commit() -> str:
    """The commit of the virtmech checkout this runs from (an editable install), else of a
    virtmech checkout in the current directory (a wheel built from it), else "unknown"."""
    for where in (Path(__file__).resolve().parent, Path.cwd()):
        top = _git(where, "rev-parse", "--show-toplevel")
        if top and (Path(top) / "python" / "virtmech" / "__init__.py").exists():
            commit = _git(where, "rev-parse", "HEAD")
            if len(commit) == 40:
                dirty = _git(where, "status", "--porcelain", "--untracked-files=no")
                return commit + ("-dirty" if dirty else "")
    return "unknown"


def build_info() -> dict:
    """{"virtmech": version, "commit": git commit or "unknown", "date": UTC ISO date-time}."""
    import virtmech

    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    return {"virtmech": virtmech.__version__, "commit": git_commit(), "date": now.isoformat()}


def _definitions() -> str:
    from ..sim.geometry import GEOMETRY
    from ..sim.output import METRICS, WITHIN_M

    rows = "".join(
        f"<tr><td><code>{html.escape(k)}</code></td><td>{html.escape(u)}</td>"
        f"<td>{html.escape(d)}</td></tr>"
        for k, (u, d) in METRICS.items()
    )
    kinds = "".join(
        f"<li>{html.escape(t)}: the {html.escape(g.point)} from {html.escape(g.target)}; "
        f"negative signed distance: {html.escape(g.negative)}</li>"
        for t, g in GEOMETRY.items()
    )
    return (
        "<h2>Definitions</h2>"
        "<p><code>dist</code> (log.csv) is the distance of the mechanism's point from where "
        "the mechanism lets it be (zero where a unilateral mechanism's tip has lifted off); "
        "<code>dist_signed</code> its signed distance from the path or surface, "
        "<code>dist_normal</code> the part along the mechanism's normal, "
        "<code>dist_across</code> the rest. The stylus tip is the handle moved by the "
        "mechanism's length along the stylus.</p>"
        f"<ul>{kinds}<li>other mechanisms: the nearest placement's position error</li></ul>"
        f"<p>Threshold: {WITHIN_M * 1e3:g} mm. Figures: force arrows at one scale in every "
        "figure (stated in each legend).</p>"
        '<table class="defs"><tr><th>metric</th><th>unit</th><th>definition</th></tr>'
        f"{rows}</table>"
    )


def write_index(out_dir: str | Path, entries: list[dict], title: str = "virtmech demo") -> Path:
    """entries: [{"name", "description", "dir" (relative), "metrics"}], shown in the paper's
    figure order (fig9, fig10, fig11, fig12, device by device; others after)."""
    from ..sim.output import paper_order

    out = Path(out_dir)
    by_name = {e["name"]: e for e in entries}
    entries = [by_name[n] for n in paper_order(by_name)]
    info = build_info()
    head = "".join(f"<th>{html.escape(lbl)}</th>" for _, lbl, _, _ in LABELS)
    rows = []
    for e in entries:
        m = e["metrics"]
        notes = m.get("notes") or {}
        cells = "".join(f"<td>{_fmt(m.get(k), s, f, notes.get(k))}</td>" for k, _, s, f in LABELS)
        rows.append(f'<tr><td><a href="#{e["name"]}">{html.escape(e["name"])}</a></td>{cells}</tr>')
    sections = []
    for e in entries:
        d = html.escape(e["dir"])
        log = html.escape(e.get("log", "log.csv"))
        sections.append(
            f'<section id="{html.escape(e["name"])}"><h2>{html.escape(e["name"])}</h2>'
            f"<p>{html.escape(e['description'])}</p>"
            f'<p><a href="{d}/{log}">{log}</a> · <a href="{d}/run.json">run.json</a></p>'
            f'<div class="figs"><img src="{d}/plane.png" alt="{d} plane">'
            f'<img src="{d}/time.png" alt="{d} time">'
            + (f'<img src="{d}/scene.png" alt="{d} in 3-D">'
               if (Path(out_dir) / e["dir"] / "scene.png").is_file() else "")
            + "</div>"
            "</section>"
        )
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em; max-width: 1500px; }}
table {{ border-collapse: collapse; font-size: 0.9em; }}
td, th {{ border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: right; }}
td:first-child {{ text-align: left; }}
.figs img {{ max-width: 49%; vertical-align: top; }}
.na {{ color: #777; font-size: 0.85em; }}
table.defs td {{ text-align: left; }}
section {{ margin-top: 2.5em; border-top: 1px solid #ddd; }}
</style></head><body>
<h1>{html.escape(title)}</h1>
<p>The paper's Figs. 9–12 (Luecke &amp; Beckman, virtual mechanisms for under-actuated haptic
devices) simulated in MuJoCo on the PHANTOM Omni and on the Planar3R. Metrics: summary.json.</p>
<p class="build">virtmech {html.escape(info["virtmech"])} · commit
<code>{html.escape(info["commit"])}</code> · {html.escape(info["date"])}</p>
<table><tr><th>scenario</th>{head}</tr>
{"".join(rows)}
</table>
{_definitions()}
{"".join(sections)}
</body></html>
"""
    path = out / "index.html"
    path.write_text(page, encoding="utf-8")
    return path
